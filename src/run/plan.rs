//! `plan`: where to measure a new material (SPEC 10).

use super::{all_others, check_restarts, indices_of, refuse};
use crate::acquire::{cell_candidates, plan_with_progress, Candidate};
use crate::acquire::{read_candidates, Criterion, Plan, PlanParams};
use crate::backend::weighted::TargetWeight;
use crate::backend::{Backend, Progress};
use crate::collection::Collection;
use crate::fit::FitParams;
use crate::Result;
use std::path::PathBuf;

/// `brdf-basis plan`: its settings, with the defaults of `plan --help`
/// ([`PlanParams::default`]).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct PlanRequest {
    /// `--basis`: the basis materials (no default).
    pub basis: Vec<String>,
    /// `--targets`: training materials (`None`: every material outside the basis).
    pub targets: Option<Vec<String>>,
    /// `--candidates`: directions the instrument can reach, a samples file (`None`: the
    /// cell centres of the evaluation mask).
    pub candidates: Option<PathBuf>,
    /// `-n`: samples to plan.
    pub n: usize,
    /// `--criterion`: error, condition or random (`nielsen` is refused: see [`Self::check`]).
    pub criterion: Criterion,
    /// `--candidates-per-step` (0: all).
    pub candidates_per_step: usize,
    /// `--shortlist`: error, screened candidates fitted exactly per step (0: all examined).
    pub shortlist: usize,
    /// `--restarts`: error, seeded greedy paths, 1 to 64.
    pub restarts: usize,
    /// `--seed`.
    pub seed: u64,
    /// `--objective` and `--eps` (SPEC 11): the weights of the plan's rows and of its
    /// training fits.
    pub objective: TargetWeight,
}

impl PlanRequest {
    /// The files this request reads besides the collection, with what they are called in
    /// messages: the output layer refuses any output that names one of them.
    pub fn input_files(&self) -> Vec<(PathBuf, &'static str)> {
        self.candidates
            .iter()
            .map(|c| (c.clone(), "candidates file"))
            .collect()
    }

    /// The defaults with `basis`.
    pub fn new(basis: Vec<String>) -> Self {
        let d = PlanParams::default();
        Self {
            basis,
            targets: None,
            candidates: None,
            n: d.n,
            criterion: d.criterion,
            candidates_per_step: d.candidates_per_step,
            shortlist: d.shortlist,
            restarts: d.restarts,
            seed: d.seed,
            objective: super::DEFAULT_OBJECTIVE,
        }
    }

    /// The rules of the settings: a criterion whose plan `fit --samples` can use, 1 to 64
    /// restarts.
    ///
    /// # Errors
    /// [`crate::error::RequestError`] naming the setting.
    pub fn check(&self) -> Result<()> {
        if self.criterion == Criterion::Nielsen {
            refuse!("--criterion nielsen: the peer baseline (Nielsen et al. 2015) reconstructs with its own PCA and ridge regression, not with a basis, so its plan is not one `fit --samples` can use; plan offers error, condition and random, and `cv --acquisition --plans nielsen` compares the baseline");
        }
        check_restarts(self.restarts)
    }

    /// The library's parameters of the plan.
    fn params(&self) -> PlanParams {
        PlanParams {
            n: self.n,
            criterion: self.criterion,
            candidates_per_step: self.candidates_per_step,
            shortlist: self.shortlist,
            seed: self.seed,
            fit: FitParams {
                objective: self.objective,
                ..FitParams::default()
            },
            restarts: self.restarts,
        }
    }

    /// Plans the samples on `coll` (the Gram quantities on `backend`) and returns the plan
    /// (`plan --json` is its JSON, `plan --out` its
    /// [`crate::acquire::plan_csv`]).
    ///
    /// # Errors
    /// [`crate::error::RequestError`], an unknown material, an unreadable candidates file, then
    /// the plan's own errors.
    pub fn run(&self, backend: &dyn Backend, coll: &Collection) -> Result<Plan> {
        self.run_with_progress(backend, coll, &|_, _| {})
    }

    /// [`Self::run`], reporting `progress(steps done, steps)` (every restart's steps); it
    /// is called per candidate within a step too, so a caller can stop the plan from it.
    ///
    /// # Errors
    /// As [`Self::run`].
    pub fn run_with_progress(
        &self,
        backend: &dyn Backend,
        coll: &Collection,
        progress: Progress<'_>,
    ) -> Result<Plan> {
        self.check()?;
        self.objective.check()?;
        let basis = indices_of(coll, &self.basis)?;
        let targets = match &self.targets {
            Some(t) => indices_of(coll, t)?,
            None => all_others(coll, &basis),
        };
        let p = self.params();
        let cands: Vec<Candidate> = match &self.candidates {
            Some(path) => read_candidates(path)?
                .into_iter()
                .map(|(wi, wo)| Candidate { wi, wo, cell: None })
                .collect(),
            None => {
                let all: Vec<usize> = basis.iter().chain(&targets).copied().collect();
                cell_candidates(coll, &all, &p.fit)?
            }
        };
        Ok(plan_with_progress(
            backend, coll, &basis, &targets, &cands, &p, progress,
        )?)
    }
}
