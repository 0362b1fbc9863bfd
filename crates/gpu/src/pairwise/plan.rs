//! Where a pairwise reduction's rows sit in the value texture, how the grid is cut into
//! chunks and runs, and which register blocks cover the requested block pairs.

use super::{
    KernelShape, BLOCK, MAX_CHUNK, MAX_CHUNK_HARDWARE, MAX_PACKED_BYTES, MAX_RUN_ITERS, TEX_W,
};
use crate::GpuContext;
use crate::NIJ;
use brdf_basis_core::backend::cpu::CANONICAL_RUN;
use brdf_basis_core::backend::Lobe;
use brdf_basis_core::error::GpuError;

/// The device limits a plan must respect.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlanLimits {
    /// Largest storage binding in bytes.
    pub max_binding: u64,
    /// Largest 2D texture side.
    pub max_texture_dim: u32,
    /// Largest dispatch dimension.
    pub max_dispatch: u32,
    /// Most cells per streamed chunk ([`MAX_CHUNK`] on a software adapter,
    /// [`MAX_CHUNK_HARDWARE`] on a hardware GPU).
    pub max_chunk: usize,
}

impl PlanLimits {
    /// The limits of a context.
    pub fn of(ctx: &GpuContext) -> Self {
        Self {
            max_binding: ctx.max_binding(),
            max_texture_dim: ctx.limits.max_texture_dimension_2d,
            max_dispatch: ctx.limits.max_compute_workgroups_per_dimension,
            max_chunk: match ctx.is_software() {
                true => MAX_CHUNK,
                false => MAX_CHUNK_HARDWARE,
            },
        }
    }
}

/// Where each lobe sits in the value texture: analytic lobes first (tabulated in
/// registers from their tables), padded to a whole texel, then measured tables (packed per
/// cell by the host), then neural lobes from a whole texel on (written per chunk by the
/// neural kernel on the device), so that no texel mixes two kinds.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RowLayout {
    /// Packed row of each lobe.
    pub row: Vec<usize>,
    /// Analytic lobes, in order.
    pub analytic: Vec<usize>,
    /// Measured tables, in order; they start at row `measured_start`.
    pub measured: Vec<usize>,
    /// Neural lobes, in order; they start at row `neural_start`.
    pub neural: Vec<usize>,
    /// First measured row (a multiple of 4).
    pub measured_start: usize,
    /// First neural row (a multiple of 4, after the measured rows).
    pub neural_start: usize,
    /// Rows in use.
    pub n_rows: usize,
}

impl RowLayout {
    /// The layout of `lobes`.
    pub fn new(lobes: &[Lobe]) -> Self {
        let kind = |i: &usize| match lobes[*i] {
            Lobe::Analytic(_) => 0,
            Lobe::Measured { .. } => 1,
            Lobe::Neural { .. } => 2,
        };
        let of = |k: i32| -> Vec<usize> { (0..lobes.len()).filter(|i| kind(i) == k).collect() };
        let (analytic, measured, neural) = (of(0), of(1), of(2));
        let measured_start = analytic.len().div_ceil(4) * 4;
        let neural_start = measured_start + measured.len().div_ceil(4) * 4;
        let mut row = vec![0; lobes.len()];
        for (k, &i) in analytic.iter().enumerate() {
            row[i] = k;
        }
        for (k, &i) in measured.iter().enumerate() {
            row[i] = measured_start + k;
        }
        for (k, &i) in neural.iter().enumerate() {
            row[i] = neural_start + k;
        }
        let n_rows = if neural.is_empty() {
            Self::rows_for(analytic.len(), measured.len())
        } else {
            neural_start + neural.len()
        };
        Self {
            row,
            n_rows,
            analytic,
            measured,
            neural,
            measured_start,
            neural_start,
        }
    }

    /// Rows of `n_analytic` analytic then `n_measured` measured lobes.
    pub fn rows_for(n_analytic: usize, n_measured: usize) -> usize {
        n_analytic.div_ceil(4) * 4 + n_measured
    }

    /// Packed rows after the analytic ones (measured, the padding to the neural rows'
    /// first texel, neural): the `n_measured` of [`PairPlan::new`].
    pub fn packed_rows(&self) -> usize {
        self.n_rows - self.measured_start
    }
}

/// f32 per row block of an analytic table: 8,100 betas and the alphas, four rows each.
pub(super) const TABLE_TEXELS: usize = NIJ + 1;

