//! Issue 15 leftovers: one number format in user output, flag names in errors, stale
//! stage directories, the select JSON's collection fingerprint.

use crate::common::{bin_cpu, tmp};
use brdf_basis::fit::file::FitFile;

fn out(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn err(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Before: `fit` printed `mean MAE 6.6871e0` (Rust's `{:.4e}`); now the crate's one
/// formatter, `stats::num`, of the fit file's mean MAE and relative errors.
#[test]
fn fit_summary_uses_the_crate_number_format() {
    let d = tmp();
    let json = d.path().join("f.json");
    let o = bin_cpu()
        .args(["fit", "--basis", "mirror-silver,matte-white-paint"])
        .args(["--targets", "polished-gold,red-acrylic-sheet", "--json"])
        .arg(&json)
        .output()
        .expect("fit");
    assert!(o.status.success(), "{}", err(&o));
    let text = out(&o);
    let f: FitFile = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let maes: Vec<f64> = f.targets.iter().map(|t| t.mae).collect();
    let want = format!(
        "(2 targets, mean MAE {}, mean relative residual ",
        brdf_basis::stats::num(brdf_basis::stats::mean(&maes))
    );
    assert!(text.contains(&want), "want {want} in {text}");
    assert!(!text.contains("e0,") && !text.contains("e-1,"), "{text}");
}

const SMALL: &str = "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n\
a,0.1,0.2,0.3,0.5,0.5,0.5,0.04,10\n\
b,0.3,0.2,0.1,0.2,0.3,0.4,0.1,50\n\
c,0.5,0.5,0.5,0.0,0.0,0.0,0.04,1\n\
d,0.05,0.05,0.05,0.9,0.8,0.7,0.9,300\n\
e,0.2,0.1,0.4,0.1,0.6,0.2,0.02,5\n";

/// `select --distances X.npy` (no collection given) carries the fingerprint its sidecar
/// records, that of the collection the matrix came from, not the embedded default's; for
/// both clustering methods.
#[test]
fn select_on_a_saved_matrix_carries_the_sidecars_fingerprint() {
    let d = tmp();
    let coll = crate::common::write(d.path(), "small.csv", SMALL);
    let npy = d.path().join("d.npy");
    let o = bin_cpu()
        .arg("distance")
        .arg(&coll)
        .args(["--stride", "8", "--out"])
        .arg(&npy)
        .output()
        .expect("distance");
    assert!(o.status.success(), "{}", err(&o));
    let side = brdf_basis::io::sidecar::read_sidecar(&npy).expect("sidecar");
    let want = brdf_basis::collection::Collection::load(&coll)
        .expect("small")
        .fingerprint();
    assert_eq!(side.collection_fingerprint, want);
    assert_ne!(
        want,
        brdf_basis::collection::Collection::embedded_default().fingerprint()
    );
    for method in [
        ["--method", "kmedoids", "-k", "2"],
        ["--method", "gcuk", "--k-min", "2"],
    ] {
        let json = d.path().join(format!("{}.json", method[1]));
        let mut c = bin_cpu();
        c.arg("select").args(method).args(["--runs", "2"]);
        if method[1] == "gcuk" {
            c.args(["--k-max", "3", "--population", "6", "--generations", "3"]);
        }
        let o = c
            .arg("--distances")
            .arg(&npy)
            .arg("--json")
            .arg(&json)
            .output()
            .expect("select");
        assert!(o.status.success(), "{}", err(&o));
        let out = brdf_basis::select::SelectOutput::read(&json).expect("read back");
        assert_eq!(
            out.collection_fingerprint(),
            Some(want.as_str()),
            "{}",
            method[1]
        );
    }
}

/// Before: a staging directory `.brdf-basis-stage-PID-N` left by a SIGKILL stayed for
/// ever. The next run staging into the same directory removes those of dead processes,
/// and only those: a live process's, a file of that name, other names stay.
#[cfg(unix)]
#[test]
fn stale_stage_directories_of_dead_processes_are_removed() {
    let d = tmp();
    let mut child = std::process::Command::new("true").spawn().expect("true");
    let dead = child.id();
    child.wait().expect("wait");
    let stale = d.path().join(format!(".brdf-basis-stage-{dead}-0"));
    std::fs::create_dir(&stale).unwrap();
    std::fs::write(stale.join("half.json"), "{").unwrap();
    let live = d
        .path()
        .join(format!(".brdf-basis-stage-{}-7", std::process::id()));
    std::fs::create_dir(&live).unwrap();
    let file = d.path().join(format!(".brdf-basis-stage-{dead}-1"));
    std::fs::write(&file, "").unwrap();
    let other = d.path().join(format!(".brdf-basis-stage-{dead}-x"));
    std::fs::create_dir(&other).unwrap();
    let coll = crate::common::write(d.path(), "small.csv", SMALL);
    let o = bin_cpu()
        .arg("distance")
        .arg(&coll)
        .args(["--stride", "8", "--out"])
        .arg(d.path().join("d.csv"))
        .output()
        .expect("distance");
    assert!(o.status.success(), "{}", err(&o));
    assert!(!stale.exists(), "stale stage directory kept");
    assert!(live.is_dir() && file.is_file() && other.is_dir());
}

/// Before: `reproduce --out r` after a SIGKILL refused `r` (not empty: the dead run's
/// staging root), and `--force` too (`.brdf-basis-stage-...` is not one of its files). The
/// plan of a tree removes a dead process's staging root first, with or without --force.
#[cfg(unix)]
#[test]
fn a_tree_with_a_dead_runs_staging_root_is_planned_again() {
    let d = tmp();
    let mut child = std::process::Command::new("true").spawn().expect("true");
    let dead = child.id();
    child.wait().expect("wait");
    let out = d.path().join("r");
    std::fs::create_dir(&out).unwrap();
    let stale = out.join(format!(".brdf-basis-stage-{dead}-3"));
    std::fs::create_dir(&stale).unwrap();
    std::fs::write(stale.join("report.md"), "half").unwrap();
    let mut plan = brdf_basis::atomic::OutputPlan::new(&[]);
    plan.tree(&out, "--out", false, |n| n == "report.md")
        .expect("a dead run's staging root is no entry of the tree");
    assert!(!stale.exists());
    // A live process's staging root is kept, and refused as before.
    let live = out.join(format!(".brdf-basis-stage-{}-3", std::process::id()));
    std::fs::create_dir(&live).unwrap();
    let mut plan = brdf_basis::atomic::OutputPlan::new(&[]);
    let e = plan
        .tree(&out, "--out", true, |n| n == "report.md")
        .unwrap_err();
    assert!(e.to_string().contains(".brdf-basis-stage-"), "{e}");
    assert!(live.is_dir());
}
