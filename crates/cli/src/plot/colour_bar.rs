//! A heatmap's colour bar: the scale from 0 to its top value beside the heatmap, both
//! ends labelled and the quantity above (plotters draws the text).

use brdf_basis::eval::image_error::{viridis, Rgb8Image};
use brdf_basis::io::image::tick_label;
use plotters::prelude::*;

const FONT: &str = "sans-serif";

/// Whether a font is registered for figure text (by `plot::font`).
pub(crate) fn font_registered() -> bool {
    (FONT, 12).into_font().box_size("0").is_ok()
}

const BAR_W: u32 = 16;
const GAP: u32 = 12;
const LABELS: u32 = 70;
const HEAD: u32 = 24;
const MIN_BAR_H: u32 = 120;

/// `heat` (a heatmap through [`viridis`]) with a colour bar for values `0..=top` beside
/// it: both ends labelled and `quantity` above when `text` (a font is registered, see
/// `plot::font`). Needs the `plot` feature.
pub(crate) fn with_colour_bar(
    heat: &Rgb8Image,
    top: f64,
    quantity: &str,
    text: bool,
) -> Result<Rgb8Image, String> {
    let bar_h = heat.height.max(MIN_BAR_H);
    let width = (heat.width + GAP + BAR_W + LABELS)
        .max((quantity.chars().count() as u32 * 12 * 3).div_ceil(5) + 16);
    let height = HEAD + bar_h + 8;
    let mut buf = vec![255u8; 3 * width as usize * height as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        let y0 = HEAD as i32;
        for (i, p) in heat.data.chunks_exact(3).enumerate() {
            let (x, y) = (
                (i as u32 % heat.width) as i32,
                (i as u32 / heat.width) as i32,
            );
            root.draw_pixel((x, y0 + y), &RGBColor(p[0], p[1], p[2]))
                .map_err(e)?;
        }
        let bx = (heat.width + GAP) as i32;
        let bh = bar_h as i32;
        for r in 0..bh {
            let t = 1.0 - r as f64 / (bh - 1).max(1) as f64;
            let [cr, cg, cb] = viridis(t).map(|v| (v * 255.0).round() as u8);
            root.draw(&Rectangle::new(
                [(bx, y0 + r), (bx + BAR_W as i32, y0 + r + 1)],
                RGBColor(cr, cg, cb).filled(),
            ))
            .map_err(e)?;
        }
        root.draw(&Rectangle::new(
            [(bx, y0), (bx + BAR_W as i32, y0 + bh)],
            BLACK.stroke_width(1),
        ))
        .map_err(e)?;
        if text {
            let f = (FONT, 12).into_font();
            root.draw(&Text::new(quantity, (4, 4), f.clone()))
                .map_err(e)?;
            let tx = bx + BAR_W as i32 + 4;
            let top_label = if top > 0.0 {
                tick_label(top)
            } else {
                "0 (equal)".into()
            };
            root.draw(&Text::new(top_label, (tx, y0), f.clone()))
                .map_err(e)?;
            root.draw(&Text::new("0", (tx, y0 + bh - 12), f))
                .map_err(e)?;
        }
        root.present().map_err(e)?;
    }
    Ok(Rgb8Image {
        width,
        height,
        data: buf,
    })
}

#[cfg(test)]
mod colour_bar_tests {
    use super::*;

    /// The bar runs from the top colour of viridis (at the top) to the bottom colour, and
    /// the heatmap's pixels are kept.
    #[test]
    fn colour_bar_spans_the_scale_and_keeps_the_heatmap() {
        let heat = Rgb8Image {
            width: 3,
            height: 2,
            data: (0..18).map(|i| i as u8 * 10).collect(),
        };
        let out = with_colour_bar(&heat, 0.5, "error", false).unwrap();
        assert!(out.width > heat.width + BAR_W && out.height >= MIN_BAR_H);
        let px = |x: u32, y: u32| {
            let i = 3 * (y * out.width + x) as usize;
            [out.data[i], out.data[i + 1], out.data[i + 2]]
        };
        for y in 0..2 {
            for x in 0..3 {
                let i = 3 * (y * 3 + x) as usize;
                assert_eq!(
                    px(x, HEAD + y),
                    [heat.data[i], heat.data[i + 1], heat.data[i + 2]]
                );
            }
        }
        let bx = heat.width + GAP + BAR_W / 2;
        let top = viridis(1.0).map(|v| (v * 255.0).round() as u8);
        let bottom = viridis(0.0).map(|v| (v * 255.0).round() as u8);
        let near = |a: [u8; 3], b: [u8; 3]| a.iter().zip(&b).all(|(x, y)| x.abs_diff(*y) <= 16);
        assert!(
            near(px(bx, HEAD + 2), top),
            "{:?} vs {top:?}",
            px(bx, HEAD + 2)
        );
        assert!(near(px(bx, HEAD + MIN_BAR_H - 3), bottom));
    }
}
