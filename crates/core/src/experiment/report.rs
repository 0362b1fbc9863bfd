//! `report.md`: the run's settings, results, figures and the paper's claims checked.
//!
//! The report is the concatenation of [`SECTIONS`]; to add a section, write a function
//! `fn(&Experiment, &ReportContext, &mut String)` and list it there.

use super::claims::check;
use super::{Experiment, StageTiming};
use crate::stats::{median, num, p_value};
use std::fmt::Write as _;

/// What the caller adds to the report: the figures written (by stem), notes and the
/// timings of stages run outside [`super::run`] (figures, files).
#[derive(Clone, Debug, Default)]
pub struct ReportContext {
    /// Figure files by stem, relative to the report (e.g. `("fig2-contributions",
    /// "figures/fig2-contributions.png")`); a section shows the figures it knows.
    pub figures: Vec<(String, String)>,
    /// Notes shown at the top (e.g. no font found).
    pub notes: Vec<String>,
    /// Extra stage timings.
    pub timings: Vec<StageTiming>,
    /// The acquisition cross-validation run beside the experiment (SPEC 10), if any.
    pub acquisition: Option<AcquisitionReport>,
    /// The appearance study run beside the experiment (SPEC 11), if any.
    pub appearance: Option<AppearanceReport>,
}

/// The appearance study of the report's "Appearance" section.
#[derive(Clone, Debug)]
pub struct AppearanceReport {
    /// The study (`appearance.json`); `None` when it was not run.
    pub study: Option<super::appearance::AppearanceStudy>,
    /// Why it was not run, instead of a result.
    pub skipped: Option<String>,
}

/// The acquisition cross-validation of the report's "Acquisition" section.
#[derive(Clone, Debug)]
pub struct AcquisitionReport {
    /// The cross-validation (`acquisition.json`).
    pub cv: crate::acquire::AcqCv,
    /// Its settings, in words (folds, k, plans, n, noise, candidates per step, stride).
    pub settings: String,
    /// Why it was not run, instead of a result.
    pub skipped: Option<String>,
}

impl ReportContext {
    fn figure(&self, out: &mut String, stem: &str, caption: &str) {
        for (s, path) in &self.figures {
            if s == stem {
                let _ = writeln!(
                    out,
                    "\n![{caption}]({path})\n\n*{caption}* ([SVG]({}))\n",
                    path.replace(".png", ".svg")
                );
            }
        }
    }
}

/// A report section.
pub type Section = fn(&Experiment, &ReportContext, &mut String);

/// The sections, in order.
pub const SECTIONS: &[Section] = &[
    header,
    empirical,
    clustering,
    statistics,
    bases,
    fits,
    cross_validation,
    appearance,
    acquisition,
    lobes,
    claims,
    timings,
];

/// The whole report.
pub fn markdown(e: &Experiment, ctx: &ReportContext) -> String {
    let mut s = String::new();
    for section in SECTIONS {
        section(e, ctx, &mut s);
    }
    s
}

/// What Fig. 3's boxes, whiskers and points show (its caption here, its footer in the
/// figure).
pub const BOXPLOT_KEY: &str = "box: quartiles, bar: median; whiskers: the most extreme run within 1.5 IQR of the box (Tukey); dots: runs beyond";

