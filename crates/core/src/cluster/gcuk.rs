//! Genetic Clustering for Unknown K (GCUK; Bandyopadhyay & Maulik 2002, "Genetic
//! clustering for automatic evolution of clusters and application to image
//! classification", doi:10.1016/S0031-3203(01)00108-X), as modified by the paper (V-B2):
//! cluster centres are real items (materials), there is no mutation, and each cluster is
//! represented by its medoid.
//!
//! # Individuals and validity
//!
//! An individual (chromosome) has `k_max` *slots*, each empty or holding an item index.
//! Every item joins the filled slot whose item is nearest to it, ties to the lowest slot.
//! A slot is **valid** when it receives at least one member. A slot's own item is at
//! distance 0 from it, so it always joins its own slot, unless an earlier slot holds the
//! same item (or an item at distance 0 from it): then the tie goes to the earlier slot, and
//! the later slot (which ties with the earlier one for every item) stays empty and
//! invalid. An individual is valid when it has at least `k_min` valid slots; its clusters
//! are its valid slots in slot order. Invalid slots are ignored but kept: the chromosome
//! is never rewritten, so a later crossover may make such a slot valid again.
//!
//! # Fitness
//!
//! The medoid of each cluster (see [`medoid_of`](super::validity::medoid_of)) is computed
//! from its members, and the fitness is the medoid Davies-Bouldin index `DB` of the
//! partition (lower is better; see [`validity`](super::validity)). The members are those
//! of the slot assignment above: they are not reassigned to the nearest medoid.
//!
//! # Evolution (SPEC section 6)
//!
//! 1. Initialisation: per individual, `K` uniform in `[k_min, k_max]`, `K` distinct
//!    uniformly drawn items put in `K` distinct uniformly drawn slots. An invalid draw
//!    (possible only with items at distance 0 from each other) is redrawn, up to 1000
//!    times per individual.
//! 2. Per generation, selection: `P` roulette draws with replacement, with probability
//!    proportional to `1 / DB` (individuals with `DB = 0` share all the mass; when every
//!    `DB` is infinite the draw is uniform).
//! 3. Crossover of the selected individuals in pairs `(0, 1), (2, 3), ...` (an odd last
//!    one passes unchanged): with probability `Prob_c`, a cut `c` uniform in
//!    `1..=k_max-1` gives children `a[..c] + b[c..]` and `b[..c] + a[c..]`; an invalid
//!    child is replaced by its first (resp. second) parent.
//! 4. Optional mutation (off by default, not in the paper): each slot, with probability
//!    `mutation_prob`, is redrawn: a filled slot is emptied with probability 1/2 or else
//!    gets a uniform item; an empty slot gets a uniform item. An invalid mutant keeps its
//!    pre-mutation chromosome.
//! 5. The best individual ever seen (lowest `DB`, scanning each population in order) is
//!    returned: an individual replaces the best only when its `DB` is lower by more than
//!    `tolerance x DB` (default [`TIE_TOLERANCE`]), so near-ties go to the first found and
//!    the choice never hinges on the last bits of the distances.
//!
//! All draws come from one [`ChaCha8Rng`] seeded with `seed_from_u64(seed)`.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::validity::{
    assign_unchecked, check_distances, db_unchecked, loss_unchecked, medoid_unchecked,
};
use super::{ClusterError, TIE_TOLERANCE};
use crate::distance::Distances;

/// Draws per individual before initialisation gives up.
const MAX_INIT_DRAWS: usize = 1000;

/// Parameters of [`Gcuk`]; the defaults are the paper's settings (VI-C) with seed 1 (as the
/// command line's `--seed`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GcukParams {
    /// Minimum number of clusters of a valid individual, `>= 2` (default 5).
    pub k_min: usize,
    /// Number of slots = maximum number of clusters, `k_min <= k_max <= n` (default 20).
    pub k_max: usize,
    /// Population size `P`, `>= 2` (default 20).
    pub population: usize,
    /// Number of generations `G_max` (default 10; 0 returns the best initial individual).
    pub generations: usize,
    /// Crossover probability `Prob_c` in `[0, 1]` (default 1.0).
    pub crossover_prob: f64,
    /// Per-slot mutation probability in `[0, 1]` (default 0.0: no mutation, as the paper).
    pub mutation_prob: f64,
    /// Seed of the run (default 1).
    pub seed: u64,
    /// Relative margin of the best-individual comparison, in `[0, 1)` (default
    /// [`TIE_TOLERANCE`]; 0: strict).
    pub tolerance: f64,
}

