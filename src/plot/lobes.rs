//! Specular-lobe polar plots (the paper's future work, VII): the BRDF in the plane of
//! incidence, one panel per incident angle, a material against its fits.
//!
//! Light comes from `wi = (sin theta_i, 0, cos theta_i)`; the curve is `f(wi, wo)`
//! (mean over RGB) for `wo = (sin theta_o, 0, cos theta_o)`, `theta_o` in `[-89.75,
//! 89.75]` deg, so the mirror direction is at `theta_o = -theta_i` (left of the normal).
//! The radius is logarithmic: [`DECADES`] decades below the panel's largest value, with a
//! guide circle per decade.

use super::{e2s, figure, series_colour, Draw, Figure, PlotError};
use crate::eval::shade::BrdfFn;
use plotters::coord::Shift;
use plotters::prelude::*;

/// Decades shown below the largest value of a panel.
pub const DECADES: f64 = 4.0;
const FONT: &str = "sans-serif";
const STEPS: usize = 719;

/// `(theta_o in degrees, mean RGB f)` along the plane of incidence.
pub fn lobe_samples(f: &BrdfFn, theta_i_deg: f64) -> Vec<(f64, f64)> {
    let ti = theta_i_deg.to_radians();
    let wi = [ti.sin(), 0.0, ti.cos()];
    (0..STEPS)
        .map(|s| {
            let to = -89.75 + 179.5 * s as f64 / (STEPS - 1) as f64;
            let r = to.to_radians();
            let v = f(wi, [r.sin(), 0.0, r.cos()]);
            (to, (v[0] + v[1] + v[2]) / 3.0)
        })
        .collect()
}

/// The lobe plot of named BRDFs (the first is the material, drawn black).
pub struct LobePlot<'a> {
    /// Title.
    pub title: String,
    /// Named BRDFs.
    pub curves: &'a [(String, BrdfFn)],
    /// Incident angles, degrees.
    pub angles: &'a [f64],
}

impl Draw for LobePlot<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let root = if text {
            root.titled(&self.title, (FONT, 18)).map_err(e2s)?
        } else {
            root.clone()
        };
        let (body, legend) = root
            .split_vertically(root.dim_in_pixel().1 - 30 * (self.curves.len() as u32).div_ceil(4));
        let panels = body.split_evenly((1, self.angles.len().max(1)));
        for (&a, area) in self.angles.iter().zip(panels) {
            let samples: Vec<Vec<(f64, f64)>> = self
                .curves
                .iter()
                .map(|(_, f)| lobe_samples(f, a))
                .collect();
            let top = samples.iter().flatten().map(|p| p.1).fold(0.0, f64::max);
            if top <= 0.0 || !top.is_finite() {
                continue;
            }
            let log_top = top.log10().ceil();
            let radius = |v: f64| (v.max(1e-300).log10() - (log_top - DECADES)).max(0.0);
            let mut b = ChartBuilder::on(&area);
            b.margin(8);
            if text {
                b.caption(format!("theta_i = {a} deg"), (FONT, 15));
            }
            let mut chart = b
                .build_cartesian_2d(-DECADES * 1.05..DECADES * 1.05, -0.05..DECADES * 1.05)
                .map_err(e2s)?;
            for d in 1..=DECADES as usize {
                let r = d as f64;
                let pts: Vec<(f64, f64)> = (0..=90)
                    .map(|s| {
                        let t = std::f64::consts::PI * s as f64 / 90.0;
                        (r * t.cos(), r * t.sin())
                    })
                    .collect();
                chart
                    .draw_series(LineSeries::new(pts, RGBColor(200, 200, 200)))
                    .map_err(e2s)?;
                if text {
                    chart
                        .draw_series([Text::new(
                            format!("1e{}", log_top as i64 - DECADES as i64 + d as i64),
                            (r * 0.94, -0.02),
                            (FONT, 10).into_font(),
                        )])
                        .map_err(e2s)?;
                }
            }
            // Surface and normal, incident direction.
            chart
                .draw_series(LineSeries::new(
                    vec![(-DECADES, 0.0), (DECADES, 0.0)],
                    BLACK,
                ))
                .map_err(e2s)?;
            chart
                .draw_series(LineSeries::new(
                    vec![(0.0, 0.0), (0.0, DECADES)],
                    RGBColor(160, 160, 160),
                ))
                .map_err(e2s)?;
            let ti = a.to_radians();
            chart
                .draw_series(LineSeries::new(
                    vec![(0.0, 0.0), (DECADES * ti.sin(), DECADES * ti.cos())],
                    RGBColor(230, 160, 0).stroke_width(2),
                ))
                .map_err(e2s)?;
            for (i, s) in samples.iter().enumerate().rev() {
                let c = if i == 0 { BLACK } else { series_colour(i - 1) };
                let pts: Vec<(f64, f64)> = s
                    .iter()
                    .map(|&(to, v)| {
                        let r = radius(v);
                        let t = to.to_radians();
                        (r * t.sin(), r * t.cos())
                    })
                    .collect();
                chart
                    .draw_series(LineSeries::new(
                        pts,
                        c.stroke_width(if i == 0 { 3 } else { 2 }),
                    ))
                    .map_err(e2s)?;
            }
        }
        if text {
            let (w, _) = legend.dim_in_pixel();
            let col = (w / 4) as i32;
            for (i, (name, _)) in self.curves.iter().enumerate() {
                let c = if i == 0 { BLACK } else { series_colour(i - 1) };
                let (x, y) = (10 + col * (i as i32 % 4), 8 + 26 * (i as i32 / 4));
                legend
                    .draw(&PathElement::new(
                        vec![(x, y + 8), (x + 24, y + 8)],
                        c.stroke_width(3),
                    ))
                    .map_err(e2s)?;
                legend
                    .draw(&Text::new(
                        name.clone(),
                        (x + 30, y),
                        (FONT, 13).into_font(),
                    ))
                    .map_err(e2s)?;
            }
        }
        Ok(())
    }
}

/// Lobe plot of `curves` (the first is the material) at `angles` (degrees).
pub fn lobe_plot(
    stem: &str,
    title: &str,
    curves: &[(String, BrdfFn)],
    angles: &[f64],
) -> Result<Figure, PlotError> {
    if curves.is_empty() || angles.is_empty() {
        return Err(PlotError::NoData(stem.into()));
    }
    let rows = (curves.len() as u32).div_ceil(4);
    figure(
        stem,
        (330 * angles.len() as u32, 230 + 30 * rows),
        &LobePlot {
            title: title.to_string(),
            curves,
            angles,
        },
    )
}
