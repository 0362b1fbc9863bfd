//! Objectives (SPEC 11) in acquisition (SPEC 10): fits from samples weighted by the
//! objective at the measured values, plans weighted by the shared weights, and
//! `cv --acquisition` under an objective with the appearance metrics of every
//! reconstruction, the `nielsen` baseline's included.

use crate::common::brute_force_nnls;
use brdf_basis::acquire::cell_candidates;
use brdf_basis::acquire::{
    acquisition_cv, fit_samples, material_at, plan, AcqCvParams, Criterion, PlanParams, Sample,
};
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::weighted::TargetWeight;
use brdf_basis::collection::Collection;
use brdf_basis::fit::FitParams;
use brdf_basis::run::{Ctx, Request};
use brdf_basis::select::ObjectiveParams;
use std::f64::consts::FRAC_1_PI;

fn dir(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
}

/// A material that is no combination of the basis, measured at 14 directions: under each
/// objective the fit from its samples reaches, per channel, the optimum of the weighted
/// NNLS with weights `phi(y_c(s), cos theta_i(s))` (found by enumeration in f64), and the
/// objectives give different fits.
#[test]
fn fits_from_samples_reach_the_weighted_optimum_of_each_objective() {
    let coll = Collection::embedded_default();
    let names = coll.names();
    let idx = |n: &str| names.iter().position(|m| m == n).unwrap();
    let basis = [
        idx("polished-gold"),
        idx("gloss-black-enamel"),
        idx("matte-white-paint"),
    ];
    let target = (0..coll.len()).find(|i| !basis.contains(i)).unwrap();
    let mut rng = crate::common::rng(11);
    let samples: Vec<Sample> = (0..14)
        .map(|_| {
            let u =
                |r: &mut rand_chacha::ChaCha8Rng, a: f64, b: f64| rand::Rng::random_range(r, a..b);
            let (wi, wo) = (
                dir(u(&mut rng, 0.0, 80.0), u(&mut rng, -180.0, 180.0)),
                dir(u(&mut rng, 0.0, 80.0), u(&mut rng, -180.0, 180.0)),
            );
            Sample {
                wi,
                wo,
                rgb: material_at(&coll.materials()[target], wi, wo).unwrap(),
                sigma: None,
                line: 0,
            }
        })
        .collect();
    let mut fits = Vec::new();
    for w in [
        TargetWeight::L2,
        TargetWeight::relative(0.01).unwrap(),
        TargetWeight::Log,
    ] {
        let f = fit_samples(&coll, &basis, &samples, w).unwrap();
        for c in 0..3 {
            let mut cols = vec![vec![FRAC_1_PI; samples.len()]];
            for &b in &basis {
                cols.push(
                    samples
                        .iter()
                        .map(|s| material_at(&coll.materials()[b], s.wi, s.wo).unwrap()[c])
                        .collect(),
                );
            }
            let y: Vec<f64> = samples.iter().map(|s| s.rgb[c]).collect();
            let ws: Vec<f64> = samples.iter().map(|s| w.phi(s.rgb[c], s.wi[2])).collect();
            let best = brute_force_nnls(&cols, &y, &ws);
            let x: Vec<f64> = f.coefficients.iter().map(|a| a[c]).collect();
            assert!(x.iter().all(|&v| v >= 0.0));
            let got: f64 = (0..y.len())
                .map(|s| {
                    let r: f64 = (0..x.len()).map(|j| x[j] * cols[j][s]).sum::<f64>() - y[s];
                    ws[s] * r * r
                })
                .sum();
            let scale: f64 = (0..y.len()).map(|s| ws[s] * y[s] * y[s]).sum();
            assert!(
                (got - best).abs() <= 1e-9 * scale,
                "{w:?} channel {c}: fit {got} vs optimum {best} (scale {scale})"
            );
        }
        if w == TargetWeight::L2 {
            assert_eq!(f.objective_residual, f.relative_residual);
        }
        fits.push(f.coefficients);
    }
    assert_ne!(fits[0], fits[1], "relative weights change the fit");
    assert_ne!(fits[0], fits[2], "log weights change the fit");
}

