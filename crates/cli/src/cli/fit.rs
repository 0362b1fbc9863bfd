//! `brdf-basis fit`.

use super::Global;
use brdf_basis::atomic::OutputPlan;
use brdf_basis::fit::diagnostics::MAX_WARNINGS;
use brdf_basis::fit::export::{
    combination_grid, export_file_names, export_index_csv, EXPORT_INDEX,
};
use brdf_basis::fit::FitParams;
use brdf_basis::merl::write_binary_to;
use brdf_basis::run::{Ctx, FitRequest, FitSamplesRequest, FitTargets, Request};
use std::path::{Path, PathBuf};

/// Arguments of `fit`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis fit --basis gloss-white-enamel,gloss-black-enamel,polished-brass --targets gloss-red-enamel,polished-gold,polished-copper --json fits.json --export fitted/\n  brdf-basis fit ngan2005_ashikhmin_shirley.csv --basis blue-acrylic,acrylic-yellow,alumina-oxide,cherry-235,steel --all-others --json ngan-fits.json"
)]
pub(crate) struct FitArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// Basis materials, comma-separated.
    #[arg(long, value_delimiter = ',', required = true)]
    pub basis: Vec<String>,
    /// Target materials, comma-separated.
    #[arg(long, value_delimiter = ',', conflicts_with = "all_others")]
    pub targets: Vec<String>,
    /// Fit every material not in the basis.
    #[arg(long)]
    pub all_others: bool,
    /// Grid cells and weights.
    #[command(flatten)]
    pub grid: super::GridArgs,
    /// NNLS solver.
    #[arg(long, value_enum, default_value_t = FitParams::default().solver.into())]
    pub solver: super::values::SolverArg,
    /// How Gram matrices are computed.
    #[arg(long, value_enum, default_value_t = FitParams::default().gram.into())]
    pub gram: super::values::GramArg,
    /// The fit objective.
    #[command(flatten)]
    pub objective: super::ObjectiveArgs,
    /// Skip the appearance metrics (log-RMSE; image error, CIEDE2000 and FLIP of renders
    /// under four lights) that are otherwise computed for every fit.
    #[arg(long)]
    pub no_appearance: bool,
    /// Output JSON.
    #[arg(long)]
    pub json: PathBuf,
    /// Also write each fitted combination as a MERL .binary file in DIR, named after the
    /// target (sanitised: letters, digits, `-`, `_`, `.`; made unique), with DIR/index.csv
    /// mapping material names to files.
    #[arg(long)]
    pub export: Option<PathBuf>,
    /// Fit a new material from its measured samples (SPEC 10) instead of collection
    /// materials: a CSV `theta_i,phi_i,theta_o,phi_o,r,g,b[,sigma | ,sigma_r,sigma_g,sigma_b]`
    /// (degrees) or an ASTM E1392 `.astm` file; the target is named after the file's stem.
    /// --stride, --mask, --weighting, --solver and --gram do not apply (refused).
    #[arg(long, conflicts_with_all = ["targets", "all_others"])]
    pub samples: Option<PathBuf>,
}

impl FitArgs {
    /// The request these flags make (`fit` without `--samples`): neither `--targets` nor
    /// `--all-others` is an empty target list, which the request refuses.
    pub(crate) fn request(&self) -> anyhow::Result<FitRequest> {
        let mut r = FitRequest::new(self.basis.clone());
        r.targets = if self.all_others {
            FitTargets::AllOthers
        } else {
            FitTargets::Named(self.targets.clone())
        };
        r.grid = self.grid.grid()?;
        r.solver = self.solver.into();
        r.gram = self.gram.into();
        r.objective = self.objective.setting();
        r.appearance = !self.no_appearance;
        Ok(r)
    }
}

impl FitArgs {
    /// The request these flags make with `--samples`.
    pub(crate) fn samples_request(&self, g: &Global) -> anyhow::Result<FitSamplesRequest> {
        let path = self
            .samples
            .clone()
            .expect("samples_request is called with --samples");
        let mut r = FitSamplesRequest::new(self.basis.clone(), path);
        r.grid = self.grid.grid()?;
        r.solver = self.solver.into();
        r.gram = self.gram.into();
        r.seed = g.seed_or(r.seed);
        r.objective = self.objective.setting();
        Ok(r)
    }
}

