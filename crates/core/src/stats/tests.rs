#[test]
fn num_has_four_significant_digits() {
    assert_eq!(super::num(24.0753), "24.08");
    assert_eq!(super::num(6.6871), "6.687");
    assert_eq!(super::num(0.012346), "0.01235");
    assert_eq!(super::num(1234.56), "1235");
    assert_eq!(super::num(2.5e-5), "2.500e-5");
    assert_eq!(super::num(-3.0e6), "-3.000e6");
    assert_eq!(super::num(0.0), "0");
    assert_eq!(super::num(f64::NAN), "n/a");
    assert_eq!(super::num(f64::INFINITY), "inf");
    assert_eq!(super::p_value(0.0123), "0.012");
    assert_eq!(super::p_value(1.5e-9), "1.50e-9");
}

#[test]
fn mean_and_median_share_one_nan_convention() {
    assert!(super::mean(&[]).is_nan() && super::median(&[]).is_nan());
    assert_eq!(super::mean(&[1.0, 2.0, 6.0]), 3.0);
    assert_eq!(super::median(&[3.0, 1.0, 2.0]), 2.0);
    assert_eq!(super::median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
}

use super::special::*;
use super::*;

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-300)
}

// Reference values of the special functions: scipy 1.17 (`scipy.special`, `scipy.stats`).
#[test]
fn special_functions_match_references() {
    assert!(close(ln_gamma(0.5), 0.5723649429247001, 1e-14));
    assert!(close(ln_gamma(10.3), 13.482036786138359, 1e-14));
    assert!(close(ln_gamma(150.5), 602.5139548705853, 1e-14));
    assert!(close(erfc(0.5), 0.4795001221869535, 1e-13));
    assert!(close(erfc(3.0), 2.2090496998585445e-05, 1e-12));
    assert!(close(erfc(-1.2), 1.9103139782296354, 1e-14));
    assert_eq!(erfc(0.0), 1.0);
    assert!(close(normal_sf(1.96), 0.024997895148220435, 1e-12));
    assert!(close(normal_sf(-1.2), 0.8849303297782918, 1e-13));
    assert!(close(normal_sf(5.0), 2.866515718791933e-07, 1e-11));
    assert!(close(normal_sf(8.0), 6.22096057427174e-16, 1e-10));
    assert!(close(chi2_sf(3.84, 1.0), 0.05004352124870519, 1e-12));
    assert!(close(chi2_sf(10.0, 5.0), 0.07523524614651217, 1e-12));
    assert!(close(chi2_sf(100.0, 80.0), 0.064570368921133, 1e-11));
    assert!(close(chi2_sf(0.01, 3.0), 0.9997348349413444, 1e-13));
    assert!(close(chi2_sf(1e-3, 1.0), 0.9747728793699604, 1e-13));
    assert!(close(chi2_sf(200.0, 150.0), 0.003973185970821635, 1e-11));
    assert!(close(f_sf(18.5, 2.0, 12.0), 0.00021573022484384756, 1e-11));
    assert!(close(f_sf(2.5, 4.0, 36.0), 0.05958742948661672, 1e-11));
    // Closed form for d1 = 2: (1 + 2 x / d2)^(-d2 / 2).
    assert!(close(f_sf(9.0, 2.0, 4.0), 1.0 / 30.25, 1e-13));
}

/// Upper 5% and 10% points of the studentized range with infinite degrees of freedom
/// divided by sqrt(2), k = 2..10: Demšar 2006, Table 5 (a) and (b), given to three
/// decimals (some truncated rather than rounded: 3.3145 / sqrt(2) = 2.3437 is 2.343).
const DEMSAR_Q05: [f64; 9] = [
    1.960, 2.343, 2.569, 2.728, 2.850, 2.949, 3.031, 3.102, 3.164,
];
const DEMSAR_Q10: [f64; 9] = [
    1.645, 2.052, 2.291, 2.459, 2.589, 2.693, 2.780, 2.855, 2.920,
];
/// Upper 5% points of the studentized range, infinite degrees of freedom, k = 11..20
/// (Harter 1960, doi:10.1080/01621459.1960.10483369; as in common q tables).
const HARTER_Q05: [f64; 10] = [
    4.552, 4.622, 4.685, 4.743, 4.796, 4.845, 4.891, 4.934, 4.974, 5.012,
];

