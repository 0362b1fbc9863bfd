//! `brdf-basis reproduce`: the paper's section VI end to end ([`brdf_basis::experiment`]);
//! this module parses the arguments, checks the output directory and writes the files.

use super::Global;
use anyhow::Context;
use brdf_basis::eval::image_error::{heatmap, DisplayParams, HeatmapScale};
use brdf_basis::experiment::bases::read_paper_bases;
use brdf_basis::experiment::files::EmpiricalFile;
use brdf_basis::experiment::report::{markdown, ReportContext};
use brdf_basis::experiment::{
    claims, clustering, evaluation, run as run_experiment, ExperimentParams, Stage, StageTiming,
};
use brdf_basis::io::atomic::write_atomic;
use brdf_basis::io::image::{write_exr, write_png, write_rgb8_image};
use brdf_basis::io::json::write_json;
use brdf_basis::io::saved::{write_csv, write_npy};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `reproduce`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis reproduce --out results\n  brdf-basis reproduce --out quick --runs 5 --stride 4 --force"
)]
pub struct ReproduceArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// Output directory (created; must be empty unless --force).
    #[arg(long)]
    pub out: PathBuf,
    /// Clear the files of an earlier `reproduce` from --out first (other files: refused).
    #[arg(long)]
    pub force: bool,
    /// Runs per clustering configuration (paper: 30).
    #[arg(long, default_value_t = 30)]
    pub runs: usize,
    /// Grid stride for distances and fits (1 = full grid).
    #[arg(long, default_value_t = 1)]
    pub stride: usize,
    /// Smallest k of k-medoids and GCUK (paper: 5).
    #[arg(long, default_value_t = 5)]
    pub k_min: usize,
    /// Largest k of k-medoids (paper: 12).
    #[arg(long, default_value_t = 12)]
    pub k_max: usize,
    /// GCUK k_max (paper: 20).
    #[arg(long, default_value_t = 20)]
    pub gcuk_k_max: usize,
    /// Render size in pixels for the image errors.
    #[arg(long, default_value_t = 96)]
    pub render_size: u32,
    /// Material shown in full-size renders, heatmaps and lobe plots (default: alum-bronze
    /// when it is evaluated, else the first evaluated material).
    #[arg(long)]
    pub showcase: Option<String>,
    /// The paper's bases, CSV with columns basis,material: fitted on the same targets.
    #[arg(long)]
    pub paper_bases: Option<PathBuf>,
    /// Folds of the cross-validation of every selection method (0: none).
    #[arg(long, default_value_t = 5)]
    pub cv_folds: usize,
    /// k-medoids restarts and GCUK runs per fold in the cross-validation.
    #[arg(long, default_value_t = 10)]
    pub cv_runs: usize,
    /// Leave out the bases chosen by fitting error (greedy, swap).
    #[arg(long)]
    pub no_selection: bool,
}

/// What `reproduce` may find in an output directory it clears with --force.
fn ours(name: &str) -> bool {
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
            | "renders"
            | "figures"
    ) || (name.starts_with("fit-") && name.ends_with(".json"))
        || (name.starts_with("distance-") && (name.ends_with(".npy") || name.ends_with(".csv")))
}

