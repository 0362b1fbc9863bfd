//! BRDF closures for rendering: an analytic material, a measured one (MERL lookup, SPEC
//! 7), a neural one (its network at the direction pair, SPEC 9), or a fitted combination `a0 / pi + sum_k a_k f_k`.

use crate::collection::{Collection, MaterialData};
use crate::merl::grid::lookup;

/// A BRDF `f(wi, wo) -> RGB` for the renderer.
pub type BrdfFn = Box<dyn Fn([f64; 3], [f64; 3]) -> [f64; 3] + Sync + Send>;

/// The BRDF of one material: analytic evaluation, or the MERL lookup of a measured table
/// (invalid cells give 0).
pub fn material_brdf(m: &MaterialData) -> BrdfFn {
    match m {
        MaterialData::Analytic(a) => {
            let a = *a;
            Box::new(move |wi, wo| a.eval(wi, wo))
        }
        MaterialData::Measured(t) => {
            let t = t.clone();
            Box::new(move |wi, wo| {
                if wi[2] <= 0.0 || wo[2] <= 0.0 {
                    return [0.0; 3];
                }
                let cell = lookup(wi, wo);
                if !t.is_valid(cell) {
                    return [0.0; 3];
                }
                [0, 1, 2].map(|c| t.value(c, cell) as f64)
            })
        }
        // An RGL file is evaluated exactly at the pixel's directions (SPEC 9), with its
        // table's convention: a negative measured value counts as 0.
        MaterialData::Rgl(t) => {
            let t = t.clone();
            Box::new(move |wi, wo| t.eval_dirs(wi, wo).map(|v| v.max(0.0)))
        }
        MaterialData::Neural(n) => {
            let n = n.clone();
            Box::new(move |wi, wo| n.eval_dirs(wi, wo))
        }
    }
}

/// A fitted combination: `coefficients[0]` is the Lambertian term, then one per basis
/// material (RGB each).
pub fn combination_brdf(coll: &Collection, basis: &[usize], coefficients: &[[f64; 3]]) -> BrdfFn {
    let parts: Vec<(BrdfFn, [f64; 3])> = basis
        .iter()
        .zip(&coefficients[1..])
        .map(|(&b, &a)| (material_brdf(&coll.materials()[b].data), a))
        .collect();
    let a0 = coefficients[0];
    Box::new(move |wi, wo| {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return [0.0; 3];
        }
        let mut v = [0, 1, 2].map(|c| a0[c] * std::f64::consts::FRAC_1_PI);
        for (f, a) in &parts {
            let x = f(wi, wo);
            for c in 0..3 {
                v[c] += a[c] * x[c];
            }
        }
        v
    })
}
