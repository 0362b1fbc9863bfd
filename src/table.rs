//! A material on the MERL grid as `brdf-basis tabulate` writes it ([`tabulate`]), and
//! what a material is made of ([`material_kind`]): the command line's `tabulate` as
//! functions, for a host in another language (the Python bindings).

use crate::backend::Backend;
use crate::collection::Collection;
use crate::errors::{Error, NotFiniteError, Result};

/// Material `name` of `coll` on the full MERL grid, as `brdf-basis tabulate` writes it:
/// `rgb[c * N_CELLS + cell]` (channel-major, [`crate::merl::flat`] cell order),
/// invalid cells `-1`. Analytic materials are tabulated on `backend`; measured ones are
/// their table.
///
/// # Errors
/// [`Error::Collection`] for an unknown name, [`Error::Backend`] for a failed pass,
/// [`Error::NotFinite`] when the parameters overflow f32 in some valid cell.
pub fn tabulate(backend: &dyn Backend, coll: &Collection, name: &str) -> Result<Vec<f32>> {
    use crate::collection::MaterialData;
    use crate::merl::{cell_info, N_CELLS};
    let m = coll.get(name)?;
    match &m.data {
        MaterialData::Measured(t) => Ok(t.rgb.clone()),
        MaterialData::Rgl(r) => Ok(r.table().rgb.clone()),
        MaterialData::Analytic(_) | MaterialData::Neural(_) => {
            let lobes: Vec<crate::backend::Lobe> = (0..3)
                .map(|c| crate::fit::channel_lobe(&m.data, c))
                .collect();
            let cells: Vec<u32> = (0..N_CELLS as u32).collect();
            let mut rgb = backend.tabulate(&lobes, &cells)?;
            let mut overflow = 0usize;
            for cell in 0..N_CELLS {
                if !cell_info(cell).valid {
                    for c in 0..3 {
                        rgb[c * N_CELLS + cell] = -1.0;
                    }
                } else if (0..3).any(|c| !rgb[c * N_CELLS + cell].is_finite()) {
                    overflow += 1;
                }
            }
            if overflow > 0 {
                return Err(Error::NotFinite(Box::new(NotFiniteError {
                    material: crate::error::short_name(&m.name).to_string(),
                    origin: m.origin.clone(),
                    cells: overflow,
                    cause: match m.analytic() {
                        Some(a) => format!("parameters too large: n = {}, s = {:?}", a.n, a.s),
                        None => "the network's output overflows f32".into(),
                    },
                })));
            }
            Ok(rgb)
        }
    }
}

/// What a material is made of, in one word: `analytic`, `measured` (a MERL table),
/// `neural` (an NBRDF) or `rgl` (an RGL-EPFL `.bsdf` file).
pub fn material_kind(m: &crate::collection::Material) -> &'static str {
    use crate::collection::MaterialData;
    match m.data {
        MaterialData::Analytic(_) => "analytic",
        MaterialData::Measured(_) => "measured",
        MaterialData::Neural(_) => "neural",
        MaterialData::Rgl(_) => "rgl",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::cpu::CpuBackend;

    /// `tabulate` is the back-end's table of the three channel lobes, -1 outside the
    /// valid cells, within f32 rounding of the f64 model; NaN-free; parameters that
    /// overflow f32 are refused with the material's name.
    #[test]
    fn tabulate_is_the_model_on_valid_cells_and_minus_one_elsewhere() {
        use crate::merl::{cell_directions, cell_info, N_CELLS};
        let cpu = CpuBackend::new();
        let coll = Collection::embedded_default();
        let name = "polished-gold";
        let rgb = tabulate(&cpu, &coll, name).unwrap();
        assert_eq!(rgb.len(), 3 * N_CELLS);
        let a = *coll.get(name).unwrap().analytic().unwrap();
        let mut checked = 0;
        for cell in (0..N_CELLS).step_by(997) {
            if !cell_info(cell).valid {
                assert!((0..3).all(|c| rgb[c * N_CELLS + cell] == -1.0));
                continue;
            }
            let (wi, wo) = cell_directions(cell);
            let f = a.eval(wi, wo);
            for c in 0..3 {
                let v = f64::from(rgb[c * N_CELLS + cell]);
                assert!(
                    (v - f[c]).abs() <= 1e-4 * f[c].abs().max(1e-3),
                    "{cell} {c}: {v} vs {}",
                    f[c]
                );
            }
            checked += 1;
        }
        assert!(checked > 500, "{checked}");
        let e = tabulate(&cpu, &coll, "polished-golf").unwrap_err();
        assert!(matches!(e, Error::Collection(_)), "{e:?}");
        let big = crate::collection::parse_csv(
            b"material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\nhot,0,0,0,3e38,3e38,3e38,1,1\n",
            std::path::Path::new("big.csv"),
        )
        .unwrap();
        let e = tabulate(&cpu, &big, "hot").unwrap_err();
        assert!(matches!(e, Error::NotFinite(_)), "{e:?}");
        assert!(e.to_string().contains("material `hot`"), "{e}");
    }
}
