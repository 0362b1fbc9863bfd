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
//! For the current basis the exact solution of every (target, channel) is kept, and each
//! candidate is evaluated by bordering its Cholesky factor by one column
//! ([`crate::nnls::incremental`]): `O(p^2)` per target and channel, with `p <= k + 1`.

use crate::backend::weighted::TargetWeight;
use crate::backend::Lobe;
use crate::backend::{Backend, Progress};
use crate::collection::Collection;
use crate::fit::{fit_cells, CollectionGrams, FitParams, GramMode};
use crate::merl::CellSet;
use crate::merl::{Mask, Weighting};
use crate::nnls::incremental::{self, ChanState, Cosine};
use crate::nnls::NnlsError;
use rayon::prelude::*;

use super::SelectionError;

mod gram;
mod screen;
use gram::{analytic_grams, analytic_grams_weighted};
pub use screen::*;

/// Parameters of the objective: the fit cells and how the Gram matrices are computed.
/// Defaults: evaluation mask, uniform weights, full grid (stride 1), automatic Gram
/// (separable closed form for analytic collections, else one back-end pass).
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectiveParams {
    /// Fit mask (default evaluation).
    pub mask: Mask,
    /// Weighting (default uniform).
    pub weighting: Weighting,
    /// Grid sub-sampling stride, 1 to 90 (default 1).
    pub stride: usize,
    /// Gram mode (default auto).
    pub gram: GramMode,
    /// The fit objective (SPEC 11; default [`crate::fit::DEFAULT_OBJECTIVE`], `relative`;
    /// `l2` is SPEC 8's). Under `relative` or `log` the Gram matrices carry SPEC 11's
    /// shared weights per channel (`shared_weights`) and the reported fits
    /// (cross-validation's held-out fits) use the per-target weights.
    pub objective: TargetWeight,
}

