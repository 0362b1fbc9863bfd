//! Saved matrices: `distance` writes a `.npy` with its names sidecar, `select --distances`
//! clusters it without recomputing, and every malformed matrix is refused with an error
//! naming the file and the offending row and column.

use crate::common::*;
use brdf_basis::io::npy::write_npy_2d;
use brdf_basis::io::saved::load_saved_matrix;
use brdf_basis::io::sidecar::{read_sidecar, sidecar_path};
use brdf_basis::io::MatrixFileError;
use std::path::Path;
use std::process::Command;

fn run_ok(c: &mut Command) {
    let out = c.output().expect("run");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn load_err(path: &Path) -> (MatrixFileError, String) {
    let e = load_saved_matrix(path).expect_err("must be refused");
    let msg = e.to_string();
    assert!(
        msg.contains(&path.display().to_string()),
        "error does not name the file: {msg}"
    );
    (e, msg)
}

const GOOD: &str = "material,a,b,c\na,0,1,2\nb,1,0,3\nc,2,3,0\n";

#[test]
fn saved_npy_and_csv_cluster_exactly_like_a_computed_matrix() {
    let dir = tmp();
    let npy = dir.path().join("d.npy");
    let csv = dir.path().join("d.csv");
    for out in [&npy, &csv] {
        run_ok(
            bin_cpu()
                .args(["distance", "--stride", "4", "--out"])
                .arg(out),
        );
    }
    // The sidecar: names, settings, N, checksum.
    let side = read_sidecar(&npy).expect("sidecar");
    assert_eq!(sidecar_path(&npy), dir.path().join("d.names.json"));
    let coll = brdf_basis::collection::Collection::embedded_default();
    assert_eq!(side.names, coll.names());
    assert_eq!(side.n, coll.len());
    assert_eq!(side.settings.metric.to_string(), "brdf-it");
    assert_eq!(side.settings.stride, 4);
    assert_eq!(side.collection_fingerprint, coll.fingerprint());
    assert_eq!(side.npy_bytes, std::fs::metadata(&npy).expect("meta").len());
    // npy and csv load to the same matrix.
    let a = load_saved_matrix(&npy).expect("npy");
    let b = load_saved_matrix(&csv).expect("csv");
    assert_eq!(a.matrix, b.matrix);
    // select on the saved matrices = select computing it.
    let mut results = Vec::new();
    for src in [None, Some(&npy), Some(&csv)] {
        let json = dir.path().join(format!("s{}.json", results.len()));
        let mut c = bin_cpu();
        c.args(["select", "--method", "kmedoids", "-k", "4", "--runs", "2"]);
        match src {
            Some(p) => c.arg("--distances").arg(p),
            None => c.args(["--stride", "4"]),
        };
        run_ok(c.arg("--json").arg(&json));
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).expect("json")).expect("parse");
        // A CSV matrix carries no collection fingerprint (the others do, the same one).
        let fp = v
            .as_object_mut()
            .and_then(|o| o.remove("collection_fingerprint"));
        assert_eq!(
            fp.is_some_and(|f| f.is_null()),
            src == Some(&csv),
            "{src:?}"
        );
        results.push(v);
    }
    assert_eq!(results[0], results[1]);
    assert_eq!(results[0], results[2]);
    assert_eq!(results[0]["runs"].as_array().expect("runs").len(), 2);
}

