//! `plan`: where to measure a new material (SPEC 10).

use super::{
    all_others, check_restarts, indices_of, refuse, Ctx, ObjectiveSetting, Refusal, Request,
};
use crate::acquire::{cell_candidates, plan_with_progress, Candidate};
use crate::acquire::{read_candidates, Criterion, Plan, PlanParams};
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
    /// `--candidates-per-step`: error and condition (0: all; default:
    /// [`PlanParams::default`]'s).
    pub candidates_per_step: Option<usize>,
    /// `--shortlist`: error, screened candidates fitted exactly per step (0: all examined;
    /// default: [`PlanParams::default`]'s).
    pub shortlist: Option<usize>,
    /// `--restarts`: error, seeded greedy paths, 1 to 64 (default:
    /// [`PlanParams::default`]'s).
    pub restarts: Option<usize>,
    /// `--seed`: of the random plans, the candidate subsets of the error and condition
    /// plans and the error plans' exploration (default [`super::SEED`]); a condition plan
    /// examining every candidate (`--candidates-per-step 0`) draws nothing at random and
    /// refuses it.
    pub seed: Option<u64>,
    /// `--objective` and `--eps` (SPEC 11): the weights of the plan's rows and of its
    /// training fits, as given.
    pub objective: ObjectiveSetting,
}

/// A criterion whose plan `fit --samples` can use: not `nielsen` (the rule of
/// [`PlanRequest::check`] and of [`crate::plan_samples`]).
pub(crate) fn check_criterion(criterion: Criterion) -> std::result::Result<(), Refusal> {
    if criterion == Criterion::Nielsen {
        refuse!(Refusal::NotOffered {
            setting: "--criterion",
            value: "nielsen".into(),
            why: "the peer baseline (Nielsen et al. 2015) reconstructs with its own PCA and ridge regression, not with a basis, so its plan is not one `fit --samples` can use; plan offers error, condition and random, and `cv --acquisition --plans nielsen` compares the baseline".into(),
        });
    }
    Ok(())
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
            candidates_per_step: None,
            shortlist: None,
            restarts: None,
            seed: None,
            objective: ObjectiveSetting::default(),
        }
    }

    /// `--candidates-per-step` with its default.
    pub fn candidates_per_step(&self) -> usize {
        self.candidates_per_step
            .unwrap_or(PlanParams::default().candidates_per_step)
    }

    /// `--shortlist` with its default.
    pub fn shortlist(&self) -> usize {
        self.shortlist.unwrap_or(PlanParams::default().shortlist)
    }

    /// `--seed` with its default.
    pub fn seed(&self) -> u64 {
        self.seed.unwrap_or(PlanParams::default().seed)
    }

    /// `--restarts` with its default.
    pub fn restarts(&self) -> usize {
        self.restarts.unwrap_or(PlanParams::default().restarts)
    }

    /// The library's parameters of the plan.
    fn params(&self) -> Result<PlanParams> {
        Ok(PlanParams {
            n: self.n,
            criterion: self.criterion,
            candidates_per_step: self.candidates_per_step(),
            shortlist: self.shortlist(),
            seed: self.seed(),
            fit: FitParams {
                objective: self.objective.weight()?,
                ..FitParams::default()
            },
            restarts: self.restarts(),
        })
    }
}

impl Request for PlanRequest {
    type Output = Plan;

    /// The rules of the settings: a criterion whose plan `fit --samples` can use, no
    /// setting the criterion does not use (`criterion_settings`), no `--seed` for a plan
    /// that draws nothing at random, 1 to 64 restarts, the objective's
    /// ([`ObjectiveSetting::weight`]).
    fn check(&self) -> std::result::Result<(), Refusal> {
        check_criterion(self.criterion)?;
        let given = [
            self.candidates_per_step.is_some(),
            self.shortlist.is_some(),
            self.restarts.is_some(),
        ];
        criterion_settings("--criterion", &[self.criterion], given)?;
        if let (Some(s), Criterion::Condition, 0) =
            (self.seed, self.criterion, self.candidates_per_step())
        {
            refuse!(Refusal::DoesNotApply {
                settings: vec!["--seed"],
                shown: format!("--seed {s}"),
                context: "to plan --criterion condition --candidates-per-step 0".into(),
                why: ": it examines every candidate at each step and draws nothing at random; leave it out".into(),
            });
        }
        check_restarts(self.restarts())?;
        self.objective.weight()?;
        Ok(())
    }

