//! `brdf-basis info`.

use super::Global;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::gpu::GpuContext;
use brdf_basis::backend::Backend;
use brdf_basis::backend::BackendChoice;
use brdf_basis::error::plural;

/// Arguments of `info`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Example:\n  brdf-basis info\n  brdf-basis info --backend cpu\n  brdf-basis info paper_white_rgb.bsdf merl/\n  brdf-basis info merl100/   # a directory of neural BRDF sets"
)]
pub(crate) struct InfoArgs {
    /// Collection(s) to describe (kinds and counts of materials); none: only the back-end.
    pub collection: Vec<std::path::PathBuf>,
}

/// Prints the back-end, adapter, driver and limits.
pub(crate) fn run(g: &Global, a: InfoArgs) -> anyhow::Result<()> {
    let backend = g.backend_choice();
    let gpu = if backend == BackendChoice::Cpu {
        None
    } else {
        Some(GpuContext::new())
    };
    let chosen = match (&gpu, backend) {
        (_, BackendChoice::Cpu) => "cpu",
        (Some(Ok(_)), BackendChoice::Gpu) => "gpu",
        (Some(Ok(c)), BackendChoice::Auto) if !c.is_software() => "auto (per operation)",
        (Some(Err(e)), BackendChoice::Gpu) => anyhow::bail!("{e}"),
        _ => "cpu",
    };
    println!("backend: {chosen} (requested: --backend {})", backend);
    if chosen.starts_with("auto") {
        for (op, on, why) in brdf_basis::backend::AUTO_ROUTES {
            println!("  {op}: {on} ({why})");
        }
    } else if backend == BackendChoice::Auto {
        println!("  everything on the cpu: no hardware GPU (a software adapter is slower than the CPU back-end)");
    }
    match gpu {
        Some(Ok(c)) => {
            println!("adapter: {}", c.info.name);
            println!(
                "adapter type: {:?}{}",
                c.info.device_type,
                if c.is_software() { " (software)" } else { "" }
            );
            println!("graphics api: {:?}", c.info.backend);
            println!("driver: {} {}", c.info.driver, c.info.driver_info);
            println!("limits used:");
            println!(
                "  max_storage_buffer_binding_size: {}",
                c.limits.max_storage_buffer_binding_size
            );
            println!("  max_buffer_size: {}", c.limits.max_buffer_size);
            println!(
                "  max_compute_workgroups_per_dimension: {}",
                c.limits.max_compute_workgroups_per_dimension
            );
            println!(
                "  max_compute_invocations_per_workgroup: {}",
                c.limits.max_compute_invocations_per_workgroup
            );
            println!(
                "  max_storage_buffers_per_shader_stage: {}",
                c.limits.max_storage_buffers_per_shader_stage
            );
        }
        Some(Err(e)) => println!("adapter: none ({e})"),
        None => {}
    }
    println!("cpu back-end: {}", CpuBackend::new().name());
    match crate::plot::font_available() {
        Some(p) => println!("figure font: {p}"),
        None => println!(
            "figure font: none ({})",
            crate::plot::no_font_message().unwrap_or_default()
        ),
    }
    if !a.collection.is_empty() {
        let coll = super::load_collection(&a.collection)?;
        let kinds: Vec<String> = coll
            .kind_counts()
            .iter()
            .map(|(k, n)| {
                plural(
                    *n,
                    k,
                    &format!("{k}{}", if *k == "MERL table" { "s" } else { "" }),
                )
            })
            .collect();
        println!(
            "collection: {} ({})",
            plural(coll.len(), "material", "materials"),
            kinds.join(", ")
        );
        for m in coll.materials() {
            if let brdf_basis::collection::MaterialData::Rgl(r) = &m.data {
                let b = r.bsdf();
                println!(
                    "  {} (RGL-EPFL: {}): {} x {} tables, {} incident elevations; {} valid cells with a negative RGB value stored as 0",
                    brdf_basis::error::short_name(&m.name),
                    b.description.escape_debug(),
                    b.resolution,
                    b.resolution,
                    b.theta_i.len(),
                    r.clamped_cells()
                );
            }
        }
    }
    Ok(())
}
