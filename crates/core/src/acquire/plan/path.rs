//! One greedy path of a plan ([`plan_path`]: the three criteria over the step's candidate
//! pool) and the rank-one screen of the error criterion ([`Screen`]).

use super::*;

/// One greedy path of [`plan`] (its parameters checked), with the training materials'
/// dense state `dense`.
///
/// Long function: one greedy loop whose three criteria share the step's candidate pool,
/// its values and the sampled state; each criterion's scoring is a closure over them.
#[allow(clippy::needless_range_loop)]
pub(super) fn plan_path(
    coll: &Collection,
    basis: &[usize],
    targets: &[usize],
    cands: &[Candidate],
    p: &PlanParams,
    dense: Option<&Dense>,
    steps: &Steps<'_>,
) -> Result<Plan, AcquireError> {
    let m = basis.len() + 1;
    let weighted = p.fit.objective != crate::backend::weighted::TargetWeight::L2;
    let mut mats = basis.to_vec();
    mats.extend_from_slice(targets);
    let per_step = if p.candidates_per_step == 0 {
        cands.len()
    } else {
        p.candidates_per_step.min(cands.len())
    };
    let mut chosen: Vec<usize> = Vec::with_capacity(p.n);
    let mut st = State::new(m, targets.len());
    let mut history = Vec::with_capacity(p.n);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(p.seed);
    let order: Vec<usize> = if p.criterion == Criterion::Random {
        // A partial Fisher-Yates shuffle: the first n entries depend only on the first n
        // draws, so the n'-plan is the prefix of the n-plan.
        let mut perm: Vec<usize> = (0..cands.len()).collect();
        for i in 0..p.n {
            let j = rand::Rng::random_range(&mut rng, i..cands.len());
            perm.swap(i, j);
        }
        perm.truncate(p.n);
        perm
    } else {
        Vec::new()
    };
    let mut cond_rows: Vec<f64> = Vec::new();
    let mut floors: Option<Vec<f64>> = None;
    for step in 0..p.n {
        steps.at(step);
        // The candidates examined at this step: a seeded subset of the ones not chosen.
        let mut explore: Vec<usize> = Vec::new();
        let pool: Vec<usize> = match p.criterion {
            Criterion::Random => vec![order[step]],
            _ => {
                let mut srng = rand_chacha::ChaCha8Rng::seed_from_u64(
                    p.seed ^ (step as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15),
                );
                let free: Vec<usize> = (0..cands.len()).filter(|i| !chosen.contains(i)).collect();
                let mut pick: Vec<usize> = if per_step >= free.len() {
                    free
                } else {
                    rand::seq::index::sample(&mut srng, free.len(), per_step)
                        .into_iter()
                        .map(|k| free[k])
                        .collect()
                };
                pick.sort_unstable();
                if p.criterion == Criterion::Error && p.shortlist > 0 {
                    explore =
                        rand::seq::index::sample(&mut srng, pick.len(), EXPLORE.min(pick.len()))
                            .into_vec();
                }
                pick
            }
        };
        let sub: Vec<Candidate> = pool.iter().map(|&i| cands[i]).collect();
        // Only the error criterion scores the training values of every candidate; the
        // others need the basis there (and the training values at the chosen one only).
        // Under an objective (SPEC 11) the training values also give the shared weights.
        let scored = if p.criterion == Criterion::Error || (weighted && !targets.is_empty()) {
            &mats[..]
        } else {
            basis
        };
        let vals = values_at_ticking(coll, scored, &sub, &|| steps.at(step))?;
        let sw = if weighted {
            sample_weights(&vals, &sub, p.fit.objective, &|| steps.at(step))
        } else {
            Default::default()
        };
        let scale = |c: usize, k: usize| if weighted { sw[c][k] } else { 1.0 };
        let row = |c: usize, k: usize| -> [f64; 16] {
            let mut r = [0.0; 16];
            let s = scale(c, k);
            r[0] = FRAC_1_PI * s;
            for b in 0..basis.len() {
                r[b + 1] = vals[c][b][k] * s;
            }
            r
        };
        let best_k = match p.criterion {
            Criterion::Random | Criterion::Nielsen => 0,
            Criterion::Condition => {
                let n0 = cond_rows.len() / m;
                let score = |k: usize| -> f64 {
                    let r: Vec<f64> = (0..m)
                        .map(|j| (row(0, k)[j] + row(1, k)[j] + row(2, k)[j]) / 3.0)
                        .collect();
                    if n0 == 0 {
                        -r.iter().map(|v| v * v).sum::<f64>()
                    } else {
                        let mut d = cond_rows.clone();
                        d.extend_from_slice(&r);
                        condition_number(n0 + 1, m, &d)
                    }
                };
                let scores: Vec<f64> = (0..sub.len())
                    .into_par_iter()
                    .map(|k| {
                        steps.at(step);
                        score(k)
                    })
                    .collect();
                argmin(&scores)
            }
            Criterion::Error => {
                let d = dense
                    .as_ref()
                    .expect("targets are given for the error criterion");
                let nt = targets.len();
                let ys = |k: usize| -> Vec<[f64; 3]> {
                    (0..nt)
                        .map(|t| [0, 1, 2].map(|c| vals[c][basis.len() + t][k] * scale(c, k)))
                        .collect()
                };
                let screen = Screen::new(&st, d);
                let floors = floors.get_or_insert_with(|| d.floors(nt));
                let current: Vec<f64> = (0..nt).map(|t| d.rho(t, &st.x[t])).collect();
                let bound = Bound::by_excess(&current, floors);
                let scores: Vec<f64> = (0..sub.len())
                    .into_par_iter()
                    .map(|k| {
                        steps.at(step);
                        screen.score(&[row(0, k), row(1, k), row(2, k)], &ys(k))
                    })
                    .collect();
                let mut ranked: Vec<usize> = (0..sub.len()).collect();
                ranked.sort_by(|&a, &b| scores[a].total_cmp(&scores[b]).then(a.cmp(&b)));
                if p.shortlist > 0 {
                    ranked.truncate(p.shortlist);
                    for &k in &explore {
                        if !ranked.contains(&k) {
                            ranked.push(k);
                        }
                    }
                }
                // Exact means, the screen's best first, then the rest in parallel, each
                // abandoned once it provably exceeds the lowest mean known: its targets
                // fitted so far plus the dense floors of the others
                // ([`State::exact_mean_below`]); the winner and its ties are always
                // computed whole, so the choice is that of every exact mean.
                let exact_of = |k: usize, beat: f64| {
                    let a = [row(0, k), row(1, k), row(2, k)];
                    st.exact_mean_below(d, (&a, &ys(k)), beat, &bound)
                };
                let first = exact_of(ranked[0], f64::INFINITY).expect("no bound to exceed");
                let low = std::sync::atomic::AtomicU64::new(first.to_bits());
                let mut exact: Vec<Option<f64>> = vec![Some(first)];
                exact.extend(
                    ranked[1..]
                        .par_iter()
                        .map(|&k| {
                            steps.at(step);
                            let beat = f64::from_bits(low.load(Ordering::Relaxed));
                            let e = exact_of(k, beat)?;
                            // Non-negative floats order as their bits.
                            low.fetch_min(e.to_bits(), Ordering::Relaxed);
                            Some(e)
                        })
                        .collect::<Vec<_>>(),
                );
                let mut best = 0;
                for i in 1..ranked.len() {
                    let Some(e) = exact[i] else { continue };
                    let b = exact[best].expect("the best is computed");
                    if e < b || (e == b && ranked[i] < ranked[best]) {
                        best = i;
                    }
                }
                ranked[best]
            }
        };
        chosen.push(pool[best_k]);
        let a = [row(0, best_k), row(1, best_k), row(2, best_k)];
        cond_rows.extend((0..m).map(|j| (a[0][j] + a[1][j] + a[2][j]) / 3.0));
        if let Some(d) = &dense {
            let at_chosen;
            let (tv, tk) = if scored.len() == mats.len() {
                (&vals, best_k)
            } else {
                at_chosen = values_at(coll, &mats, &sub[best_k..best_k + 1])?;
                (&at_chosen, 0)
            };
            let yv: Vec<[f64; 3]> = (0..targets.len())
                .map(|t| [0, 1, 2].map(|c| tv[c][basis.len() + t][tk] * scale(c, best_k)))
                .collect();
            st.push(&a, &yv);
            st.x = st.exact(None);
            history.push(mean_rho(d, &st.x));
        }
    }
    steps.at(p.n);
    Ok(Plan {
        basis: basis
            .iter()
            .map(|&b| coll.materials()[b].name.clone())
            .collect(),
        criterion: p.criterion,
        n: p.n,
        candidates_per_step: if p.criterion == Criterion::Random {
            cands.len()
        } else {
            per_step
        },
        candidates: cands.len(),
        samples: chosen
            .iter()
            .map(|&i| PlannedSample::from(&cands[i]))
            .collect(),
        history,
        seed: p.seed,
        restarts: 1,
        objective: p.fit.objective.kind().name().to_string(),
        chosen: chosen.iter().map(|&i| cands[i]).collect(),
    })
}

