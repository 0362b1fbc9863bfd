//! `brdf-basis select`: translates the flags into a [`SelectRequest`] and writes its
//! output ([`SelectOutput`]); the rules, the runs, the best-run rule and the JSON are the
//! library's.

use super::Global;
use brdf_basis::atomic::{OutputPlan, OutputSet};
use brdf_basis::cluster::KMedoidsAlgorithm;
use brdf_basis::distance::Metric;
use brdf_basis::run::{Ctx, Request, SelectMethod, SelectRequest};
use brdf_basis::select::SelectOutput;
use std::path::{Path, PathBuf};

/// The request's defaults, for `--help`.
fn defaults() -> SelectRequest {
    SelectRequest::new(SelectMethod::Empirical)
}

/// Arguments of `select`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis select --method gcuk --json gcuk.json\n  brdf-basis select --method kmedoids -k 5 --runs 30 --json km5.json\n  brdf-basis select --method empirical --json empirical.json\n  brdf-basis select --method swap -k 5 --json swap5.json\n  brdf-basis select --method greedy -k 3 --candidates polished-gold,mirror-silver,matte-white-paint,red-acrylic-sheet --json mine.json"
)]
pub(crate) struct SelectArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// Selection method.
    #[arg(long, value_enum)]
    pub method: super::values::MethodArg,
    // Distance for clustering.
    #[arg(long, help = super::with_default("kmedoids, gcuk: distance for clustering, brdf-it or euclidean (with a CSV --distances: the label of the matrix's metric)", defaults().metric()))]
    pub metric: Option<Metric>,
    /// Grid cells and weights.
    #[command(flatten)]
    pub grid: super::GridArgs,
    /// greedy, swap, ga, empirical: the fit objective whose shared weights score a basis
    /// (empirical: weight its leave-one-out fits; l2 gives the paper's).
    #[command(flatten)]
    pub objective: super::ObjectiveArgs,
    /// kmedoids, greedy, swap, ga: the basis size (kmedoids: instead of --k-min..--k-max).
    #[arg(short = 'k')]
    pub k: Option<usize>,
    /// Smallest k (k-medoids range or GCUK k_min) [default: 5].
    #[arg(long)]
    pub k_min: Option<usize>,
    /// Largest k (k-medoids range [default: 12]; GCUK k_max [default: 20]).
    #[arg(long)]
    pub k_max: Option<usize>,
    // Optional flags, so that the request can refuse one its method does not use; the
    // help shows the request's defaults.
    #[arg(long, help = super::with_default("kmedoids, gcuk: runs per k (k-medoids) or GCUK runs, seeds seed, seed + 1, ... (at least 1)", defaults().runs()))]
    pub runs: Option<usize>,
    #[arg(long, help = super::with_default("kmedoids: local search, fasterpam (Schubert & Rousseeuw 2021) or pam (BUILD-free PAM SWAP, best improvement)", defaults().algorithm()))]
    pub algorithm: Option<KMedoidsAlgorithm>,
    #[arg(long, help = super::with_default("gcuk: population", defaults().population()))]
    pub population: Option<usize>,
    #[arg(long, help = super::with_default("gcuk: generations", defaults().generations()))]
    pub generations: Option<usize>,
    #[arg(long, help = super::with_default("empirical: a material enters the basis when it contributes to more than this many fits", defaults().more_than()))]
    pub more_than: Option<usize>,
    /// Output JSON.
    #[arg(long)]
    pub json: PathBuf,
    /// Flags of the error-driven methods (greedy, swap, ga).
    #[command(flatten)]
    pub error: ErrorArgs,
    /// Cluster a saved matrix instead of computing one: a .npy written by `distance` (read
    /// with its .names.json sidecar) or a .csv (`material,<names...>` header).
    #[arg(long, value_name = "FILE")]
    pub distances: Option<PathBuf>,
}

