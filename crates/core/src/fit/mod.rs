//! Fitting materials as non-negative combinations of a basis (the paper's Eq. 1-2, SPEC 5).
//!
//! Per colour channel c, over the fit mask with weights w:
//! `min sum_s w_s (a0 / pi + sum_k a_k f_k,c(s) - f_B,c(s))^2` subject to `a >= 0`.
//! Gram quantities `A^T W A`, `A^T W b` and `b^T W b` come from one pass of the back-end
//! over the grid (f32 partials reduced in f64); the problem is solved exactly by
//! Lawson-Hanson (default) or by the batched projected-gradient solver; residuals and MAE
//! are computed on the grid in f64.

use crate::backend::cpu::CpuBackend;
use crate::backend::weighted::{TargetWeight, WeightedSystems};
use crate::backend::{Backend, Lobe, Progress};
use crate::brdf::LobeParams;
use crate::collection::{Collection, MaterialData};
use crate::error::BackendError;
use crate::merl::{CellSet, GridTables, Mask, Weighting};
use crate::nnls::{lawson_hanson, pgd, GramBatch, NnlsError, NnlsSolution};
use crate::separable::{CellMoments, SeparableLobe};
use rayon::prelude::*;
use std::num::NonZeroUsize;

pub mod appearance;
pub mod diagnostics;
mod errors;
pub mod export;
pub mod file;
mod gram;
pub(crate) use errors::add_columns;
use errors::grid_errors;

pub(crate) use gram::collection_lobes;
pub(crate) use gram::separable_lobes;
pub use gram::{channel_gram, ChannelGram, CollectionGrams, RGB_PASS_MAX_LOBES};

/// Errors of fitting.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FitError {
    /// The basis is empty.
    #[error("the basis is empty: give at least one basis material")]
    EmptyBasis,
    /// No target to fit.
    #[error("no target material to fit")]
    NoTargets,
    /// Too many basis materials for the chosen solver.
    #[error("a basis of {found} materials is larger than the {solver} solver supports ({limit})")]
    BasisTooLarge {
        /// Solver name.
        solver: &'static str,
        /// Its limit.
        limit: usize,
        /// Basis size asked for.
        found: usize,
    },
    /// A material appears twice in the basis.
    #[error("material `{}` appears twice in the basis", crate::error::short_name(.0))]
    DuplicateBasis(String),
    /// A Gram quantity is not finite (non-finite data).
    #[error("the Gram sums of `{}` (channel {channel}) are not finite: its data holds a non-finite value, or reflectances too large for the sums (a value above about 1e18, squared, leaves the back-end's f32 range; the loaders refuse NaN and infinite values, and measured reflectances are far below 1e18): check the material's data and its units", crate::error::short_name(.material))]
    NonFinite {
        /// Material.
        material: String,
        /// Channel.
        channel: usize,
    },
    /// The fit mask holds no cell valid in every material involved (measured tables
    /// with disjoint valid cells, or a grid stride that skips every valid cell).
    #[error("{}", crate::merl::no_cells_reason(*.mask, *.stride, "the fit"))]
    NoCells {
        /// The mask.
        mask: Mask,
        /// The stride.
        stride: usize,
    },
    /// A grid stride of 0 (1 is the full grid).
    #[error("a grid stride of 0 is meaningless: give --stride 1 (the full grid) or more")]
    ZeroStride,
    /// Back-end failure.
    #[error(transparent)]
    Backend(#[from] BackendError),
    /// Solver failure.
    #[error(transparent)]
    Nnls(#[from] NnlsError),
    /// A target's weighted system (SPEC 11) cannot be formed: its weights overflow with
    /// the values, or vanish on every fit cell (a fit of nothing whose objective residual
    /// of 0 would read as perfect).
    #[error("the weighted fit of `{}` (channel {channel}): {detail}", crate::error::short_name(.material))]
    Weights {
        /// Material fitted (the target).
        material: String,
        /// Colour channel (0 = R).
        channel: usize,
        /// What went wrong, naming the objective and its eps.
        detail: String,
    },
    /// The fit of one material failed (non-finite data, or no convergence).
    #[error("the NNLS fit of `{}` (channel {channel}) failed: {reason}", crate::error::short_name(.material))]
    Solve {
        /// Material fitted (the target).
        material: String,
        /// Colour channel (0 = R).
        channel: usize,
        /// What went wrong.
        reason: String,
    },
}

/// Which NNLS solver.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Solver {
    /// Exact active-set Lawson-Hanson (f64).
    Exact,
    /// Accelerated projected gradient, batched over targets; targets whose KKT violation
    /// stays above tolerance are re-solved exactly.
    Pgd,
}

