//! GPU kernels against independent references: the f64 model from directions and the CPU
//! back-end. Tolerances are written next to each assertion.

use crate::common::*;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::gpu::pairwise::{
    KernelShape, PairPlan, PlanLimits, MAX_PACKED_BYTES, MAX_RUN_ITERS,
};
use brdf_basis::backend::gpu::TEX_W;
use brdf_basis::backend::weighted::TargetWeight;
use brdf_basis::backend::{Backend, Lobe};
use brdf_basis::brdf::rho_s_angles;
use brdf_basis::brdf::LobeParams;
use brdf_basis::merl::{cell_directions, cell_info, N_CELLS};
use brdf_basis::merl::{CellSet, Mask, Weighting};
use rayon::prelude::*;

/// Per valid cell: (cell, theta_h, cos_d, max_cos), all from the sample directions in f64.
fn valid_geometry() -> Vec<(u32, f64, f64, f64)> {
    (0..N_CELLS as u32)
        .into_par_iter()
        .filter(|&c| cell_info(c as usize).valid)
        .map(|c| {
            let (wi, wo) = cell_directions(c as usize);
            let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
            let l = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
            let h = [h[0] / l, h[1] / l, h[2] / l];
            let th = h[0].hypot(h[1]).atan2(h[2]);
            let cos_d = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
            (c, th, cos_d, wi[2].max(wo[2]))
        })
        .collect()
}

#[test]
fn gpu_tabulation_of_every_ngan_material_matches_the_f64_model() {
    let Some(gpu) = gpu("gpu_tabulation_of_every_ngan_material_matches_the_f64_model") else {
        return;
    };
    let Some(coll) = ngan_or_skip("gpu_tabulation_of_every_ngan_material_matches_the_f64_model")
    else {
        return;
    };
    let geo = valid_geometry();
    let cells: Vec<u32> = geo.iter().map(|g| g.0).collect();
    let mut worst = 0f64;
    let mats: Vec<_> = coll
        .materials()
        .iter()
        .map(|m| *m.analytic().expect("analytic"))
        .collect();
    for batch in mats.chunks(10) {
        // Full RGB BRDF: three lobes (d_c, s_c, F0, n) per material.
        let lobes: Vec<Lobe> = batch
            .iter()
            .flat_map(|a| {
                (0..3).map(move |c| {
                    Lobe::Analytic(LobeParams {
                        kd: a.d[c] as f32,
                        ks: a.s[c] as f32,
                        f0: a.f0 as f32,
                        n: a.n as f32,
                    })
                })
            })
            .collect();
        let vals = gpu.tabulate(&lobes, &cells).expect("gpu tabulate");
        let w = lobes
            .par_iter()
            .enumerate()
            .map(|(l, lobe)| {
                let Lobe::Analytic(p) = lobe else {
                    unreachable!()
                };
                let a = &batch[l / 3];
                let (d, s) = (a.d[l % 3], a.s[l % 3]);
                let mut worst = 0f64;
                for (c, g) in geo.iter().enumerate() {
                    let want =
                        d / std::f64::consts::PI + s * rho_s_angles(g.1, g.2, g.3, a.f0, a.n);
                    let got = vals[l * cells.len() + c] as f64;
                    assert!(got.is_finite(), "non-finite at cell {}", g.0);
                    if want >= 1e-6 {
                        let rel = (got - want).abs() / want;
                        assert!(
                            rel <= 1e-4,
                            "material n={} lobe {l} cell {}: {got} vs {want} (rel {rel:e})",
                            p.n,
                            g.0
                        );
                        worst = worst.max(rel);
                    }
                }
                worst
            })
            .reduce(|| 0.0, f64::max);
        worst = worst.max(w);
    }
    eprintln!("gpu tabulation: worst relative error {worst:e} (tolerance 1e-4)");
}

