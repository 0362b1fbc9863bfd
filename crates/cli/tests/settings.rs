//! No setting ignored in silence (issue 47): every flag of `select`, `plan`, `cv` and
//! `cv --acquisition` that only some methods (criteria, objectives) use is walked against
//! every method (criterion, objective). The request's `check` refuses a setting given to
//! a method that does not use it, naming the flag, and passes one that the method uses.
//! `--eps` is checked once, by the requests' `check`, before any collection or device.
//! The walks drive the library's requests; the binary is run only for `--help` (so that
//! a new flag cannot miss the walk) and for the refusals made before the request exists.

use crate::common::{bin_cpu, bin_quiet};
use brdf_basis::backend::weighted::ObjectiveKind;
use brdf_basis::cluster::KMedoidsAlgorithm;
use brdf_basis::distance::Metric;
use brdf_basis::run::{
    AcquisitionRequest, Ctx, CvRequest, FitRequest, FitSamplesRequest, ObjectiveSetting,
    PlanRequest, Request, SelectMethod, SelectRequest,
};
use brdf_basis::select::cv::CvMethod;
use brdf_basis::Criterion;
use std::collections::BTreeSet;

/// A setting of `select`: its flag, how it is given, the methods that use it.
type SelectSetting = (
    &'static str,
    fn(&mut SelectRequest),
    &'static [SelectMethod],
);

/// One material, as a list setting.
fn gold() -> Option<Vec<String>> {
    Some(vec!["polished-gold".to_string()])
}

fn select_settings() -> [SelectSetting; 18] {
    use SelectMethod::{Empirical, Ga, Gcuk, Greedy, Kmedoids, Swap};
    const FITTING: &[SelectMethod] = &[Empirical, Greedy, Swap, Ga];
    const ERROR: &[SelectMethod] = &[Greedy, Swap, Ga];
    const CLUSTERING: &[SelectMethod] = &[Kmedoids, Gcuk];
    [
        ("--k-min", |r| r.k_min = Some(2), CLUSTERING),
        ("--k-max", |r| r.k_max = Some(4), CLUSTERING),
        ("--runs", |r| r.runs = Some(2), CLUSTERING),
        (
            "--algorithm",
            |r| r.algorithm = Some(KMedoidsAlgorithm::Pam),
            &[Kmedoids],
        ),
        ("--population", |r| r.population = Some(10), &[Gcuk]),
        ("--generations", |r| r.generations = Some(10), &[Gcuk]),
        ("--more-than", |r| r.more_than = Some(2), &[Empirical]),
        (
            "--metric",
            |r| r.metric = Some(Metric::Euclidean),
            CLUSTERING,
        ),
        (
            "--objective",
            |r| r.objective.objective = Some(ObjectiveKind::Log),
            FITTING,
        ),
        ("--eps", |r| r.objective.eps = Some(0.02), FITTING),
        ("--candidates", |r| r.candidates = gold(), ERROR),
        ("--targets", |r| r.targets = gold(), ERROR),
        ("--init", |r| r.init = gold(), &[Swap, Ga]),
        ("--ga-population", |r| r.ga_population = Some(8), &[Ga]),
        ("--ga-generations", |r| r.ga_generations = Some(8), &[Ga]),
        ("--ga-crossover", |r| r.ga_crossover = Some(0.5), &[Ga]),
        ("--ga-mutation", |r| r.ga_mutation = Some(0.1), &[Ga]),
        ("--seed", |r| r.seed = Some(3), &[Kmedoids, Gcuk, Ga]),
    ]
}

/// The long flags of `brdf-basis <command> --help`.
fn help_flags(command: &[&str]) -> BTreeSet<String> {
    let o = bin_cpu()
        .args(command)
        .arg("--help")
        .output()
        .expect("help");
    assert!(o.status.success());
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .filter_map(|l| {
            let l = l.trim_start();
            let l = l.strip_prefix("-k, ").unwrap_or(l);
            let l = l.strip_prefix("-n, ").unwrap_or(l);
            let flag = l.split([' ', ',']).next().unwrap_or("");
            // A help text's line may start with a flag's name too (`--acquisition: ...`).
            let name = flag.starts_with("--")
                && flag.chars().all(|c| c.is_ascii_alphanumeric() || c == '-');
            name.then(|| flag.to_string())
        })
        .collect()
}

