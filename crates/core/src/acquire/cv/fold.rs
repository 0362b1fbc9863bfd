//! One fold of the acquisition cross-validation: the state every fold shares
//! ([`Shared`]), the fold's plans and fits from samples, their scores, the `nielsen`
//! baseline, and the noise model and ridge of the fits from samples.

use super::prior::{sample_coefficients, Prior, Strength};
use super::*;

/// One reconstruction of a fold: plan, n and noise indices, the held-out material's index
/// in the fold and its coefficients per channel.
type Rec = (usize, usize, usize, usize, [Vec<f64>; 3]);

/// One fold's basis (names), the samples of the showcase's plan (empty unless it is
/// the first method's first plan, not nielsen), its rows per plan, n and noise, the
/// ridge strength per plan and n and the ridge's prior mean.
pub(super) type FoldRows = (
    Vec<String>,
    Vec<Candidate>,
    Vec<Vec<Vec<Cell>>>,
    Vec<Vec<Option<Strength>>>,
    Option<Prior>,
);

/// What every fold of every method shares: the checked settings, the fold bases, the
/// renders of every material, the candidates and cells of the fit mask.
pub(super) struct Shared<'a> {
    backend: &'a dyn Backend,
    coll: &'a Collection,
    p: &'a AcqCvParams,
    n: usize,
    nmax: usize,
    /// The objective's per-target weight of fits and plans (SPEC 11).
    pub(super) weight: TargetWeight,
    /// Fit parameters of the scores (l2: rho and MAE of SPEC 10).
    fp: FitParams,
    /// Fit parameters of the objective's fits and plans.
    fp_obj: FitParams,
    pub(super) folds: Vec<Vec<usize>>,
    /// `bases[method][0][fold]`.
    pub(super) bases: Vec<Vec<Vec<Vec<usize>>>>,
    grid: GridEval<'a>,
    pub(super) rp: RenderParams,
    pub(super) display: DisplayParams,
    pixels: PixelBrdfs,
    pub(super) originals: Vec<Image>,
    pub(super) names: Vec<String>,
    pub(super) cands: Vec<Candidate>,
    pub(super) cellset: crate::merl::CellSet,
    lights: Vec<LightRenders>,
}

/// Where one fold is: its method and index, basis, held-out and training materials.
struct FoldAt<'b> {
    mi: usize,
    f: usize,
    basis: &'b [usize],
    held: &'b [usize],
    train: &'b [usize],
}

/// The scores of a fold's reconstructions, the dense fits first (index `t` of `held`),
/// then every reconstruction (`held.len() + r` for `recs[r]`).
struct Scored {
    maes: Vec<f64>,
    ies: Vec<f64>,
    looks: Vec<Option<Appearance>>,
    /// rho of each held-out material's dense fit.
    dense_rho: Vec<f64>,
}

/// The settings' lists and counts, before any work: plans, methods and sample counts
/// given, every count at least 1, and noise levels from 0 to 1000.
fn check_counts(p: &AcqCvParams) -> Result<(), AcquireError> {
    let empty = |name: &'static str, expected: &str| AcquireError::InvalidParam {
        name,
        value: "none".into(),
        expected: expected.into(),
    };
    if p.plans.is_empty() {
        return Err(empty("plans", "at least one plan criterion"));
    }
    if p.methods.is_empty() {
        return Err(empty("methods", "at least one selection method"));
    }
    if p.ns.is_empty() {
        return Err(empty("n", "at least one sample count"));
    }
    if p.ns.contains(&0) {
        return Err(AcquireError::InvalidParam {
            name: "n",
            value: format!("{:?}", p.ns),
            expected: "sample counts of at least 1".into(),
        });
    }
    // Audit 3, T3: a level of 1e300 overflowed the fits' sums; the facade's check says
    // the same range in the flag's words.
    if let Some(s) = p.noises.iter().find(|s| !(0.0..=1e3).contains(*s)) {
        return Err(AcquireError::InvalidParam {
            name: "noise",
            value: s.to_string(),
            expected: "relative noise levels from 0 to 1000".into(),
        });
    }
    Ok(())
}

