//! The S1 and S2 defects of the second hostile audit (review/audit-2.md, Part 2): samples
//! and candidates files (N4, M1, N6, T2, T6), plans on targets in the basis (N5, T3), and
//! saved matrices changed while clustered (N7, M2). Each test fails on the code the audit
//! ran.

use crate::common::*;
use brdf_basis::run::Request as _;
use std::path::Path;
use std::process::Output;
use std::time::Duration;

const CSV: &str = "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n\
    plastic,0.2,0.1,0.05,0.3,0.3,0.3,0.04,120\n\
    metal,0,0,0,0.9,0.7,0.4,0.8,2500\n\
    satin,0.05,0.05,0.08,0.2,0.25,0.3,0.1,15\n\
    target,0.12,0.07,0.06,0.5,0.4,0.3,0.2,400\n";

/// Direction pairs in degrees, all above the horizon.
const ANGLES: [[f64; 4]; 8] = [
    [0.0, 0.0, 10.0, 180.0],
    [20.0, 0.0, 25.0, 180.0],
    [30.0, 0.0, 31.0, 175.0],
    [45.0, 90.0, 44.0, 270.0],
    [60.0, 0.0, 10.0, 90.0],
    [5.0, 0.0, 70.0, 0.0],
    [15.0, 30.0, 16.0, 212.0],
    [40.0, 0.0, 41.0, 180.5],
];

