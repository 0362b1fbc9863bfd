//! Non-negative least squares on the Gram form (SPEC section 5; the paper's Eq. 1, 2).
//!
//! Per colour channel a fit minimises `||A x - b||_W^2` subject to `x >= 0`, where column 0
//! of `A` is the Lambertian column by convention. The solvers never see `A`: they take the
//! Gram quantities
//!
//! ```text
//! G = A^T W A  (m x m, symmetric PSD, possibly rank-deficient),  h = A^T W b,  bb = b^T W b
//! q(x) = ||A x - b||_W^2 = x^T G x - 2 h^T x + bb
//! ```
//!
//! * [`lawson_hanson`]: the exact active-set solver (Lawson & Hanson 1974, ch. 23), the
//!   reference that defines "the exact optimum" of SPEC section 5, with its tie-breaking.
//! * [`pgd`]: accelerated projected gradient for many targets sharing one `G`, the CPU twin
//!   of a GPU-batched solver.
//!
//! Both work on the diagonally scaled problem `G~ = D^-1 G D^-1`, `h~ = D^-1 h`, `y = D x`,
//! `D = diag(sqrt(G_ii))`, so that every non-zero column has unit norm; a zero column
//! (`G_ii <= f64::MIN_POSITIVE`) is fixed at `x_i = 0`.
//!
//! # Scaled KKT violation
//! With the half gradient `g = G x - h`, the KKT conditions are `g_i = 0` where `x_i > 0` and
//! `g_i >= 0` where `x_i = 0`. [`kkt_violation`] reports
//!
//! ```text
//! v = max_i v_i / (sqrt(G_ii) s),   v_i = |g_i| if x_i > 0,  max(0, -g_i) if x_i = 0,
//! s = max_i |h_i| / sqrt(G_ii) + sum_j sqrt(G_jj) x_j
//! ```
//!
//! `g_i / sqrt(G_ii) = a_i^T W (A x - b) / ||a_i||_W` is the residual's projection on the unit
//! column; `s` bounds the size of the terms it is computed from (`|h_i| / sqrt(G_ii) <=
//! ||b||_W` and `||A x||_W <= sum_j ||a_j||_W x_j`). So `v` is invariant to scaling `b` or any
//! column, lies in `[0, 1]` for a feasible `x`, and rounding puts a floor of a few `1e-16`
//! under it. Zero columns are ignored; `v = 0` when `s = 0` (then `g = 0`).

use serde::{Deserialize, Serialize};

mod dense;
pub mod incremental;
pub mod lawson_hanson;
pub mod pgd;

pub use dense::solve_dense;

/// Errors from the NNLS solvers and their input views.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum NnlsError {
    /// An array has the wrong length.
    #[error("{what}: expected length {expected}, found {found}")]
    DimensionMismatch {
        /// Which array (`"G"`, `"h"`, `"x"`, `"targets"`, ...).
        what: &'static str,
        /// Length the other inputs imply.
        expected: usize,
        /// Length given.
        found: usize,
    },
    /// An entry is NaN or infinite.
    #[error("{what}: non-finite entry {value} at (row {row}, col {col})")]
    NonFinite {
        /// Which array.
        what: &'static str,
        /// Row (for a vector: the index; for a batch of vectors: the target).
        row: usize,
        /// Column (0 for a vector; for a batch: the index within the target).
        col: usize,
        /// The value found.
        value: f64,
    },
    /// The problem has no column (`m = 0`).
    #[error("empty NNLS problem (no columns)")]
    Empty,
    /// More columns than the solver supports.
    #[error("{solver}: {found} columns exceed the limit of {limit}")]
    TooManyColumns {
        /// Solver name.
        solver: &'static str,
        /// Largest supported number of columns.
        limit: usize,
        /// Number of columns given.
        found: usize,
    },
    /// A diagonal entry of `G` is negative, so `G` is not a Gram matrix.
    #[error("G: negative diagonal entry {value} at index {index}")]
    NegativeDiagonal {
        /// Index `i` of `G_ii`.
        index: usize,
        /// The value found.
        value: f64,
    },
    /// A scalar input or solver parameter is out of range.
    #[error("{what} = {value}: {reason}")]
    InvalidValue {
        /// Name of the value or parameter.
        what: &'static str,
        /// The value found.
        value: f64,
        /// The valid range.
        reason: &'static str,
    },
}

