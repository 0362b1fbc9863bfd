//! The select, fit, render and reproduce commands end to end, as a user runs them.

use crate::common::*;

fn json(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("read")).expect("json")
}

#[test]
fn select_methods_write_the_spec_json() {
    let d = tmp();
    let Some(ngan) = shared_or_skip(
        "ngan2005_ashikhmin_shirley.csv",
        "select_methods_write_the_spec_json",
    ) else {
        return;
    };
    let km = d.path().join("km.json");
    assert!(bin_cpu()
        .arg("select")
        .arg(&ngan)
        .args(["--method", "kmedoids", "-k", "5", "--runs", "3", "--stride", "3", "--json"])
        .arg(&km)
        .status()
        .expect("run")
        .success());
    let v = json(&km);
    assert_eq!(v["method"], "kmedoids");
    assert_eq!(v["metric"], "brdf-it");
    assert_eq!(v["runs"].as_array().expect("runs").len(), 3);
    assert_eq!(v["best"]["medoids"].as_array().expect("medoids").len(), 5);
    assert_eq!(v["best"]["labels"].as_array().expect("labels").len(), 100);
    // GCUK with seed 7, written to `out`.
    let gcuk = |out: &std::path::Path| {
        bin_cpu()
            .args(["--seed", "7", "select", "--method", "gcuk"])
            .args(["--metric", "euclidean", "--runs", "2", "--json"])
            .arg(out)
            .status()
            .expect("run")
            .success()
    };
    let gc = d.path().join("gc.json");
    assert!(gcuk(&gc));
    let v = json(&gc);
    assert_eq!(v["runs"][0]["seed"], 7);
    let k = v["best"]["k"].as_u64().expect("k");
    assert!((5..=20).contains(&k));
    // Same seed, same result.
    let gc2 = d.path().join("gc2.json");
    assert!(gcuk(&gc2));
    assert_eq!(json(&gc), json(&gc2));
    let em = d.path().join("em.json");
    assert!(bin_cpu()
        .args(["select", "--method", "empirical", "--stride", "4", "--json"])
        .arg(&em)
        .status()
        .expect("run")
        .success());
    let v = json(&em);
    assert_eq!(v["method"], "empirical");
    assert!(v["histogram"].as_object().expect("hist").len() >= 40);
}

#[test]
fn fit_export_and_render_round_trip() {
    let d = tmp();
    let fits = d.path().join("fits.json");
    let exp = d.path().join("exported");
    let st = bin_cpu()
        .args([
            "fit",
            "--basis",
            "mirror-silver,matte-white-paint,red-acrylic-sheet",
            "--targets",
            "polished-gold,gloss-red-enamel",
            "--stride",
            "3",
            "--json",
        ])
        .arg(&fits)
        .arg("--export")
        .arg(&exp)
        .status()
        .expect("run");
    assert!(st.success());
    let v = json(&fits);
    assert_eq!(v["targets"].as_array().expect("t").len(), 2);
    // SPEC-cli: the Lambertian term beside the basis coefficients.
    assert!(v["targets"][0]["lambertian"].is_array());
    assert!(v["targets"][0]["coefficients"].get("lambertian").is_none());
    assert!(v["targets"][0]["coefficients"]["mirror-silver"].is_array());
    assert!(v["targets"][0]["mae"].as_f64().expect("mae") >= 0.0);
    let t = brdf_basis::merl::read_binary(&exp.join("polished-gold.binary"))
        .expect("exported file reads back");
    assert_eq!(t.valid_count(), 1_096_216);
    let exr = d.path().join("f.exr");
    let png = d.path().join("f.png");
    let heat = d.path().join("h.png");
    let out = bin_cpu()
        .args([
            "render",
            "--material",
            "gloss-red-enamel",
            "--size",
            "64",
            "--fit",
        ])
        .arg(&fits)
        .arg("--out")
        .arg(&exr)
        .arg("--png")
        .arg(&png)
        .arg("--heatmap")
        .arg(&heat)
        .output()
        .expect("run");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("normalized image error"));
    let img = brdf_basis::io::image::read_exr(&exr).expect("exr");
    assert_eq!((img.width, img.height), (64, 64));
    assert!(png.exists() && heat.exists());
}

#[test]
fn reproduce_runs_end_to_end_on_a_small_setting() {
    let d = tmp();
    let out = d.path().join("r");
    let st = bin_cpu()
        .args([
            "reproduce",
            "--no-appearance",
            "--runs",
            "3",
            "--stride",
            "5",
            "--render-size",
            "24",
            "--out",
        ])
        .arg(&out)
        .status()
        .expect("run");
    assert!(st.success());
    for f in [
        "report.md",
        "distance-brdf-it.npy",
        "empirical.json",
        "clustering_db.csv",
        "statistics.json",
        "bases.json",
        "fit_errors.csv",
    ] {
        assert!(out.join(f).exists(), "{f}");
    }
    let report = std::fs::read_to_string(out.join("report.md")).expect("report");
    // The Friedman test was computed (not merely mentioned) and its statistic is the
    // report's.
    let st = json(&out.join("statistics.json"));
    let chi2 = st["friedman-brdf-it"]["statistic"]
        .as_f64()
        .expect("friedman-brdf-it computed");
    assert!(st["friedman-brdf-it"]["p_value"]
        .as_f64()
        .is_some_and(|p| (0.0..=1.0).contains(&p)));
    assert!(report.contains(&format!("chi2 = {}", brdf_basis::stats::num(chi2))));
    assert!(report.contains("## Bases"));
}