impl<'a> Shared<'a> {
    /// Checks the settings, then chooses every fold's basis and renders, tabulates and
    /// lists what the folds share.
    pub(super) fn new(
        backend: &'a dyn Backend,
        coll: &'a Collection,
        p: &'a AcqCvParams,
        tick: &Ticker<'_>,
    ) -> Result<Self, AcquireError> {
        let n = coll.len();
        let nmax = p.ns.iter().copied().max().unwrap_or(0);
        check_counts(p)?;
        let cvp = CvParams {
            methods: p.methods.clone(),
            ks: vec![p.k],
            folds: p.folds,
            seed: p.seed,
            objective: p.objective.clone(),
            ..CvParams::default()
        };
        let test = super::split::test_split(coll, &p.test)?;
        let vp = match &test {
            Some(t) => cvp.check_split(n, t.len())?,
            None => cvp.check(n)?,
        };
        // The objective's fits and plans; the scores (rho, MAE: SPEC 10) are l2's.
        let fp_obj = p.objective.fit_params();
        let weight = fp_obj.objective;
        let fp = FitParams {
            objective: TargetWeight::L2,
            ..fp_obj.clone()
        };
        let pulse = |_: u64, _: u64| tick.pulse();
        let obj = Objective::new(backend, coll, &p.objective.check()?, &pulse)?;
        let dist = if p.methods.iter().any(|m| m.clustering()) {
            let dp = DistanceParams::default()
                .metric(vp.params().metric)
                .mask(fp.mask)
                .weighting(fp.weighting)
                .stride(fp.stride)
                .check(coll)
                .map_err(crate::select::SelectionError::from)?;
            Some(
                distance_matrix(backend, coll, &dp, &pulse)
                    .map_err(crate::select::SelectionError::from)?,
            )
        } else {
            None
        };
        let folds = match test {
            Some(t) => vec![t],
            None => make_folds(n, p.folds, p.seed),
        };
        let bases = fold_bases(&obj, dist.as_ref(), &folds, &vp, &pulse)?;
        let grid = GridEval::new(coll, &fp);
        let rp = RenderParams::default()
            .with_size(p.render_size)
            .with_light(45.0, 45.0);
        let display = DisplayParams::default();
        let pixels = PixelBrdfs::new(coll, &rp).map_err(|e| AcquireError::Render(e.to_string()))?;
        let originals: Vec<_> = (0..n)
            .map(|t| {
                tick.pulse();
                pixels.render_material(t)
            })
            .collect::<Result<_, _>>()
            .map_err(|e| AcquireError::Render(e.to_string()))?;
        let names = coll.names();
        let all: Vec<usize> = (0..n).collect();
        let cands = cell_candidates(coll, &all, &fp)?;
        let cellset = fit_cells(coll, &all, &fp)?;
        let lights = if p.appearance {
            LightRenders::all_ticking(coll, &|| tick.pulse())
                .map_err(|e| AcquireError::Render(e.to_string()))?
        } else {
            Vec::new()
        };
        Ok(Self {
            backend,
            coll,
            p,
            n,
            nmax,
            weight,
            fp,
            fp_obj,
            folds,
            bases,
            grid,
            rp,
            display,
            pixels,
            originals,
            names,
            cands,
            cellset,
            lights,
        })
    }

    /// `acc[plan][n][noise]`, empty.
    pub(super) fn empty_cells(&self) -> Vec<Vec<Vec<Cell>>> {
        let p = self.p;
        vec![vec![vec![(Vec::new(), Vec::new()); p.noises.len()]; p.ns.len()]; p.plans.len()]
    }

