//! Searching k-subsets of candidates for the lowest `S(B; T)` (SPEC 8): greedy forward
//! selection, swap refinement and a genetic algorithm.
//!
//! Decisions are made robust to rounding: a later candidate displaces the best one found so
//! far only when its score is lower by more than `tie_tol` relative (default 1e-12), so
//! ties, including rounding-level differences between a measured and an analytic copy of
//! the same materials or between back-ends, go to the material earliest in collection
//! order (greedy), the earliest (position, candidate) pair (swap) or the earliest
//! individual (GA).

use rand::seq::index::sample;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::collections::HashMap;

use super::objective::Objective;
use super::SelectionError;
use crate::backend::Progress;

/// Parameters shared by every search (builder; validate with [`SearchParams::check`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SearchParams {
    /// Basis size, `1 <= k <= |candidates|`. No default.
    pub k: usize,
    /// Materials that may enter the basis (collection indices); `None` (default): all.
    pub candidates: Option<Vec<usize>>,
    /// Materials the basis must represent; `None` (default): all.
    pub targets: Option<Vec<usize>>,
    /// Starting basis of the swap refinement (and one individual of the GA's first
    /// population); `None` (default): swap starts from the greedy basis.
    pub init: Option<Vec<usize>>,
    /// Relative decrease a swap must achieve to be applied (SPEC 8: default 1e-9).
    pub swap_tol: f64,
    /// Relative margin by which a later choice must beat an earlier one (default 1e-12).
    pub tie_tol: f64,
    /// Most swaps applied (default 10,000; each lowers S, so the search ends anyway).
    pub max_swaps: usize,
}

impl SearchParams {
    /// Parameters for a basis of `k` materials, with the defaults.
    pub fn new(k: usize) -> Self {
        Self {
            k,
            candidates: None,
            targets: None,
            init: None,
            swap_tol: 1e-9,
            tie_tol: 1e-12,
            max_swaps: 10_000,
        }
    }
    /// Restricts the candidates.
    pub fn candidates(mut self, c: Vec<usize>) -> Self {
        self.candidates = Some(c);
        self
    }
    /// Restricts the targets.
    pub fn targets(mut self, t: Vec<usize>) -> Self {
        self.targets = Some(t);
        self
    }
    /// Sets the starting basis.
    pub fn init(mut self, b: Vec<usize>) -> Self {
        self.init = Some(b);
        self
    }
    /// Sets the swap threshold.
    pub fn swap_tol(mut self, t: f64) -> Self {
        self.swap_tol = t;
        self
    }

    /// Validates against a collection of `names.len()` materials: indices in range and
    /// listed once, `1 <= k <= |candidates|`, at least one target, a starting basis of `k`
    /// distinct candidates, tolerances in `[0, 1)`.
    pub fn check(&self, names: &[String]) -> Result<ValidSearchParams, SelectionError> {
        let n = names.len();
        let list =
            |what: &'static str, v: &Option<Vec<usize>>| -> Result<Vec<usize>, SelectionError> {
                let v = v.clone().unwrap_or_else(|| (0..n).collect());
                let mut seen = vec![false; n];
                for &i in &v {
                    if i >= n {
                        return Err(SelectionError::IndexOutOfRange { what, index: i, n });
                    }
                    if seen[i] {
                        return Err(SelectionError::Duplicate {
                            what,
                            material: names[i].clone(),
                        });
                    }
                    seen[i] = true;
                }
                let mut v = v;
                v.sort_unstable();
                Ok(v)
            };
        let candidates = list("candidates", &self.candidates)?;
        let targets = list("targets", &self.targets)?;
        if self.k == 0 {
            return Err(SelectionError::InvalidParam {
                name: "k",
                value: "0".into(),
                expected: "at least 1",
            });
        }
        if self.k > candidates.len() {
            return Err(SelectionError::TooFewCandidates {
                k: self.k,
                candidates: candidates.len(),
            });
        }
        if targets.is_empty() {
            return Err(SelectionError::InvalidParam {
                name: "targets",
                value: "none".into(),
                expected: "at least one target material",
            });
        }
        for (name, v) in [("swap_tol", self.swap_tol), ("tie_tol", self.tie_tol)] {
            if !(v.is_finite() && (0.0..1.0).contains(&v)) {
                return Err(SelectionError::InvalidParam {
                    name,
                    value: v.to_string(),
                    expected: "a number in [0, 1)",
                });
            }
        }
        let init = match &self.init {
            None => None,
            Some(b) => {
                if b.len() != self.k {
                    return Err(SelectionError::InvalidParam {
                        name: "init",
                        value: format!("{} materials for k = {}", b.len(), self.k),
                        expected: "the starting basis must hold exactly k materials",
                    });
                }
                let mut seen = vec![false; n];
                for &i in b {
                    if i >= n {
                        return Err(SelectionError::IndexOutOfRange {
                            what: "init",
                            index: i,
                            n,
                        });
                    }
                    if seen[i] {
                        return Err(SelectionError::Duplicate {
                            what: "init",
                            material: names[i].clone(),
                        });
                    }
                    seen[i] = true;
                    if candidates.binary_search(&i).is_err() {
                        return Err(SelectionError::InitNotCandidate(names[i].clone()));
                    }
                }
                Some(b.clone())
            }
        };
        Ok(ValidSearchParams {
            k: self.k,
            candidates,
            targets,
            init,
            swap_tol: self.swap_tol,
            tie_tol: self.tie_tol,
            max_swaps: self.max_swaps,
        })
    }
}

