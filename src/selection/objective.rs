//! The objective of SPEC 8 from one Gram matrix of all N materials per channel.
//!
//! Per channel `c` the Gram matrix `F` of the columns `[1/pi, f_1,c .. f_N,c]` over the fit
//! cells (SPEC 5: evaluation mask by default, weights normalised) is computed once: in
//! closed form from the separable tables when every material is analytic (f64, exact up to
//! rounding), else by one pass of the back-end over the grid. It is kept as the cosine
//! matrix `C_ij = F_ij / sqrt(F_ii F_jj)`, so that the fit of target `t` by columns `P` is
//! the NNLS problem `min ||A~ y - b~||^2` with unit columns and a unit target:
//! `G = C_PP`, `h = C_Pt`, `bb = 1`, and its optimum `q` is the target's residual energy
//! relative to its own energy. Then `rho(t; B) = sum_c F_tt,c q_c / sum_c F_tt,c`.
//! Measured in units of the target energy, the Gram-form residual `q` carries a rounding
//! error of a few 1e-16, so `rho` needs no pass over the grid (the tests check it against
//! grid residuals within 1e-9).
//!
//! # Incremental evaluation of "basis + one candidate"
//! For the current basis the exact Lawson-Hanson solution of every (target, channel) is
//! kept with its passive set `P`, coefficients `y_P`, the Cholesky factor `L` of `C_PP`
//! and its objective `q`. Adding candidate column `j`:
//!
//! 1. `w = C_jt - C_jP y_P` (the negative gradient). If `w <= kkt_tol * s` the old point
//!    stays optimal: `q` is unchanged (Lawson-Hanson would stop there too).
//! 2. `v = L^-1 C_Pj`, `d2 = 1 - |v|^2` (squared sine of the angle between column `j` and
//!    the span of `P`). If `d2 <= pivot_tol` the column is numerically dependent and, as in
//!    Lawson-Hanson, does not enter: `q` is unchanged.
//! 3. Otherwise the unconstrained solution on `P + j` is `z_j = w / d2`,
//!    `z_P = y_P - z_j L^-T v`, and the objective falls by exactly `w^2 / d2` (no
//!    cancellation). When every `z_P > 0` and no column of the basis outside `P` gets a
//!    positive gradient, this is the NNLS optimum; otherwise the problem is solved afresh
//!    by Lawson-Hanson (rare).
//!
//! A candidate therefore costs `O(p^2)` per target and channel, with `p <= k + 1`.

use crate::backend::{Backend, LobeParams, Progress};
use crate::collection::Collection;
use crate::fit::{channel_lobe, fit_cells, gram_full, FitParams, GramMode, LAMBERTIAN};
use crate::merl::grid::{N_TD, N_TH};
use crate::merl::{CellSet, GridTables, Mask, Weighting};
use crate::nnls::{lawson_hanson, GramProblem};
use crate::separable::{CellMoments, SeparableLobe};
use rayon::prelude::*;

use super::SelectionError;

/// Lawson-Hanson's tolerances (its defaults), shared by the incremental path.
const KKT_TOL: f64 = 1e-12;
const PIVOT_TOL: f64 = 1e-12;

/// Parameters of the objective: the fit cells and how the Gram matrices are computed.
/// Defaults: evaluation mask, uniform weights, full grid (stride 1), automatic Gram
/// (separable closed form for analytic collections, else one back-end pass).
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectiveParams {
    /// Fit mask (default evaluation).
    pub mask: Mask,
    /// Weighting (default uniform).
    pub weighting: Weighting,
    /// Grid sub-sampling stride, `>= 1` (default 1).
    pub stride: usize,
    /// Gram mode (default auto).
    pub gram: GramMode,
}

impl Default for ObjectiveParams {
    fn default() -> Self {
        Self {
            mask: Mask::Evaluation,
            weighting: Weighting::Uniform,
            stride: 1,
            gram: GramMode::Auto,
        }
    }
}

