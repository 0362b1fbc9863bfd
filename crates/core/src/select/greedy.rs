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
    let (basis, _, history) = greedy_screened(obj, p, progress)?;
    Selection::new(obj, "greedy", p, basis, history)
}

/// The greedy basis: at each step the candidate [`Objective::best_of_groups`] chooses, which
/// is exactly `argmin(scores_adding(..))` of the exhaustive sweep
/// ([`greedy_indices_exhaustive`]) without scoring the candidates that cannot win.
pub(crate) fn greedy_indices(
    obj: &Objective,
    p: &ValidSearchParams,
    progress: Progress<'_>,
) -> Result<Vec<usize>, SelectionError> {
    Ok(greedy_screened(obj, p, progress)?.0)
}

/// The basis, the exact scores computed per step and the history of [`greedy_screened`].
type Screened = (Vec<usize>, Vec<usize>, Vec<f64>);

/// [`greedy_indices`], the number of exact scores computed per step and the history
/// `S(B_i; T)`, `i = 1..=k` (as [`Objective::score`] computes it, bit for bit: from the
/// states of each step's basis).
pub(crate) fn greedy_screened(
    obj: &Objective,
    p: &ValidSearchParams,
    progress: Progress<'_>,
) -> Result<Screened, SelectionError> {
    let mut basis: Vec<usize> = Vec::with_capacity(p.k);
    let mut evaluated = Vec::with_capacity(p.k);
    let mut history = Vec::with_capacity(p.k);
    // The signs of the pairs' gradients, carried from step to step.
    let mut signs = None;
    for step in 0..p.k {
        let cands = p.candidates_outside(&basis);
        let mut r = obj.best_of_groups(
            &[(basis.as_slice(), cands.as_slice())],
            &p.targets,
            p.tie_tol,
            signs.take(),
        )?;
        signs = r.signs.take();
        if step > 0 {
            history.push(match r.scores[0] {
                Some(s) => s,
                None => obj.score(&basis, &p.targets)?,
            });
        }
        evaluated.push(r.evaluated);
        let Some((best, _)) = r.best else {
            break;
        };
        basis.push(cands[best]);
        progress(step as u64 + 1, p.k as u64);
    }
    while history.len() < basis.len() {
        history.push(obj.score(&basis[..history.len() + 1], &p.targets)?);
    }
    Ok((basis, evaluated, history))
}

/// The exhaustive greedy of SPEC 8: every candidate scored at every step, then
/// [`argmin`]. The reference of the screened greedy (tests, benches).
pub(crate) fn greedy_indices_exhaustive(
    obj: &Objective,
    p: &ValidSearchParams,
    progress: Progress<'_>,
) -> Result<Vec<usize>, SelectionError> {
    let mut basis: Vec<usize> = Vec::with_capacity(p.k);
    for step in 0..p.k {
        let cands = p.candidates_outside(&basis);
        let scores = obj.scores_adding(&basis, &p.targets, &cands)?;
        let Some(best) = argmin(&scores, p.tie_tol) else {
            break;
        };
        basis.push(cands[best]);
        progress(step as u64 + 1, p.k as u64);
    }
    Ok(basis)
}

/// [`greedy`] with the exhaustive sweep of SPEC 8 ([`greedy_indices_exhaustive`]): the
/// reference that the screened greedy equals (same basis, order and scores).
#[doc(hidden)]
pub fn greedy_exhaustive(
    obj: &Objective,
    p: &ValidSearchParams,
    progress: Progress<'_>,
) -> Result<Selection, SelectionError> {
    let basis = greedy_indices_exhaustive(obj, p, progress)?;
    let mut history = Vec::with_capacity(p.k);
    for i in 1..=basis.len() {
        history.push(obj.score(&basis[..i], &p.targets)?);
    }
    Selection::new(obj, "greedy", p, basis, history)
}

/// The screened greedy with the number of exact scores computed at each step (for the
/// benches: how much the screening saves).
#[doc(hidden)]
pub fn greedy_with_counts(
    obj: &Objective,
    p: &ValidSearchParams,
    progress: Progress<'_>,
) -> Result<(Selection, Vec<usize>), SelectionError> {
    let (basis, evaluated, history) = greedy_screened(obj, p, progress)?;
    Ok((Selection::new(obj, "greedy", p, basis, history)?, evaluated))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::cpu::CpuBackend;
    use crate::select::ObjectiveParams;

    #[test]
    fn best_first_keeps_the_ties_of_the_exhaustive_greedy() {
        use crate::select::SearchParams;
        // Exact copies (other names, same parameters) tie with their originals: the chain
        // must still choose the earliest, as the exhaustive sweep does.
        let src = crate::collection::DEFAULT_COLLECTION_CSV;
        let mut csv = src.trim_end().to_string();
        csv.push('\n');
        for row in src.lines().skip(1).step_by(3) {
            let (name, rest) = row.split_once(',').expect("row");
            csv.push_str(&format!("copy-{name},{rest}\n"));
        }
        let coll = crate::collection::parse_csv(csv.as_bytes(), std::path::Path::new("<test>"))
            .expect("collection");
        let p = ObjectiveParams::default()
            .stride(3)
            .objective(crate::backend::weighted::TargetWeight::L2)
            .check()
            .expect("p");
        let obj = Objective::new(&CpuBackend::new(), &coll, &p, &|_, _| {}).expect("obj");
        for k in [6, 15] {
            let sp = SearchParams::new(k).check(obj.names()).expect("sp");
            let exact = greedy_exhaustive(&obj, &sp, &|_, _| {}).expect("exhaustive");
            let (fast, _) = greedy_with_counts(&obj, &sp, &|_, _| {}).expect("screened");
            assert_eq!(fast, exact, "k {k}");
        }
    }
}