/// `n` and `noun`, plural unless `n` is 1 (`1 target`, `2 targets`).
pub fn count(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

fn header(e: &Experiment, ctx: &ReportContext, s: &mut String) {
    let st = &e.settings;
    let _ = writeln!(s, "# brdf-basis reproduce\n");
    let _ = writeln!(
        s,
        "Collection: {} materials; back-end: {}; seeds {}..{}; {} runs per configuration; grid stride {}; k-medoids k = {}..{}; GCUK k = {}..{}, population {}, {} generations; empirical threshold: more than {} fits; image errors on {}x{} px renders (gamma 2.2, exposure 0, light (45, 45) deg).\n",
        st.materials, st.backend, st.seed, st.seed + st.runs as u64 - 1, st.runs, st.stride,
        st.k_min, st.k_max, st.k_min, st.gcuk_k_max, st.population, st.generations, st.more_than,
        st.render_size, st.render_size
    );
    let _ = writeln!(
        s,
        "Distances: {}.\n",
        st.metrics
            .iter()
            .map(|m| if m.lobe.is_empty() {
                format!("`{}` (raw (F0, n))", m.label)
            } else {
                format!(
                    "`{}` ({} weights, {} lobe, evaluation mask)",
                    m.label, m.weighting, m.lobe
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    );
    for n in &ctx.notes {
        let _ = writeln!(s, "> **Note.** {n}\n");
    }
}

fn empirical(e: &Experiment, ctx: &ReportContext, s: &mut String) {
    let emp = &e.empirical;
    let max = emp
        .contributors
        .values()
        .map(|v| v.len())
        .max()
        .unwrap_or(0);
    let zero = emp.counts.iter().filter(|&&c| c == 0).count();
    let _ = writeln!(s, "## Empirical selection (Algorithm 1)\n");
    let _ = writeln!(s, "Most materials used by one leave-one-out fit: {max}. Materials contributing to no fit: {zero}. Materials contributing to more than {} fits: {}.", e.settings.more_than, if emp.basis.is_empty() { "none".to_string() } else { format!("{} ({})", emp.basis.len(), emp.basis.join(", ")) });
    ctx.figure(
        s,
        "fig2-contributions",
        "Fig. 2: materials by number of fits they contribute to",
    );
}

fn clustering(e: &Experiment, ctx: &ReportContext, s: &mut String) {
    let _ = writeln!(s, "## Clustering\n\nDavies-Bouldin (DB, lower is better), silhouette (higher is better) and Dunn (higher is better) of every run; medians over the {} runs, and the best run by DB.\n", e.settings.runs);
    let _ = writeln!(s, "| metric | method | median DB | best DB | k of best | median silhouette | median Dunn |\n|---|---|---|---|---|---|---|");
    for c in &e.clustering {
        let sil: Vec<f64> = c.runs.iter().map(|r| r.silhouette).collect();
        let dunn: Vec<f64> = c.runs.iter().filter_map(|r| r.dunn).collect();
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} |",
            c.metric,
            c.method,
            num(median(&c.db_values())),
            num(c.best.db_index),
            c.best.k,
            num(median(&sil)),
            if dunn.is_empty() {
                "-".into()
            } else {
                num(median(&dunn))
            }
        );
    }
    let _ = writeln!(s, "\n### Best k by each index (k-medoids, best run per k)\n\n| metric | DB (min) | silhouette (max) | Dunn (max) | agree with DB |\n|---|---|---|---|---|");
    for m in &e.settings.metrics {
        let km: Vec<_> = e
            .clustering
            .iter()
            .filter(|c| c.metric == m.label && c.method.starts_with("kmedoids"))
            .collect();
        let pick = |f: &dyn Fn(&crate::select::ClusteringSet) -> f64| {
            km.iter()
                .map(|c| (f(c), c.best.k))
                .max_by(|a, b| a.0.total_cmp(&b.0))
                .map(|x| x.1)
        };
        let db = pick(&|c| -c.best.db_index);
        let sil = pick(&|c| {
            c.runs
                .iter()
                .map(|r| r.silhouette)
                .fold(f64::NEG_INFINITY, f64::max)
        });
        let dunn = pick(&|c| {
            c.runs
                .iter()
                .filter_map(|r| r.dunn)
                .fold(f64::NEG_INFINITY, f64::max)
        });
        let show = |k: Option<usize>| k.map_or("-".into(), |k| k.to_string());
        let agree = match (db, sil, dunn) {
            (Some(a), Some(b), Some(c)) => format!(
                "silhouette {}, Dunn {}",
                if a == b { "yes" } else { "no" },
                if a == c { "yes" } else { "no" }
            ),
            _ => "-".into(),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} |",
            m.label,
            show(db),
            show(sil),
            show(dunn),
            agree
        );
    }
    ctx.figure(
        s,
        "fig3-db-boxplots",
        &format!(
            "Fig. 3: DB index of every run, per method and metric ({})",
            BOXPLOT_KEY
        ),
    );
    ctx.figure(
        s,
        "db-vs-k",
        "DB index against k (k-medoids: every run; GCUK: every run at the k it found)",
    );
}

fn statistics(e: &Experiment, ctx: &ReportContext, s: &mut String) {
    let st = &e.statistics;
    let _ = writeln!(s, "## Statistics\n");
    for (key, f) in &st.friedman {
        let _ = writeln!(s, "**{key}** ({} methods x {} runs): chi2 = {}, p = {}; Iman-Davenport F = {}, p = {}; Nemenyi critical difference (alpha 0.05) = {}. Mean ranks: {}.\n", f.methods.len(), f.blocks, num(f.statistic), p_value(f.p_value), f.iman_davenport_f.map_or("inf".into(), num), p_value(f.iman_davenport_p), num(f.nemenyi_cd), f.methods.iter().zip(&f.mean_ranks).map(|(m, r)| format!("{m} {r:.2}")).collect::<Vec<_>>().join(", "));
        ctx.figure(
            s,
            &format!("cd-{}", key.metric()),
            &format!("Nemenyi critical-difference diagram ({})", key.metric()),
        );
    }
    if let Some(c) = &st.gcuk_euclidean_vs_brdf_it {
        let _ = writeln!(s, "**GCUK Euclidean vs GCUK BRDF_it** ({} runs, paired by run): median DB {} vs {}; Wilcoxon signed-rank W = {}, p = {} ({}); Mann-Whitney U = {}, p = {} (normal approximation with continuity correction). With {} paired runs the smallest attainable two-sided signed-rank p is {}.\n", c.runs, num(c.median_a), num(c.median_b), c.wilcoxon_w, p_value(c.wilcoxon_p), c.wilcoxon_method, c.mann_whitney_u, p_value(c.mann_whitney_p), c.runs, p_value(2.0 * 0.5f64.powi(c.runs as i32)));
    }
    for n in &st.not_computed {
        let _ = writeln!(s, "Not computed: {n}.\n");
    }
}

fn bases(e: &Experiment, _: &ReportContext, s: &mut String) {
    let _ = writeln!(s, "## Bases\n");
    for b in &e.bases {
        let same = if b.same_as.is_empty() {
            String::new()
        } else {
            format!(" (= {})", b.same_as.join(", "))
        };
        let note = b
            .note
            .as_ref()
            .map_or(String::new(), |n| format!(" Note: {n}."));
        let _ = writeln!(
            s,
            "* **{}**{same} ({}): {}.{note}",
            b.name,
            b.materials.len(),
            b.materials.join(", ")
        );
    }
}

fn fits(e: &Experiment, ctx: &ReportContext, s: &mut String) {
    let ev = &e.evaluation;
    let _ = writeln!(s, "\n## Fits of the {} in no basis\n\nEvery basis fits the same targets (the materials in none of the bases above). MAE: weighted mean |fit - target| over the evaluation mask, mean over RGB; image error: normalised mean absolute difference of {1}x{1} px sphere renders after display mapping; per material in `fit_errors.csv`.\n", count(ev.targets.len(), "material"), e.settings.render_size);
    let _ = writeln!(s, "| basis | size | mean MAE | median MAE | mean image error | median image error | {} image error |\n|---|---|---|---|---|---|---|", ev.showcase.material);
    for (b, a) in ev.errors.iter().zip(&ev.showcase.approximations) {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} |",
            b.basis,
            b.size,
            num(b.mean_mae),
            num(b.median_mae),
            num(b.mean_image_error),
            num(b.median_image_error),
            num(a.image_error)
        );
    }
    ctx.figure(
        s,
        "fig4a-mae",
        "Fig. 4a: MAE on reflectance per material, sorted by the MAE of the first basis (the same order as Fig. 4b)",
    );
    ctx.figure(
        s,
        "fig4b-image-error",
        "Fig. 4b: normalised image error per material, in the order of Fig. 4a (the MAE of the first basis)",
    );
    ctx.figure(s, "fig5-showcase", &format!("Fig. 5: {} (top: target and each basis's approximation; bottom: per-pixel error heatmaps on a common scale; `renders/` has each heatmap with its colour bar). The showcase, unless `--showcase` names one: the paper's alum-bronze when it is a target; else the analytic target with a visible body and highlight whose exponent is nearest 100; else (measured collections) the target whose display-mapped render shows most body and highlight, the largest min(median, peak - median) over the lit sphere", ev.showcase.material));
}