/// The flags of a command that apply whatever the method: not walked (`select` walks
/// `--seed`; `cv` uses it with every method).
const EVERY_METHOD: &[&str] = &[
    "--backend",
    "--seed",
    "--quiet",
    "--help",
    "--json",
    "--mask",
    "--weighting",
    "--stride",
    "--method",
    "--distances",
];

/// Every flag of `select --help` is walked (or applies to every method).
#[test]
fn every_select_flag_is_walked() {
    let walked: BTreeSet<String> = select_settings()
        .iter()
        .map(|s| s.0.to_string())
        .chain(EVERY_METHOD.iter().map(|s| s.to_string()))
        .collect();
    let help = help_flags(&["select"]);
    let missing: Vec<_> = help.difference(&walked).collect();
    assert!(missing.is_empty(), "select flags not walked: {missing:?}");
}

/// `select`: each method-specific setting against each method.
#[test]
fn select_refuses_every_setting_its_method_does_not_use() {
    for (flag, give, users) in select_settings() {
        for m in SelectMethod::ALL {
            let mut r = SelectRequest::new(m);
            let ranged = matches!(flag, "--k-min" | "--k-max");
            if !ranged && !matches!(m, SelectMethod::Gcuk | SelectMethod::Empirical) {
                r.k = Some(3);
            }
            give(&mut r);
            let got = r.check();
            if users.contains(&m) {
                assert!(got.is_ok(), "{flag} with --method {m}: {:?}", got.err());
            } else {
                let e = got
                    .expect_err(&format!("{flag} with --method {m} passed"))
                    .to_string();
                assert!(
                    e.starts_with(&format!("{flag} applies to "))
                        && e.ends_with(&format!("not to --method {m}")),
                    "{flag} with --method {m}: {e}"
                );
            }
        }
    }
}

/// `cv`: each method-specific setting against each method alone, and with a method
/// that uses it beside one that does not.
#[test]
fn cv_refuses_every_setting_no_listed_method_uses() {
    type Give = fn(&mut CvRequest);
    let settings: [(&str, Give, &[CvMethod]); 4] = [
        (
            "--runs",
            |r| r.runs = Some(2),
            &[CvMethod::Kmedoids, CvMethod::Gcuk],
        ),
        (
            "--metric",
            |r| r.metric = Some(Metric::Euclidean),
            &[CvMethod::Kmedoids, CvMethod::Gcuk],
        ),
        (
            "--ga-population",
            |r| r.ga_population = Some(8),
            &[CvMethod::Ga],
        ),
        (
            "--ga-generations",
            |r| r.ga_generations = Some(8),
            &[CvMethod::Ga],
        ),
    ];
    for (flag, give, users) in settings {
        for m in CvMethod::ALL {
            let mut r = CvRequest::default();
            r.methods = vec![m];
            give(&mut r);
            let got = r.check();
            if users.contains(&m) {
                assert!(got.is_ok(), "{flag} with --methods {m}: {:?}", got.err());
            } else {
                let e = got
                    .expect_err(&format!("{flag} with --methods {m} passed"))
                    .to_string();
                assert_eq!(
                    e,
                    format!(
                        "{flag} applies to {}, not to --methods {m}",
                        if users.len() == 2 {
                            "kmedoids and gcuk"
                        } else {
                            "ga"
                        }
                    )
                );
            }
            let mut r = CvRequest::default();
            r.methods = vec![CvMethod::Random, users[0]];
            give(&mut r);
            assert!(
                r.check().is_ok(),
                "{flag} with --methods random,{}",
                users[0]
            );
        }
    }
    // Every flag of `cv --help` is walked, applies to every method, or is one of
    // `--acquisition`'s (walked below).
    let walked = [
        "--runs",
        "--metric",
        "--ga-population",
        "--ga-generations",
        "--objective",
        "--eps",
        "--methods",
        "--folds",
        "--render-size",
        "--no-appearance",
        "--markdown",
        "--acquisition",
        "--plans",
        "--noise",
        "--no-ridge",
        "--figure",
        "--candidates-per-step",
        "--shortlist",
        "--restarts",
        "--test",
    ];
    let known: BTreeSet<String> = walked
        .iter()
        .chain(EVERY_METHOD)
        .map(|s| s.to_string())
        .collect();
    let missing: Vec<_> = help_flags(&["cv"]).difference(&known).cloned().collect();
    assert!(missing.is_empty(), "cv flags not walked: {missing:?}");
}

