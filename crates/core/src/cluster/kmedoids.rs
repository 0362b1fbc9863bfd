//! k-medoids: FasterPAM (the default; Schubert & Rousseeuw 2021, "Fast and eager k-medoids
//! clustering: O(k) runtime improvement of the PAM, CLARA, and CLARANS algorithms",
//! Information Systems 101, doi:10.1016/j.is.2021.101804) and PAM (Partitioning Around
//! Medoids; Kaufman & Rousseeuw 1990, "Finding Groups in Data", ch. 2,
//! doi:10.1002/9780470316801.ch2), with seeded random restarts.
//!
//! Both minimise the loss `sum_x D[x][m_{l(x)}]` over sets of `k` medoids, each item
//! assigned to its nearest medoid (ties to the lowest cluster index), by swapping a medoid
//! with a non-medoid while that lowers the loss:
//!
//! * **FasterPAM** (default), eager: the candidates are visited in an order fixed for the
//!   run (below), cyclically; for each non-medoid `j` one `O(n)` pass gives the loss change of swapping
//!   `j` with *every* medoid (from each item's nearest and second-nearest medoid and each
//!   medoid's removal loss), and the best of them is applied at once when it lowers the
//!   loss. It stops after a full cycle of candidates without a swap, or after `max_iter`
//!   passes over the candidates. An `O(n^2)` pass per sweep instead of PAM's `O(k n^2)`
//!   per swap. This implementation follows the published algorithm (and the `kmedoids`
//!   package's tie rules: the first medoid with the least change), written for this
//!   project.
//! * **Candidate order** ([`KMedoidsOrder`]): [`KMedoidsOrder::Shuffled`] (default) visits
//!   the items in a permutation drawn for each run from the run's seed, as the `kmedoids`
//!   package's `rand_fasterpam` (what its `fasterpam(..., random_state=s)` runs);
//!   [`KMedoidsOrder::Sequential`] visits `0, 1, ..., n - 1` in every run, as the
//!   published pseudo-code and the package's `fasterpam` without a random state. The
//!   eager search takes the first improving swap it meets, so the order decides much of
//!   where it ends: with one order for all runs, runs from different random starts fall
//!   into few optima. Measured against the package's shuffled runs: on 1,000 synthetic
//!   materials (`benches/large.rs`, seed 2016), 30 runs per k = 5..20 ended in 1-7 optima
//!   in item order, 1-12 shuffled, 1-13 in the package, and the best of 30 in item order
//!   was 1.2% above the package's at k = 5 (0.03% at k = 16), shuffled equal at every k;
//!   on 400 uniform points at k = 15, 4 of 1,000 runs in item order reached the best
//!   optimum found, 86 shuffled, 85 in the package. Run `r` therefore draws its own order.
//! * **PAM**: BUILD (deterministic: the first medoid minimises the sum of distances to all
//!   items; each next one maximises the loss decrease `sum_x max(0, d_x - D[x][c])`, ties
//!   to the lowest index) and SWAP with best improvement: every step evaluates all
//!   `k (n - k)` exchanges (`O(k n^2)`) and applies the one with the most negative loss
//!   change; it stops when none lowers the loss (recomputed exactly after each swap, so
//!   float noise cannot make it cycle) or after `max_iter` swaps. The candidate order does
//!   not apply (every exchange is evaluated).
//! * **Ties** (`tolerance`, default [`TIE_TOLERANCE`]): loss changes are compared with a
//!   margin of `tolerance x loss`: a swap is made only when it lowers the loss by more
//!   than that, and two swaps whose changes differ by less count as a tie, broken in
//!   favour of the earlier one (lower medoid position, then lower item). So a decision
//!   never hinges on differences far below the accuracy of the distances (f32 sums on the
//!   back-ends, about 1e-7 relative); `tolerance = 0` gives strict comparisons, the
//!   package's. The margin is not what narrowed the runs: from the same starts and order,
//!   the default margin ended where strict comparisons end in 1,198 of 1,200 runs on the
//!   two matrices above (k = 5..25), and of the other two one ended lower, one higher.
//! * **Restarts**: run `r` in `0..restarts` uses a [`ChaCha8Rng`] seeded with `seed + r`
//!   (`seed_from_u64`, wrapping): it starts from BUILD (run 0 with
//!   [`KMedoidsInit::Build`]) or from `k` distinct medoids drawn uniformly from stream 0
//!   of that generator, and its shuffled candidate order is drawn from stream 1, so
//!   [`ValidKMedoidsParams::fit_from`] with the same seed and the run's initial medoids
//!   repeats the run. The run with the lowest loss is returned; ties (within the
//!   tolerance) go to the earliest run.
//!
//! The result lists the medoids in increasing item order; cluster `i` is `medoids[i]` and
//! `labels[x]` indexes into `medoids` (nearest-medoid assignment, ties to the lowest `i`).

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::validity::{assign_unchecked, check_distances, db_unchecked, loss_unchecked};
use super::{ClusterError, TIE_TOLERANCE};
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

