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

mod bounds;
mod kernel;
mod refine;
mod signs;

use bounds::*;
use kernel::*;
pub(super) use refine::best_first;
pub(crate) use signs::GradSigns;
use signs::*;

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

/// The argmin chain of the searches ([`crate::select::swap`]): the earliest lowest score, a later
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
    pub(super) fn mean(&self) -> f64 {
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
    ///
    /// Long function: the bounds' data of every live target (factors, gradients, the
    /// signs carried from an earlier step, the candidates' rows) built in one pass per
    /// target whose parts share that target's state.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::cpu::CpuBackend;
    use crate::collection::Collection;
    use crate::select::argmin;
    use crate::select::ObjectiveParams;

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
        let p = ObjectiveParams::default()
            .stride(2)
            .objective(crate::backend::weighted::TargetWeight::L2)
            .check()
            .expect("p");
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
        let p = ObjectiveParams::default()
            .stride(4)
            .objective(crate::backend::weighted::TargetWeight::L2)
            .check()
            .expect("p");
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
