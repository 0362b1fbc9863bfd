//! `brdf-basis render`.

use super::Global;
use anyhow::Context;
use brdf_basis::eval::image_error::{heatmap, normalized_image_error, DisplayParams, HeatmapScale};
use brdf_basis::eval::render::{render_sphere, RenderParams};
use brdf_basis::eval::shade::{combination_brdf, material_brdf};
use brdf_basis::experiment::files::FitFile;
use brdf_basis::io::image::{write_exr, write_png, write_rgb8_image};
use std::path::PathBuf;

/// Arguments of `render`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis render --material polished-gold --out gold.exr --png gold.png\n  brdf-basis render ../shared/data/ngan2005_ashikhmin_shirley.csv --material alum-bronze --fit fits.json --out fit.exr --png fit.png --heatmap err.png"
)]
pub struct RenderArgs {
    /// Collection(s) (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// Material to render (with --fit: the fitted combination of this target).
    #[arg(long)]
    pub material: String,
    /// A `fit` JSON: render the target's fitted combination instead of the material.
    #[arg(long)]
    pub fit: Option<PathBuf>,
    /// Output OpenEXR (linear radiance).
    #[arg(long)]
    pub out: PathBuf,
    /// Also a PNG preview (exposure, gamma).
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// With --fit: heatmap PNG of the error against the original material.
    #[arg(long)]
    pub heatmap: Option<PathBuf>,
    /// Light direction THETA,PHI in degrees.
    #[arg(long, default_value = "45,45", value_delimiter = ',', num_args = 2)]
    pub light: Vec<f64>,
    /// Exposure E (scale 2^E) for PNG and error.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub exposure: f64,
    /// Gamma for PNG and error.
    #[arg(long, default_value_t = 2.2)]
    pub gamma: f64,
    /// Image size in pixels.
    #[arg(long, default_value_t = 256)]
    pub size: u32,
}

/// Renders.
pub fn run(g: &Global, a: RenderArgs) -> anyhow::Result<()> {
    let coll = super::load_collection(&a.collection)?;
    let target = coll.index_of(&a.material)?;
    let params = RenderParams::default()
        .with_size(a.size)
        .with_light(a.light[0], a.light[1]);
    let display = DisplayParams::default()
        .with_exposure(a.exposure)
        .with_gamma(a.gamma);
    display.check()?;
    let original = render_sphere(&params, &material_brdf(&coll.materials()[target].data))?;
    let image = match &a.fit {
        None => original.clone(),
        Some(path) => {
            let file = FitFile::read(path)?;
            let (_, coef) = file.columns_of(&a.material, path)?;
            let basis: Vec<usize> = file
                .basis
                .iter()
                .map(|n| coll.index_of(n))
                .collect::<Result<_, _>>()
                .with_context(|| format!("{}: basis material", path.display()))?;
            render_sphere(&params, &combination_brdf(&coll, &basis, &coef))?
        }
    };
    write_exr(&a.out, &image)?;
    if let Some(p) = &a.png {
        write_png(p, &image, &display)?;
    }
    if a.fit.is_some() {
        let err = normalized_image_error(&original, &image, &display)?;
        if let Some(h) = &a.heatmap {
            write_rgb8_image(
                h,
                &heatmap(&original, &image, &display, HeatmapScale::MaxError)?,
            )?;
        }
        println!("normalized image error: {err:.6}");
    }
    if !g.quiet {
        eprintln!("wrote {}", a.out.display());
    }
    Ok(())
}
