//! `brdf-basis select --method greedy|swap|ga`: bases chosen by fitting error (SPEC 8).

use super::Global;
use anyhow::Context;
use brdf_basis::collection::Collection;
use brdf_basis::select::{
    ga, greedy, swap, GaParams, Objective, ObjectiveParams, SearchParams, Selection,
};

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
    /// ga: population size [default: 40].
    #[arg(long)]
    pub ga_population: Option<usize>,
    /// ga: generations [default: 60].
    #[arg(long)]
    pub ga_generations: Option<usize>,
    /// ga: crossover probability [default: 0.9].
    #[arg(long)]
    pub ga_crossover: Option<f64>,
    /// ga: per-gene mutation probability (default 1/k).
    #[arg(long)]
    pub ga_mutation: Option<f64>,
}

impl ErrorArgs {
    /// The first of these flags given, if any (for methods they do not apply to).
    pub fn given(&self) -> Option<&'static str> {
        [
            (!self.candidates.is_empty(), "--candidates"),
            (!self.targets.is_empty(), "--targets"),
            (!self.init.is_empty(), "--init"),
        ]
        .into_iter()
        .chain(self.ga_given())
        .find(|(given, _)| *given)
        .map(|(_, flag)| flag)
    }

    fn ga_given(&self) -> [(bool, &'static str); 4] {
        [
            (self.ga_population.is_some(), "--ga-population"),
            (self.ga_generations.is_some(), "--ga-generations"),
            (self.ga_crossover.is_some(), "--ga-crossover"),
            (self.ga_mutation.is_some(), "--ga-mutation"),
        ]
    }

    /// The GA parameters: the library defaults ([`GaParams::default`]) with the flags given.
    pub fn ga_params(&self, seed: u64) -> GaParams {
        let d = GaParams::default();
        let mut gp = GaParams::default()
            .population(self.ga_population.unwrap_or(d.population))
            .generations(self.ga_generations.unwrap_or(d.generations))
            .crossover_prob(self.ga_crossover.unwrap_or(d.crossover_prob))
            .seed(seed);
        gp.mutation_prob = self.ga_mutation;
        gp
    }
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

/// Runs greedy, swap or ga (`method`) on `coll` (the output paths are checked by the
/// caller, before this).
pub fn run(
    g: &Global,
    coll: &Collection,
    method: &str,
    k: Option<usize>,
    grid: &super::GridArgs,
    e: &ErrorArgs,
) -> anyhow::Result<Selection> {
    let k = k.context(
        "give the basis size with -k K (greedy, swap and ga choose exactly k materials)",
    )?;
    if method != "ga" {
        if let Some((_, flag)) = e.ga_given().into_iter().find(|(given, _)| *given) {
            anyhow::bail!("{flag} applies to --method ga, not to {method}");
        }
    }
    if method == "greedy" && !e.init.is_empty() {
        anyhow::bail!("--init applies to swap and ga, not to greedy");
    }
    let mut sp = SearchParams::new(k);
    sp.candidates = indices(coll, &e.candidates)?;
    sp.targets = indices(coll, &e.targets)?;
    sp.init = indices(coll, &e.init)?;
    let names = coll.names();
    let vsp = sp.check(&names)?;
    let vgp = e.ga_params(g.seed).check()?;
    let op = ObjectiveParams::default()
        .mask(grid.mask)
        .weighting(grid.weighting)
        .stride(grid.stride)
        .check()?;
    let backend = super::backend(g)?;
    let pb = super::progress_bar(g, 1, "gram");
    let progress = |done: u64, total: u64| {
        pb.set_length(total);
        pb.set_position(done);
    };
    let obj = Objective::new(backend.as_ref(), coll, &op, &progress)?;
    pb.set_message(method.to_string());
    pb.set_position(0);
    let sel = match method {
        "greedy" => greedy(&obj, &vsp, &progress)?,
        "swap" => swap(&obj, &vsp, &progress)?,
        _ => ga(&obj, &vsp, &vgp, &progress)?,
    };
    pb.finish_and_clear();
    Ok(sel)
}
