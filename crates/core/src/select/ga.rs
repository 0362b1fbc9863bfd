//! A genetic algorithm over k-subsets on `S(B; T)` (the paper's future work, VII).

use rand::seq::index::sample;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::collections::HashMap;

use super::objective::Objective;
use super::search::argmin;
use super::search::{Selection, ValidSearchParams};
use super::SelectionError;
use crate::backend::Progress;

/// Parameters of the genetic algorithm over k-subsets (builder; [`GaParams::check`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct GaParams {
    /// Population size, `>= 2` (default 40).
    pub population: usize,
    /// Generations after the initial population (default 60).
    pub generations: usize,
    /// Probability that two parents cross over (default 0.9); otherwise the child copies
    /// the first parent.
    pub crossover_prob: f64,
    /// Per-gene mutation probability; `None` (default): `1 / k`.
    pub mutation_prob: Option<f64>,
    /// Tournament size of parent selection, `>= 1` (default 2).
    pub tournament: usize,
    /// Seed (default 1, as the command line's `--seed`).
    pub seed: u64,
}

impl Default for GaParams {
    fn default() -> Self {
        Self {
            population: 40,
            generations: 60,
            crossover_prob: 0.9,
            mutation_prob: None,
            tournament: 2,
            seed: 1,
        }
    }
}

impl GaParams {
    /// Sets the population size.
    pub fn population(mut self, p: usize) -> Self {
        self.population = p;
        self
    }
    /// Sets the number of generations.
    pub fn generations(mut self, g: usize) -> Self {
        self.generations = g;
        self
    }
    /// Sets the crossover probability.
    pub fn crossover_prob(mut self, p: f64) -> Self {
        self.crossover_prob = p;
        self
    }
    /// Sets the per-gene mutation probability.
    pub fn mutation_prob(mut self, p: f64) -> Self {
        self.mutation_prob = Some(p);
        self
    }
    /// Sets the seed.
    pub fn seed(mut self, s: u64) -> Self {
        self.seed = s;
        self
    }
    /// Validates: population >= 2, tournament in 1..=population, probabilities in [0, 1].
    pub fn check(&self) -> Result<ValidGaParams, SelectionError> {
        if self.population < 2 {
            return Err(SelectionError::InvalidParam {
                name: "--ga-population",
                value: self.population.to_string(),
                expected: "at least 2",
            });
        }
        if self.tournament == 0 || self.tournament > self.population {
            return Err(SelectionError::InvalidParam {
                name: "tournament size",
                value: self.tournament.to_string(),
                expected: "between 1 and the population size",
            });
        }
        for (name, v) in [
            ("--ga-crossover", Some(self.crossover_prob)),
            ("--ga-mutation", self.mutation_prob),
        ] {
            if let Some(v) = v {
                if !(0.0..=1.0).contains(&v) {
                    return Err(SelectionError::InvalidParam {
                        name,
                        value: v.to_string(),
                        expected: "a probability in [0, 1]",
                    });
                }
            }
        }
        Ok(ValidGaParams(self.clone()))
    }
}

/// Validated [`GaParams`].
#[derive(Clone, Debug, PartialEq)]
pub struct ValidGaParams(GaParams);

impl ValidGaParams {
    /// The parameters.
    pub fn params(&self) -> &GaParams {
        &self.0
    }
}

