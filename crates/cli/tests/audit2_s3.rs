//! The S3 defects of the second hostile audit (review/audit-2.md, Part 2, "S3"): duplicate
//! candidates (T4), the suggestions of `fit --samples` (T5), flags that a command would
//! ignore (T8, T9), the `cv --acquisition --figure` format (T10), duplicate list values
//! (T11), corrupt RGL headers (T14), an all-1e308 matrix (T15). Each test fails on the
//! code the audit ran.

use crate::common::*;
use std::path::Path;
use std::process::Output;
use std::time::Duration;

pub(crate) const CSV: &str = "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n\
    plastic,0.2,0.1,0.05,0.3,0.3,0.3,0.04,120\n\
    metal,0,0,0,0.9,0.7,0.4,0.8,2500\n\
    satin,0.05,0.05,0.08,0.2,0.25,0.3,0.1,15\n\
    target,0.12,0.07,0.06,0.5,0.4,0.3,0.2,400\n";

pub(crate) fn run(dir: &Path, args: &[&str]) -> Output {
    let mut cmd = bin();
    cmd.args(["--quiet", "--backend", "cpu"])
        .args(args)
        .current_dir(dir);
    output_within(&mut cmd, Duration::from_secs(300))
        .unwrap_or_else(|| panic!("brdf-basis {args:?} hangs"))
}

pub(crate) fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A refusal: exit status 1 (not a panic's 101 or a signal) and a message holding every
/// one of `parts`.
pub(crate) fn refused(dir: &Path, args: &[&str], parts: &[&str]) -> String {
    let o = run(dir, args);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{args:?}: {:?}\n{e}", o.status);
    assert!(!e.contains("panicked"), "{args:?}: {e}");
    for p in parts {
        assert!(e.contains(p), "{args:?}: `{p}` not in: {e}");
    }
    e
}

/// T4: a candidates file giving one direction pair twice (the same row, or theta 0 under
/// two phi) is refused naming both lines; the old code planned that direction three
/// times without a word.
#[test]
fn plan_refuses_duplicate_candidates() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    let plan = |cands: &'static str| {
        vec![
            "plan",
            "c.csv",
            "--basis",
            "plastic,metal",
            "--targets",
            "satin,target",
            "-n",
            "3",
            "--candidates",
            cands,
            "--out",
            "p.csv",
        ]
    };
    let mut same = String::from("theta_i,phi_i,theta_o,phi_o\n");
    for _ in 0..50 {
        same += "30,0,40,180\n";
    }
    write(d, "same.csv", same);
    refused(
        d,
        &plan("same.csv"),
        &[
            "same.csv: line 3",
            "the direction pair is the one of line 2",
        ],
    );
    write(
        d,
        "pole.csv",
        "theta_i,phi_i,theta_o,phi_o\n10,0,20,180\n0,0,30,0\n20,0,30,90\n0,90,30,0\n",
    );
    refused(
        d,
        &plan("pole.csv"),
        &["pole.csv: line 5", "the one of line 3"],
    );
    assert!(!d.join("p.csv").exists());
    write(
        d,
        "ok.csv",
        "theta_i,phi_i,theta_o,phi_o\n10,0,20,180\n0,0,30,0\n20,0,30,90\n25,0,35,180\n",
    );
    let o = run(d, &plan("ok.csv"));
    assert!(o.status.success(), "{}", stderr(&o));
}

/// The directions listed after "e.g. at" in a warning.
fn suggested(warning: &str) -> Vec<String> {
    let list = warning
        .split("= ")
        .nth(1)
        .and_then(|s| s.split(" degrees").next())
        .unwrap_or_else(|| panic!("no directions in: {warning}"));
    list.split("), ")
        .map(|s| s.trim_end_matches(')').to_string())
        .collect()
}

