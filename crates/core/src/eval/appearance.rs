//! Appearance metrics of a fit (SPEC 11): log-RMSE on the grid, and on renders under four
//! lights the normalised image error (SPEC 7), the mean CIEDE2000 difference, the mean LDR
//! FLIP and the mean ΔE_ITP (ITU-R BT.2124, [`super::ictcp`]; issue 50).
//!
//! Conventions, where SPEC 11 leaves a choice:
//! * renders are SPEC 7's sphere at [`RENDER_SIZE`]^2 pixels, displayed with exposure 0 and
//!   gamma 2.2, clamped; the display values are taken as sRGB for CIELAB
//!   ([`super::color`]) and quantised to 8 bits for FLIP (what an LDR FLIP compares);
//! * CIEDE2000 and FLIP are averaged over the sphere's pixels (the background is black in
//!   both images; FLIP's error map is computed on the whole image, so that its filters see
//!   the sphere's silhouette, and then averaged over the sphere);
//! * FLIP is the project's own ([`super::flip`]: f32, separable passes, vectorised, each
//!   reference prepared once) at [`FLIP_PIXELS_PER_DEGREE`]; NVIDIA's implementation (the
//!   `nv-flip` crate) is its test and bench peer (per-image means within 1e-4, SPEC 11);
//! * log-RMSE is the root of the weighted mean (cell weights of the fit mask; with uniform
//!   weights, the plain mean over cells) over cells and channels of
//!   `(log(1 + max(fhat, 0) c) - log(1 + max(f, 0) c))^2`, `c = max(cos theta_i, 0)`.

use super::color::{ciede2000_slice, srgb_to_lab_all, Lab};
use super::fastmath::ln_1p;
use super::flip::{FlipKernels, FlipReference};
use super::image_error::{normalized_image_error, same_shape, DisplayParams};
use super::render::{Image, RenderError};

/// The lights of SPEC 11, `(theta, phi)` in degrees; the first is the paper's (SPEC 7).
pub const LIGHTS: [(f64, f64); 4] = [(45.0, 45.0), (0.0, 0.0), (60.0, 180.0), (75.0, 270.0)];

/// Render size of the appearance metrics (pixels per side).
pub const RENDER_SIZE: u32 = 256;

/// The size of the sphere renders [`render_looks`] counts (pixels per side): a look per
/// pixel, enough to spread over the MERL cells the renders see.
pub const LOOK_SIZE: u32 = 64;

/// How much the renders of the appearance metrics look at each cell of `cells`: over the
/// four [`LIGHTS`]' sphere renders ([`LOOK_SIZE`] px, SPEC 7's camera), the sum of
/// `cos^2 theta_i` over the lit pixels whose MERL cell, snapped down to the set's stride,
/// is that cell (a pixel's radiance is `f cos theta_i` times the light, so a reflectance
/// error there counts with that square), normalised to mean 1 over `cells` (zeros when no
/// pixel looks at any). Summed in pixel order: the same bits on every machine.
pub fn render_looks(cells: &crate::merl::CellSet) -> Result<Vec<f64>, RenderError> {
    use crate::merl::{flat, lookup, unflat};
    let s = cells.stride.max(1);
    let mut hits = std::collections::HashMap::<u32, f64>::new();
    for (t, p) in LIGHTS {
        let rp = super::render::RenderParams::default()
            .with_size(LOOK_SIZE)
            .with_light(t, p);
        let seen = std::sync::Mutex::new(Vec::new());
        super::render::render_sphere_indexed(&rp, &|px, wi, wo| {
            if wi[2] > 0.0 && wo[2] > 0.0 {
                let (i, j, k) = unflat(lookup(wi, wo));
                let c = flat(i - i % s, j - j % s, k - k % s) as u32;
                seen.lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .push((px, c, wi[2] * wi[2]));
            }
            [0.0; 3]
        })?;
        let mut seen = seen.into_inner().unwrap_or_else(|e| e.into_inner());
        seen.sort_by_key(|x| x.0);
        for (_, c, w) in seen {
            *hits.entry(c).or_insert(0.0) += w;
        }
    }
    let raw: Vec<f64> = cells
        .cells
        .iter()
        .map(|c| hits.get(c).copied().unwrap_or(0.0))
        .collect();
    let mean = raw.iter().sum::<f64>() / raw.len().max(1) as f64;
    Ok(if mean > 0.0 {
        raw.iter().map(|h| h / mean).collect()
    } else {
        raw
    })
}

