//! Exact scores chunk by chunk ([`refine`]) and the best-first search over the candidates'
//! bounds ([`best_first`]).

use super::*;

/// Whether candidate `cand` can replace a best of threshold `thr`: its bound, then,
/// chunk by chunk of live targets (those whose bounds claim the largest decrease first),
/// the bound with that chunk's exact values in place of its bounds, until the bound rules
/// it out (`Ok(None)`) or every chunk is exact: then `Ok(Some(score))`, the exact score
/// summed in the order of [`Objective::scores_adding`] (target by target, channel by
/// channel, from 0), so equal to it bit for bit. From the signs of the candidate's pairs
/// ([`Screen::signs`]), a pair whose gradient is not positive takes `q_t` without its
/// gradient: what [`ChanState::q_adding`] returns for it (the same test on the same
/// numbers).
pub(crate) fn refine(
    sc: &Screen<'_>,
    cand: usize,
    bound: &Bound,
    thr: Option<f64>,
) -> Result<Option<f64>, crate::select::SelectionError> {
    let Screen {
        obj,
        live,
        states,
        cols,
        ref tg,
        words,
        ..
    } = *sc;
    let signs = sc.signs(cand);
    let unchanged = |t: usize, c: usize| -> bool {
        signs.is_some_and(|s| s[c * words + t / 64] >> (t % 64) & 1 == 0)
    };
    let terms = 3 * live.len();
    if bound.count == 0 {
        return Ok((!ruled_out(f64::INFINITY, terms, thr)).then_some(f64::INFINITY));
    }
    if ruled_out(bound.mean(), terms, thr) {
        return Ok(None);
    }
    // Per chunk: where its exact values go (target by target, channel by channel) and the
    // sum of its `q_t`, from which its bound claims the largest decrease: those chunks are
    // made exact first (any order gives a valid bound; the final sum keeps the order).
    let nch = bound.chunks.len();
    let mut at = Vec::with_capacity(nch + 1);
    at.push(0);
    let mut claimed = Vec::with_capacity(nch);
    for (k, part) in bound.chunks.iter().enumerate() {
        let end = ((k + 1) * CHUNK).min(live.len());
        let (mut n, mut base) = (0, 0.0);
        for (i, &t) in (k * CHUNK..end).zip(&live[k * CHUNK..end]) {
            if t == cand {
                continue;
            }
            for d in tg.iter().filter(|d| d.active[i]) {
                n += 1;
                base += d.share[i] * d.q[i];
            }
        }
        at.push(at[k] + n);
        claimed.push(base - part);
    }
    let mut order: Vec<usize> = (0..nch).collect();
    order.sort_by(|&a, &b| claimed[b].total_cmp(&claimed[a]).then(a.cmp(&b)));
    let mut sum: f64 = bound.chunks.iter().sum();
    let mut values = vec![0.0; at[nch]];
    let mut scratch = crate::nnls::incremental::Scratch::default();
    for (done, &k) in order.iter().enumerate() {
        let end = ((k + 1) * CHUNK).min(live.len());
        let mut exact = 0.0;
        let mut slot = at[k];
        for (i, &t) in (k * CHUNK..end).zip(&live[k * CHUNK..end]) {
            if t == cand {
                continue;
            }
            // `share * q` as `Objective::scores_adding` has it (the screen's copies of
            // `obj.share[t][c]` and `q_t`); the state is read only for a positive pair.
            for (c, d) in tg.iter().enumerate().filter(|(_, d)| d.active[i]) {
                let q = if unchanged(t, c) {
                    d.q[i]
                } else {
                    states[i][c]
                        .q_adding(obj.view(c), cols, cand + 1, t + 1, &mut scratch)
                        .map_err(|e| obj.solve_error(t, c, e))?
                };
                let v = d.share[i] * q;
                exact += v;
                values[slot] = v;
                slot += 1;
            }
        }
        sum += exact - bound.chunks[k];
        // The slack also covers the cancellation of `exact - part` (both below the
        // running sum).
        if done + 1 < nch && ruled_out(sum / bound.count as f64, 3 * terms, thr) {
            return Ok(None);
        }
    }
    let mut total = 0.0;
    for v in values {
        total += v;
    }
    Ok(Some(total / bound.count as f64))
}

/// Largest tie tolerance for which `best_first` orders the exact scores by their bounds
/// (its cutoffs assume a small tolerance); above it, candidates go in collection order.
pub(super) const BEST_FIRST_TOL_MAX: f64 = 1e-6;

/// The cutoff of [`best_first`]: candidates scoring at least this cannot change the chain
/// once a candidate scoring `best` is known (`raise` widens it past a band with a score).
pub(super) fn cutoff(best: f64, tol: f64, raise: i32) -> f64 {
    (best * (1.0 + 16.0 * tol) + 1e-290) * (1.0 + 4.0 * tol).powi(raise)
}

