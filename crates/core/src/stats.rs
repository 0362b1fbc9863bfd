//! Non-parametric tests used to compare clustering methods over seeded runs (paper VI-C):
//! the Friedman test with the Iman-Davenport F variant, the Nemenyi post-hoc test, the
//! Wilcoxon signed-rank test (paired) and the Mann-Whitney U test (independent).
//!
//! Ranks are ascending (the smallest value gets rank 1) and tied values share their
//! average rank. All p-values are two-sided where a side applies. Conventions follow
//! Demšar 2006, "Statistical comparisons of classifiers over multiple data sets", JMLR 7,
//! 1-30 (<https://jmlr.org/papers/v7/demsar06a.html>), and agree with
//! `scipy.stats` (`friedmanchisquare`, `wilcoxon`, `mannwhitneyu`) on their defaults.
//!
//! The special functions and distributions (log-gamma, regularised incomplete gamma and
//! beta functions, chi-square and F tails) come from `statrs`; `erfc` is written through
//! its incomplete gamma function (`statrs::function::erf::erfc` is accurate to only
//! ~1e-10, which fails the published-value tests below); only the studentized range
//! distribution (for Nemenyi), which `statrs` lacks, is integrated here: see [`special`].

/// Special functions in f64 and the tail functions of the normal, chi-square, F and
/// studentized range (infinite degrees of freedom) distributions.
///
/// Everything but the studentized range delegates to `statrs` (`function::gamma`,
/// `function::beta`, `distribution`); these thin wrappers keep the names the tests check
/// against published values (scipy).
#[doc(hidden)]
pub mod special {
    use statrs::distribution::{ChiSquared, ContinuousCDF, FisherSnedecor};

    /// `ln Gamma(x)` for `x > 0`.
    pub fn ln_gamma(x: f64) -> f64 {
        statrs::function::gamma::ln_gamma(x)
    }

    /// Regularised lower incomplete gamma `P(a, x) = gamma(a, x) / Gamma(a)`, `a > 0`.
    pub fn gamma_p(a: f64, x: f64) -> f64 {
        if x <= 0.0 {
            0.0
        } else {
            statrs::function::gamma::gamma_lr(a, x)
        }
    }

    /// Regularised upper incomplete gamma `Q(a, x) = 1 - P(a, x)`, `a > 0`.
    pub fn gamma_q(a: f64, x: f64) -> f64 {
        if x <= 0.0 {
            1.0
        } else {
            statrs::function::gamma::gamma_ur(a, x)
        }
    }

    /// Complementary error function `erfc(x) = Q(1/2, x^2)` for `x >= 0`, `1 + P(1/2,
    /// x^2)` below.
    pub fn erfc(x: f64) -> f64 {
        if x >= 0.0 {
            gamma_q(0.5, x * x)
        } else {
            1.0 + gamma_p(0.5, x * x)
        }
    }

    /// Upper tail `1 - Phi(z)` of the standard normal distribution.
    pub fn normal_sf(z: f64) -> f64 {
        0.5 * erfc(z / std::f64::consts::SQRT_2)
    }

    /// Standard normal CDF `Phi(z)`.
    pub fn normal_cdf(z: f64) -> f64 {
        0.5 * erfc(-z / std::f64::consts::SQRT_2)
    }

    /// Upper tail `P(chi2_dof >= x)` of the chi-square distribution (`dof > 0`).
    pub fn chi2_sf(x: f64, dof: f64) -> f64 {
        if x <= 0.0 {
            return 1.0;
        }
        ChiSquared::new(dof).map_or(f64::NAN, |d| d.sf(x))
    }

    /// Regularised incomplete beta function `I_x(a, b)`, `a, b > 0`, `0 <= x <= 1`.
    pub fn beta_inc(a: f64, b: f64, x: f64) -> f64 {
        statrs::function::beta::beta_reg(a, b, x.clamp(0.0, 1.0))
    }

    /// Upper tail `P(F_{d1, d2} >= x)` of the F distribution.
    pub fn f_sf(x: f64, d1: f64, d2: f64) -> f64 {
        if x <= 0.0 {
            return 1.0;
        }
        if x == f64::INFINITY {
            return 0.0;
        }
        FisherSnedecor::new(d1, d2).map_or(f64::NAN, |d| d.sf(x))
    }

