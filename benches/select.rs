//! Basis selection by fitting error (SPEC 8): the objective's Gram matrices, greedy, swap
//! and GA on the 100 Ngan materials (with a fresh-solve greedy as the baseline of the
//! incremental evaluation), cross-validation of six methods, and greedy k = 20 on 1,000
//! synthetic materials (drawn from a fixed seed inside the bench).
//!
//! `cargo bench --bench select` (`BENCH_QUICK=1`: skip the cv and 1,000-material cases)

use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::weighted::TargetWeight;
use brdf_basis::brdf::AshikhminShirley;
use brdf_basis::collection::{Collection, Material, MaterialData};
use brdf_basis::select::cv::{cross_validate, CvParams};
use brdf_basis::select::{ga, greedy, swap, GaParams, Objective, ObjectiveParams, SearchParams};
use rand::{Rng, SeedableRng};
use std::path::Path;
use std::time::Instant;

fn secs(t: Instant) -> f64 {
    t.elapsed().as_secs_f64()
}

/// CPU time of the process (user + system, Linux `/proc/self/stat`, 10 ms ticks): on a
/// shared machine the wall time says little, the CPU time over the core count bounds it.
fn cpu_secs() -> f64 {
    std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            let rest = s.rsplit(')').next()?.to_string();
            let f: Vec<&str> = rest.split_whitespace().collect();
            let u: f64 = f.get(11)?.parse().ok()?;
            let k: f64 = f.get(12)?.parse().ok()?;
            Some((u + k) / 100.0)
        })
        .unwrap_or(f64::NAN)
}

/// Wall and CPU seconds of `f`.
fn timed<T>(f: impl FnOnce() -> T) -> (T, String) {
    let (t, c) = (Instant::now(), cpu_secs());
    let r = f();
    let s = format!("{:.3} s (CPU {:.2} s)", secs(t), cpu_secs() - c);
    (r, s)
}

/// Greedy by fresh exact solves of every candidate basis (no incremental state): the
/// baseline of the incremental evaluation.
fn greedy_fresh(obj: &Objective, k: usize) -> (Vec<usize>, f64) {
    let all: Vec<usize> = (0..obj.len()).collect();
    let mut b: Vec<usize> = Vec::new();
    let mut s = f64::INFINITY;
    for _ in 0..k {
        let mut best = (f64::INFINITY, 0);
        for c in all.iter().copied().filter(|c| !b.contains(c)) {
            let mut t = b.clone();
            t.push(c);
            let sc = obj.score(&t, &all).unwrap();
            if sc < best.0 {
                best = (sc, c);
            }
        }
        b.push(best.1);
        s = best.0;
    }
    (b, s)
}

fn synthetic(n: usize, seed: u64) -> Collection {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut c = Collection::new();
    for i in 0..n {
        let d = [0, 1, 2].map(|_| rng.random::<f64>() * 0.8);
        let s = [0, 1, 2].map(|_| rng.random::<f64>());
        let a = AshikhminShirley {
            d,
            s,
            f0: 0.02 + 0.98 * rng.random::<f64>(),
            n: 10f64.powf(4.0 * rng.random::<f64>()),
        };
        c.push(
            Material {
                name: format!("synthetic-{i:04}"),
                data: MaterialData::Analytic(a),
                origin: "bench".into(),
            },
            Path::new("bench"),
            i as u64,
        )
        .expect("unique names");
    }
    c
}

fn main() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/ngan2005_ashikhmin_shirley.csv");
    let coll = Collection::load(&path).unwrap_or_else(|e| {
        eprintln!("{e}: using the embedded default collection");
        Collection::embedded_default()
    });
    let cpu = CpuBackend::new();
    let op = ObjectiveParams::default()
        .objective(TargetWeight::L2)
        .check()
        .expect("params");
    let only_big = std::env::var("BENCH_BIG").is_ok_and(|v| v == "1");
    if !only_big {
        let (obj, t) = timed(|| Objective::new(&cpu, &coll, &op, &|_, _| {}).expect("objective"));
        println!(
            "objective: Gram of {} materials x 3 channels (separable, full evaluation mask): {t}",
            coll.len()
        );
        let names = coll.names();
        for k in [5, 12] {
            let p = SearchParams::new(k).check(&names).expect("p");
            let (g, tg) = timed(|| greedy(&obj, &p, &|_, _| {}).unwrap());
            let (s, ts) = timed(|| swap(&obj, &p, &|_, _| {}).unwrap());
            println!(
                "k = {k:2}: greedy {tg} (S {:.5}); swap from scratch (greedy + {} swaps) {ts} (S {:.5})",
                g.score,
                s.history.len() - 1,
                s.score
            );
            let ((fb, fs), tf) = timed(|| greedy_fresh(&obj, k));
            println!(
                "k = {k:2}: greedy by fresh solves {tf} (S {fs:.5}, same basis: {})",
                fb == g.indices
            );
            let gp = GaParams::default().seed(1).check().expect("ga");
            let (r, tga) = timed(|| ga(&obj, &p, &gp, &|_, _| {}).unwrap());
            println!(
                "k = {k:2}: ga (population 40, 60 generations) {tga} (S {:.5})",
                r.score
            );
        }
        if std::env::var("BENCH_QUICK").is_ok_and(|v| v == "1") {
            return;
        }
        let cp = CvParams::default()
            .seed(1)
            .objective(ObjectiveParams::default().objective(TargetWeight::L2))
            .check(coll.len())
            .expect("cv");
        let (cv, t) = timed(|| cross_validate(&cpu, &coll, &cp, &|_, _| {}).expect("cv"));
        println!(
            "cv: greedy, swap, kmedoids, gcuk, empirical, random at k = 5, 12, 5 folds: {t}\n{}",
            cv.table_markdown()
        );
    }
    let big = synthetic(1000, 7);
    let (obj, tgram) = timed(|| Objective::new(&cpu, &big, &op, &|_, _| {}).expect("objective"));
    let p = SearchParams::new(20).check(&big.names()).expect("p");
    let (g, tg) = timed(|| greedy(&obj, &p, &|_, _| {}).unwrap());
    println!(
        "1,000 synthetic materials: Gram {tgram}, greedy k = 20 {tg} (S {:.5})",
        g.score
    );
}
