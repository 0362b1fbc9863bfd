//! Charts of `reproduce`: contributions histogram (Fig. 2), DB box plots (Fig. 3), DB
//! against k, Nemenyi critical-difference diagram and errors per material (Fig. 4).

use super::legend::{self, tick_label, Entry, Marker};
use super::{e2s, figure, series_colour, Draw, Figure, PlotError};
use brdf_basis::experiment::evaluation::BasisErrors;
use brdf_basis::experiment::statistics::FriedmanSummary;
use brdf_basis::select::ClusteringSet;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;

const FONT: &str = "sans-serif";

/// Fig. 2: number of materials (y) that contribute to x fits.
pub(crate) struct Histogram<'a> {
    /// Contributions of each material.
    pub(crate) counts: &'a [usize],
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

/// Box-plot statistics of one sample (Tukey 1977): quartiles by linear interpolation
/// between order statistics (R's type 7, as plotters' `Quartiles`), whiskers at the most
/// extreme values within 1.5 IQR of the box, the values beyond as outliers. Whiskers are
/// always data values: never a fence no run reached.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct BoxStats {
    /// First quartile.
    pub(crate) q1: f64,
    /// Median.
    pub(crate) median: f64,
    /// Third quartile.
    pub(crate) q3: f64,
    /// Lower whisker: the smallest value `>= q1 - 1.5 IQR`.
    pub(crate) low: f64,
    /// Upper whisker: the largest value `<= q3 + 1.5 IQR`.
    pub(crate) high: f64,
    /// Values beyond the whiskers, ascending.
    pub(crate) outliers: Vec<f64>,
}

/// [`BoxStats`] of the finite values of `v` (`None` when there are none).
pub(crate) fn box_stats(v: &[f64]) -> Option<BoxStats> {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return None;
    }
    s.sort_by(f64::total_cmp);
    let q = |p: f64| {
        let r = p * (s.len() - 1) as f64;
        let (i, f) = (r.floor() as usize, r - r.floor());
        if i + 1 < s.len() {
            s[i] + (s[i + 1] - s[i]) * f
        } else {
            s[i]
        }
    };
    let (q1, median, q3) = (q(0.25), q(0.5), q(0.75));
    let iqr = q3 - q1;
    let (lo_fence, hi_fence) = (q1 - 1.5 * iqr, q3 + 1.5 * iqr);
    let inside = || {
        s.iter()
            .copied()
            .filter(|&x| lo_fence <= x && x <= hi_fence)
    };
    // The quartiles lie inside the fences, so some data value does too.
    let low = inside().next().unwrap_or(q1);
    let high = inside().next_back().unwrap_or(q3);
    let outliers = s.iter().copied().filter(|&x| x < low || x > high).collect();
    Some(BoxStats {
        q1,
        median,
        q3,
        low,
        high,
        outliers,
    })
}

pub(crate) use brdf_basis::experiment::report::BOXPLOT_KEY;

/// Fig. 3: DB box plots, one panel per metric, one box per method.
pub(crate) struct DbBoxplots<'a> {
    /// Metric labels, one panel each.
    pub(crate) metrics: &'a [String],
    /// Every clustering set.
    pub(crate) sets: &'a [ClusteringSet],
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

/// Short axis label of a clustering method: `kmedoids-k7` is `k7`.
pub(crate) fn method_label(method: &str) -> String {
    legend::short_name(method.strip_prefix("kmedoids-").unwrap_or(method), 12)
}