impl ObjectiveParams {
    /// Sets the mask.
    pub fn mask(mut self, m: Mask) -> Self {
        self.mask = m;
        self
    }
    /// Sets the weighting.
    pub fn weighting(mut self, w: Weighting) -> Self {
        self.weighting = w;
        self
    }
    /// Sets the grid stride.
    pub fn stride(mut self, s: usize) -> Self {
        self.stride = s;
        self
    }
    /// Sets the Gram mode.
    pub fn gram(mut self, g: GramMode) -> Self {
        self.gram = g;
        self
    }
    /// Validates: `1 <= stride <= 90`.
    pub fn check(&self) -> Result<ValidObjectiveParams, SelectionError> {
        if self.stride == 0 || self.stride > 90 {
            return Err(SelectionError::InvalidParam {
                name: "stride",
                value: self.stride.to_string(),
                expected: "an integer in 1..=90",
            });
        }
        Ok(ValidObjectiveParams(self.clone()))
    }
    /// The matching fit parameters (exact solver).
    pub fn fit_params(&self) -> FitParams {
        FitParams {
            mask: self.mask,
            weighting: self.weighting,
            stride: self.stride,
            gram: self.gram,
            ..FitParams::default()
        }
    }
}

/// Validated [`ObjectiveParams`].
#[derive(Clone, Debug, PartialEq)]
pub struct ValidObjectiveParams(ObjectiveParams);

impl ValidObjectiveParams {
    /// The parameters.
    pub fn params(&self) -> &ObjectiveParams {
        &self.0
    }
}

/// The SPEC 8 objective of a collection: cosine Gram matrices of all materials per channel.
#[derive(Clone, Debug)]
pub struct Objective {
    names: Vec<String>,
    /// Per channel: `(N + 1)^2` cosine matrix (column 0 Lambertian, `j + 1` material `j`),
    /// unit diagonal, zero rows and columns for zero columns.
    cos: [Vec<f64>; 3],
    /// Per channel: `sqrt(F_ii)` of every column (0 for a zero column).
    scale: [Vec<f64>; 3],
    /// Per material: `F_tt` per channel (the target energy `sum_s w_s b_c(s)^2`).
    energy: Vec<[f64; 3]>,
    /// Per material: `F_tt,c / sum_c F_tt,c` (0 for a black material).
    share: Vec<[f64; 3]>,
}

impl Objective {
    /// Builds the objective of `coll`: one Gram matrix of all materials per channel (the
    /// separable closed form when every material is analytic and the mode is auto, else one
    /// back-end pass per channel over the fit cells).
    pub fn new(
        backend: &dyn Backend,
        coll: &Collection,
        p: &ValidObjectiveParams,
        progress: Progress<'_>,
    ) -> Result<Self, SelectionError> {
        let p = p.params();
        let n = coll.len();
        if n == 0 {
            return Err(SelectionError::InvalidParam {
                name: "collection",
                value: "0 materials".into(),
                expected: "at least one material",
            });
        }
        let all: Vec<usize> = (0..n).collect();
        let cells = fit_cells(coll, &all, &p.fit_params());
        if cells.is_empty() {
            return Err(SelectionError::Fit(crate::fit::FitError::Backend(
                crate::error::BackendError::Invalid(crate::merl::grid::no_cells_reason(
                    p.mask,
                    p.stride,
                    "the collection",
                )),
            )));
        }
        let grams = if p.gram == GramMode::Auto && coll.all_analytic() {
            analytic_grams(coll, &cells)
        } else {
            let mut out: [Vec<f64>; 3] = Default::default();
            for (c, o) in out.iter_mut().enumerate() {
                let mut lobes = vec![LAMBERTIAN];
                lobes.extend(coll.materials().iter().map(|m| channel_lobe(&m.data, c)));
                *o = gram_full(backend, &lobes, &cells, n + 1, GramMode::Grid, progress)?;
            }
            out
        };
        Self::from_grams(coll.names(), grams)
    }

