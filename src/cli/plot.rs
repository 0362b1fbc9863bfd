//! `brdf-basis plot`: specular-lobe polar plots of a material and its fits; and the
//! writing of `reproduce`'s figures.

use super::Global;
use anyhow::Context;
use brdf_basis::eval::image_error::DisplayParams;
use brdf_basis::eval::shade::{combination_brdf, material_brdf, BrdfFn};
use brdf_basis::experiment::files::FitFile;
use brdf_basis::experiment::report::ReportContext;
use brdf_basis::experiment::Experiment;
use brdf_basis::atomic::{write_atomic, OutputPlan};
use brdf_basis::io::image::{rgb8_png_bytes, write_rgb8_image};
use brdf_basis::plot::{charts, font_available, lobes, showcase, Figure};
use std::path::{Path, PathBuf};

/// Arguments of `plot`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis plot --material polished-gold --out gold-lobes.svg\n  brdf-basis fit --basis mirror-silver,matte-white-paint --targets polished-gold --json f.json\n  brdf-basis plot --material polished-gold --fit f.json --out gold-lobes.png --angles 0,45,70"
)]
pub struct PlotArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// Material to plot.
    #[arg(long)]
    pub material: String,
    /// `fit` JSON files: also plot the material's fitted combination from each.
    #[arg(long)]
    pub fit: Vec<PathBuf>,
    /// Output file, .svg or .png.
    #[arg(long)]
    pub out: PathBuf,
    /// Incident angles in degrees (0 to 89).
    #[arg(long, value_delimiter = ',', default_value = "0,30,60,75")]
    pub angles: Vec<f64>,
}

/// Writes `fig` as `dir/<stem>.svg` and `.png`.
pub fn write_figure(dir: &Path, fig: &Figure) -> anyhow::Result<(PathBuf, PathBuf)> {
    let svg = dir.join(format!("{}.svg", fig.stem));
    let png = dir.join(format!("{}.png", fig.stem));
    write_atomic(&svg, |w| w.write_all(fig.svg.as_bytes()))?;
    write_rgb8_image(&png, &fig.png)?;
    Ok((svg, png))
}

/// The lobe curves of the showcase: the material, then its fit by each basis.
pub fn showcase_curves(e: &Experiment) -> anyhow::Result<Vec<(String, BrdfFn)>> {
    let coll = &e.collection;
    let s = &e.evaluation.showcase;
    let mut curves = vec![(
        s.material.clone(),
        material_brdf(&coll.get(&s.material)?.data),
    )];
    for ((name, fit, _, _), b) in s.approximations.iter().zip(&e.bases) {
        let idx: Vec<usize> = b
            .materials
            .iter()
            .map(|m| coll.index_of(m))
            .collect::<Result<_, _>>()?;
        let cols = fit
            .columns(&b.materials)
            .map_err(|m| anyhow::anyhow!("no coefficient for `{m}`"))?;
        curves.push((name.clone(), combination_brdf(coll, &idx, &cols)));
    }
    Ok(curves)
}

/// Draws and writes every figure of the report into `dir`, listing them in `ctx`.
pub fn write_report_figures(
    e: &Experiment,
    dir: &Path,
    ctx: &mut ReportContext,
) -> anyhow::Result<()> {
    let text = font_available().is_some();
    if !text {
        let msg = format!(
            "no font found (looked for {}; set BRDF_BASIS_FONT to a .ttf file): the figures have no text (labels, legends, colour-bar values)",
            brdf_basis::plot::FONT_PATHS[0]
        );
        eprintln!("warning: {msg}");
        ctx.notes.push(msg);
    }
    let metrics: Vec<String> = e.settings.metrics.iter().map(|m| m.label.clone()).collect();
    let mut figs = vec![
        charts::histogram(&e.empirical.counts)?,
        charts::db_boxplots(&metrics, &e.clustering)?,
        charts::db_vs_k(&metrics, &e.clustering)?,
        charts::errors_per_material(&e.evaluation.errors, true)?,
        charts::errors_per_material(&e.evaluation.errors, false)?,
        showcase::showcase_figure(&e.evaluation.showcase, &DisplayParams::default(), text)?,
        lobes::lobe_plot(
            "lobes-showcase",
            &format!(
                "{}: BRDF in the plane of incidence (mean RGB, log radius, 4 decades) and its fits",
                e.evaluation.showcase.material
            ),
            &showcase_curves(e)?,
            &[0.0, 30.0, 60.0, 75.0],
        )?,
    ];
    for (key, f) in &e.statistics.friedman {
        figs.push(charts::cd_diagram(key.trim_start_matches("friedman-"), f)?);
    }
    for f in &figs {
        write_figure(dir, f)?;
        let rel = format!("figures/{}.png", f.stem);
        ctx.figures.push((f.stem.clone(), rel));
    }
    Ok(())
}

/// Runs `plot`.
pub fn run(g: &Global, a: PlotArgs) -> anyhow::Result<()> {
    if let Some(bad) = a.angles.iter().find(|t| !(0.0..90.0).contains(*t)) {
        anyhow::bail!("--angles: {bad} is not an incident angle in [0, 90) degrees");
    }
    let ext = super::extension(&a.out);
    if ext != "svg" && ext != "png" {
        anyhow::bail!("--out {}: give a .svg or .png file name", a.out.display());
    }
    let mut plan = OutputPlan::new(&a.collection);
    for f in &a.fit {
        plan.input_named(f, "fit file");
    }
    plan.file(&a.out, "--out")?;
    let mut out = plan.into_set()?;
    let coll = super::load_collection(&a.collection)?;
    let idx = coll.index_of(&a.material)?;
    let mut curves = vec![(
        a.material.clone(),
        material_brdf(&coll.materials()[idx].data),
    )];
    for path in &a.fit {
        let file = FitFile::read(path)?;
        let (_, cols) = file.columns_of(&a.material, path)?;
        let basis: Vec<usize> = file
            .basis
            .iter()
            .map(|n| coll.index_of(n))
            .collect::<Result<_, _>>()
            .with_context(|| format!("{}: basis material", path.display()))?;
        let label = format!(
            "fit by {}",
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        );
        curves.push((label, combination_brdf(&coll, &basis, &cols)));
    }
    if font_available().is_none() {
        eprintln!(
            "warning: no font found: the plot has no text (set BRDF_BASIS_FONT to a .ttf file)"
        );
    }
    let fig = lobes::lobe_plot(
        "lobes",
        &format!(
            "{}: BRDF in the plane of incidence (mean RGB, log radius)",
            a.material
        ),
        &curves,
        &a.angles,
    )?;
    if ext == "svg" {
        out.stage(&a.out, |w| w.write_all(fig.svg.as_bytes()))?;
    } else {
        let png = rgb8_png_bytes(&a.out, fig.png.width, fig.png.height, &fig.png.data)?;
        out.stage(&a.out, |w| w.write_all(&png))?;
    }
    out.commit()?;
    let _ = g;
    println!("wrote {}", a.out.display());
    Ok(())
}