/// FLIP's viewing condition (SPEC 11): 67 pixels per degree (FLIP's default: a 0.7 m
/// distance to a 0.7 m wide 4K monitor).
pub const FLIP_PIXELS_PER_DEGREE: f32 = 67.0;

/// SPEC 11's render of the light `(theta, phi)` (degrees): [`RENDER_SIZE`] pixels.
pub(crate) fn render_params((theta, phi): (f64, f64)) -> super::render::RenderParams {
    super::render::RenderParams::default()
        .with_size(RENDER_SIZE)
        .with_light(theta, phi)
}

/// The image metrics of one render of a fit against the render of its target.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LightScores {
    /// The light's polar angle, degrees.
    pub theta: f64,
    /// The light's azimuth, degrees.
    pub phi: f64,
    /// Normalised image error (SPEC 7), in `[0, 1]`.
    pub image_error: f64,
    /// Mean CIEDE2000 difference over the sphere's pixels.
    pub ciede2000: f64,
    /// Mean LDR FLIP over the sphere's pixels, in `[0, 1]`.
    pub flip: f64,
    /// Mean ΔE_ITP (ITU-R BT.2124, [`super::ictcp`]) over the sphere's pixels.
    pub delta_e_itp: f64,
}

/// Every appearance metric of one fit: log-RMSE, and per light and averaged over the lights
/// the image metrics.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Appearance {
    /// log-RMSE on the grid.
    pub log_rmse: f64,
    /// Per light of [`LIGHTS`] (the paper's light first).
    pub lights: Vec<LightScores>,
    /// Mean over the lights of the image error.
    pub mean_image_error: f64,
    /// Mean over the lights of the mean CIEDE2000.
    pub mean_ciede2000: f64,
    /// Mean over the lights of the mean FLIP.
    pub mean_flip: f64,
    /// Mean over the lights of the mean ΔE_ITP.
    pub mean_delta_e_itp: f64,
}

impl Appearance {
    /// The metrics from the log-RMSE and the per-light scores (means over the lights).
    pub fn new(log_rmse: f64, lights: Vec<LightScores>) -> Self {
        let n = lights.len().max(1) as f64;
        let mean = |g: fn(&LightScores) -> f64| lights.iter().map(g).sum::<f64>() / n;
        Self {
            log_rmse,
            mean_image_error: mean(|l| l.image_error),
            mean_ciede2000: mean(|l| l.ciede2000),
            mean_flip: mean(|l| l.flip),
            mean_delta_e_itp: mean(|l| l.delta_e_itp),
            lights,
        }
    }

    /// The scores under the paper's light (45, 45).
    pub fn paper_light(&self) -> &LightScores {
        &self.lights[0]
    }
}

/// The display value of every channel of every pixel (SPEC 7's mapping).
fn display_values(img: &Image, d: &DisplayParams) -> Vec<f64> {
    d.map_all(&img.data)
}

/// Mean CIEDE2000 over the sphere's pixels between the display-mapped renders `a` and `b`.
///
/// The mean over the sphere's pixels (as `sphere_mean`) of [`super::color::ciede2000`] of the pixels'
/// [`super::color::srgb_to_lab`]: the same checks, the same bits and the same order of the
/// sum, the differences by [`ciede2000_slice`].
pub fn mean_ciede2000(a: &Image, b: &Image, d: &DisplayParams) -> Result<f64, RenderError> {
    normalized_image_error(a, b, d)?;
    let lab = |img: &Image| srgb_to_lab_all(&sphere_rgb(img, &display_values(img, d)));
    Ok(sum_ciede2000(&lab(a), &lab(b)) / a.sphere_pixels() as f64)
}

