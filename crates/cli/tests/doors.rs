//! One door per command, three ways (issue 47): the same small settings given to the
//! command line, to the library's request and to Python give the same result (the same
//! bytes: the JSON text, the matrix, the image) and the same refusal of one invalid
//! setting, in the same words. This file holds the command line against the library;
//! `python/tests/test_doors.py` holds Python against the command line with the same
//! settings and the same refusal texts (written out in both files). Every run is on the
//! embedded default collection, strided, on the CPU: seconds each.

use crate::common::bin_cpu;
use brdf_basis::backend::weighted::ObjectiveKind;
use brdf_basis::distance::Metric;
use brdf_basis::merl::GridSpec;
use brdf_basis::run::{
    AcquisitionRequest, Ctx, CvRequest, DistanceOutput, DistanceRequest, FitRequest,
    FitSamplesRequest, FitTargets, ObjectiveSetting, PlanRequest, ReproduceRequest, Request,
    SelectMethod, SelectRequest,
};
use brdf_basis::select::cv::CvMethod;
use brdf_basis::{Collection, CpuBackend, Criterion};
use std::path::Path;

/// Runs the binary on `args` in `dir`; panics unless it succeeds.
fn cli_ok(dir: &Path, args: &[&str]) {
    let o = bin_cpu()
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run brdf-basis");
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// The binary's refusal of `args` run in `dir` (the message after `error: `).
fn cli_refusal(dir: &Path, args: &[&str]) -> String {
    let o = bin_cpu()
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run brdf-basis");
    assert!(!o.status.success(), "{args:?} succeeded");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    err.lines()
        .find_map(|l| l.strip_prefix("error: "))
        .unwrap_or_else(|| panic!("{args:?}: no `error: ` line in {err}"))
        .to_string()
}

/// The text of `dir/name`.
fn read(dir: &Path, name: &str) -> String {
    std::fs::read_to_string(dir.join(name)).expect("output")
}

/// JSON as the command line writes it: pretty, with a final newline.
fn pretty<T: serde::Serialize>(v: &T) -> String {
    serde_json::to_string_pretty(v).expect("json") + "\n"
}

fn grid(stride: usize) -> GridSpec {
    GridSpec::default().with_stride(stride).expect("stride")
}

fn names(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

const BASIS: [&str; 2] = ["polished-gold", "matte-white-paint"];

/// `distance`: the matrix, bit for bit; a collection of one material, refused.
#[test]
fn distance_door() {
    let d = tempfile::tempdir().expect("tmp");
    cli_ok(d.path(), &["distance", "--stride", "9", "--out", "d.npy"]);
    let saved = brdf_basis::io::saved::load_saved_matrix(&d.path().join("d.npy"))
        .expect("matrix")
        .matrix;
    let coll = Collection::embedded_default();
    let mut req = DistanceRequest::default();
    req.metric = Metric::BrdfIt;
    req.grid = grid(9);
    req.params(&coll).expect("params");
    let DistanceOutput::Matrix(m) = req
        .run(&Ctx::new(&CpuBackend::new(), &coll))
        .expect("distance")
    else {
        panic!("a tile");
    };
    assert_eq!(m.names(), saved.names());
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(m.as_full()), bits(saved.as_full()));
    // The refusal: a matrix of one material.
    let one = d.path().join("one.csv");
    std::fs::write(
        &one,
        "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\nalone,0.1,0.1,0.1,0.2,0.2,0.2,0.05,100\n",
    )
    .expect("csv");
    let cli = cli_refusal(d.path(), &["distance", "one.csv", "--out", "o.npy"]);
    let lib = req
        .params(&Collection::load(&one).expect("one"))
        .expect_err("one material")
        .to_string();
    assert_eq!(cli, lib);
    assert_eq!(
        lib,
        "a distance matrix needs at least 2 materials, the collection has 1"
    );
}

/// `select`: the JSON text of k-medoids with a seed; `--seed` to greedy, refused.
#[test]
fn select_door() {
    let d = tempfile::tempdir().expect("tmp");
    cli_ok(
        d.path(),
        &[
            "--seed", "4", "select", "--method", "kmedoids", "-k", "3", "--runs", "2", "--stride",
            "8", "--json", "s.json",
        ],
    );
    let mut req = SelectRequest::new(SelectMethod::Kmedoids);
    (req.k, req.runs, req.seed, req.grid) = (Some(3), Some(2), Some(4), grid(8));
    let coll = Collection::embedded_default();
    let out = req
        .run(&Ctx::new(&CpuBackend::new(), &coll))
        .expect("select");
    assert_eq!(read(d.path(), "s.json"), out.to_json());
    let cli = cli_refusal(
        d.path(),
        &[
            "--seed", "4", "select", "--method", "greedy", "-k", "3", "--json", "g.json",
        ],
    );
    let mut req = SelectRequest::new(SelectMethod::Greedy);
    (req.k, req.seed) = (Some(3), Some(4));
    assert_eq!(cli, req.check().expect_err("seed").to_string());
    assert_eq!(
        cli,
        "--seed applies to kmedoids, gcuk and ga, not to --method greedy"
    );
}

/// `fit`: the JSON text; `--objective l2 --eps 5`, refused.
#[test]
fn fit_door() {
    let d = tempfile::tempdir().expect("tmp");
    cli_ok(
        d.path(),
        &[
            "fit",
            "--basis",
            &BASIS.join(","),
            "--targets",
            "polished-copper,gloss-black-enamel",
            "--stride",
            "6",
            "--no-appearance",
            "--json",
            "f.json",
        ],
    );
    let mut req = FitRequest::new(names(&BASIS));
    req.targets = FitTargets::Named(names(&["polished-copper", "gloss-black-enamel"]));
    (req.grid, req.appearance) = (grid(6), false);
    let coll = Collection::embedded_default();
    let out = req.run(&Ctx::new(&CpuBackend::new(), &coll)).expect("fit");
    assert_eq!(read(d.path(), "f.json"), pretty(&out.file));
    let cli = cli_refusal(
        d.path(),
        &[
            "fit",
            "--basis",
            &BASIS.join(","),
            "--all-others",
            "--objective",
            "l2",
            "--eps",
            "5",
            "--json",
            "f2.json",
        ],
    );
    req.objective = ObjectiveSetting {
        objective: Some(ObjectiveKind::L2),
        eps: Some(5.0),
    };
    assert_eq!(cli, req.check().expect_err("eps").to_string());
    assert_eq!(
        cli,
        "--eps 5 applies to --objective relative, not to --objective l2: only the relative objective has an offset; leave --eps out"
    );
}

/// The samples of the `fit --samples` door (degrees, then r, g, b), as
/// `python/tests/test_doors.py` gives them.
pub(crate) const SAMPLES: &str = "theta_i,phi_i,theta_o,phi_o,r,g,b
10,0,20,180,0.21,0.18,0.12
30,0,40,90,0.35,0.3,0.2
50,0,10,0,0.12,0.1,0.07
0,0,60,45,0.18,0.16,0.1
20,90,20,270,2.5,2.1,1.4
45,0,45,180,1.1,0.9,0.6
";

/// `fit --samples`: the JSON text; `--objective log --eps 0.5`, refused.
#[test]
fn fit_samples_door() {
    let d = tempfile::tempdir().expect("tmp");
    std::fs::write(d.path().join("s.csv"), SAMPLES).expect("samples");
    let b = BASIS.join(",");
    cli_ok(
        d.path(),
        &[
            "fit",
            "--basis",
            &b,
            "--samples",
            "s.csv",
            "--json",
            "f.json",
        ],
    );
    let mut req = FitSamplesRequest::new(names(&BASIS), d.path().join("s.csv"));
    let coll = Collection::embedded_default();
    let out = req.run(&Ctx::collection(&coll)).expect("fit --samples");
    // The file records the samples file's path as given: relative on the command line.
    let mut file = out.file;
    file.fitted_from = Some("s.csv".into());
    let text = read(d.path(), "f.json");
    assert_eq!(text, pretty(&file));
    let cli = cli_refusal(
        d.path(),
        &[
            "fit",
            "--basis",
            &b,
            "--samples",
            "s.csv",
            "--objective",
            "log",
            "--eps",
            "0.5",
            "--json",
            "f2.json",
        ],
    );
    req.objective = ObjectiveSetting {
        objective: Some(ObjectiveKind::Log),
        eps: Some(0.5),
    };
    assert_eq!(cli, req.check().expect_err("eps").to_string());
    assert_eq!(
        cli,
        "--eps 0.5 applies to --objective relative, not to --objective log: only the relative objective has an offset; leave --eps out"
    );
}

/// `plan`: the JSON text of a condition plan; `--shortlist` with `random`, refused.
#[test]
fn plan_door() {
    let d = tempfile::tempdir().expect("tmp");
    let b = BASIS.join(",");
    cli_ok(
        d.path(),
        &[
            "plan",
            "--basis",
            &b,
            "-n",
            "4",
            "--criterion",
            "condition",
            "--out",
            "p.csv",
            "--json",
            "p.json",
        ],
    );
    let mut req = PlanRequest::new(names(&BASIS));
    (req.n, req.criterion) = (4, Criterion::Condition);
    let coll = Collection::embedded_default();
    let plan = req.run(&Ctx::new(&CpuBackend::new(), &coll)).expect("plan");
    assert_eq!(read(d.path(), "p.json"), pretty(&plan));
    let cli = cli_refusal(
        d.path(),
        &[
            "plan",
            "--basis",
            &b,
            "--criterion",
            "random",
            "--shortlist",
            "3",
            "--out",
            "q.csv",
        ],
    );
    let mut req = PlanRequest::new(names(&BASIS));
    (req.criterion, req.shortlist) = (Criterion::Random, Some(3));
    assert_eq!(cli, req.check().expect_err("shortlist").to_string());
    assert_eq!(
        cli,
        "--shortlist applies to error plans, not to --criterion random"
    );
}

/// `plan --seed` with a condition plan that examines every candidate
/// (`--candidates-per-step 0`: nothing drawn at random) is refused by name, by the
/// binary and the library alike, as other unused `--seed`s are; with a subset per step
/// the seed draws it and is taken.
#[test]
fn plan_refuses_a_seed_it_would_not_use() {
    let d = tempfile::tempdir().expect("tmp");
    let b = BASIS.join(",");
    let args = |cps: &'static str| {
        [
            "--seed",
            "7",
            "plan",
            "--basis",
            "",
            "-n",
            "2",
            "--criterion",
            "condition",
            "--candidates-per-step",
            cps,
            "--out",
            "p.csv",
        ]
    };
    let mut a = args("0");
    a[4] = &b;
    let cli = cli_refusal(d.path(), &a);
    assert_eq!(
        cli,
        "--seed 7 does not apply to plan --criterion condition --candidates-per-step 0: it examines every candidate at each step and draws nothing at random; leave it out"
    );
    let mut req = PlanRequest::new(names(&BASIS));
    (req.criterion, req.candidates_per_step, req.seed) = (Criterion::Condition, Some(0), Some(7));
    let e = req.check().expect_err("seed");
    assert_eq!(cli, e.to_string());
    assert!(
        matches!(&e, brdf_basis::run::Refusal::DoesNotApply { settings, .. } if settings[..] == ["--seed"]),
        "{e:?}"
    );
    req.seed = None;
    req.check().expect("condition, every candidate, no seed");
    (req.candidates_per_step, req.seed) = (Some(50), Some(7));
    req.check().expect("condition on a seeded subset");
    let mut a = args("50");
    a[4] = &b;
    cli_ok(d.path(), &a);
}