#[test]
fn cpu_tabulation_matches_gpu_twin_and_model() {
    // The CPU back-end evaluates in f64 and rounds once: 1e-6 relative against f64.
    let cpu = CpuBackend::new();
    let cells: Vec<u32> = (0..N_CELLS as u32)
        .step_by(7)
        .filter(|&c| cell_info(c as usize).valid)
        .collect();
    let lobes = vec![
        Lobe::Analytic(LobeParams {
            kd: 0.0,
            ks: 1.0,
            f0: 0.05,
            n: 78_200.0,
        }),
        Lobe::Analytic(LobeParams {
            kd: 0.3,
            ks: 0.5,
            f0: 0.9,
            n: 1.2,
        }),
    ];
    let vals = cpu.tabulate(&lobes, &cells).expect("cpu tabulate");
    let t = brdf_basis::merl::GridTables::new();
    for (l, lobe) in lobes.iter().enumerate() {
        for (c, &cell) in cells.iter().enumerate() {
            let want = lobe.eval_f64(&t, cell as usize);
            let got = vals[l * cells.len() + c] as f64;
            assert!(
                (got - want).abs() <= 1e-6 * want.max(1e-30),
                "{got} vs {want}"
            );
        }
    }
}

fn assert_l1_matches_cpu(got: &[f64], lobes: &[Lobe], cells: &CellSet) {
    let want = CpuBackend::new()
        .pairwise_l1(lobes, cells, &|_, _| {})
        .expect("cpu");
    let r = max_rel(got, &want, 1e-30);
    assert!(
        r <= 1e-4,
        "{} lobes: gpu vs cpu relative {r:e}",
        lobes.len()
    );
}

fn lobes_of(coll: &brdf_basis::collection::Collection) -> Vec<Lobe> {
    brdf_basis::distance::lobes(coll, brdf_basis::distance::LobeKind::Specular)
}

#[test]
fn pairwise_kernel_matches_cpu_at_full_run_length() {
    // Every lane runs MAX_RUN_ITERS iterations: a loop cut short by the driver (lavapipe
    // ends loops after 65,535 iterations) would change the result.
    let Some(gpu) = gpu("pairwise_kernel_matches_cpu_at_full_run_length") else {
        return;
    };
    let Some(ngan) = ngan_or_skip("pairwise_kernel_matches_cpu_at_full_run_length") else {
        return;
    };
    let coll = ngan.subset(&(0..13).collect::<Vec<_>>());
    let cells = CellSet::new(Mask::Valid, Weighting::SolidAngle, 1);
    let plan = gpu.plan(13, 0, cells.len()).expect("plan");
    assert!(plan.run_iters as usize * plan.shape.lanes <= plan.chunk);
    let lobes = lobes_of(&coll);
    let g = gpu.pairwise_l1(&lobes, &cells, &|_, _| {}).expect("gpu");
    // The same after the cached device memory is dropped (a fresh texture).
    gpu.release_memory();
    let again = gpu.pairwise_l1(&lobes, &cells, &|_, _| {}).expect("gpu");
    assert_eq!(g, again, "deterministic, cache or not");
    assert_l1_matches_cpu(&g, &lobes, &cells);
}

#[test]
fn no_kernel_invocation_approaches_the_loop_limit() {
    // The largest loop of any invocation, for the largest inputs the planner accepts.
    const LAVAPIPE_LOOP_LIMIT: u32 = 65_535;
    const { assert!(MAX_RUN_ITERS < LAVAPIPE_LOOP_LIMIT / 16) };
    const { assert!(brdf_basis::backend::gpu::tabulate::BPI * 4 < LAVAPIPE_LOOP_LIMIT as usize) };
    let limits = PlanLimits {
        // The larger (hardware) chunk: the most lane-runs the f64 reduction adds per value.
        max_chunk: brdf_basis::backend::gpu::pairwise::MAX_CHUNK_HARDWARE,
        max_binding: 128 << 20,
        max_texture_dim: 16_384,
        max_dispatch: 65_535,
    };
    for rows in [2, 13, 100, 1000, 5000] {
        for software in [true, false] {
            let shape = KernelShape::choose(rows, software);
            let plan = PairPlan::new(rows, 0, 1_096_216, &limits, shape).expect("plan");
            assert!(plan.run_iters <= MAX_RUN_ITERS && (shape.lanes as u32) < LAVAPIPE_LOOP_LIMIT);
            // The f64 reduction's loop (crates/gpu/src/pairwise/reduce_f64.wgsl): one lane-run per iteration.
            assert!(plan.n_runs * shape.lanes < LAVAPIPE_LOOP_LIMIT as usize / 16);
            assert!(plan.n_pad >= rows && plan.n_pad.is_multiple_of(shape.side()));
            assert!(
                plan.texture_height() <= limits.max_texture_dim,
                "texture side"
            );
            // With measured rows instead, their texture rows stay within the budget.
            let measured = PairPlan::new(0, rows, 1_096_216, &limits, shape).expect("plan");
            assert!(
                measured.measured_blocks * measured.row_stride * 16 <= MAX_PACKED_BYTES,
                "measured texture within budget"
            );
            assert!(measured.texture_height() <= limits.max_texture_dim);
            assert!(plan.row_stride.is_multiple_of(TEX_W) && plan.row_stride >= plan.chunk);
            assert!(
                plan.n_runs * shape.lanes * plan.run_iters as usize >= plan.chunk,
                "runs cover the chunk"
            );
        }
    }
    // 100 rows on lavapipe: 20 x 20 blocks, no padding.
    assert_eq!(KernelShape::choose(100, true).side(), 20);
}

