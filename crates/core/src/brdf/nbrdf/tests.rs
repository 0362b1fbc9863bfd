use super::*;
use crate::merl::N_CELLS;

/// A network with seeded pseudo-random weights of about the trained networks' size.
fn net(seed: u64) -> Nbrdf {
    super::seeded_for_tests(seed)
}

#[test]
fn expm1f_is_accurate_against_f64_over_its_range() {
    let mut worst = 0f64;
    for k in -200_000..=200_000 {
        let z = k as f32 * 1e-4 * (1.0 + (k as f32).abs() * 1e-5);
        let want = (z as f64).exp_m1();
        for got in [expm1f::<false>(z) as f64, expm1f::<true>(z) as f64] {
            worst = worst.max(((got - want) / want.abs().max(1e-30)).abs());
        }
    }
    assert!(worst < 4e-7, "worst relative error {worst}");
    assert_eq!(expm1f::<false>(0.0), 0.0);
    assert_eq!(expm1f::<false>(-1000.0), -1.0);
    assert!(expm1f::<false>(1000.0).is_finite());
}

#[test]
fn f32_twin_matches_the_f64_network_within_spec_9() {
    let cells: Vec<u32> = (0..20_000u32).map(|k| k * 72 + k % 71).collect();
    for seed in 0..6 {
        let n = net(seed);
        let mut out = vec![vec![0f32; cells.len()]; 3];
        let [r, g, b] = &mut out[..] else {
            unreachable!()
        };
        n.eval_cells(&cells, false, [r, g, b]);
        for (k, &c) in cells.iter().enumerate() {
            let (th, td, pd) = crate::merl::cell_angles(c as usize);
            let want = n.eval_raw_f64(th, td, pd);
            for ch in 0..3 {
                let (got, want) = (out[ch][k] as f64, want[ch]);
                let tol = if want.abs() > 1e-3 {
                    5e-4 * want.abs()
                } else {
                    1e-6
                };
                assert!(
                    (got - want).abs() <= tol,
                    "seed {seed} cell {c} ch {ch}: {got} vs {want}"
                );
            }
        }
    }
}

/// The dense f32 pass, cell by cell, in the order [`forward`] documents (`acc = b`,
/// then `acc = x_i w_i + acc` for `i` ascending; fused when `fma`): what the pruned
/// block kernels must give bit for bit.
fn dense(w: &[f32], x: [f32; 5], fma: bool) -> [f32; 3] {
    let madd = |a: f32, b: f32, c: f32| if fma { a.mul_add(b, c) } else { a * b + c };
    let xs = [x[0], 0.0, x[1], x[2], x[3], x[4]];
    let mut a1 = [0f32; HIDDEN];
    for (j, a) in a1.iter_mut().enumerate() {
        let mut acc = w[B1 + j];
        for i in [0, 2, 3, 4, 5] {
            acc = madd(xs[i], w[FC1 + i * HIDDEN + j], acc);
        }
        *a = if acc > 0.0 { acc } else { 0.0 };
    }
    let mut a2 = [0f32; HIDDEN];
    for (j, a) in a2.iter_mut().enumerate() {
        let mut acc = w[B2 + j];
        for (i, &v) in a1.iter().enumerate() {
            acc = madd(v, w[FC2 + i * HIDDEN + j], acc);
        }
        *a = if acc > 0.0 { acc } else { 0.0 };
    }
    std::array::from_fn(|c| {
        let mut z = w[B3 + c];
        for (i, &v) in a2.iter().enumerate() {
            z = madd(v, w[FC3 + i * 3 + c], z);
        }
        if fma {
            expm1f::<true>(z)
        } else {
            expm1f::<false>(z)
        }
    })
}

fn rows(r: &mut [Vec<f32>]) -> [&mut [f32]; 3] {
    let [x, y, z] = r else { unreachable!() };
    [&mut x[..], &mut y[..], &mut z[..]]
}

/// Networks with many dead units (biases pushed down), so that blocks prune.
fn sparse_net(seed: u64) -> Nbrdf {
    let mut w = net(seed).weights().to_vec();
    for k in (B1..B1 + HIDDEN).chain(B2..B2 + HIDDEN) {
        w[k] -= 0.3 + 0.1 * (seed % 4) as f32;
    }
    Nbrdf::from_weights(w).expect("finite")
}

