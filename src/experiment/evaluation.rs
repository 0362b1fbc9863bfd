//! Fits of the evaluation targets by every basis (paper VI-E): MAE on reflectance over the
//! fit mask and normalised image errors of sphere renders (paper Fig. 4 and 5).

use super::bases::Basis;
use super::ExperimentError;
use crate::backend::Backend;
use crate::collection::Collection;
use crate::eval::image_error::{normalized_image_error, DisplayParams};
use crate::eval::render::{render_sphere, Image, RenderParams};
use crate::eval::shade::{combination_brdf, material_brdf};
use crate::fit::file::{FitFile, FitTarget};
use crate::fit::{fit, FitParams};
use crate::stats::{mean, median};
use rayon::prelude::*;
use std::collections::{BTreeSet, HashMap};

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

/// One basis's approximation of the showcase material.
#[derive(Clone, Debug)]
pub struct Approximation {
    /// Basis name.
    pub basis: String,
    /// The basis's fit of the showcase material.
    pub fit: FitTarget,
    /// Render of the fit.
    pub image: Image,
    /// Normalised image error against the original's render.
    pub image_error: f64,
}

/// The showcase material (paper Fig. 5): the original and each basis's approximation.
#[derive(Clone, Debug)]
pub struct Showcase {
    /// Material name.
    pub material: String,
    /// Render of the material.
    pub original: Image,
    /// One per basis, basis order.
    pub approximations: Vec<Approximation>,
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

/// The image `sum_k a_k,c images[k]_c` per channel (all images of one size and mask),
/// accumulated in f64: the render of a combination from the renders of its columns.
pub fn combine(images: &[&Image], coefficients: &[[f64; 3]]) -> Image {
    let mut out = images[0].clone();
    for (p, v) in out.data.iter_mut().enumerate() {
        let c = p % 3;
        let sum: f64 = images
            .iter()
            .zip(coefficients)
            .map(|(img, a)| a[c] * f64::from(img.data[p]))
            .sum();
        *v = sum as f32;
    }
    out
}

/// The paper's showcase material (Fig. 5).
pub const PAPER_SHOWCASE: &str = "alum-bronze";

/// Exponent a showcase's highlight should have: a lobe of visible size on a 256 px sphere
/// (neither a single bright pixel, n ~ 1e4, nor a blur across the sphere, n ~ 1).
pub const SHOWCASE_EXPONENT: f64 = 100.0;

/// Smallest mean diffuse albedo of a showcase: enough for the sphere to show under the
/// display mapping, so the render is not a highlight on black.
pub const SHOWCASE_MIN_DIFFUSE: f64 = 0.05;

/// Smallest highlight-to-body contrast of a showcase, `s (n + 1) F0 / (8 d)` (means over
/// RGB): the peak of the specular lobe, about `s (n + 1) F0 / (8 pi)` in the mirror
/// direction near normal incidence, over the diffuse `d / pi`. Below it the highlight is
/// lost in the body (Ngan's teflon: 0.45).
pub const SHOWCASE_MIN_CONTRAST: f64 = 3.0;

/// The default showcase among `targets` (collection indices, not empty):
/// [`PAPER_SHOWCASE`] when it is a target; else a moderately glossy material whose
/// render shows its lobe on a visible body: among the analytic targets with a specular
/// lobe (mean `s > 0`), a body (mean diffuse albedo `>=` [`SHOWCASE_MIN_DIFFUSE`]) and a
/// highlight that stands out (contrast `>=` [`SHOWCASE_MIN_CONTRAST`]), the one whose
/// exponent is nearest [`SHOWCASE_EXPONENT`] on a log scale (ties: the first); without
/// such a target, the analytic target with a lobe nearest that exponent; else the first
/// target (measured collections).
pub fn default_showcase(coll: &Collection, targets: &[usize]) -> usize {
    if let Some(&t) = targets.iter().find(|&&t| coll.names()[t] == PAPER_SHOWCASE) {
        return t;
    }
    let mean = |v: &[f64; 3]| (v[0] + v[1] + v[2]) / 3.0;
    let nearest = |need_body: bool| {
        targets
            .iter()
            .filter_map(|&t| {
                let a = coll.materials()[t].analytic()?;
                let lobe = mean(&a.s) > 0.0 && a.n.is_finite() && a.n > 0.0;
                let d = mean(&a.d);
                let contrast = mean(&a.s) * (a.n + 1.0) * a.f0 / (8.0 * d);
                let body = d >= SHOWCASE_MIN_DIFFUSE && contrast >= SHOWCASE_MIN_CONTRAST;
                (lobe && (body || !need_body))
                    .then(|| (t, (a.n.log10() - SHOWCASE_EXPONENT.log10()).abs()))
            })
            .fold(None, |best: Option<(usize, f64)>, c| match best {
                Some(b) if b.1 <= c.1 => Some(b),
                _ => Some(c),
            })
            .map(|b| b.0)
    };
    nearest(true)
        .or_else(|| nearest(false))
        .unwrap_or(targets[0])
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
    // Renders are linear in the BRDF, so every combination's render is the same
    // combination of the renders of its columns: one render per material, not per fit.
    let needed: BTreeSet<usize> = targets
        .iter()
        .copied()
        .chain(
            bases
                .iter()
                .flat_map(|b| b.materials.iter().filter_map(|n| coll.index_of(n).ok())),
        )
        .collect();
    let needed: Vec<usize> = needed.into_iter().collect();
    let renders: HashMap<usize, Image> = needed
        .par_iter()
        .map(|&m| {
            Ok((
                m,
                render_sphere(&s.small, &material_brdf(&coll.materials()[m].data))?,
            ))
        })
        .collect::<Result<_, ExperimentError>>()?;
    let lambert = render_sphere(&s.small, &|_, _| [std::f64::consts::FRAC_1_PI; 3])?;
    let originals: Vec<&Image> = targets.iter().map(|t| &renders[t]).collect();
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
                let columns: Vec<&Image> = std::iter::once(&lambert)
                    .chain(basis.iter().map(|b| &renders[b]))
                    .collect();
                let img = combine(&columns, &t.coefficients);
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
        approximations.push(Approximation {
            basis: b.name.clone(),
            fit: FitTarget::new(&b.materials, &show_fit),
            image: img,
            image_error: err,
        });
        let mae: Vec<f64> = f.iter().map(|t| t.mae).collect();
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A combination rendered from its columns' renders equals the direct render of the
    /// combined BRDF (f32 rounding apart).
    fn analytic(rows: &str) -> Collection {
        let csv = format!("material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n{rows}");
        crate::collection::parse_csv(csv.as_bytes(), std::path::Path::new("test.csv")).unwrap()
    }

    #[test]
    fn showcase_is_the_papers_else_moderately_glossy_with_a_body() {
        let c = analytic(
            "dot,0.0,0.0,0.0,1,1,1,0.5,120\n\
             tiny,0.3,0.3,0.3,1,1,1,0.5,10000\n\
             glossy,0.3,0.3,0.3,1,1,1,0.5,300\n\
             matte,0.5,0.5,0.5,0,0,0,0.5,1\n\
             near,0.2,0.2,0.2,1,1,1,0.5,40\n\
             faint,0.5,0.5,0.5,0.1,0.1,0.1,0.04,100\n\
             alum-bronze,0.1,0.1,0.1,1,1,1,0.5,1350\n\
             dot-far,0.0,0.0,0.0,1,1,1,0.5,5\n",
        );
        let idx = |n: &str| c.index_of(n).unwrap();
        // The paper's material wins whenever it is a target.
        assert_eq!(default_showcase(&c, &[0, 1, 2, 6]), idx("alum-bronze"));
        // |log10(300 / 100)| = 0.48 > |log10(40 / 100)| = 0.40: `near`; `dot` has no body.
        assert_eq!(default_showcase(&c, &[0, 1, 2, 3, 4]), idx("near"));
        assert_eq!(default_showcase(&c, &[0, 1, 2, 3]), idx("glossy"));
        // n = 100 exactly, but a highlight of contrast 0.1 * 101 * 0.04 / 4 = 0.1: lost.
        assert_eq!(default_showcase(&c, &[5, 0, 1, 2, 3]), idx("glossy"));
        // No target with a body: the lobe nearest the exponent.
        assert_eq!(default_showcase(&c, &[7, 0]), idx("dot"));
        // No lobe at all: the first target.
        assert_eq!(default_showcase(&c, &[3]), idx("matte"));
    }

    #[test]
    fn combined_render_equals_direct_render() {
        let coll = Collection::embedded_default();
        let basis = [0usize, 5, 9];
        let coef = [
            [0.3, 0.2, 0.1],
            [0.5, 0.4, 0.3],
            [0.0, 1.2, 0.7],
            [2.0, 0.1, 0.0],
        ];
        let p = RenderParams::default().with_size(40);
        let direct = render_sphere(&p, &combination_brdf(&coll, &basis, &coef)).unwrap();
        let lambert = render_sphere(&p, &|_, _| [std::f64::consts::FRAC_1_PI; 3]).unwrap();
        let cols: Vec<Image> = basis
            .iter()
            .map(|&b| render_sphere(&p, &material_brdf(&coll.materials()[b].data)).unwrap())
            .collect();
        let refs: Vec<&Image> = std::iter::once(&lambert).chain(&cols).collect();
        let combined = combine(&refs, &coef);
        assert_eq!(combined.mask, direct.mask);
        for (a, b) in combined.data.iter().zip(&direct.data) {
            assert!((a - b).abs() <= 1e-6 * b.abs().max(1e-3), "{a} vs {b}");
        }
    }
}