/// A plan setting: flag, how it is given to `plan` and to `cv --acquisition`, the
/// criteria that use it.
type PlanSetting = (
    &'static str,
    fn(&mut PlanRequest),
    fn(&mut AcquisitionRequest),
    &'static [Criterion],
);

/// `plan` and `cv --acquisition`: `--candidates-per-step`, `--shortlist` and
/// `--restarts` against each criterion.
#[test]
fn plans_refuse_every_setting_their_criterion_does_not_use() {
    use Criterion::{Condition, Error, Nielsen, Random};
    let settings: [PlanSetting; 3] = [
        (
            "--candidates-per-step",
            |r| r.candidates_per_step = Some(50),
            |r| r.candidates_per_step = Some(50),
            &[Error, Condition, Nielsen],
        ),
        (
            "--shortlist",
            |r| r.shortlist = Some(4),
            |r| r.shortlist = Some(4),
            &[Error],
        ),
        (
            "--restarts",
            |r| r.restarts = Some(2),
            |r| r.restarts = Some(2),
            &[Error],
        ),
    ];
    for (flag, plan, acq, users) in settings {
        for c in [Error, Condition, Random, Nielsen] {
            let mut a = AcquisitionRequest::default();
            a.plans = vec![c];
            acq(&mut a);
            let got = a.check();
            if users.contains(&c) {
                assert!(got.is_ok(), "{flag} with --plans {c:?}: {:?}", got.err());
            } else {
                let e = got.expect_err(flag).to_string();
                assert!(
                    e.starts_with(&format!("{flag} applies to "))
                        && e.ends_with(&format!("plans, not to --plans {}", c.as_str())),
                    "{e}"
                );
            }
            if c == Nielsen {
                continue; // `plan` refuses the criterion itself.
            }
            let mut p = PlanRequest::new(vec!["polished-gold".into()]);
            p.criterion = c;
            plan(&mut p);
            let got = p.check();
            if users.contains(&c) {
                assert!(
                    got.is_ok(),
                    "{flag} with --criterion {c:?}: {:?}",
                    got.err()
                );
            } else {
                let e = got.expect_err(flag).to_string();
                assert!(
                    e.ends_with(&format!("plans, not to --criterion {}", c.as_str())),
                    "{e}"
                );
            }
        }
    }
}

/// `check` of each request that takes `--objective` and `--eps`.
/// A request's `check` given an objective: its refusal, or an empty string.
type ObjectiveCheck = Box<dyn Fn(ObjectiveSetting) -> String>;

fn objective_checks() -> Vec<(&'static str, ObjectiveCheck)> {
    let show = |r: Result<(), brdf_basis::run::Refusal>| {
        r.err().map(|e| e.to_string()).unwrap_or_default()
    };
    vec![
        (
            "fit",
            Box::new(move |o| {
                let mut r = FitRequest::new(vec!["polished-gold".into()]);
                r.objective = o;
                show(r.check())
            }),
        ),
        (
            "fit --samples",
            Box::new(move |o| {
                let mut r = FitSamplesRequest::new(vec!["polished-gold".into()], "s.csv".into());
                r.objective = o;
                show(r.check())
            }),
        ),
        (
            "select --method greedy",
            Box::new(move |o| {
                let mut r = SelectRequest::new(SelectMethod::Greedy);
                r.k = Some(3);
                r.objective = o;
                show(r.check())
            }),
        ),
        (
            "plan",
            Box::new(move |o| {
                let mut r = PlanRequest::new(vec!["polished-gold".into()]);
                r.objective = o;
                show(r.check())
            }),
        ),
        (
            "cv",
            Box::new(move |o| {
                let mut r = CvRequest::default();
                r.objective = o;
                show(r.check())
            }),
        ),
        (
            "cv --acquisition",
            Box::new(move |o| {
                let mut r = AcquisitionRequest::default();
                r.objective = o;
                show(r.check())
            }),
        ),
    ]
}

