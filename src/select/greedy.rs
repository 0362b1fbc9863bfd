//! Greedy forward selection on `S(B; T)` (SPEC 8).

use super::objective::Objective;
use super::search::argmin;
use super::search::{Selection, ValidSearchParams};
use super::SelectionError;
use crate::backend::Progress;

/// Greedy forward selection: `B_{i+1} = B_i + argmin_c S(B_i + c; T)`, ties to the
/// earliest material. `progress(step, k)` after each step.
pub fn greedy(
    obj: &Objective,
    p: &ValidSearchParams,
    progress: Progress<'_>,
) -> Result<Selection, SelectionError> {
    let basis = greedy_indices(obj, p, progress)?;
    let mut history = Vec::with_capacity(p.k);
    for i in 1..=basis.len() {
        history.push(obj.score(&basis[..i], &p.targets)?);
    }
    Selection::new(obj, "greedy", p, basis, history)
}

pub(crate) fn greedy_indices(
    obj: &Objective,
    p: &ValidSearchParams,
    progress: Progress<'_>,
) -> Result<Vec<usize>, SelectionError> {
    let mut basis: Vec<usize> = Vec::with_capacity(p.k);
    for step in 0..p.k {
        let cands: Vec<usize> = p
            .candidates
            .iter()
            .copied()
            .filter(|c| !basis.contains(c))
            .collect();
        let scores = obj.scores_adding(&basis, &p.targets, &cands)?;
        let Some(best) = argmin(&scores, p.tie_tol) else {
            break;
        };
        basis.push(cands[best]);
        progress(step as u64 + 1, p.k as u64);
    }
    Ok(basis)
}
