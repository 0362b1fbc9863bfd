//! The folds and the basis each method chooses from a fold's training materials.

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::super::ga::{ga, GaParams};
use super::super::greedy::greedy_indices;
use super::super::objective::Objective;
use super::super::runs::{best_index, gcuk_runs};
use super::super::search::SearchParams;
use super::super::swap::swap;
use super::super::SelectionError;
use super::params::{CvMethod, ValidCvParams};
use crate::cluster::{GcukParams, KMedoidsParams};
use crate::distance::DistanceMatrix;

/// The folds of `n` materials for `seed`: a seeded permutation cut into `folds` parts of
/// sizes differing by at most one, each sorted.
pub(crate) fn make_folds(n: usize, folds: usize, seed: u64) -> Vec<Vec<usize>> {
    let mut perm: Vec<usize> = (0..n).collect();
    perm.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let (base, extra) = (n / folds, n % folds);
    let mut out = Vec::with_capacity(folds);
    let mut at = 0;
    for f in 0..folds {
        let len = base + usize::from(f < extra);
        let mut fold = perm[at..at + len].to_vec();
        fold.sort_unstable();
        out.push(fold);
        at += len;
    }
    out
}

/// One fold's training materials and what its methods share (computed on first use).
pub(crate) struct Fold<'a> {
    /// Fold index.
    pub f: usize,
    /// Training materials (collection indices, increasing).
    pub train: Vec<usize>,
    obj: &'a Objective,
    names: &'a [String],
    /// The distance matrix restricted to `train`.
    sub: Option<DistanceMatrix>,
    /// The greedy basis of the largest k (its prefixes are the smaller greedy bases).
    greedy_max: Option<Vec<usize>>,
    /// Leave-one-out contribution counts of the training materials.
    counts: Option<Vec<usize>>,
}

impl<'a> Fold<'a> {
    /// Fold `f` of `n` materials, `held` its held-out materials.
    pub(crate) fn new(
        f: usize,
        n: usize,
        held: &[usize],
        obj: &'a Objective,
        names: &'a [String],
        dist: Option<&DistanceMatrix>,
    ) -> Self {
        let train: Vec<usize> = (0..n).filter(|i| held.binary_search(i).is_err()).collect();
        let sub = dist.map(|d| d.subset(&train));
        Self {
            f,
            train,
            obj,
            names,
            sub,
            greedy_max: None,
            counts: None,
        }
    }

    fn distances(&self) -> Result<&DistanceMatrix, SelectionError> {
        self.sub
            .as_ref()
            .ok_or_else(|| SelectionError::InvalidParam {
                name: "distances",
                value: "none".into(),
                expected: "a distance matrix for the clustering methods",
            })
    }

    fn to_collection(&self, local: &[usize]) -> Vec<usize> {
        local.iter().map(|&i| self.train[i]).collect()
    }