/// How Gram matrices and grid errors are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum GramMode {
    /// The separable closed form (module `separable`) when every lobe is analytic, else
    /// the back-end's grid pass.
    Auto,
    /// Always the back-end's pass over the grid (GPU kernel or CPU twin).
    Grid,
}

impl Solver {
    /// Every solver.
    pub const ALL: [Solver; 2] = [Solver::Exact, Solver::Pgd];

    /// The name on the command line, in Python and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Solver::Exact => "exact",
            Solver::Pgd => "pgd",
        }
    }
}

impl std::str::FromStr for Solver {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Solver::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("solver `{s}`: give exact or pgd"))
    }
}

impl GramMode {
    /// Every mode.
    pub const ALL: [GramMode; 2] = [GramMode::Auto, GramMode::Grid];

    /// The name on the command line, in Python and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            GramMode::Auto => "auto",
            GramMode::Grid => "grid",
        }
    }
}

impl std::str::FromStr for GramMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        GramMode::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("gram `{s}`: give auto or grid"))
    }
}

/// Fit parameters. Defaults: evaluation mask, uniform weights, full grid, exact solver,
/// automatic Gram mode.
#[derive(Clone, Debug)]
pub struct FitParams {
    /// Fit mask.
    pub mask: Mask,
    /// Weighting.
    pub weighting: Weighting,
    /// Grid stride.
    pub stride: usize,
    /// Solver.
    pub solver: Solver,
    /// Gram mode.
    pub gram: GramMode,
    /// The fit objective (SPEC 11): `l2` (SPEC 5, the paper's) or per-target weights
    /// (default [`DEFAULT_OBJECTIVE`]).
    pub objective: TargetWeight,
}

/// The fit objective when none is given (SPEC 11), the one default of the library's
/// parameters ([`FitParams`], `ObjectiveParams` and those built on them), the requests,
/// the command line and Python: `relative` with `eps` 0.01, the objective with the lowest
/// mean held-out FLIP over the four lights on merl100 (README "Appearance"). The paper's
/// fits are [`TargetWeight::L2`], given explicitly (`reproduce` does).
pub const DEFAULT_OBJECTIVE: TargetWeight = TargetWeight::Relative {
    eps: TargetWeight::DEFAULT_EPS,
};

impl FitParams {
    /// These parameters on the mask, weighting and stride of a checked grid.
    pub fn grid(self, g: crate::merl::GridSpec) -> Self {
        Self {
            mask: g.mask(),
            weighting: g.weighting(),
            stride: g.stride(),
            ..self
        }
    }
}

impl Default for FitParams {
    fn default() -> Self {
        Self {
            mask: Mask::Evaluation,
            weighting: Weighting::Uniform,
            stride: 1,
            solver: Solver::Exact,
            gram: GramMode::Auto,
            objective: DEFAULT_OBJECTIVE,
        }
    }
}