/// `tabulate --backend gpu` of a measured material (a table copied as it is, on the CPU)
/// is refused by name, as `render`, `plot` and `merge` refuse it; an analytic material
/// is evaluated on the back-end and takes it (not run here: CI's GPU may be absent).
#[test]
fn tabulate_refuses_the_gpu_for_a_table() {
    let d = tempfile::tempdir().expect("tmp");
    cli_ok(
        d.path(),
        &[
            "tabulate",
            "--material",
            "polished-gold",
            "--out",
            "gold.binary",
        ],
    );
    // `--backend gpu` alone (the harness's `bin_cpu` gives `--backend cpu`).
    let o = crate::common::bin_quiet()
        .args([
            "tabulate",
            "gold.binary",
            "--material",
            "gold",
            "--backend",
            "gpu",
            "--out",
            "copy.binary",
        ])
        .current_dir(d.path())
        .output()
        .expect("run brdf-basis");
    assert!(
        !o.status.success(),
        "tabulate --backend gpu of a table succeeded"
    );
    let err = String::from_utf8_lossy(&o.stderr);
    let cli = err
        .lines()
        .find_map(|l| l.strip_prefix("error: "))
        .unwrap_or_else(|| panic!("no `error: ` line in {err}"));
    assert_eq!(
        cli,
        "--backend gpu does not apply to tabulate --material gold: a measured material is a table on the MERL grid, copied as it is on the CPU with nothing to evaluate; leave it out"
    );
    assert!(!d.path().join("copy.binary").exists());
    cli_ok(
        d.path(),
        &[
            "tabulate",
            "gold.binary",
            "--material",
            "gold",
            "--out",
            "copy.binary",
        ],
    );
}

