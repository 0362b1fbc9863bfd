//! Exact active-set NNLS on the Gram form: Lawson & Hanson, *Solving Least Squares
//! Problems* (Prentice-Hall 1974; SIAM 1995, DOI 10.1137/1.9781611971217), ch. 23, algorithm
//! NNLS, in the normal-equations form of Bro & De Jong, "A fast non-negativity-constrained
//! least squares algorithm", J. Chemometrics 11 (1997), DOI
//! 10.1002/(SICI)1099-128X(199709/10)11:5<393::AID-CEM483>3.0.CO;2-L.
//!
//! On the scaled problem (module [`crate::nnls`]: `G~` has unit diagonal) with the passive
//! set `P` (free coefficients) and the negative half gradient `w = h~ - G~ y`:
//!
//! 1. Candidates are the columns outside `P` with `w_j > kkt_tol * s` (`s` is the KKT scale
//!    of [`crate::nnls`]). None left: `y` is optimal.
//! 2. The largest `w_j` enters; every `w_i >= w_max - tie_tol * s` counts as a tie, won by
//!    the **lowest** index (SPEC 5: the Lambertian column 0 first, then earlier columns).
//! 3. Rank deficiency: `G~_PP = L L^T` is extended by one row. If the new pivot
//!    `d^2 = 1 - ||L^-1 G~_Pj||^2` (the squared sine of the angle between column `j` and the
//!    span of `P`) is `<= pivot_tol`, column `j` is numerically in that span: it does not
//!    enter and the next candidate is tried. So collinear columns never enter together and
//!    a later copy of a column never displaces the earlier one. A candidate whose own
//!    coefficient in the new solve is `<= 0` (possible only through rounding) is skipped too.
//! 4. Solve `G~_PP z = h~_P` (Cholesky plus one step of iterative refinement). While some
//!    `z_k <= 0`, step `y += alpha (z - y)` to the first bound (`alpha = min y_k / (y_k - z_k)`),
//!    drop the columns that reach 0 from `P`, refactor and solve again. Then `y = z`.
//!
//! Each outer loop lowers the objective (in exact arithmetic), so no active set repeats.
//! The outer loop is capped at `3 m + 30` by default (Lawson & Hanson cap at `3 n`); at the
//! cap the current feasible point is returned with its KKT violation.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::nnls::{GramBatch, GramProblem, NnlsError, NnlsSolution, ScaledGram};

/// Parameters of the Lawson-Hanson solver; [`Default`] gives the documented defaults.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LhParams {
    /// A column enters only when its scaled negative gradient exceeds `kkt_tol * s`
    /// (module docs). Default `1e-12`, a few hundred times the rounding floor of an f64
    /// Gram matrix; raise it (e.g. `1e-6`) for a Gram matrix accumulated in f32.
    pub kkt_tol: f64,
    /// Relative Cholesky pivot threshold: a column whose squared sine to the span of the
    /// passive columns is `<= pivot_tol` counts as dependent. Default `1e-12` (angle 1e-6 rad).
    pub pivot_tol: f64,
    /// Gradients within `tie_tol * s` of the largest are ties, won by the lowest column
    /// index. Default `1e-9`.
    pub tie_tol: f64,
    /// Cap on outer loops (columns entering); `None` means `3 m + 30`.
    pub max_outer: Option<usize>,
}

impl Default for LhParams {
    fn default() -> Self {
        Self {
            kkt_tol: 1e-12,
            pivot_tol: 1e-12,
            tie_tol: 1e-9,
            max_outer: None,
        }
    }
}

impl LhParams {
    /// Checks every parameter: tolerances finite in `(0, 1)` (`tie_tol` in `[0, 1)`), and
    /// `max_outer`, when given, at least 1.
    pub fn check(&self) -> Result<(), NnlsError> {
        let unit = |what, v: f64, lo_ok: bool| {
            if v.is_finite() && v < 1.0 && (v > 0.0 || (lo_ok && v == 0.0)) {
                Ok(())
            } else {
                Err(NnlsError::InvalidValue {
                    what,
                    value: v,
                    reason: "must lie in (0, 1)",
                })
            }
        };
        unit("kkt_tol", self.kkt_tol, false)?;
        unit("pivot_tol", self.pivot_tol, false)?;
        unit("tie_tol", self.tie_tol, true)?;
        if self.max_outer == Some(0) {
            return Err(NnlsError::InvalidValue {
                what: "max_outer",
                value: 0.0,
                reason: "must be >= 1",
            });
        }
        Ok(())
    }