/// `--eps` applies to `--objective relative` (given or the default) only, and must be a
/// positive number: every request's `check` says so, naming `--eps`.
#[test]
fn eps_is_checked_once_by_every_request() {
    for (command, check) in objective_checks() {
        for kind in [
            None,
            Some(ObjectiveKind::Relative),
            Some(ObjectiveKind::L2),
            Some(ObjectiveKind::Log),
        ] {
            let relative = matches!(kind, None | Some(ObjectiveKind::Relative));
            for eps in [None, Some(0.02)] {
                let e = check(ObjectiveSetting {
                    objective: kind,
                    eps,
                });
                if relative || eps.is_none() {
                    assert_eq!(e, "", "{command} {kind:?} {eps:?}");
                } else {
                    let name = kind.map(|k| k.name()).unwrap_or_default();
                    assert_eq!(
                        e,
                        format!("--eps 0.02 applies to --objective relative, not to --objective {name}: only the relative objective has an offset; leave --eps out"),
                        "{command}"
                    );
                }
            }
            if !relative {
                continue;
            }
            for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let e = check(ObjectiveSetting {
                    objective: kind,
                    eps: Some(bad),
                });
                assert_eq!(
                    e,
                    format!("--eps {bad}: the relative objective's eps must be a positive number, not {bad}"),
                    "{command}"
                );
            }
        }
    }
}

/// The message the binary printed after `error: ` (it must fail).
fn cli_error(args: &[&str]) -> String {
    let o = bin_cpu().args(args).output().expect("run brdf-basis");
    assert!(!o.status.success(), "{args:?} succeeded");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    err.lines()
        .find_map(|l| l.strip_prefix("error: "))
        .unwrap_or_else(|| panic!("{args:?}: no `error: ` line in {err}"))
        .to_string()
}

/// A bad `--eps` is refused before the collection is read (here: a file that does not
/// exist) and before any output is planned; the cases of the issue are refused by the
/// binary in the request's words.
#[test]
fn the_binary_refuses_before_any_work() {
    let d = tempfile::tempdir().expect("tmp");
    let json = d.path().join("out.json");
    let json = json.to_str().expect("utf-8");
    let csv = d.path().join("p.csv");
    let csv = csv.to_str().expect("utf-8");
    let missing = "no-such-collection.csv";
    for args in [
        vec!["fit", missing, "--basis", "polished-gold", "--all-others"],
        vec![
            "fit",
            missing,
            "--basis",
            "polished-gold",
            "--samples",
            "s.csv",
        ],
        vec!["select", missing, "--method", "greedy", "-k", "3"],
        vec!["cv", missing],
        vec!["cv", missing, "--acquisition"],
    ] {
        let mut args = args.clone();
        args.extend(["--eps=0", "--json", json]);
        let e = cli_error(&args);
        assert_eq!(
            e, "--eps 0: the relative objective's eps must be a positive number, not 0",
            "{args:?}"
        );
    }
    let e = cli_error(&[
        "plan",
        missing,
        "--basis",
        "polished-gold",
        "--eps=-1",
        "--out",
        csv,
    ]);
    assert!(e.starts_with("--eps -1: "), "{e}");
    for (args, want) in [
        (
            &["select", "--method", "kmedoids", "-k", "3", "--objective", "log"][..],
            "--objective applies to empirical, greedy, swap and ga, not to --method kmedoids",
        ),
        (
            &["select", "--method", "gcuk", "--eps", "0.5"],
            "--eps applies to empirical, greedy, swap and ga, not to --method gcuk",
        ),
        (
            &["select", "--method", "greedy", "-k", "3", "--runs", "50"],
            "--runs applies to kmedoids and gcuk, not to --method greedy",
        ),
        (
            &["select", "--method", "greedy", "--algorithm", "pam", "-k", "3"],
            "--algorithm applies to kmedoids, not to --method greedy",
        ),
        (
            &["fit", "--basis", "polished-gold", "--all-others", "--objective", "l2", "--eps", "5"],
            "--eps 5 applies to --objective relative, not to --objective l2: only the relative objective has an offset; leave --eps out",
        ),
        (
            &["cv", "--methods", "greedy,swap", "--runs", "30"],
            "--runs applies to kmedoids and gcuk, not to --methods greedy,swap",
        ),
        (
            &["plan", "--basis", "polished-gold", "--criterion", "random", "--shortlist", "3"],
            "--shortlist applies to error plans, not to --criterion random",
        ),
    ] {
        let mut args = args.to_vec();
        args.extend(["--json", json]);
        if args[0] == "plan" {
            args.extend(["--out", csv]);
        }
        assert_eq!(cli_error(&args), want, "{args:?}");
    }
    // `cv --acquisition` has no request field for the selection methods' settings: the
    // command line refuses them.
    for flag in ["--runs", "--metric", "--ga-population", "--ga-generations"] {
        let value = if flag == "--metric" {
            "euclidean"
        } else {
            "30"
        };
        let e = cli_error(&["cv", "--acquisition", flag, value, "--json", json]);
        assert!(
            e.starts_with(&format!("{flag} applies only without --acquisition")),
            "{e}"
        );
    }
    let e = cli_error(&["cv", "--acquisition", "-k", "3,5", "--json", json]);
    assert!(
        e.starts_with("-k 3,5: cv --acquisition takes one basis size"),
        "{e}"
    );
    assert_eq!(std::fs::read_dir(d.path()).expect("dir").count(), 0);
}

