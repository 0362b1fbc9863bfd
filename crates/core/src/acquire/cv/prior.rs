//! The ridge of the fits from samples below k + 1 samples (SPEC 10, beside it in
//! `docs/acquisition.md`): the prior toward a fold's training materials and the choice of
//! its strength, and the fits from samples themselves.

use super::*;

/// Per-channel sample fit (Lambertian + basis, SPEC 10) of the first `ns` samples:
/// `vals[c][b][s]` the basis values, `y[c]` the measurements, each sample weighted by the
/// objective's weight at its measured value and `cos[s]`, its `cos theta_i` (SPEC 11).
#[allow(clippy::needless_range_loop)]
pub(super) fn sample_coefficients(
    nb: usize,
    vals: &[Vec<Vec<f64>>; 3],
    y: &[Vec<f64>; 3],
    ns: usize,
    weight: TargetWeight,
    cos: &[f64],
    toward: Option<(&RidgePrior, Strength)>,
) -> Result<[Vec<f64>; 3], AcquireError> {
    let mm = nb + 1;
    let mut x: [Vec<f64>; 3] = Default::default();
    for c in 0..3 {
        let mut r = Vec::with_capacity(ns * mm);
        for s in 0..ns {
            r.push(FRAC_1_PI);
            r.extend((0..nb).map(|b| vals[c][b][s]));
        }
        let w: Vec<f64> = (0..ns).map(|s| weight.phi(y[c][s], cos[s])).collect();
        let pr = toward.map(|(pr, st)| Toward {
            mean: &pr.mean[c],
            shape: &pr.shape[c],
            lambda: st.toward,
            energy: Some((&pr.energy[c][..], st.energy)),
        });
        x[c] = solve_rows_toward(mm, &r, &y[c][..ns], &w, pr)?.x;
    }
    Ok(x)
}

/// The prior of the fits from samples, per channel: the mean coefficients of a fold's
/// training materials (their dense fits under the objective's shared weights) and the
/// shape of the penalty in function space ([`function_shape`]).
#[derive(Clone, Debug)]
pub(super) struct RidgePrior {
    /// Mean coefficients (Lambertian first).
    pub(super) mean: [Vec<f64>; 3],
    /// Shape of the penalty (`m x m`, trace `m`).
    pub(super) shape: [Vec<f64>; 3],
    /// Shape of the energy penalty ([`Toward::energy`]: the basis's unweighted Gram
    /// matrix on the whole mask, trace `m`).
    pub(super) energy: [Vec<f64>; 3],
}

/// The two strengths of the fits from samples: the ridge toward the training materials'
/// mean material ([`RIDGE_STRENGTHS`]) and the energy penalty toward black
/// ([`ENERGY_STRENGTHS`]); zero and zero: plain NNLS.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Strength {
    pub(super) toward: f64,
    pub(super) energy: f64,
}

/// Strengths of the energy penalty ([`Toward::energy`]) that `cv --acquisition` chooses
/// among per fold, plan and n (0: none).
pub const ENERGY_STRENGTHS: [f64; 4] = [0.0, 1e-4, 1e-2, 1.0];

/// How the energy of a reconstruction is bounded ([`Prior::fit_bounded`]): the
/// [`BOUND_NEIGHBOURS`] training materials that look most like the measured material at
/// its samples, each scaled to its samples, and [`BOUND_MARGIN`] times the largest of
/// their energies.
pub const BOUND_NEIGHBOURS: usize = 5;
/// See [`BOUND_NEIGHBOURS`] (an energy twice the bound's is `sqrt(2)` times its amplitude).
pub const BOUND_MARGIN: f64 = 2.0;

/// The rho (unweighted, SPEC 10) above which a fit from samples is wild: its error is
/// larger than the material itself (black scores 1).
pub const WILD_RHO: f64 = 1.0;

/// The ridge of the fits from samples (SPEC 10, beside it in `docs/acquisition.md`): the
/// mean over a fold's training materials of their dense fits (under the objective's
/// shared weights), and those materials' dense state to score their fits from samples.
pub(super) struct Prior {
    /// Per channel, the mean coefficients and the penalty's shape.
    pub(super) ridge: RidgePrior,
    /// The same prior without each training material in turn (`loo[t]`), which scores
    /// that material's fits from samples when the strength is chosen: a material's own
    /// coefficients must not shape the prior its fit is judged with.
    loo: Vec<RidgePrior>,
    /// The training materials' full-mask Gram quantities (shared weights).
    pub(super) dense: Dense,
    /// The same without weights (l2, the cell weights of the mask only): the training
    /// materials' rho of SPEC 10, which tells a wild fit.
    dense_l2: Dense,
    /// Each training material's energy on the whole mask (the sum over channels of
    /// `sum_s w_s f^2`, unweighted).
    energies: Vec<f64>,
}