/// The sum of the CIEDE2000 differences of the pairs `(x[i], y[i])`, added in pixel order.
fn sum_ciede2000(x: &[Lab], y: &[Lab]) -> f64 {
    let mut de = vec![0.0; x.len()];
    ciede2000_slice(x, y, &mut de);
    let mut sum = 0.0;
    for d in de {
        sum += d;
    }
    sum
}

/// The mean over the sphere's pixels of `per_pixel` of the display values of `a` and `b`,
/// in pixel order, after the image error's checks (same sizes and masks, at least one
/// sphere pixel).
fn sphere_mean(
    a: &Image,
    b: &Image,
    d: &DisplayParams,
    per_pixel: impl Fn([f64; 3], [f64; 3]) -> f64,
) -> Result<f64, RenderError> {
    normalized_image_error(a, b, d)?;
    let (da, db) = (display_values(a, d), display_values(b, d));
    let (mut sum, mut n) = (0.0, 0usize);
    for (i, &on) in a.mask.iter().enumerate() {
        if on {
            let pa = [da[3 * i], da[3 * i + 1], da[3 * i + 2]];
            let pb = [db[3 * i], db[3 * i + 1], db[3 * i + 2]];
            sum += per_pixel(pa, pb);
            n += 1;
        }
    }
    Ok(sum / n as f64)
}

/// Mean LDR FLIP ([`super::flip`]) over the sphere's pixels between the 8-bit display
/// images of `reference` and `test`.
pub fn mean_flip(reference: &Image, test: &Image, d: &DisplayParams) -> Result<f64, RenderError> {
    normalized_image_error(reference, test, d)?;
    let to8 =
        |img: &Image| -> Vec<u8> { img.data.iter().map(|&v| d.map_u8(f64::from(v))).collect() };
    let prepared = prepare_flip(reference, &to8(reference))?;
    flip_mean(&prepared, &to8(test), &reference.mask)
}

/// The FLIP filters at SPEC 11's viewing condition, built once per process.
pub fn flip_kernels() -> std::sync::Arc<FlipKernels> {
    static KERNELS: std::sync::OnceLock<std::sync::Arc<FlipKernels>> = std::sync::OnceLock::new();
    KERNELS
        .get_or_init(|| std::sync::Arc::new(FlipKernels::new(FLIP_PIXELS_PER_DEGREE)))
        .clone()
}

/// `image`'s 8-bit display bytes prepared as a FLIP reference over its sphere.
fn prepare_flip(image: &Image, bytes: &[u8]) -> Result<FlipReference, RenderError> {
    let (w, h) = (image.width as usize, image.height as usize);
    FlipReference::new(flip_kernels(), bytes, w, h, &image.mask).map_err(flip_error)
}

/// The mean FLIP of the 8-bit `test` against a prepared reference over `mask`.
fn flip_mean(reference: &FlipReference, test: &[u8], mask: &[bool]) -> Result<f64, RenderError> {
    reference.mean(test, mask).map_err(flip_error)
}

/// A FLIP refusal as a render error (the images were checked before: an empty mask).
fn flip_error(e: super::flip::FlipError) -> RenderError {
    match e {
        super::flip::FlipError::EmptyMask => RenderError::EmptyMask,
        other => RenderError::Flip(other),
    }
}

/// The image metrics of `test` against `reference`, rendered under the light `(theta, phi)`
/// ([`Reference::scores`]: the values of [`normalized_image_error`], [`mean_ciede2000`]
/// and [`mean_flip`], to the bit).
pub fn light_scores(
    reference: &Image,
    test: &Image,
    light: (f64, f64),
) -> Result<LightScores, RenderError> {
    Reference::new(reference)?.scores(test, light)
}

