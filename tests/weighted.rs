//! Per-target weighted normal equations (SPEC 11, `backend::weighted`): the GPU kernel
//! against its CPU twin (the f64 reference) for every objective and every kind of row, a
//! hand-computed case, and the layout of the kernel's parameters.

use crate::common::*;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::weighted::{
    cos_theta_i, reference, TargetWeight, WeightedSystems, WEIGHTED_TOLERANCE,
};
use brdf_basis::backend::{Backend, Lobe};
use brdf_basis::brdf::LobeParams;
use brdf_basis::merl::{CellSet, Mask, Weighting};

fn lobe(kd: f32, ks: f32, f0: f32, n: f32) -> Lobe {
    Lobe::Analytic(LobeParams { kd, ks, f0, n })
}

/// Five analytic basis lobes; targets: analytic, measured copies of analytic lobes.
fn rows() -> (Vec<Lobe>, Vec<Lobe>) {
    let basis = vec![
        lobe(0.0, 1.0, 0.04, 10.0),
        lobe(0.0, 1.0, 0.9, 500.0),
        lobe(0.3, 0.0, 0.04, 1.0),
        lobe(0.0, 0.5, 0.5, 5000.0),
        lobe(0.1, 0.7, 0.2, 60.0),
    ];
    let mut targets: Vec<Lobe> = (0..9)
        .map(|i| {
            lobe(
                0.05 * i as f32,
                0.4,
                0.03 + 0.1 * i as f32,
                3.0 * 4f32.powi(i),
            )
        })
        .collect();
    for i in [1, 4, 7] {
        targets.push(measured_lobe(&targets[i], None));
    }
    (basis, targets)
}

fn assert_close(what: &str, got: &WeightedSystems, want: &WeightedSystems) {
    assert_eq!(
        (got.columns, got.values.len()),
        (want.columns, want.values.len())
    );
    let rel = max_rel(&got.values, &want.values, 1e-30);
    eprintln!("{what}: GPU vs f64 reference max relative difference {rel:.1e}");
    assert!(
        rel <= WEIGHTED_TOLERANCE,
        "{what}: {rel:e} above {WEIGHTED_TOLERANCE:e}"
    );
}

#[test]
fn weighted_systems_by_hand() {
    // A target equal to the one basis lobe, l2 weights: r = G's column of the lobe,
    // yy = G[1][1]; the Lambertian entry is (1/pi)^2 times the weights' sum (1).
    let a = lobe(0.0, 1.0, 0.1, 40.0);
    let cells = CellSet::new(Mask::Evaluation, Weighting::SolidAngle, 6);
    let s = reference(
        &CpuBackend::new(),
        std::slice::from_ref(&a),
        std::slice::from_ref(&a),
        &cells,
        TargetWeight::L2,
        &|_, _| {},
    )
    .expect("reference");
    let g = s.gram(0);
    let l = std::f32::consts::FRAC_1_PI as f64;
    let wsum: f64 = cells.weights.iter().sum();
    assert!((g[0] - l * l * wsum).abs() <= 1e-12 * g[0]);
    assert_eq!(s.rhs(0), &[g[1], g[3]]);
    assert_eq!(s.yy(0), g[3]);
    // By hand at one cell: a cell set of one cell, weight 1.
    let c = cells.cells[cells.len() / 2];
    let one = CellSet {
        cells: vec![c],
        weights: vec![1.0],
        ..cells.clone()
    };
    let v = CpuBackend::new()
        .tabulate(std::slice::from_ref(&a), &[c])
        .expect("tab")[0] as f64;
    let y = 0.5 * v;
    let half = lobe(0.0, 0.5, 0.1, 40.0);
    for (w, phi) in [
        (TargetWeight::L2, 1.0),
        (
            TargetWeight::relative(0.01).unwrap(),
            1.0 / ((y + 0.01) * (y + 0.01)),
        ),
        (TargetWeight::Log, {
            let ci = cos_theta_i(c as usize).max(0.0);
            (ci / (1.0 + y * ci)).powi(2)
        }),
    ] {
        let s = reference(
            &CpuBackend::new(),
            std::slice::from_ref(&a),
            std::slice::from_ref(&half),
            &one,
            w,
            &|_, _| {},
        )
        .expect("reference");
        // The half lobe tabulates to exactly half the lobe (a power of two).
        let yt = CpuBackend::new()
            .tabulate(std::slice::from_ref(&half), &[c])
            .expect("tab")[0] as f64;
        assert_eq!(yt, y);
        let g = s.gram(0);
        assert!((g[3] - phi * v * v).abs() <= 1e-12 * g[3], "{w:?}");
        assert!((s.rhs(0)[1] - phi * v * y).abs() <= 1e-12 * g[3], "{w:?}");
        assert!((s.yy(0) - phi * y * y).abs() <= 1e-12 * g[3], "{w:?}");
    }
}