/// Creates `out` or checks it is empty (with `force`: removes what an earlier run wrote,
/// refusing when anything else is there), then checks it is writable: before any work.
fn prepare_out(out: &Path, force: bool) -> anyhow::Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("--out {}", out.display()))?;
    let entries: Vec<_> = std::fs::read_dir(out)
        .with_context(|| format!("--out {}", out.display()))?
        .collect::<Result<_, _>>()
        .with_context(|| format!("--out {}", out.display()))?;
    if !entries.is_empty() {
        if !force {
            anyhow::bail!(
                "--out {}: the directory is not empty ({} entries); choose a new directory, or add --force to clear the files of an earlier run",
                out.display(),
                entries.len()
            );
        }
        if let Some(e) = entries
            .iter()
            .find(|e| !ours(&e.file_name().to_string_lossy()))
        {
            anyhow::bail!(
                "--out {}: --force clears only the files `reproduce` writes, and `{}` is not one of them; remove it or choose another directory",
                out.display(),
                e.file_name().to_string_lossy()
            );
        }
        for e in entries {
            let p = e.path();
            if p.is_dir() {
                std::fs::remove_dir_all(&p)
            } else {
                std::fs::remove_file(&p)
            }
            .with_context(|| format!("removing {}", p.display()))?;
        }
    }
    for sub in ["renders", "figures"] {
        std::fs::create_dir_all(out.join(sub))
            .with_context(|| format!("{}", out.join(sub).display()))?;
    }
    let probe = out.join(".brdf-basis-probe");
    write_text(&probe, "").with_context(|| format!("--out {}: not writable", out.display()))?;
    std::fs::remove_file(&probe).with_context(|| format!("{}", probe.display()))?;
    Ok(())
}

fn write_text(path: &Path, text: &str) -> anyhow::Result<()> {
    write_atomic(path, |w| w.write_all(text.as_bytes()))?;
    Ok(())
}

/// `summary.json`: the settings, the per-basis errors, the claims and the timings.
#[derive(serde::Serialize, serde::Deserialize)]
pub struct Summary {
    /// Settings as run.
    pub settings: brdf_basis::experiment::Settings,
    /// Evaluation targets.
    pub targets: Vec<String>,
    /// Errors per basis.
    pub errors: Vec<evaluation::BasisErrors>,
    /// The paper's claims checked.
    pub claims: Vec<claims::Claim>,
    /// Wall time per stage.
    pub timings: Vec<StageTiming>,
}

/// Runs everything.
pub fn run(g: &Global, a: ReproduceArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let coll = super::load_collection(&a.collection)?;
    let paper_bases = match &a.paper_bases {
        Some(p) => read_paper_bases(p, &coll)?,
        None => vec![],
    };
    let params = ExperimentParams {
        runs: a.runs,
        stride: a.stride,
        k_min: a.k_min,
        k_max: a.k_max,
        gcuk_k_max: a.gcuk_k_max,
        render_size: a.render_size,
        showcase: a.showcase.clone(),
        seed: g.seed,
        paper_bases,
        error_driven: !a.no_selection,
        cv_folds: a.cv_folds,
        cv_runs: a.cv_runs,
        ..Default::default()
    }
    .check(&coll)?;
    let out = &a.out;
    let existed = out.exists();
    prepare_out(out, a.force)?;
    let result = run_into(g, &a, &coll, &params, started);
    if result.is_err() {
        // The directory was empty (or cleared) before: leave nothing partial behind.
        let _ = if existed {
            std::fs::read_dir(out).map(|rd| {
                for e in rd.flatten() {
                    let p = e.path();
                    let _ = if p.is_dir() {
                        std::fs::remove_dir_all(&p)
                    } else {
                        std::fs::remove_file(&p)
                    };
                }
            })
        } else {
            std::fs::remove_dir_all(out)
        };
    }
    result
}

