//! The bounds of the screen: the projections of a basis, the targets' Schur complements
//! and inactive gradients, and the lower bound of one (candidate, target) pair at the loose
//! and the tight level.

use super::*;

/// One channel's basis: its non-zero columns `nz` (`p` of them), per column `x` of the
/// matrix `|V_x|^2` and `a_x = G^-1 C_{nz,x}` (`m x p`, row `x`), and the relative rounding
/// scale `64 (p + 1) eps kappa` of `a` and `1 - |V_x|^2` (kappa: the squared ratio of the
/// extreme pivots of `L`, an estimate of the condition number of `G`).
#[derive(Default)]
pub(super) struct Basis {
    pub(super) nz: Vec<usize>,
    pub(super) nrm: Vec<f64>,
    pub(super) a: Vec<f64>,
    pub(super) e64: f64,
    pub(super) sk: f64,
    pub(super) kappa: f64,
}

/// Per channel, the [`Basis`] of `cols`, or `None` when the non-zero basis columns have no
/// Cholesky factor.
pub(super) fn projections(obj: &Objective, cols: &[usize]) -> Option<[Basis; 3]> {
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
pub(super) struct Targets {
    pub(super) y: Vec<f64>,
    pub(super) yt: Vec<f64>,
    pub(super) fresh: Vec<u32>,
    pub(super) lf: usize,
    pub(super) liveact: Vec<u64>,
    pub(super) keep: Vec<u64>,
    pub(super) hmax: Vec<f64>,
    pub(super) ysum: Vec<f64>,
    pub(super) q: Vec<f64>,
    pub(super) share: Vec<f64>,
    pub(super) active: Vec<bool>,
    pub(super) werr: Vec<f64>,
    pub(super) tight: Vec<bool>,
    pub(super) kp: Vec<f64>,
    pub(super) off: Vec<usize>,
    pub(super) room: Vec<f64>,
    pub(super) blocked: Vec<bool>,
    pub(super) grp: Vec<u32>,
    pub(super) goff: Vec<usize>,
    pub(super) gsoff: Vec<usize>,
    pub(super) inact: Vec<u32>,
    pub(super) s: Vec<f64>,
}

/// The tight bound's data of one passive set: inactive positions, `S_t` and the square
/// root of the condition estimate of `G_PP` (squared ratio of its extreme Cholesky
/// pivots).
pub(super) type Schur = (Vec<u32>, Vec<f64>, f64);

/// The tight bound's data of the targets whose passive set is `passive` ([`Targets`]):
/// inactive positions in `nz` and `S_t`; `None` when a passive column is not in `nz` or
/// `G_PP` or `S_t` has no positive pivots.
pub(super) fn schur(
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
pub(super) fn inactive_gradients(
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

/// One block of [`CB`] candidates of one channel: their positions among the live targets
/// (`usize::MAX`: none), `C_jk` over the basis columns, and per candidate whether it is a
/// zero column, `s2 = 1 - |V_j|^2`, its cosine row, whether the dual bounds apply
/// (non-negative cosines) and the relative rounding of its `d2`.
pub(super) struct Block<'a> {
    pub(super) nb: usize,
    pub(super) own: [usize; CB],
    pub(super) xg: Vec<[f64; CB]>,
    pub(super) zero: [bool; CB],
    pub(super) nc: [f64; CB],
    pub(super) rows: [&'a [f64]; CB],
    pub(super) nonneg: [bool; CB],
    pub(super) ea: [f64; CB],
}

/// One (target, candidate) pair with a positive gradient `w`: `C_ct`, `s2 = 1 - |V_c|^2`,
/// `a_c` and its norm, and whether the dual bounds apply.
pub(super) struct Pair<'a> {
    pub(super) w: f64,
    pub(super) cjt: f64,
    pub(super) s2: f64,
    pub(super) arow: &'a [f64],
    /// `64 (p + 1) eps (sqrt(kappa) + kappa |a_c|)`: the absolute rounding scale of `d2`.
    pub(super) ea: f64,
    pub(super) nonneg: bool,
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
pub(super) fn pair_bound(
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
pub(super) fn loose_dual(
    q: f64,
    w: f64,
    werr: f64,
    s2: f64,
    eps_v: f64,
    xsum: f64,
    margin_dual: f64,
) -> f64 {
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
pub(super) struct LooseCoef {
    pub(super) ok: bool,
    pub(super) a: f64,
    pub(super) b: f64,
    pub(super) c: f64,
}

impl LooseCoef {
    /// The coefficients of a candidate with `s2 = 1 - |V_c|^2` (`es2` its absolute
    /// rounding), whether the dual bounds apply to it, and `xsum`.
    #[inline(always)]
    pub(super) fn new(nonneg: bool, s2: f64, es2: f64, xsum: f64) -> Self {
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
    pub(super) fn bound(&self, q: f64, w: f64, werr: f64, margin_dual: f64) -> f64 {
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
pub(super) fn lower_bounds(
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
