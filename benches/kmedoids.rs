//! k-medoids: FasterPAM (the default) against PAM on synthetic distance matrices of
//! N = 100, 1,000 and 10,000 items. Prints seconds per run, totals for the paper's
//! protocol and the peak resident memory of the process.
//!
//! `cargo bench --bench kmedoids` (BENCH_N=100, 1000 or 10000 runs one size).
//!
//! The matrix: Euclidean distances of the points `((1 + i % 7) frac(i G), frac(i S))`,
//! `G = 0.618...`, `S = 0.414...` (the same as `tests/kmedoids.rs`, so that the `kmedoids`
//! Python package can be timed on the same matrix; see the README). Random starts come
//! from seeds 0, 1, ... as in `select`.
//!
//! * N = 100 and 1,000: the paper's protocol, 30 seeded runs x k = 5..12, one thread
//!   (sequential) and all threads (runs in parallel, as `select` and `reproduce` do), for
//!   FasterPAM; PAM one thread (at N = 1,000 on the first 3 seeds per k: a full protocol
//!   takes minutes).
//! * N = 10,000: FasterPAM, one run per k = 5..20 (all threads); PAM: one SWAP iteration
//!   at k = 5 and k = 20 (`max_iter(1)`: `k (n - k)` exchanges of `O(n)` each; a full PAM
//!   run needs tens of them).

use brdf_basis::cluster::{KMedoidsAlgorithm, KMedoidsInit, KMedoidsParams};
use brdf_basis::distance::DistanceMatrix;
use rayon::prelude::*;
use std::time::Instant;

fn synthetic(n: usize) -> DistanceMatrix {
    let (g, s) = (0.6180339887498949f64, 0.41421356237309503f64);
    let p: Vec<(f64, f64)> = (0..n)
        .map(|i| {
            let (x, y) = (i as f64 * g, i as f64 * s);
            ((1 + i % 7) as f64 * (x - x.floor()), y - y.floor())
        })
        .collect();
    let data: Vec<f64> = (0..n * n)
        .into_par_iter()
        .map(|ij| {
            let (a, b) = (p[ij / n], p[ij % n]);
            let (dx, dy) = (a.0 - b.0, a.1 - b.1);
            (dx * dx + dy * dy).sqrt()
        })
        .collect();
    DistanceMatrix::from_full((0..n).map(|i| format!("m{i}")).collect(), data).expect("matrix")
}

fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1).map(str::to_string))
        })
        .and_then(|v| v.parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// Runs `(k, seed)` jobs with `algorithm`; returns (seconds, mean loss, mean swaps).
fn protocol(
    d: &DistanceMatrix,
    jobs: &[(usize, u64)],
    algorithm: KMedoidsAlgorithm,
    max_iter: usize,
    parallel: bool,
) -> (f64, f64, f64) {
    let one = |&(k, seed): &(usize, u64)| {
        let r = KMedoidsParams::new(k)
            .algorithm(algorithm)
            .max_iter(max_iter)
            .seed(seed)
            .init(KMedoidsInit::Random)
            .fit(d)
            .expect("fit");
        (r.loss, r.iterations as f64)
    };
    let t = Instant::now();
    let out: Vec<(f64, f64)> = if parallel {
        jobs.par_iter().map(one).collect()
    } else {
        jobs.iter().map(one).collect()
    };
    let s = t.elapsed().as_secs_f64();
    let m = out.len() as f64;
    (
        s,
        out.iter().map(|o| o.0).sum::<f64>() / m,
        out.iter().map(|o| o.1).sum::<f64>() / m,
    )
}

fn jobs(ks: std::ops::RangeInclusive<usize>, runs: u64) -> Vec<(usize, u64)> {
    ks.flat_map(|k| (0..runs).map(move |s| (k, s))).collect()
}

fn report(n: usize, what: &str, jobs: usize, (s, loss, swaps): (f64, f64, f64)) {
    println!(
        "kmedoids N={n:<6} {what:<44} {jobs:>4} runs {s:>9.3} s  ({:>9.4} s/run)  mean loss {loss:.6e}  mean swaps {swaps:.1}  peak RSS {:.0} MB",
        s / jobs as f64,
        peak_rss_mb()
    );
}

fn main() {
    let only: Option<usize> = std::env::var("BENCH_N").ok().and_then(|v| v.parse().ok());
    let threads = rayon::current_num_threads();
    for n in [100usize, 1000, 10_000] {
        if only.is_some_and(|o| o != n) {
            continue;
        }
        let t = Instant::now();
        let d = synthetic(n);
        println!(
            "kmedoids N={n:<6} matrix {:.3} s, peak RSS {:.0} MB",
            t.elapsed().as_secs_f64(),
            peak_rss_mb()
        );
        let fp = KMedoidsAlgorithm::FasterPam;
        let pam = KMedoidsAlgorithm::Pam;
        if n <= 1000 {
            let all = jobs(5..=12, 30);
            let seq = protocol(&d, &all, fp, 100, false);
            report(n, "FasterPAM, 30 runs x k 5..12, 1 thread", all.len(), seq);
            let par = protocol(&d, &all, fp, 100, true);
            let what = format!("FasterPAM, 30 runs x k 5..12, {threads} threads");
            report(n, &what, all.len(), par);
            let pam_jobs = if n == 100 {
                all.clone()
            } else {
                jobs(5..=12, 3)
            };
            let p = protocol(&d, &pam_jobs, pam, 100, false);
            report(n, "PAM, 1 thread", pam_jobs.len(), p);
            println!(
                "kmedoids N={n:<6} PAM / FasterPAM time per run (1 thread): {:.1}x",
                (p.0 / pam_jobs.len() as f64) / (seq.0 / all.len() as f64)
            );
        } else {
            let all = jobs(5..=20, 1);
            let what = format!("FasterPAM, 1 run x k 5..20, {threads} threads");
            let r = protocol(&d, &all, fp, 100, true);
            report(n, &what, all.len(), r);
            for k in [5, 20] {
                let what = format!("PAM, one SWAP iteration, k = {k}");
                report(n, &what, 1, protocol(&d, &[(k, 0)], pam, 1, false));
            }
        }
    }
}