    /// Fold `f` of method `mi` (held-out materials `held`): its basis's names, the
    /// showcase's samples, its rows per plan, n and noise, the ridge strengths per plan
    /// and n, and the ridge's prior mean.
    pub(super) fn fold(
        &self,
        mi: usize,
        f: usize,
        held: &[usize],
        tick: &Ticker<'_>,
    ) -> Result<FoldRows, AcquireError> {
        let (p, coll, n) = (self.p, self.coll, self.n);
        let basis = &self.bases[mi][0][f];
        let named: Vec<String> = basis.iter().map(|&b| self.names[b].clone()).collect();
        let train: Vec<usize> = (0..n)
            .filter(|i| held.binary_search(i).is_err() && !basis.contains(i))
            .collect();
        let dense = Dense::new(self.backend, coll, basis, held, &self.fp, &|_, _| {
            tick.pulse()
        })?;
        let prior = if p.ridge && !train.is_empty() {
            // On the CPU twin, as the limits: the same ridge on every back-end.
            Some(Prior::new(
                &CpuBackend::new(),
                coll,
                basis,
                &train,
                &self.fp_obj,
                &|_, _| tick.pulse(),
            )?)
        } else {
            None
        };
        let dense_x = self.dense_limits(basis, held, &dense, tick)?;
        let at = FoldAt {
            mi,
            f,
            basis,
            held,
            train: &train,
        };
        let mut acc = self.empty_cells();
        let mut ridges: Vec<Vec<Option<Strength>>> = vec![vec![None; p.ns.len()]; p.plans.len()];
        let (recs, show) = self.our_plans(&at, prior.as_ref(), &mut acc, &mut ridges, tick)?;
        let sc = self.score(&at, &dense, &dense_x, &recs, tick)?;
        tick.step();
        let (names, (maes, ies, looks, dense_rho)) =
            (&self.names, (&sc.maes, &sc.ies, &sc.looks, &sc.dense_rho));
        for (r, (pi, ni, si, t, x)) in recs.iter().enumerate() {
            let i = held.len() + r;
            acc[*pi][*ni][*si].0.push(AcqHeldOut {
                material: names[held[*t]].clone(),
                fold: f,
                rho: dense.rho(*t, x),
                dense_rho: dense_rho[*t],
                mae: maes[i],
                image_error: ies[i],
                dense_mae: maes[*t],
                dense_image_error: ies[*t],
                appearance: looks[i].clone(),
                dense_appearance: looks[*t].clone(),
            });
        }
        self.nielsen_plans(&at, &sc, &mut acc, tick)?;
        Ok((named, show, acc, ridges, prior))
    }

    /// The dense fit of each held-out material (the limit). Under an objective the
    /// per-target weighted systems come from the CPU twin: they agree between back-ends
    /// only within `WEIGHTED_TOLERANCE`, which an ill-conditioned fit amplifies, and the
    /// limit is a small pass beside the plans; so the JSON is the same on every back-end.
    fn dense_limits(
        &self,
        basis: &[usize],
        held: &[usize],
        dense: &Dense,
        tick: &Ticker<'_>,
    ) -> Result<Vec<[Vec<f64>; 3]>, AcquireError> {
        let (coll, mm) = (self.coll, basis.len() + 1);
        Ok(if self.weight != TargetWeight::L2 {
            crate::fit::fit(
                &CpuBackend::new(),
                coll,
                basis,
                held,
                &self.fp_obj,
                &|_, _| tick.pulse(),
            )?
            .into_iter()
            .map(|tf| [0, 1, 2].map(|c| tf.coefficients.iter().map(|a| a[c]).collect()))
            .collect()
        } else {
            (0..held.len())
                .into_par_iter()
                .map(|t| -> Result<[Vec<f64>; 3], AcquireError> {
                    let x = [0, 1, 2].map(|c| {
                        let g = &dense.g[c];
                        GramProblem::new(mm, &g.gram, &g.h[t * mm..(t + 1) * mm], g.bb[t])
                            .and_then(|pr| {
                                lawson_hanson::solve(&pr, &lawson_hanson::LhParams::default())
                            })
                            .map(|s| s.x)
                    });
                    let [a, b, c] = x;
                    Ok([a?, b?, c?])
                })
                .collect::<Result<_, _>>()?
        })
    }