    /// The outer-loop cap for `m` columns: `max_outer`, or `3 m + 30`.
    pub fn outer_cap(&self, m: usize) -> usize {
        self.max_outer.unwrap_or(3 * m + 30)
    }
}

/// Solves one problem exactly (up to rounding and the tolerances of [`LhParams`]).
pub fn solve(problem: &GramProblem<'_>, params: &LhParams) -> Result<NnlsSolution, NnlsError> {
    params.check()?;
    let sg = ScaledGram::new(problem.m(), problem.g());
    Ok(solve_prepared(&sg, problem, params))
}

/// Solves every target of `batch` in parallel (rayon), sharing one scaled `G`. The result
/// is in target order and identical to calling [`solve`] on each target.
pub fn solve_batch(
    batch: &GramBatch<'_>,
    params: &LhParams,
) -> Result<Vec<NnlsSolution>, NnlsError> {
    let pb = PreparedBatch::new(batch, params)?;
    Ok((0..batch.len())
        .into_par_iter()
        .filter_map(|t| pb.solve(t))
        .collect())
}

/// A batch scaled once, its targets solved one at a time: [`PreparedBatch::solve`] of
/// target `t` is [`solve_batch`]'s entry `t`, bit for bit (for callers that stop early).
pub(crate) struct PreparedBatch<'a> {
    batch: &'a GramBatch<'a>,
    sg: ScaledGram,
    params: LhParams,
}

impl<'a> PreparedBatch<'a> {
    /// Checks the parameters and scales the batch's `G`.
    pub(crate) fn new(batch: &'a GramBatch<'a>, params: &LhParams) -> Result<Self, NnlsError> {
        params.check()?;
        Ok(Self {
            batch,
            sg: ScaledGram::new(batch.m(), batch.g()),
            params: *params,
        })
    }

    /// The solution of target `t` (`None` when `t >= len()`).
    pub(crate) fn solve(&self, t: usize) -> Option<NnlsSolution> {
        let p = self.batch.problem(t)?;
        Some(solve_prepared(&self.sg, &p, &self.params))
    }

    /// The coefficients of target `t` only, into `x` (length `m`): [`PreparedBatch::solve`]'s
    /// `x` bit for bit, without its objective and KKT check and without allocating
    /// (`ws` is reused across calls). False when `t >= len()`.
    pub(crate) fn solve_x(&self, t: usize, ws: &mut Workspace, x: &mut [f64]) -> bool {
        let Some(p) = self.batch.problem(t) else {
            return false;
        };
        let sg = &self.sg;
        ws.reset(sg.m);
        sg.scale_h(p.h(), &mut ws.hs);
        let hs = std::mem::take(&mut ws.hs);
        solve_scaled_in(sg, &hs, &self.params, None, self.params.outer_cap(sg.m), ws);
        ws.hs = hs;
        for ((xi, &yi), &di) in x.iter_mut().zip(&ws.y).zip(&sg.d) {
            *xi = if di > 0.0 && yi > 0.0 { yi / di } else { 0.0 };
        }
        true
    }
}

fn solve_prepared(sg: &ScaledGram, p: &GramProblem<'_>, params: &LhParams) -> NnlsSolution {
    let mut hs = vec![0.0; sg.m];
    sg.scale_h(p.h(), &mut hs);
    let (y, iterations) = solve_scaled(sg, &hs, params, None, params.outer_cap(sg.m));
    sg.finish(p, &y, iterations)
}

