//! K-fold cross-validation over materials of basis-selection methods (SPEC 8).
//!
//! A permutation drawn from the seed (`ChaCha8Rng::seed_from_u64(seed)`, Fisher-Yates)
//! splits the collection into K folds of sizes differing by at most one (the first
//! `N mod K` folds hold one more). For each fold every method chooses its basis from the
//! other folds only:
//!
//! * `greedy`, `swap` (from the greedy basis), `ga`: candidates and targets are the
//!   training materials; the objective's Gram matrices (of all N, computed once) are only
//!   read at training rows and columns.
//! * `kmedoids` (PAM, `runs` restarts, lowest loss) and `gcuk` (fixed `k_min = k_max = k`,
//!   `runs` runs, lowest Davies-Bouldin index): on the distance matrix (computed once for
//!   all N) restricted to the training materials.
//! * `empirical`: the leave-one-out fits of the training materials by the other training
//!   materials (from the objective's Gram matrices: under `relative` or `log`, the
//!   shared weights of `select --method empirical`); the basis is the k materials contributing to the most fits (ties:
//!   collection order).
//! * `random`: k training materials drawn uniformly (seed `seed + 1000 fold + k`).
//!
//! Each held-out material is then fitted by every basis: `rho` from the Gram form (SPEC 8),
//! MAE on the grid (SPEC 5), and the normalised image error of renders of the fit against
//! the material (SPEC 7: light (45, 45), gamma 2.2, exposure 0). Per method and k: mean and
//! median of each; between every two methods at each k, paired two-sided Wilcoxon
//! signed-rank tests on the held-out values (p = 1 when every difference is zero).

pub mod evaluate;
pub mod folds;
mod params;
pub mod report;

pub(crate) use folds::make_folds;
pub use params::*;

use super::objective::Objective;
use super::SelectionError;
use crate::backend::{Backend, Progress};
use crate::collection::Collection;
use crate::distance::{distance_matrix, DistanceMatrix, DistanceParams};

/// One held-out material fitted by one method's basis.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeldOut {
    /// Material.
    pub material: String,
    /// Its fold.
    pub fold: usize,
    /// `rho` of SPEC 8.
    pub rho: f64,
    /// MAE of SPEC 5 (grid, averaged over channels).
    pub mae: f64,
    /// Normalised image error (SPEC 7).
    pub image_error: f64,
    /// Relative residual under the objective's per-target weights (SPEC 11's `rho_W`;
    /// `rho` for `l2`).
    #[serde(default)]
    pub objective_rho: f64,
    /// log-RMSE (SPEC 11) on the grid.
    #[serde(default)]
    pub log_rmse: f64,
    /// The image metrics under the four lights of SPEC 11 (absent when not asked for).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub appearance: Option<crate::eval::appearance::Appearance>,
}

/// Results of one method at one k.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CvMethodResult {
    /// Method name.
    pub method: String,
    /// Basis size.
    pub k: usize,
    /// The basis chosen in each fold.
    pub fold_bases: Vec<Vec<String>>,
    /// Every held-out material (fold order, then collection order).
    pub held_out: Vec<HeldOut>,
    /// Mean held-out rho.
    pub mean_rho: f64,
    /// Median held-out rho.
    pub median_rho: f64,
    /// Mean held-out MAE.
    pub mean_mae: f64,
    /// Median held-out MAE.
    pub median_mae: f64,
    /// Mean held-out image error.
    pub mean_image_error: f64,
    /// Median held-out image error.
    pub median_image_error: f64,
    /// Mean held-out log-RMSE.
    #[serde(default)]
    pub mean_log_rmse: f64,
    /// Mean over held-out materials of the image metrics averaged over the four lights
    /// (absent without appearance metrics).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub appearance: Option<AppearanceMeans>,
}

/// Means over held-out materials of the appearance metrics (SPEC 11).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AppearanceMeans {
    /// Image error under the paper's light (45, 45) at SPEC 11's render size.
    pub image_error_paper_light: f64,
    /// Image error, mean over the four lights.
    pub image_error: f64,
    /// Median over held-out materials of the four-light image error.
    pub median_image_error: f64,
    /// CIEDE2000, mean over the four lights.
    pub ciede2000: f64,
    /// ΔE_ITP (ITU-R BT.2124), mean over the four lights.
    pub delta_e_itp: f64,
    /// FLIP under the paper's light.
    pub flip_paper_light: f64,
    /// FLIP, mean over the four lights.
    pub flip: f64,
    /// Median over held-out materials of the four-light FLIP.
    pub median_flip: f64,
}

/// Paired Wilcoxon signed-rank tests between two methods at one k.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CvTest {
    /// First method.
    pub a: String,
    /// Second method.
    pub b: String,
    /// Basis size.
    pub k: usize,
    /// Two-sided p on the held-out rho.
    pub wilcoxon_p: f64,
    /// Two-sided p on the held-out MAE.
    pub wilcoxon_p_mae: f64,
    /// Two-sided p on the held-out image errors.
    pub wilcoxon_p_image_error: f64,
    /// Number of held-out materials where `a` has the lower rho.
    pub a_better: usize,
    /// Number where `b` has the lower rho.
    pub b_better: usize,
}

