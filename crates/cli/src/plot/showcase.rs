//! Fig. 5 as one picture: the target and each basis's approximation (top row), their
//! per-pixel error heatmaps on one common scale (bottom row) with a colour bar.
//!
//! The PNG holds the tiles as pixels; the SVG draws frames and text as vectors and embeds
//! the tiles as PNG images (`data:` URIs), so it stays small.

use super::{e2s, series_colour, Figure, PlotError};
use brdf_basis::eval::image_error::{
    display_image, heatmap, pixel_errors, viridis, DisplayParams, HeatmapScale, Rgb8Image,
};
use brdf_basis::experiment::evaluation::Showcase;
use plotters::coord::Shift;
use plotters::prelude::*;

const FONT: &str = "sans-serif";
const TILE: u32 = 128;
const PAD: u32 = 14;
const HEAD: u32 = 40;
const LABEL: u32 = 34;

/// The common heatmap scale: the largest per-pixel error over every approximation (at
/// least 1e-6), rounded up to two significant digits.
pub(crate) fn common_scale(s: &Showcase, display: &DisplayParams) -> Result<f64, PlotError> {
    let mut max = 1e-6f64;
    for a in &s.approximations {
        let e = pixel_errors(&s.original, &a.image, display).map_err(|e| PlotError::Draw {
            stem: "fig5-showcase".into(),
            message: e.to_string(),
        })?;
        max = e.into_iter().fold(max, f64::max);
    }
    let mag = 10f64.powf(max.log10().floor() - 1.0);
    Ok((max / mag).ceil() * mag)
}

/// Halves an image by 2 x 2 box filtering until it is at most `TILE` wide.
fn shrink(img: &Rgb8Image) -> Rgb8Image {
    let mut cur = img.clone();
    while cur.width > TILE && cur.height >= 2 {
        let (w, h) = (cur.width / 2, cur.height / 2);
        let mut data = Vec::with_capacity(3 * (w * h) as usize);
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    let at = |dx: u32, dy: u32| {
                        cur.data[(3 * ((2 * y + dy) * cur.width + 2 * x + dx) + c) as usize] as u32
                    };
                    data.push(((at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1) + 2) / 4) as u8);
                }
            }
        }
        cur = Rgb8Image {
            width: w,
            height: h,
            data,
        };
    }
    cur
}

