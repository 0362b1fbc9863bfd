//! `brdf-basis reproduce`: the paper's section VI end to end.
//!
//! 1. distances (BRDF_it and Euclidean);
//! 2. empirical selection (Algorithm 1);
//! 3. k-medoids (k in [k_min, k_max], R runs each) and GCUK (R runs), both metrics, judged
//!    by the Davies-Bouldin index;
//! 4. Friedman + Nemenyi over methods, Wilcoxon and Mann-Whitney between GCUK with
//!    Euclidean and with BRDF_it;
//! 5. bases;
//! 6. NNLS fits of the materials in no basis, MAE on reflectance;
//! 7. renders and normalised image errors;
//! 8. `report.md`.

use super::select::{best, gcuk_runs, kmedoids_runs};
use super::Global;
use anyhow::Context;
use brdf_basis::cluster::GcukParams;
use brdf_basis::collection::Collection;
use brdf_basis::distance::{distance_matrix, DistanceMatrix, DistanceParams, Metric};
use brdf_basis::eval::image_error::{heatmap, normalized_image_error, DisplayParams, HeatmapScale};
use brdf_basis::eval::render::{render_sphere, RenderParams};
use brdf_basis::eval::shade::{combination_brdf, material_brdf};
use brdf_basis::fit::{fit, FitParams};
use brdf_basis::io::atomic::write_atomic;
use brdf_basis::io::image::{write_exr, write_png, write_rgb8_image};
use brdf_basis::io::json::write_json;
use brdf_basis::io::matrix::{write_csv, write_npy};
use brdf_basis::select::{empirical, EmpiricalParams};
use brdf_basis::stats;
use serde_json::{json, Value};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Arguments of `reproduce`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis reproduce --out results\n  brdf-basis reproduce ../shared/data/ngan2005_ashikhmin_shirley.csv --out paper --runs 30"
)]
pub struct ReproduceArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Runs per clustering configuration (paper: 30).
    #[arg(long, default_value_t = 30)]
    pub runs: usize,
    /// Grid stride for distances and fits (1 = full grid).
    #[arg(long, default_value_t = 1)]
    pub stride: usize,
    /// Smallest k of k-medoids and GCUK (paper: 5).
    #[arg(long, default_value_t = 5)]
    pub k_min: usize,
    /// Largest k of k-medoids (paper: 12).
    #[arg(long, default_value_t = 12)]
    pub k_max: usize,
    /// GCUK k_max (paper: 20).
    #[arg(long, default_value_t = 20)]
    pub gcuk_k_max: usize,
    /// Render size in pixels for the image errors.
    #[arg(long, default_value_t = 96)]
    pub render_size: u32,
    /// Material shown in full-size renders and heatmaps (default: alum-bronze if present,
    /// else the first evaluated material).
    #[arg(long)]
    pub showcase: Option<String>,
}

fn write_text(path: &Path, text: &str) -> anyhow::Result<()> {
    write_atomic(path, |w| w.write_all(text.as_bytes()))?;
    Ok(())
}

fn db_values(runs: &[Value]) -> Vec<f64> {
    runs.iter()
        .map(|r| r["db_index"].as_f64().unwrap_or(f64::INFINITY))
        .collect()
}

fn names_of(v: &Value) -> Vec<String> {
    serde_json::from_value(v["medoids"].clone()).unwrap_or_default()
}

