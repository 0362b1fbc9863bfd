//! The requests' refusals, matched by variant.

use super::*;
use crate::acquire::Criterion;

/// A refusal names its rule and setting as variants a caller can match, with the
/// command line's message as its `Display`.
#[test]
fn refusals_are_variants_naming_the_setting() {
    let mut r = SelectRequest::new(SelectMethod::Kmedoids);
    r.objective.objective = Some(ObjectiveKind::Log);
    let e = r.check().expect_err("an objective for kmedoids");
    assert!(
        matches!(&e, Refusal::NotApplicable { setting: "--objective", not_to, .. } if not_to == "--method kmedoids"),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        "--objective applies to empirical, greedy, swap and ga, not to --method kmedoids"
    );
    assert_eq!(e.setting(), Some("--objective"));

    let mut r = SelectRequest::new(SelectMethod::Kmedoids);
    (r.k, r.k_min) = (Some(3), Some(2));
    assert_eq!(
        r.check(),
        Err(Refusal::Conflict {
            a: "-k",
            b: "--k-min/--k-max"
        })
    );

    let mut r = SelectRequest::new(SelectMethod::Greedy);
    r.k = Some(3);
    r.objective = ObjectiveSetting {
        objective: Some(ObjectiveKind::L2),
        eps: Some(0.5),
    };
    let e = r.check().expect_err("eps with l2");
    assert!(
        matches!(&e, Refusal::NotApplicable { setting: "--eps", value: Some(v), .. } if v == "0.5"),
        "{e:?}"
    );
    r.objective = ObjectiveSetting {
        objective: None,
        eps: Some(-1.0),
    };
    let e = r.check().expect_err("eps -1");
    assert!(
        matches!(
            &e,
            Refusal::OutOfRange {
                setting: "--eps",
                ..
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().starts_with("--eps -1: "), "{e}");

    let r = SelectRequest::new(SelectMethod::Swap);
    assert!(matches!(
        r.check(),
        Err(Refusal::Missing { setting: "-k", .. })
    ));
}

/// Plan, fit --samples, cv --acquisition and reproduce refusals by variant.
#[test]
fn refusals_of_the_other_requests_are_variants() {
    let mut p = PlanRequest::new(vec!["polished-gold".into()]);
    p.criterion = Criterion::Random;
    p.shortlist = Some(4);
    let e = p.check().expect_err("shortlist for random");
    assert!(
        matches!(
            &e,
            Refusal::NotApplicable {
                setting: "--shortlist",
                ..
            }
        ),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        "--shortlist applies to error plans, not to --criterion random"
    );
    p.criterion = Criterion::Error;
    p.shortlist = None;
    p.restarts = Some(65);
    assert!(matches!(
        p.check(),
        Err(Refusal::OutOfRange { setting: "--restarts", value: Some(v), .. }) if v == "65"
    ));

    let mut f = FitSamplesRequest::new(vec!["a".into()], "s.csv".into());
    f.grid = crate::merl::GridSpec::default()
        .with_stride(2)
        .expect("stride 2")
        .with_mask(crate::merl::Mask::Valid);
    let e = f.check().expect_err("grid with --samples");
    assert!(
        matches!(&e, Refusal::DoesNotApply { settings, .. } if settings[..] == ["--stride", "--mask"]),
        "{e:?}"
    );
    assert!(
        e.to_string()
            .starts_with("--stride, --mask do not apply with --samples: "),
        "{e}"
    );

    let a = AcquisitionRequest {
        ns: vec![5, 5],
        ..Default::default()
    };
    assert_eq!(
        a.check(),
        Err(Refusal::Duplicate {
            setting: "-n",
            what: "sample count",
            value: "5".into()
        })
    );

    let mut rr = ReproduceRequest::default();
    (rr.cv_folds, rr.cv_runs) = (0, Some(3));
    assert!(matches!(
        rr.check(),
        Err(Refusal::LeftOut {
            setting: "--cv-runs",
            ..
        })
    ));
}

/// Through the library's one error: `Error::Request` holds the refusal, from `run` too.
#[test]
fn run_refuses_with_the_same_variants() {
    let coll = Collection::embedded_default();
    let mut r = SelectRequest::new(SelectMethod::Greedy);
    r.k = Some(2);
    r.runs = Some(3);
    let e = r
        .run(&Ctx::new(&crate::CpuBackend::new(), &coll))
        .expect_err("--runs for greedy");
    assert!(
        matches!(
            e,
            crate::Error::Request(Refusal::NotApplicable {
                setting: "--runs",
                ..
            })
        ),
        "{e:?}"
    );
    // A request run without the back-end or collection it needs.
    let e = FitRequest::new(vec!["polished-gold".into()])
        .run(&Ctx::collection(&coll))
        .expect_err("no back-end");
    assert!(
        matches!(
            e,
            crate::Error::Request(Refusal::Missing {
                setting: "--backend",
                ..
            })
        ),
        "{e:?}"
    );
    let e = FitSamplesRequest::new(vec!["polished-gold".into()], "s.csv".into())
        .run(&Ctx::saved())
        .expect_err("no collection");
    assert!(
        matches!(
            e,
            crate::Error::Request(Refusal::Missing {
                setting: "COLLECTION",
                ..
            })
        ),
        "{e:?}"
    );
}
