//! Acquisition (SPEC 10): fits from samples, plans, acquisition cross-validation.

use crate::common;
use brdf_basis::acquire::{
    cell_candidates, fit_samples, material_at, plan, Criterion, PlanParams, Sample,
};
use brdf_basis::backend::weighted::TargetWeight;
use brdf_basis::collection::{parse_csv, Collection};
use brdf_basis::fit::{fit, FitParams};
use brdf_basis::merl::cell_directions;
use brdf_basis::CpuBackend;
use std::path::Path;

const CSV: &str = "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n\
    plastic,0.2,0.1,0.05,0.3,0.3,0.3,0.04,120\n\
    metal,0,0,0,0.9,0.7,0.4,0.8,2500\n\
    satin,0.05,0.05,0.08,0.2,0.25,0.3,0.1,15\n\
    target,0.12,0.07,0.06,0.5,0.4,0.3,0.2,400\n";

fn coll() -> Collection {
    parse_csv(CSV.as_bytes(), Path::new("t.csv")).unwrap()
}

fn dir(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
}

/// A material that is exactly `0.1/pi + 0.5 plastic + 0.25 metal + 0.75 satin`, measured at
/// 8 directions: the samples determine the 4 coefficients per channel, so the fit returns
/// them and the reconstruction equals the material at other directions.
#[test]
#[allow(clippy::needless_range_loop)]
fn samples_of_an_exact_combination_give_its_coefficients() {
    let c = coll();
    let basis = [0, 1, 2];
    let a = [
        [0.1, 0.2, 0.3],
        [0.5, 0.5, 0.5],
        [0.25, 0.1, 0.4],
        [0.75, 1.0, 0.6],
    ];
    let truth = |wi, wo| -> [f64; 3] {
        let mut v = [0.0; 3];
        for ch in 0..3 {
            v[ch] = a[0][ch] / std::f64::consts::PI;
            for (k, &b) in basis.iter().enumerate() {
                v[ch] += a[k + 1][ch] * material_at(&c.materials()[b], wi, wo).unwrap()[ch];
            }
        }
        v
    };
    let dirs = [
        (0.0, 0.0, 10.0, 180.0),
        (20.0, 0.0, 25.0, 180.0),
        (30.0, 0.0, 31.0, 175.0),
        (45.0, 90.0, 44.0, 270.0),
        (60.0, 0.0, 10.0, 90.0),
        (5.0, 0.0, 70.0, 0.0),
        (15.0, 30.0, 16.0, 212.0),
        (40.0, 0.0, 41.0, 180.5),
    ];
    let samples: Vec<Sample> = dirs
        .iter()
        .map(|&(ti, pi, to, po)| {
            let (wi, wo) = (dir(ti, pi), dir(to, po));
            Sample {
                wi,
                wo,
                rgb: truth(wi, wo),
                sigma: None,
                line: 0,
            }
        })
        .collect();
    let f = fit_samples(&c, &basis, &samples, TargetWeight::L2).unwrap();
    for (k, row) in a.iter().enumerate() {
        for ch in 0..3 {
            let got = f.coefficients[k][ch];
            // Tolerance: the Gram form squares the condition number (~1e4 here).
            assert!(
                (got - row[ch]).abs() < 1e-6 * row[ch].max(1.0),
                "column {k} channel {ch}: {got} vs {}",
                row[ch]
            );
        }
    }
    assert_eq!(f.determination.rank, 4);
    assert!(f.relative_residual < 1e-12, "{}", f.relative_residual);
    // The reconstruction equals the material elsewhere.
    let (wi, wo) = (dir(33.0, 10.0), dir(50.0, 200.0));
    let want = truth(wi, wo);
    for ch in 0..3 {
        let mut got = f.coefficients[0][ch] / std::f64::consts::PI;
        for (k, &b) in basis.iter().enumerate() {
            got += f.coefficients[k + 1][ch] * material_at(&c.materials()[b], wi, wo).unwrap()[ch];
        }
        assert!(
            (got - want[ch]).abs() < 1e-6 * want[ch],
            "{got} vs {}",
            want[ch]
        );
    }
}

