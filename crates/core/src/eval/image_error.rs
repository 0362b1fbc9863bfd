//! Display mapping, normalised image error and error heatmaps (SPEC section 7, paper
//! Fig. 4b and Fig. 5).
//!
//! Display mapping of a linear value `v`: `clamp((v * 2^E)^(1/g), 0, 1)` with exposure `E`
//! and gamma `g` (paper Fig. 5: `E = 0`, `g = 2.2`). No further sRGB curve is applied.
//! The normalised image error between two renders is the mean, over sphere pixels and
//! colour channels, of the absolute difference of their display-mapped values; it lies in
//! `[0, 1]`.

use crate::eval::render::{Image, RenderError};

/// Display mapping parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DisplayParams {
    /// Exposure `E` in stops: values are scaled by `2^E` before the gamma. Default 0.
    pub exposure: f64,
    /// Gamma `g`: the scaled value is raised to `1/g`. Default 2.2; must be finite and > 0.
    pub gamma: f64,
}

impl Default for DisplayParams {
    fn default() -> Self {
        DisplayParams {
            exposure: 0.0,
            gamma: 2.2,
        }
    }
}

impl DisplayParams {
    /// Sets the exposure in stops.
    pub fn with_exposure(mut self, exposure: f64) -> Self {
        self.exposure = exposure;
        self
    }

    /// Sets the gamma.
    pub fn with_gamma(mut self, gamma: f64) -> Self {
        self.gamma = gamma;
        self
    }

    /// Validates the parameters.
    pub fn check(&self) -> Result<(), RenderError> {
        if !self.exposure.is_finite() {
            return Err(RenderError::InvalidParam {
                name: "exposure",
                value: self.exposure.to_string(),
                expected: "a finite number of stops",
            });
        }
        if !(self.gamma.is_finite() && self.gamma > 0.0) {
            return Err(RenderError::InvalidParam {
                name: "gamma",
                value: self.gamma.to_string(),
                expected: "a finite number > 0",
            });
        }
        Ok(())
    }

    /// Maps a linear value to `[0, 1]`: `clamp((v * 2^E)^(1/g), 0, 1)`. Negative and NaN
    /// values map to 0.
    pub fn map(&self, v: f64) -> f64 {
        if v == 0.0 && self.gamma > 0.0 {
            // The background and black channels, without the power: the same bits
            // (`max(0 x 2^E, 0)^(1 / g) = +0` for any E and any g > 0).
            return 0.0;
        }
        let s = self.scaled(v);
        if self.gamma == 2.2 {
            // The default gamma: the table-driven power, within 3 units in the last place
            // of the C library's (`eval::fastmath`); 1 from 1 up (`s^(1/g) >= 1`).
            if s >= 1.0 {
                return 1.0;
            }
            return super::fastmath::display_pow().pow(s).min(1.0);
        }
        s.powf(1.0 / self.gamma).min(1.0)
    }

    /// `max(v 2^E, 0)`: the value before the gamma (`max(NaN, 0) = 0`); `v` itself
    /// (the same bits) at exposure 0.
    #[inline]
    fn scaled(&self, v: f64) -> f64 {
        if self.exposure == 0.0 {
            v.max(0.0)
        } else {
            (v * self.exposure.exp2()).max(0.0)
        }
    }

    /// [`map`](Self::map) of every value of `values` (the same bits), the default gamma's
    /// powers four at a time.
    pub fn map_all(&self, values: &[f32]) -> Vec<f64> {
        if self.gamma != 2.2 {
            return values.iter().map(|&v| self.map(f64::from(v))).collect();
        }
        let s: Vec<f64> = values.iter().map(|&v| self.scaled(f64::from(v))).collect();
        let mut out = vec![0.0; s.len()];
        super::fastmath::display_pow().pow_slice(&s, &mut out);
        for (o, &x) in out.iter_mut().zip(&s) {
            // `map`'s order: 0 for 0 (the power gives +0 there too), 1 from 1 up.
            *o = if x >= 1.0 { 1.0 } else { o.min(1.0) };
        }
        out
    }

    /// [`map`](Self::map) quantised to 8 bits: `round(255 * map(v))`.
    pub fn map_u8(&self, v: f64) -> u8 {
        (self.map(v) * 255.0).round() as u8
    }
}

/// An 8-bit RGB image (display-mapped render or heatmap).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Rgb8Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGB, interleaved, row-major, row 0 at the top: `3 * width * height` bytes.
    pub data: Vec<u8>,
}

/// The display-mapped 8-bit version of a render (every pixel, on the sphere or not).
pub fn display_image(image: &Image, display: &DisplayParams) -> Result<Rgb8Image, RenderError> {
    image.check()?;
    display.check()?;
    Ok(Rgb8Image {
        width: image.width,
        height: image.height,
        data: image
            .data
            .iter()
            .map(|&v| display.map_u8(f64::from(v)))
            .collect(),
    })
}

