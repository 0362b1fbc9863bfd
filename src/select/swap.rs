//! Swap refinement of a basis on `S(B; T)` (SPEC 8).

use super::greedy::greedy_indices;
use super::objective::{Chain, Objective};
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
        // offered in (position, candidate) order to one argmin chain (the exhaustive
        // argmin over all pairs, without scoring the pairs that cannot win).
        let mut chain = Chain::new(p.tie_tol);
        let mut per_pos: Vec<Vec<usize>> = Vec::with_capacity(basis.len());
        let mut offset = 0;
        for pos in 0..basis.len() {
            let mut rest = basis.clone();
            rest.remove(pos);
            let cands: Vec<usize> = p
                .candidates
                .iter()
                .copied()
                .filter(|c| !basis.contains(c))
                .collect();
            obj.best_adding(&rest, &p.targets, &cands, &mut chain, offset)?;
            offset += cands.len();
            per_pos.push(cands);
            progress(pos as u64 + 1, basis.len() as u64);
        }
        let Some((best, best_score)) = chain.best() else {
            break;
        };
        if best_score >= current - p.swap_tol * current.abs() || current <= 0.0 {
            break;
        }
        let (mut pos, mut idx) = (0, best);
        while idx >= per_pos[pos].len() {
            idx -= per_pos[pos].len();
            pos += 1;
        }
        basis[pos] = per_pos[pos][idx];
        let fresh = obj.score(&basis, &p.targets)?;
        // The incremental score and the fresh one agree to rounding; never record a rise.
        current = fresh.min(current);
        history.push(current);
    }
    Selection::new(obj, "swap", p, basis, history)
}