/// Validated [`SearchParams`]: candidates and targets as sorted index lists.
#[derive(Clone, Debug, PartialEq)]
pub struct ValidSearchParams {
    /// Basis size.
    pub k: usize,
    /// Candidates, increasing.
    pub candidates: Vec<usize>,
    /// Targets, increasing.
    pub targets: Vec<usize>,
    /// Starting basis.
    pub init: Option<Vec<usize>>,
    /// Swap threshold.
    pub swap_tol: f64,
    /// Tie margin.
    pub tie_tol: f64,
    /// Swap cap.
    pub max_swaps: usize,
}

/// A basis chosen by fitting error (the `select` JSON of SPEC-cli).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Selection {
    /// `greedy`, `swap` or `ga`.
    pub method: String,
    /// Basis size.
    pub k: usize,
    /// Always `mean-relative-residual` (`S` of SPEC 8).
    pub objective: String,
    /// The basis, by name (greedy: in the order chosen; swap: positions kept through the
    /// exchanges; GA: collection order).
    pub basis: Vec<String>,
    /// `S(basis; targets)`.
    pub score: f64,
    /// Score after each step: greedy, after each addition; swap, the start then after each
    /// exchange; GA, the best ever after each generation (the first: the initial
    /// population).
    pub history: Vec<f64>,
    /// Collection indices of `basis`.
    pub indices: Vec<usize>,
    /// Number of targets the score averages over at most (targets outside the basis).
    pub targets: usize,
    /// Number of candidates.
    pub candidates: usize,
}

impl Selection {
    fn new(
        obj: &Objective,
        method: &str,
        p: &ValidSearchParams,
        basis: Vec<usize>,
        history: Vec<f64>,
    ) -> Self {
        let score = obj.score(&basis, &p.targets);
        Self {
            method: method.into(),
            k: basis.len(),
            objective: "mean-relative-residual".into(),
            basis: basis.iter().map(|&i| obj.names()[i].clone()).collect(),
            score,
            history,
            indices: basis,
            targets: p.targets.len(),
            candidates: p.candidates.len(),
        }
    }
}

/// Index of the lowest score, a later one winning only by more than `tie_tol` relative.
fn argmin(scores: &[f64], tie_tol: f64) -> Option<usize> {
    let mut best: Option<usize> = None;
    for (i, &s) in scores.iter().enumerate() {
        match best {
            None => best = Some(i),
            Some(b) if s < scores[b] - tie_tol * scores[b].abs() - 1e-300 => best = Some(i),
            _ => {}
        }
    }
    best
}

/// Greedy forward selection: `B_{i+1} = B_i + argmin_c S(B_i + c; T)`, ties to the
/// earliest material. `progress(step, k)` after each step.
pub fn greedy(obj: &Objective, p: &ValidSearchParams, progress: Progress<'_>) -> Selection {
    let basis = greedy_indices(obj, p, progress);
    let mut history = Vec::with_capacity(p.k);
    for i in 1..=basis.len() {
        history.push(obj.score(&basis[..i], &p.targets));
    }
    Selection::new(obj, "greedy", p, basis, history)
}

fn greedy_indices(obj: &Objective, p: &ValidSearchParams, progress: Progress<'_>) -> Vec<usize> {
    let mut basis: Vec<usize> = Vec::with_capacity(p.k);
    for step in 0..p.k {
        let cands: Vec<usize> = p
            .candidates
            .iter()
            .copied()
            .filter(|c| !basis.contains(c))
            .collect();
        let scores = obj.scores_adding(&basis, &p.targets, &cands);
        let Some(best) = argmin(&scores, p.tie_tol) else {
            break;
        };
        basis.push(cands[best]);
        progress(step as u64 + 1, p.k as u64);
    }
    basis
}