    /// CDF of the range of `k` independent standard normals (the studentized range with
    /// infinite degrees of freedom): `k int phi(z) (Phi(z) - Phi(z - q))^(k-1) dz`.
    ///
    /// The integrand is smooth and negligible outside `[-9, 9]` (`phi(9) < 1e-17`), where
    /// the trapezoidal rule converges exponentially: with step 1/16 it agrees with the
    /// closed form for `k = 2` and with a step of 1/256 to ~1e-15.
    pub fn studentized_range_cdf(q: f64, k: usize) -> f64 {
        if q <= 0.0 || k < 2 {
            return 0.0;
        }
        const STEPS: usize = 18 * 16;
        let h = 18.0 / STEPS as f64;
        let norm = 1.0 / (2.0 * std::f64::consts::PI).sqrt();
        let sum: f64 = (0..=STEPS)
            .map(|i| {
                let z = -9.0 + i as f64 * h;
                let inner = (normal_cdf(z) - normal_cdf(z - q)).max(0.0);
                norm * (-0.5 * z * z).exp() * inner.powi(k as i32 - 1)
            })
            .sum();
        (k as f64 * sum * h).clamp(0.0, 1.0)
    }

    /// Quantile `q` with `studentized_range_cdf(q, k) = p`, `0 < p < 1`, by bisection
    /// (absolute error < 1e-9).
    pub fn studentized_range_quantile(p: f64, k: usize) -> f64 {
        let (mut lo, mut hi) = (0.0, 8.0);
        while studentized_range_cdf(hi, k) < p && hi < 1e3 {
            hi *= 2.0;
        }
        while hi - lo > 1e-10 {
            let mid = 0.5 * (lo + hi);
            if studentized_range_cdf(mid, k) < p {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }
}

/// Mean of `v`, summed in order; NaN for no value (never a silent 0).
///
/// The crate's one mean and [`median`]: one NaN convention, NaN for an empty slice; a NaN
/// among the values propagates to the mean and sorts last ([`f64::total_cmp`]) for the
/// median.
pub fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// Median of `v` (the mean of the two middle values for an even count); NaN for no value.
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    match s.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => s[n / 2],
        n => 0.5 * (s[n / 2 - 1] + s[n / 2]),
    }
}

/// The crate's one format for a value shown to people (reports, summaries, messages): four
/// significant digits, fixed-point between 1e-3 and 1e5 (`24.08`, `0.01235`, `1235`),
/// scientific outside (`2.500e-5`); `0`; `n/a` for NaN, `inf`/`-inf` for infinities.
/// Machine-readable files (CSV, JSON) keep every digit instead.
pub fn num(v: f64) -> String {
    if v.is_nan() {
        return "n/a".into();
    }
    if v.is_infinite() {
        return if v > 0.0 { "inf".into() } else { "-inf".into() };
    }
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if (1e-3..1e5).contains(&a) {
        let digits = (3 - a.log10().floor() as i32).max(0) as usize;
        format!("{v:.digits$}")
    } else {
        format!("{v:.3e}")
    }
}

/// A p-value shown to people: three decimals, scientific (`1.23e-5`) below 1e-3; `n/a`
/// when not finite.
pub fn p_value(v: f64) -> String {
    if !v.is_finite() {
        "n/a".into()
    } else if v >= 1e-3 {
        format!("{v:.3}")
    } else {
        format!("{v:.2e}")
    }
}

use special::{chi2_sf, f_sf, normal_sf, studentized_range_cdf, studentized_range_quantile};

