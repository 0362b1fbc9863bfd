//! `brdf-basis select`: translates the flags into library calls and prints the result
//! ([`SelectOutput`]); the runs, the best-run rule and the JSON are the library's.

use super::select_error::ErrorArgs;
use super::Global;
use brdf_basis::atomic::{OutputPlan, OutputSet};
use brdf_basis::cluster::{ClusterError, GcukParams, KMedoidsAlgorithm, KMedoidsParams};
use brdf_basis::distance::{distance_matrix, DistanceMatrix, DistanceParams, Metric};
use brdf_basis::experiment::ExperimentParams;
use brdf_basis::fit::FitParams;
use brdf_basis::merl::{Mask, Weighting};
use brdf_basis::select::runs::{gcuk_runs, kmedoids_runs, named_runs};
use brdf_basis::select::{
    empirical, ClusteringOutput, EmpiricalOutput, EmpiricalParams, SelectOutput,
};
use std::path::{Path, PathBuf};

/// A selection method.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
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

impl Method {
    fn name(self) -> &'static str {
        match self {
            Method::Empirical => "empirical",
            Method::Kmedoids => "kmedoids",
            Method::Gcuk => "gcuk",
            Method::Greedy => "greedy",
            Method::Swap => "swap",
            Method::Ga => "ga",
        }
    }

    fn clustering(self) -> bool {
        matches!(self, Method::Kmedoids | Method::Gcuk)
    }

    fn error_driven(self) -> bool {
        matches!(self, Method::Greedy | Method::Swap | Method::Ga)
    }
}

/// Arguments of `select`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis select --method gcuk --json gcuk.json\n  brdf-basis select --method kmedoids -k 5 --runs 30 --json km5.json\n  brdf-basis select --method empirical --json empirical.json\n  brdf-basis select --method swap -k 5 --json swap5.json\n  brdf-basis select --method greedy -k 3 --candidates polished-gold,mirror-silver,matte-white-paint,red-acrylic-sheet --json mine.json"
)]
pub struct SelectArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// Selection method.
    #[arg(long, value_enum)]
    pub method: Method,
    /// Distance for clustering: brdf-it or euclidean (with a CSV --distances: the label of
    /// the matrix's metric).
    #[arg(long, default_value_t = Metric::BrdfIt)]
    pub metric: Metric,
    /// Grid cells and weights.
    #[command(flatten)]
    pub grid: super::GridArgs,
    /// kmedoids, greedy, swap, ga: the basis size (kmedoids: instead of --k-min..--k-max).
    #[arg(short = 'k')]
    pub k: Option<usize>,
    /// Smallest k (k-medoids range or GCUK k_min) [default: 5].
    #[arg(long)]
    pub k_min: Option<usize>,
    /// Largest k (k-medoids range [default: 12]; GCUK k_max [default: 20]).
    #[arg(long)]
    pub k_max: Option<usize>,
    /// Runs per k (k-medoids) or GCUK runs, seeds seed, seed + 1, ... (at least 1).
    #[arg(long, default_value_t = ExperimentParams::default().runs)]
    pub runs: usize,
    /// k-medoids local search: fasterpam (Schubert & Rousseeuw 2021) or pam (BUILD-free
    /// PAM SWAP, best improvement).
    #[arg(long, default_value_t = KMedoidsAlgorithm::default())]
    pub algorithm: KMedoidsAlgorithm,
    /// GCUK population.
    #[arg(long, default_value_t = GcukParams::default().population)]
    pub population: usize,
    /// GCUK generations.
    #[arg(long, default_value_t = GcukParams::default().generations)]
    pub generations: usize,
    /// Empirical: a material enters the basis when it contributes to more than this many fits.
    #[arg(long, default_value_t = EmpiricalParams::default().more_than)]
    pub more_than: usize,
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

