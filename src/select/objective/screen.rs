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
//! A candidate nearly in the span of the basis (`1 - |V_c|^2 < `[`NC_MIN`], where the
//! bordered update loses digits) is never screened, and neither is any candidate when
//! `C_BB` has no Cholesky factor. The bound costs `O(p)` per target and candidate against
//! the exact `O(p^2)`.

use super::Objective;
use crate::nnls::incremental::{cholesky, ChanState};
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

/// Lower bounds of `S(B + c; T)` for every candidate (`None`: not screened), from the
/// live targets and their states (module docs).
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
    candidates
        .par_iter()
        .map(|&cand| {
            let j = cand + 1;
            let nc: [f64; 3] = [0, 1, 2].map(|c| 1.0 - proj[c].2[j]);
            let mut chunks = vec![0.0; live.len().div_ceil(CHUNK)];
            let mut count = 0usize;
            for (k, (&t, st)) in live.iter().zip(states).enumerate() {
                if t == cand {
                    continue;
                }
                count += 1;
                for (c, ch) in st.iter().enumerate() {
                    if !ch.is_active() {
                        continue;
                    }
                    let g = obj.view(c);
                    let lb = if ch.unchanged_adding(g, j, t + 1) {
                        ch.q()
                    } else if nc[c].is_nan() || nc[c] < NC_MIN {
                        return None;
                    } else {
                        let (p, vt, nrm) = &proj[c];
                        let (vc, vtt) = (&vt[j * p..(j + 1) * p], &vt[(t + 1) * p..(t + 2) * p]);
                        let dot: f64 = vc.iter().zip(vtt).map(|(a, b)| a * b).sum();
                        let mm = (g.at(j, t + 1) - dot).max(0.0);
                        (1.0 - nrm[t + 1] - mm * mm / nc[c] - MARGIN).max(0.0)
                    };
                    chunks[k / CHUNK] += obj.share[t][c] * lb;
                }
            }
            Some(Bound { chunks, count })
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
