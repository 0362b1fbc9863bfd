//! The acquisition figure: held-out mean rho against the number of samples, one line per
//! plan (noise-free), log scale, with the dense fit's mean rho as a dashed limit.

use super::cv::AcqCv;
use crate::plot::{figure, series_colour, Draw, Figure, PlotError};
use plotters::coord::Shift;
use plotters::prelude::*;

const FONT: &str = "sans-serif";

/// [`AcqCv`] drawn as rho against n (first method, noise 0).
pub struct RhoVsN<'a> {
    /// The cross-validation.
    pub cv: &'a AcqCv,
}

impl Draw for RhoVsN<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let e2s = |e: &dyn std::fmt::Display| e.to_string();
        let Some(method) = self.cv.results.first().map(|r| r.method.clone()) else {
            return Ok(());
        };
        let rows: Vec<_> = self
            .cv
            .results
            .iter()
            .filter(|r| r.method == method && r.noise == 0.0 && r.mean_rho > 0.0)
            .collect();
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
        let nmax = rows.iter().map(|r| r.n).max().unwrap_or(1) as f64;
        let mut b = ChartBuilder::on(root);
        b.margin(12);
        if text {
            b.caption(
                format!(
                    "Held-out mean rho from n noise-free samples ({method}, k = {})",
                    self.cv.k
                ),
                (FONT, 18),
            )
            .x_label_area_size(40)
            .y_label_area_size(70);
        }
        let mut chart = b
            // Headroom above the data (a third of the plot's height on the log axis) holds
            // the legend (upper left), so that it never covers a line.
            .build_cartesian_2d(
                0.0..nmax * 1.05,
                (lo / 1.5..hi * 1.5 * (hi / lo).max(10.0).powf(0.5)).log_scale(),
            )
            .map_err(|e| e2s(&e))?;
        if text {
            chart
                .configure_mesh()
                .x_desc("samples n")
                .y_desc("mean rho (log)")
                .y_label_formatter(&|v| format!("{v:.0e}"))
                .x_label_formatter(&|v| format!("{v:.0}"))
                .label_style((FONT, 12))
                .draw()
                .map_err(|e| e2s(&e))?;
        }
        for (i, plan) in plans.iter().enumerate() {
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.plan.as_str() == *plan)
                .map(|r| (r.n as f64, r.mean_rho))
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
                .draw_series(pts.iter().map(|&p| Circle::new(p, 3, c.filled())))
                .map_err(|e| e2s(&e))?;
        }
        let dense = rows.iter().map(|r| r.mean_dense_rho).next().unwrap_or(lo);
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

/// The figure `acquisition-rho` (SVG and PNG).
pub fn rho_vs_n(cv: &AcqCv) -> Result<Figure, PlotError> {
    figure("acquisition-rho", (720, 480), &RhoVsN { cv })
}
