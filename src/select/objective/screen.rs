//! Exact screening of "basis + one candidate" (greedy and swap at scale).
//!
//! The choice of SPEC 8 is `argmin_c S(B + c; T)` with ties to the earliest candidate
//! ([`crate::select::search`]'s rule: a later score wins only by more than `tie_tol`
//! relative). It is computed here as that very chain, in candidate order, without the
//! exact score of a candidate that provably cannot win: a cheap lower bound `lb_c <=
//! S(B + c; T)` at or above the threshold of the chain's current best means the exact
//! score could not replace it either (the threshold only falls along the chain), so the
//! chain, the chosen candidate and its score are exactly those of the exhaustive sweep.
//!
//! The bound, per target `t`, channel and candidate `c` (cosine space: unit columns, unit
//! target; `B'` the non-zero columns of the basis with the Lambertian, `G = C_B'B'`,
//! `L L^T = G`; the optimum on `B` has passive set `P`, coefficients `y_P`, residual `r_t`,
//! value `q_t`, and `I = B' \ P`):
//! * when adding `c` leaves the optimum as it is ([`ChanState::unchanged_adding`]: no
//!   positive gradient `w = C_ct - C_cP y_P`), the exact value is the current `q_t`, bit for
//!   bit;
//! * otherwise, when the cosines among the columns of `B' + c` are non-negative (as those of
//!   non-negative BRDFs are), by weak duality: for any `u`, the NNLS optimum `x*` on
//!   `B' + c` satisfies `q >= 2 b.u - |u|^2 - 2 sum_k x*_k max(0, a_k.u)`, and `sum_k x*_k
//!   <= X = 2 sqrt(p + 1)` (with non-negative cosines `|A x|^2 >= |x|^2`, and `|A x*| <=
//!   2`). With `e` the part of column `c` orthogonal to the span of `P`, `d2 = |e|^2`, and
//!   `u = r_t - (w / d2) e`: `a_c.u = 0`, `a_k.u = 0` on `P` (the KKT equalities), and
//!   `q >= q_t - w^2 / d2` whenever `u` is dual feasible on `I`: `a_i.u = w_i - (w / d2)
//!   s_i <= 0`, with `w_i` the (non-positive) gradient of `i` at the optimum and `s_i` the
//!   cosine of `i` with `e`. This is the **exact** value whenever the bordered update of
//!   [`ChanState::q_adding`] keeps every coefficient positive (the common case), so the
//!   bound screens candidates whose scores differ by far less than the looser bounds could.
//!   It costs `O(|I|^2)` per pair, not `O(p^2)`: with `a = G^-1 C_B'c` (per candidate, once)
//!   and the Schur complement `S_t = G_II - G_IP G_PP^-1 G_PI` (per target, once),
//!   `s = S_t a_I` and `d2 = 1 - |V_c|^2 + a_I . s` (block inverse of `G`: `(G^-1)_II =
//!   S_t^-1`).
//! * when that `u` is not dual feasible, `u = r_t - (w / s2) z` with `z` the part of `c`
//!   orthogonal to the span of all of `B'` (`s2 = |z|^2 = 1 - |V_c|^2 <= d2`, `V = L^-1
//!   C_B'.`) is (`a_i.z = 0` on all of `B'`): `q >= q_t - w^2 / s2`;
//! * and, with any cosines, the NNLS residual on `B' + c` is at least the least-squares
//!   residual on their span with a non-negative coefficient on `c`: `q >= 1 - |V_t|^2 -
//!   max(0, C_ct - V_c . V_t)^2 / s2`.
//!
//! Between the two ends, the best dual point `u = r_t - alpha e - beta z` that is feasible
//! on `I` (`pair_bound`) keeps what the tight one gives where adding `c` would make an
//! inactive column enter.
//!
//! Rounding: the KKT conditions hold to Lawson-Hanson's tolerance (~1e-11) and dual
//! feasibility is tested with the same slack [`TAU`], hence a margin of `MARGIN (1 + X)`;
//! the computed `d2` and `a` carry an absolute error of about `64 (p + 1) eps (sqrt(kappa)
//! + kappa |a_c|)` (`kappa` the condition estimate of `G`), which the bound pays for
//! relatively to `d2` (above [`EPS_MAX`] the pair gets the looser bounds), and so do the
//! rounding of `w` and that of the exact value itself (the bordered update's `d2`, with the
//! condition of `G_PP`). A pair none of whose bounds can be trusted (`s2 < `[`NC_MIN`]
//! without the tight bound) is bounded by 0, which no computed value is below. The bounds
//! need not equal anything bit for bit: only the exact scores ([`refine`]) decide; no
//! candidate is screened when `C_B'B'` has no Cholesky factor.
//!
//! Two levels (`Screen::bounds_loose`, `Screen::bounds_tight`): the loose level bounds every pair with a positive
//! gradient by the loose dual point alone (`O(1)`, no Schur complement), the tight level as
//! above. Every candidate gets the loose level; `best_first` makes tight only the bounds
//! of the candidates it takes below the cutoff (at N = 10,000, 10-30% of them).
//!
//! Signs carried from step to step (`GradSigns`): which pairs have a positive gradient
//! depends on the target's state alone (and the fixed cosines). In a greedy run, a target
//! whose state on `B + b` is bit for bit its state on `B` (70-90% of them late in a run at
//! N = 10,000) keeps the signs of the previous step; the loose level computes the gradients
//! of the other targets only, and those of the carried positive pairs one by one. The
//! signs are also what the tight level and the exact scores read: a pair whose gradient is
//! not positive contributes `q_t` with no work.
//!
//! Cost: the gradients of the fresh targets' pairs as blocked matrix products (`O(p)` per
//! target and candidate), those of the positive pairs (about one in ten late in a greedy
//! run) one by one, then, at the tight level, `O(|I|^2)` for each positive pair; the exact
//! update costs `O(p^2)` (`O(p^3)` per change of the passive set when it is not the
//! optimum).

use super::Objective;
use crate::nnls::incremental::{cholesky, ChanState, KKT_TOL};
use rayon::prelude::*;

/// Absolute slack subtracted from each target's least-squares bound: far above the
/// rounding of the bound and of the exact value (both ~1e-15 relative on values <= 1).
pub const MARGIN: f64 = 1e-10;
/// Smallest squared sine between a candidate and the span of the basis for which the
/// least-squares bound is used.
pub const NC_MIN: f64 = 1e-4;
/// Dual infeasibility tolerated in the tight bound (module docs; the KKT tolerance of the
/// optimum on the basis is of the same size).
pub const TAU: f64 = 5e-11;
/// Largest relative rounding error of `d2` for which the tight bound is used.
pub const EPS_MAX: f64 = 1e-2;

/// The argmin chain of [`crate::select::search`]: the earliest lowest score, a later
/// one winning only by more than `tol` relative.
#[derive(Clone, Copy, Debug)]
pub struct Chain {
    tol: f64,
    best: Option<(usize, f64)>,
}

impl Chain {
    /// An empty chain with tie tolerance `tol`.
    pub fn new(tol: f64) -> Self {
        Self { tol, best: None }
    }

    /// A score below this replaces the current best (`None`: any score does).
    pub fn threshold(&self) -> Option<f64> {
        self.best.map(|(_, b)| b - self.tol * b.abs() - 1e-300)
    }

    /// Offers score `s` of item `i` (items offered in increasing order).
    pub fn offer(&mut self, i: usize, s: f64) {
        match self.threshold() {
            None => self.best = Some((i, s)),
            Some(t) if s < t => self.best = Some((i, s)),
            _ => {}
        }
    }

    /// The winner and its score.
    pub fn best(&self) -> Option<(usize, f64)> {
        self.best
    }
}

/// One channel's basis: its non-zero columns `nz` (`p` of them), per column `x` of the
/// matrix `|V_x|^2` and `a_x = G^-1 C_{nz,x}` (`m x p`, row `x`), and the relative rounding
/// scale `64 (p + 1) eps kappa` of `a` and `1 - |V_x|^2` (kappa: the squared ratio of the
/// extreme pivots of `L`, an estimate of the condition number of `G`).
#[derive(Default)]
struct Basis {
    nz: Vec<usize>,
    nrm: Vec<f64>,
    a: Vec<f64>,
    e64: f64,
    sk: f64,
    kappa: f64,
}

/// Per channel, the [`Basis`] of `cols`, or `None` when the non-zero basis columns have no
/// Cholesky factor.
fn projections(obj: &Objective, cols: &[usize]) -> Option<[Basis; 3]> {
    let m = obj.len() + 1;
    let mut out: [Basis; 3] = Default::default();
    for (c, o) in out.iter_mut().enumerate() {
        let g = obj.view(c);
        let nz: Vec<usize> = cols.iter().copied().filter(|&k| g.at(k, k) > 0.0).collect();
        let p = nz.len();
        let mut gm = vec![0.0; p * p];
        for (r, &kr) in nz.iter().enumerate() {
            for (s, &ks) in nz.iter().enumerate() {
                gm[r * p + s] = g.at(kr, ks);
            }
        }
        let l = cholesky(p, &gm)?;
        let mut a = vec![0.0; m * p];
        let mut nrm = vec![0.0; m];
        let rows: Vec<&[f64]> = nz.iter().map(|&k| g.row(k)).collect();
        a.par_chunks_mut(p.max(1))
            .zip(nrm.par_iter_mut())
            .enumerate()
            .for_each(|(x, (v, n))| {
                // V_x = L^-1 C_{nz,x}, then a_x = L^-T V_x in place.
                for r in 0..p {
                    let dot: f64 = (0..r).map(|s| l[r * p + s] * v[s]).sum();
                    v[r] = (rows[r][x] - dot) / l[r * p + r];
                }
                *n = v.iter().map(|a| a * a).sum();
                for r in (0..p).rev() {
                    let dot: f64 = (r + 1..p).map(|s| l[s * p + r] * v[s]).sum();
                    v[r] = (v[r] - dot) / l[r * p + r];
                }
            });
        let piv = (0..p).map(|r| l[r * p + r]);
        let (lo, hi) = piv.fold((f64::INFINITY, 0.0f64), |(lo, hi), d| {
            (lo.min(d), hi.max(d))
        });
        let kappa = if p == 0 { 1.0 } else { (hi / lo).powi(2) };
        *o = Basis {
            nz,
            nrm,
            a,
            e64: 64.0 * (p + 1) as f64 * f64::EPSILON,
            sk: kappa.sqrt(),
            kappa,
        };
    }
    Some(out)
}