#[test]
fn npy_without_sidecar_or_with_a_mismatched_one_is_refused() {
    let dir = tmp();
    let npy = dir.path().join("d.npy");
    run_ok(
        bin_cpu()
            .args(["distance", "--stride", "6", "--out"])
            .arg(&npy),
    );
    let side = std::fs::read(sidecar_path(&npy)).expect("sidecar");
    // A matrix rewritten without its sidecar (another collection, same size): checksum.
    let read = brdf_basis::io::npy::read_npy_2d(&npy).expect("read");
    let (n, mut data) = (read.rows, read.data);
    data[1] *= 2.0;
    data[n] *= 2.0;
    write_npy_2d(&npy, n, n, &data).expect("rewrite");
    let (e, msg) = load_err(&npy);
    assert!(matches!(e, MatrixFileError::Mismatch { .. }), "{msg}");
    assert!(msg.contains("d.names.json"), "{msg}");
    // A sidecar for another N.
    let small = dir.path().join("s.npy");
    write_npy_2d(&small, 2, 2, &[0.0, 1.0, 1.0, 0.0]).expect("small");
    std::fs::write(sidecar_path(&small), &side).expect("copy sidecar");
    let (e, msg) = load_err(&small);
    assert!(matches!(e, MatrixFileError::Mismatch { .. }), "{msg}");
    // No sidecar at all.
    std::fs::remove_file(sidecar_path(&npy)).expect("rm");
    let (e, msg) = load_err(&npy);
    assert!(matches!(e, MatrixFileError::NoSidecar { .. }), "{msg}");
    // The command line: non-zero exit, one message naming the file.
    let out = bin_cpu()
        .args(["select", "--method", "kmedoids", "-k", "2", "--distances"])
        .arg(&npy)
        .arg("--json")
        .arg(dir.path().join("o.json"))
        .output()
        .expect("run");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("d.names.json"), "{err}");
    assert!(!dir.path().join("o.json").exists());
}

#[test]
fn non_square_matrices_are_refused() {
    let dir = tmp();
    let p = dir.path().join("short.csv");
    std::fs::write(&p, "material,a,b,c\na,0,1,2\nb,1,0\nc,2,3,0\n").expect("write");
    let (e, msg) = load_err(&p);
    assert!(matches!(e, MatrixFileError::NotSquare { .. }), "{msg}");
    assert!(msg.contains("row 1 (`b`) has 2 values"), "{msg}");
    let p = dir.path().join("rows.csv");
    std::fs::write(&p, "material,a,b,c\na,0,1,2\nb,1,0,3\n").expect("write");
    let (e, msg) = load_err(&p);
    assert!(matches!(e, MatrixFileError::NotSquare { .. }), "{msg}");
    let p = dir.path().join("rect.npy");
    write_npy_2d(&p, 2, 3, &[0.0; 6]).expect("npy");
    std::fs::write(
        sidecar_path(&p),
        serde_json::to_string(&brdf_basis::io::sidecar::MatrixSidecar::new(
            vec!["a".into(), "b".into()],
            brdf_basis::io::sidecar::MatrixSettings {
                metric: brdf_basis::distance::Metric::BrdfIt,
                lobe: brdf_basis::distance::LobeKind::Specular,
                weighting: brdf_basis::merl::Weighting::Uniform,
                mask: brdf_basis::merl::Mask::Evaluation,
                stride: 1,
                band_rows: 1024,
            },
            "0".into(),
            2,
            None,
            brdf_basis::io::npy::NpyDigest { bytes: 0, xxh3: 0 },
        ))
        .expect("json"),
    )
    .expect("sidecar");
    let (e, msg) = load_err(&p);
    assert!(matches!(e, MatrixFileError::NotSquare { .. }), "{msg}");
    assert!(msg.contains("(2, 3)"), "{msg}");
}

#[test]
fn asymmetric_matrix_is_refused_naming_the_pair() {
    let dir = tmp();
    let p = dir.path().join("asym.csv");
    std::fs::write(&p, "material,a,b,c\na,0,1,2\nb,1,0,3\nc,2,3.5,0\n").expect("write");
    let (e, msg) = load_err(&p);
    match e {
        MatrixFileError::Entry {
            row, col, reason, ..
        } => {
            assert_eq!((row, col), (1, 2));
            assert!(reason.contains("not symmetric"), "{msg}");
        }
        other => panic!("{other}"),
    }
    assert!(msg.contains("`b`") && msg.contains("`c`"), "{msg}");
    // Within the stated tolerance: accepted and made exactly symmetric.
    let p = dir.path().join("near.csv");
    std::fs::write(&p, "material,a,b\na,0,1\nb,1.0000000000001,0\n").expect("write");
    let m = load_saved_matrix(&p).expect("within tolerance").matrix;
    assert_eq!(m.as_full()[1], m.as_full()[2]);
}

