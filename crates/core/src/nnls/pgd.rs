//! Accelerated projected gradient (FISTA with adaptive restart) for many NNLS targets that
//! share one Gram matrix: the CPU twin and reference of the GPU-batched solver.
//!
//! FISTA: Beck & Teboulle, "A fast iterative shrinkage-thresholding algorithm for linear
//! inverse problems", SIAM J. Imaging Sci. 2 (2009), DOI 10.1137/080716542. Adaptive
//! restart: O'Donoghue & Candes, "Adaptive restart for accelerated gradient schemes",
//! Found. Comput. Math. 15 (2015), DOI 10.1007/s10208-013-9150-3.
//!
//! On the scaled problem (module [`crate::nnls`]), one target per invocation, with
//! `x = v = 0`, `t = 1` and step `1 / L`:
//!
//! ```text
//! x+ = max(0, v - (G~ v - h~) / L)                 projected gradient step
//! stop when kkt(x+) <= tol                          scaled KKT violation, module docs
//! if (v - x+) . (x+ - x) > 0: t = 1, v = x+        gradient restart
//! else: t+ = (1 + sqrt(1 + 4 t^2)) / 2,  v = x+ + (t - 1) / t+ (x+ - x)
//! ```
//!
//! One matrix-vector product per step: `G~ v` is formed from `G~ x+` and `G~ x` by the same
//! linear combination as `v`. `L` is the largest eigenvalue of `G~` by power iteration
//! (times 1.02), capped by the Gershgorin bound `max_i sum_j |G~_ij|`, computed once per
//! batch.
//!
//! Ties: a column that is a positive multiple of an earlier one (`G~_ij > 0` and
//! `1 - G~_ij^2 <= 1e-12`, the Lawson-Hanson pivot test for a single column) is fixed at 0,
//! so duplicates and `sugar`-like multiples of the Lambertian column get the coefficients of
//! [`crate::nnls::lawson_hanson`]. Other non-unique problems (a column in the span of
//! several) reach the same objective with possibly different coefficients.
//!
//! The kernel keeps its vectors in fixed-size stack arrays. The GPU kernel fixes
//! `m <= 32` ([`PGD_KERNEL_COLUMNS`]); this twin also runs up to [`PGD_MAX_COLUMNS`] so that
//! it can cross-check fits against a whole collection.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::nnls::{kkt_scaled, GramBatch, GramProblem, NnlsError, NnlsSolution, ScaledGram};

/// Column count of the GPU kernel's fixed-size arrays (a basis of up to 31 materials plus
/// the Lambertian column).
pub const PGD_KERNEL_COLUMNS: usize = 32;

/// Largest column count this CPU solver accepts.
pub const PGD_MAX_COLUMNS: usize = 128;

/// Squared-sine threshold under which a column counts as a multiple of an earlier one.
const DUPLICATE_TOL: f64 = 1e-12;

/// Parameters of the projected-gradient solver; [`Default`] gives the documented defaults.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PgdParams {
    /// Stop when the scaled KKT violation (module [`crate::nnls`]) is `<= tol`. Default
    /// `1e-10`.
    pub tol: f64,
    /// Largest number of gradient steps per target. Default 5000.
    pub max_iter: usize,
}

impl Default for PgdParams {
    fn default() -> Self {
        Self {
            tol: 1e-10,
            max_iter: 5000,
        }
    }
}

impl PgdParams {
    /// Checks the parameters: `tol` finite and positive, `max_iter >= 1`.
    pub fn check(&self) -> Result<(), NnlsError> {
        if !(self.tol.is_finite() && self.tol > 0.0) {
            return Err(NnlsError::InvalidValue {
                what: "tol",
                value: self.tol,
                reason: "must be finite and > 0",
            });
        }
        if self.max_iter == 0 {
            return Err(NnlsError::InvalidValue {
                what: "max_iter",
                value: 0.0,
                reason: "must be >= 1",
            });
        }
        Ok(())
    }
}

/// Solves one problem (`m <= PGD_MAX_COLUMNS`).
pub fn solve(problem: &GramProblem<'_>, params: &PgdParams) -> Result<NnlsSolution, NnlsError> {
    let prep = Prepared::new(problem.m(), problem.g(), params)?;
    Ok(prep.run(problem, params))
}

/// Solves every target of `batch` in parallel (rayon), sharing the scaled `G` and its
/// Lipschitz constant. The result is in target order and identical to [`solve`] per target.
pub fn solve_batch(
    batch: &GramBatch<'_>,
    params: &PgdParams,
) -> Result<Vec<NnlsSolution>, NnlsError> {
    let prep = Prepared::new(batch.m(), batch.g(), params)?;
    Ok((0..batch.len())
        .into_par_iter()
        .filter_map(|t| batch.problem(t))
        .map(|p| prep.run(&p, params))
        .collect())
}

