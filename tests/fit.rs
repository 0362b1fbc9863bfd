//! NNLS fits: hand-made problems, both solvers against an exact f64 solve on the grid,
//! GPU Gram against CPU, the rank-deficient leave-one-out problem.

use crate::common::*;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::weighted::TargetWeight;
use brdf_basis::backend::Backend;
use brdf_basis::collection::{parse_csv, Collection};
use brdf_basis::fit::*;
use brdf_basis::nnls::{lawson_hanson, GramProblem};
use brdf_basis::select::{empirical, EmpiricalParams};
use std::path::Path;

/// The paper's kmedoids5 basis (Table I), by Ngan names.
const BASIS5: [&str; 5] = [
    "blue-acrylic",
    "acrylic-yellow",
    "alumina-oxide",
    "cherry-235",
    "steel",
];

fn idx(c: &Collection, names: &[&str]) -> Vec<usize> {
    names.iter().map(|n| c.index_of(n).expect("name")).collect()
}

#[test]
fn recovers_an_exact_combination() {
    let csv = "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n\
               lobe,0,0,0,1,1,1,0.2,300\n\
               other,0,0,0,1,1,1,0.9,3\n\
               target,0.3,0.1,0.0,0.5,0.25,0.0,0.2,300\n";
    let c = parse_csv(csv.as_bytes(), Path::new("t.csv")).expect("csv");
    let p = FitParams {
        stride: 3,
        objective: TargetWeight::L2,
        ..Default::default()
    };
    let f = &fit(&CpuBackend::new(), &c, &[0, 1], &[2], &p, &|_, _| {}).expect("fit")[0];
    let want = [[0.3, 0.1, 0.0], [0.5, 0.25, 0.0], [0.0, 0.0, 0.0]];
    for (k, w) in want.iter().enumerate() {
        for (ch, &wc) in w.iter().enumerate() {
            // The Gram matrix carries f32 rounding of the tabulated values (~1e-7
            // relative), which near-collinear columns amplify: 1e-4 absolute.
            assert!(
                (f.coefficients[k][ch] - wc).abs() < 1e-4,
                "coef {k} {ch}: {:?}",
                f.coefficients
            );
        }
    }
    assert!(f.mae < 1e-5, "mae {}", f.mae);
    assert!(
        f.coefficients[2].iter().all(|&a| a < 1e-4),
        "the unused material stays ~0: {:?}",
        f.coefficients
    );
}

#[test]
fn zero_target_and_lambertian_tie() {
    // `flat` has s = 0: it is a multiple of the Lambertian column; the tie goes to the
    // Lambertian term. `black` is zero everywhere: every coefficient is 0.
    let csv = "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n\
               flat,0.5,0.5,0.5,0,0,0,0.5,10\n\
               shiny,0,0,0,1,1,1,0.5,100\n\
               grey,0.2,0.2,0.2,0,0,0,0.5,10\n\
               black,0,0,0,0,0,0,0.5,10\n";
    let c = parse_csv(csv.as_bytes(), Path::new("t.csv")).expect("csv");
    let p = FitParams {
        stride: 4,
        objective: TargetWeight::L2,
        ..Default::default()
    };
    let f = fit(&CpuBackend::new(), &c, &[0, 1], &[2, 3], &p, &|_, _| {}).expect("fit");
    for ch in 0..3 {
        assert!(
            (f[0].coefficients[0][ch] - 0.2).abs() < 1e-6,
            "{:?}",
            f[0].coefficients
        );
        assert_eq!(
            f[0].coefficients[1][ch], 0.0,
            "tie goes to the Lambertian term"
        );
        assert!(
            f[1].coefficients.iter().all(|a| a[ch] == 0.0),
            "{:?}",
            f[1].coefficients
        );
    }
}