/// The lower edge of the band below `c` that must hold no known score: with none there, the
/// first candidate (in collection order) below the band replaces whatever the chain holds
/// (every earlier candidate scores at least `c`), and no candidate at or above `c` can
/// replace it or anything after it, so the chain over the known scores is the chain over
/// all of them.
pub(super) fn band_low(c: f64, tol: f64) -> f64 {
    c * (1.0 - tol) * (1.0 - tol) - 2e-300
}

/// One parallel job's result in [`best_first`]: an exact score (`None`: ruled out) or a
/// task's tight bounds.
pub(super) enum Done {
    Score(Option<f64>),
    Tight(Vec<Bound>),
}

/// A candidate in [`best_first`]'s queue: its bound, then its position (the lower first).
#[derive(Clone, Copy, PartialEq)]
pub(super) struct Queued(f64, usize);

impl Eq for Queued {}

impl Ord for Queued {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        // Reversed: `BinaryHeap` is a max-heap.
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}

impl PartialOrd for Queued {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}

/// The exact [`Chain`] over the concatenated candidates of `groups` (the states of each
/// group's basis in `addings`), as `(flat index, score)`, and how many exact scores were
/// computed.
///
/// Best first: candidates are taken in the order of their lower bounds, first the loose
/// ones of [`Screen::bounds`] for all; a candidate taken with a loose bound gets its tight
/// bound (in batches) and goes back in line; one taken with its tight bound is scored
/// exactly (in small parallel batches), each only until its refined bound reaches the
/// cutoff `c = s* (1 + 16 tol)` of the lowest exact score `s*` so far ([`refine`]). The
/// scan ends at the first bound at or above `c`: every candidate left has a score `>= c`
/// (whichever its bound's level), and when no known score lies in `[c (1 - tol)^2, c)`
/// (else `c` is raised and the scan goes on), the chain over the known scores in
/// collection order chooses exactly what the chain over all the scores would
/// ([`band_low`]).
///
/// With one group, `old` are the signs of the previous step of a greedy run (they serve
/// where this basis extends that one), and the signs of this step come back with the result.
///
/// Long function: one best-first scan whose state (the bounds in order, the known
/// scores, the cut-off `c` and its raise) every step reads and updates; the steps are
/// documented above in order.
pub(crate) fn best_first(
    obj: &Objective,
    addings: &[super::super::Adding],
    groups: &[(&[usize], &[usize])],
    tol: f64,
    old: Option<GradSigns>,
) -> Result<BestFirst, crate::select::SelectionError> {
    let ordered = tol <= BEST_FIRST_TOL_MAX;
    let mut old = if groups.len() == 1 { old } else { None };
    let mut screens: Vec<Option<Screen<'_>>> = addings
        .iter()
        .zip(groups)
        .map(|(a, &(_, cands))| Screen::new(obj, &a.live, &a.states, &a.cols, old.take(), cands))
        .collect();
    // Items: (group, candidate index, bound), the bounds loose (without an order, the
    // bounds only spare candidates no target is left for: any level serves).
    let mut items: Vec<(usize, usize, Option<Bound>)> = Vec::new();
    for (gi, (sc, &(_, cands))) in screens.iter_mut().zip(groups).enumerate() {
        match sc {
            None => items.extend((0..cands.len()).map(|k| (gi, k, None))),
            Some(sc) => items.extend(
                sc.bounds_loose(cands)
                    .into_iter()
                    .enumerate()
                    .map(|(k, b)| (gi, k, Some(b))),
            ),
        }
    }
    let terms: Vec<usize> = addings.iter().map(|a| 3 * a.live.len()).collect();
    // The bound each candidate is ordered by (`-inf`: not screened).
    let order_key = |g: usize, b: &Option<Bound>| match b {
        None => f64::NEG_INFINITY,
        Some(b) => {
            let m = b.mean();
            let slack = (terms[g] as f64 + 16.0) * f64::EPSILON;
            m - slack * m.abs()
        }
    };
    // Whether a candidate's bound is final (tight, or not screened, or no order).
    let mut tight: Vec<bool> = items
        .iter()
        .map(|(_, _, b)| !ordered || b.is_none())
        .collect();
    let mut queue: std::collections::BinaryHeap<Queued> = items
        .iter()
        .enumerate()
        .map(|(i, (g, _, b))| Queued(if ordered { order_key(*g, b) } else { 0.0 }, i))
        .collect();
    // Exact score per item (`None`: not known); items ruled out at cutoff `c` (score >= c).
    // A candidate no target is left for scores `+inf` (no exact work).
    let mut known: Vec<Option<f64>> = items
        .iter()
        .map(|(_, _, b)| match b {
            Some(b) if b.count == 0 => Some(f64::INFINITY),
            _ => None,
        })
        .collect();
    let mut ruled: Vec<(usize, f64)> = Vec::new();
    let mut evaluated = 0;
    let mut s_best = f64::INFINITY;
    let mut raise = 0;
    let batch = (2 * rayon::current_num_threads()).max(4);
    // Candidates made tight at a time: a few tasks per thread.
    let up_batch = 2 * CT * rayon::current_num_threads();
    loop {
        let c = if ordered {
            cutoff(s_best, tol, raise)
        } else {
            f64::INFINITY
        };
        let mut todo: Vec<usize> = Vec::new();
        // Ruled out at a lower cutoff than the present one: scored again.
        ruled.retain(|&(i, at)| {
            if at < c {
                todo.push(i);
                false
            } else {
                true
            }
        });
        let mut up: Vec<usize> = Vec::new();
        while todo.len() < batch && up.len() < up_batch {
            match queue.peek() {
                Some(&Queued(l, i)) if l < c => {
                    queue.pop();
                    if known[i].is_some() {
                        continue;
                    }
                    if tight[i] {
                        todo.push(i);
                    } else {
                        up.push(i);
                    }
                }
                _ => break,
            }
        }
        if todo.is_empty() && up.is_empty() {
            if !ordered || s_best == f64::INFINITY {
                break;
            }
            let low = band_low(c, tol);
            if known.iter().flatten().any(|&s| s >= low && s < c) {
                raise += 1;
                continue;
            }
            break;
        }
        // Tight bounds (per group, in tasks of [`CT`]) and exact scores, in one parallel
        // pass: the scores' durations vary widely, the tasks fill the gaps.
        up.sort_unstable();
        let tasks: Vec<&[usize]> = up
            .chunk_by(|&a, &b| items[a].0 == items[b].0)
            .flat_map(|run| run.chunks(CT))
            .collect();
        let out: Vec<Done> = {
            let tighten = |task: &[usize]| -> Vec<Bound> {
                let g = items[task[0]].0;
                let sc = screens[g].as_ref().expect("a loose bound has its screen");
                let cands: Vec<usize> = task.iter().map(|&i| groups[g].1[items[i].1]).collect();
                sc.bounds_tight(&cands)
            };
            let score = |i: usize| -> Result<Option<f64>, crate::select::SelectionError> {
                let (g, k, b) = &items[i];
                let a = &addings[*g];
                let cand = groups[*g].1[*k];
                match b {
                    None => Ok(Some(obj.exact_scores(a, &[cand])?[0])),
                    Some(b) => refine(
                        screens[*g].as_ref().expect("a bound has its screen"),
                        cand,
                        b,
                        c.is_finite().then_some(c),
                    ),
                }
            };
            (0..todo.len() + tasks.len())
                .into_par_iter()
                .map(|k| match todo.get(k) {
                    Some(&i) => score(i).map(Done::Score),
                    None => Ok(Done::Tight(tighten(tasks[k - todo.len()]))),
                })
                .collect::<Result<_, _>>()?
        };
        let mut out = out.into_iter();
        for (&i, s) in todo.iter().zip(out.by_ref()) {
            match s {
                Done::Score(Some(s)) => {
                    evaluated += 1;
                    known[i] = Some(s);
                    s_best = s_best.min(s);
                }
                Done::Score(None) => ruled.push((i, c)),
                Done::Tight(_) => unreachable!("scores come first"),
            }
        }
        for (task, d) in tasks.iter().zip(out) {
            let Done::Tight(bs) = d else {
                unreachable!("tight bounds come last")
            };
            for (&i, b) in task.iter().zip(bs) {
                let b = Some(b);
                queue.push(Queued(order_key(items[i].0, &b), i));
                items[i].2 = b;
                tight[i] = true;
            }
        }
    }
    let mut chain = Chain::new(tol);
    for (i, s) in known.iter().enumerate() {
        if let Some(s) = *s {
            chain.offer(i, s);
        }
    }
    let signs = match (groups.len(), screens.pop()) {
        (1, Some(Some(sc))) => Some(sc.into_signs()),
        _ => None,
    };
    Ok(BestFirst {
        best: chain.best(),
        evaluated,
        signs,
    })
}

/// The outcome of [`best_first`]: the winner (flat index) and its score, the number of
/// exact scores computed, and (one group) the signs of this step.
pub(crate) struct BestFirst {
    pub best: Option<(usize, f64)>,
    pub evaluated: usize,
    pub signs: Option<GradSigns>,
}
