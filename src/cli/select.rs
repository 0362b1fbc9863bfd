//! `brdf-basis select`.

use super::Global;
use brdf_basis::cluster::{
    clearly_lower, ClusterError, GcukParams, KMedoidsAlgorithm, KMedoidsInit, KMedoidsParams,
    TIE_TOLERANCE,
};
use brdf_basis::distance::{distance_matrix, DistanceMatrix, DistanceParams, Metric};
use brdf_basis::fit::FitParams;
use brdf_basis::io::json::write_json;
use brdf_basis::select::{empirical, EmpiricalParams};
use rayon::prelude::*;
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `select`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis select --method gcuk --json gcuk.json\n  brdf-basis select --method kmedoids -k 5 --runs 30 --json km5.json\n  brdf-basis select --method empirical --json empirical.json\n  brdf-basis select --method swap -k 5 --json swap5.json\n  brdf-basis select --method greedy -k 3 --candidates polished-gold,mirror-silver,matte-white-paint,red-acrylic-sheet --json mine.json"
)]
pub struct SelectArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// empirical (Algorithm 1), kmedoids or gcuk; greedy, swap or ga (by fitting error, SPEC 8).
    #[arg(long)]
    pub method: String,
    /// Distance for clustering: brdf-it or euclidean.
    #[arg(long, default_value = "brdf-it")]
    pub metric: Metric,
    /// Grid cells and weights.
    #[command(flatten)]
    pub grid: super::GridArgs,
    /// k-medoids: number of clusters.
    #[arg(short = 'k')]
    pub k: Option<usize>,
    /// Smallest k (k-medoids range or GCUK k_min).
    #[arg(long, default_value_t = 5)]
    pub k_min: usize,
    /// Largest k (k-medoids range: 12 when no -k; GCUK k_max: 20).
    #[arg(long)]
    pub k_max: Option<usize>,
    /// Runs per k (k-medoids) or GCUK runs, seeds seed, seed + 1, ... (at least 1).
    #[arg(long, default_value_t = 30)]
    pub runs: usize,
    /// k-medoids local search: fasterpam (Schubert & Rousseeuw 2021) or pam (BUILD-free
    /// PAM SWAP, best improvement).
    #[arg(long, default_value = "fasterpam")]
    pub algorithm: KMedoidsAlgorithm,
    /// GCUK population.
    #[arg(long, default_value_t = 20)]
    pub population: usize,
    /// GCUK generations.
    #[arg(long, default_value_t = 10)]
    pub generations: usize,
    /// Empirical: a material enters the basis when it contributes to more than this many fits.
    #[arg(long, default_value_t = 5)]
    pub more_than: usize,
    /// Output JSON.
    #[arg(long)]
    pub json: PathBuf,
    /// Flags of the error-driven methods (greedy, swap, ga).
    #[command(flatten)]
    pub error: super::select_error::ErrorArgs,
    /// Cluster a saved matrix instead of computing one: a .npy written by `distance` (read
    /// with its .names.json sidecar) or a .csv (`material,<names...>` header).
    #[arg(long, value_name = "FILE")]
    pub distances: Option<PathBuf>,
}

/// One clustering run as JSON.
pub fn run_json(
    d: &DistanceMatrix,
    seed: u64,
    medoids: &[usize],
    labels: &[usize],
    loss: f64,
    db: f64,
) -> serde_json::Value {
    json!({
        "seed": seed,
        "k": medoids.len(),
        "medoids": medoids.iter().map(|&m| d.names()[m].clone()).collect::<Vec<_>>(),
        "labels": labels,
        "loss": loss,
        "db_index": db,
    })
}

/// Runs k-medoids with `algorithm` for every k of `ks`, `runs` seeded runs each (in
/// parallel; the list is in (k, run) order whatever the thread count).
pub fn kmedoids_runs_with(
    d: &DistanceMatrix,
    ks: &[usize],
    runs: usize,
    seed: u64,
    algorithm: KMedoidsAlgorithm,
) -> anyhow::Result<Vec<serde_json::Value>> {
    let jobs: Vec<(usize, u64)> = ks
        .iter()
        .flat_map(|&k| (0..runs).map(move |r| (k, seed + r as u64)))
        .collect();
    jobs.par_iter()
        .map(|&(k, s)| {
            let km = KMedoidsParams::new(k)
                .algorithm(algorithm)
                .seed(s)
                .init(KMedoidsInit::Random)
                .fit(d)?;
            Ok(run_json(
                d,
                s,
                &km.medoids,
                &km.labels,
                km.loss,
                km.db_index,
            ))
        })
        .collect()
}

/// Runs GCUK `runs` times.
pub fn gcuk_runs(
    d: &DistanceMatrix,
    p: &GcukParams,
    runs: usize,
    seed: u64,
) -> anyhow::Result<Vec<serde_json::Value>> {
    (0..runs)
        .into_par_iter()
        .map(|r| {
            let s = seed + r as u64;
            let g = p.clone().seed(s).fit(d)?;
            Ok(run_json(d, s, &g.medoids, &g.labels, g.loss, g.db_index))
        })
        .collect()
}

