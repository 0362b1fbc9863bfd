//! `cv`: cross-validated comparison of basis-selection methods (SPEC 8).

use super::{refuse, Ctx, ObjectiveSetting, Refusal, Request};
use crate::distance::Metric;
use crate::merl::GridSpec;
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
    /// `--metric`: distance of the clustering methods (default: [`CvParams::default`]'s).
    pub metric: Option<Metric>,
    /// `--mask`, `--weighting`, `--stride`.
    pub grid: GridSpec,
    /// `--runs`: k-medoids restarts and GCUK runs per fold (default:
    /// [`CvParams::default`]'s).
    pub runs: Option<usize>,
    /// `--ga-population` (default: [`GaParams::default`]'s).
    pub ga_population: Option<usize>,
    /// `--ga-generations` (default: [`GaParams::default`]'s).
    pub ga_generations: Option<usize>,
    /// `--render-size`: pixels of the renders of the image errors.
    pub render_size: u32,
    /// `--seed`.
    pub seed: u64,
    /// `--objective` and `--eps` (SPEC 11): the selection's shared weights and the
    /// held-out fits' per-target weights, as given.
    pub objective: ObjectiveSetting,
    /// The appearance metrics of the held-out fits (`--no-appearance` turns them off).
    pub appearance: bool,
}

impl Default for CvRequest {
    fn default() -> Self {
        let d = CvParams::default();
        Self {
            methods: d.methods,
            ks: d.ks,
            folds: d.folds,
            metric: None,
            grid: GridSpec::default(),
            runs: None,
            ga_population: None,
            ga_generations: None,
            render_size: d.render_size,
            seed: d.seed,
            objective: ObjectiveSetting::default(),
            appearance: d.appearance,
        }
    }
}

impl CvRequest {
    /// The library's parameters, the defaults applied.
    fn params(&self) -> Result<CvParams> {
        let d = CvParams::default();
        let g = GaParams::default();
        Ok(CvParams {
            methods: self.methods.clone(),
            ks: self.ks.clone(),
            folds: self.folds,
            seed: self.seed,
            objective: ObjectiveParams::default()
                .grid(self.grid)
                .objective(self.objective.weight()?),
            metric: self.metric.unwrap_or(d.metric),
            runs: self.runs.unwrap_or(d.runs),
            ga: GaParams::default()
                .population(self.ga_population.unwrap_or(g.population))
                .generations(self.ga_generations.unwrap_or(g.generations))
                .seed(self.seed),
            render_size: self.render_size,
            appearance: self.appearance,
        })
    }

    /// Every setting that only some methods use: whether it was given, its flag and the
    /// methods that use it.
    fn method_settings(&self) -> [(bool, &'static str, &'static [CvMethod]); 4] {
        const CLUSTERING: &[CvMethod] = &[CvMethod::Kmedoids, CvMethod::Gcuk];
        [
            (self.runs.is_some(), "--runs", CLUSTERING),
            (self.metric.is_some(), "--metric", CLUSTERING),
            (
                self.ga_population.is_some(),
                "--ga-population",
                &[CvMethod::Ga],
            ),
            (
                self.ga_generations.is_some(),
                "--ga-generations",
                &[CvMethod::Ga],
            ),
        ]
    }
}

impl Request for CvRequest {
    type Output = CvResult;

    /// The rules of the settings that need no collection: a setting that none of
    /// `--methods` uses, and the objective's ([`ObjectiveSetting::weight`]).
    fn check(&self) -> Result<(), Refusal> {
        for (given, flag, users) in self.method_settings() {
            if given && !self.methods.iter().any(|m| users.contains(m)) {
                let users: Vec<&str> = users.iter().map(|m| m.name()).collect();
                let methods: Vec<&str> = self.methods.iter().map(|m| m.name()).collect();
                refuse!(Refusal::NotApplicable {
                    setting: flag,
                    value: None,
                    applies_to: super::list(&users),
                    not_to: format!("--methods {}", methods.join(",")),
                    why: None,
                });
            }
        }
        self.objective.weight()?;
        Ok(())
    }

    /// [`Self::check`], then the settings against a collection of `n` materials
    /// (methods, folds, sizes, runs, GA, grid and render settings: [`CvParams::check`]).
    fn check_count(&self, n: usize) -> Result<()> {
        self.check()?;
        self.params()?.check(n)?;
        Ok(())
    }

    /// Runs the cross-validation on the collection and returns what `cv --json` writes
    /// (its [`CvResult::markdown`] is `--markdown`).
    fn run(&self, ctx: &Ctx<'_>) -> Result<CvResult> {
        let (backend, coll) = (ctx.need_backend()?, ctx.need_collection()?);
        self.check()?;
        let valid = self.params()?.check(coll.len())?;
        Ok(cross_validate(backend, coll, &valid, ctx.progress)?)
    }
}
