//! One door per command (issue 34): a rule a combination of settings can break is made by
//! the command's request (`brdf_basis::run`), so the command line and the library refuse
//! it with the same words (Python's refusal is checked in `python/tests/test_requests.py`,
//! against the same text). Each case failed before on the door that lacked it: the library
//! planned a `nielsen` plan, and Python fitted a target given twice.

use crate::common::bin_cpu;
use brdf_basis::run::{
    AcquisitionRequest, Ctx, CvRequest, FitRequest, FitTargets, PlanRequest, Request, SelectMethod,
    SelectRequest,
};
use brdf_basis::{Collection, CpuBackend, Criterion};

/// The message the binary printed on stderr after `error: `.
fn cli_error(args: &[&str]) -> String {
    let d = tempfile::tempdir().expect("tmp");
    let mut args: Vec<String> = args.iter().map(|s| s.to_string()).collect();
    for a in args.iter_mut() {
        *a = a.replace("{dir}", &d.path().display().to_string());
    }
    let o = bin_cpu().args(&args).output().expect("run brdf-basis");
    assert!(!o.status.success(), "{args:?} succeeded");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    let line = err
        .lines()
        .find_map(|l| l.strip_prefix("error: "))
        .unwrap_or_else(|| panic!("no `error: ` line in {err}"));
    // Nothing was written: the refusal comes before any work.
    assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 0, "{args:?}");
    line.to_string()
}

/// `plan --criterion nielsen`: refused by the command line and by the library's request
/// (its `check` and its `run`), in the same words.
#[test]
fn plan_nielsen_is_refused_the_same_way_by_every_door() {
    let cli = cli_error(&[
        "plan",
        "--basis",
        "polished-gold,matte-white-paint",
        "-n",
        "5",
        "--criterion",
        "nielsen",
        "--out",
        "{dir}/plan.csv",
    ]);
    let mut req = PlanRequest::new(vec!["polished-gold".into(), "matte-white-paint".into()]);
    req.n = 5;
    req.criterion = Criterion::Nielsen;
    let lib = req.check().unwrap_err().to_string();
    assert_eq!(cli, lib);
    assert!(
        lib.starts_with("--criterion nielsen: the peer baseline"),
        "{lib}"
    );
    let coll = Collection::embedded_default();
    let run = req
        .run(&Ctx::new(&CpuBackend::new(), &coll))
        .unwrap_err()
        .to_string();
    assert_eq!(run, lib);
}

/// `select --method gcuk -k 5` and a GA setting for greedy: the same words from the
/// command line and from the request.
#[test]
fn select_rules_are_the_requests() {
    let cli = cli_error(&[
        "select",
        "--method",
        "gcuk",
        "-k",
        "5",
        "--json",
        "{dir}/g.json",
    ]);
    let mut req = SelectRequest::new(SelectMethod::Gcuk);
    req.k = Some(5);
    assert_eq!(cli, req.check().unwrap_err().to_string());
    let cli = cli_error(&[
        "select",
        "--method",
        "greedy",
        "-k",
        "3",
        "--ga-population",
        "8",
        "--json",
        "{dir}/g.json",
    ]);
    let mut req = SelectRequest::new(SelectMethod::Greedy);
    req.k = Some(3);
    req.ga_population = Some(8);
    assert_eq!(cli, req.check().unwrap_err().to_string());
    assert_eq!(cli, "--ga-population applies to ga, not to --method greedy");
}

/// `fit --targets X,X`: a target given twice is refused by the request the command line
/// and Python both build.
#[test]
fn fit_refuses_a_target_given_twice() {
    let cli = cli_error(&[
        "fit",
        "--basis",
        "polished-gold",
        "--targets",
        "matte-white-paint,matte-white-paint",
        "--json",
        "{dir}/f.json",
    ]);
    let mut req = FitRequest::new(vec!["polished-gold".into()]);
    req.targets = FitTargets::Named(vec!["matte-white-paint".into(), "matte-white-paint".into()]);
    let coll = Collection::embedded_default();
    let lib = req
        .run(&Ctx::new(&CpuBackend::new(), &coll))
        .unwrap_err()
        .to_string();
    assert_eq!(cli, lib);
    assert!(lib.contains("is given twice"), "{lib}");
}

/// The command line's defaults are the requests' (`--help` reads them from there).
#[test]
fn cli_defaults_are_the_requests() {
    let o = bin_cpu().args(["plan", "--help"]).output().expect("help");
    let help = String::from_utf8_lossy(&o.stdout);
    let d = PlanRequest::new(Vec::new());
    assert!(help.contains(&format!("[default: {}]", d.n)), "{help}");
    assert!(
        help.contains(&format!("[default: {}]", d.candidates_per_step())),
        "{help}"
    );
    // The lists' defaults are written in the help text: they must be the request's.
    let o = bin_cpu().args(["cv", "--help"]).output().expect("help");
    let help = String::from_utf8_lossy(&o.stdout)
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ");
    let a = AcquisitionRequest::default();
    // One `--render-size` and one `--folds` help for both modes: the same defaults.
    let c = CvRequest::default();
    assert_eq!((a.render_size, a.folds()), (c.render_size, c.folds));
    let join = |v: Vec<String>| v.join(",");
    for list in [
        join(a.plans.iter().map(|p| p.as_str().to_string()).collect()),
        join(a.ns.iter().map(|n| n.to_string()).collect()),
        join(a.noises.iter().map(|n| n.to_string()).collect()),
        join(
            CvRequest::default()
                .ks
                .iter()
                .map(|n| n.to_string())
                .collect(),
        ),
    ] {
        assert!(
            help.contains(&format!("[default: {list}]")),
            "{list}: {help}"
        );
    }
}

/// One seed default (issue 47): `--seed` left out is [`brdf_basis::run::SEED`] in every
/// request and in the core's parameter types.
#[test]
fn every_seed_default_is_the_one() {
    use brdf_basis::run::{FitSamplesRequest, ReproduceRequest, SEED};
    let seeds = [
        SelectRequest::new(SelectMethod::Kmedoids).seed(),
        PlanRequest::new(Vec::new()).seed(),
        CvRequest::default().seed,
        AcquisitionRequest::default().seed,
        ReproduceRequest::default().seed,
        FitSamplesRequest::new(Vec::new(), "s.csv".into()).seed,
        brdf_basis::select::GaParams::default().seed,
        brdf_basis::cluster::KMedoidsParams::new(3).seed,
        brdf_basis::cluster::GcukParams::default().seed,
        brdf_basis::select::cv::CvParams::default().seed,
        brdf_basis::acquire::PlanParams::default().seed,
        brdf_basis::acquire::AcqCvParams::default().seed,
        brdf_basis::experiment::ExperimentParams::default().seed,
    ];
    assert_eq!(seeds, [SEED; 13]);
    assert_eq!(SelectRequest::new(SelectMethod::Greedy).seed, None);
}