/// A batch's shared preparation: the scaled Gram matrix `G~` (duplicate columns fixed at
/// 0) and the step `1 / L`. Public so that the GPU kernel runs the same iteration.
#[derive(Debug, Clone)]
pub struct Prepared {
    sg: ScaledGram,
    inv_l: f64,
}

impl Prepared {
    /// The scaled Gram matrix `G~` (row-major `m x m`).
    pub fn scaled_gram(&self) -> &[f64] {
        &self.sg.gs
    }

    /// The step `1 / L`.
    pub fn inv_l(&self) -> f64 {
        self.inv_l
    }

    /// `h~ = D^-1 h` of one target.
    pub fn scaled_h(&self, h: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.sg.m];
        self.sg.scale_h(h, &mut out);
        out
    }

    /// The caller-facing solution (objective and KKT in f64) of scaled coefficients `y`.
    pub fn finish(&self, p: &GramProblem<'_>, y: &[f64], iterations: usize) -> NnlsSolution {
        self.sg.finish(p, y, iterations)
    }

    /// Prepares a batch with `m` columns and Gram matrix `g`.
    pub fn new(m: usize, g: &[f64], params: &PgdParams) -> Result<Self, NnlsError> {
        params.check()?;
        if m > PGD_MAX_COLUMNS {
            return Err(NnlsError::TooManyColumns {
                solver: "pgd",
                limit: PGD_MAX_COLUMNS,
                found: m,
            });
        }
        let mut sg = ScaledGram::new(m, g);
        for j in 0..m {
            let dup = (0..j).any(|i| {
                sg.d[i] > 0.0
                    && sg.gs[i * m + j] > 0.0
                    && 1.0 - sg.gs[i * m + j].powi(2) <= DUPLICATE_TOL
            });
            if dup {
                sg.pristine = false;
                sg.d[j] = 0.0;
                for k in 0..m {
                    sg.gs[j * m + k] = 0.0;
                    sg.gs[k * m + j] = 0.0;
                }
            }
        }
        let inv_l = 1.0 / lipschitz(&sg);
        Ok(Self { sg, inv_l })
    }

    fn run(&self, p: &GramProblem<'_>, params: &PgdParams) -> NnlsSolution {
        let m = self.sg.m;
        let mut hs = [0.0; PGD_MAX_COLUMNS];
        self.sg.scale_h(p.h(), &mut hs[..m]);
        let (y, iterations) = if m <= PGD_KERNEL_COLUMNS {
            let (y, it) = fista::<PGD_KERNEL_COLUMNS>(&self.sg.gs, m, self.inv_l, &hs[..m], params);
            (y[..m].to_vec(), it)
        } else {
            let (y, it) = fista::<PGD_MAX_COLUMNS>(&self.sg.gs, m, self.inv_l, &hs[..m], params);
            (y[..m].to_vec(), it)
        };
        self.sg.finish(p, &y, iterations)
    }
}

/// Lipschitz constant of `y -> G~ y`: 1.02 times a power-iteration estimate (at most 500
/// steps) of the largest eigenvalue, capped by the Gershgorin bound; 1 when `G~ = 0`.
fn lipschitz(sg: &ScaledGram) -> f64 {
    let m = sg.m;
    let gersh = sg
        .gs
        .chunks_exact(m)
        .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    if gersh.is_nan() || gersh <= 0.0 {
        return 1.0;
    }
    // An irregular positive start: overlaps the Perron vector of an all-positive (BRDF) Gram
    // matrix and is not an eigenvector of a symmetric pattern such as [[1, c], [c, 1]].
    let mut v: Vec<f64> =
        sg.d.iter()
            .enumerate()
            .map(|(i, &d)| {
                if d > 0.0 {
                    1.0 + (0.618_033_988_75 * (i + 1) as f64).fract()
                } else {
                    0.0
                }
            })
            .collect();
    let mut est = 0.0;
    for _ in 0..500 {
        let norm_v = v.iter().map(|a| a * a).sum::<f64>().sqrt();
        let w: Vec<f64> = sg
            .gs
            .chunks_exact(m)
            .map(|r| r.iter().zip(&v).map(|(a, b)| a * b).sum::<f64>() / norm_v)
            .collect();
        let next = w.iter().map(|a| a * a).sum::<f64>().sqrt();
        if next.is_nan() || next <= 0.0 {
            break;
        }
        let done = (next - est).abs() <= 1e-12 * next;
        est = next;
        v = w;
        if done {
            break;
        }
    }
    if est > 0.0 {
        (1.02 * est).min(gersh)
    } else {
        gersh
    }
}

