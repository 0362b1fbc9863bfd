//! The figure of `reproduce`'s Appearance section (`appearance-renders`): per row a
//! held-out material; per light of [`FIGURE_LIGHTS`] its target and its fits under each
//! objective, each fit captioned with its FLIP against the target.

use super::{figure, Draw, Figure, PlotError};
use brdf_basis::eval::image_error::{display_image, DisplayParams, Rgb8Image};
use brdf_basis::experiment::appearance::{AppearanceStudy, FigureRow, FIGURE_LIGHTS};
use plotters::coord::Shift;
use plotters::prelude::*;

const FONT: &str = "sans-serif";
/// Tile size in pixels (the 256 px renders halved by 2 x 2 box filtering).
const TILE: u32 = 128;
/// Gap between tiles, and between the two lights' groups.
const GAP: u32 = 6;
const GROUP_GAP: u32 = 28;
const MARGIN: u32 = 12;
/// Height of the header (title, light and column labels).
const HEADER: u32 = 58;
/// Height of a row: its material's name, the tiles and their captions.
const ROW: u32 = 20 + TILE + 22;

/// `img` halved until it is at most [`TILE`] wide (2 x 2 box filter).
fn shrink(img: &Rgb8Image) -> Rgb8Image {
    let mut cur = img.clone();
    while cur.width > TILE && cur.height >= 2 {
        let (w, h) = (cur.width / 2, cur.height / 2);
        let mut data = Vec::with_capacity(3 * (w * h) as usize);
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    let at = |dx: u32, dy: u32| {
                        u32::from(
                            cur.data[(3 * ((2 * y + dy) * cur.width + 2 * x + dx) + c) as usize],
                        )
                    };
                    data.push(((at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1) + 2) / 4) as u8);
                }
            }
        }
        cur = Rgb8Image {
            width: w,
            height: h,
            data,
        };
    }
    cur
}

/// A tile: its column label, caption and display-mapped render.
type Tile = (String, String, Rgb8Image);

/// The figure's tiles, display-mapped: per row, `(label, caption, tile)` in column order.
struct Renders {
    rows: Vec<(String, Vec<Tile>)>,
    columns: usize,
}

impl Renders {
    fn new(rows: &[FigureRow]) -> Result<Self, String> {
        let d = DisplayParams::default();
        let mut out = Vec::new();
        let mut columns = 0;
        for r in rows {
            let mut tiles = Vec::new();
            for t in &r.tiles {
                let Some(img) = &t.image else { continue };
                let tile = shrink(&display_image(img, &d).map_err(|e| e.to_string())?);
                let label = t.objective.clone().unwrap_or_else(|| "target".into());
                let caption = t.flip.map_or(String::new(), |f| {
                    format!("FLIP {}", brdf_basis::stats::num(f))
                });
                tiles.push((label, caption, tile));
            }
            columns = columns.max(tiles.len());
            let name = format!(
                "{} ({}, fold {})",
                crate::plot::legend::short_name(&r.material, 40),
                r.why,
                r.fold + 1
            );
            out.push((name, tiles));
        }
        Ok(Self { rows: out, columns })
    }

    /// The left edge of column `i` (the second light's group after a wider gap).
    fn x(&self, i: usize) -> i32 {
        let per_light = (self.columns / FIGURE_LIGHTS.len()).max(1);
        let group = (i / per_light) as u32;
        (MARGIN + i as u32 * (TILE + GAP) + group * GROUP_GAP) as i32
    }

    fn size(&self) -> (u32, u32) {
        let w = self.x(self.columns.max(1)) as u32 + MARGIN;
        (w.max(400), HEADER + self.rows.len() as u32 * ROW + MARGIN)
    }
}

impl Draw for Renders {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let e2s = |e: &dyn std::fmt::Display| e.to_string();
        let per_light = (self.columns / FIGURE_LIGHTS.len()).max(1);
        if text {
            root.draw(&Text::new(
                "Held-out renders: target and fits under each objective (FLIP against the target, 67 ppd)",
                (MARGIN as i32, 6),
                (FONT, 15).into_font(),
            ))
            .map_err(|e| e2s(&e))?;
            for (g, (th, ph)) in FIGURE_LIGHTS.iter().enumerate() {
                root.draw(&Text::new(
                    format!("light ({th}, {ph}) deg"),
                    (self.x(g * per_light), 26),
                    (FONT, 13).into_font(),
                ))
                .map_err(|e| e2s(&e))?;
            }
            if let Some((_, tiles)) = self.rows.first() {
                for (i, (label, _, _)) in tiles.iter().enumerate() {
                    root.draw(&Text::new(
                        label.clone(),
                        (self.x(i), 42),
                        (FONT, 13).into_font(),
                    ))
                    .map_err(|e| e2s(&e))?;
                }
            }
        }
        for (r, (name, tiles)) in self.rows.iter().enumerate() {
            let top = (HEADER + r as u32 * ROW) as i32;
            if text {
                root.draw(&Text::new(
                    name.clone(),
                    (MARGIN as i32, top + 2),
                    (FONT, 13).into_font(),
                ))
                .map_err(|e| e2s(&e))?;
            }
            let y = top + 20;
            for (i, (_, caption, img)) in tiles.iter().enumerate() {
                let x = self.x(i);
                for (k, p) in img.data.chunks_exact(3).enumerate() {
                    let (px, py) = ((k as u32 % img.width) as i32, (k as u32 / img.width) as i32);
                    root.draw_pixel((x + px, y + py), &RGBColor(p[0], p[1], p[2]))
                        .map_err(|e| e2s(&e))?;
                }
                if text && !caption.is_empty() {
                    root.draw(&Text::new(
                        caption.clone(),
                        (x + 4, y + TILE as i32 + 4),
                        (FONT, 12).into_font(),
                    ))
                    .map_err(|e| e2s(&e))?;
                }
            }
        }
        Ok(())
    }
}

/// The figure `appearance-renders` (SVG and PNG) of a study.
pub(crate) fn renders(st: &AppearanceStudy) -> Result<Figure, PlotError> {
    let stem = "appearance-renders";
    let r = Renders::new(&st.figure).map_err(|message| PlotError::Draw {
        stem: stem.into(),
        message,
    })?;
    if r.rows.is_empty() || r.columns == 0 {
        return Err(PlotError::NoData(stem.into()));
    }
    let size = r.size();
    figure(stem, size, &r)
}
