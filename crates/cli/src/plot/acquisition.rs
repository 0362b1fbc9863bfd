//! The acquisition figure: held-out mean rho against the number of samples, one line per
//! plan (noise-free), log scale, with the dense fit's mean rho as a dashed limit; below it,
//! when the cross-validation has a showcase, a row of renders: the showcase held-out
//! material, its dense fit and its reconstructions from each n (caption: which material,
//! fold, basis and plan).

use super::{figure, series_colour, Draw, Figure, PlotError};
use brdf_basis::acquire::{AcqCv, AcqShowcase};
use brdf_basis::eval::image_error::{display_image, DisplayParams, Rgb8Image};
use plotters::coord::Shift;
use plotters::prelude::*;

const FONT: &str = "sans-serif";

/// [`AcqCv`] drawn as rho against n (first method, noise 0, else the lowest noise level).
pub(crate) struct RhoVsN<'a> {
    /// The cross-validation.
    pub(crate) cv: &'a AcqCv,
}

impl Draw for RhoVsN<'_> {
    /// Long function: one figure drawn top to bottom (axes, a series per plan, the
    /// capped markers, the legend) on one chart context, which plotters borrows mutably
    /// for the whole drawing.
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let e2s = |e: &dyn std::fmt::Display| e.to_string();
        let Some(method) = self.cv.results.first().map(|r| r.method.clone()) else {
            return Ok(());
        };
        // The noise-free rows; without a noise-free level (`--noise 0.02` alone), the
        // lowest noise level, named in the caption (the chart was left empty).
        let noise = self
            .cv
            .results
            .iter()
            .filter(|r| r.method == method)
            .map(|r| r.noise)
            .fold(f64::INFINITY, f64::min);
        let rows: Vec<_> = self
            .cv
            .results
            .iter()
            .filter(|r| r.method == method && r.noise == noise && r.mean_rho > 0.0)
            .collect();
        let samples = if noise == 0.0 {
            "noise-free samples".to_string()
        } else {
            format!("samples at {}% noise", noise * 100.0)
        };
        let mut plans: Vec<&str> = Vec::new();
        for r in &rows {
            if !plans.contains(&r.plan.as_str()) {
                plans.push(r.plan.as_str());
            }
        }
        let ys = rows
            .iter()
            .flat_map(|r| [r.mean_rho, r.mean_dense_rho])
            .filter(|v| *v > 0.0);
        let (lo, hi) = ys.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
        if !lo.is_finite() {
            return Ok(());
        }
        // The axis spans at most OFF_SCALE times the dense limit: an ill-posed plan's mean
        // (random plans reach 1e28) would otherwise flatten every other line onto the
        // limit. Larger means sit on the top edge as triangles with their value, their
        // lines leaving the plot there (never at a height that reads as a value).
        let dense = rows.iter().map(|r| r.mean_dense_rho).next().unwrap_or(lo);
        let cap = if dense > 0.0 { dense * OFF_SCALE } else { hi };
        let hi = hi.min(cap);
        let lo = lo.min(hi);
        let nmax = rows.iter().map(|r| r.n).max().unwrap_or(1) as f64;
        // Headroom above the data (a third of the plot's height on the log axis) holds
        // the legend (upper left), so that it never covers a line.
        let top = hi * 1.5 * (hi / lo).max(10.0).powf(0.5);
        let mut b = ChartBuilder::on(root);
        b.margin(12);
        if text {
            b.caption(
                format!(
                    "Held-out mean rho from n {samples} ({method}, k = {})",
                    self.cv.k
                ),
                (FONT, 18),
            )
            .x_label_area_size(40)
            .y_label_area_size(70);
        }
        let mut chart = b
            .build_cartesian_2d(0.0..nmax * 1.05, (lo / 1.5..top).log_scale())
            .map_err(|e| e2s(&e))?;
        if text {
            chart
                .configure_mesh()
                .x_desc("samples n")
                .y_desc("mean rho (log)")
                .y_label_formatter(&|v| format!("{v:.0e}"))
                // Integer sample counts only: at most one label per integer (n = 1 gave
                // "0 0 0 0 0 0 1 1 1 1 1").
                .x_labels((nmax as usize + 1).clamp(2, 11))
                .x_label_formatter(&|v| {
                    if (v - v.round()).abs() < 1e-9 {
                        format!("{v:.0}")
                    } else {
                        String::new()
                    }
                })
                .label_style((FONT, 12))
                .draw()
                .map_err(|e| e2s(&e))?;
        }
        for (i, plan) in plans.iter().enumerate() {
            let raw: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.plan.as_str() == *plan)
                .map(|r| (r.n as f64, r.mean_rho))
                .collect();
            let pts: Vec<(f64, f64)> = raw
                .iter()
                .map(|&(x, y)| (x, if y > cap { top } else { y }))
                .collect();
            let c = series_colour(i);
            let s = chart
                .draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))
                .map_err(|e| e2s(&e))?;
            if text {
                s.label(plan.to_string()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                });
            }
            chart
                .draw_series(
                    raw.iter()
                        .filter(|p| p.1 <= cap)
                        .map(|&p| Circle::new(p, 3, c.filled())),
                )
                .map_err(|e| e2s(&e))?;
            for &(x, y) in raw.iter().filter(|p| p.1 > cap) {
                chart
                    .draw_series(std::iter::once(TriangleMarker::new((x, top), 6, c)))
                    .map_err(|e| e2s(&e))?;
                if text {
                    chart
                        .draw_series(std::iter::once(Text::new(
                            format!("{y:.1e}"),
                            (x + 0.015 * nmax, top / (hi / lo).max(10.0).powf(0.05)),
                            (FONT, 11).into_font().color(&c),
                        )))
                        .map_err(|e| e2s(&e))?;
                }
            }
        }
        let grey = RGBColor(90, 90, 90);
        let s = chart
            .draw_series(DashedLineSeries::new(
                vec![(0.0, dense), (nmax * 1.05, dense)],
                6,
                4,
                grey.stroke_width(1),
            ))
            .map_err(|e| e2s(&e))?;
        if text {
            s.label("dense fit (the limit)").legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], grey.stroke_width(1))
            });
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .border_style(BLACK)
                .background_style(WHITE.mix(0.9))
                .label_font((FONT, 12))
                .draw()
                .map_err(|e| e2s(&e))?;
        }
        Ok(())
    }
}

