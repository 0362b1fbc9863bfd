//! Untrusted inputs: a CSV with a duplicate column, a `.binary` rewritten while it is
//! read or holding values beyond f32, a thread count that would take minutes to start, a
//! 10 MB material name, and the messages for a stride and a tile count that used to
//! mislead.

use crate::common::*;
use brdf_basis::backend::cpu::{max_threads, CpuBackend};
use brdf_basis::collection::Collection;
use brdf_basis::error::{short_name, CollectionError, MerlError};
use brdf_basis::merl::{cell_info, N_CELLS};
use brdf_basis::merl::{read_binary, FILE_BYTES, SCALE};
use std::time::Duration;

const HEADER: &str = "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n";

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_csv_column_given_twice_is_refused_naming_file_line_and_column() {
    let d = tmp();
    let p = write(
        d.path(),
        "dup.csv",
        format!(
            "{HEADER},F0\na,0.1,0.1,0.1,0.5,0.5,0.5,0.5,50,0.9\nb,0.2,0.1,0.1,0.5,0.5,0.5,0.5,80,0.1\n"
        ),
    );
    let e = Collection::load(&p).expect_err("two F0 columns");
    assert!(
        matches!(
            &e,
            CollectionError::DuplicateColumn { column, first: 8, second: 10, .. } if column == "F0"
        ),
        "{e:?}"
    );
    let text = e.to_string();
    assert!(
        text.contains("dup.csv") && text.contains("line 1") && text.contains("`F0`"),
        "{text}"
    );
    // The command refuses it too, and writes nothing.
    let out = d.path().join("d.csv");
    let o = bin_cpu()
        .arg("distance")
        .arg(&p)
        .args(["--stride", "6", "--out"])
        .arg(&out)
        .output()
        .expect("run");
    assert!(!o.status.success() && !out.exists());
    assert!(
        stderr(&o).contains("column `F0` appears twice"),
        "{}",
        stderr(&o)
    );
    // An unused column twice is as ambiguous; two empty header fields are not names.
    let p = write(
        d.path(),
        "notes.csv",
        format!("{HEADER},notes,notes\na,0.1,0.1,0.1,0.5,0.5,0.5,0.5,50,x,y\n"),
    );
    assert!(matches!(
        Collection::load(&p),
        Err(CollectionError::DuplicateColumn { .. })
    ));
    let p = write(
        d.path(),
        "blank.csv",
        format!("{HEADER},,\na,0.1,0.1,0.1,0.5,0.5,0.5,0.5,50,,\n"),
    );
    assert_eq!(Collection::load(&p).expect("blank extra columns").len(), 1);
}

