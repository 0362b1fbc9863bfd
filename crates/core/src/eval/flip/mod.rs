//! LDR FLIP of our own (Andersson, Nilsson, Akenine-Möller, Oskarsson, Åström and
//! Fairchild 2020, "FLIP: A Difference Evaluator for Alternating Images"), the metric of
//! SPEC 11, written from the paper and its separable-filter note.
//!
//! The pipeline, per pixel of an 8-bit sRGB pair at `ppd` pixels per degree:
//! * **colour**: sRGB to linear RGB to XYZ (D65) to YCxCz; each channel filtered by the
//!   contrast sensitivity functions (a Gaussian for Y and Cx, a sum of two for Cz; radius
//!   `ceil(3 sqrt(b_max / (2 pi^2)) ppd)`, clamped to the image's edge), the result back to
//!   linear RGB clamped to `[0, 1]`, to CIELAB with the Hunt adjustment
//!   (`a, b <- 0.01 L a, 0.01 L b`); HyAB distance, raised to `q_c = 0.7` and remapped to
//!   `[0, 1]` (`p_c = 0.4`, `p_t = 0.95`, by the distance of green to blue);
//! * **features**: the normalised luminance `(Y + 16) / 116` filtered by the first and
//!   second derivatives of a Gaussian of standard deviation `0.5 w ppd` (`w = 0.082`
//!   degrees); edge and point strengths are the gradient magnitudes; the feature difference
//!   is `(max(|d edge|, |d point|) / sqrt 2)^q_f`, `q_f = 0.5`;
//! * **error**: `colour^(1 - feature)`.
//!
//! Implementation choices (none moves the metric beyond SPEC 11's tolerance, 1e-4 on a
//! per-image mean against NVIDIA's reference; `tests` and `tests/flip_peer.rs` check it):
//! * f32 throughout, as NVIDIA's implementation; filter weights computed by the same
//!   formulas in the same order, and every convolution sums its taps in the same order, so
//!   the filtered values are those of the reference to the bit;
//! * the powers and cube roots (`x^(1/3)`, `x^0.7`, `x^(1 - f)`) by a branch-free
//!   `exp2(y log2 x)` whose relative error is below 2e-7 (a few f32 ulps), so that whole
//!   rows vectorise; the sRGB decoding by a 256-entry table (the input is 8-bit);
//! * planar rows, so that the separable passes and the per-pixel maths run over contiguous
//!   slices (AVX2 where the processor has it: the same operations in the same order on
//!   every lane, so both paths give the same bits);
//! * a reference image is prepared once ([`FlipReference`]): its filtered CIELAB and
//!   feature strengths are kept, so scoring a test image filters the test alone;
//! * the error is evaluated on the pixels of a mask (the sphere's, SPEC 11), and the
//!   filters run over the rows and columns that those pixels' support reaches, no more.

mod kernel;
mod math;

use kernel::*;
use math::*;

/// FLIP's constants (the paper's section 4): colour exponent, remap knee and its value,
/// feature width in degrees, feature exponent.
const QC: f32 = 0.7;
const PC: f32 = 0.4;
const PT: f32 = 0.95;
const GW: f32 = 0.082;
const QF: f32 = 0.5;

/// The contrast sensitivity functions as Gaussians in the frequency domain, `(a, b)` for
/// Y, Cx, Cz: one each, and a second one for Cz.
const A1: [f32; 3] = [1.0, 1.0, 34.1];
const B1: [f32; 3] = [0.0047, 0.0053, 0.04];
const A2: [f32; 3] = [0.0, 0.0, 13.5];
const B2: [f32; 3] = [1.0e-5, 1.0e-5, 0.025];

/// D65 white (XYZ of linear RGB (1, 1, 1)) and its inverse, as FLIP uses them.
const WHITE: [f32; 3] = [0.950_428_5, 1.0, 1.088_900_4];
const INV_WHITE: [f32; 3] = [1.052_156_9, 1.0, 0.918_357_7];

