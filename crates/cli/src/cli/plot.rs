//! `brdf-basis plot`: specular-lobe polar plots of a material and its fits; and the
//! writing of `reproduce`'s figures.

use super::Global;
use crate::plot::report::report_figures;
use crate::plot::{font, lobes, no_font_message, Figure};
use brdf_basis::atomic::{write_atomic, OutputPlan};
use brdf_basis::eval::shade::material_brdf;
use brdf_basis::experiment::report::ReportContext;
use brdf_basis::experiment::Experiment;
use brdf_basis::fit::file::FitFile;
use brdf_basis::io::image::{rgb8_png_bytes, write_rgb8_image};
use std::path::{Path, PathBuf};

/// Arguments of `plot`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis plot --material polished-gold --out gold-lobes.svg\n  brdf-basis fit --basis mirror-silver,matte-white-paint --targets polished-gold --json f.json\n  brdf-basis plot --material polished-gold --fit f.json --out gold-lobes.png --angles 0,45,70"
)]
pub(crate) struct PlotArgs {
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
pub(crate) fn write_figure(dir: &Path, fig: &Figure) -> anyhow::Result<(PathBuf, PathBuf)> {
    let svg = dir.join(format!("{}.svg", fig.stem));
    let png = dir.join(format!("{}.png", fig.stem));
    write_atomic(&svg, |w| w.write_all(fig.svg.as_bytes()))?;
    write_rgb8_image(&png, &fig.png)?;
    Ok((svg, png))
}

/// Draws and writes every figure of the report into `dir`, listing them in `ctx` (the
/// figure set is the library's [`report_figures`]).
pub(crate) fn write_report_figures(
    e: &Experiment,
    dir: &Path,
    ctx: &mut ReportContext,
) -> anyhow::Result<()> {
    let set = report_figures(e)?;
    for msg in set.notes {
        eprintln!("warning: {msg}");
        ctx.notes.push(msg);
    }
    for f in &set.figures {
        write_figure(dir, f)?;
        let rel = format!("figures/{}.png", f.stem);
        ctx.figures.push((f.stem.clone(), rel));
    }
    Ok(())
}

/// Runs `plot`.
pub(crate) fn run(g: &Global, a: PlotArgs) -> anyhow::Result<()> {
    font()?; // an unusable BRDF_BASIS_FONT is refused before any work
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
    for f in &a.fit {
        // A fit from samples has no collection material to compare with (audit 2, T7).
        FitFile::read(f)?.refuse_samples_fit(f)?;
    }
    let coll = super::load_collection(&a.collection)?;
    let idx = coll.index_of(&a.material)?;
    let mut curves = vec![(
        a.material.clone(),
        material_brdf(&coll.materials()[idx].data),
    )];
    for path in &a.fit {
        let brdf = FitFile::combination_from(path, &coll, &a.material)?;
        let label = format!(
            "fit by {}",
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        );
        curves.push((label, brdf));
    }
    if let Some(msg) = no_font_message() {
        eprintln!("warning: {msg}");
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
    for msg in &fig.notes {
        eprintln!("warning: {msg}");
    }
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
