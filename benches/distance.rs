//! Pairwise BRDF_it throughput: N = 100 and N = 1000 materials on the full grid
//! (evaluation mask, 894,396 cells), each back-end. Prints G abs-diffs/s
//! (N (N - 1) / 2 x cells / s) and the peak resident memory of the process.
//!
//! `cargo bench --bench distance` (BENCH_N=100,1000,10000 sets the sizes; BENCH_N_GPU_ONLY=1000
//! runs the CPU back-end only up to that size;
//! BENCH_SHAPES=1 also times every register-block shape of the GPU kernel at N = 100 and
//! N = 240, the figures behind `KernelShape::choose`).

use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::gpu::GpuBackend;
use brdf_basis::backend::{Backend, Lobe};
use brdf_basis::brdf::LobeParams;
use brdf_basis::merl::{CellSet, Mask, Weighting};
use std::time::Instant;

fn lobes(n: usize) -> Vec<Lobe> {
    // Deterministic spread of (F0, n) like the Ngan table: n from 1 to 80,000, log-uniform.
    (0..n)
        .map(|i| {
            let t = (i as f64 + 0.5) / n as f64;
            let f0 = (0.02 + 0.96 * ((i * 37) % n) as f64 / n as f64) as f32;
            Lobe::Analytic(LobeParams {
                kd: 0.0,
                ks: 1.0,
                f0,
                n: (80_000f64).powf(t) as f32,
            })
        })
        .collect()
}

fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .map(|l| l.to_string())
        })
        .and_then(|l| {
            l.split_whitespace()
                .nth(1)
                .and_then(|v| v.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn run(name: &str, b: &dyn Backend, n: usize, cells: &CellSet, reps: usize) -> (f64, Vec<f64>) {
    let l = lobes(n);
    let mut m = b.pairwise_l1(&l, cells, &|_, _| {}).expect("warm-up");
    let t = Instant::now();
    for _ in 0..reps {
        m = std::hint::black_box(b.pairwise_l1(&l, cells, &|_, _| {}).expect("pairwise"));
    }
    let s = t.elapsed().as_secs_f64() / reps as f64;
    let diffs = (n * (n - 1) / 2) as f64 * cells.len() as f64;
    let g = diffs / s / 1e9;
    println!(
        "distance {name:<50} N={n:<5} cells={} time={:.3} s  {:.2} G abs-diffs/s  peak RSS {:.0} MB",
        cells.len(),
        s,
        g,
        peak_rss_mb()
    );
    (g, m)
}

/// Largest relative difference between two matrices of the same back-end contract.
fn worst_relative(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / x.abs().max(y.abs()).max(1e-300))
        .fold(0.0, f64::max)
}

/// Raw rate (evaluated pairs x cells / s, padding and diagonal blocks included) of each
/// kernel shape on `n` lobes, and the shape `KernelShape::choose` picks.
fn shapes(g: &GpuBackend, n: usize, cells: &CellSet) {
    use brdf_basis::backend::gpu::pairwise::{KernelShape, PairPlan, PairwiseKernel, PlanLimits};
    use brdf_basis::backend::{all_blocks, PairOp};
    let l = lobes(n);
    let ctx = g.context();
    let kernel = PairwiseKernel::new();
    let blocks = all_blocks(n);
    let software = ctx.is_software();
    // BENCH_SHAPES_EXTRA=2x128,1x64: register shapes (R x lanes) beyond the built-in ones;
    // on a hardware GPU above N = 240 only the hardware shapes and the extra ones run.
    let extra: Vec<KernelShape> = std::env::var("BENCH_SHAPES_EXTRA")
        .unwrap_or_default()
        .split(',')
        .filter_map(|s| {
            let (r, l) = s.split_once('x')?;
            Some(KernelShape::register(r.parse().ok()?, l.parse().ok()?))
        })
        .collect();
    let all: Vec<KernelShape> = KernelShape::all()
        .filter(|s| software || n <= 240 || !s.is_software())
        .chain(extra)
        .collect();
    for shape in all {
        let plan = PairPlan::new(n, 0, cells.len(), &PlanLimits::of(ctx), shape).expect("plan");
        let go = || {
            kernel
                .run(ctx, &l, cells, &blocks, PairOp::L1, &plan, &|_, _| {})
                .expect("run")
        };
        go();
        // Best of three: the machines are shared.
        let s = (0..3)
            .map(|_| {
                let t = Instant::now();
                std::hint::black_box(go());
                t.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min);
        let evaluated = shape.evaluated_pairs(n);
        println!(
            "shape {0}x{0} lanes {1:<3}{5} N={n:<4} {s:.3} s: {2:.2} G abs-diffs/s, raw {3:.2} G pair-cells/s{4}",
            shape.side(),
            shape.lanes,
            (n * (n - 1) / 2) as f64 * cells.len() as f64 / s / 1e9,
            evaluated * cells.len() as f64 / s / 1e9,
            if KernelShape::choose(n, software) == shape { "  <- chosen" } else { "" },
            match (shape.tiled, ctx.has_f64()) {
                (true, true) => " tiled, f64 totals on the device",
                (true, false) => " tiled, totals on the host",
                (false, true) => " register, f64 totals on the device",
                (false, false) => " register, totals on the host",
            }
        );
    }
}

fn main() {
    let cells = CellSet::new(Mask::Evaluation, Weighting::Uniform, 1);
    let cpu = CpuBackend::new();
    // BENCH_BACKENDS=cpu skips the GPU (lavapipe takes minutes at N = 1000).
    let gpu = if std::env::var("BENCH_BACKENDS").is_ok_and(|v| v == "cpu") {
        None
    } else {
        GpuBackend::new().ok()
    };
    if let (Some(g), true) = (&gpu, std::env::var("BENCH_SHAPES").is_ok_and(|v| v == "1")) {
        let sizes: Vec<usize> = std::env::var("BENCH_SHAPES_N")
            .ok()
            .map(|v| v.split(',').filter_map(|x| x.trim().parse().ok()).collect())
            .unwrap_or(vec![100, 240]);
        for n in sizes {
            shapes(g, n, &cells);
        }
    }
    // BENCH_N=100,1000 (default), or any list; BENCH_N_GPU_ONLY: sizes above which the CPU
    // back-end is not run (its rate at the largest CPU size stands for it: its throughput
    // does not depend on N), default 1000.
    let sizes: Vec<usize> = match std::env::var("BENCH_N") {
        Ok(v) => v.split(',').filter_map(|x| x.trim().parse().ok()).collect(),
        Err(_) => vec![100, 1000],
    };
    let cpu_max: usize = std::env::var("BENCH_N_GPU_ONLY")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1000);

    let mut cpu_rate = None;
    for n in sizes {
        let reps = if n <= 240 { 3 } else { 1 };
        let c = if n <= cpu_max {
            let (c, m) = run(&cpu.name(), &cpu, n, &cells, reps);
            cpu_rate = Some(c);
            Some((c, m))
        } else {
            None
        };
        if let Some(g) = &gpu {
            let (gg, gm) = run(&g.name(), g, n, &cells, reps);
            match &c {
                Some((c, cm)) => println!(
                    "distance N={n}: gpu / cpu throughput ratio {:.2}; matrices: largest relative difference {:.1e}, {} of {} entries identical",
                    gg / c,
                    worst_relative(&gm, cm),
                    gm.iter().zip(cm).filter(|(a, b)| a == b).count(),
                    gm.len()
                ),
                None => match cpu_rate {
                    Some(c) => println!(
                        "distance N={n}: gpu / cpu throughput ratio {:.2} (the CPU back-end's rate at N = {cpu_max}; it was not run at this size)",
                        gg / c
                    ),
                    None => println!("distance N={n}: GPU only"),
                },
            }
        } else {
            println!("distance: no GPU adapter, GPU figures skipped");
        }
    }
}
