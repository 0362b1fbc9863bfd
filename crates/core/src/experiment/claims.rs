//! The claims of the paper's section VI, each set beside our figure.

use super::evaluation::BasisErrors;
use super::Experiment;

/// One claim of the paper and what this run found.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Claim {
    /// Section of the paper.
    pub section: String,
    /// The paper's statement.
    pub paper: String,
    /// Our figure.
    pub ours: String,
    /// Whether they agree (`None`: cannot be judged from this run).
    pub agree: Option<bool>,
    /// Why not, where known.
    pub why: String,
}

fn claim(section: &str, paper: &str, ours: String, agree: Option<bool>, why: &str) -> Claim {
    Claim {
        section: section.into(),
        paper: paper.into(),
        ours,
        agree,
        why: why.into(),
    }
}

/// A claim check: appends what `e` says about one claim of the paper (nothing when `e`
/// cannot speak to it, e.g. a metric that was not run).
pub type Check = fn(&Experiment, &mut Vec<Claim>);

/// The checks, in the order of section VI.
pub const CHECKS: &[Check] = &[
    fit_sizes,
    non_contributors,
    empirical_size,
    gcuk_best_db,
    gcuk_wilcoxon,
    brdf_it_lower_db,
    best_k,
    evaluation_set,
    kmedoids_best_errors,
    empirical_unstable_but_good,
    showcase_best_rendering,
];

/// Checks the claims of section VI against `e`.
pub fn check(e: &Experiment) -> Vec<Claim> {
    let mut out = Vec::new();
    for c in CHECKS {
        c(e, &mut out);
    }
    out
}

/// Whether rank `rank` (1 = best) of `n` is in the better half: `rank <= n / 2`, so the
/// middle rank of an odd `n` is not (5 of 9 is not, 4 of 9 is). What the claims call
/// "good" on a ranking.
pub(crate) fn in_better_half(rank: usize, n: usize) -> bool {
    rank >= 1 && rank <= n / 2
}

/// Ranks (1 = best) of the empirical basis by mean MAE and by mean image error, of `n`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmpiricalRanks {
    /// Rank by mean MAE.
    pub mae: usize,
    /// Rank by mean image error.
    pub image: usize,
    /// Number of bases ranked.
    pub n: usize,
}

impl EmpiricalRanks {
    /// The paper's "unstable on reflectance MAE but good on image error": good on image
    /// error means in the better half of the bases (`in_better_half`), and it must rank
    /// better on image error than on MAE. "Ranks 7 of 9 by image error" is not good.
    pub fn agrees(&self) -> bool {
        in_better_half(self.image, self.n) && self.image < self.mae
    }
}

fn fit_sizes(e: &Experiment, out: &mut Vec<Claim>) {
    let emp = &e.empirical;
    let n = e.settings.materials;
    let sizes: Vec<(usize, &String)> = emp.contributors.iter().map(|(t, c)| (c.len(), t)).collect();
    let max = sizes.iter().map(|s| s.0).max().unwrap_or(0);
    let over4: Vec<&String> = sizes.iter().filter(|s| s.0 > 4).map(|s| s.1).collect();
    out.push(claim(
        "VI-B",
        "All but one material (polyethylene, 5) are fitted by 4 or fewer other materials.",
        format!(
            "{} of {n} fits use more than 4 materials (largest: {max}){}",
            over4.len(),
            if over4.len() <= 5 {
                format!(": {}", over4.iter().map(|s| s.as_str()).collect::<Vec<_>>().join(", "))
            } else {
                String::new()
            }
        ),
        Some(over4.len() <= 1),
        "NNLS over the full grid uses more columns than the paper's fits (its sampling and solver tolerance are not stated).",
    ));
}

fn non_contributors(e: &Experiment, out: &mut Vec<Claim>) {
    let zero = e.empirical.counts.iter().filter(|&&c| c == 0).count();
    out.push(claim(
        "VI-B",
        "Five materials contribute to no other material's fit.",
        format!("{zero} of {}", e.settings.materials),
        Some(zero == 5),
        "",
    ));
}