impl Draw for DbBoxplots<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let (body, foot) = root.split_vertically(root.dim_in_pixel().1 - 24);
        if text {
            foot.draw(&Text::new(BOXPLOT_KEY, (12, 4), (FONT, 12).into_font()))
                .map_err(e2s)?;
        }
        let panels = body.split_evenly((1, self.metrics.len().max(1)));
        for (m, area) in self.metrics.iter().zip(panels) {
            let sets: Vec<&ClusteringSet> = self.sets.iter().filter(|s| &s.metric == m).collect();
            // The axis covers every run, so nothing is clipped.
            let (lo, hi) = finite_range(sets.iter().flat_map(|s| s.db_values()));
            let names: Vec<String> = sets.iter().map(|s| method_label(&s.method)).collect();
            let slot = (area.dim_in_pixel().0.saturating_sub(80)) / (sets.len().max(1) as u32);
            let widest = names
                .iter()
                .map(|n| legend::text_width(n, 12))
                .max()
                .unwrap_or(0);
            let rotate = widest + 4 > slot;
            let mut b = ChartBuilder::on(&area);
            b.margin(10);
            if text {
                b.caption(format!("DB index: {m}"), (FONT, 18))
                    .x_label_area_size(if rotate { 20 + widest } else { 44 })
                    .y_label_area_size(60);
            }
            let mut chart = b
                .build_cartesian_2d(-0.5f64..sets.len() as f64 - 0.5, lo..hi)
                .map_err(e2s)?;
            if text {
                let style = if rotate {
                    (FONT, 12).into_font().transform(FontTransform::Rotate90)
                } else {
                    (FONT, 12).into_font()
                };
                chart
                    .configure_mesh()
                    .disable_x_mesh()
                    .label_style((FONT, 12))
                    .x_labels(sets.len() * 2 + 1)
                    .x_label_formatter(&|v| {
                        let i = v.round();
                        if (v - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < names.len() {
                            names[i as usize].clone()
                        } else {
                            String::new()
                        }
                    })
                    // After label_style, which would replace it.
                    .x_label_style(style)
                    .y_label_formatter(&|v| tick_label(*v))
                    .x_desc("method (kN: k-medoids with k = N)")
                    .y_desc("Davies-Bouldin index (lower is better)")
                    .draw()
                    .map_err(e2s)?;
            }
            for (i, s) in sets.iter().enumerate() {
                let Some(q) = box_stats(&s.db_values()) else {
                    continue;
                };
                let x = i as f64;
                let c = series_colour(if s.method == "gcuk" { 3 } else { 0 });
                chart
                    .draw_series([
                        Rectangle::new([(x - 0.3, q.q1), (x + 0.3, q.q3)], c.mix(0.35).filled()),
                        Rectangle::new([(x - 0.3, q.q1), (x + 0.3, q.q3)], c.stroke_width(1)),
                    ])
                    .map_err(e2s)?;
                chart
                    .draw_series([
                        PathElement::new(
                            vec![(x - 0.3, q.median), (x + 0.3, q.median)],
                            BLACK.stroke_width(2),
                        ),
                        PathElement::new(vec![(x, q.low), (x, q.q1)], c.stroke_width(1)),
                        PathElement::new(vec![(x, q.q3), (x, q.high)], c.stroke_width(1)),
                        PathElement::new(
                            vec![(x - 0.15, q.low), (x + 0.15, q.low)],
                            c.stroke_width(1),
                        ),
                        PathElement::new(
                            vec![(x - 0.15, q.high), (x + 0.15, q.high)],
                            c.stroke_width(1),
                        ),
                    ])
                    .map_err(e2s)?;
                chart
                    .draw_series(
                        q.outliers
                            .iter()
                            .map(|&y| Circle::new((x, y), 2, c.filled())),
                    )
                    .map_err(e2s)?;
            }
        }
        Ok(())
    }
}

/// DB against k: every k-medoids run and every GCUK run at the k it found, one panel per
/// metric; the line joins the k-medoids medians.
pub(crate) struct DbVsK<'a> {
    /// Metric labels.
    pub(crate) metrics: &'a [String],
    /// Every clustering set.
    pub(crate) sets: &'a [ClusteringSet],
}

/// The legend of [`DbVsK`], drawn under the panels.
fn db_vs_k_legend() -> Vec<Entry> {
    vec![
        Entry::new(
            "k-medoids runs (left of k)",
            Marker::Dot(over_white(series_colour(0), 0.6)),
        ),
        Entry::new("k-medoids median", Marker::Line(series_colour(0), 2)),
        Entry::new(
            "GCUK runs (right of the k found)",
            Marker::Dot(over_white(series_colour(3), 0.6)),
        ),
    ]
}

