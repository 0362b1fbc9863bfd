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
        // The grid of the distances is recorded (a .npy: its sidecar's), except for a CSV
        // matrix, which does not say.
        if src == Some(&csv) {
            assert!(v.get("stride").is_none(), "{v}");
        } else {
            assert_eq!(v["stride"], 4, "{src:?}");
            assert_eq!(v["mask"], "evaluation", "{src:?}");
            assert_eq!(v["weighting"], "uniform", "{src:?}");
            for key in ["mask", "weighting", "stride"] {
                v.as_object_mut().and_then(|o| o.remove(key));
            }
        }
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

/// A random `n x n` Euclidean matrix (points in the unit cube; exactly symmetric) saved as
/// `.npy` + sidecar at `path`.
fn save_random(path: &Path, n: usize, seed: u64) -> brdf_basis::distance::DistanceMatrix {
    use brdf_basis::distance::{DistanceMatrix, DistanceParams, DEFAULT_BAND_ROWS};
    use brdf_basis::io::saved::write_npy_with_sidecar;
    use brdf_basis::io::sidecar::MatrixSettings;
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let pts: Vec<[f64; 3]> = (0..n)
        .map(|_| [rng.random(), rng.random(), rng.random()])
        .collect();
    let mut data = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            let d2: f64 = (0..3).map(|c| (pts[i][c] - pts[j][c]).powi(2)).sum();
            data[i * n + j] = d2.sqrt();
        }
    }
    let names = (0..n).map(|i| format!("m{i:04}")).collect();
    let m = DistanceMatrix::from_full(names, data).expect("matrix");
    let coll = brdf_basis::collection::Collection::embedded_default();
    let p = DistanceParams::default().check(&coll).expect("params");
    write_npy_with_sidecar(
        path,
        &m,
        &MatrixSettings::of(&p, DEFAULT_BAND_ROWS),
        "random",
    )
    .expect("write");
    m
}

/// `select --distances` reads a `.npy` in place (memory-mapped): the same values as read
/// into memory, and k-medoids (both algorithms), GCUK and every validity index give the
/// same medoids, labels, losses and indices, bit for bit.
#[test]
fn mapped_matrix_clusters_bit_for_bit_like_the_loaded_one() {
    use brdf_basis::cluster::{GcukParams, KMedoidsAlgorithm, KMedoidsParams};
    use brdf_basis::io::saved::{load_saved_matrix_with, MatrixLoad};
    use brdf_basis::select::{gcuk_runs, kmedoids_runs, named_runs};
    let dir = tmp();
    let npy = dir.path().join("r.npy");
    let m = save_random(&npy, 240, 7);
    let before = std::fs::read(&npy).expect("bytes");
    let mapped = load_saved_matrix_with(&npy, MatrixLoad::Map).expect("map");
    let read = load_saved_matrix_with(&npy, MatrixLoad::Read).expect("read");
    assert!(cfg!(not(unix)) || mapped.matrix.is_mapped());
    assert!(!read.matrix.is_mapped());
    assert_eq!(mapped.sidecar, read.sidecar);
    let bits = |d: &brdf_basis::distance::DistanceMatrix| -> Vec<u64> {
        d.as_full().iter().map(|v| v.to_bits()).collect()
    };
    assert_eq!(bits(&mapped.matrix), bits(&read.matrix));
    assert_eq!(bits(&mapped.matrix), bits(&m));
    assert_eq!(mapped.matrix.names(), read.matrix.names());
    // `{:?}` of f64 is exact (shortest round-trip form), so equal text = equal bits.
    for algorithm in [KMedoidsAlgorithm::FasterPam, KMedoidsAlgorithm::Pam] {
        for k in [2, 5, 9] {
            let p = KMedoidsParams::new(k)
                .algorithm(algorithm)
                .seed(3)
                .restarts(2);
            let a = p.fit(&mapped.matrix).expect("mapped");
            let b = p.fit(&read.matrix).expect("read");
            assert_eq!(format!("{a:?}"), format!("{b:?}"), "{algorithm} k {k}");
        }
    }
    let g = GcukParams::default().k_range(2, 8).generations(15).seed(5);
    let a = g.fit(&mapped.matrix).expect("gcuk mapped");
    let b = g.fit(&read.matrix).expect("gcuk read");
    assert_eq!(format!("{a:?}"), format!("{b:?}"));
    // The select path: runs, then every validity index of each run.
    let quiet = |_: u64, _: u64| {};
    let runs = |d| {
        let mut r = kmedoids_runs(d, &[3, 6], 2, 11, KMedoidsAlgorithm::FasterPam, &quiet)
            .expect("kmedoids runs");
        let gp = g.check().expect("gcuk params");
        r.extend(gcuk_runs(d, &gp, 2, 11, &quiet).expect("gcuk runs"));
        format!("{:?}", named_runs(d, &r).expect("named"))
    };
    assert_eq!(runs(&mapped.matrix), runs(&read.matrix));
    drop(mapped);
    assert_eq!(
        std::fs::read(&npy).expect("bytes"),
        before,
        "the file is unchanged"
    );
}

