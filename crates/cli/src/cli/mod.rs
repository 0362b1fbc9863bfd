//! The command line: clap arguments -> library parameters, one module per subcommand.

pub(crate) mod cv;
pub(crate) mod distance;
pub(crate) mod fit;
pub(crate) mod info;
pub(crate) mod merge;
pub(crate) mod plan;
pub(crate) mod plot;
pub(crate) mod render;
pub(crate) mod reproduce;
pub(crate) mod select;
pub(crate) mod tabulate;
mod values;

use brdf_basis::atomic::OutputPlan;
use brdf_basis::backend::Backend;
use brdf_basis::collection::Collection;
use brdf_basis::merl::GridSpec;
use clap::{Args, Parser, Subcommand};
use std::path::{Path, PathBuf};

/// Find small, expressive bases of BRDFs and fit materials as non-negative combinations
/// of them (GPU through wgpu/Vulkan, or a fast multi-threaded CPU back-end).
#[derive(Parser, Debug)]
#[command(name = "brdf-basis", version, about, long_about = None)]
pub(crate) struct Cli {
    /// Global options.
    #[command(flatten)]
    pub global: Global,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Options every subcommand takes, as given (`None`: not given). A command that draws
/// nothing at random refuses `--seed`, and one that never opens a back-end refuses
/// `--backend gpu` ([`Command::unused_globals`]).
#[derive(Args, Debug, Clone)]
pub(crate) struct Global {
    #[arg(long, global = true, help = with_default("Compute back-end: auto (a hardware GPU if present, else CPU), gpu (any adapter, lavapipe included) or cpu", brdf_basis::BackendChoice::default().as_str()))]
    pub backend: Option<values::BackendArg>,
    #[arg(long, global = true, help = with_default("Seed of every random step", brdf_basis::run::SEED))]
    pub seed: Option<u64>,
    /// No progress bars.
    #[arg(long, global = true)]
    pub quiet: bool,
}

impl Global {
    /// `--backend` with its default.
    pub(crate) fn backend_choice(&self) -> brdf_basis::BackendChoice {
        self.backend.map(Into::into).unwrap_or_default()
    }

    /// `--seed`, or the request's default `seed` when not given.
    pub(crate) fn seed_or(&self, default: u64) -> u64 {
        self.seed.unwrap_or(default)
    }
}

/// Which grid cells a reduction runs over and how they are weighted (shared by
/// `distance`, `select` and `fit`).
#[derive(Args, Debug, Clone)]
pub(crate) struct GridArgs {
    /// uniform (the paper's Eq. 5) or solid-angle (exact bin measure).
    #[arg(long, default_value = "uniform")]
    pub weighting: values::WeightingArg,
    /// evaluation (theta <= 80 deg, >= 3 deg from retroreflection) or valid.
    #[arg(long, default_value = "evaluation")]
    pub mask: values::MaskArg,
    /// Use every s-th cell on each grid axis (1 = full grid; larger for quick runs; 1..=90).
    #[arg(long, default_value_t = 1, value_parser = parse_stride)]
    pub stride: usize,
}

impl GridArgs {
    /// The flags as a request's grid ([`brdf_basis::merl::GridSpec`], checked when built;
    /// clap has checked the stride by the same rule).
    pub(crate) fn grid(&self) -> anyhow::Result<GridSpec> {
        Ok(GridSpec::new(
            self.mask.into(),
            self.weighting.into(),
            self.stride,
        )?)
    }
}

/// The fit objective (SPEC 11): `--objective` and `--eps` (shared by `fit`, `select`,
/// `plan` and `cv`), as given: the request applies the defaults and refuses what does not
/// apply ([`brdf_basis::run::ObjectiveSetting`]).
#[derive(Args, Debug, Clone)]
pub(crate) struct ObjectiveArgs {
    /// What a fit minimises: relative (weights 1 / (f + eps)^2: every cell counts by its
    /// relative error, so the diffuse body is not given up for the highlight), l2 (raw
    /// reflectance, the paper's) or log (an L2 in log(1 + f cos theta_i)) [default:
    /// relative].
    #[arg(long, value_enum)]
    pub objective: Option<values::ObjectiveArg>,
    // eps of `--objective relative` (> 0).
    // A negative value is read as a value (and refused by the request), not as a flag.
    #[arg(long, allow_negative_numbers = true, help = with_default("eps of --objective relative, in MERL reflectance units (1e-100 to 1e100)", brdf_basis::backend::weighted::TargetWeight::DEFAULT_EPS))]
    pub eps: Option<f64>,
}

impl ObjectiveArgs {
    /// The flags as given.
    pub(crate) fn setting(&self) -> brdf_basis::run::ObjectiveSetting {
        brdf_basis::run::ObjectiveSetting {
            objective: self.objective.map(Into::into),
            eps: self.eps,
        }
    }
}

/// `text` with ` [default: value]`, as clap shows a default: the help of a flag that is
/// an `Option` (so that a request can tell a setting given from one defaulted).
fn with_default(text: &str, value: impl std::fmt::Display) -> String {
    format!("{text} [default: {value}]")
}

/// `--stride`: 1 (the full grid) to 90 (one cell per axis), by the library's rule and in
/// its words ([`GridSpec::STRIDE_RULE`]), checked here too so that clap names the flag
/// and its value.
fn parse_stride(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(v) if GridSpec::stride_ok(v) => Ok(v),
        _ => Err(format!("{}, got `{s}`", GridSpec::STRIDE_RULE)),
    }
}