/// `c` at opacity `a` over white, as drawn.
fn over_white(c: RGBColor, a: f64) -> RGBColor {
    let over = |v: u8| (v as f64 * a + 255.0 * (1.0 - a)).round() as u8;
    RGBColor(over(c.0), over(c.1), over(c.2))
}

impl Draw for DbVsK<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let (body, foot) = root.split_vertically(root.dim_in_pixel().1 - 28);
        legend::draw_flow(&foot, &db_vs_k_legend(), 13, text)?;
        let panels = body.split_evenly((1, self.metrics.len().max(1)));
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
                    .y_label_formatter(&|v| tick_label(*v))
                    .label_style((FONT, 12))
                    .draw()
                    .map_err(e2s)?;
            }
            for s in &sets {
                let gc = s.method == "gcuk";
                let c = series_colour(if gc { 3 } else { 0 });
                let dx = if gc { 0.15 } else { -0.15 };
                chart
                    .draw_series(s.runs.iter().filter(|r| r.db_index.is_finite()).map(|r| {
                        Circle::new((r.k as f64 + dx, r.db_index), 2, c.mix(0.6).filled())
                    }))
                    .map_err(e2s)?;
            }
            let med: Vec<(f64, f64)> = sets
                .iter()
                .filter(|s| s.method != "gcuk")
                .map(|s| {
                    (
                        s.best.k as f64 - 0.15,
                        brdf_basis::stats::median(&s.db_values()),
                    )
                })
                .filter(|p| p.1.is_finite())
                .collect();
            chart
                .draw_series(LineSeries::new(med, series_colour(0).stroke_width(2)))
                .map_err(e2s)?;
        }
        Ok(())
    }
}

/// The rank axis's height in a CD diagram, pixels from the top.
const CD_AXIS_Y: i32 = 70;
/// Pixels between the label rows of a CD diagram.
const CD_ROW: i32 = 30;

/// The height of the first label row of a CD diagram with `groups` clique bars (6 pixels
/// each below the axis).
fn cd_first_row(groups: usize) -> i32 {
    // The labels sit 16 pixels above their row's line: 24 pixels below the last bar keep
    // the bars clear of the first labels.
    CD_AXIS_Y + 12 + 6 * groups as i32 + 24 + 16
}

/// Nemenyi critical-difference diagram (Demšar 2006, Fig. 1): methods on the axis of mean
/// ranks; a bar joins methods whose ranks differ by less than the critical difference.
pub(crate) struct CdDiagram<'a> {
    /// Metric label.
    pub(crate) metric: &'a str,
    /// The Friedman summary.
    pub(crate) friedman: &'a FriedmanSummary,
}

/// Methods by ascending mean rank, and the groups of methods not significantly different
/// (mean ranks within the critical difference) as `(lowest, highest)` mean rank, none
/// inside another.
pub(crate) fn cd_groups(f: &FriedmanSummary) -> (Vec<usize>, Vec<(f64, f64)>) {
    let mut order: Vec<usize> = (0..f.methods.len()).collect();
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
    (order, groups)
}

impl Draw for CdDiagram<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
    ) -> Result<(), String> {
        let f = self.friedman;
        let k = f.methods.len();
        let (w, _) = root.dim_in_pixel();
        let (left, right) = (60.0, w as f64 - 60.0);
        let x_of = |r: f64| left + (r - 1.0) / (k as f64 - 1.0).max(1.0) * (right - left);
        let axis_y = CD_AXIS_Y;
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
        if text {
            root.draw(&Text::new(
                format!("CD = {}", tick_label(f.nemenyi_cd)),
                (x_of(1.0 + f.nemenyi_cd) as i32 + 8, cd_y - 8),
                style.clone(),
            ))
            .map_err(e2s)?;
        }
        let (order, groups) = cd_groups(f);
        // Methods, sorted by rank: first half labelled on the left, second on the right.
        let top = cd_first_row(groups.len());
        let row = CD_ROW;
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

/// Fig. 4: one error per material for each basis. 4a and 4b show the materials in the
/// same order, [`material_order`], and name them on the x axis; the legend is a column
/// right of the chart.
pub(crate) struct ErrorsPerMaterial<'a> {
    /// Target names (the order of the error vectors).
    pub(crate) targets: &'a [String],
    /// Errors per basis.
    pub(crate) errors: &'a [BasisErrors],
    /// `true`: MAE (log scale); `false`: image error.
    pub(crate) mae: bool,
}