fn cross_validation(e: &Experiment, _: &ReportContext, s: &mut String) {
    let Some(cv) = &e.cv else {
        return;
    };
    let _ = writeln!(
        s,
        "\n## Cross-validation of the selection methods (SPEC 8)\n"
    );
    let _ = writeln!(s, "The fits above score every basis on the materials outside all bases, and the error-driven bases (greedy, swap) were chosen on those very materials. Here each method chooses its basis from the training folds only (clustering on the BRDF_it matrix restricted to them, empirical on its own leave-one-out) and every held-out material is fitted by it. rho: relative residual of the fit (SPEC 8); `cv.json` has every fold's bases and every held-out value.\n");
    s.push_str(&cv.markdown());
    s.push('\n');
}

fn acquisition(_: &Experiment, ctx: &ReportContext, s: &mut String) {
    let Some(a) = &ctx.acquisition else {
        return;
    };
    let _ = writeln!(s, "\n## Acquisition (SPEC 10)\n");
    if let Some(why) = &a.skipped {
        let _ = writeln!(s, "Not run: {why}.\n");
        return;
    }
    let _ = writeln!(s, "A new material from a few measured samples: per fold a basis chosen on the training materials, plans chosen on them (under an objective other than `l2`, weighted by how much the renders of SPEC 11 look at each cell), each held-out material measured at the plan's first n samples (simulated, `f (1 + noise N(0, 1))`), fitted from them by NNLS under the objective `{}` (error, condition, random: each sample weighted by the objective at its measured value; with fewer samples than unknowns a ridge toward the training materials' mean coefficients, and at every n a penalty on the reconstruction's energy in the highlight, their strengths chosen on the training folds) and scored on the whole evaluation mask against its own values: rho (relative residual, unweighted), MAE, the image error of its render and, in the second table, the appearance metrics of SPEC 11 (log-RMSE; image error, CIEDE2000, ΔE_ITP and FLIP on 256 x 256 renders under four lights). `nielsen` is the peer baseline (Nielsen, Jensen & Ramamoorthi 2015: log-mapped cosine-weighted PCA of every training material's channels, condition-number plan with local moves, ridge reconstruction with eta = 40), with its own reconstructor; its `dense rho` column is our basis's, for reference. Settings: {}. `acquisition.json` has every fold's basis, plan and held-out value.\n", a.cv.objective, a.settings);
    s.push_str(&a.cv.markdown());
    s.push('\n');
    for line in against_nielsen(&a.cv) {
        let _ = writeln!(s, "{line}");
    }
    let caption = match &a.cv.showcase {
        Some(sh) => format!("Acquisition: held-out mean rho against n (noise-free, log scale; dashed: the dense fit); below, held-out `{}` (fold {}, median rho at the largest n by the {} plan): target, dense fit and reconstructions from n samples", sh.material, sh.fold + 1, sh.plan.as_str()),
        None => "Acquisition: held-out mean rho against n (noise-free, log scale; dashed: the dense fit)".into(),
    };
    ctx.figure(s, "acquisition-rho", &caption);
}