/// A MERL file holding `stored` in every valid cell of every channel.
fn constant_binary(stored: f64) -> Vec<u8> {
    let mut b = Vec::with_capacity(FILE_BYTES as usize);
    for d in [90i32, 90, 180] {
        b.extend_from_slice(&d.to_le_bytes());
    }
    for _ in 0..3 {
        for cell in 0..N_CELLS {
            let v = if cell_info(cell).valid { stored } else { -1.0 };
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    b
}

#[test]
fn a_binary_rewritten_while_it_is_read_is_refused_not_mixed() {
    use std::io::{Seek, Write};
    use std::sync::atomic::{AtomicBool, Ordering};
    let d = tmp();
    let versions = [constant_binary(100.0), constant_binary(200.0)];
    let p = write(d.path(), "live.binary", &versions[0]);
    let stop = AtomicBool::new(false);
    let (mut changed, mut whole) = (0, 0);
    std::thread::scope(|s| {
        // Another program rewriting the file in place, one version after the other,
        // for as long as the reads go on.
        s.spawn(|| {
            let mut f = std::fs::OpenOptions::new()
                .write(true)
                .open(&p)
                .expect("open");
            for v in versions.iter().cycle() {
                if stop.load(Ordering::Relaxed) {
                    break;
                }
                f.rewind().expect("seek");
                for chunk in v.chunks(1 << 20) {
                    f.write_all(chunk).expect("write");
                }
            }
        });
        for _ in 0..40 {
            match read_binary(&p) {
                Ok(t) => {
                    // One version, whole: every valid value the same.
                    let first = t.rgb[..N_CELLS].iter().find(|v| **v >= 0.0).copied();
                    let mixed = t.rgb[..N_CELLS]
                        .iter()
                        .any(|v| *v >= 0.0 && Some(*v) != first);
                    assert!(!mixed, "a read mixed two versions of the file");
                    whole += 1;
                }
                Err(e @ MerlError::Changed { .. }) => {
                    assert!(e.to_string().contains("live.binary"), "{e}");
                    assert!(e.to_string().contains("changed while it was read"), "{e}");
                    changed += 1;
                    if changed >= 3 {
                        break;
                    }
                }
                Err(e) => panic!("unexpected: {e}"),
            }
        }
        stop.store(true, Ordering::Relaxed);
    });
    eprintln!("{changed} reads refused as changed, {whole} whole");
    assert!(
        changed >= 1,
        "the rewrites overlapped no read ({whole} whole reads)"
    );
    // Once nothing writes, it reads.
    read_binary(&p).expect("quiet file");
}

#[test]
fn binary_values_beyond_f32_are_refused_naming_the_value_and_cell() {
    let d = tmp();
    let mut b = constant_binary(100.0);
    // Channel G (1), cell (theta_h 30, theta_d 40, phi_d 50): valid, and reflectance
    // 1e39 x 1.15 / 1500 is beyond f32.
    let cell = (30 * 90 + 40) * 180 + 50;
    assert!(cell_info(cell).valid);
    let index = N_CELLS + cell;
    let stored = 1e42;
    assert!(stored * SCALE[1] > f32::MAX as f64);
    b[12 + 8 * index..12 + 8 * index + 8].copy_from_slice(&stored.to_le_bytes());
    let p = write(d.path(), "huge.binary", &b);
    let e = read_binary(&p).expect_err("beyond f32");
    assert!(
        matches!(
            e,
            MerlError::BadValue { index: i, channel: 1, cell: [30, 40, 50], .. } if i == index
        ),
        "{e:?}"
    );
    let text = e.to_string();
    for want in [
        "huge.binary",
        &format!("value {index}"),
        "channel G",
        "theta_h row 30",
        "theta_d row 40",
        "phi_d column 50",
        "f32",
    ] {
        assert!(text.contains(want), "`{want}` in {text}");
    }
    // The largest value f32 holds is accepted.
    let ok = (f32::MAX as f64) / SCALE[1];
    b[12 + 8 * index..12 + 8 * index + 8].copy_from_slice(&ok.to_le_bytes());
    let p = write(d.path(), "max.binary", &b);
    let t = read_binary(&p).expect("f32::MAX");
    assert!(t.rgb[index].is_finite());
}

#[test]
fn a_huge_rayon_thread_count_is_capped_with_a_warning() {
    // RAYON_NUM_THREADS=100000 used to start 100,000 threads: killed after 300 s.
    let d = tmp();
    let out = d.path().join("d.csv");
    let o = output_within(
        bin()
            .args(["--backend", "cpu", "distance", "--stride", "6", "--out"])
            .arg(&out)
            .env("RAYON_NUM_THREADS", "100000"),
        Duration::from_secs(120),
    )
    .expect("finishes within 120 s");
    assert!(o.status.success(), "{}", stderr(&o));
    let max = max_threads();
    assert!(
        stderr(&o).contains("warning: RAYON_NUM_THREADS=100000 is more than 4 threads per CPU")
            && stderr(&o).contains(&format!("using {max} threads")),
        "{}",
        stderr(&o)
    );
    assert!(out.exists());
    // A sane request is left alone; an own pool above the cap is refused.
    let o = output_within(
        bin()
            .args(["--backend", "cpu", "info"])
            .env("RAYON_NUM_THREADS", "2"),
        Duration::from_secs(120),
    )
    .expect("info");
    assert!(o.status.success() && !stderr(&o).contains("RAYON_NUM_THREADS"));
    let e = CpuBackend::with_threads(max + 1).expect_err("above the cap");
    assert!(
        e.to_string()
            .contains(&format!("{} threads requested", max + 1)),
        "{e}"
    );
    assert_eq!(CpuBackend::with_threads(2).expect("2").threads(), 2);
}

#[test]
fn a_10_mb_material_name_is_shortened_in_every_message() {
    let long = "x".repeat(10 << 20);
    let shown = format!("{}... ({} bytes)", "x".repeat(60), long.len());
    assert_eq!(short_name(&long).to_string(), shown);
    assert_eq!(short_name("gold").to_string(), "gold");
    assert_eq!(short_name("red\u{1b}").to_string(), "red\\u{1b}");
    // 60 characters, not bytes: a multi-byte name is cut on a character boundary.
    let wide = "é".repeat(100);
    assert_eq!(
        short_name(&wide).to_string(),
        format!("{}... (200 bytes)", "é".repeat(60))
    );
    let d = tmp();
    // The long-named material is a black one: its fit warns.
    let csv = write(
        d.path(),
        "long.csv",
        format!(
            "{HEADER}\n{long},0.1,0.1,0.1,0.5,0.5,0.5,0.9,100\n\
             a,0.2,0.1,0.1,0.5,0.5,0.5,0.5,50\nblack,0,0,0,0,0,0,0.5,80\n"
        ),
    );
    let json = d.path().join("fit.json");
    let o = output_within(
        bin()
            .args(["--backend", "cpu", "fit"])
            .arg(&csv)
            .args(["--basis", "black", "--all-others", "--json"])
            .arg(&json),
        Duration::from_secs(120),
    )
    .expect("fit");
    let err = stderr(&o);
    assert!(o.status.success(), "{}", &err[..err.len().min(2000)]);
    assert!(err.len() < 10_000, "{} bytes of messages", err.len());
    assert!(err.contains(&format!("the fit of `{shown}`")), "{err}");
    // A duplicate of the long name: the error names it short, once.
    let dup = write(
        d.path(),
        "dup.csv",
        format!(
            "{HEADER}\n{long},0.1,0.1,0.1,0.5,0.5,0.5,0.9,100\n{long},0.2,0.1,0.1,0.5,0.5,0.5,0.5,50\n"
        ),
    );
    let e = Collection::load(&dup).expect_err("duplicate").to_string();
    assert!(
        e.len() < 1000 && e.contains(&shown),
        "{}",
        &e[..e.len().min(2000)]
    );
    let o = output_within(
        bin_cpu().arg("distance").arg(&dup).args(["--out", "x.csv"]),
        Duration::from_secs(120),
    )
    .expect("distance");
    assert!(
        !o.status.success() && o.stderr.len() < 1000,
        "{} bytes",
        o.stderr.len()
    );
}

#[test]
fn a_stride_that_leaves_no_cell_says_so() {
    let d = tmp();
    for args in [
        vec!["distance", "--stride", "90", "--out", "d.csv"],
        vec![
            "select", "--method", "greedy", "-k", "2", "--stride", "90", "--json", "s.json",
        ],
    ] {
        let o = bin_cpu()
            .args(&args)
            .current_dir(d.path())
            .output()
            .expect("run");
        assert!(!o.status.success());
        let err = stderr(&o);
        assert!(
            err.contains("--stride 90 leaves too few cells")
                && err.contains("1 x 1 x 2 = 2 cells, none of them in the evaluation mask")
                && !err.contains("valid in every material"),
            "{args:?}: {err}"
        );
    }
    // The largest stride that leaves cells is named, and works.
    let msg =
        brdf_basis::merl::no_cells_reason(brdf_basis::merl::Mask::Evaluation, 90, "the collection");
    let s: usize = msg
        .split("use --stride ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{msg}"));
    let cells = brdf_basis::merl::CellSet::new(
        brdf_basis::merl::Mask::Evaluation,
        brdf_basis::merl::Weighting::Uniform,
        s,
    );
    assert!(!cells.cells.is_empty(), "stride {s}");
    let none = brdf_basis::merl::CellSet::new(
        brdf_basis::merl::Mask::Evaluation,
        brdf_basis::merl::Weighting::Uniform,
        s + 1,
    );
    assert!(
        none.cells.is_empty() || s + 1 == 90,
        "stride {} also works",
        s + 1
    );
}

#[test]
fn too_many_tiles_names_the_number_of_materials() {
    // Tiles are row ranges (issue 17): any count up to the number of materials works,
    // whatever --band-rows; one more is refused, naming the number of materials.
    let d = tmp();
    let n = Collection::embedded_default().len();
    let o = bin_cpu()
        .args(["distance", "--stride", "6", "--band-rows", "8", "--tile"])
        .arg(format!("{}/{}", n + 1, n + 1))
        .arg("--out")
        .arg(d.path().join("t.npy"))
        .output()
        .expect("run");
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains(&format!(
            "{} tiles asked for, but the collection has {n} materials: use at most {n} tiles",
            n + 1
        )),
        "{err}"
    );
    let o = bin_cpu()
        .args(["distance", "--stride", "6", "--tile", "3/3", "--out"])
        .arg(d.path().join("t3.npy"))
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", stderr(&o));
}