/// Samples at every cell centre of the (stride-4) fit mask, unweighted, are the grid fit:
/// the same coefficients as `fit` on that grid (up to the grid's f32 model parameters).
#[test]
fn samples_at_all_cell_centres_give_the_grid_fit() {
    let c = coll();
    let basis = [0, 1, 2];
    let p = FitParams {
        stride: 4,
        objective: TargetWeight::L2,
        ..FitParams::default()
    };
    let grid = fit(&CpuBackend::new(), &c, &basis, &[3], &p, &|_, _| {}).unwrap();
    let cells = brdf_basis::fit::fit_cells(&c, &[0, 1, 2, 3], &p).unwrap();
    let samples: Vec<Sample> = cells
        .cells
        .iter()
        .map(|&cell| {
            let (wi, wo) = cell_directions(cell as usize);
            Sample {
                wi,
                wo,
                rgb: material_at(&c.materials()[3], wi, wo).unwrap(),
                sigma: None,
                line: 0,
            }
        })
        .collect();
    let f = fit_samples(&c, &basis, &samples, TargetWeight::L2).unwrap();
    for k in 0..4 {
        for ch in 0..3 {
            let (a, b) = (f.coefficients[k][ch], grid[0].coefficients[k][ch]);
            assert!(
                (a - b).abs() <= 1e-5 * b.abs().max(1e-3),
                "column {k} channel {ch}: samples {a} vs grid {b}"
            );
        }
    }
}

