//! `brdf-basis select --method greedy|swap|ga`: bases chosen by fitting error (SPEC 8).

use super::select::SelectArgs;
use super::Global;
use anyhow::Context;
use brdf_basis::collection::Collection;
use brdf_basis::io::json::write_json;
use brdf_basis::selection::{ga, greedy, swap, GaParams, Objective, ObjectiveParams, SearchParams};
use std::path::Path;

/// Flags of the error-driven methods (flattened into `select`).
#[derive(clap::Args, Debug, Clone)]
pub struct ErrorArgs {
    /// greedy, swap, ga: materials that may enter the basis, comma-separated (default: all).
    #[arg(long, value_delimiter = ',')]
    pub candidates: Vec<String>,
    /// greedy, swap, ga: materials the basis must represent, comma-separated (default: all).
    #[arg(long, value_delimiter = ',')]
    pub targets: Vec<String>,
    /// swap: starting basis (default: the greedy basis); ga: one individual of the first
    /// population. Exactly k materials.
    #[arg(long, value_delimiter = ',')]
    pub init: Vec<String>,
    /// ga: population size.
    #[arg(long, default_value_t = 40)]
    pub ga_population: usize,
    /// ga: generations.
    #[arg(long, default_value_t = 60)]
    pub ga_generations: usize,
    /// ga: crossover probability.
    #[arg(long, default_value_t = 0.9)]
    pub ga_crossover: f64,
    /// ga: per-gene mutation probability (default 1/k).
    #[arg(long)]
    pub ga_mutation: Option<f64>,
}

/// Collection indices of comma-separated names (empty: `None`).
pub fn indices(coll: &Collection, names: &[String]) -> anyhow::Result<Option<Vec<usize>>> {
    if names.is_empty() {
        return Ok(None);
    }
    Ok(Some(
        names
            .iter()
            .map(|n| coll.index_of(n.trim()))
            .collect::<Result<_, _>>()?,
    ))
}

/// Fails early when `path`'s directory does not exist (before any long computation).
pub fn check_output(path: &Path) -> anyhow::Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    anyhow::ensure!(
        dir.is_dir(),
        "{}: the output directory {} does not exist",
        path.display(),
        dir.display()
    );
    Ok(())
}

/// Runs greedy, swap or ga and writes the SPEC-cli JSON.
pub fn run(g: &Global, a: &SelectArgs) -> anyhow::Result<()> {
    check_output(&a.json)?;
    let coll = super::load_collection(&a.collection)?;
    let k = a.k.context(
        "give the basis size with -k K (greedy, swap and ga choose exactly k materials)",
    )?;
    let e = &a.error;
    let mut sp = SearchParams::new(k);
    sp.candidates = indices(&coll, &e.candidates)?;
    sp.targets = indices(&coll, &e.targets)?;
    sp.init = indices(&coll, &e.init)?;
    let names = coll.names();
    let vsp = sp.check(&names)?;
    let mut gp = GaParams::default()
        .population(e.ga_population)
        .generations(e.ga_generations)
        .crossover_prob(e.ga_crossover)
        .seed(g.seed);
    gp.mutation_prob = e.ga_mutation;
    let vgp = gp.check()?;
    let op = ObjectiveParams::default()
        .mask(a.grid.mask)
        .weighting(a.grid.weighting)
        .stride(a.grid.stride)
        .check()?;
    let backend = super::backend(g)?;
    let pb = super::progress_bar(g, 1, "gram");
    let progress = |done: u64, total: u64| {
        pb.set_length(total);
        pb.set_position(done);
    };
    let obj = Objective::new(backend.as_ref(), &coll, &op, &progress)?;
    pb.set_message(a.method.clone());
    pb.set_position(0);
    let sel = match a.method.as_str() {
        "greedy" => greedy(&obj, &vsp, &progress),
        "swap" => swap(&obj, &vsp, &progress),
        _ => ga(&obj, &vsp, &vgp, &progress),
    };
    pb.finish_and_clear();
    write_json(&a.json, &sel)?;
    if !g.quiet {
        eprintln!(
            "{} k = {}: S = {:.6e} with {} -> {}",
            sel.method,
            sel.k,
            sel.score,
            sel.basis.join(","),
            a.json.display()
        );
    }
    Ok(())
}
