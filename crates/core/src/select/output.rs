//! The result of `brdf-basis select` (SPEC-cli, `select`): one typed value per method
//! family, written and read back by the same type, each carrying the fingerprint of the
//! collection it came from ([`crate::collection::Collection::fingerprint`]; for a saved
//! matrix, the one its sidecar records; `null` for a CSV matrix, which has none).

use super::empirical::Empirical;
use super::runs::{best_run, ClusteringRun};
use super::search::Selection;
use super::SelectionError;
use crate::backend::weighted::TargetWeight;
use crate::cluster::ClusterError;
use crate::merl::{Mask, Weighting};
use std::collections::BTreeMap;
use std::path::Path;

/// `select --method empirical`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EmpiricalOutput {
    /// Always `empirical`.
    pub method: String,
    /// Contributions of each material.
    pub histogram: BTreeMap<String, usize>,
    /// For each target, the materials that contributed to its fit.
    pub contributors: BTreeMap<String, Vec<String>>,
    /// The basis: materials contributing to more than the threshold.
    pub basis: Vec<String>,
    /// Fingerprint of the collection.
    pub collection_fingerprint: Option<String>,
    /// The fit objective of the fits that chose the basis (`l2`, `relative`, `log`;
    /// recorded by `select`, absent in older files and in `reproduce`'s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit_objective: Option<String>,
    /// `eps` of the `relative` fit objective.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eps: Option<f64>,
    /// Grid cells of the fits (`evaluation`, `valid`; recorded by `select`, absent in
    /// older files and in `reproduce`'s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask: Option<String>,
    /// Cell weights of the fits (`uniform`, `solid-angle`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weighting: Option<String>,
    /// Every `stride`-th cell on each grid axis of the fits.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stride: Option<usize>,
}

impl EmpiricalOutput {
    /// The output of an empirical selection of the collection with `fingerprint`; an
    /// error when the basis is empty (no material contributes to more than `more_than`
    /// fits).
    pub fn new(
        e: &Empirical,
        more_than: usize,
        fingerprint: Option<String>,
    ) -> Result<Self, SelectionError> {
        if e.basis.is_empty() {
            return Err(SelectionError::EmptyEmpiricalBasis {
                more_than,
                most: e.counts.iter().copied().max().unwrap_or(0),
            });
        }
        Ok(Self::of(e, fingerprint))
    }

    /// The output of an empirical selection as it is, an empty basis included (`reproduce`
    /// writes it as `empirical.json` and reports an empty basis itself).
    pub fn of(e: &Empirical, fingerprint: Option<String>) -> Self {
        Self {
            method: "empirical".into(),
            histogram: e.histogram.clone(),
            contributors: e.contributors.clone(),
            basis: e.basis.clone(),
            collection_fingerprint: fingerprint,
            fit_objective: None,
            eps: None,
            mask: None,
            weighting: None,
            stride: None,
        }
    }
}

/// `select --method kmedoids|gcuk`: every seeded run and the best one.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClusteringOutput {
    /// `kmedoids` or `gcuk`.
    pub method: String,
    /// k-medoids local search (`fasterpam`, `pam`); absent for GCUK.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub algorithm: Option<String>,
    /// Metric of the distance matrix.
    pub metric: String,
    /// Every run, in (k, seed) order.
    pub runs: Vec<ClusteringRun>,
    /// The best run ([`best_run`]: lowest DB index, ties within the tolerance to the first).
    pub best: ClusteringRun,
    /// Fingerprint of the collection (`null` for a CSV matrix).
    pub collection_fingerprint: Option<String>,
    /// Grid cells of the distances (`evaluation`, `valid`; recorded by `select`, absent in
    /// older files and for a CSV matrix).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask: Option<String>,
    /// Cell weights of the distances (`uniform`, `solid-angle`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weighting: Option<String>,
    /// Every `stride`-th cell on each grid axis of the distances.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stride: Option<usize>,
}

impl ClusteringOutput {
    /// The output of `runs`; an error when there is no run or when no run has a defined
    /// Davies-Bouldin index (two medoids at distance 0 in every run: the matrix holds
    /// duplicate or all-zero rows; or distances so large that their sums overflow).
    pub fn new(
        method: &str,
        algorithm: Option<String>,
        metric: &str,
        runs: Vec<ClusteringRun>,
        fingerprint: Option<String>,
    ) -> Result<Self, ClusterError> {
        let best = best_run(&runs).cloned().ok_or(ClusterError::ZeroRuns)?;
        if !best.db_index.is_finite() {
            let overflowed = runs.iter().filter(|r| !r.loss.is_finite()).count();
            if overflowed > 0 {
                return Err(ClusterError::DistanceSumOverflow {
                    runs: runs.len(),
                    overflowed,
                });
            }
            return Err(ClusterError::UndefinedDbIndex { runs: runs.len() });
        }
        Ok(Self {
            method: method.into(),
            algorithm,
            metric: metric.into(),
            runs,
            best,
            collection_fingerprint: fingerprint,
            mask: None,
            weighting: None,
            stride: None,
        })
    }
}

