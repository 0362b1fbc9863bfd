//! Fits of the evaluation targets by every basis (paper VI-E): MAE on reflectance over the
//! fit mask and normalised image errors of sphere renders (paper Fig. 4 and 5).

use super::bases::Basis;
use super::files::{FitFile, FitTarget};
use super::statistics::median;
use super::ExperimentError;
use crate::backend::Backend;
use crate::collection::Collection;
use crate::eval::image_error::{normalized_image_error, DisplayParams};
use crate::eval::render::{render_sphere, Image, RenderParams};
use crate::eval::shade::{combination_brdf, material_brdf};
use crate::fit::{fit, FitParams};
use rayon::prelude::*;

/// Errors of every target by one basis, target order.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BasisErrors {
    /// Basis name.
    pub basis: String,
    /// Number of materials in the basis.
    pub size: usize,
    /// MAE per target.
    pub mae: Vec<f64>,
    /// Normalised image error per target.
    pub image_error: Vec<f64>,
    /// Mean MAE.
    pub mean_mae: f64,
    /// Median MAE.
    pub median_mae: f64,
    /// Mean image error.
    pub mean_image_error: f64,
    /// Median image error.
    pub median_image_error: f64,
}

/// The showcase material (paper Fig. 5): the original and each basis's approximation.
#[derive(Clone, Debug)]
pub struct Showcase {
    /// Material name.
    pub material: String,
    /// Render of the material.
    pub original: Image,
    /// Per basis (basis order): name, its fit, its render and the normalised image error.
    pub approximations: Vec<(String, FitTarget, Image, f64)>,
}

/// Results of the evaluation stage.
#[derive(Clone, Debug)]
pub struct Evaluation {
    /// Target materials (collection order).
    pub targets: Vec<String>,
    /// One `fit` file per basis (basis order).
    pub fits: Vec<FitFile>,
    /// Errors per basis (basis order).
    pub errors: Vec<BasisErrors>,
    /// The showcase.
    pub showcase: Showcase,
}

/// Settings of the evaluation.
#[derive(Clone, Debug)]
pub struct EvalSettings {
    /// Fit settings.
    pub fit: FitParams,
    /// Renders for the image errors (size, light).
    pub small: RenderParams,
    /// Renders of the showcase.
    pub big: RenderParams,
    /// Display mapping of the image errors.
    pub display: DisplayParams,
}

/// `fit_errors.csv`: `material`, then `mae-<basis>,image-error-<basis>` per basis.
pub fn errors_csv(e: &Evaluation) -> String {
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["material".to_string()];
    for b in &e.errors {
        header.push(format!("mae-{}", b.basis));
        header.push(format!("image-error-{}", b.basis));
    }
    let _ = w.write_record(&header);
    for (t, name) in e.targets.iter().enumerate() {
        let mut row = vec![name.clone()];
        for b in &e.errors {
            row.push(format!("{:e}", b.mae[t]));
            row.push(format!("{:e}", b.image_error[t]));
        }
        let _ = w.write_record(&row);
    }
    String::from_utf8(w.into_inner().unwrap_or_default()).unwrap_or_default()
}

/// Fits `targets` by every basis, renders fits and originals, and the showcase.
pub fn evaluate(
    backend: &dyn Backend,
    coll: &Collection,
    bases: &[Basis],
    targets: &[usize],
    showcase: usize,
    s: &EvalSettings,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Evaluation, ExperimentError> {
    let originals: Vec<Image> = targets
        .par_iter()
        .map(|&t| render_sphere(&s.small, &material_brdf(&coll.materials()[t].data)))
        .collect::<Result<_, _>>()?;
    let show_orig = render_sphere(&s.big, &material_brdf(&coll.materials()[showcase].data))?;
    let mut fits = Vec::new();
    let mut errors = Vec::new();
    let mut approximations = Vec::new();
    let total = bases.len() as u64;
    for (bi, b) in bases.iter().enumerate() {
        progress(bi as u64, total);
        let basis: Vec<usize> = b
            .materials
            .iter()
            .map(|n| coll.index_of(n))
            .collect::<Result<_, _>>()?;
        let f = fit(backend, coll, &basis, targets, &s.fit, &|_, _| {})?;
        let file = FitFile::new(coll, &basis, &f, &s.fit);
        let image_error: Vec<f64> = f
            .par_iter()
            .zip(&originals)
            .map(|(t, orig)| {
                let img =
                    render_sphere(&s.small, &combination_brdf(coll, &basis, &t.coefficients))?;
                Ok(normalized_image_error(orig, &img, &s.display)?)
            })
            .collect::<Result<_, ExperimentError>>()?;
        let show_fit = match targets.iter().position(|&t| t == showcase) {
            Some(i) => f[i].clone(),
            None => fit(backend, coll, &basis, &[showcase], &s.fit, &|_, _| {})?.remove(0),
        };
        let img = render_sphere(
            &s.big,
            &combination_brdf(coll, &basis, &show_fit.coefficients),
        )?;
        let err = normalized_image_error(&show_orig, &img, &s.display)?;
        approximations.push((
            b.name.clone(),
            FitTarget::new(&b.materials, &show_fit),
            img,
            err,
        ));
        let mae: Vec<f64> = f.iter().map(|t| t.mae).collect();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        errors.push(BasisErrors {
            basis: b.name.clone(),
            size: basis.len(),
            mean_mae: mean(&mae),
            median_mae: median(&mae),
            mean_image_error: mean(&image_error),
            median_image_error: median(&image_error),
            mae,
            image_error,
        });
        fits.push(file);
    }
    progress(total, total);
    Ok(Evaluation {
        targets: targets.iter().map(|&t| coll.names()[t].clone()).collect(),
        fits,
        errors,
        showcase: Showcase {
            material: coll.names()[showcase].clone(),
            original: show_orig,
            approximations,
        },
    })
}