/// Errors of the statistical tests.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StatsError {
    /// Fewer blocks (rows, e.g. runs) than the test needs.
    #[error("too few blocks: found {found}, need at least {needed}")]
    TooFewBlocks {
        /// Number of blocks given.
        found: usize,
        /// Minimum number of blocks.
        needed: usize,
    },
    /// Fewer treatments (columns, e.g. methods) than the test needs.
    #[error("too few treatments: found {found}, need at least {needed}")]
    TooFewTreatments {
        /// Number of treatments given.
        found: usize,
        /// Minimum number of treatments.
        needed: usize,
    },
    /// A block does not have one value per treatment.
    #[error("block {block} has {found} values, expected {expected} (one per treatment)")]
    RaggedBlock {
        /// Index of the offending block.
        block: usize,
        /// Number of treatments (length of block 0).
        expected: usize,
        /// Length of the offending block.
        found: usize,
    },
    /// A value is NaN or infinite.
    #[error("value {index} of {sample} is not finite")]
    NonFinite {
        /// Which input: "x", "y" or "block r".
        sample: String,
        /// Position of the value.
        index: usize,
    },
    /// A sample that must not be empty is empty.
    #[error("sample {sample} is empty")]
    EmptySample {
        /// Which input.
        sample: &'static str,
    },
    /// Paired samples differ in length.
    #[error("paired samples differ in length: x has {x}, y has {y}")]
    LengthMismatch {
        /// Length of `x`.
        x: usize,
        /// Length of `y`.
        y: usize,
    },
    /// Every paired difference is zero: the signed-rank test is undefined.
    #[error("every paired difference is zero")]
    AllZeroDifferences,
    /// Every value is tied (within every block for Friedman): the statistic is 0/0.
    #[error("no variation: every value is tied")]
    NoVariation,
    /// The significance level is not in (0, 1).
    #[error("significance level alpha = {alpha} is not in (0, 1)")]
    AlphaOutOfRange {
        /// The offending value.
        alpha: f64,
    },
}

fn check_finite(values: &[f64], sample: impl Fn() -> String) -> Result<(), StatsError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(StatsError::NonFinite {
            sample: sample(),
            index,
        }),
        None => Ok(()),
    }
}

/// Average ranks (1-based, ascending) of `values` and the tie term `sum_t (t^3 - t)` over
/// groups of `t` tied values.
fn average_ranks(values: &[f64]) -> (Vec<f64>, f64) {
    let mut order: Vec<usize> = (0..values.len()).collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    let mut ranks = vec![0.0; values.len()];
    let mut ties = 0.0;
    let mut start = 0;
    while start < order.len() {
        let mut end = start + 1;
        while end < order.len() && values[order[end]] == values[order[start]] {
            end += 1;
        }
        let t = (end - start) as f64;
        ties += t * t * t - t;
        // Ranks start + 1 ..= end share their mean.
        let rank = (start + end + 1) as f64 / 2.0;
        order[start..end].iter().for_each(|&i| ranks[i] = rank);
        start = end;
    }
    (ranks, ties)
}

/// Result of [`friedman`].
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FriedmanResult {
    /// Tie-corrected Friedman chi-square statistic `Q`.
    pub statistic: f64,
    /// Degrees of freedom `k - 1`.
    pub dof: usize,
    /// `P(chi2_{k-1} >= Q)`.
    pub p_value: f64,
    /// Mean rank of each treatment over the blocks (rank 1 = smallest value).
    pub mean_ranks: Vec<f64>,
    /// Number of blocks `N`.
    pub blocks: usize,
    /// The Iman-Davenport F variant.
    pub iman_davenport: ImanDavenport,
}

/// Iman & Davenport's F statistic (1980, doi:10.1080/03610928008827904), less
/// conservative than `Q`: `F = (N - 1) Q / (N (k - 1) - Q)` with `(k - 1, (k - 1)(N - 1))`
/// degrees of freedom (`F = +inf`, `p = 0` when the rankings agree perfectly).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ImanDavenport {
    /// The F statistic.
    pub statistic: f64,
    /// Numerator degrees of freedom `k - 1`.
    pub dof1: usize,
    /// Denominator degrees of freedom `(k - 1)(N - 1)`.
    pub dof2: usize,
    /// `P(F_{dof1, dof2} >= F)`.
    pub p_value: f64,
}

