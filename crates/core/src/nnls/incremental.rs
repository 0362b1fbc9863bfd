//! Incremental NNLS on a cosine Gram matrix: the exact fit of a target by a set of columns,
//! and the objective after adding one more column, by bordering the Cholesky factor of the
//! previous optimum instead of solving afresh.
//!
//! The matrix ([`Cosine`]) is a symmetric `m x m` Gram matrix scaled to unit diagonal (a
//! zero column keeps a zero diagonal): the fit of target column `t` by columns `P` is the
//! NNLS problem `G = C_PP`, `h = C_Pt`, `bb = 1`, whose optimum `q` is the target's residual
//! energy relative to its own energy.
//!
//! For the current columns the exact Lawson-Hanson solution is kept ([`ChanState`]) with its
//! passive set `P`, coefficients `y_P`, the Cholesky factor `L` of `C_PP` and its objective
//! `q`. Adding column `j` ([`ChanState::q_adding`]):
//!
//! 1. `w = C_jt - C_jP y_P` (the negative gradient). If `w <= kkt_tol * s` the old point
//!    stays optimal: `q` is unchanged (Lawson-Hanson would stop there too).
//! 2. `v = L^-1 C_Pj`, `d2 = 1 - |v|^2` (squared sine of the angle between column `j` and
//!    the span of `P`). If `d2 <= pivot_tol` the column is numerically dependent and, as in
//!    Lawson-Hanson, does not enter: `q` is unchanged.
//! 3. Otherwise the unconstrained solution on `P + j` is `z_j = w / d2`,
//!    `z_P = y_P - z_j L^-T v`, and the objective falls by exactly `w^2 / d2` (no
//!    cancellation). When every `z_P > 0` and no column outside `P` gets a positive
//!    gradient, this is the NNLS optimum; otherwise Lawson-Hanson runs on `cols + j` from
//!    the old optimum instead of from 0 (its inner loop, then columns entering, until the
//!    KKT conditions hold): the same optimum up to rounding, in a few small Cholesky solves.
//!    Only a failed factorisation or a loop past Lawson-Hanson's cap solves afresh.
//!
//! A candidate therefore costs `O(p^2)`, with `p` the number of columns (`O(p^3)` per
//! change of the passive set when the update is not the optimum).

use super::lawson_hanson::{self, LhParams};
use super::{GramProblem, NnlsError};

/// Lawson-Hanson's tolerances (its defaults), shared by the incremental path.
pub const KKT_TOL: f64 = 1e-12;
/// Smallest squared pivot (relative to the unit diagonal) a column may enter with.
pub const PIVOT_TOL: f64 = 1e-12;

/// A symmetric `m x m` cosine matrix, row-major: unit diagonal, zero rows and columns for
/// zero columns. Column indices address the fit columns and the target alike.
#[derive(Clone, Copy, Debug)]
pub struct Cosine<'a> {
    m: usize,
    data: &'a [f64],
}

impl<'a> Cosine<'a> {
    /// A view of `data` (`m * m` entries).
    pub fn new(m: usize, data: &'a [f64]) -> Result<Self, NnlsError> {
        if data.len() != m * m {
            return Err(NnlsError::DimensionMismatch {
                what: "cosine matrix",
                expected: m * m,
                found: data.len(),
            });
        }
        Ok(Self { m, data })
    }

    /// Row `i`.
    #[inline]
    pub fn row(&self, i: usize) -> &'a [f64] {
        &self.data[i * self.m..(i + 1) * self.m]
    }

    /// Entry `(i, j)`.
    #[inline]
    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.data[i * self.m + j]
    }
}