/// How a pairwise reduction is cut into chunks, runs and dispatches, and where its rows
/// sit in the value texture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairPlan {
    /// Register block and workgroup.
    pub shape: KernelShape,
    /// Packed rows padded to a multiple of the block side `4R`.
    pub n_pad: usize,
    /// Analytic row blocks (4 rows each; the last one may be part padding).
    pub analytic_blocks: usize,
    /// Measured row blocks.
    pub measured_blocks: usize,
    /// Cells per chunk (a multiple of [`CANONICAL_RUN`] unless the whole set is smaller).
    pub chunk: usize,
    /// Texels between measured row blocks: `chunk` rounded up to whole texture rows.
    pub row_stride: usize,
    /// Loop iterations per lane ([`MAX_RUN_ITERS`]: one canonical run).
    pub run_iters: u32,
    /// Runs per chunk.
    pub n_runs: usize,
}

impl PairPlan {
    /// Plans `n_analytic` analytic and `n_measured` measured lobes over `cells` cells.
    pub fn new(
        n_analytic: usize,
        n_measured: usize,
        cells: usize,
        limits: &PlanLimits,
        shape: KernelShape,
    ) -> Result<Self, GpuError> {
        let n_rows = RowLayout::rows_for(n_analytic, n_measured);
        let side = shape.side();
        let n_pad = n_rows.max(1).div_ceil(side) * side;
        let analytic_blocks = n_analytic.div_ceil(4);
        let measured_blocks = n_measured.div_ceil(4);
        let max_dim = limits.max_texture_dim as usize;
        let table_rows = table_rows(analytic_blocks);
        if table_rows > max_dim {
            return Err(GpuError::Limits(format!(
                "{n_analytic} analytic lobes need {table_rows} texture rows of tables; the \
                 adapter allows {max_dim}"
            )));
        }
        let by_texture = if measured_blocks == 0 {
            limits.max_chunk
        } else {
            (MAX_PACKED_BYTES / (16 * measured_blocks))
                .min((max_dim - table_rows) * TEX_W / measured_blocks)
                / TEX_W
                * TEX_W
        };
        let mut chunk = by_texture.min(limits.max_chunk).min(cells.max(1));
        if chunk < shape.lanes.min(cells.max(1)) {
            return Err(GpuError::Limits(format!(
                "{n_measured} measured lobes do not fit a texture of {MAX_PACKED_BYTES} bytes \
                 and side {max_dim} even {TEX_W} cells at a time"
            )));
        }
        // Every shape runs canonical runs of CANONICAL_LANES x MAX_RUN_ITERS cells (the
        // summation order shared with the CPU back-end); chunks hold whole canonical runs so
        // that runs start at the same cells whatever the chunk size.
        let run_iters = MAX_RUN_ITERS;
        let run = shape.lanes * run_iters as usize;
        let canonical = CANONICAL_RUN;
        if chunk > canonical {
            chunk = chunk / canonical * canonical;
        }
        let n_runs = chunk.div_ceil(run);
        if n_runs > limits.max_dispatch as usize {
            return Err(GpuError::Limits(format!(
                "{n_runs} runs per chunk exceed the dispatch limit {}",
                limits.max_dispatch
            )));
        }
        Ok(Self {
            shape,
            n_pad,
            analytic_blocks,
            measured_blocks,
            chunk,
            row_stride: chunk.next_multiple_of(TEX_W),
            run_iters,
            n_runs,
        })
    }

    /// Texel of the all-zero table (after the analytic tables).
    pub fn zero_base(&self) -> usize {
        self.analytic_blocks * TABLE_TEXELS
    }

    /// Texel of the first measured block's cell 0 (after the tables, on a whole row).
    pub fn measured_base(&self) -> usize {
        table_rows(self.analytic_blocks) * TEX_W
    }

    /// Height of the value texture (width [`TEX_W`]).
    pub fn texture_height(&self) -> u32 {
        (table_rows(self.analytic_blocks) + self.measured_blocks * self.row_stride / TEX_W) as u32
    }

    /// f32 of per-lane partial sums one register block writes per chunk.
    pub fn partials_per_block(&self) -> usize {
        self.n_runs * self.shape.lanes * self.shape.side() * self.shape.side()
    }
}

/// Texture rows of `blocks` analytic tables and the zero table.
pub(super) fn table_rows(blocks: usize) -> usize {
    ((blocks + 1) * TABLE_TEXELS).div_ceil(TEX_W)
}

