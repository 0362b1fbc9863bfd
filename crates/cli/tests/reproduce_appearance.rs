//! `reproduce`'s Appearance section (SPEC 11, issue 37) on the embedded default collection:
//! the table's three objectives with the numbers of `appearance.json`, the figure, and
//! `--no-appearance`, which leaves every other output as it was (the paper's part does not
//! move).

use crate::common::*;
use brdf_basis::experiment::appearance::AppearanceStudy;
use brdf_basis::stats::num;
use std::path::Path;
use std::process::Command;

fn run(out: &Path, extra: &[&str]) -> Command {
    let mut c = bin_cpu();
    c.args([
        "reproduce",
        "--runs",
        "3",
        "--stride",
        "6",
        "--render-size",
        "24",
        "--k-max",
        "7",
        "--gcuk-k-max",
        "8",
        "--no-acquisition",
    ])
    .args(extra)
    .arg("--out")
    .arg(out);
    c
}

/// Every file under `dir`, relative, sorted.
fn files(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("dir") {
            let p = e.expect("entry").path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p.strip_prefix(dir).expect("prefix").to_path_buf());
            }
        }
    }
    out.sort();
    out
}

/// The report without its timing table and without the Appearance section.
fn paper_part(report: &str) -> String {
    let head = report.split("## Timings").next().expect("report");
    match head.split_once("\n## Appearance (SPEC 11)") {
        Some((before, after)) => {
            let rest = after.find("\n## ").map_or("", |i| &after[i + 1..]);
            format!("{before}{rest}")
        }
        None => head.to_string(),
    }
}

