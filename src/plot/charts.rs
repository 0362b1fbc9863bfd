//! Charts of `reproduce`: contributions histogram (Fig. 2), DB box plots (Fig. 3), DB
//! against k, Nemenyi critical-difference diagram and errors per material (Fig. 4).

use super::{e2s, figure, series_colour, Draw, Figure, PlotError};
use crate::experiment::evaluation::BasisErrors;
use crate::experiment::statistics::FriedmanSummary;
use crate::select::runs::ClusteringSet;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;

const FONT: &str = "sans-serif";

/// Fig. 2: number of materials (y) that contribute to x fits.
pub struct Histogram<'a> {
    /// Contributions of each material.
    pub counts: &'a [usize],
}

impl Draw for Histogram<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let max = self.counts.iter().copied().max().unwrap_or(0);
        let mut bins = vec![0usize; max + 1];
        self.counts.iter().for_each(|&c| bins[c] += 1);
        let top = bins.iter().copied().max().unwrap_or(1) as u32 + 1;
        let mut b = ChartBuilder::on(root);
        b.margin(12);
        if text {
            b.caption("Contributions to leave-one-out fits", (FONT, 20))
                .x_label_area_size(40)
                .y_label_area_size(50);
        }
        let mut chart = b
            .build_cartesian_2d(-0.5f64..max as f64 + 0.5, 0u32..top)
            .map_err(e2s)?;
        if text {
            chart
                .configure_mesh()
                .disable_x_mesh()
                .x_desc("number of fits a material contributes to")
                .y_desc("number of materials")
                .x_label_formatter(&|v| format!("{v:.0}"))
                .label_style((FONT, 14))
                .draw()
                .map_err(e2s)?;
        }
        chart
            .draw_series(bins.iter().enumerate().map(|(x, &c)| {
                let x = x as f64;
                Rectangle::new(
                    [(x - 0.4, 0), (x + 0.4, c as u32)],
                    series_colour(0).filled(),
                )
            }))
            .map_err(e2s)?;
        Ok(())
    }
}

/// Fig. 3: DB box plots, one panel per metric, one box per method.
pub struct DbBoxplots<'a> {
    /// Metric labels, one panel each.
    pub metrics: &'a [String],
    /// Every clustering set.
    pub sets: &'a [ClusteringSet],
}

fn finite_range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = v
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    if lo > hi {
        (0.0, 1.0)
    } else {
        let pad = ((hi - lo) * 0.08).max(1e-9);
        (lo - pad, hi + pad)
    }
}

impl Draw for DbBoxplots<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let panels = root.split_evenly((1, self.metrics.len().max(1)));
        for (m, area) in self.metrics.iter().zip(panels) {
            let sets: Vec<&ClusteringSet> = self.sets.iter().filter(|s| &s.metric == m).collect();
            let (lo, hi) = finite_range(sets.iter().flat_map(|s| s.db_values()));
            let names: Vec<String> = sets
                .iter()
                .map(|s| s.method.replace("kmedoids-", "km "))
                .collect();
            let mut b = ChartBuilder::on(&area);
            b.margin(10);
            if text {
                b.caption(format!("DB index: {m}"), (FONT, 18))
                    .x_label_area_size(60)
                    .y_label_area_size(60);
            }
            let mut chart = b
                .build_cartesian_2d(-0.5f64..sets.len() as f64 - 0.5, lo as f32..hi as f32)
                .map_err(e2s)?;
            if text {
                chart
                    .configure_mesh()
                    .disable_x_mesh()
                    .x_labels(sets.len() * 2 + 1)
                    .x_label_formatter(&|v| {
                        let i = v.round();
                        if (v - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < names.len() {
                            names[i as usize].clone()
                        } else {
                            String::new()
                        }
                    })
                    .x_label_style((FONT, 12).into_font().transform(FontTransform::Rotate90))
                    .y_desc("Davies-Bouldin index (lower is better)")
                    .label_style((FONT, 12))
                    .draw()
                    .map_err(e2s)?;
            }
            for (i, s) in sets.iter().enumerate() {
                let v: Vec<f64> = s
                    .db_values()
                    .into_iter()
                    .filter(|x| x.is_finite())
                    .collect();
                if v.is_empty() {
                    continue;
                }
                let q = Quartiles::new(&v);
                let [w0, q1, q2, q3, w1] = q.values();
                let x = i as f64;
                let c = series_colour(if s.method == "gcuk" { 3 } else { 0 });
                chart
                    .draw_series([
                        Rectangle::new([(x - 0.3, q1), (x + 0.3, q3)], c.mix(0.35).filled()),
                        Rectangle::new([(x - 0.3, q1), (x + 0.3, q3)], c.stroke_width(1)),
                    ])
                    .map_err(e2s)?;
                chart
                    .draw_series([
                        PathElement::new(vec![(x - 0.3, q2), (x + 0.3, q2)], BLACK.stroke_width(2)),
                        PathElement::new(vec![(x, w0), (x, q1)], c.stroke_width(1)),
                        PathElement::new(vec![(x, q3), (x, w1)], c.stroke_width(1)),
                        PathElement::new(vec![(x - 0.15, w0), (x + 0.15, w0)], c.stroke_width(1)),
                        PathElement::new(vec![(x - 0.15, w1), (x + 0.15, w1)], c.stroke_width(1)),
                    ])
                    .map_err(e2s)?;
                // Runs outside the whiskers.
                chart
                    .draw_series(
                        v.iter()
                            .filter(|&&y| (y as f32) < w0 || (y as f32) > w1)
                            .map(|&y| Circle::new((x, y as f32), 2, c.filled())),
                    )
                    .map_err(e2s)?;
            }
        }
        Ok(())
    }
}