/// The x order of Fig. 4a and 4b: targets by ascending MAE of the first basis (ties: target
/// order), the same for both panels so that a material sits at one x in both.
pub(crate) fn material_order(errors: &[BasisErrors]) -> Vec<usize> {
    let first = errors.first().map_or(&[][..], |b| &b.mae[..]);
    let mut order: Vec<usize> = (0..first.len()).collect();
    order.sort_by(|&a, &b| first[a].total_cmp(&first[b]));
    order
}

/// Longest material name shown on Fig. 4's axis (longer ones are cut with `...`).
const NAME_CHARS: usize = 28;
const NAME_SIZE: u32 = 11;

fn fig4_legend(errors: &[BasisErrors]) -> Vec<Entry> {
    errors
        .iter()
        .enumerate()
        .map(|(i, b)| {
            Entry::new(
                legend::short_name(&b.basis, NAME_CHARS),
                Marker::Line(series_colour(i), 3),
            )
        })
        .collect()
}

/// Height of Fig. 4's x labels (names written downwards).
fn name_area(targets: &[String]) -> u32 {
    let widest = targets
        .iter()
        .map(|t| legend::text_width(&legend::short_name(t, NAME_CHARS), NAME_SIZE))
        .max()
        .unwrap_or(0);
    // Names are written downwards from 6 px below the axis; the axis title goes under them.
    widest + 34
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
        let order = material_order(self.errors);
        let all: Vec<f64> = self
            .errors
            .iter()
            .flat_map(get)
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect();
        let lo = all.iter().copied().fold(f64::INFINITY, f64::min).min(1.0);
        let hi = all.iter().copied().fold(0.0, f64::max).max(lo * 10.0);
        let n = order.len() as f64;
        let title = if self.mae {
            "MAE on reflectance per material"
        } else {
            "Normalised image error per material"
        };
        let entries = fig4_legend(self.errors);
        let (w, _) = root.dim_in_pixel();
        let (plot_area, legend_area) = if text {
            root.split_horizontally(w - legend::column_width(&entries, 12) - 10)
        } else {
            root.split_horizontally(w)
        };
        legend::draw_column(&legend_area, &entries, 12, 44, text)?;
        let mut b = ChartBuilder::on(&plot_area);
        b.margin(12);
        if text {
            b.caption(title, (FONT, 20))
                .x_label_area_size(name_area(self.targets))
                .y_label_area_size(70);
        }
        let names: Vec<String> = order
            .iter()
            .map(|&t| {
                legend::short_name(self.targets.get(t).map_or("?", String::as_str), NAME_CHARS)
            })
            .collect();
        let xdesc = format!(
            "material (sorted by the MAE of {}; the same order in Fig. 4a and 4b)",
            legend::short_name(&self.errors[0].basis, NAME_CHARS)
        );
        let ydesc = if self.mae {
            "MAE (log scale)"
        } else {
            "normalised image error"
        };
        macro_rules! body {
            ($chart:ident) => {{
                if text {
                    $chart
                        .configure_mesh()
                        .x_desc(xdesc.clone())
                        .x_labels(0)
                        .disable_x_mesh()
                        .y_desc(ydesc)
                        .y_label_formatter(&|v| tick_label(*v))
                        .label_style((FONT, 12))
                        .draw()
                        .map_err(e2s)?;
                    let y0 = $chart.y_range().start;
                    let at: Vec<(i32, i32)> = (0..names.len())
                        .map(|x| $chart.backend_coord(&(x as f64, y0)))
                        .collect();
                    draw_names(root, &names, &at)?;
                }
                draw_lines(&mut $chart, self.errors, &order, self.mae, lo)?;
            }};
        }
        if self.mae {
            let mut chart = b
                .build_cartesian_2d(-0.5..n - 0.5, (lo * 0.8..hi * 1.25).log_scale())
                .map_err(e2s)?;
            body!(chart);
        } else {
            let mut chart = b
                .build_cartesian_2d(-0.5..n - 0.5, 0.0..hi * 1.1)
                .map_err(e2s)?;
            body!(chart);
        }
        Ok(())
    }
}