/// Runs the fits.
pub(crate) fn run(g: &Global, a: FitArgs) -> anyhow::Result<()> {
    if a.samples.is_some() {
        return run_samples(g, a);
    }
    let req = a.request()?;
    req.check()?;
    // Output paths before the work: a typo costs no computation.
    let mut plan = OutputPlan::new(&a.collection);
    plan.file(&a.json, "--json")?;
    let coll = super::load_collection(&a.collection)?;
    let (_, targets) = req.indices(&coll)?;
    let mut removed = Vec::new();
    if let Some(dir) = &a.export {
        let names: Vec<&str> = targets
            .iter()
            .map(|&t| coll.materials()[t].name.as_str())
            .collect();
        removed = plan_export(&mut plan, dir, &export_file_names(&names))?;
    }
    let mut out = plan.into_set()?;
    let backend = super::backend(g)?;
    let pb = super::progress_bar(g, 1, "gram");
    let fitted = req.run(&Ctx::new(backend.as_ref(), &coll).progress(&|d, t| {
        pb.set_length(t);
        pb.set_position(d);
    }))?;
    pb.finish_and_clear();
    let (basis, fits) = (&fitted.basis, &fitted.fits);
    let warnings = &fitted.warnings;
    for w in warnings.iter().take(MAX_WARNINGS) {
        eprintln!("warning: {w}");
    }
    if warnings.len() > MAX_WARNINGS {
        eprintln!(
            "warning: ... and {} more targets this basis cannot represent",
            warnings.len() - MAX_WARNINGS
        );
    }
    // Every file is staged and renamed into place only when all are written: a failed
    // export leaves neither the JSON nor the other exports (nor a created directory).
    let names: Vec<&str> = fits.iter().map(|f| f.material.as_str()).collect();
    let files = export_file_names(&names);
    if let Some(dir) = &a.export {
        for (f, file) in fits.iter().zip(&files) {
            let rgb = combination_grid(&coll, basis, f);
            out.stage(&dir.join(file), |w| write_binary_to(w, &rgb))?;
        }
        let index = export_index_csv(&names, &files)?;
        out.stage(&dir.join(EXPORT_INDEX), |w| w.write_all(&index))?;
        if !g.quiet {
            for (n, file) in names.iter().zip(&files) {
                if format!("{n}.binary") != *file {
                    eprintln!("export: `{}` -> {file}", brdf_basis::error::short_name(n));
                }
            }
        }
    }
    let text = serde_json::to_string_pretty(&fitted.file)?;
    out.stage(&a.json, |w| {
        w.write_all(text.as_bytes())?;
        w.write_all(b"\n")
    })?;
    out.commit()?;
    println!("{}", summary(&a.json, fits));
    if let Some(line) = appearance_summary(&fitted.appearance) {
        println!("{line}");
    }
    print_export(a.export.as_deref(), &files, &removed);
    Ok(())
}

/// The lines of an export: every file written, then every file of an earlier export
/// that this one removed (audit 2, U10: they went silently).
fn print_export(dir: Option<&Path>, files: &[String], removed: &[String]) {
    let Some(dir) = dir else { return };
    for file in files.iter().map(String::as_str).chain([EXPORT_INDEX]) {
        println!("wrote {}", dir.join(file).display());
    }
    for file in removed {
        println!(
            "removed {} (listed by the earlier export's {EXPORT_INDEX}; this export does not write it)",
            dir.join(file).display()
        );
    }
}

/// `wrote FILE (N targets, mean MAE .., mean relative residual .., mean relative MAE ..)`,
/// in the crate's number format ([`brdf_basis::stats::num`]).
fn summary(json: &Path, fits: &[brdf_basis::fit::TargetFit]) -> String {
    let mean_of = |v: fn(&brdf_basis::fit::TargetFit) -> f64| {
        brdf_basis::stats::num(brdf_basis::stats::mean(
            &fits.iter().map(v).collect::<Vec<_>>(),
        ))
    };
    format!(
        "wrote {} ({} target{}, mean MAE {}, mean relative residual {}, mean relative MAE {})",
        json.display(),
        fits.len(),
        if fits.len() == 1 { "" } else { "s" },
        mean_of(|f| f.mae),
        mean_of(|f| f.relative_residual),
        mean_of(|f| f.relative_mae)
    )
}

/// `appearance: mean log-RMSE .., under the four lights mean image error .., CIEDE2000 ..,
/// FLIP ..` (`None` without appearance metrics).
fn appearance_summary(a: &[brdf_basis::eval::appearance::Appearance]) -> Option<String> {
    use brdf_basis::eval::appearance::Appearance;
    if a.is_empty() {
        return None;
    }
    let mean_of = |v: fn(&Appearance) -> f64| {
        brdf_basis::stats::num(brdf_basis::stats::mean(
            &a.iter().map(v).collect::<Vec<_>>(),
        ))
    };
    Some(format!(
        "appearance: mean log-RMSE {}; under the four lights mean image error {}, CIEDE2000 {}, ΔE_ITP {}, FLIP {} (paper's light: image error {}, FLIP {})",
        mean_of(|x| x.log_rmse),
        mean_of(|x| x.mean_image_error),
        mean_of(|x| x.mean_ciede2000),
        mean_of(|x| x.mean_delta_e_itp),
        mean_of(|x| x.mean_flip),
        mean_of(|x| x.paper_light().image_error),
        mean_of(|x| x.paper_light().flip),
    ))
}