fn empirical_size(e: &Experiment, out: &mut Vec<Claim>) {
    let basis = &e.empirical.basis;
    out.push(claim(
        "VI-B",
        "14 materials contribute to more than five fits (the empirical basis).",
        format!("{}", basis.len()),
        Some(basis.len() == 14),
        "",
    ));
}

fn gcuk_best_db(e: &Experiment, out: &mut Vec<Claim>) {
    for m in ["euclidean", "brdf-it"] {
        if let Some(f) = e.statistics.friedman_of(m) {
            let best = f
                .mean_ranks
                .iter()
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(b.1))
                .map(|(i, _)| f.methods[i].clone())
                .unwrap_or_default();
            out.push(claim(
                "VI-C",
                &format!(
                    "GCUK obtains the best (lowest) DB of all algorithms with {m} (Friedman, 95%)."
                ),
                format!(
                    "lowest mean rank: {best}; Friedman p = {}",
                    crate::stats::p_value(f.p_value)
                ),
                Some(best == "gcuk" && f.p_value < 0.05),
                "",
            ));
        }
    }
}

fn gcuk_wilcoxon(e: &Experiment, out: &mut Vec<Claim>) {
    if let Some(c) = &e.statistics.gcuk_euclidean_vs_brdf_it {
        out.push(claim(
            "VI-C",
            "Wilcoxon test of GCUK Euclidean vs GCUK BRDF_it: p < 2.2e-16.",
            format!("p = {} ({}, {} paired runs)", crate::stats::p_value(c.wilcoxon_p), c.wilcoxon_method, c.runs),
            Some(c.wilcoxon_p < 0.05),
            "Significant, as the paper; but with 30 paired runs the smallest attainable two-sided signed-rank p is 2/2^30 = 1.9e-9, so p < 2.2e-16 (R's print floor) cannot come from this test on 30 runs.",
        ));
    }
}

fn brdf_it_lower_db(e: &Experiment, out: &mut Vec<Claim>) {
    let medians = |m: &str| -> Vec<(String, f64)> {
        e.clustering
            .iter()
            .filter(|s| s.metric == m)
            .map(|s| (s.method.clone(), crate::stats::median(&s.db_values())))
            .collect()
    };
    let (eu, bi) = (medians("euclidean"), medians("brdf-it"));
    if !eu.is_empty() {
        let lower = eu.iter().zip(&bi).filter(|((_, a), (_, b))| b < a).count();
        out.push(claim(
            "VI-C",
            "BRDF_it gives lower DB values than Euclidean distance (Fig. 3).",
            format!("median DB lower with BRDF_it for {lower} of {} methods", eu.len()),
            Some(lower == eu.len()),
            "DB values on different distances are on different scales; the comparison holds only as the paper frames it.",
        ));
    }
}

fn best_k(e: &Experiment, out: &mut Vec<Claim>) {
    for b in &e.bases {
        if b.name.starts_with("kmedoids-best-k") {
            out.push(claim(
                "VI-D",
                "The best k-medoids configuration over k = 5..12 by DB has k = 5 (kmedoids5).",
                b.name.clone(),
                Some(b.materials.len() == 5),
                "",
            ));
        }
        if b.name.starts_with("gcuk-best-k") {
            out.push(claim(
                "VI-D",
                "The best GCUK run by DB has k = 5 (gcuk5).",
                b.name.clone(),
                Some(b.materials.len() == 5),
                "",
            ));
        }
    }
}

fn evaluation_set(e: &Experiment, out: &mut Vec<Claim>) {
    let n = e.evaluation.targets.len();
    out.push(claim(
        "VI-E",
        "62 materials are in no basis (the evaluation set).",
        format!("{n}"),
        Some(n == 62),
        "Our bases differ from the paper's, so their union differs.",
    ));
}

/// Basis names sorted by `key` (ascending: best first).
fn ranked(e: &Experiment, key: fn(&BasisErrors) -> f64) -> Vec<String> {
    let mut v: Vec<(f64, String)> = e
        .evaluation
        .errors
        .iter()
        .map(|b| (key(b), b.basis.clone()))
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    v.into_iter().map(|x| x.1).collect()
}