fn base64(bytes: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            if i <= c.len() {
                s.push(T[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

fn png_bytes(img: &Rgb8Image) -> Vec<u8> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    let _ = image::codecs::png::PngEncoder::new(&mut out).write_image(
        &img.data,
        img.width,
        img.height,
        image::ExtendedColorType::Rgb8,
    );
    out
}

struct Layout {
    tiles: Vec<(String, Rgb8Image, String)>,
    heat: Vec<Rgb8Image>,
    scale: f64,
    title: String,
}

impl Layout {
    fn size(&self) -> (u32, u32) {
        let cols = self.tiles.len() as u32;
        (
            PAD + cols * (TILE + PAD) + 70,
            HEAD + 2 * (LABEL + TILE + PAD) + 20,
        )
    }
    fn origin(&self, col: usize, row: u32) -> (i32, i32) {
        (
            (PAD + col as u32 * (TILE + PAD)) as i32,
            (HEAD + LABEL + row * (LABEL + TILE + PAD)) as i32,
        )
    }
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        text: bool,
        raster: bool,
    ) -> Result<(), String> {
        if text {
            root.draw(&Text::new(
                self.title.clone(),
                (PAD as i32, 10),
                (FONT, 17).into_font(),
            ))
            .map_err(e2s)?;
        }
        for (col, (name, img, err)) in self.tiles.iter().enumerate() {
            let (x, y) = self.origin(col, 0);
            if text {
                let c = if col == 0 {
                    BLACK
                } else {
                    series_colour(col - 1)
                };
                root.draw(&Text::new(
                    name.clone(),
                    (x, y - 30),
                    (FONT, 12).into_font().color(&c),
                ))
                .map_err(e2s)?;
                root.draw(&Text::new(err.clone(), (x, y - 15), (FONT, 11).into_font()))
                    .map_err(e2s)?;
            }
            if raster {
                blit(root, img, x, y)?;
                if col > 0 {
                    let (hx, hy) = self.origin(col, 1);
                    blit(root, &self.heat[col - 1], hx, hy)?;
                }
            }
        }
        // Colour bar in the first cell of the heatmap row.
        let (x, y) = self.origin(0, 1);
        let (bw, bh) = (24i32, TILE as i32);
        for r in 0..bh {
            let t = 1.0 - r as f64 / (bh - 1) as f64;
            let [cr, cg, cb] = viridis(t).map(|v| (v * 255.0).round() as u8);
            root.draw(&Rectangle::new(
                [(x + 40, y + r), (x + 40 + bw, y + r + 1)],
                RGBColor(cr, cg, cb).filled(),
            ))
            .map_err(e2s)?;
        }
        root.draw(&Rectangle::new(
            [(x + 40, y), (x + 40 + bw, y + bh)],
            BLACK.stroke_width(1),
        ))
        .map_err(e2s)?;
        if text {
            let f = (FONT, 11).into_font();
            root.draw(&Text::new(
                format!("{:.3}", self.scale),
                (x + 70, y - 4),
                f.clone(),
            ))
            .map_err(e2s)?;
            root.draw(&Text::new(
                format!("{:.3}", self.scale / 2.0),
                (x + 70, y + bh / 2 - 6),
                f.clone(),
            ))
            .map_err(e2s)?;
            root.draw(&Text::new("0", (x + 70, y + bh - 10), f.clone()))
                .map_err(e2s)?;
            root.draw(&Text::new("per-pixel", (x - 2, y - 30), f.clone()))
                .map_err(e2s)?;
            root.draw(&Text::new("|error|", (x - 2, y - 16), f))
                .map_err(e2s)?;
        }
        Ok(())
    }
}

fn blit<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    img: &Rgb8Image,
    x: i32,
    y: i32,
) -> Result<(), String> {
    for (i, p) in img.data.chunks_exact(3).enumerate() {
        let (px, py) = ((i as u32 % img.width) as i32, (i as u32 / img.width) as i32);
        root.draw_pixel((x + px, y + py), &RGBColor(p[0], p[1], p[2]))
            .map_err(e2s)?;
    }
    Ok(())
}

/// Fig. 5 of `s` under `display`, heatmaps on [`common_scale`].
pub(crate) fn showcase_figure(
    s: &Showcase,
    display: &DisplayParams,
    text: bool,
) -> Result<Figure, PlotError> {
    let stem = "fig5-showcase";
    let err = |message: String| PlotError::Draw {
        stem: stem.into(),
        message,
    };
    let scale = common_scale(s, display)?;
    let mut tiles = vec![(
        format!("target: {}", super::legend::short_name(&s.material, 22)),
        shrink(&display_image(&s.original, display).map_err(|e| err(e.to_string()))?),
        String::new(),
    )];
    let mut heat = Vec::new();
    for a in &s.approximations {
        tiles.push((
            super::legend::short_name(&a.basis, 22),
            shrink(&display_image(&a.image, display).map_err(|e| err(e.to_string()))?),
            format!("image error {}", brdf_basis::stats::num(a.image_error)),
        ));
        heat.push(shrink(
            &heatmap(&s.original, &a.image, display, HeatmapScale::Fixed(scale))
                .map_err(|e| err(e.to_string()))?,
        ));
    }
    let layout = Layout {
        tiles,
        heat,
        scale,
        title: format!(
            "{}: renders (gamma {}, exposure {}, light (45, 45) deg) and per-pixel error heatmaps, scale 0 to {scale:.3}",
            super::legend::short_name(&s.material, 60),
            display.gamma,
            display.exposure
        ),
    };
    let mut notes = Vec::new();
    if s.original.data.iter().all(|&v| v == 0.0) {
        notes.push(format!(
            "Fig. 5: the render of `{}` is black (its BRDF is 0 under this light), so its error heatmaps show the approximations themselves",
            super::legend::short_name(&s.material, 60)
        ));
    }
    let size = layout.size();
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        layout.draw(&root, text, false).map_err(err)?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    let mut images = String::new();
    for (col, (_, img, _)) in layout.tiles.iter().enumerate() {
        let mut put = |img: &Rgb8Image, (x, y): (i32, i32)| {
            images.push_str(&format!(
                "<image x=\"{x}\" y=\"{y}\" width=\"{}\" height=\"{}\" href=\"data:image/png;base64,{}\"/>\n",
                img.width,
                img.height,
                base64(&png_bytes(img))
            ));
        };
        put(img, layout.origin(col, 0));
        if col > 0 {
            put(&layout.heat[col - 1], layout.origin(col, 1));
        }
    }
    if let Some(at) = svg.rfind("</svg>") {
        svg.insert_str(at, &images);
    }
    let mut buf = vec![0u8; 3 * size.0 as usize * size.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        layout.draw(&root, text, true).map_err(err)?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(Figure {
        stem: stem.into(),
        svg,
        png: Rgb8Image {
            width: size.0,
            height: size.1,
            data: buf,
        },
        notes,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn base64_matches_rfc4648_vectors() {
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(super::base64(i.as_bytes()), o);
        }
    }
}
