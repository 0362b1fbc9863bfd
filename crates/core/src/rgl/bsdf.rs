//! Evaluation of an isotropic RGB RGL-EPFL measured BSDF (Dupuy & Jakob, "An Adaptive
//! Parameterization for Efficient Material Acquisition and Rendering", ACM TOG 37(6),
//! 2018, doi:10.1145/3272127.3275059), as Mitsuba 3's `measured` BSDF defines it.
//!
//! The paper stores the BRDF not on an angle grid but in the sample space of its own
//! importance sampler: for an incident direction `wi` (elevation `theta_i`), the visible
//! normal distribution `D_wi(m)` tabulated on the microfacet angles
//! `(u_theta, u_phi) = (sqrt(2 theta_m / pi), (phi_m - phi_i + pi) / 2 pi)` (`vndf`,
//! 128 x 128 per `theta_i`) is turned into a bijection of the unit square by the inverse
//! of its continuous marginal/conditional sampling (rows = `u_phi`, columns =
//! `u_theta`, bilinear density). A direction pair is evaluated by
//!
//! 1. `m = normalize(wi + wo)`, its unit coordinates `u_m` as above;
//! 2. `s = T^-1(u_m; theta_i)`: the inverse sampling map of the VNDF (CDFs of the
//!    bilinear density, linearly interpolated between the two `theta_i` slices around
//!    `theta_i`);
//! 3. `v_c = rgb_c(s; theta_i)`: the RGB table (`N x N` per `theta_i` and channel),
//!    bilinear in `s`, linear in `theta_i`;
//! 4. with the `jacobian` flag: `f cos theta_o = v_c D(m) / (4 sigma(wi))`, with `D`
//!    (`ndf`) and the projected area `sigma` tabulated on `sqrt(2 theta / pi)`. The
//!    stored values are reflectance over the sampler's density `D(m) / (4 sigma(wi))`
//!    of `wo`, so the product is `f cos theta_o`.
//!
//! [`RglBsdf::eval`] returns `f` itself (divided by `cos theta_o`): reflectance per
//! steradian, RGB, in the units of a MERL table times its channel scales (SPEC 2).
//! Everything is evaluated in f64 from the file's f32 tables.

use super::tensor::{Dtype, Field, TensorFile};
use crate::error::RglError;
use std::f64::consts::{FRAC_2_PI, PI};
use std::path::Path;

/// A regular grid of values on the unit square, bilinearly interpolated (`w` columns
/// along x, `h` rows along y, row-major), possibly many slices of it.
#[derive(Clone, Debug)]
struct Grid {
    w: usize,
    h: usize,
    data: Vec<f64>,
}

/// Bilinear-patch position of a unit coordinate on `n` samples: `(index, fraction)`.
#[inline]
fn patch(u: f64, n: usize) -> (usize, f64) {
    let x = u.clamp(0.0, 1.0) * (n - 1) as f64;
    let i = (x.floor() as usize).min(n - 2);
    (i, x - i as f64)
}

#[inline]
fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

impl Grid {
    /// Bilinear interpolation of slice `slice` at `(x, y)` in the unit square.
    fn eval(&self, slice: usize, x: f64, y: f64) -> f64 {
        let (i, fx) = patch(x, self.w);
        let (j, fy) = patch(y, self.h);
        let d = &self.data[slice * self.w * self.h..];
        let at = |r: usize, c: usize| d[r * self.w + c];
        let top = lerp(at(j, i), at(j, i + 1), fx);
        let bottom = lerp(at(j + 1, i), at(j + 1, i + 1), fx);
        lerp(top, bottom, fy)
    }
}

/// The continuous marginal/conditional warp of a bilinear density on the unit square,
/// one per `theta_i` slice: density normalised to integrate to 1, the conditional CDF
/// along x of every row (`h x (w - 1)`), the marginal CDF along y (`h - 1`).
#[derive(Clone, Debug)]
struct Warp {
    pdf: Grid,
    cond: Vec<f64>,
    marg: Vec<f64>,
}

