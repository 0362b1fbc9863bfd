//! Fit objectives (SPEC 11): weighted fits against an independent f64 reference, the
//! `l2` path unchanged, and the objective through the command line (`fit`, `cv`).

use crate::common::*;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::weighted::cos_theta_i;
use brdf_basis::backend::weighted::TargetWeight;
use brdf_basis::collection::Collection;
use brdf_basis::fit::{channel_lobe, fit, fit_cells, FitParams, LAMBERTIAN};

/// SPEC 11: a weighted fit's objective is within 1e-6 x sum W b^2 of the exact optimum,
/// per target and channel, with the objective's per-target weights; the optimum by
/// enumeration on f64 values (not the back-end's f32 tabulation, not Lawson-Hanson).
#[test]
fn weighted_fits_reach_the_optimum_of_an_independent_f64_reference() {
    let coll = Collection::embedded_default();
    let names = coll.names();
    let idx = |n: &str| names.iter().position(|m| m == n).unwrap();
    let basis = [
        idx("polished-gold"),
        idx("gloss-black-enamel"),
        idx("matte-white-paint"),
    ];
    let targets: Vec<usize> = (0..coll.len())
        .filter(|i| !basis.contains(i))
        .take(4)
        .collect();
    let cpu = CpuBackend::new();
    for weight in [
        TargetWeight::relative(0.01).unwrap(),
        TargetWeight::relative(0.3).unwrap(),
        TargetWeight::Log,
    ] {
        let p = FitParams {
            stride: 6,
            objective: weight,
            ..FitParams::default()
        };
        let fits = fit(&cpu, &coll, &basis, &targets, &p, &|_, _| {}).unwrap();
        let mut all = basis.to_vec();
        all.extend(&targets);
        let cells = fit_cells(&coll, &all, &p).unwrap();
        for (f, &t) in fits.iter().zip(&targets) {
            for c in 0..3 {
                let mut cols = vec![cpu.values_f64(&LAMBERTIAN, &cells.cells)];
                for &b in &basis {
                    cols.push(
                        cpu.values_f64(&channel_lobe(&coll.materials()[b].data, c), &cells.cells),
                    );
                }
                let y = cpu.values_f64(&channel_lobe(&coll.materials()[t].data, c), &cells.cells);
                let w: Vec<f64> = cells
                    .cells
                    .iter()
                    .zip(&cells.weights)
                    .zip(&y)
                    .map(|((&s, &ws), &yv)| ws * weight.phi(yv, cos_theta_i(s as usize)))
                    .collect();
                let x: Vec<f64> = f.coefficients.iter().map(|a| a[c]).collect();
                assert!(x.iter().all(|&v| v >= 0.0));
                let got: f64 = (0..y.len())
                    .map(|s| {
                        let r: f64 = (0..cols.len()).map(|j| x[j] * cols[j][s]).sum::<f64>() - y[s];
                        w[s] * r * r
                    })
                    .sum();
                let want = brute_force_nnls(&cols, &y, &w);
                let scale: f64 = y.iter().zip(&w).map(|(v, w)| w * v * v).sum();
                assert!(
                    got - want <= 1e-6 * scale,
                    "{weight:?} {} channel {c}: objective {got} vs optimum {want} (scale {scale})",
                    f.material
                );
            }
            assert!(f.objective_residual >= 0.0 && f.objective_residual <= 1.0 + 1e-9);
        }
    }
}

/// The `l2` objective is SPEC 5's fit, bit for bit: `objective_residual` is the relative
/// residual, and the coefficients are those of the unweighted path.
#[test]
fn the_l2_objective_is_spec_5s_fit_and_a_weighted_fit_differs() {
    let coll = Collection::embedded_default();
    let basis = [0, 3, 7];
    let targets = [1, 2, 5];
    let cpu = CpuBackend::new();
    let p = FitParams {
        stride: 4,
        objective: TargetWeight::L2,
        ..FitParams::default()
    };
    assert_eq!(p.objective, TargetWeight::L2);
    let l2 = fit(&cpu, &coll, &basis, &targets, &p, &|_, _| {}).unwrap();
    for f in &l2 {
        assert_eq!(f.objective_residual, f.relative_residual);
    }
    let rel = FitParams {
        objective: TargetWeight::relative(0.01).unwrap(),
        ..p.clone()
    };
    let r = fit(&cpu, &coll, &basis, &targets, &rel, &|_, _| {}).unwrap();
    assert!(l2
        .iter()
        .zip(&r)
        .any(|(a, b)| a.coefficients != b.coefficients));
    // The weighted fit is worse in L2 than the L2 fit (it minimises something else).
    for (a, b) in l2.iter().zip(&r) {
        assert!(
            b.relative_residual >= a.relative_residual - 1e-9,
            "{}",
            a.material
        );
    }
}

/// A non-positive or non-finite eps is refused with the setting named.
#[test]
fn fit_refuses_a_bad_eps_and_writes_the_objective_and_appearance() {
    let dir = tmp();
    let json = dir.path().join("f.json");
    let out = bin_cpu()
        .args([
            "fit",
            "--basis",
            "polished-gold,gloss-black-enamel",
            "--targets",
            "gloss-red-enamel",
        ])
        .args([
            "--objective",
            "relative",
            "--eps",
            "0",
            "--stride",
            "6",
            "--json",
        ])
        .arg(&json)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("eps") && err.contains("positive"), "{err}");
    assert!(!json.exists());
    let out = bin_cpu()
        .args([
            "fit",
            "--basis",
            "polished-gold,gloss-black-enamel",
            "--targets",
            "polished-copper",
        ])
        .args(["--objective", "log", "--stride", "6", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("appearance: mean log-RMSE"), "{stdout}");
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(v["objective"], "log");
    let a = &v["targets"][0]["appearance"];
    assert_eq!(a["lights"].as_array().unwrap().len(), 4);
    for key in [
        "mean_flip",
        "mean_ciede2000",
        "mean_delta_e_itp",
        "mean_image_error",
        "log_rmse",
    ] {
        let x = a[key].as_f64().unwrap();
        assert!(x.is_finite() && x > 0.0, "{key} = {x}");
    }
}
