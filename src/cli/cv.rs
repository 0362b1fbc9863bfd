//! `brdf-basis cv`: cross-validated comparison of basis-selection methods (SPEC 8).

use super::select_error::check_output;
use super::Global;
use anyhow::Context;
use brdf_basis::distance::Metric;
use brdf_basis::atomic::write_atomic;
use brdf_basis::io::json::write_json;
use brdf_basis::selection::{cross_validate, CvMethod, CvParams, GaParams, ObjectiveParams};
use std::path::PathBuf;

/// Arguments of `cv`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis cv --methods greedy,swap,kmedoids,random -k 5 --folds 5 --json cv.json --markdown cv.md\n  brdf-basis cv --stride 3 -k 3,5 --json quick.json"
)]
pub struct CvArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// Methods, comma-separated: greedy, swap, ga, kmedoids, gcuk, empirical, random.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "greedy,swap,kmedoids,gcuk,empirical,random"
    )]
    pub methods: Vec<String>,
    /// Basis sizes, comma-separated.
    #[arg(short = 'k', value_delimiter = ',', default_value = "5,12")]
    pub k: Vec<usize>,
    /// Number of folds.
    #[arg(long, default_value_t = 5)]
    pub folds: usize,
    /// Distance of the clustering methods: brdf-it or euclidean.
    #[arg(long, default_value = "brdf-it")]
    pub metric: Metric,
    /// Grid cells and weights.
    #[command(flatten)]
    pub grid: super::GridArgs,
    /// k-medoids restarts and GCUK runs per fold.
    #[arg(long, default_value_t = 10)]
    pub runs: usize,
    /// ga: population size.
    #[arg(long, default_value_t = 40)]
    pub ga_population: usize,
    /// ga: generations.
    #[arg(long, default_value_t = 60)]
    pub ga_generations: usize,
    /// Render size in pixels for the image errors.
    #[arg(long, default_value_t = 64)]
    pub render_size: u32,
    /// Output JSON.
    #[arg(long)]
    pub json: PathBuf,
    /// Also write the summary as Markdown.
    #[arg(long)]
    pub markdown: Option<PathBuf>,
}

/// Runs the cross-validation.
pub fn run(g: &Global, a: CvArgs) -> anyhow::Result<()> {
    check_output(&a.json)?;
    if let Some(m) = &a.markdown {
        check_output(m)?;
    }
    let coll = super::load_collection(&a.collection)?;
    let methods: Vec<CvMethod> = a
        .methods
        .iter()
        .map(|m| m.trim().parse())
        .collect::<Result<_, _>>()?;
    let p = CvParams {
        methods,
        ks: a.k.clone(),
        folds: a.folds,
        seed: g.seed,
        objective: ObjectiveParams::default()
            .mask(a.grid.mask)
            .weighting(a.grid.weighting)
            .stride(a.grid.stride),
        metric: a.metric,
        runs: a.runs,
        ga: GaParams::default()
            .population(a.ga_population)
            .generations(a.ga_generations)
            .seed(g.seed),
        render_size: a.render_size,
    }
    .check(coll.len())?;
    let backend = super::backend(g)?;
    let pb = super::progress_bar(g, 1, "cv");
    let res = cross_validate(backend.as_ref(), &coll, &p, &|d, t| {
        pb.set_length(t);
        pb.set_position(d);
    })?;
    pb.finish_and_clear();
    write_json(&a.json, &res)?;
    if let Some(m) = &a.markdown {
        let text = res.markdown();
        write_atomic(m, |w| w.write_all(text.as_bytes()))
            .with_context(|| format!("writing {}", m.display()))?;
    }
    if !g.quiet {
        eprint!("{}", res.table_markdown());
        eprintln!("wrote {}", a.json.display());
    }
    Ok(())
}