impl Prior {
    pub(super) fn new(
        backend: &dyn Backend,
        coll: &Collection,
        basis: &[usize],
        train: &[usize],
        fp: &FitParams,
        progress: crate::backend::Progress<'_>,
    ) -> Result<Self, AcquireError> {
        let dense = Dense::new(backend, coll, basis, train, fp, progress)?;
        let fp_l2 = FitParams {
            objective: TargetWeight::L2,
            ..fp.clone()
        };
        let dense_l2 = Dense::new(backend, coll, basis, train, &fp_l2, progress)?;
        let m = dense.m;
        let nt = train.len();
        let mut coefs: [Vec<Vec<f64>>; 3] = Default::default();
        for (c, cc) in coefs.iter_mut().enumerate() {
            let g = &dense.g[c];
            let xs = crate::nnls::GramBatch::new(m, &g.gram, &g.h[..nt * m], &g.bb[..nt])
                .and_then(|b| {
                    lawson_hanson::solve_batch(&b, &lawson_hanson::LhParams::default())
                })?;
            *cc = xs.into_iter().map(|s| s.x).collect();
        }
        let prior_of = |skip: Option<usize>| -> RidgePrior {
            let mut mean: [Vec<f64>; 3] = Default::default();
            let mut shape: [Vec<f64>; 3] = Default::default();
            let energy = [0, 1, 2].map(|c| function_shape(m, &dense_l2.g[c].gram));
            for c in 0..3 {
                let rows: Vec<&[f64]> = (0..nt)
                    .filter(|&t| Some(t) != skip)
                    .map(|t| &coefs[c][t][..])
                    .collect();
                let mut mc = vec![0.0; m];
                for x in &rows {
                    for (a, v) in mc.iter_mut().zip(x.iter()) {
                        *a += v / rows.len() as f64;
                    }
                }
                shape[c] = function_shape(m, &dense.g[c].gram);
                mean[c] = mc;
            }
            RidgePrior {
                mean,
                shape,
                energy,
            }
        };
        let ridge = prior_of(None);
        let loo = if nt > 1 {
            (0..nt).map(|t| prior_of(Some(t))).collect()
        } else {
            vec![ridge.clone(); nt]
        };
        let energies = (0..nt)
            .map(|t| (0..3).map(|c| dense_l2.g[c].bb[t]).sum())
            .collect();
        Ok(Self {
            ridge,
            loo,
            dense,
            dense_l2,
            energies,
        })
    }

    /// The strengths ([`Strength`]) of the fits from samples of the first `ns` samples,
    /// chosen on the training materials fitted from their noise-free values `tv[c][t][s]`
    /// (basis values `vals[c][b][s]`), each with the prior without it: first the fewest
    /// wild fits (rho above [`WILD_RHO`]: an error larger than the material), then the
    /// lowest mean score under the objective (`rho_W` under the shared weights on the
    /// whole mask, what the plans lower); ties to the weaker penalties (energy first, then
    /// the ridge toward the mean). The ridge toward the mean is tried only when `toward`
    /// (fewer samples than unknowns), the energy penalty at every n.
    #[allow(clippy::needless_range_loop, clippy::too_many_arguments)]
    pub(super) fn choose(
        &self,
        vals: &[Vec<Vec<f64>>; 3],
        tv: &[Vec<Vec<f64>>; 3],
        ns: usize,
        weight: TargetWeight,
        cos: &[f64],
        toward: bool,
    ) -> Result<Strength, AcquireError> {
        let nb = self.dense.m - 1;
        let nt = tv[0].len();
        let towards: &[f64] = if toward { &RIDGE_STRENGTHS } else { &[0.0] };
        let grid: Vec<Strength> = ENERGY_STRENGTHS
            .iter()
            .flat_map(|&energy| towards.iter().map(move |&t| Strength { toward: t, energy }))
            .collect();
        let scores: Vec<(usize, f64)> = grid
            .par_iter()
            .map(|&st| -> Result<(usize, f64), AcquireError> {
                let (mut sum, mut wild) = (0.0, 0);
                for t in 0..nt {
                    let y = [0, 1, 2].map(|c| tv[c][t].clone());
                    let x = sample_coefficients(
                        nb,
                        vals,
                        &y,
                        ns,
                        weight,
                        cos,
                        Some((&self.loo[t], st)),
                    )?;
                    sum += self.dense.rho(t, &x);
                    if self.dense_l2.rho(t, &x) > WILD_RHO {
                        wild += 1;
                    }
                }
                Ok((wild, sum / nt.max(1) as f64))
            })
            .collect::<Result<_, _>>()?;
        let mut best = 0;
        for (i, v) in scores.iter().enumerate() {
            let b = scores[best];
            if v.0 < b.0 || (v.0 == b.0 && v.1 < b.1) {
                best = i;
            }
        }
        Ok(grid[best])
    }