/// A reference render prepared for [`Reference::scores`]: its display values, CIELAB
/// colours and 8-bit image computed once (the separate metric functions each map both
/// images again: five display mappings per image and light).
pub struct Reference<'a> {
    image: &'a Image,
    /// Display values of every channel of every pixel.
    display: Vec<f64>,
    /// CIELAB of every sphere pixel, in pixel order.
    lab: Vec<super::color::Lab>,
    /// ICtCp of every sphere pixel, in pixel order.
    itp: Vec<super::ictcp::Ictcp>,
    /// The 8-bit display image prepared for FLIP.
    flip: FlipReference,
}

impl<'a> Reference<'a> {
    /// Prepares `image` (checked: well-formed, at least one sphere pixel).
    pub fn new(image: &'a Image) -> Result<Self, RenderError> {
        image.check()?;
        if image.sphere_pixels() == 0 {
            return Err(RenderError::EmptyMask);
        }
        let d = DisplayParams::default();
        let display = display_values(image, &d);
        let lin = super::color::srgb_decode_all(&sphere_rgb(image, &display));
        let lab = super::color::lab_from_linear_all(&lin);
        let itp = super::ictcp::ictcp_from_linear_all(&lin);
        let flip = prepare_flip(image, &to_bytes(&display))?;
        Ok(Self {
            image,
            display,
            lab,
            itp,
            flip,
        })
    }

    /// The image metrics of `test` against this reference under the light `(theta, phi)`:
    /// each test pixel mapped once, then the sums of [`normalized_image_error`],
    /// [`mean_ciede2000`] and [`mean_flip`] in their order (the same bits).
    pub fn scores(
        &self,
        test: &Image,
        (theta, phi): (f64, f64),
    ) -> Result<LightScores, RenderError> {
        let (a, d) = (self.image, DisplayParams::default());
        // Sizes, masks and form: the image error's checks.
        a.check()?;
        test.check()?;
        same_shape(a, test)?;
        let td = display_values(test, &d);
        let count = a.sphere_pixels();
        let errors: Vec<f64> = a
            .mask
            .iter()
            .enumerate()
            .filter(|&(_, &on)| on)
            .map(|(i, _)| {
                let sum: f64 = (0..3)
                    .map(|c| (self.display[3 * i + c] - td[3 * i + c]).abs())
                    .sum();
                sum / 3.0
            })
            .collect();
        let image_error = errors.iter().sum::<f64>() / count as f64;
        // The sphere's colours decoded once for CIELAB and ICtCp.
        let lin = super::color::srgb_decode_all(&sphere_rgb(test, &td));
        let test_lab = super::color::lab_from_linear_all(&lin);
        let ciede = sum_ciede2000(&self.lab, &test_lab) / self.lab.len() as f64;
        let mut sum = 0.0;
        for (a, b) in self
            .itp
            .iter()
            .zip(super::ictcp::ictcp_from_linear_all(&lin))
        {
            sum += super::ictcp::delta_e_itp(*a, b);
        }
        let itp = sum / self.itp.len() as f64;
        Ok(LightScores {
            theta,
            phi,
            image_error,
            ciede2000: ciede,
            flip: flip_mean(&self.flip, &to_bytes(&td), &a.mask)?,
            delta_e_itp: itp,
        })
    }
}

/// Display values quantised to 8 bits ([`DisplayParams::map_u8`] of the same values).
fn to_bytes(dv: &[f64]) -> Vec<u8> {
    dv.iter().map(|&v| (v * 255.0).round() as u8).collect()
}

/// The display values of the sphere pixels of `img` (`dv` of every pixel), in pixel order.
fn sphere_rgb(img: &Image, dv: &[f64]) -> Vec<f64> {
    let mut rgb = Vec::with_capacity(dv.len());
    for (&on, p) in img.mask.iter().zip(dv.chunks_exact(3)) {
        if on {
            rgb.extend_from_slice(p);
        }
    }
    rgb
}

