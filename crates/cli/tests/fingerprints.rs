//! Every result file names the collection it came from by its fingerprint (issue 15):
//! before, `cv.json` and `reproduce`'s `summary.json` carried none, so a reader could not
//! tell which collection their numbers belong to.

use crate::common::{bin_cpu, tmp};
use brdf_basis::collection::Collection;

fn json(path: &std::path::Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn cv_and_reproduce_results_carry_the_collection_fingerprint() {
    let want = Collection::embedded_default().fingerprint();
    let d = tmp();
    let cv = d.path().join("cv.json");
    let o = bin_cpu()
        .args([
            "cv",
            "--methods",
            "greedy,random",
            "-k",
            "2",
            "--stride",
            "8",
            "--json",
        ])
        .arg(&cv)
        .output()
        .expect("run cv");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(json(&cv)["collection_fingerprint"], want.as_str());

    let out = d.path().join("r");
    let o = bin_cpu()
        .args([
            "reproduce",
            "--no-appearance",
            "--runs",
            "2",
            "--stride",
            "8",
            "--render-size",
            "16",
            "--k-max",
            "6",
            "--gcuk-k-max",
            "7",
            "--cv-folds",
            "0",
            "--out",
        ])
        .arg(&out)
        .output()
        .expect("run reproduce");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = json(&out.join("summary.json"));
    assert_eq!(summary["settings"]["collection_fingerprint"], want.as_str());
    for f in std::fs::read_dir(&out).expect("out") {
        let p = f.expect("entry").path();
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        if name.starts_with("fit-") && name.ends_with(".json") {
            assert_eq!(json(&p)["collection_fingerprint"], want.as_str(), "{name}");
        }
    }
}
