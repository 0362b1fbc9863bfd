//! `brdf-basis fit`.

use super::Global;
use brdf_basis::collection::Collection;
use brdf_basis::experiment::files::FitFile;
use brdf_basis::fit::{combination_values, fit, FitParams, GramMode, Solver, TargetFit};
use brdf_basis::io::json::write_json;
use brdf_basis::merl::grid::{cell_info, N_CELLS};
use brdf_basis::merl::write_binary;
use std::path::{Path, PathBuf};

/// Arguments of `fit`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis fit ../shared/data/ngan2005_ashikhmin_shirley.csv --basis blue-acrylic,acrylic-yellow,alumina-oxide,cherry-235,steel --all-others --json fits.json\n  brdf-basis fit --basis mirror-silver,matte-white-paint --targets polished-gold --json f.json --export fitted/"
)]
pub struct FitArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// Basis materials, comma-separated.
    #[arg(long, value_delimiter = ',', required = true)]
    pub basis: Vec<String>,
    /// Target materials, comma-separated.
    #[arg(long, value_delimiter = ',', conflicts_with = "all_others")]
    pub targets: Vec<String>,
    /// Fit every material not in the basis.
    #[arg(long)]
    pub all_others: bool,
    /// Grid cells and weights.
    #[command(flatten)]
    pub grid: super::GridArgs,
    /// exact (Lawson-Hanson) or pgd (batched projected gradient, exact fallback).
    #[arg(long, default_value = "exact")]
    pub solver: String,
    /// auto (closed-form separable Gram when every material is analytic) or grid (the
    /// back-end's pass over the grid).
    #[arg(long, default_value = "auto")]
    pub gram: String,
    /// Output JSON.
    #[arg(long)]
    pub json: PathBuf,
    /// Also write each fitted combination as DIR/<target>.binary.
    #[arg(long)]
    pub export: Option<PathBuf>,
}

/// Writes the fitted combination on the full grid as a MERL file.
pub fn export(
    coll: &Collection,
    basis: &[usize],
    f: &TargetFit,
    path: &Path,
) -> anyhow::Result<()> {
    let cells: Vec<u32> = (0..N_CELLS as u32).collect();
    let mut rgb = vec![-1f32; 3 * N_CELLS];
    for c in 0..3 {
        let v = combination_values(coll, basis, f, c, &cells);
        for (cell, x) in v.into_iter().enumerate() {
            if cell_info(cell).valid {
                rgb[c * N_CELLS + cell] = x as f32;
            }
        }
    }
    write_binary(path, &rgb)?;
    Ok(())
}

/// Runs the fits.
pub fn run(g: &Global, a: FitArgs) -> anyhow::Result<()> {
    let coll = super::load_collection(&a.collection)?;
    let basis: Vec<usize> = a
        .basis
        .iter()
        .map(|n| coll.index_of(n.trim()))
        .collect::<Result<_, _>>()?;
    let targets: Vec<usize> = if a.all_others {
        (0..coll.len()).filter(|i| !basis.contains(i)).collect()
    } else if a.targets.is_empty() {
        anyhow::bail!("give --targets X,Y or --all-others");
    } else {
        a.targets
            .iter()
            .map(|n| coll.index_of(n.trim()))
            .collect::<Result<_, _>>()?
    };
    let solver = match a.solver.as_str() {
        "exact" => Solver::Exact,
        "pgd" => Solver::Pgd,
        s => anyhow::bail!("unknown solver `{s}` (expected exact or pgd)"),
    };
    let gram = match a.gram.as_str() {
        "auto" => GramMode::Auto,
        "grid" => GramMode::Grid,
        g => anyhow::bail!("unknown gram mode `{g}` (expected auto or grid)"),
    };
    let p = FitParams {
        mask: a.grid.mask,
        weighting: a.grid.weighting,
        stride: a.grid.stride,
        solver,
        gram,
    };
    let backend = super::backend(g)?;
    let pb = super::progress_bar(g, 1, "gram");
    let fits = fit(backend.as_ref(), &coll, &basis, &targets, &p, &|d, t| {
        pb.set_length(t);
        pb.set_position(d);
    })?;
    pb.finish_and_clear();
    write_json(&a.json, &FitFile::new(&coll, &basis, &fits, &p))?;
    if let Some(dir) = &a.export {
        std::fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("{}: {e}", dir.display()))?;
        for f in &fits {
            export(
                &coll,
                &basis,
                f,
                &dir.join(format!("{}.binary", f.material)),
            )?;
        }
    }
    if !g.quiet {
        let mean = fits.iter().map(|f| f.mae).sum::<f64>() / fits.len() as f64;
        eprintln!(
            "wrote {} ({} targets, mean MAE {mean:.4e})",
            a.json.display(),
            fits.len()
        );
    }
    Ok(())
}