/// Result of one NNLS solve, in the caller's (unscaled) variables.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NnlsSolution {
    /// Coefficients, `x_i >= 0` (exactly 0 on the active bounds and for zero columns).
    pub x: Vec<f64>,
    /// Gram-form objective `q(x) = x^T G x - 2 h^T x + bb`. It suffers cancellation of order
    /// `1e-16 * bb`, so it may be slightly negative for a near-exact fit (and is offset by
    /// `-bb` when the caller passed `bb = 0`). Compute residuals on the grid for reporting.
    pub objective: f64,
    /// Solver iterations (outer loops for Lawson-Hanson, gradient steps for PGD).
    pub iterations: usize,
    /// Scaled KKT violation of `x` (module docs), with a rounding floor of about `1e-16`.
    /// Lawson-Hanson leaves at most about its `kkt_tol` (more only where it refused a
    /// numerically dependent column); PGD stops at its `tol` or at `max_iter`.
    pub max_kkt_violation: f64,
}

/// A validated, borrowed NNLS problem in Gram form.
#[derive(Debug, Clone, Copy)]
pub struct GramProblem<'a> {
    m: usize,
    g: &'a [f64],
    h: &'a [f64],
    bb: f64,
}

impl<'a> GramProblem<'a> {
    /// Validates and wraps `G` (`m x m`, row-major), `h` (`m`) and `bb = b^T W b >= 0` (pass 0
    /// when unknown: only [`NnlsSolution::objective`] shifts). Rejects `m = 0`, wrong
    /// lengths, non-finite entries, a negative `G_ii` or a negative `bb`. `G` must be
    /// symmetric; the solvers use `(G_ij + G_ji) / 2`, so rounding-level asymmetry is harmless.
    pub fn new(m: usize, g: &'a [f64], h: &'a [f64], bb: f64) -> Result<Self, NnlsError> {
        check_gram(m, g)?;
        check_len("h", m, h.len())?;
        check_finite("h", h, 1)?;
        if !bb.is_finite() {
            return Err(NnlsError::NonFinite {
                what: "bb",
                row: 0,
                col: 0,
                value: bb,
            });
        }
        if bb < 0.0 {
            return Err(NnlsError::InvalidValue {
                what: "bb",
                value: bb,
                reason: "must be >= 0",
            });
        }
        Ok(Self { m, g, h, bb })
    }

    /// Number of columns `m`.
    pub fn m(&self) -> usize {
        self.m
    }

    /// `G`, row-major `m x m`.
    pub fn g(&self) -> &'a [f64] {
        self.g
    }

    /// `h = A^T W b`.
    pub fn h(&self) -> &'a [f64] {
        self.h
    }

    /// `bb = b^T W b`.
    pub fn bb(&self) -> f64 {
        self.bb
    }

    /// Gram-form objective `q(x) = bb + sum_i x_i ((G x)_i - 2 h_i)`.
    pub fn objective(&self, x: &[f64]) -> Result<f64, NnlsError> {
        check_len("x", self.m, x.len())?;
        Ok(objective_unchecked(self.m, self.g, self.h, self.bb, x))
    }

    /// Scaled KKT violation of `x` (module docs); `+inf` if some `x_i` is negative or NaN.
    pub fn kkt_violation(&self, x: &[f64]) -> Result<f64, NnlsError> {
        check_len("x", self.m, x.len())?;
        Ok(kkt_unchecked(self.m, self.g, self.h, x))
    }
}

/// A validated batch of targets sharing one `G`: target `t` has `h_t = hs[t*m..(t+1)*m]` and
/// `bb_t = bbs[t]`.
#[derive(Debug, Clone, Copy)]
pub struct GramBatch<'a> {
    m: usize,
    g: &'a [f64],
    hs: &'a [f64],
    bbs: &'a [f64],
}