#[test]
fn every_kernel_shape_matches_cpu() {
    // Each register-block shape the back-end may pick (whatever this adapter is), on 37
    // lobes with 3 measured ones (packed on the host) among them; L1 and dot.
    let Some(gpu) = gpu("every_kernel_shape_matches_cpu") else {
        return;
    };
    use brdf_basis::backend::gpu::pairwise::{PairwiseKernel, RowLayout};
    use brdf_basis::backend::{all_blocks, PairOp};
    let Some(ngan) = ngan_or_skip("every_kernel_shape_matches_cpu") else {
        return;
    };
    let coll = ngan.subset(&(0..37).collect::<Vec<_>>());
    let mut lobes = brdf_basis::distance::lobes(&coll, brdf_basis::distance::LobeKind::Full);
    let cpu = CpuBackend::new();
    for m in [1usize, 17, 36] {
        lobes[m] = measured_lobe(&lobes[m], Some(1));
    }
    let cells = CellSet::new(Mask::Evaluation, Weighting::SolidAngle, 7);
    let ctx = gpu.context();
    let kernel = PairwiseKernel::new();
    let layout = RowLayout::new(&lobes);
    assert_eq!((layout.measured_start, layout.n_rows), (36, 39));
    let blocks = all_blocks(lobes.len());
    for op in [PairOp::L1, PairOp::Dot] {
        let want = cpu
            .reduce_pairs(&lobes, &cells, &blocks, op, &|_, _| {})
            .expect("cpu");
        for shape in KernelShape::all() {
            let plan =
                PairPlan::new(34, 3, cells.len(), &PlanLimits::of(ctx), shape).expect("plan");
            let got = kernel
                .run(ctx, &lobes, &cells, &blocks, op, &plan, &|_, _| {})
                .expect("gpu");
            let r = max_rel(&got, &want, 1e-30);
            assert!(r <= 1e-4, "{op:?} {shape:?}: gpu vs cpu relative {r:e}");
        }
    }
}

#[test]
fn pairwise_handles_padding_measured_rows_and_tiny_sets() {
    // 5 materials (padded to 8), one of them measured; a handful of cells.
    let Some(gpu) = gpu("pairwise_handles_padding_measured_rows_and_tiny_sets") else {
        return;
    };
    let Some(ngan) = ngan_or_skip("pairwise_handles_padding_measured_rows_and_tiny_sets") else {
        return;
    };
    let coll = ngan.subset(&[0, 10, 20, 30, 40]);
    let mut lobes = brdf_basis::distance::lobes(&coll, brdf_basis::distance::LobeKind::Full);
    let cpu = CpuBackend::new();
    lobes[2] = measured_lobe(&lobes[2], None);
    for stride in [1usize, 13] {
        let cells = CellSet::new(Mask::Evaluation, Weighting::Uniform, stride);
        let g = gpu.pairwise_l1(&lobes, &cells, &|_, _| {}).expect("gpu");
        let c = cpu.pairwise_l1(&lobes, &cells, &|_, _| {}).expect("cpu");
        let r = brdf_basis::distance::reference_pairwise_f64(&lobes, &cells);
        assert!(max_rel(&g, &r, 1e-30) <= 1e-4, "gpu stride {stride}");
        assert!(max_rel(&c, &r, 1e-30) <= 1e-4, "cpu stride {stride}");
        // Gram (dot) mode with the measured row among the basis columns.
        let gg = gpu.gram(&lobes, &cells, 3, &|_, _| {}).expect("gpu gram");
        let gc = cpu.gram(&lobes, &cells, 3, &|_, _| {}).expect("cpu gram");
        assert!(max_rel(&gg, &gc, 1e-30) <= 1e-4, "gram stride {stride}");
    }
}