/// `cv`: the JSON text; `--runs` with greedy alone, refused.
#[test]
fn cv_door() {
    let d = tempfile::tempdir().expect("tmp");
    cli_ok(
        d.path(),
        &[
            "cv",
            "--methods",
            "greedy,random",
            "-k",
            "2",
            "--folds",
            "3",
            "--stride",
            "9",
            "--render-size",
            "16",
            "--no-appearance",
            "--json",
            "c.json",
        ],
    );
    let mut req = CvRequest::default();
    req.methods = vec![CvMethod::Greedy, CvMethod::Random];
    req.ks = vec![2];
    req.folds = 3;
    req.grid = grid(9);
    req.render_size = 16;
    req.appearance = false;
    let coll = Collection::embedded_default();
    req.check_count(coll.len()).expect("check");
    let res = req.run(&Ctx::new(&CpuBackend::new(), &coll)).expect("cv");
    assert_eq!(read(d.path(), "c.json"), pretty(&res));
    let cli = cli_refusal(
        d.path(),
        &[
            "cv",
            "--methods",
            "greedy",
            "--runs",
            "30",
            "--json",
            "c2.json",
        ],
    );
    let mut req = CvRequest::default();
    req.methods = vec![CvMethod::Greedy];
    req.runs = Some(30);
    assert_eq!(cli, req.check().expect_err("runs").to_string());
    assert_eq!(
        cli,
        "--runs applies to kmedoids and gcuk, not to --methods greedy"
    );
}

