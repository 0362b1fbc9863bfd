//! The Appearance stage of `reproduce` (SPEC 11, issue 37): the run's collection
//! cross-validated once per fit objective (`l2`, `relative`, `log`), greedy bases of one
//! size chosen on the training folds under each objective's shared weights, every held-out
//! material fitted under the objective's per-target weights and scored by rho, the
//! objective's own relative residual, log-RMSE and the image metrics of SPEC 11 under its
//! four lights; then the renders of the figure: four held-out materials (the worst `l2` fit
//! by four-light FLIP, the worst `relative` and `log` fits, the median `l2` fit), their
//! targets and fits under two lights.
//!
//! The stage is additive: the paper's stages ([`super::run`]) keep `l2` and do not see it.

use crate::backend::weighted::{ObjectiveKind, TargetWeight};
use crate::backend::Backend;
use crate::collection::Collection;
use crate::eval::appearance::{render_params, Reference};
use crate::eval::render::Image;
use crate::eval::shade::PixelBrdfs;
use crate::select::cv::{cross_validate_on, CvMethod, CvParams, CvResult, HeldOut};
use crate::select::{Objective, ObjectiveParams};
use crate::stats::mean;

use super::ExperimentError;

/// The objectives compared, in the table's order.
pub const OBJECTIVES: [ObjectiveKind; 3] = [
    ObjectiveKind::L2,
    ObjectiveKind::Relative,
    ObjectiveKind::Log,
];

/// The two lights of the figure (SPEC 11): the paper's and the grazing one.
pub const FIGURE_LIGHTS: [(f64, f64); 2] = [(45.0, 45.0), (75.0, 270.0)];

/// Collections above this many materials are cross-validated on a grid stride of at least
/// 2 (the renders and image metrics do not depend on it).
const BIG: usize = 40;

/// Settings of the stage.
#[derive(Clone, Debug, PartialEq)]
pub struct AppearanceParams {
    /// Folds (the run's `--cv-folds`, 5 when it is 0).
    pub folds: usize,
    /// Greedy basis size (the run's `--k-max`, at most the smallest training fold less one).
    pub k: usize,
    /// Seed of the folds.
    pub seed: u64,
    /// Grid stride of the fits.
    pub stride: usize,
    /// `eps` of `relative`.
    pub eps: f64,
}

impl AppearanceParams {
    /// The stage's settings for a run with `p` on `n` materials, or why it cannot run.
    pub fn of(p: &super::ExperimentParams, n: usize) -> Result<Self, String> {
        let folds = if p.cv_folds >= 2 { p.cv_folds } else { 5 };
        if folds > n {
            return Err(format!("{n} materials cannot be split into {folds} folds"));
        }
        let train = n - n.div_ceil(folds);
        let k = p.k_max.min(train.saturating_sub(1));
        if k == 0 {
            return Err(format!(
                "{n} materials in {folds} folds leave no training material outside a basis"
            ));
        }
        Ok(Self {
            folds,
            k,
            seed: p.seed,
            stride: if n > BIG { p.stride.max(2) } else { p.stride },
            eps: TargetWeight::DEFAULT_EPS,
        })
    }
}

/// One objective's row of the table: means over the held-out materials.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ObjectiveRow {
    /// `l2`, `relative` or `log`.
    pub objective: String,
    /// `eps` of `relative`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eps: Option<f64>,
    /// Held-out materials.
    pub materials: usize,
    /// Mean rho (SPEC 8: unweighted relative residual).
    pub rho: f64,
    /// Mean relative residual under the objective's per-target weights.
    pub objective_rho: f64,
    /// Mean log-RMSE.
    pub log_rmse: f64,
    /// Mean image error under the paper's light (45, 45).
    pub image_error_paper_light: f64,
    /// Mean image error over the four lights.
    pub image_error: f64,
    /// Mean CIEDE2000 over the four lights.
    pub ciede2000: f64,
    /// Mean ΔE_ITP (ITU-R BT.2124) over the four lights.
    pub delta_e_itp: f64,
    /// Mean FLIP under the paper's light.
    pub flip_paper_light: f64,
    /// Mean FLIP over the four lights.
    pub flip: f64,
    /// Held-out materials whose four-light FLIP is lower than under `l2` (absent for `l2`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flip_better_than_l2: Option<usize>,
}

/// One render of the figure.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FigureTile {
    /// The light, `(theta, phi)` degrees.
    pub light: (f64, f64),
    /// The objective of the fit (`None`: the target).
    pub objective: Option<String>,
    /// FLIP of the fit's render against the target's (`None` for the target).
    pub flip: Option<f64>,
    /// The render (not written to JSON).
    #[serde(skip)]
    pub image: Option<Image>,
}

