//! NNLS fitting: (1) up to 62 targets x 5-material basis end to end (Gram pass over the full
//! evaluation mask + exact solves + grid errors) on each back-end; (2) 100,000 targets x
//! 10-material basis batched projected gradient (targets/s) on each back-end.
//!
//! `cargo bench --bench fit`

use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::gpu::GpuBackend;
use brdf_basis::backend::weighted::TargetWeight;
use brdf_basis::backend::Backend;
use brdf_basis::collection::Collection;
use brdf_basis::fit::{channel_gram, fit, fit_cells, FitParams, GramMode};
use brdf_basis::nnls::pgd::PgdParams;
use brdf_basis::nnls::GramBatch;
use std::time::Instant;

fn main() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/ngan2005_ashikhmin_shirley.csv");
    let coll = Collection::load(&path).unwrap_or_else(|e| {
        eprintln!("{e}: using the embedded default collection");
        Collection::embedded_default()
    });
    let mut backends: Vec<Box<dyn Backend>> = vec![Box::new(CpuBackend::new())];
    if let Ok(g) = GpuBackend::new() {
        backends.push(Box::new(g));
    }
    let basis: Vec<usize> = (0..5).map(|i| i * 7).collect();
    let targets: Vec<usize> = (0..coll.len())
        .filter(|i| !basis.contains(i))
        .take(62)
        .collect();
    for b in &backends {
        for gram in [GramMode::Auto, GramMode::Grid] {
            let p = FitParams {
                gram,
                objective: TargetWeight::L2,
                ..Default::default()
            };
            let t = Instant::now();
            let fits = fit(b.as_ref(), &coll, &basis, &targets, &p, &|_, _| {}).expect("fit");
            let s = t.elapsed().as_secs_f64();
            let mae = fits.iter().map(|f| f.mae).sum::<f64>() / fits.len() as f64;
            println!(
                "fit {:<50} gram {gram:?}: {} targets x 5 basis, full evaluation mask: {s:.3} s (mean MAE {mae:.3e})",
                b.name(),
                targets.len()
            );
        }
    }
    // 100,000 targets x 10-material basis: the Gram of 10 materials, targets = random
    // non-negative combinations of 30 other materials' h vectors.
    let basis10: Vec<usize> = (0..10).map(|i| i * 9).collect();
    let others: Vec<usize> = (0..coll.len())
        .filter(|i| !basis10.contains(i))
        .take(30)
        .collect();
    let p = FitParams {
        stride: 3,
        objective: TargetWeight::L2,
        ..Default::default()
    };
    let cells = fit_cells(&coll, &(0..coll.len()).collect::<Vec<_>>(), &p).expect("cells");
    let brdf_basis::fit::ChannelGram {
        gram: g,
        h: h30,
        bb: bb30,
    } = channel_gram(
        &CpuBackend::new(),
        &coll,
        &basis10,
        &others,
        &cells,
        0,
        GramMode::Auto,
        &|_, _| {},
    )
    .expect("gram");
    let m = 11;
    let n = 100_000;
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut rnd = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut hs = Vec::with_capacity(n * m);
    let mut bbs = Vec::with_capacity(n);
    for _ in 0..n {
        let k = (rnd() * 30.0) as usize % 30;
        let a = 0.5 + rnd();
        hs.extend(h30[k * m..(k + 1) * m].iter().map(|v| a * v));
        bbs.push(a * a * bb30[k]);
    }
    let batch = GramBatch::new(m, &g, &hs, &bbs).expect("batch");
    let mut rates = Vec::new();
    for b in &backends {
        let t = Instant::now();
        let sols = b.nnls_pgd(&batch, &PgdParams::default()).expect("pgd");
        let s = t.elapsed().as_secs_f64();
        let worst = sols.iter().map(|s| s.max_kkt_violation).fold(0.0, f64::max);
        let iters = sols.iter().map(|s| s.iterations).sum::<usize>() as f64 / n as f64;
        println!("pgd {:<50} {n} targets x 10 basis: {s:.2} s, {:.0} targets/s (mean {iters:.0} steps, worst KKT {worst:.1e})", b.name(), n as f64 / s);
        rates.push(n as f64 / s);
    }
    if rates.len() == 2 {
        println!("pgd: gpu / cpu targets/s ratio {:.2}", rates[1] / rates[0]);
    }
}
