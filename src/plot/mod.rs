//! Figures of the paper as SVG and PNG (plotters): the contributions histogram (Fig. 2),
//! DB box plots (Fig. 3), DB against k, Nemenyi critical-difference diagrams, errors per
//! material (Fig. 4), the showcase comparison (Fig. 5) and specular-lobe polar plots.
//!
//! Text needs a font: [`font_available`] registers DejaVu Sans (or Liberation Sans) from
//! the usual system paths at run time. Without one, figures are drawn without text (and
//! the caller says so); nothing needs fontconfig at build time.

pub mod charts;
pub mod lobes;
pub mod showcase;

use crate::eval::image_error::Rgb8Image;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::sync::OnceLock;

/// A figure: SVG text and a PNG raster of the same drawing.
#[derive(Clone, Debug)]
pub struct Figure {
    /// File stem (e.g. `fig2-contributions`).
    pub stem: String,
    /// SVG document.
    pub svg: String,
    /// Raster of the same figure.
    pub png: Rgb8Image,
}

/// Errors while drawing.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// plotters failed.
    #[error("drawing {stem}: {message}")]
    Draw {
        /// Figure.
        stem: String,
        /// plotters' message.
        message: String,
    },
    /// Nothing to plot.
    #[error("{0}: no data to plot")]
    NoData(String),
}

/// Where a sans-serif font is looked for.
pub const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/Library/Fonts/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

/// Registers the first font of [`FONT_PATHS`] (or `BRDF_BASIS_FONT`) as `sans-serif`, once;
/// returns its path, or `None` when no font could be loaded (figures then have no text;
/// `BRDF_BASIS_FONT=none` asks for that).
pub fn font_available() -> Option<&'static str> {
    static FONT: OnceLock<Option<String>> = OnceLock::new();
    FONT.get_or_init(|| {
        let env = std::env::var("BRDF_BASIS_FONT").ok();
        if env.as_deref() == Some("none") {
            return None; // text-free figures on request (tests the no-font path)
        }
        let candidates = env
            .iter()
            .map(String::as_str)
            .chain(FONT_PATHS.iter().copied());
        for p in candidates {
            if let Ok(bytes) = std::fs::read(p) {
                // plotters keeps fonts for the life of the process.
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                    return Some(p.to_string());
                }
            }
        }
        None
    })
    .as_deref()
}

/// Whether figures get text (a font was found).
pub fn with_text() -> bool {
    font_available().is_some()
}

/// A drawing that can go to any plotters back-end.
pub trait Draw {
    /// Draws on `root`; `text` is false when no font is available.
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String>;
}

/// Draws `d` at `size` into an SVG string and an RGB raster.
pub fn figure<D: Draw>(stem: &str, size: (u32, u32), d: &D) -> Result<Figure, PlotError> {
    let text = with_text();
    let err = |message: String| PlotError::Draw {
        stem: stem.to_string(),
        message,
    };
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        d.draw(&root, text).map_err(err)?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    let mut buf = vec![0u8; 3 * size.0 as usize * size.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        d.draw(&root, text).map_err(err)?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(Figure {
        stem: stem.to_string(),
        svg,
        png: Rgb8Image {
            width: size.0,
            height: size.1,
            data: buf,
        },
    })
}

/// Colour of series `i` (a qualitative palette: Tableau 10, then ten darker or more
/// saturated hues, so that up to 20 bases get distinct colours).
pub fn series_colour(i: usize) -> RGBColor {
    const P: [(u8, u8, u8); 20] = [
        (31, 119, 180),
        (255, 127, 14),
        (44, 160, 44),
        (214, 39, 40),
        (148, 103, 189),
        (140, 86, 75),
        (227, 119, 194),
        (127, 127, 127),
        (188, 189, 34),
        (23, 190, 207),
        (23, 63, 95),
        (170, 80, 0),
        (0, 100, 0),
        (130, 0, 0),
        (90, 50, 140),
        (200, 170, 0),
        (0, 128, 128),
        (255, 0, 255),
        (100, 100, 0),
        (70, 130, 180),
    ];
    let (r, g, b) = P[i % P.len()];
    RGBColor(r, g, b)
}

/// Fraction of pixels of `img` that differ from white: a figure is not blank when this is
/// well above 0 (used by tests).
pub fn ink_fraction(img: &Rgb8Image) -> f64 {
    let px = img
        .data
        .chunks_exact(3)
        .filter(|p| p != &[255, 255, 255])
        .count();
    px as f64 / (img.width as f64 * img.height as f64).max(1.0)
}

pub(crate) fn e2s<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}