/// Per n, noise-free, first method: our plan of the lowest mean four-light FLIP (the
/// lowest mean image error without appearance metrics) against `nielsen`, metric by
/// metric, in words.
fn against_nielsen(cv: &crate::acquire::AcqCv) -> Vec<String> {
    use crate::acquire::{AcqResult, Criterion};
    let first = cv
        .results
        .first()
        .map(|r| r.method.clone())
        .unwrap_or_default();
    let rows: Vec<&AcqResult> = cv
        .results
        .iter()
        .filter(|r| r.method == first && r.noise == 0.0)
        .collect();
    let key = |r: &AcqResult| r.appearance.as_ref().map_or(r.mean_image_error, |a| a.flip);
    let mut ns: Vec<usize> = rows.iter().map(|r| r.n).collect();
    ns.sort_unstable();
    ns.dedup();
    let mut out = Vec::new();
    for n in ns {
        let theirs = rows
            .iter()
            .find(|r| r.n == n && r.plan == Criterion::Nielsen);
        let ours = rows
            .iter()
            .filter(|r| r.n == n && r.plan != Criterion::Nielsen)
            .min_by(|a, b| key(a).total_cmp(&key(b)));
        let (Some(t), Some(o)) = (theirs, ours) else {
            continue;
        };
        let mut cmp = vec![
            ("rho", o.mean_rho, t.mean_rho),
            (
                "image error (64 px)",
                o.mean_image_error,
                t.mean_image_error,
            ),
        ];
        if let (Some(a), Some(b)) = (&o.appearance, &t.appearance) {
            cmp.extend([
                (
                    "image error (45, 45; 256 px)",
                    a.image_error_paper_light,
                    b.image_error_paper_light,
                ),
                (
                    "image error (4 lights; 256 px)",
                    a.image_error,
                    b.image_error,
                ),
                ("CIEDE2000", a.ciede2000, b.ciede2000),
                ("ΔE_ITP", a.delta_e_itp, b.delta_e_itp),
                ("FLIP (4 lights)", a.flip, b.flip),
            ]);
        }
        if let (Some(a), Some(b)) = (o.mean_log_rmse, t.mean_log_rmse) {
            cmp.push(("log-RMSE", a, b));
        }
        let side = |better: bool| -> Vec<String> {
            cmp.iter()
                .filter(|(_, a, b)| (a < b) == better)
                .map(|(m, a, b)| format!("{m} {} vs {}", num(*a), num(*b)))
                .collect()
        };
        let (wins, losses) = (side(true), side(false));
        let list = |v: &[String]| {
            if v.is_empty() {
                "none".to_string()
            } else {
                v.join(", ")
            }
        };
        out.push(format!(
            "* n = {n}, noise-free, our `{}` plan (our lowest mean FLIP) against `nielsen`: better on {}; not better on {}.",
            o.plan.as_str(),
            list(&wins),
            list(&losses)
        ));
    }
    out
}

