//! `brdf-basis plan`: where to measure a new material (SPEC 10).

use super::Global;
use brdf_basis::acquire::plan_csv;
use brdf_basis::atomic::OutputPlan;
use brdf_basis::run::{Ctx, PlanRequest, Request};
use std::path::PathBuf;

/// The request's defaults, for `--help`.
fn defaults() -> PlanRequest {
    PlanRequest::new(Vec::new())
}

/// Arguments of `plan`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis plan ngan2005_ashikhmin_shirley.csv --basis blue-acrylic,steel,cherry-235 -n 20 --out plan.csv --json plan.json\n  brdf-basis plan --basis gloss-white-enamel,polished-brass -n 10 --criterion condition --out plan.csv"
)]
pub(crate) struct PlanArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// Basis materials, comma-separated.
    #[arg(long, value_delimiter = ',', required = true)]
    pub basis: Vec<String>,
    /// Samples to plan.
    #[arg(short = 'n', default_value_t = defaults().n)]
    pub n: usize,
    /// error (greedy on the mean training score), condition (greedy on the condition
    /// number of the sampled design) or random. (`nielsen`, the peer baseline, has its own
    /// reconstructor, which `fit --samples` does not run: `cv --acquisition --plans nielsen`
    /// compares it.)
    #[arg(long, value_enum, default_value_t = defaults().criterion.into())]
    pub criterion: super::values::CriterionArg,
    /// Training materials, comma-separated [default: every material outside the basis].
    #[arg(long, value_delimiter = ',')]
    pub targets: Vec<String>,
    /// Directions the instrument can reach: a CSV with `theta_i,phi_i,theta_o,phi_o`
    /// (degrees; other columns such as `r,g,b` are ignored, so a `--out` plan is one) or
    /// an ASTM `.astm` file [default: the cell centres of the evaluation mask].
    #[arg(long)]
    pub candidates: Option<PathBuf>,
    // Optional flags of some criteria, so that the request can refuse one the criterion
    // does not use; the help shows the request's defaults.
    #[arg(long, help = super::with_default("error, condition: candidates examined per step (0: all)", defaults().candidates_per_step()))]
    pub candidates_per_step: Option<usize>,
    #[arg(long, help = super::with_default("error: screened candidates fitted exactly per step (0: all examined)", defaults().shortlist()))]
    pub shortlist: Option<usize>,
    #[arg(long, help = super::with_default("error: seeded greedy paths (1 to 64) sharing the candidates of each step, the one of the lowest final training score kept (the plan's prefixes are its shorter plans; a run at a smaller -n may choose another path)", defaults().restarts()))]
    pub restarts: Option<usize>,
    #[command(flatten)]
    pub objective: super::ObjectiveArgs,
    /// Output CSV: the samples-file header and one row per sample, in the order chosen.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the plan as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

impl PlanArgs {
    /// The request these flags make.
    pub(crate) fn request(&self, g: &Global) -> PlanRequest {
        let mut r = PlanRequest::new(self.basis.clone());
        r.targets = (!self.targets.is_empty()).then(|| self.targets.clone());
        r.candidates = self.candidates.clone();
        r.n = self.n;
        r.criterion = self.criterion.into();
        r.candidates_per_step = self.candidates_per_step;
        r.shortlist = self.shortlist;
        r.restarts = self.restarts;
        r.seed = g.seed;
        r.objective = self.objective.setting();
        r
    }
}

/// Plans the samples.
pub(crate) fn run(g: &Global, a: PlanArgs) -> anyhow::Result<()> {
    let req = a.request(g);
    req.check()?;
    let mut op = OutputPlan::new(&a.collection);
    for (path, noun) in req.input_files() {
        op.input_named(&path, noun);
    }
    op.file(&a.out, "--out")?;
    if let Some(j) = &a.json {
        op.file(j, "--json")?;
    }
    let mut out = op.into_set()?;
    // After the output checks: an output naming an input or a device says so first.
    if super::extension(&a.out) != "csv" {
        anyhow::bail!(
            "--out {}: writes the plan as a samples-file CSV (theta_i,phi_i,theta_o,phi_o) and its name must end in .csv",
            a.out.display()
        );
    }
    let coll = super::load_collection(&a.collection)?;
    let backend = super::backend(g)?;
    let t0 = std::time::Instant::now();
    let pb = super::progress_bar(g, 1, "plan");
    // Called per candidate: the bar only when a step completes.
    let pl = req.run(&Ctx::new(backend.as_ref(), &coll).progress(&super::step_progress(&pb)))?;
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    let csv = plan_csv(&pl);
    out.stage(&a.out, |w| w.write_all(csv.as_bytes()))?;
    if let Some(j) = &a.json {
        let text = serde_json::to_string_pretty(&pl)?;
        out.stage(j, |w| {
            w.write_all(text.as_bytes())?;
            w.write_all(b"\n")
        })?;
    }
    out.commit()?;
    println!(
        "planned {} ({}, {} of {} per step, {:.2} s); mean training score after the last: {}",
        brdf_basis::error::plural(pl.n, "sample", "samples"),
        pl.criterion.as_str(),
        pl.candidates_per_step,
        brdf_basis::error::plural(pl.candidates, "candidate", "candidates"),
        secs,
        pl.history
            .last()
            .map_or("n/a".into(), |&v| brdf_basis::stats::num(v))
    );
    println!("wrote {}", a.out.display());
    if let Some(j) = &a.json {
        println!("wrote {}", j.display());
    }
    Ok(())
}
