//! CPU renderer of a sphere under one directional light (SPEC section 7).
//!
//! The scene, as in the paper's Fig. 1 and Fig. 5 (rendered there with Disney's BRDF
//! Explorer): a unit sphere seen orthographically from +z, lit by one directional light.
//!
//! * Image plane: pixel centres in `[-1, 1]^2`, x to the right, y up, row 0 at the top:
//!   `x = -1 + (col + 0.5) * 2 / w`, `y = 1 - (row + 0.5) * 2 / h`.
//! * A pixel is on the sphere iff `x^2 + y^2 < 1`; its normal is
//!   `N = (x, y, sqrt(1 - x^2 - y^2))`. Off-sphere pixels are 0.
//! * View direction `wo = (0, 0, 1)` in world coordinates; light direction
//!   `wi = (sin t cos p, sin t sin p, cos t)` for `(theta, phi) = (t, p)` in world
//!   coordinates (theta from +z, phi from +x towards +y).
//! * Radiance per channel `L = f(wi_local, wo_local) * max(N.wi, 0)`, linear, where the
//!   local frame has N as +z (see `tangent_frame`). Where `N.wi <= 0` the BRDF is not
//!   called and the pixel is 0, so a BRDF may return anything below the horizon.
//!
//! The BRDF is a closure, so analytic materials (evaluated analytically), measured ones
//! (MERL lookup) and linear combinations of either render through the same code.

use rayon::prelude::*;

/// Errors from rendering parameters and from comparing images.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// A parameter is out of its valid range.
    #[error("invalid {name} `{value}` (expected {expected})")]
    InvalidParam {
        /// Parameter name.
        name: &'static str,
        /// Value given.
        value: String,
        /// Accepted range.
        expected: &'static str,
    },
    /// Two images to compare have different sizes.
    #[error("images differ in size: {a_width}x{a_height} vs {b_width}x{b_height}")]
    SizeMismatch {
        /// Width of the first image.
        a_width: u32,
        /// Height of the first image.
        a_height: u32,
        /// Width of the second image.
        b_width: u32,
        /// Height of the second image.
        b_height: u32,
    },
    /// Two images to compare have different sphere masks.
    #[error("images differ in their sphere masks at pixel (col {col}, row {row})")]
    MaskMismatch {
        /// Column of the first differing pixel.
        col: u32,
        /// Row of the first differing pixel.
        row: u32,
    },
    /// An image's buffers do not match its size.
    #[error(
        "malformed {width}x{height} image: {data_len} samples (expected {}), {mask_len} mask entries (expected {})",
        3 * (*.width as usize) * (*.height as usize),
        (*.width as usize) * (*.height as usize)
    )]
    Malformed {
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
        /// Length of `data`.
        data_len: usize,
        /// Length of `mask`.
        mask_len: usize,
    },
    /// No pixel lies on the sphere, so there is nothing to compare.
    #[error("no pixel lies on the sphere")]
    EmptyMask,
    /// FLIP refused the pair (its buffers do not match the size).
    #[error(transparent)]
    Flip(super::flip::FlipError),
}

/// A rendered image: linear RGB radiance and the sphere mask.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB, interleaved, row-major, row 0 at the top: `3 * width * height` values.
    pub data: Vec<f32>,
    /// `true` for pixels on the sphere, row-major: `width * height` entries.
    pub mask: Vec<bool>,
}

impl Image {
    /// A black image of the given size whose mask is the sphere's ([`sphere_mask`]).
    pub fn black(width: u32, height: u32) -> Image {
        let n = width as usize * height as usize;
        Image {
            width,
            height,
            data: vec![0.0; 3 * n],
            mask: sphere_mask(width, height),
        }
    }