/// One row of the figure: a held-out material, its target and fits under the two lights.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FigureRow {
    /// Material.
    pub material: String,
    /// Its fold (0-based).
    pub fold: usize,
    /// Why it is shown (e.g. `worst l2`).
    pub why: String,
    /// Per light of [`FIGURE_LIGHTS`]: the target, then the fit of each objective.
    pub tiles: Vec<FigureTile>,
}

/// What the stage computes (`appearance.json`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AppearanceStudy {
    /// Folds.
    pub folds: usize,
    /// Selection method of the fold bases (`greedy`).
    pub method: String,
    /// Basis size.
    pub k: usize,
    /// Seed.
    pub seed: u64,
    /// Grid stride of the fits.
    pub stride: usize,
    /// [`Collection::fingerprint`] of the collection.
    pub collection_fingerprint: String,
    /// Per objective (order of [`OBJECTIVES`]).
    pub rows: Vec<ObjectiveRow>,
    /// Each objective's cross-validation (fold bases and every held-out value).
    pub cv: Vec<CvResult>,
    /// The figure's rows.
    pub figure: Vec<FigureRow>,
}

/// Runs the stage on `coll` (module docs). `progress(done, total)` counts objectives.
pub fn run(
    backend: &dyn Backend,
    coll: &Collection,
    p: &AppearanceParams,
    progress: crate::backend::Progress<'_>,
) -> Result<AppearanceStudy, ExperimentError> {
    let total = OBJECTIVES.len() as u64 + 1;
    let mut cvs = Vec::new();
    let mut objs = Vec::new();
    for (i, kind) in OBJECTIVES.iter().enumerate() {
        progress(i as u64, total);
        let op = ObjectiveParams::default()
            .stride(p.stride)
            .objective(kind.weight(p.eps).map_err(crate::fit::FitError::from)?);
        let obj = Objective::new(backend, coll, &op.check()?, &|_, _| {})?;
        let vp = CvParams::default()
            .methods(vec![CvMethod::Greedy])
            .ks(vec![p.k])
            .folds(p.folds)
            .seed(p.seed)
            .objective(op)
            .appearance(true)
            .check(coll.len())?;
        cvs.push(cross_validate_on(
            backend,
            coll,
            &obj,
            None,
            &vp,
            &|_, _| {},
        )?);
        objs.push(obj);
    }
    progress(OBJECTIVES.len() as u64, total);
    let held = |c: &CvResult| -> Vec<HeldOut> {
        c.results
            .first()
            .map(|r| r.held_out.clone())
            .unwrap_or_default()
    };
    let l2 = held(&cvs[0]);
    let rows = OBJECTIVES
        .iter()
        .zip(&cvs)
        .map(|(kind, c)| row(*kind, p.eps, &held(c), &l2))
        .collect();
    let chosen = figure_materials(&cvs.iter().map(held).collect::<Vec<_>>());
    let figure = figure_rows(backend, coll, p, &cvs, &objs, &chosen)?;
    progress(total, total);
    Ok(AppearanceStudy {
        folds: p.folds,
        method: CvMethod::Greedy.name().into(),
        k: p.k,
        seed: p.seed,
        stride: p.stride,
        collection_fingerprint: coll.fingerprint(),
        rows,
        cv: cvs,
        figure,
    })
}

/// The four-light FLIP of a held-out fit (NaN without appearance metrics).
fn flip4(h: &HeldOut) -> f64 {
    h.appearance.as_ref().map_or(f64::NAN, |a| a.mean_flip)
}

/// The table row of one objective's held-out fits `h` (`l2`: those of `l2`).
fn row(kind: ObjectiveKind, eps: f64, h: &[HeldOut], l2: &[HeldOut]) -> ObjectiveRow {
    let m = |g: &dyn Fn(&HeldOut) -> f64| mean(&h.iter().map(g).collect::<Vec<f64>>());
    let a = |g: &dyn Fn(&crate::eval::appearance::Appearance) -> f64| {
        m(&|x: &HeldOut| x.appearance.as_ref().map_or(f64::NAN, g))
    };
    ObjectiveRow {
        objective: kind.name().into(),
        eps: (kind == ObjectiveKind::Relative).then_some(eps),
        materials: h.len(),
        rho: m(&|x| x.rho),
        objective_rho: m(&|x| x.objective_rho),
        log_rmse: m(&|x| x.log_rmse),
        image_error_paper_light: a(&|x| x.paper_light().image_error),
        image_error: a(&|x| x.mean_image_error),
        ciede2000: a(&|x| x.mean_ciede2000),
        delta_e_itp: a(&|x| x.mean_delta_e_itp),
        flip_paper_light: a(&|x| x.paper_light().flip),
        flip: a(&|x| x.mean_flip),
        flip_better_than_l2: (kind != ObjectiveKind::L2).then(|| {
            h.iter()
                .zip(l2)
                .filter(|(x, y)| x.material == y.material && flip4(x) < flip4(y))
                .count()
        }),
    }
}