/// Subcommands.
#[derive(Subcommand, Debug)]
pub(crate) enum Command {
    /// Back-end, adapter name, driver and the limits used.
    Info(info::InfoArgs),
    /// Write one material on the MERL grid as a MERL .binary file.
    Tabulate(tabulate::TabulateArgs),
    /// Pairwise distance matrix (BRDF_it or Euclidean) as .npy or .csv.
    Distance(distance::DistanceArgs),
    /// Select a basis: empirical (Algorithm 1), kmedoids, gcuk, or by fitting error: greedy, swap, ga.
    Select(select::SelectArgs),
    /// Fit materials as non-negative combinations of a basis (NNLS per channel).
    Fit(fit::FitArgs),
    /// Render a material or a fitted combination on a sphere (OpenEXR, PNG, heatmap).
    Render(render::RenderArgs),
    /// Re-run the paper's experiments (section VI) end to end into a directory.
    Reproduce(reproduce::ReproduceArgs),
    /// Cross-validated comparison of basis-selection methods (SPEC 8).
    Cv(cv::CvArgs),
    /// Specular-lobe polar plots of a material and its fits (SVG or PNG).
    Plot(plot::PlotArgs),
    /// Where to measure a new material: n direction pairs for a basis (SPEC 10).
    Plan(plan::PlanArgs),
    /// Assemble the tiles of `distance --tile I/N` into the whole matrix.
    Merge(merge::MergeArgs),
}

impl Command {
    /// The command's name, why it does not use `--seed` and why it never opens a back-end
    /// (`None`: it uses it; `select` refuses `--seed` by method in its request and
    /// `--backend gpu` with `--distances`).
    fn unused_globals(&self) -> (&'static str, Option<&'static str>, Option<&'static str>) {
        const NOTHING_RANDOM: Option<&str> = Some("it draws nothing at random");
        match self {
            Command::Info(_) => ("info", NOTHING_RANDOM, None),
            Command::Tabulate(_) => ("tabulate", NOTHING_RANDOM, None),
            Command::Distance(_) => ("distance", NOTHING_RANDOM, None),
            Command::Select(_) | Command::Reproduce(_) | Command::Cv(_) | Command::Plan(_) => {
                ("", None, None)
            }
            Command::Fit(a) if a.samples.is_some() => (
                "fit --samples",
                None,
                Some("the fit from samples solves its least-squares problem on the CPU (no grid cells to tabulate, no Gram matrix)"),
            ),
            Command::Fit(_) => ("fit", NOTHING_RANDOM, None),
            Command::Render(_) => ("render", NOTHING_RANDOM, Some("it renders on the CPU")),
            Command::Plot(_) => ("plot", NOTHING_RANDOM, Some("it draws on the CPU")),
            Command::Merge(_) => (
                "merge",
                NOTHING_RANDOM,
                Some("it copies the tiles' rows, computing nothing"),
            ),
        }
    }
}

/// Refuses, naming the flag, before any work: `--seed` given to a command that draws
/// nothing at random, and `--backend gpu` given to one that never opens a back-end (it
/// would run on the CPU without a word; `--backend cpu` and `auto` are what it does).
fn refuse_unused_globals(g: &Global, c: &Command) -> anyhow::Result<()> {
    let (name, seed, cpu_only) = c.unused_globals();
    if let (Some(s), Some(why)) = (g.seed, seed) {
        anyhow::bail!("--seed {s} does not apply to {name}: {why}; leave it out");
    }
    if let (Some(values::BackendArg::Gpu), Some(why)) = (g.backend, cpu_only) {
        anyhow::bail!("--backend gpu does not apply to {name}: {why}; leave it out");
    }
    Ok(())
}