fn run(dir: &Path, args: &[&str]) -> Output {
    let mut cmd = bin();
    cmd.args(["--quiet", "--backend", "cpu"])
        .args(args)
        .current_dir(dir);
    output_within(&mut cmd, Duration::from_secs(120))
        .unwrap_or_else(|| panic!("brdf-basis {args:?} hangs"))
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A refusal: exit status 1 (not a panic's 101 or a signal), no backtrace, and a message
/// holding every one of `parts`.
fn refused(dir: &Path, args: &[&str], parts: &[&str]) {
    let o = run(dir, args);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{args:?}: {:?}\n{e}", o.status);
    assert!(!e.contains("panicked"), "{args:?}: {e}");
    for p in parts {
        assert!(e.contains(p), "{args:?}: `{p}` not in: {e}");
    }
}

/// A samples CSV: `header`, then one row per [`ANGLES`] entry with `tail(row)` appended.
fn samples_csv(dir: &Path, name: &str, header: &str, tail: impl Fn(usize) -> String) {
    let mut s = format!("{header}\n");
    for (i, a) in ANGLES.iter().enumerate() {
        s += &format!("{},{},{},{},{}\n", a[0], a[1], a[2], a[3], tail(i));
    }
    write(dir, name, s);
}

/// An ASTM file with `vars`, one row per [`ANGLES`] entry (radians) with `tail(row)`.
fn astm(dir: &Path, name: &str, vars: &str, tail: impl Fn(usize) -> String) {
    let mut s = format!("SOURCE test\nNUM_POINTS {}\nVARS {vars}\n", ANGLES.len());
    for (i, a) in ANGLES.iter().enumerate() {
        let r = a.map(f64::to_radians);
        s += &format!("{},{},{},{},{}\n", r[0], r[1], r[2], r[3], tail(i));
    }
    write(dir, name, s);
}

/// N4: a samples or candidates file naming a column twice (CSV), or one quantity twice
/// under one or two names (ASTM `VARS`), is refused naming the file, the line and the
/// column; the collection CSV does the same since the first audit.
#[test]
fn samples_and_candidates_refuse_duplicate_and_ambiguous_columns() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    let grey = |_| "0.1,0.12,0.15".to_string();
    samples_csv(d, "ok.csv", "theta_i,phi_i,theta_o,phi_o,r,g,b", grey);
    samples_csv(
        d,
        "dup_r.csv",
        "theta_i,phi_i,theta_o,phi_o,r,g,b,r",
        |_| "0.1,0.12,0.15,5".into(),
    );
    samples_csv(
        d,
        "dup_t.csv",
        "theta_i,phi_i,theta_o,phi_o,r,g,b,theta_i",
        |_| "0.1,0.12,0.15,70".into(),
    );
    samples_csv(
        d,
        "dup_note.csv",
        "theta_i,phi_i,theta_o,phi_o,r,g,b,note,note",
        |_| "0.1,0.12,0.15,x,y".into(),
    );
    astm(d, "ok.astm", "theta_i,phi_i,theta_s,phi_s,R,G,B", grey);
    astm(
        d,
        "dup_r.astm",
        "theta_i,phi_i,theta_s,phi_s,R,G,B,R",
        |_| "0.1,0.12,0.15,5".into(),
    );
    astm(
        d,
        "both.astm",
        "theta_i,phi_i,theta_s,phi_s,theta_o,phi_o,R,G,B",
        |_| "0.2,0.3,0.1,0.12,0.15".into(),
    );
    astm(
        d,
        "rgb_brdf.astm",
        "theta_i,phi_i,theta_s,phi_s,R,G,B,BRDF",
        |_| "0.1,0.12,0.15,0.2".into(),
    );
    let fit = |s: &str| -> Vec<String> {
        [
            "fit",
            "c.csv",
            "--basis",
            "plastic,metal",
            "--samples",
            s,
            "--json",
            "f.json",
        ]
        .map(String::from)
        .to_vec()
    };
    for ok in ["ok.csv", "ok.astm"] {
        let o = run(d, &fit(ok).iter().map(String::as_str).collect::<Vec<_>>());
        assert!(o.status.success(), "{ok}: {}", stderr(&o));
    }
    let cases: [(&str, &[&str]); 6] = [
        (
            "dup_r.csv",
            &[
                "dup_r.csv: line 1, column `r`",
                "appears twice (columns 5 and 8)",
            ],
        ),
        (
            "dup_t.csv",
            &[
                "dup_t.csv: line 1, column `theta_i`",
                "appears twice (columns 1 and 8)",
            ],
        ),
        (
            "dup_note.csv",
            &[
                "dup_note.csv: line 1, column `note`",
                "appears twice (columns 8 and 9)",
            ],
        ),
        (
            "dup_r.astm",
            &[
                "dup_r.astm: line 3, column `R`",
                "appears twice (variables 5 and 8)",
            ],
        ),
        (
            "both.astm",
            &[
                "both.astm: line 3, column `theta_o`",
                "names the same quantity as `theta_s` (variables 3 and 5)",
            ],
        ),
        (
            "rgb_brdf.astm",
            &[
                "rgb_brdf.astm: line 3, column `BRDF`",
                "R,G,B or BRDF, not both",
            ],
        ),
    ];
    for (file, parts) in cases {
        let args = fit(file);
        refused(
            d,
            &args.iter().map(String::as_str).collect::<Vec<_>>(),
            parts,
        );
        // The same reader reads plan's candidates.
        refused(
            d,
            &[
                "plan",
                "c.csv",
                "--basis",
                "plastic,metal",
                "-n",
                "2",
                "--candidates",
                file,
                "--out",
                "p.csv",
            ],
            parts,
        );
    }
    assert!(!d.join("p.csv").exists(), "a plan was written");
}

/// T2 and T6: plan reads its own `--out` (angles only) as candidates, values ignored even
/// when they are not numbers; an ASTM file whose `NUM_POINTS` disagrees with its rows, or
/// with numbers before `VARS`, is refused naming the line.
#[test]
fn candidates_need_only_angles_and_astm_counts_its_rows() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    let plan = |cands: &str, out: &str| {
        run(
            d,
            &[
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
                out,
            ],
        )
    };
    samples_csv(d, "x.csv", "theta_i,phi_i,theta_o,phi_o,r,g,b", |_| {
        "x,y,z".into()
    });
    let o = plan("x.csv", "p1.csv");
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(d.join("p1.csv")).expect("plan");
    assert!(text.starts_with("theta_i,phi_i,theta_o,phi_o\n"), "{text}");
    let o = plan("p1.csv", "p2.csv");
    assert!(o.status.success(), "{}", stderr(&o));
    // Same three directions, whichever order the plan takes them in.
    let rows = |p: &str| {
        let mut v: Vec<String> = std::fs::read_to_string(d.join(p))
            .expect("plan")
            .lines()
            .skip(1)
            .map(String::from)
            .collect();
        v.sort();
        v
    };
    assert_eq!(rows("p1.csv").len(), 3);
    // Fitting still needs the values.
    refused(
        d,
        &[
            "fit",
            "c.csv",
            "--basis",
            "plastic",
            "--samples",
            "p1.csv",
            "--json",
            "f.json",
        ],
        &["p1.csv: line 1, column `r`", "missing column"],
    );
    // ASTM: NUM_POINTS 8, 7 rows.
    let full = {
        astm(d, "a.astm", "theta_i,phi_i,theta_s,phi_s,R,G,B", |_| {
            "0.1,0.1,0.1".into()
        });
        std::fs::read_to_string(d.join("a.astm")).expect("astm")
    };
    let cut: String = full
        .lines()
        .take(full.lines().count() - 1)
        .fold(String::new(), |a, l| a + l + "\n");
    write(d, "cut.astm", &cut);
    refused(
        d,
        &[
            "fit",
            "c.csv",
            "--basis",
            "plastic",
            "--samples",
            "cut.astm",
            "--json",
            "f.json",
        ],
        &[
            "cut.astm: line 2",
            "NUM_POINTS 8, but the file has 7 data rows",
        ],
    );
    let early = full.replacen("VARS", "0.1,0.2,0.3,0.4,1,1,1\nVARS", 1);
    write(d, "early.astm", &early);
    refused(
        d,
        &[
            "fit",
            "c.csv",
            "--basis",
            "plastic",
            "--samples",
            "early.astm",
            "--json",
            "f.json",
        ],
        &["early.astm: line 3", "before the `VARS` line"],
    );
    // T1: a directory is not described as a collection, and no "line 0".
    std::fs::create_dir(d.join("dir")).expect("dir");
    let o = plan("dir", "p3.csv");
    let e = stderr(&o);
    assert!(
        !o.status.success()
            && e.contains("dir: is a directory")
            && e.contains("candidates file")
            && !e.contains("line 0")
            && !e.contains("collection"),
        "{e}"
    );
}

