//! Distance matrices: GPU and CPU against an f64 reference on the full Ngan table.

use crate::common::*;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::Backend;
use brdf_basis::collection::Collection;
use brdf_basis::distance::*;
use brdf_basis::error::DistanceError;
use brdf_basis::merl::{Mask, Weighting};

fn check_backend_against_reference(coll: &Collection, backends: &[&dyn Backend]) {
    for mask in [Mask::Evaluation, Mask::Valid] {
        for weighting in [Weighting::Uniform, Weighting::SolidAngle] {
            let p = DistanceParams::default()
                .mask(mask)
                .weighting(weighting)
                .check(coll)
                .expect("params");
            let cells = cell_set(coll, &p);
            let reference = reference_pairwise_f64(&lobes(coll, p.lobe()), &cells);
            for b in backends {
                let d = distance_matrix(*b, coll, &p, &|_, _| {}).expect("distance");
                let r = max_rel(&d.condensed(), &reference, 1e-300);
                eprintln!("{} {mask} {weighting}: max relative error {r:e}", b.name());
                assert!(r <= 1e-4, "{} {mask} {weighting}: {r:e} > 1e-4", b.name());
            }
        }
    }
}

#[test]
fn full_ngan_table_gpu_and_cpu_match_f64_reference() {
    const TEST: &str = "full_ngan_table_gpu_and_cpu_match_f64_reference";
    let Some(coll) = ngan_or_skip(TEST) else {
        return;
    };
    let cpu = CpuBackend::new();
    match gpu(TEST) {
        Some(g) => check_backend_against_reference(&coll, &[g, &cpu]),
        None => check_backend_against_reference(&coll, &[&cpu]),
    }
}

#[test]
fn hand_computed_tiny_case() {
    // Two materials differing only in the Lambertian term of the full lobe: the distance
    // is |kd_a - kd_b| / pi whatever the mask and weights.
    let csv = "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\na,0.3,0.3,0.3,0.5,0.5,0.5,0.1,20\nb,0.6,0.6,0.6,0.5,0.5,0.5,0.1,20\n";
    let coll = brdf_basis::collection::parse_csv(csv.as_bytes(), std::path::Path::new("t.csv"))
        .expect("csv");
    let p = DistanceParams::default()
        .lobe(LobeKind::Full)
        .weighting(Weighting::SolidAngle)
        .stride(5)
        .check(&coll)
        .expect("p");
    let d = distance_matrix(&CpuBackend::new(), &coll, &p, &|_, _| {}).expect("d");
    let want = 0.3 / std::f64::consts::PI;
    assert!(
        (d.dist(0, 1) - want).abs() < 1e-6 * want,
        "{} vs {want}",
        d.dist(0, 1)
    );
    assert_eq!(d.dist(0, 0), 0.0);
    assert_eq!(d.dist(1, 0), d.dist(0, 1));
}

#[test]
fn euclidean_is_on_f0_and_n() {
    let Some(ngan) = ngan_or_skip("euclidean_is_on_f0_and_n") else {
        return;
    };
    let coll = ngan.subset(&[0, 1, 2]);
    let p = DistanceParams::default()
        .metric(Metric::Euclidean)
        .check(&coll)
        .expect("p");
    let d = distance_matrix(&CpuBackend::new(), &coll, &p, &|_, _| {}).expect("d");
    let a = coll.materials()[0].analytic().copied().expect("a");
    let b = coll.materials()[2].analytic().copied().expect("b");
    assert_eq!(d.dist(0, 2), (a.f0 - b.f0).hypot(a.n - b.n));
}

#[test]
fn rejects_bad_options_and_inputs() {
    assert!(matches!(
        "cosine".parse::<Metric>(),
        Err(DistanceError::UnknownOption { what: "metric", .. })
    ));
    assert!(matches!(
        "area".parse::<Weighting>(),
        Err(DistanceError::UnknownOption {
            what: "weighting",
            ..
        })
    ));
    assert!(matches!(
        "all".parse::<Mask>(),
        Err(DistanceError::UnknownOption { what: "mask", .. })
    ));
    assert!(matches!(
        "diffuse".parse::<LobeKind>(),
        Err(DistanceError::UnknownOption { what: "lobe", .. })
    ));
    let Some(ngan) = ngan_or_skip("rejects_bad_options_and_inputs") else {
        return;
    };
    let one = ngan.subset(&[3]);
    assert!(matches!(
        DistanceParams::default().check(&one),
        Err(DistanceError::TooFew(1))
    ));
    assert!(DistanceParams::default().stride(0).check(&ngan).is_err());
}

#[test]
fn matrix_files_round_trip() {
    let Some(ngan) = ngan_or_skip("matrix_files_round_trip") else {
        return;
    };
    let coll = ngan.subset(&[0, 5, 9, 77]);
    let p = DistanceParams::default().stride(6).check(&coll).expect("p");
    let d = distance_matrix(&CpuBackend::new(), &coll, &p, &|_, _| {}).expect("d");
    let dir = tmp();
    let npy = dir.path().join("d.npy");
    brdf_basis::io::saved::write_npy(&npy, &d).expect("npy");
    let read = brdf_basis::io::npy::read_npy_2d(&npy).expect("read npy");
    assert_eq!((read.rows, read.cols), (4, 4));
    assert_eq!(read.data, d.as_full());
    let csv = dir.path().join("d.csv");
    brdf_basis::io::saved::write_csv(&csv, &d).expect("csv");
    let text = std::fs::read_to_string(&csv).expect("read");
    let mut lines = text.lines();
    assert_eq!(
        lines.next().expect("header"),
        format!("material,{}", d.names().join(","))
    );
    for (i, line) in lines.enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f[0], d.names()[i]);
        let row: Vec<f64> = f[1..].iter().map(|x| x.parse().expect("num")).collect();
        assert_eq!(row, d.row(i));
    }
}
