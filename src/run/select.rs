//! `select`: a basis by the paper's Algorithm 1, by clustering a distance matrix (computed
//! or saved), or by fitting error (SPEC 8).

use super::{optional_indices, refuse, Ctx, ObjectiveSetting, Refusal, Request};
use crate::backend::{Backend, Progress};
use crate::cluster::{ClusterError, GcukParams, KMedoidsAlgorithm, KMedoidsParams};
use crate::collection::Collection;
use crate::distance::{distance_matrix, DistanceMatrix, DistanceParams, Metric};
use crate::experiment::ExperimentParams;
use crate::fit::FitParams;
use crate::merl::GridSpec;
use crate::select::ErrorDrivenOutput;
use crate::select::{gcuk_runs, kmedoids_runs, named_runs};
use crate::select::{
    ClusteringOutput, EmpiricalOutput, EmpiricalParams, GaParams, Objective, ObjectiveParams,
    SearchParams, SelectOutput,
};
use crate::Result;
use std::path::{Path, PathBuf};

/// A selection method.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SelectMethod {
    /// The paper's Algorithm 1 (leave-one-out contributions).
    Empirical,
    /// k-medoids on the distance matrix, seeded runs per k.
    Kmedoids,
    /// GCUK (genetic clustering for unknown k) on the distance matrix.
    Gcuk,
    /// Greedy forward selection by fitting error (SPEC 8).
    Greedy,
    /// Swap refinement of the greedy basis by fitting error (SPEC 8).
    Swap,
    /// Genetic algorithm over k-subsets by fitting error.
    Ga,
}

impl SelectMethod {
    /// Every method, in the order the help lists them.
    pub const ALL: [SelectMethod; 6] = [
        SelectMethod::Empirical,
        SelectMethod::Kmedoids,
        SelectMethod::Gcuk,
        SelectMethod::Greedy,
        SelectMethod::Swap,
        SelectMethod::Ga,
    ];

    /// The spelling (`--method`, the output's `method`).
    pub fn as_str(self) -> &'static str {
        match self {
            SelectMethod::Empirical => "empirical",
            SelectMethod::Kmedoids => "kmedoids",
            SelectMethod::Gcuk => "gcuk",
            SelectMethod::Greedy => "greedy",
            SelectMethod::Swap => "swap",
            SelectMethod::Ga => "ga",
        }
    }

    /// k-medoids or GCUK: a method on a distance matrix.
    pub fn clustering(self) -> bool {
        matches!(self, SelectMethod::Kmedoids | SelectMethod::Gcuk)
    }

    /// greedy, swap or ga: a method by fitting error.
    pub fn error_driven(self) -> bool {
        matches!(
            self,
            SelectMethod::Greedy | SelectMethod::Swap | SelectMethod::Ga
        )
    }
}

impl std::fmt::Display for SelectMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for SelectMethod {
    type Err = Refusal;
    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|m| m.as_str() == s)
            .ok_or_else(|| Refusal::Unknown {
                what: "method",
                value: s.to_string(),
                expected: "empirical, kmedoids, gcuk, greedy, swap, ga",
            })
    }
}