/// The register blocks `(I <= J)` (in units of `4R` packed rows) that hold every lobe pair
/// of the requested `BLOCK x BLOCK` block pairs, sorted.
pub(crate) fn covering_blocks(
    blocks: &[[u32; 2]],
    layout: &RowLayout,
    shape: KernelShape,
) -> Vec<[u32; 2]> {
    let side = shape.side();
    let n = layout.row.len();
    let mut v = Vec::new();
    for &[bi, bj] in blocks {
        for r in 0..BLOCK {
            for q in 0..BLOCK {
                let (i, j) = (bi as usize * BLOCK + r, bj as usize * BLOCK + q);
                if i < n && j < n {
                    let (a, b) = (layout.row[i] / side, layout.row[j] / side);
                    v.push([a.min(b) as u32, a.max(b) as u32]);
                }
            }
        }
    }
    v.sort_unstable();
    v.dedup();
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf_basis_core::backend::all_blocks;
    use brdf_basis_core::brdf::LobeParams;
    use brdf_basis_core::merl::MerlTable;
    use std::sync::Arc;

    fn lobes(kinds: &str) -> Vec<Lobe> {
        kinds
            .chars()
            .map(|k| match k {
                'a' => Lobe::Analytic(LobeParams {
                    kd: 0.0,
                    ks: 1.0,
                    f0: 0.5,
                    n: 10.0,
                }),
                'n' => Lobe::Neural {
                    net: Arc::new(
                        brdf_basis_core::brdf::Nbrdf::from_weights(
                            vec![0.0; brdf_basis_core::brdf::NBRDF_WEIGHTS],
                        )
                        .expect("weights"),
                    ),
                    channel: None,
                },
                _ => Lobe::Measured {
                    table: Arc::new(MerlTable { rgb: Vec::new() }),
                    channel: None,
                },
            })
            .collect()
    }

    #[test]
    fn analytic_rows_come_first_and_measured_start_on_a_texel() {
        let l = RowLayout::new(&lobes("amaam"));
        assert_eq!(l.analytic, [0, 2, 3]);
        assert_eq!(l.measured, [1, 4]);
        assert_eq!(l.measured_start, 4);
        assert_eq!(l.row, [0, 4, 1, 2, 5]);
        assert_eq!(l.n_rows, 6);
        assert_eq!(RowLayout::rows_for(3, 2), 6);
        assert_eq!(l.packed_rows(), 2);
    }

    #[test]
    fn neural_rows_start_on_a_texel_after_the_measured_ones() {
        // a n m a n m m m m n: analytic 0, 3 | measured 2, 5, 6, 7, 8 | neural 1, 4, 9.
        let l = RowLayout::new(&lobes("anmanmmmmn"));
        assert_eq!(l.analytic, [0, 3]);
        assert_eq!(l.measured, [2, 5, 6, 7, 8]);
        assert_eq!(l.neural, [1, 4, 9]);
        assert_eq!((l.measured_start, l.neural_start, l.n_rows), (4, 12, 15));
        assert_eq!(l.row, [0, 12, 4, 1, 13, 5, 6, 7, 8, 14]);
        assert_eq!(l.packed_rows(), 11);
        // Neural lobes only: they start at row 0.
        let l = RowLayout::new(&lobes("nn"));
        assert_eq!((l.measured_start, l.neural_start, l.n_rows), (0, 0, 2));
    }

    #[test]
    fn covering_blocks_hold_every_requested_pair_in_row_order() {
        // Rows 0, 4, 1, 2 | 5 for lobes a m a a | m; register blocks of 4 rows (R = 1).
        let l = RowLayout::new(&lobes("amaam"));
        let r1 = KernelShape::register(1, 8);
        // Lobes 0..3 sit in rows 0, 1, 2 (block 0) and 4 (block 1).
        assert_eq!(covering_blocks(&[[0, 0]], &l, r1), [[0, 0], [0, 1], [1, 1]]);
        assert_eq!(
            covering_blocks(&all_blocks(5), &l, r1),
            [[0, 0], [0, 1], [1, 1]]
        );
        // Blocks of 8 rows hold them all.
        let r2 = KernelShape::register(2, 8);
        assert_eq!(covering_blocks(&all_blocks(5), &l, r2), [[0, 0]]);
    }

    #[test]
    fn diagonal_blocks_evaluate_the_upper_texel_pairs() {
        let s = KernelShape::register(5, 8);
        // 100 rows: 5 blocks of 20; 10 off the diagonal (400 pairs), 5 on it (15 of 25
        // texel pairs of 16 lobe pairs).
        assert_eq!(s.evaluated_pairs(100), 10.0 * 400.0 + 5.0 * 15.0 * 16.0);
    }
}
