//! The types of a plan (SPEC 10): the criterion, its parameters, the candidates and the
//! `plan --json` schema. They sit beside the greedy plans ([`super::plan()`]) and the
//! [`super::nielsen`] baseline, which both make plans, so that neither imports the other
//! for them.

use super::eval::angles_deg;
use super::AcquireError;
use crate::fit::FitParams;

/// A planning criterion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Criterion {
    /// Greedy on the mean training score.
    Error,
    /// Greedy on the condition number of the sampled design.
    Condition,
    /// Uniform random candidates.
    Random,
    /// The peer baseline of Nielsen et al. 2015 (its own PCA of the training materials, no
    /// basis).
    Nielsen,
}

impl Criterion {
    /// The spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            Criterion::Error => "error",
            Criterion::Condition => "condition",
            Criterion::Random => "random",
            Criterion::Nielsen => "nielsen",
        }
    }
}

impl std::str::FromStr for Criterion {
    type Err = AcquireError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        [
            Criterion::Error,
            Criterion::Condition,
            Criterion::Random,
            Criterion::Nielsen,
        ]
        .into_iter()
        .find(|c| c.as_str() == s)
        .ok_or_else(|| AcquireError::InvalidParam {
            name: "criterion",
            value: s.into(),
            expected: "one of error, condition, random, nielsen".into(),
        })
    }
}

/// A candidate direction pair, with its MERL cell when it sits at a cell centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// Incoming direction.
    pub wi: [f64; 3],
    /// Outgoing direction.
    pub wo: [f64; 3],
    /// The MERL cell of SPEC 2 when the pair is that cell's centre.
    pub cell: Option<u32>,
}

/// A planned sample as written (`plan --json`, `cv --acquisition`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PlannedSample {
    /// Incoming polar angle, degrees.
    pub theta_i: f64,
    /// Incoming azimuth, degrees.
    pub phi_i: f64,
    /// Outgoing polar angle, degrees.
    pub theta_o: f64,
    /// Outgoing azimuth, degrees.
    pub phi_o: f64,
    /// MERL cell index when the sample sits at a cell centre, else null.
    pub cell: Option<u32>,
}

impl From<&Candidate> for PlannedSample {
    /// The candidate's angles, re-derived from its unit vectors and rounded to 1e-9
    /// degrees (a candidate at 30 degrees is written 30, not 29.999999999999993; a phi of
    /// 720 is written 0, not -0.000000000000028), azimuths in (-180, 180].
    fn from(c: &Candidate) -> Self {
        let round = |v: f64| (v * 1e9).round() / 1e9 + 0.0;
        let ((theta_i, phi_i), (theta_o, phi_o)) = (angles_deg(c.wi), angles_deg(c.wo));
        let [theta_i, phi_i, theta_o, phi_o] = [theta_i, phi_i, theta_o, phi_o].map(round);
        Self {
            theta_i,
            phi_i,
            theta_o,
            phi_o,
            cell: c.cell,
        }
    }
}

/// Parameters of [`plan`](super::plan()). Defaults: `n = 20`, `error`, 10,000 candidates per step, a
/// shortlist of 32, seed 1, one path (no restarts: every n'-prefix is the n'-plan).
#[derive(Clone, Debug)]
pub struct PlanParams {
    /// Samples to plan.
    pub n: usize,
    /// Criterion.
    pub criterion: Criterion,
    /// Candidates examined per step (0: all).
    pub candidates_per_step: usize,
    /// Candidates of the error screen fitted exactly per step (0: every examined one).
    pub shortlist: usize,
    /// Seed of the candidate subsets and of `random`.
    pub seed: u64,
    /// Fit mask and weighting of the training scores.
    pub fit: FitParams,
    /// `error`: seeded greedy paths compared by their final training score, the
    /// candidates examined per step shared among them ([`plan`](super::plan())); 1: one path.
    pub restarts: usize,
}

impl Default for PlanParams {
    fn default() -> Self {
        Self {
            n: 20,
            criterion: Criterion::Error,
            candidates_per_step: 10_000,
            shortlist: 32,
            seed: 1,
            fit: FitParams::default(),
            restarts: 1,
        }
    }
}

/// A plan (the `plan --json` schema of SPEC-cli).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Plan {
    /// Basis, in column order.
    pub basis: Vec<String>,
    /// Criterion.
    pub criterion: Criterion,
    /// Samples planned.
    pub n: usize,
    /// Candidates examined per step.
    pub candidates_per_step: usize,
    /// Total candidates.
    pub candidates: usize,
    /// Samples in the order chosen.
    pub samples: Vec<PlannedSample>,
    /// Exact mean training score after each sample (empty without training materials).
    pub history: Vec<f64>,
    /// Seed (of the chosen path: [`plan`](super::plan()) with it and one restart gives this plan).
    pub seed: u64,
    /// Greedy paths compared (`error` with restarts; 1 otherwise).
    #[serde(default = "one")]
    pub restarts: usize,
    /// The objective the plan weighs its rows by (SPEC 11; `l2` in files written before
    /// objectives reached plans).
    #[serde(default = "l2_name")]
    pub objective: String,
    /// The chosen candidates, in order (not written).
    #[serde(skip)]
    pub chosen: Vec<Candidate>,
}

/// The serde default of `objective`: `l2`.
pub(crate) fn l2_name() -> String {
    "l2".into()
}

/// The serde default of `restarts` (files written before restarts existed: one path).
pub(crate) fn one() -> usize {
    1
}
