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
