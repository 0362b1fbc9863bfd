//! k-medoids by PAM (Partitioning Around Medoids; Kaufman & Rousseeuw 1990, "Finding
//! Groups in Data", ch. 2, doi:10.1002/9780470316801.ch2) with seeded random restarts.
//!
//! Minimises the loss `sum_x D[x][m_{l(x)}]` over sets of `k` medoids, each item assigned
//! to its nearest medoid (ties to the lowest cluster index):
//!
//! * **BUILD** (deterministic): the first medoid minimises the sum of distances to all
//!   items; each next one maximises the loss decrease `sum_x max(0, d_x - D[x][c])`, where
//!   `d_x` is the distance of `x` to its nearest medoid so far (ties to the lowest index).
//! * **SWAP**, best improvement: every iteration evaluates all `k (n - k)` exchanges of a
//!   medoid with a non-medoid (using nearest and second-nearest distances, `O(k n^2)`)
//!   and applies the one with the most negative loss change. It stops when no exchange
//!   lowers the loss (recomputed exactly after each swap, so float noise cannot make it
//!   cycle) or after `max_iter` swaps.
//! * **Restarts**: run `r` in `0..restarts` starts from BUILD (run 0 with
//!   [`KMedoidsInit::Build`]) or from `k` distinct medoids drawn uniformly by a
//!   [`ChaCha8Rng`] seeded with `seed + r` (`seed_from_u64`, wrapping). The run with the
//!   lowest loss is returned; ties go to the earliest run.
//!
//! The result lists the medoids in increasing item order; cluster `i` is `medoids[i]` and
//! `labels[x]` indexes into `medoids` (nearest-medoid assignment, ties to the lowest `i`).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::validity::{assign_unchecked, check_distances, db_unchecked, loss_unchecked};
use super::ClusterError;
use crate::distance::Distances;

/// How the runs of k-medoids choose their initial medoids.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub enum KMedoidsInit {
    /// Run 0 starts from PAM's deterministic BUILD; runs `1..restarts` from random medoids.
    #[default]
    Build,
    /// Every run starts from `k` distinct medoids drawn uniformly at random.
    Random,
}

/// Parameters of [`KMedoids`] (builder; validate with [`KMedoidsParams::check`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct KMedoidsParams {
    /// Number of clusters, `2 <= k <= n`. No default.
    pub k: usize,
    /// Maximum number of SWAP steps per run (default 100; 0 keeps the initial medoids).
    pub max_iter: usize,
    /// Number of runs, at least 1 (default 1).
    pub restarts: usize,
    /// Seed of the random starts: run `r` uses `seed + r` (default 0).
    pub seed: u64,
    /// Initialisation (default [`KMedoidsInit::Build`]).
    pub init: KMedoidsInit,
}

impl KMedoidsParams {
    /// Parameters for `k` clusters with the defaults: 100 SWAP steps, 1 run, seed 0, BUILD.
    pub fn new(k: usize) -> Self {
        Self {
            k,
            max_iter: 100,
            restarts: 1,
            seed: 0,
            init: KMedoidsInit::Build,
        }
    }

    /// Sets the maximum number of SWAP steps per run.
    pub fn max_iter(mut self, max_iter: usize) -> Self {
        self.max_iter = max_iter;
        self
    }

    /// Sets the number of runs.
    pub fn restarts(mut self, restarts: usize) -> Self {
        self.restarts = restarts;
        self
    }

    /// Sets the seed of the random starts.
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// Sets the initialisation.
    pub fn init(mut self, init: KMedoidsInit) -> Self {
        self.init = init;
        self
    }

    /// Validates the parameters that do not depend on the data (`k >= 2`, `restarts >= 1`);
    /// `k <= n` is checked by [`ValidKMedoidsParams::fit`].
    pub fn check(self) -> Result<ValidKMedoidsParams, ClusterError> {
        if self.k < 2 {
            return Err(ClusterError::KTooSmall { k: self.k });
        }
        if self.restarts == 0 {
            return Err(ClusterError::ZeroRuns);
        }
        Ok(ValidKMedoidsParams(self))
    }

    /// Shorthand for `self.clone().check()?.fit(d)`.
    pub fn fit<D: Distances + ?Sized>(&self, d: &D) -> Result<KMedoids, ClusterError> {
        self.clone().check()?.fit(d)
    }
}

/// Validated [`KMedoidsParams`].
#[derive(Debug, Clone, PartialEq)]
pub struct ValidKMedoidsParams(KMedoidsParams);

