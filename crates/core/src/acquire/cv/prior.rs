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
    /// matrix on the highlight cells of the mask ([`HIGHLIGHT_DEG`]), trace `m`).
    pub(super) energy: [Vec<f64>; 3],
}

/// The two strengths of the fits from samples: the ridge toward the training materials'
/// mean material ([`RIDGE_STRENGTHS`]) and the penalty on the reconstruction's energy in
/// the highlight ([`ENERGY_STRENGTHS`]); zero and zero: plain NNLS.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Strength {
    pub(super) toward: f64,
    pub(super) energy: f64,
}

/// Strengths of the energy penalty in the highlight (docs/acquisition.md) that
/// `cv --acquisition` chooses among per fold, plan and n (0: none).
pub const ENERGY_STRENGTHS: [f64; 4] = [0.0, 1e-4, 1e-2, 1.0];

/// The highlight of the energy penalty (docs/acquisition.md): the cells whose half vector
/// is within this angle of the normal (`theta_h`, degrees), where every isotropic
/// material's specular peak lies and where a few samples rarely look.
pub const HIGHLIGHT_DEG: f64 = 10.0;

/// The rho (unweighted, SPEC 10) above which a training fit from samples counts as wild
/// when the strengths are chosen (docs/acquisition.md): an error ten times the material's
/// own size (black scores 1), the orders-of-magnitude extrapolations of an unpinned peak.
/// Not 1 or 2: choosing against every fit above 1 shrank the reconstructions' bodies with
/// their peaks and cost the images 5-30%, and 2 cost the Ngan table's log-RMSE 1.6-2.6x
/// (docs/acquisition.md, "Bounded reconstructions").
pub const WILD_RHO: f64 = 10.0;

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
        let highlight = highlight_gram(coll, basis, &fp_l2)?;
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
            let energy = [0, 1, 2].map(|c| function_shape(m, &highlight[c]));
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
        Ok(Self {
            ridge,
            loo,
            dense,
            dense_l2,
        })
    }

    /// The strengths ([`Strength`]) of the fits from samples of the first `ns` samples,
    /// chosen on the training materials fitted from their noise-free values `tv[c][t][s]`
    /// (basis values `vals[c][b][s]`), each with the prior without it: first the fewest
    /// wild fits (rho above [`WILD_RHO`]), then the
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
}