/// M1: values and sigmas beyond the range the fit carries end in a refusal naming the
/// file, the line and the column (exit 1), never a panic (exit 101).
#[test]
fn samples_beyond_the_fits_range_are_refused_not_panicked() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    let first = |v: &'static str| {
        move |i: usize| {
            if i == 0 {
                v.to_string()
            } else {
                "0.1,0.12,0.15".into()
            }
        }
    };
    samples_csv(
        d,
        "huge.csv",
        "theta_i,phi_i,theta_o,phi_o,r,g,b",
        first("1e308,1e308,1e308"),
    );
    samples_csv(
        d,
        "huge200.csv",
        "theta_i,phi_i,theta_o,phi_o,r,g,b",
        first("0.1,1e200,0.1"),
    );
    samples_csv(
        d,
        "mix.csv",
        "theta_i,phi_i,theta_o,phi_o,r,g,b,sigma",
        |i| format!("0.1,0.12,0.15,{}", if i == 3 { "1e-200" } else { "1" }),
    );
    samples_csv(
        d,
        "mix3.csv",
        "theta_i,phi_i,theta_o,phi_o,r,g,b,sigma_r,sigma_g,sigma_b",
        |i| format!("0.1,0.12,0.15,1,{},1", if i == 5 { "1e150" } else { "1" }),
    );
    astm(d, "huge.astm", "theta_i,phi_i,theta_s,phi_s,R,G,B", |i| {
        if i == 2 { "1e300,1,1" } else { "0.1,0.12,0.15" }.into()
    });
    let cases: [(&str, &[&str]); 5] = [
        (
            "huge.csv",
            &[
                "huge.csv: line 2, column `r`",
                "1e308 is beyond the largest reflectance",
            ],
        ),
        (
            "huge200.csv",
            &["huge200.csv: line 2, column `g`", "1e200 is beyond"],
        ),
        (
            "mix.csv",
            &[
                "mix.csv: line 2, column `sigma`",
                "1e200 times the smallest",
                "(line 5, column `sigma`)",
            ],
        ),
        (
            "mix3.csv",
            &[
                "mix3.csv: line 7, column `sigma_g`",
                "1e150 times the smallest",
            ],
        ),
        (
            "huge.astm",
            &["huge.astm: line 6, column `R`", "1e300 is beyond"],
        ),
    ];
    for (file, parts) in cases {
        refused(
            d,
            &[
                "fit",
                "c.csv",
                "--basis",
                "plastic,metal",
                "--samples",
                file,
                "--json",
                "f.json",
            ],
            parts,
        );
    }
    assert!(!d.join("f.json").exists());
    // The library's arrays: an error, not a panic.
    let c = brdf_basis::collection::parse_csv(CSV.as_bytes(), Path::new("t.csv")).expect("csv");
    let angles = ANGLES.to_vec();
    let mut rgb = vec![[0.1, 0.12, 0.15]; ANGLES.len()];
    rgb[1] = [1e300, 0.1, 0.1];
    let e = brdf_basis::fit_from_arrays(
        &c,
        &["plastic"],
        &angles,
        &rgb,
        None,
        brdf_basis::backend::weighted::TargetWeight::L2,
    )
    .expect_err("refused")
    .to_string();
    assert!(
        e.contains("line 2, column `r`") && e.contains("1e300"),
        "{e}"
    );
}

