//! The appearance metrics' unit costs (SPEC 11: 256 x 256 renders under four lights), to
//! size `reproduce` and `cv --acquisition --appearance`: per image, the render of a
//! 12-material combination from the pixel table, the prepared reference, and the scores
//! of one render against it (image error, CIEDE2000 and our FLIP), and FLIP alone: ours
//! (`eval::flip`: a pair from scratch, and against a prepared reference) beside NVIDIA's
//! C++ reference through `nv-flip`, with the ratios. One thread; the embedded default
//! collection.
//!
//! `cargo bench --bench appearance`

use brdf_basis::collection::Collection;
use brdf_basis::eval::appearance::{
    flip_kernels, mean_flip, Reference, FLIP_PIXELS_PER_DEGREE, LIGHTS, RENDER_SIZE,
};
use brdf_basis::eval::flip::FlipReference;
use brdf_basis::eval::image_error::DisplayParams;
use brdf_basis::eval::render::RenderParams;
use brdf_basis::eval::shade::PixelBrdfs;
use std::time::Instant;

/// Mean seconds of `f` over `reps` calls (after one warm-up call).
fn per_call<T>(reps: usize, mut f: impl FnMut() -> T) -> f64 {
    std::hint::black_box(f());
    let t = Instant::now();
    for _ in 0..reps {
        std::hint::black_box(f());
    }
    t.elapsed().as_secs_f64() / reps as f64
}

fn main() {
    let coll = Collection::embedded_default();
    let light = LIGHTS[0];
    let rp = RenderParams::default()
        .with_size(RENDER_SIZE)
        .with_light(light.0, light.1);
    let t = Instant::now();
    let pixels = PixelBrdfs::new(&coll, &rp).expect("pixel table");
    println!(
        "pixel table of {} materials at {RENDER_SIZE}^2: {:.3} s",
        coll.len(),
        t.elapsed().as_secs_f64()
    );
    let k = 12.min(coll.len() - 1);
    let basis: Vec<usize> = (1..=k).collect();
    let coef: Vec<[f64; 3]> = (0..=k)
        .map(|j| [0.1 + 0.01 * j as f64, 0.05, 0.2 / (1.0 + j as f64)])
        .collect();
    let target = pixels.render_material(0).expect("render");
    let test = pixels.render_combination(&basis, &coef).expect("render");
    let reps = 20;
    let render = per_call(reps, || pixels.render_combination(&basis, &coef));
    let prepare = per_call(reps, || Reference::new(&target).is_ok());
    let reference = Reference::new(&target).expect("reference");
    let scores = per_call(reps, || reference.scores(&test, light));
    let flip = per_call(reps, || {
        mean_flip(&target, &test, &DisplayParams::default())
    });
    println!("per image, one thread (ms): render of k = {k} {:.2}, reference {:.2}, scores {:.2} (`mean_flip` alone {:.2})",
        1e3 * render, 1e3 * prepare, 1e3 * scores, 1e3 * flip);
    println!(
        "scores of 1,000 reconstructions under the four lights: {:.1} CPU-s ({:.1} in FLIP)",
        4e3 * (render + scores),
        4e3 * flip
    );

    // FLIP alone on the 8-bit display images, ours against NVIDIA's, one thread.
    let d = DisplayParams::default();
    let to8 = |img: &brdf_basis::eval::render::Image| -> Vec<u8> {
        img.data.iter().map(|&v| d.map_u8(f64::from(v))).collect()
    };
    let (rb, tb) = (to8(&target), to8(&test));
    let (w, h) = (target.width as usize, target.height as usize);
    let all = vec![true; w * h];
    let nvidia = per_call(reps, || {
        let r = nv_flip::FlipImageRgb8::with_data(w as u32, h as u32, &rb);
        let t = nv_flip::FlipImageRgb8::with_data(w as u32, h as u32, &tb);
        nv_flip::flip(r, t, FLIP_PIXELS_PER_DEGREE).to_vec()
    });
    let kernels = flip_kernels();
    let ours_pair = per_call(reps, || {
        let r = FlipReference::new(kernels.clone(), &rb, w, h, &all).expect("flip");
        r.map(&tb, &all).expect("flip")
    });
    let ours_sphere = per_call(reps, || {
        let r = FlipReference::new(kernels.clone(), &rb, w, h, &target.mask).expect("flip");
        r.mean(&tb, &target.mask).expect("flip")
    });
    let prepared = FlipReference::new(kernels.clone(), &rb, w, h, &target.mask).expect("flip");
    let ours_prepared = per_call(reps, || prepared.mean(&tb, &target.mask).expect("flip"));
    println!(
        "FLIP per {RENDER_SIZE}^2 pair, one thread (ms): nv-flip {:.2}; ours, whole map {:.2} ({:.1}x), \
         sphere mean {:.2} ({:.1}x), against a prepared reference {:.2} ({:.1}x)",
        1e3 * nvidia,
        1e3 * ours_pair,
        nvidia / ours_pair,
        1e3 * ours_sphere,
        nvidia / ours_sphere,
        1e3 * ours_prepared,
        nvidia / ours_prepared
    );

    // A batch of pairs on the GPU back-end (when an adapter opens), per pair against
    // nv-flip's per-image time above; the first call compiles the pipelines (not timed).
    match brdf_basis::backend::gpu::GpuBackend::new() {
        Ok(gpu) => {
            use brdf_basis::backend::Backend;
            let batch: usize = std::env::var("BENCH_FLIP_BATCH")
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(64);
            let pairs: Vec<(&[u8], &[u8])> = (0..batch).map(|_| (&rb[..], &tb[..])).collect();
            let maps = gpu
                .flip_maps(&kernels, &pairs[..1], w, h)
                .expect("gpu flip");
            let cpu_map = FlipReference::new(kernels.clone(), &rb, w, h, &all)
                .expect("flip")
                .map(&tb, &all)
                .expect("flip");
            let diff = maps[0]
                .iter()
                .zip(&cpu_map)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            let gpu_batch = per_call(3, || {
                gpu.flip_maps(&kernels, &pairs, w, h).expect("gpu flip")
            });
            println!(
                "FLIP on {} (batch of {batch} pairs): {:.3} ms per pair ({:.2}x nv-flip's {:.2} ms); largest pixel difference from the CPU twin {diff:.1e}",
                gpu.name(),
                1e3 * gpu_batch / batch as f64,
                nvidia * batch as f64 / gpu_batch,
                1e3 * nvidia
            );
        }
        Err(e) => println!("FLIP on the GPU: skipped (no adapter: {e})"),
    }
}
