//! `reproduce` on a reduced configuration: the report's content checked against the CSV
//! and JSON files it writes, figures present and not blank, and bad settings refused
//! before any work.

use crate::common::*;
use brdf_basis::experiment::bases::Basis;
use brdf_basis::experiment::statistics::Statistics;
use brdf_basis::fit::file::FitFile;
use brdf_basis::select::ClusteringSet;
use std::path::Path;
use std::process::Command;

fn read<T: serde::de::DeserializeOwned>(path: &Path) -> T {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn quick(out: &Path) -> Command {
    let mut c = bin_cpu();
    c.args([
        "reproduce",
        "--runs",
        "4",
        "--stride",
        "6",
        "--render-size",
        "24",
        "--k-max",
        "7",
        "--gcuk-k-max",
        "9",
        "--out",
    ])
    .arg(out);
    c
}

#[test]
fn reproduce_report_matches_its_files_and_figures() {
    let d = tmp();
    let out = d.path().join("r");
    let o = quick(&out).output().expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report = std::fs::read_to_string(out.join("report.md")).expect("report");
    // Text follows the settings.
    assert!(report.contains("4 runs per configuration"), "{report}");
    assert!(report.contains("grid stride 6") && report.contains("k = 5..7"));
    assert!(!report.contains("With 30 runs") && !report.contains("W = -0"));
    // Clustering: every run in clustering.json, with silhouette and Dunn in range, and the
    // CSV row count; the report's medians are those of the JSON.
    let sets: Vec<ClusteringSet> = read(&out.join("clustering.json"));
    assert_eq!(sets.len(), 3 * 4, "3 metrics x (k 5..7 + GCUK)");
    let csv = std::fs::read_to_string(out.join("clustering_db.csv")).expect("csv");
    assert!(csv.starts_with("metric,method,run,seed,k,db_index,loss,medoids,silhouette,dunn\n"));
    assert_eq!(csv.lines().count(), 1 + 12 * 4);
    for s in &sets {
        assert_eq!(s.runs.len(), 4);
        for r in &s.runs {
            assert!((-1.0..=1.0).contains(&r.silhouette));
            assert!(r.dunn.is_none_or(|v| v >= 0.0));
        }
        let med = brdf_basis::stats::median(&s.db_values());
        let row = format!(
            "| {} | {} | {} |",
            s.metric,
            s.method,
            brdf_basis::stats::num(med)
        );
        assert!(report.contains(&row), "missing {row}");
    }
    // Statistics: the Wilcoxon p in the report is the JSON's, exact for 4 paired runs.
    let st: Statistics = read(&out.join("statistics.json"));
    let c = st.gcuk_euclidean_vs_brdf_it.expect("gcuk comparison");
    assert_eq!(c.runs, 4);
    assert!(report.contains(&format!("p = {}", brdf_basis::stats::p_value(c.wilcoxon_p))));
    assert!(st.friedman.keys().any(|k| k.metric() == "brdf-it"));
    // Bases are named once; every fit file has the same targets, all in no basis, and the
    // fit_errors.csv numbers are the fit files' MAEs.
    let bases: Vec<Basis> = read(&out.join("bases.json"));
    let mut sets_seen: Vec<Vec<String>> = Vec::new();
    for b in &bases {
        let mut m = b.materials.clone();
        m.sort();
        assert!(!sets_seen.contains(&m), "{} listed twice", b.name);
        sets_seen.push(m);
    }
    let errors = std::fs::read_to_string(out.join("fit_errors.csv")).expect("fit errors");
    let mut rows = errors.lines();
    let header: Vec<&str> = rows.next().expect("header").split(',').collect();
    let rows: Vec<Vec<&str>> = rows.map(|l| l.split(',').collect()).collect();
    for b in &bases {
        let f: FitFile = read(&out.join(format!("fit-{}.json", b.name)));
        assert_eq!(f.basis, b.materials);
        assert_eq!(f.targets.len(), rows.len());
        let col = header
            .iter()
            .position(|h| *h == format!("mae-{}", b.name))
            .expect("column");
        for (t, row) in f.targets.iter().zip(&rows) {
            assert_eq!(t.material, row[0]);
            assert!(!bases.iter().any(|b| b.materials.contains(&t.material)));
            let v: f64 = row[col].parse().expect("number");
            assert!(
                (v - t.mae).abs() <= 1e-12 * t.mae.abs().max(1e-300),
                "{v} vs {}",
                t.mae
            );
        }
        let mean = f.targets.iter().map(|t| t.mae).sum::<f64>() / f.targets.len() as f64;
        let row = format!(
            "| {} | {} | {} |",
            b.name,
            b.materials.len(),
            brdf_basis::stats::num(mean)
        );
        assert!(report.contains(&row), "missing {row}");
    }
    // Figures: present in the report, PNG and SVG on disk, not blank.
    for stem in [
        "fig2-contributions",
        "fig3-db-boxplots",
        "db-vs-k",
        "cd-brdf-it",
        "fig4a-mae",
        "fig4b-image-error",
        "fig5-showcase",
        "lobes-showcase",
        "acquisition-rho",
    ] {
        assert!(
            report.contains(&format!("](figures/{stem}.png)")),
            "{stem} not in report"
        );
        let img = image::open(out.join("figures").join(format!("{stem}.png")))
            .expect(stem)
            .to_rgb8();
        let ink = img.pixels().filter(|p| p.0 != [255, 255, 255]).count() as f64
            / (img.width() * img.height()) as f64;
        // Without a font a line plot keeps only its axes and lines (db-vs-k: 0.5% ink).
        let ink_least = if with_text() { 0.02 } else { 0.002 };
        assert!(
            ink > ink_least,
            "{stem}: only {ink} of the pixels are not white"
        );
        let svg =
            std::fs::read_to_string(out.join("figures").join(format!("{stem}.svg"))).expect(stem);
        // Without a font (none installed, or BRDF_BASIS_FONT=none) the figures carry no
        // text, so an SVG is shorter; it still draws.
        let least = if with_text() { 2000 } else { 500 };
        assert!(
            svg.contains("<svg") && svg.len() > least,
            "{stem}.svg: {} bytes",
            svg.len()
        );
    }
    assert!(report.contains("## The paper's claims") && report.contains("## Timings"));
    // Acquisition: the table of acquisition.json, the baseline beside our plans, and the
    // settings said.
    let acq: brdf_basis::acquire::AcqCv = read(&out.join("acquisition.json"));
    assert!(report.contains("## Acquisition (SPEC 10)") && report.contains("grid stride 6"));
    assert!(acq
        .results
        .iter()
        .any(|r| r.plan == brdf_basis::acquire::Criterion::Nielsen));
    for r in &acq.results {
        let row = format!(
            "| {} | {} | {} | {} | {} |",
            r.method,
            r.plan.as_str(),
            r.n,
            brdf_basis::stats::num(r.noise),
            brdf_basis::stats::num(r.mean_rho)
        );
        assert!(report.contains(&row), "missing {row}");
    }
    // A second run into the same directory is refused; --force clears it.
    let o = quick(&out).output().expect("run");
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("not empty"));
    std::fs::write(out.join("mine.txt"), "keep").expect("write");
    let o = quick(&out).arg("--force").output().expect("run");
    assert!(
        !o.status.success(),
        "--force must not delete files it did not write"
    );
    assert!(out.join("mine.txt").exists());
}