/// The condition plan under an objective (SPEC 11) starts at the candidate whose row
/// `[1/pi, f_b]`, scaled per channel by the square root of the objective's weight at the
/// median over the basis and training materials there and averaged over channels, has
/// the largest norm; computed here from the materials' f64 values, candidate by
/// candidate. The plan records its objective.
#[test]
fn the_condition_plan_weighs_its_rows_by_the_shared_weights() {
    let coll = Collection::embedded_default();
    let basis = [0, 1, 2];
    let targets: Vec<usize> = (3..coll.len()).collect();
    let all: Vec<usize> = (0..coll.len()).collect();
    let w = TargetWeight::relative(0.01).unwrap();
    let fit = FitParams {
        stride: 12,
        objective: w,
        ..FitParams::default()
    };
    let cands = cell_candidates(&coll, &all, &fit).unwrap();
    let p = PlanParams {
        n: 3,
        criterion: Criterion::Condition,
        candidates_per_step: 0,
        fit: fit.clone(),
        ..PlanParams::default()
    };
    let pl = plan(&CpuBackend::new(), &coll, &basis, &targets, &cands, &p).unwrap();
    assert_eq!(pl.objective, "relative");
    let norm = |k: usize| -> f64 {
        let cand = &cands[k];
        let mut row = vec![0.0; basis.len() + 1];
        for c in 0..3 {
            let mut v: Vec<f64> = all
                .iter()
                .map(|&m| material_at(&coll.materials()[m], cand.wi, cand.wo).unwrap()[c])
                .collect();
            v.sort_by(f64::total_cmp);
            let n = v.len();
            let med = if n % 2 == 1 {
                v[n / 2]
            } else {
                0.5 * (v[n / 2 - 1] + v[n / 2])
            };
            let s = w.phi(med, cand.wi[2]).sqrt();
            row[0] += FRAC_1_PI * s / 3.0;
            for (j, &b) in basis.iter().enumerate() {
                row[j + 1] +=
                    material_at(&coll.materials()[b], cand.wi, cand.wo).unwrap()[c] * s / 3.0;
            }
        }
        row.iter().map(|v| v * v).sum()
    };
    let norms: Vec<f64> = (0..cands.len()).map(norm).collect();
    let best = (0..cands.len())
        .max_by(|&a, &b| norms[a].total_cmp(&norms[b]).then(b.cmp(&a)))
        .unwrap();
    let first = &pl.chosen[0];
    assert!(
        (norms[best] - norm(cands.iter().position(|c| c == first).unwrap())).abs()
            <= 1e-9 * norms[best],
        "the plan's first sample is not the weighted row of largest norm"
    );
    let l2 = plan(
        &CpuBackend::new(),
        &coll,
        &basis,
        &targets,
        &cands,
        &PlanParams {
            fit: FitParams {
                objective: TargetWeight::L2,
                ..fit
            },
            ..p
        },
    )
    .unwrap();
    assert_eq!(l2.objective, "l2");
    assert_ne!(l2.samples, pl.samples, "the weights move the plan");
}

/// `cv --acquisition` under an objective: every reconstruction (ours and the baseline's)
/// and every dense fit carries its appearance metrics (finite, FLIP and image error in
/// [0, 1]); the baseline, which has its own reconstructor, scores the same under every
/// objective of ours; the table shows the appearance metrics and the objective.
#[test]
fn acquisition_cv_under_an_objective_scores_appearance_beside_the_baseline() {
    let all = Collection::embedded_default();
    let coll = all.subset(&(0..10).collect::<Vec<_>>());
    let run = |w: TargetWeight| {
        let p = AcqCvParams {
            k: 2,
            plans: vec![Criterion::Error, Criterion::Condition, Criterion::Nielsen],
            ns: vec![3, 6],
            noises: vec![0.0],
            folds: 2,
            candidates_per_step: 200,
            render_size: 16,
            objective: ObjectiveParams::default().stride(8).objective(w),
            ..AcqCvParams::default()
        };
        acquisition_cv(&CpuBackend::new(), &coll, &p).unwrap()
    };
    let rel = run(TargetWeight::relative(0.01).unwrap());
    let l2 = run(TargetWeight::L2);
    assert_eq!(rel.objective, "relative");
    for r in &rel.results {
        let a = r.appearance.as_ref().expect("appearance means");
        assert!(r.mean_log_rmse.unwrap().is_finite() && r.dense_appearance.is_some());
        assert!((0.0..=1.0).contains(&a.flip) && (0.0..=1.0).contains(&a.image_error));
        for h in &r.held_out {
            let x = h.appearance.as_ref().expect("per material");
            assert_eq!(x.lights.len(), 4);
            assert!(x.log_rmse.is_finite() && x.mean_ciede2000.is_finite());
        }
    }
    let nielsen = |c: &brdf_basis::acquire::AcqCv| -> Vec<_> {
        c.results
            .iter()
            .filter(|r| r.plan == Criterion::Nielsen)
            .flat_map(|r| {
                r.held_out
                    .iter()
                    .map(|h| (h.material.clone(), h.rho, h.mae, h.appearance.clone()))
            })
            .collect()
    };
    assert_eq!(nielsen(&rel), nielsen(&l2));
    let md = rel.markdown();
    assert!(
        md.contains("Appearance (objective `relative`")
            && md.contains("| greedy | nielsen | 6 | 0 |"),
        "{md}"
    );
}