/// Swap refinement (SPEC 8): from `p.init` (or the greedy basis), apply the single
/// exchange that lowers S the most while it lowers S by more than `swap_tol` relative.
/// `progress(position, k)` after each basis position of each round of exchanges.
pub fn swap(obj: &Objective, p: &ValidSearchParams, progress: Progress<'_>) -> Selection {
    let mut basis = match &p.init {
        Some(b) => b.clone(),
        None => greedy_indices(obj, p, &|_, _| {}),
    };
    let mut current = obj.score(&basis, &p.targets);
    let mut history = vec![current];
    for _ in 0..p.max_swaps {
        // Every (position, candidate) pair: states of B - b, then every candidate added.
        let per_pos: Vec<(Vec<usize>, Vec<f64>)> = (0..basis.len())
            .map(|pos| {
                let mut rest = basis.clone();
                rest.remove(pos);
                let cands: Vec<usize> = p
                    .candidates
                    .iter()
                    .copied()
                    .filter(|c| !basis.contains(c))
                    .collect();
                let scores = obj.scores_adding(&rest, &p.targets, &cands);
                progress(pos as u64 + 1, basis.len() as u64);
                (cands, scores)
            })
            .collect();
        let flat: Vec<f64> = per_pos
            .iter()
            .flat_map(|(_, s)| s.iter().copied())
            .collect();
        let Some(best) = argmin(&flat, p.tie_tol) else {
            break;
        };
        if flat[best] >= current - p.swap_tol * current.abs() || current <= 0.0 {
            break;
        }
        let (mut pos, mut idx) = (0, best);
        while idx >= per_pos[pos].0.len() {
            idx -= per_pos[pos].0.len();
            pos += 1;
        }
        basis[pos] = per_pos[pos].0[idx];
        let fresh = obj.score(&basis, &p.targets);
        // The incremental score and the fresh one agree to rounding; never record a rise.
        current = fresh.min(current);
        history.push(current);
    }
    Selection::new(obj, "swap", p, basis, history)
}

/// The error-driven bases `reproduce` compares: greedy and swap (from the greedy basis) at
/// each k of `ks` (k larger than the collection is skipped), every material a candidate and
/// a target; in the order greedy k1, swap k1, greedy k2, ...
pub fn error_driven_bases(obj: &Objective, ks: &[usize]) -> Result<Vec<Selection>, SelectionError> {
    let mut out = Vec::new();
    for &k in ks.iter().filter(|&&k| k >= 1 && k <= obj.len()) {
        let p = SearchParams::new(k).check(obj.names())?;
        let g = greedy(obj, &p, &|_, _| {});
        let s = swap(
            obj,
            &SearchParams::new(k)
                .init(g.indices.clone())
                .check(obj.names())?,
            &|_, _| {},
        );
        out.push(g);
        out.push(s);
    }
    Ok(out)
}

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
    /// Seed (default 0).
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
            seed: 0,
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
                name: "population",
                value: self.population.to_string(),
                expected: "at least 2",
            });
        }
        if self.tournament == 0 || self.tournament > self.population {
            return Err(SelectionError::InvalidParam {
                name: "tournament",
                value: self.tournament.to_string(),
                expected: "between 1 and the population size",
            });
        }
        for (name, v) in [
            ("crossover_prob", Some(self.crossover_prob)),
            ("mutation_prob", self.mutation_prob),
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
) -> Selection {
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
    let mut scores = evaluate(obj, &p.targets, &pop, &mut cache);
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
        scores = evaluate(obj, &p.targets, &pop, &mut cache);
        if let Some(i) = argmin(&scores, p.tie_tol) {
            if scores[i] < best.1 - p.tie_tol * best.1.abs() - 1e-300 {
                best = (pop[i].clone(), scores[i]);
            }
        }
        history.push(best.1);
        progress(gen as u64 + 1, g.generations as u64);
    }
    let mut sel = Selection::new(obj, "ga", p, best.0, history);
    // The recorded best and the fresh score are the same computation.
    sel.score = best.1;
    sel
}

/// Scores of a population (cached per subset; new subsets in parallel).
fn evaluate(
    obj: &Objective,
    targets: &[usize],
    pop: &[Vec<usize>],
    cache: &mut HashMap<Vec<usize>, f64>,
) -> Vec<f64> {
    let mut todo: Vec<&Vec<usize>> = pop.iter().filter(|i| !cache.contains_key(*i)).collect();
    todo.sort();
    todo.dedup();
    let new: Vec<f64> = todo.par_iter().map(|b| obj.score(b, targets)).collect();
    for (b, s) in todo.into_iter().zip(new) {
        cache.insert(b.clone(), s);
    }
    pop.iter().map(|i| cache[i]).collect()
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn argmin_keeps_the_earlier_on_ties() {
        assert_eq!(argmin(&[1.0, 1.0 - 1e-15, 0.5, 0.5], 1e-12), Some(2));
        assert_eq!(argmin(&[1.0, 1.0 - 1e-9], 1e-12), Some(1));
        assert_eq!(argmin(&[], 1e-12), None);
    }
}
