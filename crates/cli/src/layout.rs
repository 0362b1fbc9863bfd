//! The files of a reproduced experiment (what `brdf-basis reproduce --out DIR` holds):
//! their names, the rule telling them from any other file ([`is_output`]), the
//! [`Summary`], and the writers of everything but the figures ([`write_files`], then
//! [`write_summary_and_report`] once the figures are listed in the report context).
//!
//! ```text
//! DIR/report.md            the report (figures linked from figures/)
//! DIR/summary.json         settings, targets, errors per basis, claims, timings
//! DIR/distance-<m>.npy     each distance matrix (with its .names.json sidecar) and .csv
//! DIR/empirical.json       empirical selection          DIR/clustering.json, clustering_db.csv
//! DIR/statistics.json      statistical tests            DIR/bases.json
//! DIR/selection.json       bases chosen by fitting error (when run)
//! DIR/cv.json              cross-validation (when run)
//! DIR/acquisition.json     acquisition cross-validation (when run)
//! DIR/appearance.json      held-out fits under each objective of SPEC 11 (when run)
//! DIR/fit-<basis>.json     the fits of each basis       DIR/fit_errors.csv
//! DIR/renders/             showcase renders (EXR, PNG) and heatmaps
//! DIR/figures/             the report's figures (SVG and PNG)
//! ```
//!
//! The writers write into any directory: the command line gives them the staging root
//! of its output tree ([`brdf_basis::atomic::OutputPlan::tree`]), so the tree appears whole
//! or not at all.

use crate::plot::colour_bar::{font_registered, with_colour_bar};
use brdf_basis::distance::{DistanceParams, Metric, DEFAULT_BAND_ROWS};
use brdf_basis::error::{DistanceError, OutputError};
use brdf_basis::eval::image_error::{heatmap, DisplayParams, HeatmapScale};
use brdf_basis::eval::render::RenderError;
use brdf_basis::experiment::report::{markdown, ReportContext};
use brdf_basis::experiment::{claims, evaluation, Experiment, StageTiming};
use brdf_basis::io::image::{write_exr, write_png, write_rgb8_image, HEATMAP_QUANTITY};
use brdf_basis::io::json::write_json;
use brdf_basis::io::saved::{write_csv, write_npy_with_sidecar};
use brdf_basis::io::sidecar::{sidecar_path, MatrixSettings};
use brdf_basis::merl::Weighting;
use brdf_basis::select as clustering;
use brdf_basis::select::EmpiricalOutput;
use std::path::{Path, PathBuf};

/// The report.
pub(crate) const REPORT: &str = "report.md";
/// The summary ([`Summary`]).
pub(crate) const SUMMARY: &str = "summary.json";
/// The directory of the figures.
pub(crate) const FIGURES: &str = "figures";
/// The acquisition cross-validation (`reproduce`'s "Acquisition" section).
pub(crate) const ACQUISITION: &str = "acquisition.json";

/// The appearance study (`reproduce`'s "Appearance" section).
pub(crate) const APPEARANCE: &str = "appearance.json";

/// The directory of the showcase renders.
pub(crate) const RENDERS: &str = "renders";

/// Whether `name` (an entry of the output directory) is one `reproduce` writes: what
/// `--force` may replace.
pub(crate) fn is_output(name: &str) -> bool {
    matches!(
        name,
        "report.md"
            | "statistics.json"
            | "clustering.json"
            | "clustering_db.csv"
            | "bases.json"
            | "empirical.json"
            | "fit_errors.csv"
            | "summary.json"
            | "selection.json"
            | "cv.json"
            | "acquisition.json"
            | "appearance.json"
            | "renders"
            | "figures"
    ) || (name.starts_with("fit-") && name.ends_with(".json"))
        || (name.starts_with("distance-")
            && (name.ends_with(".npy") || name.ends_with(".csv") || name.ends_with(".names.json")))
}

/// Errors writing the experiment's files.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub(crate) enum LayoutError {
    /// Writing a file failed.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// A heatmap could not be made.
    #[error(transparent)]
    Render(#[from] RenderError),
    /// The settings of a distance matrix (for its sidecar) are not valid.
    #[error(transparent)]
    Distance(#[from] DistanceError),
}

/// `summary.json`: the settings, the per-basis errors, the claims and the timings.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub(crate) struct Summary {
    /// Settings as run.
    pub(crate) settings: brdf_basis::experiment::Settings,
    /// Evaluation targets.
    pub(crate) targets: Vec<String>,
    /// Errors per basis.
    pub(crate) errors: Vec<evaluation::BasisErrors>,
    /// The paper's claims checked.
    pub(crate) claims: Vec<claims::Claim>,
    /// Wall time per stage.
    pub(crate) timings: Vec<StageTiming>,
}

impl Summary {
    /// The summary of `e`, with the extra timings of `ctx` (files, figures).
    pub(crate) fn of(e: &Experiment, ctx: &ReportContext) -> Self {
        Summary {
            settings: e.settings.clone(),
            targets: e.evaluation.targets.clone(),
            errors: e.evaluation.errors.clone(),
            claims: claims::check(e),
            timings: e.timings.iter().chain(&ctx.timings).cloned().collect(),
        }
    }
}

