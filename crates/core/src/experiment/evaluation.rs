//! Fits of the evaluation targets by every basis (paper VI-E): MAE on reflectance over the
//! fit mask and normalised image errors of sphere renders (paper Fig. 4 and 5).

use super::bases::Basis;
use super::ExperimentError;
use crate::backend::cpu::CpuBackend;
use crate::backend::Backend;
use crate::collection::Collection;
use crate::eval::image_error::{normalized_image_error, DisplayParams};
use crate::eval::render::{render_sphere, Image, RenderParams};
use crate::eval::shade::{combination_brdf, material_brdf};
use crate::fit::file::{FitFile, FitTarget};
use crate::fit::{
    channel_gram, fit, fit_cells, solve_channel, CollectionGrams, FitError, FitParams, GramMode,
    Solver, TargetFit,
};
use crate::merl::CellSet;
use crate::select::cv::evaluate::{cell_sums, MaeJob};
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
pub(crate) fn combine(images: &[&Image], coefficients: &[[f64; 3]]) -> Image {
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

/// Render size of the renders `default_showcase` judges measured materials by.
pub const SHOWCASE_PROBE_SIZE: u32 = 64;

/// The default showcase among `targets` (collection indices, not empty):
/// [`PAPER_SHOWCASE`] when it is a target; else a moderately glossy material whose
/// render shows its lobe on a visible body: among the analytic targets with a specular
/// lobe (mean `s > 0`), a body (mean diffuse albedo `>=` [`SHOWCASE_MIN_DIFFUSE`]) and a
/// highlight that stands out (contrast `>=` [`SHOWCASE_MIN_CONTRAST`]), the one whose
/// exponent is nearest [`SHOWCASE_EXPONENT`] on a log scale (ties: the first); without
/// such a target, the analytic target with a lobe nearest that exponent; else (measured,
/// neural and RGL collections) the target whose render shows most, by
/// [`visible_showcase`].
pub(crate) fn default_showcase(coll: &Collection, targets: &[usize]) -> usize {
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
        .unwrap_or_else(|| visible_showcase(coll, targets))
}

/// The target (of `targets`, not empty) whose display-mapped render ([`SHOWCASE_PROBE_SIZE`]
/// px, light (45, 45), the default display mapping) shows both a body and a highlight on
/// it: the largest `min(body, peak - body)`, `body` the median and `peak` the largest
/// display value (mean over RGB) of the lit sphere pixels (ties, and renders that fail:
/// the first). A near-black material (small body) and a matte one (no peak above its body)
/// both score low.
pub(crate) fn visible_showcase(coll: &Collection, targets: &[usize]) -> usize {
    let rp = RenderParams::default()
        .with_size(SHOWCASE_PROBE_SIZE)
        .with_light(45.0, 45.0);
    let display = DisplayParams::default();
    // The lit pixels: those a white Lambertian sphere shows.
    let lit: Vec<bool> = match render_sphere(&rp, &|_, _| [1.0; 3]) {
        Ok(img) => img.data.chunks_exact(3).map(|p| p[0] > 0.0).collect(),
        Err(_) => return targets[0],
    };
    let score = |t: usize| -> f64 {
        let Ok(img) = render_sphere(&rp, &material_brdf(&coll.materials()[t].data)) else {
            return f64::NEG_INFINITY;
        };
        let mut v: Vec<f64> = img
            .data
            .chunks_exact(3)
            .zip(&lit)
            .filter(|(_, &l)| l)
            .map(|(p, _)| p.iter().map(|&x| display.map(f64::from(x))).sum::<f64>() / 3.0)
            .collect();
        if v.is_empty() {
            return f64::NEG_INFINITY;
        }
        v.sort_by(f64::total_cmp);
        let body = v[v.len() / 2];
        let peak = v[v.len() - 1];
        body.min(peak - body)
    };
    let scores: Vec<f64> = targets.par_iter().map(|&t| score(t)).collect();
    let mut best = 0;
    for i in 1..targets.len() {
        if scores[i] > scores[best] {
            best = i;
        }
    }
    targets[best]
}

/// [`fit`] of `targets` by every basis (collection indices), the same fits to the bit.
/// When `fit` would compute its grid errors cell by cell (some material of the fit not
/// analytic, exact solver), the coefficients come from `fit`'s Gram quantities and solver
/// per basis, and the grid errors of every basis's fits from one pass over the cells for
/// all of them ([`cell_sums`]: each material tabulated once per block of cells, not once per
/// basis and channel); bases whose fits share no cell set get one pass per cell set.
///
/// Long function: two phases over the same per-basis state (the coefficients per cell
/// set, then one grid pass per distinct cell set for every basis's errors), with
/// `fit`'s arithmetic channel by channel so that the results are `fit`'s to the bit.
fn fit_all(
    backend: &dyn Backend,
    coll: &Collection,
    bases: &[Vec<usize>],
    targets: &[usize],
    p: &FitParams,
    shared: Option<&CollectionGrams>,
) -> Result<Vec<Vec<TargetFit>>, ExperimentError> {
    let analytic = |i: &usize| coll.materials()[*i].analytic().is_some();
    let mut out: Vec<Option<Vec<TargetFit>>> = vec![None; bases.len()];
    // Per basis fitted here: its cells and its fits without grid errors.
    let mut pending: Vec<Pending> = Vec::new();
    for (bi, basis) in bases.iter().enumerate() {
        let by_moments = p.gram == GramMode::Auto && basis.iter().chain(targets).all(analytic);
        let duplicate = (0..basis.len()).any(|i| basis[..i].contains(&basis[i]));
        if by_moments
            || p.solver != Solver::Exact
            || basis.is_empty()
            || targets.is_empty()
            || duplicate
        {
            out[bi] = Some(fit(backend, coll, basis, targets, p, &|_, _| {})?);
            continue;
        }
        let mut all: Vec<usize> = basis.clone();
        all.extend_from_slice(targets);
        let cells = fit_cells(coll, &all, p)?;
        if cells.cells.is_empty() {
            return Err(FitError::NoCells {
                mask: p.mask,
                stride: p.stride,
            }
            .into());
        }
        let m = basis.len() + 1;
        let fits: Vec<TargetFit> = targets
            .iter()
            .map(|&t| TargetFit {
                material: coll.materials()[t].name.clone(),
                coefficients: vec![[0.0; 3]; m],
                residual: [0.0; 3],
                mae: 0.0,
                relative_residual: 0.0,
                relative_mae: 0.0,
                objective_residual: 0.0,
                kkt: [0.0; 3],
                iterations: [0; 3],
            })
            .collect();
        let norms = vec![[0.0; 3]; targets.len()];
        pending.push((bi, cells, fits, norms));
    }
    // One pass per distinct cell set.
    let mut done = vec![false; pending.len()];
    let cpu = CpuBackend::new();
    for first in 0..pending.len() {
        if done[first] {
            continue;
        }
        let group: Vec<usize> = (first..pending.len())
            .filter(|&i| {
                let (a, b) = (&pending[i].1, &pending[first].1);
                !done[i] && a.cells == b.cells && a.weights == b.weights
            })
            .collect();
        union_fits(
            backend,
            coll,
            bases,
            targets,
            p,
            shared,
            &mut pending,
            &group,
        )?;
        let jobs: Vec<MaeJob<'_>> = group
            .iter()
            .flat_map(|&i| {
                let basis = &bases[pending[i].0];
                targets
                    .iter()
                    .zip(&pending[i].2)
                    .map(move |(&t, f)| MaeJob {
                        basis,
                        target: t,
                        coef: &f.coefficients,
                    })
            })
            .collect();
        let sums = cell_sums::<true, false>(&cpu, coll, &pending[first].1, &jobs, &|| {});
        drop(jobs);
        let mut sums = sums.into_iter();
        for &i in &group {
            done[i] = true;
            let (_, _, fits, norms) = &mut pending[i];
            for (f, norm) in fits.iter_mut().zip(norms.iter()) {
                let e = sums.next().expect("one sum per job");
                // `fit`'s arithmetic, channel by channel.
                let (mut target_norm, mut target_l1) = (0.0, 0.0);
                for c in 0..3 {
                    target_norm += norm[c];
                    target_l1 += e[c].target;
                    f.residual[c] = e[c].squared.sqrt();
                    f.mae += e[c].absolute / 3.0;
                }
                let sq: f64 = f.residual.iter().map(|r| r * r).sum();
                f.relative_residual = if target_norm > 0.0 {
                    sq / target_norm
                } else {
                    0.0
                };
                f.objective_residual = f.relative_residual;
                f.relative_mae = if target_l1 > 0.0 {
                    3.0 * f.mae / target_l1
                } else {
                    0.0
                };
            }
        }
    }
    for (bi, _, fits, _) in pending {
        out[bi] = Some(fits);
    }
    Ok(out
        .into_iter()
        .map(|f| f.expect("every basis fitted"))
        .collect())
}

/// A basis fitted by [`fit_all`]'s shared passes: its index, cells, fits and per target
/// the squared norm of each channel.
type Pending = (usize, CellSet, Vec<TargetFit>, Vec<[f64; 3]>);

/// The coefficients of the fits of the bases `group` of `pending` (one cell set): per
/// channel one Gram pass of the back-end over the Lambertian column, the union of their
/// materials and the targets, from which each basis's [`channel_gram`] quantities are read
/// (a pair's sum depends only on its two rows and the cells: the canonical order of
/// `backend::cpu`), or read from `shared` when it covers the same cells (the same numbers),
/// then `fit`'s solver.
#[allow(clippy::too_many_arguments)]
fn union_fits(
    backend: &dyn Backend,
    coll: &Collection,
    bases: &[Vec<usize>],
    targets: &[usize],
    p: &FitParams,
    shared: Option<&CollectionGrams>,
    pending: &mut [Pending],
    group: &[usize],
) -> Result<(), ExperimentError> {
    let mut union: Vec<usize> = Vec::new();
    for &i in group {
        for &b in &bases[pending[i].0] {
            if !union.contains(&b) {
                union.push(b);
            }
        }
    }
    let pos = |b: usize| 1 + union.iter().position(|&u| u == b).expect("in the union");
    let cells = pending[group[0]].1.clone();
    let shared = shared.filter(|s| s.covers(&cells));
    for c in 0..3 {
        let full = match shared {
            Some(s) => s.channel_gram(coll, &union, targets, c)?,
            None => channel_gram(
                backend,
                coll,
                &union,
                targets,
                &cells,
                c,
                p.gram,
                &|_, _| {},
            )?,
        };
        let mu = union.len() + 1;
        for &i in group {
            let (bi, _, fits, norms) = &mut pending[i];
            let basis = &bases[*bi];
            let cols: Vec<usize> = std::iter::once(0)
                .chain(basis.iter().map(|&b| pos(b)))
                .collect();
            let m = cols.len();
            let mut g = vec![0.0; m * m];
            for (a, &ca) in cols.iter().enumerate() {
                for (b, &cb) in cols.iter().enumerate() {
                    g[a * m + b] = full.gram[ca * mu + cb];
                }
            }
            if let Some(e) = g.iter().position(|v| !v.is_finite()) {
                let k = (e / m).max(1) - 1;
                return Err(FitError::NonFinite {
                    material: coll.materials()[basis[k]].name.clone(),
                    channel: c,
                }
                .into());
            }
            let hs: Vec<f64> = (0..targets.len())
                .flat_map(|t| cols.iter().map(move |&ca| (t, ca)))
                .map(|(t, ca)| full.h[t * mu + ca])
                .collect();
            let sols = solve_channel(backend, m, &g, &hs, &full.bb, p.solver)?;
            for (((f, s), n), &bb) in fits
                .iter_mut()
                .zip(&sols)
                .zip(norms.iter_mut())
                .zip(&full.bb)
            {
                n[c] = bb;
                for (k, &a) in s.x.iter().enumerate() {
                    f.coefficients[k][c] = a;
                }
                f.kkt[c] = s.max_kkt_violation;
                f.iterations[c] = s.iterations;
            }
        }
    }
    Ok(())
}

/// Fits `targets` by every basis, renders fits and originals, and the showcase. `shared`:
/// the Gram matrices of the whole collection when the experiment made them (the fits over
/// the same cells read their Gram quantities there instead of making a pass of their own).
#[allow(clippy::too_many_arguments)]
pub fn evaluate(
    backend: &dyn Backend,
    coll: &Collection,
    bases: &[Basis],
    targets: &[usize],
    showcase: usize,
    s: &EvalSettings,
    shared: Option<&CollectionGrams>,
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
    let indices: Vec<Vec<usize>> = bases
        .iter()
        .map(|b| b.materials.iter().map(|n| coll.index_of(n)).collect())
        .collect::<Result<_, _>>()?;
    let mut fits: Vec<Option<Vec<TargetFit>>> =
        fit_all(backend, coll, &indices, targets, &s.fit, shared)?
            .into_iter()
            .map(Some)
            .collect();
    let mut files = Vec::new();
    let mut errors = Vec::new();
    let mut approximations = Vec::new();
    let total = bases.len() as u64;
    for (bi, b) in bases.iter().enumerate() {
        progress(bi as u64, total);
        let basis = indices[bi].clone();
        let f = fits[bi].take().expect("one fit per basis");
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
        files.push(file);
    }
    progress(total, total);
    Ok(Evaluation {
        targets: targets.iter().map(|&t| coll.names()[t].clone()).collect(),
        fits: files,
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
        // No lobe at all: the render that shows most (the only target).
        assert_eq!(default_showcase(&c, &[3]), idx("matte"));
    }

    #[test]
    fn a_measured_showcase_has_a_body_and_a_highlight() {
        let c = analytic(
            "black,0.005,0.005,0.005,0.01,0.01,0.01,0.04,100\n\
             matte,0.5,0.5,0.5,0,0,0,0.5,1\n\
             glossy,0.3,0.3,0.3,1,1,1,0.5,100\n",
        );
        let idx = |n: &str| c.index_of(n).unwrap();
        assert_eq!(visible_showcase(&c, &[0, 1, 2]), idx("glossy"));
        assert_eq!(visible_showcase(&c, &[0, 1]), idx("matte"));
        assert_eq!(visible_showcase(&c, &[0]), idx("black"));
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