/// `--seed` given to a command that draws nothing at random, and `--backend gpu` given to
/// one that never opens a back-end, are refused by name before any work (issue 47:
/// before, both were ignored without a word); `select` refuses `--seed` by method.
#[test]
fn unused_global_flags_are_refused_by_name() {
    let missing = "no-such-collection.csv";
    for (args, want) in [
        (
            &["--seed", "3", "distance", missing, "--out", "d.npy"][..],
            "--seed 3 does not apply to distance: it draws nothing at random; leave it out",
        ),
        (
            &["fit", missing, "--basis", "polished-gold", "--seed", "2", "--json", "f.json"],
            "--seed 2 does not apply to fit: it draws nothing at random; leave it out",
        ),
        (
            &["render", missing, "--material", "polished-gold", "--out", "r.exr", "--backend", "gpu"],
            "--backend gpu does not apply to render: it renders on the CPU; leave it out",
        ),
        (
            &["fit", missing, "--basis", "polished-gold", "--samples", "s.csv", "--backend", "gpu", "--json", "f.json"],
            "--backend gpu does not apply to fit --samples: the fit from samples solves its least-squares problem on the CPU (no grid cells to tabulate, no Gram matrix); leave it out",
        ),
        (
            &["select", missing, "--method", "greedy", "-k", "3", "--seed", "3", "--json", "s.json"],
            "--seed applies to kmedoids, gcuk and ga, not to --method greedy",
        ),
        (
            &["select", "--method", "gcuk", "--distances", "saved.npy", "--backend", "gpu", "--json", "s.json"],
            "--backend gpu does not apply with --distances: a saved matrix is clustered on the CPU, with no distance to compute; leave it out",
        ),
    ] {
        let o = bin_quiet().args(args).output().expect("run brdf-basis");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        let got = err.lines().find_map(|l| l.strip_prefix("error: "));
        assert_eq!(got, Some(want), "{args:?}: {err}");
    }
}