impl<'a> GramBatch<'a> {
    /// Validates like [`GramProblem::new`] for every target; `hs.len()` must equal
    /// `bbs.len() * m`. An empty batch (no target) is valid.
    pub fn new(m: usize, g: &'a [f64], hs: &'a [f64], bbs: &'a [f64]) -> Result<Self, NnlsError> {
        check_gram(m, g)?;
        check_len("targets h", bbs.len() * m, hs.len())?;
        check_finite("targets h", hs, m)?;
        for (t, &bb) in bbs.iter().enumerate() {
            if !bb.is_finite() {
                return Err(NnlsError::NonFinite {
                    what: "targets bb",
                    row: t,
                    col: 0,
                    value: bb,
                });
            }
            if bb < 0.0 {
                return Err(NnlsError::InvalidValue {
                    what: "targets bb",
                    value: bb,
                    reason: "must be >= 0",
                });
            }
        }
        Ok(Self { m, g, hs, bbs })
    }

    /// Number of columns `m`.
    pub fn m(&self) -> usize {
        self.m
    }

    /// The shared `G`, row-major `m x m`.
    pub fn g(&self) -> &'a [f64] {
        self.g
    }

    /// Number of targets.
    pub fn len(&self) -> usize {
        self.bbs.len()
    }

    /// True when the batch holds no target.
    pub fn is_empty(&self) -> bool {
        self.bbs.is_empty()
    }

    /// Target `t` as a problem (`None` when `t >= len()`).
    pub fn problem(&self, t: usize) -> Option<GramProblem<'a>> {
        let bb = *self.bbs.get(t)?;
        Some(GramProblem {
            m: self.m,
            g: self.g,
            h: &self.hs[t * self.m..(t + 1) * self.m],
            bb,
        })
    }
}

/// Scaled KKT violation (module docs) of `x` for `G` (`m x m` row-major, `m = h.len()`) and
/// `h`. Returns `+inf` if some `x_i` is negative or NaN; errors on wrong lengths or a
/// non-finite `G` or `h`.
pub fn kkt_violation(g: &[f64], h: &[f64], x: &[f64]) -> Result<f64, NnlsError> {
    let m = h.len();
    check_gram(m, g)?;
    check_finite("h", h, 1)?;
    check_len("x", m, x.len())?;
    Ok(kkt_unchecked(m, g, h, x))
}

fn check_len(what: &'static str, expected: usize, found: usize) -> Result<(), NnlsError> {
    if expected == found {
        Ok(())
    } else {
        Err(NnlsError::DimensionMismatch {
            what,
            expected,
            found,
        })
    }
}

/// Rejects a non-finite entry, reported as (row, col) = (k / stride, k % stride).
fn check_finite(what: &'static str, a: &[f64], stride: usize) -> Result<(), NnlsError> {
    match a.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(k) => Err(NnlsError::NonFinite {
            what,
            row: k / stride,
            col: k % stride,
            value: a[k],
        }),
    }
}

fn check_gram(m: usize, g: &[f64]) -> Result<(), NnlsError> {
    if m == 0 {
        return Err(NnlsError::Empty);
    }
    check_len("G", m * m, g.len())?;
    check_finite("G", g, m)?;
    match (0..m).find(|&i| g[i * m + i] < 0.0) {
        None => Ok(()),
        Some(i) => Err(NnlsError::NegativeDiagonal {
            index: i,
            value: g[i * m + i],
        }),
    }
}

fn objective_unchecked(m: usize, g: &[f64], h: &[f64], bb: f64, x: &[f64]) -> f64 {
    let mut q = bb;
    for (i, (&xi, row)) in x.iter().zip(g.chunks_exact(m)).enumerate() {
        if xi != 0.0 {
            let gx: f64 = row.iter().zip(x).map(|(a, b)| a * b).sum();
            q += xi * (gx - 2.0 * h[i]);
        }
    }
    q
}

fn kkt_unchecked(m: usize, g: &[f64], h: &[f64], x: &[f64]) -> f64 {
    ScaledGram::new(m, g).kkt(h, x)
}

