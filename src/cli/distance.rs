//! `brdf-basis distance`.

use super::Global;
use brdf_basis::distance::{distance_matrix, DistanceParams, LobeKind, Metric};
use brdf_basis::io::matrix::{write_csv, write_npy};
use std::path::PathBuf;

/// Arguments of `distance`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis distance --out d.csv\n  brdf-basis distance ../shared/data/ngan2005_ashikhmin_shirley.csv --metric brdf-it --weighting solid-angle --out d.npy"
)]
pub struct DistanceArgs {
    /// Collection(s): analytic .csv, .binary file or directory (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// brdf-it (the paper's Eq. 5) or euclidean (on F0, n).
    #[arg(long, default_value = "brdf-it")]
    pub metric: Metric,
    /// Grid cells and weights.
    #[command(flatten)]
    pub grid: super::GridArgs,
    /// specular (rho_s, analytic only) or full (mean of R, G, B); default: specular when
    /// every material is analytic.
    #[arg(long)]
    pub lobe: Option<LobeKind>,
    /// Output: .npy (float64 N x N) or .csv.
    #[arg(long)]
    pub out: PathBuf,
}

/// Computes and writes the matrix.
pub fn run(g: &Global, a: DistanceArgs) -> anyhow::Result<()> {
    let ext = a
        .out
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    if ext != "npy" && ext != "csv" {
        anyhow::bail!("{}: output must end in .npy or .csv", a.out.display());
    }
    let coll = super::load_collection(&a.collection)?;
    let mut p = DistanceParams::default()
        .metric(a.metric)
        .mask(a.grid.mask)
        .weighting(a.grid.weighting)
        .stride(a.grid.stride);
    p.lobe = a.lobe;
    let p = p.check(&coll)?;
    let backend = super::backend(g)?;
    let pb = super::progress_bar(g, 1, "distance");
    let d = distance_matrix(backend.as_ref(), &coll, &p, &|done, total| {
        pb.set_length(total);
        pb.set_position(done);
    })?;
    pb.finish_and_clear();
    match ext.as_str() {
        "npy" => write_npy(&a.out, &d)?,
        _ => write_csv(&a.out, &d)?,
    }
    if !g.quiet {
        eprintln!(
            "wrote {} ({} x {} {}, lobe {}, mask {}, weighting {})",
            a.out.display(),
            d.names().len(),
            d.names().len(),
            p.metric,
            p.lobe,
            p.mask,
            p.weighting
        );
    }
    Ok(())
}
