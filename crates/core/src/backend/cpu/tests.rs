use super::*;

#[test]
fn avx2_and_portable_kernels_agree_with_a_hand_sum() {
    let rows: Vec<Vec<f32>> = (0..8)
        .map(|r| {
            (0..1037)
                .map(|c| ((r * 31 + c * 7) % 13) as f32 - 6.0)
                .collect()
        })
        .collect();
    let a: [&[f32]; BLOCK] = std::array::from_fn(|r| rows[r].as_slice());
    let b: [&[f32]; BLOCK] = std::array::from_fn(|q| rows[4 + q].as_slice());
    for op in [PairOp::L1, PairOp::Dot] {
        let mut fast = [[0f64; BLOCK]; BLOCK];
        block_reduce(op, a, b, &mut fast).expect("same lengths");
        let mut port = [[0f64; BLOCK]; BLOCK];
        match op {
            PairOp::L1 => block_portable::<false>(a, b, &mut port),
            PairOp::Dot => block_portable::<true>(a, b, &mut port),
        }
        for r in 0..BLOCK {
            for q in 0..BLOCK {
                let want: f64 = a[r]
                    .iter()
                    .zip(b[q])
                    .map(|(&x, &y)| {
                        if op == PairOp::Dot {
                            x as f64 * y as f64
                        } else {
                            (x as f64 - y as f64).abs()
                        }
                    })
                    .sum();
                // Small integers: every partial sum is exact in f32.
                assert_eq!(fast[r][q], want, "{op:?} {r} {q}");
                assert_eq!(port[r][q], want, "{op:?} {r} {q}");
            }
        }
    }
}

#[test]
fn rows_of_different_lengths_are_an_error_not_a_read_past_the_end() {
    let long = vec![1f32; 4096];
    let short = [2f32; 8];
    for op in [PairOp::L1, PairOp::Dot] {
        for bad in 0..2 * BLOCK {
            let rows: [&[f32]; 2 * BLOCK] =
                std::array::from_fn(|i| if i == bad { &short[..] } else { &long[..] });
            let (a, b) = (
                std::array::from_fn(|r| rows[r]),
                std::array::from_fn(|q| rows[BLOCK + q]),
            );
            let mut acc = [[0f64; BLOCK]; BLOCK];
            let err = block_reduce(op, a, b, &mut acc).unwrap_err();
            assert!(err.to_string().contains("4096") && err.to_string().contains('8'));
            assert_eq!(acc, [[0f64; BLOCK]; BLOCK], "nothing added");
        }
    }
    // Rows of one length, even empty ones, are fine.
    let mut acc = [[0f64; BLOCK]; BLOCK];
    block_reduce(PairOp::L1, [&[][..]; BLOCK], [&[][..]; BLOCK], &mut acc).expect("empty");
}

#[test]
fn a_channels_cached_values_are_its_own_tabulation_whichever_channel_came_first() {
    // A miss on one channel tabulates the network's three channels together and keeps
    // them: each must be the bits of that channel's own tabulation (`tabulate_into`),
    // whichever channel was asked first, over a cell count that is not a multiple of the
    // chunk or of the network's run.
    let cpu = CpuBackend::new();
    let cells: Vec<u32> = crate::merl::CellSet::new(
        crate::merl::Mask::Evaluation,
        crate::merl::Weighting::Uniform,
        3,
    )
    .cells
    .into_iter()
    .take((1 << 14) + 2_345)
    .collect();
    for first in 0..3 {
        let net = std::sync::Arc::new(crate::brdf::seeded_for_tests(40 + first as u64));
        let lobe = |c: usize| Lobe::Neural {
            net: net.clone(),
            channel: Some(c),
        };
        let order = [first, (first + 1) % 3, (first + 2) % 3];
        for c in order {
            let cached = cpu.values_f64(&lobe(c), &cells);
            let mut own = vec![0f32; cells.len()];
            cpu.tabulate_into(&lobe(c), &cells, None, &mut own);
            assert!(
                cached
                    .iter()
                    .zip(&own)
                    .all(|(&a, &b)| a.to_bits() == f64::from(b).to_bits()),
                "channel {c} (asked after {first})"
            );
        }
    }
}