/// Scaled KKT violation in scaled variables, given `gy = G~ y` (module docs).
pub(crate) fn kkt_scaled(hs: &[f64], y: &[f64], gy: &[f64]) -> f64 {
    let s = hs.iter().fold(0.0f64, |a, v| a.max(v.abs())) + y.iter().sum::<f64>();
    if s.is_nan() || s <= 0.0 {
        return 0.0;
    }
    let mut worst = 0.0f64;
    for ((&hi, &yi), &gi) in hs.iter().zip(y).zip(gy) {
        let g = gi - hi; // half gradient
        worst = worst.max(if yi > 0.0 { g.abs() } else { (-g).max(0.0) });
    }
    worst / s
}

/// The diagonally scaled Gram matrix shared by both solvers.
#[derive(Debug, Clone)]
pub(crate) struct ScaledGram {
    /// Number of columns.
    pub(crate) m: usize,
    /// `d_i = sqrt(G_ii)`, or 0 for a zero column.
    pub(crate) d: Vec<f64>,
    /// `G~ = D^-1 sym(G) D^-1`, row-major, unit diagonal, zero rows/columns for zero columns.
    pub(crate) gs: Vec<f64>,
    /// Whether `d` and `gs` are still those [`ScaledGram::new`] computed from `G` (a
    /// solver that zeroes duplicate columns clears it): then [`ScaledGram::finish`] measures
    /// the KKT violation on them instead of scaling `G` again per target (the same numbers).
    pub(crate) pristine: bool,
}

impl ScaledGram {
    /// Scales a validated `G`.
    pub(crate) fn new(m: usize, g: &[f64]) -> Self {
        let mut gs = g[..m * m].to_vec();
        let d = incremental::cosine_in_place(m, &mut gs);
        Self {
            m,
            d,
            gs,
            pristine: true,
        }
    }

    /// The scaled KKT violation of `x >= 0` for `h` (module docs; `inf` for a negative or
    /// non-finite `x`), on this scaling of `G`.
    fn kkt(&self, h: &[f64], x: &[f64]) -> f64 {
        if x.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return f64::INFINITY;
        }
        let mut hs = vec![0.0; self.m];
        self.scale_h(h, &mut hs);
        let y: Vec<f64> = x.iter().zip(&self.d).map(|(xi, di)| xi * di).collect();
        let gy: Vec<f64> = self
            .gs
            .chunks_exact(self.m)
            .map(|row| row.iter().zip(&y).map(|(a, b)| a * b).sum())
            .collect();
        kkt_scaled(&hs, &y, &gy)
    }

    /// `h~ = D^-1 h` (0 for zero columns) into `out`.
    pub(crate) fn scale_h(&self, h: &[f64], out: &mut [f64]) {
        for ((o, &hi), &di) in out.iter_mut().zip(h).zip(&self.d) {
            *o = if di > 0.0 { hi / di } else { 0.0 };
        }
    }

    /// Builds the caller-facing solution from scaled coefficients `y`.
    pub(crate) fn finish(&self, p: &GramProblem<'_>, y: &[f64], iterations: usize) -> NnlsSolution {
        let x: Vec<f64> = y
            .iter()
            .zip(&self.d)
            .map(|(&yi, &di)| if di > 0.0 && yi > 0.0 { yi / di } else { 0.0 })
            .collect();
        let objective = objective_unchecked(self.m, p.g, p.h, p.bb, &x);
        // `p.g` is the `G` this scaling was made from (one per solve or batch).
        let max_kkt_violation = if self.pristine {
            self.kkt(p.h, &x)
        } else {
            kkt_unchecked(self.m, p.g, p.h, &x)
        };
        NnlsSolution {
            x,
            objective,
            iterations,
            max_kkt_violation,
        }
    }
}

#[cfg(test)]
pub(crate) mod test_support {
    //! Seeded random problems and checks made on `A` itself, shared by the solver tests.

    /// The seeded generator of the solver tests: ChaCha8, as every seeded step of the
    /// crate and the integration tests (`tests/common::rng`).
    pub(crate) struct Rng(rand_chacha::ChaCha8Rng);