/// `cv --acquisition`: the JSON text; `--shortlist` with random plans, refused.
#[test]
fn acquisition_door() {
    let d = tempfile::tempdir().expect("tmp");
    cli_ok(
        d.path(),
        &[
            "cv",
            "--acquisition",
            "-k",
            "3",
            "--plans",
            "condition",
            "-n",
            "3",
            "--noise",
            "0",
            "--folds",
            "2",
            "--stride",
            "6",
            "--candidates-per-step",
            "200",
            "--render-size",
            "16",
            "--no-appearance",
            "--json",
            "a.json",
        ],
    );
    let mut req = AcquisitionRequest::default();
    req.k = 3;
    req.plans = vec![Criterion::Condition];
    req.ns = vec![3];
    req.noises = vec![0.0];
    req.folds = Some(2);
    req.grid = grid(6);
    req.candidates_per_step = Some(200);
    req.render_size = 16;
    req.appearance = false;
    let coll = Collection::embedded_default();
    let res = req
        .run(&Ctx::new(&CpuBackend::new(), &coll))
        .expect("cv --acquisition");
    assert_eq!(read(d.path(), "a.json"), pretty(&res));
    let cli = cli_refusal(
        d.path(),
        &[
            "cv",
            "--acquisition",
            "--plans",
            "random",
            "--shortlist",
            "3",
            "--json",
            "a2.json",
        ],
    );
    let mut req = AcquisitionRequest::default();
    req.plans = vec![Criterion::Random];
    req.shortlist = Some(3);
    assert_eq!(cli, req.check().expect_err("shortlist").to_string());
    assert_eq!(
        cli,
        "--shortlist applies to error plans, not to --plans random"
    );
}

/// `render`: the OpenEXR's pixels, bit for bit; `--size 0`, refused.
#[test]
fn render_door() {
    use brdf_basis::eval::render::{render_sphere, RenderParams};
    let d = tempfile::tempdir().expect("tmp");
    cli_ok(
        d.path(),
        &[
            "render",
            "--material",
            "polished-gold",
            "--size",
            "32",
            "--out",
            "r.exr",
        ],
    );
    let img = brdf_basis::io::image::read_exr(d.path().join("r.exr")).expect("exr");
    let coll = Collection::embedded_default();
    let gold = &coll.materials()[coll.index_of("polished-gold").expect("gold")];
    let p = RenderParams::default().with_size(32);
    let lib =
        render_sphere(&p, &brdf_basis::eval::shade::material_brdf(&gold.data)).expect("render");
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!((img.width, img.height), (lib.width, lib.height));
    assert_eq!(bits(&img.data), bits(&lib.data));
    let cli = cli_refusal(
        d.path(),
        &[
            "render",
            "--material",
            "polished-gold",
            "--size",
            "0",
            "--out",
            "r0.exr",
        ],
    );
    let lib = RenderParams::default()
        .with_size(0)
        .check()
        .expect_err("size 0")
        .to_string();
    assert_eq!(cli, lib);
    assert_eq!(cli, "invalid image size `0` (expected 1..=16384 pixels)");
}

/// `reproduce` (no Python door; its run takes minutes, so only the refusal):
/// `--cv-runs` with `--cv-folds 0`.
#[test]
fn reproduce_door_refusal() {
    let d = tempfile::tempdir().expect("tmp");
    let cli = cli_refusal(
        d.path(),
        &[
            "reproduce",
            "--cv-folds",
            "0",
            "--cv-runs",
            "3",
            "--out",
            "r",
        ],
    );
    let mut req = ReproduceRequest::default();
    req.cv_folds = 0;
    req.cv_runs = Some(3);
    assert_eq!(cli, req.check().expect_err("cv-runs").to_string());
    assert!(
        cli.starts_with("--cv-runs 3 applies to the cross-validation"),
        "{cli}"
    );
}
