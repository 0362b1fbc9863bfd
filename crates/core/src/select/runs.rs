//! Seeded multi-run clustering (k-medoids per k, GCUK) and the one best-run rule.
//!
//! Run `r` of a configuration uses seed `seed + r` (k-medoids: random initial medoids;
//! GCUK: the whole run). Runs are computed in parallel but listed in (k, run) order, so the
//! result does not depend on the thread count. The best run is the one with the lowest
//! Davies-Bouldin index, a later run winning only when it is lower by more than
//! [`TIE_TOLERANCE`] (relative; `clearly_lower`), so ties go to the earliest run. `select`,
//! `reproduce` and `cv` all choose by [`best_index`].

use crate::backend::Progress;
use crate::cluster::indices::{dunn, silhouette};
use crate::cluster::{
    clearly_lower, ClusterError, GcukParams, KMedoidsAlgorithm, KMedoidsInit, KMedoidsParams,
    ValidGcukParams, TIE_TOLERANCE,
};
use crate::distance::DistanceMatrix;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// One seeded run, by material index.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// Seed of the run.
    pub seed: u64,
    /// Medoid of each cluster (indices into the matrix).
    pub medoids: Vec<usize>,
    /// Cluster index of each material.
    pub labels: Vec<usize>,
    /// k-medoids loss `sum_x D[x][medoid(x)]`.
    pub loss: f64,
    /// Medoid Davies-Bouldin index (`+inf` when two medoids are at distance 0).
    pub db_index: f64,
}

/// The index of the best of `db` values: the lowest, a later one winning only when
/// `clearly_lower` by [`TIE_TOLERANCE`] (ties: the first); `None` for no value.
pub fn best_index(db: impl IntoIterator<Item = f64>) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (i, v) in db.into_iter().enumerate() {
        if best.is_none_or(|(_, b)| clearly_lower(v, b, TIE_TOLERANCE)) {
            best = Some((i, v));
        }
    }
    best.map(|(i, _)| i)
}

/// A counter shared by parallel runs, reporting `(done, total)` after each.
fn counter<'a>(total: u64, progress: Progress<'a>) -> impl Fn() + Sync + 'a {
    let done = AtomicU64::new(0);
    move || progress(done.fetch_add(1, Ordering::Relaxed) + 1, total)
}

/// `runs` seeded k-medoids runs with `algorithm` (random initial medoids, seeds `seed`,
/// `seed + 1`, ...) for every k of `ks`, in (k, run) order. `progress(done, total)` counts
/// runs. Needs `runs >= 1`.
pub fn kmedoids_runs(
    d: &DistanceMatrix,
    ks: &[usize],
    runs: usize,
    seed: u64,
    algorithm: KMedoidsAlgorithm,
    progress: Progress<'_>,
) -> Result<Vec<Run>, ClusterError> {
    if runs == 0 {
        return Err(ClusterError::ZeroRuns);
    }
    let jobs: Vec<(usize, u64)> = ks
        .iter()
        .flat_map(|&k| (0..runs as u64).map(move |r| (k, seed.wrapping_add(r))))
        .collect();
    let tick = counter(jobs.len() as u64, progress);
    jobs.par_iter()
        .map(|&(k, s)| {
            let km = KMedoidsParams::new(k)
                .algorithm(algorithm)
                .seed(s)
                .init(KMedoidsInit::Random)
                .fit(d)?;
            tick();
            Ok(Run {
                seed: s,
                medoids: km.medoids,
                labels: km.labels,
                loss: km.loss,
                db_index: km.db_index,
            })
        })
        .collect()
}

/// `runs` seeded GCUK runs with parameters `p` (the seed is replaced by `seed + r`), in
/// run order. `progress(done, total)` counts runs. Needs `runs >= 1`.
pub fn gcuk_runs(
    d: &DistanceMatrix,
    p: &ValidGcukParams,
    runs: usize,
    seed: u64,
    progress: Progress<'_>,
) -> Result<Vec<Run>, ClusterError> {
    if runs == 0 {
        return Err(ClusterError::ZeroRuns);
    }
    let tick = counter(runs as u64, progress);
    (0..runs as u64)
        .into_par_iter()
        .map(|r| {
            let s = seed.wrapping_add(r);
            let g = GcukParams {
                seed: s,
                ..p.params().clone()
            }
            .fit(d)?;
            tick();
            Ok(Run {
                seed: s,
                medoids: g.medoids,
                labels: g.labels,
                loss: g.loss,
                db_index: g.db_index,
            })
        })
        .collect()
}