/// Friedman test (Friedman 1937, doi:10.1080/01621459.1937.10503522) of `k` treatments
/// over `N` blocks: `blocks[r][j]` is the value of treatment `j` (method) in block `r`
/// (run `r` of every method; SPEC section 6). Needs `N >= 2`, `k >= 2`.
///
/// With `R_j` the rank sum of treatment `j` and `t` the sizes of tie groups in a block,
/// ```text
/// Q = (12 / (N k (k + 1)) sum_j R_j^2 - 3 N (k + 1)) / (1 - sum t^3 - t / (N (k^3 - k)))
/// ```
/// is compared with a chi-square distribution with `k - 1` degrees of freedom.
pub fn friedman<R: AsRef<[f64]>>(blocks: &[R]) -> Result<FriedmanResult, StatsError> {
    let n = blocks.len();
    if n < 2 {
        return Err(StatsError::TooFewBlocks {
            found: n,
            needed: 2,
        });
    }
    let k = blocks[0].as_ref().len();
    if k < 2 {
        return Err(StatsError::TooFewTreatments {
            found: k,
            needed: 2,
        });
    }
    let mut rank_sums = vec![0.0; k];
    let mut ties = 0.0;
    for (r, block) in blocks.iter().enumerate() {
        let block = block.as_ref();
        if block.len() != k {
            return Err(StatsError::RaggedBlock {
                block: r,
                expected: k,
                found: block.len(),
            });
        }
        check_finite(block, || format!("block {r}"))?;
        let (ranks, t) = average_ranks(block);
        rank_sums.iter_mut().zip(&ranks).for_each(|(s, r)| *s += r);
        ties += t;
    }
    let (nf, kf) = (n as f64, k as f64);
    let correction = 1.0 - ties / (nf * (kf * kf * kf - kf));
    if correction <= 0.0 {
        return Err(StatsError::NoVariation);
    }
    let sum_sq: f64 = rank_sums.iter().map(|s| s * s).sum();
    let q =
        ((12.0 / (nf * kf * (kf + 1.0)) * sum_sq - 3.0 * nf * (kf + 1.0)) / correction).max(0.0);
    let (dof1, dof2) = (k - 1, (k - 1) * (n - 1));
    let denom = nf * (kf - 1.0) - q;
    let (f, f_p) = if denom > 0.0 {
        let f = (nf - 1.0) * q / denom;
        (f, f_sf(f, dof1 as f64, dof2 as f64))
    } else {
        (f64::INFINITY, 0.0)
    };
    Ok(FriedmanResult {
        statistic: q,
        dof: dof1,
        p_value: chi2_sf(q, dof1 as f64),
        mean_ranks: rank_sums.iter().map(|s| s / nf).collect(),
        blocks: n,
        iman_davenport: ImanDavenport {
            statistic: f,
            dof1,
            dof2,
            p_value: f_p,
        },
    })
}

/// Result of `nemenyi`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NemenyiResult {
    /// Significance level.
    pub alpha: f64,
    /// `q_alpha`: the upper-`alpha` quantile of the studentized range of `k` standard
    /// normals (infinite degrees of freedom) divided by `sqrt(2)` (Demšar's Table 5).
    pub q_alpha: f64,
    /// Critical difference `CD = q_alpha sqrt(k (k + 1) / (6 N))`.
    pub critical_difference: f64,
    /// Mean ranks, copied from the Friedman result.
    pub mean_ranks: Vec<f64>,
    /// `p_values[i][j]`: two-sided p-value of the pair (1 on the diagonal).
    pub p_values: Vec<Vec<f64>>,
    /// `significant[i][j]`: `|R_i - R_j| > CD`.
    pub significant: Vec<Vec<bool>>,
}