/// Two images of the same size and the same sphere mask, or the error naming the first
/// difference.
pub(crate) fn same_shape(a: &Image, b: &Image) -> Result<(), RenderError> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(RenderError::SizeMismatch {
            a_width: a.width,
            a_height: a.height,
            b_width: b.width,
            b_height: b.height,
        });
    }
    if let Some(i) = a.mask.iter().zip(&b.mask).position(|(x, y)| x != y) {
        let w = a.width as usize;
        return Err(RenderError::MaskMismatch {
            col: (i % w) as u32,
            row: (i / w) as u32,
        });
    }
    Ok(())
}

/// Per-pixel error: the mean over the three channels of `|map(a) - map(b)|`, row-major;
/// 0 off the sphere. Errors when the images differ in size or mask or are malformed.
pub fn pixel_errors(
    a: &Image,
    b: &Image,
    display: &DisplayParams,
) -> Result<Vec<f64>, RenderError> {
    a.check()?;
    b.check()?;
    display.check()?;
    same_shape(a, b)?;
    let (da, db) = (display.map_all(&a.data), display.map_all(&b.data));
    let errors = a
        .mask
        .iter()
        .zip(da.chunks_exact(3).zip(db.chunks_exact(3)))
        .map(|(&on, (pa, pb))| {
            if !on {
                return 0.0;
            }
            let sum: f64 = pa.iter().zip(pb).map(|(&x, &y)| (x - y).abs()).sum();
            sum / 3.0
        })
        .collect();
    Ok(errors)
}

/// Normalised image error: mean over sphere pixels and channels of
/// `|map(a) - map(b)|` (paper Fig. 4b, Fig. 5). Errors when the images differ in size or
/// mask, are malformed, or have no sphere pixel.
pub fn normalized_image_error(
    a: &Image,
    b: &Image,
    display: &DisplayParams,
) -> Result<f64, RenderError> {
    let errors = pixel_errors(a, b, display)?;
    let count = a.sphere_pixels();
    if count == 0 {
        return Err(RenderError::EmptyMask);
    }
    let sum: f64 = errors
        .iter()
        .zip(&a.mask)
        .filter(|&(_, &on)| on)
        .map(|(e, _)| e)
        .sum();
    Ok(sum / count as f64)
}

/// The error value that maps to the top of the heatmap's colour scale.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum HeatmapScale {
    /// The largest per-pixel error in the image (the default). When the images are equal
    /// every sphere pixel gets the bottom colour.
    #[default]
    MaxError,
    /// A fixed error value (finite, > 0), so heatmaps of several materials share a scale.
    Fixed(f64),
}

/// Heatmap of the per-pixel error ([`pixel_errors`]) through [`viridis`], with
/// `t = error / scale` clamped to `[0, 1]`; pixels off the sphere are black.
pub fn heatmap(
    a: &Image,
    b: &Image,
    display: &DisplayParams,
    scale: HeatmapScale,
) -> Result<Rgb8Image, RenderError> {
    let errors = pixel_errors(a, b, display)?;
    let max = match scale {
        HeatmapScale::MaxError => errors.iter().copied().fold(0.0, f64::max),
        HeatmapScale::Fixed(s) => {
            if !(s.is_finite() && s > 0.0) {
                return Err(RenderError::InvalidParam {
                    name: "heatmap scale",
                    value: s.to_string(),
                    expected: "a finite error value > 0",
                });
            }
            s
        }
    };
    let mut data = Vec::with_capacity(3 * errors.len());
    for (&e, &on) in errors.iter().zip(&a.mask) {
        if !on {
            data.extend_from_slice(&[0, 0, 0]);
            continue;
        }
        let t = if max > 0.0 { e / max } else { 0.0 };
        data.extend(viridis(t).iter().map(|&c| (c * 255.0).round() as u8));
    }
    Ok(Rgb8Image {
        width: a.width,
        height: a.height,
        data,
    })
}

/// Matplotlib's viridis colour map (van der Walt, Smith and Firing, 2015; CC0) sampled at
/// 16 evenly spaced points: entries `0, 17, 34, ..., 255` of its 256-entry table.
pub const VIRIDIS: [[f64; 3]; 16] = [
    [0.267004, 0.004874, 0.329415],
    [0.282656, 0.100196, 0.422160],
    [0.277134, 0.185228, 0.489898],
    [0.253935, 0.265254, 0.529983],
    [0.221989, 0.339161, 0.548752],
    [0.190631, 0.407061, 0.556089],
    [0.163625, 0.471133, 0.558148],
    [0.139147, 0.533812, 0.555298],
    [0.120565, 0.596422, 0.543611],
    [0.134692, 0.658636, 0.517649],
    [0.208030, 0.718701, 0.472873],
    [0.327796, 0.773980, 0.406640],
    [0.477504, 0.821444, 0.318195],
    [0.647257, 0.858400, 0.209861],
    [0.824940, 0.884720, 0.106217],
    [0.993248, 0.906157, 0.143936],
];