impl ValidKMedoidsParams {
    /// The validated parameters.
    pub fn params(&self) -> &KMedoidsParams {
        &self.0
    }

    /// Runs PAM on `d`. Fails when `k > n` or a distance is negative or not finite.
    pub fn fit<D: Distances + ?Sized>(&self, d: &D) -> Result<KMedoids, ClusterError> {
        let p = &self.0;
        let n = d.len();
        if p.k > n {
            return Err(ClusterError::KOutOfRange { k: p.k, n });
        }
        check_distances(d)?;
        let mut best: Option<KMedoids> = None;
        for run in 0..p.restarts {
            let mut medoids = if run == 0 && p.init == KMedoidsInit::Build {
                build(d, p.k)
            } else {
                let mut rng = ChaCha8Rng::seed_from_u64(p.seed.wrapping_add(run as u64));
                rand::seq::index::sample(&mut rng, n, p.k).into_vec()
            };
            let iterations = swap(d, &mut medoids, p.max_iter);
            medoids.sort_unstable();
            let labels = assign_unchecked(d, &medoids);
            let loss = loss_unchecked(d, &medoids, &labels);
            if best.as_ref().is_none_or(|b| loss < b.loss) {
                let db_index = db_unchecked(d, &medoids, &labels);
                best = Some(KMedoids {
                    medoids,
                    labels,
                    loss,
                    iterations,
                    db_index,
                });
            }
        }
        // `restarts >= 1` was checked, so at least one run was made.
        best.ok_or(ClusterError::ZeroRuns)
    }
}

/// Result of k-medoids: the best of all runs.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct KMedoids {
    /// Medoid item of each cluster, in increasing item order (cluster `i` is `medoids[i]`).
    pub medoids: Vec<usize>,
    /// Cluster of each item: an index into `medoids`.
    pub labels: Vec<usize>,
    /// `sum_x D[x][medoids[labels[x]]]`.
    pub loss: f64,
    /// Number of SWAP steps made by the returned run.
    pub iterations: usize,
    /// Medoid Davies-Bouldin index of the partition.
    pub db_index: f64,
}

/// PAM's BUILD: greedy deterministic choice of `k` medoids.
fn build<D: Distances + ?Sized>(d: &D, k: usize) -> Vec<usize> {
    let n = d.len();
    let mut nearest = vec![f64::INFINITY; n];
    let mut is_medoid = vec![false; n];
    let mut medoids = Vec::with_capacity(k);
    for _ in 0..k {
        // Minimising the new loss is maximising the gain; ties to the lowest index.
        let mut best = (f64::INFINITY, 0);
        for c in (0..n).filter(|&c| !is_medoid[c]) {
            let cost: f64 = (0..n).map(|x| nearest[x].min(d.dist(x, c))).sum();
            if cost < best.0 {
                best = (cost, c);
            }
        }
        let c = best.1;
        is_medoid[c] = true;
        medoids.push(c);
        for (x, near) in nearest.iter_mut().enumerate() {
            *near = near.min(d.dist(x, c));
        }
    }
    medoids
}