fn appearance(_: &Experiment, ctx: &ReportContext, s: &mut String) {
    let Some(a) = &ctx.appearance else {
        return;
    };
    let _ = writeln!(s, "\n## Appearance (SPEC 11)\n");
    let Some(st) = &a.study else {
        let why = a.skipped.as_deref().unwrap_or("not run");
        let _ = writeln!(s, "Not run: {why}.\n");
        return;
    };
    let n = st.rows.first().map_or(0, |r| r.materials);
    let _ = writeln!(s, "The paper's fits above minimise `l2` on raw reflectance, and so do every number before this section: they reproduce the paper. Here the same model (a non-negative combination of basis materials and the Lambertian term, per channel) is fitted under each objective of SPEC 11, held out: {} folds (seed {}), per fold a {} basis of k = {} chosen on the training materials under the objective's shared weights, each of the {n} held-out materials fitted under its per-target weights (`relative`: eps {}) on a grid of stride {}. rho: the relative residual of SPEC 8 (unweighted); objective rho: under the objective's own weights; log-RMSE on the grid; image error, CIEDE2000, ΔE_ITP (ITU-R BT.2124, white at 100 cd/m²) and FLIP (67 ppd) on 256 x 256 renders under the paper's light (45, 45) and averaged over the four lights of SPEC 11. Last column: the held-out materials whose four-light FLIP is lower than under `l2`. `appearance.json` has every fold's basis and every held-out value.\n", st.folds, st.seed, st.method, st.k, st.rows.iter().find_map(|r| r.eps).map_or("-".into(), |e| e.to_string()), st.stride);
    let _ = writeln!(s, "| objective | rho | objective rho | log-RMSE | image error (45, 45) | image error (4 lights) | CIEDE2000 (4 lights) | ΔE_ITP (4 lights) | FLIP (45, 45) | FLIP (4 lights) | FLIP below l2 |\n|---|---|---|---|---|---|---|---|---|---|---|");
    for r in &st.rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.objective,
            num(r.rho),
            num(r.objective_rho),
            num(r.log_rmse),
            num(r.image_error_paper_light),
            num(r.image_error),
            num(r.ciede2000),
            num(r.delta_e_itp),
            num(r.flip_paper_light),
            num(r.flip),
            r.flip_better_than_l2
                .map_or("-".into(), |b| format!("{b} of {}", r.materials))
        );
    }
    let shown: Vec<String> = st
        .figure
        .iter()
        .map(|f| format!("`{}` ({}, fold {})", f.material, f.why, f.fold + 1))
        .collect();
    ctx.figure(s, "appearance-renders", &format!("Held-out renders: per row a material ({}); columns: the target and its fits under `l2`, `relative` and `log` by the material's fold basis, under the light (45, 45) deg, then (75, 270) deg; under each fit its FLIP against the target under that light", shown.join(", ")));
}