    /// Every reconstruction of the fold by a plan of ours: (plan, n, noise, held-out index,
    /// coefficients per channel), scored together by [`Self::score`] (one pass over the
    /// grid for every MAE, renders from the pixel table); the plans' samples go to `acc`,
    /// the ridge strengths to `ridges`. Also returns the showcase's samples (the first
    /// method's first plan).
    #[allow(clippy::needless_range_loop)]
    fn our_plans(
        &self,
        at: &FoldAt<'_>,
        prior: Option<&Prior>,
        acc: &mut [Vec<Vec<Cell>>],
        ridges: &mut [Vec<Option<Strength>>],
        tick: &Ticker<'_>,
    ) -> Result<(Vec<Rec>, Vec<Candidate>), AcquireError> {
        let (p, coll, backend, nmax, weight) =
            (self.p, self.coll, self.backend, self.nmax, self.weight);
        let (mi, f, basis, held, train) = (at.mi, at.f, at.basis, at.held, at.train);
        let (cands, fp_obj, mm) = (&self.cands, &self.fp_obj, basis.len() + 1);
        let mut show = Vec::new();
        let mut recs: Vec<Rec> = Vec::new();
        let seed_f = p.seed.wrapping_add(1000 * f as u64);
        for (pi, &crit) in p.plans.iter().enumerate() {
            if crit == Criterion::Nielsen {
                continue;
            }
            let pp = PlanParams {
                n: nmax,
                criterion: crit,
                candidates_per_step: p.candidates_per_step,
                shortlist: p.shortlist,
                seed: seed_f,
                fit: fp_obj.clone(),
                restarts: p.restarts,
            };
            // Condition and random plans need no training materials (but for the
            // shared weights of an objective): without them `plan` skips the
            // training-score history the results never use.
            let train_of = if crit == Criterion::Error
                || (crit == Criterion::Condition && weight != TargetWeight::L2)
            {
                train
            } else {
                &[]
            };
            // The training materials' dense state is the ridge's (CPU twin, the same
            // fit parameters): computed once per fold, not once per plan.
            let chosen = match prior {
                Some(pr) if !train_of.is_empty() => {
                    super::super::plan::check(coll, basis, train_of, cands, &pp)?;
                    plan_given_dense(
                        coll,
                        basis,
                        train_of,
                        cands,
                        &pp,
                        Some(&pr.dense),
                        &|_, _| tick.pulse(),
                    )?
                }
                _ => plan_with_progress(backend, coll, basis, train_of, cands, &pp, &|_, _| {
                    tick.pulse()
                })?,
            }
            .chosen;
            let samples: Vec<PlannedSample> = chosen.iter().map(PlannedSample::from).collect();
            if mi == 0 && pi == 0 {
                show = chosen.clone();
            }
            let mut mats = basis.to_vec();
            mats.extend_from_slice(held);
            let vals = values_at(coll, &mats, &chosen)?;
            let cos: Vec<f64> = chosen.iter().map(|c| c.wi[2]).collect();
            let tv = match prior {
                Some(_) => values_at(coll, train, &chosen)?,
                None => Default::default(),
            };
            let lambdas = self.ridge_strengths(prior, &tv, &vals, &cos, mm)?;
            if prior.is_some() {
                for (ni, &l) in lambdas.iter().enumerate() {
                    ridges[pi][ni] = Some(l);
                }
            }
            for si in 0..p.noises.len() {
                let sigma = p.noises[si];
                // Noisy measurements of every held-out material at the nmax samples.
                let ys: Vec<[Vec<f64>; 3]> = held
                    .iter()
                    .enumerate()
                    .map(|(t, &ti)| {
                        measure(p.seed, ti, si, sigma, nmax, |c, s| {
                            vals[c][basis.len() + t][s]
                        })
                    })
                    .collect();
                for (ni, &ns) in p.ns.iter().enumerate() {
                    let xs: Vec<[Vec<f64>; 3]> = (0..held.len())
                        .into_par_iter()
                        .map(|t| {
                            tick.pulse();
                            sample_coefficients(
                                basis.len(),
                                &vals,
                                &ys[t],
                                ns,
                                weight,
                                &cos,
                                prior.map(|pr| (&pr.ridge, lambdas[ni])),
                            )
                        })
                        .collect::<Result<_, _>>()?;
                    recs.extend(xs.into_iter().enumerate().map(|(t, x)| (pi, ni, si, t, x)));
                    acc[pi][ni][si].1.push(samples[..ns].to_vec());
                }
            }
            tick.step();
        }
        Ok((recs, show))
    }

    /// The strengths of the fits from samples of each n for one plan's samples `chosen`
    /// (values `vals` of the basis and held-out materials, `cos` their cos theta_i),
    /// chosen on the training materials (values `tv` at the samples, [`Prior::choose`]);
    /// none without a prior,
    /// and no ridge toward the mean where the samples determine the fit (n >= the basis
    /// size + 1).
    fn ridge_strengths(
        &self,
        prior: Option<&Prior>,
        tv: &[Vec<Vec<f64>>; 3],
        vals: &[Vec<Vec<f64>>; 3],
        cos: &[f64],
        mm: usize,
    ) -> Result<Vec<Strength>, AcquireError> {
        let (p, nmax) = (self.p, self.nmax);
        let Some(pr) = prior else {
            return Ok(vec![Strength::default(); p.ns.len()]);
        };
        p.ns.iter()
            .map(|&ns| {
                let ns = ns.min(nmax);
                pr.choose(vals, tv, ns, self.weight, cos, ns < mm)
            })
            .collect()
    }