/// Plans `--export DIR` with the export file names `files`: DIR (created if missing),
/// its `index.csv` and the `.binary` files. DIR may hold an earlier export: its index
/// and the files that index lists are ours and replaced, and the listed files this
/// export does not write are removed at commit (no stale material survives; returned, to
/// be printed). Any other file of a name this export writes is refused, never replaced.
fn plan_export(plan: &mut OutputPlan, dir: &Path, files: &[String]) -> anyhow::Result<Vec<String>> {
    plan.dir(dir, "--export")?;
    let index = dir.join(EXPORT_INDEX);
    let earlier = if index.is_file() {
        read_export_index(&index)
    } else {
        None
    };
    plan.owned_file(
        &index,
        "--export",
        "file index written by `fit --export` (header `material,file`)",
        |p| read_export_index(p).is_some(),
    )?;
    let owned = earlier.unwrap_or_default();
    for f in files {
        plan.owned_file(
            &dir.join(f),
            "--export",
            "fitted material listed in the index.csv of an earlier export",
            |_| owned.contains(f),
        )?;
    }
    let mut removed = Vec::new();
    for stale in owned.iter().filter(|f| !files.contains(f)) {
        plan.remove(&dir.join(stale), "--export")?;
        removed.push(stale.clone());
    }
    Ok(removed)
}

/// The files an export index lists, when `path` is one (`material,file` header, plain
/// `.binary` file names, at most 64 MiB read); `None` otherwise.
fn read_export_index(path: &Path) -> Option<Vec<String>> {
    use std::io::Read;
    let mut text = Vec::new();
    std::fs::File::open(path)
        .ok()?
        .take(64 << 20)
        .read_to_end(&mut text)
        .ok()?;
    let mut r = csv::Reader::from_reader(text.as_slice());
    if r.headers().ok()?.iter().collect::<Vec<_>>() != ["material", "file"] {
        return None;
    }
    let mut files = Vec::new();
    for rec in r.records() {
        let rec = rec.ok()?;
        let f = rec.get(1)?;
        let plain = !f.is_empty()
            && !f.starts_with('.')
            && f.ends_with(".binary")
            && !f.contains(['/', '\\']);
        if !plain {
            return None;
        }
        files.push(f.to_string());
    }
    Some(files)
}

/// `fit --samples`: the material of a samples file fitted by the basis (SPEC 10), its
/// JSON (the `fit` schema with `samples` and `fitted_from`; residual and MAE on the
/// samples) and, with `--export`, the whole reconstruction as a MERL `.binary`.
fn run_samples(g: &Global, a: FitArgs) -> anyhow::Result<()> {
    let req = a.samples_request(g)?;
    req.check()?;
    // The grid fit's flags (--stride, --mask, ...) are refused by the request's check;
    // --no-appearance is the command line's own (audit 3, U6: accepted silently before;
    // the fit from samples scores no render).
    if a.no_appearance {
        anyhow::bail!(
            "--no-appearance does not apply with --samples: the fit from samples solves a least-squares problem over the measured samples alone (no grid cells, no Gram matrix, its own NNLS, no appearance metrics); leave it out"
        );
    }
    let mut out_plan = OutputPlan::new(&a.collection);
    for (path, noun) in req.input_files() {
        out_plan.input_named(&path, noun);
    }
    out_plan.file(&a.json, "--json")?;
    let stem = req.target_name();
    let files = export_file_names(&[stem.as_str()]);
    let mut removed = Vec::new();
    if let Some(dir) = &a.export {
        removed = plan_export(&mut out_plan, dir, &files)?;
    }
    let mut out = out_plan.into_set()?;
    let coll = super::load_collection(&a.collection)?;
    let fitted = req.run(&Ctx::collection(&coll))?;
    for w in &fitted.warnings {
        eprintln!("warning: {w}");
    }
    let (basis, tf, d) = (&fitted.basis, &fitted.target, &fitted.fit.determination);
    if let Some(dir) = &a.export {
        let rgb = combination_grid(&coll, basis, tf);
        out.stage(&dir.join(&files[0]), |w| write_binary_to(w, &rgb))?;
        let index = export_index_csv(&[stem.as_str()], &files)?;
        out.stage(&dir.join(EXPORT_INDEX), |w| w.write_all(&index))?;
    }
    let text = serde_json::to_string_pretty(&fitted.file)?;
    out.stage(&a.json, |w| {
        w.write_all(text.as_bytes())?;
        w.write_all(b"\n")
    })?;
    out.commit()?;
    println!(
        "wrote {} ({}, rank {} of {}, condition number {}, relative residual on the samples {})",
        a.json.display(),
        brdf_basis::error::plural(fitted.samples, "sample", "samples"),
        d.rank,
        d.columns,
        brdf_basis::stats::num(d.condition),
        brdf_basis::stats::num(fitted.fit.relative_residual)
    );
    print_export(a.export.as_deref(), &files, &removed);
    Ok(())
}