    /// RGB of pixel (`col`, `row`). Panics when out of range.
    pub fn pixel(&self, col: u32, row: u32) -> [f32; 3] {
        let i = 3 * (row as usize * self.width as usize + col as usize);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// Whether pixel (`col`, `row`) is on the sphere. Panics when out of range.
    pub fn on_sphere(&self, col: u32, row: u32) -> bool {
        self.mask[row as usize * self.width as usize + col as usize]
    }

    /// Number of pixels on the sphere.
    pub fn sphere_pixels(&self) -> usize {
        self.mask.iter().filter(|&&m| m).count()
    }

    /// Checks that `data` and `mask` have the lengths the size implies.
    pub fn check(&self) -> Result<(), RenderError> {
        let n = self.width as usize * self.height as usize;
        if self.data.len() != 3 * n || self.mask.len() != n {
            return Err(RenderError::Malformed {
                width: self.width,
                height: self.height,
                data_len: self.data.len(),
                mask_len: self.mask.len(),
            });
        }
        Ok(())
    }
}

/// Largest accepted [`RenderParams::size`].
pub const MAX_SIZE: u32 = 16384;

/// Parameters of [`render_sphere`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderParams {
    /// Image width and height in pixels. Default 256; valid `1..=`[`MAX_SIZE`].
    pub size: u32,
    /// Light direction `(theta, phi)` in degrees, world coordinates, theta from +z, phi
    /// from +x towards +y. Default `(45, 45)` (paper Fig. 5); theta in `[0, 180]`, phi
    /// any finite value.
    pub light: (f64, f64),
}

impl Default for RenderParams {
    fn default() -> Self {
        RenderParams {
            size: 256,
            light: (45.0, 45.0),
        }
    }
}

impl RenderParams {
    /// Sets the image size.
    pub fn with_size(mut self, size: u32) -> Self {
        self.size = size;
        self
    }

    /// Sets the light direction `(theta, phi)` in degrees.
    pub fn with_light(mut self, theta_deg: f64, phi_deg: f64) -> Self {
        self.light = (theta_deg, phi_deg);
        self
    }

    /// Validates the parameters.
    pub fn check(&self) -> Result<(), RenderError> {
        if self.size == 0 || self.size > MAX_SIZE {
            return Err(RenderError::InvalidParam {
                name: "image size",
                value: self.size.to_string(),
                expected: "1..=16384 pixels",
            });
        }
        let (theta, phi) = self.light;
        if !(0.0..=180.0).contains(&theta) {
            return Err(RenderError::InvalidParam {
                name: "light theta",
                value: theta.to_string(),
                expected: "degrees in [0, 180]",
            });
        }
        if !phi.is_finite() {
            return Err(RenderError::InvalidParam {
                name: "light phi",
                value: phi.to_string(),
                expected: "finite degrees",
            });
        }
        Ok(())
    }

    /// The light direction `wi` as a world-space unit vector.
    pub fn light_direction(&self) -> [f64; 3] {
        light_direction(self.light.0, self.light.1)
    }
}

/// Unit vector for spherical angles in degrees: `(sin t cos p, sin t sin p, cos t)`.
pub fn light_direction(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
    let (st, ct) = theta_deg.to_radians().sin_cos();
    let (sp, cp) = phi_deg.to_radians().sin_cos();
    [st * cp, st * sp, ct]
}

/// Image-plane coordinates `(x, y)` of the centre of pixel (`col`, `row`) in an image of
/// `width` x `height`: `x = -1 + (col + 0.5) * 2 / width`, `y = 1 - (row + 0.5) * 2 / height`.
pub fn pixel_centre(col: u32, row: u32, width: u32, height: u32) -> (f64, f64) {
    let x = -1.0 + (f64::from(col) + 0.5) * 2.0 / f64::from(width);
    let y = 1.0 - (f64::from(row) + 0.5) * 2.0 / f64::from(height);
    (x, y)
}

/// The sphere mask: `true` where the pixel centre satisfies `x^2 + y^2 < 1`.
pub fn sphere_mask(width: u32, height: u32) -> Vec<bool> {
    let mut mask = Vec::with_capacity(width as usize * height as usize);
    for row in 0..height {
        for col in 0..width {
            let (x, y) = pixel_centre(col, row, width, height);
            mask.push(x * x + y * y < 1.0);
        }
    }
    mask
}