fn run_into(
    g: &Global,
    a: &ReproduceArgs,
    coll: &brdf_basis::collection::Collection,
    params: &brdf_basis::experiment::ValidExperimentParams,
    started: Instant,
) -> anyhow::Result<()> {
    let out = &a.out;
    let backend = super::backend(g)?;
    let bars = StageBars::new(g);
    let e = run_experiment(backend.as_ref(), coll, params, &|s, d, t| {
        bars.update(s, d, t)
    })?;
    bars.finish();

    let t_files = Instant::now();
    for (m, d) in e.settings.metrics.iter().zip(&e.distances) {
        write_npy(&out.join(format!("distance-{}.npy", m.label)), d)?;
        write_csv(&out.join(format!("distance-{}.csv", m.label)), d)?;
    }
    write_json(
        &out.join("empirical.json"),
        &EmpiricalFile::from(&e.empirical),
    )?;
    write_json(&out.join("clustering.json"), &e.clustering)?;
    write_text(
        &out.join("clustering_db.csv"),
        &clustering::db_csv(&e.clustering),
    )?;
    write_json(&out.join("statistics.json"), &e.statistics)?;
    write_json(&out.join("bases.json"), &e.bases)?;
    if !e.selections.is_empty() {
        write_json(&out.join("selection.json"), &e.selections)?;
    }
    if let Some(cv) = &e.cv {
        write_json(&out.join("cv.json"), cv)?;
    }
    for (b, f) in e.bases.iter().zip(&e.evaluation.fits) {
        write_json(&out.join(format!("fit-{}.json", b.name)), f)?;
    }
    write_text(
        &out.join("fit_errors.csv"),
        &evaluation::errors_csv(&e.evaluation),
    )?;
    let display = DisplayParams::default();
    let show = &e.evaluation.showcase;
    let scale = brdf_basis::plot::showcase::common_scale(show, &display)?;
    let r = out.join("renders");
    write_exr(r.join("showcase-original.exr"), &show.original)?;
    write_png(r.join("showcase-original.png"), &show.original, &display)?;
    for (name, _, img, _) in &show.approximations {
        write_exr(r.join(format!("showcase-{name}.exr")), img)?;
        write_png(r.join(format!("showcase-{name}.png")), img, &display)?;
        write_rgb8_image(
            r.join(format!("showcase-{name}-heatmap.png")),
            &heatmap(&show.original, img, &display, HeatmapScale::Fixed(scale))?,
        )?;
    }
    let mut ctx = ReportContext::default();
    ctx.timings.push(StageTiming {
        stage: "files".into(),
        seconds: t_files.elapsed().as_secs_f64(),
    });
    let t_fig = Instant::now();
    super::plot::write_report_figures(&e, &out.join("figures"), &mut ctx)?;
    ctx.timings.push(StageTiming {
        stage: "figures".into(),
        seconds: t_fig.elapsed().as_secs_f64(),
    });
    let summary = Summary {
        settings: e.settings.clone(),
        targets: e.evaluation.targets.clone(),
        errors: e.evaluation.errors.clone(),
        claims: claims::check(&e),
        timings: e.timings.iter().chain(&ctx.timings).cloned().collect(),
    };
    write_json(&out.join("summary.json"), &summary)?;
    write_text(&out.join("report.md"), &markdown(&e, &ctx))?;
    if !g.quiet {
        eprintln!(
            "wrote {} ({:.1} s)",
            out.join("report.md").display(),
            started.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// One progress bar per stage.
struct StageBars {
    quiet: bool,
    g: Global,
    current: std::sync::Mutex<Option<(Stage, indicatif::ProgressBar)>>,
}

impl StageBars {
    fn new(g: &Global) -> Self {
        StageBars {
            quiet: g.quiet,
            g: g.clone(),
            current: std::sync::Mutex::new(None),
        }
    }

    fn update(&self, stage: Stage, done: u64, total: u64) {
        if self.quiet {
            return;
        }
        let Ok(mut cur) = self.current.lock() else {
            return;
        };
        if cur.as_ref().map(|c| c.0) != Some(stage) {
            if let Some((_, pb)) = cur.take() {
                pb.finish();
            }
            *cur = Some((
                stage,
                super::progress_bar(&self.g, total.max(1), &stage.to_string()),
            ));
        }
        if let Some((_, pb)) = cur.as_ref() {
            pb.set_length(total.max(1));
            pb.set_position(done);
        }
    }

    fn finish(&self) {
        if let Ok(mut cur) = self.current.lock() {
            if let Some((_, pb)) = cur.take() {
                pb.finish();
            }
        }
    }
}
