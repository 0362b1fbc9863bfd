//! BRDF closures for rendering: an analytic material, a measured one (MERL lookup, SPEC
//! 7), a neural one (its network at the direction pair, SPEC 9), or a fitted combination `a0 / pi + sum_k a_k f_k`.

use crate::collection::{Collection, MaterialData};
use crate::eval::render::{render_sphere_indexed, Image, RenderError, RenderParams};
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

/// Every material's BRDF at the direction pairs of one render's lit pixels (one light, one
/// view: the renders of the fits and reconstructions of a collection share them), so that
/// the render of a combination costs a multiply-add per basis material and pixel, not an
/// evaluation of every basis material (a neural network each) per pixel. The values are
/// [`material_brdf`]'s at the same pairs and [`Self::combination`] sums them as
/// [`combination_brdf`] does: the renders are the same to the bit.
pub struct PixelBrdfs {
    /// Direction pair (bits of `wi`, `wo`) to its row of `values`.
    index: std::collections::HashMap<[u64; 6], usize>,
    /// Per pair (in the pairs' bit order), every material's RGB.
    values: Vec<Vec<[f64; 3]>>,
    /// Every material's BRDF (for pairs not in the table).
    brdfs: Vec<BrdfFn>,
    /// The render the table was made for.
    rp: RenderParams,
    /// Per pixel of that render (`row * size + col`), its row of `values` (`u32::MAX`: none).
    pixel_rows: Vec<u32>,
}

fn pair_key(wi: [f64; 3], wo: [f64; 3]) -> [u64; 6] {
    [wi[0], wi[1], wi[2], wo[0], wo[1], wo[2]].map(f64::to_bits)
}

impl PixelBrdfs {
    /// The table of `coll`'s materials at the lit pixels of renders with `rp`.
    pub fn new(coll: &Collection, rp: &RenderParams) -> Result<Self, RenderError> {
        use rayon::prelude::*;
        let pairs = std::sync::Mutex::new(Vec::new());
        render_sphere_indexed(rp, &|px, wi, wo| {
            if wi[2] > 0.0 && wo[2] > 0.0 {
                pairs
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .push((wi, wo, px));
            }
            [0.0; 3]
        })?;
        let mut pairs = pairs.into_inner().unwrap_or_else(|p| p.into_inner());
        // Rayon's order of the pixels is not fixed; the table's is.
        pairs.sort_by_key(|a| (pair_key(a.0, a.1), a.2));
        let mut index = std::collections::HashMap::new();
        let mut unique = Vec::new();
        let mut pixel_rows = vec![u32::MAX; rp.size as usize * rp.size as usize];
        for (wi, wo, px) in pairs {
            let row = *index.entry(pair_key(wi, wo)).or_insert_with(|| {
                unique.push((wi, wo));
                unique.len() - 1
            });
            pixel_rows[px] = row as u32;
        }
        let brdfs: Vec<BrdfFn> = coll
            .materials()
            .iter()
            .map(|m| material_brdf(&m.data))
            .collect();
        let values = unique
            .par_iter()
            .map(|&(wi, wo)| brdfs.iter().map(|f| f(wi, wo)).collect())
            .collect();
        Ok(Self {
            index,
            values,
            brdfs,
            rp: *rp,
            pixel_rows,
        })
    }

    /// The row of the table of pixel `px` of the table's render.
    fn pixel_row(&self, px: usize) -> Option<&Vec<[f64; 3]>> {
        match self.pixel_rows.get(px) {
            Some(&r) if r != u32::MAX => Some(&self.values[r as usize]),
            _ => None,
        }
    }

    /// The render (with the parameters the table was made for) of material `m`: the image
    /// `render_sphere(rp, &self.material(m))` gives, each pixel's value found by its index.
    pub fn render_material(&self, m: usize) -> Result<Image, RenderError> {
        render_sphere_indexed(&self.rp, &|px, wi, wo| match self.pixel_row(px) {
            Some(r) => r[m],
            None => self.brdfs[m](wi, wo),
        })
    }

    /// The render (with the parameters the table was made for) of a fitted combination:
    /// the image `render_sphere(rp, &self.combination(basis, coefficients))` gives, each
    /// pixel's values found by its index.
    pub fn render_combination(
        &self,
        basis: &[usize],
        coefficients: &[[f64; 3]],
    ) -> Result<Image, RenderError> {
        render_sphere_indexed(&self.rp, &|px, wi, wo| {
            self.combine(self.pixel_row(px), basis, coefficients, wi, wo)
        })
    }

    /// `a0 / pi + sum_k a_k f_k(wi, wo)`, the values `f_k` from `row` when given.
    #[inline]
    fn combine(
        &self,
        row: Option<&Vec<[f64; 3]>>,
        basis: &[usize],
        coefficients: &[[f64; 3]],
        wi: [f64; 3],
        wo: [f64; 3],
    ) -> [f64; 3] {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return [0.0; 3];
        }
        let mut v = [0, 1, 2].map(|c| coefficients[0][c] * std::f64::consts::FRAC_1_PI);
        for (&b, a) in basis.iter().zip(&coefficients[1..]) {
            let x = match row {
                Some(r) => r[b],
                None => self.brdfs[b](wi, wo),
            };
            for c in 0..3 {
                v[c] += a[c] * x[c];
            }
        }
        v
    }

    /// Material `m`'s [`material_brdf`], from the table.
    pub fn material(&self, m: usize) -> impl Fn([f64; 3], [f64; 3]) -> [f64; 3] + Sync + '_ {
        move |wi, wo| match self.index.get(&pair_key(wi, wo)) {
            Some(&r) => self.values[r][m],
            None => self.brdfs[m](wi, wo),
        }
    }

    /// `combination_brdf(coll, basis, coefficients)`, from the table.
    pub fn combination<'s>(
        &'s self,
        basis: &'s [usize],
        coefficients: &'s [[f64; 3]],
    ) -> impl Fn([f64; 3], [f64; 3]) -> [f64; 3] + Sync + 's {
        move |wi, wo| {
            if wi[2] <= 0.0 || wo[2] <= 0.0 {
                return [0.0; 3];
            }
            let row = self.index.get(&pair_key(wi, wo)).map(|&r| &self.values[r]);
            self.combine(row, basis, coefficients, wi, wo)
        }
    }
}
