//! The isotropic Ashikhmin-Shirley model as fitted by Ngan et al. 2005.
//!
//! Per colour channel c, directions in the local frame (N = +z):
//!
//! ```text
//! f_c(wi, wo) = d_c / pi + s_c * rho_s(wi, wo; F0, n)
//! rho_s       = (n + 1) (N.H)^n F(F0, wo.H) / (8 pi (wo.H) max(N.wi, N.wo))
//! F(F0, x)    = F0 + (1 - F0) (1 - x)^5,        H = normalize(wi + wo)
//! ```
//!
//! | parameter | meaning                                 | range        |
//! |-----------|-----------------------------------------|--------------|
//! | `d`       | diffuse albedo, RGB                     | `>= 0`       |
//! | `s`       | specular scale, RGB                     | `>= 0`       |
//! | `f0`      | Schlick normal-incidence reflectance    | `[0, 1]`     |
//! | `n`       | isotropic Phong exponent                | `> 0`        |
//!
//! Ashikhmin & Shirley, "An Anisotropic Phong BRDF Model", JGT 5(2), 2000,
//! doi:10.1080/10867651.2000.10487522; Ngan, Durand & Matusik, "Experimental Analysis of
//! BRDF Models", EGSR 2005, doi:10.2312/EGWR/EGSR05/117-126.
//!
//! `(N.H)^n` is evaluated as `exp(n log1p(-2 sin^2(theta_h / 2)))`, which keeps its
//! relative error near 1e-15 in f64 for `n` up to 1e5 and more (a naive `pow(cos, n)`
//! in f32 rounds `cos` to 1 near the peak).

use super::fresnel::schlick;

/// Ashikhmin-Shirley parameters of one material (f64).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AshikhminShirley {
    /// Diffuse albedo (R, G, B).
    pub d: [f64; 3],
    /// Specular scale (R, G, B).
    pub s: [f64; 3],
    /// Schlick normal-incidence reflectance, shared by R, G, B.
    pub f0: f64,
    /// Isotropic exponent.
    pub n: f64,
}

/// `(N.H)^n` from `theta_h` (radians) with small relative error for huge `n`.
#[inline]
pub(crate) fn cos_pow(theta_h: f64, n: f64) -> f64 {
    let s = (0.5 * theta_h).sin();
    (n * (-2.0 * s * s).ln_1p()).exp()
}

/// The colour-free specular lobe `rho_s` from the half/difference angles.
///
/// `cos_d = wo.H = wi.H`, `max_cos = max(N.wi, N.wo)`. Returns 0 when `max_cos <= 0` or
/// `cos_d <= 0` (below the horizon).
#[inline]
pub fn rho_s_angles(theta_h: f64, cos_d: f64, max_cos: f64, f0: f64, n: f64) -> f64 {
    if max_cos <= 0.0 || cos_d <= 0.0 {
        return 0.0;
    }
    (n + 1.0) * cos_pow(theta_h, n) * schlick(f0, cos_d)
        / (8.0 * std::f64::consts::PI * cos_d * max_cos)
}