    /// The objective from given Gram matrices (per channel `(N + 1)^2`, row-major, column 0
    /// the Lambertian `1/pi`, column `j + 1` material `j`).
    pub fn from_grams(
        names: Vec<String>,
        mut grams: [Vec<f64>; 3],
    ) -> Result<Self, SelectionError> {
        let n = names.len();
        let m = n + 1;
        for (c, g) in grams.iter().enumerate() {
            if g.len() != m * m {
                return Err(SelectionError::GramShape {
                    channel: c,
                    expected: m * m,
                    found: g.len(),
                });
            }
            if let Some(i) = g.iter().position(|v| !v.is_finite()) {
                let col = (i / m).max(i % m);
                return Err(SelectionError::NonFinite {
                    material: if col == 0 {
                        "lambertian".into()
                    } else {
                        names[col - 1].clone()
                    },
                    channel: c,
                });
            }
        }
        let energy: Vec<[f64; 3]> = (0..n)
            .map(|t| [0, 1, 2].map(|c| grams[c][(t + 1) * m + t + 1].max(0.0)))
            .collect();
        // Each Gram matrix becomes its cosine matrix in place (no second (N + 1)^2 copy:
        // at N = 10,000 the three matrices alone are 2.4 GB).
        let mut scale: [Vec<f64>; 3] = Default::default();
        for (g, sc) in grams.iter_mut().zip(scale.iter_mut()) {
            let d: Vec<f64> = (0..m)
                .map(|i| {
                    let v = g[i * m + i];
                    if v > f64::MIN_POSITIVE {
                        v.sqrt()
                    } else {
                        0.0
                    }
                })
                .collect();
            for i in 0..m {
                g[i * m + i] = if d[i] == 0.0 { 0.0 } else { 1.0 };
                for j in i + 1..m {
                    let sum = g[i * m + j] + g[j * m + i];
                    let live = d[i] != 0.0 && d[j] != 0.0;
                    g[i * m + j] = if live { 0.5 * sum / d[i] / d[j] } else { 0.0 };
                    g[j * m + i] = if live { 0.5 * sum / d[j] / d[i] } else { 0.0 };
                }
            }
            *sc = d;
        }
        let cos = grams;
        let share = energy
            .iter()
            .map(|e| {
                let tot: f64 = e.iter().sum();
                if tot > 0.0 {
                    e.map(|v| v / tot)
                } else {
                    [0.0; 3]
                }
            })
            .collect();
        Ok(Self {
            names,
            cos,
            scale,
            energy,
            share,
        })
    }

    /// Number of materials.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// True when there is no material.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Material names, in collection order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Target energy `sum_s w_s b_c(s)^2` of material `t` per channel.
    pub fn energy(&self, t: usize) -> [f64; 3] {
        self.energy[t]
    }

    /// Entry `(i, j)` of the cosine matrix of channel `c` (0 = Lambertian).
    #[inline]
    fn cs(&self, c: usize, i: usize, j: usize) -> f64 {
        self.cos[c][i * (self.names.len() + 1) + j]
    }

    /// Row `i` of the cosine matrix of channel `c`.
    #[inline]
    fn row(&self, c: usize, i: usize) -> &[f64] {
        let m = self.names.len() + 1;
        &self.cos[c][i * m..(i + 1) * m]
    }

    /// Exact NNLS of target `t`, channel `c`, on the Gram columns `cols` (0 = Lambertian):
    /// coefficients and the relative residual `q`.
    fn solve(&self, c: usize, cols: &[usize], t: usize) -> (Vec<f64>, f64) {
        let m = cols.len();
        let mut g = vec![0.0; m * m];
        for (a, &ca) in cols.iter().enumerate() {
            let row = self.row(c, ca);
            for (b, &cb) in cols.iter().enumerate() {
                g[a * m + b] = row[cb];
            }
        }
        let h: Vec<f64> = cols.iter().map(|&ca| self.cs(c, ca, t + 1)).collect();
        let sol = GramProblem::new(m, &g, &h, 1.0)
            .and_then(|p| lawson_hanson::solve(&p, &lawson_hanson::LhParams::default()));
        match sol {
            Ok(s) => {
                let q = s.objective.clamp(0.0, 1.0);
                (s.x, q)
            }
            // The cosine matrix is finite with a unit or zero diagonal, so the problem is
            // always valid; a rejected one would be a bug, reported as no fit at all.
            Err(_) => (vec![0.0; m], 1.0),
        }
    }