/// The fit of one target.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TargetFit {
    /// Target material.
    pub material: String,
    /// Coefficients per column (0 = Lambertian, then the basis in order), RGB.
    pub coefficients: Vec<[f64; 3]>,
    /// `sqrt(sum_s w_s r_s^2)` per channel, on the grid.
    pub residual: [f64; 3],
    /// Weighted mean of |fit - target| over the mask, averaged over channels.
    pub mae: f64,
    /// Relative residual (SPEC 8): `sum_c residual_c^2 / sum_c sum_s w_s b_c(s)^2`; 0 is
    /// a perfect fit, 1 a fit that explains nothing of the target.
    pub relative_residual: f64,
    /// `mae` divided by the weighted mean of |target| over the mask (averaged over the
    /// channels likewise): above 1 the fit is further from the target than the zero BRDF.
    pub relative_mae: f64,
    /// Relative residual under the objective's weights `W` (SPEC 11's `rho_W`):
    /// `sum_c sum_s W r^2 / sum_c sum_s W b^2`; equal to `relative_residual` for `l2`.
    pub objective_residual: f64,
    /// Largest scaled KKT violation per channel.
    pub kkt: [f64; 3],
    /// Solver iterations per channel.
    pub iterations: [usize; 3],
}

impl TargetFit {
    /// Whether basis column `k` (0-based, Lambertian excluded) contributes (`a > 0` in
    /// some channel).
    pub fn contributes(&self, k: usize) -> bool {
        self.coefficients[k + 1].iter().any(|&a| a > 0.0)
    }
}

/// The lobe of channel `c` of a material.
pub fn channel_lobe(m: &MaterialData, c: usize) -> Lobe {
    match m {
        MaterialData::Analytic(a) => Lobe::Analytic(LobeParams {
            kd: a.d[c] as f32,
            ks: a.s[c] as f32,
            f0: a.f0 as f32,
            n: a.n as f32,
        }),
        MaterialData::Measured(t) => Lobe::Measured {
            table: t.clone(),
            channel: Some(c),
        },
        MaterialData::Rgl(t) => Lobe::Measured {
            table: t.table().clone(),
            channel: Some(c),
        },
        MaterialData::Neural(net) => Lobe::Neural {
            net: net.clone(),
            channel: Some(c),
        },
    }
}

/// The Lambertian column `1 / pi`.
pub const LAMBERTIAN: Lobe = Lobe::Analytic(LobeParams {
    kd: 1.0,
    ks: 0.0,
    f0: 0.0,
    n: 1.0,
});

/// The cells of a fit of the materials `idx` of `coll`: the mask on the grid
/// sub-sampled by the stride, restricted to cells valid in every measured one of them
/// ([`CellSet::for_collection`]). A stride of 0 is refused.
pub fn fit_cells(coll: &Collection, idx: &[usize], p: &FitParams) -> Result<CellSet, FitError> {
    let stride = NonZeroUsize::new(p.stride).ok_or(FitError::ZeroStride)?;
    Ok(CellSet::for_collection(
        &coll.subset(idx),
        p.mask,
        p.weighting,
        stride,
    ))
}

/// Scaled-KKT level above which a projected-gradient solution is re-solved exactly.
pub const PGD_FALLBACK_KKT: f64 = 1e-5;

/// Solves one channel's batch with the chosen solver (PGD on the back-end: the GPU kernel
/// in f32 on the GPU back-end; targets left above [`PGD_FALLBACK_KKT`] are re-solved
/// exactly).
pub(crate) fn solve_channel(
    backend: &dyn Backend,
    m: usize,
    g: &[f64],
    hs: &[f64],
    bbs: &[f64],
    solver: Solver,
) -> Result<Vec<NnlsSolution>, FitError> {
    let batch = GramBatch::new(m, g, hs, bbs)?;
    let lh = lawson_hanson::LhParams::default();
    Ok(match solver {
        Solver::Exact => lawson_hanson::solve_batch(&batch, &lh)?,
        Solver::Pgd => {
            let pp = pgd::PgdParams::default();
            let mut sols = backend.nnls_pgd(&batch, &pp)?;
            for (t, s) in sols.iter_mut().enumerate() {
                if s.max_kkt_violation > PGD_FALLBACK_KKT.max(pp.tol) {
                    if let Some(p) = batch.problem(t) {
                        *s = lawson_hanson::solve(&p, &lh)?;
                    }
                }
            }
            sols
        }
    })
}