/// The filters of one viewing condition (pixels per degree): built once, shared by every
/// image pair scored at it.
#[derive(Clone, Debug, PartialEq)]
pub struct FlipKernels {
    /// Radius of the colour filters (taps `2 r + 1`).
    spatial_radius: usize,
    /// Colour filters: Y, Cx, and the two halves of Cz's sum of Gaussians.
    g_y: Vec<f32>,
    g_cx: Vec<f32>,
    g_cz1: Vec<f32>,
    g_cz2: Vec<f32>,
    /// Radius of the feature filters.
    feature_radius: usize,
    /// Feature filters: Gaussian, first and second derivative.
    f_g: Vec<f32>,
    f_dg: Vec<f32>,
    f_ddg: Vec<f32>,
    /// `cmax = HyAB(green, blue)^q_c` and `p_c cmax`.
    cmax: f32,
    pccmax: f32,
}

/// The frequency-domain Gaussian `a sqrt(pi / b) exp(-pi^2 x^2 / b)`.
fn csf_gaussian(x2: f32, a: f32, b: f32) -> f32 {
    let (pi, pi_sq) = (
        std::f64::consts::PI as f32,
        (std::f64::consts::PI * std::f64::consts::PI) as f32,
    );
    a * (pi / b).sqrt() * (-pi_sq * x2 / b).exp()
}

/// The separable half of a Gaussian of a sum of two: `sqrt(a sqrt(pi / b)) exp(-pi^2 x^2 / b)`.
fn csf_gaussian_sqrt(x2: f32, a: f32, b: f32) -> f32 {
    let (pi, pi_sq) = (
        std::f64::consts::PI as f32,
        (std::f64::consts::PI * std::f64::consts::PI) as f32,
    );
    (a * (pi / b).sqrt()).sqrt() * (-pi_sq * x2 / b).exp()
}

impl FlipKernels {
    /// The filters at `ppd` pixels per degree (finite and positive).
    pub fn new(ppd: f32) -> Self {
        assert!(
            ppd.is_finite() && ppd > 0.0,
            "FLIP: pixels per degree must be positive"
        );
        let pi_sq = (std::f64::consts::PI * std::f64::consts::PI) as f32;
        let b_max = B1.iter().chain(&B2).fold(0.0f32, |m, &b| m.max(b));
        let spatial_radius = (3.0 * (b_max / (2.0 * pi_sq)).sqrt() * ppd).ceil() as usize;
        let width = 2 * spatial_radius + 1;
        let dx = 1.0 / ppd;
        let (mut g_y, mut g_cx, mut g_cz1, mut g_cz2) = (vec![], vec![], vec![], vec![]);
        let (mut s_y, mut s_cx, mut s_cz1, mut s_cz2) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
        for x in 0..width {
            let ix = (x as i32 - spatial_radius as i32) as f32 * dx;
            let ix2 = ix * ix;
            let v = [
                csf_gaussian(ix2, A1[0], B1[0]),
                csf_gaussian(ix2, A1[1], B1[1]),
                csf_gaussian_sqrt(ix2, A1[2], B1[2]),
                csf_gaussian_sqrt(ix2, A2[2], B2[2]),
            ];
            s_y += v[0];
            s_cx += v[1];
            s_cz1 += v[2];
            s_cz2 += v[3];
            g_y.push(v[0]);
            g_cx.push(v[1]);
            g_cz1.push(v[2]);
            g_cz2.push(v[3]);
        }
        let (n_y, n_cx) = (1.0 / s_y, 1.0 / s_cx);
        let n_cz = 1.0 / (s_cz1 * s_cz1 + s_cz2 * s_cz2).sqrt();
        g_y.iter_mut().for_each(|v| *v *= n_y);
        g_cx.iter_mut().for_each(|v| *v *= n_cx);
        g_cz1.iter_mut().for_each(|v| *v *= n_cz);
        g_cz2.iter_mut().for_each(|v| *v *= n_cz);

        let sd = 0.5 * GW * ppd;
        let feature_radius = (3.0 * sd).ceil() as usize;
        let (mut f_g, mut f_dg, mut f_ddg) = (vec![], vec![], vec![]);
        let (mut gs, mut dpos, mut dneg, mut ddpos, mut ddneg) =
            (0.0f32, 0.0f32, 0.0f32, 0.0f32, 0.0f32);
        for x in 0..2 * feature_radius + 1 {
            let xx = (x as i32 - feature_radius as i32) as f32;
            let g = (-(xx * xx) / (2.0 * sd * sd)).exp();
            gs += g;
            let dg = -xx * g;
            if dg > 0.0 {
                dpos += dg;
            } else {
                dneg -= dg;
            }
            let ddg = (xx * xx / (sd * sd) - 1.0) * g;
            if ddg > 0.0 {
                ddpos += ddg;
            } else {
                ddneg -= ddg;
            }
            f_g.push(g);
            f_dg.push(dg);
            f_ddg.push(ddg);
        }
        f_g.iter_mut().for_each(|v| *v /= gs);
        f_dg.iter_mut()
            .for_each(|v| *v /= if *v > 0.0 { dpos } else { dneg });
        f_ddg
            .iter_mut()
            .for_each(|v| *v /= if *v > 0.0 { ddpos } else { ddneg });

        let hunt_lab = |rgb: [f32; 3]| {
            let [l, a, b] = xyz_to_lab_exact(linear_rgb_to_xyz(rgb));
            [l, 0.01 * l * a, 0.01 * l * b]
        };
        let (green, blue) = (hunt_lab([0.0, 1.0, 0.0]), hunt_lab([0.0, 0.0, 1.0]));
        let cmax = hyab(green, blue).powf(QC);
        Self {
            spatial_radius,
            g_y,
            g_cx,
            g_cz1,
            g_cz2,
            feature_radius,
            f_g,
            f_dg,
            f_ddg,
            cmax,
            pccmax: PC * cmax,
        }
    }