/// N6: the fit weights samples by `1 / sigma^2` scaled by the smallest sigma: scaling every
/// sigma by one constant (here 1e-200 and 1e200, where `1 / sigma^2` overflows or
/// underflows) gives the same fit, and that fit is not the all-zero one.
#[test]
fn scaling_every_sigma_by_one_constant_changes_nothing() {
    let c = brdf_basis::collection::parse_csv(CSV.as_bytes(), Path::new("t.csv")).expect("csv");
    let target = &c.materials()[c.index_of("target").expect("target")];
    let dir = |t: f64, p: f64| {
        let (t, p) = (t.to_radians(), p.to_radians());
        [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
    };
    let angles = ANGLES.to_vec();
    let rgb: Vec<[f64; 3]> = ANGLES
        .iter()
        .map(|a| {
            brdf_basis::acquire::material_at(target, dir(a[0], a[1]), dir(a[2], a[3]))
                .expect("value")
        })
        .collect();
    let sigma = |scale: f64| -> Vec<[f64; 3]> {
        (0..ANGLES.len())
            .map(|i| [1.0 + i as f64, 2.0, 0.5 + 0.25 * i as f64].map(|s| s * scale))
            .collect()
    };
    let basis = ["plastic", "metal", "satin"];
    let fit = |scale: f64| {
        brdf_basis::fit_from_arrays(
            &c,
            &basis,
            &angles,
            &rgb,
            Some(&sigma(scale)),
            brdf_basis::backend::weighted::TargetWeight::L2,
        )
        .unwrap_or_else(|e| panic!("scale {scale}: {e}"))
    };
    let one = fit(1.0);
    assert!(
        one.coefficients.iter().flatten().any(|&a| a > 1e-3),
        "{:?}",
        one.coefficients
    );
    for scale in [1e-200, 1e-150, 1e150, 1e200] {
        let f = fit(scale);
        for (a, b) in one
            .coefficients
            .iter()
            .flatten()
            .zip(f.coefficients.iter().flatten())
        {
            assert!(
                (a - b).abs() <= 1e-9 * a.abs().max(1e-6),
                "scale {scale}: {a} vs {b}"
            );
        }
        assert!(
            (f.relative_residual - one.relative_residual).abs()
                <= 1e-9 * one.relative_residual.max(1e-20),
            "scale {scale}: {} vs {}",
            f.relative_residual,
            one.relative_residual
        );
        assert!(f.mae.is_finite(), "scale {scale}");
    }
}

/// N5 and T3: a plan whose training targets all lie in the basis is refused as `select`
/// refuses its analogous case (a zero objective would choose the samples); with one
/// target outside the basis it plans. A basis or target list naming a material twice is
/// refused, as `fit` refuses it.
#[test]
fn plan_refuses_targets_all_in_the_basis_and_duplicates() {
    let dir = tmp();
    let d = dir.path();
    write(d, "c.csv", CSV);
    fn plan<'a>(extra: &[&'a str]) -> Vec<&'a str> {
        let mut a = vec!["plan", "c.csv", "-n", "3", "--out", "p.csv"];
        a.extend_from_slice(extra);
        a
    }
    refused(
        d,
        &plan(&["--basis", "plastic,metal", "--targets", "metal"]),
        &["a basis of 2 materials holds the only target and leaves none to score"],
    );
    // Audit 2, U1: counts of one are singular here too.
    refused(
        d,
        &plan(&["--basis", "metal", "--targets", "metal"]),
        &["a basis of 1 material holds the only target and leaves none to score"],
    );
    refused(
        d,
        &plan(&[
            "--basis",
            "plastic,metal",
            "--targets",
            "metal,plastic",
            "--criterion",
            "condition",
        ]),
        &["holds all 2 targets and leaves none to score"],
    );
    refused(
        d,
        &plan(&["--basis", "plastic,plastic"]),
        &["material `plastic` appears twice in the basis"],
    );
    refused(
        d,
        &plan(&["--basis", "plastic,metal", "--targets", "satin,satin"]),
        &["material `satin` appears twice in the targets"],
    );
    assert!(!d.join("p.csv").exists());
    let o = run(
        d,
        &plan(&["--basis", "plastic,metal", "--targets", "metal,satin"]),
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

/// N7 and M2: `select --distances` reads a `.npy` in place from a memory map. A file
/// rewritten in place (same size) or truncated while it is clustered ends in an error
/// naming the file and the change, never in a result of the mixed matrix (old code: exit
/// 0) or `SIGBUS` (old code: the process dies). The change is made from the clustering's
/// progress callback, so it always lands inside the run; each case runs in a child
/// process ([`matrix_change_child`]), so that a `SIGBUS` fails this test instead of
/// killing the test binary.
#[test]
fn a_mapped_matrix_changed_while_clustered_is_refused() {
    let exe = std::env::current_exe().expect("test binary");
    for mode in ["none", "truncate", "rewrite"] {
        let mut cmd = std::process::Command::new(&exe);
        cmd.args([
            "--exact",
            "audit2::matrix_change_child",
            "--include-ignored",
            "--nocapture",
        ])
        .env("AUDIT2_MATRIX_CHANGE", mode);
        let o = output_within(&mut cmd, Duration::from_secs(300)).expect("child hangs");
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success() && out.contains(&format!("CHILD-OK {mode}")),
            "{mode}: {:?}\n{out}\n{}",
            o.status,
            stderr(&o)
        );
    }
}

