//! Searching k-subsets of candidates for the lowest `S(B; T)` (SPEC 8): greedy forward
//! selection, swap refinement and a genetic algorithm.
//!
//! Decisions are made robust to rounding: a later candidate displaces the best one found so
//! far only when its score is lower by more than `tie_tol` relative (default 1e-12), so
//! ties, including rounding-level differences between a measured and an analytic copy of
//! the same materials or between back-ends, go to the material earliest in collection
//! order (greedy), the earliest (position, candidate) pair (swap) or the earliest
//! individual (GA).

pub(crate) use super::objective::argmin;
use super::objective::Objective;
use super::SelectionError;

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
    /// listed once, `1 <= k <= |candidates|`, at least one target, a target that no basis
    /// can absorb (a target outside the candidates, or more targets than `k`), a starting
    /// basis of `k` distinct candidates, tolerances in `[0, 1)`.
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
                name: "-k",
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
                name: "--targets",
                value: "none".into(),
                expected: "at least one target material",
            });
        }
        // A basis of k candidates that holds every target leaves nothing to score: refuse
        // when some basis can (every target a candidate and no more targets than k).
        let all_candidates = targets.iter().all(|t| candidates.binary_search(t).is_ok());
        if all_candidates && targets.len() <= self.k {
            return Err(SelectionError::NoTargetLeft {
                basis: self.k,
                targets: targets.len(),
            });
        }
        for (name, v) in [
            ("swap tolerance", self.swap_tol),
            ("tie tolerance", self.tie_tol),
        ] {
            if !(v.is_finite() && (0.0..1.0).contains(&v)) {
                return Err(SelectionError::InvalidParam {
                    name,
                    value: v.to_string(),
                    expected: "a number in [0, 1)",
                });
            }
        }
        let init = self.checked_init(names, &candidates)?;
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

    /// The starting basis, checked: exactly `k` distinct candidates.
    fn checked_init(
        &self,
        names: &[String],
        candidates: &[usize],
    ) -> Result<Option<Vec<usize>>, SelectionError> {
        let n = names.len();
        Ok(match &self.init {
            None => None,
            Some(b) => {
                if b.len() != self.k {
                    return Err(SelectionError::InvalidParam {
                        name: "--init",
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

impl ValidSearchParams {
    /// The candidates outside `basis`, in increasing order.
    pub fn candidates_outside(&self, basis: &[usize]) -> Vec<usize> {
        self.candidates
            .iter()
            .copied()
            .filter(|c| !basis.contains(c))
            .collect()
    }
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
    pub(crate) fn new(
        obj: &Objective,
        method: &str,
        p: &ValidSearchParams,
        basis: Vec<usize>,
        history: Vec<f64>,
    ) -> Result<Self, SelectionError> {
        let score = obj.score(&basis, &p.targets)?;
        Ok(Self {
            method: method.into(),
            k: basis.len(),
            objective: "mean-relative-residual".into(),
            basis: basis.iter().map(|&i| obj.names()[i].clone()).collect(),
            score,
            history,
            indices: basis,
            targets: p.targets.len(),
            candidates: p.candidates.len(),
        })
    }
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