/// Exact f64 reference: Gram in f64 from f64 values, Lawson-Hanson, objective on the grid.
fn reference_objective(
    c: &Collection,
    basis: &[usize],
    t: usize,
    ch: usize,
    cells: &brdf_basis::merl::CellSet,
) -> (f64, f64) {
    let cpu = CpuBackend::new();
    let mut cols = vec![cpu.values_f64(&LAMBERTIAN, &cells.cells)];
    cols.extend(
        basis
            .iter()
            .map(|&b| cpu.values_f64(&channel_lobe(&c.materials()[b].data, ch), &cells.cells)),
    );
    let b = cpu.values_f64(&channel_lobe(&c.materials()[t].data, ch), &cells.cells);
    let m = cols.len();
    let mut g = vec![0.0; m * m];
    let mut h = vec![0.0; m];
    for i in 0..m {
        for j in 0..m {
            g[i * m + j] = cols[i]
                .iter()
                .zip(&cols[j])
                .zip(&cells.weights)
                .map(|((x, y), w)| w * x * y)
                .sum();
        }
        h[i] = cols[i]
            .iter()
            .zip(&b)
            .zip(&cells.weights)
            .map(|((x, y), w)| w * x * y)
            .sum();
    }
    let bb: f64 = b.iter().zip(&cells.weights).map(|(x, w)| w * x * x).sum();
    let x = lawson_hanson::solve(
        &GramProblem::new(m, &g, &h, bb).expect("problem"),
        &Default::default(),
    )
    .expect("lh")
    .x;
    let obj: f64 = (0..b.len())
        .map(|s| {
            let r: f64 = cols.iter().zip(&x).map(|(col, a)| a * col[s]).sum::<f64>() - b[s];
            cells.weights[s] * r * r
        })
        .sum();
    (obj, bb)
}

fn check_solvers_on(c: &Collection, backend: &dyn Backend, gram: GramMode) {
    let basis = idx(c, &BASIS5);
    let targets: Vec<usize> = (0..c.len()).filter(|i| !basis.contains(i)).collect();
    for solver in [Solver::Exact, Solver::Pgd] {
        let p = FitParams {
            solver,
            gram,
            objective: TargetWeight::L2,
            ..Default::default()
        };
        let fits = fit(backend, c, &basis, &targets, &p, &|_, _| {}).expect("fit");
        let cells = fit_cells(c, &(0..c.len()).collect::<Vec<_>>(), &p).expect("cells");
        let mut worst = 0f64;
        let mut worst_kkt = 0f64;
        for (f, &t) in fits.iter().zip(&targets).step_by(3) {
            for ch in 0..3 {
                let (opt, energy) = reference_objective(c, &basis, t, ch, &cells);
                let excess = (f.residual[ch].powi(2) - opt) / energy;
                worst = worst.max(excess);
                assert!(
                    excess <= 1e-6,
                    "{} {solver:?} channel {ch}: excess {excess:e}",
                    f.material
                );
                worst_kkt = worst_kkt.max(f.kkt[ch]);
                // Exact: 1e-8. PGD: the GPU kernel is f32 (KKT ~1e-6); anything above
                // PGD_FALLBACK_KKT is re-solved exactly, so that is the bound.
                let tol = if solver == Solver::Exact {
                    1e-8
                } else {
                    PGD_FALLBACK_KKT
                };
                assert!(
                    f.kkt[ch] <= tol,
                    "{} {solver:?}: KKT {:e}",
                    f.material,
                    f.kkt[ch]
                );
            }
        }
        eprintln!(
            "{} {gram:?} {solver:?}: worst objective excess {worst:e} x energy, worst KKT {worst_kkt:e}",
            backend.name()
        );
    }
}

#[test]
fn both_solvers_reach_the_exact_optimum_on_the_grid() {
    let Some(c) = ngan_or_skip("both_solvers_reach_the_exact_optimum_on_the_grid") else {
        return;
    };
    check_solvers_on(&c, &CpuBackend::new(), GramMode::Auto);
    check_solvers_on(&c, &CpuBackend::new(), GramMode::Grid);
    if let Some(g) = gpu("both_solvers_reach_the_exact_optimum_on_the_grid (gpu)") {
        check_solvers_on(&c, g, GramMode::Grid);
    }
}

#[test]
fn gpu_gram_matches_cpu_gram() {
    let Some(g) = gpu("gpu_gram_matches_cpu_gram") else {
        return;
    };
    let Some(c) = ngan_or_skip("gpu_gram_matches_cpu_gram") else {
        return;
    };
    let p = FitParams {
        objective: TargetWeight::L2,
        ..FitParams::default()
    };
    let cells = fit_cells(&c, &(0..c.len()).collect::<Vec<_>>(), &p).expect("cells");
    let basis = idx(&c, &BASIS5);
    let targets: Vec<usize> = (0..40).collect();
    for ch in 0..3 {
        let brdf_basis::fit::ChannelGram {
            gram: gg,
            h: hg,
            bb: bg,
        } = channel_gram(
            g,
            &c,
            &basis,
            &targets,
            &cells,
            ch,
            GramMode::Grid,
            &|_, _| {},
        )
        .expect("gpu");
        let brdf_basis::fit::ChannelGram {
            gram: gc,
            h: hc,
            bb: bc,
        } = channel_gram(
            &CpuBackend::new(),
            &c,
            &basis,
            &targets,
            &cells,
            ch,
            GramMode::Grid,
            &|_, _| {},
        )
        .expect("cpu");
        assert!(max_rel(&gg, &gc, 1e-300) <= 1e-4, "G");
        assert!(max_rel(&hg, &hc, 1e-300) <= 1e-4, "h");
        assert!(max_rel(&bg, &bc, 1e-300) <= 1e-4, "bb");
    }
}