impl Warp {
    /// Builds the warp of `slices` densities of `w x h` values (non-negative; each slice
    /// integrates to a positive value, checked by the caller).
    fn new(values: &[f64], w: usize, h: usize, slices: usize) -> Self {
        let mut data = Vec::with_capacity(values.len());
        let mut cond = Vec::with_capacity(slices * h * (w - 1));
        let mut marg = Vec::with_capacity(slices * (h - 1));
        let (dx, dy) = (1.0 / (w - 1) as f64, 1.0 / (h - 1) as f64);
        for s in 0..slices {
            let v = &values[s * w * h..(s + 1) * w * h];
            let c0 = cond.len();
            let mut row_total = Vec::with_capacity(h);
            for r in 0..h {
                let mut acc = 0.0;
                for c in 0..w - 1 {
                    // Trapezoid rule: exact for the piecewise-linear row.
                    acc += 0.5 * dx * (v[r * w + c] + v[r * w + c + 1]);
                    cond.push(acc);
                }
                row_total.push(acc);
            }
            let m0 = marg.len();
            let mut acc = 0.0;
            for r in 0..h - 1 {
                acc += 0.5 * dy * (row_total[r] + row_total[r + 1]);
                marg.push(acc);
            }
            let norm = 1.0 / acc;
            cond[c0..].iter_mut().for_each(|x| *x *= norm);
            marg[m0..].iter_mut().for_each(|x| *x *= norm);
            data.extend(v.iter().map(|x| x * norm));
        }
        Self {
            pdf: Grid { w, h, data },
            cond,
            marg,
        }
    }

    /// The inverse of the sampling map at `u`, for the density interpolated between
    /// slices `s0` and `s1` with weights `(w0, w1)`: every table entry the inverse reads is
    /// the weighted sum of the two slices' entries (the density and its CDFs are linear in
    /// the slice weights).
    fn invert(&self, u: [f64; 2], s: ParamWeights) -> [f64; 2] {
        let (w, h) = (self.pdf.w, self.pdf.h);
        let (n_data, n_cond, n_marg) = (w * h, h * (w - 1), h - 1);
        let mix = |t: &[f64], n: usize, i: usize| s.w0 * t[s.s0 * n + i] + s.w1 * t[s.s1 * n + i];
        let (px, fx) = patch(u[0], w);
        let (py, fy) = patch(u[1], h);
        let d = |r: usize, c: usize| mix(&self.pdf.data, n_data, r * w + c);
        let cond = |r: usize, c: usize| mix(&self.cond, n_cond, r * (w - 1) + c);
        // Along x, in the row interpolated at fy: the density is linear between c0 and
        // c1 over the patch, so the CDF gains fx * (c0 + (c1 - c0) fx / 2) * patch width.
        let c0 = lerp(d(py, px), d(py + 1, px), fy);
        let c1 = lerp(d(py, px + 1), d(py + 1, px + 1), fy);
        let mut x = fx * lerp(c0, c1, 0.5 * fx) / (w - 1) as f64;
        if px > 0 {
            x += lerp(cond(py, px - 1), cond(py + 1, px - 1), fy);
        }
        let r0 = cond(py, w - 2);
        let r1 = cond(py + 1, w - 2);
        let row = lerp(r0, r1, fy);
        x = if row > 0.0 { x / row } else { 0.0 };
        // Along y: the row integrals are linear between r0 and r1 over the patch.
        let mut y = fy * lerp(r0, r1, 0.5 * fy) / (h - 1) as f64;
        if py > 0 {
            y += mix(&self.marg, n_marg, py - 1);
        }
        [x, y]
    }
}

/// Two neighbouring slices of a 1-D parameter and their linear weights.
#[derive(Clone, Copy, Debug)]
struct ParamWeights {
    s0: usize,
    s1: usize,
    w0: f64,
    w1: f64,
}