/// `brdf-basis select`: its settings, with the defaults of `select --help`.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct SelectRequest {
    /// `--method`.
    pub method: SelectMethod,
    /// `-k`: the basis size of kmedoids (instead of `--k-min..--k-max`), greedy, swap and ga.
    pub k: Option<usize>,
    /// `--k-min`: smallest k of the k-medoids range (default 5) or GCUK's k_min (default 5).
    pub k_min: Option<usize>,
    /// `--k-max`: largest k of the k-medoids range (default 12) or GCUK's k_max (default 20).
    pub k_max: Option<usize>,
    /// `--runs`: runs per k (k-medoids) or GCUK runs, seeds `seed`, `seed + 1`, ...
    /// (default: [`ExperimentParams::default`]'s).
    pub runs: Option<usize>,
    /// `--algorithm`: the k-medoids local search (default: [`KMedoidsAlgorithm::default`]).
    pub algorithm: Option<KMedoidsAlgorithm>,
    /// `--population`: GCUK population (default: [`GcukParams::default`]'s).
    pub population: Option<usize>,
    /// `--generations`: GCUK generations (default: [`GcukParams::default`]'s).
    pub generations: Option<usize>,
    /// `--more-than`: empirical, a material enters the basis when it contributes to more
    /// than this many fits (default: [`EmpiricalParams::default`]'s).
    pub more_than: Option<usize>,
    /// `--candidates`: greedy, swap, ga: materials that may enter the basis (`None`: all).
    pub candidates: Option<Vec<String>>,
    /// `--targets`: greedy, swap, ga: materials the basis must represent (`None`: all).
    pub targets: Option<Vec<String>>,
    /// `--init`: swap's starting basis, or one individual of the GA's first population.
    pub init: Option<Vec<String>>,
    /// `--ga-population` (default 40).
    pub ga_population: Option<usize>,
    /// `--ga-generations` (default 60).
    pub ga_generations: Option<usize>,
    /// `--ga-crossover` (default 0.9).
    pub ga_crossover: Option<f64>,
    /// `--ga-mutation`: per-gene mutation probability (default 1/k).
    pub ga_mutation: Option<f64>,
    /// `--metric`: distance of the clustering methods (with a CSV `distances`: the label
    /// of the matrix's metric; default brdf-it).
    pub metric: Option<Metric>,
    /// `--mask`, `--weighting`, `--stride`.
    pub grid: GridSpec,
    /// `--seed`: of the seeded runs of kmedoids and gcuk and of the GA (default
    /// [`super::SEED`]); the other methods draw nothing at random and refuse it.
    pub seed: Option<u64>,
    /// `--distances`: cluster this saved matrix (a `.npy` written by `distance`, read with
    /// its sidecar, or a `.csv`) instead of computing one (run with [`Ctx::saved`]).
    pub distances: Option<PathBuf>,
    /// `--objective` and `--eps` (SPEC 11): greedy, swap and ga score bases, and
    /// `empirical` makes its leave-one-out fits, under the objective's shared weights
    /// (`l2`: the paper's fits). The clustering methods work on distances: they refuse
    /// an objective.
    pub objective: ObjectiveSetting,
}

impl SelectRequest {
    /// The default of `--metric`.
    pub const METRIC: Metric = Metric::BrdfIt;

    /// The defaults with `method`: every setting not given.
    pub fn new(method: SelectMethod) -> Self {
        Self {
            method,
            k: None,
            k_min: None,
            k_max: None,
            runs: None,
            algorithm: None,
            population: None,
            generations: None,
            more_than: None,
            candidates: None,
            targets: None,
            init: None,
            ga_population: None,
            ga_generations: None,
            ga_crossover: None,
            ga_mutation: None,
            metric: None,
            grid: GridSpec::default(),
            seed: None,
            distances: None,
            objective: ObjectiveSetting::default(),
        }
    }

    /// `--runs` with its default.
    pub fn runs(&self) -> usize {
        self.runs.unwrap_or(ExperimentParams::default().runs)
    }

    /// `--algorithm` with its default.
    pub fn algorithm(&self) -> KMedoidsAlgorithm {
        self.algorithm.unwrap_or_default()
    }

    /// `--population` with its default.
    pub fn population(&self) -> usize {
        self.population.unwrap_or(GcukParams::default().population)
    }

    /// `--generations` with its default.
    pub fn generations(&self) -> usize {
        self.generations
            .unwrap_or(GcukParams::default().generations)
    }

    /// `--more-than` with its default.
    pub fn more_than(&self) -> usize {
        self.more_than
            .unwrap_or(EmpiricalParams::default().more_than)
    }

    /// `--seed` with its default.
    pub fn seed(&self) -> u64 {
        self.seed.unwrap_or(super::SEED)
    }

    /// `--metric` with its default.
    pub fn metric(&self) -> Metric {
        self.metric.unwrap_or(Self::METRIC)
    }

    /// Every setting that only some methods use: whether it was given, its flag and the
    /// methods that use it (the one table of [`Self::check`]'s "applies to" rule).
    fn method_settings(&self) -> [(bool, &'static str, &'static [SelectMethod]); 18] {
        use SelectMethod::{Empirical, Ga, Gcuk, Greedy, Kmedoids, Swap};
        const CLUSTERING: &[SelectMethod] = &[Kmedoids, Gcuk];
        const ERROR: &[SelectMethod] = &[Greedy, Swap, Ga];
        const FITTING: &[SelectMethod] = &[Empirical, Greedy, Swap, Ga];
        let o = &self.objective;
        [
            (self.k_min.is_some(), "--k-min", CLUSTERING),
            (self.k_max.is_some(), "--k-max", CLUSTERING),
            (self.runs.is_some(), "--runs", CLUSTERING),
            (self.algorithm.is_some(), "--algorithm", &[Kmedoids]),
            (self.population.is_some(), "--population", &[Gcuk]),
            (self.generations.is_some(), "--generations", &[Gcuk]),
            (self.more_than.is_some(), "--more-than", &[Empirical]),
            (self.metric.is_some(), "--metric", CLUSTERING),
            (o.objective.is_some(), "--objective", FITTING),
            (o.eps.is_some(), "--eps", FITTING),
            (self.candidates.is_some(), "--candidates", ERROR),
            (self.targets.is_some(), "--targets", ERROR),
            (self.init.is_some(), "--init", &[Swap, Ga]),
            (self.ga_population.is_some(), "--ga-population", &[Ga]),
            (self.ga_generations.is_some(), "--ga-generations", &[Ga]),
            (self.ga_crossover.is_some(), "--ga-crossover", &[Ga]),
            (self.ga_mutation.is_some(), "--ga-mutation", &[Ga]),
            (self.seed.is_some(), "--seed", &[Kmedoids, Gcuk, Ga]),
        ]
    }

