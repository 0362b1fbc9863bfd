//! `brdf-basis select`.

use super::Global;
use brdf_basis::cluster::{GcukParams, KMedoidsParams};
use brdf_basis::distance::{distance_matrix, DistanceMatrix, DistanceParams, Metric};
use brdf_basis::fit::FitParams;
use brdf_basis::io::json::write_json;
use brdf_basis::select::{empirical, EmpiricalParams};
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `select`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis select --method gcuk --json gcuk.json\n  brdf-basis select ../shared/data/ngan2005_ashikhmin_shirley.csv --method kmedoids -k 5 --runs 30 --json km5.json\n  brdf-basis select --method empirical --json empirical.json"
)]
pub struct SelectArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// empirical (Algorithm 1), kmedoids or gcuk.
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
    /// Runs per k (k-medoids) or GCUK runs, seeds seed, seed + 1, ...
    #[arg(long, default_value_t = 30)]
    pub runs: usize,
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

/// Runs k-medoids for every k of `ks`, `runs` seeded runs each.
pub fn kmedoids_runs(
    d: &DistanceMatrix,
    ks: &[usize],
    runs: usize,
    seed: u64,
) -> anyhow::Result<Vec<serde_json::Value>> {
    let mut out = Vec::new();
    for &k in ks {
        for r in 0..runs {
            let s = seed + r as u64;
            let km = KMedoidsParams::new(k)
                .seed(s)
                .init(brdf_basis::cluster::KMedoidsInit::Random)
                .fit(d)?;
            out.push(run_json(
                d,
                s,
                &km.medoids,
                &km.labels,
                km.loss,
                km.db_index,
            ));
        }
    }
    Ok(out)
}

/// Runs GCUK `runs` times.
pub fn gcuk_runs(
    d: &DistanceMatrix,
    p: &GcukParams,
    runs: usize,
    seed: u64,
) -> anyhow::Result<Vec<serde_json::Value>> {
    (0..runs)
        .map(|r| {
            let s = seed + r as u64;
            let g = p.clone().seed(s).fit(d)?;
            Ok(run_json(d, s, &g.medoids, &g.labels, g.loss, g.db_index))
        })
        .collect()
}

/// The run with the lowest DB index (ties: first).
pub fn best(runs: &[serde_json::Value]) -> serde_json::Value {
    runs.iter()
        .min_by(|a, b| {
            a["db_index"]
                .as_f64()
                .unwrap_or(f64::INFINITY)
                .total_cmp(&b["db_index"].as_f64().unwrap_or(f64::INFINITY))
        })
        .cloned()
        .unwrap_or(serde_json::Value::Null)
}

/// Runs the selection.
pub fn run(g: &Global, a: SelectArgs) -> anyhow::Result<()> {
    if a.distances.is_some() && (!a.collection.is_empty() || a.method == "empirical") {
        anyhow::bail!("--distances clusters a saved matrix (--method kmedoids or gcuk) and takes no COLLECTION");
    }
    let coll = super::load_collection(&a.collection)?;
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
                .stride(a.grid.stride);
            let (d, metric) = match &a.distances {
                Some(path) => {
                    let saved = brdf_basis::io::matrix::load_saved_matrix(path)?;
                    let metric = saved
                        .sidecar
                        .map_or(a.metric.to_string(), |s| s.settings.metric);
                    (saved.matrix, metric)
                }
                None => {
                    let dp = dp.check(&coll)?;
                    let d = distance_matrix(backend.as_ref(), &coll, &dp, &progress)?;
                    (d, a.metric.to_string())
                }
            };
            let runs = if a.method == "kmedoids" {
                let ks: Vec<usize> = match a.k {
                    Some(k) => vec![k],
                    None => (a.k_min..=a.k_max.unwrap_or(12)).collect(),
                };
                kmedoids_runs(&d, &ks, a.runs, g.seed)?
            } else {
                let p = GcukParams::default()
                    .k_range(a.k_min, a.k_max.unwrap_or(20))
                    .population(a.population)
                    .generations(a.generations);
                gcuk_runs(&d, &p, a.runs, g.seed)?
            };
            json!({"method": a.method, "metric": metric, "runs": runs, "best": best(&runs)})
        }
        other => anyhow::bail!("unknown method `{other}` (expected empirical, kmedoids or gcuk)"),
    };
    pb.finish_and_clear();
    write_json(&a.json, &value)?;
    if !g.quiet {
        eprintln!("wrote {}", a.json.display());
    }
    Ok(())
}
