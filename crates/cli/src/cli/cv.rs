//! `brdf-basis cv`: cross-validated comparison of basis-selection methods (SPEC 8).

use super::Global;
use brdf_basis::atomic::OutputPlan;
use brdf_basis::distance::Metric;
use brdf_basis::run::{AcquisitionRequest, Ctx, CvRequest, Request};
use brdf_basis::select::cv::CvMethod;
use std::path::PathBuf;

/// The requests' defaults, for `--help`.
fn defaults() -> CvRequest {
    CvRequest::default()
}

/// The acquisition cross-validation's defaults, for `--help`.
fn acq_defaults() -> brdf_basis::acquire::AcqCvParams {
    brdf_basis::acquire::AcqCvParams::default()
}

/// Arguments of `cv`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis cv --methods greedy,swap,kmedoids,random -k 5 --folds 5 --json cv.json --markdown cv.md\n  brdf-basis cv --stride 3 -k 3,5 --json quick.json"
)]
pub(crate) struct CvArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// Methods, comma-separated: greedy, swap, ga, kmedoids, gcuk, empirical, random
    /// [default: greedy,swap,kmedoids,gcuk,empirical,random].
    #[arg(long, value_delimiter = ',')]
    pub methods: Vec<String>,
    /// Basis sizes, comma-separated [default: 5,12].
    #[arg(short = 'k', value_delimiter = ',')]
    pub k: Vec<usize>,
    #[arg(long, help = super::with_default("Number of folds (not with --test)", defaults().folds))]
    pub folds: Option<usize>,
    // Optional flags of some methods, so that the request can refuse one that no method
    // given uses; the help shows the request's defaults.
    #[arg(long, help = super::with_default("kmedoids, gcuk: distance, brdf-it or euclidean", brdf_basis::select::cv::CvParams::default().metric))]
    pub metric: Option<Metric>,
    /// Grid cells and weights.
    #[command(flatten)]
    pub grid: super::GridArgs,
    #[arg(long, help = super::with_default("kmedoids, gcuk: k-medoids restarts and GCUK runs per fold", brdf_basis::select::cv::CvParams::default().runs))]
    pub runs: Option<usize>,
    #[arg(long, help = super::with_default("ga: population size", brdf_basis::select::GaParams::default().population))]
    pub ga_population: Option<usize>,
    #[arg(long, help = super::with_default("ga: generations", brdf_basis::select::GaParams::default().generations))]
    pub ga_generations: Option<usize>,
    // Render size in pixels for the image errors (`cv` and `cv --acquisition` have the same
    // default: `requests::cli_defaults_are_the_requests`).
    #[arg(long, help = super::with_default("Render size in pixels for the image errors", defaults().render_size))]
    pub render_size: Option<u32>,
    /// The fit objective of the selection and the held-out fits.
    #[command(flatten)]
    pub objective: super::ObjectiveArgs,
    /// Skip the appearance metrics of the held-out fits (renders at 256 x 256 under four
    /// lights: image error, CIEDE2000, FLIP).
    #[arg(long)]
    pub no_appearance: bool,
    /// --acquisition: fit from samples by plain NNLS, without the ridge toward the training
    /// materials' mean material (used below k + 1 samples; its strength is chosen on the
    /// training folds).
    #[arg(long)]
    pub no_ridge: bool,
    /// Output JSON.
    #[arg(long)]
    pub json: PathBuf,
    /// Also write the summary as Markdown.
    #[arg(long)]
    pub markdown: Option<PathBuf>,
    /// Acquisition cross-validation (SPEC 10): bases chosen by --methods at the first -k,
    /// plans by --plans, held-out materials reconstructed from -n samples.
    #[arg(long)]
    pub acquisition: bool,
    /// --acquisition: plan criteria, comma-separated (error, condition, random, nielsen:
    /// the peer baseline of Nielsen et al. 2015 with its own PCA, plan and ridge
    /// reconstruction, at most 500 candidates per step) [default: error,condition,random].
    #[arg(long, value_enum, value_delimiter = ',')]
    pub plans: Vec<super::values::CriterionArg>,
    /// --acquisition: sample counts, comma-separated [default: 5,10,20].
    #[arg(short = 'n', value_delimiter = ',')]
    pub n: Vec<usize>,
    /// --acquisition: relative noise levels of the simulated measurements, comma-separated
    /// [default: 0,0.02].
    #[arg(long, value_delimiter = ',')]
    pub noise: Vec<f64>,
    #[arg(long, help = super::with_default("--acquisition: candidates examined per step of the error, condition and nielsen plans (0: all)", acq_defaults().candidates_per_step))]
    pub candidates_per_step: Option<usize>,
    #[arg(long, help = super::with_default("--acquisition: error plans fit this many screened candidates exactly per step (0: every examined candidate)", acq_defaults().shortlist))]
    pub shortlist: Option<usize>,
    #[arg(long, help = super::with_default("--acquisition: error plans compare this many seeded greedy paths, each examining its share of --candidates-per-step, and keep the lowest final training score (1 to 64)", acq_defaults().restarts))]
    pub restarts: Option<usize>,
    /// --acquisition: also write the figure (held-out mean rho against n, one line per
    /// plan, log scale; below it the renders of one held-out material: target, dense fit,
    /// reconstructions from each n by the first plan) as this .svg or .png file.
    #[arg(long)]
    pub figure: Option<PathBuf>,
    /// --acquisition: a fixed split instead of folds: the held-out materials, as names
    /// separated by commas or a file of names (one per line; `#` starts a comment). The
    /// basis, the plans and the nielsen model are trained on the other materials; the
    /// JSON is that of one fold (seeded as fold 0).
    #[arg(long, value_name = "LIST|FILE")]
    pub test: Option<String>,
}

