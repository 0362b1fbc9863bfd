//! Per-target weighted fits (SPEC 11): every target's weighted normal equations by a
//! 12-material basis (plus the Lambertian column), three channels, under the `relative`
//! objective (per-target weights), over the evaluation mask (894,396 cells), on each
//! back-end; targets are the 100 NBRDF MERL networks repeated to `BENCH_T` (default 10,000
//! on a hardware GPU, 300 on the CPU back-end: the repeats cost what distinct networks
//! would, each row is evaluated on its own), evaluated where the systems are summed.
//! Prints seconds, targets/s and the largest relative difference between the back-ends'
//! systems on the targets both ran.
//!
//! `cargo bench --bench weighted` (needs `../shared/data/real/nbrdf/merl100`;
//! `BENCH_T=...` sets the GPU's targets, `BENCH_T_CPU=...` the CPU back-end's;
//! `BENCH_BACKENDS=cpu` or `gpu` runs one).

use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::gpu::GpuBackend;
use brdf_basis::backend::weighted::{TargetWeight, WeightedSystems};
use brdf_basis::backend::{Backend, Lobe};
use brdf_basis::brdf::Nbrdf;
use brdf_basis::collection::{Collection, MaterialData};
use brdf_basis::merl::{CellSet, Mask, Weighting};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

fn channel_lobes(nets: &[Arc<Nbrdf>], c: usize) -> Vec<Lobe> {
    nets.iter()
        .map(|n| Lobe::Neural {
            net: n.clone(),
            channel: Some(c),
        })
        .collect()
}

/// The three channels' systems of `targets` nets by the first 12; wall seconds.
fn run(
    b: &dyn Backend,
    nets: &[Arc<Nbrdf>],
    t: usize,
    cells: &CellSet,
) -> (f64, Vec<WeightedSystems>) {
    let targets: Vec<Arc<Nbrdf>> = (0..t).map(|i| nets[i % nets.len()].clone()).collect();
    let w = TargetWeight::relative(0.01).unwrap();
    let start = Instant::now();
    let out = (0..3)
        .map(|c| {
            b.weighted_systems(
                &channel_lobes(&nets[..12], c),
                &channel_lobes(&targets, c),
                cells,
                w,
                &|_, _| {},
            )
            .expect("weighted systems")
        })
        .collect();
    (start.elapsed().as_secs_f64(), out)
}

fn main() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real/nbrdf/merl100");
    if !dir.exists() {
        println!(
            "weighted bench: {} is missing; nothing measured",
            dir.display()
        );
        return;
    }
    let coll = Collection::load(&dir).expect("merl100");
    let nets: Vec<Arc<Nbrdf>> = coll
        .materials()
        .iter()
        .filter_map(|m| match &m.data {
            MaterialData::Neural(n) => Some(n.clone()),
            _ => None,
        })
        .collect();
    let cells = CellSet::new(Mask::Evaluation, Weighting::SolidAngle, 1);
    let which = std::env::var("BENCH_BACKENDS").unwrap_or_default();
    let env_n = |k: &str, d: usize| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    };
    let mut cpu_out = None;
    if which != "gpu" {
        let cpu = CpuBackend::new();
        let t = env_n("BENCH_T_CPU", 300);
        let (s, out) = run(&cpu, &nets, t, &cells);
        println!(
            "weighted {:<50} {t} targets x 3 channels, basis 12 + Lambertian, {} cells: {s:.2} s, {:.0} targets/s",
            cpu.name(),
            cells.len(),
            t as f64 / s
        );
        cpu_out = Some((t, out));
    }
    if which != "cpu" {
        match GpuBackend::new() {
            Ok(g) => {
                let t = env_n(
                    "BENCH_T",
                    if g.context().is_software() {
                        100
                    } else {
                        10_000
                    },
                );
                let _ = run(&g, &nets, 100.min(t), &cells);
                let (s, out) = run(&g, &nets, t, &cells);
                println!(
                    "weighted {:<50} {t} targets x 3 channels, basis 12 + Lambertian, {} cells: {s:.2} s, {:.0} targets/s",
                    g.name(),
                    cells.len(),
                    t as f64 / s
                );
                if let Some((tc, c)) = &cpu_out {
                    let shared = (*tc).min(t);
                    let mut worst = 0f64;
                    for (a, b) in out.iter().zip(c) {
                        let n = shared * a.stride();
                        for (x, y) in a.values[..n].iter().zip(&b.values[..n]) {
                            worst = worst.max((x - y).abs() / x.abs().max(y.abs()).max(1e-30));
                        }
                    }
                    println!("weighted: GPU vs CPU systems of the first {shared} targets: largest relative difference {worst:.1e}");
                }
            }
            Err(e) => println!("weighted: no GPU ({e})"),
        }
    }
}