fn normalize(v: [f64; 3]) -> Option<[f64; 3]> {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    (l > 0.0).then(|| [v[0] / l, v[1] / l, v[2] / l])
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl AshikhminShirley {
    /// `rho_s(wi, wo)` for unit directions in the local frame. 0 below the horizon.
    pub fn rho_s(&self, wi: [f64; 3], wo: [f64; 3]) -> f64 {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return 0.0;
        }
        let Some(h) = normalize([wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]]) else {
            return 0.0;
        };
        let cos_d = dot(wo, h).clamp(-1.0, 1.0);
        // theta_h from the half vector: atan2 keeps accuracy near the pole.
        let theta_h = (h[0].hypot(h[1])).atan2(h[2]);
        rho_s_angles(theta_h, cos_d, wi[2].max(wo[2]), self.f0, self.n)
    }

    /// The full RGB BRDF `f_c(wi, wo)`. 0 below the horizon.
    pub fn eval(&self, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return [0.0; 3];
        }
        let rs = self.rho_s(wi, wo);
        let inv_pi = std::f64::consts::FRAC_1_PI;
        [
            self.d[0] * inv_pi + self.s[0] * rs,
            self.d[1] * inv_pi + self.s[1] * rs,
            self.d[2] * inv_pi + self.s[2] * rs,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn dir(theta: f64, phi: f64) -> [f64; 3] {
        [
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        ]
    }

    #[test]
    fn hand_computed_normal_incidence() {
        // wi = wo = N: H = N, N.H = 1, wo.H = 1, F = F0, max = 1.
        let m = AshikhminShirley {
            d: [0.5, 0.25, 0.0],
            s: [1.0, 2.0, 0.0],
            f0: 0.04,
            n: 10.0,
        };
        let rs = m.rho_s([0.0, 0.0, 1.0], [0.0, 0.0, 1.0]);
        let expect = 11.0 * 0.04 / (8.0 * PI);
        assert!((rs - expect).abs() < 1e-15 * expect, "{rs} vs {expect}");
        let f = m.eval([0.0, 0.0, 1.0], [0.0, 0.0, 1.0]);
        assert!((f[0] - (0.5 / PI + expect)).abs() < 1e-15);
        assert!((f[1] - (0.25 / PI + 2.0 * expect)).abs() < 1e-15);
    }

    #[test]
    fn hand_computed_off_specular() {
        // wi at 60 deg, wo at 0 deg in one plane: H at 30 deg, wo.H = cos 30.
        let m = AshikhminShirley {
            d: [0.0; 3],
            s: [1.0; 3],
            f0: 0.5,
            n: 2.0,
        };
        let wi = dir(PI / 3.0, 0.0);
        let wo = [0.0, 0.0, 1.0];
        let c = (PI / 6.0).cos();
        let f = 0.5 + 0.5 * (1.0 - c).powi(5);
        let expect = 3.0 * c * c * f / (8.0 * PI * c * 1.0);
        let got = m.rho_s(wi, wo);
        assert!((got - expect).abs() < 1e-14 * expect, "{got} vs {expect}");
    }

    #[test]
    fn non_negative_and_reciprocal() {
        let mats = [
            AshikhminShirley {
                d: [0.1, 0.2, 0.3],
                s: [0.5, 0.4, 0.3],
                f0: 0.9,
                n: 1.0,
            },
            AshikhminShirley {
                d: [0.0; 3],
                s: [1.0; 3],
                f0: 0.04,
                n: 300.0,
            },
            AshikhminShirley {
                d: [0.0; 3],
                s: [1.0; 3],
                f0: 0.0,
                n: 80_000.0,
            },
        ];
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12345);
        let mut rnd = || rng.random::<f64>();
        for m in &mats {
            for _ in 0..2000 {
                let wi = dir(rnd() * PI / 2.0, rnd() * 2.0 * PI);
                let wo = dir(rnd() * PI / 2.0, rnd() * 2.0 * PI);
                let a = m.eval(wi, wo);
                let b = m.eval(wo, wi);
                for c in 0..3 {
                    assert!(a[c] >= 0.0 && a[c].is_finite());
                    // n amplifies the rounding of theta_h: 1e-9 relative.
                    assert!(
                        (a[c] - b[c]).abs() <= 1e-9 * a[c].abs().max(1e-300),
                        "{a:?} {b:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn cos_pow_stable_for_huge_exponents() {
        // Compare with a high-precision expansion: ln cos t = -t^2/2 - t^4/12 - t^6/45 - ...
        for &n in &[1.0, 80.0, 5_000.0, 80_000.0] {
            for &t in &[1e-6f64, 1e-4, 1e-3, 3e-3, 1e-2] {
                let lc: f64 =
                    -t * t / 2.0 - t.powi(4) / 12.0 - t.powi(6) / 45.0 - 17.0 * t.powi(8) / 2520.0;
                let want = (n * lc).exp();
                let got = cos_pow(t, n);
                if want > 1e-300 {
                    assert!(
                        (got - want).abs() <= 1e-12 * want,
                        "n={n} t={t}: {got} vs {want}"
                    );
                }
            }
        }
        // The peak value is exactly 1.
        assert_eq!(cos_pow(0.0, 80_000.0), 1.0);
    }

    #[test]
    fn below_horizon_is_zero() {
        let m = AshikhminShirley {
            d: [1.0; 3],
            s: [1.0; 3],
            f0: 0.5,
            n: 10.0,
        };
        assert_eq!(m.eval([0.0, 0.6, -0.8], [0.0, 0.0, 1.0]), [0.0; 3]);
    }
}