/// Scratch vectors of one Lawson-Hanson solve, reused across solves by
/// [`PreparedBatch::solve_x`] (contents never carried from one solve to the next: every
/// entry read is written first in the same solve).
#[derive(Default)]
pub(crate) struct Workspace {
    hs: Vec<f64>,
    y: Vec<f64>,
    gy: Vec<f64>,
    in_p: Vec<bool>,
    tried: Vec<bool>,
    z: Vec<f64>,
    ratios: Vec<f64>,
    leaving: Vec<bool>,
    set: Passive,
}

impl Workspace {
    /// Sized for `m` columns, the state of a fresh solve (`y = 0`, empty passive set).
    fn reset(&mut self, m: usize) {
        for v in [&mut self.hs, &mut self.y, &mut self.gy] {
            v.clear();
            v.resize(m, 0.0);
        }
        for v in [&mut self.in_p, &mut self.tried, &mut self.leaving] {
            v.clear();
            v.resize(m, false);
        }
        self.z.clear();
        self.ratios.clear();
        self.set.passive.clear();
    }
}

/// The passive set in entry order and the Cholesky factor of `G~_PP` (row `r` of `l`,
/// stride `m`, belongs to `passive[r]`), with the scratch of its solves.
#[derive(Default)]
struct Passive {
    passive: Vec<usize>,
    // Rows are added as columns enter (a full m x m zero matrix per solve would cost more
    // than the solve when few columns enter); a row is written before it is read.
    l: Vec<f64>,
    /// Refinement residual of [`Passive::solve`].
    r: Vec<f64>,
    /// The previous passive set during [`Passive::refactor`].
    old: Vec<usize>,
    /// Columns [`Passive::refactor`] dropped on the pivot test.
    failed: Vec<usize>,
}

impl Passive {
    /// Appends column `j` unless its pivot `1 - ||L^-1 G~_Pj||^2` is `<= pivot_tol`.
    fn try_push(&mut self, sg: &ScaledGram, j: usize, pivot_tol: f64) -> bool {
        let (m, p) = (sg.m, self.passive.len());
        if self.l.len() < (p + 1) * m {
            self.l.resize((p + 1) * m, 0.0);
        }
        let mut d2 = sg.gs[j * m + j];
        // Row `p` of `l` is written left to right, each entry from the entries before it.
        let (above, new) = self.l.split_at_mut(p * m);
        let new = &mut new[..m];
        for (r, &pr) in self.passive.iter().enumerate() {
            let lr = &above[r * m..r * m + m];
            let dot: f64 = lr[..r].iter().zip(&new[..r]).map(|(a, b)| a * b).sum();
            let v = (sg.gs[pr * m + j] - dot) / lr[r];
            new[r] = v;
            d2 -= v * v;
        }
        if d2.is_nan() || d2 <= pivot_tol {
            return false;
        }
        self.l[p * m + p] = d2.sqrt();
        self.passive.push(j);
        true
    }

    /// Rebuilds the factor for the columns of `passive` kept by `keep`, in order; the kept
    /// columns that failed the pivot test (only possible through rounding) are left in
    /// `self.failed`.
    fn refactor(&mut self, sg: &ScaledGram, keep: impl Fn(usize) -> bool, pivot_tol: f64) {
        std::mem::swap(&mut self.old, &mut self.passive);
        self.passive.clear();
        self.failed.clear();
        let old = std::mem::take(&mut self.old);
        for &j in &old {
            if keep(j) && !self.try_push(sg, j, pivot_tol) {
                self.failed.push(j);
            }
        }
        self.old = old;
    }

    /// Solves `L L^T z = rhs` in place (`rhs.len() == passive.len()`).
    fn chol_solve(l: &[f64], m: usize, z: &mut [f64]) {
        let p = z.len();
        for r in 0..p {
            let lr = &l[r * m..r * m + r + 1];
            let dot: f64 = lr[..r].iter().zip(&z[..r]).map(|(a, b)| a * b).sum();
            z[r] = (z[r] - dot) / lr[r];
        }
        for r in (0..p).rev() {
            // Column `r` of `l` below the diagonal: rows r + 1 .. p.
            let (head, tail) = z.split_at_mut(r + 1);
            let col = l[r..].iter().step_by(m).skip(r + 1);
            let dot: f64 = col.zip(tail.iter()).map(|(a, b)| a * b).sum();
            head[r] = (head[r] - dot) / l[r * m + r];
        }
    }