#[test]
fn studentized_range_matches_tables() {
    for (i, (q05, q10)) in DEMSAR_Q05.iter().zip(&DEMSAR_Q10).enumerate() {
        let k = i + 2;
        let q = studentized_range_quantile(0.95, k) / std::f64::consts::SQRT_2;
        assert!((q - q05).abs() < 1e-3, "k {k}: {q} vs {q05}");
        let q = studentized_range_quantile(0.90, k) / std::f64::consts::SQRT_2;
        assert!((q - q10).abs() < 1e-3, "k {k}: {q} vs {q10}");
    }
    for (i, q05) in HARTER_Q05.iter().enumerate() {
        let q = studentized_range_quantile(0.95, i + 11);
        assert!((q - q05).abs() < 6e-4, "k {}: {q} vs {q05}", i + 11);
    }
    // scipy 1.17 `studentized_range.ppf(0.95, k, 1e6)` (df = 1e6 ~ infinity).
    assert!((studentized_range_quantile(0.95, 5) - 3.857655510378623).abs() < 1e-5);
    assert!((studentized_range_quantile(0.95, 20) - 5.0116887941184425).abs() < 1e-5);
    // k = 2: the range of two normals is |N(0, 2)|, so q = 1.959964 sqrt(2).
    let q = studentized_range_quantile(0.95, 2);
    assert!((q - 1.959963984540054 * std::f64::consts::SQRT_2).abs() < 1e-9);
    for q in [0.1, 1.0, 2.77, 6.0] {
        let exact = 1.0 - 2.0 * normal_sf(q / std::f64::consts::SQRT_2);
        assert!((studentized_range_cdf(q, 2) - exact).abs() < 1e-14);
    }
}

#[test]
fn average_ranks_share_ties() {
    let (r, t) = average_ranks(&[3.0, 1.0, 3.0, 2.0, 3.0]);
    assert_eq!(r, vec![4.0, 1.0, 4.0, 2.0, 4.0]);
    assert_eq!(t, 24.0);
}

/// scipy.stats.friedmanchisquare documentation example (heart rates of 7 patients,
/// before, immediately after and 5 minutes after exercise): Q = 10.5714, p = 0.00506.
#[test]
fn friedman_published_example() {
    let before = [72.0, 96.0, 88.0, 92.0, 74.0, 76.0, 82.0];
    let after = [120.0, 120.0, 132.0, 120.0, 101.0, 96.0, 112.0];
    let five = [76.0, 95.0, 104.0, 96.0, 84.0, 72.0, 76.0];
    let blocks: Vec<[f64; 3]> = (0..7).map(|r| [before[r], after[r], five[r]]).collect();
    let f = friedman(&blocks).unwrap();
    assert!(close(f.statistic, 10.57142857142857, 1e-14));
    assert!(close(f.p_value, 0.005063414171757498, 1e-12));
    assert_eq!(f.dof, 2);
    assert_eq!(f.mean_ranks, vec![10.0 / 7.0, 3.0, 11.0 / 7.0]);
    // F = 6 Q / (14 - Q) = 18.5 with (2, 12) dof.
    assert!(close(f.iman_davenport.statistic, 18.5, 1e-13));
    assert_eq!((f.iman_davenport.dof1, f.iman_davenport.dof2), (2, 12));
    assert!(close(
        f.iman_davenport.p_value,
        (1.0f64 + 37.0 / 12.0).powi(-6),
        1e-11
    ));
}

/// By hand: blocks (1, 1, 2), (1, 2, 3), (2, 1, 3) -> rank sums 4.5, 4.5, 9, tie term 6,
/// Q = 4.5 / (1 - 6 / 72) = 54/11, p = exp(-27/11); F = 9 on (2, 4), p = 1/30.25.
#[test]
fn friedman_with_ties_by_hand() {
    let f = friedman(&[[1.0, 1.0, 2.0], [1.0, 2.0, 3.0], [2.0, 1.0, 3.0]]).unwrap();
    assert!(close(f.statistic, 54.0 / 11.0, 1e-14));
    assert!(close(f.p_value, (-27.0f64 / 11.0).exp(), 1e-13));
    assert!(close(f.iman_davenport.statistic, 9.0, 1e-13));
    assert!(close(f.iman_davenport.p_value, 1.0 / 30.25, 1e-12));
}

