//! Acquisition (SPEC 10) on the 100 Ngan materials: planning n = 20 for a 12-material basis
//! and the 88 other materials (error criterion, 10,000 candidates per step screened with
//! the best 32 and a random 200 fitted exactly, one path and 4 restarts sharing them, and the prototype's 200 per step all fitted
//! exactly; condition; random), `fit --samples` of 20 samples, and the acquisition cross-validation (greedy
//! k = 12, 3 plans x n = 5, 10, 20, noise-free). Wall and CPU seconds (on a shared machine
//! the CPU time over the core count bounds the wall time), quality beside time.
//!
//! `cargo bench --bench acquisition` (`BENCH_QUICK=1`: skip the cross-validation)

use brdf_basis::acquire::cell_candidates;
use brdf_basis::acquire::{
    acquisition_cv, fit_samples, plan, AcqCvParams, Criterion, PlanParams, Sample,
};
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::weighted::TargetWeight;
use brdf_basis::collection::Collection;
use brdf_basis::fit::FitParams;
use std::path::Path;
use std::time::Instant;

/// CPU time of the process (user + system, Linux `/proc/self/stat`, 10 ms ticks).
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

fn timed<T>(f: impl FnOnce() -> T) -> (T, String) {
    let (t, c) = (Instant::now(), cpu_secs());
    let r = f();
    (
        r,
        format!(
            "{:.3} s wall, {:.3} s CPU",
            t.elapsed().as_secs_f64(),
            cpu_secs() - c
        ),
    )
}

fn main() {
    let path = Path::new("../shared/data/ngan2005_ashikhmin_shirley.csv");
    let Ok(coll) = Collection::load(path) else {
        println!("SKIP (no {})", path.display());
        return;
    };
    let be = CpuBackend::new();
    let basis: Vec<usize> = (0..12).collect();
    let targets: Vec<usize> = (12..coll.len()).collect();
    let all: Vec<usize> = (0..coll.len()).collect();
    let cands = cell_candidates(&coll, &all, &FitParams::default()).expect("candidates");
    // The default search (10,000 candidates per step screened, the best 32 and a random
    // 200 fitted exactly), then the prototype's (200 per step, all fitted exactly).
    let runs = [
        (Criterion::Error, 10_000, 32, 1),
        (Criterion::Error, 10_000, 32, 4),
        (Criterion::Error, 200, 0, 1),
        (Criterion::Condition, 10_000, 32, 1),
        (Criterion::Random, 10_000, 32, 1),
    ];
    for (i, (crit, per_step, shortlist, restarts)) in runs.into_iter().enumerate() {
        let p = PlanParams {
            n: 20,
            criterion: crit,
            candidates_per_step: per_step,
            shortlist,
            restarts,
            fit: brdf_basis::fit::FitParams {
                objective: TargetWeight::L2,
                ..Default::default()
            },
            ..PlanParams::default()
        };
        let (pl, t) = timed(|| plan(&be, &coll, &basis, &targets, &cands, &p).expect("plan"));
        println!(
            "plan {:<9} n = 20, k = 12, {} training, {} path(s) of {} of {} candidates per step: {t}; mean training rho {:.4}",
            crit.as_str(),
            targets.len(),
            restarts,
            pl.candidates_per_step,
            pl.candidates,
            pl.history.last().copied().unwrap_or(f64::NAN)
        );
        if i == 0 {
            let samples: Vec<Sample> = pl
                .chosen
                .iter()
                .map(|c| Sample {
                    wi: c.wi,
                    wo: c.wo,
                    rgb: brdf_basis::acquire::material_at(&coll.materials()[50], c.wi, c.wo)
                        .expect("value"),
                    sigma: None,
                    line: 0,
                })
                .collect();
            let reps = 100;
            let (f, t) = timed(|| {
                let mut last = None;
                for _ in 0..reps {
                    last = Some(
                        fit_samples(
                            &coll,
                            &basis,
                            &samples,
                            brdf_basis::backend::weighted::TargetWeight::L2,
                        )
                        .expect("fit"),
                    );
                }
                last.expect("one fit")
            });
            println!(
                "fit --samples (20 samples, k = 12), {reps} times: {t}; relative residual on the samples {:.3e}",
                f.relative_residual
            );
        }
    }
    if std::env::var_os("BENCH_QUICK").is_some() {
        return;
    }
    let p = AcqCvParams {
        noises: vec![0.0],
        objective: brdf_basis::select::ObjectiveParams::default().objective(TargetWeight::L2),
        ..AcqCvParams::default()
    };
    let (r, t) = timed(|| acquisition_cv(&be, &coll, &p).expect("cv"));
    println!("cv --acquisition (greedy k = 12, 3 plans x n = 5, 10, 20, 5 folds): {t}");
    print!("{}", r.markdown());
}