    /// `z = G~_PP^-1 h~_P` with one step of iterative refinement.
    fn solve(&mut self, sg: &ScaledGram, hs: &[f64], z: &mut Vec<f64>) {
        let m = sg.m;
        z.clear();
        z.extend(self.passive.iter().map(|&i| hs[i]));
        Self::chol_solve(&self.l, m, z);
        self.r.clear();
        self.r.extend(self.passive.iter().map(|&i| {
            let row = &sg.gs[i * m..(i + 1) * m];
            hs[i]
                - self
                    .passive
                    .iter()
                    .zip(z.iter())
                    .map(|(&k, zk)| row[k] * zk)
                    .sum::<f64>()
        }));
        Self::chol_solve(&self.l, m, &mut self.r);
        z.iter_mut().zip(&self.r).for_each(|(zk, rk)| *zk += rk);
    }
}

/// The active-set iteration on the scaled problem; returns `y` and the outer-loop count.
/// Column `excluded` (its `hs` entry must be 0) never enters: the result is the solve
/// without that column, operation for operation.
fn solve_scaled(
    sg: &ScaledGram,
    hs: &[f64],
    params: &LhParams,
    excluded: Option<usize>,
    cap: usize,
) -> (Vec<f64>, usize) {
    let mut ws = Workspace::default();
    ws.reset(sg.m);
    let outer = solve_scaled_in(sg, hs, params, excluded, cap, &mut ws);
    (ws.y, outer)
}

/// [`solve_scaled`] in the scratch `ws` (reset for `sg.m` columns): `y` is left in `ws.y`.
fn solve_scaled_in(
    sg: &ScaledGram,
    hs: &[f64],
    params: &LhParams,
    excluded: Option<usize>,
    cap: usize,
    ws: &mut Workspace,
) -> usize {
    let m = sg.m;
    let Workspace {
        y,
        gy,
        in_p,
        tried,
        z,
        ratios,
        leaving,
        set,
        ..
    } = ws;
    if let Some(c) = excluded {
        // Never passive, never a candidate: marked as if in P, but never in `passive`.
        in_p[c] = true;
    }
    let mut outer = 0;
    while outer < cap {
        for (gi, row) in gy.iter_mut().zip(sg.gs.chunks_exact(m)) {
            *gi = set.passive.iter().map(|&k| row[k] * y[k]).sum();
        }
        let s = hs.iter().fold(0.0f64, |a, v| a.max(v.abs())) + y.iter().sum::<f64>();
        tried.fill(false);
        let mut entered = None;
        while let Some(j) = pick(sg, hs, gy, in_p, tried, s, params) {
            tried[j] = true;
            if !set.try_push(sg, j, params.pivot_tol) {
                continue;
            }
            set.solve(sg, hs, z);
            if z.last().is_some_and(|&zj| zj > 0.0) {
                entered = Some(j);
                break;
            }
            set.passive.pop();
        }
        let Some(j) = entered else { break };
        outer += 1;
        in_p[j] = true;
        // Inner loop: move towards z until every passive coefficient is positive.
        while z.iter().any(|&zk| zk <= 0.0) {
            ratios.clear();
            ratios.extend(set.passive.iter().zip(z.iter()).map(|(&i, &zk)| {
                if zk <= 0.0 {
                    y[i] / (y[i] - zk)
                } else {
                    f64::NAN
                }
            }));
            let alpha = ratios.iter().fold(1.0, |a: f64, &r| a.min(r));
            leaving.fill(false);
            for ((&i, &zk), &r) in set.passive.iter().zip(z.iter()).zip(ratios.iter()) {
                y[i] = if r <= alpha {
                    0.0
                } else {
                    y[i] + alpha * (zk - y[i])
                };
                leaving[i] = y[i] <= 0.0;
            }
            set.refactor(sg, |i| !leaving[i], params.pivot_tol);
            for &i in &set.failed {
                leaving[i] = true;
            }
            for i in (0..m).filter(|&i| leaving[i]) {
                in_p[i] = false;
                y[i] = 0.0;
            }
            set.solve(sg, hs, z);
        }
        for (&i, &zk) in set.passive.iter().zip(z.iter()) {
            y[i] = zk;
        }
    }
    outer
}