#[test]
fn friedman_rejects_bad_input() {
    assert_eq!(
        friedman(&[[1.0, 2.0]]),
        Err(StatsError::TooFewBlocks {
            found: 1,
            needed: 2
        })
    );
    assert_eq!(
        friedman(&[[1.0], [2.0]]),
        Err(StatsError::TooFewTreatments {
            found: 1,
            needed: 2
        })
    );
    let ragged: Vec<Vec<f64>> = vec![vec![1.0, 2.0], vec![1.0]];
    assert_eq!(
        friedman(&ragged),
        Err(StatsError::RaggedBlock {
            block: 1,
            expected: 2,
            found: 1
        })
    );
    assert_eq!(
        friedman(&[[1.0, 1.0], [2.0, 2.0]]),
        Err(StatsError::NoVariation)
    );
    let err = friedman(&[[1.0, f64::NAN], [2.0, 3.0]]).unwrap_err();
    assert_eq!(
        err,
        StatsError::NonFinite {
            sample: "block 0".into(),
            index: 1
        }
    );
}

#[test]
fn nemenyi_critical_difference() {
    // Perfect agreement over 10 blocks: mean ranks 1, 2, 3, 4.
    let blocks = vec![[0.1, 0.2, 0.3, 0.4]; 10];
    let f = friedman(&blocks).unwrap();
    assert_eq!(f.iman_davenport.statistic, f64::INFINITY);
    let n = nemenyi(&f, 0.05).unwrap();
    // Demšar: CD = q_0.05 sqrt(k (k + 1) / (6 N)) = 2.569 sqrt(20 / 60).
    assert!((n.critical_difference - 2.569 * (20.0f64 / 60.0).sqrt()).abs() < 1e-3);
    assert!(n.significant[0][3] && n.significant[3][0] && !n.significant[0][1]);
    assert!(n.p_values[0][3] < 0.05 && n.p_values[0][1] > 0.05 && n.p_values[2][2] == 1.0);
    // The p-value at a difference of exactly CD is alpha.
    let ranks = [1.0, 1.0 + n.critical_difference, 2.5, 2.5];
    let g = FriedmanResult {
        mean_ranks: ranks.to_vec(),
        ..f
    };
    assert!((nemenyi(&g, 0.05).unwrap().p_values[0][1] - 0.05).abs() < 1e-8);
    assert_eq!(
        nemenyi(&g, 1.0),
        Err(StatsError::AlphaOutOfRange { alpha: 1.0 })
    );
}

/// scipy.stats.wilcoxon documentation example (Darwin's paired plant heights):
/// W = 24, exact two-sided p = 0.041259765625; normal approximation p = 0.0437723.
#[test]
#[allow(clippy::approx_constant)] // 3.14 is a measurement, not pi.
fn wilcoxon_published_example() {
    let d = [
        6.0, 8.0, 14.0, 16.0, 23.0, 24.0, 28.0, 29.0, 41.0, -48.0, 49.0, 56.0, 60.0, -67.0, 75.0,
    ];
    let w = wilcoxon_signed_rank(&d, &[0.0; 15]).unwrap();
    assert_eq!(
        (w.statistic, w.w_minus, w.w_plus, w.n),
        (24.0, 24.0, 96.0, 15)
    );
    assert_eq!(w.method, PMethod::Exact);
    assert_eq!(w.p_value, 0.041259765625);
    // Hollander & Wolfe (1973) depression scores, as in R's `wilcox.test` example:
    // V = 40, two-sided p = 0.0390625.
    let x = [1.83, 0.50, 1.62, 2.48, 1.68, 1.88, 1.55, 3.06, 1.30];
    let y = [0.878, 0.647, 0.598, 2.05, 1.06, 1.29, 1.06, 3.14, 1.29];
    let w = wilcoxon_signed_rank(&x, &y).unwrap();
    assert_eq!((w.w_plus, w.statistic), (40.0, 5.0));
    assert!(close(w.p_value, 0.0390625, 1e-14));
}

/// Ties and a zero difference force the normal approximation; reference
/// `scipy.stats.wilcoxon(d, zero_method="wilcox", correction=True, method="approx")`.
#[test]
fn wilcoxon_normal_approximation_with_ties_and_zeros() {
    let d = [1.0, 2.0, 2.0, 3.0, 3.0, 3.0, 4.0, 0.0, 5.0, -2.0, -2.0, 6.0];
    let w = wilcoxon_signed_rank(&d, &[0.0; 12]).unwrap();
    assert_eq!(
        (w.n, w.zeros, w.statistic, w.method),
        (11, 1, 7.0, PMethod::Normal)
    );
    assert!(close(w.p_value, 0.022426036096601796, 1e-11));
    // n = 50 without ties: the normal approximation (R's threshold; scipy 1.17
    // `method="approx", correction=True`: 0.9077798683161526).
    let alternating: Vec<f64> = (0..50).map(|i| (-1f64).powi(i) * (i + 1) as f64).collect();
    let w = wilcoxon_signed_rank(&alternating, &[0.0; 50]).unwrap();
    assert_eq!((w.statistic, w.method), (625.0, PMethod::Normal));
    assert!(close(w.p_value, 0.9077798683161526, 1e-11));
}