    /// MAE, image error and appearance of the fold's dense fits (first) and of every
    /// reconstruction in `recs`, and the dense fits' rho.
    fn score(
        &self,
        at: &FoldAt<'_>,
        dense: &Dense,
        dense_x: &[[Vec<f64>; 3]],
        recs: &[Rec],
        tick: &Ticker<'_>,
    ) -> Result<Scored, AcquireError> {
        let (p, basis, held, mm) = (self.p, at.basis, at.held, at.basis.len() + 1);
        let (grid, lights, pixels, display, originals) = (
            &self.grid,
            &self.lights,
            &self.pixels,
            &self.display,
            &self.originals,
        );
        let coefs: Vec<Vec<[f64; 3]>> = dense_x
            .iter()
            .chain(recs.iter().map(|r| &r.4))
            .map(|x| (0..mm).map(|j| [x[0][j], x[1][j], x[2][j]]).collect())
            .collect();
        let target = |i: usize| {
            held[if i < held.len() {
                i
            } else {
                recs[i - held.len()].3
            }]
        };
        let jobs: Vec<MaeJob<'_>> = coefs
            .iter()
            .enumerate()
            .map(|(i, coef)| MaeJob {
                basis,
                target: target(i),
                coef,
            })
            .collect();
        let (maes, logs): (Vec<f64>, Vec<f64>) = if p.appearance {
            grid.sums(&jobs, &|| tick.pulse()).into_iter().unzip()
        } else {
            (grid.maes(&jobs, &|| tick.pulse()), Vec::new())
        };
        let looks: Vec<Option<Appearance>> = if p.appearance {
            // Per held-out material, its dense fit and reconstructions against the
            // references of its renders, prepared once per light.
            let mut of: Vec<Vec<usize>> = vec![Vec::new(); held.len()];
            for i in 0..coefs.len() {
                of[if i < held.len() {
                    i
                } else {
                    recs[i - held.len()].3
                }]
                .push(i);
            }
            let scored = of
                .par_iter()
                .map(|is| {
                    let each = LightRenders::scores_of_each(
                        lights,
                        target(is[0]),
                        is.len(),
                        |l, k| l.pixels().render_combination(basis, &coefs[is[k]]),
                        &|| tick.pulse(),
                    );
                    each.map_err(|e| AcquireError::Render(e.to_string()))
                })
                .collect::<Result<Vec<_>, AcquireError>>()?;
            let mut looks = vec![None; coefs.len()];
            for (is, each) in of.iter().zip(scored) {
                for (&i, mut a) in is.iter().zip(each) {
                    a.log_rmse = logs[i];
                    looks[i] = Some(a);
                }
            }
            looks
        } else {
            vec![None; coefs.len()]
        };
        let ies: Vec<f64> = coefs
            .par_iter()
            .enumerate()
            .map(|(i, coef)| {
                tick.pulse();
                image_error_of(pixels, display, &originals[target(i)], basis, coef)
            })
            .collect::<Result<_, _>>()?;
        let dense_rho: Vec<f64> = (0..held.len()).map(|t| dense.rho(t, &dense_x[t])).collect();
        Ok(Scored {
            maes,
            ies,
            looks,
            dense_rho,
        })
    }