/// Nemenyi post-hoc test after [`friedman`] (Nemenyi 1963; Demšar 2006, section 3.2.2):
/// treatments `i` and `j` differ when their mean ranks differ by more than the critical
/// difference `CD`. The pair's p-value is `1 - F_k(|R_i - R_j| sqrt(2) / sqrt(k (k + 1) /
/// (6 N)))` with `F_k` the studentized range CDF ([`special::studentized_range_cdf`]).
///
/// `q_alpha` is computed, not tabulated; the tests check it against Demšar's table of
/// `q_0.05` and `q_0.10` for `k = 2..10` and against `q_0.05` for `k` up to 20 (Harter
/// 1960, doi:10.1080/01621459.1960.10483369).
pub(crate) fn nemenyi(friedman: &FriedmanResult, alpha: f64) -> Result<NemenyiResult, StatsError> {
    if !(alpha > 0.0 && alpha < 1.0) {
        return Err(StatsError::AlphaOutOfRange { alpha });
    }
    let k = friedman.mean_ranks.len();
    let kf = k as f64;
    let se = (kf * (kf + 1.0) / (6.0 * friedman.blocks as f64)).sqrt();
    let q_alpha = studentized_range_quantile(1.0 - alpha, k) / std::f64::consts::SQRT_2;
    let cd = q_alpha * se;
    let r = &friedman.mean_ranks;
    let p_values = (0..k)
        .map(|i| {
            (0..k)
                .map(|j| {
                    let q = (r[i] - r[j]).abs() / se * std::f64::consts::SQRT_2;
                    if i == j {
                        1.0
                    } else {
                        (1.0 - studentized_range_cdf(q, k)).clamp(0.0, 1.0)
                    }
                })
                .collect()
        })
        .collect();
    let significant = (0..k)
        .map(|i| (0..k).map(|j| (r[i] - r[j]).abs() > cd).collect())
        .collect();
    Ok(NemenyiResult {
        alpha,
        q_alpha,
        critical_difference: cd,
        mean_ranks: r.clone(),
        p_values,
        significant,
    })
}

/// How a p-value was computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PMethod {
    /// Exact null distribution.
    Exact,
    /// Normal approximation with tie and continuity corrections.
    Normal,
}

impl std::fmt::Display for PMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            PMethod::Exact => "exact",
            PMethod::Normal => "normal approximation with continuity correction",
        })
    }
}

/// The signed-rank p-value is exact below this many non-zero differences (when there are
/// no ties and no zeros), as R's `wilcox.test` and `scipy.stats.wilcoxon`: the exact counts
/// of `n = 49` (`2^49` subsets) are still exact integers in f64.
pub const WILCOXON_EXACT_BELOW: usize = 50;

/// Result of [`wilcoxon_signed_rank`].
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WilcoxonResult {
    /// Number of non-zero differences (the sample size of the test).
    pub n: usize,
    /// Number of zero differences dropped.
    pub zeros: usize,
    /// Sum of the ranks of the positive differences `x - y`.
    pub w_plus: f64,
    /// Sum of the ranks of the negative differences.
    pub w_minus: f64,
    /// `min(W+, W-)`, the two-sided statistic (as `scipy.stats.wilcoxon`).
    pub statistic: f64,
    /// Continuity-corrected z score (`<= 0`) of the normal approximation, if used.
    pub z: Option<f64>,
    /// Two-sided p-value.
    pub p_value: f64,
    /// How `p_value` was computed.
    pub method: PMethod,
}