    /// Radius of the colour filters (taps `2 r + 1`).
    pub fn spatial_radius(&self) -> usize {
        self.spatial_radius
    }

    /// Radius of the feature filters (taps `2 r + 1`).
    pub fn feature_radius(&self) -> usize {
        self.feature_radius
    }

    /// Every filter's taps in one array, for a kernel on another device: the colour
    /// filters Y, Cx and Cz's two halves (`2 r_s + 1` each), then the feature filters'
    /// Gaussian, first and second derivative (`2 r_f + 1` each).
    pub fn packed_taps(&self) -> Vec<f32> {
        [
            &self.g_y,
            &self.g_cx,
            &self.g_cz1,
            &self.g_cz2,
            &self.f_g,
            &self.f_dg,
            &self.f_ddg,
        ]
        .into_iter()
        .flat_map(|v| v.iter().copied())
        .collect()
    }

    /// The colour remap's constants: `cmax = HyAB(green, blue)^q_c` and `p_c cmax`.
    pub fn remap(&self) -> (f32, f32) {
        (self.cmax, self.pccmax)
    }

    /// The widest radius of the two filter families: how far a pixel's support reaches.
    fn reach(&self) -> usize {
        self.spatial_radius.max(self.feature_radius)
    }
}

/// A reference image prepared for FLIP against many test images: the region of its mask
/// and its perceived values there.
pub struct FlipReference {
    kernels: std::sync::Arc<FlipKernels>,
    width: usize,
    height: usize,
    region: Region,
    perceived: Perceived,
}

/// Why FLIP cannot score a pair.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum FlipError {
    /// The byte or mask lengths do not match the size.
    #[error("FLIP: a {width} x {height} image needs {want} bytes and {pixels} mask entries, got {got} bytes and {mask} mask entries")]
    Size {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
        /// Bytes expected (`3 w h`).
        want: usize,
        /// Mask entries expected (`w h`).
        pixels: usize,
        /// Bytes given.
        got: usize,
        /// Mask entries given.
        mask: usize,
    },
    /// The mask selects no pixel: no mean exists.
    #[error("FLIP: the mask selects no pixel")]
    EmptyMask,
}

