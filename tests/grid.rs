//! The MERL grid: lookups, counts, weights (SPEC 2-3).

use brdf_basis::brdf::AshikhminShirley;
use brdf_basis::merl::*;
use brdf_basis::merl::{CellSet, GridTables, Mask, Weighting};
use std::f64::consts::PI;

#[test]
fn every_sample_point_looks_up_its_own_cell() {
    for idx in 0..N_CELLS {
        let (wi, wo) = cell_directions(idx);
        // Cells whose directions are below the horizon still have well-defined angles.
        let (th, td, pd) = cell_angles(idx);
        assert_eq!(lookup_angles(th, td, pd), idx, "angles of cell {idx}");
        if cell_info(idx).valid {
            assert_eq!(lookup(wi, wo), idx, "directions of cell {idx}");
        }
    }
}

#[test]
fn directions_have_the_half_and_difference_angles() {
    for &idx in &[0usize, 12345, 700_000, N_CELLS - 1] {
        let (th, td, _) = cell_angles(idx);
        let (wi, wo) = cell_directions(idx);
        let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
        let l = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
        assert!((h[2] / l - th.cos()).abs() < 1e-12, "N.H = cos theta_h");
        let wh = (wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]) / l;
        assert!((wh - td.cos()).abs() < 1e-12, "wo.H = cos theta_d");
    }
}

#[test]
fn valid_and_evaluation_counts_match_spec() {
    let (mut valid, mut eval, mut eval_row1) = (0, 0, 0);
    for idx in 0..N_CELLS {
        let c = cell_info(idx);
        valid += usize::from(c.valid);
        eval += usize::from(c.evaluation);
        if unflat(idx).1 == 1 {
            // Row j = 1 sits exactly on the 3 deg boundary (2 theta_d = 3 deg): the
            // tolerance includes it, so only the 80 deg tests can exclude its cells.
            let (wi, wo) = cell_directions(idx);
            let cos_io = wi[0] * wo[0] + wi[1] * wo[1] + wi[2] * wo[2];
            assert!((cos_io.clamp(-1.0, 1.0).acos() - 3f64.to_radians()).abs() < 1e-9);
            let lim = 80f64.to_radians() + ANGLE_TOL;
            let inside = c.valid && wi[2].acos() <= lim && wo[2].acos() <= lim;
            assert_eq!(c.evaluation, inside, "cell {idx}");
            eval_row1 += 1;
        }
        if !c.valid {
            assert!(!c.evaluation);
        }
    }
    assert_eq!(valid, 1_096_216);
    assert_eq!(eval, 894_396);
    assert_eq!(eval_row1, 16_200, "theta_d row 1 has 90 x 180 cells");
    assert_eq!(
        CellSet::new(Mask::Evaluation, Weighting::Uniform, 1).len(),
        894_396
    );
    assert_eq!(
        CellSet::new(Mask::Valid, Weighting::SolidAngle, 1).len(),
        1_096_216
    );
}