/// The facade's `plan_samples` refuses the `nielsen` criterion, as `brdf-basis plan` and
/// `PlanRequest::check` do, with the same refusal (the core's `plan` plans it for
/// `cv --acquisition`'s baseline).
#[test]
fn plan_samples_refuses_nielsen_as_the_plan_request_does() {
    let coll = Collection::embedded_default();
    let p = PlanParams {
        criterion: Criterion::Nielsen,
        ..PlanParams::default()
    };
    let cands = [brdf_basis::Candidate {
        wi: [0.0, 0.0, 1.0],
        wo: [0.0, 0.0, 1.0],
        cell: None,
    }];
    let e = brdf_basis::plan_samples(&CpuBackend::new(), &coll, &[0, 1], &[2, 3], &cands, &p)
        .expect_err("nielsen planned");
    assert!(matches!(e, brdf_basis::Error::Request(_)), "{e:?}");
    let mut r = brdf_basis::run::PlanRequest::new(vec![coll.materials()[0].name.clone()]);
    r.criterion = Criterion::Nielsen;
    let want = r.check().expect_err("nielsen accepted").to_string();
    assert_eq!(e.to_string(), want);
}

/// `fit --samples` has one door (issue 47): samples given as arrays (Python's
/// `fit_samples`) go through the same request as a samples file, with the same fit and
/// the same refusal of the grid fit's settings.
#[test]
fn fit_samples_from_arrays_is_the_request_of_a_samples_file() {
    use brdf_basis::run::{FitSamplesRequest, Samples};
    let coll = Collection::embedded_default();
    let basis = vec!["polished-gold".to_string(), "matte-white-paint".to_string()];
    let angles = vec![
        [10.0, 0.0, 20.0, 180.0],
        [30.0, 0.0, 40.0, 90.0],
        [50.0, 0.0, 10.0, 0.0],
    ];
    let rgb = vec![[0.2, 0.3, 0.4], [0.1, 0.2, 0.25], [0.15, 0.1, 0.3]];
    let dir = std::env::temp_dir().join(format!("bb-arrays-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("s.csv");
    let mut text = String::from("theta_i,phi_i,theta_o,phi_o,r,g,b\n");
    for (a, y) in angles.iter().zip(&rgb) {
        let row: Vec<String> = a.iter().chain(y).map(|v| format!("{v:?}")).collect();
        text += &(row.join(",") + "\n");
    }
    std::fs::write(&csv, text).unwrap();
    let from_file = FitSamplesRequest::new(basis.clone(), csv)
        .run(&Ctx::collection(&coll))
        .unwrap();
    let samples = Samples::Arrays {
        angles,
        rgb,
        sigma: None,
    };
    let mut req = FitSamplesRequest::of(basis, samples);
    let from_arrays = req.run(&Ctx::collection(&coll)).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(from_arrays.fit.coefficients, from_file.fit.coefficients);
    assert_eq!(from_arrays.warnings, from_file.warnings);
    assert!(req.input_files().is_empty());
    req.grid = brdf_basis::merl::GridSpec::default()
        .with_stride(4)
        .expect("stride 4");
    let e = req.check().unwrap_err().to_string();
    assert!(
        e.starts_with("--stride does not apply with --samples"),
        "{e}"
    );
}

/// A plan's objective is checked with its other settings, before any work, whatever the
/// criterion and targets (before: a `condition` plan without targets never formed its
/// shared weights, and an `eps` of -1 was planned without a word). An `eps` of -1 cannot
/// reach `plan` (issue 47): the weight refuses it when built, and the request names
/// `--eps`.
#[test]
fn plan_refuses_a_bad_eps_with_its_settings() {
    let want = "the relative objective's eps must be a positive number, not -1";
    let e = TargetWeight::relative(-1.0)
        .expect_err("eps -1")
        .to_string();
    assert_eq!(e, want);
    let coll = Collection::embedded_default();
    for criterion in [Criterion::Condition, Criterion::Error] {
        let mut r = brdf_basis::run::PlanRequest::new(vec![coll.materials()[0].name.clone()]);
        r.criterion = criterion;
        r.objective.eps = Some(-1.0);
        let e = r.check().expect_err("a plan with eps -1").to_string();
        assert_eq!(e, format!("--eps -1: {want}"), "{criterion:?}");
    }
}
