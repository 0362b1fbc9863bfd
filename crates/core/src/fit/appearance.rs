//! The appearance metrics (SPEC 11, [`crate::eval::appearance`]) of fits of collection
//! materials: log-RMSE over the fit cells, and renders of the fit against renders of the
//! material under the four lights.

use super::{channel_lobe, combination_values, FitError, TargetFit};
use crate::backend::cpu::CpuBackend;
use crate::backend::weighted::cos_theta_i;
use crate::collection::Collection;
use crate::eval::appearance::{light_scores, render_params, Appearance, LogSums, LIGHTS};
use crate::eval::render::{render_sphere, Image};
use crate::eval::shade::{combination_brdf, material_brdf};
use crate::merl::CellSet;
use rayon::prelude::*;

/// The log-RMSE (SPEC 11) of `fit` (of collection material `target` by `basis`) over
/// `cells`, from the f64 values of every column and of the target.
pub fn log_rmse(
    coll: &Collection,
    basis: &[usize],
    target: usize,
    fit: &TargetFit,
    cells: &CellSet,
) -> f64 {
    let cpu = CpuBackend::new();
    let cos: Vec<f64> = cells
        .cells
        .iter()
        .map(|&c| cos_theta_i(c as usize))
        .collect();
    let mut sums = LogSums::default();
    for c in 0..3 {
        let fitted = combination_values(coll, basis, fit, c, &cells.cells);
        let t = cpu.values_f64(
            &channel_lobe(&coll.materials()[target].data, c),
            &cells.cells,
        );
        for (((&f, &b), &w), &ci) in fitted.iter().zip(&t).zip(&cells.weights).zip(&cos) {
            sums.add(f, b, w, ci);
        }
    }
    sums.value()
}

/// Renders of material `m` under the four lights ([`LIGHTS`], [`crate::eval::appearance::RENDER_SIZE`]).
pub(crate) fn material_renders(coll: &Collection, m: usize) -> Result<Vec<Image>, FitError> {
    let brdf = material_brdf(&coll.materials()[m].data);
    LIGHTS
        .iter()
        .map(|&(th, ph)| {
            let rp = render_params((th, ph));
            render_sphere(&rp, &brdf).map_err(render_error)
        })
        .collect()
}

fn render_error(e: crate::eval::render::RenderError) -> FitError {
    FitError::Backend(crate::error::BackendError::Invalid(format!(
        "appearance render: {e}"
    )))
}

/// The appearance metrics of each fit (`fits[i]` of collection material `targets[i]` by
/// `basis`), over the fit `cells` and under the four lights; targets in parallel.
pub fn appearance(
    coll: &Collection,
    basis: &[usize],
    targets: &[usize],
    fits: &[TargetFit],
    cells: &CellSet,
) -> Result<Vec<Appearance>, FitError> {
    targets
        .par_iter()
        .zip(fits)
        .map(|(&t, fit)| {
            let originals = material_renders(coll, t)?;
            let brdf = combination_brdf(coll, basis, &fit.coefficients);
            let lights = LIGHTS
                .iter()
                .zip(&originals)
                .map(|(&(th, ph), orig)| {
                    let rp = render_params((th, ph));
                    let img = render_sphere(&rp, &brdf).map_err(render_error)?;
                    light_scores(orig, &img, (th, ph)).map_err(render_error)
                })
                .collect::<Result<Vec<_>, _>>()?;
            Ok(Appearance::new(
                log_rmse(coll, basis, t, fit, cells),
                lights,
            ))
        })
        .collect()
}
