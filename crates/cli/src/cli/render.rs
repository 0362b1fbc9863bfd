//! `brdf-basis render`.

use super::Global;
use anyhow::Context;
use brdf_basis::atomic::OutputPlan;
use brdf_basis::eval::image_error::{normalized_image_error, DisplayParams, HeatmapScale};
use brdf_basis::eval::render::{render_sphere, RenderParams};
use brdf_basis::eval::shade::material_brdf;
use brdf_basis::fit::file::FitFile;
use brdf_basis::io::image::{exr_bytes, png_bytes, rgb8_png_bytes};
use std::path::PathBuf;

/// Arguments of `render`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  brdf-basis render --material polished-gold --out gold.exr --png gold.png\n  brdf-basis render --material polished-gold --fit fits.json --out fit.exr --png fit.png --heatmap err.png  # fits.json from `brdf-basis fit`"
)]
pub(crate) struct RenderArgs {
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
    #[arg(long, requires = "fit")]
    pub heatmap: Option<PathBuf>,
    /// Light direction THETA,PHI in degrees (theta from the normal, in [0, 180]).
    #[arg(long, default_value = "45,45", value_name = "THETA,PHI", value_parser = parse_light)]
    pub light: (f64, f64),
    /// With --png or --fit: exposure E (scale 2^E) of the PNG, the heatmap and the error
    /// (an `Option` so that one given to an OpenEXR alone, which is linear, is refused).
    #[arg(long, allow_hyphen_values = true, help = super::with_default("With --png or --fit: exposure E (scale 2^E) of the PNG, the heatmap and the error", DisplayParams::default().exposure))]
    pub exposure: Option<f64>,
    /// With --png or --fit: gamma of the PNG, the heatmap and the error.
    #[arg(long, help = super::with_default("With --png or --fit: gamma of the PNG, the heatmap and the error", DisplayParams::default().gamma))]
    pub gamma: Option<f64>,
    /// Image size in pixels.
    #[arg(long, default_value_t = 256)]
    pub size: u32,
}

/// Parses `THETA,PHI` (degrees, finite).
fn parse_light(s: &str) -> Result<(f64, f64), String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let bad = || format!("expected THETA,PHI in degrees (e.g. 45,45), got `{s}`");
    if parts.len() != 2 {
        return Err(bad());
    }
    let t: f64 = parts[0].parse().map_err(|_| bad())?;
    let p: f64 = parts[1].parse().map_err(|_| bad())?;
    if !(t.is_finite() && p.is_finite()) {
        return Err(bad());
    }
    Ok((t, p))
}

/// Plans an output image before the work ([`OutputPlan::file`]) and checks that its
/// extension is the format written (`ext`, case-insensitive).
pub(crate) fn plan_image(
    plan: &mut OutputPlan,
    path: &std::path::Path,
    flag: &str,
    ext: &str,
) -> anyhow::Result<()> {
    let found = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    if !found.eq_ignore_ascii_case(ext) {
        anyhow::bail!(
            "{flag} {}: writes {} and its name must end in .{ext}",
            path.display(),
            if ext == "exr" { "OpenEXR" } else { "PNG" }
        );
    }
    plan.file(path, flag)?;
    Ok(())
}

/// Renders.
pub(crate) fn run(g: &Global, a: RenderArgs) -> anyhow::Result<()> {
    // The display mapping is that of the PNG and of the error against the material: the
    // OpenEXR alone is linear radiance, which would ignore it.
    if a.png.is_none() && a.fit.is_none() {
        for (given, flag) in [
            (a.exposure.is_some(), "--exposure"),
            (a.gamma.is_some(), "--gamma"),
        ] {
            if given {
                anyhow::bail!(
                    "{flag} applies to --png and --fit (the PNG preview, the heatmap and the image error), not to the OpenEXR alone, which is linear radiance: add --png or --fit, or leave it out"
                );
            }
        }
    }
    if a.heatmap.is_some() {
        // The heatmap's colour bar is labelled: an unusable BRDF_BASIS_FONT is refused now.
        crate::plot::font()?;
        if let Some(msg) = crate::plot::no_font_message() {
            eprintln!("warning: {msg}");
        }
    }
    let mut plan = OutputPlan::new(&a.collection);
    if let Some(f) = &a.fit {
        // Never open a FIFO or a device (reading one could block forever).
        let meta = std::fs::metadata(f).with_context(|| format!("--fit {}", f.display()))?;
        if !meta.is_file() {
            anyhow::bail!(
                "--fit {}: is {}, not a regular file (give the JSON written by `brdf-basis fit`)",
                f.display(),
                brdf_basis::merl::file_kind(&meta)
            );
        }
        plan.input_named(f, "fit file");
    }
    plan_image(&mut plan, &a.out, "--out", "exr")?;
    for (p, flag) in [(&a.png, "--png"), (&a.heatmap, "--heatmap")] {
        if let Some(p) = p {
            plan_image(&mut plan, p, flag, "png")?;
        }
    }
    let mut out = plan.into_set()?;
    if let Some(f) = &a.fit {
        // A fit from samples has no collection material to compare with (audit 2, T7):
        // said before the material is looked up.
        FitFile::read(f)?.refuse_samples_fit(f)?;
    }
    let coll = super::load_collection(&a.collection)?;
    let target = coll.index_of(&a.material)?;
    let params = RenderParams::default()
        .with_size(a.size)
        .with_light(a.light.0, a.light.1);
    params.check()?;
    let mut display = DisplayParams::default();
    if let Some(e) = a.exposure {
        display = display.with_exposure(e);
    }
    if let Some(gamma) = a.gamma {
        display = display.with_gamma(gamma);
    }
    display.check()?;
    let original = render_sphere(&params, &material_brdf(&coll.materials()[target].data))?;
    let image = match &a.fit {
        None => original.clone(),
        Some(path) => render_sphere(
            &params,
            &FitFile::combination_from(path, &coll, &a.material)?,
        )?,
    };
    // All outputs staged, then renamed into place together: a failure leaves none.
    let exr = exr_bytes(&a.out, &image)?;
    out.stage(&a.out, |w| w.write_all(&exr))?;
    if let Some(p) = &a.png {
        let png = png_bytes(p, &image, &display)?;
        out.stage(p, |w| w.write_all(&png))?;
    }
    let mut err = None;
    if a.fit.is_some() {
        err = Some(normalized_image_error(&original, &image, &display)?);
        if let Some(h) = &a.heatmap {
            let map = crate::plot::heatmap::heatmap_with_colour_bar(
                &original,
                &image,
                &display,
                HeatmapScale::MaxError,
            )?;
            let png = rgb8_png_bytes(h, map.width, map.height, &map.data)?;
            out.stage(h, |w| w.write_all(&png))?;
        }
    }
    out.commit()?;
    if let Some(err) = err {
        // The crate's number format: a small error is not printed as 0.000000.
        println!("normalized image error: {}", brdf_basis::stats::num(err));
    }
    let _ = g;
    for p in [Some(&a.out), a.png.as_ref(), a.heatmap.as_ref()]
        .into_iter()
        .flatten()
    {
        println!("wrote {}", p.display());
    }
    Ok(())
}
