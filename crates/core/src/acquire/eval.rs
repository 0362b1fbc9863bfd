//! A material at an arbitrary direction pair (SPEC 9, "At an arbitrary direction pair").

use super::AcquireError;
use crate::collection::Material;
#[cfg(any(doc, test))]
use crate::collection::MaterialData;
use crate::merl::lookup;

/// Checks that `d` is a finite direction above the horizon and returns it normalised.
pub(crate) fn unit_above(what: &'static str, d: [f64; 3]) -> Result<[f64; 3], AcquireError> {
    let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if !l.is_finite() || l <= 0.0 {
        return Err(AcquireError::BadDirection { what, dir: d });
    }
    let u = [d[0] / l, d[1] / l, d[2] / l];
    if u[2] <= 0.0 {
        return Err(AcquireError::BelowHorizon { what, dir: d });
    }
    Ok(u)
}

/// The RGB reflectance of `m` at the direction pair `(wi, wo)` (local frame, z = normal;
/// normalised here), by the one evaluation of every kind
/// ([`MaterialData::eval_dirs`]): analytic and neural materials exactly, RGL files by their
/// own evaluation, MERL tables by the cell the MERL lookup returns
/// ([`crate::merl::lookup`]); a table with no measurement in that cell is an error,
/// as is a direction below the horizon.
pub fn material_at(m: &Material, wi: [f64; 3], wo: [f64; 3]) -> Result<[f64; 3], AcquireError> {
    let wi = unit_above("incoming", wi)?;
    let wo = unit_above("outgoing", wo)?;
    m.data
        .eval_dirs(wi, wo)
        .ok_or_else(|| AcquireError::InvalidCell {
            material: m.name.clone(),
            cell: lookup(wi, wo),
        })
}

/// Direction of polar angle `theta` and azimuth `phi` (radians).
pub fn direction(theta: f64, phi: f64) -> [f64; 3] {
    [
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    ]
}

/// `(theta, phi)` in degrees of a unit direction (phi in `(-180, 180]`).
pub(crate) fn angles_deg(d: [f64; 3]) -> (f64, f64) {
    let theta = d[2].clamp(-1.0, 1.0).acos().to_degrees();
    let phi = d[1].atan2(d[0]).to_degrees();
    (theta, phi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::AshikhminShirley;
    use crate::merl::MerlTable;
    use crate::merl::{cell_directions, flat, N_CELLS};
    use std::sync::Arc;

    fn analytic() -> Material {
        Material {
            name: "a".into(),
            data: MaterialData::Analytic(AshikhminShirley {
                d: [0.5, 0.25, 0.1],
                s: [1.0, 2.0, 0.5],
                f0: 0.04,
                n: 10.0,
            }),
            origin: "test".into(),
        }
    }

    /// At normal incidence and exitance (H = N): d / pi + s (n + 1) F0 / (8 pi).
    #[test]
    fn analytic_at_normal_incidence_is_hand_computed() {
        let v = material_at(&analytic(), [0.0, 0.0, 1.0], [0.0, 0.0, 2.0]).unwrap();
        let pi = std::f64::consts::PI;
        for (c, (d, s)) in [(0.5, 1.0), (0.25, 2.0), (0.1, 0.5)].iter().enumerate() {
            let want = d / pi + s * 11.0 * 0.04 / (8.0 * pi);
            assert!(
                (v[c] - want).abs() < 1e-15 * want.max(1.0),
                "{c}: {} vs {want}",
                v[c]
            );
        }
    }

    #[test]
    fn below_horizon_and_zero_directions_are_errors() {
        let e = material_at(&analytic(), [0.0, 0.0, 1.0], [1.0, 0.0, -0.1]).unwrap_err();
        assert!(e.to_string().contains("outgoing"), "{e}");
        let e = material_at(&analytic(), [0.0; 3], [0.0, 0.0, 1.0]).unwrap_err();
        assert!(e.to_string().contains("incoming"), "{e}");
    }

    /// A table is read at the cell of the lookup; an invalid cell is an error.
    #[test]
    fn table_is_read_at_the_lookup_cell() {
        let mut rgb = vec![-1f32; 3 * N_CELLS];
        let cell = flat(20, 30, 40);
        for c in 0..3 {
            rgb[c * N_CELLS + cell] = 0.1 * (c + 1) as f32;
        }
        let m = Material {
            name: "t".into(),
            data: MaterialData::Measured(Arc::new(MerlTable { rgb })),
            origin: "test".into(),
        };
        let (wi, wo) = cell_directions(cell);
        let v = material_at(&m, wi, wo).unwrap();
        assert_eq!(v, [0.1f32 as f64, 0.2f32 as f64, 0.3f32 as f64]);
        let (wi, wo) = cell_directions(flat(20, 30, 41));
        let e = material_at(&m, wi, wo).unwrap_err().to_string();
        assert!(e.contains("no measurement in MERL cell"), "{e}");
    }
}
