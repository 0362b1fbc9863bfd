//! Collections: CSV loading and every rejected input (SPEC 1).

use crate::common::*;
use brdf_basis::collection::{parse_csv, Collection};
use brdf_basis::error::CollectionError;
use std::path::Path;

const HEAD: &str = "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n";

fn parse(body: &str) -> Result<Collection, CollectionError> {
    parse_csv(body.as_bytes(), Path::new("t.csv"))
}

fn err(body: &str) -> String {
    parse(body).expect_err("should be rejected").to_string()
}

#[test]
fn loads_the_ngan_table() {
    let Some(c) = ngan_or_skip("loads_the_ngan_table") else {
        return;
    };
    assert_eq!(c.len(), 100);
    let g = c
        .get("gold-metallic-paint")
        .expect("gold")
        .analytic()
        .copied()
        .expect("analytic");
    assert!(g.n > 0.0 && (0.0..=1.0).contains(&g.f0));
    assert!(c
        .materials()
        .iter()
        .filter_map(|m| m.analytic())
        .any(|a| a.n > 78_000.0));
}

#[test]
fn embedded_default_is_valid_and_diverse() {
    let c = Collection::embedded_default();
    assert!(c.len() >= 40, "{} materials", c.len());
    let ns: Vec<f64> = c
        .materials()
        .iter()
        .filter_map(|m| m.analytic().map(|a| a.n))
        .collect();
    let (lo, hi) = ns
        .iter()
        .fold((f64::MAX, 0f64), |(l, h), &n| (l.min(n), h.max(n)));
    assert!(lo <= 3.0 && hi >= 50_000.0, "exponents span {lo}..{hi}");
    // Authored by the project: no name of the Ngan table.
    let Some(ngan) = ngan_or_skip("embedded_default_is_valid_and_diverse") else {
        return;
    };
    assert!(c.names().iter().all(|n| ngan.index_of(n).is_err()));
}

#[test]
fn columns_in_any_order_and_extra_columns_ignored() {
    let c = parse("n,F0,extra,material,s_b,s_g,s_r,d_b,d_g,d_r\n10,0.5,x,a,1,2,3,0.1,0.2,0.3\n")
        .expect("valid");
    let a = c
        .get("a")
        .expect("a")
        .analytic()
        .copied()
        .expect("analytic");
    assert_eq!(a.d, [0.3, 0.2, 0.1]);
    assert_eq!(a.s, [3.0, 2.0, 1.0]);
    assert_eq!((a.f0, a.n), (0.5, 10.0));
}

#[test]
fn missing_column() {
    let e = err("material,d_r,d_g,d_b,s_r,s_g,s_b,n\na,0,0,0,0,0,0,1\n");
    assert!(
        e.contains("t.csv") && e.contains("missing required column `F0`"),
        "{e}"
    );
}

#[test]
fn non_numeric_value() {
    let e = err(&format!("{HEAD}a,0.1,abc,0,0,0,0,0.5,10\n"));
    assert!(
        e.contains("line 2")
            && e.contains("`d_g`")
            && e.contains("`a`")
            && e.contains("not a number"),
        "{e}"
    );
}

#[test]
fn non_finite_value() {
    for bad in ["nan", "inf", "-inf", "NaN"] {
        let e = err(&format!(
            "{HEAD}a,0.1,0.1,0,0,0,0,0.5,10\nb,0,0,0,{bad},0,0,0.5,10\n"
        ));
        assert!(
            e.contains("line 3")
                && e.contains("`s_r`")
                && e.contains("`b`")
                && e.contains("finite"),
            "{e}"
        );
    }
}

#[test]
fn negative_diffuse_or_specular() {
    let e = err(&format!("{HEAD}a,-0.1,0,0,0,0,0,0.5,10\n"));
    assert!(e.contains("`d_r`") && e.contains(">= 0"), "{e}");
    let e = err(&format!("{HEAD}a,0,0,0,0,0,-1e-9,0.5,10\n"));
    assert!(e.contains("`s_b`") && e.contains(">= 0"), "{e}");
}

#[test]
fn f0_outside_unit_interval() {
    for bad in ["-0.01", "1.01"] {
        let e = err(&format!("{HEAD}a,0,0,0,0,0,0,{bad},10\n"));
        assert!(e.contains("`F0`") && e.contains("[0, 1]"), "{e}");
    }
    assert!(parse(&format!("{HEAD}a,0,0,0,0,0,0,0,10\nb,0,0,0,0,0,0,1,10\n")).is_ok());
}

#[test]
fn n_not_positive() {
    for bad in ["0", "-3"] {
        let e = err(&format!("{HEAD}a,0,0,0,0,0,0,0.5,{bad}\n"));
        assert!(e.contains("`n`") && e.contains("> 0"), "{e}");
    }
}

#[test]
fn duplicate_names() {
    let e = err(&format!(
        "{HEAD}a,0,0,0,0,0,0,0.5,1\nb,0,0,0,0,0,0,0.5,1\na,0,0,0,0,0,0,0.5,2\n"
    ));
    assert!(
        e.contains("line 4") && e.contains("duplicate material name `a`") && e.contains("t.csv:2"),
        "{e}"
    );
}

#[test]
fn empty_file() {
    assert!(matches!(parse(""), Err(CollectionError::Empty { .. })));
    assert!(matches!(parse(HEAD), Err(CollectionError::Empty { .. })));
}

#[test]
fn wrong_number_of_fields() {
    let e = err(&format!("{HEAD}a,0,0,0,0,0,0,0.5\n"));
    assert!(e.contains("line 2") && e.contains("malformed"), "{e}");
}

#[test]
fn unknown_material_suggests_close_names() {
    let Some(c) = ngan_or_skip("unknown_material_suggests_close_names") else {
        return;
    };
    let e = c
        .index_of("gold-metalic-paint")
        .expect_err("typo")
        .to_string();
    assert!(
        e.contains("did you mean") && e.contains("gold-metallic-paint"),
        "{e}"
    );
}

#[test]
fn load_reports_missing_file_and_unknown_kind() {
    let e = Collection::load(Path::new("/nonexistent/x.csv"))
        .expect_err("missing")
        .to_string();
    assert!(e.contains("/nonexistent/x.csv"), "{e}");
    let d = tmp();
    let p = d.path().join("x.txt");
    std::fs::write(&p, "hello").expect("write");
    let e = Collection::load(&p).expect_err("kind").to_string();
    assert!(e.contains("x.txt") && e.contains("not a collection"), "{e}");
}

#[test]
fn several_collections_reject_duplicates_across_files() {
    let d = tmp();
    let a = d.path().join("a.csv");
    let b = d.path().join("b.csv");
    std::fs::write(&a, format!("{HEAD}x,0,0,0,0,0,0,0.5,1\n")).expect("write");
    std::fs::write(
        &b,
        format!("{HEAD}y,0,0,0,0,0,0,0.5,1\nx,0,0,0,0,0,0,0.5,1\n"),
    )
    .expect("write");
    let e = Collection::load_many(&[a.clone(), b.clone()])
        .expect_err("dup")
        .to_string();
    assert!(
        e.contains("b.csv") && e.contains("`x`") && e.contains("a.csv"),
        "{e}"
    );
    let c = Collection::load_many(&[a]).expect("one");
    assert_eq!(c.names(), vec!["x".to_string()]);
}