impl Default for GcukParams {
    fn default() -> Self {
        Self {
            k_min: 5,
            k_max: 20,
            population: 20,
            generations: 10,
            crossover_prob: 1.0,
            mutation_prob: 0.0,
            seed: 1,
            tolerance: TIE_TOLERANCE,
        }
    }
}

impl GcukParams {
    /// Sets the range `[k_min, k_max]` of cluster counts.
    pub fn k_range(mut self, k_min: usize, k_max: usize) -> Self {
        self.k_min = k_min;
        self.k_max = k_max;
        self
    }

    /// Sets the population size.
    pub fn population(mut self, population: usize) -> Self {
        self.population = population;
        self
    }

    /// Sets the number of generations.
    pub fn generations(mut self, generations: usize) -> Self {
        self.generations = generations;
        self
    }

    /// Sets the crossover probability.
    pub fn crossover_prob(mut self, p: f64) -> Self {
        self.crossover_prob = p;
        self
    }

    /// Sets the per-slot mutation probability (0 disables mutation).
    pub fn mutation_prob(mut self, p: f64) -> Self {
        self.mutation_prob = p;
        self
    }

    /// Sets the seed.
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// Sets the relative tie margin of the best-individual comparison (0: strict).
    pub fn tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = tolerance;
        self
    }

    /// Validates the parameters that do not depend on the data; `k_max <= n` is checked by
    /// [`ValidGcukParams::fit`].
    pub fn check(&self) -> Result<ValidGcukParams, ClusterError> {
        if self.k_min < 2 {
            return Err(ClusterError::KMinTooSmall { k_min: self.k_min });
        }
        if self.k_min > self.k_max {
            return Err(ClusterError::EmptyKRange {
                k_min: self.k_min,
                k_max: self.k_max,
            });
        }
        if self.population < 2 {
            return Err(ClusterError::PopulationTooSmall {
                population: self.population,
            });
        }
        for (name, value) in [
            ("the crossover probability", self.crossover_prob),
            ("the mutation probability", self.mutation_prob),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(ClusterError::ProbabilityOutOfRange { name, value });
            }
        }
        if !(0.0..1.0).contains(&self.tolerance) {
            return Err(ClusterError::BadTolerance(self.tolerance));
        }
        Ok(ValidGcukParams(self.clone()))
    }

    /// Shorthand for `self.check()?.fit(d)`.
    pub fn fit<D: Distances + ?Sized>(&self, d: &D) -> Result<Gcuk, ClusterError> {
        self.check()?.fit(d)
    }
}

/// Validated [`GcukParams`].
#[derive(Debug, Clone, PartialEq)]
pub struct ValidGcukParams(GcukParams);

/// Result of GCUK: the best individual ever seen.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Gcuk {
    /// Medoid item of each cluster; clusters are the valid slots in slot order.
    pub medoids: Vec<usize>,
    /// Cluster of each item: an index into `medoids`.
    pub labels: Vec<usize>,
    /// Medoid Davies-Bouldin index of the partition (the fitness).
    pub db_index: f64,
    /// `sum_x D[x][medoids[labels[x]]]`.
    pub loss: f64,
    /// Number of clusters (valid slots).
    pub k: usize,
    /// The best chromosome: `k_max` slots, each empty or an item index.
    pub chromosome: Vec<Option<usize>>,
    /// Number of generations run.
    pub generations_run: usize,
    /// Best-ever `DB` after the initial population (`history[0]`) and after each
    /// generation: `generations_run + 1` non-increasing values.
    pub history: Vec<f64>,
}

/// A valid individual with its decoded partition.
#[derive(Debug, Clone)]
struct Individual {
    slots: Vec<Option<usize>>,
    medoids: Vec<usize>,
    labels: Vec<usize>,
    db: f64,
}

/// Decodes `slots`; `None` when fewer than `k_min` slots receive members.
fn evaluate<D: Distances + ?Sized>(
    d: &D,
    slots: &[Option<usize>],
    k_min: usize,
) -> Option<Individual> {
    let filled: Vec<usize> = slots.iter().flatten().copied().collect();
    if filled.len() < k_min {
        return None;
    }
    // Position in `filled` = slot order, so ties go to the lowest slot.
    let by_slot = assign_unchecked(d, &filled);
    let mut members = vec![Vec::new(); filled.len()];
    for (x, &s) in by_slot.iter().enumerate() {
        members[s].push(x);
    }
    let valid: Vec<usize> = (0..filled.len())
        .filter(|&s| !members[s].is_empty())
        .collect();
    if valid.len() < k_min {
        return None;
    }
    let mut labels = vec![0; d.len()];
    let mut medoids = Vec::with_capacity(valid.len());
    for (cluster, &s) in valid.iter().enumerate() {
        members[s].iter().for_each(|&x| labels[x] = cluster);
        medoids.push(medoid_unchecked(d, &members[s]));
    }
    let db = db_unchecked(d, &medoids, &labels);
    Some(Individual {
        slots: slots.to_vec(),
        medoids,
        labels,
        db,
    })
}

