//! The showcase of an acquisition cross-validation: renders of one held-out material, its
//! dense fit and its reconstructions from each n of one plan.

use super::fold::measure;
use super::prior::sample_coefficients;
use super::*;

/// What the showcase renders need.
pub(super) struct Showcase<'a> {
    pub(super) backend: &'a dyn Backend,
    pub(super) coll: &'a Collection,
    pub(super) p: &'a AcqCvParams,
    pub(super) folds: &'a [Vec<usize>],
    pub(super) bases: &'a [Vec<usize>],
    pub(super) chosen: &'a [Vec<Candidate>],
    pub(super) prior: &'a [Option<super::prior::Prior>],
    pub(super) cellset: &'a crate::merl::CellSet,
    pub(super) cands: &'a [Candidate],
    pub(super) rp: &'a RenderParams,
    pub(super) display: &'a DisplayParams,
    pub(super) originals: &'a [Image],
}

impl Showcase<'_> {
    /// The showcase of [`AcqShowcase`] (none without results).
    pub(super) fn build(&self, results: &[AcqResult]) -> Result<Option<AcqShowcase>, AcquireError> {
        let (p, coll) = (self.p, self.coll);
        let (Some(&crit), Some(m)) = (p.plans.first(), p.methods.first()) else {
            return Ok(None);
        };
        let si = p.noises.iter().position(|&s| s == 0.0).unwrap_or(0);
        let Some(&sigma) = p.noises.get(si) else {
            return Ok(None);
        };
        let mut ns: Vec<usize> = p.ns.clone();
        ns.sort_unstable();
        ns.dedup();
        let nmax = ns.last().copied().unwrap_or(0);
        let find = |n: usize| {
            results
                .iter()
                .find(|r| r.method == m.name() && r.plan == crit && r.n == n && r.noise == sigma)
        };
        let Some(last) = find(nmax) else {
            return Ok(None);
        };
        let mut order: Vec<&AcqHeldOut> = last.held_out.iter().collect();
        order.sort_by(|a, b| a.rho.total_cmp(&b.rho).then(a.material.cmp(&b.material)));
        let Some(h) = order.get(order.len() / 2) else {
            return Ok(None);
        };
        let names = coll.names();
        let Some(ti) = names.iter().position(|x| *x == h.material) else {
            return Ok(None);
        };
        let f = h.fold;
        let basis = &self.bases[f];
        let render = |b: &(dyn Fn([f64; 3], [f64; 3]) -> [f64; 3] + Sync)| {
            let img = render_sphere(self.rp, b).map_err(|e| AcquireError::Render(e.to_string()))?;
            let ie = normalized_image_error(&self.originals[ti], &img, self.display)
                .map_err(|e| AcquireError::Render(e.to_string()))?;
            Ok::<_, AcquireError>((img, ie))
        };
        // The dense fit of the fold's basis (under the objective; rho is l2's).
        let fp_obj = p.objective.fit_params();
        let weight = fp_obj.objective;
        let fp = FitParams {
            objective: TargetWeight::L2,
            ..fp_obj.clone()
        };
        let dense = Dense::new(self.backend, coll, basis, &[ti], &fp, &|_, _| {})?;
        let mm = basis.len() + 1;
        let x = if weight == TargetWeight::L2 {
            let x = [0, 1, 2].map(|c| {
                let g = &dense.g[c];
                GramProblem::new(mm, &g.gram, &g.h[..mm], g.bb[0])
                    .and_then(|pr| lawson_hanson::solve(&pr, &lawson_hanson::LhParams::default()))
                    .map(|s| s.x)
            });
            let [a, b, c] = x;
            [a?, b?, c?]
        } else {
            // On the CPU twin, as the held-out limits (acquisition_cv).
            let tf = crate::fit::fit(&CpuBackend::new(), coll, basis, &[ti], &fp_obj, &|_, _| {})?;
            [0, 1, 2].map(|c| tf[0].coefficients.iter().map(|a| a[c]).collect())
        };
        let coef: Vec<[f64; 3]> = (0..mm).map(|j| [x[0][j], x[1][j], x[2][j]]).collect();
        let (img, ie) = render(&combination_brdf(coll, basis, &coef))?;
        let mut tiles = vec![("dense fit".to_string(), img, ie, dense.rho(0, &x))];
        let rho_at = |n: usize| {
            find(n)
                .and_then(|r| r.held_out.iter().find(|x| x.material == h.material))
                .map_or(f64::NAN, |x| x.rho)
        };
        if crit == Criterion::Nielsen {
            let held = &self.folds[f];
            let train_all: Vec<usize> = (0..coll.len())
                .filter(|i| held.binary_search(i).is_err())
                .collect();
            let model = NielsenModel::train(coll, &train_all, &self.cellset.cells, nmax)?;
            let seed_f = p.seed.wrapping_add(1000 * f as u64);
            let chosen = model.plan(nmax, nielsen_per_step(p.candidates_per_step), seed_f);
            let at: Vec<Candidate> = chosen.iter().map(|&j| self.cands[j]).collect();
            let vals = values_at(coll, &[ti], &at)?;
            let y = measure(p.seed, ti, si, sigma, chosen.len(), |c, s| vals[c][0][s]);
            for &n in &ns {
                let k = n.min(chosen.len());
                let coef = [0, 1, 2].map(|c| model.coefficients(&chosen[..k], &y[c][..k], ETA));
                let (img, ie) = render(&model.brdf(&coef))?;
                tiles.push((format!("n = {n}"), img, ie, rho_at(n)));
            }
        } else {
            let chosen = &self.chosen[f];
            let mut mats = basis.clone();
            mats.push(ti);
            let vals = values_at(coll, &mats, chosen)?;
            let nb = basis.len();
            let y = measure(p.seed, ti, si, sigma, chosen.len(), |c, s| vals[c][nb][s]);
            let cos: Vec<f64> = chosen.iter().map(|c| c.wi[2]).collect();
            for &n in &ns {
                let st = find(n).map_or(super::prior::Strength::default(), |r| {
                    super::prior::Strength {
                        toward: r.ridge.get(f).copied().unwrap_or(0.0),
                        energy: r.energy_ridge.get(f).copied().unwrap_or(0.0),
                    }
                });
                let k = n.min(chosen.len());
                let toward = self.prior[f].as_ref().map(|pr| (&pr.ridge, st));
                let x = sample_coefficients(nb, &vals, &y, k, weight, &cos, toward)?;
                let coef: Vec<[f64; 3]> = (0..mm).map(|j| [x[0][j], x[1][j], x[2][j]]).collect();
                let (img, ie) = render(&combination_brdf(coll, basis, &coef))?;
                tiles.push((format!("n = {n}"), img, ie, rho_at(n)));
            }
        }
        Ok(Some(AcqShowcase {
            material: h.material.clone(),
            fold: f,
            method: m.name().to_string(),
            plan: crit,
            noise: sigma,
            original: self.originals[ti].clone(),
            tiles,
        }))
    }
}