    /// Refuses a collection given with `distances` (a saved matrix is clustered
    /// without one); `collection`: whether one is given.
    ///
    /// # Errors
    /// [`Refusal::Rule`] naming `--distances`.
    pub fn check_source(&self, collection: bool) -> std::result::Result<(), Refusal> {
        if self.distances.is_some() && collection {
            refuse!(Refusal::Rule {
                setting: "--distances",
                message: "--distances clusters a saved matrix: give no COLLECTION with it".into(),
            });
        }
        Ok(())
    }

    /// The k values of a k-medoids selection, checked.
    fn kmedoids_ks(&self) -> std::result::Result<Vec<usize>, ClusterError> {
        if self.runs() == 0 {
            return Err(ClusterError::ZeroRuns);
        }
        let d = ExperimentParams::default();
        let ks: Vec<usize> = match self.k {
            Some(k) => vec![k],
            None => {
                let (k_min, k_max) = (self.k_min.unwrap_or(d.k_min), self.k_max.unwrap_or(d.k_max));
                if k_min > k_max {
                    return Err(ClusterError::EmptyKRange { k_min, k_max });
                }
                (k_min..=k_max).collect()
            }
        };
        for &k in &ks {
            KMedoidsParams::new(k).algorithm(self.algorithm()).check()?;
        }
        Ok(ks)
    }

    /// The GCUK parameters, checked.
    fn gcuk_params(&self) -> std::result::Result<GcukParams, ClusterError> {
        if self.runs() == 0 {
            return Err(ClusterError::ZeroRuns);
        }
        let d = GcukParams::default();
        let p = GcukParams::default()
            .k_range(self.k_min.unwrap_or(d.k_min), self.k_max.unwrap_or(d.k_max))
            .population(self.population())
            .generations(self.generations());
        p.check()?;
        Ok(p)
    }