/// Refuses the flags that do not apply to the method (or to `--distances`), so that none
/// is ignored without a word.
fn check_flags(a: &SelectArgs) -> anyhow::Result<()> {
    let m = a.method.name();
    if a.k.is_some() && matches!(a.method, Method::Gcuk | Method::Empirical) {
        anyhow::bail!(if a.method == Method::Gcuk {
            "-k does not apply to --method gcuk: GCUK chooses k itself within --k-min..--k-max (give --k-min K --k-max K to fix it)".to_string()
        } else {
            "-k does not apply to --method empirical: its basis is every material contributing to more than --more-than fits".to_string()
        });
    }
    if a.k.is_some() && (a.k_min.is_some() || a.k_max.is_some()) {
        anyhow::bail!("give either -k or --k-min/--k-max, not both");
    }
    if !a.method.clustering() && (a.k_min.is_some() || a.k_max.is_some()) {
        anyhow::bail!("--k-min and --k-max apply to kmedoids and gcuk, not to --method {m}");
    }
    if !a.method.error_driven() {
        if let Some(flag) = a.error.given() {
            anyhow::bail!("{flag} applies to greedy, swap and ga, not to --method {m}");
        }
    }
    if a.distances.is_some() {
        if !a.method.clustering() {
            anyhow::bail!(
                "--distances clusters a saved matrix: it needs --method kmedoids or gcuk, not {m}"
            );
        }
        if !a.collection.is_empty() {
            anyhow::bail!("--distances clusters a saved matrix: give no COLLECTION with it");
        }
        let g = &a.grid;
        // A CSV matrix has no sidecar: --metric labels it.
        let npy = a
            .distances
            .as_ref()
            .and_then(|p| p.extension())
            .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
        for (given, flag) in [
            (npy && a.metric != Metric::BrdfIt, "--metric"),
            (g.stride != 1, "--stride"),
            (g.mask != Mask::Evaluation, "--mask"),
            (g.weighting != Weighting::Uniform, "--weighting"),
        ] {
            if given {
                anyhow::bail!("{flag} does not apply with --distances: the saved matrix was computed with its own settings (a .npy's sidecar records them)");
            }
        }
    }
    Ok(())
}

/// The k values of a k-medoids selection, checked (before any distance is computed).
fn kmedoids_ks(a: &SelectArgs) -> Result<Vec<usize>, ClusterError> {
    if a.runs == 0 {
        return Err(ClusterError::ZeroRuns);
    }
    let d = ExperimentParams::default();
    let ks: Vec<usize> = match a.k {
        Some(k) => vec![k],
        None => {
            let (k_min, k_max) = (a.k_min.unwrap_or(d.k_min), a.k_max.unwrap_or(d.k_max));
            if k_min > k_max {
                return Err(ClusterError::EmptyKRange { k_min, k_max });
            }
            (k_min..=k_max).collect()
        }
    };
    for &k in &ks {
        KMedoidsParams::new(k).algorithm(a.algorithm).check()?;
    }
    Ok(ks)
}

/// The GCUK parameters of a selection, checked.
fn gcuk_params(a: &SelectArgs) -> Result<GcukParams, ClusterError> {
    if a.runs == 0 {
        return Err(ClusterError::ZeroRuns);
    }
    let d = GcukParams::default();
    let p = GcukParams::default()
        .k_range(a.k_min.unwrap_or(d.k_min), a.k_max.unwrap_or(d.k_max))
        .population(a.population)
        .generations(a.generations);
    p.check()?;
    Ok(p)
}

/// Checks the clustering flags before any long work: a clear error naming the flags.
fn check_clustering(a: &SelectArgs, n: usize) -> anyhow::Result<()> {
    let flags = "check --runs, -k, --k-min and --k-max";
    match a.method {
        Method::Kmedoids => {
            let ks = kmedoids_ks(a).map_err(|e| anyhow::anyhow!("select: {e} ({flags})"))?;
            if let Some(&k) = ks.iter().find(|&&k| k > n) {
                anyhow::bail!(
                    "select: {} ({flags}; the collection has {n} materials)",
                    ClusterError::KOutOfRange { k, n }
                );
            }
        }
        Method::Gcuk => {
            let p = gcuk_params(a).map_err(|e| {
                anyhow::anyhow!("select: {e} ({flags}, --population and --generations)")
            })?;
            if p.k_max > n {
                anyhow::bail!(
                    "select: {} ({flags}; the collection has {n} materials)",
                    ClusterError::KMaxTooLarge { k_max: p.k_max, n }
                );
            }
        }
        _ => {}
    }
    Ok(())
}

