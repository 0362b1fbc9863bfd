//! `brdf-basis tabulate`.

use super::Global;
use anyhow::Context;
use brdf_basis::atomic::OutputPlan;
use brdf_basis::backend::Lobe;
use brdf_basis::collection::MaterialData;
use brdf_basis::fit::channel_lobe;
use brdf_basis::merl::grid::{cell_info, N_CELLS};
use brdf_basis::merl::write_binary_to;
use std::path::PathBuf;

/// Arguments of `tabulate`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Example:\n  brdf-basis tabulate --material polished-gold --out gold.binary\n  brdf-basis tabulate ngan2005_ashikhmin_shirley.csv --material gold-metallic-paint --out g.binary"
)]
pub struct TabulateArgs {
    /// Collection(s): analytic .csv, .binary file or directory (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// Material to write.
    #[arg(long)]
    pub material: String,
    /// Output MERL .binary file.
    #[arg(long)]
    pub out: PathBuf,
}

/// Writes the material on the full MERL grid (invalid cells = -1).
pub fn run(g: &Global, a: TabulateArgs) -> anyhow::Result<()> {
    let mut plan = OutputPlan::new(&a.collection);
    plan.file(&a.out, "--out")?;
    let mut out = plan.into_set()?;
    let coll = super::load_collection(&a.collection)?;
    let m = coll.get(&a.material)?;
    let mut rgb = vec![0f32; 3 * N_CELLS];
    match &m.data {
        MaterialData::Analytic(_) => {
            let backend = super::backend(g)?;
            let lobes: Vec<Lobe> = (0..3).map(|c| channel_lobe(&m.data, c)).collect();
            let cells: Vec<u32> = (0..N_CELLS as u32).collect();
            rgb = backend.tabulate(&lobes, &cells).context("tabulating")?;
            let mut overflow = 0usize;
            for cell in 0..N_CELLS {
                if !cell_info(cell).valid {
                    for c in 0..3 {
                        rgb[c * N_CELLS + cell] = -1.0;
                    }
                } else if (0..3).any(|c| !rgb[c * N_CELLS + cell].is_finite()) {
                    overflow += 1;
                }
            }
            if overflow > 0 {
                anyhow::bail!(
                    "material `{}` ({}): its reflectance is not a finite f32 number in {overflow} valid cells (parameters too large: n = {}, s = {:?}); nothing written",
                    brdf_basis::error::short_name(&m.name),
                    m.origin,
                    m.analytic().map_or(0.0, |p| p.n),
                    m.analytic().map_or([0.0; 3], |p| p.s),
                );
            }
        }
        MaterialData::Measured(t) => rgb.copy_from_slice(&t.rgb),
        MaterialData::Neural(_) => {
            // The network's f32 twin at every valid cell (the grid's tabulation, SPEC 9),
            // clamped at 0 by the network's definition; invalid cells -1.
            let backend = super::backend(g)?;
            let lobes: Vec<Lobe> = (0..3).map(|c| channel_lobe(&m.data, c)).collect();
            let cells: Vec<u32> = (0..N_CELLS as u32).collect();
            rgb = backend.tabulate(&lobes, &cells).context("tabulating")?;
            for cell in 0..N_CELLS {
                if !cell_info(cell).valid {
                    for c in 0..3 {
                        rgb[c * N_CELLS + cell] = -1.0;
                    }
                }
            }
        }
    }
    out.stage(&a.out, |w| write_binary_to(w, &rgb))?;
    out.commit()?;
    println!(
        "wrote {} ({} bytes)",
        a.out.display(),
        std::fs::metadata(&a.out).map(|m| m.len()).unwrap_or(0)
    );
    Ok(())
}
