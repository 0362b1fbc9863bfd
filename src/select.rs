//! Empirical basis selection (the paper's Algorithm 1, leave-one-out): every material is
//! fitted by all the others; each material that contributes (a coefficient > 0 in some
//! channel) gets a count; the basis is the materials counted more than a threshold.

use crate::backend::{Backend, Progress};
use crate::collection::Collection;
use crate::fit::{channel_lobe, fit_cells, FitError, FitParams, LAMBERTIAN};
use crate::nnls::{lawson_hanson, GramProblem};
use rayon::prelude::*;
use std::collections::BTreeMap;

/// Parameters of the empirical selection.
#[derive(Clone, Debug)]
pub struct EmpiricalParams {
    /// Fit settings (mask, weighting, stride; the solver is always exact here).
    pub fit: FitParams,
    /// A material enters the basis when it contributes to more than this many fits
    /// (paper: 5).
    pub more_than: usize,
}

impl Default for EmpiricalParams {
    fn default() -> Self {
        Self {
            fit: FitParams::default(),
            more_than: 5,
        }
    }
}

/// Result of the empirical selection.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Empirical {
    /// Contributions of each material (collection order).
    pub histogram: BTreeMap<String, usize>,
    /// For each target, the materials that contributed to its fit (collection order).
    pub contributors: BTreeMap<String, Vec<String>>,
    /// Materials counted more than the threshold, most frequent first (ties: collection
    /// order).
    pub basis: Vec<String>,
    /// Counts in collection order.
    pub counts: Vec<usize>,
}

/// Runs Algorithm 1 on `coll`: one Gram pass over the grid per channel for all materials,
/// then one exact rank-deficiency-safe NNLS per target and channel.
pub fn empirical(
    backend: &dyn Backend,
    coll: &Collection,
    p: &EmpiricalParams,
    progress: Progress<'_>,
) -> Result<Empirical, FitError> {
    let n = coll.len();
    if n < 2 {
        return Err(FitError::EmptyBasis);
    }
    let all: Vec<usize> = (0..n).collect();
    let cells = fit_cells(coll, &all, &p.fit);
    let mut contributes = vec![vec![false; n]; n];
    let lh = lawson_hanson::LhParams::default();
    for c in 0..3 {
        let mut lobes = vec![LAMBERTIAN];
        lobes.extend(coll.materials().iter().map(|m| channel_lobe(&m.data, c)));
        let m1 = n + 1;
        let full = crate::fit::gram_full(backend, &lobes, &cells, m1, p.fit.gram, progress)?;
        let rows: Vec<Vec<bool>> = (0..n)
            .into_par_iter()
            .map(|t| {
                // Columns: Lambertian, then every material but t.
                let cols: Vec<usize> = std::iter::once(0)
                    .chain((0..n).filter(|&j| j != t).map(|j| j + 1))
                    .collect();
                let m = cols.len();
                let mut g = vec![0.0; m * m];
                for (a, &ca) in cols.iter().enumerate() {
                    for (b, &cb) in cols.iter().enumerate() {
                        g[a * m + b] = full[ca * m1 + cb];
                    }
                }
                let h: Vec<f64> = cols.iter().map(|&ca| full[ca * m1 + t + 1]).collect();
                let bb = full[(t + 1) * m1 + t + 1];
                let mut used = vec![false; n];
                let sol =
                    GramProblem::new(m, &g, &h, bb).and_then(|pr| lawson_hanson::solve(&pr, &lh));
                if let Ok(sol) = sol {
                    for (k, &ca) in cols.iter().enumerate().skip(1) {
                        if sol.x[k] > 0.0 {
                            used[ca - 1] = true;
                        }
                    }
                }
                used
            })
            .collect();
        for (t, r) in rows.into_iter().enumerate() {
            for (j, u) in r.into_iter().enumerate() {
                contributes[t][j] |= u;
            }
        }
    }
    let names = coll.names();
    let counts: Vec<usize> = (0..n)
        .map(|j| (0..n).filter(|&t| contributes[t][j]).count())
        .collect();
    let mut order: Vec<usize> = (0..n).filter(|&j| counts[j] > p.more_than).collect();
    order.sort_by_key(|&j| (std::cmp::Reverse(counts[j]), j));
    Ok(Empirical {
        histogram: names.iter().cloned().zip(counts.iter().copied()).collect(),
        contributors: (0..n)
            .map(|t| {
                (
                    names[t].clone(),
                    (0..n)
                        .filter(|&j| contributes[t][j])
                        .map(|j| names[j].clone())
                        .collect(),
                )
            })
            .collect(),
        basis: order.into_iter().map(|j| names[j].clone()).collect(),
        counts,
    })
}