/// PAM's SWAP with best improvement; returns the number of swaps made.
fn swap<D: Distances + ?Sized>(d: &D, medoids: &mut [usize], max_iter: usize) -> usize {
    let n = d.len();
    let k = medoids.len();
    let mut loss = loss_unchecked(d, medoids, &assign_unchecked(d, medoids));
    let mut iterations = 0;
    while iterations < max_iter {
        // Nearest cluster, its distance and the second-nearest distance of every item.
        let mut near = vec![0usize; n];
        let mut first = vec![f64::INFINITY; n];
        let mut second = vec![f64::INFINITY; n];
        for x in 0..n {
            for (i, &m) in medoids.iter().enumerate() {
                let dx = d.dist(x, m);
                if dx < first[x] {
                    second[x] = first[x];
                    first[x] = dx;
                    near[x] = i;
                } else if dx < second[x] {
                    second[x] = dx;
                }
            }
        }
        let mut is_medoid = vec![false; n];
        medoids.iter().for_each(|&m| is_medoid[m] = true);
        let mut best: Option<(f64, usize, usize)> = None;
        for i in 0..k {
            for h in (0..n).filter(|&h| !is_medoid[h]) {
                let delta: f64 = (0..n)
                    .map(|x| {
                        let dh = d.dist(x, h);
                        if near[x] == i {
                            dh.min(second[x]) - first[x]
                        } else {
                            (dh - first[x]).min(0.0)
                        }
                    })
                    .sum();
                if delta < best.map_or(0.0, |b| b.0) {
                    best = Some((delta, i, h));
                }
            }
        }
        let Some((_, i, h)) = best else { break };
        let old = medoids[i];
        medoids[i] = h;
        let new_loss = loss_unchecked(d, medoids, &assign_unchecked(d, medoids));
        if new_loss >= loss {
            medoids[i] = old;
            break;
        }
        loss = new_loss;
        iterations += 1;
    }
    iterations
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster::validity::tests::{Line, Matrix};
    use rand::Rng;

    fn random_points(n: usize, seed: u64) -> Matrix {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let p: Vec<[f64; 2]> = (0..n)
            .map(|_| [rng.random::<f64>(), rng.random::<f64>()])
            .collect();
        let data = (0..n * n)
            .map(|ij| {
                let (a, b) = (p[ij / n], p[ij % n]);
                ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
            })
            .collect();
        Matrix(n, data)
    }

    /// Minimum loss over all k-subsets, by enumeration (n <= 8).
    fn brute_force(d: &Matrix, k: usize) -> f64 {
        let n = d.len();
        (0u32..1 << n)
            .filter(|mask| mask.count_ones() as usize == k)
            .map(|mask| {
                let medoids: Vec<usize> = (0..n).filter(|&i| mask & (1 << i) != 0).collect();
                loss_unchecked(d, &medoids, &assign_unchecked(d, &medoids))
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn two_separated_groups() {
        let d = Line(vec![100.0, 0.0, 101.0, 1.0, 102.0, 2.0]);
        let r = KMedoidsParams::new(2).fit(&d).unwrap();
        assert_eq!(r.medoids, vec![2, 3]);
        assert_eq!(r.labels, vec![0, 1, 0, 1, 0, 1]);
        assert_eq!(r.loss, 4.0);
        // S = (2/3, 2/3), medoids 101 and 1 at distance 100.
        assert!((r.db_index - (4.0 / 3.0) / 100.0).abs() < 1e-15);
    }

    #[test]
    fn reaches_brute_force_optimum_on_tiny_sets() {
        for seed in 0..6 {
            let d = random_points(8, seed);
            for k in 2..=5 {
                let r = KMedoidsParams::new(k)
                    .restarts(10)
                    .seed(seed)
                    .fit(&d)
                    .unwrap();
                let opt = brute_force(&d, k);
                assert!(
                    (r.loss - opt).abs() <= 1e-12 * opt,
                    "seed {seed} k {k}: {} vs {opt}",
                    r.loss
                );
            }
        }
    }

    #[test]
    fn same_seed_same_result() {
        let d = random_points(40, 7);
        let p = KMedoidsParams::new(5)
            .restarts(4)
            .seed(11)
            .init(KMedoidsInit::Random);
        let a = p.fit(&d).unwrap();
        assert_eq!(a, p.fit(&d).unwrap());
        // Restarts never do worse than run 0 alone (same seed for run 0).
        assert!(a.loss <= p.clone().restarts(1).fit(&d).unwrap().loss);
    }

    #[test]
    fn max_iter_zero_keeps_build() {
        let d = random_points(20, 3);
        let r = KMedoidsParams::new(3).max_iter(0).fit(&d).unwrap();
        assert_eq!(r.iterations, 0);
        let mut b = build(&d, 3);
        b.sort_unstable();
        assert_eq!(r.medoids, b);
    }

    #[test]
    fn rejects_k_below_two() {
        assert_eq!(
            KMedoidsParams::new(1).check(),
            Err(ClusterError::KTooSmall { k: 1 })
        );
    }

    #[test]
    fn rejects_k_above_n() {
        let d = Line(vec![0.0, 1.0, 2.0]);
        assert_eq!(
            KMedoidsParams::new(4).fit(&d),
            Err(ClusterError::KOutOfRange { k: 4, n: 3 })
        );
    }

    #[test]
    fn rejects_zero_restarts() {
        assert_eq!(
            KMedoidsParams::new(2).restarts(0).check(),
            Err(ClusterError::ZeroRuns)
        );
    }

    #[test]
    fn rejects_non_finite_distance() {
        let d = Line(vec![0.0, 1.0, f64::INFINITY]);
        let err = KMedoidsParams::new(2).fit(&d).unwrap_err();
        assert!(matches!(
            err,
            ClusterError::NonFiniteDistance { i: 0, j: 2, .. }
        ));
    }
}