/// The cross-validation result (the `cv` JSON of SPEC-cli).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CvResult {
    /// The folds, by name (collection order within a fold).
    pub folds: Vec<Vec<String>>,
    /// Seed.
    pub seed: u64,
    /// Per method and k.
    pub results: Vec<CvMethodResult>,
    /// Paired tests.
    pub tests: Vec<CvTest>,
    /// Fit mask.
    pub mask: String,
    /// Weighting.
    pub weighting: String,
    /// The fit objective (SPEC 11).
    #[serde(default = "l2_name")]
    pub objective: String,
    /// `eps` of the `relative` objective.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eps: Option<f64>,
    /// [`Collection::fingerprint`] of the collection cross-validated.
    pub collection_fingerprint: String,
    /// The size of the renders of `mean_image_error` (pixels), for the Markdown's headers
    /// (audit 3, U5: the appearance table's image error is at 256 px); not in the JSON,
    /// whose fields stay as they were (`None` when read back).
    #[serde(skip)]
    pub render_size: Option<u32>,
}

/// Runs the cross-validation: builds the objective and (for clustering methods) the
/// distance matrix of the whole collection once, then `cross_validate_with`.
pub fn cross_validate(
    backend: &dyn Backend,
    coll: &Collection,
    p: &ValidCvParams,
    progress: Progress<'_>,
) -> Result<CvResult, SelectionError> {
    let q = p.params();
    let obj = Objective::new(backend, coll, &q.objective.check()?, &|_, _| {})?;
    let dist = if q.methods.iter().any(|m| m.clustering()) {
        let dp = DistanceParams::default()
            .metric(q.metric)
            .mask(q.objective.mask)
            .weighting(q.objective.weighting)
            .stride(q.objective.stride)
            .check(coll)?;
        Some(distance_matrix(backend, coll, &dp, &|_, _| {})?)
    } else {
        None
    };
    cross_validate_on(backend, coll, &obj, dist.as_ref(), p, progress)
}

fn l2_name() -> String {
    "l2".into()
}

/// [`cross_validate_with`] on the CPU back-end (the held-out fits of a weighted objective
/// go through a back-end: [`cross_validate_on`] names it).
pub(crate) fn cross_validate_with(
    coll: &Collection,
    obj: &Objective,
    dist: Option<&DistanceMatrix>,
    vp: &ValidCvParams,
    progress: Progress<'_>,
) -> Result<CvResult, SelectionError> {
    let cpu = crate::backend::cpu::CpuBackend::new();
    cross_validate_on(&cpu, coll, obj, dist, vp, progress)
}

/// Runs the cross-validation with a given objective (of `coll`) and distance matrix (of
/// `coll`; needed only by the clustering methods): the fold bases ([`folds`]), then every
/// held-out material by every basis and the paired tests ([`evaluate`]); the weighted
/// held-out fits of `relative` and `log` run on `backend`.
/// `progress(done, total)` counts (fold, method, k) selections.
pub(crate) fn cross_validate_on(
    backend: &dyn Backend,
    coll: &Collection,
    obj: &Objective,
    dist: Option<&DistanceMatrix>,
    vp: &ValidCvParams,
    progress: Progress<'_>,
) -> Result<CvResult, SelectionError> {
    let p = vp.params();
    let n = coll.len();
    if obj.len() != n || dist.is_some_and(|d| d.names().len() != n) {
        return Err(SelectionError::InvalidParam {
            name: "objective / distances",
            value: format!(
                "{} / {} materials",
                obj.len(),
                dist.map_or(n, |d| d.names().len())
            ),
            expected: "the same materials as the collection",
        });
    }
    let folds = make_folds(n, p.folds, p.seed);
    let bases = folds::fold_bases(obj, dist, &folds, vp, progress)?;
    let eval = evaluate::Evaluator::new(
        backend,
        coll,
        obj,
        &p.objective.fit_params(),
        p.render_size,
        p.appearance,
    )?;
    let methods: Vec<&str> = p.methods.iter().map(|m| m.name()).collect();
    let results = eval.methods(&methods, &p.ks, &folds, &bases)?;
    let tests = evaluate::paired_tests(&p.ks, &results)?;
    let names = coll.names();
    Ok(CvResult {
        folds: folds
            .iter()
            .map(|f| f.iter().map(|&i| names[i].clone()).collect())
            .collect(),
        seed: p.seed,
        results,
        tests,
        mask: p.objective.mask.to_string(),
        weighting: p.objective.weighting.to_string(),
        objective: p.objective.objective.kind().name().into(),
        eps: p.objective.objective.eps(),
        collection_fingerprint: coll.fingerprint(),
        render_size: Some(p.render_size),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folds_partition_the_collection_evenly() {
        let f = make_folds(23, 5, 7);
        let sizes: Vec<usize> = f.iter().map(Vec::len).collect();
        assert_eq!(sizes, vec![5, 5, 5, 4, 4]);
        let mut all: Vec<usize> = f.concat();
        all.sort_unstable();
        assert_eq!(all, (0..23).collect::<Vec<_>>());
        assert_eq!(f, make_folds(23, 5, 7));
        assert_ne!(f, make_folds(23, 5, 8));
    }
}