/// `select --method greedy|swap|ga`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ErrorDrivenOutput {
    /// The selection.
    #[serde(flatten)]
    pub selection: Selection,
    /// Fingerprint of the collection.
    pub collection_fingerprint: Option<String>,
    /// The fit objective of the fits that chose the basis (`l2`, `relative`, `log`;
    /// recorded by `select`, absent in older files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit_objective: Option<String>,
    /// `eps` of the `relative` fit objective.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eps: Option<f64>,
    /// Grid cells of the fits (`evaluation`, `valid`; recorded by `select`, absent in
    /// older files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask: Option<String>,
    /// Cell weights of the fits (`uniform`, `solid-angle`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weighting: Option<String>,
    /// Every `stride`-th cell on each grid axis of the fits.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stride: Option<usize>,
}

/// The `select` JSON, any method.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
pub enum SelectOutput {
    /// Empirical (Algorithm 1).
    Empirical(EmpiricalOutput),
    /// k-medoids or GCUK.
    Clustering(ClusteringOutput),
    /// Greedy, swap or GA (by fitting error).
    ErrorDriven(ErrorDrivenOutput),
}

/// Errors reading a `select` JSON.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SelectFileError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: std::path::PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file is not a `select` result.
    #[error("{path} is not a `select` result: {message}")]
    Parse {
        /// The file.
        path: std::path::PathBuf,
        /// What failed.
        message: String,
    },
}

impl SelectOutput {
    /// Reads a `select` JSON.
    pub fn read(path: &Path) -> Result<Self, SelectFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| SelectFileError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json(&text).map_err(|message| SelectFileError::Parse {
            path: path.to_path_buf(),
            message,
        })
    }

    /// Parses a `select` JSON.
    pub fn from_json(text: &str) -> Result<Self, String> {
        serde_json::from_str(text).map_err(|e| e.to_string())
    }

    /// The JSON text (pretty, with a final newline).
    pub fn to_json(&self) -> String {
        // Plain structs of strings, numbers and maps with string keys always serialise.
        let mut s = serde_json::to_string_pretty(self).unwrap_or_default();
        s.push('\n');
        s
    }

    /// Records what chose the basis (issue 47): the grid of the fits or distances, and
    /// the fit objective of the methods that fit (empirical, greedy, swap, ga; `None` for
    /// the clustering methods, which work on distances).
    pub fn record(
        &mut self,
        objective: Option<TargetWeight>,
        mask: Mask,
        weighting: Weighting,
        stride: usize,
    ) {
        let grid = (
            Some(mask.to_string()),
            Some(weighting.to_string()),
            Some(stride),
        );
        let fit = (
            objective.map(|w| w.kind().name().to_string()),
            objective.and_then(TargetWeight::eps),
        );
        match self {
            SelectOutput::Empirical(e) => {
                (e.mask, e.weighting, e.stride) = grid;
                (e.fit_objective, e.eps) = fit;
            }
            SelectOutput::ErrorDriven(s) => {
                (s.mask, s.weighting, s.stride) = grid;
                (s.fit_objective, s.eps) = fit;
            }
            SelectOutput::Clustering(c) => (c.mask, c.weighting, c.stride) = grid,
        }
    }

    /// The chosen basis, by name (clustering: the best run's medoids).
    pub fn basis(&self) -> &[String] {
        match self {
            SelectOutput::Empirical(e) => &e.basis,
            SelectOutput::Clustering(c) => &c.best.medoids,
            SelectOutput::ErrorDriven(s) => &s.selection.basis,
        }
    }

    /// The fingerprint of the collection it came from.
    pub fn collection_fingerprint(&self) -> Option<&str> {
        match self {
            SelectOutput::Empirical(e) => e.collection_fingerprint.as_deref(),
            SelectOutput::Clustering(c) => c.collection_fingerprint.as_deref(),
            SelectOutput::ErrorDriven(s) => s.collection_fingerprint.as_deref(),
        }
    }
}

impl std::fmt::Display for SelectOutput {
    /// One line: the method, k, the basis and its score (loss and DB index, or S).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SelectOutput::Empirical(e) => write!(
                f,
                "empirical: k = {}, basis {}",
                e.basis.len(),
                e.basis.join(",")
            ),
            SelectOutput::Clustering(c) => write!(
                f,
                "{} (best of {} runs, seed {}): k = {}, loss = {}, DB = {}, medoids {}",
                c.method,
                c.runs.len(),
                c.best.seed,
                c.best.k,
                crate::stats::num(c.best.loss),
                crate::stats::num(c.best.db_index),
                c.best.medoids.join(",")
            ),
            SelectOutput::ErrorDriven(s) => {
                let s = &s.selection;
                write!(
                    f,
                    "{}: k = {}, S = {}, basis {}",
                    s.method,
                    s.k,
                    crate::stats::num(s.score),
                    s.basis.join(",")
                )
            }
        }
    }
}