    /// The basis (collection indices) method `m` chooses from the training materials.
    pub(crate) fn basis(
        &mut self,
        m: CvMethod,
        k: usize,
        vp: &ValidCvParams,
    ) -> Result<Vec<usize>, SelectionError> {
        let p = vp.params();
        let sp = SearchParams::new(k)
            .candidates(self.train.clone())
            .targets(self.train.clone());
        Ok(match m {
            CvMethod::Greedy | CvMethod::Swap => {
                let start = self.greedy_prefix(k, p.ks.iter().copied().max().unwrap_or(k))?;
                if m == CvMethod::Greedy {
                    start
                } else {
                    swap(self.obj, &sp.init(start).check(self.names)?, &|_, _| {})?.indices
                }
            }
            CvMethod::Ga => {
                let gp = GaParams {
                    seed: vp.ga.params().seed.wrapping_add(self.f as u64),
                    ..vp.ga.params().clone()
                }
                .check()?;
                ga(self.obj, &sp.check(self.names)?, &gp, &|_, _| {})?.indices
            }
            CvMethod::Kmedoids => {
                let km = KMedoidsParams::new(k)
                    .restarts(p.runs)
                    .seed(p.seed)
                    .fit(self.distances()?)?;
                self.to_collection(&km.medoids)
            }
            CvMethod::Gcuk => {
                let gp = GcukParams::default().k_range(k, k).check()?;
                let runs = gcuk_runs(self.distances()?, &gp, p.runs, p.seed, &|_, _| {})?;
                let best = best_index(runs.iter().map(|r| r.db_index))
                    .ok_or(crate::cluster::ClusterError::ZeroRuns)?;
                self.to_collection(&runs[best].medoids)
            }
            CvMethod::Empirical => {
                if self.counts.is_none() {
                    self.counts = Some(empirical_counts(self.obj, &self.train)?);
                }
                let c = self.counts.as_deref().unwrap_or_default();
                let mut order: Vec<usize> = (0..self.train.len()).collect();
                order.sort_by_key(|&j| (std::cmp::Reverse(c[j]), j));
                self.to_collection(&order[..k])
            }
            CvMethod::Random => {
                let mut rng =
                    ChaCha8Rng::seed_from_u64(p.seed.wrapping_add(1000 * self.f as u64 + k as u64));
                let mut b = self.to_collection(
                    &rand::seq::index::sample(&mut rng, self.train.len(), k).into_vec(),
                );
                b.sort_unstable();
                b
            }
        })
    }

    /// The first `k` materials of the greedy basis of size `kmax`.
    fn greedy_prefix(&mut self, k: usize, kmax: usize) -> Result<Vec<usize>, SelectionError> {
        if self.greedy_max.is_none() {
            let spm = SearchParams::new(kmax)
                .candidates(self.train.clone())
                .targets(self.train.clone())
                .check(self.names)?;
            self.greedy_max = Some(greedy_indices(self.obj, &spm, &|_, _| {})?);
        }
        let g = self.greedy_max.as_deref().unwrap_or_default();
        Ok(g[..k.min(g.len())].to_vec())
    }
}

/// Contributions counted by the leave-one-out fits of `train` (index into `train`).
fn empirical_counts(obj: &Objective, train: &[usize]) -> Result<Vec<usize>, SelectionError> {
    let used: Vec<Vec<bool>> = train
        .par_iter()
        .map(|&t| {
            let others: Vec<usize> = train.iter().copied().filter(|&j| j != t).collect();
            let u = obj.contributors(&others, t)?;
            // Back to positions in `train` (t's own position stays false).
            let mut row = vec![false; train.len()];
            let mut it = u.into_iter();
            for (pos, &j) in train.iter().enumerate() {
                if j != t {
                    row[pos] = it.next().unwrap_or(false);
                }
            }
            Ok(row)
        })
        .collect::<Result<_, SelectionError>>()?;
    Ok((0..train.len())
        .map(|j| used.iter().filter(|r| r[j]).count())
        .collect())
}

/// Every method's basis at every k in every fold: `bases[method][k][fold]`.
/// `progress(done, total)` counts (fold, method, k) selections.
pub(crate) fn fold_bases(
    obj: &Objective,
    dist: Option<&DistanceMatrix>,
    folds: &[Vec<usize>],
    vp: &ValidCvParams,
    progress: crate::backend::Progress<'_>,
) -> Result<Vec<Vec<Vec<Vec<usize>>>>, SelectionError> {
    let p = vp.params();
    let n = obj.len();
    let mut bases = vec![vec![vec![Vec::new(); p.folds]; p.ks.len()]; p.methods.len()];
    let total = (p.folds * p.methods.len() * p.ks.len()) as u64;
    let mut done = 0;
    for (f, held) in folds.iter().enumerate() {
        let mut fold = Fold::new(f, n, held, obj, obj.names(), dist);
        for (mi, &m) in p.methods.iter().enumerate() {
            for (ki, &k) in p.ks.iter().enumerate() {
                bases[mi][ki][f] = fold.basis(m, k, vp)?;
                done += 1;
                progress(done, total);
            }
        }
    }
    Ok(bases)
}
