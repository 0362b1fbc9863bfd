//! `brdf-basis tabulate`.

use super::Global;
use brdf_basis::atomic::OutputPlan;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::collection::MaterialData;
use brdf_basis::merl::write_binary_to;
use std::path::PathBuf;

/// Arguments of `tabulate`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Example:\n  brdf-basis tabulate --material polished-gold --out gold.binary\n  brdf-basis tabulate ngan2005_ashikhmin_shirley.csv --material gold-metallic-paint --out g.binary"
)]
pub(crate) struct TabulateArgs {
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
pub(crate) fn run(g: &Global, a: TabulateArgs) -> anyhow::Result<()> {
    let mut plan = OutputPlan::new(&a.collection);
    plan.file(&a.out, "--out")?;
    let mut out = plan.into_set()?;
    // After the output checks: an output naming an input or a device says so first.
    if super::extension(&a.out) != "binary" {
        anyhow::bail!(
            "--out {}: writes a MERL table and its name must end in .binary (a collection directory reads a .bsdf as an RGL-EPFL file and a .npy as part of a neural BRDF)",
            a.out.display()
        );
    }
    let coll = super::load_collection(&a.collection)?;
    let m = coll.get(&a.material)?;
    // Tables are copied as they are; only a material evaluated on the grid needs the
    // back-end (a GPU is not opened for a copy, so `--backend gpu` is refused for one,
    // as `render`, `plot` and `merge` refuse it).
    let table = matches!(m.data, MaterialData::Measured(_) | MaterialData::Rgl(_));
    if table && g.backend == Some(super::values::BackendArg::Gpu) {
        anyhow::bail!(
            "--backend gpu does not apply to tabulate --material {}: a {} material is a table on the MERL grid, copied as it is on the CPU with nothing to evaluate; leave it out",
            a.material,
            brdf_basis::material_kind(m)
        );
    }
    let rgb = match &m.data {
        MaterialData::Measured(_) | MaterialData::Rgl(_) => {
            brdf_basis::tabulate(&CpuBackend::new(), &coll, &a.material)
        }
        MaterialData::Analytic(_) | MaterialData::Neural(_) => {
            brdf_basis::tabulate(super::backend(g)?.as_ref(), &coll, &a.material)
        }
    }
    .map_err(|e| anyhow::anyhow!("{e}; nothing written"))?;
    out.stage(&a.out, |w| write_binary_to(w, &rgb))?;
    out.commit()?;
    println!(
        "wrote {} ({} bytes)",
        a.out.display(),
        std::fs::metadata(&a.out).map(|m| m.len()).unwrap_or(0)
    );
    Ok(())
}