/// The values are those of the dense f32 pass followed by the cell's own recheck
/// (`recheck_cell`: the f64 network's where its estimate says so), bit for bit, on
/// every path: pruning and the blocks change no value.
#[test]
fn pruned_blocks_give_the_dense_pass_bit_for_bit() {
    // Grid runs (shared theta_h), a row boundary inside a block, scattered cells and
    // a short tail.
    let mut cells: Vec<u32> = (0..3000u32).chain(16_150..16_290).collect();
    cells.extend((0..500u32).map(|k| k * 2903 % N_CELLS as u32));
    cells.extend(700_001..700_013);
    let feats: Vec<[f32; 5]> = cells.iter().map(|&c| cell_features(c as usize)).collect();
    let fma = fma_available();
    let mut rechecked = 0;
    for seed in 0..8 {
        for n in [net(seed), sparse_net(seed)] {
            let w: &[f32; NBRDF_WEIGHTS] = n.weights().try_into().expect("675");
            let mut got = vec![vec![0f32; cells.len()]; 4 * 3];
            let (a, rest) = got.split_at_mut(3);
            let (b, rest) = rest.split_at_mut(3);
            let (c, d) = rest.split_at_mut(3);
            n.eval_cells(&cells, false, rows(a));
            n.eval_features(&feats, false, rows(b));
            eval_blocks(Portable::<true>, w, &GridCells(&cells), false, rows(c));
            eval_blocks(Portable::<false>, w, &GridCells(&cells), false, rows(d));
            // Each SIMD kernel the processor has (`eval_cells` picks one), bit for bit.
            #[cfg(target_arch = "x86_64")]
            for avx512 in [false, true] {
                if !fma || (avx512 && !avx512_available()) {
                    continue;
                }
                let mut e = vec![vec![0f32; cells.len()]; 3];
                // SAFETY: checked just before.
                unsafe {
                    if avx512 {
                        eval_blocks_avx512(w, &GridCells(&cells), false, rows(&mut e))
                    } else {
                        eval_blocks_avx2(w, &GridCells(&cells), false, rows(&mut e))
                    }
                }
                for (e, a) in e.iter().zip(&got[..3]) {
                    let bits = |r: &[f32]| r.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                    assert!(bits(e) == bits(a), "seed {seed}: avx512 {avx512}");
                }
            }
            for (k, f) in feats.iter().enumerate() {
                // The dense pass, then the cell's own recheck (from the cell's f64
                // inputs, or, features given in f32, from those).
                let x64 = cell_features_f64(cells[k] as usize);
                let f64in = f.map(f64::from);
                let want = [
                    recheck_cell(w, dense(w, *f, fma), x64, false),
                    recheck_cell(w, dense(w, *f, fma), f64in, false),
                    recheck_cell(w, dense(w, *f, true), x64, false),
                    recheck_cell(w, dense(w, *f, false), x64, false),
                ];
                rechecked += usize::from(want[0] != dense(w, *f, fma));
                for ch in 0..3 {
                    let seen = [got[ch][k], got[3 + ch][k], got[6 + ch][k], got[9 + ch][k]];
                    let expect = want.map(|v| v[ch]);
                    // `==`: an exact zero may carry either sign.
                    assert!(
                        seen.iter().zip(&expect).all(|(a, b)| a == b),
                        "seed {seed} cell {} ch {ch}: {seen:?} vs {expect:?}",
                        cells[k]
                    );
                }
            }
        }
    }
    // The rechecked values were exercised (the pruned nets give small values).
    assert!(rechecked > 0);
}