fn kmedoids_best_errors(e: &Experiment, out: &mut Vec<Claim>) {
    let by_mae = ranked(e, |b| b.mean_mae);
    for (group, label) in [("kmedoids", "our"), ("paper-kmedoids", "the paper's")] {
        let members: Vec<&String> = e
            .evaluation
            .errors
            .iter()
            .map(|b| &b.basis)
            .filter(|b| b.starts_with(group) && (group != "kmedoids" || !b.starts_with("paper")))
            .collect();
        let pool: Vec<&String> = by_mae
            .iter()
            .filter(|b| b.starts_with("paper-") == group.starts_with("paper-"))
            .collect();
        if members.is_empty() || pool.len() < 2 {
            continue;
        }
        let top = pool
            .iter()
            .take(members.len())
            .filter(|b| members.contains(b))
            .count();
        out.push(claim(
            "VI-E",
            &format!("The k-medoids bases reach the best errors ({label} bases, mean MAE)."),
            format!(
                "MAE order: {}",
                pool.iter()
                    .map(|s| s.as_str())
                    .collect::<Vec<_>>()
                    .join(" < ")
            ),
            Some(top == members.len()),
            "",
        ));
    }
}

fn empirical_unstable_but_good(e: &Experiment, out: &mut Vec<Claim>) {
    let (by_mae, by_img) = (ranked(e, |b| b.mean_mae), ranked(e, |b| b.mean_image_error));
    if let (Some(m), Some(i)) = (
        by_mae.iter().position(|b| b == "empirical"),
        by_img.iter().position(|b| b == "empirical"),
    ) {
        let r = EmpiricalRanks {
            mae: m + 1,
            image: i + 1,
            n: by_mae.len(),
        };
        out.push(claim(
            "VI-E",
            "The empirical basis is unstable on reflectance MAE but good on image error.",
            format!(
                "empirical ranks {} of {} by mean MAE, {} by mean image error (good: in the better half, rank <= {})",
                r.mae, r.n, r.image, r.n / 2
            ),
            Some(r.agrees()),
            "",
        ));
    }
}

fn showcase_best_rendering(e: &Experiment, out: &mut Vec<Claim>) {
    let s = &e.evaluation.showcase;
    if let Some(best) = s
        .approximations
        .iter()
        .min_by(|a, b| a.image_error.total_cmp(&b.image_error))
    {
        out.push(claim(
            "VI-E",
            "On alum-bronze (Fig. 5) the empirical basis gives the best rendering.",
            format!(
                "{}: best image error by {} ({})",
                s.material,
                best.basis,
                crate::stats::num(best.image_error)
            ),
            (s.material == "alum-bronze")
                .then_some(best.basis == "empirical" || best.basis == "paper-empirical"),
            if s.material == "alum-bronze" {
                ""
            } else {
                "the showcase is not alum-bronze"
            },
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn better_half_excludes_the_middle_and_below() {
        assert!(in_better_half(1, 9) && in_better_half(4, 9));
        assert!(!in_better_half(5, 9) && !in_better_half(7, 9) && !in_better_half(9, 9));
        assert!(in_better_half(1, 13) && in_better_half(6, 13) && !in_better_half(7, 13));
        assert!(in_better_half(2, 4) && !in_better_half(3, 4));
        assert!(!in_better_half(1, 1) && !in_better_half(0, 9));
    }

    /// The report's defect: "ranks 3 of 9 by mean MAE, 7 by image error" was not the
    /// case, but 9 by MAE and 7 by image error was marked as agreeing (7 < 9).
    #[test]
    fn empirical_claim_judges_rank_evidence() {
        let r = |mae, image, n| EmpiricalRanks { mae, image, n }.agrees();
        assert!(!r(9, 7, 9), "7 of 9 by image error is not good");
        assert!(!r(3, 5, 9));
        assert!(r(13, 1, 13));
        assert!(r(8, 4, 9));
        assert!(
            !r(2, 4, 9),
            "good on image error but better still on MAE: not unstable"
        );
    }
}
