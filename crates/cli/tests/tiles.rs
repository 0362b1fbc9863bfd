//! Tiles: `distance --tile I/N` bands merged by `brdf-basis merge` equal the whole matrix
//! byte for byte; a missing, doubled or foreign tile is refused, naming the files.

use crate::common::*;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::Backend;
use brdf_basis::collection::Collection;
use brdf_basis::distance::tile_rows;
use brdf_basis::distance::{distance_matrix_banded, distance_tile, lobes, DistanceParams};
use std::path::{Path, PathBuf};

fn tile(dir: &Path, name: &str, extra: &[&str], i: usize, n: usize) -> PathBuf {
    let out = dir.join(name);
    let st = bin_cpu()
        .args(["distance", "--stride", "4", "--band-rows", "8"])
        .args(extra)
        .args(["--tile", &format!("{i}/{n}"), "--out"])
        .arg(&out)
        .output()
        .expect("run");
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    out
}

fn merge(tiles: &[&PathBuf], out: &Path) -> std::process::Output {
    bin_cpu()
        .arg("merge")
        .args(tiles)
        .arg("--out")
        .arg(out)
        .output()
        .expect("run")
}

#[test]
fn merged_tiles_equal_the_whole_matrix_byte_for_byte() {
    let dir = tmp();
    let d = dir.path();
    let whole = d.join("whole.npy");
    let st = bin_cpu()
        .args(["distance", "--stride", "4", "--band-rows", "8", "--out"])
        .arg(&whole)
        .status()
        .expect("run");
    assert!(st.success());
    let t: Vec<PathBuf> = (1..=3)
        .map(|i| tile(d, &format!("t{i}.npy"), &[], i, 3))
        .collect();
    let merged = d.join("merged.npy");
    // Any order.
    let out = merge(&[&t[2], &t[0], &t[1]], &merged);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        std::fs::read(&whole).expect("whole"),
        std::fs::read(&merged).expect("merged")
    );
    assert_eq!(
        std::fs::read(d.join("whole.names.json")).expect("a"),
        std::fs::read(d.join("merged.names.json")).expect("b")
    );
}

#[test]
fn banding_does_not_change_any_value() {
    // CPU: every pair's value is independent of the other rows of its call, so any band
    // size gives the single-call matrix exactly, and tiles hold exactly its rows.
    let coll = Collection::embedded_default();
    let p = DistanceParams::default().stride(5).check(&coll).expect("p");
    let cpu = CpuBackend::new();
    let single = distance_matrix_banded(&cpu, &coll, &p, 1024, &|_, _| {}).expect("single");
    let cells = brdf_basis::distance::cell_set(&coll, &p);
    let direct = cpu
        .pairwise_l1(&lobes(&coll, p.lobe()), &cells, &|_, _| {})
        .expect("direct");
    assert_eq!(single.condensed(), direct);
    for band in [4, 12, 20] {
        let banded = distance_matrix_banded(&cpu, &coll, &p, band, &|_, _| {}).expect("banded");
        assert_eq!(banded, single, "band rows {band}");
    }
    let mut backends: Vec<(&str, &dyn Backend)> = vec![("cpu", &cpu)];
    if let Some(g) = gpu("tiles gpu") {
        backends.push(("gpu", g));
    }
    let n = coll.len();
    for (name, b) in backends {
        let whole = distance_matrix_banded(b, &coll, &p, 16, &|_, _| {}).expect("whole");
        for i in 1..=4 {
            let t = distance_tile(b, &coll, &p, 16, i, 4, &|_, _| {}).expect("tile");
            for (r, row) in t.rows.clone().enumerate() {
                let w = n - t.rows.start;
                assert_eq!(t.data.len(), t.rows.len() * w);
                let got = &t.data[r * w..(r + 1) * w];
                assert_eq!(
                    got,
                    &whole.row(row)[t.rows.start..],
                    "{name} tile {i} row {row}"
                );
            }
        }
    }
}

#[test]
fn tiles_cover_every_row_once_and_balance_work() {
    for (n, count) in [
        (58usize, 3usize),
        (1000, 7),
        (100_000, 64),
        (9, 3),
        (9, 9),
        (100, 3),
    ] {
        let mut next = 0;
        let mut work = Vec::new();
        for i in 1..=count {
            let r = tile_rows(n, i, count).expect("tile");
            assert_eq!(r.start, next);
            assert!(r.end > r.start);
            work.push(r.clone().map(|a| n - 1 - a).sum::<usize>());
            next = r.end;
        }
        assert_eq!(next, n);
        let total: usize = work.iter().sum();
        if n >= 4 * count {
            // Within one row's work of an even share.
            let even = total / count;
            assert!(work.iter().all(|&w| w.abs_diff(even) <= n), "{work:?}");
        }
    }
    assert!(tile_rows(58, 0, 3).is_err());
    assert!(tile_rows(58, 4, 3).is_err());
    assert!(tile_rows(58, 1, 59).is_err(), "more tiles than rows");
}

#[test]
fn missing_doubled_and_foreign_tiles_are_refused() {
    let dir = tmp();
    let d = dir.path();
    let t: Vec<PathBuf> = (1..=3)
        .map(|i| tile(d, &format!("t{i}.npy"), &[], i, 3))
        .collect();
    let out = d.join("m.npy");
    let refuse = |tiles: &[&PathBuf], want: &[&str]| {
        let o = merge(tiles, &out);
        assert!(!o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        for w in want {
            assert!(err.contains(w), "`{w}` not in: {err}");
        }
        assert!(!out.exists(), "nothing written on error");
    };
    refuse(&[&t[0], &t[2]], &["2/3 missing"]);
    refuse(&[&t[0], &t[1], &t[1], &t[2]], &["given twice", "t2.npy"]);
    // Another tiling, other settings, another collection.
    let other_count = tile(d, "x2.npy", &[], 2, 4);
    refuse(
        &[&t[0], &other_count, &t[2]],
        &["different tilings", "x2.npy"],
    );
    let euclid = tile(d, "e2.npy", &["--metric", "euclidean"], 2, 3);
    refuse(&[&t[0], &euclid, &t[2]], &["other settings", "e2.npy"]);
    let csv = std::fs::read_to_string(
        crate::common::repo().join("crates/core/data/default_collection.csv"),
    )
    .expect("csv");
    // Same names, one parameter changed.
    let changed = csv.replacen(",79998,", ",79000,", 1);
    assert_ne!(changed, csv);
    let other = d.join("other.csv");
    std::fs::write(&other, changed).expect("write");
    let foreign = d.join("f2.npy");
    let st = bin_cpu()
        .args([
            "distance",
            "--stride",
            "4",
            "--band-rows",
            "8",
            "--tile",
            "2/3",
            "--out",
        ])
        .arg(&foreign)
        .arg(&other)
        .status()
        .expect("run");
    assert!(st.success());
    refuse(&[&t[0], &foreign, &t[2]], &["another collection", "f2.npy"]);
    // A tile whose data no longer matches its sidecar.
    let bytes = std::fs::read(&t[1]).expect("read");
    let mut bad = bytes.clone();
    let last = bad.len() - 1;
    bad[last] ^= 1;
    std::fs::write(&t[1], bad).expect("write");
    refuse(&[&t[0], &t[1], &t[2]], &["t2.npy", "t2.names.json"]);
    std::fs::write(&t[1], bytes).expect("restore");
    let o = merge(&[&t[0], &t[1], &t[2]], &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