/// Leave-one-out solves on one Gram matrix: column `c` fitted by all the other columns
/// (`G` without row and column `c`, `h = G[., c]`, `bb = G[c][c]`), as in the paper's
/// Algorithm 1. `G` is validated and scaled once; each solve then costs
/// `O(m x passive set)` instead of the `O(m^2)` of building and scaling its own
/// sub-problem, and returns exactly the coefficients [`solve`] gives on that
/// sub-problem (same operations in the same order), re-indexed: `x[c] = 0`.
#[derive(Debug, Clone)]
pub struct LeaveOneOut<'a> {
    g: &'a [f64],
    sg: ScaledGram,
    params: LhParams,
}

impl<'a> LeaveOneOut<'a> {
    /// Validates `G` (`m x m`, finite, non-negative diagonal) and the parameters.
    pub fn new(m: usize, g: &'a [f64], params: &LhParams) -> Result<Self, NnlsError> {
        params.check()?;
        super::check_gram(m, g)?;
        Ok(Self {
            g,
            sg: ScaledGram::new(m, g),
            params: *params,
        })
    }

    /// Number of columns `m`.
    pub fn m(&self) -> usize {
        self.sg.m
    }

    /// The outer-loop cap of one leave-one-out solve (that of its `m - 1` columns).
    pub fn outer_cap(&self) -> usize {
        self.params.outer_cap(self.sg.m - 1)
    }

    /// Fits column `c` (`< m`) by the others.
    pub fn solve(&self, c: usize) -> NnlsSolution {
        let (m, sg) = (self.sg.m, &self.sg);
        let h: Vec<f64> = (0..m)
            .map(|i| if i == c { 0.0 } else { self.g[i * m + c] })
            .collect();
        let mut hs = vec![0.0; m];
        sg.scale_h(&h, &mut hs);
        let (y, iterations) = solve_scaled(sg, &hs, &self.params, Some(c), self.outer_cap());
        let x: Vec<f64> = y
            .iter()
            .zip(&sg.d)
            .map(|(&yi, &di)| if di > 0.0 && yi > 0.0 { yi / di } else { 0.0 })
            .collect();
        let objective = super::objective_unchecked(m, self.g, &h, self.g[c * m + c], &x);
        // KKT on the sub-problem from the shared scaled G: O(m x non-zeros).
        let ys: Vec<f64> = x.iter().zip(&sg.d).map(|(xi, di)| xi * di).collect();
        let nz: Vec<usize> = (0..m).filter(|&k| ys[k] != 0.0).collect();
        let mut gy: Vec<f64> = (0..m)
            .map(|i| nz.iter().map(|&k| sg.gs[i * m + k] * ys[k]).sum())
            .collect();
        gy[c] = 0.0;
        NnlsSolution {
            objective,
            iterations,
            max_kkt_violation: super::kkt_scaled(&hs, &ys, &gy),
            x,
        }
    }
}