/// Five samples at one direction pair: rank 1 of 4, warned about with how many more
/// samples and where.
#[test]
fn a_rank_deficient_sample_set_is_warned_about() {
    let d = common::tmp();
    let collp = common::write(d.path(), "c.csv", CSV);
    let row = "10,0,12,180,0.05,0.04,0.03\n".repeat(5);
    let s = common::write(
        d.path(),
        "meas.csv",
        format!("theta_i,phi_i,theta_o,phi_o,r,g,b\n{row}"),
    );
    let json = d.path().join("fit.json");
    let out = common::bin_cpu()
        .arg("fit")
        .arg(&collp)
        .args(["--basis", "plastic,metal,satin", "--samples"])
        .arg(&s)
        .arg("--json")
        .arg(&json)
        .args(["--export"])
        .arg(d.path().join("exp"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("rank 1 of 4") && err.contains("more samples") && err.contains("theta_i"),
        "{err}"
    );
    let text = std::fs::read_to_string(&json).unwrap();
    assert!(
        text.contains("\"samples\": 5") && text.contains("\"material\": \"meas\""),
        "{text}"
    );
    let bin = std::fs::metadata(d.path().join("exp/meas.binary")).unwrap();
    assert_eq!(bin.len(), 34_992_012);
    // Refused: a sample below the horizon, named by line and column.
    let bad = common::write(
        d.path(),
        "bad.csv",
        "theta_i,phi_i,theta_o,phi_o,r,g,b\n10,0,12,180,0.05,0.04,0.03\n10,0,92,0,1,1,1\n",
    );
    let out = common::bin_cpu()
        .arg("fit")
        .arg(&collp)
        .args(["--basis", "plastic,metal", "--samples"])
        .arg(&bad)
        .arg("--json")
        .arg(d.path().join("bad.json"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("line 3") && err.contains("theta_o"),
        "{err}"
    );
}

/// Plans are deterministic for a seed and nested; the error plan lowers the training score
/// at every step.
#[test]
fn plans_are_deterministic_nested_and_error_plans_lower_the_score() {
    let c = coll();
    let cands = cell_candidates(
        &c,
        &[0, 1, 2, 3],
        &FitParams {
            stride: 3,
            objective: TargetWeight::L2,
            ..FitParams::default()
        },
    )
    .unwrap();
    let be = CpuBackend::new();
    for crit in [Criterion::Error, Criterion::Condition, Criterion::Random] {
        let p = PlanParams {
            n: 6,
            criterion: crit,
            candidates_per_step: 500,
            seed: 7,
            fit: brdf_basis::fit::FitParams {
                objective: TargetWeight::L2,
                ..Default::default()
            },
            ..PlanParams::default()
        };
        let a = plan(&be, &c, &[0, 1], &[2, 3], &cands, &p).unwrap();
        let b = plan(&be, &c, &[0, 1], &[2, 3], &cands, &p).unwrap();
        assert_eq!(a, b, "{crit:?}");
        let short = plan(
            &be,
            &c,
            &[0, 1],
            &[2, 3],
            &cands,
            &PlanParams { n: 3, ..p.clone() },
        )
        .unwrap();
        assert_eq!(short.samples[..], a.samples[..3], "{crit:?} nested");
        if crit == Criterion::Error {
            assert!(
                a.history.windows(2).all(|w| w[1] <= w[0] * (1.0 + 1e-9)),
                "{:?}",
                a.history
            );
        }
        if crit == Criterion::Random {
            let other = plan(
                &be,
                &c,
                &[0, 1],
                &[2, 3],
                &cands,
                &PlanParams {
                    seed: 8,
                    ..p.clone()
                },
            )
            .unwrap();
            assert_ne!(other.samples, a.samples);
        }
    }
}

/// The `nielsen` baseline on a real (analytic) collection: a training material is in the
/// span of the PCA, so with as many samples as the centred observations' rank and no ridge
/// it is reconstructed exactly on every cell; the published ridge (eta = 40) stays close;
/// the plan through `plan` is deterministic and nested.
#[test]
fn nielsen_reconstructs_a_training_material_and_plans_nested() {
    use brdf_basis::acquire::nielsen::{NielsenModel, ETA};
    let c = coll();
    let fp = FitParams {
        stride: 4,
        objective: TargetWeight::L2,
        ..FitParams::default()
    };
    let cands = cell_candidates(&c, &[0, 1, 2, 3], &fp).unwrap();
    let cells: Vec<u32> = cands.iter().map(|x| x.cell.unwrap()).collect();
    let train = [0, 1, 2];
    let model = NielsenModel::train(&c, &train, &cells, 20).unwrap();
    // 9 observations, centred: rank at most 8.
    assert!(model.k <= 8 && model.k >= 3, "{}", model.k);
    let plan_ = model.plan(model.k, 0, 5);
    assert_eq!(plan_.len(), model.k);
    let be = CpuBackend::new();
    let vals: Vec<Vec<f64>> = (0..3)
        .map(|ch| {
            be.values_f64(
                &brdf_basis::fit::channel_lobe(&c.materials()[1].data, ch),
                &cells,
            )
        })
        .collect();
    let mut worst = 0.0f64;
    let mut worst_ridge = 0.0f64;
    for v_ch in &vals {
        let y: Vec<f64> = plan_.iter().map(|&j| v_ch[j]).collect();
        let exact = model.coefficients(&plan_, &y, 0.0);
        let ridge = model.coefficients(&plan_, &y, ETA);
        for (j, &v) in v_ch.iter().enumerate() {
            let rel = |x: f64| (x - v).abs() / v.max(1e-3);
            worst = worst.max(rel(model.value(j, &exact)));
            worst_ridge = worst_ridge.max(rel(model.value(j, &ridge)));
        }
    }
    assert!(worst < 1e-6, "exact reconstruction off by {worst}");
    assert!(worst_ridge.is_finite(), "{worst_ridge}");
    // Through `plan`: deterministic, nested, on the candidates.
    let p = PlanParams {
        n: 5,
        criterion: Criterion::Nielsen,
        seed: 3,
        fit: brdf_basis::fit::FitParams {
            objective: TargetWeight::L2,
            ..Default::default()
        },
        ..PlanParams::default()
    };
    let a = plan(&be, &c, &[0], &[1, 2], &cands, &p).unwrap();
    assert_eq!(a, plan(&be, &c, &[0], &[1, 2], &cands, &p).unwrap());
    let short = plan(
        &be,
        &c,
        &[0],
        &[1, 2],
        &cands,
        &PlanParams { n: 2, ..p.clone() },
    )
    .unwrap();
    assert_eq!(short.samples[..], a.samples[..2]);
    assert_eq!(a.candidates_per_step, 500);
    assert!(
        a.history.iter().all(|h| h.is_finite() && *h >= 1.0),
        "{:?}",
        a.history
    );
}

/// `cv --acquisition` runs the baseline beside our plans: one row per plan, n and noise,
/// every held-out material scored (rho, MAE, image error), plans nested, a showcase with
/// the dense fit and one render per n, and the table names the baseline.
#[test]
fn acquisition_cv_runs_the_nielsen_baseline() {
    use brdf_basis::acquire::{acquisition_cv, AcqCvParams};
    let csv = format!(
        "{CSV}m5,0.3,0.3,0.1,0.4,0.3,0.2,0.3,60\nm6,0.01,0.2,0.3,0.7,0.7,0.7,0.05,800\nm7,0.25,0.05,0.2,0.1,0.2,0.3,0.6,30\nm8,0.15,0.15,0.15,0.6,0.5,0.4,0.9,200\n"
    );
    let c = parse_csv(csv.as_bytes(), Path::new("t8.csv")).unwrap();
    let p = AcqCvParams {
        k: 2,
        plans: vec![Criterion::Condition, Criterion::Nielsen],
        ns: vec![3, 6],
        noises: vec![0.0, 0.02],
        folds: 2,
        candidates_per_step: 300,
        render_size: 16,
        objective: brdf_basis::select::ObjectiveParams::default()
            .objective(TargetWeight::L2)
            .stride(6),
        appearance: false,
        ..AcqCvParams::default()
    };
    let r = acquisition_cv(&CpuBackend::new(), &c, &p).unwrap();
    assert_eq!(r.results.len(), 2 * 2 * 2);
    for x in &r.results {
        assert_eq!(x.held_out.len(), 8);
        assert!(x.held_out.iter().all(|h| h.rho.is_finite()
            && h.rho >= 0.0
            && h.mae.is_finite()
            && h.image_error.is_finite()
            && h.dense_image_error.is_finite()));
        assert!(x.fold_plans.iter().all(|f| f.len() == x.n));
    }
    let get = |n: usize, noise: f64| {
        r.results
            .iter()
            .find(|x| x.plan == Criterion::Nielsen && x.n == n && x.noise == noise)
            .unwrap()
    };
    assert_eq!(
        get(3, 0.0).fold_plans[0][..],
        get(6, 0.0).fold_plans[0][..3]
    );
    assert_ne!(
        get(6, 0.0).mean_rho,
        get(6, 0.02).mean_rho,
        "noise changes the measurements"
    );
    let md = r.markdown();
    assert!(
        md.contains("| nielsen | 6 |") && md.contains("dense fit (the limit)"),
        "{md}"
    );
    let sh = r.showcase.as_ref().expect("showcase");
    assert_eq!(sh.plan, Criterion::Condition);
    assert_eq!(sh.tiles.len(), 3, "dense fit, n = 3, n = 6");
    assert_eq!(acquisition_cv(&CpuBackend::new(), &c, &p).unwrap(), r);

    // Audit 2, T12: progress in steps (shared state, per method and fold each plan and
    // the scores, the showcase), never backwards, ending at its total; the same result.
    let seen = std::sync::Mutex::new(Vec::new());
    let with =
        brdf_basis::acquire::acquisition_cv_with_progress(&CpuBackend::new(), &c, &p, &|d, t| {
            seen.lock().unwrap().push((d, t))
        })
        .unwrap();
    assert_eq!(with, r);
    let seen = seen.into_inner().unwrap();
    let total = 2 + 2 * (2 + 1);
    assert!(seen.iter().all(|&(d, t)| t == total && d <= t), "{seen:?}");
    assert!(seen.windows(2).all(|w| w[0].0 <= w[1].0), "{seen:?}");
    assert_eq!(seen.first(), Some(&(0, total)));
    assert_eq!(seen.last(), Some(&(total, total)));
    assert!(
        seen.len() > 2 * total as usize,
        "pulses inside the steps: {}",
        seen.len()
    );
}

/// `cv --acquisition --test` (issue 50, item 3): a fixed split equal to fold `f` of a
/// cross-validation, seeded as that fold (`seed + 1000 f`: a split is fold 0), gives that
/// fold's basis, plans and every held-out number (the default objective, the ridge and the
/// energy bound, the appearance metrics, `nielsen` beside ours); names it does not know or
/// lists twice are refused by name.
#[test]
fn a_fixed_split_equal_to_a_fold_gives_that_folds_numbers() {
    use brdf_basis::acquire::{acquisition_cv, AcqCvParams};
    let c = brdf_basis::collection::synthetic(14, 3);
    let p = AcqCvParams {
        k: 2,
        plans: vec![Criterion::Error, Criterion::Random, Criterion::Nielsen],
        ns: vec![2, 5],
        noises: vec![0.0],
        folds: 3,
        candidates_per_step: 200,
        render_size: 16,
        objective: brdf_basis::select::ObjectiveParams::default().stride(8),
        ..AcqCvParams::default()
    };
    let all = acquisition_cv(&CpuBackend::new(), &c, &p).unwrap();
    let f = 2;
    let split = AcqCvParams {
        test: all.folds[f].iter().rev().cloned().collect(),
        seed: p.seed + 1000 * f as u64,
        ..p.clone()
    };
    let one = acquisition_cv(&CpuBackend::new(), &c, &split).unwrap();
    assert_eq!(one.folds, vec![all.folds[f].clone()]);
    assert_eq!(one.results.len(), all.results.len());
    for (a, b) in all.results.iter().zip(&one.results) {
        assert_eq!((a.plan, a.n), (b.plan, b.n));
        assert_eq!(b.fold_bases, vec![a.fold_bases[f].clone()]);
        assert_eq!(b.fold_plans, vec![a.fold_plans[f].clone()]);
        if !a.ridge.is_empty() {
            assert_eq!(
                (b.ridge[0], b.energy_ridge[0]),
                (a.ridge[f], a.energy_ridge[f])
            );
        }
        let rows: Vec<_> = a.held_out.iter().filter(|h| h.fold == f).collect();
        assert_eq!(rows.len(), b.held_out.len());
        assert!(!rows.is_empty());
        for (x, y) in rows.iter().zip(&b.held_out) {
            assert_eq!(y.fold, 0);
            let y = brdf_basis::acquire::AcqHeldOut {
                fold: f,
                ..y.clone()
            };
            assert_eq!(**x, y, "{} {} {}", a.plan.as_str(), a.n, x.material);
        }
    }
    for (bad, says) in [
        (vec!["no-such".to_string()], "no-such"),
        (
            vec![all.folds[0][0].clone(), all.folds[0][0].clone()],
            "once",
        ),
        (c.names(), "at least one to train on"),
    ] {
        let e = acquisition_cv(
            &CpuBackend::new(),
            &c,
            &AcqCvParams {
                test: bad,
                ..p.clone()
            },
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains(says) && e.contains("test"), "{e}");
    }
}

/// `cv --acquisition --test LIST|FILE` on the command line: a file of names (comments and
/// blank lines skipped) and the same names comma-separated give the same JSON, one fold
/// of those materials; `--folds` beside it and a name the collection lacks are refused by
/// name before anything is written.
#[test]
fn cv_acquisition_test_takes_a_list_or_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let csv = format!(
        "{CSV}m5,0.3,0.3,0.1,0.4,0.3,0.2,0.3,60\nm6,0.01,0.2,0.3,0.7,0.7,0.7,0.05,800\nm7,0.25,0.05,0.2,0.1,0.2,0.3,0.6,30\n"
    );
    std::fs::write(d.join("c.csv"), csv).unwrap();
    std::fs::write(
        d.join("test.txt"),
        "# held out\nm6\n\n  satin  # a comment\n",
    )
    .unwrap();
    let run = |test: &str, extra: &[&str], json: &str| {
        let mut c = common::bin_cpu();
        c.current_dir(d).args([
            "cv",
            "c.csv",
            "--acquisition",
            "--methods",
            "greedy",
            "-k",
            "2",
            "--plans",
            "error,random",
            "-n",
            "2,4",
            "--noise",
            "0",
            "--stride",
            "8",
            "--render-size",
            "16",
            "--no-appearance",
            "--candidates-per-step",
            "100",
            "--test",
            test,
            "--json",
            json,
        ]);
        c.args(extra);
        c.output().unwrap()
    };
    let a = run("test.txt", &[], "a.json");
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    let b = run("m6,satin", &[], "b.json");
    assert!(b.status.success(), "{}", String::from_utf8_lossy(&b.stderr));
    let ja = std::fs::read_to_string(d.join("a.json")).unwrap();
    assert_eq!(ja, std::fs::read_to_string(d.join("b.json")).unwrap());
    let v: serde_json::Value = serde_json::from_str(&ja).unwrap();
    assert_eq!(v["folds"], serde_json::json!([["satin", "m6"]]));
    for (test, extra, says) in [
        (
            "m6",
            &["--folds", "3"][..],
            "--folds 3 does not apply with --test",
        ),
        ("m6,no-such", &[][..], "no-such"),
        ("m6,,satin", &[][..], "an empty name"),
    ] {
        let o = run(test, extra, "x.json");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && e.contains(says), "{test}: {e}");
        assert!(!d.join("x.json").exists());
    }
}

