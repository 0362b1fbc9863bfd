//! Seeded clustering runs (k-medoids per k, GCUK) with every validity index, as written to
//! `clustering.json` and `clustering_db.csv`.

use super::files::inf_as_null;
use crate::cluster::indices::{dunn, silhouette};
use crate::cluster::{ClusterError, GcukParams, KMedoidsInit, KMedoidsParams};
use crate::distance::DistanceMatrix;
use rayon::prelude::*;

/// One seeded clustering run.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClusteringRun {
    /// Seed of the run.
    pub seed: u64,
    /// Number of clusters.
    pub k: usize,
    /// Medoid of each cluster (material names).
    pub medoids: Vec<String>,
    /// Cluster index of each material, collection order.
    pub labels: Vec<usize>,
    /// k-medoids loss `sum_x D[x][medoid(x)]`.
    pub loss: f64,
    /// Medoid Davies-Bouldin index (lower is better; `null` for +inf).
    #[serde(with = "inf_as_null")]
    pub db_index: f64,
    /// Mean silhouette width (higher is better).
    pub silhouette: f64,
    /// Dunn index (higher is better; `null` when every cluster is a singleton).
    pub dunn: Option<f64>,
}

/// Every run of one method on one metric.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClusteringSet {
    /// Metric label (`euclidean`, `brdf-it`, `brdf-it-solid-angle`).
    pub metric: String,
    /// Method label (`kmedoids-k5`, ..., `gcuk`).
    pub method: String,
    /// Runs in seed order.
    pub runs: Vec<ClusteringRun>,
    /// The run with the lowest DB index (ties: the first).
    pub best: ClusteringRun,
}

impl ClusteringSet {
    /// DB index of every run, in run order.
    pub fn db_values(&self) -> Vec<f64> {
        self.runs.iter().map(|r| r.db_index).collect()
    }
}

/// The run with the lowest DB index (ties: the first); `None` for no runs.
pub fn best_run<'a>(
    runs: impl IntoIterator<Item = &'a ClusteringRun>,
) -> Option<&'a ClusteringRun> {
    runs.into_iter()
        .fold(None, |best: Option<&ClusteringRun>, r| match best {
            Some(b) if b.db_index <= r.db_index => Some(b),
            _ => Some(r),
        })
}

fn run_of(
    d: &DistanceMatrix,
    seed: u64,
    medoids: &[usize],
    labels: &[usize],
    loss: f64,
    db_index: f64,
) -> Result<ClusteringRun, ClusterError> {
    Ok(ClusteringRun {
        seed,
        k: medoids.len(),
        medoids: medoids.iter().map(|&m| d.names()[m].clone()).collect(),
        labels: labels.to_vec(),
        loss,
        db_index,
        silhouette: silhouette(d, labels)?,
        dunn: dunn(d, labels)?,
    })
}

fn set(metric: &str, method: String, runs: Vec<ClusteringRun>) -> ClusteringSet {
    let best = best_run(&runs).cloned().unwrap_or_else(|| runs[0].clone());
    ClusteringSet {
        metric: metric.to_string(),
        method,
        runs,
        best,
    }
}

/// `runs` seeded k-medoids runs (seeds `seed`, `seed + 1`, ...; random initial medoids)
/// for every `k` of `ks`, one [`ClusteringSet`] per `k`. Needs `runs >= 1`.
pub fn kmedoids_sets(
    d: &DistanceMatrix,
    metric: &str,
    ks: &[usize],
    runs: usize,
    seed: u64,
) -> Result<Vec<ClusteringSet>, ClusterError> {
    if runs == 0 {
        return Err(ClusterError::ZeroRuns);
    }
    ks.iter()
        .map(|&k| {
            let runs = (0..runs as u64)
                .into_par_iter()
                .map(|r| {
                    let km = KMedoidsParams::new(k)
                        .seed(seed + r)
                        .init(KMedoidsInit::Random)
                        .fit(d)?;
                    run_of(d, seed + r, &km.medoids, &km.labels, km.loss, km.db_index)
                })
                .collect::<Result<Vec<_>, _>>()?;
            Ok(set(metric, format!("kmedoids-k{k}"), runs))
        })
        .collect()
}

/// `runs` seeded GCUK runs with parameters `p` (the seed is replaced by `seed + r`).
pub fn gcuk_set(
    d: &DistanceMatrix,
    metric: &str,
    p: &GcukParams,
    runs: usize,
    seed: u64,
) -> Result<ClusteringSet, ClusterError> {
    if runs == 0 {
        return Err(ClusterError::ZeroRuns);
    }
    let valid = p.clone().check()?;
    let runs = (0..runs as u64)
        .into_par_iter()
        .map(|r| {
            let g = GcukParams {
                seed: seed + r,
                ..valid.params().clone()
            }
            .fit(d)?;
            run_of(d, seed + r, &g.medoids, &g.labels, g.loss, g.db_index)
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(set(metric, "gcuk".into(), runs))
}

/// `clustering_db.csv`: `metric,method,run,seed,k,db_index,loss,medoids,silhouette,dunn`
/// (medoids joined by `;`, an undefined index left empty; CSV quoting as needed).
pub fn db_csv(sets: &[ClusteringSet]) -> String {
    let num = |v: f64| {
        if v.is_finite() {
            format!("{v:e}")
        } else {
            String::new()
        }
    };
    let mut w = csv::Writer::from_writer(Vec::new());
    let header = [
        "metric",
        "method",
        "run",
        "seed",
        "k",
        "db_index",
        "loss",
        "medoids",
        "silhouette",
        "dunn",
    ];
    // Writing to a Vec cannot fail.
    let _ = w.write_record(header);
    for c in sets {
        for (r, run) in c.runs.iter().enumerate() {
            let _ = w.write_record([
                c.metric.clone(),
                c.method.clone(),
                r.to_string(),
                run.seed.to_string(),
                run.k.to_string(),
                num(run.db_index),
                num(run.loss),
                run.medoids.join(";"),
                num(run.silhouette),
                run.dunn.map(num).unwrap_or_default(),
            ]);
        }
    }
    String::from_utf8(w.into_inner().unwrap_or_default()).unwrap_or_default()
}
