//! RGL-EPFL `.bsdf` files (SPEC 9): the container reader refuses malformed files with the
//! file and field named; the evaluation matches Mitsuba 3's `measured` BSDF (values in
//! `tests/reference/rgl_mitsuba_values.csv`, written by `tests/reference/rgl_mitsuba.py`);
//! the tabulation round-trips through a `.binary` file; and every command runs on a
//! collection mixing RGL and analytic materials.

use crate::common;
use brdf_basis::rgl::{self, RglBsdf};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The four RGL files of `../shared/data/real/rgl_bsdf`.
const FILES: [&str; 4] = [
    "cc_ibiza_sunset_rgb",
    "cg_sunflower_rgb",
    "colodur_napoli_4f_rgb",
    "paper_white_rgb",
];

fn rgl_path(stem: &str, test: &str) -> Option<PathBuf> {
    common::shared_or_skip(&format!("real/rgl_bsdf/{stem}.bsdf"), test)
}

/// One row of the Mitsuba reference: file stem, kind of pair, wi, wo, f (RGB).
struct RefRow {
    file: String,
    kind: String,
    wi: [f64; 3],
    wo: [f64; 3],
    f: [f64; 3],
}

fn reference_rows() -> Vec<RefRow> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/reference/rgl_mitsuba_values.csv");
    let mut rdr = csv::Reader::from_path(&path).expect("reference CSV");
    rdr.records()
        .map(|r| {
            let r = r.expect("row");
            let x = |i: usize| r[i].parse::<f64>().expect("number");
            RefRow {
                file: r[0].to_string(),
                kind: r[1].to_string(),
                wi: [x(2), x(3), x(4)],
                wo: [x(5), x(6), x(7)],
                f: [x(8), x(9), x(10)],
            }
        })
        .collect()
}

/// Relative tolerance against Mitsuba wherever the reference exceeds [`FLOOR`] (SPEC 9).
const REL: f64 = 1e-3;
/// Below it, the difference must stay under `REL * FLOOR`.
const FLOOR: f64 = 1e-4;

#[test]
fn rgl_eval_matches_mitsuba() {
    let rows = reference_rows();
    assert!(rows.len() >= 4 * 300, "{} reference rows", rows.len());
    let mut worst: HashMap<String, (f64, usize, usize)> = HashMap::new();
    let mut bsdfs: HashMap<String, RglBsdf> = HashMap::new();
    for stem in FILES {
        let Some(p) = rgl_path(stem, "rgl_eval_matches_mitsuba") else {
            return;
        };
        bsdfs.insert(stem.to_string(), rgl::read(&p).expect("read"));
    }
    let mut failures = Vec::new();
    for (k, row) in rows.iter().enumerate() {
        let b = &bsdfs[&row.file];
        let f = b.eval(row.wi, row.wo);
        let e = worst.entry(row.file.clone()).or_insert((0.0, 0, 0));
        for c in 0..3 {
            let (a, r) = (f[c], row.f[c]);
            let bad = if r.abs() > FLOOR {
                let rel = (a - r).abs() / r.abs();
                if rel > e.0 {
                    *e = (rel, k, e.2);
                }
                rel > REL
            } else {
                (a - r).abs() > REL * FLOOR
            };
            if r.abs() > FLOOR {
                e.2 += 1;
            }
            if bad {
                failures.push(format!(
                    "row {} ({} {}): channel {c}: {a:e} vs Mitsuba {r:e}",
                    k + 2,
                    row.file,
                    row.kind
                ));
            }
        }
    }
    for stem in FILES {
        let (rel, k, n) = worst[stem];
        println!(
            "{stem}: max relative error vs Mitsuba {rel:.2e} (row {}, {n} values above {FLOOR:e})",
            k + 2
        );
        assert!(
            n >= 600,
            "{stem}: only {n} reference values above the floor"
        );
    }
    assert!(
        failures.is_empty(),
        "{} mismatches:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