/// `select`'s JSON records what chose the basis (issue 47): the fit objective and its eps
/// (methods that fit), and the grid (every method); the keys it had keep their values.
#[test]
fn select_json_records_what_chose_the_basis() {
    use brdf_basis::select::SelectOutput;
    let coll = brdf_basis::Collection::embedded_default();
    let cpu = brdf_basis::CpuBackend::new();
    let mut r = SelectRequest::new(SelectMethod::Greedy);
    r.k = Some(2);
    r.grid = brdf_basis::merl::GridSpec::default()
        .with_stride(8)
        .expect("stride 8");
    r.objective.eps = Some(0.02);
    let out = r.run(&Ctx::new(&cpu, &coll)).expect("greedy");
    let v: serde_json::Value = serde_json::from_str(&out.to_json()).expect("json");
    assert_eq!(v["fit_objective"], "relative");
    assert_eq!(v["eps"], 0.02);
    assert_eq!(
        v["objective"], "mean-relative-residual",
        "the score's name, as before"
    );
    assert_eq!(
        (&v["mask"], &v["weighting"], &v["stride"]),
        (&"evaluation".into(), &"uniform".into(), &8.into())
    );
    assert_eq!(SelectOutput::from_json(&out.to_json()), Ok(out));
    // l2 has no eps; k-medoids has no fit objective, only the grid of its distances.
    r.objective = ObjectiveSetting {
        objective: Some(ObjectiveKind::L2),
        eps: None,
    };
    let v: serde_json::Value =
        serde_json::from_str(&r.run(&Ctx::new(&cpu, &coll)).expect("l2").to_json()).expect("json");
    assert_eq!(v["fit_objective"], "l2");
    assert!(v.get("eps").is_none(), "{v}");
    let mut r = SelectRequest::new(SelectMethod::Kmedoids);
    r.k = Some(2);
    r.runs = Some(1);
    r.grid = brdf_basis::merl::GridSpec::default()
        .with_stride(8)
        .expect("stride 8");
    let v: serde_json::Value =
        serde_json::from_str(&r.run(&Ctx::new(&cpu, &coll)).expect("kmedoids").to_json())
            .expect("json");
    assert!(
        v.get("fit_objective").is_none() && v.get("eps").is_none(),
        "{v}"
    );
    assert_eq!(v["stride"], 8);
    assert_eq!(v["metric"], "brdf-it");
}

/// How a flag of a command is shown to be used or refused (the table of
/// [`every_flag_of_every_command_is_classified`]).
#[derive(Clone, Copy, Debug)]
enum Use {
    /// A global flag used by every run of the command: the back-end, the seed of every
    /// random step, progress bars.
    Global,
    /// Used by every run of the command (an output, an input, a setting of every mode).
    Always,
    /// Used by some methods or criteria only: walked against each by this file's walks of
    /// the requests (`select`, `plan`, `cv`, the objective's `--eps`).
    Walked,
    /// Used in some modes only: given in a mode (these arguments) where it does not
    /// apply, the binary refuses it by name before any work.
    RefusedWith(&'static [&'static str]),
}

