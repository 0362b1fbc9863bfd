//! `brdf-basis reproduce`: the paper's section VI end to end ([`brdf_basis::experiment`]);
//! this module translates the arguments, plans the output tree (checked before any
//! work, written whole at the end or not at all) and calls the library's writers
//! ([`brdf_basis::experiment::layout`]).

use super::Global;
use crate::layout;
use anyhow::Context;
use brdf_basis::atomic::OutputPlan;
use brdf_basis::eval::image_error::DisplayParams;
use brdf_basis::experiment::report::ReportContext;
use brdf_basis::experiment::{Stage, StageTiming};
use brdf_basis::run::{Ctx, ReproduceRequest, Request};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The request's defaults, for `--help`.
fn defaults() -> ReproduceRequest {
    ReproduceRequest::default()
}

/// Arguments of `reproduce`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis reproduce --out results\n  brdf-basis reproduce --out quick --runs 5 --stride 4 --force"
)]
pub(crate) struct ReproduceArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// Output directory (created, its parent must exist; an existing one must be empty
    /// unless --force). Written whole at the end, or not at all.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the files of an earlier `reproduce` in --out (any other file: refused);
    /// they are kept until the new run is complete.
    #[arg(long)]
    pub force: bool,
    /// Runs per clustering configuration (paper: 30).
    #[arg(long, default_value_t = defaults().runs)]
    pub runs: usize,
    /// Grid stride for distances and fits (1 = full grid).
    #[arg(long, default_value_t = defaults().stride)]
    pub stride: usize,
    /// Smallest k of k-medoids and GCUK (paper: 5).
    #[arg(long, default_value_t = defaults().k_min)]
    pub k_min: usize,
    /// Largest k of k-medoids (paper: 12).
    #[arg(long, default_value_t = defaults().k_max)]
    pub k_max: usize,
    /// GCUK k_max (paper: 20).
    #[arg(long, default_value_t = defaults().gcuk_k_max)]
    pub gcuk_k_max: usize,
    /// Render size in pixels for the image errors.
    #[arg(long, default_value_t = defaults().render_size)]
    pub render_size: u32,
    /// Material shown in full-size renders, heatmaps and lobe plots (default: alum-bronze
    /// when it is evaluated, else a moderately glossy analytic target with a visible body,
    /// else the target whose render shows most body and highlight).
    #[arg(long)]
    pub showcase: Option<String>,
    /// The paper's bases, CSV with columns basis,material: fitted on the same targets.
    #[arg(long)]
    pub paper_bases: Option<PathBuf>,
    /// Folds of the cross-validation of every selection method (0: none).
    #[arg(long, default_value_t = defaults().cv_folds)]
    pub cv_folds: usize,
    /// k-medoids restarts and GCUK runs per fold in the cross-validation (an `Option`:
    /// given with --cv-folds 0 it is refused).
    #[arg(long, help = super::with_default("k-medoids restarts and GCUK runs per fold in the cross-validation (with --cv-folds above 0)", brdf_basis::experiment::ExperimentParams::default().cv_runs))]
    pub cv_runs: Option<usize>,
    /// Leave out the bases chosen by fitting error (greedy, swap).
    #[arg(long)]
    pub no_selection: bool,
    /// Leave out the acquisition cross-validation (SPEC 10; otherwise run with
    /// --cv-folds folds, greedy bases, plans error, condition, random and nielsen, n = 5,
    /// 10, 20, noise 0 and 2%).
    #[arg(long)]
    pub no_acquisition: bool,
    /// Leave out the Appearance section (SPEC 11; otherwise the collection is
    /// cross-validated under each fit objective, l2, relative and log: greedy bases of
    /// --k-max, --cv-folds folds (5 when 0); appearance.json and a figure of renders) and
    /// the appearance metrics (renders under four lights) of the Acquisition section.
    #[arg(long)]
    pub no_appearance: bool,
}

impl ReproduceArgs {
    /// The request these flags make.
    pub(crate) fn request(&self, g: &Global) -> ReproduceRequest {
        let mut r = ReproduceRequest::default();
        r.runs = self.runs;
        r.stride = self.stride;
        r.k_min = self.k_min;
        r.k_max = self.k_max;
        r.gcuk_k_max = self.gcuk_k_max;
        r.render_size = self.render_size;
        r.showcase = self.showcase.clone();
        r.paper_bases = self.paper_bases.clone();
        r.cv_folds = self.cv_folds;
        r.cv_runs = self.cv_runs;
        r.selection = !self.no_selection;
        r.acquisition = !self.no_acquisition;
        r.appearance = !self.no_appearance;
        r.seed = g.seed_or(r.seed);
        r
    }
}