/// Runs everything.
pub fn run(g: &Global, a: ReproduceArgs) -> anyhow::Result<()> {
    let coll = super::load_collection(&a.collection)?;
    let out = &a.out;
    std::fs::create_dir_all(out.join("renders")).with_context(|| format!("{}", out.display()))?;
    let backend = super::backend(g)?;
    let say = |s: &str| {
        if !g.quiet {
            eprintln!("[reproduce] {s}");
        }
    };
    let noop = |_: u64, _: u64| {};
    let mut report = String::new();
    writeln!(report, "# brdf-basis reproduce\n\nCollection: {} materials; back-end: {}; seed {}; runs {}; grid stride {}.\n", coll.len(), backend.name(), g.seed, a.runs, a.stride)?;

    // 1. Distances.
    say("distances");
    let mut dists: Vec<(Metric, DistanceMatrix)> = Vec::new();
    for metric in [Metric::BrdfIt, Metric::Euclidean] {
        let p = DistanceParams::default()
            .metric(metric)
            .stride(a.stride)
            .check(&coll)?;
        let d = distance_matrix(backend.as_ref(), &coll, &p, &noop)?;
        write_npy(&out.join(format!("distance-{metric}.npy")), &d)?;
        write_csv(&out.join(format!("distance-{metric}.csv")), &d)?;
        dists.push((metric, d));
    }

    // 2. Empirical selection.
    say("empirical selection (leave-one-out NNLS)");
    let fp = FitParams {
        stride: a.stride,
        ..Default::default()
    };
    let emp = empirical(
        backend.as_ref(),
        &coll,
        &EmpiricalParams {
            fit: fp.clone(),
            more_than: 5,
        },
        &noop,
    )?;
    write_json(
        &out.join("empirical.json"),
        &json!({"method": "empirical", "histogram": emp.histogram, "contributors": emp.contributors, "basis": emp.basis}),
    )?;
    let max_contrib = emp
        .contributors
        .values()
        .map(|v| v.len())
        .max()
        .unwrap_or(0);
    writeln!(report, "## Empirical selection (Algorithm 1)\n\nMost contributors needed by one fit: {max_contrib}. Materials contributing to more than 5 fits: {} ({}).\n", emp.basis.len(), emp.basis.join(", "))?;

    // 3. Clustering, both metrics.
    say("k-medoids and GCUK, both metrics");
    let mut db_csv = String::from("metric,method,run,seed,k,db_index,loss,medoids\n");
    let mut all_runs: Vec<(Metric, String, Vec<Value>)> = Vec::new();
    let gp = GcukParams::default().k_range(a.k_min, a.gcuk_k_max.min(coll.len() - 1));
    for (metric, d) in &dists {
        for k in a.k_min..=a.k_max.min(coll.len() - 1) {
            all_runs.push((
                *metric,
                format!("kmedoids-k{k}"),
                kmedoids_runs(d, &[k], a.runs, g.seed)?,
            ));
        }
        all_runs.push((*metric, "gcuk".into(), gcuk_runs(d, &gp, a.runs, g.seed)?));
    }
    for (metric, method, runs) in &all_runs {
        for (r, v) in runs.iter().enumerate() {
            writeln!(
                db_csv,
                "{metric},{method},{r},{},{},{},{},{}",
                v["seed"],
                v["k"],
                v["db_index"],
                v["loss"],
                names_of(v).join(";")
            )?;
        }
    }
    write_text(&out.join("clustering_db.csv"), &db_csv)?;
    write_json(&out.join("clustering.json"), &all_runs.iter().map(|(m, me, r)| json!({"metric": m.to_string(), "method": me, "runs": r, "best": best(r)})).collect::<Vec<_>>())?;

    // 4. Statistics.
    say("Friedman, Nemenyi, Wilcoxon");
    writeln!(report, "## Clustering (Davies-Bouldin index, lower is better)\n\n| metric | method | median DB | best DB | k of best |\n|---|---|---|---|---|")?;
    for (metric, method, runs) in &all_runs {
        let mut v = db_values(runs);
        v.sort_by(f64::total_cmp);
        let b = best(runs);
        writeln!(
            report,
            "| {metric} | {method} | {:.4} | {:.4} | {} |",
            v[v.len() / 2],
            v[0],
            b["k"]
        )?;
    }
    let mut stats_json = serde_json::Map::new();
    for metric in [Metric::Euclidean, Metric::BrdfIt] {
        let cols: Vec<&(Metric, String, Vec<Value>)> =
            all_runs.iter().filter(|r| r.0 == metric).collect();
        let blocks: Vec<Vec<f64>> = (0..a.runs)
            .map(|r| {
                cols.iter()
                    .map(|c| c.2[r]["db_index"].as_f64().unwrap_or(f64::INFINITY))
                    .collect()
            })
            .collect();
        match stats::friedman(&blocks) {
            Ok(f) => {
                let nem = stats::nemenyi(&f, 0.05).ok();
                writeln!(report, "\nFriedman ({metric}, {} methods x {} runs): chi2 = {:.3}, p = {:.3e}. Mean ranks: {}.", cols.len(), a.runs, f.statistic, f.p_value,
                    cols.iter().zip(&f.mean_ranks).map(|(c, r)| format!("{} {:.2}", c.1, r)).collect::<Vec<_>>().join(", "))?;
                if let Some(n) = &nem {
                    writeln!(
                        report,
                        "Nemenyi critical difference (alpha 0.05): {:.3}.",
                        n.critical_difference
                    )?;
                }
                stats_json.insert(format!("friedman-{metric}"), json!({"methods": cols.iter().map(|c| c.1.clone()).collect::<Vec<_>>(), "statistic": f.statistic, "p_value": f.p_value, "mean_ranks": f.mean_ranks, "nemenyi_cd": nem.map(|n| n.critical_difference)}));
            }
            Err(e) => writeln!(report, "\nFriedman ({metric}): not computed: {e}.")?,
        }
    }
    let ge = db_values(
        &all_runs
            .iter()
            .find(|r| r.0 == Metric::Euclidean && r.1 == "gcuk")
            .map(|r| r.2.clone())
            .unwrap_or_default(),
    );
    let gb = db_values(
        &all_runs
            .iter()
            .find(|r| r.0 == Metric::BrdfIt && r.1 == "gcuk")
            .map(|r| r.2.clone())
            .unwrap_or_default(),
    );
    match (
        stats::wilcoxon_signed_rank(&ge, &gb),
        stats::mann_whitney_u(&ge, &gb),
    ) {
        (Ok(w), Ok(u)) => {
            writeln!(report, "\nGCUK Euclidean vs GCUK BRDF_it: Wilcoxon signed-rank (paired by run) W = {}, p = {:.3e}; Mann-Whitney U = {}, p = {:.3e}. (With 30 runs the smallest attainable signed-rank p is ~1.9e-9, so the paper's p < 2.2e-16 cannot come from this test.)\n", w.statistic, w.p_value, u.u, u.p_value)?;
            stats_json.insert("gcuk-euclidean-vs-brdf-it".into(), json!({"wilcoxon_w": w.statistic, "wilcoxon_p": w.p_value, "mann_whitney_u": u.u, "mann_whitney_p": u.p_value}));
        }
        (w, u) => writeln!(
            report,
            "\nWilcoxon/Mann-Whitney not computed: {:?} {:?}",
            w.err(),
            u.err()
        )?,
    }
    write_json(&out.join("statistics.json"), &Value::Object(stats_json))?;

    // 5. Bases (BRDF_it clusterings, as the paper).
    let bi: Vec<&(Metric, String, Vec<Value>)> =
        all_runs.iter().filter(|r| r.0 == Metric::BrdfIt).collect();
    let km_all: Vec<Value> = bi
        .iter()
        .filter(|r| r.1.starts_with("kmedoids"))
        .flat_map(|r| r.2.clone())
        .collect();
    let km_max: Vec<Value> = bi
        .iter()
        .filter(|r| r.1 == format!("kmedoids-k{}", a.k_max.min(coll.len() - 1)))
        .flat_map(|r| r.2.clone())
        .collect();
    let gc: Vec<Value> = bi
        .iter()
        .filter(|r| r.1 == "gcuk")
        .flat_map(|r| r.2.clone())
        .collect();
    let kmax_gc = gc
        .iter()
        .map(|r| r["k"].as_u64().unwrap_or(0))
        .max()
        .unwrap_or(0);
    let gc_large: Vec<Value> = gc
        .iter()
        .filter(|r| r["k"].as_u64() == Some(kmax_gc))
        .cloned()
        .collect();
    let mut emp_basis = emp.basis.clone();
    if emp_basis.is_empty() {
        let mut order: Vec<usize> = (0..coll.len()).collect();
        order.sort_by_key(|&j| (std::cmp::Reverse(emp.counts[j]), j));
        emp_basis = order
            .into_iter()
            .take(a.k_min)
            .map(|j| coll.names()[j].clone())
            .collect();
    }
    let bases: Vec<(String, Vec<String>)> = vec![
        ("empirical".into(), emp_basis),
        (
            format!("kmedoids-best-k{}", best(&km_all)["k"]),
            names_of(&best(&km_all)),
        ),
        (
            format!("kmedoids-k{}", a.k_max.min(coll.len() - 1)),
            names_of(&best(&km_max)),
        ),
        (
            format!("gcuk-best-k{}", best(&gc)["k"]),
            names_of(&best(&gc)),
        ),
        (
            format!("gcuk-largest-k{kmax_gc}"),
            names_of(&best(&gc_large)),
        ),
    ];
    write_json(
        &out.join("bases.json"),
        &bases
            .iter()
            .map(|(n, b)| json!({"basis": n, "materials": b}))
            .collect::<Vec<_>>(),
    )?;
    writeln!(report, "## Bases\n")?;
    for (n, b) in &bases {
        writeln!(report, "* **{n}** ({}): {}", b.len(), b.join(", "))?;
    }

    // 6. Fits of the materials in no basis.
    let in_any: std::collections::HashSet<&String> =
        bases.iter().flat_map(|b| b.1.iter()).collect();
    let eval: Vec<usize> = (0..coll.len())
        .filter(|&i| !in_any.contains(&coll.names()[i]))
        .collect();
    writeln!(
        report,
        "\n## Fits of the {} materials in no basis\n",
        eval.len()
    )?;
    if eval.is_empty() {
        writeln!(
            report,
            "Every material is in some basis: nothing to evaluate."
        )?;
    } else {
        evaluate(
            g,
            &a,
            &coll,
            backend.as_ref(),
            &bases,
            &eval,
            &fp,
            out,
            &mut report,
        )?;
    }
    write_text(&out.join("report.md"), &report)?;
    say(&format!("wrote {}", out.join("report.md").display()));
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn evaluate(
    g: &Global,
    a: &ReproduceArgs,
    coll: &Collection,
    backend: &dyn brdf_basis::backend::Backend,
    bases: &[(String, Vec<String>)],
    eval: &[usize],
    fp: &FitParams,
    out: &Path,
    report: &mut String,
) -> anyhow::Result<()> {
    let display = DisplayParams::default();
    let small = RenderParams::default()
        .with_size(a.render_size)
        .with_light(45.0, 45.0);
    let originals: Vec<_> = eval
        .iter()
        .map(|&t| render_sphere(&small, &material_brdf(&coll.materials()[t].data)))
        .collect::<Result<_, _>>()?;
    let showcase = a
        .showcase
        .clone()
        .filter(|s| coll.index_of(s).is_ok())
        .unwrap_or_else(|| {
            if eval.iter().any(|&t| coll.names()[t] == "alum-bronze") {
                "alum-bronze".into()
            } else {
                coll.names()[eval[0]].clone()
            }
        });
    let big = RenderParams::default()
        .with_size(256)
        .with_light(45.0, 45.0);
    let show_idx = coll.index_of(&showcase)?;
    let show_orig = render_sphere(&big, &material_brdf(&coll.materials()[show_idx].data))?;
    write_exr(
        out.join("renders").join(format!("{showcase}-original.exr")),
        &show_orig,
    )?;
    write_png(
        out.join("renders").join(format!("{showcase}-original.png")),
        &show_orig,
        &display,
    )?;
    let mut csv = String::from("material");
    for (n, _) in bases {
        write!(csv, ",mae-{n},image-error-{n}")?;
    }
    csv.push('\n');
    let mut table = vec![vec![(0.0, 0.0); bases.len()]; eval.len()];
    writeln!(report, "| basis | size | mean MAE | median MAE | mean image error | {showcase} image error |\n|---|---|---|---|---|---|")?;
    for (bi, (name, names)) in bases.iter().enumerate() {
        if !g.quiet {
            eprintln!("[reproduce] fitting {} materials with {name}", eval.len());
        }
        let basis: Vec<usize> = names
            .iter()
            .map(|n| coll.index_of(n))
            .collect::<Result<_, _>>()?;
        let fits = fit(backend, coll, &basis, eval, fp, &|_, _| {})?;
        write_json(
            &out.join(format!("fit-{name}.json")),
            &super::fit::fits_json(coll, &basis, &fits, fp),
        )?;
        let mut show_err = f64::NAN;
        for (ti, f) in fits.iter().enumerate() {
            let img = render_sphere(&small, &combination_brdf(coll, &basis, &f.coefficients))?;
            let e = normalized_image_error(&originals[ti], &img, &display)?;
            table[ti][bi] = (f.mae, e);
            if eval[ti] == show_idx {
                let bigf = render_sphere(&big, &combination_brdf(coll, &basis, &f.coefficients))?;
                show_err = normalized_image_error(&show_orig, &bigf, &display)?;
                write_exr(
                    out.join("renders").join(format!("{showcase}-{name}.exr")),
                    &bigf,
                )?;
                write_png(
                    out.join("renders").join(format!("{showcase}-{name}.png")),
                    &bigf,
                    &display,
                )?;
                write_rgb8_image(
                    out.join("renders")
                        .join(format!("{showcase}-{name}-heatmap.png")),
                    &heatmap(&show_orig, &bigf, &display, HeatmapScale::Fixed(0.25))?,
                )?;
            }
        }
        let mut maes: Vec<f64> = fits.iter().map(|f| f.mae).collect();
        let mean_img = table.iter().map(|r| r[bi].1).sum::<f64>() / eval.len() as f64;
        let mean_mae = maes.iter().sum::<f64>() / maes.len() as f64;
        maes.sort_by(f64::total_cmp);
        writeln!(
            report,
            "| {name} | {} | {mean_mae:.4e} | {:.4e} | {mean_img:.4} | {show_err:.4} |",
            basis.len(),
            maes[maes.len() / 2]
        )?;
    }
    for (ti, &t) in eval.iter().enumerate() {
        csv.push_str(&coll.names()[t]);
        for (m, e) in &table[ti] {
            write!(csv, ",{m:e},{e:e}")?;
        }
        csv.push('\n');
    }
    write_text(&out.join("fit_errors.csv"), &csv)?;
    writeln!(report, "\nPer-material MAE (reflectance, evaluation mask) and normalised image errors (gamma 2.2, exposure 0, light (45, 45), {0}x{0} px): `fit_errors.csv`. Renders of `{showcase}`: `renders/`.", a.render_size)?;
    Ok(())
}
