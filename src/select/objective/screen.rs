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
//! The bound, per target `t`, channel and candidate `c`:
//! * when adding `c` leaves the optimum as it is ([`ChanState::unchanged_adding`]: no
//!   positive gradient), the exact value is the current `q_t`, bit for bit;
//! * otherwise the NNLS residual on `B + c` is at least the least-squares residual on the
//!   span of `B + c` with a non-negative coefficient on `c`:
//!   `q >= 1 - |V_t|^2 - max(0, C_ct - V_c . V_t)^2 / (1 - |V_c|^2)`, with `V = L^-1 C_B.`
//!   (`L L^T = C_BB` over the non-zero basis columns), less [`MARGIN`] for rounding.
//!
//! * and, when the cosines among the columns of `B + c` are non-negative (as those of
//!   non-negative BRDFs are), at least the value of the dual NNLS problem at
//!   `u = r_t - (w / s2) z`, with `r_t` the residual of the optimum on `B`, `w` the gradient
//!   of `c`, `z` the part of column `c` orthogonal to the span of `B` and `s2 = |z|^2 = 1 -
//!   |V_c|^2`: `u` is dual feasible (`A_B^T u = A_B^T r_t <= 0` by the KKT conditions of the
//!   optimum, `a_c^T u = 0`), so `q >= 2 b.u - |u|^2 = q_t - w^2 / s2`. The KKT conditions
//!   hold to Lawson-Hanson's tolerance (~1e-11) and the coefficients of a fit with
//!   non-negative cosines sum to at most `2 sqrt(p)`, hence a margin of `MARGIN (1 + 2
//!   sqrt(p))`. Unlike the least-squares bound, it starts from the NNLS residual `q_t`.
//!
//! A candidate nearly in the span of the basis (`1 - |V_c|^2 < `[`NC_MIN`], where the
//! bordered update loses digits) is never screened, and neither is any candidate when
//! `C_BB` has no Cholesky factor. The bound costs `O(p)` per target and candidate against
//! the exact `O(p^2)`.

use super::Objective;
use crate::nnls::incremental::{cholesky, ChanState, KKT_TOL};
use rayon::prelude::*;

/// Absolute slack subtracted from each target's least-squares bound: far above the
/// rounding of the bound and of the exact value (both ~1e-15 relative on values <= 1).
pub const MARGIN: f64 = 1e-10;
/// Smallest squared sine between a candidate and the span of the basis for which the
/// least-squares bound is used.
pub const NC_MIN: f64 = 1e-4;

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

/// One channel's projections: the number `p` of non-zero basis columns, `V^T` (`m x p`)
/// and `|V_x|^2` per column.
type Projection = (usize, Vec<f64>, Vec<f64>);