/// Fits every target by the basis.
///
/// Long function: the checks, the Gram quantities (shared, separable or on the grid),
/// the per-channel solves and the grid errors in the order that fixes the results; each
/// step is a call, the body is their wiring under the objective.
pub fn fit(
    backend: &dyn Backend,
    coll: &Collection,
    basis: &[usize],
    targets: &[usize],
    p: &FitParams,
    progress: Progress<'_>,
) -> Result<Vec<TargetFit>, FitError> {
    if basis.is_empty() {
        return Err(FitError::EmptyBasis);
    }
    if targets.is_empty() {
        return Err(FitError::NoTargets);
    }
    for (i, &b) in basis.iter().enumerate() {
        if basis[..i].contains(&b) {
            return Err(FitError::DuplicateBasis(coll.materials()[b].name.clone()));
        }
    }
    if p.solver == Solver::Pgd && basis.len() + 1 > pgd::PGD_MAX_COLUMNS {
        return Err(FitError::BasisTooLarge {
            solver: "pgd",
            limit: pgd::PGD_MAX_COLUMNS - 1,
            found: basis.len(),
        });
    }
    let mut all: Vec<usize> = basis.to_vec();
    all.extend_from_slice(targets);
    let cells = fit_cells(coll, &all, p)?;
    if cells.cells.is_empty() {
        return Err(FitError::NoCells {
            mask: p.mask,
            stride: p.stride,
        });
    }
    let m = basis.len() + 1;
    let mut fits: Vec<TargetFit> = targets
        .iter()
        .map(|&t| TargetFit {
            material: coll.materials()[t].name.clone(),
            coefficients: vec![[0.0; 3]; m],
            residual: [0.0; 3],
            mae: 0.0,
            relative_residual: 0.0,
            relative_mae: 0.0,
            objective_residual: 0.0,
            kkt: [0.0; 3],
            iterations: [0; 3],
        })
        .collect();
    let weight = p.objective;
    let weighted = weight != TargetWeight::L2;
    // Per target, the objective's sums `sum_c sum_s W r^2` and `sum_c sum_s W b^2`.
    let mut objective_sums = vec![[0.0f64; 2]; targets.len()];
    let cpu = CpuBackend::new();
    let all_analytic = all
        .iter()
        .all(|&i| coll.materials()[i].analytic().is_some());
    let moments = (p.gram == GramMode::Auto && all_analytic)
        .then(|| CellMoments::new(&GridTables::new(), &cells));
    let mut target_norms = vec![0.0; targets.len()];
    let mut target_l1 = vec![0.0; targets.len()];
    // Under a weighted objective the three channels' systems come from one back-end call
    // (a network runs once per cell for its three channels).
    let mut systems = if weighted {
        weighted_systems(backend, coll, basis, targets, &cells, weight, progress)?.map(Some)
    } else {
        [None, None, None]
    };
    for (c, system) in systems.iter_mut().enumerate() {
        let sols = if let Some(sys) = system.take() {
            let ws = weighted_channel(coll, basis.len(), targets, &sys, c, weight)?;
            for (o, s) in objective_sums.iter_mut().zip(&ws) {
                o[0] += s.objective;
                o[1] += s.yy;
            }
            ws.into_iter().map(|s| s.solution).collect()
        } else {
            let ChannelGram {
                gram: g,
                h: hs,
                bb: bbs,
            } = channel_gram(backend, coll, basis, targets, &cells, c, p.gram, progress)?;
            target_norms
                .iter_mut()
                .zip(&bbs)
                .for_each(|(n, &b)| *n += b);
            solve_channel(backend, m, &g, &hs, &bbs, p.solver)?
        };
        let errs = grid_errors(
            coll,
            basis,
            targets,
            &sols,
            &cells,
            moments.as_ref(),
            c,
            &cpu,
        );
        for ((((f, s), e), tl1), tn) in fits
            .iter_mut()
            .zip(&sols)
            .zip(errs)
            .zip(&mut target_l1)
            .zip(&mut target_norms)
        {
            *tl1 += e.l1;
            if weighted {
                // The l2 path takes `sum_s w_s b^2` from the Gram pass; here, from the grid.
                *tn += e.energy;
            }
            for (k, &a) in s.x.iter().enumerate() {
                f.coefficients[k][c] = a;
            }
            f.residual[c] = e.residual;
            f.mae += e.mae / 3.0;
            f.kkt[c] = s.max_kkt_violation;
            f.iterations[c] = s.iterations;
        }
    }
    for ((f, &norm), o) in fits.iter_mut().zip(&target_norms).zip(&objective_sums) {
        let sq: f64 = f.residual.iter().map(|r| r * r).sum();
        f.relative_residual = if norm > 0.0 { sq / norm } else { 0.0 };
        f.objective_residual = if !weighted {
            f.relative_residual
        } else if o[1] > 0.0 {
            (o[0] / o[1]).max(0.0)
        } else {
            0.0
        };
    }
    for (f, &l1) in fits.iter_mut().zip(&target_l1) {
        f.relative_mae = if l1 > 0.0 { 3.0 * f.mae / l1 } else { 0.0 };
    }
    Ok(fits)
}