/// The run with the lowest DB index; runs within [`TIE_TOLERANCE`] (relative) of each
/// other tie, and ties go to the first.
pub fn best(runs: &[serde_json::Value]) -> serde_json::Value {
    let db = |v: &serde_json::Value| v["db_index"].as_f64().unwrap_or(f64::INFINITY);
    let mut best: Option<&serde_json::Value> = None;
    for r in runs {
        if best.is_none_or(|b| clearly_lower(db(r), db(b), TIE_TOLERANCE)) {
            best = Some(r);
        }
    }
    best.cloned().unwrap_or(serde_json::Value::Null)
}

/// The k values of a k-medoids selection, checked (before any distance is computed).
fn kmedoids_ks(a: &SelectArgs) -> Result<Vec<usize>, ClusterError> {
    if a.runs == 0 {
        return Err(ClusterError::ZeroRuns);
    }
    let ks: Vec<usize> = match a.k {
        Some(k) => vec![k],
        None => {
            let k_max = a.k_max.unwrap_or(12);
            if a.k_min > k_max {
                return Err(ClusterError::EmptyKRange {
                    k_min: a.k_min,
                    k_max,
                });
            }
            (a.k_min..=k_max).collect()
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
    let p = GcukParams::default()
        .k_range(a.k_min, a.k_max.unwrap_or(20))
        .population(a.population)
        .generations(a.generations);
    p.clone().check()?;
    Ok(p)
}

/// Checks the clustering flags before any long work: a clear error naming the flags.
fn check_clustering(a: &SelectArgs, n: usize) -> anyhow::Result<()> {
    let flags = "check --runs, -k, --k-min and --k-max";
    match a.method.as_str() {
        "kmedoids" => {
            let ks = kmedoids_ks(a).map_err(|e| anyhow::anyhow!("select: {e} ({flags})"))?;
            if let Some(&k) = ks.iter().find(|&&k| k > n) {
                anyhow::bail!(
                    "select: {} ({flags}; the collection has {n} materials)",
                    ClusterError::KOutOfRange { k, n }
                );
            }
        }
        "gcuk" => {
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
    if let Some(path) = &a.distances {
        return run_saved(g, &a, path);
    }
    if matches!(a.method.as_str(), "greedy" | "swap" | "ga") {
        return super::select_error::run(g, &a);
    }
    let coll = super::load_collection(&a.collection)?;
    check_clustering(&a, coll.len())?;
    let backend = super::backend(g)?;
    let pb = super::progress_bar(g, 1, &a.method);
    let progress = |done: u64, total: u64| {
        pb.set_length(total);
        pb.set_position(done);
    };
    let value = match a.method.as_str() {
        "empirical" => {
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
            json!({"method": "empirical", "histogram": e.histogram, "contributors": e.contributors, "basis": e.basis})
        }
        "kmedoids" | "gcuk" => {
            let dp = DistanceParams::default()
                .metric(a.metric)
                .mask(a.grid.mask)
                .weighting(a.grid.weighting)
                .stride(a.grid.stride)
                .check(&coll)?;
            let d = distance_matrix(backend.as_ref(), &coll, &dp, &progress)?;
            cluster_json(&a, &d, &a.metric.to_string(), g.seed)?
        }
        other => anyhow::bail!(
            "unknown method `{other}` (expected empirical, kmedoids, gcuk, greedy, swap or ga)"
        ),
    };
    pb.finish_and_clear();
    write_json(&a.json, &value)?;
    if !g.quiet {
        eprintln!("wrote {}", a.json.display());
    }
    Ok(())
}

/// Clusters a saved matrix (`--distances`): no collection, no back-end.
fn run_saved(g: &Global, a: &SelectArgs, path: &std::path::Path) -> anyhow::Result<()> {
    if !a.collection.is_empty() {
        anyhow::bail!(
            "--distances clusters a saved matrix and takes no COLLECTION (given: {})",
            a.collection
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    if !matches!(a.method.as_str(), "kmedoids" | "gcuk") {
        anyhow::bail!(
            "--distances works with --method kmedoids or gcuk only (a saved matrix holds distances, not materials); --method {} needs a COLLECTION instead",
            a.method
        );
    }
    brdf_basis::io::atomic::check_output_path(&a.json, "--json")?;
    let saved = brdf_basis::io::matrix::load_saved_matrix(path)?;
    check_clustering(a, saved.matrix.names().len())?;
    let metric = saved
        .sidecar
        .map_or(a.metric.to_string(), |s| s.settings.metric);
    let value = cluster_json(a, &saved.matrix, &metric, g.seed)?;
    write_json(&a.json, &value)?;
    if !g.quiet {
        eprintln!("wrote {}", a.json.display());
    }
    Ok(())
}

/// Runs k-medoids or GCUK on a distance matrix and forms the SPEC-cli JSON.
fn cluster_json(
    a: &SelectArgs,
    d: &DistanceMatrix,
    metric: &str,
    seed: u64,
) -> anyhow::Result<serde_json::Value> {
    Ok(if a.method == "kmedoids" {
        let ks = kmedoids_ks(a)?;
        let runs = kmedoids_runs_with(d, &ks, a.runs, seed, a.algorithm)?;
        json!({"method": a.method, "algorithm": a.algorithm.to_string(), "metric": metric, "runs": runs, "best": best(&runs)})
    } else {
        let runs = gcuk_runs(d, &gcuk_params(a)?, a.runs, seed)?;
        json!({"method": a.method, "metric": metric, "runs": runs, "best": best(&runs)})
    })
}