/// Live targets per refinement chunk (a bound is kept per chunk).
pub const CHUNK: usize = 128;

/// A lower bound of one candidate's `S(B + c; T)`: the sum over the live targets (but the
/// candidate) of each target's bound, per chunk of [`CHUNK`] live targets, and the count
/// the mean divides by; `None` when the candidate is not screened.
#[derive(Clone, Debug)]
pub(super) struct Bound {
    /// Per chunk of live targets: the sum of their bounds (share-weighted).
    pub chunks: Vec<f64>,
    /// Targets the mean divides by.
    pub count: usize,
}

impl Bound {
    /// The bound of the mean.
    pub fn mean(&self) -> f64 {
        if self.count == 0 {
            f64::INFINITY
        } else {
            self.chunks.iter().sum::<f64>() / self.count as f64
        }
    }
}

/// Whether a candidate whose score is at least `lb` (up to the rounding of a sum of
/// `terms` non-negative terms, taken in another order than the exact score's) cannot
/// replace a best of threshold `thr`.
pub(super) fn ruled_out(lb: f64, terms: usize, thr: Option<f64>) -> bool {
    let slack = (terms as f64 + 16.0) * f64::EPSILON;
    thr.is_some_and(|t| lb - slack * lb.abs() >= t)
}

/// Per channel, the live targets' data of the bounds: per live position the coefficients
/// `yt` (row-major, `lp x cols`, zero outside the passive set: the gradient of one pair), and
/// the coefficients `y` of the fresh targets (those whose signs are computed again, at live
/// positions `fresh`, padded with `u32::MAX` to `lf`), column-major for the register tiles
/// (`cols x lf`: entry `k * lf + f`); per material, as bits, the live targets of an active
/// channel (`liveact`) and those among them whose carried signs hold (`keep`); per target
/// the KKT scale, `q`, share, whether the channel counts, the rounding scale of its
/// gradients, and the data of the tight bound: its group (the targets with the same passive
/// set, which share the positions in `nz` of the inactive columns and the Schur complement
/// `S_t`, row-major, at `goff[g]..goff[g + 1]` and `gsoff[g]..`) and the room left in the
/// dual feasibility of its inactive columns, `TAU - werr - w_i` at `off[i]..off[i + 1]`
/// (`tight[i]` false: none; `blocked[i]`: one of them is negative).
#[derive(Default)]
struct Targets {
    y: Vec<f64>,
    yt: Vec<f64>,
    fresh: Vec<u32>,
    lf: usize,
    liveact: Vec<u64>,
    keep: Vec<u64>,
    hmax: Vec<f64>,
    ysum: Vec<f64>,
    q: Vec<f64>,
    share: Vec<f64>,
    active: Vec<bool>,
    werr: Vec<f64>,
    tight: Vec<bool>,
    kp: Vec<f64>,
    off: Vec<usize>,
    room: Vec<f64>,
    blocked: Vec<bool>,
    grp: Vec<u32>,
    goff: Vec<usize>,
    gsoff: Vec<usize>,
    inact: Vec<u32>,
    s: Vec<f64>,
}

/// The tight bound's data of one passive set: inactive positions, `S_t` and the square
/// root of the condition estimate of `G_PP` (squared ratio of its extreme Cholesky
/// pivots).
type Schur = (Vec<u32>, Vec<f64>, f64);

/// The tight bound's data of the targets whose passive set is `passive` ([`Targets`]):
/// inactive positions in `nz` and `S_t`; `None` when a passive column is not in `nz` or
/// `G_PP` or `S_t` has no positive pivots.
fn schur(
    g: crate::nnls::incremental::Cosine<'_>,
    nz: &[usize],
    passive: &[usize],
) -> Option<Schur> {
    if !passive.iter().all(|k| nz.contains(k)) {
        return None;
    }
    let inact: Vec<u32> = (0..nz.len())
        .filter(|&r| !passive.contains(&nz[r]))
        .map(|r| r as u32)
        .collect();
    let (np, ni) = (passive.len(), inact.len());
    let mut gpp = vec![0.0; np * np];
    for (r, &kr) in passive.iter().enumerate() {
        for (s, &ks) in passive.iter().enumerate() {
            gpp[r * np + s] = g.at(kr, ks);
        }
    }
    let l = cholesky(np, &gpp)?;
    let piv = (0..np).map(|r| l[r * np + r]);
    let (lo, hi) = piv.fold((f64::INFINITY, 0.0f64), |(lo, hi), d| {
        (lo.min(d), hi.max(d))
    });
    let kp = if np == 0 { 1.0 } else { hi / lo };
    // X = L^-1 G_PI (np x ni, column by column), S = G_II - X^T X.
    let mut x = vec![0.0; np * ni];
    for (col, &ri) in inact.iter().enumerate() {
        let row = g.row(nz[ri as usize]);
        for r in 0..np {
            let dot: f64 = (0..r).map(|s| l[r * np + s] * x[s * ni + col]).sum();
            x[r * ni + col] = (row[passive[r]] - dot) / l[r * np + r];
        }
    }
    let mut s = vec![0.0; ni * ni];
    for a in 0..ni {
        let ra = g.row(nz[inact[a] as usize]);
        for b in 0..ni {
            let xx: f64 = (0..np).map(|r| x[r * ni + a] * x[r * ni + b]).sum();
            s[a * ni + b] = ra[nz[inact[b] as usize]] - xx;
        }
        if s[a * ni + a].is_nan() || s[a * ni + a] <= 0.0 {
            return None;
        }
    }
    Some((inact, s, kp))
}

/// The gradients `w_i = C_it - C_iP y_P` of the inactive columns `inact` (positions in
/// `nz`) of target `t` at its optimum.
fn inactive_gradients(
    g: crate::nnls::incremental::Cosine<'_>,
    nz: &[usize],
    inact: &[u32],
    st: &ChanState,
    t: usize,
) -> Vec<f64> {
    let (passive, y, _, _) = st.kkt_parts();
    inact
        .iter()
        .map(|&ri| {
            let row = g.row(nz[ri as usize]);
            row[t]
                - passive
                    .iter()
                    .zip(y)
                    .map(|(&k, &yk)| row[k] * yk)
                    .sum::<f64>()
        })
        .collect()
}

/// Targets per register tile, candidates per block, targets per cache tile and
/// candidates per parallel task of [`Screen::bounds`].
const TT: usize = 4;
const CB: usize = 4;
const TB: usize = 64;
const CT: usize = 64;

/// `acc[a][b] = sum_k x[k][a] y[k * lp + t0 + b]` for `k` in order (the sums of
/// [`ChanState::unchanged_adding`]'s gradient, entry by entry).
#[inline(always)]
fn tile(x: &[[f64; CB]], y: &[f64], lp: usize, t0: usize) -> [[f64; TT]; CB] {
    let mut acc = [[0.0f64; TT]; CB];
    for (k, xk) in x.iter().enumerate() {
        let yk: [f64; TT] = y[k * lp + t0..k * lp + t0 + TT].try_into().expect("tile");
        for a in 0..CB {
            for b in 0..TT {
                acc[a][b] += xk[a] * yk[b];
            }
        }
    }
    acc
}

/// One block of [`CB`] candidates of one channel: their positions among the live targets
/// (`usize::MAX`: none), `C_jk` over the basis columns, and per candidate whether it is a
/// zero column, `s2 = 1 - |V_j|^2`, its cosine row, whether the dual bounds apply
/// (non-negative cosines) and the relative rounding of its `d2`.
struct Block<'a> {
    nb: usize,
    own: [usize; CB],
    xg: Vec<[f64; CB]>,
    zero: [bool; CB],
    nc: [f64; CB],
    rows: [&'a [f64]; CB],
    nonneg: [bool; CB],
    ea: [f64; CB],
}

/// One (target, candidate) pair with a positive gradient `w`: `C_ct`, `s2 = 1 - |V_c|^2`,
/// `a_c` and its norm, and whether the dual bounds apply.
struct Pair<'a> {
    w: f64,
    cjt: f64,
    s2: f64,
    arow: &'a [f64],
    /// `64 (p + 1) eps (sqrt(kappa) + kappa |a_c|)`: the absolute rounding scale of `d2`.
    ea: f64,
    nonneg: bool,
}

