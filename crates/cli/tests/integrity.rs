//! Integrity of saved results (issue 15): the XXH3 checksums of a matrix and of its
//! sidecar, old sidecars refused, the fit file's collection fingerprint, `.npy` headers
//! as NumPy writes them, short files explained, and merges that leave nothing behind.

use crate::common::*;
use brdf_basis::backend::weighted::TargetWeight;
use brdf_basis::collection::Collection;
use brdf_basis::io::npy::read_npy_2d;
use brdf_basis::io::saved::load_saved_matrix;
use brdf_basis::io::sidecar::{read_sidecar, sidecar_path, MatrixSidecar};
use brdf_basis::io::MatrixFileError;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn cli() -> Command {
    let mut c = bin();
    c.args(["--quiet", "--backend", "cpu"]);
    c
}

fn ok(c: &mut Command) -> Output {
    let out = c.output().expect("run");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn refused(c: &mut Command) -> String {
    let out = c.output().expect("run");
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "accepted; stderr: {err}");
    err
}

/// A `.npy` (with sidecar) of the embedded collection at stride 6.
fn saved(dir: &Path) -> PathBuf {
    let npy = dir.join("d.npy");
    ok(cli().args(["distance", "--stride", "6", "--out"]).arg(&npy));
    npy
}

fn read_json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).expect("read")).expect("json")
}

fn write_json(p: &Path, v: &serde_json::Value) {
    std::fs::write(p, serde_json::to_string_pretty(v).expect("json")).expect("write");
}

/// The embedded collection's CSV with the first material's `n` changed (same names).
fn other_collection(dir: &Path) -> PathBuf {
    let csv = std::fs::read_to_string(
        crate::common::repo().join("crates/core/data/default_collection.csv"),
    )
    .expect("csv");
    let changed = csv.replacen(",79998,", ",79000,", 1);
    assert_ne!(changed, csv);
    let p = dir.join("other.csv");
    std::fs::write(&p, changed).expect("write");
    p
}

/// The word-wise FNV variant of sidecar format 1 (a transcription of the removed
/// `io::matrix::Fnv64`), to write a valid format-1 sidecar.
fn old_fnv64(bytes: &[u8]) -> u64 {
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let words = bytes.chunks_exact(8);
    let rest = words.remainder();
    for w in words {
        h = (h ^ u64::from_le_bytes(w.try_into().expect("8 bytes"))).wrapping_mul(PRIME);
    }
    for &b in rest {
        h = (h ^ b as u64).wrapping_mul(PRIME);
    }
    (h ^ rest.len() as u64).wrapping_mul(PRIME)
}

#[test]
fn two_sign_flips_in_a_saved_matrix_are_detected() {
    // [0.5, 1.25, 3, 7] and [-0.5, 1.25, -3, 7] collided under the format-1 checksum.
    let words = |v: [f64; 4]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let (a, b) = (words([0.5, 1.25, 3.0, 7.0]), words([-0.5, 1.25, -3.0, 7.0]));
    assert_eq!(old_fnv64(&a), old_fnv64(&b), "the old checksum collides");
    let hash = |x: &[u8]| {
        let mut h = brdf_basis::hash::Hasher::new();
        h.write(x);
        h.finish()
    };
    assert_ne!(hash(&a), hash(&b));
    // A saved matrix whose D[0][1] and D[1][0] had their sign bit flipped on disk.
    let dir = tmp();
    let npy = saved(dir.path());
    let mut bytes = std::fs::read(&npy).expect("read");
    let n = read_sidecar(&npy).expect("sidecar").n;
    let off = bytes.len() - 8 * n * n;
    for k in [1, n] {
        bytes[off + 8 * k + 7] ^= 0x80;
    }
    std::fs::write(&npy, bytes).expect("write");
    let e = load_saved_matrix(&npy).expect_err("refused");
    assert!(matches!(e, MatrixFileError::Mismatch { .. }), "{e}");
    assert!(e.to_string().contains("checksum"), "{e}");
}

#[test]
fn sidecar_with_reordered_names_is_refused() {
    let dir = tmp();
    let npy = saved(dir.path());
    let sp = sidecar_path(&npy);
    let mut side = read_json(&sp);
    side["names"].as_array_mut().expect("names").swap(0, 1);
    write_json(&sp, &side);
    let err = refused(
        cli()
            .args(["select", "--method", "kmedoids", "-k", "3", "--distances"])
            .arg(&npy)
            .arg("--json")
            .arg(dir.path().join("s.json")),
    );
    assert!(err.contains("d.names.json"), "{err}");
    assert!(err.contains("edited or damaged"), "{err}");
    assert!(!dir.path().join("s.json").exists());
}

