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
    toward: Option<(&RidgePrior, f64)>,
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
        let pr = toward.map(|(pr, lambda)| Toward {
            mean: &pr.mean[c],
            shape: &pr.shape[c],
            lambda,
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
}

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
            RidgePrior { mean, shape }
        };
        let ridge = prior_of(None);
        let loo = if nt > 1 {
            (0..nt).map(|t| prior_of(Some(t))).collect()
        } else {
            vec![ridge.clone(); nt]
        };
        Ok(Self { ridge, loo, dense })
    }

    /// The ridge strength of [`RIDGE_STRENGTHS`] whose fits of the training materials
    /// from their noise-free values `tv[c][t][s]` at the first `ns` samples (basis values
    /// `vals[c][b][s]`) have the lowest mean score (`rho` under the shared weights on the
    /// whole mask); ties to the weaker ridge.
    #[allow(clippy::needless_range_loop)]
    pub(super) fn choose(
        &self,
        vals: &[Vec<Vec<f64>>; 3],
        tv: &[Vec<Vec<f64>>; 3],
        ns: usize,
        weight: TargetWeight,
        cos: &[f64],
    ) -> Result<f64, AcquireError> {
        let nb = self.dense.m - 1;
        let nt = tv[0].len();
        let scores: Vec<f64> = RIDGE_STRENGTHS
            .par_iter()
            .map(|&l| -> Result<f64, AcquireError> {
                let mut sum = 0.0;
                for t in 0..nt {
                    let y = [0, 1, 2].map(|c| tv[c][t].clone());
                    let x = sample_coefficients(
                        nb,
                        vals,
                        &y,
                        ns,
                        weight,
                        cos,
                        Some((&self.loo[t], l)),
                    )?;
                    sum += self.dense.rho(t, &x);
                }
                Ok(sum / nt.max(1) as f64)
            })
            .collect::<Result<_, _>>()?;
        let mut best = 0;
        for (i, v) in scores.iter().enumerate() {
            if *v < scores[best] {
                best = i;
            }
        }
        Ok(RIDGE_STRENGTHS[best])
    }
}