/// The bound of one pair with a positive gradient (module docs), target `i` of `d`, or
/// `None` when the candidate must not be screened (it is nearly in the span of the
/// target's passive columns, or, without the tight bound's data, of the basis).
///
/// With the data of the tight bound: the best dual point `u = r_t - alpha e - beta z` on
/// the segment from the loose one (`alpha = 0`) to the tight one (`alpha = w / d2`) that is
/// dual feasible on the inactive columns (`w_i - alpha s_i <= TAU`), with `beta = (w -
/// alpha d2) / s2` so that `a_c.u = 0` (`beta = 0` at the tight end); its value is `q_t -
/// f`, `f = 2 alpha w - alpha^2 d2 + (w - alpha d2)^2 / s2` (`|e'|^2` of `u = r_t - e'`,
/// with `e.z = s2`), which falls as `alpha` grows. With `alpha = 0`, or without those data,
/// also the least-squares bound; never below 0.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn pair_bound(
    pr: &Pair<'_>,
    d: &Targets,
    i: usize,
    bs: &Basis,
    (gt, t_col): (&[f64], usize),
    margin_dual: f64,
    xsum: f64,
    (quad, sig): (f64, &[f64]),
) -> f64 {
    let Pair {
        w,
        cjt,
        s2,
        arow,
        ea,
        nonneg,
    } = *pr;
    let q = d.q[i];
    let werr = d.werr[i];
    // Absolute rounding of `1 - |V_x|^2`; `s2` is usable above 16 times it.
    let es2 = bs.e64 * bs.sk;
    let s2_ok = s2 > 16.0 * es2;
    let eps_v = es2 / s2;
    // The least-squares bound (any cosines).
    let ls = |alpha: f64| -> f64 {
        if alpha != 0.0 || !s2_ok {
            return f64::NEG_INFINITY;
        }
        let dv: f64 = arow.iter().zip(&bs.nz).map(|(&x, &k)| x * gt[k]).sum();
        let mm = (cjt - dv).max(0.0);
        1.0 - bs.nrm[t_col] - mm * mm / s2 * (1.0 + 4.0 * eps_v) - MARGIN - 2.0 * es2
    };
    if nonneg && d.tight[i] {
        let (lo, hi) = (d.off[i], d.off[i + 1]);
        let ni = hi - lo;
        let d2 = s2 + quad.max(0.0);
        let inv = 1.0 / d2;
        // `ea / d2` bounds `e64 (sk + kappa |a| sqrt(d2)) / d2` (`d2 <= 1`).
        let eps = ea * inv;
        // The exact value's own rounding (the bordered update's `d2`, module docs).
        let exact_err = 4.0 * bs.e64 * d.kp[i] * inv;
        // `d2 > 0` first: a candidate in the span of the basis can make the rounded `s2`,
        // and `d2` with it, negative.
        if d2 > 0.0 && eps <= EPS_MAX && exact_err <= EPS_MAX {
            let full = w * inv;
            let mut alpha = full;
            let room = &d.room[lo..hi];
            if d.blocked[i] {
                // An inactive column with no room: only the loose end is feasible.
                alpha = 0.0;
            } else if room.iter().zip(&sig[..ni]).fold(false, |hit, (&r, &sk)| {
                hit | (sk < 0.0 && full * (-sk * (1.0 + eps)) > r)
            }) {
                // Some column leaves the full step infeasible: shorten it column by column
                // (without a hit, the loop below leaves `alpha = full`).
                for (&r, &sk) in room.iter().zip(&sig[..ni]) {
                    let push = -sk * (1.0 + eps);
                    if sk < 0.0 && alpha * push > r {
                        alpha = alpha.min(r / push);
                    }
                }
            }
            let f = if alpha == full {
                w * w * inv * (1.0 + 4.0 * eps) + 4.0 * w * werr * inv
            } else if s2_ok {
                let rest = w - alpha * d2;
                (2.0 * alpha * w - alpha * alpha * d2) * (1.0 + 4.0 * eps)
                    + rest * rest / s2 * (1.0 + 4.0 * eps_v)
                    + 4.0 * w * werr / s2
            } else {
                f64::INFINITY
            };
            let dual = q - f - 4.0 * xsum * w * eps - (4.0 * eps + exact_err) * q - margin_dual;
            return dual.max(ls(alpha)).max(0.0);
        }
    }
    // The loose bounds alone: they need `s2` (the exact value's rounding, too, is then
    // below the margins), else 0 (which no computed value is below).
    if s2.is_nan() || s2 < NC_MIN {
        return 0.0;
    }
    let dual = LooseCoef::new(nonneg, s2, es2, xsum).bound(q, w, werr, margin_dual);
    dual.max(ls(0.0)).max(0.0)
}

/// The loose dual bound `q_t - w^2 / s2` of a pair with a positive gradient `w` (module
/// docs), less the rounding of `s2` (relative `eps_v`), of `w` (`werr`) and of the KKT
/// conditions (`margin_dual`); needs non-negative cosines and `s2 >= `[`NC_MIN`]. The
/// definition that [`LooseCoef`], which both levels use, is tested against.
#[cfg(test)]
fn loose_dual(q: f64, w: f64, werr: f64, s2: f64, eps_v: f64, xsum: f64, margin_dual: f64) -> f64 {
    q - w * w / s2 * (1.0 + 4.0 * eps_v)
        - 4.0 * w * werr / s2
        - 4.0 * xsum * w * eps_v
        - margin_dual
}

/// The loose dual bound of [`loose_dual`] for one candidate, as `max(0, q - margin_dual - w
/// (w A + werr B + C))`: built once per candidate, no division per pair (the loose level;
/// the tight level's fallback builds it per pair). `A = (1 + 4 eps_v) / s2`, `B = 4 / s2` and
/// `C = 4 xsum eps_v` are each raised by `16 eps` relative, which covers the rounding of
/// the reciprocal and of the regrouped sum (a few units in the last place of the
/// subtracted term; the `4 eps_v >= 512 eps` of `A` is for the rounding of `s2` itself),
/// so it stays at or below [`loose_dual`]'s value but for the rounding of the last
/// subtraction (units of `q`, inside the margin). Where the bound does not apply (cosines
/// of either sign, `s2 < `[`NC_MIN`]), it is 0.
#[derive(Clone, Copy)]
struct LooseCoef {
    ok: bool,
    a: f64,
    b: f64,
    c: f64,
}

impl LooseCoef {
    /// The coefficients of a candidate with `s2 = 1 - |V_c|^2` (`es2` its absolute
    /// rounding), whether the dual bounds apply to it, and `xsum`.
    #[inline(always)]
    fn new(nonneg: bool, s2: f64, es2: f64, xsum: f64) -> Self {
        let ok = nonneg && s2 >= NC_MIN;
        let up = 1.0 + 16.0 * f64::EPSILON;
        let eps_v = es2 / s2;
        Self {
            ok,
            a: (1.0 + 4.0 * eps_v) / s2 * up,
            b: 4.0 / s2 * up,
            c: 4.0 * xsum * eps_v * up,
        }
    }

    /// The bound of a pair with value `q`, positive gradient `w` of rounding `werr`.
    #[inline(always)]
    fn bound(&self, q: f64, w: f64, werr: f64, margin_dual: f64) -> f64 {
        if self.ok {
            (q - margin_dual - w * (w * self.a + werr * self.b + self.c)).max(0.0)
        } else {
            0.0
        }
    }
}

/// Lower bounds of `S(B + c; T)` for every candidate (`None`: not screened), from the
/// live targets and their states, at either level of [`Screen::bounds`].
#[cfg(test)]
fn lower_bounds(
    obj: &Objective,
    live: &[usize],
    states: &[[ChanState; 3]],
    cols: &[usize],
    candidates: &[usize],
    tight: bool,
) -> Vec<Option<Bound>> {
    match Screen::new(obj, live, states, cols, None, candidates) {
        None => vec![None; candidates.len()],
        Some(mut sc) => {
            let loose = sc.bounds_loose(candidates);
            let b = if tight {
                sc.bounds_tight(candidates)
            } else {
                loose
            };
            b.into_iter().map(Some).collect()
        }
    }
}

/// What one channel state contributes to the test "adding column `j` leaves the optimum as
/// it is" ([`ChanState::unchanged_adding`]) of every `j`: the passive columns, their
/// coefficients and the KKT scale, bit for bit.
#[derive(Clone, Debug, PartialEq)]
struct Print {
    passive: Vec<usize>,
    y: Vec<u64>,
    hmax: u64,
    ysum: u64,
}

impl Print {
    /// The print of an active state.
    fn of(st: &ChanState) -> Self {
        let (passive, y, hmax, ysum) = st.kkt_parts();
        Self {
            passive: passive.to_vec(),
            y: y.iter().map(|v| v.to_bits()).collect(),
            hmax: hmax.to_bits(),
            ysum: ysum.to_bits(),
        }
    }

    /// Whether `st` (active) has this print.
    fn matches(&self, st: &ChanState) -> bool {
        let (passive, y, hmax, ysum) = st.kkt_parts();
        self.passive == passive
            && self.y.iter().copied().eq(y.iter().map(|v| v.to_bits()))
            && self.hmax == hmax.to_bits()
            && self.ysum == ysum.to_bits()
    }
}

/// The signs of one screened step's gradients, carried to the next step of a greedy run:
/// per candidate and channel, as bits over the materials, the live targets whose optimum
/// may change when the candidate is added (gradient above the KKT threshold), with the
/// basis columns and the states they were decided on.
///
/// On the next basis (these columns and more at the end), a target whose state is the same
/// bit for bit (no new column in its passive set) has the same gradients, summed in the same
/// order (the new columns add exact zeros), against the same threshold: the same signs. So
/// the next step computes the gradients of the other targets only, and those of the carried
/// targets' positive pairs one by one; late in a greedy run 70-90% of the states are the
/// same and one pair in ten is positive.
#[derive(Clone, Debug)]
pub(crate) struct GradSigns {
    cols: Vec<usize>,
    /// Per material and channel, the print of its state (`None`: not a live target of an
    /// active channel).
    prints: Vec<[Option<Print>; 3]>,
    words: usize,
    /// Per candidate (material) and channel, `words` words of bits over the materials.
    bits: Vec<u64>,
    /// Per material, whether its rows of `bits` were computed.
    has_row: Vec<bool>,
}

impl GradSigns {
    /// The rows of candidate `cand`, channel after channel.
    fn rows(&self, cand: usize) -> &[u64] {
        &self.bits[cand * 3 * self.words..(cand + 1) * 3 * self.words]
    }
}

/// The data of the bounds of "basis + one candidate" for one basis (its live targets,
/// their states, the projections on the basis), built once and asked for bounds at two
/// levels ([`Screen::bounds_loose`], then [`Screen::bounds_tight`]).
pub(super) struct Screen<'a> {
    obj: &'a Objective,
    live: &'a [usize],
    states: &'a [[ChanState; 3]],
    cols: &'a [usize],
    tg: Vec<Targets>,
    proj: [Basis; 3],
    basis_nonneg: [bool; 3],
    margin_dual: f64,
    xsum: f64,
    /// Per material, its position among the live targets (`usize::MAX`: not live).
    live_pos: Vec<usize>,
    /// Words per row of signs (bits over the materials).
    words: usize,
    /// The signs carried from the previous step (until the loose bounds are computed).
    old: Option<GradSigns>,
    /// Per candidate (material) and channel, the signs of its pairs with the live targets
    /// ([`GradSigns`]' layout; filled by [`Screen::bounds_loose`]).
    bits: Vec<u64>,
    has_row: Vec<bool>,
}

