//! Figures of the paper as SVG and PNG (plotters): the contributions histogram (Fig. 2),
//! DB box plots (Fig. 3), DB against k, Nemenyi critical-difference diagrams, errors per
//! material (Fig. 4), the showcase comparison (Fig. 5) and specular-lobe polar plots.
//!
//! Text needs a font: [`font`] registers the file named by `BRDF_BASIS_FONT`, or DejaVu
//! Sans (or Liberation Sans) from the usual system paths, at run time; nothing needs
//! fontconfig at build time. A font is an input like any other: a regular file of at most
//! [`MAX_FONT_BYTES`]; an explicit `BRDF_BASIS_FONT` that cannot be used is an error
//! naming the variable and the path, reported before any work. With no font found (or
//! `BRDF_BASIS_FONT=none`) figures are still written, PNG and SVG, without text (plotters
//! lays text out with the font in both), and the caller says so ([`no_font_message`]).
//!
//! [`report::report_figures`] builds the whole figure set of `reproduce`'s report.

pub(crate) mod acquisition;
pub(crate) mod appearance;
pub(crate) mod charts;
pub(crate) mod colour_bar;
pub(crate) mod heatmap;
pub(crate) mod legend;
pub(crate) mod lobes;
pub(crate) mod report;
pub(crate) mod showcase;
#[cfg(test)]
mod tests;

use brdf_basis::eval::image_error::Rgb8Image;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::sync::OnceLock;

/// A figure: SVG text and a PNG raster of the same drawing.
#[derive(Clone, Debug)]
pub(crate) struct Figure {
    /// File stem (e.g. `fig2-contributions`).
    pub(crate) stem: String,
    /// SVG document.
    pub(crate) svg: String,
    /// Raster of the same figure.
    pub(crate) png: Rgb8Image,
    /// What the reader should be told beside the figure (e.g. a curve that is zero
    /// everywhere and so cannot be drawn on a log scale); the caller shows them as
    /// warnings.
    pub(crate) notes: Vec<String>,
}

/// Errors while drawing.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub(crate) enum PlotError {
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
    /// The experiment does not hold what a figure needs (e.g. a basis without a fit).
    #[error("{figure}: {message}")]
    Data {
        /// Figure.
        figure: String,
        /// What is missing.
        message: String,
    },
}

/// Where a sans-serif font is looked for.
pub(crate) const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/Library/Fonts/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

/// The environment variable naming the font file (`none`: figures without text).
pub(crate) const FONT_VAR: &str = "BRDF_BASIS_FONT";

/// Largest font file read (a font is an input like any other: a regular file of bounded
/// size, so `BRDF_BASIS_FONT=/dev/zero` is refused instead of read forever).
pub(crate) const MAX_FONT_BYTES: u64 = 64 << 20;

/// A font named by [`FONT_VAR`] that cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{FONT_VAR}={path}: {reason} (give a .ttf/.otf file, or {FONT_VAR}=none for figures without text)")]
pub(crate) struct FontError {
    /// The path given.
    pub(crate) path: String,
    /// Why it cannot be used.
    pub(crate) reason: String,
}

/// Reads a font file: a regular file of at most [`MAX_FONT_BYTES`] (whether it parses is
/// checked when it is registered, in [`font`]). The size is checked before reading and the read is bounded, so
/// a file that grows while it is read cannot make it unbounded either.
pub(crate) fn read_font_file(path: &str) -> Result<Vec<u8>, FontError> {
    use std::io::Read as _;
    let fail = |reason: String| FontError {
        path: path.to_string(),
        reason,
    };
    let meta = std::fs::metadata(path).map_err(|e| fail(e.to_string()))?;
    if !meta.is_file() {
        return Err(fail("not a regular file".into()));
    }
    if meta.len() > MAX_FONT_BYTES {
        return Err(fail(format!(
            "{} bytes, more than the {} MiB a font may have",
            meta.len(),
            MAX_FONT_BYTES >> 20
        )));
    }
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(MAX_FONT_BYTES + 1).read_to_end(&mut bytes))
        .map_err(|e| fail(e.to_string()))?;
    if bytes.len() as u64 > MAX_FONT_BYTES {
        return Err(fail(format!(
            "more than the {} MiB a font may have",
            MAX_FONT_BYTES >> 20
        )));
    }
    Ok(bytes)
}

