//! The S4 items of the second hostile audit (review/audit-2.md, Part 2, "S4") done in
//! issue 36: plurals (U1), no "line 0" in whole-file errors (U2), the extensions of
//! `plan --out` and `tabulate --out` (U4), the `cv --acquisition` report (U5), the
//! acquisition figure's ticks (U6), the angles `plan` writes (U7); and later the note on
//! mixing channel scales (U14) and the k checks before loading (U17). Each test fails on the
//! code the audit ran.

use crate::audit2_s3::{refused, run, stderr, CSV};
use crate::common::*;

fn stdout(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// U1: one of a thing is singular ("1 materials", "planned 1 samples", "(1 samples, ...").
#[test]
fn counts_of_one_are_singular() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    write(
        d,
        "one.csv",
        CSV.lines().take(2).collect::<Vec<_>>().join("\n") + "\n",
    );
    let o = run(d, &["info", "one.csv"]);
    assert!(
        stdout(&o).contains("collection: 1 material (1 analytic)"),
        "{}",
        stdout(&o)
    );
    write(
        d,
        "s.csv",
        "theta_i,phi_i,theta_o,phi_o,r,g,b\n30,0,30,180,0.2,0.2,0.2\n",
    );
    let o = run(
        d,
        &[
            "fit",
            "c.csv",
            "--basis",
            "plastic",
            "--samples",
            "s.csv",
            "--json",
            "f.json",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("(1 sample, rank 1 of 2"),
        "{}",
        stdout(&o)
    );
    assert!(
        stderr(&o).contains(
            "1 sample for 2 unknowns per channel (the Lambertian term and 1 basis material)"
        ),
        "{}",
        stderr(&o)
    );
    assert!(
        stderr(&o).contains("but 1 more sample would"),
        "{}",
        stderr(&o)
    );
    let o = run(
        d,
        &[
            "plan",
            "c.csv",
            "--basis",
            "plastic,metal",
            "--targets",
            "satin,target",
            "-n",
            "1",
            "--out",
            "p.csv",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("planned 1 sample ("), "{}", stdout(&o));
}

/// U2: an error about a whole file says no "line 0" (an ASTM file without a `VARS` line).
#[test]
fn whole_file_errors_name_no_line_0() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    write(
        d,
        "a.astm",
        "SOURCE lab\nNUM_POINTS 1\n0.5,0,0.5,3.1,0.1,0.1,0.1\n",
    );
    let e = refused(
        d,
        &[
            "fit",
            "c.csv",
            "--basis",
            "plastic",
            "--samples",
            "a.astm",
            "--json",
            "f.json",
        ],
        &["a.astm", "VARS"],
    );
    assert!(!e.contains("line 0"), "{e}");
}

/// U4: `plan --out` must end in .csv and `tabulate --out` in .binary (the old code wrote
/// a CSV to `plan_noext` and MERL data to `x.bsdf`, which a directory load then read as an
/// RGL file).
#[test]
fn plan_and_tabulate_outputs_have_their_formats_extension() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    for out in ["p", "p.json"] {
        refused(
            d,
            &[
                "plan",
                "c.csv",
                "--basis",
                "plastic,metal",
                "--targets",
                "satin,target",
                "-n",
                "2",
                "--out",
                out,
            ],
            &[
                &format!("--out {out}: writes the plan as a samples-file CSV"),
                "must end in .csv",
            ],
        );
    }
    for out in ["x.bsdf", "x.npy", "x"] {
        refused(
            d,
            &["tabulate", "c.csv", "--material", "plastic", "--out", out],
            &[
                &format!("--out {out}: writes a MERL table"),
                "must end in .binary",
            ],
        );
        assert!(!d.join(out).exists());
    }
}

/// U5 and U6: `cv --acquisition` reports the figure it wrote, prints noise levels as given
/// (`0.02`, not `0.02000`), and the figure's sample-count axis labels each integer at most
/// once (n = 1 gave "0 0 0 0 0 0 1 1 1 1 1").
#[test]
fn cv_acquisition_reports_its_figure_and_labels_integers_once() {
    let dir = tmp();
    let d = dir.path();
    let mut c = String::from(CSV);
    c += "rough,0.3,0.3,0.3,0.05,0.05,0.05,0.04,5\n\
        gold,0,0,0,0.9,0.6,0.2,0.9,1200\n\
        paint,0.4,0.05,0.05,0.1,0.1,0.1,0.05,60\n\
        chalk,0.5,0.5,0.45,0.02,0.02,0.02,0.03,3\n";
    write(d, "c8.csv", c);
    for (ns, fig) in [("1", "a.svg"), ("1,3", "b.svg"), ("1,3", "b.png")] {
        let o = run(
            d,
            &[
                "cv",
                "c8.csv",
                "--acquisition",
                "--methods",
                "random",
                "-k",
                "2",
                "--plans",
                "random,error",
                "-n",
                ns,
                "--noise",
                "0,0.02",
                "--folds",
                "2",
                "--stride",
                "8",
                "--render-size",
                "16",
                "--no-appearance",
                "--candidates-per-step",
                "50",
                "--json",
                "q.json",
                "--figure",
                fig,
            ],
        );
        let out = stdout(&o);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(out.contains(&format!("wrote {fig}")), "{out}");
        assert!(
            out.contains("| 0.02 |") && !out.contains("0.02000"),
            "{out}"
        );
        if fig.ends_with(".svg") {
            let svg = std::fs::read_to_string(d.join(fig)).expect("svg");
            let ints: Vec<&str> = svg
                .split("</text>")
                .filter_map(|t| t.rsplit('>').next().map(str::trim))
                .filter(|t| !t.is_empty() && t.chars().all(|c| c.is_ascii_digit()))
                .collect();
            let mut seen = ints.clone();
            seen.sort();
            seen.dedup();
            assert_eq!(seen.len(), ints.len(), "{ns}: x labels {ints:?}");
            assert!(ints.contains(&"1"), "{ns}: x labels {ints:?}");
        }
    }
}