#[test]
fn reproduce_rejects_bad_settings_before_work() {
    let d = tmp();
    let cases: [(&[&str], &str); 4] = [
        (&["--runs", "0"], "--runs"),
        (&["--k-min", "9", "--k-max", "6"], "--k-max = 6"),
        (&["--showcase", "polished-gol"], "polished-gold"),
        (&["--k-max", "80"], "number of materials"),
    ];
    for (i, (args, expect)) in cases.iter().enumerate() {
        let out = d.path().join(format!("o{i}"));
        let t = std::time::Instant::now();
        let o = bin_cpu()
            .args(["reproduce", "--no-appearance"])
            .args(*args)
            .arg("--out")
            .arg(&out)
            .output()
            .expect("run");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} accepted");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!out.exists(), "{args:?}: output written before the check");
        assert!(t.elapsed().as_secs_f64() < 20.0);
    }
    // A paper-bases file naming an unknown material: line and suggestion.
    let csv = d.path().join("pb.csv");
    std::fs::write(
        &csv,
        "basis,material\nmine,polished-gold\nmine,polished-gol\n",
    )
    .expect("write");
    let o = bin_cpu()
        .args(["reproduce", "--no-appearance"])
        .arg("--paper-bases")
        .arg(&csv)
        .arg("--out")
        .arg(d.path().join("p"))
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("line 3") && err.contains("polished-gold"),
        "{err}"
    );
    // A failure after the work started (every material in some basis: nothing to
    // evaluate) leaves no partial output directory.
    let coll = d.path().join("small.csv");
    let mut text = String::from("material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n");
    let mut pb = String::from("basis,material\n");
    for i in 0..8 {
        text.push_str(&format!(
            "m{i},0.{i}1,0.2,0.3,0.5,0.5,0.5,0.{i}5,{}\n",
            10 + 300 * i
        ));
        pb.push_str(&format!("all,m{i}\n"));
    }
    std::fs::write(&coll, text).expect("write");
    std::fs::write(&csv, pb).expect("write");
    let out = d.path().join("partial");
    let o = bin_cpu()
        .args(["reproduce", "--no-appearance"])
        .arg(&coll)
        .args([
            "--runs",
            "2",
            "--stride",
            "8",
            "--k-min",
            "2",
            "--k-max",
            "3",
            "--gcuk-k-max",
            "4",
            "--paper-bases",
        ])
        .arg(&csv)
        .arg("--out")
        .arg(&out)
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("no material is left"),
        "{err}"
    );
    assert!(!out.exists(), "partial output left behind");
}