    impl Rng {
        /// A generator seeded with `seed`.
        pub(crate) fn new(seed: u64) -> Self {
            Self(rand::SeedableRng::seed_from_u64(seed))
        }
        pub(crate) fn next_u64(&mut self) -> u64 {
            rand::RngCore::next_u64(&mut self.0)
        }
        /// Uniform in [0, 1).
        pub(crate) fn uniform(&mut self) -> f64 {
            (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
        }
        /// Standard normal (Box-Muller).
        pub(crate) fn normal(&mut self) -> f64 {
            let u = 1.0 - self.uniform();
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * self.uniform()).cos()
        }
    }

    /// A dense weighted least-squares problem: `a` is `rows x cols` column-major (column `j`
    /// at `a[j*rows..]`), `w` the sample weights, `b` the target.
    pub(crate) struct Dense {
        pub(crate) rows: usize,
        pub(crate) cols: usize,
        pub(crate) a: Vec<f64>,
        pub(crate) w: Vec<f64>,
        pub(crate) b: Vec<f64>,
    }

    impl Dense {
        pub(crate) fn col(&self, j: usize) -> &[f64] {
            &self.a[j * self.rows..(j + 1) * self.rows]
        }
        fn dot(&self, u: &[f64], v: &[f64]) -> f64 {
            u.iter()
                .zip(v)
                .zip(&self.w)
                .map(|((a, b), w)| a * b * w)
                .sum()
        }
        /// `(G, h, bb)` computed in f64.
        pub(crate) fn gram(&self) -> (Vec<f64>, Vec<f64>, f64) {
            let m = self.cols;
            let mut g = vec![0.0; m * m];
            for i in 0..m {
                for j in i..m {
                    let v = self.dot(self.col(i), self.col(j));
                    g[i * m + j] = v;
                    g[j * m + i] = v;
                }
            }
            let h = (0..m).map(|i| self.dot(self.col(i), &self.b)).collect();
            (g, h, self.dot(&self.b, &self.b))
        }
        /// Objective `||A x - b||_W^2` computed on `A`.
        pub(crate) fn objective(&self, x: &[f64]) -> f64 {
            let r = self.residual(x);
            self.dot(&r, &r)
        }
        fn residual(&self, x: &[f64]) -> Vec<f64> {
            let mut r: Vec<f64> = self.b.iter().map(|v| -v).collect();
            for (j, &xj) in x.iter().enumerate() {
                for (ri, aij) in r.iter_mut().zip(self.col(j)) {
                    *ri += xj * aij;
                }
            }
            r
        }
        /// KKT violation computed on `A`: `c_i = a_i^T W (A x - b) / (||a_i|| ||b||)`, `|c_i|`
        /// where `x_i > 0`, `max(0, -c_i)` where `x_i = 0`.
        pub(crate) fn kkt_on_a(&self, x: &[f64]) -> f64 {
            let r = self.residual(x);
            let nb = self.dot(&self.b, &self.b).sqrt();
            let mut worst = 0.0f64;
            for (j, &xj) in x.iter().enumerate() {
                let na = self.dot(self.col(j), self.col(j)).sqrt();
                if na == 0.0 || nb == 0.0 {
                    continue;
                }
                let c = self.dot(self.col(j), &r) / (na * nb);
                worst = worst.max(if xj > 0.0 { c.abs() } else { (-c).max(0.0) });
            }
            worst
        }
    }