#[test]
fn cos_theta_i_is_the_incoming_cosine_of_the_merl_convention() {
    use brdf_basis::merl::{phi_d, theta_d, theta_h, N_PD, N_TD};
    // theta_h near 0 (the first row's centre, 4.8e-5 rad): the incoming direction is the
    // difference vector, cos theta_i ~ cos theta_d.
    for j in [0, 30, 89] {
        let cell = j * N_PD + 17;
        assert!((cos_theta_i(cell) - theta_d(j).cos()).abs() < 1e-4);
    }
    // phi_d = 90 degrees: cos theta_h cos theta_d (the in-plane term vanishes).
    let (i, j, k) = (40, 20, 89);
    let cell = (i * N_TD + j) * N_PD + k;
    let want =
        theta_h(i).cos() * theta_d(j).cos() - theta_h(i).sin() * theta_d(j).sin() * phi_d(k).cos();
    assert!((cos_theta_i(cell) - want).abs() < 1e-15);
    assert!(phi_d(k).cos().abs() < 0.01);
}

#[test]
fn gpu_weighted_systems_match_the_f64_reference() {
    let Some(g) = gpu("gpu_weighted_systems_match_the_f64_reference") else {
        return;
    };
    let (basis, targets) = rows();
    let cells = CellSet::new(Mask::Evaluation, Weighting::SolidAngle, 3);
    for w in [
        TargetWeight::L2,
        TargetWeight::relative(0.01).unwrap(),
        TargetWeight::Log,
    ] {
        let want =
            reference(&CpuBackend::new(), &basis, &targets, &cells, w, &|_, _| {}).expect("cpu");
        let got = g
            .weighted_systems(&basis, &targets, &cells, w, &|_, _| {})
            .expect("gpu");
        assert_close(&format!("{w:?}"), &got, &want);
        // The CPU back-end's own method is the reference.
        let cpu = CpuBackend::new()
            .weighted_systems(&basis, &targets, &cells, w, &|_, _| {})
            .expect("cpu method");
        assert_eq!(cpu, want);
    }
    // A bad eps cannot reach either: it is refused when the weight is built.
    assert!(TargetWeight::relative(0.0).is_err());
}

#[test]
fn gpu_weighted_systems_of_neural_targets_match_the_f64_reference() {
    let Some(g) = gpu("gpu_weighted_systems_of_neural_targets_match_the_f64_reference") else {
        return;
    };
    let Some(dir) = shared_or_skip(
        "real/nbrdf/merl100",
        "gpu_weighted_systems_of_neural_targets_match_the_f64_reference",
    ) else {
        return;
    };
    let coll = brdf_basis::collection::Collection::load(&dir).expect("merl100");
    let sub = coll.subset(&(0..6).collect::<Vec<_>>());
    let lobes = brdf_basis::distance::lobes(&sub, brdf_basis::distance::LobeKind::Full);
    let (basis, targets) = lobes.split_at(5);
    let cells = CellSet::new(Mask::Evaluation, Weighting::SolidAngle, 4);
    for w in [TargetWeight::L2, TargetWeight::relative(0.01).unwrap()] {
        let want =
            reference(&CpuBackend::new(), basis, targets, &cells, w, &|_, _| {}).expect("cpu");
        let got = g
            .weighted_systems(basis, targets, &cells, w, &|_, _| {})
            .expect("gpu");
        // The networks themselves agree within SPEC 9 between back-ends (1e-5 relative
        // per value), on top of the kernel's summation.
        let rel = max_rel(&got.values, &want.values, 1e-30);
        eprintln!("neural {w:?}: GPU vs f64 reference max relative difference {rel:.1e}");
        assert!(rel <= 1e-3, "{w:?}: {rel:e}");
    }
}

#[test]
fn weighted_shader_validates_and_matches_rust_structs() {
    use brdf_basis::backend::gpu::weighted::{kernel_source, WeightedParams};
    use std::mem::{offset_of, size_of};
    for k in [0, 1, 5, 12] {
        let src = kernel_source(k);
        assert!(!src.lines().any(|l| l.trim_start().starts_with("//@")));
        let full = brdf_basis::backend::gpu::kernel_source(&src);
        let m = naga::front::wgsl::parse_str(&full)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&full)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::empty(),
        )
        .validate(&m)
        .unwrap_or_else(|e| panic!("validation: {e:?}"));
        let ty = m
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some("WeightedParams"))
            .expect("struct")
            .1;
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            panic!("struct");
        };
        assert_eq!(*span as usize, size_of::<WeightedParams>());
        let names = [
            ("n_cells", offset_of!(WeightedParams, n_cells)),
            ("n_targets", offset_of!(WeightedParams, n_targets)),
            ("run_len", offset_of!(WeightedParams, run_len)),
            ("n_runs", offset_of!(WeightedParams, n_runs)),
            ("chunk", offset_of!(WeightedParams, chunk)),
            ("weight", offset_of!(WeightedParams, weight)),
            ("eps", offset_of!(WeightedParams, eps)),
            ("lambert", offset_of!(WeightedParams, lambert)),
        ];
        for (mem, (n, o)) in members.iter().zip(names) {
            assert_eq!((mem.name.as_deref(), mem.offset as usize), (Some(n), o));
        }
    }
}