#[test]
fn solid_angle_weights_integrate_closed_forms() {
    // Over the whole grid: int 4 sin th cos td sin td = 4 (1 - cos(pi/2)) (1/2) pi = 2 pi.
    let total: f64 = (0..N_CELLS)
        .map(|i| {
            let (a, b, c) = unflat(i);
            bin_measure(a, b, c)
        })
        .sum();
    assert!((total - 2.0 * PI).abs() < 1e-10, "{total}");
    // Over theta_h < (10/90)^2 pi/2 and theta_d < 30 deg: 4 (1 - cos a)(sin^2 30 deg / 2) pi.
    let a = (10.0f64 / 90.0).powi(2) * PI / 2.0;
    let want = 4.0 * (1.0 - a.cos()) * (0.25 / 2.0) * PI;
    let got: f64 = (0..10)
        .flat_map(|i| (0..30).flat_map(move |j| (0..180).map(move |k| bin_measure(i, j, k))))
        .sum();
    assert!((got - want).abs() < 1e-12, "{got} vs {want}");
    // Normalised weights sum to 1.
    let cs = CellSet::new(Mask::Evaluation, Weighting::SolidAngle, 1);
    assert!((cs.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12);
}

#[test]
fn subsampled_grid_takes_every_sth_cell() {
    let cs = CellSet::new(Mask::Valid, Weighting::Uniform, 3);
    assert!(cs.cells.iter().all(|&c| {
        let (i, j, k) = unflat(c as usize);
        i % 3 == 0 && j % 3 == 0 && k % 3 == 0
    }));
    let full = (0..N_CELLS).filter(|&i| {
        let (a, b, c) = unflat(i);
        a % 3 == 0 && b % 3 == 0 && c % 3 == 0 && cell_info(i).valid
    });
    assert_eq!(cs.len(), full.count());
}

#[test]
fn factored_tables_equal_the_model_from_directions() {
    let t = GridTables::new();
    let m = AshikhminShirley {
        d: [0.0; 3],
        s: [1.0; 3],
        f0: 0.3,
        n: 5000.0,
    };
    for idx in (0..N_CELLS).step_by(97) {
        if !cell_info(idx).valid {
            continue;
        }
        let (wi, wo) = cell_directions(idx);
        let want = m.rho_s(wi, wo);
        let (i, j, k) = unflat(idx);
        let got = t.rho_s(i, j, k, m.f0, m.n);
        assert!(
            (got - want).abs() <= 1e-9 * want.max(1e-300),
            "cell {idx}: {got} vs {want}"
        );
    }
}

/// The grid has one home (issue 47): `merl::GridSpec`, checked when it is built, which
/// the requests, the command line and Python hold. A stride outside 1..=90 cannot make
/// one, and the refusal names `--stride` in the command line's words; the core's
/// parameter types (objective, distances, reproduce) refuse it by the same rule and
/// wording (before: "an integer in 1..=90", "an integer >= 1" with no upper bound, and
/// "at least 1").
#[test]
fn the_grid_is_checked_when_built_by_one_rule() {
    use brdf_basis::distance::DistanceParams;
    use brdf_basis::experiment::ExperimentParams;
    use brdf_basis::merl::{GridSpec, Mask, Weighting};
    use brdf_basis::select::ObjectiveParams;
    let coll = brdf_basis::Collection::embedded_default();
    for stride in [0, 91, 360] {
        let want = format!("--stride {stride}: {}", GridSpec::STRIDE_RULE);
        let e = GridSpec::new(Mask::Valid, Weighting::SolidAngle, stride).expect_err("built");
        assert_eq!(e.to_string(), want);
        let e = GridSpec::default().with_stride(stride).expect_err("built");
        assert_eq!(e.to_string(), want);
        assert!(!GridSpec::stride_ok(stride));
        let e = ObjectiveParams::default()
            .stride(stride)
            .check()
            .expect_err("objective")
            .to_string();
        assert!(e.contains(GridSpec::STRIDE_RULE), "{e}");
        let e = DistanceParams::default()
            .stride(stride)
            .check(&coll)
            .expect_err("distance")
            .to_string();
        assert!(e.contains(GridSpec::STRIDE_RULE), "{e}");
        let e = ExperimentParams {
            stride,
            ..ExperimentParams::default()
        }
        .check_count(coll.len())
        .expect_err("reproduce")
        .to_string();
        assert!(e.contains(GridSpec::STRIDE_RULE), "{e}");
    }
    for stride in [1, 8, 90] {
        let g = GridSpec::new(Mask::Valid, Weighting::SolidAngle, stride).expect("in range");
        assert_eq!(
            (g.mask(), g.weighting(), g.stride()),
            (Mask::Valid, Weighting::SolidAngle, stride)
        );
        assert!(ObjectiveParams::default().grid(g).check().is_ok());
        assert!(DistanceParams::default().grid(g).check(&coll).is_ok());
    }
    let d = GridSpec::default();
    assert_eq!(
        (d.mask(), d.weighting(), d.stride()),
        (Mask::Evaluation, Weighting::Uniform, 1)
    );
    // The requests' default grid is the core's.
    assert_eq!(brdf_basis::run::DistanceRequest::default().grid, d);
    assert_eq!(
        brdf_basis::run::SelectRequest::new(brdf_basis::run::SelectMethod::Greedy).grid,
        d
    );
}