impl std::fmt::Display for KMedoidsInit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Build => "build",
            Self::Random => "random",
        })
    }
}

/// The local search of k-medoids.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum KMedoidsAlgorithm {
    /// FasterPAM (Schubert & Rousseeuw 2021): eager swaps, `O(n^2)` per sweep.
    #[default]
    FasterPam,
    /// PAM SWAP with best improvement, `O(k n^2)` per swap.
    Pam,
}

impl std::str::FromStr for KMedoidsAlgorithm {
    type Err = ClusterError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "fasterpam" => Ok(Self::FasterPam),
            "pam" => Ok(Self::Pam),
            _ => Err(ClusterError::UnknownAlgorithm(s.to_string())),
        }
    }
}

impl std::fmt::Display for KMedoidsAlgorithm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::FasterPam => "fasterpam",
            Self::Pam => "pam",
        })
    }
}

/// The order in which FasterPAM visits the candidates (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum KMedoidsOrder {
    /// A permutation of the items drawn for each run from its seed (stream 1 of the run's
    /// generator): runs from different starts also search in different orders.
    #[default]
    Shuffled,
    /// Items `0, 1, ..., n - 1` in every run (the published pseudo-code; the `kmedoids`
    /// package's `fasterpam` with given medoids and no random state).
    Sequential,
}

impl std::fmt::Display for KMedoidsOrder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Shuffled => "shuffled",
            Self::Sequential => "sequential",
        })
    }
}

/// Parameters of [`KMedoids`] (builder; validate with [`KMedoidsParams::check`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct KMedoidsParams {
    /// Number of clusters, `2 <= k <= n`. No default.
    pub k: usize,
    /// Local search (default [`KMedoidsAlgorithm::FasterPam`]).
    pub algorithm: KMedoidsAlgorithm,
    /// Most passes over the candidates (FasterPAM) or swaps (PAM) per run (default 100;
    /// 0 keeps the initial medoids).
    pub max_iter: usize,
    /// Number of runs, at least 1 (default 1).
    pub restarts: usize,
    /// Seed of the random starts: run `r` uses `seed + r` (default 1, as the command
    /// line's `--seed`).
    pub seed: u64,
    /// Initialisation (default [`KMedoidsInit::Build`]).
    pub init: KMedoidsInit,
    /// FasterPAM's candidate order (default [`KMedoidsOrder::Shuffled`]; PAM ignores it).
    pub order: KMedoidsOrder,
    /// Relative margin of the loss comparisons (module docs; default [`TIE_TOLERANCE`]).
    pub tolerance: f64,
}

impl KMedoidsParams {
    /// Parameters for `k` clusters with the defaults: FasterPAM, 100 iterations, 1 run,
    /// seed 1, BUILD, shuffled candidate order, tolerance [`TIE_TOLERANCE`].
    pub fn new(k: usize) -> Self {
        Self {
            k,
            algorithm: KMedoidsAlgorithm::FasterPam,
            max_iter: 100,
            restarts: 1,
            seed: 1,
            init: KMedoidsInit::Build,
            order: KMedoidsOrder::Shuffled,
            tolerance: TIE_TOLERANCE,
        }
    }

    /// Sets the local search.
    pub fn algorithm(mut self, algorithm: KMedoidsAlgorithm) -> Self {
        self.algorithm = algorithm;
        self
    }

    /// Sets the most passes (FasterPAM) or swaps (PAM) per run.
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

    /// Sets FasterPAM's candidate order.
    pub fn order(mut self, order: KMedoidsOrder) -> Self {
        self.order = order;
        self
    }