/// T5: two conflicting samples at one direction for a basis of 3 materials (4 unknowns):
/// they tell one thing (rank 1), so the warning says "3 more samples" and lists 3 distinct
/// directions (the old code: "2 more" and 3 directions, two of them the same).
#[test]
fn fit_samples_suggests_as_many_distinct_directions_as_it_says() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    write(
        d,
        "s.csv",
        "theta_i,phi_i,theta_o,phi_o,r,g,b\n30,0,30,180,0.2,0.2,0.2\n30,0,30,180,0.6,0.6,0.6\n",
    );
    let o = run(
        d,
        &[
            "fit",
            "c.csv",
            "--basis",
            "plastic,metal,satin",
            "--samples",
            "s.csv",
            "--json",
            "f.json",
        ],
    );
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    let w = e
        .lines()
        .find(|l| l.contains("more samples would determine it"))
        .unwrap_or_else(|| panic!("no warning: {e}"));
    assert!(w.contains(" 3 more samples"), "{w}");
    let dirs = suggested(w);
    assert_eq!(dirs.len(), 3, "{w}");
    for (i, a) in dirs.iter().enumerate() {
        assert!(!dirs[..i].contains(a), "{w}");
    }
    assert!(!dirs.iter().any(|s| s == "(30.0, 0.0, 30.0, 180.0"), "{w}");
}

/// T8: `fit --samples` solves over the samples alone; the grid fit's flags, which it
/// would ignore (and record in the JSON as if they had applied), are refused by name.
#[test]
fn fit_samples_refuses_the_grid_fits_flags() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    let mut s = String::from("theta_i,phi_i,theta_o,phi_o,r,g,b\n");
    for (ti, to) in [(10, 20), (20, 25), (30, 31), (40, 45), (50, 10), (60, 70)] {
        s += &format!("{ti},0,{to},180,0.2,0.1,0.1\n");
    }
    write(d, "s.csv", s);
    let fit = |extra: &[&'static str]| {
        let mut a = vec![
            "fit",
            "c.csv",
            "--basis",
            "plastic,metal",
            "--samples",
            "s.csv",
            "--json",
            "f.json",
        ];
        a.extend_from_slice(extra);
        a
    };
    for (flag, value) in [
        ("--stride", "4"),
        ("--solver", "pgd"),
        ("--weighting", "solid-angle"),
        ("--mask", "valid"),
    ] {
        refused(
            d,
            &fit(&[flag, value]),
            &[
                &format!("{flag} does not apply with --samples"),
                "leave it out",
            ],
        );
    }
    refused(
        d,
        &fit(&["--stride", "2", "--mask", "valid"]),
        &["--stride, --mask do not apply with --samples"],
    );
    assert!(!d.join("f.json").exists());
    let o = run(d, &fit(&[]));
    assert!(o.status.success(), "{}", stderr(&o));
}

/// T9: `cv` without `--acquisition` refuses the acquisition flags it would ignore (the
/// old code exited 0 and wrote no figure), naming each.
#[test]
fn cv_without_acquisition_refuses_its_flags() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    let cv = |extra: &[&'static str]| {
        let mut a = vec![
            "cv",
            "c.csv",
            "--methods",
            "random",
            "-k",
            "1",
            "--json",
            "q.json",
        ];
        a.extend_from_slice(extra);
        a
    };
    refused(
        d,
        &cv(&["--plans", "random", "-n", "3", "--figure", "x.png"]),
        &[
            "--plans, -n, --figure apply only with --acquisition",
            "add --acquisition or leave them out",
        ],
    );
    for extra in [
        &["--no-ridge"][..],
        &["--noise", "0.1"],
        &["--restarts", "3"],
    ] {
        refused(
            d,
            &cv(extra),
            &[&format!("{} applies only with --acquisition", extra[0])],
        );
    }
    assert!(!d.join("q.json").exists() && !d.join("x.png").exists());
}