fn lobes(e: &Experiment, ctx: &ReportContext, s: &mut String) {
    if ctx.figures.iter().any(|f| f.0 == "lobes-showcase") {
        let _ = writeln!(s, "## Specular lobes\n\nBRDF in the plane of incidence (mean over RGB, log scale) of `{}` and its fit by each basis, at several incident angles.", e.evaluation.showcase.material);
        ctx.figure(
            s,
            "lobes-showcase",
            "Specular lobes in the plane of incidence",
        );
    }
}

fn claims(e: &Experiment, _: &ReportContext, s: &mut String) {
    let _ = writeln!(s, "## The paper's claims (section VI)\n\n| section | paper | ours | agree | why not |\n|---|---|---|---|---|");
    for c in check(e) {
        let agree = match c.agree {
            Some(true) => "yes",
            Some(false) => "no",
            None => "n/a",
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {agree} | {} |",
            c.section,
            c.paper,
            c.ours.replace('|', "/"),
            c.why
        );
    }
    s.push('\n');
}

fn timings(e: &Experiment, ctx: &ReportContext, s: &mut String) {
    let _ = writeln!(s, "## Timings\n\n| stage | seconds |\n|---|---|");
    let all: Vec<&StageTiming> = e.timings.iter().chain(&ctx.timings).collect();
    for t in &all {
        let _ = writeln!(s, "| {} | {:.2} |", t.stage, t.seconds);
    }
    let _ = writeln!(
        s,
        "| total | {:.2} |",
        all.iter().map(|t| t.seconds).sum::<f64>()
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_are_singular_for_one() {
        assert_eq!(count(1, "target"), "1 target");
        assert_eq!(count(0, "target"), "0 targets");
        assert_eq!(count(62, "material"), "62 materials");
    }
}