    /// `rho(t; B)` of SPEC 8 from the Gram matrices (exact Lawson-Hanson per channel).
    pub fn rho(&self, basis: &[usize], t: usize) -> f64 {
        let cols = basis_cols(basis);
        (0..3)
            .filter(|&c| self.share[t][c] > 0.0)
            .map(|c| self.share[t][c] * self.solve(c, &cols, t).1)
            .sum()
    }

    /// The exact fit of target `t` by `basis` (SPEC 5) from the Gram matrices:
    /// coefficients per column (0 = Lambertian, then the basis in order), RGB, in the
    /// units of the materials, and `rho(t; basis)`.
    pub fn fit(&self, basis: &[usize], t: usize) -> (Vec<[f64; 3]>, f64) {
        let cols = basis_cols(basis);
        let mut coef = vec![[0.0; 3]; cols.len()];
        let mut rho = 0.0;
        for c in (0..3).filter(|&c| self.share[t][c] > 0.0) {
            let (x, q) = self.solve(c, &cols, t);
            rho += self.share[t][c] * q;
            let dt = self.scale[c][t + 1];
            for ((a, &y), &col) in coef.iter_mut().zip(&x).zip(&cols) {
                let dj = self.scale[c][col];
                if y > 0.0 && dj > 0.0 {
                    a[c] = y * dt / dj;
                }
            }
        }
        (coef, rho)
    }

    /// Which materials of `basis` contribute (a coefficient > 0 in some channel) to the
    /// exact fit of target `t` (the empirical selection's count, SPEC 5).
    pub fn contributors(&self, basis: &[usize], t: usize) -> Vec<bool> {
        let cols = basis_cols(basis);
        let mut used = vec![false; basis.len()];
        for c in (0..3).filter(|&c| self.share[t][c] > 0.0) {
            let (x, _) = self.solve(c, &cols, t);
            for (u, &v) in used.iter_mut().zip(&x[1..]) {
                *u |= v > 0.0;
            }
        }
        used
    }

    /// `S(B; T)`: the mean of `rho(t; B)` over `t` in `targets` not in `basis` (0 when no
    /// target remains).
    pub fn score(&self, basis: &[usize], targets: &[usize]) -> f64 {
        let left: Vec<usize> = targets
            .iter()
            .copied()
            .filter(|t| !basis.contains(t))
            .collect();
        if left.is_empty() {
            return 0.0;
        }
        let rhos: Vec<f64> = left.par_iter().map(|&t| self.rho(basis, t)).collect();
        rhos.iter().sum::<f64>() / left.len() as f64
    }

    /// The solution state of target `t` by `basis` in every channel.
    pub(crate) fn state(&self, basis: &[usize], t: usize) -> TargetState {
        let cols = basis_cols(basis);
        let chans = [0, 1, 2].map(|c| {
            if self.share[t][c] <= 0.0 {
                return ChanState::default();
            }
            let (x, q) = self.solve(c, &cols, t);
            let passive: Vec<usize> = cols
                .iter()
                .zip(&x)
                .filter(|(_, &v)| v > 0.0)
                .map(|(&i, _)| i)
                .collect();
            let inactive: Vec<usize> = cols
                .iter()
                .zip(&x)
                .filter(|(_, &v)| v <= 0.0)
                .map(|(&i, _)| i)
                .collect();
            let y: Vec<f64> = x.iter().copied().filter(|&v| v > 0.0).collect();
            let p = passive.len();
            let mut a = vec![0.0; p * p];
            for (r, &i) in passive.iter().enumerate() {
                for (s, &j) in passive.iter().enumerate() {
                    a[r * p + s] = self.cs(c, i, j);
                }
            }
            let l = cholesky(p, &a);
            ChanState {
                hmax: cols
                    .iter()
                    .map(|&i| self.cs(c, i, t + 1).abs())
                    .fold(0.0, f64::max),
                ysum: y.iter().sum(),
                fast: l.is_some(),
                l: l.unwrap_or_default(),
                passive,
                inactive,
                y,
                q,
                active: true,
            }
        });
        TargetState { chans }
    }