/// Linear interpolation weights of `x` among increasing `values`, clamped at both ends
/// (the interval is the last one whose left end lies below `x`).
fn param_weights(values: &[f64], x: f64) -> ParamWeights {
    let n = values.len();
    if n == 1 {
        return ParamWeights {
            s0: 0,
            s1: 0,
            w0: 1.0,
            w1: 0.0,
        };
    }
    let i = values[1..n - 1].partition_point(|&v| v < x);
    let (p0, p1) = (values[i], values[i + 1]);
    let w1 = ((x - p0) / (p1 - p0)).clamp(0.0, 1.0);
    ParamWeights {
        s0: i,
        s1: i + 1,
        w0: 1.0 - w1,
        w1,
    }
}

/// An isotropic RGB measured BSDF read from an RGL-EPFL `.bsdf` file.
#[derive(Clone, Debug)]
pub struct RglBsdf {
    /// The file's `description` (the material, in words).
    pub description: String,
    /// Incident elevations of the slices (radians, increasing).
    pub theta_i: Vec<f64>,
    /// Side of the RGB tables (32 or 64 in the RGL database).
    pub resolution: usize,
    jacobian: bool,
    ndf: Grid,
    sigma: Grid,
    vndf: Warp,
    /// `theta_i.len() x 3` slices of `resolution x resolution`.
    rgb: Grid,
}

/// Elevation of a unit vector, accurate near the pole (`2 asin(|d - z| / 2)`).
#[inline]
fn elevation(d: [f64; 3]) -> f64 {
    let dist = (d[0] * d[0] + d[1] * d[1] + (d[2] - 1.0) * (d[2] - 1.0)).sqrt();
    2.0 * (0.5 * dist).min(1.0).asin()
}

/// Azimuth `atan2(y, x)`, with Dr.Jit's reading of signed zeros (Mitsuba's arithmetic):
/// `y = +-0` gives 0 unless `x < 0` (then pi), whatever the signs of the zeros.
#[inline]
fn azimuth(d: [f64; 3]) -> f64 {
    if d[1] == 0.0 {
        if d[0] < 0.0 {
            PI
        } else {
            0.0
        }
    } else {
        d[1].atan2(d[0])
    }
}

#[inline]
fn theta_to_u(theta: f64) -> f64 {
    (theta * FRAC_2_PI).sqrt()
}

#[inline]
fn phi_to_u(phi: f64) -> f64 {
    (phi + PI) / (2.0 * PI)
}

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / l, v[1] / l, v[2] / l]
}

