//! Same seed, same collection, same settings: the same results on every back-end, by the
//! determinism contract (docs/determinism.md), on any conformant driver.
//!
//! The CPU back-end and the GPU kernels sum in one canonical order (see
//! `brdf_basis::backend::cpu`), so every sum whose terms involve no multiply feeding an add
//! (L1 sums of specular lobes and of measured rows) is identical bit for bit on every
//! driver; sums of analytic lobes with a diffuse term (`beta g + alpha w` per cell) and
//! dot products (`acc + a b`), which a driver may fuse into `fma` (NVIDIA does, lavapipe
//! does not), agree within
//! `CONTRACTION_TOLERANCE`; the clustering then compares losses and fitness with a
//! relative tie margin (`cluster::TIE_TOLERANCE`) on top, and the bases, medoids and
//! orders are the same.

use crate::common::*;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::gpu::pairwise::{KernelShape, PairPlan, PairwiseKernel, PlanLimits};
use brdf_basis::backend::gpu::CONTRACTION_TOLERANCE;
use brdf_basis::backend::Backend;
use brdf_basis::backend::{all_blocks, gram_blocks, PairOp};
use brdf_basis::cluster::{GcukParams, KMedoidsAlgorithm, KMedoidsInit, KMedoidsParams};
use brdf_basis::collection::Collection;
use brdf_basis::distance::{distance_matrix, DistanceMatrix, DistanceParams, LobeKind};
use brdf_basis::merl::{CellSet, Mask, Weighting};
use std::path::Path;

/// Largest relative difference and the number of entries that differ at all.
fn compare(a: &[f64], b: &[f64]) -> (f64, usize) {
    let rel = max_rel(a, b, 1e-300);
    (rel, a.iter().zip(b).filter(|(x, y)| x != y).count())
}

/// BRDF_it of the Ngan table on the CPU and on the GPU with `p`.
fn both(
    coll: &Collection,
    gpu: &dyn Backend,
    p: DistanceParams,
) -> (DistanceMatrix, DistanceMatrix) {
    let p = p.check(coll).expect("params");
    let cpu = distance_matrix(&CpuBackend::new(), coll, &p, &|_, _| {}).expect("cpu");
    let gpu = distance_matrix(gpu, coll, &p, &|_, _| {}).expect("gpu");
    (cpu, gpu)
}

/// Asserts the contract for one comparison: identical where no multiply feeds an add
/// (`fused = false`), else within `CONTRACTION_TOLERANCE`.
fn assert_contract(what: &str, got: &[f64], want: &[f64], fused: bool) {
    let (rel, differ) = compare(got, want);
    eprintln!(
        "{what}: GPU vs CPU max relative difference {rel:e}, {differ} of {} entries differ",
        got.len()
    );
    match fused {
        false => assert_eq!(differ, 0, "{what}: max relative difference {rel:e}"),
        true => assert!(
            rel <= CONTRACTION_TOLERANCE,
            "{what}: max relative difference {rel:e} above the contract's {CONTRACTION_TOLERANCE:e}"
        ),
    }
}

#[test]
fn cpu_and_gpu_brdf_it_of_the_ngan_table_agree_by_the_contract() {
    let Some(g) = gpu("cpu_and_gpu_brdf_it_of_the_ngan_table_agree_by_the_contract") else {
        return;
    };
    let Some(ngan) = ngan_or_skip("cpu_and_gpu_brdf_it_of_the_ngan_table_agree_by_the_contract")
    else {
        return;
    };
    for (what, p, fused) in [
        (
            "BRDF_it specular, evaluation mask, uniform",
            DistanceParams::default(),
            false,
        ),
        (
            "BRDF_it full lobe, valid cells, solid angle",
            DistanceParams::default()
                .lobe(LobeKind::Full)
                .mask(Mask::Valid)
                .weighting(Weighting::SolidAngle),
            true,
        ),
    ] {
        let (c, gm) = both(&ngan, g, p);
        assert_contract(what, gm.as_full(), c.as_full(), fused);
    }
}