impl<'a> Screen<'a> {
    /// The bounds' data of the live targets and their states on `cols`, with the signs
    /// `old` of an earlier step where they serve (`cols` extends their columns, and each of
    /// `cands` has its rows); `None` when no candidate can be screened (the non-zero basis
    /// columns have no Cholesky factor).
    pub(super) fn new(
        obj: &'a Objective,
        live: &'a [usize],
        states: &'a [[ChanState; 3]],
        cols: &'a [usize],
        old: Option<GradSigns>,
        cands: &[usize],
    ) -> Option<Self> {
        let proj = projections(obj, cols)?;
        let n = obj.len();
        let words = n.div_ceil(64);
        let old = old.filter(|o| {
            o.prints.len() == n
                && o.words == words
                && cols.starts_with(&o.cols)
                && cands.iter().all(|&c| o.has_row[c])
        });
        let nl = live.len();
        let lp = nl.div_ceil(TT) * TT;
        let nk = cols.len();
        let pos: std::collections::HashMap<usize, usize> =
            cols.iter().enumerate().map(|(k, &c)| (c, k)).collect();
        let werr_scale = 4.0 * (nk + 2) as f64 * f64::EPSILON;
        let tg: Vec<Targets> = (0..3)
            .map(|c| {
                let g = obj.view(c);
                let nz = &proj[c].nz;
                let mut d = Targets {
                    yt: vec![0.0; lp * nk],
                    liveact: vec![0; words],
                    keep: vec![0; words],
                    hmax: vec![0.0; lp],
                    ysum: vec![0.0; lp],
                    q: vec![0.0; lp],
                    share: vec![0.0; lp],
                    active: vec![false; lp],
                    werr: vec![0.0; lp],
                    tight: vec![false; lp],
                    blocked: vec![false; lp],
                    kp: vec![0.0; lp],
                    off: vec![0; lp + 1],
                    grp: vec![0; lp],
                    goff: vec![0],
                    gsoff: vec![0],
                    ..Default::default()
                };
                // The passive sets (sorted), each once, in order of first appearance: late in
                // a run a few hundred sets serve thousands of targets.
                let mut ids: std::collections::HashMap<Vec<usize>, u32> = Default::default();
                let mut sets: Vec<Vec<usize>> = Vec::new();
                let tgrp: Vec<Option<u32>> = states
                    .iter()
                    .map(|st| {
                        st[c].is_active().then(|| {
                            let mut set = st[c].kkt_parts().0.to_vec();
                            set.sort_unstable();
                            *ids.entry(set).or_insert_with_key(|set| {
                                sets.push(set.clone());
                                (sets.len() - 1) as u32
                            })
                        })
                    })
                    .collect();
                let sch: Vec<Option<Schur>> =
                    sets.par_iter().map(|set| schur(g, nz, set)).collect();
                // Per group: its position among the groups with the tight bound's data.
                let mut gpos = vec![u32::MAX; sch.len()];
                for (gi, sc) in sch.iter().enumerate() {
                    if let Some((inact, s, _)) = sc {
                        gpos[gi] = (d.goff.len() - 1) as u32;
                        d.inact.extend(inact);
                        d.s.extend(s);
                        d.goff.push(d.inact.len());
                        d.gsoff.push(d.s.len());
                    }
                }
                let wold: Vec<Option<Vec<f64>>> = live
                    .par_iter()
                    .zip(states)
                    .zip(&tgrp)
                    .map(|((&t, st), gr)| {
                        let (inact, _, _) = sch[(*gr)? as usize].as_ref()?;
                        Some(inactive_gradients(g, nz, inact, &st[c], t + 1))
                    })
                    .collect();
                for (i, ((&t, st), (gr, wo))) in live
                    .iter()
                    .zip(states)
                    .zip(tgrp.iter().zip(wold))
                    .enumerate()
                {
                    let ch = &st[c];
                    d.off[i + 1] = d.off[i];
                    if !ch.is_active() {
                        continue;
                    }
                    let (passive, y, hmax, ysum) = ch.kkt_parts();
                    for (&k, &yk) in passive.iter().zip(y) {
                        d.yt[i * nk + pos[&k]] = yk;
                    }
                    let bit = 1u64 << (t % 64);
                    d.liveact[t / 64] |= bit;
                    let carried = old
                        .as_ref()
                        .is_some_and(|o| o.prints[t][c].as_ref().is_some_and(|p| p.matches(ch)));
                    if carried {
                        d.keep[t / 64] |= bit;
                    } else {
                        d.fresh.push(i as u32);
                    }
                    d.hmax[i] = hmax;
                    d.ysum[i] = ysum;
                    d.q[i] = ch.q();
                    d.share[i] = obj.share[t][c];
                    d.active[i] = true;
                    d.werr[i] = werr_scale * (1.0 + ysum);
                    if let (Some(gr), Some(wo)) = (gr, wo) {
                        let gr = *gr as usize;
                        d.tight[i] = true;
                        d.kp[i] = sch[gr].as_ref().map_or(1.0, |sc| sc.2);
                        d.grp[i] = gpos[gr];
                        d.off[i + 1] += wo.len();
                        // The slack of each inactive column's dual feasibility.
                        let werr = d.werr[i];
                        let start = d.room.len();
                        d.room.extend(wo.iter().map(|&w| TAU - werr - w));
                        d.blocked[i] = d.room[start..].iter().any(|&r| r < 0.0);
                    }
                }
                // The fresh targets' coefficients, column-major for the register tiles.
                d.lf = d.fresh.len().div_ceil(TT) * TT;
                d.y = vec![0.0; nk * d.lf];
                for (f, &i) in d.fresh.iter().enumerate() {
                    let yi = &d.yt[i as usize * nk..(i as usize + 1) * nk];
                    for (k, &yk) in yi.iter().enumerate() {
                        d.y[k * d.lf + f] = yk;
                    }
                }
                d.fresh.resize(d.lf, u32::MAX);
                d
            })
            .collect();
        // The dual bounds need non-negative cosines among the columns.
        let basis_nonneg: [bool; 3] = std::array::from_fn(|c| {
            let g = obj.view(c);
            cols.iter()
                .all(|&k| cols.iter().all(|&l| g.at(k, l) >= 0.0))
        });
        let xsum = 2.0 * ((nk + 1) as f64).sqrt();
        let margin_dual = MARGIN * (1.0 + xsum);
        let mut live_pos = vec![usize::MAX; obj.len()];
        for (i, &t) in live.iter().enumerate() {
            live_pos[t] = i;
        }
        Some(Self {
            obj,
            live,
            states,
            cols,
            tg,
            proj,
            basis_nonneg,
            margin_dual,
            xsum,
            live_pos,
            words,
            old,
            bits: Vec::new(),
            has_row: vec![false; n],
        })
    }

    /// The loose level of the bounds of `candidates` (each pair whose optimum may change is
    /// bounded by the loose dual point alone, or 0 where that does not apply: no Schur
    /// complement, no per-pair search, enough to rule most candidates out), and the signs of
    /// their pairs ([`GradSigns`]), which the tight level and [`refine`] read.
    ///
    /// The fresh targets' gradients: candidates in parallel tasks of [`CT`] and blocks of
    /// [`CB`], fresh targets in cache tiles of [`TB`] and register tiles of [`TT`], small
    /// matrix products with each entry summed in the order of the per-pair test, so that
    /// "unchanged" is decided on the very numbers [`ChanState::q_adding`] decides it on. The
    /// carried targets' positive pairs, one by one, from the old signs.
    pub(super) fn bounds_loose(&mut self, candidates: &[usize]) -> Vec<Bound> {
        let out: Vec<(Vec<Vec<f64>>, Vec<u64>)> = candidates
            .par_chunks(CT)
            .map(|task| task_bounds(self, task, false))
            .collect();
        let w3 = 3 * self.words;
        if self.bits.is_empty() {
            self.bits = vec![0; self.obj.len() * w3];
        }
        let mut bounds = Vec::with_capacity(candidates.len());
        for (task, (chunks, rows)) in candidates.chunks(CT).zip(out) {
            for ((&cand, ch), r) in task.iter().zip(chunks).zip(rows.chunks_exact(w3)) {
                self.bits[cand * w3..(cand + 1) * w3].copy_from_slice(r);
                self.has_row[cand] = true;
                bounds.push(self.bound_of(cand, ch));
            }
        }
        self.old = None;
        bounds
    }

    /// The tight level of the bounds of `candidates` (the best of the module docs' bounds
    /// per pair), from the signs of [`Screen::bounds_loose`]: the positive pairs one by one,
    /// in parallel tasks of [`CT`] candidates.
    pub(super) fn bounds_tight(&self, candidates: &[usize]) -> Vec<Bound> {
        candidates
            .par_chunks(CT)
            .flat_map_iter(|task| {
                let (chunks, _) = task_bounds(self, task, true);
                chunks
                    .into_iter()
                    .zip(task)
                    .map(|(ch, &cand)| self.bound_of(cand, ch))
                    .collect::<Vec<_>>()
            })
            .collect()
    }

    /// The [`Bound`] of candidate `cand` from its chunk sums.
    fn bound_of(&self, cand: usize, chunks: Vec<f64>) -> Bound {
        Bound {
            chunks,
            count: self.live.len() - usize::from(self.live_pos[cand] != usize::MAX),
        }
    }

    /// The signs of candidate `cand`'s pairs, channel after channel (`None`: not computed).
    pub(super) fn signs(&self, cand: usize) -> Option<&[u64]> {
        let w3 = 3 * self.words;
        self.has_row[cand].then(|| &self.bits[cand * w3..(cand + 1) * w3])
    }

    /// The signs of this step, to carry to the next ([`GradSigns`]), with the prints of the
    /// live targets' states.
    pub(super) fn into_signs(self) -> GradSigns {
        let mut prints: Vec<[Option<Print>; 3]> = vec![Default::default(); self.obj.len()];
        for (&t, st) in self.live.iter().zip(self.states) {
            prints[t] = std::array::from_fn(|c| st[c].is_active().then(|| Print::of(&st[c])));
        }
        GradSigns {
            cols: self.cols.to_vec(),
            prints,
            words: self.words,
            bits: self.bits,
            has_row: self.has_row,
        }
    }
}

/// The chunk sums of the bounds of one task's candidates and, at the loose level, their
/// rows of signs: with AVX2 where the CPU has it (the same operations, so the same numbers,
/// in wider registers).
fn task_bounds(sc: &Screen<'_>, task: &[usize], tight: bool) -> (Vec<Vec<f64>>, Vec<u64>) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked above).
        return unsafe {
            if tight {
                task_bounds_avx2::<true>(sc, task)
            } else {
                task_bounds_avx2::<false>(sc, task)
            }
        };
    }
    if tight {
        task_bounds_body::<true>(sc, task)
    } else {
        task_bounds_body::<false>(sc, task)
    }
}