#[test]
fn empirical_selection_copes_with_the_rank_deficient_gram_of_all_materials() {
    let Some(c) =
        ngan_or_skip("empirical_selection_copes_with_the_rank_deficient_gram_of_all_materials")
    else {
        return;
    };
    let p = EmpiricalParams {
        fit: FitParams {
            stride: 2,
            objective: TargetWeight::L2,
            ..Default::default()
        },
        more_than: 5,
    };
    let e = empirical(&CpuBackend::new(), &c, &p, &|_, _| {}).expect("empirical");
    assert_eq!(e.histogram.len(), 100);
    // Leave-one-out: a target never contributes to its own fit, and the histogram counts
    // the contributor lists.
    assert_eq!(e.contributors.len(), 100);
    for (target, v) in &e.contributors {
        assert!(!v.contains(target), "{target} fitted by itself");
    }
    for (name, &count) in &e.histogram {
        let listed = e.contributors.values().filter(|v| v.contains(name)).count();
        assert_eq!(listed, count, "{name}");
    }
    // Every target is fitted by few materials (the paper: at most 5 for all but one).
    let most = e.contributors.values().map(|v| v.len()).max().unwrap_or(0);
    assert!((1..40).contains(&most), "{most}");
    assert!(!e.basis.is_empty());
    for b in &e.basis {
        assert!(e.histogram[b] > 5);
    }
    // Deterministic.
    let again = empirical(&CpuBackend::new(), &c, &p, &|_, _| {}).expect("again");
    assert_eq!(again.counts, e.counts);
}

#[test]
fn rejects_bad_fits() {
    let Some(c) = ngan_or_skip("rejects_bad_fits") else {
        return;
    };
    let cpu = CpuBackend::new();
    let p = FitParams {
        stride: 6,
        objective: TargetWeight::L2,
        ..Default::default()
    };
    assert!(matches!(
        fit(&cpu, &c, &[], &[1], &p, &|_, _| {}),
        Err(FitError::EmptyBasis)
    ));
    assert!(matches!(
        fit(&cpu, &c, &[1], &[], &p, &|_, _| {}),
        Err(FitError::NoTargets)
    ));
    let e = fit(&cpu, &c, &[1, 1], &[2], &p, &|_, _| {})
        .expect_err("dup")
        .to_string();
    assert!(e.contains("twice"), "{e}");
    let big: Vec<usize> = (0..99).collect();
    let pg = FitParams {
        solver: Solver::Pgd,
        ..p.clone()
    };
    assert!(
        fit(&cpu, &c, &big, &[99], &pg, &|_, _| {}).is_ok(),
        "99 columns is within the PGD limit"
    );
    // Non-finite measured data.
    let mut rgb = vec![0.1f32; 3 * brdf_basis::merl::N_CELLS];
    rgb[brdf_basis::merl::flat(10, 10, 10)] = f32::INFINITY;
    let mut m = Collection::new();
    m.push(c.materials()[0].clone(), Path::new("x"), 0)
        .expect("push");
    m.push(
        brdf_basis::collection::Material {
            name: "nan-table".into(),
            data: brdf_basis::collection::MaterialData::Measured(std::sync::Arc::new(
                brdf_basis::merl::MerlTable { rgb },
            )),
            origin: "test".into(),
        },
        Path::new("x"),
        0,
    )
    .expect("push");
    let p1 = FitParams {
        stride: 1,
        objective: TargetWeight::L2,
        ..Default::default()
    };
    let e = fit(&cpu, &m, &[0], &[1], &p1, &|_, _| {})
        .expect_err("nan")
        .to_string();
    assert!(e.contains("nan-table") && e.contains("non-finite"), "{e}");
}

