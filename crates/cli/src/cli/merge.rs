//! `brdf-basis merge`.

use super::Global;
use brdf_basis::atomic::OutputPlan;
use brdf_basis::io::merge::{plan_merge, write_merged, TileFile};
use brdf_basis::io::sidecar::sidecar_path;
use std::path::PathBuf;

/// Arguments of `merge`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Every tile is a .npy written by `brdf-basis distance --tile I/N` with its \
.names.json sidecar. The tiles must come from the same collection and settings, and each \
of 1..N must be given exactly once; the merged matrix (with its sidecar) is byte-identical to \
computing it at once.\n\nExamples:\n  \
brdf-basis distance --stride 2 --band-rows 16 --tile 1/2 --out t1.npy\n  \
brdf-basis distance --stride 2 --band-rows 16 --tile 2/2 --out t2.npy\n  \
brdf-basis merge t1.npy t2.npy --out d.npy"
)]
pub(crate) struct MergeArgs {
    /// Tile files (.npy, each with its .names.json sidecar), in any order.
    #[arg(required = true)]
    pub tiles: Vec<PathBuf>,
    /// Output .npy (its sidecar is written beside it).
    #[arg(long)]
    pub out: PathBuf,
}

/// Merges the tiles.
pub(crate) fn run(g: &Global, a: MergeArgs) -> anyhow::Result<()> {
    let ext = super::extension(&a.out);
    if ext != "npy" {
        anyhow::bail!("{}: merge writes a .npy", a.out.display());
    }
    // Every output path before the work: not a tile or a tile's sidecar (any spelling),
    // the sidecar replaces only a sidecar, the directory is writable.
    let mut plan = OutputPlan::new(&[]);
    for t in &a.tiles {
        plan.input_named(t, "tile");
    }
    super::plan_matrix(&mut plan, &a.out, "--out")?;
    let mut out = plan.into_set()?;
    let tiles: Vec<TileFile> = a
        .tiles
        .iter()
        .map(|t| TileFile::open(t))
        .collect::<Result<_, _>>()?;
    let side = write_merged(&plan_merge(&tiles)?, &mut out, &a.out)?;
    out.commit()?;
    let _ = g;
    println!(
        "wrote {} ({} x {} {}, from {})",
        a.out.display(),
        side.n,
        side.n,
        side.settings.metric,
        brdf_basis::error::plural(a.tiles.len(), "tile", "tiles")
    );
    println!("wrote {}", sidecar_path(&a.out).display());
    Ok(())
}
