//! Neural BRDFs (SPEC 9), in one run, as ratios:
//!
//! * tabulating the 100 NBRDF MERL materials (RGB) on the full grid (1,458,000 cells):
//!   CPU back-end, GPU back-end (lavapipe: the WGSL network kernel), and a plain numpy evaluation of the same networks
//!   (`benches/nbrdf_numpy.py`, run with `$BRDF_BASIS_PYTHON`, else `/work/venv/bin/python`,
//!   else `python3`), whose per-material sums also check the Rust values;
//! * BRDF_it (full lobe, evaluation mask, uniform weights) and the Gram pass of 12 basis
//!   lobes against all 300 channel lobes on them, CPU and GPU;
//! * peak RSS of BRDF_it over 1,000 distinct networks (the 100, perturbed), every 16th
//!   cell: rows are evaluated per chunk of cells, never stored whole.
//!
//! `cargo bench --bench nbrdf` (needs `../shared/data/real/nbrdf/merl100`). Each timing
//! prints wall and CPU seconds (this process, all threads) and the load average.
//! `BRDF_BASIS_NBRDF_CPU_ONLY=1` leaves out the GPU back-end (lavapipe takes minutes on
//! 2 cores); `BRDF_BASIS_NBRDF_TABULATE_ONLY=1` stops after the tabulation ratios.
//! The tabulation clock covers the `tabulate` calls only; the per-material checksums are
//! summed after it stops (numpy's time includes its own sums, about 1% of it).

use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::gpu::GpuBackend;
use brdf_basis::backend::{Backend, Lobe};
use brdf_basis::brdf::Nbrdf;
use brdf_basis::collection::{Collection, MaterialData};
use brdf_basis::merl::N_CELLS;
use brdf_basis::merl::{CellSet, Mask, Weighting};
use std::path::PathBuf;
use std::process::Command;
use std::sync::Arc;
use std::time::Instant;

fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

/// CPU seconds of this process so far (user + system, all threads).
fn cpu_seconds() -> f64 {
    rusage_seconds(libc::RUSAGE_SELF)
}

/// CPU seconds (user + system) of `who` (`RUSAGE_SELF`, or `RUSAGE_CHILDREN`: the
/// children waited for).
fn rusage_seconds(who: libc::c_int) -> f64 {
    // SAFETY: getrusage writes the struct it is given.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    unsafe { libc::getrusage(who, &mut u) };
    let t = |v: libc::timeval| v.tv_sec as f64 + v.tv_usec as f64 * 1e-6;
    t(u.ru_utime) + t(u.ru_stime)
}

/// The 1-minute load average (`/proc/loadavg`), for reading a timing on a shared machine.
fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(str::to_owned))
        .unwrap_or_else(|| "?".into())
}

fn python() -> String {
    std::env::var("BRDF_BASIS_PYTHON").unwrap_or_else(|_| {
        if std::path::Path::new("/work/venv/bin/python").exists() {
            "/work/venv/bin/python".into()
        } else {
            "python3".into()
        }
    })
}

/// Tabulates every network's three channels on the full grid, ten materials at a time;
/// returns the wall seconds of the `tabulate` calls, their CPU seconds (this process)
/// and each material's f64 sum of its RGB values (summed outside the clock).
fn tabulate_all(b: &dyn Backend, nets: &[Arc<Nbrdf>]) -> (f64, f64, Vec<f64>) {
    let cells: Vec<u32> = (0..N_CELLS as u32).collect();
    let mut sums = Vec::new();
    let (mut wall, mut cpu) = (0.0, 0.0);
    for batch in nets.chunks(10) {
        let lobes: Vec<Lobe> = batch
            .iter()
            .flat_map(|n| {
                (0..3).map(|c| Lobe::Neural {
                    net: n.clone(),
                    channel: Some(c),
                })
            })
            .collect();
        let (t, c) = (Instant::now(), cpu_seconds());
        let v = b.tabulate(&lobes, &cells).expect("tabulate");
        wall += t.elapsed().as_secs_f64();
        cpu += cpu_seconds() - c;
        for m in v.chunks(3 * N_CELLS) {
            sums.push(m.iter().map(|&x| x as f64).sum());
        }
    }
    (wall, cpu, sums)
}