/// The basis columns' unweighted Gram matrix (Lambertian first, `m x m` per channel) over
/// the fit mask's cells in the highlight ([`HIGHLIGHT_DEG`]), with the mask's cell
/// weights; in blocks of cells, so that its memory does not grow with the grid.
fn highlight_gram(
    coll: &Collection,
    basis: &[usize],
    fp: &FitParams,
) -> Result<[Vec<f64>; 3], AcquireError> {
    let cs = fit_cells(coll, basis, fp)?;
    let limit = HIGHLIGHT_DEG.to_radians();
    let cells: Vec<(u32, f64)> = cs
        .cells
        .iter()
        .zip(&cs.weights)
        .filter(|(c, _)| crate::merl::theta_h(crate::merl::unflat(**c as usize).0) < limit)
        .map(|(c, w)| (*c, *w))
        .collect();
    let m = basis.len() + 1;
    let mut g: [Vec<f64>; 3] = [vec![0.0; m * m], vec![0.0; m * m], vec![0.0; m * m]];
    for block in cells.chunks(8192) {
        let cands: Vec<Candidate> = block
            .iter()
            .map(|&(c, _)| {
                let (wi, wo) = crate::merl::cell_directions(c as usize);
                Candidate {
                    wi,
                    wo,
                    cell: Some(c),
                }
            })
            .collect();
        let vals = values_at(coll, basis, &cands)?;
        for (c, gc) in g.iter_mut().enumerate() {
            let mut row = vec![0.0; m];
            for (k, &(_, w)) in block.iter().enumerate() {
                row[0] = FRAC_1_PI;
                for b in 0..basis.len() {
                    row[b + 1] = vals[c][b][k];
                }
                for i in 0..m {
                    let wi = w * row[i];
                    for j in 0..m {
                        gc[i * m + j] += wi * row[j];
                    }
                }
            }
        }
    }
    Ok(g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::acquire::plan::cell_candidates;

    /// The energy penalty on a constructed underdetermined case: two grazing samples for
    /// four unknowns. Its strength lowers the reconstruction's energy in the highlight
    /// (`x^T H x`, the highlight Gram matrix) monotonically, and a zero strength is the
    /// plain NNLS bit for bit.
    #[test]
    fn the_energy_penalty_shrinks_an_unpinned_highlight() {
        let coll = crate::collection::synthetic(10, 7);
        let basis = [0, 1, 2];
        let train: Vec<usize> = (4..10).collect();
        let fp = FitParams {
            stride: 8,
            ..FitParams::default()
        };
        let pr = Prior::new(&CpuBackend::new(), &coll, &basis, &train, &fp, &|_, _| {}).unwrap();
        let h = highlight_gram(
            &coll,
            &basis,
            &FitParams {
                objective: TargetWeight::L2,
                ..fp.clone()
            },
        )
        .unwrap();
        let all: Vec<usize> = (0..coll.len()).collect();
        let cands = cell_candidates(&coll, &all, &fp).unwrap();
        let mut grazing: Vec<Candidate> = cands
            .iter()
            .filter(|c| c.wi[2] < 0.3 && c.wo[2] < 0.3)
            .copied()
            .collect();
        grazing.truncate(2);
        assert_eq!(grazing.len(), 2);
        let mut mats = basis.to_vec();
        mats.push(3);
        let vals = values_at(&coll, &mats, &grazing).unwrap();
        let y = [0, 1, 2].map(|c| vals[c][3].clone());
        let cos: Vec<f64> = grazing.iter().map(|c| c.wi[2]).collect();
        let w = TargetWeight::L2;
        let m = 4;
        let energy = |x: &[Vec<f64>; 3]| -> f64 {
            (0..3)
                .map(|c| {
                    (0..m)
                        .map(|i| x[c][i] * (0..m).map(|j| h[c][i * m + j] * x[c][j]).sum::<f64>())
                        .sum::<f64>()
                })
                .sum()
        };
        let plain = sample_coefficients(3, &vals, &y, 2, w, &cos, None).unwrap();
        let zero = Strength::default();
        let same = sample_coefficients(3, &vals, &y, 2, w, &cos, Some((&pr.ridge, zero))).unwrap();
        assert_eq!(same, plain);
        let mut last = energy(&plain);
        assert!(last > 0.0);
        for e in [1e-2, 1.0, 1e2, 1e4] {
            let st = Strength {
                toward: 0.0,
                energy: e,
            };
            let x = sample_coefficients(3, &vals, &y, 2, w, &cos, Some((&pr.ridge, st))).unwrap();
            let now = energy(&x);
            assert!(now <= last * (1.0 + 1e-9), "{e}: {now} > {last}");
            last = now;
        }
        assert!(last < 0.5 * energy(&plain), "{last}");
    }

    /// The rule of the strengths on a constructed underdetermined case (two grazing
    /// samples, four unknowns, under `relative`): the chosen strengths leave the fewest
    /// training fits wilder than [`WILD_RHO`] of the whole grid, and among those the
    /// lowest mean score; each training material judged with the prior without it.
    #[test]
    #[allow(clippy::needless_range_loop)]
    fn the_strengths_leave_the_fewest_wild_training_fits() {
        let coll = crate::collection::synthetic(12, 11);
        let basis = [0, 1, 2];
        let train: Vec<usize> = (3..12).collect();
        let w = TargetWeight::relative(0.01).unwrap();
        let fp = FitParams {
            stride: 8,
            objective: w,
            ..FitParams::default()
        };
        let pr = Prior::new(&CpuBackend::new(), &coll, &basis, &train, &fp, &|_, _| {}).unwrap();
        let all: Vec<usize> = (0..coll.len()).collect();
        let cands = cell_candidates(&coll, &all, &fp).unwrap();
        let grazing: Vec<Candidate> = cands
            .iter()
            .filter(|c| c.wi[2] < 0.3 && c.wo[2] < 0.3)
            .copied()
            .skip(1)
            .step_by(7)
            .take(2)
            .collect();
        assert_eq!(grazing.len(), 2);
        let vals = values_at(&coll, &basis, &grazing).unwrap();
        let tv = values_at(&coll, &train, &grazing).unwrap();
        let cos: Vec<f64> = grazing.iter().map(|c| c.wi[2]).collect();
        let chosen = pr.choose(&vals, &tv, 2, w, &cos, true).unwrap();
        let judge = |st: Strength| -> (usize, f64) {
            let (mut wild, mut sum) = (0, 0.0);
            for t in 0..train.len() {
                let y = [0, 1, 2].map(|c| tv[c][t].clone());
                let x =
                    sample_coefficients(3, &vals, &y, 2, w, &cos, Some((&pr.loo[t], st))).unwrap();
                wild += usize::from(pr.dense_l2.rho(t, &x) > WILD_RHO);
                sum += pr.dense.rho(t, &x);
            }
            (wild, sum / train.len() as f64)
        };
        let got = judge(chosen);
        for &energy in &ENERGY_STRENGTHS {
            for &toward in &RIDGE_STRENGTHS {
                let other = judge(Strength { toward, energy });
                assert!(
                    got.0 < other.0 || (got.0 == other.0 && got.1 <= other.1),
                    "chosen {chosen:?} {got:?} against {toward} {energy}: {other:?}"
                );
            }
        }
        // The case is one where the rule matters: plain NNLS leaves a wild fit.
        assert!(judge(Strength::default()).0 > got.0, "{got:?}");
    }
}
