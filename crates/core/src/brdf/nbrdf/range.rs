//! The range check of a network's outputs (audit 2, T13): the f32 evaluations (the CPU
//! twin's `expm1f` clamps its argument at 88, the GPU kernel's `exp` overflows) cannot
//! represent an output of `e^88` or more, so a network reaching it is refused when it is
//! read rather than clamped in one back-end and infinite in the other.

use super::{Nbrdf, B1, B2, B3, FC1, FC1_ROWS, FC2, FC3, HIDDEN};
use crate::merl::{cell_angles, geometric_validity};

/// The largest output the f32 evaluations represent: `expm1f` clamps its argument at 88
/// (`e^88 - 1` = 1.65e38; f32 ends at 3.40e38).
pub(super) const MAX_OUTPUT: f32 = 1.6e38;

/// The exponent of [`MAX_OUTPUT`]: an upper bound of the last layer below it proves the
/// network in range without evaluating it.
const MAX_Z: f64 = 87.9;

impl Nbrdf {
    /// An upper bound of the last layer's pre-activation `z` (output `e^z - 1`) of each
    /// channel over every input (interval arithmetic over the input box: `sin th`,
    /// `cos th`, `cos td` in [0, 1], the two `sin td cos/sin pd` in [-1, 1]).
    pub(crate) fn output_bound(&self) -> [f64; 3] {
        let w = |k: usize| f64::from(self.w[k]);
        let boxes = [(0.0, 1.0), (0.0, 1.0), (-1.0, 1.0), (-1.0, 1.0), (0.0, 1.0)];
        let hi1: Vec<f64> = (0..HIDDEN)
            .map(|j| {
                let z = w(B1 + j)
                    + FC1_ROWS
                        .iter()
                        .zip(boxes)
                        .map(|(&r, (lo, hi))| {
                            let c = w(FC1 + r * HIDDEN + j);
                            (c * lo).max(c * hi)
                        })
                        .sum::<f64>();
                z.max(0.0)
            })
            .collect();
        // The activations are >= 0, so a weight's largest contribution is at 0 or at hi.
        let layer = |hi: &[f64], b: usize, fc: usize, n: usize, j: usize| {
            w(b + j)
                + (0..hi.len())
                    .map(|i| (w(fc + i * n + j) * hi[i]).max(0.0))
                    .sum::<f64>()
        };
        let hi2: Vec<f64> = (0..HIDDEN)
            .map(|j| layer(&hi1, B2, FC2, HIDDEN, j).max(0.0))
            .collect();
        std::array::from_fn(|c| layer(&hi2, B3, FC3, 3, c))
    }

    /// Refuses a network whose output reaches `MAX_OUTPUT` (1.6e38) at a geometrically valid cell
    /// of the MERL grid (every cell a distance, fit or tabulation evaluates): the message
    /// gives the channel, the cell's angles and the output in f64. Most networks are
    /// proved in range by an interval bound of the last layer; the others are evaluated on the grid.
    pub fn check_output_range(&self) -> Result<(), String> {
        if self.output_bound().iter().all(|&z| z < MAX_Z) {
            return Ok(());
        }
        let valid = geometric_validity();
        let cells: Vec<u32> = (0..valid.len() as u32)
            .filter(|&c| valid[c as usize])
            .collect();
        const RUN: usize = 1 << 16;
        let mut out = [vec![0f32; RUN], vec![0f32; RUN], vec![0f32; RUN]];
        for run in cells.chunks(RUN) {
            let n = run.len();
            {
                let [r, g, b] = &mut out;
                self.eval_cells(run, false, [&mut r[..n], &mut g[..n], &mut b[..n]]);
            }
            for (c, row) in out.iter().enumerate() {
                let Some(k) = row[..n]
                    .iter()
                    .position(|v| v.abs() >= MAX_OUTPUT || v.is_nan())
                else {
                    continue;
                };
                let (th, td, pd) = cell_angles(run[k] as usize);
                let exact = self.eval_raw_f64(th, td, pd)[c];
                return Err(format!(
                    "the network's {} output (the `_b3` and `_fc3` weights) reaches {exact:.3e} at theta_h, theta_d, phi_d = {:.2}, {:.2}, {:.2} degrees: a value beyond the f32 range the evaluations hold (up to e^88 = 1.65e38; f32 ends at 3.40e38)",
                    ["red", "green", "blue"][c],
                    th.to_degrees(),
                    td.to_degrees(),
                    pd.to_degrees()
                ));
            }
        }
        Ok(())
    }
}