/// Every flag of every command, by how it is used ([`Use`]).
fn flag_uses() -> Vec<(&'static str, &'static str, Use)> {
    use Use::*;
    const SAMPLES: &[&str] = &["--samples", "s.csv"];
    const NO_ACQUISITION: &[&str] = &[];
    const ACQUISITION: &[&str] = &["--acquisition"];
    const EXR_ALONE: &[&str] = &[];
    let mut t = vec![];
    for c in [
        "info",
        "tabulate",
        "distance",
        "select",
        "fit",
        "render",
        "reproduce",
        "cv",
        "plot",
        "plan",
        "merge",
    ] {
        t.push((c, "--quiet", Global));
    }
    // `--seed`: used by the commands that draw at random (by `select`'s seeded methods,
    // walked), refused by the others; `--backend gpu`: refused by the commands and modes
    // that never open a back-end (`--backend cpu` and `auto` are what they do).
    for c in ["reproduce", "cv", "plan"] {
        t.push((c, "--seed", Global));
    }
    for c in [
        "info", "tabulate", "distance", "fit", "render", "plot", "merge",
    ] {
        t.push((c, "--seed", RefusedWith(&[])));
    }
    for c in ["info", "tabulate", "distance", "reproduce", "cv", "plan"] {
        t.push((c, "--backend", Global));
    }
    for c in ["render", "plot", "merge"] {
        t.push((c, "--backend", RefusedWith(&[])));
    }
    t.push(("fit", "--backend", RefusedWith(SAMPLES)));
    t.push((
        "select",
        "--backend",
        RefusedWith(&["--distances", "saved.npy"]),
    ));
    for (c, f) in [
        ("tabulate", "--material"),
        ("tabulate", "--out"),
        ("distance", "--metric"),
        ("distance", "--weighting"),
        ("distance", "--mask"),
        ("distance", "--stride"),
        ("distance", "--lobe"),
        ("distance", "--tile"),
        ("distance", "--band-rows"),
        ("distance", "--out"),
        ("fit", "--basis"),
        ("fit", "--objective"),
        ("fit", "--json"),
        ("fit", "--export"),
        ("fit", "--samples"),
        ("render", "--material"),
        ("render", "--fit"),
        ("render", "--out"),
        ("render", "--png"),
        ("render", "--light"),
        ("render", "--size"),
        ("reproduce", "--out"),
        ("reproduce", "--force"),
        ("reproduce", "--no-selection"),
        ("reproduce", "--no-acquisition"),
        ("reproduce", "--no-appearance"),
        ("cv", "--methods"),
        ("cv", "--folds"),
        ("cv", "--weighting"),
        ("cv", "--mask"),
        ("cv", "--stride"),
        ("cv", "--render-size"),
        ("cv", "--objective"),
        ("cv", "--no-appearance"),
        ("cv", "--acquisition"),
        ("cv", "--json"),
        ("cv", "--markdown"),
        ("plot", "--material"),
        ("plot", "--fit"),
        ("plot", "--out"),
        ("plot", "--angles"),
        ("plan", "--basis"),
        ("plan", "--criterion"),
        ("plan", "--targets"),
        ("plan", "--candidates"),
        ("plan", "--objective"),
        ("plan", "--out"),
        ("plan", "--json"),
        ("merge", "--out"),
    ] {
        t.push((c, f, Always));
    }
    // `select`: every flag but the global ones and those of every method is walked
    // (`every_select_flag_is_walked`).
    for s in select_settings() {
        t.push(("select", s.0, Walked));
    }
    for f in EVERY_METHOD {
        if !["--backend", "--seed", "--quiet", "--help"].contains(f) {
            t.push(("select", f, Always));
        }
    }
    for (c, f) in [
        ("fit", "--eps"),
        ("plan", "--eps"),
        ("plan", "--candidates-per-step"),
        ("plan", "--shortlist"),
        ("plan", "--restarts"),
        ("cv", "--eps"),
    ] {
        t.push((c, f, Walked));
    }
    for f in [
        "--targets",
        "--all-others",
        "--weighting",
        "--mask",
        "--stride",
        "--solver",
        "--gram",
        "--no-appearance",
    ] {
        t.push(("fit", f, RefusedWith(SAMPLES)));
    }
    for f in ["--metric", "--runs", "--ga-population", "--ga-generations"] {
        t.push(("cv", f, RefusedWith(ACQUISITION)));
    }
    for f in [
        "--no-ridge",
        "--plans",
        "--noise",
        "--candidates-per-step",
        "--shortlist",
        "--restarts",
        "--figure",
        "--test",
    ] {
        t.push(("cv", f, RefusedWith(NO_ACQUISITION)));
    }
    for f in ["--exposure", "--gamma", "--heatmap"] {
        t.push(("render", f, RefusedWith(EXR_ALONE)));
    }
    // The paper's pipeline (section VI) runs whatever --no-selection, --no-acquisition and
    // --no-appearance leave out; the Acquisition and Appearance sections fold by
    // --cv-folds too (5 when 0).
    for f in [
        "--runs",
        "--stride",
        "--k-min",
        "--k-max",
        "--gcuk-k-max",
        "--render-size",
        "--showcase",
        "--paper-bases",
        "--cv-folds",
    ] {
        t.push(("reproduce", f, Always));
    }
    t.push(("reproduce", "--cv-runs", RefusedWith(&["--cv-folds", "0"])));
    t
}

