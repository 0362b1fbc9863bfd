//! Our FLIP (`eval::flip`) against NVIDIA's C++ reference (`nv-flip`) on the renders the
//! appearance metrics score (SPEC 11): merl100 targets and their fits under the three
//! objectives, under the four lights, 256 x 256, the 8-bit display images. At least 500
//! pairs; per-image means over the sphere within 1e-4 and error maps over the sphere within
//! 1e-3 at the 99.9th percentile (the tolerance); the largest differences printed.

use crate::common::shared_or_skip;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::weighted::ObjectiveKind;
use brdf_basis::collection::Collection;
use brdf_basis::eval::appearance::{flip_kernels, FLIP_PIXELS_PER_DEGREE, LIGHTS, RENDER_SIZE};
use brdf_basis::eval::flip::FlipReference;
use brdf_basis::eval::image_error::DisplayParams;
use brdf_basis::eval::render::{Image, RenderParams};
use brdf_basis::eval::shade::PixelBrdfs;
use brdf_basis::fit::{fit, FitParams};
use rayon::prelude::*;

fn bytes(img: &Image) -> Vec<u8> {
    let d = DisplayParams::default();
    img.data.iter().map(|&v| d.map_u8(f64::from(v))).collect()
}

#[test]
fn flip_agrees_with_nvidia_on_500_merl100_render_pairs() {
    let Some(dir) = shared_or_skip(
        "real/nbrdf/merl100",
        "flip_agrees_with_nvidia_on_500_merl100_render_pairs",
    ) else {
        return;
    };
    let coll = Collection::load(&dir).expect("merl100");
    // A basis of 8 spread materials; 42 targets among the others.
    let basis: Vec<usize> = (0..8).map(|i| i * 12 + 3).collect();
    let targets: Vec<usize> = (0..coll.len())
        .filter(|m| !basis.contains(m))
        .step_by(2)
        .take(42)
        .collect();
    let cpu = CpuBackend::new();
    let fits: Vec<_> = ObjectiveKind::ALL
        .iter()
        .map(|o| {
            let p = FitParams {
                objective: o.weight(0.01).unwrap(),
                stride: 4,
                ..FitParams::default()
            };
            fit(&cpu, &coll, &basis, &targets, &p, &|_, _| {}).expect("fit")
        })
        .collect();
    let (w, h) = (RENDER_SIZE as usize, RENDER_SIZE as usize);
    let mut pairs = 0usize;
    let (mut worst_mean, mut diffs) = (0.0f64, Vec::new());
    for &(th, ph) in &LIGHTS {
        let rp = RenderParams::default()
            .with_size(RENDER_SIZE)
            .with_light(th, ph);
        let table = PixelBrdfs::new(&coll, &rp).expect("pixel table");
        let results: Vec<(f64, Vec<f32>)> = targets
            .par_iter()
            .enumerate()
            .flat_map_iter(|(i, &t)| {
                let target = table.render_material(t).expect("render");
                let rb = bytes(&target);
                let prepared =
                    FlipReference::new(flip_kernels(), &rb, w, h, &target.mask).expect("flip");
                let table = &table;
                let basis = &basis;
                fits.iter().map(move |f| {
                    let img = table
                        .render_combination(basis, &f[i].coefficients)
                        .expect("render");
                    let tb = bytes(&img);
                    let ours = prepared.map(&tb, &target.mask).expect("flip");
                    let mean_ours = prepared.mean(&tb, &target.mask).expect("flip");
                    let r = nv_flip::FlipImageRgb8::with_data(w as u32, h as u32, &rb);
                    let tt = nv_flip::FlipImageRgb8::with_data(w as u32, h as u32, &tb);
                    let theirs = nv_flip::flip(r, tt, FLIP_PIXELS_PER_DEGREE).to_vec();
                    let (mut sum, mut n, mut d) = (0.0f64, 0usize, Vec::new());
                    for ((&a, &b), &on) in ours.iter().zip(&theirs).zip(&target.mask) {
                        if on {
                            sum += f64::from(b);
                            n += 1;
                            d.push((a - b).abs());
                        }
                    }
                    ((mean_ours - sum / n as f64).abs(), d)
                })
            })
            .collect();
        for (m, d) in results {
            pairs += 1;
            worst_mean = worst_mean.max(m);
            diffs.extend(d);
        }
    }
    diffs.sort_by(f32::total_cmp);
    let p999 = diffs[(diffs.len() as f64 * 0.999) as usize];
    let max = *diffs.last().expect("pixels");
    println!(
        "FLIP, ours against nv-flip, {pairs} merl100 render pairs: largest per-image mean difference {worst_mean:.2e}, \
         largest pixel difference {max:.2e}, 99.9th percentile {p999:.2e}"
    );
    assert!(pairs >= 500, "{pairs} pairs");
    assert!(worst_mean <= 1e-4, "largest mean difference {worst_mean}");
    assert!(p999 <= 1e-3, "99.9th percentile {p999}");
}