/// Flags of the error-driven methods (flattened into `select`).
#[derive(clap::Args, Debug, Clone)]
pub(crate) struct ErrorArgs {
    /// greedy, swap, ga: materials that may enter the basis, comma-separated (default: all).
    #[arg(long, value_delimiter = ',')]
    pub candidates: Vec<String>,
    /// greedy, swap, ga: materials the basis must represent, comma-separated (default: all).
    #[arg(long, value_delimiter = ',')]
    pub targets: Vec<String>,
    /// swap: starting basis (default: the greedy basis); ga: one individual of the first
    /// population. Exactly k materials.
    #[arg(long, value_delimiter = ',')]
    pub init: Vec<String>,
    /// ga: population size [default: 40].
    #[arg(long)]
    pub ga_population: Option<usize>,
    /// ga: generations [default: 60].
    #[arg(long)]
    pub ga_generations: Option<usize>,
    /// ga: crossover probability [default: 0.9].
    #[arg(long)]
    pub ga_crossover: Option<f64>,
    /// ga: per-gene mutation probability (default 1/k).
    #[arg(long)]
    pub ga_mutation: Option<f64>,
}

/// A comma-separated list flag: `None` when not given.
fn given(names: &[String]) -> Option<Vec<String>> {
    (!names.is_empty()).then(|| names.to_vec())
}

impl SelectArgs {
    /// The request these flags make.
    pub(crate) fn request(&self, g: &Global) -> anyhow::Result<SelectRequest> {
        let e = &self.error;
        let mut r = SelectRequest::new(self.method.into());
        r.k = self.k;
        r.k_min = self.k_min;
        r.k_max = self.k_max;
        r.runs = self.runs;
        r.algorithm = self.algorithm;
        r.population = self.population;
        r.generations = self.generations;
        r.more_than = self.more_than;
        r.candidates = given(&e.candidates);
        r.targets = given(&e.targets);
        r.init = given(&e.init);
        r.ga_population = e.ga_population;
        r.ga_generations = e.ga_generations;
        r.ga_crossover = e.ga_crossover;
        r.ga_mutation = e.ga_mutation;
        r.metric = self.metric;
        r.grid = self.grid.grid()?;
        r.seed = g.seed;
        r.distances = self.distances.clone();
        r.objective = self.objective.setting();
        Ok(r)
    }
}

/// Runs the selection.
pub(crate) fn run(g: &Global, a: SelectArgs) -> anyhow::Result<()> {
    let req = a.request(g)?;
    req.check()?;
    req.check_source(!a.collection.is_empty())?;
    if a.distances.is_some() && g.backend == Some(super::values::BackendArg::Gpu) {
        anyhow::bail!("--backend gpu does not apply with --distances: a saved matrix is clustered on the CPU, with no distance to compute; leave it out");
    }
    // Every output path before the work: a typo costs no computation.
    let mut plan = OutputPlan::new(&a.collection);
    if let Some(d) = &a.distances {
        plan.input_named(d, "distance matrix");
    }
    plan.file(&a.json, "--json")?;
    let out = plan.into_set()?;
    let pb = super::progress_bar(g, 1, SelectMethod::from(a.method).as_str());
    let progress = |done: u64, total: u64| {
        pb.set_length(total);
        pb.set_position(done);
    };
    let output = if a.distances.is_some() {
        req.run(&Ctx::saved().progress(&progress))?
    } else {
        let coll = super::load_collection(&a.collection)?;
        let backend = super::backend(g)?;
        req.run(&Ctx::new(backend.as_ref(), &coll).progress(&progress))?
    };
    pb.finish_and_clear();
    write(&a.json, &output, out)
}

/// Stages and commits the JSON, then prints what was found and written on stdout.
fn write(path: &Path, output: &SelectOutput, mut out: OutputSet) -> anyhow::Result<()> {
    let text = output.to_json();
    out.stage(path, |w| w.write_all(text.as_bytes()))?;
    out.commit()?;
    println!("{output}");
    println!("wrote {}", path.display());
    Ok(())
}