#[test]
fn separable_gram_matches_the_grid_pass() {
    // The closed form (f64, exact) against the CPU grid pass (f32 values, f64 partials).
    let Some(c) = ngan_or_skip("separable_gram_matches_the_grid_pass") else {
        return;
    };
    for weighting in [
        brdf_basis::merl::Weighting::Uniform,
        brdf_basis::merl::Weighting::SolidAngle,
    ] {
        let p = FitParams {
            weighting,
            stride: 2,
            objective: TargetWeight::L2,
            ..Default::default()
        };
        let cells = fit_cells(&c, &(0..c.len()).collect::<Vec<_>>(), &p).expect("cells");
        let basis = idx(&c, &BASIS5);
        let targets: Vec<usize> = (0..c.len()).collect();
        for ch in 0..3 {
            let cpu = CpuBackend::new();
            let a = channel_gram(
                &cpu,
                &c,
                &basis,
                &targets,
                &cells,
                ch,
                GramMode::Auto,
                &|_, _| {},
            )
            .expect("separable");
            let b = channel_gram(
                &cpu,
                &c,
                &basis,
                &targets,
                &cells,
                ch,
                GramMode::Grid,
                &|_, _| {},
            )
            .expect("grid");
            // f32 rounding of the tabulated values bounds the agreement: 1e-5 relative.
            assert!(max_rel(&a.gram, &b.gram, 1e-300) <= 1e-5, "G {weighting:?}");
            assert!(max_rel(&a.h, &b.h, 1e-300) <= 1e-5, "h {weighting:?}");
            assert!(max_rel(&a.bb, &b.bb, 1e-300) <= 1e-5, "bb {weighting:?}");
        }
    }
}

/// A mixed collection: analytic rows of the embedded default, a measured copy of one, and
/// seeded neural networks.
fn mixed_collection(nets: usize) -> Collection {
    use brdf_basis::brdf::{Nbrdf, NBRDF_WEIGHTS};
    use brdf_basis::collection::{Material, MaterialData};
    use rand::Rng;
    let base = Collection::embedded_default();
    let mut c = Collection::new();
    let mut add = |m: Material| c.push(m, Path::new("<test>"), 0).expect("unique names");
    for i in [0, 7, 19] {
        add(base.materials()[i].clone());
    }
    let mut copy = measured_material(&base.materials()[30]);
    copy.name = format!("measured-{}", copy.name);
    add(copy);
    let mut r = rng(11);
    for i in 0..nets {
        let w: Vec<f32> = (0..NBRDF_WEIGHTS)
            .map(|_| r.random_range(-0.6f32..0.6))
            .collect();
        add(Material {
            name: format!("net-{i}"),
            data: MaterialData::Neural(std::sync::Arc::new(Nbrdf::from_weights(w).expect("w"))),
            origin: "seeded".into(),
        });
    }
    c
}

/// The Gram matrices of a collection from one pass for the three channels
/// (`CollectionGrams::grid`) equal, bit for bit, one pass per channel of the same back-end
/// (what the objective, the empirical selection and the fits made before sharing them), and
/// the fit quantities read from them equal `channel_gram`'s pass over a basis and targets.
fn shared_grams_equal_per_channel_passes(backend: &dyn Backend) {
    let c = mixed_collection(6);
    let n = c.len();
    let p = FitParams {
        stride: 5,
        objective: TargetWeight::L2,
        ..Default::default()
    };
    let shared = CollectionGrams::grid(backend, &c, &p, &|_, _| {}).expect("shared pass");
    assert!(CollectionGrams::needed(&c, p.gram));
    let all: Vec<usize> = (0..n).collect();
    let cells = fit_cells(&c, &all, &p).expect("cells");
    assert!(shared.covers(&cells));
    let (basis, targets) = ([4usize, 1, 7], [0usize, 2, 3, 5, 6, 8, 9]);
    for ch in 0..3 {
        let mut lobes = vec![LAMBERTIAN];
        lobes.extend(c.materials().iter().map(|m| channel_lobe(&m.data, ch)));
        let alone = backend
            .gram(&lobes, &cells, n + 1, &|_, _| {})
            .expect("pass");
        assert_eq!(shared.grams[ch].len(), (n + 1) * (n + 1));
        let same = shared.grams[ch]
            .iter()
            .zip(&alone)
            .all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(
            same,
            "channel {ch}: the shared pass differs from a pass of its own"
        );
        let want = channel_gram(
            backend,
            &c,
            &basis,
            &targets,
            &cells,
            ch,
            GramMode::Auto,
            &|_, _| {},
        )
        .expect("channel gram");
        let got = shared.channel_gram(&c, &basis, &targets, ch).expect("read");
        assert_eq!(got, want, "channel {ch}: fit quantities");
    }
}

#[test]
fn shared_grams_equal_per_channel_passes_cpu() {
    shared_grams_equal_per_channel_passes(&CpuBackend::new());
}

#[test]
fn shared_grams_equal_per_channel_passes_gpu() {
    if let Some(g) = gpu("shared_grams_equal_per_channel_passes_gpu") {
        shared_grams_equal_per_channel_passes(g);
    }
}