/// DB against k: every k-medoids run and every GCUK run at the k it found, one panel per
/// metric; the line joins the k-medoids medians.
pub struct DbVsK<'a> {
    /// Metric labels.
    pub metrics: &'a [String],
    /// Every clustering set.
    pub sets: &'a [ClusteringSet],
}

impl Draw for DbVsK<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let panels = root.split_evenly((1, self.metrics.len().max(1)));
        for (m, area) in self.metrics.iter().zip(panels) {
            let sets: Vec<&ClusteringSet> = self.sets.iter().filter(|s| &s.metric == m).collect();
            let runs = || sets.iter().flat_map(|s| s.runs.iter());
            let (lo, hi) = finite_range(runs().map(|r| r.db_index));
            let kmax = runs().map(|r| r.k).max().unwrap_or(2) as f64;
            let kmin = runs().map(|r| r.k).min().unwrap_or(2) as f64;
            let mut b = ChartBuilder::on(&area);
            b.margin(10);
            if text {
                b.caption(format!("DB against k: {m}"), (FONT, 18))
                    .x_label_area_size(40)
                    .y_label_area_size(60);
            }
            let mut chart = b
                .build_cartesian_2d(kmin - 0.5..kmax + 0.5, lo..hi)
                .map_err(e2s)?;
            if text {
                chart
                    .configure_mesh()
                    .x_desc("k (number of clusters)")
                    .y_desc("Davies-Bouldin index")
                    .x_label_formatter(&|v| format!("{v:.0}"))
                    .label_style((FONT, 12))
                    .draw()
                    .map_err(e2s)?;
            }
            for s in &sets {
                let gc = s.method == "gcuk";
                let c = series_colour(if gc { 3 } else { 0 });
                let dx = if gc { 0.15 } else { -0.15 };
                let series = chart
                    .draw_series(s.runs.iter().filter(|r| r.db_index.is_finite()).map(|r| {
                        Circle::new((r.k as f64 + dx, r.db_index), 2, c.mix(0.6).filled())
                    }))
                    .map_err(e2s)?;
                if text && (gc || s.method.ends_with(&format!("k{}", kmin as usize))) {
                    series
                        .label(if gc { "GCUK runs" } else { "k-medoids runs" })
                        .legend(move |(x, y)| Circle::new((x, y), 3, c.filled()));
                }
            }
            let med: Vec<(f64, f64)> = sets
                .iter()
                .filter(|s| s.method != "gcuk")
                .map(|s| {
                    (
                        s.best.k as f64 - 0.15,
                        crate::experiment::statistics::median(&s.db_values()),
                    )
                })
                .filter(|p| p.1.is_finite())
                .collect();
            chart
                .draw_series(LineSeries::new(med, series_colour(0).stroke_width(2)))
                .map_err(e2s)?;
            if text {
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK)
                    .label_font((FONT, 12))
                    .draw()
                    .map_err(e2s)?;
            }
        }
        Ok(())
    }
}

/// Nemenyi critical-difference diagram (Demšar 2006, Fig. 1): methods on the axis of mean
/// ranks; a bar joins methods whose ranks differ by less than the critical difference.
pub struct CdDiagram<'a> {
    /// Metric label.
    pub metric: &'a str,
    /// The Friedman summary.
    pub friedman: &'a FriedmanSummary,
}