#[test]
fn gpu_pgd_solver_reaches_the_exact_optimum() {
    use brdf_basis::fit::{fit_cells, FitParams};
    use brdf_basis::nnls::{lawson_hanson, pgd::PgdParams, GramBatch};
    let Some(gpu) = gpu("gpu_pgd_solver_reaches_the_exact_optimum") else {
        return;
    };
    let Some(c) = ngan_or_skip("gpu_pgd_solver_reaches_the_exact_optimum") else {
        return;
    };
    let basis: Vec<usize> = [
        "blue-acrylic",
        "acrylic-yellow",
        "alumina-oxide",
        "cherry-235",
        "steel",
    ]
    .iter()
    .map(|n| c.index_of(n).expect("name"))
    .collect();
    let targets: Vec<usize> = (0..c.len()).filter(|i| !basis.contains(i)).collect();
    let p = FitParams {
        stride: 2,
        objective: TargetWeight::L2,
        ..Default::default()
    };
    let cells = fit_cells(&c, &(0..c.len()).collect::<Vec<_>>(), &p).expect("cells");
    let cpu = CpuBackend::new();
    let (mut worst, mut worst_kkt, mut over) = (0f64, 0f64, 0usize);
    for ch in 0..3 {
        let brdf_basis::fit::ChannelGram {
            gram: g,
            h: hs,
            bb: bbs,
        } = brdf_basis::fit::channel_gram(
            &cpu,
            &c,
            &basis,
            &targets,
            &cells,
            ch,
            brdf_basis::fit::GramMode::Grid,
            &|_, _| {},
        )
        .expect("gram");
        let batch = GramBatch::new(6, &g, &hs, &bbs).expect("batch");
        let gp = gpu.context();
        let kernel = brdf_basis::backend::gpu::pgd::PgdKernel::new(gp).expect("kernel");
        let sols = kernel
            .solve_batch(gp, &batch, &PgdParams::default())
            .expect("gpu pgd");
        let exact = lawson_hanson::solve_batch(&batch, &Default::default()).expect("lh");
        for ((s, e), &bb) in sols.iter().zip(&exact).zip(&bbs) {
            let excess = (s.objective - e.objective) / bb;
            worst = worst.max(excess);
            worst_kkt = worst_kkt.max(s.max_kkt_violation);
            over += usize::from(s.max_kkt_violation > brdf_basis::fit::PGD_FALLBACK_KKT);
            // SPEC 5: within 1e-6 x the target's energy of the exact optimum.
            assert!(excess <= 1e-6, "objective excess {excess:e}");
        }
    }
    eprintln!("gpu pgd (f32): worst objective excess {worst:e} x energy, worst f64 KKT {worst_kkt:e}, {over} of {} above the fallback level", 3 * targets.len());
}