    /// `rows x cols` problem with uniform(0, 1) columns and weights (all-positive, strongly
    /// correlated like BRDFs); columns listed in `combos` are replaced by non-negative
    /// combinations of earlier columns, making `G` exactly rank-deficient.
    pub(crate) fn random_dense(rng: &mut Rng, rows: usize, cols: usize, combos: &[usize]) -> Dense {
        let mut a: Vec<f64> = (0..rows * cols).map(|_| rng.uniform()).collect();
        for &j in combos {
            let (p, q) = (rng.next_u64() as usize % j, rng.next_u64() as usize % j);
            let (s, t) = (rng.uniform(), rng.uniform());
            for r in 0..rows {
                a[j * rows + r] = s * a[p * rows + r] + t * a[q * rows + r];
            }
        }
        let w = (0..rows).map(|_| 0.5 + rng.uniform()).collect();
        let b = (0..rows).map(|_| rng.uniform()).collect();
        Dense {
            rows,
            cols,
            a,
            w,
            b,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_rejects_bad_input() {
        let g = [2.0, 1.0, 1.0, 2.0];
        assert_eq!(
            GramProblem::new(0, &[], &[], 0.0).unwrap_err(),
            NnlsError::Empty
        );
        assert!(matches!(
            GramProblem::new(2, &g[..3], &[1.0, 1.0], 1.0),
            Err(NnlsError::DimensionMismatch {
                what: "G",
                expected: 4,
                found: 3
            })
        ));
        assert!(matches!(
            GramProblem::new(2, &g, &[1.0], 1.0),
            Err(NnlsError::DimensionMismatch { .. })
        ));
        let bad = [2.0, 1.0, f64::NAN, 2.0];
        assert!(matches!(
            GramProblem::new(2, &bad, &[1.0, 1.0], 1.0),
            Err(NnlsError::NonFinite { row: 1, col: 0, .. })
        ));
        let neg = [-2.0, 1.0, 1.0, 2.0];
        assert!(matches!(
            GramProblem::new(2, &neg, &[1.0, 1.0], 1.0),
            Err(NnlsError::NegativeDiagonal { index: 0, .. })
        ));
        assert!(matches!(
            GramProblem::new(2, &g, &[1.0, 1.0], -1.0),
            Err(NnlsError::InvalidValue { .. })
        ));
        assert!(matches!(
            GramBatch::new(2, &g, &[1.0; 3], &[1.0, 1.0]),
            Err(NnlsError::DimensionMismatch { .. })
        ));
        assert!(GramBatch::new(2, &g, &[], &[]).is_ok_and(|b| b.is_empty()));
        let p = GramProblem::new(2, &g, &[1.0, 1.0], 1.0).unwrap();
        assert!(p.objective(&[1.0]).is_err());
    }

    #[test]
    fn objective_and_kkt_on_a_known_point() {
        // A = I (2x2), b = (1, -1): optimum x = (1, 0), q = 1.
        let (g, h) = ([1.0, 0.0, 0.0, 1.0], [1.0, -1.0]);
        let p = GramProblem::new(2, &g, &h, 2.0).unwrap();
        assert_eq!(p.objective(&[1.0, 0.0]).unwrap(), 1.0);
        assert_eq!(p.kkt_violation(&[1.0, 0.0]).unwrap(), 0.0);
        // x = 0: gradient -h, violation |h_0| / s with s = max |h| = 1.
        assert_eq!(kkt_violation(&g, &h, &[0.0, 0.0]).unwrap(), 1.0);
        assert_eq!(kkt_violation(&g, &h, &[-1.0, 0.0]).unwrap(), f64::INFINITY);
        // Scale-free: scaling b and a column leaves it unchanged.
        let (g2, h2) = ([4.0, 0.0, 0.0, 1.0], [6.0, -3.0]);
        let v1 = kkt_violation(&g, &h, &[0.5, 0.0]).unwrap();
        let v2 = kkt_violation(&g2, &h2, &[0.75, 0.0]).unwrap();
        assert!((v1 - v2).abs() < 1e-15, "{v1} vs {v2}");
        assert_eq!(kkt_violation(&g, &[0.0, 0.0], &[0.0, 0.0]).unwrap(), 0.0);
    }

    #[test]
    fn gram_on_dense_matches_objective() {
        let mut rng = test_support::Rng::new(7);
        let d = test_support::random_dense(&mut rng, 40, 5, &[4]);
        let (g, h, bb) = d.gram();
        let p = GramProblem::new(5, &g, &h, bb).unwrap();
        let x = [0.1, 0.0, 0.3, 0.2, 0.05];
        assert!((p.objective(&x).unwrap() - d.objective(&x)).abs() < 1e-12 * bb);
    }
}
