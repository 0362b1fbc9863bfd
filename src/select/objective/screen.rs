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

/// Per channel: `V^T` (`m x p`, row `x` = `V_x`) and `|V_x|^2`, or `None` when the
/// non-zero basis columns have no Cholesky factor.
fn projections(obj: &Objective, cols: &[usize]) -> Option<[(usize, Vec<f64>, Vec<f64>); 3]> {
    let m = obj.len() + 1;
    let mut out: [(usize, Vec<f64>, Vec<f64>); 3] = Default::default();
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

/// Lower bounds of `S(B + c; T)` for every candidate (`-inf`: not screened), from the
/// live targets and their states (module docs).
pub(super) fn lower_bounds(
    obj: &Objective,
    live: &[usize],
    states: &[[ChanState; 3]],
    cols: &[usize],
    candidates: &[usize],
) -> Vec<f64> {
    let Some(proj) = projections(obj, cols) else {
        return vec![f64::NEG_INFINITY; candidates.len()];
    };
    candidates
        .par_iter()
        .map(|&cand| {
            let j = cand + 1;
            let nc: [f64; 3] = [0, 1, 2].map(|c| 1.0 - proj[c].2[j]);
            let mut sum = 0.0;
            let mut count = 0usize;
            for (&t, st) in live.iter().zip(states) {
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
                        return f64::NEG_INFINITY;
                    } else {
                        let (p, vt, nrm) = &proj[c];
                        let (vc, vtt) = (&vt[j * p..(j + 1) * p], &vt[(t + 1) * p..(t + 2) * p]);
                        let dot: f64 = vc.iter().zip(vtt).map(|(a, b)| a * b).sum();
                        let mm = (g.at(j, t + 1) - dot).max(0.0);
                        (1.0 - nrm[t + 1] - mm * mm / nc[c] - MARGIN).max(0.0)
                    };
                    sum += obj.share[t][c] * lb;
                }
            }
            if count == 0 {
                f64::INFINITY
            } else {
                sum / count as f64
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::cpu::CpuBackend;
    use crate::collection::Collection;
    use crate::select::objective::ObjectiveParams;
    use crate::select::search::argmin;

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
            let lbs = lower_bounds(&obj, &a.live, &a.states, &a.cols, &cands);
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