/// The MERL networks of `dir` by name, read part by part (not through `collection`,
/// which depends on this module).
fn merl100_nets(dir: &std::path::Path) -> Vec<(String, Nbrdf)> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("merl100")
        .filter_map(|e| {
            let n = e.ok()?.file_name().into_string().ok()?;
            n.strip_suffix("_fc1.npy").map(str::to_string)
        })
        .collect();
    names.sort();
    names
        .into_iter()
        .map(|name| {
            let mut flat = Vec::with_capacity(NBRDF_WEIGHTS);
            for (part, _, _) in NBRDF_PARTS {
                let f = dir.join(format!("{name}_{part}.npy"));
                let a = crate::npy_format::read_npy_f32(&f, 4096).expect("weights");
                flat.extend(a.data);
            }
            let n = Nbrdf::from_weights(flat).expect("network");
            (name, n)
        })
        .collect()
}

/// Hashes of every tabulated value of the 100 MERL networks on the full grid, per
/// path (AVX-512 where the CPU has it, AVX2 clamped and raw, the portable pass with and
/// without FMA), written to `$BRDF_BASIS_NBRDF_GOLDEN` when that file is missing, else
/// compared with it: a kernel change must leave every bit as it was. A tool for kernel
/// changes, not a check of the current code (it needs the hashes of the code before the
/// change, and minutes of CPU):
/// `BRDF_BASIS_NBRDF_GOLDEN=/tmp/nb_golden.txt cargo test --release --lib golden -- --ignored`.
/// The tests that always run check every kernel against the f64 network and the SIMD
/// kernels against the portable pass bit for bit.
#[test]
#[ignore = "a tool for kernel changes: compares with hashes written before the change (BRDF_BASIS_NBRDF_GOLDEN), minutes of CPU"]
fn golden_hashes_of_the_merl100_tabulation() {
    use rayon::prelude::*;
    let Ok(file) = std::env::var("BRDF_BASIS_NBRDF_GOLDEN") else {
        return;
    };
    let dir =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real/nbrdf/merl100");
    let nets = merl100_nets(&dir);
    assert_eq!(nets.len(), 100);
    let cells: Vec<u32> = (0..N_CELLS as u32).collect();
    let hash = |rows: &[Vec<f32>]| {
        let mut h = 0xcbf2_9ce4_8422_2325u64;
        for r in rows {
            for v in r {
                h = (h ^ v.to_bits() as u64).wrapping_mul(0x0000_0100_0000_01b3);
            }
        }
        h
    };
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn port_fma(w: &[f32; NBRDF_WEIGHTS], cells: &[u32], clamp: bool, out: [&mut [f32]; 3]) {
        eval_blocks(Portable::<true>, w, &GridCells(cells), clamp, out);
    }
    // The AVX2 and AVX-512 kernels, explicitly (`eval_cells` picks one).
    let simd = |avx512: bool, w: &[f32; NBRDF_WEIGHTS], clamp: bool, out: [&mut [f32]; 3]| {
        // SAFETY: checked just before.
        assert!(fma_available() && (!avx512 || avx512_available()));
        unsafe {
            if avx512 {
                eval_blocks_avx512(w, &GridCells(&cells), clamp, out)
            } else {
                eval_blocks_avx2(w, &GridCells(&cells), clamp, out)
            }
        }
    };
    let paths = [
        "avx2-clamp",
        "avx2-raw",
        "port-fma-clamp",
        "port-nofma-clamp",
    ];
    let t = std::time::Instant::now();
    let lines: Vec<String> = nets
        .par_iter()
        .map(|(name, n)| {
            let w: &[f32; NBRDF_WEIGHTS] = n.weights().try_into().expect("675");
            let mut line = name.clone();
            for p in paths {
                let mut out = vec![vec![0f32; cells.len()]; 3];
                match p {
                    "avx2-clamp" | "avx2-raw" => {
                        let clamp = p == "avx2-clamp";
                        simd(false, w, clamp, rows(&mut out));
                        // The AVX-512 kernel and `eval_cells` give the same bits.
                        let mut more = vec![vec![0f32; cells.len()]; 3];
                        if avx512_available() {
                            simd(true, w, clamp, rows(&mut more));
                            assert_eq!(hash(&more), hash(&out), "{name} {p}: avx512");
                        }
                        n.eval_cells(&cells, clamp, rows(&mut more));
                        assert_eq!(hash(&more), hash(&out), "{name} {p}: eval_cells");
                    }
                    // SAFETY: the test machine has AVX2 and FMA (x86-64 CI).
                    "port-fma-clamp" => unsafe { port_fma(w, &cells, true, rows(&mut out)) },
                    _ => {
                        eval_blocks(
                            Portable::<false>,
                            w,
                            &GridCells(&cells),
                            true,
                            rows(&mut out),
                        );
                    }
                }
                line += &format!(" {p}={:016x}", hash(&out));
            }
            line
        })
        .collect();
    let text = lines.join("\n") + "\n";
    eprintln!("golden: {:.1} s", t.elapsed().as_secs_f64());
    match std::fs::read_to_string(&file) {
        Ok(want) => {
            let bad: Vec<_> = text
                .lines()
                .zip(want.lines())
                .filter(|(a, b)| a != b)
                .collect();
            assert!(
                bad.is_empty() && text.lines().count() == want.lines().count(),
                "{} networks differ: {bad:?}",
                bad.len()
            );
            eprintln!("golden: all {} networks bit for bit", lines.len());
        }
        Err(_) => std::fs::write(&file, text).expect("write golden"),
    }
}