/// The arguments that give `flag` to `command` (a value of the right kind), after the
/// arguments that make a run of it (on a collection file that does not exist).
fn giving(command: &str, flag: &str) -> Vec<&'static str> {
    let mut a: Vec<&'static str> = match command {
        "fit" => vec![
            "fit",
            "no-such-collection.csv",
            "--basis",
            "polished-gold",
            "--json",
            "f.json",
        ],
        "cv" => vec![
            "cv",
            "no-such-collection.csv",
            "--methods",
            "greedy",
            "--json",
            "c.json",
        ],
        "reproduce" => vec!["reproduce", "no-such-collection.csv", "--out", "r"],
        "render" => vec![
            "render",
            "no-such-collection.csv",
            "--material",
            "polished-gold",
            "--out",
            "r.exr",
        ],
        "info" => vec!["info"],
        "tabulate" => vec![
            "tabulate",
            "no-such-collection.csv",
            "--material",
            "polished-gold",
            "--out",
            "t.binary",
        ],
        "distance" => vec!["distance", "no-such-collection.csv", "--out", "d.npy"],
        "plot" => vec![
            "plot",
            "no-such-collection.csv",
            "--material",
            "polished-gold",
            "--out",
            "p.svg",
        ],
        "merge" => vec!["merge", "no-such-collection.npy", "--out", "m.npy"],
        "select" => vec![
            "select", "--method", "kmedoids", "-k", "3", "--json", "s.json",
        ],
        _ => panic!("no run of {command}"),
    };
    a.extend(match flag {
        "--targets" => vec!["--targets", "polished-copper"],
        "--all-others" => vec!["--all-others"],
        "--weighting" => vec!["--weighting", "solid-angle"],
        "--mask" => vec!["--mask", "valid"],
        "--stride" => vec!["--stride", "4"],
        "--solver" => vec!["--solver", "pgd"],
        "--gram" => vec!["--gram", "grid"],
        "--no-appearance" => vec!["--no-appearance"],
        "--metric" => vec!["--metric", "euclidean"],
        "--runs" => vec!["--runs", "3"],
        "--ga-population" => vec!["--ga-population", "8"],
        "--ga-generations" => vec!["--ga-generations", "3"],
        "--no-ridge" => vec!["--no-ridge"],
        "--plans" => vec!["--plans", "random"],
        "--noise" => vec!["--noise", "0.1"],
        "--candidates-per-step" => vec!["--candidates-per-step", "5"],
        "--shortlist" => vec!["--shortlist", "4"],
        "--restarts" => vec!["--restarts", "2"],
        "--figure" => vec!["--figure", "f.png"],
        "--test" => vec!["--test", "polished-gold"],
        "--exposure" => vec!["--exposure", "1"],
        "--gamma" => vec!["--gamma", "1.8"],
        "--heatmap" => vec!["--heatmap", "h.png"],
        "--cv-runs" => vec!["--cv-runs", "3"],
        "--seed" => vec!["--seed", "3"],
        "--backend" => vec!["--backend", "gpu"],
        _ => panic!("no value of {flag}"),
    });
    a
}

/// No setting ignored in silence (issue 47), for every command: each flag of each
/// command's `--help` is classified ([`Use`]), so that a new flag cannot slip by, and each
/// flag that only some modes use is refused by name, before any work (here: before the
/// collection, a file that does not exist, is read), when given in a mode that does not.
#[test]
fn every_flag_of_every_command_is_classified() {
    let top = bin_cpu().arg("--help").output().expect("help");
    let commands: BTreeSet<String> = String::from_utf8_lossy(&top.stdout)
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .filter(|c| c != "help")
        .collect();
    let uses = flag_uses();
    let classified: BTreeSet<String> = uses.iter().map(|u| u.0.to_string()).collect();
    assert_eq!(commands, classified, "commands");
    for c in &commands {
        let help = help_flags(&[c]);
        let table: BTreeSet<String> = uses
            .iter()
            .filter(|u| u.0 == c)
            .map(|u| u.1.to_string())
            .collect();
        assert_eq!(help, table, "flags of `{c}`: --help against the table");
    }
    for (command, flag, u) in uses {
        if let Use::RefusedWith(mode) = u {
            let mut args = giving(command, flag);
            args.extend_from_slice(mode);
            // `--backend gpu` in place of the harness's `--backend cpu`.
            let mut bin = match flag {
                "--backend" => bin_quiet(),
                _ => bin_cpu(),
            };
            let o = bin.args(&args).output().expect("run brdf-basis");
            let e = String::from_utf8_lossy(&o.stderr);
            // clap's `requires` names what is missing: --heatmap needs --fit.
            let named = if flag == "--heatmap" { "--fit" } else { flag };
            assert!(
                !o.status.success() && e.contains(named) && !e.contains("no-such-collection"),
                "{args:?}: {e}"
            );
        }
    }
}