/// Runs everything.
pub(crate) fn run(g: &Global, a: ReproduceArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let req = a.request(g);
    req.check()?;
    // The output tree before any work: a new directory (its parent exists), an empty one,
    // or with --force one holding only an earlier run's files; writable.
    let mut plan = OutputPlan::new(&a.collection);
    if let Some(p) = &a.paper_bases {
        plan.input_named(p, "paper-bases file");
    }
    plan.tree(&a.out, "--out", a.force, layout::is_output)?;
    // The k ranges and folds against the number of materials before the collection is
    // loaded (and its RGL-EPFL files or networks tabulated).
    req.check_count(brdf_basis::collection::Collection::count_many(
        &a.collection,
    )?)?;
    let coll = super::load_collection(&a.collection)?;
    req.params(&coll)?;
    crate::plot::font()?; // an unusable BRDF_BASIS_FONT is refused before any work
    let mut out = plan.into_set()?;
    let root = out.tree_root(&a.out)?;
    let written = run_into(g, &req, &coll, &root)?;
    out.commit()?;
    for f in &written {
        println!("wrote {}", a.out.join(f).display());
    }
    println!(
        "wrote {} ({} files, {:.1} s)",
        a.out.join(layout::REPORT).display(),
        written.len(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Runs the experiment and writes its files into `root` (the staging root of --out);
/// returns the files written, relative to it.
fn run_into(
    g: &Global,
    req: &ReproduceRequest,
    coll: &brdf_basis::collection::Collection,
    root: &Path,
) -> anyhow::Result<Vec<PathBuf>> {
    let backend = super::backend(g)?;
    let bars = StageBars::new(g);
    let r = req.run(&Ctx::new(backend.as_ref(), coll).stages(&|s, d, t| bars.update(s, d, t)))?;
    bars.finish();
    let e = r.experiment;

    let t_files = Instant::now();
    let scale =
        crate::plot::showcase::common_scale(&e.evaluation.showcase, &DisplayParams::default())?;
    let mut written = layout::write_files(&e, root, scale)?;
    let mut ctx = ReportContext::default();
    // Audit 3, U9: a section left out by a flag is named, not silently missing.
    let left_out: Vec<&str> = [
        (
            r.acquisition.is_none(),
            "Acquisition (SPEC 10, `--no-acquisition`)",
        ),
        (
            r.appearance.is_none(),
            "Appearance (SPEC 11, `--no-appearance`)",
        ),
    ]
    .into_iter()
    .filter_map(|(out, what)| out.then_some(what))
    .collect();
    if !left_out.is_empty() {
        ctx.notes.push(format!(
            "Left out as asked: the {} {}.",
            left_out.join(" and the "),
            if left_out.len() == 1 {
                "section"
            } else {
                "sections"
            }
        ));
    }
    if let Some(a) = r.acquisition {
        ctx.timings.push(StageTiming {
            stage: "acquisition".into(),
            seconds: r.acquisition_seconds,
        });
        if a.skipped.is_none() {
            brdf_basis::io::json::write_json(&root.join(layout::ACQUISITION), &a.cv)?;
            written.push(PathBuf::from(layout::ACQUISITION));
        }
        ctx.acquisition = Some(a);
    }
    if let Some(a) = r.appearance {
        ctx.timings.push(StageTiming {
            stage: "appearance".into(),
            seconds: r.appearance_seconds,
        });
        if let Some(st) = &a.study {
            brdf_basis::io::json::write_json(&root.join(layout::APPEARANCE), st)?;
            written.push(PathBuf::from(layout::APPEARANCE));
        }
        ctx.appearance = Some(a);
    }
    ctx.timings.push(StageTiming {
        stage: "files".into(),
        seconds: t_files.elapsed().as_secs_f64(),
    });
    let t_fig = Instant::now();
    let figures = root.join(layout::FIGURES);
    std::fs::create_dir(&figures).with_context(|| format!("{}", figures.display()))?;
    super::plot::write_report_figures(&e, &figures, &mut ctx)?;
    if let Some(a) = ctx.acquisition.as_ref().filter(|a| a.skipped.is_none()) {
        let fig = crate::plot::acquisition::rho_vs_n(&a.cv)?;
        super::plot::write_figure(&figures, &fig)?;
        ctx.figures
            .push((fig.stem.clone(), format!("figures/{}.png", fig.stem)));
    }
    if let Some(st) = ctx.appearance.as_ref().and_then(|a| a.study.as_ref()) {
        let fig = crate::plot::appearance::renders(st)?;
        super::plot::write_figure(&figures, &fig)?;
        ctx.figures
            .push((fig.stem.clone(), format!("figures/{}.png", fig.stem)));
    }
    for (stem, _) in &ctx.figures {
        for ext in ["svg", "png"] {
            written.push(Path::new(layout::FIGURES).join(format!("{stem}.{ext}")));
        }
    }
    ctx.timings.push(StageTiming {
        stage: "figures".into(),
        seconds: t_fig.elapsed().as_secs_f64(),
    });
    written.extend(layout::write_summary_and_report(&e, &ctx, root)?);
    Ok(written)
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