/// [`task_bounds_body`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn task_bounds_avx2<const TIGHT: bool>(
    sc: &Screen<'_>,
    task: &[usize],
) -> (Vec<Vec<f64>>, Vec<u64>) {
    task_bounds_body::<TIGHT>(sc, task)
}

/// Asks for the cache lines of `v` (a hint; no effect on any value).
#[inline(always)]
fn prefetch(v: &[f64]) {
    #[cfg(target_arch = "x86_64")]
    for k in (0..v.len()).step_by(8) {
        // SAFETY: a prefetch of an address inside `v` (SSE, in the x86_64 baseline).
        unsafe {
            std::arch::x86_64::_mm_prefetch(
                v.as_ptr().add(k).cast::<i8>(),
                std::arch::x86_64::_MM_HINT_T0,
            );
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = v;
}

/// `sig = S x` for the symmetric `ni x ni` matrix `S` (by its rows, as `axpy`s), and
/// `x . sig`.
#[inline(always)]
fn schur1(sm: &[f64], x: &[f64], sig: &mut [f64]) -> f64 {
    let ni = x.len();
    sig.fill(0.0);
    for (row, &xl) in sm.chunks_exact(ni.max(1)).zip(x) {
        for (sv, &r) in sig.iter_mut().zip(row) {
            *sv += r * xl;
        }
    }
    x.iter().zip(&*sig).map(|(a, b)| a * b).sum()
}

/// Per group of targets with the same passive set ([`Targets`]), per candidate of a task:
/// `a_I . S a_I` and `S a_I` (`1 + ni` values), computed on first use. One arena per task,
/// reused from channel to channel: only the slots used are written.
#[derive(Default)]
struct Memo {
    /// Per group and candidate (`group * CT + candidate`): the offset of its values in
    /// `vals` (`u32::MAX`: not computed yet).
    at: Vec<u32>,
    vals: Vec<f64>,
    x: Vec<f64>,
}

impl Memo {
    /// Forgets every value, for `groups` groups.
    fn reset(&mut self, groups: usize) {
        self.at.clear();
        self.at.resize(groups * CT, u32::MAX);
        self.vals.clear();
    }

    /// `(a_I . S a_I, S a_I)` of candidate `ca` (`< CT`, row `arow` of `a`) for group `gr`
    /// of `d`.
    #[inline(always)]
    fn get(&mut self, d: &Targets, gr: usize, ca: usize, arow: &[f64]) -> (f64, &[f64]) {
        let (lo, hi) = (d.goff[gr], d.goff[gr + 1]);
        let ni = hi - lo;
        let key = gr * CT + ca;
        let mut o = self.at[key] as usize;
        if self.at[key] == u32::MAX {
            o = self.vals.len();
            self.at[key] = u32::try_from(o).expect("memo arena below 2^32 values");
            self.x.clear();
            self.x
                .extend(d.inact[lo..hi].iter().map(|&r| arow[r as usize]));
            let sm = &d.s[d.gsoff[gr]..d.gsoff[gr] + ni * ni];
            self.vals.resize(o + 1 + ni, 0.0);
            let (q, sig) = self.vals[o..].split_first_mut().expect("1 + ni");
            *q = schur1(sm, &self.x, sig);
        }
        (self.vals[o], &self.vals[o + 1..o + 1 + ni])
    }
}

/// Calls `f(ca, i, C_ct, w)` for each pair of a task's candidate `ca` (`rows(ca)`: its bits
/// over the materials) and a live target at position `i` whose bit is set in `mask` (but
/// the candidate's own), with its gradient ([`with_gradients`]): word by word of targets,
/// so that the coefficients of 64 targets stay in cache across the task's candidates, then
/// candidate by candidate (for each candidate, the targets come in increasing order).
#[inline(always)]
fn pairs_by_word<'r>(
    task: &[usize],
    blocks: &[Block<'_>],
    rows: impl Fn(usize) -> &'r [u64],
    mask: &[u64],
    (live, live_pos, yt, nk): (&[usize], &[usize], &[f64], usize),
    ids: &mut Vec<u32>,
    mut f: impl FnMut(usize, usize, f64, f64),
) {
    for (wi, &m) in mask.iter().enumerate() {
        if m == 0 {
            continue;
        }
        // The cosines of the next word's pairs, one row segment per candidate: too many
        // streams for the hardware prefetcher.
        if let Some(&mn) = mask.get(wi + 1) {
            for ca in 0..task.len() {
                let (blk, a) = (&blocks[ca / CB], ca % CB);
                let b = rows(ca)[wi + 1] & mn;
                let row = blk.rows[a];
                for byte in 0..8 {
                    if (b >> (8 * byte)) & 0xff != 0 {
                        // Materials `t..t + 8`: cosines `t + 1..=t + 8`, one or two lines.
                        let t = (wi + 1) * 64 + 8 * byte;
                        let hi = (t + 8).min(row.len() - 1);
                        prefetch(&row[t + 1..=t + 1]);
                        prefetch(&row[hi..=hi]);
                    }
                }
            }
        }
        for (ca, &cand) in task.iter().enumerate() {
            let (blk, a) = (&blocks[ca / CB], ca % CB);
            let mut b = rows(ca)[wi] & m;
            if blk.zero[a] || b == 0 {
                continue;
            }
            ids.clear();
            while b != 0 {
                let t = wi * 64 + b.trailing_zeros() as usize;
                b &= b - 1;
                if t != cand {
                    ids.push(live_pos[t] as u32);
                }
            }
            with_gradients(blk, a, (live, yt, nk), ids, |i, cjt, w| f(ca, i, cjt, w));
        }
    }
}

/// Calls `f(i, C_ct, w)` for each live position `i` of `ids` (target `t`), with the gradient
/// `w = C_ct - sum_k C_ck y_tk` of candidate `a` of `blk` (coefficients `yt`, row-major with
/// `nk` per target), each summed in the order of [`tile`]'s entries (so equal to them bit for
/// bit), four targets at a time.
#[inline(always)]
fn with_gradients(
    blk: &Block<'_>,
    a: usize,
    (live, yt, nk): (&[usize], &[f64], usize),
    ids: &[u32],
    mut f: impl FnMut(usize, f64, f64),
) {
    let row = blk.rows[a];
    let mut quads = ids.chunks_exact(4);
    for q in &mut quads {
        let i: [usize; 4] = std::array::from_fn(|b| q[b] as usize);
        let y: [&[f64]; 4] = std::array::from_fn(|b| &yt[i[b] * nk..(i[b] + 1) * nk]);
        let mut acc = [0.0f64; 4];
        for (k, xk) in blk.xg.iter().enumerate() {
            for b in 0..4 {
                acc[b] += xk[a] * y[b][k];
            }
        }
        for b in 0..4 {
            let cjt = row[live[i[b]] + 1];
            f(i[b], cjt, cjt - acc[b]);
        }
    }
    for &i in quads.remainder() {
        let i = i as usize;
        let mut acc = 0.0;
        for (xk, &yk) in blk.xg.iter().zip(&yt[i * nk..(i + 1) * nk]) {
            acc += xk[a] * yk;
        }
        let cjt = row[live[i] + 1];
        f(i, cjt, cjt - acc);
    }
}

/// A running sum of one candidate's bound adjustments, added to its chunk sum whenever the
/// chunk changes (chunks come in increasing order): each chunk sum takes a few additions,
/// whatever the number of pairs.
struct Acc {
    chunk: usize,
    sum: f64,
}

impl Acc {
    const NONE: Self = Self {
        chunk: usize::MAX,
        sum: 0.0,
    };

    #[inline(always)]
    fn add(&mut self, chunks: &mut [f64], k: usize, v: f64) {
        if k != self.chunk {
            self.flush(chunks);
            self.chunk = k;
        }
        self.sum += v;
    }

    #[inline(always)]
    fn flush(&mut self, chunks: &mut [f64]) {
        if self.chunk != usize::MAX {
            chunks[self.chunk] += self.sum;
        }
        *self = Self::NONE;
    }
}

/// The body of [`task_bounds`], per channel: every chunk sum starts from the `q_t` of its
/// targets (every pair unchanged), and each pair whose optimum may change adds `lb - q_t`.
/// Loose level: the fresh targets' gradients by register tiles (their signs set in the
/// rows), then the carried targets' positive pairs; tight level: every positive pair from
/// the signs ([`Memo`] per passive set and candidate, then [`pair_bound`]).
#[inline(always)]
fn task_bounds_body<const TIGHT: bool>(
    sc: &Screen<'_>,
    task: &[usize],
) -> (Vec<Vec<f64>>, Vec<u64>) {
    let Screen {
        obj,
        live,
        cols,
        ref tg,
        ref proj,
        basis_nonneg,
        margin_dual,
        xsum,
        ref live_pos,
        words,
        ref old,
        ..
    } = *sc;
    let nl = live.len();
    let nk = cols.len();
    let nchunks = nl.div_ceil(CHUNK);
    let nt = task.len();
    let mut chunks = vec![vec![0.0; nchunks]; nt];
    let mut rows: Vec<u64> = if TIGHT {
        Vec::new()
    } else {
        vec![0; nt * 3 * words]
    };
    // Per chunk, the sum of the `q_t` it starts from: every partial sum of the chunk is at
    // most twice it in magnitude, which bounds the rounding of the adjusted sums.
    let mut slack = vec![vec![0.0; nchunks]; nt];
    let mut memo = Memo::default();
    let mut accs: Vec<Acc> = (0..nt).map(|_| Acc::NONE).collect();
    let mut ids: Vec<u32> = Vec::new();
    for (c, d) in tg.iter().enumerate() {
        if TIGHT {
            memo.reset(d.goff.len() - 1);
        }
        let g = obj.view(c);
        let bs = &proj[c];
        let p = bs.nz.len();
        let blocks: Vec<Block<'_>> = task
            .chunks(CB)
            .map(|blk| {
                let nb = blk.len();
                let j: [usize; CB] = std::array::from_fn(|a| blk[a.min(nb - 1)] + 1);
                let xg: Vec<[f64; CB]> = cols
                    .iter()
                    .map(|&k| std::array::from_fn(|a| g.at(j[a], k)))
                    .collect();
                let nc: [f64; CB] = std::array::from_fn(|a| 1.0 - bs.nrm[j[a]]);
                Block {
                    nb,
                    own: std::array::from_fn(|a| live_pos[j[a] - 1]),
                    zero: std::array::from_fn(|a| g.at(j[a], j[a]) == 0.0),
                    nc,
                    rows: std::array::from_fn(|a| g.row(j[a])),
                    nonneg: std::array::from_fn(|a| {
                        basis_nonneg[c] && xg.iter().all(|x| x[a] >= 0.0)
                    }),
                    ea: std::array::from_fn(|a| {
                        let r = &bs.a[j[a] * p..(j[a] + 1) * p];
                        let anorm = r.iter().map(|x| x * x).sum::<f64>().sqrt();
                        bs.e64 * (bs.sk + bs.kappa * anorm)
                    }),
                    xg,
                }
            })
            .collect();
        // Every pair starts at `q_t` (unchanged); a changed pair adds `lb - q_t`.
        let chunk_sum = |k: usize, own: usize| -> f64 {
            let end = ((k + 1) * CHUNK).min(nl);
            (k * CHUNK..end)
                .filter(|&i| i != own && d.active[i])
                .map(|i| d.share[i] * d.q[i])
                .sum()
        };
        let base: Vec<f64> = (0..nchunks).map(|k| chunk_sum(k, usize::MAX)).collect();
        for (ca, ch) in chunks.iter_mut().enumerate() {
            let own = live_pos[task[ca]];
            for (k, (v, sl)) in ch.iter_mut().zip(slack[ca].iter_mut()).enumerate() {
                let b = if own / CHUNK == k {
                    chunk_sum(k, own)
                } else {
                    base[k]
                };
                *v += b;
                *sl += b;
            }
        }
        if TIGHT {
            // Every positive pair, from the signs.
            let rows = |ca: usize| {
                let signs = sc.signs(task[ca]).expect("the loose level first");
                &signs[c * words..(c + 1) * words]
            };
            let data = (live, &live_pos[..], &d.yt[..], nk);
            pairs_by_word(
                task,
                &blocks,
                rows,
                &d.liveact,
                data,
                &mut ids,
                |ca, i, cjt, w| {
                    let (blk, a) = (&blocks[ca / CB], ca % CB);
                    let j = task[ca] + 1;
                    let arow = &bs.a[j * p..(j + 1) * p];
                    let t = live[i];
                    let (quad, sig) = if d.tight[i] {
                        memo.get(d, d.grp[i] as usize, ca, arow)
                    } else {
                        (0.0, &[][..])
                    };
                    let lb = pair_bound(
                        &Pair {
                            w,
                            cjt,
                            s2: blk.nc[a],
                            arow,
                            ea: blk.ea[a],
                            nonneg: blk.nonneg[a],
                        },
                        d,
                        i,
                        bs,
                        (g.row(t + 1), t + 1),
                        margin_dual,
                        xsum,
                        (quad, sig),
                    );
                    accs[ca].add(&mut chunks[ca], i / CHUNK, d.share[i] * (lb - d.q[i]));
                },
            );
            for (acc, ch) in accs.iter_mut().zip(chunks.iter_mut()) {
                acc.flush(ch);
            }
            continue;
        }
        // Per candidate of each block, the loose bound's coefficients ([`LooseCoef`]).
        let coefs: Vec<[LooseCoef; CB]> = blocks
            .iter()
            .map(|blk| {
                std::array::from_fn(|a| {
                    LooseCoef::new(blk.nonneg[a], blk.nc[a], bs.e64 * bs.sk, xsum)
                })
            })
            .collect();
        // The loose bound of one pair with a positive gradient `w`, target `i`, candidate
        // `a` of block `bi`.
        let loose = |bi: usize, a: usize, i: usize, w: f64| -> f64 {
            let q = d.q[i];
            d.share[i] * (coefs[bi][a].bound(q, w, d.werr[i], margin_dual) - q)
        };
        // The carried signs that hold.
        if let Some(o) = old {
            for (ca, &cand) in task.iter().enumerate() {
                let orow = &o.rows(cand)[c * words..(c + 1) * words];
                let nrow = &mut rows[(ca * 3 + c) * words..(ca * 3 + c + 1) * words];
                for ((n, &r), &m) in nrow.iter_mut().zip(orow).zip(&d.keep) {
                    *n = r & m;
                }
            }
        }
        // The fresh targets, by register tiles.
        let (lf, fresh) = (d.lf, &d.fresh);
        let nf = fresh.iter().take_while(|&&i| i != u32::MAX).count();
        for t0 in (0..lf).step_by(TB) {
            let t1 = (t0 + TB).min(lf);
            // The candidates' cosines with the next tile's targets: one stream per
            // candidate, too many for the hardware prefetcher to follow (when the tile's
            // targets lie close together).
            if t1 < nf {
                let lo = live[fresh[t1] as usize] + 1;
                let hi = live[fresh[(t1 + TB).min(nf) - 1] as usize] + 1;
                if hi - lo < 4 * TB {
                    for blk in &blocks {
                        for row in &blk.rows[..blk.nb] {
                            prefetch(&row[lo..=hi]);
                        }
                    }
                }
            }
            for (bi, blk) in blocks.iter().enumerate() {
                for u0 in (t0..t1).step_by(TT) {
                    let gw = tile(&blk.xg, &d.y, lf, u0);
                    let pos: [usize; TT] = std::array::from_fn(|b| fresh[u0 + b] as usize);
                    let valid: u32 = (0..TT).fold(0, |m, b| m | (u32::from(pos[b] < nl) << b));
                    let tix: [usize; TT] =
                        std::array::from_fn(|b| if pos[b] < nl { live[pos[b]] + 1 } else { 0 });
                    // Live targets are increasing: four in a row are one load per row.
                    let run = valid == (1 << TT) - 1 && tix[TT - 1] == tix[0] + (TT - 1);
                    let hm: [f64; TT] =
                        std::array::from_fn(|b| if pos[b] < nl { d.hmax[pos[b]] } else { 0.0 });
                    let ys: [f64; TT] =
                        std::array::from_fn(|b| if pos[b] < nl { d.ysum[pos[b]] } else { 0.0 });
                    for (a, gwa) in gw.iter().enumerate().take(blk.nb) {
                        if blk.zero[a] {
                            continue;
                        }
                        let row = blk.rows[a];
                        let cj: [f64; TT] = if run {
                            row[tix[0]..tix[0] + TT].try_into().expect("tile")
                        } else {
                            std::array::from_fn(|b| row[tix[b]])
                        };
                        let w: [f64; TT] = std::array::from_fn(|b| cj[b] - gwa[b]);
                        let thr: [f64; TT] =
                            std::array::from_fn(|b| KKT_TOL * (hm[b].max(cj[b].abs()) + ys[b]));
                        // Branch-free (about one pair in ten goes on, at random): the pairs
                        // with a positive gradient. Not `>`: a NaN gradient is not
                        // "unchanged", as in the test of `ChanState::q_adding`.
                        #[allow(clippy::neg_cmp_op_on_partial_ord)]
                        let up: [bool; TT] = std::array::from_fn(|b| !(w[b] <= thr[b]));
                        let mut m = up
                            .iter()
                            .enumerate()
                            .fold(0u32, |m, (b, &u)| m | (u32::from(u) << b))
                            & valid;
                        if m == 0 {
                            continue;
                        }
                        let ca = bi * CB + a;
                        let nrow = &mut rows[(ca * 3 + c) * words..(ca * 3 + c + 1) * words];
                        let own = blk.own[a];
                        while m != 0 {
                            let b = m.trailing_zeros() as usize;
                            m &= m - 1;
                            let t = tix[b] - 1;
                            nrow[t / 64] |= 1 << (t % 64);
                            // The candidate's own target does not count.
                            if pos[b] != own {
                                let v = loose(bi, a, pos[b], w[b]);
                                accs[ca].add(&mut chunks[ca], pos[b] / CHUNK, v);
                            }
                        }
                    }
                }
            }
        }
        for (acc, ch) in accs.iter_mut().zip(chunks.iter_mut()) {
            acc.flush(ch);
        }
        // The carried targets' positive pairs.
        if let Some(o) = old {
            let rows = |ca: usize| &o.rows(task[ca])[c * words..(c + 1) * words];
            let data = (live, &live_pos[..], &d.yt[..], nk);
            pairs_by_word(
                task,
                &blocks,
                rows,
                &d.keep,
                data,
                &mut ids,
                |ca, i, _, w| {
                    let v = loose(ca / CB, ca % CB, i, w);
                    accs[ca].add(&mut chunks[ca], i / CHUNK, v);
                },
            );
            for (acc, ch) in accs.iter_mut().zip(chunks.iter_mut()) {
                acc.flush(ch);
            }
        }
    }
    let round = 4.0 * (CHUNK + 1) as f64 * f64::EPSILON;
    for (ch, sl) in chunks.iter_mut().zip(&slack) {
        for (v, &b) in ch.iter_mut().zip(sl) {
            *v = (*v - round * b).max(0.0);
        }
    }
    (chunks, rows)
}

/// Whether candidate `cand` can replace a best of threshold `thr`: its bound, then,
/// chunk by chunk of live targets (those whose bounds claim the largest decrease first),
/// the bound with that chunk's exact values in place of its bounds, until the bound rules
/// it out (`Ok(None)`) or every chunk is exact: then `Ok(Some(score))`, the exact score
/// summed in the order of [`Objective::scores_adding`] (target by target, channel by
/// channel, from 0), so equal to it bit for bit. From the signs of the candidate's pairs
/// ([`Screen::signs`]), a pair whose gradient is not positive takes `q_t` without its
/// gradient: what [`ChanState::q_adding`] returns for it (the same test on the same
/// numbers).
pub(super) fn refine(
    sc: &Screen<'_>,
    cand: usize,
    bound: &Bound,
    thr: Option<f64>,
) -> Result<Option<f64>, crate::select::SelectionError> {
    let Screen {
        obj,
        live,
        states,
        cols,
        ref tg,
        words,
        ..
    } = *sc;
    let signs = sc.signs(cand);
    let unchanged = |t: usize, c: usize| -> bool {
        signs.is_some_and(|s| s[c * words + t / 64] >> (t % 64) & 1 == 0)
    };
    let terms = 3 * live.len();
    if bound.count == 0 {
        return Ok((!ruled_out(f64::INFINITY, terms, thr)).then_some(f64::INFINITY));
    }
    if ruled_out(bound.mean(), terms, thr) {
        return Ok(None);
    }
    // Per chunk: where its exact values go (target by target, channel by channel) and the
    // sum of its `q_t`, from which its bound claims the largest decrease: those chunks are
    // made exact first (any order gives a valid bound; the final sum keeps the order).
    let nch = bound.chunks.len();
    let mut at = Vec::with_capacity(nch + 1);
    at.push(0);
    let mut claimed = Vec::with_capacity(nch);
    for (k, part) in bound.chunks.iter().enumerate() {
        let end = ((k + 1) * CHUNK).min(live.len());
        let (mut n, mut base) = (0, 0.0);
        for (i, &t) in (k * CHUNK..end).zip(&live[k * CHUNK..end]) {
            if t == cand {
                continue;
            }
            for d in tg.iter().filter(|d| d.active[i]) {
                n += 1;
                base += d.share[i] * d.q[i];
            }
        }
        at.push(at[k] + n);
        claimed.push(base - part);
    }
    let mut order: Vec<usize> = (0..nch).collect();
    order.sort_by(|&a, &b| claimed[b].total_cmp(&claimed[a]).then(a.cmp(&b)));
    let mut sum: f64 = bound.chunks.iter().sum();
    let mut values = vec![0.0; at[nch]];
    let mut scratch = crate::nnls::incremental::Scratch::default();
    for (done, &k) in order.iter().enumerate() {
        let end = ((k + 1) * CHUNK).min(live.len());
        let mut exact = 0.0;
        let mut slot = at[k];
        for (i, &t) in (k * CHUNK..end).zip(&live[k * CHUNK..end]) {
            if t == cand {
                continue;
            }
            // `share * q` as `Objective::scores_adding` has it (the screen's copies of
            // `obj.share[t][c]` and `q_t`); the state is read only for a positive pair.
            for (c, d) in tg.iter().enumerate().filter(|(_, d)| d.active[i]) {
                let q = if unchanged(t, c) {
                    d.q[i]
                } else {
                    states[i][c]
                        .q_adding(obj.view(c), cols, cand + 1, t + 1, &mut scratch)
                        .map_err(|e| obj.solve_error(t, c, e))?
                };
                let v = d.share[i] * q;
                exact += v;
                values[slot] = v;
                slot += 1;
            }
        }
        sum += exact - bound.chunks[k];
        // The slack also covers the cancellation of `exact - part` (both below the
        // running sum).
        if done + 1 < nch && ruled_out(sum / bound.count as f64, 3 * terms, thr) {
            return Ok(None);
        }
    }
    let mut total = 0.0;
    for v in values {
        total += v;
    }
    Ok(Some(total / bound.count as f64))
}

/// Largest tie tolerance for which `best_first` orders the exact scores by their bounds
/// (its cutoffs assume a small tolerance); above it, candidates go in collection order.
pub const BEST_FIRST_TOL_MAX: f64 = 1e-6;

/// The cutoff of [`best_first`]: candidates scoring at least this cannot change the chain
/// once a candidate scoring `best` is known (`raise` widens it past a band with a score).
fn cutoff(best: f64, tol: f64, raise: i32) -> f64 {
    (best * (1.0 + 16.0 * tol) + 1e-290) * (1.0 + 4.0 * tol).powi(raise)
}

/// The lower edge of the band below `c` that must hold no known score: with none there, the
/// first candidate (in collection order) below the band replaces whatever the chain holds
/// (every earlier candidate scores at least `c`), and no candidate at or above `c` can
/// replace it or anything after it, so the chain over the known scores is the chain over
/// all of them.
fn band_low(c: f64, tol: f64) -> f64 {
    c * (1.0 - tol) * (1.0 - tol) - 2e-300
}

/// One parallel job's result in [`best_first`]: an exact score (`None`: ruled out) or a
/// task's tight bounds.
enum Done {
    Score(Option<f64>),
    Tight(Vec<Bound>),
}

/// A candidate in [`best_first`]'s queue: its bound, then its position (the lower first).
#[derive(Clone, Copy, PartialEq)]
struct Queued(f64, usize);

impl Eq for Queued {}

impl Ord for Queued {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        // Reversed: `BinaryHeap` is a max-heap.
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}

impl PartialOrd for Queued {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}

/// The exact [`Chain`] over the concatenated candidates of `groups` (the states of each
/// group's basis in `addings`), as `(flat index, score)`, and how many exact scores were
/// computed.
///
/// Best first: candidates are taken in the order of their lower bounds, first the loose
/// ones of [`Screen::bounds`] for all; a candidate taken with a loose bound gets its tight
/// bound (in batches) and goes back in line; one taken with its tight bound is scored
/// exactly (in small parallel batches), each only until its refined bound reaches the
/// cutoff `c = s* (1 + 16 tol)` of the lowest exact score `s*` so far ([`refine`]). The
/// scan ends at the first bound at or above `c`: every candidate left has a score `>= c`
/// (whichever its bound's level), and when no known score lies in `[c (1 - tol)^2, c)`
/// (else `c` is raised and the scan goes on), the chain over the known scores in
/// collection order chooses exactly what the chain over all the scores would
/// ([`band_low`]).
///
/// With one group, `old` are the signs of the previous step of a greedy run (they serve
/// where this basis extends that one), and the signs of this step come back with the result.
pub(super) fn best_first(
    obj: &Objective,
    addings: &[super::Adding],
    groups: &[(&[usize], &[usize])],
    tol: f64,
    old: Option<GradSigns>,
) -> Result<BestFirst, crate::select::SelectionError> {
    let ordered = tol <= BEST_FIRST_TOL_MAX;
    let mut old = if groups.len() == 1 { old } else { None };
    let mut screens: Vec<Option<Screen<'_>>> = addings
        .iter()
        .zip(groups)
        .map(|(a, &(_, cands))| Screen::new(obj, &a.live, &a.states, &a.cols, old.take(), cands))
        .collect();
    // Items: (group, candidate index, bound), the bounds loose (without an order, the
    // bounds only spare candidates no target is left for: any level serves).
    let mut items: Vec<(usize, usize, Option<Bound>)> = Vec::new();
    for (gi, (sc, &(_, cands))) in screens.iter_mut().zip(groups).enumerate() {
        match sc {
            None => items.extend((0..cands.len()).map(|k| (gi, k, None))),
            Some(sc) => items.extend(
                sc.bounds_loose(cands)
                    .into_iter()
                    .enumerate()
                    .map(|(k, b)| (gi, k, Some(b))),
            ),
        }
    }
    let terms: Vec<usize> = addings.iter().map(|a| 3 * a.live.len()).collect();
    // The bound each candidate is ordered by (`-inf`: not screened).
    let order_key = |g: usize, b: &Option<Bound>| match b {
        None => f64::NEG_INFINITY,
        Some(b) => {
            let m = b.mean();
            let slack = (terms[g] as f64 + 16.0) * f64::EPSILON;
            m - slack * m.abs()
        }
    };
    // Whether a candidate's bound is final (tight, or not screened, or no order).
    let mut tight: Vec<bool> = items
        .iter()
        .map(|(_, _, b)| !ordered || b.is_none())
        .collect();
    let mut queue: std::collections::BinaryHeap<Queued> = items
        .iter()
        .enumerate()
        .map(|(i, (g, _, b))| Queued(if ordered { order_key(*g, b) } else { 0.0 }, i))
        .collect();
    // Exact score per item (`None`: not known); items ruled out at cutoff `c` (score >= c).
    // A candidate no target is left for scores `+inf` (no exact work).
    let mut known: Vec<Option<f64>> = items
        .iter()
        .map(|(_, _, b)| match b {
            Some(b) if b.count == 0 => Some(f64::INFINITY),
            _ => None,
        })
        .collect();
    let mut ruled: Vec<(usize, f64)> = Vec::new();
    let mut evaluated = 0;
    let mut s_best = f64::INFINITY;
    let mut raise = 0;
    let batch = (2 * rayon::current_num_threads()).max(4);
    // Candidates made tight at a time: a few tasks per thread.
    let up_batch = 2 * CT * rayon::current_num_threads();
    loop {
        let c = if ordered {
            cutoff(s_best, tol, raise)
        } else {
            f64::INFINITY
        };
        let mut todo: Vec<usize> = Vec::new();
        // Ruled out at a lower cutoff than the present one: scored again.
        ruled.retain(|&(i, at)| {
            if at < c {
                todo.push(i);
                false
            } else {
                true
            }
        });
        let mut up: Vec<usize> = Vec::new();
        while todo.len() < batch && up.len() < up_batch {
            match queue.peek() {
                Some(&Queued(l, i)) if l < c => {
                    queue.pop();
                    if known[i].is_some() {
                        continue;
                    }
                    if tight[i] {
                        todo.push(i);
                    } else {
                        up.push(i);
                    }
                }
                _ => break,
            }
        }
        if todo.is_empty() && up.is_empty() {
            if !ordered || s_best == f64::INFINITY {
                break;
            }
            let low = band_low(c, tol);
            if known.iter().flatten().any(|&s| s >= low && s < c) {
                raise += 1;
                continue;
            }
            break;
        }
        // Tight bounds (per group, in tasks of [`CT`]) and exact scores, in one parallel
        // pass: the scores' durations vary widely, the tasks fill the gaps.
        up.sort_unstable();
        let tasks: Vec<&[usize]> = up
            .chunk_by(|&a, &b| items[a].0 == items[b].0)
            .flat_map(|run| run.chunks(CT))
            .collect();
        let out: Vec<Done> = {
            let tighten = |task: &[usize]| -> Vec<Bound> {
                let g = items[task[0]].0;
                let sc = screens[g].as_ref().expect("a loose bound has its screen");
                let cands: Vec<usize> = task.iter().map(|&i| groups[g].1[items[i].1]).collect();
                sc.bounds_tight(&cands)
            };
            let score = |i: usize| -> Result<Option<f64>, crate::select::SelectionError> {
                let (g, k, b) = &items[i];
                let a = &addings[*g];
                let cand = groups[*g].1[*k];
                match b {
                    None => Ok(Some(obj.exact_scores(a, &[cand])?[0])),
                    Some(b) => refine(
                        screens[*g].as_ref().expect("a bound has its screen"),
                        cand,
                        b,
                        c.is_finite().then_some(c),
                    ),
                }
            };
            (0..todo.len() + tasks.len())
                .into_par_iter()
                .map(|k| match todo.get(k) {
                    Some(&i) => score(i).map(Done::Score),
                    None => Ok(Done::Tight(tighten(tasks[k - todo.len()]))),
                })
                .collect::<Result<_, _>>()?
        };
        let mut out = out.into_iter();
        for (&i, s) in todo.iter().zip(out.by_ref()) {
            match s {
                Done::Score(Some(s)) => {
                    evaluated += 1;
                    known[i] = Some(s);
                    s_best = s_best.min(s);
                }
                Done::Score(None) => ruled.push((i, c)),
                Done::Tight(_) => unreachable!("scores come first"),
            }
        }
        for (task, d) in tasks.iter().zip(out) {
            let Done::Tight(bs) = d else {
                unreachable!("tight bounds come last")
            };
            for (&i, b) in task.iter().zip(bs) {
                let b = Some(b);
                queue.push(Queued(order_key(items[i].0, &b), i));
                items[i].2 = b;
                tight[i] = true;
            }
        }
    }
    let mut chain = Chain::new(tol);
    for (i, s) in known.iter().enumerate() {
        if let Some(s) = *s {
            chain.offer(i, s);
        }
    }
    let signs = match (groups.len(), screens.pop()) {
        (1, Some(Some(sc))) => Some(sc.into_signs()),
        _ => None,
    };
    Ok(BestFirst {
        best: chain.best(),
        evaluated,
        signs,
    })
}

/// The outcome of [`best_first`]: the winner (flat index) and its score, the number of
/// exact scores computed, and (one group) the signs of this step.
pub(super) struct BestFirst {
    pub best: Option<(usize, f64)>,
    pub evaluated: usize,
    pub signs: Option<GradSigns>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::cpu::CpuBackend;
    use crate::collection::Collection;
    use crate::select::objective::argmin;
    use crate::select::objective::ObjectiveParams;

    /// Asserts that every candidate's bound, loose and tight, is at most its exact score for
    /// `basis`, and returns how many tight bounds exceed the best exact score (rule their
    /// candidate out) and the number of candidates.
    fn bounds_below_exact(obj: &Objective, basis: &[usize], all: &[usize]) -> (usize, usize) {
        let cands: Vec<usize> = all.iter().copied().filter(|c| !basis.contains(c)).collect();
        let a = obj.adding(basis, all).expect("states");
        let exact = obj.exact_scores(&a, &cands).expect("exact");
        let best = exact.iter().copied().fold(f64::INFINITY, f64::min);
        let mut out = 0;
        for tight in [false, true] {
            let lbs: Vec<f64> = lower_bounds(obj, &a.live, &a.states, &a.cols, &cands, tight)
                .iter()
                .map(|b| b.as_ref().map_or(f64::NEG_INFINITY, Bound::mean))
                .collect();
            for ((&c, &lb), &s) in cands.iter().zip(&lbs).zip(&exact) {
                assert!(
                    lb <= s,
                    "basis {basis:?}, candidate {c}, tight {tight}: bound {lb} > exact {s}"
                );
            }
            out = lbs.iter().filter(|&&lb| lb > best).count();
        }
        (out, cands.len())
    }

    #[test]
    fn the_chain_is_the_argmin_of_the_search() {
        let tol = 1e-12;
        let cases: [&[f64]; 5] = [
            &[1.0, 1.0 - 1e-15, 0.5, 0.5],
            &[1.0, 1.0 - 0.6e-12, 1.0 - 1.2e-12],
            &[f64::INFINITY, 3.0, 3.0, 2.0],
            &[0.0, 0.0, 1.0],
            &[],
        ];
        for s in cases {
            let mut c = Chain::new(tol);
            for (i, &v) in s.iter().enumerate() {
                c.offer(i, v);
            }
            assert_eq!(c.best().map(|b| b.0), argmin(s, tol), "{s:?}");
        }
    }

    #[test]
    fn the_bounds_never_exceed_the_exact_scores() {
        let coll = Collection::embedded_default();
        let p = ObjectiveParams::default().stride(2).check().expect("p");
        let obj = Objective::new(&CpuBackend::new(), &coll, &p, &|_, _| {}).expect("obj");
        let all: Vec<usize> = (0..coll.len()).collect();
        let mut screened = 0;
        for basis in [
            vec![],
            vec![3],
            vec![3, 17, 40],
            vec![1, 5, 9, 22, 30, 44, 51],
        ] {
            screened += bounds_below_exact(&obj, &basis, &all).0;
        }
        // Not a bound that cannot screen: some candidates are ruled out.
        assert!(screened > 0);
    }

    /// The objective of a 300-material synthetic collection (stride 4) and its materials.
    fn synthetic_300() -> (Objective, Vec<usize>) {
        let coll = crate::collection::synthetic(300, 2016);
        let p = ObjectiveParams::default().stride(4).check().expect("p");
        let obj = Objective::new(&CpuBackend::new(), &coll, &p, &|_, _| {}).expect("obj");
        (obj, (0..coll.len()).collect())
    }

    #[test]
    fn carried_signs_are_the_signs_computed_afresh() {
        // Step by step through a greedy run: the signs and bounds of a screen that carries
        // the previous step's signs equal those of a screen that computes them all.
        let (obj, all) = synthetic_300();
        let mut basis: Vec<usize> = Vec::new();
        let mut signs: Option<GradSigns> = None;
        let mut carried_total = 0;
        for step in 0..12 {
            let cands: Vec<usize> = all.iter().copied().filter(|c| !basis.contains(c)).collect();
            let a = obj.adding(&basis, &all).expect("states");
            let mut fresh =
                Screen::new(&obj, &a.live, &a.states, &a.cols, None, &cands).expect("screen");
            let mut carry = Screen::new(&obj, &a.live, &a.states, &a.cols, signs.take(), &cands)
                .expect("screen");
            let carried: usize = carry
                .tg
                .iter()
                .map(|d| {
                    d.keep
                        .iter()
                        .map(|w| w.count_ones() as usize)
                        .sum::<usize>()
                })
                .sum();
            carried_total += carried;
            let (lf, lc) = (fresh.bounds_loose(&cands), carry.bounds_loose(&cands));
            let (tf, tc) = (fresh.bounds_tight(&cands), carry.bounds_tight(&cands));
            for (k, &c) in cands.iter().enumerate() {
                assert_eq!(fresh.signs(c), carry.signs(c), "step {step}, candidate {c}");
                for (x, y) in [(&lf[k], &lc[k]), (&tf[k], &tc[k])] {
                    let (x, y) = (x.mean(), y.mean());
                    assert!(
                        (x - y).abs() <= 1e-13 * x.abs().max(1e-300),
                        "step {step}, candidate {c}: {x} {y}"
                    );
                }
            }
            // The carried screen's signs go on; the step adds the exhaustive choice.
            signs = Some(carry.into_signs());
            let scores = obj.exact_scores(&a, &cands).expect("exact");
            basis.push(cands[argmin(&scores, 1e-12).expect("a candidate")]);
        }
        // Most states carry over late in the run: the carried path is exercised.
        assert!(carried_total > 1000, "{carried_total}");
    }

    #[test]
    fn late_greedy_steps_are_bounded_validly_and_tightly() {
        // Late in a greedy run most candidates lie close to the span of the basis: the
        // bounds must stay below every exact score and still rule most candidates out.
        let (obj, all) = synthetic_300();
        // The greedy basis, step by step (the chain of every step, as the greedy takes it).
        let mut full: Vec<usize> = Vec::new();
        for _ in 0..15 {
            let cands: Vec<usize> = all.iter().copied().filter(|c| !full.contains(c)).collect();
            let r = obj
                .best_of_groups(&[(full.as_slice(), cands.as_slice())], &all, 1e-12, None)
                .expect("step");
            full.push(cands[r.best.expect("a candidate").0]);
        }
        for k in [4, 10, 15] {
            let basis = &full[..k];
            let (out, cands) = bounds_below_exact(&obj, basis, &all);
            assert!(
                out * 4 >= cands * 3,
                "k {k}: only {out} of {cands} candidates ruled out"
            );
        }
    }

    #[test]
    fn loose_coefficients_bound_below_the_loose_dual_formula_and_as_tightly() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (mut n, mut ok) = (0, 0);
        for _ in 0..200_000 {
            let p = rng.random_range(1..=24usize);
            let e64 = 64.0 * (p + 1) as f64 * f64::EPSILON;
            let sk = 10f64.powf(rng.random_range(0.0..4.0));
            let es2 = e64 * sk;
            let s2 = 10f64.powf(rng.random_range(-4.5..0.0));
            let nonneg = rng.random_bool(0.9);
            let q = 10f64.powf(rng.random_range(-8.0..0.0));
            let w = q.sqrt() * s2.sqrt() * rng.random_range(0.0..1.5);
            let ysum = rng.random_range(0.0..30.0);
            let werr = 4.0 * (p + 2) as f64 * f64::EPSILON * (1.0 + ysum);
            let xsum = 2.0 * ((p + 1) as f64).sqrt();
            let md = MARGIN * (1.0 + xsum);
            let new = LooseCoef::new(nonneg, s2, es2, xsum).bound(q, w, werr, md);
            let old = if nonneg && s2 >= NC_MIN {
                loose_dual(q, w, werr, s2, es2 / s2, xsum, md).max(0.0)
            } else {
                0.0
            };
            // Never above the formula (a valid bound wherever it is) but by the rounding of
            // the last subtraction (two units of `q`, far inside the `1e-10` margin both
            // subtract), and below it by no more than the extra 16 eps of the coefficients
            // on the subtracted term.
            assert!(new <= old + 2.0 * f64::EPSILON * q, "{new} > {old}");
            assert!(
                old - new <= 64.0 * f64::EPSILON * q.max(w * w / s2),
                "{new} << {old}"
            );
            n += 1;
            ok += usize::from(new > 0.0);
        }
        assert!(
            ok > n / 10,
            "the positive bounds were exercised: {ok} of {n}"
        );
    }
}
