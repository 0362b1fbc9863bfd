//! `cv`: cross-validated comparison of basis-selection methods (SPEC 8).

use super::Grid;
use crate::backend::{Backend, Progress};
use crate::collection::Collection;
use crate::distance::Metric;
use crate::select::cv::{cross_validate, CvMethod, CvParams, CvResult};
use crate::select::{GaParams, ObjectiveParams};
use crate::Result;

/// `brdf-basis cv` (without `--acquisition`): its settings, with the defaults of
/// `cv --help` ([`CvParams::default`], [`GaParams::default`]).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct CvRequest {
    /// `--methods`.
    pub methods: Vec<CvMethod>,
    /// `-k`: basis sizes.
    pub ks: Vec<usize>,
    /// `--folds`.
    pub folds: usize,
    /// `--metric`: distance of the clustering methods.
    pub metric: Metric,
    /// `--mask`, `--weighting`, `--stride`.
    pub grid: Grid,
    /// `--runs`: k-medoids restarts and GCUK runs per fold.
    pub runs: usize,
    /// `--ga-population`.
    pub ga_population: usize,
    /// `--ga-generations`.
    pub ga_generations: usize,
    /// `--render-size`: pixels of the renders of the image errors.
    pub render_size: u32,
    /// `--seed`.
    pub seed: u64,
    /// `--objective` and `--eps` (SPEC 11): the selection's shared weights and the
    /// held-out fits' per-target weights.
    pub objective: crate::backend::weighted::TargetWeight,
    /// The appearance metrics of the held-out fits (`--no-appearance` turns them off).
    pub appearance: bool,
}

impl Default for CvRequest {
    fn default() -> Self {
        let d = CvParams::default();
        let g = GaParams::default();
        Self {
            methods: d.methods,
            ks: d.ks,
            folds: d.folds,
            metric: d.metric,
            grid: Grid::default(),
            runs: d.runs,
            ga_population: g.population,
            ga_generations: g.generations,
            render_size: d.render_size,
            seed: d.seed,
            objective: super::DEFAULT_OBJECTIVE,
            appearance: d.appearance,
        }
    }
}

impl CvRequest {
    /// The library's parameters.
    fn params(&self) -> CvParams {
        CvParams {
            methods: self.methods.clone(),
            ks: self.ks.clone(),
            folds: self.folds,
            seed: self.seed,
            objective: ObjectiveParams::default()
                .mask(self.grid.mask)
                .weighting(self.grid.weighting)
                .stride(self.grid.stride)
                .objective(self.objective),
            metric: self.metric,
            runs: self.runs,
            ga: GaParams::default()
                .population(self.ga_population)
                .generations(self.ga_generations)
                .seed(self.seed),
            render_size: self.render_size,
            appearance: self.appearance,
        }
    }

    /// The settings against a collection of `n` materials (methods, folds, sizes, runs,
    /// GA, grid and render settings: [`CvParams::check`]).
    ///
    /// # Errors
    /// [`crate::Error::Selection`] naming the setting.
    pub fn check(&self, n: usize) -> Result<()> {
        self.params().check(n)?;
        Ok(())
    }

    /// Runs the cross-validation on `coll` and returns what `cv --json` writes (its
    /// [`CvResult::markdown`] is `--markdown`).
    ///
    /// # Errors
    /// The settings' errors before any work, then the stages' errors.
    pub fn run(
        &self,
        backend: &dyn Backend,
        coll: &Collection,
        progress: Progress<'_>,
    ) -> Result<CvResult> {
        let valid = self.params().check(coll.len())?;
        Ok(cross_validate(backend, coll, &valid, progress)?)
    }
}