impl Draw for CdDiagram<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let f = self.friedman;
        let k = f.methods.len();
        let (w, h) = root.dim_in_pixel();
        let (left, right) = (60.0, w as f64 - 60.0);
        let x_of = |r: f64| left + (r - 1.0) / (k as f64 - 1.0).max(1.0) * (right - left);
        let axis_y = 70i32;
        let style = (FONT, 13).into_font();
        if text {
            root.draw(&Text::new(
                format!("Nemenyi critical difference, {} (alpha 0.05): CD = {:.2}; mean rank, 1 = lowest DB", self.metric, f.nemenyi_cd),
                (10, 8),
                (FONT, 15).into_font(),
            ))
            .map_err(e2s)?;
        }
        root.draw(&PathElement::new(
            vec![(x_of(1.0) as i32, axis_y), (x_of(k as f64) as i32, axis_y)],
            BLACK.stroke_width(2),
        ))
        .map_err(e2s)?;
        for r in 1..=k {
            let x = x_of(r as f64) as i32;
            root.draw(&PathElement::new(vec![(x, axis_y - 6), (x, axis_y)], BLACK))
                .map_err(e2s)?;
            if text {
                root.draw(&Text::new(
                    format!("{r}"),
                    (x - 4, axis_y - 22),
                    style.clone(),
                ))
                .map_err(e2s)?;
            }
        }
        // CD bar.
        let cd_y = 36;
        root.draw(&PathElement::new(
            vec![
                (x_of(1.0) as i32, cd_y),
                (x_of(1.0 + f.nemenyi_cd) as i32, cd_y),
            ],
            series_colour(3).stroke_width(3),
        ))
        .map_err(e2s)?;
        // Groups not significantly different.
        let mut order: Vec<usize> = (0..k).collect();
        order.sort_by(|&a, &b| f.mean_ranks[a].total_cmp(&f.mean_ranks[b]));
        let mut groups: Vec<(f64, f64)> = Vec::new();
        for (a, &i) in order.iter().enumerate() {
            let last = order[a..]
                .iter()
                .take_while(|&&j| f.mean_ranks[j] - f.mean_ranks[i] <= f.nemenyi_cd)
                .last()
                .copied()
                .unwrap_or(i);
            let g = (f.mean_ranks[i], f.mean_ranks[last]);
            if last != i && !groups.iter().any(|h| h.0 <= g.0 && g.1 <= h.1) {
                groups.push(g);
            }
        }
        // Methods, sorted by rank: first half labelled on the left, second on the right.
        let top = axis_y + 30 + 6 * groups.len() as i32;
        let row = (h as i32 - top - 10) / ((k as i32 + 1) / 2 + 1).max(1);
        for (pos, &i) in order.iter().enumerate() {
            let x = x_of(f.mean_ranks[i]) as i32;
            let half = pos < k.div_ceil(2);
            let level = if half { pos } else { k - 1 - pos } as i32;
            let y = top + row * level;
            let end = if half { 20 } else { w as i32 - 20 };
            root.draw(&PathElement::new(
                vec![(x, axis_y), (x, y), (end, y)],
                BLACK,
            ))
            .map_err(e2s)?;
            if text {
                let label = format!("{} ({:.2})", f.methods[i], f.mean_ranks[i]);
                let tx = if half {
                    end
                } else {
                    end - 7 * label.len() as i32
                };
                root.draw(&Text::new(label, (tx, y - 16), style.clone()))
                    .map_err(e2s)?;
            }
        }
        for (gi, (a, b)) in groups.iter().enumerate() {
            let y = axis_y + 12 + 6 * gi as i32;
            root.draw(&PathElement::new(
                vec![(x_of(*a) as i32 - 3, y), (x_of(*b) as i32 + 3, y)],
                BLACK.stroke_width(4),
            ))
            .map_err(e2s)?;
        }
        Ok(())
    }
}

/// Fig. 4: one error per material for each basis, materials sorted by the first basis.
pub struct ErrorsPerMaterial<'a> {
    /// Errors per basis.
    pub errors: &'a [BasisErrors],
    /// `true`: MAE (log scale); `false`: image error.
    pub mae: bool,
}

