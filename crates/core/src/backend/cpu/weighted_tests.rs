//! The weighted systems' tests (`backend::weighted`) that need the CPU back-end: here, so
//! that `weighted` does not import `cpu` (which implements them).

use super::CpuBackend;
use crate::backend::weighted::*;
use crate::backend::Lobe;
use crate::brdf::LobeParams;
use crate::merl::CellSet;
use crate::merl::{Mask, Weighting};

/// Audit 3, D1: eps is checked against its range where the weight is built; inside it
/// the weights of every reflectance from 0 to 1e100 are normal f64 numbers.
#[test]
fn eps_is_refused_outside_its_range_and_weights_stay_normal_inside() {
    for bad in [
        0.0,
        -1.0,
        f64::NAN,
        f64::INFINITY,
        1.4e154,
        1e101,
        9.9e-101,
        1e-300,
    ] {
        let e = TargetWeight::relative(bad)
            .expect_err("refused")
            .to_string();
        assert!(e.contains("eps must"), "{bad}: {e}");
    }
    for eps in [
        TargetWeight::MIN_EPS,
        1e-40,
        0.01,
        1e30,
        TargetWeight::MAX_EPS,
    ] {
        let w = TargetWeight::relative(eps).expect("valid");
        for y in [0.0, 1e-20, 1.0, 1e30, 3.4e38, 1e100] {
            let phi = w.phi(y, 0.5);
            assert!(
                phi.is_normal() && (1e-201..=1.001e200).contains(&phi),
                "eps {eps}, f {y}: {phi:e}"
            );
        }
    }
}

/// The matrix-product reference gives the scalar loop's systems within 1e-12 relative
/// (every term is non-negative here: the sums bound the rounding), for every objective,
/// a target count that is not a multiple of the tiles, a column count whose products
/// are not a multiple of the tile's columns, and more cells than one chunk.
#[test]
fn matrix_product_reference_is_the_scalar_loop_within_rounding() {
    // Ashikhmin-Shirley lobes from dull to sharp, with and without a diffuse term.
    let lobes: Vec<Lobe> = (0..12)
        .map(|i| {
            Lobe::Analytic(LobeParams {
                kd: 0.05 * (i % 3) as f32,
                ks: 0.1 + 0.07 * i as f32,
                f0: 0.04 + 0.03 * (i % 4) as f32,
                n: 2.0 * 1.9f32.powi(i),
            })
        })
        .collect();
    let (basis, targets) = (&lobes[..5], &lobes[5..12]);
    let cpu = CpuBackend::new();
    let cells = CellSet::new(Mask::Evaluation, Weighting::SolidAngle, 2);
    assert!(cells.cells.len() > REFERENCE_CHUNK);
    for weight in [
        TargetWeight::L2,
        TargetWeight::Relative { eps: 0.01 },
        TargetWeight::Log,
    ] {
        let fast = reference(&cpu, basis, targets, &cells, weight, &|_, _| {}).unwrap();
        let slow = reference_scalar(&cpu, basis, targets, &cells, weight, &|_, _| {}).unwrap();
        assert_eq!(fast.len(), targets.len());
        assert_eq!(fast.values.len(), slow.values.len());
        let mut worst = 0f64;
        for (q, (a, b)) in fast.values.iter().zip(&slow.values).enumerate() {
            assert!(*b > 0.0, "{weight:?}: value {q} is {b}");
            worst = worst.max((a - b).abs() / b);
        }
        assert!(worst < 1e-12, "{weight:?}: {worst:e}");
        // Not the same bits: the fused chain rounds differently (else this test would
        // not be measuring the new form).
        assert_ne!(fast, slow, "{weight:?}");
    }
}

/// The weighted systems of three channels in one pass are each channel's reference,
/// bit for bit, with networks among the lobes (their three channels from one run).
#[test]
fn one_pass_per_channel_is_each_channels_reference_to_the_bit() {
    let nets: Vec<std::sync::Arc<crate::brdf::Nbrdf>> = (0..4)
        .map(|seed| std::sync::Arc::new(crate::brdf::seeded_for_tests(seed)))
        .collect();
    let lobes = |c: usize| -> Vec<Lobe> {
        let mut v: Vec<Lobe> = nets
            .iter()
            .map(|n| Lobe::Neural {
                net: n.clone(),
                channel: Some(c),
            })
            .collect();
        v.push(Lobe::Analytic(LobeParams {
            kd: 0.1 * (c + 1) as f32,
            ks: 0.3,
            f0: 0.05,
            n: 60.0,
        }));
        v
    };
    let all: [Vec<Lobe>; 3] = std::array::from_fn(lobes);
    let (b, t): (Vec<_>, Vec<_>) = all.iter().map(|l| l.split_at(2)).unzip();
    let cpu = CpuBackend::new();
    let cells = CellSet::new(Mask::Evaluation, Weighting::SolidAngle, 3);
    assert!(cells.cells.len() > REFERENCE_CHUNK);
    for weight in [
        TargetWeight::L2,
        TargetWeight::Relative { eps: 0.01 },
        TargetWeight::Log,
    ] {
        let three = reference_per_channel(
            &cpu,
            [b[0], b[1], b[2]],
            [t[0], t[1], t[2]],
            &cells,
            weight,
            &|_, _| {},
        )
        .unwrap();
        for c in 0..3 {
            let own = reference(&cpu, b[c], t[c], &cells, weight, &|_, _| {}).unwrap();
            assert_eq!(three[c], own, "{weight:?}, channel {c}");
        }
    }
}