#[test]
fn negative_entry_is_refused() {
    let dir = tmp();
    let p = dir.path().join("neg.csv");
    std::fs::write(&p, "material,a,b,c\na,0,-1,2\nb,-1,0,3\nc,2,3,0\n").expect("write");
    let (e, msg) = load_err(&p);
    assert!(
        matches!(e, MatrixFileError::Entry { row: 0, col: 1, .. }),
        "{msg}"
    );
    assert!(msg.contains("negative"), "{msg}");
}

#[test]
fn nan_and_infinite_entries_are_refused() {
    let dir = tmp();
    for (name, text) in [
        ("nan.csv", "material,a,b,c\na,0,1,2\nb,1,0,NaN\nc,2,NaN,0\n"),
        ("inf.csv", "material,a,b,c\na,0,1,2\nb,1,0,inf\nc,2,inf,0\n"),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, text).expect("write");
        let (e, msg) = load_err(&p);
        assert!(
            matches!(e, MatrixFileError::Entry { row: 1, col: 2, .. }),
            "{msg}"
        );
        assert!(msg.contains("not a finite number"), "{msg}");
    }
    let p = dir.path().join("word.csv");
    std::fs::write(&p, "material,a,b\na,0,x\nb,1,0\n").expect("write");
    let (_, msg) = load_err(&p);
    assert!(msg.contains("`x` is not a number"), "{msg}");
}

#[test]
fn nonzero_diagonal_is_refused() {
    let dir = tmp();
    let p = dir.path().join("diag.csv");
    std::fs::write(&p, "material,a,b,c\na,0,1,2\nb,1,0.5,3\nc,2,3,0\n").expect("write");
    let (e, msg) = load_err(&p);
    assert!(
        matches!(e, MatrixFileError::Entry { row: 1, col: 1, .. }),
        "{msg}"
    );
    assert!(msg.contains("diagonal"), "{msg}");
}

#[test]
fn names_that_do_not_match_are_refused() {
    let dir = tmp();
    let good = dir.path().join("good.csv");
    std::fs::write(&good, GOOD).expect("write");
    assert_eq!(
        load_saved_matrix(&good).expect("good").matrix.names(),
        ["a", "b", "c"]
    );
    // Row named differently from its header column.
    let p = dir.path().join("rowname.csv");
    std::fs::write(&p, "material,a,b,c\na,0,1,2\nx,1,0,3\nc,2,3,0\n").expect("write");
    let (e, msg) = load_err(&p);
    assert!(matches!(e, MatrixFileError::Names { .. }), "{msg}");
    assert!(msg.contains("`x`"), "{msg}");
    // A name twice.
    let p = dir.path().join("dup.csv");
    std::fs::write(&p, "material,a,b,a\na,0,1,2\nb,1,0,3\na,2,3,0\n").expect("write");
    let (e, msg) = load_err(&p);
    assert!(matches!(e, MatrixFileError::Names { .. }), "{msg}");
    assert!(msg.contains("named twice"), "{msg}");
    // A sidecar with fewer names than the matrix has rows.
    let npy = dir.path().join("d.npy");
    run_ok(
        bin_cpu()
            .args(["distance", "--stride", "6", "--out"])
            .arg(&npy),
    );
    let sp = sidecar_path(&npy);
    let mut side: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&sp).expect("read")).expect("json");
    side["names"].as_array_mut().expect("names").pop();
    std::fs::write(&sp, side.to_string()).expect("write");
    let (e, msg) = load_err(&npy);
    assert!(matches!(e, MatrixFileError::Names { .. }), "{msg}");
}