    /// The largest energy a reconstruction from measurements `y` at the first `ns`
    /// samples may hold ([`BOUND_NEIGHBOURS`]): each training material (values `tv[c][t][s]`
    /// at the samples) scaled to the measurements by weighted least squares under the
    /// objective's weights at the measured values; the [`BOUND_NEIGHBOURS`] of the lowest
    /// relative residual; [`BOUND_MARGIN`] times the largest energy among them, scaled.
    /// Infinite without training materials.
    pub(super) fn energy_bound(
        &self,
        tv: &[Vec<Vec<f64>>; 3],
        y: &[Vec<f64>; 3],
        ns: usize,
        weight: TargetWeight,
        cos: &[f64],
    ) -> f64 {
        let nt = tv[0].len();
        let mut near: Vec<(f64, f64)> = (0..nt)
            .map(|t| {
                let (mut yv, mut vv, mut yy) = (0.0, 0.0, 0.0);
                for c in 0..3 {
                    for s in 0..ns {
                        let w = weight.phi(y[c][s], cos[s]);
                        let v = tv[c][t][s];
                        yv += w * y[c][s] * v;
                        vv += w * v * v;
                        yy += w * y[c][s] * y[c][s];
                    }
                }
                let scale = if vv > 0.0 { (yv / vv).max(0.0) } else { 0.0 };
                let res = (yy - 2.0 * scale * yv + scale * scale * vv).max(0.0)
                    / yy.max(f64::MIN_POSITIVE);
                (res, scale * scale * self.energies[t])
            })
            .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0));
        near.iter()
            .take(BOUND_NEIGHBOURS)
            .map(|x| x.1 * BOUND_MARGIN)
            .fold(f64::NEG_INFINITY, f64::max)
            .max(if nt == 0 { f64::INFINITY } else { 0.0 })
    }

    /// The energy of coefficients `x` on the whole mask (`sum_c x_c^T G_c x_c`, the basis's
    /// unweighted Gram matrix).
    pub(super) fn energy(&self, x: &[Vec<f64>; 3]) -> f64 {
        let m = self.dense_l2.m;
        (0..3)
            .map(|c| {
                let g = &self.dense_l2.g[c].gram;
                (0..m)
                    .map(|i| x[c][i] * (0..m).map(|j| g[i * m + j] * x[c][j]).sum::<f64>())
                    .sum::<f64>()
            })
            .sum()
    }

    /// The fit from the first `ns` measurements `y` with strengths `st`, its energy
    /// penalty raised (each step 10x, from [`ENERGY_STRENGTHS`]' first non-zero value up
    /// to 1e12) while the reconstruction holds more energy than [`Self::energy_bound`]
    /// allows: a wild peak is shrunk toward none. Returns the coefficients and the energy
    /// strength used.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn fit_bounded(
        &self,
        vals: &[Vec<Vec<f64>>; 3],
        tv: &[Vec<Vec<f64>>; 3],
        y: &[Vec<f64>; 3],
        ns: usize,
        weight: TargetWeight,
        cos: &[f64],
        st: Strength,
    ) -> Result<([Vec<f64>; 3], f64), AcquireError> {
        let nb = self.dense.m - 1;
        let fit = |st: Strength| {
            sample_coefficients(nb, vals, y, ns, weight, cos, Some((&self.ridge, st)))
        };
        let mut x = fit(st)?;
        let bound = self.energy_bound(tv, y, ns, weight, cos);
        let mut e = st.energy;
        while self.energy(&x) > bound && e < 1e12 {
            e = if e > 0.0 {
                e * 10.0
            } else {
                ENERGY_STRENGTHS[1]
            };
            x = fit(Strength { energy: e, ..st })?;
        }
        Ok((x, e))
    }
}