/// Mean ΔE_ITP ([`super::ictcp`]) over the sphere's pixels between the display-mapped
/// renders `a` and `b`.
pub fn mean_delta_e_itp(a: &Image, b: &Image, d: &DisplayParams) -> Result<f64, RenderError> {
    use super::ictcp::{delta_e_itp, srgb_to_ictcp};
    sphere_mean(a, b, d, |pa, pb| {
        delta_e_itp(srgb_to_ictcp(pa), srgb_to_ictcp(pb))
    })
}

/// Running sums of the log-RMSE: add cells with [`LogSums::add`], then [`LogSums::value`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LogSums {
    /// `sum_s w_s (log(1 + max(fhat, 0) c) - log(1 + max(f, 0) c))^2` over cells and channels.
    pub squared: f64,
    /// `sum_s w_s` over cells and channels.
    pub weight: f64,
}

impl LogSums {
    /// Adds one cell and channel: fitted value `fit`, target value `target`, cell weight `w`
    /// and incoming cosine `cos_i`.
    #[inline]
    pub fn add(&mut self, fit: f64, target: f64, w: f64, cos_i: f64) {
        let c = cos_i.max(0.0);
        let d = ln_1p(fit.max(0.0) * c) - ln_1p(target.max(0.0) * c);
        self.squared += w * d * d;
        self.weight += w;
    }

    /// `log(1 + max(f, 0) c)` with `c = max(cos_i, 0)`: the target's term of [`Self::add`],
    /// for [`Self::add_against`] when one target is compared with many fits.
    #[inline]
    pub fn target_log(target: f64, cos_i: f64) -> f64 {
        ln_1p(target.max(0.0) * cos_i.max(0.0))
    }