/// The figure's materials (indices into the held-out lists, which every objective orders
/// alike) with why each is shown: the worst fit under `l2`, `relative` and `log` by
/// four-light FLIP, and the median `l2` fit; a material already chosen gives way to the
/// next one down the same list.
fn figure_materials(held: &[Vec<HeldOut>]) -> Vec<(usize, String)> {
    let mut chosen: Vec<(usize, String)> = Vec::new();
    let n = held.first().map_or(0, Vec::len);
    let by_flip = |h: &[HeldOut]| {
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| flip4(&h[b]).total_cmp(&flip4(&h[a])).then(a.cmp(&b)));
        order
    };
    let mut pick = |order: &[usize], why: String| {
        if let Some(&i) = order.iter().find(|i| !chosen.iter().any(|c| c.0 == **i)) {
            chosen.push((i, why));
        }
    };
    for (kind, h) in OBJECTIVES.iter().zip(held) {
        pick(&by_flip(h), format!("worst {} fit", kind.name()));
    }
    if let Some(h) = held.first() {
        let order = by_flip(h);
        pick(&order[n / 2..], "median l2 fit".into());
    }
    chosen
}

/// A fold basis (collection indices) and a fit's coefficients by it.
type BasisFit = (Vec<usize>, Vec<[f64; 3]>);

/// The renders of the figure: per chosen material and light of [`FIGURE_LIGHTS`], the
/// target and the fit of each objective by the material's fold basis (the coefficients of
/// the cross-validation: `l2` from the objective's Gram form, the others refitted with
/// the per-target weights on the same cells), each fit with its FLIP against the target.
fn figure_rows(
    backend: &dyn Backend,
    coll: &Collection,
    p: &AppearanceParams,
    cvs: &[CvResult],
    objs: &[Objective],
    chosen: &[(usize, String)],
) -> Result<Vec<FigureRow>, ExperimentError> {
    // Per chosen material and objective: the fold basis (collection indices) and the fit.
    let mut fits: Vec<Vec<BasisFit>> = Vec::new();
    let mut rows = Vec::new();
    for (i, why) in chosen {
        let first = &cvs[0].results[0].held_out[*i];
        let t = coll.index_of(&first.material)?;
        let mut per = Vec::new();
        for ((kind, c), obj) in OBJECTIVES.iter().zip(cvs).zip(objs) {
            let r = &c.results[0];
            let names = &r.fold_bases[r.held_out[*i].fold];
            let basis = names
                .iter()
                .map(|b| coll.index_of(b))
                .collect::<Result<Vec<usize>, _>>()?;
            let coef = if *kind == ObjectiveKind::L2 {
                obj.fit(&basis, t)?.coefficients
            } else {
                let fp = ObjectiveParams::default()
                    .stride(p.stride)
                    .objective(kind.weight(p.eps).map_err(crate::fit::FitError::from)?)
                    .fit_params();
                let f = crate::fit::fit(backend, coll, &basis, &[t], &fp, &|_, _| {})?;
                f[0].coefficients.clone()
            };
            per.push((basis, coef));
        }
        fits.push(per);
        rows.push(FigureRow {
            material: first.material.clone(),
            fold: first.fold,
            why: why.clone(),
            tiles: Vec::new(),
        });
    }
    // The materials the renders need, as a sub-collection tabulated once per light.
    let mut used: Vec<usize> = Vec::new();
    for (row, per) in rows.iter().zip(&fits) {
        used.push(coll.index_of(&row.material)?);
        used.extend(per.iter().flat_map(|(b, _)| b.iter().copied()));
    }
    used.sort_unstable();
    used.dedup();
    let sub = coll.subset(&used);
    let local = |m: usize| used.binary_search(&m).unwrap_or(0);
    for light in FIGURE_LIGHTS {
        let pixels = PixelBrdfs::new(&sub, &render_params(light))?;
        for (row, per) in rows.iter_mut().zip(&fits) {
            let target = pixels.render_material(local(coll.index_of(&row.material)?))?;
            let reference = Reference::new(&target)?;
            let mut tiles = Vec::new();
            for (kind, (basis, coef)) in OBJECTIVES.iter().zip(per) {
                let b: Vec<usize> = basis.iter().map(|&m| local(m)).collect();
                let img = pixels.render_combination(&b, coef)?;
                tiles.push(FigureTile {
                    light,
                    objective: Some(kind.name().into()),
                    flip: Some(reference.scores(&img, light)?.flip),
                    image: Some(img),
                });
            }
            row.tiles.push(FigureTile {
                light,
                objective: None,
                flip: None,
                image: Some(target),
            });
            row.tiles.extend(tiles);
        }
    }
    Ok(rows)
}