impl Draw for ErrorsPerMaterial<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let get = |b: &BasisErrors| {
            if self.mae {
                b.mae.clone()
            } else {
                b.image_error.clone()
            }
        };
        let first = get(&self.errors[0]);
        let mut order: Vec<usize> = (0..first.len()).collect();
        order.sort_by(|&a, &b| first[a].total_cmp(&first[b]));
        let all: Vec<f64> = self
            .errors
            .iter()
            .flat_map(get)
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect();
        let lo = all.iter().copied().fold(f64::INFINITY, f64::min).min(1.0);
        let hi = all.iter().copied().fold(0.0, f64::max).max(lo * 10.0);
        let n = first.len() as f64;
        let title = if self.mae {
            "MAE on reflectance per material"
        } else {
            "Normalised image error per material"
        };
        let mut b = ChartBuilder::on(root);
        b.margin(12);
        if text {
            b.caption(title, (FONT, 20))
                .x_label_area_size(40)
                .y_label_area_size(70);
        }
        let xdesc = format!("material (sorted by the error of {})", self.errors[0].basis);
        if self.mae {
            let mut chart = b
                .build_cartesian_2d(-0.5..n - 0.5, (lo * 0.8..hi * 1.25).log_scale())
                .map_err(e2s)?;
            if text {
                chart
                    .configure_mesh()
                    .x_desc(xdesc)
                    .x_label_formatter(&|v| format!("{v:.0}"))
                    .y_desc("MAE (log scale)")
                    .label_style((FONT, 12))
                    .draw()
                    .map_err(e2s)?;
            }
            draw_lines(&mut chart, self.errors, &order, self.mae, lo, text)?;
        } else {
            let mut chart = b
                .build_cartesian_2d(-0.5..n - 0.5, 0.0..hi * 1.1)
                .map_err(e2s)?;
            if text {
                chart
                    .configure_mesh()
                    .x_desc(xdesc)
                    .x_label_formatter(&|v| format!("{v:.0}"))
                    .y_desc("normalised image error")
                    .label_style((FONT, 12))
                    .draw()
                    .map_err(e2s)?;
            }
            draw_lines(&mut chart, self.errors, &order, self.mae, lo, text)?;
        }
        Ok(())
    }
}

fn draw_lines<'a, DB: DrawingBackend + 'a, Y: Ranged<ValueType = f64>>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<RangedCoordf64, Y>>,
    errors: &[BasisErrors],
    order: &[usize],
    mae: bool,
    lo: f64,
    text: bool,
) -> Result<(), String> {
    for (i, be) in errors.iter().enumerate() {
        let v = if mae { &be.mae } else { &be.image_error };
        let c = series_colour(i);
        let pts: Vec<(f64, f64)> = order
            .iter()
            .enumerate()
            .map(|(x, &t)| (x as f64, v[t].max(lo)))
            .collect();
        let s = chart
            .draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))
            .map_err(e2s)?;
        if text {
            s.label(be.basis.clone()).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(3))
            });
        }
        chart
            .draw_series(pts.into_iter().map(|p| Circle::new(p, 2, c.filled())))
            .map_err(e2s)?;
    }
    if text {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font((FONT, 12))
            .draw()
            .map_err(e2s)?;
    }
    Ok(())
}

/// Fig. 2.
pub fn histogram(counts: &[usize]) -> Result<Figure, PlotError> {
    figure("fig2-contributions", (800, 500), &Histogram { counts })
}

/// Fig. 3.
pub fn db_boxplots(metrics: &[String], sets: &[ClusteringSet]) -> Result<Figure, PlotError> {
    figure(
        "fig3-db-boxplots",
        (420 * metrics.len().max(1) as u32, 520),
        &DbBoxplots { metrics, sets },
    )
}

/// DB against k.
pub fn db_vs_k(metrics: &[String], sets: &[ClusteringSet]) -> Result<Figure, PlotError> {
    figure(
        "db-vs-k",
        (420 * metrics.len().max(1) as u32, 420),
        &DbVsK { metrics, sets },
    )
}

/// Nemenyi critical-difference diagram of one metric.
pub fn cd_diagram(metric: &str, friedman: &FriedmanSummary) -> Result<Figure, PlotError> {
    let h = 190 + 30 * friedman.methods.len().div_ceil(2) as u32;
    figure(
        &format!("cd-{metric}"),
        (900, h),
        &CdDiagram { metric, friedman },
    )
}

/// Fig. 4a (`mae`) or 4b.
pub fn errors_per_material(errors: &[BasisErrors], mae: bool) -> Result<Figure, PlotError> {
    if errors.is_empty() || errors[0].mae.is_empty() {
        return Err(PlotError::NoData("errors per material".into()));
    }
    let stem = if mae {
        "fig4a-mae"
    } else {
        "fig4b-image-error"
    };
    figure(stem, (1000, 560), &ErrorsPerMaterial { errors, mae })
}
