//! The figure set of `reproduce`'s report, built from an [`Experiment`]: a library user
//! gets the same figures as the command line (writing them is the caller's part).

use super::{charts, lobes, no_font_message, showcase, with_text, Figure, PlotError};
use brdf_basis::eval::image_error::DisplayParams;
use brdf_basis::eval::shade::{combination_brdf, material_brdf, BrdfFn};
use brdf_basis::experiment::Experiment;

/// Incident angles of the showcase's lobe plot, degrees.
pub(crate) const LOBE_ANGLES: [f64; 4] = [0.0, 30.0, 60.0, 75.0];

/// The report's figures and what the reader must be told about them.
#[derive(Clone, Debug)]
pub(crate) struct ReportFigures {
    /// Figures in report order (stems as [`brdf_basis::experiment::report`] expects them).
    pub(crate) figures: Vec<Figure>,
    /// Notes for the report and warnings (no font; figures' own notes).
    pub(crate) notes: Vec<String>,
}

fn data_error(figure: &str, message: String) -> PlotError {
    PlotError::Data {
        figure: figure.into(),
        message,
    }
}

/// The lobe curves of the showcase: the material, then its fit by each basis.
pub(crate) fn showcase_curves(e: &Experiment) -> Result<Vec<(String, BrdfFn)>, PlotError> {
    let err = |m: String| data_error("lobes-showcase", m);
    let coll = &e.collection;
    let s = &e.evaluation.showcase;
    let m = coll.get(&s.material).map_err(|x| err(x.to_string()))?;
    let mut curves = vec![(s.material.clone(), material_brdf(&m.data))];
    for (a, b) in s.approximations.iter().zip(&e.bases) {
        let idx: Vec<usize> = b
            .materials
            .iter()
            .map(|m| coll.index_of(m))
            .collect::<Result<_, _>>()
            .map_err(|x| err(x.to_string()))?;
        let cols = a
            .fit
            .columns(&b.materials)
            .map_err(|m| err(format!("basis `{}` has no coefficient for `{m}`", b.name)))?;
        curves.push((a.basis.clone(), combination_brdf(coll, &idx, &cols)));
    }
    Ok(curves)
}

/// Every figure of the report: Fig. 2, Fig. 3, DB against k, Fig. 4a/4b, Fig. 5, the
/// showcase's lobe plot and one critical-difference diagram per metric.
pub(crate) fn report_figures(e: &Experiment) -> Result<ReportFigures, PlotError> {
    let mut notes: Vec<String> = no_font_message().into_iter().collect();
    let metrics: Vec<String> = e.settings.metrics.iter().map(|m| m.label.clone()).collect();
    let ev = &e.evaluation;
    let mut figures = vec![
        charts::histogram(&e.empirical.counts)?,
        charts::db_boxplots(&metrics, &e.clustering)?,
        charts::db_vs_k(&metrics, &e.clustering)?,
        charts::errors_per_material(&ev.targets, &ev.errors, true)?,
        charts::errors_per_material(&ev.targets, &ev.errors, false)?,
        showcase::showcase_figure(&ev.showcase, &DisplayParams::default(), with_text())?,
        lobes::lobe_plot(
            "lobes-showcase",
            &format!(
                "{}: BRDF in the plane of incidence (mean RGB, log radius over 4 decades, one scale for all panels) and its fits",
                ev.showcase.material
            ),
            &showcase_curves(e)?,
            &LOBE_ANGLES,
        )?,
    ];
    for (key, f) in &e.statistics.friedman {
        figures.push(charts::cd_diagram(key.metric(), f)?);
    }
    for f in &figures {
        notes.extend(f.notes.iter().cloned());
    }
    Ok(ReportFigures { figures, notes })
}
