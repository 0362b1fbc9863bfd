//! Unit tests of the figures: box-plot whiskers at the data, tick labels without float
//! noise, Fig. 4a/4b named and in one order.

use super::charts::{box_stats, errors_per_material, material_order};
use brdf_basis::experiment::evaluation::BasisErrors;

/// Whiskers were plotters' Tukey fences: values no run had (0.69 and 4.19 here, when every
/// run lies in [1, 3.4]), and an axis fitted to the data clipped them.
#[test]
fn box_whiskers_are_data_values() {
    let runs = [1.0, 2.0, 2.0, 2.5, 3.0, 3.4];
    let q = box_stats(&runs).expect("stats");
    assert_eq!((q.q1, q.median, q.q3), (2.0, 2.25, 2.875));
    assert_eq!((q.low, q.high), (1.0, 3.4));
    assert!(q.outliers.is_empty());
    let fences = plotters::data::Quartiles::new(&runs).values();
    assert!(
        f64::from(fences[0]) < 1.0 && f64::from(fences[4]) > 3.4,
        "{fences:?}"
    );
    // Outliers beyond 1.5 IQR are points; the whisker stops at the last run inside.
    let q = box_stats(&[1.0, 2.0, 3.0, 4.0, 100.0, f64::NAN]).expect("stats");
    assert_eq!((q.low, q.high, q.outliers.clone()), (1.0, 4.0, vec![100.0]));
    // One run: everything is that run.
    let q = box_stats(&[0.7]).expect("stats");
    assert_eq!((q.q1, q.q3, q.low, q.high), (0.7, 0.7, 0.7, 0.7));
    assert!(box_stats(&[f64::INFINITY]).is_none());
}

/// The text of every `<text>` element of an SVG.
fn texts(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .filter_map(|t| {
            let body = &t[t.find('>')? + 1..];
            Some(body[..body.find("</text>")?].trim().to_string())
        })
        .collect()
}

fn errors(basis: &str, mae: &[f64], img: &[f64]) -> BasisErrors {
    BasisErrors {
        basis: basis.into(),
        size: 3,
        mae: mae.to_vec(),
        image_error: img.to_vec(),
        mean_mae: 0.0,
        median_mae: 0.0,
        mean_image_error: 0.0,
        median_image_error: 0.0,
    }
}

/// Fig. 4a and 4b name the materials on the x axis, in the same order (by the first
/// basis's MAE, whatever the image errors), and their log ticks read `1e-4`, not
/// `9.999999999999999e-5`.
#[test]
fn fig4_names_materials_in_one_order_with_clean_ticks() {
    if !super::with_text() {
        eprintln!("SKIP (no font) fig4_names_materials_in_one_order_with_clean_ticks");
        return;
    }
    let targets: Vec<String> = ["alpha-paint", "beta-metal", "gamma-wood", "delta-stone"]
        .map(String::from)
        .to_vec();
    let e = vec![
        errors("one", &[3e-3, 1e-5, 0.2, 4e-4], &[0.01, 0.3, 0.02, 0.5]),
        errors("two", &[2e-3, 2e-5, 0.1, 5e-4], &[0.02, 0.2, 0.01, 0.4]),
    ];
    assert_eq!(material_order(&e), vec![1, 3, 0, 2]);
    let order_in = |svg: &str| -> Vec<usize> {
        let mut at: Vec<(usize, usize)> = targets
            .iter()
            .enumerate()
            .map(|(i, t)| {
                (
                    svg.find(&format!("\n{t}\n"))
                        .unwrap_or_else(|| panic!("{t} not named")),
                    i,
                )
            })
            .collect();
        at.sort();
        at.into_iter().map(|p| p.1).collect()
    };
    let a = errors_per_material(&targets, &e, true).expect("4a");
    let b = errors_per_material(&targets, &e, false).expect("4b");
    assert_eq!(order_in(&a.svg), vec![1, 3, 0, 2]);
    assert_eq!(order_in(&b.svg), vec![1, 3, 0, 2]);
    for svg in [&a.svg, &b.svg] {
        for t in texts(svg) {
            assert!(
                !t.contains("9999") && !t.contains("0000"),
                "float noise in `{t}`"
            );
        }
    }
    // plotters writes a text element's content on a line of its own.
    assert!(
        a.svg.contains("\n1e-4\n") || a.svg.contains("\n0.001\n"),
        "no decade tick"
    );
}
