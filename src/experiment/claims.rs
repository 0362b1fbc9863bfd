//! The claims of the paper's section VI, each set beside our figure.

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

/// Checks the claims of section VI against `e`.
pub fn check(e: &Experiment) -> Vec<Claim> {
    let mut out = Vec::new();
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
    let zero = emp.counts.iter().filter(|&&c| c == 0).count();
    out.push(claim(
        "VI-B",
        "Five materials contribute to no other material's fit.",
        format!("{zero} of {n}"),
        Some(zero == 5),
        "",
    ));
    out.push(claim(
        "VI-B",
        "14 materials contribute to more than five fits (the empirical basis).",
        format!("{}", emp.basis.len()),
        Some(emp.basis.len() == 14),
        "",
    ));
    for m in ["euclidean", "brdf-it"] {
        if let Some(f) = e.statistics.friedman.get(&format!("friedman-{m}")) {
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
                format!("lowest mean rank: {best}; Friedman p = {:.2e}", f.p_value),
                Some(best == "gcuk" && f.p_value < 0.05),
                "",
            ));
        }
    }
    if let Some(c) = &e.statistics.gcuk_euclidean_vs_brdf_it {
        out.push(claim(
            "VI-C",
            "Wilcoxon test of GCUK Euclidean vs GCUK BRDF_it: p < 2.2e-16.",
            format!("p = {:.3e} ({}, {} paired runs)", c.wilcoxon_p, c.wilcoxon_method, c.runs),
            Some(c.wilcoxon_p < 0.05),
            "Significant, as the paper; but with 30 paired runs the smallest attainable two-sided signed-rank p is 2/2^30 = 1.9e-9, so p < 2.2e-16 (R's print floor) cannot come from this test on 30 runs.",
        ));
    }
    let medians = |m: &str| -> Vec<(String, f64)> {
        e.clustering
            .iter()
            .filter(|s| s.metric == m)
            .map(|s| (s.method.clone(), super::statistics::median(&s.db_values())))
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
    out.push(claim(
        "VI-E",
        "62 materials are in no basis (the evaluation set).",
        format!("{}", e.evaluation.targets.len()),
        Some(e.evaluation.targets.len() == 62),
        "Our bases differ from the paper's, so their union differs.",
    ));
    let errs = &e.evaluation.errors;
    let rank = |key: fn(&super::evaluation::BasisErrors) -> f64| -> Vec<String> {
        let mut v: Vec<(f64, String)> = errs.iter().map(|b| (key(b), b.basis.clone())).collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        v.into_iter().map(|x| x.1).collect()
    };
    let by_mae = rank(|b| b.mean_mae);
    let by_img = rank(|b| b.mean_image_error);
    for (group, label) in [("kmedoids", "our"), ("paper-kmedoids", "the paper's")] {
        let members: Vec<&String> = errs
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
    if let (Some(m), Some(i)) = (
        by_mae.iter().position(|b| b == "empirical"),
        by_img.iter().position(|b| b == "empirical"),
    ) {
        out.push(claim(
            "VI-E",
            "The empirical basis is unstable on reflectance MAE but good on image error.",
            format!(
                "empirical ranks {} of {} by mean MAE, {} by mean image error",
                m + 1,
                by_mae.len(),
                i + 1
            ),
            Some(i < m),
            "",
        ));
    }
    let s = &e.evaluation.showcase;
    if let Some(best) = s.approximations.iter().min_by(|a, b| a.3.total_cmp(&b.3)) {
        out.push(claim(
            "VI-E",
            "On alum-bronze (Fig. 5) the empirical basis gives the best rendering.",
            format!(
                "{}: best image error by {} ({:.4})",
                s.material, best.0, best.3
            ),
            (s.material == "alum-bronze")
                .then_some(best.0 == "empirical" || best.0 == "paper-empirical"),
            if s.material == "alum-bronze" {
                ""
            } else {
                "the showcase is not alum-bronze"
            },
        ));
    }
    out
}