/// The rho axis ends at this multiple of the dense fit's mean rho (larger means are
/// marked off scale on the top edge).
const OFF_SCALE: f64 = 1e3;

/// Render tiles' size in pixels.
const TILE: u32 = 128;
/// Height of the rho chart.
const CHART_H: u32 = 440;
/// Height of the render row (labels, tile, caption).
const ROW_H: u32 = 60 + TILE + 56;
const WIDTH: u32 = 860;

/// `img` resized to `TILE` wide: integer pixel replication up, 2 x 2 box filtering down.
fn to_tile(img: &Rgb8Image) -> Rgb8Image {
    let mut cur = img.clone();
    while cur.width > TILE && cur.height >= 2 {
        let (w, h) = (cur.width / 2, cur.height / 2);
        let mut data = Vec::with_capacity(3 * (w * h) as usize);
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    let at = |dx: u32, dy: u32| {
                        cur.data[(3 * ((2 * y + dy) * cur.width + 2 * x + dx) + c) as usize] as u32
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
    let f = (TILE / cur.width.max(1)).max(1);
    if f == 1 {
        return cur;
    }
    let (w, h) = (cur.width * f, cur.height * f);
    let mut data = Vec::with_capacity(3 * (w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let i = (3 * ((y / f) * cur.width + x / f)) as usize;
            data.extend_from_slice(&cur.data[i..i + 3]);
        }
    }
    Rgb8Image {
        width: w,
        height: h,
        data,
    }
}

/// The render row of a showcase.
struct Renders {
    tiles: Vec<(String, String, Rgb8Image)>,
    caption: [String; 2],
}

impl Renders {
    fn new(s: &AcqShowcase, k: usize) -> Result<Self, String> {
        let d = DisplayParams::default();
        let disp = |i: &brdf_basis::eval::render::Image| {
            display_image(i, &d)
                .map(|x| to_tile(&x))
                .map_err(|e| e.to_string())
        };
        let mut tiles = vec![(
            "target".to_string(),
            crate::plot::legend::short_name(&s.material, 20),
            disp(&s.original)?,
        )];
        for (label, img, ie, rho) in &s.tiles {
            tiles.push((
                label.clone(),
                format!(
                    "rho {}, img {}",
                    brdf_basis::stats::num(*rho),
                    brdf_basis::stats::num(*ie)
                ),
                disp(img)?,
            ));
        }
        let noise = if s.noise == 0.0 {
            "noise-free".to_string()
        } else {
            format!("{}% noise", s.noise * 100.0)
        };
        Ok(Self {
            tiles,
            caption: [
                format!(
                    "Held-out `{}` (fold {}, the median rho at the largest n by the {} plan), {noise}; light (45, 45) deg.",
                    crate::plot::legend::short_name(&s.material, 40),
                    s.fold + 1,
                    s.plan.as_str(),
                ),
                format!(
                    "Dense fit and reconstructions from the plan's first n samples by its fold's {} k = {k} basis{}.",
                    s.method,
                    if s.plan == brdf_basis::acquire::Criterion::Nielsen {
                        " (nielsen: its own PCA and ridge)"
                    } else {
                        ""
                    }
                ),
            ],
        })
    }

    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let e2s = |e: &dyn std::fmt::Display| e.to_string();
        let n = self.tiles.len() as u32;
        let pad = (WIDTH.saturating_sub(n * TILE) / (n + 1)).max(4);
        for (i, (label, sub, img)) in self.tiles.iter().enumerate() {
            let x = (pad + i as u32 * (TILE + pad)) as i32;
            let y = 44i32;
            if text {
                root.draw(&Text::new(label.clone(), (x, 8), (FONT, 14).into_font()))
                    .map_err(|e| e2s(&e))?;
                root.draw(&Text::new(sub.clone(), (x, 26), (FONT, 11).into_font()))
                    .map_err(|e| e2s(&e))?;
            }
            for (k, p) in img.data.chunks_exact(3).enumerate() {
                let (px, py) = ((k as u32 % img.width) as i32, (k as u32 / img.width) as i32);
                root.draw_pixel((x + px, y + py), &RGBColor(p[0], p[1], p[2]))
                    .map_err(|e| e2s(&e))?;
            }
        }
        if text {
            for (l, c) in self.caption.iter().enumerate() {
                root.draw(&Text::new(
                    c.clone(),
                    (pad as i32, 44 + TILE as i32 + 10 + 18 * l as i32),
                    (FONT, 12).into_font(),
                ))
                .map_err(|e| e2s(&e))?;
            }
        }
        Ok(())
    }
}

/// The chart above the render row.
struct WithRenders<'a> {
    chart: RhoVsN<'a>,
    renders: Option<Renders>,
}

impl Draw for WithRenders<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        match &self.renders {
            None => self.chart.draw(root, text),
            Some(r) => {
                let (top, bottom) = root.split_vertically(CHART_H);
                self.chart.draw(&top, text)?;
                r.draw(&bottom, text)
            }
        }
    }
}

/// The figure `acquisition-rho` (SVG and PNG): the chart, and the render row when `cv` has
/// a showcase.
pub(crate) fn rho_vs_n(cv: &AcqCv) -> Result<Figure, PlotError> {
    let renders = match &cv.showcase {
        Some(s) => Some(Renders::new(s, cv.k).map_err(|message| PlotError::Draw {
            stem: "acquisition-rho".into(),
            message,
        })?),
        None => None,
    };
    let size = if renders.is_some() {
        (WIDTH, CHART_H + ROW_H)
    } else {
        (720, 480)
    };
    figure(
        "acquisition-rho",
        size,
        &WithRenders {
            chart: RhoVsN { cv },
            renders,
        },
    )
}