/// Exact p-values below 50 differences, reference scipy 1.17 `scipy.stats.wilcoxon`
/// (`method="auto"`, exact here).
#[test]
fn wilcoxon_exact_below_fifty() {
    // 30 paired runs, every difference positive: W = 0, p = 2 / 2^30 (the case of
    // `reproduce`'s GCUK comparison; the normal approximation gave 1.8e-6).
    let x: Vec<f64> = (1..=30).map(f64::from).collect();
    let w = wilcoxon_signed_rank(&x, &[0.0; 30]).unwrap();
    assert_eq!((w.statistic, w.method), (0.0, PMethod::Exact));
    assert!(w.statistic.is_sign_positive(), "W prints as 0, not -0");
    assert!(close(w.p_value, 1.862645149230957e-09, 1e-14));
    // Darwin's differences and the same scaled by 100 plus 0.5: n = 30, W = 78.
    let d = [
        6.0, 8.0, 14.0, 16.0, 23.0, 24.0, 28.0, 29.0, 41.0, -48.0, 49.0, 56.0, 60.0, -67.0, 75.0,
    ];
    let mut long = d.to_vec();
    long.extend(d.iter().map(|v| v * 100.0 + 0.5));
    let w = wilcoxon_signed_rank(&long, &[0.0; 30]).unwrap();
    assert_eq!((w.statistic, w.method), (78.0, PMethod::Exact));
    assert!(close(w.p_value, 0.0009517744183540344, 1e-12));
    // n = 49, alternating signs: W = 600, p = 0.9058435571951513.
    let alternating: Vec<f64> = (0..49).map(|i| (-1f64).powi(i) * (i + 1) as f64).collect();
    let w = wilcoxon_signed_rank(&alternating, &[0.0; 49]).unwrap();
    assert_eq!((w.statistic, w.method), (600.0, PMethod::Exact));
    assert!(close(w.p_value, 0.9058435571951513, 1e-12));
}

#[test]
fn wilcoxon_rejects_bad_input() {
    let err = wilcoxon_signed_rank(&[1.0], &[1.0, 2.0]).unwrap_err();
    assert_eq!(err, StatsError::LengthMismatch { x: 1, y: 2 });
    assert_eq!(
        wilcoxon_signed_rank(&[1.0, 2.0], &[1.0, 2.0]),
        Err(StatsError::AllZeroDifferences)
    );
    assert_eq!(
        wilcoxon_signed_rank(&[], &[]),
        Err(StatsError::EmptySample { sample: "x" })
    );
    let err = wilcoxon_signed_rank(&[1.0, 2.0], &[f64::INFINITY, 2.0]).unwrap_err();
    assert_eq!(
        err,
        StatsError::NonFinite {
            sample: "y".into(),
            index: 0
        }
    );
}

/// scipy.stats.mannwhitneyu documentation example (ages of males and females):
/// U = 17, asymptotic two-sided p = 0.11134688653314041.
#[test]
fn mann_whitney_published_example() {
    let males = [19.0, 22.0, 16.0, 29.0, 24.0];
    let females = [20.0, 11.0, 17.0, 12.0];
    let r = mann_whitney_u(&males, &females).unwrap();
    assert_eq!(r.u, 17.0);
    assert!(close(r.p_value, 0.11134688653314041, 1e-12));
    // With ties (reference: scipy, method="asymptotic", use_continuity=True).
    let r = mann_whitney_u(
        &[1.0, 2.0, 2.0, 3.0, 5.0, 7.0],
        &[2.0, 3.0, 3.0, 4.0, 8.0, 9.0, 9.0],
    )
    .unwrap();
    assert_eq!(r.u, 11.0);
    assert!(r.z < 0.0);
    assert!(close(r.p_value, 0.16936768223501375, 1e-12));
}

#[test]
fn mann_whitney_rejects_bad_input() {
    assert_eq!(
        mann_whitney_u(&[], &[1.0]),
        Err(StatsError::EmptySample { sample: "x" })
    );
    assert_eq!(
        mann_whitney_u(&[1.0], &[]),
        Err(StatsError::EmptySample { sample: "y" })
    );
    assert_eq!(
        mann_whitney_u(&[1.0, 1.0], &[1.0]),
        Err(StatsError::NoVariation)
    );
}