impl Default for ObjectiveParams {
    fn default() -> Self {
        Self {
            mask: Mask::Evaluation,
            weighting: Weighting::Uniform,
            stride: 1,
            gram: GramMode::Auto,
            objective: crate::fit::DEFAULT_OBJECTIVE,
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
    /// Sets the fit objective.
    pub fn objective(mut self, o: TargetWeight) -> Self {
        self.objective = o;
        self
    }
    /// Sets the mask, weighting and stride of a checked grid.
    pub fn grid(self, g: crate::merl::GridSpec) -> Self {
        self.mask(g.mask())
            .weighting(g.weighting())
            .stride(g.stride())
    }
    /// Validates: the stride's rule ([`crate::merl::GridSpec::STRIDE_RULE`]) and the
    /// objective's.
    pub fn check(&self) -> Result<ValidObjectiveParams, SelectionError> {
        if !crate::merl::GridSpec::stride_ok(self.stride) {
            return Err(SelectionError::InvalidParam {
                name: "stride",
                value: self.stride.to_string(),
                expected: crate::merl::GridSpec::STRIDE_RULE,
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
            objective: self.objective,
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

/// Bytes of tabulated values [`shared_weights`] holds at once.
const SHARED_WEIGHT_BLOCK_BYTES: usize = 32 << 20;

/// SPEC 11's shared weights of an objective over `cells`, one cell set per channel:
/// `W_c(s) = w_s phi(m_c(s), s)` with `m_c(s)` the median over the collection's materials
/// of `f_c(s)` (the mean of the two middle values for an even count), normalised to sum 1
/// (the scale of the weights changes no fit and no relative residual). The materials'
/// three channels are tabulated by `backend` (f32) together, block by block of cells (a
/// network runs once per cell for its three channels). `weight` is checked by the caller's
/// door (`ObjectiveParams::check`, `empirical`, the plan's checks).
pub(crate) fn shared_weights(
    backend: &dyn Backend,
    coll: &Collection,
    cells: &CellSet,
    weight: TargetWeight,
    progress: Progress<'_>,
) -> Result<[CellSet; 3], SelectionError> {
    let mats: Vec<Lobe> = crate::fit::collection_lobes(coll)
        .into_iter()
        .flat_map(|l| l.into_iter().skip(1))
        .collect();
    let total = cells.cells.len() as u64;
    let n = coll.len();
    let block = (SHARED_WEIGHT_BLOCK_BYTES / (12 * n.max(1))).clamp(256, 1 << 16);
    let mut out: [CellSet; 3] = std::array::from_fn(|_| cells.clone());
    let mut at = 0;
    for cc in cells.cells.chunks(block) {
        let v = backend
            .tabulate(&mats, cc)
            .map_err(crate::fit::FitError::from)?;
        let len = cc.len();
        for (c, o) in out.iter_mut().enumerate() {
            let v = &v[c * n * len..(c + 1) * n * len];
            // Tiles of cells, each turned cell-major once (the materials' rows read in
            // runs, not one strided value per material and cell), then a median per cell.
            const TILE: usize = 64;
            o.weights[at..at + len]
                .par_chunks_mut(TILE)
                .enumerate()
                .for_each(|(t, ow)| {
                    let (i0, k) = (t * TILE, ow.len());
                    let mut col = vec![0f32; k * n];
                    for m in 0..n {
                        for (r, &x) in v[m * len + i0..m * len + i0 + k].iter().enumerate() {
                            col[r * n + m] = x;
                        }
                    }
                    for (r, o) in ow.iter_mut().enumerate() {
                        let med = median_f32(&mut col[r * n..(r + 1) * n]);
                        let cos_i = crate::backend::weighted::cos_theta_i(cc[i0 + r] as usize);
                        *o *= weight.phi(med, cos_i);
                    }
                });
        }
        at += len;
        progress(at as u64, total);
    }
    for (c, o) in out.iter_mut().enumerate() {
        let total: f64 = o.weights.iter().sum();
        if !(total.is_finite() && total > 0.0) {
            let what = match weight.eps() {
                Some(eps) => {
                    format!("the relative objective's weights 1/(f + eps)^2 at eps {eps:e}")
                }
                None => format!("the {} objective's weights", weight.kind().name()),
            };
            return Err(crate::fit::FitError::Weights {
                material: "the collection's median".into(),
                channel: c,
                detail: format!("{what} sum to {total:e} over the fit cells: they must sum to a positive finite number (a larger or smaller eps moves them back into range)"),
            }
            .into());
        }
        o.weights.iter_mut().for_each(|w| *w /= total);
    }
    Ok(out)
}

/// The Gram matrices of `coll` under SPEC 11's shared weights of `weight` over `cells`
/// ([`shared_weights`]): per channel `(N + 1)^2`, column 0 the Lambertian `1/pi`, column
/// `j + 1` material `j`. An all-analytic collection's come in closed form with each
/// channel's weights (`analytic_grams_weighted`: no grid pass, as under `l2`); otherwise
/// from the back-end, each channel under its weights ([`Backend::grams_per_channel`]).
pub(crate) fn shared_weight_grams(
    backend: &dyn Backend,
    coll: &Collection,
    cells: &CellSet,
    weight: TargetWeight,
    progress: Progress<'_>,
) -> Result<[Vec<f64>; 3], SelectionError> {
    let weighted = shared_weights(backend, coll, cells, weight, progress)?;
    if coll.all_analytic() {
        return Ok(analytic_grams_weighted(
            coll,
            [&weighted[0], &weighted[1], &weighted[2]],
        ));
    }
    let lobes = crate::fit::collection_lobes(coll);
    let [w0, w1, w2] = &weighted;
    Ok(backend
        .grams_per_channel(lobes, [w0, w1, w2], coll.len() + 1, progress)
        .map_err(crate::fit::FitError::from)?)
}

/// The median of `v` (NaN-free, non-empty: the mean of the two middle values for an even
/// length), in f64; reorders `v`.
fn median_f32(v: &mut [f32]) -> f64 {
    let n = v.len();
    let cmp = |a: &f32, b: &f32| a.total_cmp(b);
    let (_, &mut hi, _) = v.select_nth_unstable_by(n / 2, cmp);
    if n % 2 == 1 {
        return f64::from(hi);
    }
    let lo = v[..n / 2].iter().copied().fold(f32::NEG_INFINITY, f32::max);
    0.5 * (f64::from(lo) + f64::from(hi))
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
    /// back-end pass over the fit cells for the three channels together,
    /// [`CollectionGrams::over`]).
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
        let cells = fit_cells(coll, &all, &p.fit_params())?;
        if cells.is_empty() {
            return Err(SelectionError::Fit(crate::fit::FitError::Backend(
                crate::error::BackendError::Invalid(crate::merl::no_cells_reason(
                    p.mask,
                    p.stride,
                    "the collection",
                )),
            )));
        }
        let grams = if p.objective != TargetWeight::L2 {
            shared_weight_grams(backend, coll, &cells, p.objective, progress)?
        } else if CollectionGrams::needed(coll, p.gram) {
            CollectionGrams::over(backend, coll, &cells, progress)?
        } else {
            analytic_grams(coll, &cells)
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
            *sc = incremental::cosine_in_place(m, g);
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

    /// The cosine matrix of channel `c` (column 0 Lambertian, `j + 1` material `j`).
    #[inline]
    fn view(&self, c: usize) -> Cosine<'_> {
        let m = self.names.len() + 1;
        Cosine::new(m, &self.cos[c]).expect("the cosine matrices are (N + 1)^2")
    }

    /// The error of a rejected solve of target `t`, channel `c`.
    fn solve_error(&self, t: usize, c: usize, e: NnlsError) -> SelectionError {
        SelectionError::Solve {
            material: self.names[t].clone(),
            channel: c,
            source: e,
        }
    }

    /// Exact NNLS of target `t`, channel `c`, on the Gram columns `cols` (0 = Lambertian):
    /// coefficients and the relative residual `q`. A rejected problem (which a finite
    /// cosine matrix with a unit or zero diagonal never is) is an error naming the target.
    fn solve(&self, c: usize, cols: &[usize], t: usize) -> Result<(Vec<f64>, f64), SelectionError> {
        incremental::solve(self.view(c), cols, t + 1).map_err(|e| self.solve_error(t, c, e))
    }

    /// `rho(t; B)` of SPEC 8 from the Gram matrices (exact Lawson-Hanson per channel).
    pub fn rho(&self, basis: &[usize], t: usize) -> Result<f64, SelectionError> {
        let cols = basis_cols(basis);
        let mut rho = 0.0;
        for c in (0..3).filter(|&c| self.share[t][c] > 0.0) {
            rho += self.share[t][c] * self.solve(c, &cols, t)?.1;
        }
        Ok(rho)
    }

    /// The exact fit of target `t` by `basis` (SPEC 5) from the Gram matrices:
    /// coefficients per column (0 = Lambertian, then the basis in order), RGB, in the
    /// units of the materials, and `rho(t; basis)`.
    pub fn fit(&self, basis: &[usize], t: usize) -> Result<ObjectiveFit, SelectionError> {
        let cols = basis_cols(basis);
        let mut coef = vec![[0.0; 3]; cols.len()];
        let mut rho = 0.0;
        for c in (0..3).filter(|&c| self.share[t][c] > 0.0) {
            let (x, q) = self.solve(c, &cols, t)?;
            rho += self.share[t][c] * q;
            let dt = self.scale[c][t + 1];
            for ((a, &y), &col) in coef.iter_mut().zip(&x).zip(&cols) {
                let dj = self.scale[c][col];
                if y > 0.0 && dj > 0.0 {
                    a[c] = y * dt / dj;
                }
            }
        }
        Ok(ObjectiveFit {
            coefficients: coef,
            rho,
        })
    }

    /// Which materials of `basis` contribute (a coefficient > 0 in some channel) to the
    /// exact fit of target `t` (the empirical selection's count, SPEC 5).
    pub fn contributors(&self, basis: &[usize], t: usize) -> Result<Vec<bool>, SelectionError> {
        let cols = basis_cols(basis);
        let mut used = vec![false; basis.len()];
        for c in (0..3).filter(|&c| self.share[t][c] > 0.0) {
            let (x, _) = self.solve(c, &cols, t)?;
            for (u, &v) in used.iter_mut().zip(&x[1..]) {
                *u |= v > 0.0;
            }
        }
        Ok(used)
    }

    /// `S(B; T)`: the mean of `rho(t; B)` over `t` in `targets` not in `basis`; an error
    /// when no target remains (the mean of nothing is no score).
    pub fn score(&self, basis: &[usize], targets: &[usize]) -> Result<f64, SelectionError> {
        let left: Vec<usize> = targets
            .iter()
            .copied()
            .filter(|t| !basis.contains(t))
            .collect();
        if left.is_empty() {
            return Err(SelectionError::NoTargetLeft {
                basis: basis.len(),
                targets: targets.len(),
            });
        }
        let rhos: Vec<f64> = left
            .par_iter()
            .map(|&t| self.rho(basis, t))
            .collect::<Result<_, _>>()?;
        Ok(rhos.iter().sum::<f64>() / left.len() as f64)
    }

    /// The solution state of target `t` by `basis` in every channel.
    fn state(&self, basis: &[usize], t: usize) -> Result<[ChanState; 3], SelectionError> {
        let cols = basis_cols(basis);
        let mut out: [ChanState; 3] = Default::default();
        for (c, o) in out.iter_mut().enumerate() {
            if self.share[t][c] > 0.0 {
                *o = ChanState::new(self.view(c), &cols, t + 1)
                    .map_err(|e| self.solve_error(t, c, e))?;
            }
        }
        Ok(out)
    }

    /// The live targets (not in `basis`), their solution states and the basis columns.
    fn adding(&self, basis: &[usize], targets: &[usize]) -> Result<Adding, SelectionError> {
        let live: Vec<usize> = targets
            .iter()
            .copied()
            .filter(|t| !basis.contains(t))
            .collect();
        let states: Vec<[ChanState; 3]> = live
            .par_iter()
            .map(|&t| self.state(basis, t))
            .collect::<Result<_, _>>()?;
        Ok(Adding {
            live,
            states,
            cols: basis_cols(basis),
        })
    }

    /// `S(B + c; T)` for every `c` of `candidates` (`c` not in `basis`), from the states of
    /// `basis` (the mean excludes `basis` and `c` from the targets; `+inf` when none
    /// remains, so such a candidate is never chosen).
    pub fn scores_adding(
        &self,
        basis: &[usize],
        targets: &[usize],
        candidates: &[usize],
    ) -> Result<Vec<f64>, SelectionError> {
        let a = self.adding(basis, targets)?;
        self.exact_scores(&a, candidates)
    }

    /// The choice of the exhaustive sweep over several groups (a basis and candidates not
    /// in it): the [`argmin`] with tie tolerance `tol` of the concatenated
    /// `scores_adding(group.basis, targets, group.candidates)`, as `(flat index, score)`,
    /// found without the exact score of the candidates that provably cannot change it
    /// ([`screen::best_first`]). Also the number of exact scores computed and, per group,
    /// `S(basis; targets)` from the states of the basis (`None` when no target is left),
    /// equal to [`Objective::score`] bit for bit.
    ///
    /// With one group, `signs` may be those of the previous step of a greedy run
    /// ([`GroupsBest::signs`]): the same result, with less work where they still hold.
    pub(crate) fn best_of_groups(
        &self,
        groups: &[(&[usize], &[usize])],
        targets: &[usize],
        tol: f64,
        signs: Option<screen::GradSigns>,
    ) -> Result<GroupsBest, SelectionError> {
        let addings: Vec<Adding> = groups
            .iter()
            .map(|&(basis, _)| self.adding(basis, targets))
            .collect::<Result<_, _>>()?;
        let scores = addings.iter().map(|a| self.score_of(a)).collect();
        let r = screen::best_first(self, &addings, groups, tol, signs)?;
        Ok(GroupsBest {
            best: r.best,
            evaluated: r.evaluated,
            scores,
            signs: r.signs,
        })
    }

    /// `S(B; T)` from the states of `B` ([`Objective::score`]'s sum, bit for bit).
    fn score_of(&self, a: &Adding) -> Option<f64> {
        if a.live.is_empty() {
            return None;
        }
        let rhos: Vec<f64> = a
            .live
            .iter()
            .zip(&a.states)
            .map(|(&t, st)| {
                let mut rho = 0.0;
                for c in (0..3).filter(|&c| self.share[t][c] > 0.0) {
                    rho += self.share[t][c] * st[c].q();
                }
                rho
            })
            .collect();
        Some(rhos.iter().sum::<f64>() / a.live.len() as f64)
    }

    /// Exact `S(B + c; T)` of each candidate from the states of the basis.
    fn exact_scores(&self, a: &Adding, candidates: &[usize]) -> Result<Vec<f64>, SelectionError> {
        let Adding { live, states, cols } = a;
        // Candidates in blocks, so that each target's state is read once per block and the
        // block's cosine rows stay in cache; each candidate still sums its targets in
        // order, so the result does not depend on the blocking or the threads.
        let block = candidates
            .len()
            .div_ceil(rayon::current_num_threads())
            .clamp(1, 16);
        let blocks: Vec<Vec<f64>> = candidates
            .par_chunks(block)
            .map(|block| {
                let mut sums = vec![0.0; block.len()];
                let mut counts = vec![0usize; block.len()];
                let mut scratch = crate::nnls::incremental::Scratch::default();
                for (&t, st) in live.iter().zip(states) {
                    for (b, &cand) in block.iter().enumerate() {
                        if t == cand {
                            continue;
                        }
                        counts[b] += 1;
                        for (c, ch) in st.iter().enumerate() {
                            if ch.is_active() {
                                let q = ch
                                    .q_adding(self.view(c), cols, cand + 1, t + 1, &mut scratch)
                                    .map_err(|e| self.solve_error(t, c, e))?;
                                sums[b] += self.share[t][c] * q;
                            }
                        }
                    }
                }
                Ok(sums
                    .iter()
                    .zip(&counts)
                    .map(|(&s, &n)| if n == 0 { f64::INFINITY } else { s / n as f64 })
                    .collect())
            })
            .collect::<Result<_, SelectionError>>()?;
        Ok(blocks.concat())
    }
}

/// The outcome of [`Objective::best_of_groups`].
#[derive(Clone, Debug)]
pub(crate) struct GroupsBest {
    /// The winner over the concatenated groups (flat index) and its exact score.
    pub best: Option<(usize, f64)>,
    /// Exact scores computed.
    pub evaluated: usize,
    /// Per group: `S(basis; targets)` (`None`: no target left).
    pub scores: Vec<Option<f64>>,
    /// With one group, the signs of the pairs' gradients, for the next greedy step.
    pub signs: Option<screen::GradSigns>,
}

/// The live targets of a basis, their states and the basis columns.
struct Adding {
    live: Vec<usize>,
    states: Vec<[ChanState; 3]>,
    cols: Vec<usize>,
}

/// The exact fit of one target by a basis, from the Gram matrices.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectiveFit {
    /// Coefficients per column (0 = Lambertian, then the basis in order), RGB, in the
    /// units of the materials.
    pub coefficients: Vec<[f64; 3]>,
    /// `rho(t; basis)` of SPEC 8.
    pub rho: f64,
}

/// Gram columns of a basis: the Lambertian (0), then `j + 1` per material.
fn basis_cols(basis: &[usize]) -> Vec<usize> {
    std::iter::once(0)
        .chain(basis.iter().map(|&b| b + 1))
        .collect()
}

/// Index of the lowest score, a later one winning only by more than `tie_tol` relative.
pub(crate) fn argmin(scores: &[f64], tie_tol: f64) -> Option<usize> {
    let mut best: Option<usize> = None;
    for (i, &s) in scores.iter().enumerate() {
        match best {
            None => best = Some(i),
            Some(b) if s < scores[b] - tie_tol * scores[b].abs() - 1e-300 => best = Some(i),
            _ => {}
        }
    }
    best
}