    /// Relative residual `q` of channel `c` of target `t` after adding material `cand` to
    /// the basis whose state is `st` (`cols`: that basis' Gram columns).
    #[allow(clippy::too_many_arguments)]
    fn q_adding(
        &self,
        st: &ChanState,
        c: usize,
        cols: &[usize],
        cand: usize,
        t: usize,
        scratch: &mut Vec<f64>,
    ) -> f64 {
        let j = cand + 1;
        let row = self.row(c, j);
        if row[j] == 0.0 {
            return st.q; // a zero column never helps
        }
        let w = row[t + 1]
            - st.passive
                .iter()
                .zip(&st.y)
                .map(|(&k, &y)| row[k] * y)
                .sum::<f64>();
        let hmax = st.hmax.max(row[t + 1].abs());
        if w <= KKT_TOL * (hmax + st.ysum) {
            return st.q;
        }
        if !st.fast {
            return self.solve_adding(c, cols, j, t);
        }
        let p = st.passive.len();
        scratch.clear();
        scratch.resize(2 * p, 0.0);
        let (v, z) = scratch.split_at_mut(p);
        // v = L^-1 C_Pj
        for r in 0..p {
            let lr = &st.l[r * p..r * p + r];
            let dot: f64 = lr.iter().zip(&v[..r]).map(|(a, b)| a * b).sum();
            v[r] = (row[st.passive[r]] - dot) / st.l[r * p + r];
        }
        let d2 = 1.0 - v.iter().map(|x| x * x).sum::<f64>();
        if d2.is_nan() || d2 <= PIVOT_TOL {
            return st.q;
        }
        // u = L^-T v (in place)
        for r in (0..p).rev() {
            let dot: f64 = (r + 1..p).map(|s| st.l[s * p + r] * v[s]).sum();
            v[r] = (v[r] - dot) / st.l[r * p + r];
        }
        let delta = w / d2;
        for ((zk, y), u) in z.iter_mut().zip(&st.y).zip(v.iter()) {
            *zk = y - delta * u;
        }
        if z.iter().any(|&x| x <= 0.0) {
            return self.warm_inner(st, c, cols, j, t, z, delta);
        }
        let s = hmax + z.iter().sum::<f64>() + delta;
        for &i in &st.inactive {
            let ri = self.row(c, i);
            if ri[i] == 0.0 {
                continue;
            }
            let wi = ri[t + 1]
                - st.passive
                    .iter()
                    .zip(z.iter())
                    .map(|(&k, &zk)| ri[k] * zk)
                    .sum::<f64>()
                - ri[j] * delta;
            if wi > KKT_TOL * s {
                return self.solve_adding(c, cols, j, t);
            }
        }
        (st.q - w * w / d2).max(0.0)
    }

    /// Lawson-Hanson's inner loop from the old optimum (feasible, column `j` at 0) towards
    /// the unconstrained solution `z` on `P + j` (`z_P`, `z_j = delta`): step to the first
    /// bound, drop the columns that reach 0, re-solve, until every coefficient is positive;
    /// then the KKT conditions of every other basis column are checked (a failure, rare,
    /// falls back to a fresh solve).
    #[allow(clippy::too_many_arguments)]
    fn warm_inner(
        &self,
        st: &ChanState,
        c: usize,
        cols: &[usize],
        j: usize,
        t: usize,
        z_p: &[f64],
        delta: f64,
    ) -> f64 {
        let mut set: Vec<usize> = st.passive.clone();
        set.push(j);
        let mut x: Vec<f64> = st.y.clone();
        x.push(0.0);
        let mut z: Vec<f64> = z_p.to_vec();
        z.push(delta);
        for _ in 0..=set.len() {
            if z.iter().all(|&v| v > 0.0) {
                break;
            }
            let alpha = x
                .iter()
                .zip(&z)
                .filter(|(_, &zk)| zk <= 0.0)
                .map(|(&xk, &zk)| xk / (xk - zk))
                .fold(1.0f64, f64::min);
            let mut keep_set = Vec::with_capacity(set.len());
            let mut keep_x = Vec::with_capacity(set.len());
            for ((&k, &xk), &zk) in set.iter().zip(&x).zip(&z) {
                let nx = if zk <= 0.0 && xk / (xk - zk) <= alpha {
                    0.0
                } else {
                    xk + alpha * (zk - xk)
                };
                if nx > 0.0 {
                    keep_set.push(k);
                    keep_x.push(nx);
                }
            }
            set = keep_set;
            x = keep_x;
            match self.solve_on(c, &set, t) {
                Some(sol) => z = sol,
                None => return self.solve_adding(c, cols, j, t),
            }
        }
        if z.iter().any(|&v| v <= 0.0) {
            return self.solve_adding(c, cols, j, t);
        }
        // KKT of the columns outside the final set.
        let hmax = cols
            .iter()
            .chain(std::iter::once(&j))
            .map(|&i| self.cs(c, i, t + 1).abs())
            .fold(0.0, f64::max);
        let s = hmax + z.iter().sum::<f64>();
        for &i in cols.iter().chain(std::iter::once(&j)) {
            if set.contains(&i) {
                continue;
            }
            let ri = self.row(c, i);
            if ri[i] == 0.0 {
                continue;
            }
            let wi = ri[t + 1] - set.iter().zip(&z).map(|(&k, &zk)| ri[k] * zk).sum::<f64>();
            if wi > KKT_TOL * s {
                return self.solve_adding(c, cols, j, t);
            }
        }
        // q = 1 + sum_k z_k ((C z)_k - 2 h_k)
        let mut q = 1.0;
        for (&a, &za) in set.iter().zip(&z) {
            let ra = self.row(c, a);
            let cz: f64 = set.iter().zip(&z).map(|(&b, &zb)| ra[b] * zb).sum();
            q += za * (cz - 2.0 * ra[t + 1]);
        }
        q.clamp(0.0, 1.0)
    }