/// Viridis colour (linear interpolation between the [`VIRIDIS`] control points) for
/// `t` in `[0, 1]` (clamped; NaN maps to 0): dark purple at 0, yellow at 1.
pub fn viridis(t: f64) -> [f64; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let s = t * (VIRIDIS.len() - 1) as f64;
    let i = (s.floor() as usize).min(VIRIDIS.len() - 2);
    let f = s - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    [
        a[0] + f * (b[0] - a[0]),
        a[1] + f * (b[1] - a[1]),
        a[2] + f * (b[2] - a[2]),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn constant(size: u32, v: [f32; 3]) -> Image {
        let mut img = Image::black(size, size);
        for (p, &on) in img.data.chunks_exact_mut(3).zip(&img.mask) {
            if on {
                p.copy_from_slice(&v);
            }
        }
        img
    }

    #[test]
    fn default_display() {
        let d = DisplayParams::default();
        assert_eq!((d.exposure, d.gamma), (0.0, 2.2));
        assert!(d.check().is_ok());
    }

    #[test]
    fn rejects_bad_gamma() {
        for g in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let err = DisplayParams::default().with_gamma(g).check().unwrap_err();
            assert!(
                matches!(err, RenderError::InvalidParam { name: "gamma", .. }),
                "{g}"
            );
        }
    }

    #[test]
    fn rejects_bad_exposure() {
        let err = DisplayParams::default()
            .with_exposure(f64::NAN)
            .check()
            .unwrap_err();
        assert!(matches!(
            err,
            RenderError::InvalidParam {
                name: "exposure",
                ..
            }
        ));
    }

    #[test]
    fn display_map_by_hand() {
        let d = DisplayParams::default();
        assert_eq!(d.map(0.0), 0.0);
        assert_eq!(d.map(1.0), 1.0);
        assert_eq!(d.map(4.0), 1.0);
        assert_eq!(d.map(-0.5), 0.0);
        assert_eq!(d.map(f64::NAN), 0.0);
        assert!((d.map(0.25) - 0.25f64.powf(1.0 / 2.2)).abs() < 1e-15);
        let e = DisplayParams {
            exposure: 1.0,
            gamma: 2.0,
        };
        assert!((e.map(0.125) - 0.5).abs() < 1e-15); // (0.125 * 2)^(1/2)
        assert_eq!(e.map_u8(0.125), 128);
        assert_eq!(e.map_u8(10.0), 255);
    }

    #[test]
    fn error_with_itself_is_zero() {
        let mut img = constant(32, [0.3, 0.1, 0.7]);
        img.data[3 * (16 * 32 + 16)] = 5.0;
        assert_eq!(
            normalized_image_error(&img, &img, &DisplayParams::default()).unwrap(),
            0.0
        );
    }

    #[test]
    fn error_of_constant_images_by_hand() {
        let a = constant(16, [0.25, 0.5, 1.0]);
        let b = constant(16, [0.0, 0.5, 2.0]);
        // Channel errors: 0.25^(1/2.2) - 0, 0, 1 - 1 (both clamp); mean over channels.
        let want = 0.25f64.powf(1.0 / 2.2) / 3.0;
        let got = normalized_image_error(&a, &b, &DisplayParams::default()).unwrap();
        assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        // Exposure -1, gamma 1: channel errors 0.125, 0, 0.5 (1.0 vs 0.5 after scaling, 2.0 -> 1).
        let d = DisplayParams {
            exposure: -1.0,
            gamma: 1.0,
        };
        let got = normalized_image_error(&a, &b, &d).unwrap();
        assert!((got - (0.125 + 0.5) / 3.0).abs() < 1e-12, "{got}");
        // Symmetric.
        assert_eq!(got, normalized_image_error(&b, &a, &d).unwrap());
    }

    #[test]
    fn off_sphere_pixels_are_ignored() {
        let a = constant(16, [0.5; 3]);
        let mut b = a.clone();
        let off = b.mask.iter().position(|&m| !m).unwrap();
        b.data[3 * off] = 100.0;
        assert_eq!(
            normalized_image_error(&a, &b, &DisplayParams::default()).unwrap(),
            0.0
        );
    }

    #[test]
    fn size_mismatch_is_an_error() {
        let err = normalized_image_error(
            &constant(8, [0.0; 3]),
            &constant(9, [0.0; 3]),
            &DisplayParams::default(),
        )
        .unwrap_err();
        assert!(matches!(
            err,
            RenderError::SizeMismatch {
                a_width: 8,
                b_width: 9,
                ..
            }
        ));
    }

    #[test]
    fn mask_mismatch_is_an_error() {
        let a = constant(8, [0.0; 3]);
        let mut b = a.clone();
        b.mask[3 * 8 + 1] = !b.mask[3 * 8 + 1];
        let err = normalized_image_error(&a, &b, &DisplayParams::default()).unwrap_err();
        assert!(
            matches!(err, RenderError::MaskMismatch { col: 1, row: 3 }),
            "{err}"
        );
    }

    #[test]
    fn empty_mask_is_an_error() {
        let mut a = constant(4, [0.0; 3]);
        a.mask.iter_mut().for_each(|m| *m = false);
        let err = normalized_image_error(&a, &a, &DisplayParams::default()).unwrap_err();
        assert!(matches!(err, RenderError::EmptyMask));
    }

    #[test]
    fn viridis_endpoints_and_interpolation() {
        assert_eq!(viridis(0.0), VIRIDIS[0]);
        assert_eq!(viridis(1.0), VIRIDIS[15]);
        assert_eq!(viridis(-3.0), VIRIDIS[0]);
        assert_eq!(viridis(7.0), VIRIDIS[15]);
        assert_eq!(viridis(f64::NAN), VIRIDIS[0]);
        let mid = viridis(0.5 / 15.0);
        for c in 0..3 {
            assert!((mid[c] - 0.5 * (VIRIDIS[0][c] + VIRIDIS[1][c])).abs() < 1e-15);
        }
        // Perceptual map: luminance-ish (green) increases monotonically.
        for w in VIRIDIS.windows(2) {
            assert!(w[1][1] > w[0][1]);
        }
    }

    #[test]
    fn heatmap_colours() {
        let a = constant(16, [0.0; 3]);
        let mut b = a.clone();
        // One pixel with the largest error (1.0 in every channel), one at half of it.
        let on: Vec<usize> = (0..256).filter(|&i| a.mask[i]).collect();
        b.data[3 * on[0]..3 * on[0] + 3].copy_from_slice(&[1.0; 3]);
        let half = 0.5f32.powf(2.2);
        b.data[3 * on[1]..3 * on[1] + 3].copy_from_slice(&[half; 3]);
        let h = heatmap(&a, &b, &DisplayParams::default(), HeatmapScale::MaxError).unwrap();
        assert_eq!((h.width, h.height, h.data.len()), (16, 16, 768));
        let px = |i: usize| [h.data[3 * i], h.data[3 * i + 1], h.data[3 * i + 2]];
        let u8s = |c: [f64; 3]| c.map(|v| (v * 255.0).round() as u8);
        assert_eq!(px(on[0]), u8s(VIRIDIS[15]));
        assert_eq!(px(on[2]), u8s(VIRIDIS[0]));
        let mid = u8s(viridis(0.5));
        for (got, want) in px(on[1]).iter().zip(&mid) {
            assert!((i32::from(*got) - i32::from(*want)).abs() <= 1);
        }
        let off = (0..256).find(|&i| !a.mask[i]).unwrap();
        assert_eq!(px(off), [0, 0, 0]);
        // Fixed scale 2: the worst pixel sits at t = 0.5.
        let h = heatmap(&a, &b, &DisplayParams::default(), HeatmapScale::Fixed(2.0)).unwrap();
        assert_eq!(px_of(&h, on[0]), mid);
        assert!(heatmap(&a, &b, &DisplayParams::default(), HeatmapScale::Fixed(0.0)).is_err());
        // Equal images: all sphere pixels get the bottom colour.
        let h = heatmap(&a, &a, &DisplayParams::default(), HeatmapScale::MaxError).unwrap();
        assert_eq!(px_of(&h, on[0]), u8s(VIRIDIS[0]));
    }

    fn px_of(h: &Rgb8Image, i: usize) -> [u8; 3] {
        [h.data[3 * i], h.data[3 * i + 1], h.data[3 * i + 2]]
    }

    #[test]
    fn display_image_maps_every_sample() {
        let img = constant(8, [0.25, 1.0, 3.0]);
        let d = display_image(&img, &DisplayParams::default()).unwrap();
        let i = img.mask.iter().position(|&m| m).unwrap();
        assert_eq!(
            px_of(&d, i),
            [(0.25f64.powf(1.0 / 2.2) * 255.0).round() as u8, 255, 255]
        );
        assert_eq!(d.data.len(), 192);
    }
}