#[test]
fn every_kernel_shape_sums_in_the_canonical_order() {
    // Each kernel shape (the hardware ones included, run here on whatever adapter this
    // is) gives the CPU back-end's sums bit for bit for specular lobes, and within the
    // contract's tolerance for full lobes (a diffuse term: multiply-adds a driver may
    // fuse), for L1 and dot products.
    let Some(g) = gpu("every_kernel_shape_sums_in_the_canonical_order") else {
        return;
    };
    let Some(ngan) = ngan_or_skip("every_kernel_shape_sums_in_the_canonical_order") else {
        return;
    };
    let coll = ngan.subset(&(0..37).collect::<Vec<_>>());
    for kind in [LobeKind::Specular, LobeKind::Full] {
        shapes_against_cpu(g, &coll, kind);
    }
}

fn shapes_against_cpu(g: &brdf_basis::backend::gpu::GpuBackend, coll: &Collection, kind: LobeKind) {
    let lobes = brdf_basis::distance::lobes(coll, kind);
    let cells = CellSet::new(Mask::Evaluation, Weighting::SolidAngle, 3);
    let ctx = g.context();
    let kernel = PairwiseKernel::new();
    let cpu = CpuBackend::new();
    for (op, blocks) in [
        (PairOp::L1, all_blocks(lobes.len())),
        (PairOp::Dot, gram_blocks(lobes.len(), 6)),
    ] {
        let want = cpu
            .reduce_pairs(&lobes, &cells, &blocks, op, &|_, _| {})
            .expect("cpu");
        for shape in KernelShape::all() {
            let plan = PairPlan::new(lobes.len(), 0, cells.len(), &PlanLimits::of(ctx), shape)
                .expect("plan");
            let got = kernel
                .run(ctx, &lobes, &cells, &blocks, op, &plan, &|_, _| {})
                .expect("gpu");
            // Fusable: the full lobe's rows (beta g + alpha w) and every dot product's
            // accumulation (acc + a b); a specular lobe's L1 sums have no multiply-add.
            let fused = kind == LobeKind::Full || op == PairOp::Dot;
            assert_contract(&format!("{kind:?} {op:?} {shape:?}"), &got, &want, fused);
        }
    }
}

#[test]
fn clustering_runs_are_identical_on_both_back_ends() {
    // The paper's protocol on BRDF_it of the Ngan table: k-medoids 30 runs x k = 5..12
    // (FasterPAM and PAM) and GCUK 30 runs: the same medoids, labels, losses and DB.
    let Some(g) = gpu("clustering_runs_are_identical_on_both_back_ends") else {
        return;
    };
    let Some(ngan) = ngan_or_skip("clustering_runs_are_identical_on_both_back_ends") else {
        return;
    };
    let (c, gm) = both(&ngan, g, DistanceParams::default());
    let mut runs = 0;
    for algorithm in [KMedoidsAlgorithm::FasterPam, KMedoidsAlgorithm::Pam] {
        for k in 5..=12 {
            for seed in 0..30 {
                let p = KMedoidsParams::new(k)
                    .algorithm(algorithm)
                    .seed(seed)
                    .init(KMedoidsInit::Random);
                let (a, b) = (p.fit(&c).expect("cpu"), p.fit(&gm).expect("gpu"));
                assert_eq!(a, b, "{algorithm} k {k} seed {seed}");
                runs += 1;
            }
        }
    }
    for seed in 0..30 {
        let p = GcukParams::default().seed(seed);
        assert_eq!(
            p.fit(&c).expect("cpu"),
            p.fit(&gm).expect("gpu"),
            "GCUK seed {seed}"
        );
        runs += 1;
    }
    eprintln!("{runs} clustering runs identical on both back-ends");
}