/// T11: a sample count, noise level or plan listed twice in `cv --acquisition` is refused,
/// as a method listed twice is (each gave a duplicate row).
#[test]
fn cv_acquisition_refuses_values_listed_twice() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    let cv = |extra: &[&'static str]| {
        let mut a = vec!["cv", "c.csv", "--acquisition", "--json", "q.json"];
        a.extend_from_slice(extra);
        a
    };
    refused(
        d,
        &cv(&["-n", "3,3"]),
        &["-n: sample count 3 is listed twice"],
    );
    refused(
        d,
        &cv(&["--noise", "0,0.02,0"]),
        &["--noise: noise level 0 is listed twice"],
    );
    refused(
        d,
        &cv(&["--plans", "error,error"]),
        &["--plans: plan `error` is listed twice"],
    );
    refused(
        d,
        &cv(&["--methods", "greedy,greedy"]),
        &["method `greedy` is listed twice"],
    );
}

/// T10: `cv --acquisition --figure` writes the format its name ends in (the old code
/// wrote PNG bytes into `x.svg`), and refuses another extension before any work.
#[test]
fn cv_acquisition_figure_is_written_in_the_format_it_is_named() {
    let dir = tmp();
    let d = dir.path();
    let mut c = String::from(CSV);
    c += "rough,0.3,0.3,0.3,0.05,0.05,0.05,0.04,5\n\
        gold,0,0,0,0.9,0.6,0.2,0.9,1200\n\
        paint,0.4,0.05,0.05,0.1,0.1,0.1,0.05,60\n\
        chalk,0.5,0.5,0.45,0.02,0.02,0.02,0.03,3\n";
    write(d, "c8.csv", c);
    let cv = |fig: &'static str| {
        vec![
            "cv",
            "c8.csv",
            "--acquisition",
            "--methods",
            "random",
            "-k",
            "2",
            "--plans",
            "random",
            "-n",
            "3",
            "--noise",
            "0",
            "--folds",
            "2",
            "--stride",
            "8",
            "--render-size",
            "16",
            "--no-appearance",
            "--json",
            "q.json",
            "--figure",
            fig,
        ]
    };
    refused(
        d,
        &cv("x.jpg"),
        &["--figure x.jpg: give a .svg or .png file name"],
    );
    assert!(!d.join("q.json").exists());
    let o = run(d, &cv("x.svg"));
    assert!(o.status.success(), "{}", stderr(&o));
    let svg = std::fs::read(d.join("x.svg")).expect("svg");
    let head = String::from_utf8_lossy(&svg[..svg.len().min(200)]).into_owned();
    assert!(head.contains("<svg"), "{head}");
    let o = run(d, &cv("x.PNG"));
    assert!(o.status.success(), "{}", stderr(&o));
    let png = std::fs::read(d.join("x.PNG")).expect("png");
    assert!(png.starts_with(b"\x89PNG"));
}

/// T14: a corrupt RGL header whose field name is 5,000 bytes of binary garbage ends in a
/// message of printable ASCII, the name escaped and cut (the old message held the raw
/// bytes, up to 19.7 KB).
#[test]
fn rgl_field_names_are_escaped_and_cut_in_messages() {
    let dir = tmp();
    let d = dir.path();
    let mut b = b"tensor_file\0".to_vec();
    b.extend_from_slice(&[1, 0]);
    b.extend_from_slice(&1u32.to_le_bytes());
    let name: Vec<u8> = (0..5000u32).map(|i| (i * 7 + 0x80) as u8).collect();
    b.extend_from_slice(&(name.len() as u16).to_le_bytes());
    b.extend_from_slice(&name);
    b.extend_from_slice(&[3, 0]); // dimension count, then nothing: truncated
    let f = write(d, "bad_rgb.bsdf", &b);
    let e = refused(
        d,
        &["info", f.to_str().expect("path")],
        &["truncated", "of field `\\x80"],
    );
    assert!(e.len() < 1000, "{} bytes: {e}", e.len());
    assert!(
        e.chars()
            .all(|c| c.is_ascii_graphic() || c == ' ' || c == '\n'),
        "{e}"
    );
    let err = brdf_basis::rgl::TensorFile::parse(b, &f).unwrap_err();
    assert!(err.to_string().contains("... ("), "{err}");
}