#[test]
fn bad_weights_are_refused_with_the_part_named() {
    assert!(Nbrdf::from_weights(vec![0.0; 674])
        .unwrap_err()
        .contains("674"));
    let mut w = vec![0.0; NBRDF_WEIGHTS];
    w[600] = f32::NAN;
    let e = Nbrdf::from_weights(w).unwrap_err();
    assert!(e.contains("`b2`") && e.contains("weight 12"), "{e}");
}

#[test]
fn directions_and_angles_agree_and_below_the_horizon_is_zero() {
    let n = net(3);
    for cell in [0usize, 12345, 700_000, 1_000_001] {
        let (th, td, pd) = crate::merl::cell_angles(cell);
        let (wi, wo) = crate::merl::cell_directions(cell);
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            assert_eq!(n.eval_dirs(wi, wo), [0.0; 3]);
            continue;
        }
        let a = n.eval_f64(th, td, pd);
        let b = n.eval_dirs(wi, wo);
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() <= 1e-9 * a[c].abs().max(1e-9), "{cell}");
        }
    }
}

/// The four-lane f64 evaluation gives `eval_f64`'s values to the bit (AVX2 and the
/// portable loop), on inputs from real angles, inputs that drive units to exactly 0, and a
/// count that is not a multiple of the lanes.
#[test]
fn f64_lanes_are_the_scalar_f64_network_to_the_bit() {
    let mut xs: Vec<[f64; 6]> = (0..4001u32)
        .map(|k| {
            let (th, td, pd) = crate::merl::cell_angles((k as usize * 367) % N_CELLS);
            Nbrdf::inputs_f64(th, td, pd)
        })
        .collect();
    xs.push([0.0; 6]);
    xs.push([-0.0, 0.0, -0.0, 0.0, -0.0, 0.0]);
    xs.push([-50.0, 0.0, -50.0, -50.0, -50.0, -50.0]);
    for seed in 0..5 {
        let n = net(seed);
        let want: Vec<[f64; 3]> = xs
            .iter()
            .map(|x| n.eval_inputs_f64(x).map(|v| v.max(0.0)))
            .collect();
        let mut got = vec![[0f64; 3]; xs.len()];
        n.eval_inputs_f64_batch(&xs, &mut got);
        let w: Vec<f64> = n.weights().iter().map(|&v| v as f64).collect();
        let mut portable = vec![[0f64; 3]; xs.len()];
        eval_f64_lanes(&w, &xs, &mut portable);
        for (k, ((g, p), want)) in got.iter().zip(&portable).zip(&want).enumerate() {
            let bits = |v: &[f64; 3]| v.map(f64::to_bits);
            assert_eq!(bits(g), bits(want), "seed {seed}, input {k}");
            assert_eq!(bits(p), bits(want), "seed {seed}, input {k}");
        }
        let (th, td, pd) = crate::merl::cell_angles(12345);
        assert_eq!(
            n.eval_f64(th, td, pd),
            n.eval_inputs_f64(&Nbrdf::inputs_f64(th, td, pd))
                .map(|v| v.max(0.0))
        );
    }
}