/// Whether `line` gives a duration: a number followed by `s` or `ms` (`12.5 s`, `80ms`).
fn has_duration(line: &str) -> bool {
    let b = line.as_bytes();
    (0..b.len()).any(|i| {
        if !b[i].is_ascii_digit()
            || b.get(i + 1)
                .is_some_and(|c| c.is_ascii_digit() || *c == b'.')
        {
            return false;
        }
        let mut j = i + 1;
        while b.get(j) == Some(&b' ') {
            j += 1;
        }
        let unit = if b.get(j) == Some(&b'm') { j + 1 } else { j };
        b.get(unit) == Some(&b's') && !b.get(unit + 1).is_some_and(|c| c.is_ascii_alphanumeric())
    })
}

/// Lines of a text output with the back-end's name and timings masked.
fn masked(text: &str) -> Vec<String> {
    // Inside a Markdown section named for timings every line is a duration.
    let mut in_timings = false;
    text.lines()
        .map(|l| {
            let lower = l.to_lowercase();
            if lower.starts_with('#') {
                in_timings = lower.contains("timing");
            }
            let named = ["back-end", "backend", "elapsed", "timing", "seconds"]
                .iter()
                .any(|t| lower.contains(t));
            if named || in_timings || has_duration(&lower) {
                "<masked>".to_string()
            } else {
                l.to_string()
            }
        })
        .collect()
}

#[test]
fn masking_hides_back_end_and_timing_lines_only() {
    assert!(has_duration("distances: 12.5 s") && has_duration("(80ms)"));
    assert!(!has_duration("k = 5, 30 runs") && !has_duration("3 materials"));
    let m = masked("back-end: cpu\nDB 0.51\ntook 3.2 s\n5 runs");
    assert_eq!(m, ["<masked>", "DB 0.51", "<masked>", "5 runs"]);
    let t = masked("## Timings\n\n| distances | 1.58 |\n## Bases\n| b | 0.5 |");
    assert_eq!(
        t,
        [
            "<masked>",
            "<masked>",
            "<masked>",
            "## Bases",
            "| b | 0.5 |"
        ]
    );
}

/// Every file under `dir`, relative paths, sorted.
fn files(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("read dir") {
            let p = e.expect("entry").path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p.strip_prefix(dir).expect("prefix").to_path_buf());
            }
        }
    }
    out.sort();
    out
}

#[test]
fn reproduce_writes_the_same_outputs_with_the_cpu_and_the_gpu() {
    const TEST: &str = "reproduce_writes_the_same_outputs_with_the_cpu_and_the_gpu";
    let Some(csv) = shared_or_skip("ngan2005_ashikhmin_shirley.csv", TEST) else {
        return;
    };
    if gpu(TEST).is_none() {
        return;
    }
    let dir = tmp();
    let run = |backend: &str| {
        let out = dir.path().join(backend);
        let o = bin()
            .args(["--quiet", "--backend", backend, "--seed", "3", "reproduce"])
            .arg(&csv)
            .args([
                "--runs",
                "10",
                "--render-size",
                "32",
                "--no-appearance",
                "--out",
            ])
            .arg(&out)
            .output()
            .expect("run");
        assert!(
            o.status.success(),
            "{backend}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        out
    };
    let (c, g) = (run("cpu"), run("gpu"));
    let names = files(&c);
    assert_eq!(names, files(&g), "the same files");
    assert!(names.iter().any(|n| n.ends_with("report.md")));
    for name in &names {
        let (a, b) = (c.join(name), g.join(name));
        let ext = name.extension().and_then(|e| e.to_str()).unwrap_or("");
        match ext {
            "md" | "json" | "csv" | "txt" => {
                let (ta, tb) = (
                    std::fs::read_to_string(&a).expect("read"),
                    std::fs::read_to_string(&b).expect("read"),
                );
                assert_eq!(masked(&ta), masked(&tb), "{}", name.display());
            }
            // EXR chunk order is the writer's: compare the pixels.
            "exr" => assert_eq!(
                brdf_basis::io::image::read_exr(&a).expect("exr"),
                brdf_basis::io::image::read_exr(&b).expect("exr"),
                "{}",
                name.display()
            ),
            _ => assert!(
                std::fs::read(&a).expect("read") == std::fs::read(&b).expect("read"),
                "{} differs",
                name.display()
            ),
        }
    }
}
