//! Large collections: time and peak resident memory of every stage at N = 1,000, 3,000
//! and 10,000 synthetic analytic materials (generated from a seed; nothing is read from
//! disk). Each stage runs as a child process so that its peak RSS (VmHWM) is its own:
//!
//! * `distance`: the banded BRDF_it matrix (CPU back-end), written as `.npy` + sidecar;
//! * `kmedoids`: the saved matrix loaded (`select --distances` path: memory-mapped),
//!   k-medoids for k = 5..20, one seeded run each (the library default algorithm);
//! * `gcuk`: the saved matrix loaded, one GCUK run (default parameters);
//! * `greedy`: error-driven greedy selection (SPEC 8) at k = 20 (Gram + screened greedy;
//!   at N <= 1,000 also the exhaustive greedy, and whether both chose the same basis);
//! * `swap`: swap refinement at k = 12 from the greedy basis, N <= 1,000;
//! * `empirical`: Algorithm 1 (leave-one-out NNLS over the whole collection), N <= 3,000.
//!
//! `cargo bench --bench large` runs N = 1000, 3000, 10000. Environment: `BENCH_N=1000,3000`
//! (sizes), `BENCH_STAGES=distance,kmedoids` (stages), `BENCH_STRIDE=2` (grid stride of the
//! distance stage; default 1 at N <= 1,000, 2 above: the full-grid cost scales as
//! `stride^3`), `BENCH_SEED` (collection seed, default 2016), `BENCH_LOAD=read` (the
//! kmedoids and gcuk stages read the saved matrix into memory instead of memory-mapping
//! it as `select --distances` does).

use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::weighted::TargetWeight;
use brdf_basis::cluster::{GcukParams, KMedoidsParams};
use brdf_basis::collection::Collection;
use brdf_basis::distance::{distance_matrix_banded, DistanceParams, DEFAULT_BAND_ROWS};
use brdf_basis::io::saved::write_npy_with_sidecar;
use brdf_basis::io::sidecar::MatrixSettings;
use brdf_basis::select::{empirical, EmpiricalParams};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use brdf_basis::collection::synthetic;

fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// The saved matrix as `select --distances` loads it: memory-mapped (the default), or
/// read into memory with `BENCH_LOAD=read`; and which it was.
fn load_for_clustering(path: &Path) -> (brdf_basis::distance::DistanceMatrix, &'static str) {
    use brdf_basis::io::saved::{load_saved_matrix_with, MatrixLoad};
    let how = match std::env::var("BENCH_LOAD").as_deref() {
        Ok("read") => MatrixLoad::Read,
        _ => MatrixLoad::Map,
    };
    let d = load_saved_matrix_with(path, how).expect("load").matrix;
    let label = if d.is_mapped() { "mapped" } else { "read" };
    (d, label)
}

/// `RssAnon` and `RssFile` now (the matrix still loaded): mapped file pages count in the
/// resident set but are reclaimable, anonymous memory is not.
fn rss_split() -> String {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<f64>().ok())
            .map_or(f64::NAN, |kb| kb / 1024.0)
    };
    format!(
        "RssAnon {:.0} MB, RssFile {:.0} MB",
        field("RssAnon:"),
        field("RssFile:")
    )
}

fn env_list(name: &str, default: &str) -> Vec<String> {
    std::env::var(name)
        .unwrap_or_else(|_| default.into())
        .split(',')
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .collect()
}