impl FlipReference {
    /// Prepares the 8-bit sRGB image `rgb8` (`width x height`, interleaved RGB, row-major)
    /// for errors over the pixels of `mask` (row-major, at least one `true`).
    pub fn new(
        kernels: std::sync::Arc<FlipKernels>,
        rgb8: &[u8],
        width: usize,
        height: usize,
        mask: &[bool],
    ) -> Result<Self, FlipError> {
        check_size(rgb8, width, height, mask)?;
        let region = Region::of(mask, width, height, kernels.reach());
        if region.spans.is_empty() {
            return Err(FlipError::EmptyMask);
        }
        let perceived =
            SCRATCH.with_borrow_mut(|s| perceive_image(&kernels, rgb8, width, height, &region, s));
        Ok(Self {
            kernels,
            width,
            height,
            region,
            perceived,
        })
    }

    /// The FLIP error of every pixel of the spans of the mask, in row order (columns from
    /// each row's first to its last mask pixel).
    fn errors<R>(&self, test: &[u8], read: impl FnOnce(&[f32]) -> R) -> R {
        let k = &*self.kernels;
        SCRATCH.with_borrow_mut(|s| {
            test_errors(
                k,
                &self.perceived,
                test,
                self.width,
                self.height,
                &self.region,
                s,
            );
            read(&s.errors)
        })
    }

    /// The mean FLIP error of `test` (the reference's size, 8-bit sRGB) over the mask's
    /// pixels, summed in f64 in row order.
    pub fn mean(&self, test: &[u8], mask: &[bool]) -> Result<f64, FlipError> {
        check_size(test, self.width, self.height, mask)?;
        let (sum, n) = self.errors(test, |errors| {
            let (mut sum, mut n, mut at) = (0.0f64, 0usize, 0usize);
            for &(y, a, b) in &self.region.spans {
                for (x, &e) in (a..b).zip(&errors[at..at + b - a]) {
                    if mask[y * self.width + x] {
                        sum += f64::from(e);
                        n += 1;
                    }
                }
                at += b - a;
            }
            (sum, n)
        });
        if n == 0 {
            return Err(FlipError::EmptyMask);
        }
        Ok(sum / n as f64)
    }

    /// The error map of `test`: FLIP at each pixel of the mask, 0 elsewhere.
    pub fn map(&self, test: &[u8], mask: &[bool]) -> Result<Vec<f32>, FlipError> {
        check_size(test, self.width, self.height, mask)?;
        Ok(self.errors(test, |errors| {
            let mut map = vec![0.0; self.width * self.height];
            let mut at = 0;
            for &(y, a, b) in &self.region.spans {
                for (x, &e) in (a..b).zip(&errors[at..at + b - a]) {
                    if mask[y * self.width + x] {
                        map[y * self.width + x] = e;
                    }
                }
                at += b - a;
            }
            map
        }))
    }
}

fn check_size(rgb8: &[u8], width: usize, height: usize, mask: &[bool]) -> Result<(), FlipError> {
    let pixels = width * height;
    if rgb8.len() != 3 * pixels || mask.len() != pixels {
        return Err(FlipError::Size {
            width,
            height,
            want: 3 * pixels,
            pixels,
            got: rgb8.len(),
            mask: mask.len(),
        });
    }
    Ok(())
}

/// The FLIP error map of `test` against `reference` (8-bit sRGB, `width x height`) at
/// `ppd` pixels per degree, every pixel scored.
pub fn flip_map(
    reference: &[u8],
    test: &[u8],
    width: usize,
    height: usize,
    ppd: f32,
) -> Result<Vec<f32>, FlipError> {
    let mask = vec![true; width * height];
    FlipReference::new(
        std::sync::Arc::new(FlipKernels::new(ppd)),
        reference,
        width,
        height,
        &mask,
    )?
    .map(test, &mask)
}

/// [`flip_map`] of every pair `(reference, test)` with the filters of `kernels`, pairs in
/// parallel (threads across images; each pair's work is one thread's).
pub fn flip_maps(
    kernels: &FlipKernels,
    pairs: &[(&[u8], &[u8])],
    width: usize,
    height: usize,
) -> Result<Vec<Vec<f32>>, FlipError> {
    use rayon::prelude::*;
    let kernels = std::sync::Arc::new(kernels.clone());
    let mask = vec![true; width * height];
    pairs
        .par_iter()
        .map(|(r, t)| FlipReference::new(kernels.clone(), r, width, height, &mask)?.map(t, &mask))
        .collect()
}

#[cfg(test)]
mod tests;