#[test]
fn reproduce_appearance_section_matches_its_json_and_leaves_the_paper_alone() {
    let d = tmp();
    let (with, without) = (d.path().join("with"), d.path().join("without"));
    let o = run(&with, &[]).output().expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = run(&without, &["--no-appearance"]).output().expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    // The section: the three objectives, numbers as in appearance.json.
    let report = std::fs::read_to_string(with.join("report.md")).expect("report");
    let st: AppearanceStudy =
        serde_json::from_str(&std::fs::read_to_string(with.join("appearance.json")).expect("json"))
            .expect("appearance.json");
    assert!(report.contains("## Appearance (SPEC 11)"));
    let names: Vec<&str> = st.rows.iter().map(|r| r.objective.as_str()).collect();
    assert_eq!(names, ["l2", "relative", "log"]);
    assert_eq!((st.k, st.folds, st.method.as_str()), (7, 5, "greedy"));
    for (r, c) in st.rows.iter().zip(&st.cv) {
        assert_eq!(c.objective, r.objective);
        // Every material is held out once.
        assert_eq!(
            r.materials,
            brdf_basis::collection::Collection::embedded_default().len()
        );
        let line = format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.objective,
            num(r.rho),
            num(r.objective_rho),
            num(r.log_rmse),
            num(r.image_error_paper_light),
            num(r.image_error),
            num(r.ciede2000),
            num(r.delta_e_itp),
            num(r.flip_paper_light),
            num(r.flip),
            r.flip_better_than_l2
                .map_or("-".into(), |b| format!("{b} of {}", r.materials))
        );
        assert!(report.contains(&line), "missing {line}");
        // The row's means are the cross-validation's.
        let m = &c.results[0];
        assert_eq!(r.rho, m.mean_rho);
        assert_eq!(r.flip, m.appearance.as_ref().expect("appearance").flip);
        assert!(r.flip > 0.0 && r.flip <= 1.0 && r.ciede2000 > 0.0 && r.delta_e_itp > 0.0);
    }
    assert!(st.rows[0].flip_better_than_l2.is_none());
    assert!(st.rows[1].flip_better_than_l2.is_some());
    // The figure: four materials, the first the worst l2 fit by four-light FLIP; per light
    // the target and three fits, each fit with its FLIP; the paper-light FLIP of each fit
    // is the cross-validation's for that material.
    assert_eq!(st.figure.len(), 4);
    let flip4 = |h: &brdf_basis::select::cv::HeldOut| h.appearance.as_ref().expect("a").mean_flip;
    let l2 = &st.cv[0].results[0].held_out;
    let worst = l2
        .iter()
        .max_by(|a, b| flip4(a).total_cmp(&flip4(b)))
        .expect("held out");
    assert_eq!(st.figure[0].material, worst.material);
    for row in &st.figure {
        assert_eq!(row.tiles.len(), 8);
        for (i, t) in row.tiles.iter().enumerate() {
            assert_eq!(t.objective.is_none(), i % 4 == 0);
            assert_eq!(t.flip.is_some(), i % 4 != 0);
            if i > 0 && i < 4 {
                let c = &st.cv[i - 1].results[0];
                let h = c
                    .held_out
                    .iter()
                    .find(|h| h.material == row.material)
                    .expect("held out");
                let cv_flip = h.appearance.as_ref().expect("a").paper_light().flip;
                let f = t.flip.expect("flip");
                assert!(
                    (f - cv_flip).abs() <= 1e-9 + 1e-6 * cv_flip,
                    "{f} vs {cv_flip}"
                );
            }
        }
    }
    assert!(report.contains("](figures/appearance-renders.png)"));
    let img = image::open(with.join("figures/appearance-renders.png"))
        .expect("png")
        .to_rgb8();
    let ink = img.pixels().filter(|p| p.0 != [255, 255, 255]).count() as f64
        / (img.width() * img.height()) as f64;
    assert!(
        ink > 0.3,
        "{ink}: the render tiles are drawn with or without a font"
    );
    let svg = std::fs::read_to_string(with.join("figures/appearance-renders.svg")).expect("svg");
    assert!(svg.contains("<svg"));
    if with_text() {
        assert!(svg.contains("FLIP"));
    }

    // --no-appearance: no section, no file; every other output byte for byte the same
    // (summary.json but its timings; the report but its timings and the section).
    let report_without = std::fs::read_to_string(without.join("report.md")).expect("report");
    assert!(!report_without.contains("## Appearance"));
    assert!(!without.join("appearance.json").exists());
    // Each report says which sections were left out (audit 3, U9), in a note of its own;
    // the paper's part is otherwise the same.
    let acq = "the Acquisition (SPEC 10, `--no-acquisition`)";
    let app = "the Appearance (SPEC 11, `--no-appearance`)";
    let note = |what: &str| format!("> **Note.** Left out as asked: {what}.\n\n");
    let (with_note, without_note) = (
        note(&format!("{acq} section")),
        note(&format!("{acq} and {app} sections")),
    );
    assert!(report.contains(&with_note), "{report}");
    assert!(report_without.contains(&without_note), "{report_without}");
    assert_eq!(
        paper_part(&report.replacen(&with_note, "", 1)),
        paper_part(&report_without.replacen(&without_note, "", 1))
    );
    let extra = [
        "appearance.json",
        "figures/appearance-renders.png",
        "figures/appearance-renders.svg",
    ];
    let fw: Vec<_> = files(&with)
        .into_iter()
        .filter(|p| !extra.iter().any(|e| p == Path::new(e)))
        .collect();
    assert_eq!(fw, files(&without));
    for f in fw {
        let (a, b) = (
            std::fs::read(with.join(&f)).expect("with"),
            std::fs::read(without.join(&f)).expect("without"),
        );
        match f.to_str() {
            Some("report.md") => {}
            Some("summary.json") => {
                let strip = |b: &[u8]| {
                    let mut v: serde_json::Value = serde_json::from_slice(b).expect("json");
                    v.as_object_mut().expect("object").remove("timings");
                    v
                };
                assert_eq!(strip(&a), strip(&b), "summary.json");
            }
            _ => assert!(
                a == b,
                "{} differs with the Appearance section",
                f.display()
            ),
        }
    }
}