    /// The clustering settings against `n` materials, before any long work.
    fn check_clustering(&self, n: usize) -> Result<()> {
        let flags = "check --runs, -k, --k-min and --k-max";
        let range = |cause: String, hint: String| Refusal::Range {
            command: "select",
            cause,
            hint,
        };
        match self.method {
            SelectMethod::Kmedoids => {
                let ks = self
                    .kmedoids_ks()
                    .map_err(|e| range(e.to_string(), flags.into()))?;
                if let Some(&k) = ks.iter().find(|&&k| k > n) {
                    let e = ClusterError::KOutOfRange { k, n };
                    return Err(range(
                        e.to_string(),
                        format!("{flags}; the collection has {n} materials"),
                    )
                    .into());
                }
            }
            SelectMethod::Gcuk => {
                let p = self.gcuk_params().map_err(|e| {
                    range(
                        e.to_string(),
                        format!("{flags}, --population and --generations"),
                    )
                })?;
                if p.k_max > n {
                    let e = ClusterError::KMaxTooLarge { k_max: p.k_max, n };
                    return Err(range(
                        e.to_string(),
                        format!("{flags}; the collection has {n} materials"),
                    )
                    .into());
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// The GA settings: the library's defaults ([`GaParams::default`]) with those given.
    fn ga_params(&self) -> GaParams {
        let d = GaParams::default();
        let mut gp = GaParams::default()
            .population(self.ga_population.unwrap_or(d.population))
            .generations(self.ga_generations.unwrap_or(d.generations))
            .crossover_prob(self.ga_crossover.unwrap_or(d.crossover_prob))
            .seed(self.seed());
        gp.mutation_prob = self.ga_mutation;
        gp
    }

    /// The selection on `coll` with the record of what chose the basis: the grid, and
    /// the fit objective of the methods that fit ([`SelectOutput::record`]).
    fn run_recorded(
        &self,
        backend: &dyn Backend,
        coll: &Collection,
        progress: Progress<'_>,
    ) -> Result<SelectOutput> {
        let mut out = self.run_unrecorded(backend, coll, progress)?;
        let objective = if self.method.clustering() {
            None
        } else {
            Some(self.objective.weight()?)
        };
        let g = &self.grid;
        out.record(objective, g.mask(), g.weighting(), g.stride());
        Ok(out)
    }

    /// [`Self::run_recorded`] without the record of its settings.
    fn run_unrecorded(
        &self,
        backend: &dyn Backend,
        coll: &Collection,
        progress: Progress<'_>,
    ) -> Result<SelectOutput> {
        let fingerprint = Some(coll.fingerprint());
        if self.method.error_driven() {
            return self.run_error_driven(backend, coll, fingerprint, progress);
        }
        self.check_clustering(coll.len())?;
        let g = &self.grid;
        if self.method == SelectMethod::Empirical {
            let p = EmpiricalParams {
                fit: FitParams {
                    objective: self.objective.weight()?,
                    ..Default::default()
                }
                .grid(*g),
                more_than: self.more_than(),
            };
            let e = crate::select::empirical(backend, coll, &p, progress)?;
            return Ok(SelectOutput::Empirical(EmpiricalOutput::new(
                &e,
                self.more_than(),
                fingerprint,
            )?));
        }
        let dp = DistanceParams::default()
            .metric(self.metric())
            .grid(*g)
            .check(coll)?;
        let d = distance_matrix(backend, coll, &dp, progress)?;
        self.cluster(&d, &self.metric().to_string(), fingerprint, progress)
    }

    fn cluster_saved(&self, path: &Path, progress: Progress<'_>) -> Result<SelectOutput> {
        let saved = crate::io::saved::load_saved_matrix(path)?;
        self.check_clustering(saved.matrix.names().len())?;
        let (metric, fingerprint) = match &saved.sidecar {
            Some(s) => (
                s.settings.metric.to_string(),
                Some(s.collection_fingerprint.clone()),
            ),
            None => (self.metric().to_string(), None),
        };
        // A mapped matrix file rewritten or truncated while it is clustered (crate::io::mmap)
        // is refused after the work, whatever the work made of the changed values (an
        // error, or even a panic on values no check saw, is reported as the change).
        let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            self.cluster(&saved.matrix, &metric, fingerprint, progress)
        }));
        if let Err(message) = saved.matrix.source_unchanged() {
            return Err(crate::io::MatrixFileError::Changed {
                path: path.to_path_buf(),
                message,
            }
            .into());
        }
        let mut out = out.unwrap_or_else(|panic| std::panic::resume_unwind(panic))?;
        if let Some(s) = &saved.sidecar {
            let g = &s.settings;
            out.record(None, g.mask, g.weighting, g.stride);
        }
        Ok(out)
    }

    /// k-medoids or GCUK runs on `d`.
    fn cluster(
        &self,
        d: &DistanceMatrix,
        metric: &str,
        fingerprint: Option<String>,
        progress: Progress<'_>,
    ) -> Result<SelectOutput> {
        let (runs, algorithm) = if self.method == SelectMethod::Kmedoids {
            let ks = self.kmedoids_ks()?;
            let a = self.algorithm();
            let runs = kmedoids_runs(d, &ks, self.runs(), self.seed(), a, progress)?;
            (runs, Some(a.to_string()))
        } else {
            let p = self.gcuk_params()?.check()?;
            (gcuk_runs(d, &p, self.runs(), self.seed(), progress)?, None)
        };
        let named = named_runs(d, &runs)?;
        Ok(SelectOutput::Clustering(ClusteringOutput::new(
            self.method.as_str(),
            algorithm,
            metric,
            named,
            fingerprint,
        )?))
    }

    /// greedy, swap or ga (the settings checked).
    fn run_error_driven(
        &self,
        backend: &dyn Backend,
        coll: &Collection,
        fingerprint: Option<String>,
        progress: Progress<'_>,
    ) -> Result<SelectOutput> {
        let Some(k) = self.k else {
            unreachable!("check() refuses greedy, swap and ga without k")
        };
        let mut sp = SearchParams::new(k);
        sp.candidates = optional_indices(coll, self.candidates.as_deref())?;
        sp.targets = optional_indices(coll, self.targets.as_deref())?;
        sp.init = optional_indices(coll, self.init.as_deref())?;
        let vsp = sp.check(&coll.names())?;
        let vgp = self.ga_params().check()?;
        let g = &self.grid;
        let op = ObjectiveParams::default()
            .grid(*g)
            .objective(self.objective.weight()?)
            .check()?;
        let obj = Objective::new(backend, coll, &op, progress)?;
        let selection = match self.method {
            SelectMethod::Greedy => crate::select::greedy(&obj, &vsp, progress)?,
            SelectMethod::Swap => crate::select::swap(&obj, &vsp, progress)?,
            _ => crate::select::ga(&obj, &vsp, &vgp, progress)?,
        };
        Ok(SelectOutput::ErrorDriven(ErrorDrivenOutput {
            selection,
            collection_fingerprint: fingerprint,
            fit_objective: None,
            eps: None,
            mask: None,
            weighting: None,
            stride: None,
        }))
    }
}

impl Request for SelectRequest {
    type Output = SelectOutput;