/// Per channel: `V^T` (`m x p`, row `x` = `V_x`) and `|V_x|^2`, or `None` when the
/// non-zero basis columns have no Cholesky factor.
fn projections(obj: &Objective, cols: &[usize]) -> Option<[Projection; 3]> {
    let m = obj.len() + 1;
    let mut out: [Projection; 3] = Default::default();
    for (c, o) in out.iter_mut().enumerate() {
        let g = obj.view(c);
        let nz: Vec<usize> = cols.iter().copied().filter(|&k| g.at(k, k) > 0.0).collect();
        let p = nz.len();
        let mut a = vec![0.0; p * p];
        for (r, &kr) in nz.iter().enumerate() {
            for (s, &ks) in nz.iter().enumerate() {
                a[r * p + s] = g.at(kr, ks);
            }
        }
        let l = cholesky(p, &a)?;
        let mut vt = vec![0.0; m * p];
        let rows: Vec<&[f64]> = nz.iter().map(|&k| g.row(k)).collect();
        vt.par_chunks_mut(p.max(1)).enumerate().for_each(|(x, v)| {
            for r in 0..p {
                let dot: f64 = (0..r).map(|s| l[r * p + s] * v[s]).sum();
                v[r] = (rows[r][x] - dot) / l[r * p + r];
            }
        });
        let nrm: Vec<f64> = if p == 0 {
            vec![0.0; m]
        } else {
            vt.chunks(p)
                .map(|v| v.iter().map(|a| a * a).sum())
                .collect()
        };
        *o = (p, vt, nrm);
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

/// Per channel, the live targets' data of the bounds, laid out for [`lower_bounds`]'s
/// tiles: coefficient matrix `y` (`cols x lp`, column-major by target: entry `k * lp + t`,
/// zero outside the passive set), `V` (`p x lp`), and per target the KKT scale, `q`,
/// `|V_t|^2`, share and whether the channel counts.
struct Targets {
    y: Vec<f64>,
    v: Vec<f64>,
    hmax: Vec<f64>,
    ysum: Vec<f64>,
    q: Vec<f64>,
    nrm: Vec<f64>,
    share: Vec<f64>,
    active: Vec<bool>,
}

/// Targets per register tile and candidates per block of [`lower_bounds`].
const TT: usize = 4;
const CB: usize = 4;

/// `acc[a][b] = sum_k x[k][a] y[k * lp + t0 + b]` for `k` in order (the sums of
/// [`ChanState::unchanged_adding`]'s gradient and of the projections, entry by entry).
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

/// Lower bounds of `S(B + c; T)` for every candidate (`None`: not screened), from the
/// live targets and their states (module docs). Candidates in blocks of [`CB`], live
/// targets in tiles of [`TT`]: the gradients and projections of a block are small matrix
/// products, each entry summed in the order of the per-pair test, so that "unchanged" is
/// decided on the very numbers [`ChanState::q_adding`] decides it on.
pub(super) fn lower_bounds(
    obj: &Objective,
    live: &[usize],
    states: &[[ChanState; 3]],
    cols: &[usize],
    candidates: &[usize],
) -> Vec<Option<Bound>> {
    let Some(proj) = projections(obj, cols) else {
        return vec![None; candidates.len()];
    };
    let nl = live.len();
    let lp = nl.div_ceil(TT) * TT;
    let nk = cols.len();
    let pos: std::collections::HashMap<usize, usize> =
        cols.iter().enumerate().map(|(k, &c)| (c, k)).collect();
    let tg: Vec<Targets> = (0..3)
        .map(|c| {
            let (p, vt, nrm) = &proj[c];
            let p = *p;
            let mut d = Targets {
                y: vec![0.0; nk * lp],
                v: vec![0.0; p * lp],
                hmax: vec![0.0; lp],
                ysum: vec![0.0; lp],
                q: vec![0.0; lp],
                nrm: vec![0.0; lp],
                share: vec![0.0; lp],
                active: vec![false; lp],
            };
            for (i, (&t, st)) in live.iter().zip(states).enumerate() {
                let ch = &st[c];
                if !ch.is_active() {
                    continue;
                }
                let (passive, y, hmax, ysum) = ch.kkt_parts();
                for (&k, &yk) in passive.iter().zip(y) {
                    d.y[pos[&k] * lp + i] = yk;
                }
                for r in 0..p {
                    d.v[r * lp + i] = vt[(t + 1) * p + r];
                }
                d.hmax[i] = hmax;
                d.ysum[i] = ysum;
                d.q[i] = ch.q();
                d.nrm[i] = nrm[t + 1];
                d.share[i] = obj.share[t][c];
                d.active[i] = true;
            }
            d
        })
        .collect();
    // The dual bound (module docs) needs non-negative cosines among the columns.
    let basis_nonneg: [bool; 3] = std::array::from_fn(|c| {
        let g = obj.view(c);
        cols.iter()
            .all(|&k| cols.iter().all(|&l| g.at(k, l) >= 0.0))
    });
    let margin_dual = MARGIN * (1.0 + 2.0 * ((nk + 1) as f64).sqrt());
    let nchunks = nl.div_ceil(CHUNK);
    let mut is_live = vec![false; obj.len()];
    for &t in live {
        is_live[t] = true;
    }
    candidates
        .par_chunks(CB)
        .flat_map_iter(|blk| {
            let nb = blk.len();
            let mut chunks = vec![vec![0.0; nchunks]; nb];
            let mut none = [false; CB];
            for (c, d) in tg.iter().enumerate() {
                let g = obj.view(c);
                let (p, vt, nrm) = &proj[c];
                let p = *p;
                let j: [usize; CB] = std::array::from_fn(|a| blk[a.min(nb - 1)] + 1);
                let xg: Vec<[f64; CB]> = cols
                    .iter()
                    .map(|&k| std::array::from_fn(|a| g.at(j[a], k)))
                    .collect();
                let xv: Vec<[f64; CB]> = (0..p)
                    .map(|r| std::array::from_fn(|a| vt[j[a] * p + r]))
                    .collect();
                let zero: [bool; CB] = std::array::from_fn(|a| g.at(j[a], j[a]) == 0.0);
                let nc: [f64; CB] = std::array::from_fn(|a| 1.0 - nrm[j[a]]);
                let rows: [&[f64]; CB] = std::array::from_fn(|a| g.row(j[a]));
                let nonneg: [bool; CB] =
                    std::array::from_fn(|a| basis_nonneg[c] && xg.iter().all(|x| x[a] >= 0.0));
                for t0 in (0..nl).step_by(TT) {
                    let gw = tile(&xg, &d.y, lp, t0);
                    let dv = tile(&xv, &d.v, lp, t0);
                    for b in 0..TT.min(nl - t0) {
                        let i = t0 + b;
                        if !d.active[i] {
                            continue;
                        }
                        let t = live[i];
                        for a in 0..nb {
                            if t + 1 == j[a] || none[a] {
                                continue;
                            }
                            let cjt = rows[a][t + 1];
                            let w = cjt - gw[a][b];
                            let lb = if zero[a]
                                || w <= KKT_TOL * (d.hmax[i].max(cjt.abs()) + d.ysum[i])
                            {
                                d.q[i]
                            } else if nc[a].is_nan() || nc[a] < NC_MIN {
                                none[a] = true;
                                continue;
                            } else {
                                let mm = (cjt - dv[a][b]).max(0.0);
                                let ls = 1.0 - d.nrm[i] - mm * mm / nc[a] - MARGIN;
                                let dual = if nonneg[a] {
                                    d.q[i] - w * w / nc[a] - margin_dual
                                } else {
                                    f64::NEG_INFINITY
                                };
                                ls.max(dual).max(0.0)
                            };
                            chunks[a][i / CHUNK] += d.share[i] * lb;
                        }
                    }
                }
            }
            let mut out = Vec::with_capacity(nb);
            for (a, ch) in chunks.into_iter().enumerate() {
                out.push((!none[a]).then(|| Bound {
                    chunks: ch,
                    count: nl - usize::from(is_live[blk[a]]),
                }));
            }
            out
        })
        .collect()
}

/// Whether candidate `cand` can replace a best of threshold `thr`: its bound, then,
/// chunk by chunk of live targets, the bound with that chunk's exact values in place of
/// its bounds, until the bound rules it out (`Ok(None)`) or every chunk is exact: then
/// `Ok(Some(score))`, the exact score summed in the order of
/// [`Objective::scores_adding`] (target by target, channel by channel, from 0), so equal
/// to it bit for bit.
pub(super) fn refine(
    obj: &Objective,
    live: &[usize],
    states: &[[ChanState; 3]],
    cols: &[usize],
    cand: usize,
    bound: &Bound,
    thr: Option<f64>,
) -> Result<Option<f64>, crate::select::SelectionError> {
    let terms = 3 * live.len();
    if bound.count == 0 {
        return Ok((!ruled_out(f64::INFINITY, terms, thr)).then_some(f64::INFINITY));
    }
    if ruled_out(bound.mean(), terms, thr) {
        return Ok(None);
    }
    let mut sum: f64 = bound.chunks.iter().sum();
    let mut values = Vec::with_capacity(terms);
    let mut scratch = Vec::new();
    for (k, part) in bound.chunks.iter().enumerate() {
        let end = ((k + 1) * CHUNK).min(live.len());
        let mut exact = 0.0;
        for (&t, st) in live[k * CHUNK..end].iter().zip(&states[k * CHUNK..end]) {
            if t == cand {
                continue;
            }
            for (c, ch) in st.iter().enumerate() {
                if ch.is_active() {
                    let q = ch
                        .q_adding(obj.view(c), cols, cand + 1, t + 1, &mut scratch)
                        .map_err(|e| obj.solve_error(t, c, e))?;
                    let v = obj.share[t][c] * q;
                    exact += v;
                    values.push(v);
                }
            }
        }
        sum += exact - part;
        // The slack also covers the cancellation of `exact - part` (both below the
        // running sum).
        if k + 1 < bound.chunks.len() && ruled_out(sum / bound.count as f64, 3 * terms, thr) {
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

/// The exact [`Chain`] over the concatenated candidates of `groups` (the states of each
/// group's basis in `addings`), as `(flat index, score)`, and how many exact scores were
/// computed.
///
/// Best first: candidates are scored exactly in the order of their lower bounds (in small
/// parallel batches), each only until its refined bound reaches the cutoff
/// `c = s* (1 + 16 tol)` of the lowest exact score `s*` so far ([`refine`]); the scan
/// ends at the first bound at or above `c`. Every candidate left has a score `>= c`, and
/// when no known score lies in `[c (1 - tol)^2, c)` (else `c` is raised and the scan goes
/// on), the chain over the known scores in collection order chooses exactly what the
/// chain over all the scores would ([`band_low`]).
pub(super) fn best_first(
    obj: &Objective,
    addings: &[super::Adding],
    groups: &[(&[usize], &[usize])],
    tol: f64,
) -> Result<(Option<(usize, f64)>, usize), crate::select::SelectionError> {
    // Items: (group, candidate index, bound).
    let mut items: Vec<(usize, usize, Option<Bound>)> = Vec::new();
    for (gi, (a, &(_, cands))) in addings.iter().zip(groups).enumerate() {
        let b = lower_bounds(obj, &a.live, &a.states, &a.cols, cands);
        items.extend(b.into_iter().enumerate().map(|(k, b)| (gi, k, b)));
    }
    let n = items.len();
    let terms: Vec<usize> = addings.iter().map(|a| 3 * a.live.len()).collect();
    // The bound each candidate is ordered by (`-inf`: not screened).
    let lb: Vec<f64> = items
        .iter()
        .map(|(g, _, b)| match b {
            None => f64::NEG_INFINITY,
            Some(b) => {
                let m = b.mean();
                let slack = (terms[*g] as f64 + 16.0) * f64::EPSILON;
                m - slack * m.abs()
            }
        })
        .collect();
    let ordered = tol <= BEST_FIRST_TOL_MAX;
    let mut order: Vec<usize> = (0..n).collect();
    if ordered {
        order.sort_by(|&a, &b| lb[a].total_cmp(&lb[b]).then(a.cmp(&b)));
    }
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
    let mut pos = 0;
    let batch = (2 * rayon::current_num_threads()).max(4);
    let score = |i: usize, c: f64| -> Result<Option<f64>, crate::select::SelectionError> {
        let (g, k, b) = &items[i];
        let a = &addings[*g];
        let cand = groups[*g].1[*k];
        match b {
            None => Ok(Some(obj.exact_scores(a, &[cand])?[0])),
            Some(b) => refine(
                obj,
                &a.live,
                &a.states,
                &a.cols,
                cand,
                b,
                c.is_finite().then_some(c),
            ),
        }
    };
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
        while todo.len() < batch && pos < n && lb[order[pos]] < c {
            if known[order[pos]].is_none() {
                todo.push(order[pos]);
            }
            pos += 1;
        }
        if todo.is_empty() {
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
        let out: Vec<Option<f64>> = todo
            .par_iter()
            .map(|&i| score(i, c))
            .collect::<Result<_, _>>()?;
        for (&i, s) in todo.iter().zip(out) {
            match s {
                Some(s) => {
                    evaluated += 1;
                    known[i] = Some(s);
                    s_best = s_best.min(s);
                }
                None => ruled.push((i, c)),
            }
        }
    }
    let mut chain = Chain::new(tol);
    for (i, s) in known.iter().enumerate() {
        if let Some(s) = *s {
            chain.offer(i, s);
        }
    }
    Ok((chain.best(), evaluated))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::cpu::CpuBackend;
    use crate::collection::Collection;
    use crate::select::objective::argmin;
    use crate::select::objective::ObjectiveParams;

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
            let cands: Vec<usize> = all.iter().copied().filter(|c| !basis.contains(c)).collect();
            let a = obj.adding(&basis, &all).expect("states");
            let lbs: Vec<f64> = lower_bounds(&obj, &a.live, &a.states, &a.cols, &cands)
                .iter()
                .map(|b| b.as_ref().map_or(f64::NEG_INFINITY, Bound::mean))
                .collect();
            let exact = obj.exact_scores(&a, &cands).expect("exact");
            let best = exact.iter().copied().fold(f64::INFINITY, f64::min);
            for ((&c, &lb), &s) in cands.iter().zip(&lbs).zip(&exact) {
                assert!(
                    lb <= s,
                    "basis {basis:?}, candidate {c}: bound {lb} > exact {s}"
                );
                screened += usize::from(lb > best);
            }
        }
        // Not a bound that cannot screen: some candidates are ruled out.
        assert!(screened > 0);
    }
}