/// A basis material named `lambertian` no longer overwrites the Lambertian coefficients
/// (SPEC-cli: `lambertian` sits beside `coefficients`), and `render --fit` reads it back.
#[test]
fn fit_json_keeps_a_material_named_lambertian() {
    let d = tmp();
    let csv = d.path().join("c.csv");
    std::fs::write(
        &csv,
        "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\nlambertian,0.5,0.4,0.3,0.2,0.2,0.2,0.05,50\nshiny,0.01,0.01,0.01,1.0,0.9,0.8,0.9,2000\ntarget,0.3,0.2,0.1,0.5,0.5,0.5,0.5,300\n",
    )
    .expect("csv");
    let fits = d.path().join("f.json");
    let o = bin_cpu()
        .arg("fit")
        .arg(&csv)
        .args([
            "--basis",
            "lambertian,shiny",
            "--targets",
            "target",
            "--stride",
            "4",
            "--json",
        ])
        .arg(&fits)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let f: FitFile = read(&fits);
    let t = &f.targets[0];
    assert_eq!(f.basis, ["lambertian", "shiny"]);
    assert!(t.coefficients.contains_key("lambertian") && t.coefficients.contains_key("shiny"));
    let v: serde_json::Value = read(&fits);
    assert!(v["targets"][0]["lambertian"].is_array());
    // Reading back gives the columns in basis order, the Lambertian term first.
    let (_, cols) = f.columns_of("target", &fits).expect("columns");
    assert_eq!(
        cols,
        vec![
            t.lambertian,
            t.coefficients["lambertian"],
            t.coefficients["shiny"]
        ]
    );
    let exr = d.path().join("t.exr");
    let o = bin_cpu()
        .arg("render")
        .arg(&csv)
        .args(["--material", "target", "--size", "16", "--fit"])
        .arg(&fits)
        .arg("--out")
        .arg(&exr)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The plot command reads the same file.
    let svg = d.path().join("l.svg");
    let o = bin_cpu()
        .arg("plot")
        .arg(&csv)
        .args(["--material", "target", "--angles", "0,45", "--fit"])
        .arg(&fits)
        .arg("--out")
        .arg(&svg)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&svg).expect("svg");
    if with_text() {
        assert!(text.contains("fit by f"));
    } else {
        // No font on this machine: the figure has no legend, and the user is told.
        assert!(text.contains("<svg"));
        assert!(String::from_utf8_lossy(&o.stderr).contains("no font"));
    }
}

/// Without a font, figures are drawn without text: still written, not blank, and the
/// user is told.
#[test]
fn figures_without_a_font_are_text_free_not_missing() {
    let d = tmp();
    let png = d.path().join("l.png");
    let o = bin_cpu()
        .env("BRDF_BASIS_FONT", "none")
        .args([
            "plot",
            "--material",
            "polished-gold",
            "--angles",
            "0,60",
            "--out",
        ])
        .arg(&png)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no font"));
    let img = image::open(&png).expect("png").to_rgb8();
    let ink = img.pixels().filter(|p| p.0 != [255, 255, 255]).count();
    assert!(ink > 1000, "{ink} inked pixels");
}