/// Index drawn by roulette on `1 / DB` (module docs for the degenerate cases).
fn roulette(rng: &mut ChaCha8Rng, pop: &[Individual]) -> usize {
    let zero: Vec<usize> = (0..pop.len()).filter(|&i| pop[i].db == 0.0).collect();
    if !zero.is_empty() {
        return zero[rng.random_range(0..zero.len())];
    }
    let total: f64 = pop.iter().map(|p| 1.0 / p.db).sum();
    if total <= 0.0 {
        return rng.random_range(0..pop.len());
    }
    let u = rng.random::<f64>() * total;
    let mut acc = 0.0;
    let mut last = 0;
    for (i, p) in pop.iter().enumerate() {
        let w = 1.0 / p.db;
        if w > 0.0 {
            acc += w;
            last = i;
            if u < acc {
                return i;
            }
        }
    }
    last
}

/// Makes `best` the first individual of `pop` with the lowest `DB`, if below `best` by
/// more than `tolerance x DB`.
fn keep_best(pop: &[Individual], best: &mut Individual, tolerance: f64) {
    for ind in pop {
        if super::clearly_lower(ind.db, best.db, tolerance) {
            *best = ind.clone();
        }
    }
}

/// Optional mutation of a chromosome (module docs).
fn mutate(rng: &mut ChaCha8Rng, slots: &mut [Option<usize>], n: usize, p: f64) {
    for slot in slots.iter_mut() {
        if rng.random::<f64>() < p {
            *slot = match slot {
                Some(_) if rng.random::<bool>() => None,
                _ => Some(rng.random_range(0..n)),
            };
        }
    }
}

impl ValidGcukParams {
    /// The validated parameters.
    pub fn params(&self) -> &GcukParams {
        &self.0
    }

    /// Runs GCUK on `d`. Fails when `k_max > n`, a distance is negative or not finite, or
    /// no valid initial individual can be drawn.
    pub fn fit<D: Distances + ?Sized>(&self, d: &D) -> Result<Gcuk, ClusterError> {
        let p = &self.0;
        let n = d.len();
        if p.k_max > n {
            return Err(ClusterError::KMaxTooLarge { k_max: p.k_max, n });
        }
        check_distances(d)?;
        let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
        let mut pop = Vec::with_capacity(p.population);
        for _ in 0..p.population {
            pop.push(self.draw(d, &mut rng)?);
        }
        let mut best = pop[0].clone();
        keep_best(&pop, &mut best, p.tolerance);
        let mut history = vec![best.db];
        for _ in 0..p.generations {
            d.intact().map_err(ClusterError::SourceChanged)?;
            let selected: Vec<Individual> = (0..p.population)
                .map(|_| pop[roulette(&mut rng, &pop)].clone())
                .collect();
            pop.clear();
            for pair in selected.chunks(2) {
                let [a, b] = pair else {
                    pop.push(pair[0].clone());
                    continue;
                };
                if rng.random::<f64>() < p.crossover_prob {
                    let cut = rng.random_range(1..p.k_max);
                    let ab = [&a.slots[..cut], &b.slots[cut..]].concat();
                    let ba = [&b.slots[..cut], &a.slots[cut..]].concat();
                    pop.push(evaluate(d, &ab, p.k_min).unwrap_or_else(|| a.clone()));
                    pop.push(evaluate(d, &ba, p.k_min).unwrap_or_else(|| b.clone()));
                } else {
                    pop.extend([a.clone(), b.clone()]);
                }
            }
            if p.mutation_prob > 0.0 {
                for ind in pop.iter_mut() {
                    let mut slots = ind.slots.clone();
                    mutate(&mut rng, &mut slots, n, p.mutation_prob);
                    if let Some(m) = evaluate(d, &slots, p.k_min) {
                        *ind = m;
                    }
                }
            }
            keep_best(&pop, &mut best, p.tolerance);
            history.push(best.db);
        }
        let loss = loss_unchecked(d, &best.medoids, &best.labels);
        Ok(Gcuk {
            k: best.medoids.len(),
            medoids: best.medoids,
            labels: best.labels,
            db_index: best.db,
            loss,
            chromosome: best.slots,
            generations_run: p.generations,
            history,
        })
    }

