//! BRDF closures for rendering: an analytic material, a measured one (MERL lookup, SPEC
//! 7), a neural one (its network at the direction pair, SPEC 9), or a fitted combination `a0 / pi + sum_k a_k f_k`.

use crate::collection::{Collection, MaterialData};
use crate::eval::render::{render_sphere_indexed, Image, RenderError, RenderParams};
use crate::merl::lookup;

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
    /// Direction pair (bits of `wi`, `wo`) to its row (the pairs in their bits' order).
    index: std::collections::HashMap<[u64; 6], usize>,
    /// Per material, its RGB at every row: a combination's render streams the basis
    /// materials' columns (a multiply-add per row, in the basis order of
    /// [`combination_brdf`]'s sum).
    columns: Vec<Vec<[f64; 3]>>,
    /// Every material's BRDF (for pairs not in the table).
    brdfs: Vec<BrdfFn>,
    /// The render the table was made for.
    rp: RenderParams,
    /// The render's lit pixels that have a row, row-major: index, row and
    /// `cos theta_i` (the other pixels of any render from the table are black: a lit pixel
    /// without a row has a direction below its horizon).
    lit: Vec<(u32, u32, f64)>,
    /// Per row, the MERL cell of its direction pair ([`lookup`]).
    cells: Vec<u32>,
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
        let cells = unique
            .par_iter()
            .map(|&(wi, wo)| lookup(wi, wo) as u32)
            .collect();
        // A network's column from the inputs of every pair, computed once for all
        // networks, four pairs per vector (`eval_dirs`'s values, to the bit: every pair
        // here is above both horizons).
        let inputs: Vec<[f64; 6]> = if coll
            .materials()
            .iter()
            .any(|m| matches!(m.data, MaterialData::Neural(_)))
        {
            unique
                .par_iter()
                .map(|&(wi, wo)| {
                    let (th, td, pd) = crate::merl::half_diff(wi, wo);
                    crate::brdf::Nbrdf::inputs_f64(th, td, pd)
                })
                .collect()
        } else {
            Vec::new()
        };
        let columns = coll
            .materials()
            .iter()
            .zip(&brdfs)
            .map(|(m, f)| match &m.data {
                MaterialData::Neural(n) => {
                    let mut col = vec![[0f64; 3]; unique.len()];
                    col.par_chunks_mut(1024)
                        .zip(inputs.par_chunks(1024))
                        .for_each(|(o, x)| n.eval_inputs_f64_batch(x, o));
                    col
                }
                _ => unique.par_iter().map(|&(wi, wo)| f(wi, wo)).collect(),
            })
            .collect();
        let lit = crate::eval::render::lit_pixels(rp)?
            .into_iter()
            .filter(|&(px, _)| pixel_rows[px] != u32::MAX)
            .map(|(px, cos_i)| (px as u32, pixel_rows[px], cos_i))
            .collect();
        Ok(Self {
            index,
            columns,
            brdfs,
            rp: *rp,
            lit,
            cells,
        })
    }

    /// The render (with the parameters the table was made for) of material `m`: the image
    /// `render_sphere(rp, &self.material(m))` gives, to the bit.
    pub fn render_material(&self, m: usize) -> Result<Image, RenderError> {
        Ok(self.render_rows(|r| self.columns[m][r]))
    }

    /// The render (with the parameters the table was made for) of a fitted combination:
    /// the image `render_sphere(rp, &self.combination(basis, coefficients))` gives, to the
    /// bit (the same sum in the same order, times the same `cos theta_i`), without the
    /// render's geometry or a lookup per pixel.
    pub fn render_combination(
        &self,
        basis: &[usize],
        coefficients: &[[f64; 3]],
    ) -> Result<Image, RenderError> {
        if coefficients.len() != basis.len() + 1 {
            return Err(RenderError::InvalidParam {
                name: "coefficients",
                value: format!("{} for a basis of {}", coefficients.len(), basis.len()),
                expected: "one per basis material, the Lambertian term's first",
            });
        }
        if let Some(&b) = basis.iter().find(|&&b| b >= self.brdfs.len()) {
            return Err(RenderError::InvalidParam {
                name: "basis material",
                value: b.to_string(),
                expected: "an index of the table's materials",
            });
        }
        let a0 = [0, 1, 2].map(|c| coefficients[0][c] * std::f64::consts::FRAC_1_PI);
        // Every row's sum, one basis material at a time: per row the same terms in the
        // same order as `combination_brdf`'s (the same bits).
        let mut sums = vec![a0; self.cells.len()];
        for (&b, a) in basis.iter().zip(&coefficients[1..]) {
            for (v, x) in sums.iter_mut().zip(&self.columns[b]) {
                for c in 0..3 {
                    v[c] += a[c] * x[c];
                }
            }
        }
        Ok(self.render_rows(|r| sums[r]))
    }

    /// The render (with the parameters the table was made for) of a BRDF that is constant
    /// on each MERL cell (a tabulated reconstruction), `f(cell)` its value: the image
    /// `render_sphere` gives of `|wi, wo| if wi[2] <= 0 || wo[2] <= 0 { 0 } else {
    /// f(lookup(wi, wo)) }`, to the bit, with one lookup per distinct pair of the render.
    pub fn render_cells(&self, f: impl Fn(usize) -> [f64; 3]) -> Image {
        let mut rows = self.lit.iter().map(|&(_, row, _)| row).collect::<Vec<_>>();
        rows.sort_unstable();
        rows.dedup();
        // Each row's value once (rows shared by pixels are rare but possible).
        let mut at = vec![[0.0; 3]; self.cells.len()];
        for r in rows {
            at[r as usize] = f(self.cells[r as usize] as usize);
        }
        self.render_rows(|r| at[r])
    }

    /// The render whose lit pixels with a row get `value(row) * cos theta_i`, rounded to
    /// f32 (the others black), as `render_sphere` writes them.
    fn render_rows(&self, value: impl Fn(usize) -> [f64; 3]) -> Image {
        let size = self.rp.size;
        let mut image = Image::black(size, size);
        for &(px, row, cos_i) in &self.lit {
            let f = value(row as usize);
            let o = 3 * px as usize;
            for (d, v) in image.data[o..o + 3].iter_mut().zip(f) {
                *d = (v * cos_i) as f32;
            }
        }
        image
    }

    /// `a0 / pi + sum_k a_k f_k(wi, wo)`, the values `f_k` from the table's `row` when
    /// given.
    #[inline]
    fn combine(
        &self,
        row: Option<usize>,
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
                Some(r) => self.columns[b][r],
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
            Some(&r) => self.columns[m][r],
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
            let row = self.index.get(&pair_key(wi, wo)).copied();
            self.combine(row, basis, coefficients, wi, wo)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collection::Material;
    use crate::eval::render::render_sphere;
    use crate::merl::MerlTable;
    use crate::merl::N_CELLS;
    use std::path::Path;
    use std::sync::Arc;

    /// The embedded default collection and a measured table with invalid cells (a pattern
    /// of -1 cells: lit pixels without a measurement render black).
    fn mixed() -> Collection {
        let mut coll = Collection::embedded_default();
        let rgb: Vec<f32> = (0..3 * N_CELLS)
            .map(|i| {
                if i % 7 == 3 {
                    -1.0
                } else {
                    0.01 + (i % 1000) as f32 * 1e-3
                }
            })
            .collect();
        let m = Material {
            name: "measured".into(),
            data: MaterialData::Measured(Arc::new(MerlTable { rgb })),
            origin: "test".into(),
        };
        coll.push(m, Path::new("test"), 1).unwrap();
        coll
    }

    /// The table's renders are `render_sphere`'s of the closures to the bit, at odd and
    /// even sizes and under the four lights of SPEC 11 (a grazing one included).
    #[test]
    fn table_renders_are_render_sphere_bit_for_bit() {
        let coll = mixed();
        let n = coll.len();
        let basis = [n - 1, 0, 5, 9];
        let coef = [
            [0.3, 0.2, 0.1],
            [0.7, 0.0, 0.2],
            [0.5, 0.4, 0.3],
            [0.0, 1.2, 0.7],
            [2.0, 0.1, 0.0],
        ];
        for size in [17u32, 40] {
            for (th, ph) in crate::eval::appearance::LIGHTS {
                let rp = RenderParams::default().with_size(size).with_light(th, ph);
                let table = PixelBrdfs::new(&coll, &rp).unwrap();
                let direct = render_sphere(&rp, &combination_brdf(&coll, &basis, &coef)).unwrap();
                let fast = table.render_combination(&basis, &coef).unwrap();
                assert_eq!(fast.mask, direct.mask);
                let bits = |i: &Image| i.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(&fast),
                    bits(&direct),
                    "size {size}, light ({th}, {ph})"
                );
                for m in [0, n - 1] {
                    let direct =
                        render_sphere(&rp, &material_brdf(&coll.materials()[m].data)).unwrap();
                    assert_eq!(bits(&table.render_material(m).unwrap()), bits(&direct));
                }
            }
        }
    }

    /// A BRDF constant per MERL cell renders from the table's cells as `render_sphere`
    /// renders it through the lookup, to the bit (cells of value 0 included).
    #[test]
    fn cell_renders_are_render_sphere_bit_for_bit() {
        let coll = Collection::embedded_default();
        let f = |cell: usize| {
            if cell.is_multiple_of(5) {
                [0.0; 3]
            } else {
                [0, 1, 2].map(|c| ((cell * (c + 3)) % 977) as f64 * 1e-3 + 0.01)
            }
        };
        for size in [17u32, 64] {
            for (th, ph) in crate::eval::appearance::LIGHTS {
                let rp = RenderParams::default().with_size(size).with_light(th, ph);
                let table = PixelBrdfs::new(&coll, &rp).unwrap();
                let direct = render_sphere(&rp, &|wi: [f64; 3], wo: [f64; 3]| {
                    if wi[2] <= 0.0 || wo[2] <= 0.0 {
                        [0.0; 3]
                    } else {
                        f(lookup(wi, wo))
                    }
                })
                .unwrap();
                let fast = table.render_cells(f);
                let bits = |i: &Image| i.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(fast.mask, direct.mask);
                assert_eq!(
                    bits(&fast),
                    bits(&direct),
                    "size {size}, light ({th}, {ph})"
                );
            }
        }
    }

    /// A coefficient count that is not the basis' plus one, or a basis index beyond the
    /// table, is an error, not a truncated sum or a panic.
    #[test]
    fn mismatched_coefficients_are_refused() {
        let coll = Collection::embedded_default();
        let table = PixelBrdfs::new(&coll, &RenderParams::default().with_size(8)).unwrap();
        let e = table
            .render_combination(&[0, 1], &[[0.1; 3]; 2])
            .unwrap_err();
        assert!(e.to_string().contains("coefficients"), "{e}");
        let e = table
            .render_combination(&[coll.len()], &[[0.1; 3]; 2])
            .unwrap_err();
        assert!(e.to_string().contains("basis material"), "{e}");
    }
}