/// Runs the parsed command line.
pub(crate) fn run(cli: Cli) -> anyhow::Result<()> {
    refuse_unused_globals(&cli.global, &cli.command)?;
    match cli.command {
        Command::Info(a) => info::run(&cli.global, a),
        Command::Tabulate(a) => tabulate::run(&cli.global, a),
        Command::Distance(a) => distance::run(&cli.global, a),
        Command::Select(a) => select::run(&cli.global, a),
        Command::Fit(a) => fit::run(&cli.global, a),
        Command::Render(a) => render::run(&cli.global, a),
        Command::Reproduce(a) => reproduce::run(&cli.global, a),
        Command::Cv(a) => cv::run(&cli.global, a),
        Command::Plot(a) => plot::run(&cli.global, a),
        Command::Merge(a) => merge::run(&cli.global, a),
        Command::Plan(a) => plan::run(&cli.global, a),
    }
}

/// Loads the COLLECTION arguments (none: the embedded default).
pub(crate) fn load_collection(paths: &[PathBuf]) -> anyhow::Result<Collection> {
    let coll = Collection::load_many(paths)?;
    if let Some(note) = mixing_note(&coll) {
        eprintln!("{note}");
    }
    Ok(coll)
}

/// The warning printed when a collection mixes analytic rows with measured or neural
/// materials (their channel scales differ; brdf-basis rescales nothing).
fn mixing_note(coll: &Collection) -> Option<String> {
    let (analytic, other) = coll.mixed_scales()?;
    Some(format!(
        "warning: the collection mixes {analytic} analytic material(s) with {other} measured or neural one(s); the Ngan 2005 table's albedos leave out MERL's channel scales (1, 1.15, 1.66 for R, G, B) that measured data include, so scale the analytic G and B parameters first or keep the kinds apart (docs/selection.md, \"Mixing analytic and measured materials\")"
    ))
}

/// Opens the back-end chosen by `--backend`.
pub(crate) fn backend(g: &Global) -> anyhow::Result<Box<dyn Backend>> {
    let b = brdf_basis::backend::open(g.backend_choice())?;
    if !g.quiet {
        eprintln!("backend: {}", b.name());
    }
    Ok(b)
}

/// A progress bar over `total` units (hidden with --quiet or when stderr is no terminal).
pub(crate) fn progress_bar(g: &Global, total: u64, what: &str) -> indicatif::ProgressBar {
    if g.quiet {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new(total);
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "{msg:>12} [{bar:40}] {percent:>3}% {elapsed_precise} eta {eta}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

/// The progress callback of `pb` for work that also calls it inside a step with the same
/// position (its cancel check, per candidate or render): the bar, behind a lock, is set
/// only when the position changes.
pub(crate) fn step_progress(pb: &indicatif::ProgressBar) -> impl Fn(u64, u64) + Sync + '_ {
    let shown = std::sync::atomic::AtomicU64::new(u64::MAX);
    move |done, total| {
        if shown.swap(done, std::sync::atomic::Ordering::Relaxed) != done {
            pb.set_length(total);
            pb.set_position(done);
        }
    }
}

/// The extension of an output path, lower-case (`""` when none).
pub(crate) fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// Plans a `.npy` matrix output and its `.names.json` sidecar: the sidecar replaces only
/// an earlier matrix sidecar (any format version), never another file of that name.
pub(crate) fn plan_matrix(plan: &mut OutputPlan, npy: &Path, flag: &str) -> anyhow::Result<()> {
    plan.file(npy, flag)?;
    plan.owned_file(
        &brdf_basis::io::sidecar::sidecar_path(npy),
        flag,
        "matrix sidecar written by brdf-basis (it holds no `format: brdf-basis-matrix/...`)",
        is_matrix_sidecar,
    )?;
    Ok(())
}

/// Whether `path` is a matrix sidecar written by brdf-basis: a JSON object whose
/// `format` starts with `brdf-basis-matrix/` (read at most 64 MiB).
pub(crate) fn is_matrix_sidecar(path: &Path) -> bool {
    use std::io::Read;
    let mut text = String::new();
    let read = std::fs::File::open(path)
        .and_then(|f| f.take(64 << 20).read_to_string(&mut text))
        .is_ok();
    read && serde_json::from_str::<serde_json::Value>(&text).is_ok_and(|v| {
        v.get("format")
            .and_then(|f| f.as_str())
            .is_some_and(|f| f.starts_with("brdf-basis-matrix/"))
    })
}