    /// Draws one valid initial individual.
    fn draw<D: Distances + ?Sized>(
        &self,
        d: &D,
        rng: &mut ChaCha8Rng,
    ) -> Result<Individual, ClusterError> {
        let p = &self.0;
        for _ in 0..MAX_INIT_DRAWS {
            let k = rng.random_range(p.k_min..=p.k_max);
            let items = rand::seq::index::sample(rng, d.len(), k);
            let places = rand::seq::index::sample(rng, p.k_max, k);
            let mut slots = vec![None; p.k_max];
            for (item, place) in items.iter().zip(places.iter()) {
                slots[place] = Some(item);
            }
            if let Some(ind) = evaluate(d, &slots, p.k_min) {
                return Ok(ind);
            }
        }
        Err(ClusterError::NoValidIndividual {
            attempts: MAX_INIT_DRAWS,
            k_min: p.k_min,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster::tests::Line;

    /// Six tight groups of four items on a line: 0, 10, ..., 50 plus 0.0..0.3.
    fn six_groups() -> Line {
        Line(
            (0..24)
                .map(|i| 10.0 * (i % 6) as f64 + 0.1 * (i / 6) as f64)
                .collect(),
        )
    }

    #[test]
    fn finds_the_true_number_of_clusters() {
        let d = six_groups();
        for seed in 0..5 {
            let r = GcukParams::default()
                .k_range(2, 10)
                .population(40)
                .generations(30)
                .seed(seed);
            let g = r.fit(&d).unwrap();
            assert_eq!(g.k, 6, "seed {seed}: {g:?}");
            // Clusters are the groups: items i and j share a label iff i = j mod 6.
            for i in 0..24 {
                for j in 0..24 {
                    assert_eq!(g.labels[i] == g.labels[j], i % 6 == j % 6);
                }
            }
            // Each group {x, x+.1, x+.2, x+.3} has medoid x+.1 (tie with x+.2, lower index).
            // S = 0.1 everywhere, neighbours at 10: DB = 0.2 / 10.
            assert!((g.db_index - 0.02).abs() < 1e-12);
        }
    }

    #[test]
    fn same_seed_same_result_and_history_is_monotone() {
        let d = Line((0..60).map(|i| ((i * 37) % 101) as f64).collect());
        let p = GcukParams::default().seed(42);
        let a = p.fit(&d).unwrap();
        assert_eq!(a, p.fit(&d).unwrap());
        assert_eq!(a.history.len(), 11);
        assert!(a.history.windows(2).all(|w| w[1] <= w[0]));
        assert_eq!(*a.history.last().unwrap(), a.db_index);
        assert!((5..=20).contains(&a.k));
        let m = p.clone().mutation_prob(0.1);
        assert_eq!(m.fit(&d).unwrap(), m.fit(&d).unwrap());
    }

    #[test]
    fn duplicate_slot_material_is_an_invalid_slot() {
        let d = Line(vec![0.0, 1.0, 10.0, 11.0]);
        let slots = [Some(0), None, Some(0), Some(3)];
        let ind = evaluate(&d, &slots, 2).unwrap();
        assert_eq!(ind.labels, vec![0, 0, 1, 1]);
        assert_eq!(ind.medoids, vec![0, 2]);
        assert!(evaluate(&d, &slots, 3).is_none());
    }

    #[test]
    fn rejects_k_min_below_two() {
        let err = GcukParams::default().k_range(1, 5).check().unwrap_err();
        assert_eq!(err, ClusterError::KMinTooSmall { k_min: 1 });
    }

    #[test]
    fn rejects_empty_k_range() {
        let err = GcukParams::default().k_range(6, 5).check().unwrap_err();
        assert_eq!(err, ClusterError::EmptyKRange { k_min: 6, k_max: 5 });
    }

    #[test]
    fn rejects_small_population() {
        let err = GcukParams::default().population(1).check().unwrap_err();
        assert_eq!(err, ClusterError::PopulationTooSmall { population: 1 });
    }

    #[test]
    fn rejects_bad_probabilities() {
        let err = GcukParams::default()
            .crossover_prob(1.5)
            .check()
            .unwrap_err();
        assert!(matches!(
            err,
            ClusterError::ProbabilityOutOfRange {
                name: "the crossover probability",
                ..
            }
        ));
        let err = GcukParams::default()
            .mutation_prob(f64::NAN)
            .check()
            .unwrap_err();
        assert!(matches!(
            err,
            ClusterError::ProbabilityOutOfRange {
                name: "the mutation probability",
                ..
            }
        ));
    }

    #[test]
    fn rejects_k_max_above_n() {
        let d = Line((0..10).map(f64::from).collect());
        let err = GcukParams::default().fit(&d).unwrap_err();
        assert_eq!(err, ClusterError::KMaxTooLarge { k_max: 20, n: 10 });
    }
}