impl RglBsdf {
    /// Validates the fields of a parsed container and builds the evaluation tables.
    ///
    /// Long function: one check per field and per property (dtype, shape,
    /// agreement with `theta_i` and the RGB resolution, values), in the order Mitsuba's
    /// reader checks them, each with its own message.
    pub fn from_tensor(tf: &TensorFile, path: &Path) -> Result<Self, RglError> {
        let p = || path.to_path_buf();
        if tf.field("rgb").is_none() && tf.field("spectra").is_some() {
            return Err(RglError::SpectralOnly { path: p() });
        }
        let get = |name: &'static str, dtype: Dtype, ndim: usize| -> Result<&Field, RglError> {
            let f = tf.field(name).ok_or(RglError::MissingField {
                path: p(),
                field: name,
            })?;
            if f.dtype != dtype {
                return Err(RglError::WrongDtype {
                    path: p(),
                    field: name,
                    expected: dtype.name(),
                    found: f.dtype.name(),
                });
            }
            if f.shape.len() != ndim {
                return Err(RglError::Shape {
                    path: p(),
                    field: name,
                    expected: format!("{ndim} dimensions"),
                    found: f.shape.clone(),
                });
            }
            Ok(f)
        };
        let shape_err = |name: &'static str, f: &Field, expected: String| RglError::Shape {
            path: p(),
            field: name,
            expected,
            found: f.shape.clone(),
        };
        let description = get("description", Dtype::U8, 1)?;
        let description = String::from_utf8_lossy(tf.data(description)).into_owned();
        let phi_i = get("phi_i", Dtype::F32, 1)?;
        if phi_i.count != 1 {
            return Err(RglError::Anisotropic {
                path: p(),
                count: phi_i.count,
            });
        }
        let theta_f = get("theta_i", Dtype::F32, 1)?;
        if theta_f.count == 0 {
            return Err(shape_err("theta_i", theta_f, "at least 1 entry".into()));
        }
        let theta_i: Vec<f64> = tf.f32s(theta_f).into_iter().map(f64::from).collect();
        for (k, &t) in theta_i.iter().enumerate() {
            let bad = |message: &str| RglError::BadValue {
                path: p(),
                field: "theta_i",
                index: k as u64,
                value: t,
                message: message.to_string(),
            };
            if !(t.is_finite() && (0.0..=PI / 2.0 + 1e-5).contains(&t)) {
                return Err(bad("an incident elevation must lie in [0, pi/2] radians"));
            }
            if k > 0 && t <= theta_i[k - 1] {
                return Err(bad("incident elevations must increase"));
            }
        }
        let n_theta = theta_i.len() as u64;
        let grid2 = |name: &'static str, positive: bool| -> Result<Grid, RglError> {
            let f = get(name, Dtype::F32, 2)?;
            if f.shape[0] < 2 || f.shape[1] < 2 {
                return Err(shape_err(name, f, "at least 2 x 2".into()));
            }
            let data = values(tf, f, name, path, positive)?;
            Ok(Grid {
                w: f.shape[1] as usize,
                h: f.shape[0] as usize,
                data,
            })
        };
        let sigma = grid2("sigma", true)?;
        let ndf = grid2("ndf", false)?;
        let vndf_f = get("vndf", Dtype::F32, 4)?;
        let s = &vndf_f.shape;
        if s[0] != 1 || s[1] != n_theta || s[2] < 2 || s[3] < 2 {
            return Err(shape_err(
                "vndf",
                vndf_f,
                format!("1 x {n_theta} x H x W (phi_i x theta_i x rows x columns, H, W >= 2)"),
            ));
        }
        let (vh, vw) = (s[2] as usize, s[3] as usize);
        let vndf_v = values(tf, vndf_f, "vndf", path, false)?;
        for (k, slice) in vndf_v.chunks_exact(vw * vh).enumerate() {
            if slice.iter().all(|&x| x == 0.0) {
                return Err(RglError::BadValue {
                    path: p(),
                    field: "vndf",
                    index: (k * vw * vh) as u64,
                    value: 0.0,
                    message: format!(
                        "slice {} (theta_i = {:.4} rad) is zero everywhere: it has no inverse",
                        k + 1,
                        theta_i[k]
                    ),
                });
            }
        }
        let vndf = Warp::new(&vndf_v, vw, vh, theta_i.len());
        let lum = get("luminance", Dtype::F32, 4)?;
        let l = &lum.shape;
        if l[0] != 1 || l[1] != n_theta || l[2] != l[3] || l[2] < 2 {
            return Err(shape_err(
                "luminance",
                lum,
                format!("1 x {n_theta} x N x N (N >= 2)"),
            ));
        }
        values(tf, lum, "luminance", path, false)?;
        let n = l[2];
        let rgb_f = get("rgb", Dtype::F32, 5)?;
        if rgb_f.shape != [1, n_theta, 3, n, n] {
            return Err(shape_err(
                "rgb",
                rgb_f,
                format!("1 x {n_theta} x 3 x {n} x {n} (phi_i x theta_i x channel x the luminance table's N x N)"),
            ));
        }
        let rgb = values_signed(tf, rgb_f, "rgb", path)?;
        let jac = get("jacobian", Dtype::U8, 1)?;
        if jac.count != 1 {
            return Err(shape_err("jacobian", jac, "1 entry".into()));
        }
        let jacobian = match tf.data(jac)[0] {
            0 => false,
            1 => true,
            v => {
                return Err(RglError::BadValue {
                    path: p(),
                    field: "jacobian",
                    index: 0,
                    value: v as f64,
                    message: "the jacobian flag is 0 or 1".into(),
                })
            }
        };
        Ok(Self {
            description,
            theta_i,
            resolution: n as usize,
            jacobian,
            ndf,
            sigma,
            vndf,
            rgb: Grid {
                w: n as usize,
                h: n as usize,
                data: rgb,
            },
        })
    }

    /// RGB reflectance `f(wi, wo)` (per steradian, not times `cos theta_o`) of unit
    /// directions in the local frame (z = normal); 0 when either is at or below the
    /// horizon. A channel may be negative (the file's linear sRGB of a colour outside the
    /// sRGB gamut); it is returned as it is, as Mitsuba does.
    pub fn eval(&self, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
        let fcos = self.eval_cos(wi, wo);
        let cos_o = normalize(wo)[2];
        if cos_o.is_nan() || cos_o <= 0.0 {
            return [0.0; 3];
        }
        fcos.map(|v| v / cos_o)
    }

    /// `f(wi, wo) cos theta_o`, what Mitsuba's `eval` returns.
    pub fn eval_cos(&self, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
        if !(wi[2] > 0.0 && wo[2] > 0.0) {
            return [0.0; 3];
        }
        let (mut wi, mut wo) = (normalize(wi), normalize(wo));
        // Mitsuba turns the pair by pi about the normal when wi.y is not negative (its
        // `mulsign_neg` on the sign bit, so +0 counts as positive). For an isotropic
        // material this changes nothing but the azimuths of zero-length projections
        // (exact normal incidence, exact mirror pairs), which we then read as it does.
        if wi[1].is_sign_positive() {
            for v in [&mut wi, &mut wo] {
                v[0] = -v[0];
                v[1] = -v[1];
            }
        }
        let m = normalize([wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]]);
        let theta_i = elevation(wi);
        let phi_i = azimuth(wi);
        let theta_m = elevation(m);
        let phi_m = azimuth(m);
        let u_wi = [theta_to_u(theta_i), phi_to_u(phi_i)];
        let mut u_m = [theta_to_u(theta_m), phi_to_u(phi_m - phi_i)];
        u_m[1] -= u_m[1].floor();
        let pw = param_weights(&self.theta_i, theta_i);
        let s = self.vndf.invert(u_m, pw);
        let scale = if self.jacobian {
            self.ndf.eval(0, u_m[0], u_m[1]) / (4.0 * self.sigma.eval(0, u_wi[0], u_wi[1]))
        } else {
            1.0
        };
        [0, 1, 2].map(|c| {
            let v0 = self.rgb.eval(3 * pw.s0 + c, s[0], s[1]);
            let v1 = self.rgb.eval(3 * pw.s1 + c, s[0], s[1]);
            (pw.w0 * v0 + pw.w1 * v1) * scale
        })
    }
}

