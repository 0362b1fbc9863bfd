//! Specular-lobe polar plots (the paper's future work, VII): the BRDF in the plane of
//! incidence, one panel per incident angle, a material against its fits.
//!
//! Light comes from `wi = (sin theta_i, 0, cos theta_i)`; the curve is `f(wi, wo)`
//! (mean over RGB) for `wo = (sin theta_o, 0, cos theta_o)`, `theta_o` in `[-89.75,
//! 89.75]` deg, so the mirror direction is at `theta_o = -theta_i` (left of the normal).
//! The radius is logarithmic: [`DECADES`] decades below the largest value of all panels
//! (one scale for the panels side by side), with a guide circle per decade.

use super::legend::{self, Entry, Marker};
use super::{e2s, figure, series_colour, Draw, Figure, PlotError};
use brdf_basis::eval::shade::BrdfFn;
use plotters::coord::Shift;
use plotters::prelude::*;

/// Decades shown below the largest value of a panel.
pub(crate) const DECADES: f64 = 4.0;
const FONT: &str = "sans-serif";
const STEPS: usize = 719;
/// Colour of the incident direction: a neutral near-black, dashed, so that it is taken for
/// no curve (the series palette has a mid grey).
const INCIDENT: RGBColor = RGBColor(40, 40, 40);
const LEGEND_SIZE: u32 = 13;

/// `(theta_o in degrees, mean RGB f)` along the plane of incidence.
pub(crate) fn lobe_samples(f: &BrdfFn, theta_i_deg: f64) -> Vec<(f64, f64)> {
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
pub(crate) struct LobePlot<'a> {
    /// Title.
    pub(crate) title: String,
    /// Named BRDFs.
    pub(crate) curves: &'a [(String, BrdfFn)],
    /// Incident angles, degrees.
    pub(crate) angles: &'a [f64],
}

impl LobePlot<'_> {
    fn colour(i: usize) -> RGBColor {
        if i == 0 {
            BLACK
        } else {
            series_colour(i - 1)
        }
    }

    fn legend(&self) -> Vec<Entry> {
        let mut e: Vec<Entry> = self
            .curves
            .iter()
            .enumerate()
            .map(|(i, (name, _))| {
                Entry::new(
                    legend::short_name(name, 40),
                    Marker::Line(Self::colour(i), if i == 0 { 3 } else { 2 }),
                )
            })
            .collect();
        e.push(Entry::new(
            "incident direction (towards the light)",
            Marker::Dashed(INCIDENT),
        ));
        e
    }

    fn legend_height(&self, width: u32) -> u32 {
        legend::flow_rows(&self.legend(), width, LEGEND_SIZE) * legend::row_height(LEGEND_SIZE) + 8
    }
}

/// Curves that are zero (or not finite) at every sampled direction of every panel: they
/// cannot be drawn on a log radius, and a blank plot must not pass for a result.
pub(crate) fn zero_curves(curves: &[(String, BrdfFn)], angles: &[f64]) -> Vec<String> {
    curves
        .iter()
        .filter(|(_, f)| {
            angles.iter().all(|&a| {
                lobe_samples(f, a)
                    .iter()
                    .all(|p| !(p.1 > 0.0 && p.1.is_finite()))
            })
        })
        .map(|(n, _)| n.clone())
        .collect()
}

impl Draw for LobePlot<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let root = if text {
            let w = root.dim_in_pixel().0.saturating_sub(20);
            root.titled(&legend::fit_text(&self.title, 18, w), (FONT, 18))
                .map_err(e2s)?
        } else {
            root.clone()
        };
        let (w, h) = root.dim_in_pixel();
        let (body, legend_area) = root.split_vertically(h - self.legend_height(w));
        let panels = body.split_evenly((1, self.angles.len().max(1)));
        // Every panel's curves first: one radial scale for all panels.
        let samples: Vec<Vec<Vec<(f64, f64)>>> = self
            .angles
            .iter()
            .map(|&a| {
                self.curves
                    .iter()
                    .map(|(_, f)| lobe_samples(f, a))
                    .collect()
            })
            .collect();
        let top = samples.iter().map(|s| largest(s)).fold(0.0, f64::max);
        for ((&a, s), area) in self.angles.iter().zip(&samples).zip(panels) {
            self.panel(&area, a, s, top, text)?;
        }
        legend::draw_flow(&legend_area, &self.legend(), LEGEND_SIZE, text)
    }

    fn notes(&self) -> Vec<String> {
        zero_curves(self.curves, self.angles)
            .into_iter()
            .map(|n| {
                format!(
                    "lobe plot: the BRDF of `{}` is 0 at every direction plotted, so it has no curve (log radius)",
                    legend::short_name(&n, 60)
                )
            })
            .collect()
    }
}

impl LobePlot<'_> {
    /// One panel at the incident angle `a`: guide circles, surface, normal, incident
    /// direction and the curves' `samples`, on the radial scale of `top` (the largest
    /// value of all panels).
    fn panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        a: f64,
        samples: &[Vec<(f64, f64)>],
        top: f64,
        text: bool,
    ) -> Result<(), String> {
        let log_top = if top > 0.0 { top.log10().ceil() } else { 0.0 };
        let radius = |v: f64| (v.max(1e-300).log10() - (log_top - DECADES)).max(0.0);
        let mut b = ChartBuilder::on(area);
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
            if text && top > 0.0 {
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
            .draw_series(DashedLineSeries::new(
                vec![(0.0, 0.0), (DECADES * ti.sin(), DECADES * ti.cos())],
                4,
                4,
                INCIDENT.stroke_width(1),
            ))
            .map_err(e2s)?;
        if largest(samples) <= 0.0 {
            if text {
                chart
                    .draw_series([Text::new(
                        "BRDF = 0 in this plane",
                        (-DECADES * 0.45, DECADES * 0.5),
                        (FONT, 13).into_font(),
                    )])
                    .map_err(e2s)?;
            }
            return Ok(());
        }
        for (i, s) in samples.iter().enumerate().rev() {
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
                    Self::colour(i).stroke_width(if i == 0 { 3 } else { 2 }),
                ))
                .map_err(e2s)?;
        }
        Ok(())
    }
}

/// The largest finite value of a panel's curves (0 when none is positive).
fn largest(samples: &[Vec<(f64, f64)>]) -> f64 {
    samples
        .iter()
        .flatten()
        .map(|p| p.1)
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max)
}

/// Lobe plot of `curves` (the first is the material) at `angles` (degrees).
pub(crate) fn lobe_plot(
    stem: &str,
    title: &str,
    curves: &[(String, BrdfFn)],
    angles: &[f64],
) -> Result<Figure, PlotError> {
    if curves.is_empty() || angles.is_empty() {
        return Err(PlotError::NoData(stem.into()));
    }
    let plot = LobePlot {
        title: title.to_string(),
        curves,
        angles,
    };
    let w = 330 * angles.len() as u32;
    let h = 230 + plot.legend_height(w);
    figure(stem, (w, h), &plot)
}