/// The held-out materials of `--test`: the lines of the file it names (blank lines and
/// `#` comments skipped, names trimmed), or else its comma-separated names.
fn test_names(v: &str) -> anyhow::Result<Vec<String>> {
    let path = std::path::Path::new(v);
    let names: Vec<String> = if path.is_file() {
        let text = std::fs::read_to_string(path).map_err(|e| {
            anyhow::anyhow!(
                "--test {}: cannot read the file of names: {e}",
                path.display()
            )
        })?;
        text.lines()
            .map(|l| l.split('#').next().unwrap_or("").trim().to_string())
            .filter(|l| !l.is_empty())
            .collect()
    } else {
        v.split(',').map(|s| s.trim().to_string()).collect()
    };
    if names.is_empty() || names.iter().any(|n| n.is_empty()) {
        anyhow::bail!(
            "--test {v}: give the held-out materials' names, comma-separated, or a file of names (one per line); an empty name is not one"
        );
    }
    Ok(names)
}

/// `--methods`, parsed (`None` when not given).
fn methods(a: &CvArgs) -> anyhow::Result<Option<Vec<CvMethod>>> {
    if a.methods.is_empty() {
        return Ok(None);
    }
    Ok(Some(
        a.methods
            .iter()
            .map(|m| m.trim().parse())
            .collect::<Result<_, _>>()?,
    ))
}

impl CvArgs {
    /// The `cv` request these flags make.
    pub(crate) fn request(&self, g: &Global) -> anyhow::Result<CvRequest> {
        let mut r = CvRequest::default();
        if let Some(m) = methods(self)? {
            r.methods = m;
        }
        if !self.k.is_empty() {
            r.ks = self.k.clone();
        }
        r.folds = self.folds.unwrap_or(r.folds);
        r.metric = self.metric;
        r.grid = self.grid.grid()?;
        r.runs = self.runs;
        r.ga_population = self.ga_population;
        r.ga_generations = self.ga_generations;
        r.render_size = self.render_size.unwrap_or(r.render_size);
        r.seed = g.seed_or(r.seed);
        r.objective = self.objective.setting();
        r.appearance = !self.no_appearance;
        Ok(r)
    }