/// One target's fit of one channel under a weighted objective.
pub(crate) struct WeightedFit {
    /// The exact NNLS solution of its weighted system.
    pub(crate) solution: NnlsSolution,
    /// Its objective `sum_s W r^2` (from the system: `x' G x - 2 x' r + yy`, at least 0).
    pub(crate) objective: f64,
    /// `sum_s W b^2`.
    pub(crate) yy: f64,
}

/// The weighted systems (SPEC 11) of every target by `basis` plus the Lambertian column,
/// per channel, from the back-end ([`Backend::weighted_systems_per_channel`]: one pass for
/// every target and channel).
fn weighted_systems(
    backend: &dyn Backend,
    coll: &Collection,
    basis: &[usize],
    targets: &[usize],
    cells: &CellSet,
    weight: TargetWeight,
    progress: Progress<'_>,
) -> Result<[WeightedSystems; 3], FitError> {
    let lobes = |ids: &[usize], c: usize| -> Vec<Lobe> {
        ids.iter()
            .map(|&i| channel_lobe(&coll.materials()[i].data, c))
            .collect()
    };
    let b: [Vec<Lobe>; 3] = std::array::from_fn(|c| lobes(basis, c));
    let t: [Vec<Lobe>; 3] = std::array::from_fn(|c| lobes(targets, c));
    Ok(backend.weighted_systems_per_channel(
        [&b[0], &b[1], &b[2]],
        [&t[0], &t[1], &t[2]],
        cells,
        weight,
        progress,
    )?)
}

/// Every target's fit of channel `c` under the per-target weights `weight` (SPEC 11) from
/// its weighted system `sys` (basis of `k` materials): an exact Lawson-Hanson solve per
/// target.
pub(crate) fn weighted_channel(
    coll: &Collection,
    k: usize,
    targets: &[usize],
    sys: &WeightedSystems,
    c: usize,
    weight: TargetWeight,
) -> Result<Vec<WeightedFit>, FitError> {
    let m = k + 1;
    let lh = lawson_hanson::LhParams::default();
    targets
        .par_iter()
        .enumerate()
        .map(|(t, &ti)| {
            let g = sys.gram(t);
            let (h, yy) = (sys.rhs(t), sys.yy(t));
            check_weighted_system(&g, h, yy, weight).map_err(|detail| FitError::Weights {
                material: coll.materials()[ti].name.clone(),
                channel: c,
                detail,
            })?;
            let problem = crate::nnls::GramProblem::new(m, &g, h, yy)?;
            let solution = lawson_hanson::solve(&problem, &lh)?;
            let objective = problem.objective(&solution.x)?.max(0.0);
            Ok(WeightedFit {
                solution,
                objective,
                yy,
            })
        })
        .collect()
}