    /// The `nielsen` rows of the fold (SPEC 10's peer baseline): its own model of every
    /// training material of the fold (no basis), plan and reconstruction of each held-out
    /// material, beside the dense fit of our basis.
    fn nielsen_plans(
        &self,
        at: &FoldAt<'_>,
        sc: &Scored,
        acc: &mut [Vec<Vec<Cell>>],
        tick: &Ticker<'_>,
    ) -> Result<(), AcquireError> {
        let (p, coll, n, nmax) = (self.p, self.coll, self.n, self.nmax);
        let (f, held, names, cands, cellset) =
            (at.f, at.held, &self.names, &self.cands, &self.cellset);
        let (pixels, display, lights, originals) =
            (&self.pixels, &self.display, &self.lights, &self.originals);
        let (maes, ies, looks, dense_rho) = (&sc.maes, &sc.ies, &sc.looks, &sc.dense_rho);
        let seed_f = p.seed.wrapping_add(1000 * f as u64);
        for (pi, &crit) in p.plans.iter().enumerate() {
            if crit != Criterion::Nielsen {
                continue;
            }
            // The peer baseline: its own model of every training material of the
            // fold (no basis), plan and reconstruction.
            let train_all: Vec<usize> = (0..n).filter(|i| held.binary_search(i).is_err()).collect();
            let model = NielsenModel::train(coll, &train_all, &cellset.cells, nmax)?;
            let chosen = model.plan(nmax, nielsen_per_step(p.candidates_per_step), seed_f);
            let samples: Vec<PlannedSample> = chosen
                .iter()
                .map(|&j| PlannedSample::from(&cands[j]))
                .collect();
            let cos_i: Vec<f64> = if lights.is_empty() {
                Vec::new()
            } else {
                model
                    .cells
                    .iter()
                    .map(|&c| crate::backend::weighted::cos_theta_i(c as usize))
                    .collect()
            };
            let nf = NielsenFold {
                coll,
                model: &model,
                chosen: &chosen,
                weights: &cellset.weights,
                pixels,
                display,
                lights,
                cos_i: &cos_i,
            };
            let per: Vec<Vec<Vec<Scores>>> = held
                .par_iter()
                .map(|&ti| {
                    tick.pulse();
                    nielsen_rows(&nf, p, ti, &originals[ti])
                })
                .collect::<Result<_, _>>()?;
            for (ni, &ns) in p.ns.iter().enumerate() {
                for si in 0..p.noises.len() {
                    let rows = held.iter().enumerate().map(|(t, &ti)| {
                        let (rho, mae, image_error, appearance) = per[t][ni][si].clone();
                        AcqHeldOut {
                            material: names[ti].clone(),
                            fold: f,
                            rho,
                            dense_rho: dense_rho[t],
                            mae,
                            image_error,
                            dense_mae: maes[t],
                            dense_image_error: ies[t],
                            appearance,
                            dense_appearance: looks[t].clone(),
                        }
                    });
                    acc[pi][ni][si].0.extend(rows);
                    acc[pi][ni][si]
                        .1
                        .push(samples[..ns.min(samples.len())].to_vec());
                }
            }
            tick.step();
        }
        Ok(())
    }
}

/// Noisy measurements `f (1 + sigma N(0, 1))` of held-out material `ti` (collection index)
/// at `nmax` samples, `f(c, s)` its noise-free value: one draw per sample and channel,
/// seeded per material and noise level (the same draws for every plan).
pub(super) fn measure(
    seed: u64,
    ti: usize,
    si: usize,
    sigma: f64,
    nmax: usize,
    f: impl Fn(usize, usize) -> f64,
) -> [Vec<f64>; 3] {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(
        seed ^ ((ti as u64 + 1) << 20) ^ ((si as u64 + 1) << 8),
    );
    let mut y: [Vec<f64>; 3] = Default::default();
    for s in 0..nmax {
        for (c, yc) in y.iter_mut().enumerate() {
            let z = standard_normal(&mut rng);
            yc.push(f(c, s) * (1.0 + sigma * z));
        }
    }
    y
}

/// What the `nielsen` rows of one fold share.
struct NielsenFold<'a> {
    coll: &'a Collection,
    model: &'a NielsenModel,
    chosen: &'a [usize],
    weights: &'a [f64],
    /// The pixel table of the renders of SPEC 7 (`rp`).
    pixels: &'a PixelBrdfs,
    display: &'a DisplayParams,
    lights: &'a [LightRenders],
    /// `cos theta_i` of every model cell (empty without `lights`: no log-RMSE).
    cos_i: &'a [f64],
}