#[test]
fn format_1_sidecar_is_refused_with_what_to_do() {
    let dir = tmp();
    let npy = saved(dir.path());
    let sp = sidecar_path(&npy);
    // The sidecar as format 1 wrote it: `npy_fnv64` over the .npy, no content checksum.
    let mut side = read_json(&sp);
    let obj = side.as_object_mut().expect("object");
    obj.remove("npy_xxh3");
    obj.remove("checksum");
    obj.insert("format".into(), "brdf-basis-matrix/1".into());
    let fnv = old_fnv64(&std::fs::read(&npy).expect("npy"));
    obj.insert("npy_fnv64".into(), format!("{fnv:016x}").into());
    write_json(&sp, &side);
    let e = load_saved_matrix(&npy).expect_err("refused");
    let msg = e.to_string();
    assert!(msg.contains("brdf-basis-matrix/1"), "{msg}");
    assert!(msg.contains("brdf-basis distance"), "{msg}");
    assert!(msg.contains("d.names.json"), "{msg}");
}

#[test]
fn fit_file_of_another_collection_is_refused_by_render_and_plot() {
    let dir = tmp();
    let d = dir.path();
    let fits = d.join("fits.json");
    ok(cli()
        .args([
            "fit",
            "--stride",
            "6",
            "--basis",
            "gloss-white-enamel,gloss-black-enamel",
            "--targets",
            "gloss-red-enamel",
            "--json",
        ])
        .arg(&fits));
    let file = brdf_basis::fit::file::FitFile::read(&fits).expect("fit file");
    let coll = Collection::embedded_default();
    assert_eq!(file.collection_fingerprint, Some(coll.fingerprint()));
    assert_eq!(file.collection_size, Some(coll.len()));
    let other = other_collection(d);
    let theirs = Collection::load(&other).expect("other").fingerprint();
    for args in [
        &["render", "--size", "16", "--out"][..],
        &["plot", "--out"][..],
    ] {
        let out = d.join(if args[0] == "render" {
            "r.exr"
        } else {
            "p.svg"
        });
        let err = refused(
            cli()
                .arg(args[0])
                .arg(&other)
                .args(["--material", "gloss-red-enamel", "--fit"])
                .arg(&fits)
                .args(&args[1..])
                .arg(&out),
        );
        assert!(err.contains("fits.json"), "{err}");
        assert!(err.contains("another collection"), "{err}");
        assert!(
            err.contains(&coll.fingerprint()) && err.contains(&theirs),
            "{err}"
        );
        assert!(!out.exists());
    }
    // A fit file without a fingerprint (written before it was recorded) is refused too.
    let mut v = read_json(&fits);
    v.as_object_mut()
        .expect("object")
        .remove("collection_fingerprint");
    write_json(&fits, &v);
    let err = refused(
        cli()
            .args([
                "render",
                "--material",
                "gloss-red-enamel",
                "--size",
                "16",
                "--fit",
            ])
            .arg(&fits)
            .arg("--out")
            .arg(d.join("r.exr")),
    );
    assert!(err.contains("no collection fingerprint"), "{err}");
    // The right collection still renders.
    let v = read_json(&fits);
    let mut v = v;
    v["collection_fingerprint"] = coll.fingerprint().into();
    write_json(&fits, &v);
    ok(cli()
        .args([
            "render",
            "--material",
            "gloss-red-enamel",
            "--size",
            "16",
            "--fit",
        ])
        .arg(&fits)
        .arg("--out")
        .arg(d.join("r.exr")));
}

#[test]
fn short_npy_says_how_many_bytes_were_expected_and_found() {
    let dir = tmp();
    let p = dir.path().join("short.npy");
    // A (7, 7) header and no data.
    std::fs::write(&p, brdf_basis::io::npy::npy_header(7, 7)).expect("write");
    let msg = read_npy_2d(&p).expect_err("short").to_string();
    assert!(msg.contains("short.npy"), "{msg}");
    assert!(msg.contains("has 128 bytes"), "{msg}");
    assert!(msg.contains("needs 520"), "{msg}");
    assert!(msg.contains("49 values"), "{msg}");
    assert!(msg.contains("0 bytes of data"), "{msg}");
    // A truncated matrix beside its sidecar: the same explanation, not a bare count.
    let npy = saved(dir.path());
    let bytes = std::fs::read(&npy).expect("read");
    std::fs::write(&npy, &bytes[..bytes.len() - 12]).expect("truncate");
    let msg = load_saved_matrix(&npy).expect_err("short").to_string();
    assert!(
        msg.contains(&format!("has {} bytes", bytes.len() - 12)),
        "{msg}"
    );
    assert!(msg.contains("4 stray bytes"), "{msg}");
}