/// The values of a float32 field as f64: finite, non-negative (positive with
/// `positive`), else an error naming the field and the index.
fn values(
    tf: &TensorFile,
    f: &Field,
    name: &'static str,
    path: &Path,
    positive: bool,
) -> Result<Vec<f64>, RglError> {
    let v = values_signed(tf, f, name, path)?;
    if let Some((k, &x)) = v
        .iter()
        .enumerate()
        .find(|(_, &x)| x < 0.0 || (positive && x <= 0.0))
    {
        return Err(RglError::BadValue {
            path: path.to_path_buf(),
            field: name,
            index: k as u64,
            value: x,
            message: if positive {
                "must be positive".into()
            } else {
                "must not be negative".into()
            },
        });
    }
    Ok(v)
}

/// The values of a float32 field as f64, all finite.
fn values_signed(
    tf: &TensorFile,
    f: &Field,
    name: &'static str,
    path: &Path,
) -> Result<Vec<f64>, RglError> {
    let v: Vec<f64> = tf.f32s(f).into_iter().map(f64::from).collect();
    if let Some((k, &x)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
        return Err(RglError::BadValue {
            path: path.to_path_buf(),
            field: name,
            index: k as u64,
            value: x,
            message: "not a finite number".into(),
        });
    }
    Ok(v)
}