/// The child of [`a_mapped_matrix_changed_while_clustered_is_refused`].
#[test]
#[ignore = "run by a_mapped_matrix_changed_while_clustered_is_refused in a child process"]
fn matrix_change_child() {
    use brdf_basis::run::{SelectMethod, SelectRequest};
    use std::os::unix::fs::FileExt;
    let Ok(mode) = std::env::var("AUDIT2_MATRIX_CHANGE") else {
        return;
    };
    let dir = tmp();
    let d = dir.path();
    for (name, stride) in [("d.npy", "4"), ("e.npy", "5")] {
        let o = bin_cpu()
            .args(["distance", "--stride", stride, "--out"])
            .arg(d.join(name))
            .output()
            .expect("distance");
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let path = d.join("d.npy");
    let other = std::fs::read(d.join("e.npy")).expect("e.npy");
    let len = std::fs::metadata(&path).expect("meta").len();
    assert!(len > 5 * 4096 && other.len() as u64 == len, "{len}");
    let mut req = SelectRequest::new(SelectMethod::Kmedoids);
    req.k = Some(5);
    req.runs = Some(40);
    req.distances = Some(path.clone());
    let changed = std::sync::atomic::AtomicBool::new(false);
    let progress = |_: u64, _: u64| {
        if changed.swap(true, std::sync::atomic::Ordering::SeqCst) {
            return;
        }
        let f = std::fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .expect("open");
        match mode.as_str() {
            "truncate" => f.set_len(4096).expect("truncate"),
            "rewrite" => f.write_all_at(&other, 0).expect("rewrite"),
            _ => {}
        }
    };
    let r = req.run(&brdf_basis::run::Ctx::saved().progress(&progress));
    assert!(
        changed.load(std::sync::atomic::Ordering::SeqCst),
        "no progress report"
    );
    match mode.as_str() {
        "none" => {
            r.expect("an unchanged file clusters");
        }
        m => {
            let e = r.expect_err("a changed file is refused").to_string();
            let want = if m == "truncate" {
                "truncated"
            } else {
                "written to"
            };
            assert!(
                e.contains("d.npy: changed while it was read") && e.contains(want),
                "{m}: {e}"
            );
        }
    }
    println!("CHILD-OK {mode}");
}

/// Audit 2, U9: an ASTM file whose header or comment lines are Latin-1 (a `SOURCE` with
/// "Müller" as an instrument writes it) is read as it would be in UTF-8; a data row that is
/// not text is refused naming its line.
#[test]
fn astm_headers_in_latin1_are_read_and_bad_data_rows_named() {
    let dir = tmp();
    let d = dir.path();
    astm(d, "u.astm", "theta_i,phi_i,theta_s,phi_s,R,G,B", |_| {
        "0.1,0.2,0.3".into()
    });
    let utf8 = std::fs::read(d.join("u.astm")).expect("read");
    let latin1 = [b"SOURCE M\xfcller gonio\n".as_slice(), &utf8].concat();
    std::fs::write(d.join("l.astm"), &latin1).expect("write");
    let a = brdf_basis::acquire::read_samples(&d.join("u.astm")).expect("utf-8");
    let b = brdf_basis::acquire::read_samples(&d.join("l.astm")).expect("latin-1 header");
    // The same samples, one line further down (the extra SOURCE line).
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!((x.wi, x.wo, x.rgb, x.line + 1), (y.wi, y.wo, y.rgb, y.line));
    }
    let mut bad = latin1.clone();
    let at = bad.len() - 2;
    bad[at] = 0xff;
    std::fs::write(d.join("b.astm"), &bad).expect("write");
    let e = brdf_basis::acquire::read_samples(&d.join("b.astm"))
        .unwrap_err()
        .to_string();
    let last = latin1.split(|&c| c == b'\n').count() - 1;
    assert!(
        e.contains(&format!("line {last}")) && e.contains("must be ASCII or UTF-8"),
        "{e}"
    );
}