fn stride_for(n: usize) -> usize {
    std::env::var("BENCH_STRIDE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(if n <= 1000 { 1 } else { 2 })
}

fn matrix_path(dir: &Path, n: usize) -> PathBuf {
    dir.join(format!("d{n}.npy"))
}

/// Error-driven greedy selection (SPEC 8) at k = 20 on the grid of stride
/// `BENCH_GREEDY_STRIDE` (default 3): the Gram of all materials (closed form), then the
/// screened greedy (`select --method greedy`); at N <= `BENCH_GREEDY_CHECK` (default
/// 1,000) also the exhaustive greedy of SPEC 8, and whether both chose the same basis in
/// the same order with the same scores; a one-line summary.
fn stage_greedy(coll: &Collection) -> Option<String> {
    use brdf_basis::select::{greedy_exhaustive, greedy_with_counts};
    use brdf_basis::select::{Objective, ObjectiveParams, SearchParams};
    let cpu = CpuBackend::new();
    let stride = env_usize("BENCH_GREEDY_STRIDE", 3);
    let t = Instant::now();
    let op = ObjectiveParams::default()
        .objective(TargetWeight::L2)
        .stride(stride)
        .check()
        .expect("objective params");
    let obj = Objective::new(&cpu, coll, &op, &|_, _| {}).expect("objective");
    let gram = t.elapsed().as_secs_f64();
    let p = SearchParams::new(20)
        .check(obj.names())
        .expect("search params");
    let t1 = Instant::now();
    let (sel, evaluated) = greedy_with_counts(&obj, &p, &|_, _| {}).unwrap();
    let fast = t1.elapsed().as_secs_f64();
    let n = coll.len();
    let swept: usize = (0..sel.indices.len()).map(|s| n - s).sum();
    let scored: usize = evaluated.iter().sum();
    let check = if n <= env_usize("BENCH_GREEDY_CHECK", 1000) {
        let t2 = Instant::now();
        let exact = greedy_exhaustive(&obj, &p, &|_, _| {}).unwrap();
        let slow = t2.elapsed().as_secs_f64();
        format!(
            "exhaustive greedy {slow:.2} s ({:.1}x), same basis, order and scores: {}",
            slow / fast,
            if exact == sel { "yes" } else { "NO" }
        )
    } else {
        "exhaustive greedy not run at this N (BENCH_GREEDY_CHECK)".into()
    };
    Some(format!(
        "k 20, stride {stride}, S {:.4e}, Gram {gram:.2} s, greedy {fast:.2} s (full exact scores {scored} of {swept}); {check}; basis {}",
        sel.score,
        sel.indices
            .iter()
            .map(|i| i.to_string())
            .collect::<Vec<_>>()
            .join(",")
    ))
}

/// Swap refinement (SPEC 8) at k = 12 from the greedy basis (stride as the greedy stage).
fn stage_swap(coll: &Collection) -> String {
    use brdf_basis::select::{swap, Objective, ObjectiveParams, SearchParams};
    let stride = env_usize("BENCH_GREEDY_STRIDE", 3);
    let t = Instant::now();
    let op = ObjectiveParams::default()
        .objective(TargetWeight::L2)
        .stride(stride)
        .check()
        .expect("objective params");
    let obj = Objective::new(&CpuBackend::new(), coll, &op, &|_, _| {}).expect("objective");
    let gram = t.elapsed().as_secs_f64();
    let p = SearchParams::new(12).check(obj.names()).expect("params");
    let sel = swap(&obj, &p, &|_, _| {}).unwrap();
    format!(
        "k 12, stride {stride}, S {:.4e}, {} exchanges, Gram {gram:.2} s, greedy + swap {:.2} s",
        sel.score,
        sel.history.len() - 1,
        t.elapsed().as_secs_f64() - gram
    )
}

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

/// One stage in this process; prints `RESULT ...`.
fn child(stage: &str, n: usize, dir: &Path) {
    let seed = std::env::var("BENCH_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2016);
    let coll = synthetic(n, seed);
    let t = Instant::now();
    let detail = match stage {
        "distance" => {
            let stride = stride_for(n);
            let p = DistanceParams::default()
                .stride(stride)
                .check(&coll)
                .expect("params");
            let cpu = CpuBackend::new();
            let d = distance_matrix_banded(&cpu, &coll, &p, DEFAULT_BAND_ROWS, &|_, _| {})
                .expect("distance");
            let computed = t.elapsed().as_secs_f64();
            write_npy_with_sidecar(
                &matrix_path(dir, n),
                &d,
                &MatrixSettings::of(&p, DEFAULT_BAND_ROWS),
                &coll.fingerprint(),
            )
            .expect("write");
            let cells = brdf_basis::distance::cell_set(&coll, &p).len();
            let diffs = (n * (n - 1) / 2) as f64 * cells as f64;
            format!(
                "stride {stride}, {cells} cells, compute {computed:.1} s ({:.2} G abs-diffs/s), write {:.1} s",
                diffs / computed / 1e9,
                t.elapsed().as_secs_f64() - computed
            )
        }
        "kmedoids" => {
            let (d, how) = load_for_clustering(&matrix_path(dir, n));
            let load = t.elapsed().as_secs_f64();
            let mut losses = Vec::new();
            for k in 5..=20 {
                let km = KMedoidsParams::new(k).seed(1).fit(&d).expect("kmedoids");
                losses.push(format!("{:.4}", km.loss));
            }
            format!(
                "{how}, load {load:.1} s, {}; k = 5..20 one run each; loss {}",
                rss_split(),
                losses.join(" ")
            )
        }
        "gcuk" => {
            let (d, how) = load_for_clustering(&matrix_path(dir, n));
            let load = t.elapsed().as_secs_f64();
            let g = GcukParams::default().seed(1).fit(&d).expect("gcuk");
            format!(
                "{how}, load {load:.1} s, {}; k = {} DB {:.4}",
                rss_split(),
                g.medoids.len(),
                g.db_index
            )
        }
        "swap" => stage_swap(&coll),
        "greedy" => match stage_greedy(&coll) {
            Some(s) => s,
            None => "NOT RUN: error-driven selection (src/select) is not on this branch".into(),
        },
        "empirical" => {
            let e = empirical(
                &CpuBackend::new(),
                &coll,
                &EmpiricalParams {
                    fit: brdf_basis::fit::FitParams {
                        objective: TargetWeight::L2,
                        ..Default::default()
                    },
                    ..EmpiricalParams::default()
                },
                &|_, _| {},
            )
            .expect("empirical");
            let links: usize = e.contributors.values().map(Vec::len).sum();
            // Digest of every target's contributor list (order-sensitive), to compare runs.
            let mut h = brdf_basis::hash::Hasher::new();
            for (t, c) in &e.contributors {
                h.write(t.as_bytes());
                for name in c {
                    h.write(name.as_bytes());
                }
            }
            format!(
                "basis {} materials, {links} contributor links, contributors digest {:016x}",
                e.basis.len(),
                h.finish()
            )
        }
        other => panic!("unknown stage {other}"),
    };
    println!(
        "RESULT {stage} N={n} time={:.2}s peak_rss={:.0}MB  {detail}",
        t.elapsed().as_secs_f64(),
        peak_rss_mb()
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(k) = args.iter().position(|a| a == "--stage") {
        let stage = &args[k + 1];
        let n: usize = args[k + 2].parse().expect("n");
        child(stage, n, Path::new(&args[k + 3]));
        return;
    }
    let sizes: Vec<usize> = env_list("BENCH_N", "1000,3000,10000")
        .iter()
        .map(|s| s.parse().expect("BENCH_N"))
        .collect();
    let stages = env_list(
        "BENCH_STAGES",
        "distance,kmedoids,gcuk,greedy,swap,empirical",
    );
    let dir = tempfile::tempdir().expect("temp dir");
    let exe = std::env::current_exe().expect("exe");
    for &n in &sizes {
        for stage in &stages {
            if (stage == "empirical" && n > 3000) || (stage == "swap" && n > 1000) {
                continue;
            }
            let out = Command::new(&exe)
                .args(["--stage", stage, &n.to_string()])
                .arg(dir.path())
                .output()
                .expect("child");
            let text = String::from_utf8_lossy(&out.stdout);
            match text.lines().find(|l| l.starts_with("RESULT ")) {
                Some(l) => println!("large {}", &l[7..]),
                None => println!(
                    "large {stage} N={n} FAILED: {}",
                    String::from_utf8_lossy(&out.stderr)
                ),
            }
        }
    }
}