/// Refuses a target's weighted system (SPEC 11) that cannot mean what it says: a sum that
/// overflowed (values times weights beyond f64: `eps` too small for the data), or weights
/// that vanish on every cell (`G[0][0] = sum_s W / pi^2` is not a positive normal number:
/// the fit would fit nothing and its objective residual of 0 would read as perfect).
/// Returns the reason, naming the objective and its eps.
pub(crate) fn check_weighted_system(
    g: &[f64],
    h: &[f64],
    yy: f64,
    weight: TargetWeight,
) -> Result<(), String> {
    let objective = match weight {
        TargetWeight::Relative { eps } => {
            format!("the relative objective's weights 1/(f + eps)^2 at eps {eps:e}")
        }
        w => format!("the {} objective's weights", w.kind().name()),
    };
    if !yy.is_finite() || h.iter().chain(g).any(|v| !v.is_finite()) {
        let hint = match weight {
            TargetWeight::Relative { eps } => format!(
                " (up to 1/eps^2 = {:e} where the reflectance is 0): give a larger eps",
                1.0 / (eps * eps)
            ),
            _ => String::new(),
        };
        return Err(format!(
            "{objective}, times its values and the basis values, overflow f64{hint}"
        ));
    }
    let g00 = g.first().copied().unwrap_or(0.0);
    if !(g00.is_normal() && g00 > 0.0) {
        return Err(format!(
            "{objective} vanish on every fit cell (their sum is {g00:e}): it would fit nothing, and an objective residual of 0 would read as a perfect fit"
        ));
    }
    Ok(())
}

/// The fitted combination of channel `c` at the given cells (f64).
pub(crate) fn combination_values(
    coll: &Collection,
    basis: &[usize],
    fit: &TargetFit,
    c: usize,
    cells: &[u32],
) -> Vec<f64> {
    let cpu = CpuBackend::new();
    let mut out = cpu.values_f64(&LAMBERTIAN, cells);
    out.iter_mut().for_each(|v| *v *= fit.coefficients[0][c]);
    for (k, &b) in basis.iter().enumerate() {
        let a = fit.coefficients[k + 1][c];
        if a != 0.0 {
            let v = cpu.values_f64(&channel_lobe(&coll.materials()[b].data, c), cells);
            out.iter_mut().zip(v).for_each(|(o, x)| *o += a * x);
        }
    }
    out
}

#[cfg(test)]
mod weighted_system_tests {
    use super::*;

    #[test]
    fn columns_added_four_at_a_time_are_one_at_a_time_to_the_bit() {
        let mut s = 7u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.3)
                * 1e3f64.powf(((s >> 3) % 5) as f64 - 2.0)
        };
        let n = 203;
        for count in 0..11 {
            let cols: Vec<Vec<f64>> = (0..count)
                .map(|k| (0..n - (k % 3)).map(|_| next()).collect())
                .collect();
            let a: Vec<f64> = (0..count).map(|_| next()).collect();
            let mut want = vec![-0.0; n];
            for (c, &x) in cols.iter().zip(&a) {
                for (f, &v) in want.iter_mut().zip(c) {
                    *f += x * v;
                }
            }
            let mut got = vec![-0.0; n];
            add_columns(
                &mut got,
                cols.iter().map(Vec::as_slice).zip(a.iter().copied()),
            );
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&got), bits(&want), "{count} columns");
        }
    }

    /// Audit 3, D1: a weighted system whose weights vanish is refused (its objective
    /// residual of 0 read as perfect), and one that overflowed names eps.
    #[test]
    fn vanishing_or_overflowing_weights_are_refused_naming_eps() {
        let w = TargetWeight::Relative { eps: 1e-90 };
        let e = check_weighted_system(&[0.0; 4], &[0.0; 2], 0.0, w).expect_err("vanish");
        assert!(e.contains("vanish") && e.contains("eps 1e-90"), "{e}");
        let e = check_weighted_system(&[f64::INFINITY, 0.0, 0.0, 1.0], &[0.0; 2], 1.0, w)
            .expect_err("overflow");
        assert!(
            e.contains("overflow f64") && e.contains("give a larger eps"),
            "{e}"
        );
        assert!(check_weighted_system(&[1.0, 0.0, 0.0, 1.0], &[0.5; 2], 1.0, w).is_ok());
    }
}
