//! Embedding brdf-basis in a program that owns its wgpu device: the program opens the
//! adapter and device, hands them to brdf-basis, and computes BRDF_it distances, a
//! k-medoids basis and NNLS fits on the GPU, checked against the CPU back-end.
//!
//! ```sh
//! cargo run --release --example embed
//! ```
//!
//! Without a GPU adapter it prints `SKIP (no adapter)` and exits 0, unless
//! `BRDF_BASIS_REQUIRE_GPU=1` (as in CI), when it fails.

//! Only the crate-root facade and the requests (`brdf_basis::run`) are used, and wgpu and
//! pollster through `brdf_basis`.

use brdf_basis::run::{Ctx, DistanceOutput, DistanceRequest, FitRequest, Request};
use brdf_basis::{pollster, wgpu};
use brdf_basis::{Backend, Collection, CpuBackend, Distances, GramMode};
use brdf_basis::{DistanceMatrix, KMedoidsInit, KMedoidsParams, Metric};

/// The BRDF_it matrix of `coll` on `backend` (every 4th cell per grid axis).
fn distances(
    backend: &dyn Backend,
    coll: &Collection,
) -> Result<DistanceMatrix, Box<dyn std::error::Error>> {
    let mut req = DistanceRequest::default();
    req.metric = Metric::BrdfIt;
    req.grid = brdf_basis::merl::GridSpec::default().with_stride(4)?;
    match req.run(&Ctx::new(backend, coll))? {
        DistanceOutput::Matrix(d) => Ok(d),
        _ => unreachable!("no --tile: the whole matrix"),
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // 0. A headless host without XDG_RUNTIME_DIR: the Vulkan loader's Wayland probe would
    //    print "error: XDG_RUNTIME_DIR is invalid or not set" twice. Point it at a private
    //    directory first, as the `brdf-basis` binary does (docs/formats.md); before any
    //    thread exists.
    let _runtime = match std::env::var_os("XDG_RUNTIME_DIR") {
        Some(d) if std::path::Path::new(&d).is_absolute() && std::path::Path::new(&d).is_dir() => {
            None
        }
        _ => {
            let dir = tempfile::Builder::new()
                .prefix("brdf-basis-runtime-")
                .tempdir()?;
            std::env::set_var("XDG_RUNTIME_DIR", dir.path());
            Some(dir)
        }
    };

    // 1. The host program's own device (any adapter; lavapipe in CI).
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapter = match pollster::block_on(wgpu::util::initialize_adapter_from_env_or_default(
        &instance, None,
    )) {
        Ok(a) => a,
        Err(e) => {
            if std::env::var("BRDF_BASIS_REQUIRE_GPU").is_ok_and(|v| v == "1") {
                return Err(format!("BRDF_BASIS_REQUIRE_GPU=1 but no GPU adapter: {e}").into());
            }
            println!("SKIP (no adapter): {e}");
            return Ok(());
        }
    };
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("host program"),
        required_limits: adapter.limits(),
        ..Default::default()
    }))?;
    println!("adapter: {}", adapter.get_info().name);

    // 2. Hand it to brdf-basis.
    let gpu = brdf_basis::gpu_backend(device, queue, adapter.get_info())?;

    // 3. Distances, a basis and fits on the embedded default collection (every 4th cell
    //    per grid axis, to stay quick on a software adapter).
    let coll = Collection::embedded_default();
    let d = distances(&gpu, &coll)?;
    let d_cpu = distances(&CpuBackend::new(), &coll)?;
    let n = coll.len();
    let mut worst = 0f64;
    for i in 0..n {
        for j in 0..n {
            let (a, b) = (d.dist(i, j), d_cpu.dist(i, j));
            worst = worst.max((a - b).abs() / b.abs().max(1e-12));
        }
    }
    println!("BRDF_it {n} x {n}: largest relative difference GPU vs CPU {worst:.2e}");
    if worst > 1e-4 {
        return Err(format!("GPU and CPU distances differ by {worst:e} (> 1e-4)").into());
    }
    let km = KMedoidsParams::new(5)
        .seed(1)
        .init(KMedoidsInit::Random)
        .fit(&d)?;
    let basis: Vec<usize> = km.medoids.clone();
    println!(
        "k-medoids basis (DB {:.4}): {}",
        km.db_index,
        basis
            .iter()
            .map(|&b| coll.names()[b].clone())
            .collect::<Vec<_>>()
            .join(", ")
    );
    // Every other material fitted by the basis under the paper's `l2` objective, whose
    // shared Gram matrices come from a pass of the GPU over the grid (analytic
    // collections would otherwise take the closed form on the host; `--gram` concerns
    // `l2` only, and the request refuses it beside a weighted objective).
    let mut fr = FitRequest::new(basis.iter().map(|&b| coll.names()[b].clone()).collect());
    fr.grid = brdf_basis::merl::GridSpec::default().with_stride(4)?;
    fr.objective.objective = Some(brdf_basis::backend::weighted::ObjectiveKind::L2);
    fr.gram = GramMode::Grid;
    fr.appearance = false;
    let fits = fr.run(&Ctx::new(&gpu, &coll))?.fits;
    let mean = fits.iter().map(|f| f.mae).sum::<f64>() / fits.len() as f64;
    println!("fitted {} materials, mean MAE {mean:.4}", fits.len());
    if fits.len() != n - basis.len() || !mean.is_finite() {
        return Err("fits incomplete".into());
    }
    Ok(())
}