    /// Refuses the settings that do not apply to the method (or to `distances`), so that
    /// none is ignored without a word.
    ///
    fn check(&self) -> std::result::Result<(), Refusal> {
        let m = self.method;
        let range = self.k_min.is_some() || self.k_max.is_some();
        let k_why = match m {
            SelectMethod::Gcuk => Some(": GCUK chooses k itself within --k-min..--k-max (give --k-min K --k-max K to fix it)"),
            SelectMethod::Empirical => Some(": its basis is every material contributing to more than --more-than fits"),
            _ => None,
        };
        if let (Some(_), Some(why)) = (self.k, k_why) {
            refuse!(Refusal::DoesNotApply {
                settings: vec!["-k"],
                shown: "-k".into(),
                context: format!("to --method {m}"),
                why: why.into(),
            });
        }
        if self.k.is_some() && range {
            refuse!(Refusal::Conflict {
                a: "-k",
                b: "--k-min/--k-max",
            });
        }
        for (given, flag, methods) in self.method_settings() {
            if given && !methods.contains(&m) {
                let names: Vec<&str> = methods.iter().map(|m| m.as_str()).collect();
                refuse!(Refusal::NotApplicable {
                    setting: flag,
                    value: None,
                    applies_to: super::list(&names),
                    not_to: format!("--method {m}"),
                    why: None,
                });
            }
        }
        if let Some(path) = &self.distances {
            if !m.clustering() {
                refuse!(Refusal::Rule {
                    setting: "--distances",
                    message: format!("--distances clusters a saved matrix: it needs --method kmedoids or gcuk, not {m}"),
                });
            }
            // A CSV matrix has no sidecar: --metric labels it.
            let npy = path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
            let g = &self.grid;
            let d = GridSpec::default();
            for (given, flag) in [
                (npy && self.metric.is_some(), "--metric"),
                (g.stride() != d.stride(), "--stride"),
                (g.mask() != d.mask(), "--mask"),
                (g.weighting() != d.weighting(), "--weighting"),
            ] {
                if given {
                    refuse!(Refusal::DoesNotApply {
                        settings: vec![flag],
                        shown: flag.into(),
                        context: "with --distances".into(),
                        why: ": the saved matrix was computed with its own settings (a .npy's sidecar records them)".into(),
                    });
                }
            }
        }
        if m.error_driven() && self.k.is_none() {
            refuse!(Refusal::Missing {
                setting: "-k",
                message:
                    "give the basis size with -k K (greedy, swap and ga choose exactly k materials)"
                        .into(),
            });
        }
        self.objective.weight()?;
        Ok(())
    }

    /// [`Self::check`], then the clustering settings (k range, runs, GCUK's population
    /// and generations) against `n` materials.
    fn check_count(&self, n: usize) -> Result<()> {
        self.check()?;
        self.check_clustering(n)
    }

    /// Runs the selection and returns what `select --json` writes
    /// ([`SelectOutput::to_json`]); the progress callback is called from the working
    /// threads, per stage. With `distances`, clusters the saved matrix (kmedoids or
    /// gcuk; run with [`Ctx::saved`]: no collection, no back-end): the metric and
    /// fingerprint are the sidecar's (a CSV: `metric`, none). Otherwise runs on the
    /// collection and back-end of `ctx`.
    ///
    /// The output records what chose the basis: the grid, and the fit objective of the
    /// methods that fit ([`SelectOutput::record`]).
    fn run(&self, ctx: &Ctx<'_>) -> Result<SelectOutput> {
        self.check()?;
        match &self.distances {
            Some(path) => {
                self.check_source(ctx.has_collection())?;
                self.cluster_saved(path, ctx.progress)
            }
            None => {
                let (backend, coll) = (ctx.need_backend()?, ctx.need_collection()?);
                self.run_recorded(backend, coll, ctx.progress)
            }
        }
    }
}