/// Material names written downwards under the x axis, one at each backend point of `at`.
fn draw_names<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    names: &[String],
    at: &[(i32, i32)],
) -> Result<(), String> {
    for (name, &(px, py)) in names.iter().zip(at) {
        root.draw(&Text::new(
            name.clone(),
            (px + NAME_SIZE as i32 / 2, py + 6),
            (FONT, NAME_SIZE)
                .into_font()
                .transform(FontTransform::Rotate90),
        ))
        .map_err(e2s)?;
    }
    Ok(())
}

fn draw_lines<'a, DB: DrawingBackend + 'a, Y: Ranged<ValueType = f64>>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<RangedCoordf64, Y>>,
    errors: &[BasisErrors],
    order: &[usize],
    mae: bool,
    lo: f64,
) -> Result<(), String> {
    for (i, be) in errors.iter().enumerate() {
        let v = if mae { &be.mae } else { &be.image_error };
        let c = series_colour(i);
        let pts: Vec<(f64, f64)> = order
            .iter()
            .enumerate()
            .map(|(x, &t)| (x as f64, v[t].max(lo)))
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))
            .map_err(e2s)?;
        chart
            .draw_series(pts.into_iter().map(|p| Circle::new(p, 2, c.filled())))
            .map_err(e2s)?;
    }
    Ok(())
}

/// Fig. 2.
pub(crate) fn histogram(counts: &[usize]) -> Result<Figure, PlotError> {
    figure("fig2-contributions", (800, 500), &Histogram { counts })
}

/// Fig. 3.
pub(crate) fn db_boxplots(metrics: &[String], sets: &[ClusteringSet]) -> Result<Figure, PlotError> {
    figure(
        "fig3-db-boxplots",
        (420 * metrics.len().max(1) as u32, 544),
        &DbBoxplots { metrics, sets },
    )
}

/// DB against k.
pub(crate) fn db_vs_k(metrics: &[String], sets: &[ClusteringSet]) -> Result<Figure, PlotError> {
    figure(
        "db-vs-k",
        (420 * metrics.len().max(1) as u32, 450),
        &DbVsK { metrics, sets },
    )
}

/// Nemenyi critical-difference diagram of one metric.
pub(crate) fn cd_diagram(metric: &str, friedman: &FriedmanSummary) -> Result<Figure, PlotError> {
    // As tall as the label rows need: the first row below the clique bars, then one row
    // per method of the longer side, and a margin under the last label.
    let levels = friedman.methods.len().div_ceil(2).max(1) as i32;
    let h = cd_first_row(cd_groups(friedman).1.len()) + CD_ROW * (levels - 1) + 24;
    figure(
        &format!("cd-{metric}"),
        (900, h as u32),
        &CdDiagram { metric, friedman },
    )
}

/// Fig. 4a (`mae`) or 4b of the errors of `targets`.
pub(crate) fn errors_per_material(
    targets: &[String],
    errors: &[BasisErrors],
    mae: bool,
) -> Result<Figure, PlotError> {
    if errors.is_empty() || errors[0].mae.is_empty() {
        return Err(PlotError::NoData("errors per material".into()));
    }
    let stem = if mae {
        "fig4a-mae"
    } else {
        "fig4b-image-error"
    };
    let n = errors[0].mae.len() as u32;
    let legend_w = legend::column_width(&fig4_legend(errors), 12);
    let w = (180 + legend_w + 18 * n).max(1000);
    figure(
        stem,
        (w, 460 + name_area(targets)),
        &ErrorsPerMaterial {
            targets,
            errors,
            mae,
        },
    )
}