/// Genetic algorithm over k-subsets of the candidates, fitness `S` (lower is better): the
/// paper's proposal (VII) of genetic optimisation for the approximation step.
///
/// * Initial population: `p.init` (when given) then uniformly drawn k-subsets.
/// * Each generation: the best individual ever seen is carried over (elitism); every other
///   child comes from two parents chosen by tournament (lowest score of `tournament`
///   uniform draws, ties to the earlier draw); with `crossover_prob` the child keeps the
///   parents' common materials and fills up with a uniform draw from the others, otherwise
///   it copies the first parent; then each gene is replaced, with `mutation_prob`, by a
///   uniform candidate outside the child.
/// * The best individual ever seen is returned; scores are cached per subset.
///
/// All draws come from one `ChaCha8Rng` seeded with `seed`; fitness evaluations run in
/// parallel but do not touch the generator, so the result depends on the seed alone.
pub fn ga(
    obj: &Objective,
    p: &ValidSearchParams,
    gp: &ValidGaParams,
    progress: Progress<'_>,
) -> Result<Selection, SelectionError> {
    let g = gp.params();
    let k = p.k;
    let nc = p.candidates.len();
    let pm = g.mutation_prob.unwrap_or(1.0 / k as f64);
    let mut rng = ChaCha8Rng::seed_from_u64(g.seed);
    let mut cache: HashMap<Vec<usize>, f64> = HashMap::new();
    let mut pop: Vec<Vec<usize>> = Vec::with_capacity(g.population);
    if let Some(b) = &p.init {
        let mut b = b.clone();
        b.sort_unstable();
        pop.push(b);
    }
    while pop.len() < g.population {
        let mut ind: Vec<usize> = sample(&mut rng, nc, k)
            .into_iter()
            .map(|i| p.candidates[i])
            .collect();
        ind.sort_unstable();
        pop.push(ind);
    }
    let mut scores = evaluate(obj, &p.targets, &pop, &mut cache)?;
    let first = argmin(&scores, p.tie_tol).unwrap_or(0);
    let mut best = (pop[first].clone(), scores[first]);
    let mut history = vec![best.1];
    for gen in 0..g.generations {
        let mut next = vec![best.0.clone()];
        while next.len() < g.population {
            let a = tournament(&mut rng, &scores, g.tournament);
            let b = tournament(&mut rng, &scores, g.tournament);
            let mut child = if rng.random::<f64>() < g.crossover_prob {
                crossover(&mut rng, &pop[a], &pop[b], k)
            } else {
                pop[a].clone()
            };
            for gi in 0..k {
                if rng.random::<f64>() < pm && nc > k {
                    loop {
                        let c = p.candidates[rng.random_range(0..nc)];
                        if !child.contains(&c) {
                            child[gi] = c;
                            break;
                        }
                    }
                }
            }
            child.sort_unstable();
            next.push(child);
        }
        pop = next;
        scores = evaluate(obj, &p.targets, &pop, &mut cache)?;
        if let Some(i) = argmin(&scores, p.tie_tol) {
            if scores[i] < best.1 - p.tie_tol * best.1.abs() - 1e-300 {
                best = (pop[i].clone(), scores[i]);
            }
        }
        history.push(best.1);
        progress(gen as u64 + 1, g.generations as u64);
    }
    let mut sel = Selection::new(obj, "ga", p, best.0, history)?;
    // The recorded best and the fresh score are the same computation.
    sel.score = best.1;
    Ok(sel)
}

/// Scores of a population (cached per subset; new subsets in parallel).
fn evaluate(
    obj: &Objective,
    targets: &[usize],
    pop: &[Vec<usize>],
    cache: &mut HashMap<Vec<usize>, f64>,
) -> Result<Vec<f64>, SelectionError> {
    let mut todo: Vec<&Vec<usize>> = pop.iter().filter(|i| !cache.contains_key(*i)).collect();
    todo.sort();
    todo.dedup();
    let new: Vec<f64> = todo
        .par_iter()
        .map(|b| obj.score(b, targets))
        .collect::<Result<_, _>>()?;
    for (b, s) in todo.into_iter().zip(new) {
        cache.insert(b.clone(), s);
    }
    Ok(pop.iter().map(|i| cache[i]).collect())
}

fn tournament(rng: &mut ChaCha8Rng, scores: &[f64], size: usize) -> usize {
    let mut best = rng.random_range(0..scores.len());
    for _ in 1..size {
        let c = rng.random_range(0..scores.len());
        if scores[c] < scores[best] {
            best = c;
        }
    }
    best
}

fn crossover(rng: &mut ChaCha8Rng, a: &[usize], b: &[usize], k: usize) -> Vec<usize> {
    let mut child: Vec<usize> = a.iter().copied().filter(|x| b.contains(x)).collect();
    let mut rest: Vec<usize> = a
        .iter()
        .chain(b)
        .copied()
        .filter(|x| !child.contains(x))
        .collect();
    rest.sort_unstable();
    rest.dedup();
    let need = k - child.len();
    for i in sample(rng, rest.len(), need) {
        child.push(rest[i]);
    }
    child
}