/// A measured copy of `lobe` times `scale` (in f32), with `spikes` cells set to `spike`.
fn scaled(lobe: &Lobe, scale: f32, spike: Option<f32>) -> Lobe {
    use brdf_basis::merl::{MerlTable, N_CELLS};
    let all: Vec<u32> = (0..N_CELLS as u32).collect();
    let mut table = CpuBackend::new()
        .tabulate(std::slice::from_ref(lobe), &all)
        .expect("tab");
    table.iter_mut().for_each(|v| *v *= scale);
    if let Some(s) = spike {
        for c in (0..N_CELLS).step_by(N_CELLS / 10).take(10) {
            table[c] = s;
        }
    }
    Lobe::Measured {
        table: std::sync::Arc::new(MerlTable {
            rgb: [table.clone(), table.clone(), table].concat(),
        }),
        channel: Some(0),
    }
}

/// Each value of each target's system against the reference, relative to its own scale:
/// `G_ij` to `sqrt(G_ii G_jj)`, `r_i` to `sqrt(G_ii yy)`, `yy` to itself.
fn assert_close_scaled(what: &str, got: &WeightedSystems, want: &WeightedSystems) {
    assert_eq!(got.values.len(), want.values.len(), "{what}");
    let m = want.columns;
    for t in 0..want.len() {
        let (g, w) = (got.gram(t), want.gram(t));
        let (gy, wy) = (got.yy(t), want.yy(t));
        let near = |a: f64, b: f64, scale: f64| (a - b).abs() <= WEIGHTED_TOLERANCE * scale;
        for i in 0..m {
            for j in 0..m {
                let s = (w[i * m + i] * w[j * m + j]).sqrt();
                assert!(
                    near(g[i * m + j], w[i * m + j], s),
                    "{what}, target {t}: G[{i}][{j}] {} against {}",
                    g[i * m + j],
                    w[i * m + j]
                );
            }
            let s = (w[i * m + i] * wy).sqrt();
            assert!(
                near(got.rhs(t)[i], want.rhs(t)[i], s),
                "{what}, target {t}: r[{i}] {} against {}",
                got.rhs(t)[i],
                want.rhs(t)[i]
            );
        }
        assert!(near(gy, wy, wy), "{what}, target {t}: yy {gy} against {wy}");
        assert!(w[0] > 0.0 && g[0] > 0.0, "{what}, target {t}: no weight");
    }
}

/// Audit 3, D2 and T3 (GPU part): at the edges of f32 (values of 1e-20, 1e22 and 1e30,
/// ten cells of 1e30 among 0.05, eps of 1e-20 and 1e-40) the GPU's systems are the CPU
/// back-end's: the kernel flags the targets whose weights left f32's range, and those
/// come from the f64 reference. Before, a 1e30 target had weight 0 (objective residual
/// 0) and eps 1e-20 gave "NaN or infinite data" on the GPU alone.
#[test]
fn gpu_weighted_systems_at_the_edges_of_f32_are_the_cpus() {
    let Some(g) = gpu("gpu_weighted_systems_at_the_edges_of_f32_are_the_cpus") else {
        return;
    };
    let (basis, targets) = rows();
    let basis = &basis[..3];
    let t = &targets[3];
    let grey = lobe(0.05 * std::f32::consts::PI, 0.0, 0.04, 1.0);
    let edge = vec![
        targets[5].clone(),
        scaled(t, 1e-20, None),
        scaled(t, 1e22, None),
        scaled(t, 1e30, None),
        scaled(&grey, 1.0, Some(1e30)),
    ];
    let cells = CellSet::new(Mask::Evaluation, Weighting::SolidAngle, 4);
    for w in [
        TargetWeight::relative(0.01).unwrap(),
        TargetWeight::relative(1e-20).unwrap(),
        TargetWeight::relative(1e-40).unwrap(),
        TargetWeight::relative(1e30).unwrap(),
        TargetWeight::Log,
        TargetWeight::L2,
    ] {
        // Under l2 a value of 1e-20 squares below f32's range in `yy` on both back-ends'
        // f32 Gram paths (the l2 fit does not use these systems): left out there.
        let edge: Vec<Lobe> = match w {
            TargetWeight::L2 => edge
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != 1)
                .map(|(_, l)| l.clone())
                .collect(),
            _ => edge.clone(),
        };
        let want = reference(&CpuBackend::new(), basis, &edge, &cells, w, &|_, _| {}).expect("cpu");
        let got = g
            .weighted_systems(basis, &edge, &cells, w, &|_, _| {})
            .expect("gpu");
        assert_close_scaled(&format!("{w:?}"), &got, &want);
    }
}