/// A `.npy` of version `major` with the given header text (padded as NumPy pads it).
fn npy_with_header(major: u8, header: &str, data: &[f64]) -> Vec<u8> {
    let len_bytes = if major == 1 { 2 } else { 4 };
    let mut h = header.to_string();
    let total = 8 + len_bytes + h.len() + 1;
    h.push_str(&" ".repeat(total.next_multiple_of(64) - total));
    h.push('\n');
    let mut out = b"\x93NUMPY".to_vec();
    out.extend_from_slice(&[major, 0]);
    if major == 1 {
        out.extend_from_slice(&(h.len() as u16).to_le_bytes());
    } else {
        out.extend_from_slice(&(h.len() as u32).to_le_bytes());
    }
    out.extend_from_slice(h.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

#[test]
fn npy_headers_with_other_key_orders_quotes_spacing_and_versions_are_read() {
    let dir = tmp();
    let data = [0.0, 1.0, 2.0, 1.0, 0.0, 3.0];
    for (k, (major, header)) in [
        (
            1,
            "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3), }",
        ),
        (
            1,
            "{\"descr\": \"<f8\", \"fortran_order\": False, \"shape\": (2, 3)}",
        ),
        (
            1,
            "{'shape': (2, 3), 'fortran_order': False, 'descr': '<f8'}",
        ),
        (1, "{'descr':'<f8','fortran_order':False,'shape':(2,3)}"),
        (
            2,
            "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3), }",
        ),
        (
            3,
            "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3), }",
        ),
    ]
    .into_iter()
    .enumerate()
    {
        let p = dir.path().join(format!("h{k}.npy"));
        std::fs::write(&p, npy_with_header(major, header, &data)).expect("write");
        let a = read_npy_2d(&p).unwrap_or_else(|e| panic!("{header}: {e}"));
        assert_eq!((a.rows, a.cols), (2, 3), "{header}");
        assert_eq!(a.data, data, "{header}");
    }
    // Not float64 little-endian C order: refused saying why.
    for (header, want) in [
        (
            "{'descr': '>f8', 'fortran_order': False, 'shape': (2, 3)}",
            "`>f8`",
        ),
        (
            "{'descr': '<f8', 'fortran_order': True, 'shape': (2, 3)}",
            "Fortran",
        ),
    ] {
        let p = dir.path().join("bad.npy");
        std::fs::write(&p, npy_with_header(1, header, &data)).expect("write");
        let msg = read_npy_2d(&p).expect_err(header).to_string();
        assert!(msg.contains(want), "{msg}");
    }
}

fn tiles(d: &Path) -> Vec<PathBuf> {
    (1..=2)
        .map(|i| {
            let p = d.join(format!("t{i}.npy"));
            ok(cli()
                .args(["distance", "--stride", "6", "--band-rows", "8", "--tile"])
                .arg(format!("{i}/2"))
                .arg("--out")
                .arg(&p));
            p
        })
        .collect()
}

fn leftovers(d: &Path) -> Vec<String> {
    std::fs::read_dir(d)
        .expect("dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect()
}

#[test]
fn merge_leaves_nothing_behind_on_error() {
    let dir = tmp();
    let d = dir.path();
    let t = tiles(d);
    // The sidecar's path is taken by a directory: neither file is written.
    let out = d.join("m.npy");
    std::fs::create_dir(d.join("m.names.json")).expect("dir");
    let err = refused(cli().arg("merge").args(&t).arg("--out").arg(&out));
    assert!(err.contains("m.names.json"), "{err}");
    assert!(
        !out.exists(),
        "the matrix was put in place without its sidecar"
    );
    assert_eq!(leftovers(d), Vec::<String>::new());
    std::fs::remove_dir(d.join("m.names.json")).expect("rmdir");
    ok(cli().arg("merge").args(&t).arg("--out").arg(&out));
    assert!(out.exists() && sidecar_path(&out).exists());
    assert_eq!(leftovers(d), Vec::<String>::new());
}

#[cfg(unix)]
#[test]
fn merge_refuses_a_fifo_tile_and_leaves_no_temporary_file() {
    let dir = tmp();
    let d = dir.path();
    let t = tiles(d);
    // A FIFO in place of tile 2 (its sidecar intact): opening it would block forever.
    let fifo = d.join("f2.npy");
    std::fs::copy(sidecar_path(&t[1]), sidecar_path(&fifo)).expect("sidecar");
    let c = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).expect("path");
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo");
    let out = d.join("m.npy");
    let mut child = cli()
        .arg("merge")
        .arg(&t[0])
        .arg(&fifo)
        .arg("--out")
        .arg(&out)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn");
    let t0 = std::time::Instant::now();
    while child.try_wait().expect("wait").is_none() && t0.elapsed().as_secs() < 5 {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    if child.try_wait().expect("wait").is_none() {
        // Still blocked on the FIFO: stop it as a user or a batch system would
        // (SIGTERM: SIGINT is ignored by processes started in the background).
        unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    }
    let status = child.wait().expect("wait");
    assert!(!status.success());
    assert!(!out.exists());
    assert_eq!(leftovers(d), Vec::<String>::new(), "temporary files left");
    assert!(
        t0.elapsed().as_secs() < 5,
        "merge blocked on a FIFO instead of refusing it"
    );
}

#[test]
fn merge_says_in_words_what_differs() {
    let dir = tmp();
    let d = dir.path();
    let t = tiles(d);
    // Other settings: the setting named, no Rust debug dump.
    let e2 = d.join("e2.npy");
    ok(cli()
        .args([
            "distance",
            "--stride",
            "6",
            "--band-rows",
            "8",
            "--metric",
            "euclidean",
            "--tile",
            "2/2",
            "--out",
        ])
        .arg(&e2));
    let err = refused(
        cli()
            .arg("merge")
            .arg(&t[0])
            .arg(&e2)
            .arg("--out")
            .arg(d.join("m.npy")),
    );
    assert!(err.contains("--metric euclidean vs brdf-it"), "{err}");
    assert!(!err.contains("MatrixSettings"), "{err}");
    // Same fingerprint, other names (a sidecar rewritten with a valid checksum): the
    // message says which name differs instead of printing one fingerprint twice.
    let mut side: MatrixSidecar = read_sidecar(&t[1]).expect("sidecar");
    side.names.swap(0, 1);
    side.checksum = side.content_checksum();
    std::fs::write(
        sidecar_path(&t[1]),
        serde_json::to_string_pretty(&side).expect("json"),
    )
    .expect("write");
    let err = refused(
        cli()
            .arg("merge")
            .args(&t)
            .arg("--out")
            .arg(d.join("m.npy")),
    );
    assert!(err.contains("another collection"), "{err}");
    assert!(err.contains("material 0 is"), "{err}");
    // Another collection: both fingerprints, which differ.
    let other = other_collection(d);
    let f2 = d.join("f2.npy");
    ok(cli()
        .args([
            "distance",
            "--stride",
            "6",
            "--band-rows",
            "8",
            "--tile",
            "2/2",
            "--out",
        ])
        .arg(&f2)
        .arg(&other));
    let err = refused(
        cli()
            .arg("merge")
            .arg(&t[0])
            .arg(&f2)
            .arg("--out")
            .arg(d.join("m.npy")),
    );
    let ours = Collection::embedded_default().fingerprint();
    let theirs = Collection::load(&other).expect("other").fingerprint();
    assert_ne!(ours, theirs);
    assert!(err.contains(&ours) && err.contains(&theirs), "{err}");
}

#[test]
fn a_fit_with_grid_stride_0_is_an_error() {
    let coll = Collection::embedded_default();
    let p = brdf_basis::fit::FitParams {
        stride: 0,
        objective: TargetWeight::L2,
        ..Default::default()
    };
    let e = brdf_basis::fit::fit(
        &brdf_basis::backend::cpu::CpuBackend::new(),
        &coll,
        &[0, 1],
        &[2],
        &p,
        &|_, _| {},
    )
    .expect_err("stride 0");
    assert!(matches!(e, brdf_basis::fit::FitError::ZeroStride), "{e}");
}

#[test]
fn info_names_the_backend_by_its_flag() {
    let out = ok(bin().args(["info", "--backend", "cpu"]));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("requested: --backend cpu"), "{text}");
    assert!(!text.contains("Cpu"), "{text}");
}

#[test]
fn a_stride_that_leaves_no_cell_is_explained_as_such() {
    let dir = tmp();
    let err = refused(
        cli()
            .args(["distance", "--stride", "90", "--out"])
            .arg(dir.path().join("d.npy")),
    );
    assert!(err.contains("--stride 90 leaves too few cells"), "{err}");
    assert!(!err.contains("valid in every material"), "{err}");
}

#[cfg(unix)]
#[test]
fn plot_refuses_a_fifo_as_fit_file_instead_of_blocking() {
    let dir = tmp();
    let fifo = dir.path().join("fits.json");
    let c = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).expect("path");
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo");
    let mut child = cli()
        .args(["plot", "--material", "gloss-red-enamel", "--fit"])
        .arg(&fifo)
        .arg("--out")
        .arg(dir.path().join("p.svg"))
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn");
    let t0 = std::time::Instant::now();
    while child.try_wait().expect("wait").is_none() && t0.elapsed().as_secs() < 5 {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let blocked = child.try_wait().expect("wait").is_none();
    if blocked {
        unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    }
    let out = child.wait_with_output().expect("wait");
    assert!(!blocked, "plot blocked reading a FIFO");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("fits.json") && err.contains("not a regular file"),
        "{err}"
    );
}