    /// The terms `log(1 + max(v, 0) max(c, 0))` of many cells at once ([`Self::target_log`]
    /// of each, the same bits, four at a time): a fit's or a target's, for
    /// [`Self::add_logs`].
    pub fn logs(values: &[f64], cos_i: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; values.len()];
        Self::logs_into(values, cos_i, &mut Vec::new(), &mut out);
        out
    }

    /// [`Self::logs`] into `out` (of the same length as `values`), with `scratch` for the
    /// products: no allocation once `scratch` has grown.
    pub fn logs_into(values: &[f64], cos_i: &[f64], scratch: &mut Vec<f64>, out: &mut [f64]) {
        assert!(values.len() == cos_i.len() && values.len() == out.len());
        scratch.clear();
        scratch.extend(
            values
                .iter()
                .zip(cos_i)
                .map(|(&v, &c)| v.max(0.0) * c.max(0.0)),
        );
        super::fastmath::ln_1p_slice(scratch, out);
    }

    /// [`Self::add`] with the target's term given ([`Self::target_log`] of the target and
    /// `cos_i`): the same bits.
    #[inline]
    pub fn add_against(&mut self, fit: f64, target_log: f64, w: f64, cos_i: f64) {
        self.add_logs(ln_1p(fit.max(0.0) * cos_i.max(0.0)), target_log, w);
    }

    /// [`Self::add`] with both terms given ([`Self::logs`] or [`Self::target_log`] of the
    /// fit and of the target): the same bits.
    #[inline]
    pub fn add_logs(&mut self, fit_log: f64, target_log: f64, w: f64) {
        let d = fit_log - target_log;
        self.squared += w * d * d;
        self.weight += w;
    }

    /// Adds another set of sums.
    pub fn merge(&mut self, o: &LogSums) {
        self.squared += o.squared;
        self.weight += o.weight;
    }

    /// The log-RMSE (0 with no cell).
    pub fn value(&self) -> f64 {
        if self.weight > 0.0 {
            (self.squared / self.weight).sqrt()
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::render::{render_sphere, RenderParams};

    fn render(rgb: [f64; 3], light: (f64, f64)) -> Image {
        let p = RenderParams::default()
            .with_size(64)
            .with_light(light.0, light.1);
        render_sphere(&p, &move |_, _| rgb).unwrap()
    }

    #[test]
    fn equal_renders_score_zero_and_a_hue_shift_scores_more_than_a_small_grey_change() {
        let a = render([0.1, 0.2, 0.6], LIGHTS[0]);
        let s = light_scores(&a, &a, LIGHTS[0]).unwrap();
        assert_eq!((s.image_error, s.ciede2000, s.flip), (0.0, 0.0, 0.0));
        assert_eq!(s.delta_e_itp, 0.0);
        let hue = render([0.6, 0.2, 0.1], LIGHTS[0]);
        let grey = render([0.11, 0.21, 0.61], LIGHTS[0]);
        let h = light_scores(&a, &hue, LIGHTS[0]).unwrap();
        let g = light_scores(&a, &grey, LIGHTS[0]).unwrap();
        assert!(h.ciede2000 > 10.0 * g.ciede2000, "{h:?} {g:?}");
        assert!(h.flip > 5.0 * g.flip && h.flip <= 1.0, "{h:?} {g:?}");
        assert!(h.delta_e_itp > 10.0 * g.delta_e_itp, "{h:?} {g:?}");
    }

    /// The prepared reference gives the separate metric functions' values to the bit.
    #[test]
    fn prepared_reference_scores_equal_the_separate_metrics() {
        let d = DisplayParams::default();
        for light in LIGHTS {
            let p = RenderParams::default()
                .with_size(48)
                .with_light(light.0, light.1);
            let a = render_sphere(&p, &|wi, wo| {
                [0.2 + wi[0].abs(), 0.1 + 3.0 * wo[2].powi(8), 0.05 * wi[2]]
            })
            .unwrap();
            let b = render_sphere(&p, &|wi, _| [0.25, 0.12 + wi[1].abs(), 0.04]).unwrap();
            let s = light_scores(&a, &b, light).unwrap();
            assert_eq!(s.image_error, normalized_image_error(&a, &b, &d).unwrap());
            assert_eq!(s.ciede2000, mean_ciede2000(&a, &b, &d).unwrap());
            assert_eq!(s.flip, mean_flip(&a, &b, &d).unwrap());
            assert_eq!(s.delta_e_itp, mean_delta_e_itp(&a, &b, &d).unwrap());
            assert!(s.delta_e_itp > 0.0);
            assert!(s.image_error > 0.0 && s.ciede2000 > 0.0 && s.flip > 0.0);
        }
        let small = render([0.1, 0.2, 0.3], LIGHTS[0]);
        let other = RenderParams::default().with_size(32);
        let b = render_sphere(&other, &|_, _| [0.1; 3]).unwrap();
        assert!(light_scores(&small, &b, LIGHTS[0]).is_err());
    }

    #[test]
    fn log_rmse_of_a_constant_factor_is_the_log_of_its_effect() {
        let mut s = LogSums::default();
        // fit e - 1 against 0 at c = 1: log(e) - log(1) = 1 on every cell.
        for _ in 0..10 {
            s.add(std::f64::consts::E - 1.0, 0.0, 0.1, 1.0);
        }
        assert!((s.value() - 1.0).abs() < 1e-12);
        // A negative fit counts as 0; a cell below the horizon compares nothing.
        let mut t = LogSums::default();
        t.add(-5.0, 0.0, 1.0, 0.5);
        t.add(3.0, 1.0, 1.0, -0.2);
        assert_eq!(t.value(), 0.0);
    }

    /// The target's term computed once gives the sums of [`LogSums::add`] to the bit.
    #[test]
    fn sums_against_a_prepared_target_log_are_the_same_bits() {
        let (mut a, mut b) = (LogSums::default(), LogSums::default());
        for i in 0..200 {
            let x = f64::from(i);
            let (fit, target) = ((x * 0.37).sin() * 3.0, (x * 0.11).cos() * 40.0);
            let (w, cos) = (0.5 + (x * 0.7).sin().abs(), (x * 0.05).cos());
            a.add(fit, target, w, cos);
            b.add_against(fit, LogSums::target_log(target, cos), w, cos);
        }
        assert_eq!(a, b);
        assert!(a.value() > 0.0);
    }
}