/// The square roots of SPEC 11's shared weights at each candidate of a step, per channel:
/// the objective's weight at the median over the materials of `vals` (`vals[c][material]
/// [candidate]`: the basis and, when there are any, the training materials) and the
/// candidate's `cos theta_i`. A plan chooses where to measure before the material is
/// known, so it weighs its rows as selection does (SPEC 11), by the weights of the
/// typical material; the fit from the measured samples uses the material's own.
///
/// In parallel over the candidates, calling `tick` for each (the plan's progress, through
/// which a caller stops it).
fn sample_weights(
    vals: &[Vec<Vec<f64>>; 3],
    sub: &[Candidate],
    w: crate::backend::weighted::TargetWeight,
    tick: &(dyn Fn() + Sync),
) -> [Vec<f64>; 3] {
    [0, 1, 2].map(|c| {
        (0..sub.len())
            .into_par_iter()
            .map(|k| {
                tick();
                let col: Vec<f64> = vals[c].iter().map(|v| v[k]).collect();
                w.phi(crate::stats::median(&col), sub[k].wi[2]).sqrt()
            })
            .collect()
    })
}

/// Per target and channel: the passive set of the current sample fit, its solution and
/// the pseudo-inverse of the sampled Gram on it: what the rank-one screen updates.
pub(super) struct Screen<'a> {
    pub(super) d: &'a Dense,
    /// Per channel, the sampled Gram's Lambertian entry and `h_0` of each target (for the
    /// empty passive set).
    pub(super) g00: [f64; 3],
    pub(super) h0: Vec<[f64; 3]>,
    pub(super) fits: Vec<[PassiveFit; 3]>,
}