/// Local shading frame `[t, b, n]` (rows: tangent, bitangent, normal) for a unit normal
/// `n` on the visible hemisphere.
///
/// Choice: `t = normalize(cross((0, 1, 0), n)) = (n.z, 0, -n.x) / sqrt(n.x^2 + n.z^2)`,
/// `b = cross(n, t)`. This is continuous and deterministic on the whole open visible
/// hemisphere (`n.z > 0`; it degenerates only at `n = (0, +-1, 0)`, where a fallback
/// orthogonalises `(1, 0, 0)` against `n`), and at the sphere's centre (`n = +z`) it is
/// the world frame. For an isotropic BRDF only the relative azimuth of `wi` and `wo`
/// matters, so any consistent choice renders the same image.
pub(crate) fn tangent_frame(n: [f64; 3]) -> [[f64; 3]; 3] {
    let c = [n[2], 0.0, -n[0]];
    let len = (c[0] * c[0] + c[2] * c[2]).sqrt();
    let t = if len > 1e-12 {
        [c[0] / len, 0.0, c[2] / len]
    } else {
        // n is (anti)parallel to +y: (1, 0, 0) minus its projection on n.
        let p = [1.0 - n[0] * n[0], -n[0] * n[1], -n[0] * n[2]];
        let l = dot(p, p).sqrt();
        [p[0] / l, p[1] / l, p[2] / l]
    };
    let b = cross(n, t);
    [t, b, n]
}