/// The entering candidate: the largest `w_i = h~_i - (G~ y)_i > kkt_tol * s` among untried
/// non-zero columns outside `P`, ties (within `tie_tol * s`) to the lowest index.
fn pick(
    sg: &ScaledGram,
    hs: &[f64],
    gy: &[f64],
    in_p: &[bool],
    tried: &[bool],
    s: f64,
    params: &LhParams,
) -> Option<usize> {
    let eligible = |i: &usize| {
        !in_p[*i] && !tried[*i] && sg.d[*i] > 0.0 && hs[*i] - gy[*i] > params.kkt_tol * s
    };
    let w_max = (0..sg.m)
        .filter(eligible)
        .map(|i| hs[i] - gy[i])
        .fold(f64::NEG_INFINITY, f64::max);
    (0..sg.m)
        .filter(eligible)
        .find(|&i| hs[i] - gy[i] >= w_max - params.tie_tol * s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nnls::test_support::{random_dense, Dense, Rng};

    fn lh(m: usize, g: &[f64], h: &[f64], bb: f64) -> NnlsSolution {
        solve(
            &GramProblem::new(m, g, h, bb).unwrap(),
            &LhParams::default(),
        )
        .unwrap()
    }

    fn lh_dense(d: &Dense) -> NnlsSolution {
        let (g, h, bb) = d.gram();
        lh(d.cols, &g, &h, bb)
    }

    /// Exact optimum by enumerating every support: solve `G_SS z = h_S` by Gaussian
    /// elimination with partial pivoting, skip singular or infeasible supports.
    fn brute_force(m: usize, g: &[f64], h: &[f64], bb: f64) -> f64 {
        let p = GramProblem::new(m, g, h, bb).unwrap();
        let mut best = bb;
        for mask in 1u32..(1 << m) {
            let idx: Vec<usize> = (0..m).filter(|i| mask >> i & 1 == 1).collect();
            let k = idx.len();
            let mut a: Vec<Vec<f64>> = idx
                .iter()
                .map(|&i| idx.iter().map(|&j| g[i * m + j]).chain([h[i]]).collect())
                .collect();
            let mut singular = false;
            for c in 0..k {
                let piv = (c..k)
                    .max_by(|&r, &s| a[r][c].abs().total_cmp(&a[s][c].abs()))
                    .unwrap();
                a.swap(c, piv);
                if a[c][c].abs() < 1e-9 * g[idx[c] * m + idx[c]].max(1e-300) {
                    singular = true;
                    break;
                }
                let pivot_row = a[c].clone();
                for (_, row) in a.iter_mut().enumerate().filter(|(r, _)| *r != c) {
                    let f = row[c] / pivot_row[c];
                    row[c..]
                        .iter_mut()
                        .zip(&pivot_row[c..])
                        .for_each(|(v, p)| *v -= f * p);
                }
            }
            let z: Vec<f64> = (0..k).map(|r| a[r][k] / a[r][r]).collect();
            if singular || z.iter().any(|&v| v < 0.0) {
                continue;
            }
            let mut x = vec![0.0; m];
            idx.iter().zip(&z).for_each(|(&i, &v)| x[i] = v);
            best = best.min(p.objective(&x).unwrap());
        }
        best
    }

    #[test]
    fn params_check_rejects_each_bad_parameter() {
        let d = LhParams::default();
        assert!(d.check().is_ok());
        for bad in [
            LhParams { kkt_tol: 0.0, ..d },
            LhParams {
                kkt_tol: f64::NAN,
                ..d
            },
            LhParams {
                pivot_tol: 1.0,
                ..d
            },
            LhParams {
                tie_tol: -1e-9,
                ..d
            },
            LhParams {
                max_outer: Some(0),
                ..d
            },
        ] {
            assert!(
                matches!(bad.check(), Err(NnlsError::InvalidValue { .. })),
                "{bad:?}"
            );
        }
        assert_eq!(d.outer_cap(10), 60);
    }

    #[test]
    fn unconstrained_optimum_already_positive() {
        // G = [[2, 1], [1, 2]], x* = (1, 2): h = G x* = (4, 5), exact fit bb = h.x* = 14.
        let s = lh(2, &[2.0, 1.0, 1.0, 2.0], &[4.0, 5.0], 14.0);
        assert!(
            (s.x[0] - 1.0).abs() < 1e-14 && (s.x[1] - 2.0).abs() < 1e-14,
            "{:?}",
            s.x
        );
        assert!(s.objective.abs() < 1e-13 && s.max_kkt_violation < 1e-15);
    }

    #[test]
    fn active_bound_clamps_one_coefficient() {
        // Unconstrained optimum (1, -1); NNLS: x = (h_0 / G_00, 0) = (0.5, 0), q = 2 - 0.5.
        let s = lh(2, &[2.0, 1.0, 1.0, 2.0], &[1.0, -1.0], 2.0);
        assert!((s.x[0] - 0.5).abs() < 1e-15 && s.x[1] == 0.0, "{:?}", s.x);
        assert!((s.objective - 1.5).abs() < 1e-15 && s.max_kkt_violation < 1e-15);
    }

    #[test]
    fn identical_columns_weight_goes_to_earlier() {
        let mut rng = Rng::new(11);
        let mut d = random_dense(&mut rng, 50, 4, &[]);
        let c1 = d.col(1).to_vec();
        d.a[3 * 50..].copy_from_slice(&c1);
        d.b = (0..50)
            .map(|r| 0.2 * d.a[r] + 0.5 * d.a[50 + r] + 0.3 * d.a[100 + r] + 0.01 * rng.normal())
            .collect();
        let s = lh_dense(&d);
        assert!(s.x[1] > 0.4 && s.x[3] == 0.0, "{:?}", s.x);
        let (g, h, bb) = d.gram();
        assert!(s.objective - brute_force(4, &g, &h, bb) <= 1e-12 * bb);
    }

    #[test]
    fn zero_target_gives_zero() {
        let s = lh(2, &[2.0, 1.0, 1.0, 2.0], &[0.0, 0.0], 0.0);
        assert_eq!(
            (s.x, s.objective, s.iterations, s.max_kkt_violation),
            (vec![0.0, 0.0], 0.0, 0, 0.0)
        );
    }

    #[test]
    fn anti_correlated_target_gives_zero() {
        let mut rng = Rng::new(12);
        let mut d = random_dense(&mut rng, 30, 5, &[]);
        d.b.iter_mut().for_each(|v| *v = -*v);
        let (g, h, bb) = d.gram();
        assert!(h.iter().all(|&v| v < 0.0));
        let s = lh(5, &g, &h, bb);
        assert_eq!(
            (s.x, s.objective, s.max_kkt_violation),
            (vec![0.0; 5], bb, 0.0)
        );
    }

    #[test]
    fn lambertian_tie_goes_to_column_zero() {
        // Column 0 is Lambertian (1 / pi); a `sugar`-like column 3.7 / pi sits at index 1 or 2.
        let mut rng = Rng::new(13);
        for dup in [1, 2] {
            let mut d = random_dense(&mut rng, 40, 3, &[]);
            d.a[..40].fill(std::f64::consts::FRAC_1_PI);
            d.a[dup * 40..(dup + 1) * 40].fill(3.7 * std::f64::consts::FRAC_1_PI);
            let other = 3 - dup;
            d.b = (0..40)
                .map(|r| 0.4 * d.a[r] + 0.6 * d.a[other * 40 + r])
                .collect();
            let s = lh_dense(&d);
            assert_eq!(s.x[dup], 0.0, "{:?}", s.x);
            assert!(
                (s.x[0] - 0.4).abs() < 1e-12 && (s.x[other] - 0.6).abs() < 1e-12,
                "{:?}",
                s.x
            );
        }
    }

    #[test]
    fn zero_column_is_fixed_at_zero() {
        let g = [1.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.5, 0.0, 1.0];
        let s = lh(3, &g, &[1.0, 0.0, 1.0], 4.0);
        assert_eq!(s.x[1], 0.0);
        assert!(
            (s.x[0] - 2.0 / 3.0).abs() < 1e-15 && (s.x[2] - 2.0 / 3.0).abs() < 1e-15,
            "{:?}",
            s.x
        );
    }

    #[test]
    fn matches_brute_force_over_all_active_sets() {
        let mut rng = Rng::new(14);
        let mut worst = 0.0f64;
        for trial in 0..300 {
            let m = 2 + trial % 7;
            let combos: Vec<usize> = if trial % 3 == 0 { vec![m - 1] } else { vec![] };
            let mut d = random_dense(&mut rng, 12 + m, m, &combos);
            if trial % 2 == 1 {
                // Mixed-sign columns and targets give many active bounds.
                d.a.iter_mut().for_each(|v| *v -= 0.5);
                d.b.iter_mut().for_each(|v| *v = rng.normal());
            }
            let (g, h, bb) = d.gram();
            let s = lh(m, &g, &h, bb);
            let excess = (s.objective - brute_force(m, &g, &h, bb)) / bb;
            worst = worst.max(excess);
            assert!(excess <= 1e-12, "trial {trial}: excess {excess:e}");
            assert!(
                s.max_kkt_violation < 1e-12,
                "trial {trial}: kkt {:e}",
                s.max_kkt_violation
            );
        }
        eprintln!("LH vs brute force: worst relative objective excess {worst:e}");
    }

    #[test]
    fn rank_deficient_kkt_holds_on_a() {
        let mut rng = Rng::new(15);
        let combos = [7, 19, 20, 33, 48, 61, 62, 75, 88, 99];
        for t in 0..3 {
            let mut d = random_dense(&mut rng, 300, 100, &combos);
            if t == 2 {
                d.a.iter_mut().for_each(|v| *v -= 0.5);
            }
            let s = lh_dense(&d);
            let kkt_a = d.kkt_on_a(&s.x);
            let rel = (s.objective - d.objective(&s.x)).abs() / d.objective(&s.x);
            eprintln!(
                "rank-deficient {t}: support {}, iterations {}, KKT on A {kkt_a:e}, Gram KKT {:e}, Gram vs A objective {rel:e}",
                s.x.iter().filter(|&&v| v > 0.0).count(),
                s.iterations,
                s.max_kkt_violation,
            );
            assert!(kkt_a <= 1e-8 && s.max_kkt_violation <= 1e-10, "{kkt_a:e}");
            assert!(rel <= 1e-9, "{rel:e}");
        }
    }

    #[test]
    fn batch_is_deterministic_and_matches_single_solves() {
        let mut rng = Rng::new(16);
        let d = random_dense(&mut rng, 80, 12, &[5, 11]);
        let (g, _, _) = d.gram();
        let (mut hs, mut bbs) = (Vec::new(), Vec::new());
        for _ in 0..40 {
            let t = Dense {
                b: (0..80).map(|_| rng.uniform() - 0.2).collect(),
                a: d.a.clone(),
                w: d.w.clone(),
                ..d
            };
            let (_, h, bb) = t.gram();
            hs.extend(h);
            bbs.push(bb);
        }
        let batch = GramBatch::new(12, &g, &hs, &bbs).unwrap();
        let first = solve_batch(&batch, &LhParams::default()).unwrap();
        assert_eq!(first, solve_batch(&batch, &LhParams::default()).unwrap());
        for (t, sol) in first.iter().enumerate() {
            assert_eq!(
                *sol,
                solve(&batch.problem(t).unwrap(), &LhParams::default()).unwrap()
            );
        }
        // The coefficients alone, one workspace reused across targets, the targets in
        // reverse (whatever the previous solve left in it): the same bits.
        let pb = PreparedBatch::new(&batch, &LhParams::default()).unwrap();
        let mut ws = Workspace::default();
        let mut x = vec![0.0; 12];
        for (t, sol) in first.iter().enumerate().rev() {
            assert!(pb.solve_x(t, &mut ws, &mut x));
            let bits = |v: &[f64]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&x), bits(&sol.x), "target {t}");
        }
        assert!(!pb.solve_x(first.len(), &mut ws, &mut x));
    }

    #[test]
    fn outer_loop_cap_is_respected() {
        let mut rng = Rng::new(17);
        let d = random_dense(&mut rng, 60, 10, &[]);
        let (g, h, bb) = d.gram();
        let s = solve(
            &GramProblem::new(10, &g, &h, bb).unwrap(),
            &LhParams {
                max_outer: Some(1),
                ..LhParams::default()
            },
        )
        .unwrap();
        assert_eq!(s.iterations, 1);
        assert_eq!(s.x.iter().filter(|&&v| v > 0.0).count(), 1);
    }
}