/// Scales a symmetric `m x m` Gram matrix `g` (row-major) to its cosine matrix in place,
/// `C_ij = (G_ij + G_ji) / 2 / d_i / d_j` with `d_i = sqrt(G_ii)` (unit diagonal; a zero
/// column, `G_ii <= f64::MIN_POSITIVE`, gets `d_i = 0` and a zero row and column), and
/// returns `d`. The one diagonal scaling of the crate: the solvers' scaled problem and the
/// objective's cosine matrices (in place: at N = 10,000 one matrix is 800 MB).
pub(crate) fn cosine_in_place(m: usize, g: &mut [f64]) -> Vec<f64> {
    use rayon::prelude::*;
    assert_eq!(g.len(), m * m, "cosine_in_place: an m x m matrix");
    let scale: Vec<f64> = (0..m)
        .map(|i| {
            let v = g[i * m + i];
            if v > f64::MIN_POSITIVE {
                v.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    // In tiles of `TILE x TILE` (a row-major pass would read every column with a stride of
    // one row): the tiles `(I, J)` and `(J, I)`, `I <= J`, belong to tile row `I`, so the
    // tile rows touch disjoint entries and run in parallel.
    const TILE: usize = 64;
    struct Shared(*mut f64);
    impl Shared {
        /// Entry `k` of the matrix.
        ///
        /// # Safety
        /// `k < m * m`.
        unsafe fn at(&self, k: usize) -> *mut f64 {
            // SAFETY: inside the matrix (the caller's contract).
            unsafe { self.0.add(k) }
        }
    }
    // SAFETY: the tile rows write disjoint entries (above) and read only their own.
    unsafe impl Sync for Shared {}
    let base = Shared(g.as_mut_ptr());
    let (base, d) = (&base, &scale);
    let tile_row = |ti: usize| {
        let i0 = ti * TILE;
        let i1 = (i0 + TILE).min(m);
        for j0 in (i0..m).step_by(TILE) {
            let j1 = (j0 + TILE).min(m);
            for i in i0..i1 {
                let di = d[i];
                if j0 == i0 {
                    // SAFETY: `i < m`, an entry of tile (I, I), owned by this tile row.
                    unsafe { *base.at(i * m + i) = if di == 0.0 { 0.0 } else { 1.0 } };
                }
                let js = j0.max(i + 1)..j1;
                for (j, &dj) in js.clone().zip(&d[js]) {
                    // SAFETY: `i, j < m`; `(i, j)` is in tile (I, J) and `(j, i)` in tile
                    // (J, I), both owned by tile row `I` (`I <= J`).
                    unsafe {
                        let (up, lo) = (base.at(i * m + j), base.at(j * m + i));
                        let sum = *up + *lo;
                        let live = di != 0.0 && dj != 0.0;
                        *up = if live { 0.5 * sum / di / dj } else { 0.0 };
                        *lo = if live { 0.5 * sum / dj / di } else { 0.0 };
                    }
                }
            }
        }
    };
    // One tile row (the solvers' small matrices, per target): no tasks.
    match m.div_ceil(TILE) {
        0 | 1 => (0..m.div_ceil(TILE)).for_each(tile_row),
        rows => (0..rows).into_par_iter().for_each(tile_row),
    }
    scale
}

/// Exact NNLS (Lawson-Hanson, default parameters) of target column `t` on the columns
/// `cols`: the coefficients (in `cols` order, scaled units) and the relative residual `q`
/// clamped to `[0, 1]`.
pub fn solve(g: Cosine<'_>, cols: &[usize], t: usize) -> Result<(Vec<f64>, f64), NnlsError> {
    let m = cols.len();
    let mut a = vec![0.0; m * m];
    for (r, &ca) in cols.iter().enumerate() {
        let row = g.row(ca);
        for (s, &cb) in cols.iter().enumerate() {
            a[r * m + s] = row[cb];
        }
    }
    let h: Vec<f64> = cols.iter().map(|&ca| g.at(ca, t)).collect();
    let sol = lawson_hanson::solve(&GramProblem::new(m, &a, &h, 1.0)?, &LhParams::default())?;
    Ok((sol.x, sol.objective.clamp(0.0, 1.0)))
}

/// Lower Cholesky factor (row-major `p x p`) of a symmetric positive-definite matrix, or
/// `None` when a pivot is not positive.
pub(crate) fn cholesky(p: usize, a: &[f64]) -> Option<Vec<f64>> {
    let mut l = Vec::new();
    cholesky_into(p, a, &mut l).then_some(l)
}

/// [`cholesky`] into `l` (resized to `p x p`); false when a pivot is not positive.
fn cholesky_into(p: usize, a: &[f64], l: &mut Vec<f64>) -> bool {
    l.clear();
    l.resize(p * p, 0.0);
    for r in 0..p {
        for s in 0..=r {
            let dot: f64 = (0..s).map(|k| l[r * p + k] * l[s * p + k]).sum();
            let v = a[r * p + s] - dot;
            if r == s {
                if v.is_nan() || v <= 0.0 {
                    return false;
                }
                l[r * p + r] = v.sqrt();
            } else {
                l[r * p + s] = v / l[s * p + s];
            }
        }
    }
    true
}

/// The exact optimum of one target on a set of columns, kept for bordered updates.
#[derive(Clone, Debug, Default)]
pub struct ChanState {
    /// False for a problem that does not count (e.g. a channel of zero energy).
    active: bool,
    /// Passive columns and their coefficients.
    passive: Vec<usize>,
    y: Vec<f64>,
    /// Cholesky factor of `C_PP`.
    l: Vec<f64>,
    /// Columns at zero.
    inactive: Vec<usize>,
    /// Relative residual.
    q: f64,
    /// `max |h|` over the columns.
    hmax: f64,
    /// `sum y`.
    ysum: f64,
    /// Whether `l` is usable.
    fast: bool,
}

impl ChanState {
    /// A problem that does not count ([`ChanState::is_active`] is false).
    pub fn inactive() -> Self {
        Self::default()
    }

    /// The exact optimum of target column `t` on `cols`.
    pub fn new(g: Cosine<'_>, cols: &[usize], t: usize) -> Result<Self, NnlsError> {
        let (x, q) = solve(g, cols, t)?;
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
                a[r * p + s] = g.at(i, j);
            }
        }
        let l = cholesky(p, &a);
        Ok(Self {
            hmax: cols.iter().map(|&i| g.at(i, t).abs()).fold(0.0, f64::max),
            ysum: y.iter().sum(),
            fast: l.is_some(),
            l: l.unwrap_or_default(),
            passive,
            inactive,
            y,
            q,
            active: true,
        })
    }

    /// Whether the problem counts.
    pub fn is_active(&self) -> bool {
        self.active
    }

    /// The relative residual of the optimum.
    pub fn q(&self) -> f64 {
        self.q
    }

    /// The passive columns, their coefficients and the scale `(max |h|, sum y)` of the KKT
    /// test of [`ChanState::unchanged_adding`] (for the same test on many columns at once).
    pub fn kkt_parts(&self) -> (&[usize], &[f64], f64, f64) {
        (&self.passive, &self.y, self.hmax, self.ysum)
    }

    /// `w = C_jt - C_jP y_P` of column `j` (its cosine row `row`) for target `t`.
    #[inline]
    fn gradient(&self, row: &[f64], t: usize) -> f64 {
        row[t]
            - self
                .passive
                .iter()
                .zip(&self.y)
                .map(|(&k, &y)| row[k] * y)
                .sum::<f64>()
    }

    /// Whether adding column `j` leaves the optimum of target `t` as it is (a zero column,
    /// or step 1 of the module docs: no positive gradient); [`ChanState::q_adding`] then
    /// returns [`ChanState::q`], bit for bit (the same test on the same numbers).
    #[inline]
    pub fn unchanged_adding(&self, g: Cosine<'_>, j: usize, t: usize) -> bool {
        let row = g.row(j);
        row[j] == 0.0
            || self.gradient(row, t) <= KKT_TOL * (self.hmax.max(row[t].abs()) + self.ysum)
    }

    /// Relative residual `q` of target column `t` after adding column `j` to `cols` (the
    /// columns this state was built on). `ws` is scratch, reused between calls.
    pub fn q_adding(
        &self,
        g: Cosine<'_>,
        cols: &[usize],
        j: usize,
        t: usize,
        ws: &mut Scratch,
    ) -> Result<f64, NnlsError> {
        let row = g.row(j);
        if row[j] == 0.0 {
            return Ok(self.q); // a zero column never helps
        }
        let w = self.gradient(row, t);
        let hmax = self.hmax.max(row[t].abs());
        if w <= KKT_TOL * (hmax + self.ysum) {
            return Ok(self.q);
        }
        if !self.fast {
            return solve_adding(g, cols, j, t);
        }
        let p = self.passive.len();
        let v = &mut ws.v;
        v.clear();
        v.resize(p, 0.0);
        // v = L^-1 C_Pj
        for r in 0..p {
            let lr = &self.l[r * p..r * p + r];
            let dot: f64 = lr.iter().zip(&v[..r]).map(|(a, b)| a * b).sum();
            v[r] = (row[self.passive[r]] - dot) / self.l[r * p + r];
        }
        let d2 = 1.0 - v.iter().map(|x| x * x).sum::<f64>();
        if d2.is_nan() || d2 <= PIVOT_TOL {
            return Ok(self.q);
        }
        // u = L^-T v (in place)
        for r in (0..p).rev() {
            let dot: f64 = (r + 1..p).map(|s| self.l[s * p + r] * v[s]).sum();
            v[r] = (v[r] - dot) / self.l[r * p + r];
        }
        let delta = w / d2;
        // The unconstrained solution on `P + j`, and the old optimum (feasible, `j` at 0).
        ws.z.clear();
        ws.z.extend(self.y.iter().zip(v.iter()).map(|(y, u)| y - delta * u));
        ws.z.push(delta);
        if ws.z.iter().all(|&x| x > 0.0) {
            let s = hmax + ws.z.iter().sum::<f64>();
            let zp = &ws.z[..p];
            let enters = self.inactive.iter().any(|&i| {
                let ri = g.row(i);
                ri[i] != 0.0 && {
                    let wi = ri[t]
                        - self
                            .passive
                            .iter()
                            .zip(zp)
                            .map(|(&k, &zk)| ri[k] * zk)
                            .sum::<f64>()
                        - ri[j] * delta;
                    wi > KKT_TOL * s
                }
            });
            if !enters {
                return Ok((self.q - w * w / d2).max(0.0));
            }
        }
        ws.set.clear();
        ws.set.extend_from_slice(&self.passive);
        ws.set.push(j);
        ws.x.clear();
        ws.x.extend_from_slice(&self.y);
        ws.x.push(0.0);
        match warm_lh(g, cols, j, t, ws) {
            Some(q) => Ok(q),
            None => solve_adding(g, cols, j, t),
        }
    }
}

/// Scratch of [`ChanState::q_adding`], reused between calls (every entry read is written
/// first in the same call).
#[derive(Default, Debug)]
pub struct Scratch {
    v: Vec<f64>,
    set: Vec<usize>,
    x: Vec<f64>,
    z: Vec<f64>,
    keep_set: Vec<usize>,
    keep_x: Vec<f64>,
    tried: Vec<usize>,
    a: Vec<f64>,
    l: Vec<f64>,
}

/// Lawson-Hanson on `cols + j` for target `t`, continued from a feasible point instead of
/// from 0: `ws.set` the passive columns, `ws.x` their (non-negative) coefficients and `ws.z`
/// the unconstrained solution on `ws.set`. The inner loop steps from `x` towards `z` to the
/// first bound and drops the columns that reach 0, until `z > 0`; then the column with the
/// largest gradient above the KKT tolerance enters (one whose solve gives it no positive
/// coefficient, or no pivot, is passed over, as in [`lawson_hanson`]), until none is left:
/// the optimum, whose `q` is returned. The same optimum as a fresh solve (a strictly convex
/// problem on the passive set; `q` is unique in any case) from another starting point, so
/// equal to it up to rounding. `None` (the caller solves afresh) when a factorisation fails
/// or the outer or inner loop exceeds Lawson-Hanson's cap.
fn warm_lh(g: Cosine<'_>, cols: &[usize], j: usize, t: usize, ws: &mut Scratch) -> Option<f64> {
    let m = cols.len() + 1;
    let col = |k: usize| if k < cols.len() { cols[k] } else { j };
    let hmax = (0..m).map(|k| g.at(col(k), t).abs()).fold(0.0, f64::max);
    let cap = 3 * m + 30;
    for _ in 0..cap {
        // Inner loop: towards `z` until every passive coefficient is positive.
        let mut inner = 0;
        while ws.z.iter().any(|&v| v <= 0.0) {
            inner += 1;
            if inner > m + 1 {
                return None;
            }
            let alpha =
                ws.x.iter()
                    .zip(&ws.z)
                    .filter(|(_, &zk)| zk <= 0.0)
                    .map(|(&xk, &zk)| xk / (xk - zk))
                    .fold(1.0f64, f64::min);
            ws.keep_set.clear();
            ws.keep_x.clear();
            for ((&k, &xk), &zk) in ws.set.iter().zip(&ws.x).zip(&ws.z) {
                let nx = if zk <= 0.0 && xk / (xk - zk) <= alpha {
                    0.0
                } else {
                    xk + alpha * (zk - xk)
                };
                if nx > 0.0 {
                    ws.keep_set.push(k);
                    ws.keep_x.push(nx);
                }
            }
            std::mem::swap(&mut ws.set, &mut ws.keep_set);
            std::mem::swap(&mut ws.x, &mut ws.keep_x);
            if !solve_on(g, &ws.set, t, &mut ws.z, &mut ws.a, &mut ws.l) {
                return None;
            }
        }
        ws.x.clear();
        ws.x.extend_from_slice(&ws.z);
        // Outer step: the entering column, if any.
        let s = hmax + ws.z.iter().sum::<f64>();
        ws.tried.clear();
        loop {
            let mut best: Option<(usize, f64)> = None;
            for k in 0..m {
                let i = col(k);
                let ri = g.row(i);
                if ri[i] == 0.0 || ws.set.contains(&i) || ws.tried.contains(&i) {
                    continue;
                }
                let wi = ri[t]
                    - ws.set
                        .iter()
                        .zip(&ws.z)
                        .map(|(&k, &zk)| ri[k] * zk)
                        .sum::<f64>();
                if wi > KKT_TOL * s && best.is_none_or(|(_, b)| wi > b) {
                    best = Some((i, wi));
                }
            }
            let Some((i, _)) = best else {
                // The optimum: q = 1 + sum_k z_k ((C z)_k - 2 h_k).
                let mut q = 1.0;
                for (&a, &za) in ws.set.iter().zip(&ws.z) {
                    let ra = g.row(a);
                    let cz: f64 = ws.set.iter().zip(&ws.z).map(|(&b, &zb)| ra[b] * zb).sum();
                    q += za * (cz - 2.0 * ra[t]);
                }
                return Some(q.clamp(0.0, 1.0));
            };
            ws.tried.push(i);
            ws.set.push(i);
            if solve_on(g, &ws.set, t, &mut ws.z, &mut ws.a, &mut ws.l)
                && ws.z.last().is_some_and(|&zi| zi > 0.0)
            {
                ws.x.push(0.0);
                break;
            }
            ws.set.pop();
            // `z` is the solution on the set without `i` again.
            ws.z.clear();
            ws.z.extend_from_slice(&ws.x);
        }
    }
    None
}

/// The unconstrained solution `z` of `C_SS z = C_St` by Cholesky (`a` and `l` scratch);
/// false when `C_SS` is not numerically positive definite.
fn solve_on(
    g: Cosine<'_>,
    set: &[usize],
    t: usize,
    z: &mut Vec<f64>,
    a: &mut Vec<f64>,
    l: &mut Vec<f64>,
) -> bool {
    let p = set.len();
    a.clear();
    for &i in set {
        let ri = g.row(i);
        a.extend(set.iter().map(|&k| ri[k]));
    }
    if !cholesky_into(p, a, l) || (0..p).any(|r| l[r * p + r] * l[r * p + r] <= PIVOT_TOL) {
        return false;
    }
    z.clear();
    z.extend(set.iter().map(|&i| g.at(i, t)));
    for r in 0..p {
        let dot: f64 = (0..r).map(|k| l[r * p + k] * z[k]).sum();
        z[r] = (z[r] - dot) / l[r * p + r];
    }
    for r in (0..p).rev() {
        let dot: f64 = (r + 1..p).map(|k| l[k * p + r] * z[k]).sum();
        z[r] = (z[r] - dot) / l[r * p + r];
    }
    true
}

/// The exact `q` on `cols + j`.
fn solve_adding(g: Cosine<'_>, cols: &[usize], j: usize, t: usize) -> Result<f64, NnlsError> {
    let mut all = cols.to_vec();
    all.push(j);
    Ok(solve(g, &all, t)?.1)
}

#[cfg(test)]
mod tests {
    /// The row-major definition of [`cosine_in_place`], entry by entry.
    fn cosine_reference(m: usize, g: &mut [f64]) -> Vec<f64> {
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
        d
    }

    #[test]
    fn the_tiled_cosine_matrix_is_the_row_major_one_bit_for_bit() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for m in [1, 2, 63, 64, 65, 130, 200] {
            // Asymmetric (the mean of both halves is taken), one zero column.
            let mut g: Vec<f64> = (0..m * m).map(|_| next() * 3.0).collect();
            for i in 0..m {
                g[i * m + i] = 1.0 + next() * 5.0;
            }
            if m > 2 {
                g[2 * m + 2] = 0.0;
            }
            let mut want = g.clone();
            let dw = cosine_reference(m, &mut want);
            let dg = cosine_in_place(m, &mut g);
            assert_eq!(dg, dw, "m = {m}");
            for (k, (a, b)) in g.iter().zip(&want).enumerate() {
                assert_eq!(a.to_bits(), b.to_bits(), "m = {m}, entry {k}");
            }
        }
    }

    use super::*;

    #[test]
    fn cholesky_of_a_known_matrix() {
        // [[4, 2], [2, 5]] = L L^T with L = [[2, 0], [1, 2]].
        let l = cholesky(2, &[4.0, 2.0, 2.0, 5.0]).expect("pd");
        assert_eq!(l, vec![2.0, 0.0, 1.0, 2.0]);
        assert!(cholesky(2, &[1.0, 1.0, 1.0, 1.0]).is_none());
    }

    /// A cosine matrix of `m` random non-negative vectors of length `len` (the last one the
    /// target).
    fn random_cosine(m: usize, len: usize, seed: u64) -> Vec<f64> {
        let mut s = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 33) as f64) / (1u64 << 31) as f64
        };
        let v: Vec<Vec<f64>> = (0..m).map(|_| (0..len).map(|_| next()).collect()).collect();
        cosines_of(&v)
    }

    /// The cosine matrix (unit diagonal) of the vectors `v`.
    fn cosines_of(v: &[Vec<f64>]) -> Vec<f64> {
        let m = v.len();
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let mut c = vec![0.0; m * m];
        for i in 0..m {
            for j in 0..m {
                c[i * m + j] = if i == j {
                    1.0
                } else {
                    dot(&v[i], &v[j]) / (dot(&v[i], &v[i]) * dot(&v[j], &v[j])).sqrt()
                };
            }
        }
        c
    }

    #[test]
    fn bordered_update_matches_a_fresh_solve() {
        for seed in 0..20 {
            let m = 8;
            let c = random_cosine(m, 5, seed);
            let g = Cosine::new(m, &c).unwrap();
            let t = m - 1;
            let cols = [0, 2, 4];
            let st = ChanState::new(g, &cols, t).unwrap();
            assert_eq!(st.q(), solve(g, &cols, t).unwrap().1);
            let mut scratch = Scratch::default();
            for j in [1, 3, 5, 6] {
                let inc = st.q_adding(g, &cols, j, t, &mut scratch).unwrap();
                let mut all = cols.to_vec();
                all.push(j);
                let fresh = solve(g, &all, t).unwrap().1;
                assert!(
                    (inc - fresh).abs() <= 1e-12,
                    "seed {seed} j {j}: {inc} vs {fresh}"
                );
            }
        }
    }

    /// A cosine matrix of `m` sparse non-negative vectors (entries `u^4` of uniform `u`,
    /// like the lobes of BRDFs): adding one column to a basis often moves coefficients to
    /// zero and makes other basis columns enter.
    fn peaky_cosine(m: usize, len: usize, seed: u64) -> Vec<f64> {
        let mut s = seed.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s >> 11) as f64) / (1u64 << 53) as f64
        };
        let v: Vec<Vec<f64>> = (0..m)
            .map(|_| (0..len).map(|_| next().powi(4)).collect())
            .collect();
        cosines_of(&v)
    }

    /// The warm-started Lawson-Hanson of `q_adding` (coefficients leaving, basis columns
    /// entering) against a fresh solve of every `basis + j`, on bases of 4 to 20 columns.
    #[test]
    fn warm_started_updates_match_fresh_solves() {
        let (m, mut entered, mut left, mut pairs) = (48, 0, 0, 0);
        for seed in 0..24u64 {
            let c = peaky_cosine(m, 10 + (seed as usize % 3) * 6, seed);
            let g = Cosine::new(m, &c).unwrap();
            let t = m - 1 - (seed as usize % 5);
            let p = 4 + (seed as usize * 7) % 17;
            let cols: Vec<usize> = (0..p).map(|k| (k * 5 + seed as usize) % (m - 6)).collect();
            let mut cols_sorted = cols.clone();
            cols_sorted.sort_unstable();
            cols_sorted.dedup();
            let cols = cols_sorted;
            let st = ChanState::new(g, &cols, t).unwrap();
            let mut scratch = Scratch::default();
            for j in (0..m).filter(|j| !cols.contains(j) && *j != t) {
                let inc = st.q_adding(g, &cols, j, t, &mut scratch).unwrap();
                let mut all = cols.clone();
                all.push(j);
                let (x, fresh) = solve(g, &all, t).unwrap();
                assert!(
                    (inc - fresh).abs() <= 1e-12 * (1.0 + fresh),
                    "seed {seed} j {j}: {inc} vs {fresh}"
                );
                pairs += 1;
                let was = |k: usize| st.passive.contains(&all[k]);
                entered += usize::from((0..cols.len()).any(|k| x[k] > 0.0 && !was(k)));
                left += usize::from((0..cols.len()).any(|k| x[k] <= 0.0 && was(k)));
            }
        }
        // Both warm paths were taken, many times.
        assert!(
            entered >= 20 && left >= 20,
            "{pairs} pairs: {entered} entered, {left} left"
        );
    }

    #[test]
    fn a_wrong_size_is_an_error() {
        assert!(Cosine::new(3, &[1.0; 8]).is_err());
    }
}