/// Wilcoxon signed-rank test of paired samples (Wilcoxon 1945, doi:10.2307/3001968),
/// two-sided, on the differences `x_i - y_i`.
///
/// Zero differences are dropped (Wilcoxon's convention); the `n` others are ranked by
/// absolute value with average ranks for ties. As R's `wilcox.test` and
/// `scipy.stats.wilcoxon` (`method="auto"`): with `n <` [`WILCOXON_EXACT_BELOW`], no ties
/// and no zero difference the p-value is exact, `min(1, 2 P(W <= T))` for `T = min(W+,
/// W-)`, from the distribution of the rank sum of a random subset of `1..=n`. Otherwise
/// the normal approximation with continuity correction: `z = (T - n(n+1)/4 + 1/2) /
/// sigma` with `sigma^2 = n(n+1)(2n+1)/24 - sum_t (t^3 - t)/48`, `p = min(1, 2 Phi(z))`.
pub fn wilcoxon_signed_rank(x: &[f64], y: &[f64]) -> Result<WilcoxonResult, StatsError> {
    if x.len() != y.len() {
        return Err(StatsError::LengthMismatch {
            x: x.len(),
            y: y.len(),
        });
    }
    // Audit 2, U15: no pairs at all is not "every paired difference is zero".
    if x.is_empty() {
        return Err(StatsError::EmptySample { sample: "x" });
    }
    check_finite(x, || "x".into())?;
    check_finite(y, || "y".into())?;
    let diffs: Vec<f64> = x
        .iter()
        .zip(y)
        .map(|(a, b)| a - b)
        .filter(|d| *d != 0.0)
        .collect();
    let n = diffs.len();
    if n == 0 {
        return Err(StatsError::AllZeroDifferences);
    }
    let (ranks, ties) = average_ranks(&diffs.iter().map(|d| d.abs()).collect::<Vec<_>>());
    let w_plus: f64 = diffs
        .iter()
        .zip(&ranks)
        .filter(|(d, _)| **d > 0.0)
        .map(|(_, r)| r)
        .sum();
    // `+ 0.0`: an empty f64 sum is -0.0, which would print as "-0".
    let w_plus = w_plus + 0.0;
    let nf = n as f64;
    let w_minus = nf * (nf + 1.0) / 2.0 - w_plus + 0.0;
    let t = w_plus.min(w_minus);
    let zeros = x.len() - n;
    let (z, p_value, method) = if n < WILCOXON_EXACT_BELOW && ties == 0.0 && zeros == 0 {
        // counts[s] = number of subsets of 1..=n with rank sum s.
        let max = n * (n + 1) / 2;
        let mut counts = vec![0.0f64; max + 1];
        counts[0] = 1.0;
        for r in 1..=n {
            for s in (r..=max).rev() {
                counts[s] += counts[s - r];
            }
        }
        // `t` is an integer here (no ties), at most max / 2.
        let cdf: f64 = counts[..=t as usize].iter().sum::<f64>() / 2f64.powi(n as i32);
        (None, (2.0 * cdf).min(1.0), PMethod::Exact)
    } else {
        let mean = nf * (nf + 1.0) / 4.0;
        let sd = (nf * (nf + 1.0) * (2.0 * nf + 1.0) / 24.0 - ties / 48.0).sqrt();
        let z = ((t - mean + 0.5) / sd).min(0.0);
        (Some(z), (2.0 * normal_sf(-z)).min(1.0), PMethod::Normal)
    };
    Ok(WilcoxonResult {
        n,
        zeros,
        w_plus,
        w_minus,
        statistic: t,
        z,
        p_value,
        method,
    })
}

/// Result of [`mann_whitney_u`].
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MannWhitneyResult {
    /// `U` of `x`: `R_x - n_x (n_x + 1) / 2` (as `scipy.stats.mannwhitneyu`).
    pub u: f64,
    /// Continuity-corrected z score, signed like `U - n_x n_y / 2`.
    pub z: f64,
    /// Two-sided p-value (normal approximation).
    pub p_value: f64,
}

/// Mann-Whitney U (Wilcoxon rank-sum) test of independent samples (Mann & Whitney 1947,
/// doi:10.1214/aoms/1177730491), two-sided, normal approximation with tie and continuity
/// corrections: `mu = n_x n_y / 2`, `sigma^2 = n_x n_y / 12 ((n + 1) - sum_t (t^3 - t) /
/// (n (n - 1)))`, `z = sign(U - mu) max(|U - mu| - 1/2, 0) / sigma`, `p = min(1, 2 (1 -
/// Phi(|z|)))`, with `n = n_x + n_y` and `t` the sizes of tie groups of the pooled sample.
pub fn mann_whitney_u(x: &[f64], y: &[f64]) -> Result<MannWhitneyResult, StatsError> {
    if x.is_empty() {
        return Err(StatsError::EmptySample { sample: "x" });
    }
    if y.is_empty() {
        return Err(StatsError::EmptySample { sample: "y" });
    }
    check_finite(x, || "x".into())?;
    check_finite(y, || "y".into())?;
    let pooled: Vec<f64> = x.iter().chain(y).copied().collect();
    let (ranks, ties) = average_ranks(&pooled);
    let (nx, ny, n) = (x.len() as f64, y.len() as f64, pooled.len() as f64);
    let u = ranks[..x.len()].iter().sum::<f64>() - nx * (nx + 1.0) / 2.0;
    let var = nx * ny / 12.0 * ((n + 1.0) - ties / (n * (n - 1.0)));
    if var <= 0.0 {
        return Err(StatsError::NoVariation);
    }
    let dev = u - nx * ny / 2.0;
    let z = dev.signum() * (dev.abs() - 0.5).max(0.0) / var.sqrt();
    Ok(MannWhitneyResult {
        u,
        z,
        p_value: (2.0 * normal_sf(z.abs())).min(1.0),
    })
}

#[cfg(test)]
mod tests;