    /// The `cv --acquisition` request these flags make (the first `-k` is the basis size).
    pub(crate) fn acquisition_request(&self, g: &Global) -> anyhow::Result<AcquisitionRequest> {
        let mut r = AcquisitionRequest::default();
        if let Some(m) = methods(self)? {
            r.methods = m;
        }
        if let Some(&k) = self.k.first() {
            r.k = k;
        }
        if !self.plans.is_empty() {
            r.plans = self.plans.iter().map(|&c| c.into()).collect();
        }
        if !self.n.is_empty() {
            r.ns = self.n.clone();
        }
        if !self.noise.is_empty() {
            r.noises = self.noise.clone();
        }
        if let Some(t) = &self.test {
            r.test = test_names(t)?;
        }
        r.folds = self.folds;
        r.candidates_per_step = self.candidates_per_step;
        r.shortlist = self.shortlist;
        r.restarts = self.restarts;
        r.render_size = self.render_size.unwrap_or(r.render_size);
        r.grid = self.grid.grid()?;
        r.seed = g.seed_or(r.seed);
        r.objective = self.objective.setting();
        r.appearance = !self.no_appearance;
        r.ridge = !self.no_ridge;
        Ok(r)
    }
}

/// The `--acquisition` flags given without `--acquisition` (which would ignore them).
fn acquisition_only(a: &CvArgs) -> Vec<&'static str> {
    [
        ("--plans", !a.plans.is_empty()),
        ("-n", !a.n.is_empty()),
        ("--noise", !a.noise.is_empty()),
        ("--figure", a.figure.is_some()),
        ("--no-ridge", a.no_ridge),
        ("--candidates-per-step", a.candidates_per_step.is_some()),
        ("--shortlist", a.shortlist.is_some()),
        ("--restarts", a.restarts.is_some()),
        ("--test", a.test.is_some()),
    ]
    .into_iter()
    .filter_map(|(flag, given)| given.then_some(flag))
    .collect()
}

/// Runs the cross-validation.
pub(crate) fn run(g: &Global, a: CvArgs) -> anyhow::Result<()> {
    if a.acquisition {
        return run_acquisition(g, a);
    }
    let ignored = acquisition_only(&a);
    if !ignored.is_empty() {
        anyhow::bail!(
            "{} {} only with --acquisition (acquisition cross-validation); without it `cv` compares basis-selection methods and would ignore {}: add --acquisition or leave {} out",
            ignored.join(", "),
            if ignored.len() == 1 { "applies" } else { "apply" },
            if ignored.len() == 1 { "it" } else { "them" },
            if ignored.len() == 1 { "it" } else { "them" },
        );
    }
    let req = a.request(g)?;
    req.check()?;
    // Every output path before the work (two outputs on one path are refused).
    let mut plan = OutputPlan::new(&a.collection);
    plan.file(&a.json, "--json")?;
    if let Some(m) = &a.markdown {
        plan.file(m, "--markdown")?;
    }
    let mut out = plan.into_set()?;
    let coll = super::load_collection(&a.collection)?;
    req.check_count(coll.len())?;
    let backend = super::backend(g)?;
    let pb = super::progress_bar(g, 1, "cv");
    let res = req.run(&Ctx::new(backend.as_ref(), &coll).progress(&|d, t| {
        pb.set_length(t);
        pb.set_position(d);
    }))?;
    pb.finish_and_clear();
    let json = serde_json::to_string_pretty(&res)?;
    out.stage(&a.json, |w| {
        w.write_all(json.as_bytes())?;
        w.write_all(b"\n")
    })?;
    if let Some(m) = &a.markdown {
        let text = res.markdown();
        out.stage(m, |w| w.write_all(text.as_bytes()))?;
    }
    out.commit()?;
    print!("{}", res.table_markdown());
    if let Some(t) = res.appearance_markdown() {
        println!(
            "appearance of the held-out fits (objective {}):",
            res.objective
        );
        print!("{t}");
    }
    println!("wrote {}", a.json.display());
    if let Some(m) = &a.markdown {
        println!("wrote {}", m.display());
    }
    Ok(())
}