/// Held-out material `ti` reconstructed by the `nielsen` baseline from its first n samples,
/// per n and noise level (`[n][noise]`): rho and MAE on every model cell (the fit mask),
/// image error of the render.
fn nielsen_rows(
    nf: &NielsenFold<'_>,
    p: &AcqCvParams,
    ti: usize,
    original: &Image,
) -> Result<Vec<Vec<Scores>>, AcquireError> {
    let cpu = CpuBackend::new();
    let data = &nf.coll.materials()[ti].data;
    let tv = super::super::nielsen::channel_values(&cpu, data, &nf.model.cells);
    let e: f64 = tv
        .iter()
        .map(|t| {
            t.iter()
                .zip(nf.weights)
                .map(|(v, w)| w * v * v)
                .sum::<f64>()
        })
        .sum();
    // The target's terms of the log-RMSE, once for all its reconstructions.
    let target_logs: Vec<Vec<f64>> = if nf.lights.is_empty() {
        Vec::new()
    } else {
        tv.iter().map(|t| LogSums::logs(t, nf.cos_i)).collect()
    };
    let nmax = nf.chosen.len();
    // Every (n, noise) reconstruction in loop order: its coefficients, rho, MAE, image
    // error and log-RMSE sums.
    let mut recs = Vec::with_capacity(p.noises.len() * p.ns.len());
    for (si, &sigma) in p.noises.iter().enumerate() {
        let y = measure(p.seed, ti, si, sigma, nmax, |c, s| tv[c][nf.chosen[s]]);
        for &ns in &p.ns {
            let ns = ns.min(nmax);
            let coef: [Vec<f64>; 3] =
                [0, 1, 2].map(|c| nf.model.coefficients(&nf.chosen[..ns], &y[c][..ns], ETA));
            let (mut sq, mut ab) = (0.0, 0.0);
            let mut logs = LogSums::default();
            for c in 0..3 {
                let values: Vec<f64> = (0..tv[c].len())
                    .map(|j| nf.model.value(j, &coef[c]))
                    .collect();
                // The reconstruction's terms of the log-RMSE, four cells at a time.
                let fit_logs = target_logs.get(c).map(|_| LogSums::logs(&values, nf.cos_i));
                for (j, ((&t, &w), &v)) in tv[c].iter().zip(nf.weights).zip(&values).enumerate() {
                    let r = v - t;
                    sq += w * r * r;
                    ab += w * r.abs();
                    if let (Some(tl), Some(fl)) = (target_logs.get(c), &fit_logs) {
                        logs.add_logs(fl[j], tl[j], w);
                    }
                }
            }
            // The reconstruction is constant per MERL cell: its renders from the pixel
            // tables' cells (`render_sphere` of `nf.model.brdf(&coef)`, to the bit).
            let img = nf.pixels.render_cells(nf.model.at_cell(&coef));
            let ie = normalized_image_error(original, &img, nf.display)
                .map_err(|e| AcquireError::Render(e.to_string()))?;
            let rho = if e > 0.0 { sq / e } else { 0.0 };
            recs.push((coef, rho, ab / 3.0, ie, logs));
        }
    }
    // Each light's reference prepared once for every reconstruction.
    let looks: Vec<Option<Appearance>> = if nf.lights.is_empty() {
        vec![None; recs.len()]
    } else {
        let each = LightRenders::scores_of_each(
            nf.lights,
            ti,
            recs.len(),
            |l, k| Ok(l.pixels().render_cells(nf.model.at_cell(&recs[k].0))),
            &|| {},
        )
        .map_err(|e| AcquireError::Render(e.to_string()))?;
        each.into_iter()
            .zip(&recs)
            .map(|(mut a, r)| {
                a.log_rmse = r.4.value();
                Some(a)
            })
            .collect()
    };
    let mut out = vec![Vec::with_capacity(p.noises.len()); p.ns.len()];
    for (k, ((_, rho, mae, ie, _), look)) in recs.into_iter().zip(looks).enumerate() {
        out[k % p.ns.len()].push((rho, mae, ie, look));
    }
    Ok(out)
}

/// The image error against `original` of the render of `combination_brdf(coll, basis,
/// coef)` with the parameters `pixels` was made for (from the table: the same bits as
/// `render_sphere` of the combination, without a lookup per pixel).
fn image_error_of(
    pixels: &PixelBrdfs,
    display: &DisplayParams,
    original: &Image,
    basis: &[usize],
    coef: &[[f64; 3]],
) -> Result<f64, AcquireError> {
    let img = pixels
        .render_combination(basis, coef)
        .map_err(|e| AcquireError::Render(e.to_string()))?;
    normalized_image_error(original, &img, display).map_err(|e| AcquireError::Render(e.to_string()))
}

/// A standard normal draw (Box-Muller on two uniform draws in (0, 1]).
fn standard_normal(rng: &mut rand_chacha::ChaCha8Rng) -> f64 {
    let u1 = 1.0 - rand::Rng::random::<f64>(rng);
    let u2 = rand::Rng::random::<f64>(rng);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}