    /// The unconstrained solution of `C_SS z = C_St` by Cholesky (`None` when `C_SS` is not
    /// numerically positive definite).
    fn solve_on(&self, c: usize, set: &[usize], t: usize) -> Option<Vec<f64>> {
        let p = set.len();
        let mut a = vec![0.0; p * p];
        for (r, &i) in set.iter().enumerate() {
            let ri = self.row(c, i);
            for (s, &k) in set.iter().enumerate() {
                a[r * p + s] = ri[k];
            }
        }
        let l = cholesky(p, &a)?;
        if (0..p).any(|r| l[r * p + r] * l[r * p + r] <= PIVOT_TOL) {
            return None;
        }
        let mut z: Vec<f64> = set.iter().map(|&i| self.cs(c, i, t + 1)).collect();
        for r in 0..p {
            let dot: f64 = (0..r).map(|k| l[r * p + k] * z[k]).sum();
            z[r] = (z[r] - dot) / l[r * p + r];
        }
        for r in (0..p).rev() {
            let dot: f64 = (r + 1..p).map(|k| l[k * p + r] * z[k]).sum();
            z[r] = (z[r] - dot) / l[r * p + r];
        }
        Some(z)
    }

    fn solve_adding(&self, c: usize, cols: &[usize], j: usize, t: usize) -> f64 {
        let mut all = cols.to_vec();
        all.push(j);
        self.solve(c, &all, t).1
    }

    /// `S(B + c; T)` for every `c` of `candidates` (`c` not in `basis`), from the states of
    /// `basis` (the mean excludes `basis` and `c` from the targets; 0 when none remains).
    pub fn scores_adding(
        &self,
        basis: &[usize],
        targets: &[usize],
        candidates: &[usize],
    ) -> Vec<f64> {
        let live: Vec<usize> = targets
            .iter()
            .copied()
            .filter(|t| !basis.contains(t))
            .collect();
        let states: Vec<TargetState> = live.par_iter().map(|&t| self.state(basis, t)).collect();
        let cols = basis_cols(basis);
        // Candidates in blocks, so that each target's state is read once per block and the
        // block's cosine rows stay in cache; each candidate still sums its targets in
        // order, so the result does not depend on the blocking or the threads.
        const BLOCK: usize = 16;
        let blocks: Vec<Vec<f64>> = candidates
            .par_chunks(BLOCK)
            .map(|block| {
                let mut sums = vec![0.0; block.len()];
                let mut counts = vec![0usize; block.len()];
                let mut scratch = Vec::new();
                for (&t, st) in live.iter().zip(&states) {
                    for (b, &cand) in block.iter().enumerate() {
                        if t == cand {
                            continue;
                        }
                        counts[b] += 1;
                        for (c, ch) in st.chans.iter().enumerate() {
                            if ch.active {
                                sums[b] += self.share[t][c]
                                    * self.q_adding(ch, c, &cols, cand, t, &mut scratch);
                            }
                        }
                    }
                }
                sums.iter()
                    .zip(&counts)
                    .map(|(&s, &n)| if n == 0 { 0.0 } else { s / n as f64 })
                    .collect()
            })
            .collect();
        blocks.concat()
    }
}