/// The flags of `cv` without `--acquisition` given with it (which would ignore them).
fn selection_only(a: &CvArgs) -> Vec<&'static str> {
    [
        ("--runs", a.runs.is_some()),
        ("--metric", a.metric.is_some()),
        ("--ga-population", a.ga_population.is_some()),
        ("--ga-generations", a.ga_generations.is_some()),
    ]
    .into_iter()
    .filter_map(|(flag, given)| given.then_some(flag))
    .collect()
}

/// `cv --acquisition` (SPEC 10).
fn run_acquisition(g: &Global, a: CvArgs) -> anyhow::Result<()> {
    let ignored = selection_only(&a);
    if !ignored.is_empty() {
        anyhow::bail!(
            "{} {} only without --acquisition (the selection methods' settings of `cv`); `cv --acquisition` chooses its fold bases with each method's defaults and would ignore {}: leave {} out",
            ignored.join(", "),
            if ignored.len() == 1 { "applies" } else { "apply" },
            if ignored.len() == 1 { "it" } else { "them" },
            if ignored.len() == 1 { "it" } else { "them" },
        );
    }
    if a.k.len() > 1 {
        anyhow::bail!(
            "-k {}: cv --acquisition takes one basis size (it would use the first and ignore the others); give one -k",
            a.k.iter().map(|k| k.to_string()).collect::<Vec<_>>().join(",")
        );
    }
    let req = a.acquisition_request(g)?;
    req.check()?;
    let mut plan = OutputPlan::new(&a.collection);
    plan.file(&a.json, "--json")?;
    if let Some(m) = &a.markdown {
        plan.file(m, "--markdown")?;
    }
    if let Some(f) = &a.figure {
        // Written as the format its name says, as `plot --out` does.
        if !matches!(super::extension(f).as_str(), "svg" | "png") {
            anyhow::bail!(
                "--figure {}: give a .svg or .png file name (the figure is written in the format its name ends in)",
                f.display()
            );
        }
        plan.file(f, "--figure")?;
    }
    let mut out = plan.into_set()?;
    let coll = super::load_collection(&a.collection)?;
    let backend = super::backend(g)?;
    let t0 = std::time::Instant::now();
    let pb = super::progress_bar(g, 1, "cv --acq");
    // Called inside the steps too: the bar only when a step completes.
    let res = req.run(&Ctx::new(backend.as_ref(), &coll).progress(&super::step_progress(&pb)))?;
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    let json = serde_json::to_string_pretty(&res)?;
    out.stage(&a.json, |w| {
        w.write_all(json.as_bytes())?;
        w.write_all(b"\n")
    })?;
    let md = res.markdown();
    if let Some(m) = &a.markdown {
        out.stage(m, |w| w.write_all(md.as_bytes()))?;
    }
    if let Some(f) = &a.figure {
        let fig = crate::plot::acquisition::rho_vs_n(&res)?;
        if super::extension(f) == "svg" {
            out.stage(f, |w| w.write_all(fig.svg.as_bytes()))?;
        } else {
            let (w, h) = (fig.png.width, fig.png.height);
            let bytes = brdf_basis::io::image::rgb8_png_bytes(f, w, h, &fig.png.data)?;
            out.stage(f, |w| w.write_all(&bytes))?;
        }
    }
    out.commit()?;
    print!("{md}");
    println!("({secs:.1} s)");
    println!("wrote {}", a.json.display());
    if let Some(m) = &a.markdown {
        println!("wrote {}", m.display());
    }
    if let Some(f) = &a.figure {
        println!("wrote {}", f.display());
    }
    Ok(())
}
