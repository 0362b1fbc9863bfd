//! Error heatmaps as figures: the heatmap of [`brdf_basis::eval::image_error::heatmap`] with a
//! colour bar beside it, labelled with the quantity and the values of its ends, so that a
//! heatmap PNG can be read on its own.

pub(crate) use super::colour_bar::with_colour_bar;
use super::{with_text, PlotError};
use brdf_basis::eval::image_error::{
    heatmap, pixel_errors, DisplayParams, HeatmapScale, Rgb8Image,
};
use brdf_basis::eval::render::Image;

/// What the colour bar measures.
pub(crate) const QUANTITY: &str = brdf_basis::io::image::HEATMAP_QUANTITY;

/// The value at the top of the colour scale: `scale`'s fixed value, or the largest
/// per-pixel error (0 when the images are equal).
pub(crate) fn scale_top(
    a: &Image,
    b: &Image,
    display: &DisplayParams,
    scale: HeatmapScale,
) -> Result<f64, PlotError> {
    match scale {
        HeatmapScale::Fixed(s) => Ok(s),
        HeatmapScale::MaxError => Ok(pixel_errors(a, b, display)
            .map_err(|e| draw_error(e.to_string()))?
            .into_iter()
            .fold(0.0, f64::max)),
    }
}

fn draw_error(message: String) -> PlotError {
    PlotError::Draw {
        stem: "heatmap".into(),
        message,
    }
}

/// The heatmap of `a` against `b` with a colour bar from 0 (bottom) to the scale's top,
/// both ends labelled, and [`QUANTITY`] above (labels only when a font is available).
pub(crate) fn heatmap_with_colour_bar(
    a: &Image,
    b: &Image,
    display: &DisplayParams,
    scale: HeatmapScale,
) -> Result<Rgb8Image, PlotError> {
    let heat = heatmap(a, b, display, scale).map_err(|e| draw_error(e.to_string()))?;
    let top = scale_top(a, b, display, scale)?;
    with_colour_bar(&heat, top, QUANTITY, with_text()).map_err(draw_error)
}
