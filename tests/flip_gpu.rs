//! FLIP on the device (`flip.wgsl`, lavapipe in CI) against its CPU twin
//! (`eval::flip`) and against NVIDIA's reference (`nv-flip`): renders of the embedded
//! default collection under SPEC 11's four lights (256 x 256) and synthetic edge cases
//! (black, white, a single lit pixel, noise, saturated colours), at odd sizes too.

use crate::common::*;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::gpu::flip::FLIP_GPU_TOLERANCE;
use brdf_basis::backend::Backend;
use brdf_basis::collection::Collection;
use brdf_basis::eval::appearance::{flip_kernels, FLIP_PIXELS_PER_DEGREE, LIGHTS, RENDER_SIZE};
use brdf_basis::eval::image_error::DisplayParams;
use brdf_basis::eval::render::RenderParams;
use brdf_basis::eval::shade::PixelBrdfs;

fn nvidia(r: &[u8], t: &[u8], w: usize, h: usize) -> Vec<f32> {
    let a = nv_flip::FlipImageRgb8::with_data(w as u32, h as u32, r);
    let b = nv_flip::FlipImageRgb8::with_data(w as u32, h as u32, t);
    nv_flip::flip(a, b, FLIP_PIXELS_PER_DEGREE).to_vec()
}

fn noise(n: usize, seed: u64) -> Vec<u8> {
    let mut x = seed.max(1);
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 32) as u8
        })
        .collect()
}

fn mean(v: &[f32]) -> f64 {
    v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64
}

/// GPU maps against the CPU twin (per pixel within `FLIP_GPU_TOLERANCE`) and against
/// NVIDIA's (means within 1e-4, SPEC 11); returns the largest differences seen.
fn check(pairs: &[(Vec<u8>, Vec<u8>)], w: usize, h: usize, label: &str) -> (f32, f64) {
    let Some(gpu) = gpu(label) else {
        return (0.0, 0.0);
    };
    let refs: Vec<(&[u8], &[u8])> = pairs.iter().map(|(r, t)| (&r[..], &t[..])).collect();
    let kernels = flip_kernels();
    let on_gpu = gpu.flip_maps(&kernels, &refs, w, h).expect("gpu flip");
    let on_cpu = CpuBackend::new()
        .flip_maps(&kernels, &refs, w, h)
        .expect("cpu flip");
    let (mut worst_pixel, mut worst_mean) = (0.0f32, 0.0f64);
    for (i, ((g, c), (r, t))) in on_gpu.iter().zip(&on_cpu).zip(pairs).enumerate() {
        let d = g
            .iter()
            .zip(c)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(
            d <= FLIP_GPU_TOLERANCE,
            "{label} pair {i}: GPU and CPU maps differ by {d}"
        );
        worst_pixel = worst_pixel.max(d);
        let theirs = mean(&nvidia(r, t, w, h));
        let dm = (mean(g) - theirs).abs();
        assert!(
            dm <= 1e-4,
            "{label} pair {i}: GPU mean {} vs nv-flip {theirs}",
            mean(g)
        );
        worst_mean = worst_mean.max(dm);
    }
    println!("{label}: {} pairs, GPU vs CPU largest pixel difference {worst_pixel:.2e}; GPU vs nv-flip largest mean difference {worst_mean:.2e}", pairs.len());
    (worst_pixel, worst_mean)
}

#[test]
fn gpu_flip_matches_its_cpu_twin_and_nvidia_on_edge_cases() {
    for (w, h) in [(61, 47), (16, 9)] {
        let n = 3 * w * h;
        let black = vec![0u8; n];
        let white = vec![255u8; n];
        let mut single = black.clone();
        single[3 * (h / 2 * w + w / 3)..3 * (h / 2 * w + w / 3) + 3]
            .copy_from_slice(&[255, 255, 255]);
        let saturated: Vec<u8> = (0..w * h)
            .flat_map(|i| match i % 3 {
                0 => [255, 0, 0],
                1 => [0, 255, 0],
                _ => [0, 0, 255],
            })
            .collect();
        let pairs = vec![
            (black.clone(), white.clone()),
            (white.clone(), black.clone()),
            (black.clone(), single),
            (noise(n, 1), noise(n, 2)),
            (saturated.clone(), vec![128; n]),
            (noise(n, 5), noise(n, 5)),
        ];
        check(&pairs, w, h, &format!("gpu_flip edge cases {w}x{h}"));
    }
}

#[test]
fn gpu_flip_matches_its_cpu_twin_and_nvidia_on_renders() {
    let coll = Collection::embedded_default();
    let d = DisplayParams::default();
    let bytes = |img: &brdf_basis::eval::render::Image| -> Vec<u8> {
        img.data.iter().map(|&v| d.map_u8(f64::from(v))).collect()
    };
    let mut pairs = Vec::new();
    for &(th, ph) in &LIGHTS {
        let rp = RenderParams::default()
            .with_size(RENDER_SIZE)
            .with_light(th, ph);
        let table = PixelBrdfs::new(&coll, &rp).expect("pixel table");
        for m in [0usize, 7, 19] {
            let target = table.render_material(m).expect("render");
            let other = table.render_material(m + 1).expect("render");
            pairs.push((bytes(&target), bytes(&other)));
        }
    }
    let n = RENDER_SIZE as usize;
    check(&pairs, n, n, "gpu_flip renders");
}