#[derive(Default)]
pub(super) struct PassiveFit {
    pub(super) cols: Vec<usize>,
    pub(super) z: Vec<f64>,
    /// `p x p` pseudo-inverse of the sampled Gram on `cols`.
    pub(super) inv: Vec<f64>,
}

impl<'a> Screen<'a> {
    pub(super) fn new(st: &State, d: &'a Dense) -> Self {
        let m = st.m;
        let grams: Vec<Vec<f64>> = (0..3)
            .map(|c| {
                let mut g = vec![0.0; m * m];
                for row in st.rows[c].chunks_exact(m) {
                    for i in 0..m {
                        for j in 0..m {
                            g[i * m + j] += row[i] * row[j];
                        }
                    }
                }
                g
            })
            .collect();
        let h0 = (0..st.x.len())
            .map(|t| {
                [0, 1, 2].map(|c| {
                    st.rows[c]
                        .chunks_exact(m)
                        .zip(&st.y[c][t])
                        .map(|(r, y)| r[0] * y)
                        .sum()
                })
            })
            .collect();
        let fits =
            st.x.par_iter()
                .map(|xt| {
                    [0, 1, 2].map(|c| {
                        let cols: Vec<usize> = (0..m).filter(|&j| xt[c][j] > 0.0).collect();
                        let p = cols.len();
                        let sub: Vec<f64> = cols
                            .iter()
                            .flat_map(|&i| cols.iter().map(move |&j| (i, j)))
                            .map(|(i, j)| grams[c][i * m + j])
                            .collect();
                        let (l, v) = sym_eigen(p, &sub);
                        let top = l.first().copied().unwrap_or(0.0);
                        let mut inv = vec![0.0; p * p];
                        for (e, &lam) in l.iter().enumerate() {
                            if lam > 1e-13 * top && lam > 0.0 {
                                for r in 0..p {
                                    for s in 0..p {
                                        inv[r * p + s] += v[r * p + e] * v[s * p + e] / lam;
                                    }
                                }
                            }
                        }
                        PassiveFit {
                            z: cols.iter().map(|&j| xt[c][j]).collect(),
                            cols,
                            inv,
                        }
                    })
                })
                .collect();
        Self {
            d,
            g00: [0, 1, 2].map(|c| grams[c][0]),
            h0,
            fits,
        }
    }

    /// Screened mean training score after adding rows `a` (per channel) with values `y`.
    pub(super) fn score(&self, a: &[[f64; 16]; 3], y: &[[f64; 3]]) -> f64 {
        let m = self.d.m;
        let mut total = 0.0;
        let mut x = [0.0f64; 16];
        for (t, yt) in y.iter().enumerate() {
            let (mut r, mut e) = (0.0, 0.0);
            for c in 0..3 {
                let pf = &self.fits[t][c];
                x[..m].fill(0.0);
                if pf.cols.is_empty() {
                    // Only the Lambertian column, fitted to every sample so far and the new one.
                    let g = self.g00[c] + a[c][0] * a[c][0];
                    x[0] = ((self.h0[t][c] + a[c][0] * yt[c]) / g).max(0.0);
                } else {
                    let p = pf.cols.len();
                    let mut ap = [0.0f64; 16];
                    for (v, &j) in ap.iter_mut().zip(&pf.cols) {
                        *v = a[c][j];
                    }
                    let mut u = [0.0f64; 16];
                    let (mut au, mut az) = (0.0, 0.0);
                    for r_ in 0..p {
                        let ar = ap[r_];
                        az += ar * pf.z[r_];
                        let inv = &pf.inv[r_ * p..(r_ + 1) * p];
                        for s in 0..p {
                            u[r_] += inv[s] * ap[s];
                        }
                        au += ar * u[r_];
                    }
                    let kappa = (yt[c] - az) / (1.0 + au);
                    for r_ in 0..p {
                        x[pf.cols[r_]] = (pf.z[r_] + kappa * u[r_]).max(0.0);
                    }
                }
                r += self.d.r2(c, t, &x[..m]);
                e += self.d.g[c].bb[t];
            }
            total += if e > 0.0 { r / e } else { 0.0 };
        }
        total / y.len().max(1) as f64
    }
}