/// `v` expressed in `frame` (rows `[t, b, n]`): `(v.t, v.b, v.n)`.
fn to_local(frame: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [dot(frame[0], v), dot(frame[1], v), dot(frame[2], v)]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Renders the sphere lit by the light of `params` with the BRDF `brdf(wi, wo) -> RGB`
/// (local directions, normal = +z), returning linear radiance (module docs give the
/// conventions). Rows are rendered in parallel with rayon; the result is deterministic.
pub fn render_sphere(
    params: &RenderParams,
    brdf: &(dyn Fn([f64; 3], [f64; 3]) -> [f64; 3] + Sync),
) -> Result<Image, RenderError> {
    params.check()?;
    Ok(render_with_frame(params, brdf, &tangent_frame))
}

/// [`render_sphere`] whose BRDF is also given the pixel's index (`row * size + col`): the
/// same image as [`render_sphere`] with `|wi, wo| brdf(index, wi, wo)`.
pub(crate) fn render_sphere_indexed(
    params: &RenderParams,
    brdf: &(dyn Fn(usize, [f64; 3], [f64; 3]) -> [f64; 3] + Sync),
) -> Result<Image, RenderError> {
    params.check()?;
    Ok(render_frame_indexed(params, brdf, &tangent_frame))
}

/// The sphere's normal at the centre of pixel (`col`, `row`) of a `size` x `size` render
/// and `cos theta_i` of the light `wi` there, when the pixel is on the sphere and lit.
#[inline]
fn lit_normal(col: u32, row: u32, size: u32, wi: [f64; 3]) -> Option<([f64; 3], f64)> {
    let (x, y) = pixel_centre(col, row, size, size);
    let r2 = x * x + y * y;
    if r2 >= 1.0 {
        return None;
    }
    let n = [x, y, (1.0 - r2).sqrt()];
    let cos_i = dot(n, wi);
    (cos_i > 0.0).then_some((n, cos_i))
}

/// The lit sphere pixels of a render with `params`, row-major: each pixel's index (`row *
/// size + col`) and `cos theta_i`, the factor [`render_sphere`] multiplies the BRDF by
/// there (the same bits).
pub(crate) fn lit_pixels(params: &RenderParams) -> Result<Vec<(usize, f64)>, RenderError> {
    params.check()?;
    let (size, wi) = (params.size, params.light_direction());
    let mut out = Vec::new();
    for row in 0..size {
        for col in 0..size {
            if let Some((_, cos_i)) = lit_normal(col, row, size, wi) {
                out.push((row as usize * size as usize + col as usize, cos_i));
            }
        }
    }
    Ok(out)
}

/// [`render_sphere`] with a caller-chosen shading frame (tests check frame independence).
fn render_with_frame(
    params: &RenderParams,
    brdf: &(dyn Fn([f64; 3], [f64; 3]) -> [f64; 3] + Sync),
    frame_of: &(dyn Fn([f64; 3]) -> [[f64; 3]; 3] + Sync),
) -> Image {
    render_frame_indexed(params, &|_, wi, wo| brdf(wi, wo), frame_of)
}

fn render_frame_indexed(
    params: &RenderParams,
    brdf: &(dyn Fn(usize, [f64; 3], [f64; 3]) -> [f64; 3] + Sync),
    frame_of: &(dyn Fn([f64; 3]) -> [[f64; 3]; 3] + Sync),
) -> Image {
    let size = params.size;
    let wi = params.light_direction();
    let wo = [0.0, 0.0, 1.0];
    let mut image = Image::black(size, size);
    let row_len = 3 * size as usize;
    image
        .data
        .par_chunks_mut(row_len)
        .enumerate()
        .for_each(|(row, out)| {
            for col in 0..size {
                let Some((n, cos_i)) = lit_normal(col, row as u32, size, wi) else {
                    continue;
                };
                let frame = frame_of(n);
                let index = row * size as usize + col as usize;
                let f = brdf(index, to_local(&frame, wi), to_local(&frame, wo));
                let o = 3 * col as usize;
                for c in 0..3 {
                    out[o + c] = (f[c] * cos_i) as f32;
                }
            }
        });
    image
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn lambert(rho: [f64; 3]) -> impl Fn([f64; 3], [f64; 3]) -> [f64; 3] + Sync {
        move |_wi, _wo| [rho[0] / PI, rho[1] / PI, rho[2] / PI]
    }

    #[test]
    fn default_params() {
        let p = RenderParams::default();
        assert_eq!(p.size, 256);
        assert_eq!(p.light, (45.0, 45.0));
        assert!(p.check().is_ok());
    }

    #[test]
    fn rejects_zero_size() {
        assert!(matches!(
            RenderParams::default().with_size(0).check(),
            Err(RenderError::InvalidParam {
                name: "image size",
                ..
            })
        ));
    }

    #[test]
    fn rejects_huge_size() {
        assert!(RenderParams::default()
            .with_size(MAX_SIZE + 1)
            .check()
            .is_err());
        assert!(RenderParams::default().with_size(MAX_SIZE).check().is_ok());
    }

    #[test]
    fn rejects_bad_theta() {
        for t in [-1.0, 180.5, f64::NAN, f64::INFINITY] {
            let err = RenderParams::default()
                .with_light(t, 0.0)
                .check()
                .unwrap_err();
            assert!(
                matches!(
                    err,
                    RenderError::InvalidParam {
                        name: "light theta",
                        ..
                    }
                ),
                "{t}"
            );
        }
    }

    #[test]
    fn rejects_bad_phi() {
        let err = RenderParams::default()
            .with_light(45.0, f64::NAN)
            .check()
            .unwrap_err();
        assert!(matches!(
            err,
            RenderError::InvalidParam {
                name: "light phi",
                ..
            }
        ));
        assert!(err.to_string().contains("light phi"));
    }

    #[test]
    fn render_checks_params() {
        let f = lambert([1.0; 3]);
        assert!(render_sphere(&RenderParams::default().with_size(0), &f).is_err());
    }

    #[test]
    fn light_direction_by_hand() {
        let w = light_direction(45.0, 45.0);
        let h = 0.5;
        assert!((w[0] - h).abs() < 1e-15 && (w[1] - h).abs() < 1e-15);
        assert!((w[2] - 0.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(light_direction(0.0, 123.0), [0.0, 0.0, 1.0]);
    }

    #[test]
    fn pixel_centres_by_hand() {
        assert_eq!(pixel_centre(0, 0, 4, 4), (-0.75, 0.75));
        assert_eq!(pixel_centre(3, 3, 4, 4), (0.75, -0.75));
        assert_eq!(pixel_centre(1, 0, 3, 3), (0.0, 1.0 - 1.0 / 3.0));
    }

    #[test]
    fn lambert_centre_pixel_light_overhead() {
        // Odd size: the centre pixel has N = +z exactly, so L = rho / pi.
        let rho = [0.2, 0.5, 0.8];
        let img = render_sphere(
            &RenderParams::default().with_size(65).with_light(0.0, 0.0),
            &lambert(rho),
        )
        .unwrap();
        let p = img.pixel(32, 32);
        for c in 0..3 {
            assert_eq!(p[c], (rho[c] / PI) as f32);
        }
    }

    #[test]
    fn lambert_pixels_by_hand() {
        let rho = [0.3, 0.6, 0.9];
        let params = RenderParams::default().with_size(64);
        let img = render_sphere(&params, &lambert(rho)).unwrap();
        let wi = light_direction(45.0, 45.0);
        for (col, row) in [(10, 20), (40, 12), (32, 32), (50, 50), (5, 40)] {
            let (x, y) = pixel_centre(col, row, 64, 64);
            let r2 = x * x + y * y;
            let p = img.pixel(col, row);
            if r2 >= 1.0 {
                assert!(!img.on_sphere(col, row));
                assert_eq!(p, [0.0; 3]);
                continue;
            }
            let n = [x, y, (1.0 - r2).sqrt()];
            let cos = dot(n, wi).max(0.0);
            for c in 0..3 {
                let want = rho[c] / PI * cos;
                assert!(
                    (f64::from(p[c]) - want).abs() <= 1e-6 * want.max(1e-30),
                    "({col},{row})"
                );
            }
        }
    }

    #[test]
    fn brightest_pixel_faces_the_light() {
        let img =
            render_sphere(&RenderParams::default().with_size(128), &lambert([1.0; 3])).unwrap();
        let (mut best, mut at) = (-1.0f32, (0, 0));
        for row in 0..128 {
            for col in 0..128 {
                let v = img.pixel(col, row)[0];
                if v > best {
                    best = v;
                    at = (col, row);
                }
            }
        }
        // The normal facing wi = (0.5, 0.5, 0.707) is at image (x, y) = (0.5, 0.5):
        // upper right, col = (x + 1) / 2 * 128 - 0.5 ~ 95.5, row = (1 - y) / 2 * 128 - 0.5 ~ 31.5.
        let (x, y) = pixel_centre(at.0, at.1, 128, 128);
        assert!(
            (x - 0.5).abs() <= 1.0 / 64.0 && (y - 0.5).abs() <= 1.0 / 64.0,
            "{at:?}"
        );
        assert!((f64::from(best) - 1.0 / PI).abs() < 1e-3);
    }

    #[test]
    fn sphere_pixel_count_size_64() {
        let img =
            render_sphere(&RenderParams::default().with_size(64), &lambert([1.0; 3])).unwrap();
        let mut direct = 0;
        for row in 0..64 {
            for col in 0..64 {
                let x = (2 * col + 1) as f64 / 64.0 - 1.0;
                let y = 1.0 - (2 * row + 1) as f64 / 64.0;
                if x * x + y * y < 1.0 {
                    direct += 1;
                }
            }
        }
        assert_eq!(img.sphere_pixels(), direct);
        // Roughly pi / 4 of the square.
        assert!((direct as f64 / 4096.0 - PI / 4.0).abs() < 0.01);
        assert!(img.check().is_ok());
    }

    #[test]
    fn off_sphere_and_unlit_pixels_are_zero() {
        // Light from behind-left: the right half of the sphere is unlit.
        let called_below = std::sync::atomic::AtomicBool::new(false);
        let f = |wi: [f64; 3], _wo: [f64; 3]| {
            if wi[2] <= 0.0 {
                called_below.store(true, std::sync::atomic::Ordering::Relaxed);
            }
            [1.0; 3]
        };
        let img = render_sphere(
            &RenderParams::default()
                .with_size(32)
                .with_light(90.0, 180.0),
            &f,
        )
        .unwrap();
        assert!(!called_below.load(std::sync::atomic::Ordering::Relaxed));
        for row in 0..32 {
            for col in 0..32 {
                let (x, _) = pixel_centre(col, row, 32, 32);
                if !img.on_sphere(col, row) || x >= 0.0 {
                    assert_eq!(img.pixel(col, row), [0.0; 3]);
                }
            }
        }
    }

    #[test]
    fn frame_is_orthonormal_and_continuous() {
        for n in [
            [0.0, 0.0, 1.0],
            [0.6, 0.0, 0.8],
            [0.0, 0.6, 0.8],
            [-0.48, 0.36, 0.8],
            [0.0, 1.0, 0.0],
        ] {
            let f = tangent_frame(n);
            for i in 0..3 {
                for j in 0..3 {
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((dot(f[i], f[j]) - want).abs() < 1e-12);
                }
            }
            let c = cross(f[0], f[1]);
            assert!((dot(c, f[2]) - 1.0).abs() < 1e-12, "right-handed");
            assert!((to_local(&f, n)[2] - 1.0).abs() < 1e-12);
        }
        assert_eq!(
            tangent_frame([0.0, 0.0, 1.0]),
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        );
        let a = tangent_frame([0.0, 0.0, 1.0]);
        let s = (1.0f64 - 1e-12).sqrt();
        let b = tangent_frame([1e-6, 0.0, s]);
        assert!((dot(a[0], b[0]) - 1.0).abs() < 1e-9);
    }

    /// Rotates the frame of `tangent_frame` about N by an angle that varies over the sphere.
    fn twisted_frame(n: [f64; 3]) -> [[f64; 3]; 3] {
        let [t, b, n] = tangent_frame(n);
        let (s, c) = (7.0 * n[0] + 3.0 * n[1] + 1.0).sin_cos();
        let t2 = [
            c * t[0] + s * b[0],
            c * t[1] + s * b[1],
            c * t[2] + s * b[2],
        ];
        let b2 = cross(n, t2);
        [t2, b2, n]
    }

    #[test]
    fn isotropic_brdf_ignores_frame() {
        // Depends only on N.wi, N.wo and wi.wo: invariant under rotation about N.
        let iso = |wi: [f64; 3], wo: [f64; 3]| {
            let d = dot(wi, wo);
            let g = (wi[2] * wo[2]).sqrt();
            [
                0.1 + d * d,
                0.3 * g + (8.0 * (d - 1.0)).exp(),
                0.05 + wi[2] * wo[2] * d.abs(),
            ]
        };
        let params = RenderParams::default().with_size(48).with_light(30.0, 70.0);
        let a = render_sphere(&params, &iso).unwrap();
        let b = render_with_frame(&params, &iso, &twisted_frame);
        assert_eq!(a.mask, b.mask);
        for (x, y) in a.data.iter().zip(&b.data) {
            assert!((x - y).abs() <= 1e-6 * x.abs().max(1e-20), "{x} vs {y}");
        }
        // Sanity: an anisotropic BRDF does see the frame, so the test can fail.
        let aniso = |wi: [f64; 3], _wo: [f64; 3]| [wi[0] * wi[0]; 3];
        let a = render_sphere(&params, &aniso).unwrap();
        let b = render_with_frame(&params, &aniso, &twisted_frame);
        assert!(a
            .data
            .iter()
            .zip(&b.data)
            .any(|(x, y)| (x - y).abs() > 1e-3));
    }

    #[test]
    fn malformed_image_is_reported() {
        let mut img = Image::black(4, 4);
        img.data.pop();
        assert!(matches!(
            img.check(),
            Err(RenderError::Malformed { data_len: 47, .. })
        ));
    }
}