    /// Plans the samples on the collection (the Gram quantities on the back-end) and
    /// returns the plan (`plan --json` is its JSON, `plan --out` its
    /// [`crate::acquire::plan_csv`]). The progress callback gets `(steps done, steps)`
    /// (every restart's steps); it is called per candidate within a step too, so a
    /// caller can stop the plan from it.
    fn run(&self, ctx: &Ctx<'_>) -> Result<Plan> {
        let (backend, coll) = (ctx.need_backend()?, ctx.need_collection()?);
        self.check()?;
        let basis = indices_of(coll, &self.basis)?;
        let targets = match &self.targets {
            Some(t) => indices_of(coll, t)?,
            None => all_others(coll, &basis),
        };
        refuse_basis_twins(coll, &basis, &targets)?;
        let p = self.params()?;
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
            backend,
            coll,
            &basis,
            &targets,
            &cands,
            &p,
            ctx.progress,
        )?)
    }
}

/// Refuses a target whose values are a basis material's (the same analytic parameters or
/// the same measured table under another name): the basis fits it exactly from any
/// sample, so its score is 0 after the first and a plan would choose samples on a zero
/// objective (audit 3, T7).
fn refuse_basis_twins(coll: &Collection, basis: &[usize], targets: &[usize]) -> Result<()> {
    use crate::collection::MaterialData as D;
    let m = coll.materials();
    let same = |a: &D, b: &D| match (a, b) {
        (D::Analytic(x), D::Analytic(y)) => format!("{x:?}") == format!("{y:?}"),
        (D::Measured(x), D::Measured(y)) => x.rgb == y.rgb,
        _ => false,
    };
    for &t in targets {
        if let Some(&b) = basis
            .iter()
            .find(|&&b| b != t && same(&m[t].data, &m[b].data))
        {
            refuse!(Refusal::SameAsBasis {
                target: crate::error::short_name(&m[t].name).to_string(),
                basis: crate::error::short_name(&m[b].name).to_string(),
            });
        }
    }
    Ok(())
}

/// Refuses a plan setting that none of `criteria` (given by `by`: `--criterion` or
/// `--plans`) uses: `given` says whether
/// `--candidates-per-step`, `--shortlist` and `--restarts` were given (the one table of
/// which criterion uses which, for `plan` and `cv --acquisition`).
///
/// # Errors
/// [`Refusal::NotApplicable`] naming the setting and the criteria that use it.
pub(super) fn criterion_settings(
    by: &str,
    criteria: &[Criterion],
    given: [bool; 3],
) -> std::result::Result<(), Refusal> {
    use Criterion::{Condition, Error, Nielsen};
    let table: [(&str, &[Criterion]); 3] = [
        ("--candidates-per-step", &[Error, Condition, Nielsen]),
        ("--shortlist", &[Error]),
        ("--restarts", &[Error]),
    ];
    for ((flag, users), given) in table.into_iter().zip(given) {
        if given && !criteria.iter().any(|c| users.contains(c)) {
            let users: Vec<&str> = users.iter().map(|c| c.as_str()).collect();
            let got: Vec<&str> = criteria.iter().map(|c| c.as_str()).collect();
            refuse!(Refusal::NotApplicable {
                setting: flag,
                value: None,
                applies_to: format!("{} plans", super::list(&users)),
                not_to: format!("{by} {}", got.join(",")),
                why: None,
            });
        }
    }
    Ok(())
}