fn main() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real/nbrdf/merl100");
    if !dir.exists() {
        println!(
            "nbrdf bench: {} is missing; nothing measured",
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
    if std::env::var("BRDF_BASIS_NBRDF_MANY").is_ok_and(|v| v == "1") {
        return many(&coll, &nets);
    }
    let flag = |k: &str| std::env::var(k).is_ok_and(|v| v == "1");
    let cell_evals = (nets.len() * N_CELLS) as f64;
    let cpu = CpuBackend::new();
    let gpu = if flag("BRDF_BASIS_NBRDF_CPU_ONLY") {
        None
    } else {
        GpuBackend::new().ok()
    };

    // Tabulation.
    let _ = tabulate_all(&cpu, &nets[..2]);
    let load_before = load();
    let (t_cpu, c_cpu, sums) = tabulate_all(&cpu, &nets);
    println!(
        "tabulate 100 NBRDF x RGB x {N_CELLS} cells, {}, network kernel {}: {t_cpu:.2} s wall, {c_cpu:.2} s CPU, load {load_before} -> {} ({:.1} M network evaluations/s)",
        cpu.name(),
        brdf_basis::brdf::cpu_kernel(),
        load(),
        cell_evals / t_cpu / 1e6
    );
    let t_gpu = gpu.as_ref().map(|g| {
        let (t, _, s) = tabulate_all(g, &nets);
        // The GPU kernel and the CPU twin agree within SPEC 9, not bit for bit.
        let worst = s
            .iter()
            .zip(&sums)
            .map(|(a, b)| (a - b).abs() / b.abs().max(1e-30))
            .fold(0.0, f64::max);
        assert!(worst < 1e-4, "GPU and CPU per-material sums differ by {worst:.1e}");
        println!(
            "tabulate, {}: {t:.2} s (WGSL kernel; per-material sums within {worst:.1e} of the CPU's)",
            g.name()
        );
        t
    });
    let load_before = load();
    let children = rusage_seconds(libc::RUSAGE_CHILDREN);
    let out = Command::new(python())
        .arg(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("benches/nbrdf_numpy.py"))
        .arg(&dir)
        .arg("100")
        .output();
    let mut t_numpy = None;
    match out {
        Ok(o) if o.status.success() => {
            let text = String::from_utf8_lossy(&o.stdout);
            let mut worst = 0f64;
            for (line, (m, &s)) in text.lines().zip(coll.materials().iter().zip(&sums)) {
                let mut f = line.split_whitespace();
                assert_eq!(f.next(), Some(m.name.as_str()));
                let v: f64 = f.next().and_then(|v| v.parse().ok()).expect("sum");
                worst = worst.max((v - s).abs() / v.abs().max(1e-30));
            }
            let secs: f64 = text
                .lines()
                .find_map(|l| l.strip_prefix("seconds ")?.trim().parse().ok())
                .expect("seconds");
            println!(
                "tabulate, numpy (float32 matrix products): {secs:.2} s, load {load_before} -> {} (the python process: {:.2} s CPU, loading included); per-material sums agree with the CPU back-end to {worst:.1e} relative",
                load(),
                rusage_seconds(libc::RUSAGE_CHILDREN) - children
            );
            t_numpy = Some(secs);
        }
        Ok(o) => println!(
            "numpy baseline failed: {}",
            String::from_utf8_lossy(&o.stderr)
                .lines()
                .last()
                .unwrap_or("")
        ),
        Err(e) => println!("numpy baseline not run ({}): {e}", python()),
    }
    if let Some(n) = t_numpy {
        println!("tabulate ratio: cpu = {:.1} x numpy", n / t_cpu);
        if let Some(g) = t_gpu {
            println!("tabulate ratio: gpu (lavapipe) = {:.1} x numpy", n / g);
        }
    }
    if flag("BRDF_BASIS_NBRDF_TABULATE_ONLY") {
        return;
    }

    // BRDF_it and the Gram pass.
    let cells = CellSet::for_collection(
        &coll,
        Mask::Evaluation,
        Weighting::Uniform,
        std::num::NonZeroUsize::new(1).expect("1"),
    );
    let mean: Vec<Lobe> = nets
        .iter()
        .map(|n| Lobe::Neural {
            net: n.clone(),
            channel: None,
        })
        .collect();
    let channels: Vec<Lobe> = nets
        .iter()
        .flat_map(|n| {
            (0..3).map(|c| Lobe::Neural {
                net: n.clone(),
                channel: Some(c),
            })
        })
        .collect();
    let mut backends: Vec<&dyn Backend> = vec![&cpu];
    if let Some(g) = &gpu {
        backends.push(g);
    }
    let mut first: Option<(f64, f64)> = None;
    for b in backends {
        let t = Instant::now();
        let d = b.pairwise_l1(&mean, &cells, &|_, _| {}).expect("BRDF_it");
        let t_d = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let g = b.gram(&channels, &cells, 12, &|_, _| {}).expect("gram");
        let t_g = t.elapsed().as_secs_f64();
        std::hint::black_box((d, g));
        println!(
            "BRDF_it 100 NBRDF x {} cells, {}: {t_d:.2} s; Gram 12 x 300 channel lobes: {t_g:.2} s",
            cells.len(),
            b.name()
        );
        match first {
            None => first = Some((t_d, t_g)),
            Some((d0, g0)) => println!(
                "ratios gpu / cpu time: BRDF_it {:.2}, Gram {:.2}",
                t_d / d0,
                t_g / g0
            ),
        }
    }
    if let Some((d0, _)) = first {
        println!("BRDF_it / tabulation (cpu): {:.2}", d0 / t_cpu);
    }

    // 1,000 networks: peak memory of BRDF_it, in a fresh process (peak RSS counts the
    // whole life of a process).
    let out = Command::new(std::env::current_exe().expect("exe"))
        .env("BRDF_BASIS_NBRDF_MANY", "1")
        .output()
        .expect("run the 1,000-network part");
    print!("{}", String::from_utf8_lossy(&out.stdout));
}

/// BRDF_it over 1,000 distinct networks, every 16th cell of the evaluation mask.
fn many(coll: &Collection, nets: &[Arc<Nbrdf>]) {
    let cpu = CpuBackend::new();
    let many: Vec<Lobe> = (0..1000)
        .map(|i| {
            let mut w = nets[i % nets.len()].weights().to_vec();
            let f = 1.0 + (i / nets.len()) as f32 * 1e-3;
            w.iter_mut().for_each(|x| *x *= f);
            Lobe::Neural {
                net: Arc::new(Nbrdf::from_weights(w).expect("finite")),
                channel: None,
            }
        })
        .collect();
    let sparse = CellSet::for_collection(
        coll,
        Mask::Evaluation,
        Weighting::Uniform,
        std::num::NonZeroUsize::new(16).expect("16"),
    );
    let before = peak_rss_mib();
    let t = Instant::now();
    let d = cpu.pairwise_l1(&many, &sparse, &|_, _| {}).expect("1000");
    println!(
        "BRDF_it 1,000 NBRDF x {} cells (cpu): {:.2} s, {} distances; peak RSS {:.0} MiB (before: {before:.0} MiB; 1,000 full RGB tables would be {:.0} MiB)",
        sparse.len(),
        t.elapsed().as_secs_f64(),
        d.len(),
        peak_rss_mib(),
        1000.0 * 3.0 * N_CELLS as f64 * 4.0 / (1 << 20) as f64
    );
}