/// `out = G~ x` over the first `m` entries (the kernel's only matrix-vector product).
#[inline]
fn matvec<const N: usize>(gs: &[f64], m: usize, x: &[f64; N], out: &mut [f64; N]) {
    for (o, row) in out.iter_mut().zip(gs.chunks_exact(m)) {
        *o = row.iter().zip(x).map(|(a, b)| a * b).sum();
    }
}

/// The per-target kernel (one GPU invocation): FISTA with gradient restart on the scaled
/// problem, all vectors on the stack. Returns `y` and the number of steps taken.
#[allow(clippy::needless_range_loop)] // index loops mirror the WGSL kernel
fn fista<const N: usize>(
    gs: &[f64],
    m: usize,
    inv_l: f64,
    hs: &[f64],
    params: &PgdParams,
) -> ([f64; N], usize) {
    let (mut x, mut gx) = ([0.0; N], [0.0; N]);
    let (mut v, mut gv) = ([0.0; N], [0.0; N]);
    let (mut xn, mut gxn) = ([0.0; N], [0.0; N]);
    let mut t = 1.0f64;
    let mut k = 0;
    while k < params.max_iter {
        k += 1;
        for i in 0..m {
            xn[i] = (v[i] - (gv[i] - hs[i]) * inv_l).max(0.0);
        }
        matvec(gs, m, &xn, &mut gxn);
        if kkt_scaled(hs, &xn[..m], &gxn[..m]) <= params.tol {
            return (xn, k);
        }
        let mut restart = 0.0;
        for i in 0..m {
            restart += (v[i] - xn[i]) * (xn[i] - x[i]);
        }
        if restart > 0.0 {
            t = 1.0;
            v = xn;
            gv = gxn;
        } else {
            let t_next = 0.5 * (1.0 + (1.0 + 4.0 * t * t).sqrt());
            let beta = (t - 1.0) / t_next;
            for i in 0..m {
                v[i] = xn[i] + beta * (xn[i] - x[i]);
                gv[i] = gxn[i] + beta * (gxn[i] - gx[i]);
            }
            t = t_next;
        }
        x = xn;
        gx = gxn;
    }
    (x, k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nnls::lawson_hanson::{self, LhParams};
    use crate::nnls::test_support::{random_dense, Dense, Rng};

    fn both(m: usize, g: &[f64], h: &[f64], bb: f64) -> (NnlsSolution, NnlsSolution) {
        let p = GramProblem::new(m, g, h, bb).unwrap();
        (
            solve(&p, &PgdParams::default()).unwrap(),
            lawson_hanson::solve(&p, &LhParams::default()).unwrap(),
        )
    }

    #[test]
    fn params_check_rejects_each_bad_parameter() {
        let d = PgdParams::default();
        assert!(d.check().is_ok());
        for bad in [
            PgdParams { tol: 0.0, ..d },
            PgdParams {
                tol: f64::INFINITY,
                ..d
            },
            PgdParams { max_iter: 0, ..d },
        ] {
            assert!(
                matches!(bad.check(), Err(NnlsError::InvalidValue { .. })),
                "{bad:?}"
            );
        }
    }

    #[test]
    fn rejects_too_many_columns() {
        let m = PGD_MAX_COLUMNS + 1;
        let g: Vec<f64> = (0..m * m)
            .map(|k| if k % (m + 1) == 0 { 1.0 } else { 0.0 })
            .collect();
        let h = vec![1.0; m];
        let p = GramProblem::new(m, &g, &h, 1.0).unwrap();
        let err = solve(&p, &PgdParams::default()).unwrap_err();
        assert_eq!(
            err,
            NnlsError::TooManyColumns {
                solver: "pgd",
                limit: PGD_MAX_COLUMNS,
                found: m
            }
        );
    }

    #[test]
    fn hand_made_cases() {
        let g = [2.0, 1.0, 1.0, 2.0];
        // (a) positive unconstrained optimum, (b) one active bound.
        let (s, _) = both(2, &g, &[4.0, 5.0], 14.0);
        assert!(
            (s.x[0] - 1.0).abs() < 1e-9
                && (s.x[1] - 2.0).abs() < 1e-9
                && s.max_kkt_violation <= 1e-10,
            "{s:?}"
        );
        let (s, _) = both(2, &g, &[1.0, -1.0], 2.0);
        assert!((s.x[0] - 0.5).abs() < 1e-10 && s.x[1] == 0.0, "{s:?}");
        // (d) zero target, (e) anti-correlated target.
        let (s, _) = both(2, &g, &[0.0, 0.0], 0.0);
        assert_eq!((s.x, s.iterations), (vec![0.0, 0.0], 1));
        let (s, _) = both(2, &g, &[-1.0, -0.5], 3.0);
        assert_eq!((s.x, s.objective), (vec![0.0, 0.0], 3.0));
    }

    #[test]
    fn duplicate_and_lambertian_multiple_get_no_weight() {
        let mut rng = Rng::new(21);
        for dup in [1, 2] {
            // (c) column `dup` copies column 0; (f) with column 0 Lambertian and `dup` 3.7x it.
            for lambertian in [false, true] {
                let mut d = random_dense(&mut rng, 40, 3, &[]);
                if lambertian {
                    d.a[..40].fill(std::f64::consts::FRAC_1_PI);
                }
                let c0: Vec<f64> = d
                    .col(0)
                    .iter()
                    .map(|v| if lambertian { 3.7 * v } else { *v })
                    .collect();
                d.a[dup * 40..(dup + 1) * 40].copy_from_slice(&c0);
                let other = 3 - dup;
                d.b = (0..40)
                    .map(|r| 0.4 * d.a[r] + 0.6 * d.a[other * 40 + r])
                    .collect();
                let (g, h, bb) = d.gram();
                let (s, l) = both(3, &g, &h, bb);
                assert_eq!(s.x[dup], 0.0, "{s:?}");
                assert!(
                    (s.x[0] - 0.4).abs() < 1e-8 && (s.x[other] - 0.6).abs() < 1e-8,
                    "{s:?}"
                );
                assert!(
                    s.x.iter().zip(&l.x).all(|(a, b)| (a - b).abs() < 1e-8),
                    "{s:?} vs {l:?}"
                );
            }
        }
    }

    #[test]
    fn rank_deficient_matches_lawson_hanson() {
        let mut rng = Rng::new(22);
        let combos = [7, 19, 20, 33, 48, 61, 62, 75, 88, 99];
        for t in 0..3 {
            let mut d = random_dense(&mut rng, 300, 100, &combos);
            if t == 2 {
                d.a.iter_mut().for_each(|v| *v -= 0.5);
            }
            let (g, h, bb) = d.gram();
            let p = GramProblem::new(100, &g, &h, bb).unwrap();
            let s = solve(&p, &PgdParams::default()).unwrap();
            let l = lawson_hanson::solve(&p, &LhParams::default()).unwrap();
            let (rel, kkt_a) = ((s.objective - l.objective) / bb, d.kkt_on_a(&s.x));
            eprintln!(
                "rank-deficient {t}: PGD - LH objective {rel:e} x bb, PGD steps {}, PGD KKT {:e} (on A {kkt_a:e}), LH KKT on A {:e}",
                s.iterations,
                s.max_kkt_violation,
                d.kkt_on_a(&l.x)
            );
            assert!(rel.abs() <= 1e-9 && rel >= -1e-12, "{rel:e}");
        }
    }

    #[test]
    fn matches_lawson_hanson_on_random_problems() {
        let mut rng = Rng::new(23);
        let mut worst = 0.0f64;
        for trial in 0..200 {
            let m = 1 + trial % 32;
            let mut d = random_dense(&mut rng, 3 * m + 10, m, &[]);
            d.a.iter_mut().for_each(|v| *v = rng.normal());
            let (g, h, bb) = d.gram();
            let (s, l) = both(m, &g, &h, bb);
            let rel = (s.objective - l.objective).abs() / bb;
            worst = worst.max(rel);
            assert!(rel <= 1e-6, "trial {trial}: {rel:e}");
        }
        eprintln!("PGD vs LH on 200 random problems: worst |objective difference| {worst:e} x bb");
    }

    #[test]
    fn batch_is_deterministic_and_matches_single_solves() {
        let mut rng = Rng::new(24);
        let d = random_dense(&mut rng, 60, 20, &[9, 19]);
        let (g, _, _) = d.gram();
        let (mut hs, mut bbs) = (Vec::new(), Vec::new());
        for _ in 0..64 {
            let t = Dense {
                b: (0..60).map(|_| rng.uniform() - 0.1).collect(),
                a: d.a.clone(),
                w: d.w.clone(),
                ..d
            };
            let (_, h, bb) = t.gram();
            hs.extend(h);
            bbs.push(bb);
        }
        let batch = GramBatch::new(20, &g, &hs, &bbs).unwrap();
        let first = solve_batch(&batch, &PgdParams::default()).unwrap();
        assert_eq!(first, solve_batch(&batch, &PgdParams::default()).unwrap());
        for (t, sol) in first.iter().enumerate() {
            assert_eq!(
                *sol,
                solve(&batch.problem(t).unwrap(), &PgdParams::default()).unwrap()
            );
        }
    }
}