/// Gram columns of a basis: the Lambertian (0), then `j + 1` per material.
fn basis_cols(basis: &[usize]) -> Vec<usize> {
    std::iter::once(0)
        .chain(basis.iter().map(|&b| b + 1))
        .collect()
}

/// Lower Cholesky factor (row-major `p x p`) of a symmetric positive-definite matrix, or
/// `None` when a pivot is not positive.
fn cholesky(p: usize, a: &[f64]) -> Option<Vec<f64>> {
    let mut l = vec![0.0; p * p];
    for r in 0..p {
        for s in 0..=r {
            let dot: f64 = (0..s).map(|k| l[r * p + k] * l[s * p + k]).sum();
            let v = a[r * p + s] - dot;
            if r == s {
                if v.is_nan() || v <= 0.0 {
                    return None;
                }
                l[r * p + r] = v.sqrt();
            } else {
                l[r * p + s] = v / l[s * p + s];
            }
        }
    }
    Some(l)
}

/// Solution state of one target in every channel.
#[derive(Clone, Debug)]
pub(crate) struct TargetState {
    chans: [ChanState; 3],
}

/// Solution state of one (target, channel).
#[derive(Clone, Debug, Default)]
struct ChanState {
    /// False for a channel of zero energy (it does not count).
    active: bool,
    /// Passive Gram columns and their coefficients.
    passive: Vec<usize>,
    y: Vec<f64>,
    /// Cholesky factor of `C_PP`.
    l: Vec<f64>,
    /// Basis columns at zero.
    inactive: Vec<usize>,
    /// Relative residual.
    q: f64,
    /// `max |h|` over the basis columns.
    hmax: f64,
    /// `sum y`.
    ysum: f64,
    /// Whether `l` is usable.
    fast: bool,
}

/// The Gram matrices of an all-analytic collection in closed form: every channel lobe is
/// `kd / pi + ks beta_unit(F0, n)`, so one product `R R^T` of the unit lobes (rows
/// `beta_unit * sqrt(M_2)`) serves the three channels.
fn analytic_grams(coll: &Collection, cells: &CellSet) -> [Vec<f64>; 3] {
    let t = GridTables::new();
    let mom = CellMoments::new(&t, cells);
    let n = coll.len();
    let mats: Vec<_> = coll
        .materials()
        .iter()
        .map(|m| *m.analytic().expect("all analytic"))
        .collect();
    let unit: Vec<SeparableLobe> = mats
        .par_iter()
        .map(|a| {
            SeparableLobe::new(
                &t,
                &LobeParams {
                    kd: 0.0,
                    ks: 1.0,
                    f0: a.f0 as f32,
                    n: a.n as f32,
                },
            )
        })
        .collect();
    let sq: Vec<f64> = mom.m2.iter().map(|v| v.max(0.0).sqrt()).collect();
    let nij = N_TH * N_TD;
    let rows: Vec<f64> = unit
        .iter()
        .flat_map(|u| u.beta.iter().zip(&sq).map(|(b, s)| b * s))
        .collect();
    let c1: Vec<f64> = unit
        .iter()
        .map(|u| u.beta.iter().zip(&mom.m1).map(|(b, m)| b * m).sum())
        .collect();
    let u = gram_rows(&rows, n, nij);
    // Freed before the three (N + 1)^2 matrices are built (650 MB each at N = 10,000).
    drop(rows);
    drop(unit);
    let total = mom.total;
    [0, 1, 2].map(|c| {
        let m = n + 1;
        // Column 0: alpha = 1/pi, ks = 0. Parameters rounded to f32 as every lobe is.
        let alpha: Vec<f64> = std::iter::once(std::f64::consts::FRAC_1_PI)
            .chain(
                mats.iter()
                    .map(|a| a.d[c] as f32 as f64 * std::f64::consts::FRAC_1_PI),
            )
            .collect();
        let ks: Vec<f64> = std::iter::once(0.0)
            .chain(mats.iter().map(|a| a.s[c] as f32 as f64))
            .collect();
        let c1x: Vec<f64> = std::iter::once(0.0).chain(c1.iter().copied()).collect();
        let mut g = vec![0.0; m * m];
        g.par_chunks_mut(m).enumerate().for_each(|(i, row)| {
            for (j, o) in row.iter_mut().enumerate() {
                let uij = if i > 0 && j > 0 {
                    u[(i - 1) * n + j - 1]
                } else {
                    0.0
                };
                *o = alpha[i] * alpha[j] * total
                    + alpha[i] * ks[j] * c1x[j]
                    + alpha[j] * ks[i] * c1x[i]
                    + ks[i] * ks[j] * uij;
            }
        });
        g
    })
}