/// T15: a matrix of distances 1e308 is refused naming the overflow of the sums, not
/// "two medoids at distance 0" (they are 1e308 apart).
#[test]
fn select_on_distances_too_large_to_add_names_the_overflow() {
    let dir = tmp();
    let d = dir.path();
    let names = ["a", "b", "c", "d", "e", "f"];
    let mut s = format!("material,{}\n", names.join(","));
    for (i, n) in names.iter().enumerate() {
        let row: Vec<&str> = (0..names.len())
            .map(|j| if i == j { "0" } else { "1e308" })
            .collect();
        s += &format!("{n},{}\n", row.join(","));
    }
    write(d, "huge.csv", s);
    let e = refused(
        d,
        &[
            "select",
            "--distances",
            "huge.csv",
            "--method",
            "kmedoids",
            "-k",
            "2",
            "--runs",
            "3",
            "--json",
            "k.json",
        ],
        &["too large to add up", "overflows to infinity"],
    );
    assert!(!e.contains("distance 0"), "{e}");
}

/// T7: `render --fit` and `plot --fit` refuse the JSON of a fit from samples, saying why
/// and how to render it (the old code said "no material named `s`", or, with the samples
/// file named like a collection material, compared the fit with that other material and
/// exited 0). A samples file named like a collection material is fitted with a warning.
#[test]
fn render_and_plot_refuse_a_fit_from_samples() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    let mut s = String::from("theta_i,phi_i,theta_o,phi_o,r,g,b\n");
    for (ti, to) in [(10, 20), (20, 25), (30, 31), (40, 45), (50, 10), (60, 70)] {
        s += &format!("{ti},0,{to},180,0.2,0.1,0.1\n");
    }
    // `s` is no collection material, `target` one outside the basis, `plastic` a basis one.
    for (name, warned) in [
        ("s", None),
        ("target", Some("a")),
        ("plastic", Some("a basis")),
    ] {
        let samples = format!("{name}.csv");
        write(d, &samples, &s);
        let json = format!("f-{name}.json");
        let args = [
            "fit",
            "c.csv",
            "--basis",
            "plastic,metal",
            "--samples",
            &samples,
            "--json",
            &json,
        ];
        let o = run(d, &args);
        let e = stderr(&o);
        assert!(o.status.success(), "{e}");
        let w = format!("{} material of the collection", warned.unwrap_or("?"));
        assert_eq!(e.contains(&w), warned.is_some(), "{name}: {e}");
        if warned.is_some() {
            assert!(e.contains(&format!("named `{name}` after the samples file {samples}")));
        }
        let parts = [
            &format!("{json}: a fit from samples (`{samples}`, 6 samples)") as &str,
            "has no material in the collection to compare with",
            &format!("--samples {samples} --export DIR"),
            &format!("`DIR/{name}.binary` as the collection, with `--material {name}`"),
        ];
        let render = [
            "render",
            "c.csv",
            "--material",
            name,
            "--fit",
            &json,
            "--out",
            "r.exr",
            "--png",
            "r.png",
            "--heatmap",
            "h.png",
            "--size",
            "16",
        ];
        let e = refused(d, &render, &parts);
        assert!(!e.contains("normalized image error"), "{e}");
        refused(
            d,
            &[
                "plot",
                "c.csv",
                "--material",
                name,
                "--fit",
                &json,
                "--out",
                "p.svg",
            ],
            &parts,
        );
        for f in ["r.exr", "r.png", "h.png", "p.svg"] {
            assert!(!d.join(f).exists(), "{f}");
        }
    }
    // The way the message gives works.
    let args = [
        "fit",
        "c.csv",
        "--basis",
        "plastic,metal",
        "--samples",
        "s.csv",
        "--json",
        "g.json",
        "--export",
        "x",
    ];
    assert!(run(d, &args).status.success());
    let o = run(
        d,
        &[
            "render",
            "x/s.binary",
            "--material",
            "s",
            "--out",
            "r.exr",
            "--size",
            "16",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

/// T13: an RGL file whose reflectance overflows f32 is refused when it is read, naming the
/// file, the field and the cause (the old code: "invalid distance inf between ..." from
/// `distance`, naming neither).
#[test]
fn rgl_values_beyond_f32_are_refused_naming_the_file() {
    let dir = tmp();
    let d = dir.path();
    let b = crate::rgl::with(|v| {
        let f = crate::rgl::field_mut(v, "rgb");
        let n = f.data.len() / 4;
        f.data = crate::rgl::f32_bytes(std::iter::repeat_n(3e38f32, n));
    });
    std::fs::create_dir(d.join("m")).expect("dir");
    let f = write(&d.join("m"), "rgb_huge.bsdf", &b);
    let parts = [
        "rgb_huge.bsdf: field `rgb`: the reflectance it gives reaches",
        "beyond the f32 range",
    ];
    for args in [
        &["info", "m/rgb_huge.bsdf"][..],
        &["distance", "m", "--out", "d.npy"],
    ] {
        let e = refused(d, args, &parts);
        assert!(!e.contains("invalid distance"), "{e}");
    }
    assert!(!d.join("d.npy").exists());
    let e = brdf_basis::rgl::RglMaterial::load(&f).unwrap_err();
    assert!(
        matches!(e, brdf_basis::error::RglError::OutOfRange { .. }),
        "{e}"
    );
    // The file's own values at 1e30 are in range and read.
    let b = crate::rgl::with(|v| {
        let f = crate::rgl::field_mut(v, "rgb");
        let n = f.data.len() / 4;
        f.data = crate::rgl::f32_bytes(std::iter::repeat_n(1e30f32, n));
    });
    let f = write(d, "rgb_big.bsdf", &b);
    assert!(brdf_basis::rgl::RglMaterial::load(&f).is_ok());
}

/// T13: a neural BRDF set whose outputs pass the f32 range (b3 = 1e30: infinite in f32;
/// b3 = 100: e^100, which the old code clamped to e^88 without a word and `tabulate`
/// wrote as 2.48e41) is refused when it is read, naming the set, the material and the
/// cause, for every command and back-end alike.
#[test]
fn nbrdf_outputs_beyond_f32_are_refused_naming_the_set() {
    use brdf_basis::brdf::{Nbrdf, NBRDF_PARTS};
    let dir = tmp();
    let d = dir.path();
    let n = d.join("n");
    std::fs::create_dir(&n).expect("dir");
    let ok = crate::nbrdf::random_net(3);
    crate::nbrdf::write_set(&n, "fine", &ok);
    assert!(ok.check_output_range().is_ok());
    let part = |name: &str| NBRDF_PARTS.iter().find(|p| p.0 == name).expect("part").2;
    for (b3, zero_fc3, shown) in [(1e30f32, false, "inf"), (100.0, true, "2.688e43")] {
        let mut w = ok.weights().to_vec();
        w[part("b3")..].fill(b3);
        if zero_fc3 {
            w[part("fc3")..part("b3")].fill(0.0);
        }
        let net = Nbrdf::from_weights(w).expect("finite weights");
        let e = net.check_output_range().unwrap_err();
        assert!(e.contains(&format!("reaches {shown}")), "{e}");
        crate::nbrdf::write_set(&n, "huge", &net);
        let parts = [
            "huge_*.npy: material `huge`: the network's red output",
            "beyond the f32 range",
        ];
        for args in [
            &["info", "n"][..],
            &["distance", "n", "--out", "d.npy"],
            &["tabulate", "n", "--material", "huge", "--out", "t.binary"],
        ] {
            let e = refused(d, args, &parts);
            assert!(!e.contains("invalid distance"), "{e}");
        }
        // The GPU back-end alike (the set is refused as it is read, before any kernel).
        let mut cmd = bin();
        cmd.args([
            "--quiet",
            "--backend",
            "gpu",
            "distance",
            "n",
            "--out",
            "d.npy",
        ])
        .current_dir(d);
        let o = output_within(&mut cmd, Duration::from_secs(300)).expect("hangs");
        let e = stderr(&o);
        assert!(e.contains(parts[0]) || e.contains("adapter"), "{e}");
        for f in ["d.npy", "t.binary"] {
            assert!(!d.join(f).exists(), "{f}");
        }
    }
}