#[test]
fn pairwise_in_several_block_passes_matches_cpu() {
    // 1,500 lobes (the Ngan lobes repeated, scaled): more register blocks than one
    // dispatch dimension (65,535) or binding of per-lane partials allows in one pass.
    let Some(gpu) = gpu("pairwise_in_several_block_passes_matches_cpu") else {
        return;
    };
    let Some(ngan) = ngan_or_skip("pairwise_in_several_block_passes_matches_cpu") else {
        return;
    };
    let base = lobes_of(&ngan);
    let lobes: Vec<Lobe> = (0..1500)
        .map(|i| match &base[i % base.len()] {
            Lobe::Analytic(p) => Lobe::Analytic(LobeParams {
                ks: p.ks * (1.0 + i as f32 / 97.0),
                ..*p
            }),
            other => other.clone(),
        })
        .collect();
    let cells = CellSet::new(Mask::Evaluation, Weighting::Uniform, 3);
    let plan = gpu.plan(lobes.len(), 0, cells.len()).expect("plan");
    let per_block = plan.partials_per_block() * 4;
    let nb = plan.n_pad / plan.shape.side();
    let blocks = nb * (nb + 1) / 2;
    assert!(
        blocks > 65_535 || blocks * per_block > 128 << 20,
        "the test must need several passes: {plan:?}"
    );
    let g = gpu.pairwise_l1(&lobes, &cells, &|_, _| {}).expect("gpu");
    assert_l1_matches_cpu(&g, &lobes, &cells);
}

#[test]
fn concurrent_calls_on_one_backend_match_cpu() {
    // One back-end shared by threads (as the tests share it): each call must own its
    // textures and buffers while it runs.
    let Some(gpu) = gpu("concurrent_calls_on_one_backend_match_cpu") else {
        return;
    };
    let Some(coll) = ngan_or_skip("concurrent_calls_on_one_backend_match_cpu") else {
        return;
    };
    let cells = CellSet::new(Mask::Evaluation, Weighting::Uniform, 5);
    let sets: Vec<Vec<Lobe>> = (0..4)
        .map(|k| lobes_of(&coll.subset(&(k * 20..k * 20 + 9 + 3 * k).collect::<Vec<_>>())))
        .collect();
    std::thread::scope(|s| {
        let runs: Vec<_> = sets
            .iter()
            .map(|l| {
                s.spawn(|| {
                    (0..3)
                        .map(|_| gpu.pairwise_l1(l, &cells, &|_, _| {}).expect("gpu"))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        for (run, l) in runs.into_iter().zip(&sets) {
            for got in run.join().expect("thread") {
                assert_l1_matches_cpu(&got, l, &cells);
            }
        }
    });
}

#[test]
fn gpu_pgd_at_the_column_limit_reaches_the_exact_optimum() {
    // 32 columns (the kernel's limit, loops too long to unroll fully) against
    // Lawson-Hanson on random well-posed problems.
    use brdf_basis::nnls::pgd::{PgdParams, PGD_KERNEL_COLUMNS};
    use brdf_basis::nnls::{lawson_hanson, GramBatch};
    let Some(gpu) = gpu("gpu_pgd_at_the_column_limit_reaches_the_exact_optimum") else {
        return;
    };
    let (m, rows, targets) = (PGD_KERNEL_COLUMNS, 96, 40);
    use rand::Rng;
    let mut rng = rng(7);
    let mut rnd = || rng.random::<f64>();
    let a: Vec<f64> = (0..rows * m).map(|_| rnd()).collect();
    let g: Vec<f64> = (0..m * m)
        .map(|k| (0..rows).map(|r| a[r * m + k / m] * a[r * m + k % m]).sum())
        .collect();
    let (mut hs, mut bbs) = (Vec::new(), Vec::new());
    for _ in 0..targets {
        let b: Vec<f64> = (0..rows).map(|_| rnd() - 0.3).collect();
        hs.extend((0..m).map(|k| (0..rows).map(|r| a[r * m + k] * b[r]).sum::<f64>()));
        bbs.push(b.iter().map(|v| v * v).sum::<f64>());
    }
    let batch = GramBatch::new(m, &g, &hs, &bbs).expect("batch");
    let ctx = gpu.context();
    let kernel = brdf_basis::backend::gpu::pgd::PgdKernel::new(ctx).expect("kernel");
    let sols = kernel
        .solve_batch(ctx, &batch, &PgdParams::default())
        .expect("gpu pgd");
    let exact = lawson_hanson::solve_batch(&batch, &Default::default()).expect("lh");
    for ((s, e), &bb) in sols.iter().zip(&exact).zip(&bbs) {
        let excess = (s.objective - e.objective) / bb;
        // SPEC 5: within 1e-6 x the target's energy of the exact optimum.
        assert!(excess <= 1e-6, "objective excess {excess:e}");
    }
}