/// A mapped matrix with pairs that differ within the tolerance holds their means, as the
/// loaded one does, and the file on disk keeps its bytes (the mapping is private).
#[test]
fn mapped_matrix_within_tolerance_is_made_symmetric_without_touching_the_file() {
    use brdf_basis::io::npy::{npy_header, read_npy_2d};
    use brdf_basis::io::saved::{load_saved_matrix_with, MatrixLoad};
    let dir = tmp();
    let npy = dir.path().join("r.npy");
    let m = save_random(&npy, 20, 9);
    // Nudge D[2][5] by a relative 1e-12 and write the pair with a matching sidecar.
    let n = 20;
    let mut data = m.as_full().to_vec();
    data[2 * n + 5] *= 1.0 + 1e-12;
    let mut bytes = npy_header(n, n);
    for v in &data {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    let side = read_sidecar(&npy).expect("sidecar");
    std::fs::write(&npy, &bytes).expect("npy");
    let digest = read_npy_2d(&npy).expect("read").digest;
    let side = brdf_basis::io::sidecar::MatrixSidecar::new(
        side.names.clone(),
        side.settings,
        side.collection_fingerprint.clone(),
        n,
        None,
        digest,
    );
    let mut set = brdf_basis::atomic::OutputSet::new();
    brdf_basis::io::sidecar::stage_sidecar(&mut set, &npy, &side).expect("stage");
    set.commit().expect("sidecar");
    let mapped = load_saved_matrix_with(&npy, MatrixLoad::Map).expect("map");
    let read = load_saved_matrix_with(&npy, MatrixLoad::Read).expect("read");
    assert!(cfg!(not(unix)) || mapped.matrix.is_mapped());
    assert_eq!(mapped.matrix.as_full(), read.matrix.as_full());
    let (a, b) = (
        mapped.matrix.as_full()[2 * n + 5],
        mapped.matrix.as_full()[5 * n + 2],
    );
    assert_eq!(a.to_bits(), b.to_bits());
    assert_eq!(a, 0.5 * (data[2 * n + 5] + data[5 * n + 2]));
    assert_eq!(std::fs::read(&npy).expect("bytes"), bytes);
}

/// Truncated, extended, rewritten and lying `.npy` files are refused the same way whether
/// mapped or read: the same error, naming the file.
#[test]
fn damaged_npy_is_refused_alike_mapped_or_read() {
    use brdf_basis::io::saved::{load_saved_matrix_with, MatrixLoad};
    let dir = tmp();
    let npy = dir.path().join("r.npy");
    save_random(&npy, 12, 1);
    let good = std::fs::read(&npy).expect("bytes");
    let header_len = good.len() - 8 * 144;
    let mut cases: Vec<(&str, Vec<u8>)> = vec![
        ("truncated by 12 bytes", good[..good.len() - 12].to_vec()),
        ("truncated to the header", good[..header_len].to_vec()),
        ("header cut", good[..20].to_vec()),
        ("empty", Vec::new()),
        ("one stray byte more", [&good[..], &[0u8]].concat()),
        ("one value more", [&good[..], &[0u8; 8]].concat()),
    ];
    let mut flipped = good.clone();
    flipped[header_len + 8 * 13 + 7] ^= 0x80;
    cases.push(("a sign bit flipped", flipped));
    let mut lying = good.clone();
    let text = String::from_utf8_lossy(&lying[10..header_len]).replace("(12, 12)", "(12, 11)");
    lying[10..header_len].copy_from_slice(text.as_bytes());
    cases.push(("a header that lies about the shape", lying));
    let mut nan = good.clone();
    nan[header_len + 8..header_len + 16].copy_from_slice(&f64::NAN.to_le_bytes());
    cases.push(("NaN (checksum first)", nan));
    for (what, bytes) in cases {
        std::fs::write(&npy, &bytes).expect("write");
        let a = load_saved_matrix_with(&npy, MatrixLoad::Map).expect_err(what);
        let b = load_saved_matrix_with(&npy, MatrixLoad::Read).expect_err(what);
        assert_eq!(a.to_string(), b.to_string(), "{what}");
        assert!(a.to_string().contains("r.npy"), "{what}: {a}");
    }
}