/// Writes a finite value as a number, anything else as `null`; reads `null` as `+inf`.
pub mod inf_as_null {
    use serde::{Deserialize, Deserializer, Serializer};

    /// Writes a finite value as a number, anything else as `null`.
    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            s.serialize_f64(*v)
        } else {
            s.serialize_none()
        }
    }

    /// Reads a number, or `null` as `+inf`.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
    }
}

/// One seeded clustering run, by name, with every validity index.
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

impl ClusteringRun {
    /// The run `r` of matrix `d` by name, with its silhouette and Dunn index.
    pub fn named(d: &DistanceMatrix, r: &Run) -> Result<Self, ClusterError> {
        Ok(ClusteringRun {
            seed: r.seed,
            k: r.medoids.len(),
            medoids: r.medoids.iter().map(|&m| d.names()[m].clone()).collect(),
            labels: r.labels.clone(),
            loss: r.loss,
            db_index: r.db_index,
            silhouette: silhouette(d, &r.labels)?,
            dunn: dunn(d, &r.labels)?,
        })
    }
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
    /// The best run ([`best_run`]).
    pub best: ClusteringRun,
}

impl ClusteringSet {
    /// DB index of every run, in run order.
    pub fn db_values(&self) -> Vec<f64> {
        self.runs.iter().map(|r| r.db_index).collect()
    }
}

/// The run with the lowest DB index, ties within [`TIE_TOLERANCE`] to the first
/// ([`best_index`]); `None` for no runs.
pub fn best_run<'a>(
    runs: impl IntoIterator<Item = &'a ClusteringRun>,
) -> Option<&'a ClusteringRun> {
    let runs: Vec<&ClusteringRun> = runs.into_iter().collect();
    best_index(runs.iter().map(|r| r.db_index)).map(|i| runs[i])
}

/// Named runs with their indices, in order.
pub fn named_runs(d: &DistanceMatrix, runs: &[Run]) -> Result<Vec<ClusteringRun>, ClusterError> {
    runs.par_iter()
        .map(|r| ClusteringRun::named(d, r))
        .collect()
}

fn set(
    metric: &str,
    method: String,
    runs: Vec<ClusteringRun>,
) -> Result<ClusteringSet, ClusterError> {
    let best = best_run(&runs).cloned().ok_or(ClusterError::ZeroRuns)?;
    Ok(ClusteringSet {
        metric: metric.to_string(),
        method,
        runs,
        best,
    })
}

/// `runs` seeded k-medoids runs (FasterPAM, seeds `seed`, `seed + 1`, ...; random initial
/// medoids) for every `k` of `ks`, one [`ClusteringSet`] per `k`. Needs `runs >= 1`.
pub(crate) fn kmedoids_sets(
    d: &DistanceMatrix,
    metric: &str,
    ks: &[usize],
    runs: usize,
    seed: u64,
) -> Result<Vec<ClusteringSet>, ClusterError> {
    let all = kmedoids_runs(d, ks, runs, seed, KMedoidsAlgorithm::FasterPam, &|_, _| {})?;
    let named = named_runs(d, &all)?;
    ks.iter()
        .zip(named.chunks(runs))
        .map(|(&k, chunk)| set(metric, format!("kmedoids-k{k}"), chunk.to_vec()))
        .collect()
}

/// `runs` seeded GCUK runs with parameters `p` (the seed is replaced by `seed + r`).
pub(crate) fn gcuk_set(
    d: &DistanceMatrix,
    metric: &str,
    p: &GcukParams,
    runs: usize,
    seed: u64,
) -> Result<ClusteringSet, ClusterError> {
    let valid = p.check()?;
    let all = gcuk_runs(d, &valid, runs, seed, &|_, _| {})?;
    set(metric, "gcuk".into(), named_runs(d, &all)?)
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