/// The sidecar settings of the experiment's distance matrix `i`.
fn matrix_settings(e: &Experiment, i: usize) -> Result<MatrixSettings, LayoutError> {
    let m = &e.settings.metrics[i];
    let p = DistanceParams::default()
        .metric(m.metric.parse::<Metric>()?)
        .weighting(m.weighting.parse::<Weighting>()?)
        .stride(e.settings.stride)
        .check(&e.collection)?;
    Ok(MatrixSettings::of(&p, DEFAULT_BAND_ROWS))
}

/// Writes every file but the figures, the summary and the report into `dir` (which
/// exists): the distance matrices (`.npy` with its sidecar, and `.csv`), the JSON and
/// CSV results, and the showcase renders with heatmaps on the common `heatmap_scale`
/// (`plot::showcase::common_scale`). Returns the files written, relative to `dir`.
pub(crate) fn write_files(
    e: &Experiment,
    dir: &Path,
    heatmap_scale: f64,
) -> Result<Vec<PathBuf>, LayoutError> {
    let mut written = Vec::new();
    let mut rel = |p: &Path| written.push(p.strip_prefix(dir).unwrap_or(p).to_path_buf());
    let fingerprint = e.collection.fingerprint();
    for (i, (m, d)) in e.settings.metrics.iter().zip(&e.distances).enumerate() {
        let npy = dir.join(format!("distance-{}.npy", m.label));
        write_npy_with_sidecar(&npy, d, &matrix_settings(e, i)?, &fingerprint)?;
        rel(&npy);
        rel(&sidecar_path(&npy));
        let csv = dir.join(format!("distance-{}.csv", m.label));
        write_csv(&csv, d)?;
        rel(&csv);
    }
    let mut json = |name: &str, value: &dyn erased::Json| -> Result<(), LayoutError> {
        let p = dir.join(name);
        value.write(&p)?;
        rel(&p);
        Ok(())
    };
    json(
        "empirical.json",
        &EmpiricalOutput::of(&e.empirical, Some(fingerprint.clone())),
    )?;
    json("clustering.json", &e.clustering)?;
    json("statistics.json", &e.statistics)?;
    json("bases.json", &e.bases)?;
    if !e.selections.is_empty() {
        json("selection.json", &e.selections)?;
    }
    if let Some(cv) = &e.cv {
        json("cv.json", cv)?;
    }
    for (b, f) in e.bases.iter().zip(&e.evaluation.fits) {
        json(&format!("fit-{}.json", b.name), f)?;
    }
    for (name, text) in [
        ("clustering_db.csv", clustering::db_csv(&e.clustering)),
        ("fit_errors.csv", evaluation::errors_csv(&e.evaluation)),
    ] {
        let p = dir.join(name);
        write_text(&p, &text)?;
        rel(&p);
    }
    let display = DisplayParams::default();
    let show = &e.evaluation.showcase;
    let r = dir.join(RENDERS);
    std::fs::create_dir(&r).map_err(|source| OutputError::Io {
        path: r.clone(),
        source,
    })?;
    let p = r.join("showcase-original.exr");
    write_exr(&p, &show.original)?;
    rel(&p);
    let p = r.join("showcase-original.png");
    write_png(&p, &show.original, &display)?;
    rel(&p);
    for a in &show.approximations {
        let (name, img) = (&a.basis, &a.image);
        let p = r.join(format!("showcase-{name}.exr"));
        write_exr(&p, img)?;
        rel(&p);
        let p = r.join(format!("showcase-{name}.png"));
        write_png(&p, img, &display)?;
        rel(&p);
        let p = r.join(format!("showcase-{name}-heatmap.png"));
        let heat = heatmap(
            &show.original,
            img,
            &display,
            HeatmapScale::Fixed(heatmap_scale),
        )?;
        // With its colour bar, labelled when a font is registered (`plot::font`).
        let bar = with_colour_bar(&heat, heatmap_scale, HEATMAP_QUANTITY, font_registered())
            .map_err(|message| OutputError::Encode {
                path: p.clone(),
                message,
            })?;
        write_rgb8_image(&p, &bar)?;
        rel(&p);
    }
    Ok(written)
}

/// Writes `summary.json` and `report.md` into `dir` (after the figures, which `ctx`
/// lists). Returns the files written, relative to `dir`.
pub(crate) fn write_summary_and_report(
    e: &Experiment,
    ctx: &ReportContext,
    dir: &Path,
) -> Result<Vec<PathBuf>, LayoutError> {
    write_json(&dir.join(SUMMARY), &Summary::of(e, ctx))?;
    write_text(&dir.join(REPORT), &markdown(e, ctx))?;
    Ok(vec![PathBuf::from(SUMMARY), PathBuf::from(REPORT)])
}

fn write_text(path: &Path, text: &str) -> Result<(), OutputError> {
    brdf_basis::atomic::write_atomic(path, |w| w.write_all(text.as_bytes()))
}

/// `write_json` for values of different types through one closure.
mod erased {
    use brdf_basis::error::OutputError;
    use std::path::Path;

    pub(super) trait Json {
        fn write(&self, path: &Path) -> Result<(), OutputError>;
    }

    impl<T: serde::Serialize> Json for T {
        fn write(&self, path: &Path) -> Result<(), OutputError> {
            brdf_basis::io::json::write_json(path, self)
        }
    }
}