/// Issue 50, item 2: samples of a specular material all far from its peak leave the peak
/// to the basis; `fit --samples` says so, naming near-mirror directions that would pin it
/// (`theta_o` within a few degrees of `theta_i`, `phi_o` opposite `phi_i`). Samples at its
/// mirror directions pin it: no such warning.
#[test]
fn fit_samples_warns_when_the_samples_do_not_pin_the_peak() {
    let c = coll();
    let basis = [0, 1, 2];
    let target = &c.materials()[3];
    let sample = |ti: f64, pi: f64, to: f64, po: f64| {
        let (wi, wo) = (dir(ti, pi), dir(to, po));
        Sample {
            wi,
            wo,
            rgb: material_at(target, wi, wo).unwrap(),
            sigma: None,
            line: 0,
        }
    };
    let far: Vec<Sample> = [
        (10.0, 0.0, 60.0, 90.0),
        (50.0, 0.0, 20.0, 60.0),
        (30.0, 0.0, 70.0, 0.0),
        (65.0, 0.0, 40.0, 100.0),
        (20.0, 0.0, 45.0, 300.0),
        (40.0, 0.0, 10.0, 30.0),
    ]
    .iter()
    .map(|&(a, b, cc, d)| sample(a, b, cc, d))
    .collect();
    let fit = fit_samples(&c, &basis, &far, TargetWeight::L2).unwrap();
    let w = brdf_basis::acquire::peak_warning(&c, &basis, &fit, &far)
        .unwrap()
        .expect("a warning");
    assert!(
        w.contains("no sample looks at the highlight") && w.contains("`metal`"),
        "{w}"
    );
    // The first direction named is near a mirror pair.
    let first = w.split("degrees) (").nth(1).unwrap();
    let nums: Vec<f64> = first
        .split(')')
        .next()
        .unwrap()
        .split(", ")
        .map(|x| x.parse().unwrap())
        .collect();
    assert!((nums[0] - nums[2]).abs() < 6.0, "{w}");
    assert!(
        ((nums[3] - nums[1]).rem_euclid(360.0) - 180.0).abs() < 10.0,
        "{w}"
    );
    let mut pinned = far.clone();
    for t in [5.0, 20.0, 35.0, 50.0, 65.0, 80.0] {
        pinned.push(sample(t, 0.0, t, 180.0));
    }
    let fit = fit_samples(&c, &basis, &pinned, TargetWeight::L2).unwrap();
    assert_eq!(
        brdf_basis::acquire::peak_warning(&c, &basis, &fit, &pinned).unwrap(),
        None
    );
}