/// The acquisition figure of a run without a noise-free level (`--noise 0.02` alone) drew
/// an empty chart: it plotted only the noise-free rows. It now draws the lowest noise
/// level, named in the caption, with as many lines as a noise-free run.
#[test]
fn cv_acquisition_figure_without_a_noise_free_level_is_not_empty() {
    let dir = tmp();
    let d = dir.path();
    let mut c = String::from(CSV);
    c += "rough,0.3,0.3,0.3,0.05,0.05,0.05,0.04,5\n\
        gold,0,0,0,0.9,0.6,0.2,0.9,1200\n";
    write(d, "c6.csv", c);
    let mut lines = Vec::new();
    for (noise, fig) in [("0", "z.svg"), ("0.02", "y.svg")] {
        let o = run(
            d,
            &[
                "cv",
                "c6.csv",
                "--acquisition",
                "--methods",
                "random",
                "-k",
                "2",
                "--plans",
                "random,error",
                "-n",
                "1,3",
                "--noise",
                noise,
                "--folds",
                "2",
                "--stride",
                "8",
                "--render-size",
                "16",
                "--no-appearance",
                "--candidates-per-step",
                "50",
                "--json",
                &format!("{fig}.json"),
                "--figure",
                fig,
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let svg = std::fs::read_to_string(d.join(fig)).expect("svg");
        lines.push(svg.matches("<polyline").count());
        if noise == "0.02" {
            assert!(
                svg.contains("samples at 2% noise"),
                "caption names the noise"
            );
        }
    }
    assert!(lines[0] > 0 && lines[0] == lines[1], "{lines:?}");
}

/// U7: `plan` writes a candidate's angles as given, not re-derived ones
/// (29.999999999999993 for 30, -0.000000000000028 for a phi of 720).
#[test]
fn plan_writes_candidate_angles_as_given() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    write(
        d,
        "k.csv",
        "theta_i,phi_i,theta_o,phi_o\n30,720,40,180\n60,0,30,180\n45,90,45,-90\n",
    );
    let o = run(
        d,
        &plan_args(&["-n", "3", "--candidates", "k.csv", "--out", "p.csv"]),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let mut rows: Vec<String> = std::fs::read_to_string(d.join("p.csv"))
        .expect("plan")
        .lines()
        .skip(1)
        .map(String::from)
        .collect();
    rows.sort();
    assert_eq!(rows, ["30,0,40,180", "45,90,45,-90", "60,0,30,180"]);
}

/// U17: a hand-edited tile sidecar is refused with the way to make that tile again (the
/// old message named `brdf-basis distance` without `--tile`).
#[test]
fn an_edited_tile_sidecar_says_how_to_compute_the_tile_again() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    for t in ["1/2", "2/2"] {
        let out = format!("t{}.npy", &t[..1]);
        let o = run(
            d,
            &[
                "distance", "c.csv", "--stride", "16", "--tile", t, "--out", &out,
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let side = d.join("t2.names.json");
    let text = std::fs::read_to_string(&side).expect("sidecar");
    assert!(text.contains("\"satin\""), "{text}");
    std::fs::write(&side, text.replace("\"satin\"", "\"satyn\"")).expect("edit");
    refused(
        d,
        &["merge", "t1.npy", "t2.npy", "--out", "m.npy"],
        &[
            "edited or damaged",
            "compute the tile again with `brdf-basis distance --tile 2/2`",
        ],
    );
}

/// U3 (in part): `cv --acquisition -n 0` said "plans / methods / n = 3 / 1 / [0]"; the
/// request now names the flag in its own words.
#[test]
fn cv_acquisition_refuses_a_zero_sample_count_in_the_flags_words() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    refused(
        d,
        &[
            "cv",
            "c.csv",
            "--acquisition",
            "-n",
            "0",
            "--json",
            "q.json",
        ],
        &["-n: give sample counts of at least 1 (got 0)"],
    );
    refused(
        d,
        &[
            "cv",
            "c.csv",
            "--acquisition",
            "-n",
            "5,0",
            "--json",
            "q.json",
        ],
        &["-n: give sample counts of at least 1 (got 5,0)"],
    );
}

/// U14: analytic rows mixed with measured materials get a warning about the channel scales
/// (before: nothing); one kind alone gets none.
#[test]
fn mixing_analytic_and_measured_materials_warns_about_channel_scales() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    let o = run(
        d,
        &[
            "tabulate",
            "c.csv",
            "--material",
            "plastic",
            "--out",
            "m.binary",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(d, &["info", "c.csv"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("channel scales"), "{}", stderr(&o));
    let o = run(d, &["info", "c.csv", "m.binary"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    let analytic = CSV.lines().skip(1).filter(|l| !l.trim().is_empty()).count();
    assert!(
        e.contains(&format!(
            "mixes {analytic} analytic material(s) with 1 measured or neural one(s)"
        )) && e.contains("channel scales"),
        "{e}"
    );
}

/// U17: `reproduce` checks its k ranges against the number of materials before it loads
/// them (before: 4 RGL-EPFL files were read and tabulated for 7 s, then `--k-max 12` was
/// refused). The files here are not valid `.bsdf` files, so a load would fail first.
#[test]
fn reproduce_refuses_k_max_before_loading_the_collection() {
    let dir = tmp();
    let d = dir.path();
    std::fs::create_dir(d.join("rgl")).unwrap();
    for name in ["a", "b", "c", "d"] {
        write(
            &d.join("rgl"),
            &format!("{name}.bsdf"),
            b"not a tensor file",
        );
    }
    let o = run(d, &["reproduce", "rgl", "--k-max", "12", "--out", "out"]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("--k-max") && e.contains("below the number of materials (4)"),
        "{e}"
    );
    assert!(!e.contains("a.bsdf"), "{e}");
    assert!(!d.join("out").exists());
    // Settings that fit: the load runs and names the bad file.
    let o = run(
        d,
        &[
            "reproduce",
            "rgl",
            "--k-min",
            "2",
            "--k-max",
            "2",
            "--gcuk-k-max",
            "3",
            "--cv-folds",
            "2",
            "--out",
            "out",
        ],
    );
    assert!(!o.status.success());
    assert!(stderr(&o).contains("a.bsdf"), "{}", stderr(&o));
}

/// U11: a signal that arrives once the outputs are committed says so (before: "the
/// outputs not yet in place were removed" although every output had been replaced).
/// `remove_pending` ends every later write of its process, so the check runs in a child
/// process: this test binary, running this test alone.
#[test]
fn a_signal_after_the_commit_says_the_outputs_are_in_place() {
    use brdf_basis::atomic::{remove_pending, OutputPlan};
    const CHILD: &str = "BRDF_BASIS_TEST_U11_CHILD";
    if std::env::var_os(CHILD).is_none() {
        let o = std::process::Command::new(std::env::current_exe().unwrap())
            .args([
                "--exact",
                "audit2_s4::a_signal_after_the_commit_says_the_outputs_are_in_place",
                "--test-threads",
                "1",
            ])
            .env(CHILD, "1")
            .output()
            .unwrap();
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success() && out.contains("1 passed"), "{out}");
        return;
    }
    let dir = tmp();
    let target = dir.path().join("a.json");
    let mut plan = OutputPlan::new(&[]);
    plan.file(&target, "--json").unwrap();
    let mut set = plan.into_set().unwrap();
    set.stage(&target, |w| w.write_all(b"{}")).unwrap();
    set.commit().unwrap();
    let c = remove_pending();
    assert_eq!(c.removed, 0);
    assert!(c.in_place);
    assert_eq!(
        c.message(),
        "interrupted after the outputs were in place; nothing was removed"
    );
    assert_eq!(std::fs::read(&target).unwrap(), b"{}");
}

/// U3 (the rest): `plan -n` beyond the candidates names their number; a plan by the error
/// criterion with every material in the basis says what to do, not "targets = none:
/// training materials outside the basis for the error criterion".
#[test]
fn plan_messages_give_the_number_of_candidates_and_the_way_out() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    write(
        d,
        "k.csv",
        "theta_i,phi_i,theta_o,phi_o\n30,0,40,180\n60,0,30,180\n45,90,45,-90\n",
    );
    refused(
        d,
        &plan_args(&["-n", "5", "--candidates", "k.csv", "--out", "p.csv"]),
        &["n = 5: at least 1 and at most the number of candidates (3)"],
    );
    let all: Vec<&str> = CSV
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').next())
        .filter(|n| !n.is_empty())
        .collect();
    let basis = all.join(",");
    refused(
        d,
        &[
            "plan", "c.csv", "--basis", &basis, "-n", "3", "--out", "p.csv",
        ],
        &["give a basis that leaves some out, or the condition or random criterion"],
    );
}

/// `plan c.csv` with the basis plastic, metal and the targets satin, target, then `rest`.
fn plan_args<'a>(rest: &[&'a str]) -> Vec<&'a str> {
    let mut a = vec![
        "plan",
        "c.csv",
        "--basis",
        "plastic,metal",
        "--targets",
        "satin,target",
    ];
    a.extend_from_slice(rest);
    a
}
