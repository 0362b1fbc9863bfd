//! Swap refinement of a basis on `S(B; T)` (SPEC 8).

use super::greedy::greedy_indices;
use super::objective::Objective;
use super::search::{Selection, ValidSearchParams};
use super::SelectionError;
use crate::backend::Progress;

/// Swap refinement (SPEC 8): from `p.init` (or the greedy basis), apply the single
/// exchange that lowers S the most while it lowers S by more than `swap_tol` relative.
/// `progress(position, k)` after each basis position of each round of exchanges.
pub fn swap(
    obj: &Objective,
    p: &ValidSearchParams,
    progress: Progress<'_>,
) -> Result<Selection, SelectionError> {
    let mut basis = match &p.init {
        Some(b) => b.clone(),
        None => greedy_indices(obj, p, &|_, _| {})?,
    };
    let mut current = obj.score(&basis, &p.targets)?;
    let mut history = vec![current];
    for _ in 0..p.max_swaps {
        // Every (position, candidate) pair: states of B - b, then every candidate added,
        // in (position, candidate) order, the exhaustive argmin over all pairs (without
        // scoring the pairs that cannot win).
        let cands = p.candidates_outside(&basis);
        let rests: Vec<Vec<usize>> = (0..basis.len())
            .map(|pos| {
                let mut rest = basis.clone();
                rest.remove(pos);
                rest
            })
            .collect();
        let groups: Vec<(&[usize], &[usize])> = rests
            .iter()
            .map(|r| (r.as_slice(), cands.as_slice()))
            .collect();
        let r = obj.best_of_groups(&groups, &p.targets, p.tie_tol, None)?;
        for pos in 0..basis.len() {
            progress(pos as u64 + 1, basis.len() as u64);
        }
        let Some((best, best_score)) = r.best else {
            break;
        };
        if best_score >= current - p.swap_tol * current.abs() || current <= 0.0 {
            break;
        }
        basis[best / cands.len()] = cands[best % cands.len()];
        let fresh = obj.score(&basis, &p.targets)?;
        // The incremental score and the fresh one agree to rounding; never record a rise.
        current = fresh.min(current);
        history.push(current);
    }
    Selection::new(obj, "swap", p, basis, history)
}
