//! Beyond one machine: `--tile I/N` for every N up to the number of materials holds
//! exactly the bytes of the whole matrix (any tiling, any band size, CPU and GPU), and
//! `distance --tile I/3` on the embedded default merges into the whole matrix byte for
//! byte.

use crate::common::*;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::Backend;
use brdf_basis::collection::Collection;
use brdf_basis::distance::tile_rows;
use brdf_basis::distance::{distance_matrix_banded, distance_tile, DistanceParams};
use std::path::Path;

/// Every row of every tile of `count` equals the whole matrix's row from the tile's
/// first row on, bit for bit.
fn check_tiling(name: &str, b: &dyn Backend, coll: &Collection, stride: usize) {
    let p = DistanceParams::default()
        .stride(stride)
        .check(coll)
        .expect("p");
    let n = coll.len();
    // The reference: one call per 1,024 rows (the whole collection in one call here).
    let whole = distance_matrix_banded(b, coll, &p, 1024, &|_, _| {}).expect("whole");
    for band in [4, 8, 1024] {
        for count in [1, 2, 3, 5, 7, n] {
            let mut next = 0;
            for i in 1..=count {
                let t = distance_tile(b, coll, &p, band, i, count, &|_, _| {}).expect("tile");
                assert_eq!(t.rows, tile_rows(n, i, count).expect("rows"));
                assert_eq!(t.rows.start, next, "{name}: tiles in order");
                next = t.rows.end;
                let w = n - t.rows.start;
                assert_eq!(t.data.len(), t.rows.len() * w);
                for (r, row) in t.rows.clone().enumerate() {
                    assert_eq!(
                        &t.data[r * w..(r + 1) * w],
                        &whole.row(row)[t.rows.start..],
                        "{name}: band {band}, tile {i}/{count}, row {row}"
                    );
                }
            }
            assert_eq!(next, n, "{name}: the tiles cover every row");
        }
    }
}

/// A small mixed collection: analytic materials and measured copies of others (the
/// padding of a short chunk copies a lobe of either kind).
fn mixed() -> Collection {
    let def = Collection::embedded_default();
    let mut c = Collection::new();
    for (k, m) in def.materials().iter().enumerate().step_by(7).take(13) {
        let m = if k % 3 == 0 {
            measured_material(m)
        } else {
            m.clone()
        };
        c.push(m, Path::new("mixed"), 0).expect("push");
    }
    c
}

#[test]
fn any_tiling_holds_the_whole_matrix_bytes_on_cpu_and_gpu() {
    let cpu = CpuBackend::new();
    let sub = Collection::embedded_default().subset(&(0..58).step_by(2).collect::<Vec<_>>());
    check_tiling("cpu analytic", &cpu, &sub, 5);
    check_tiling("cpu mixed", &cpu, &mixed(), 6);
    if let Some(g) = gpu("any_tiling_holds_the_whole_matrix_bytes_on_cpu_and_gpu") {
        check_tiling("gpu analytic", g, &sub, 5);
        check_tiling("gpu mixed", g, &mixed(), 6);
    }
}

#[test]
fn more_tiles_than_materials_are_refused_by_name() {
    let dir = tmp();
    let o = bin_cpu()
        .args(["distance", "--stride", "6", "--tile", "1/59", "--out"])
        .arg(dir.path().join("t.npy"))
        .output()
        .expect("run");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("59 tiles") && err.contains("58 materials"),
        "{err}"
    );
}

#[test]
fn three_tiles_of_the_embedded_default_merge_into_the_whole_matrix() {
    let dir = tmp();
    let d = dir.path();
    let run = |args: &[&str], out: &Path| {
        let o = bin_cpu()
            .arg("distance")
            .args(args)
            .arg("--out")
            .arg(out)
            .output()
            .expect("run");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    // The case: the 58 materials, default band rows (one band), three tiles.
    let whole = d.join("whole.npy");
    run(&[], &whole);
    let tiles: Vec<_> = (1..=3)
        .map(|i| {
            let t = d.join(format!("t{i}.npy"));
            run(&["--tile", &format!("{i}/3")], &t);
            t
        })
        .collect();
    let merged = d.join("merged.npy");
    let o = bin_cpu()
        .arg("merge")
        .args([&tiles[2], &tiles[0], &tiles[1]])
        .arg("--out")
        .arg(&merged)
        .output()
        .expect("merge");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        std::fs::read(&whole).expect("whole"),
        std::fs::read(&merged).expect("merged"),
        "merged .npy"
    );
    assert_eq!(
        std::fs::read(d.join("whole.names.json")).expect("whole sidecar"),
        std::fs::read(d.join("merged.names.json")).expect("merged sidecar"),
        "merged sidecar"
    );
}