/// Runs the selection.
pub fn run(g: &Global, a: SelectArgs) -> anyhow::Result<()> {
    check_flags(&a)?;
    // Every output path before the work: a typo costs no computation.
    let mut plan = OutputPlan::new(&a.collection);
    if let Some(d) = &a.distances {
        plan.input_named(d, "distance matrix");
    }
    plan.file(&a.json, "--json")?;
    let out = plan.into_set()?;
    if let Some(path) = &a.distances {
        return run_saved(g, &a, path, out);
    }
    let coll = super::load_collection(&a.collection)?;
    let fingerprint = Some(coll.fingerprint());
    if a.method.error_driven() {
        let sel = super::select_error::run(g, &coll, a.method.name(), a.k, &a.grid, &a.error)?;
        let output = SelectOutput::ErrorDriven(brdf_basis::select::output::ErrorDrivenOutput {
            selection: sel,
            collection_fingerprint: fingerprint,
        });
        return write(g, &a.json, &output, out);
    }
    check_clustering(&a, coll.len())?;
    let backend = super::backend(g)?;
    let stage = if a.method == Method::Empirical {
        "empirical"
    } else {
        "distances"
    };
    let pb = super::progress_bar(g, 1, stage);
    let progress = |done: u64, total: u64| {
        pb.set_length(total);
        pb.set_position(done);
    };
    let output = if a.method == Method::Empirical {
        let p = EmpiricalParams {
            fit: FitParams {
                mask: a.grid.mask,
                weighting: a.grid.weighting,
                stride: a.grid.stride,
                ..Default::default()
            },
            more_than: a.more_than,
        };
        let e = empirical(backend.as_ref(), &coll, &p, &progress)?;
        pb.finish_and_clear();
        SelectOutput::Empirical(EmpiricalOutput::new(&e, a.more_than, fingerprint)?)
    } else {
        let dp = DistanceParams::default()
            .metric(a.metric)
            .mask(a.grid.mask)
            .weighting(a.grid.weighting)
            .stride(a.grid.stride)
            .check(&coll)?;
        let d = distance_matrix(backend.as_ref(), &coll, &dp, &progress)?;
        pb.finish_and_clear();
        cluster(g, &a, &d, &a.metric.to_string(), fingerprint)?
    };
    write(g, &a.json, &output, out)
}

/// Clusters a saved matrix (`--distances`): no collection, no back-end.
fn run_saved(g: &Global, a: &SelectArgs, path: &Path, out: OutputSet) -> anyhow::Result<()> {
    let saved = brdf_basis::io::saved::load_saved_matrix(path)?;
    check_clustering(a, saved.matrix.names().len())?;
    let (metric, fingerprint) = match &saved.sidecar {
        Some(s) => (
            s.settings.metric.to_string(),
            Some(s.collection_fingerprint.clone()),
        ),
        None => (a.metric.to_string(), None),
    };
    let output = cluster(g, a, &saved.matrix, &metric, fingerprint)?;
    write(g, &a.json, &output, out)
}

/// Runs k-medoids or GCUK on a distance matrix (a labelled progress bar over the runs).
fn cluster(
    g: &Global,
    a: &SelectArgs,
    d: &DistanceMatrix,
    metric: &str,
    fingerprint: Option<String>,
) -> anyhow::Result<SelectOutput> {
    let label = if a.method == Method::Kmedoids {
        "k-medoids runs"
    } else {
        "GCUK runs"
    };
    let pb = super::progress_bar(g, 1, label);
    let progress = |done: u64, total: u64| {
        pb.set_length(total);
        pb.set_position(done);
    };
    let (runs, algorithm) = if a.method == Method::Kmedoids {
        let ks = kmedoids_ks(a)?;
        let runs = kmedoids_runs(d, &ks, a.runs, g.seed, a.algorithm, &progress)?;
        (runs, Some(a.algorithm.to_string()))
    } else {
        let p = gcuk_params(a)?.check()?;
        (gcuk_runs(d, &p, a.runs, g.seed, &progress)?, None)
    };
    pb.finish_and_clear();
    let named = named_runs(d, &runs)?;
    Ok(SelectOutput::Clustering(ClusteringOutput::new(
        a.method.name(),
        algorithm,
        metric,
        named,
        fingerprint,
    )?))
}

/// Stages and commits the JSON, then prints what was found and written on stdout.
fn write(g: &Global, path: &Path, output: &SelectOutput, mut out: OutputSet) -> anyhow::Result<()> {
    let text = output.to_json();
    out.stage(path, |w| w.write_all(text.as_bytes()))?;
    out.commit()?;
    let _ = g;
    println!("{output}");
    println!("wrote {}", path.display());
    Ok(())
}