/// `R R^T` of `n` rows of length `len` (row-major), symmetric `n x n`, in 4 x 4 register
/// tiles, row tiles in parallel.
fn gram_rows(rows: &[f64], n: usize, len: usize) -> Vec<f64> {
    const T: usize = 4;
    let tiles = n.div_ceil(T);
    let pairs: Vec<(usize, usize)> = (0..tiles)
        .flat_map(|a| (a..tiles).map(move |b| (a, b)))
        .collect();
    let blocks: Vec<[[f64; T]; T]> = pairs
        .par_iter()
        .map(|&(a, b)| {
            let row = |i: usize| {
                let i = i.min(n - 1);
                &rows[i * len..(i + 1) * len]
            };
            let ra = [0, 1, 2, 3].map(|r| row(a * T + r));
            let rb = [0, 1, 2, 3].map(|r| row(b * T + r));
            let mut acc = [[[0.0f64; 4]; T]; T];
            let chunks = len / 4;
            for e in 0..chunks {
                let o = e * 4;
                let xa = ra.map(|r| [r[o], r[o + 1], r[o + 2], r[o + 3]]);
                let xb = rb.map(|r| [r[o], r[o + 1], r[o + 2], r[o + 3]]);
                for i in 0..T {
                    for j in 0..T {
                        for l in 0..4 {
                            acc[i][j][l] += xa[i][l] * xb[j][l];
                        }
                    }
                }
            }
            let mut out = [[0.0; T]; T];
            for i in 0..T {
                for j in 0..T {
                    let mut s = acc[i][j][0] + acc[i][j][1] + acc[i][j][2] + acc[i][j][3];
                    for o in chunks * 4..len {
                        s += ra[i][o] * rb[j][o];
                    }
                    out[i][j] = s;
                }
            }
            out
        })
        .collect();
    let mut g = vec![0.0; n * n];
    for (&(a, b), blk) in pairs.iter().zip(&blocks) {
        for (i, r) in blk.iter().enumerate() {
            for (j, &v) in r.iter().enumerate() {
                let (gi, gj) = (a * T + i, b * T + j);
                if gi < n && gj < n {
                    g[gi * n + gj] = v;
                    g[gj * n + gi] = v;
                }
            }
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_of_a_known_matrix() {
        // [[4, 2], [2, 5]] = L L^T with L = [[2, 0], [1, 2]].
        let l = cholesky(2, &[4.0, 2.0, 2.0, 5.0]).expect("pd");
        assert_eq!(l, vec![2.0, 0.0, 1.0, 2.0]);
        assert!(cholesky(2, &[1.0, 1.0, 1.0, 1.0]).is_none());
    }

    #[test]
    fn gram_rows_matches_naive_products() {
        let (n, len) = (7, 13);
        let rows: Vec<f64> = (0..n * len).map(|i| ((i * 37 % 11) as f64) - 4.0).collect();
        let g = gram_rows(&rows, n, len);
        for i in 0..n {
            for j in 0..n {
                let naive: f64 = (0..len)
                    .map(|e| rows[i * len + e] * rows[j * len + e])
                    .sum();
                assert_eq!(g[i * n + j], naive, "({i}, {j})");
            }
        }
    }
}