mod greedy_at_scale {
    use crate::common::*;
    use brdf_basis::backend::cpu::CpuBackend;
    use brdf_basis::backend::weighted::TargetWeight;
    use brdf_basis::collection::Collection;
    use brdf_basis::select::{greedy_exhaustive, greedy_with_counts};
    use brdf_basis::select::{swap, Objective, ObjectiveParams, SearchParams};

    fn objective(coll: &Collection, stride: usize) -> Objective {
        let p = ObjectiveParams::default()
            .objective(TargetWeight::L2)
            .stride(stride)
            .check()
            .expect("params");
        Objective::new(&CpuBackend::new(), coll, &p, &|_, _| {}).expect("objective")
    }

    /// The screened greedy chooses the exhaustive greedy's basis: same materials, same
    /// order, same scores (bit for bit), and it scores fewer candidates.
    fn same_greedy(name: &str, obj: &Objective, k: usize) {
        let p = SearchParams::new(k).check(obj.names()).expect("p");
        let exact = greedy_exhaustive(obj, &p, &|_, _| {}).expect("exhaustive");
        let (fast, evaluated) = greedy_with_counts(obj, &p, &|_, _| {}).expect("screened");
        assert_eq!(fast, exact, "{name}: screened greedy = exhaustive greedy");
        let n = obj.len();
        let swept: usize = (0..fast.indices.len()).map(|s| n - s).sum();
        let scored: usize = evaluated.iter().sum();
        eprintln!("{name}: k {k}, exact scores {scored} of {swept} ({evaluated:?})");
        assert!(scored <= swept);
    }

    #[test]
    fn screened_greedy_equals_the_exhaustive_greedy() {
        let def = Collection::embedded_default();
        same_greedy("embedded default", &objective(&def, 1), 20);
        // Measured copies (the Gram from the back-end, zero-share channels).
        if let Some(ngan) = ngan_or_skip("screened_greedy_equals_the_exhaustive_greedy") {
            same_greedy("ngan", &objective(&ngan, 1), 20);
            same_greedy("ngan stride 3", &objective(&ngan, 3), 12);
            // Targets and candidates restricted.
            let obj = objective(&ngan, 2);
            let p = SearchParams::new(8)
                .candidates((0..ngan.len()).step_by(2).collect())
                .targets((0..ngan.len()).step_by(3).collect())
                .check(obj.names())
                .expect("p");
            let exact = greedy_exhaustive(&obj, &p, &|_, _| {}).expect("exhaustive");
            let (fast, _) = greedy_with_counts(&obj, &p, &|_, _| {}).expect("screened");
            assert_eq!(fast, exact, "restricted targets and candidates");
        }
    }

    /// The exhaustive swap of SPEC 8 as it was before the screening: every (position,
    /// candidate) pair scored, one argmin over them all (ties to the earliest).
    fn swap_exhaustive(obj: &Objective, p: &SearchParams, init: Vec<usize>) -> Vec<usize> {
        let p = p.clone().init(init.clone()).check(obj.names()).expect("p");
        let argmin = |s: &[f64]| {
            let mut best: Option<usize> = None;
            for (i, &v) in s.iter().enumerate() {
                match best {
                    None => best = Some(i),
                    Some(b) if v < s[b] - p.tie_tol * s[b].abs() - 1e-300 => best = Some(i),
                    _ => {}
                }
            }
            best
        };
        let mut basis = init;
        let mut current = obj.score(&basis, &p.targets).expect("score");
        for _ in 0..p.max_swaps {
            let mut flat = Vec::new();
            let mut pairs = Vec::new();
            for pos in 0..basis.len() {
                let mut rest = basis.clone();
                rest.remove(pos);
                let cands: Vec<usize> = p
                    .candidates
                    .iter()
                    .copied()
                    .filter(|c| !basis.contains(c))
                    .collect();
                flat.extend(obj.scores_adding(&rest, &p.targets, &cands).expect("s"));
                pairs.extend(cands.iter().map(|&c| (pos, c)));
            }
            let Some(best) = argmin(&flat) else { break };
            if flat[best] >= current - p.swap_tol * current.abs() || current <= 0.0 {
                break;
            }
            basis[pairs[best].0] = pairs[best].1;
            current = obj.score(&basis, &p.targets).expect("score").min(current);
        }
        basis
    }

    #[test]
    fn screened_swap_equals_the_exhaustive_swap() {
        let def = Collection::embedded_default();
        let obj = objective(&def, 2);
        for (k, init) in [(4, vec![0, 1, 2, 3]), (6, vec![10, 20, 30, 40, 50, 57])] {
            let sp = SearchParams::new(k);
            let want = swap_exhaustive(&obj, &sp, init.clone());
            let p = sp.init(init).check(obj.names()).expect("p");
            let got = swap(&obj, &p, &|_, _| {}).expect("swap");
            assert_eq!(got.indices, want, "k {k}");
        }
    }
}