    /// Sets the relative tie margin of loss comparisons (0: strict).
    pub fn tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = tolerance;
        self
    }

    /// Validates the parameters that do not depend on the data (`k >= 2`, `restarts >= 1`,
    /// `0 <= tolerance < 1`); `k <= n` is checked by [`ValidKMedoidsParams::fit`].
    pub fn check(&self) -> Result<ValidKMedoidsParams, ClusterError> {
        if self.k < 2 {
            return Err(ClusterError::KTooSmall { k: self.k });
        }
        if self.restarts == 0 {
            return Err(ClusterError::ZeroRuns);
        }
        if !(0.0..1.0).contains(&self.tolerance) {
            return Err(ClusterError::BadTolerance(self.tolerance));
        }
        Ok(ValidKMedoidsParams(self.clone()))
    }

    /// Shorthand for `self.check()?.fit(d)`.
    pub fn fit<D: Distances + ?Sized>(&self, d: &D) -> Result<KMedoids, ClusterError> {
        self.check()?.fit(d)
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

    /// Runs k-medoids on `d`. Fails when `k > n` or a distance is negative or not finite.
    pub fn fit<D: Distances + ?Sized>(&self, d: &D) -> Result<KMedoids, ClusterError> {
        let p = &self.0;
        let n = d.len();
        if p.k > n {
            return Err(ClusterError::KOutOfRange { k: p.k, n });
        }
        check_distances(d)?;
        let mut best: Option<KMedoids> = None;
        for run in 0..p.restarts {
            d.intact().map_err(ClusterError::SourceChanged)?;
            let seed = p.seed.wrapping_add(run as u64);
            let medoids = if run == 0 && p.init == KMedoidsInit::Build {
                build(d, p.k)
            } else {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                rand::seq::index::sample(&mut rng, n, p.k).into_vec()
            };
            let r = self.search(d, medoids, seed)?;
            if best
                .as_ref()
                .is_none_or(|b| super::clearly_lower(r.loss, b.loss, p.tolerance))
            {
                best = Some(r);
            }
        }
        // `restarts >= 1` was checked, so at least one run was made.
        best.ok_or(ClusterError::ZeroRuns)
    }

    /// Runs the local search from the given initial medoids (distinct items, `k` of them),
    /// in the candidate order of the parameters (shuffled: drawn from `seed`, as run 0 of
    /// [`Self::fit`]; the package's `fasterpam(D, medoids)` is [`KMedoidsOrder::Sequential`]
    /// with `tolerance = 0`).
    pub fn fit_from<D: Distances + ?Sized>(
        &self,
        d: &D,
        initial: &[usize],
    ) -> Result<KMedoids, ClusterError> {
        let n = d.len();
        if initial.len() != self.0.k {
            return Err(ClusterError::MedoidCount {
                expected: self.0.k,
                found: initial.len(),
            });
        }
        let mut seen = vec![false; n];
        for &m in initial {
            if m >= n {
                return Err(ClusterError::IndexOutOfRange { index: m, n });
            }
            if std::mem::replace(&mut seen[m], true) {
                return Err(ClusterError::DuplicateMedoid(m));
            }
        }
        check_distances(d)?;
        self.search(d, initial.to_vec(), self.0.seed)
    }

    /// The local search from `medoids` (run seed `seed`) and the result; stops when the
    /// values are no longer intact ([`Distances::intact`]).
    fn search<D: Distances + ?Sized>(
        &self,
        d: &D,
        mut medoids: Vec<usize>,
        seed: u64,
    ) -> Result<KMedoids, ClusterError> {
        let p = &self.0;
        let iterations = match p.algorithm {
            KMedoidsAlgorithm::FasterPam => {
                let order = candidate_order(d.len(), p.order, seed);
                faster_pam(d, &mut medoids, &order, p.max_iter, p.tolerance)
            }
            KMedoidsAlgorithm::Pam => swap(d, &mut medoids, p.max_iter, p.tolerance),
        }
        .map_err(ClusterError::SourceChanged)?;
        medoids.sort_unstable();
        let labels = assign_unchecked(d, &medoids);
        let loss = loss_unchecked(d, &medoids, &labels);
        let db_index = db_unchecked(d, &medoids, &labels);
        Ok(KMedoids {
            medoids,
            labels,
            loss,
            iterations,
            db_index,
        })
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
    /// Number of swaps made by the returned run.
    pub iterations: usize,
    /// Medoid Davies-Bouldin index of the partition.
    pub db_index: f64,
}

/// FasterPAM's candidate order for a run with seed `seed`: `0..n`, or a uniform
/// permutation of it drawn from stream 1 of `ChaCha8Rng::seed_from_u64(seed)` (stream 0
/// draws the random initial medoids).
fn candidate_order(n: usize, order: KMedoidsOrder, seed: u64) -> Vec<usize> {
    let mut items: Vec<usize> = (0..n).collect();
    if order == KMedoidsOrder::Shuffled {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(1);
        items.shuffle(&mut rng);
    }
    items
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

/// Nearest medoid (position in the medoid list, ties to the lowest), its distance and the
/// second-nearest distance of every item.
struct Nearest {
    near: Vec<usize>,
    first: Vec<f64>,
    second: Vec<f64>,
}

impl Nearest {
    fn new<D: Distances + ?Sized>(d: &D, medoids: &[usize]) -> Self {
        let n = d.len();
        let mut s = Self {
            near: vec![0; n],
            first: vec![f64::INFINITY; n],
            second: vec![f64::INFINITY; n],
        };
        for x in 0..n {
            for (i, &m) in medoids.iter().enumerate() {
                let dx = d.dist(x, m);
                if dx < s.first[x] {
                    s.second[x] = s.first[x];
                    s.first[x] = dx;
                    s.near[x] = i;
                } else if dx < s.second[x] {
                    s.second[x] = dx;
                }
            }
        }
        s
    }

    /// `sum_x D[x][nearest medoid]`.
    fn loss(&self) -> f64 {
        self.first.iter().sum()
    }

    /// Loss increase of removing each medoid (its members go to their second-nearest).
    fn removal_loss(&self, k: usize) -> Vec<f64> {
        let mut r = vec![0.0; k];
        for ((&i, &a), &b) in self.near.iter().zip(&self.first).zip(&self.second) {
            r[i] += b - a;
        }
        r
    }
}

/// FasterPAM, visiting the candidates in `order` (a permutation of `0..n`) in every
/// pass; returns the number of swaps made. Asks [`Distances::intact`] after each swap
/// and every [`INTACT_EVERY`] distances read, and stops with its reason.
fn faster_pam<D: Distances + ?Sized>(
    d: &D,
    medoids: &mut [usize],
    order: &[usize],
    max_passes: usize,
    tolerance: f64,
) -> Result<usize, String> {
    let n = d.len();
    let k = medoids.len();
    let mut is_medoid = vec![false; n];
    medoids.iter().for_each(|&m| is_medoid[m] = true);
    let mut nb = Nearest::new(d, medoids);
    let mut loss = nb.loss();
    let mut removal = nb.removal_loss(k);
    let mut change = vec![0.0; k];
    let (mut swaps, mut last_swap) = (0, None);
    let mut read = 0usize;
    'passes: for _ in 0..max_passes {
        let before = swaps;
        for &j in order {
            if last_swap == Some(j) {
                // A full cycle of candidates without a swap: a local optimum.
                break 'passes;
            }
            if is_medoid[j] {
                continue;
            }
            read += n;
            if read >= INTACT_EVERY {
                read = 0;
                d.intact()?;
            }
            // change[i]: loss change of swapping medoid i with j, less `gain` (shared).
            change.copy_from_slice(&removal);
            let mut gain = 0.0;
            for o in 0..n {
                let djo = d.dist(j, o);
                let (a, b) = (nb.first[o], nb.second[o]);
                if djo < a {
                    gain += djo - a;
                    change[nb.near[o]] += a - b;
                } else if djo < b {
                    change[nb.near[o]] += djo - b;
                }
            }
            let margin = tolerance * loss;
            let mut best = 0;
            for i in 1..k {
                if change[i] < change[best] - margin {
                    best = i;
                }
            }
            if change[best] + gain < -margin {
                is_medoid[medoids[best]] = false;
                medoids[best] = j;
                is_medoid[j] = true;
                nb = Nearest::new(d, medoids);
                loss = nb.loss();
                removal = nb.removal_loss(k);
                swaps += 1;
                last_swap = Some(j);
                d.intact()?;
            }
        }
        if swaps == before {
            break;
        }
    }
    Ok(swaps)
}

/// Distances read between two cheap checks that the values are intact (about a
/// millisecond of work; a check is one `fstat`).
const INTACT_EVERY: usize = 1 << 18;

/// PAM's SWAP with best improvement; returns the number of swaps made. Asks
/// [`Distances::intact`] for every candidate medoid slot and after each swap.
fn swap<D: Distances + ?Sized>(
    d: &D,
    medoids: &mut [usize],
    max_iter: usize,
    tolerance: f64,
) -> Result<usize, String> {
    let n = d.len();
    let k = medoids.len();
    let mut loss = loss_unchecked(d, medoids, &assign_unchecked(d, medoids));
    let mut iterations = 0;
    while iterations < max_iter {
        let nb = Nearest::new(d, medoids);
        let mut is_medoid = vec![false; n];
        medoids.iter().for_each(|&m| is_medoid[m] = true);
        let margin = tolerance * loss;
        let mut best: Option<(f64, usize, usize)> = None;
        for i in 0..k {
            d.intact()?;
            for h in (0..n).filter(|&h| !is_medoid[h]) {
                let delta: f64 = (0..n)
                    .map(|x| {
                        let dh = d.dist(x, h);
                        if nb.near[x] == i {
                            dh.min(nb.second[x]) - nb.first[x]
                        } else {
                            (dh - nb.first[x]).min(0.0)
                        }
                    })
                    .sum();
                if delta < best.map_or(0.0, |b| b.0) - margin {
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
        d.intact()?;
    }
    Ok(iterations)
}

#[cfg(test)]
mod tests;
