//! Legends drawn beside or under the data (never over it), tick labels and name
//! shortening shared by the charts.
//!
//! Text widths are estimated from the font size ([`text_width`]) rather than measured, so
//! a figure's size can be chosen before anything is drawn and does not depend on the font.

use super::e2s;
use plotters::coord::Shift;
use plotters::prelude::*;

const FONT: &str = "sans-serif";

/// How an entry is drawn.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Marker {
    /// A line of this colour and width.
    Line(RGBColor, u32),
    /// A dashed line.
    Dashed(RGBColor),
    /// A dot.
    Dot(RGBColor),
}

/// One legend entry.
#[derive(Clone, Debug)]
pub(crate) struct Entry {
    /// Text.
    pub(crate) label: String,
    /// Sample.
    pub(crate) marker: Marker,
}

impl Entry {
    /// An entry.
    pub(crate) fn new(label: impl Into<String>, marker: Marker) -> Self {
        Entry {
            label: label.into(),
            marker,
        }
    }
}

/// Width in pixels of `s` at `size` px: measured with the registered font, else
/// estimated (DejaVu Sans averages about 0.6 em).
pub(crate) fn text_width(s: &str, size: u32) -> u32 {
    if super::with_text() {
        if let Ok((w, _)) = (FONT, size).into_font().box_size(s) {
            return w;
        }
    }
    (s.chars().count() as f64 * 0.6 * size as f64).ceil() as u32
}

/// `s` cut (with `...`) to fit `max_px` at `size` px.
pub(crate) fn fit_text(s: &str, size: u32, max_px: u32) -> String {
    if text_width(s, size) <= max_px {
        return s.to_string();
    }
    // Longest prefix that fits, by bisection on the character count.
    let (mut lo, mut hi) = (0usize, s.chars().count().min(4096));
    while lo < hi {
        let mid = (lo + hi).div_ceil(2);
        if text_width(&short_name(s, mid), size) <= max_px {
            lo = mid;
        } else {
            hi = mid - 1;
        }
    }
    short_name(s, lo.max(3))
}

/// `name` cut to at most `max` characters (with `...`), so that a long material name does
/// not push a figure's layout off the page.
pub(crate) fn short_name(name: &str, max: usize) -> String {
    if name.chars().count() <= max {
        name.to_string()
    } else {
        let head: String = name.chars().take(max.saturating_sub(3)).collect();
        format!("{head}...")
    }
}

pub(crate) use brdf_basis::io::image::tick_label;

/// Rows of width `width` px that [`draw_flow`] needs for `entries` at `size` px.
pub(crate) fn flow_rows(entries: &[Entry], width: u32, size: u32) -> u32 {
    let mut rows = 1;
    let mut x = 10;
    for e in entries {
        let w = entry_width(e, size);
        if x + w > width && x > 10 {
            rows += 1;
            x = 10;
        }
        x += w;
    }
    rows
}

fn entry_width(e: &Entry, size: u32) -> u32 {
    30 + text_width(&e.label, size) + 24
}

/// Height of one legend row at `size` px.
pub(crate) fn row_height(size: u32) -> u32 {
    size + 10
}

fn sample<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    m: Marker,
    (x, y): (i32, i32),
) -> Result<(), String> {
    match m {
        Marker::Line(c, w) => area
            .draw(&PathElement::new(
                vec![(x, y), (x + 24, y)],
                c.stroke_width(w),
            ))
            .map_err(e2s),
        Marker::Dashed(c) => {
            for s in 0..3 {
                area.draw(&PathElement::new(
                    vec![(x + 8 * s, y), (x + 8 * s + 4, y)],
                    c.stroke_width(1),
                ))
                .map_err(e2s)?;
            }
            Ok(())
        }
        Marker::Dot(c) => area
            .draw(&Circle::new((x + 12, y), 4, c.filled()))
            .map_err(e2s),
    }
}

/// Draws `entries` left to right, wrapping at the area's width (a legend strip under the
/// panels). Nothing is drawn without text.
pub(crate) fn draw_flow<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[Entry],
    size: u32,
    text: bool,
) -> Result<(), String> {
    if !text {
        return Ok(());
    }
    let (w, _) = area.dim_in_pixel();
    let (mut x, mut y) = (10u32, 4u32);
    for e in entries {
        let ew = entry_width(e, size);
        if x + ew > w && x > 10 {
            x = 10;
            y += row_height(size);
        }
        let mid = (y + size / 2 + 1) as i32;
        sample(area, e.marker, (x as i32, mid))?;
        area.draw(&Text::new(
            e.label.clone(),
            (x as i32 + 30, y as i32),
            (FONT, size).into_font(),
        ))
        .map_err(e2s)?;
        x += ew;
    }
    Ok(())
}

/// Width a [`draw_column`] legend of `entries` needs at `size` px.
pub(crate) fn column_width(entries: &[Entry], size: u32) -> u32 {
    entries
        .iter()
        .map(|e| 30 + text_width(&e.label, size) + 12)
        .max()
        .unwrap_or(0)
}

/// Draws `entries` one per row from the top of `area` (a legend column beside a chart).
pub(crate) fn draw_column<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[Entry],
    size: u32,
    top: u32,
    text: bool,
) -> Result<(), String> {
    if !text {
        return Ok(());
    }
    for (i, e) in entries.iter().enumerate() {
        let y = top + i as u32 * row_height(size);
        sample(area, e.marker, (4, (y + size / 2 + 1) as i32))?;
        area.draw(&Text::new(
            e.label.clone(),
            (34, y as i32),
            (FONT, size).into_font(),
        ))
        .map_err(e2s)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_have_no_float_noise() {
        for (v, want) in [
            (9.999999999999999e-5, "1e-4"),
            (1e-4, "1e-4"),
            (1e-15, "1e-15"),
            (1e-15 * (1.0 + f64::EPSILON), "1e-15"),
            (2.0000000000000004e-5, "2e-5"),
            (2.5e-7, "2.5e-7"),
            (0.001, "0.001"),
            (0.009999999999999998, "0.01"),
            (0.1, "0.1"),
            (0.30000000000000004, "0.3"),
            (1.0, "1"),
            (10.0, "10"),
            (999.9999999999999, "1000"),
            (10000.0, "1e4"),
            (0.25, "0.25"),
            (0.0, "0"),
            (-0.5, "-0.5"),
            (1234.5678, "1235"),
        ] {
            assert_eq!(tick_label(v), want, "{v:e}");
        }
    }

    #[test]
    fn fitted_text_fits() {
        let long = "m".repeat(100_000);
        let t = fit_text(&long, 18, 400);
        assert!(
            text_width(&t, 18) <= 400 && t.ends_with("...") && t.len() > 10,
            "{t}"
        );
        assert_eq!(fit_text("short", 18, 400), "short");
    }

    #[test]
    fn short_names_are_cut() {
        assert_eq!(short_name("polished-gold", 20), "polished-gold");
        assert_eq!(short_name(&"x".repeat(1000), 10), "xxxxxxx...");
        assert_eq!(short_name("ééééé", 5), "ééééé");
    }

    #[test]
    fn legend_rows_wrap() {
        let e: Vec<Entry> = (0..6)
            .map(|i| Entry::new(format!("basis-{i}"), Marker::Dot(BLACK)))
            .collect();
        let one = entry_width(&e[0], 13);
        assert_eq!(flow_rows(&e, 10 + 6 * one, 13), 1);
        assert_eq!(flow_rows(&e, 10 + 3 * one, 13), 2);
        assert_eq!(flow_rows(&e, 10 + one, 13), 6);
    }
}