/// Where the figures' font comes from, as [`font`] found it.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum FontSource {
    /// A font file (from [`FONT_VAR`] or [`FONT_PATHS`]).
    File(String),
    /// `BRDF_BASIS_FONT=none`: figures without text, on request.
    NoneRequested,
    /// No variable set and none of [`FONT_PATHS`] usable: figures without text.
    NotFound,
}

/// Registers the figures' font as `sans-serif`, once per process, and says where it came
/// from. An explicit [`FONT_VAR`] (set and not empty) must name a usable font ([`read_font_file`]): a missing,
/// non-regular, oversized or unparsable file is an error naming the variable and the path
/// (call this before long work, so the error comes first). Unset, the first usable file
/// of [`FONT_PATHS`] is taken; with none, figures are drawn without text (text in PNGs
/// and SVGs is laid out with the font) and the caller should say so
/// ([`no_font_message`]).
pub(crate) fn font() -> Result<&'static FontSource, FontError> {
    static FONT: OnceLock<Result<FontSource, FontError>> = OnceLock::new();
    FONT.get_or_init(|| {
        let register = |p: &str, bytes: Vec<u8>| {
            // plotters keeps fonts for the life of the process.
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
                .map(|_| FontSource::File(p.to_string()))
                .map_err(|_| FontError {
                    path: p.to_string(),
                    reason: "not a TrueType or OpenType font".into(),
                })
        };
        // Empty counts as unset (`BRDF_BASIS_FONT= brdf-basis ...`).
        match std::env::var_os(FONT_VAR).filter(|v| !v.is_empty()) {
            Some(v) if v == "none" => Ok(FontSource::NoneRequested),
            Some(v) => {
                let p = v.to_string_lossy().into_owned();
                let bytes = read_font_file(&p)?;
                register(&p, bytes)
            }
            None => Ok(FONT_PATHS
                .iter()
                .find_map(|p| register(p, read_font_file(p).ok()?).ok())
                .unwrap_or(FontSource::NotFound)),
        }
    })
    .as_ref()
    .map_err(Clone::clone)
}

/// The path of the registered font, or `None` when figures have no text (no font found,
/// `BRDF_BASIS_FONT=none`, or an unusable `BRDF_BASIS_FONT`: see [`font`] for the error).
pub(crate) fn font_available() -> Option<&'static str> {
    match font() {
        Ok(FontSource::File(p)) => Some(p),
        _ => None,
    }
}

/// Whether figures get text (a font was found).
pub(crate) fn with_text() -> bool {
    font_available().is_some()
}

/// What to tell the user when figures have no text (`None` when they have).
pub(crate) fn no_font_message() -> Option<String> {
    match font() {
        Ok(FontSource::File(_)) => None,
        Ok(FontSource::NoneRequested) => Some(format!(
            "{FONT_VAR}=none: no font, so the figures have no text (labels, legends, colour-bar values)"
        )),
        Ok(FontSource::NotFound) => Some(format!(
            "no font found (looked for {}; set {FONT_VAR} to a .ttf file): the figures have no text (labels, legends, colour-bar values)",
            FONT_PATHS[0]
        )),
        Err(e) => Some(format!("{e}: the figures have no text")),
    }
}

/// A drawing that can go to any plotters back-end.
pub(crate) trait Draw {
    /// Draws on `root`; `text` is false when no font is available.
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String>;

    /// Notes for the reader ([`Figure::notes`]); none by default.
    fn notes(&self) -> Vec<String> {
        Vec::new()
    }
}

/// Draws `d` at `size` into an SVG string and an RGB raster.
pub(crate) fn figure<D: Draw>(stem: &str, size: (u32, u32), d: &D) -> Result<Figure, PlotError> {
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
        notes: d.notes(),
    })
}

/// Colour of series `i` (a qualitative palette: Tableau 10, then ten darker or more
/// saturated hues, so that up to 20 bases get distinct colours).
pub(crate) fn series_colour(i: usize) -> RGBColor {
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

pub(crate) fn e2s<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}
