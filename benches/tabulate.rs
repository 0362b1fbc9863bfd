//! Tabulation of 100 materials (full RGB: 300 lobes) over the full grid (1,458,000 cells)
//! on each back-end, printing cells/s (material-cells per second).
//!
//! `cargo bench --bench tabulate`

use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::{Backend, Lobe, LobeParams};
use brdf_basis::gpu::GpuBackend;
use brdf_basis::merl::grid::N_CELLS;
use std::time::Instant;

fn main() {
    let lobes: Vec<Lobe> = (0..300)
        .map(|i| {
            let t = (i / 3) as f64 / 100.0;
            Lobe::Analytic(LobeParams {
                kd: 0.1,
                ks: 0.5,
                f0: 0.05 + 0.9 * t as f32,
                n: 80_000f64.powf(t) as f32,
            })
        })
        .collect();
    let cells: Vec<u32> = (0..N_CELLS as u32).collect();
    let mut results = Vec::new();
    let cpu = CpuBackend::new();
    let mut backends: Vec<Box<dyn Backend>> = vec![Box::new(cpu)];
    if let Ok(g) = GpuBackend::new() {
        backends.push(Box::new(g));
    }
    for b in &backends {
        // 100 materials x 3 channels, in batches of 30 lobes to bound memory.
        let _ = b.tabulate(&lobes[..30], &cells).expect("warm-up");
        let t = Instant::now();
        for batch in lobes.chunks(30) {
            std::hint::black_box(b.tabulate(batch, &cells).expect("tabulate"));
        }
        let s = t.elapsed().as_secs_f64();
        let rate = (lobes.len() * N_CELLS) as f64 / s;
        println!(
            "tabulate {:<50} 100 materials x RGB x {N_CELLS} cells: {s:.2} s, {:.1} M lobe-cells/s",
            b.name(),
            rate / 1e6
        );
        results.push(rate);
    }
    if results.len() == 2 {
        println!("tabulate: gpu / cpu ratio {:.2}", results[1] / results[0]);
    }
}
