//! Pair reductions of the CPU back-end ([`Backend::reduce_pairs`]) and the per-channel
//! weighted Gram matrices of one pass ([`Backend::grams_per_channel`]).
//!
//! A pass streams the cells chunk by chunk; every lobe belongs to a *group* with its own
//! cell weights (the row scale of each cell). With one group this is `reduce_pairs`; with
//! three (a channel each, SPEC 11's shared weights differ per channel) the networks of a
//! collection run once per chunk for their three channels instead of once per channel.
//! Every row, block and sum is formed as in a pass of its group alone, so each group's
//! entries are the same bits as that pass's.

use super::super::blocks::{add_block, gram_blocks, PairOp, BLOCK};
use super::{block_reduce_same_len, fill_analytic, fill_rows_each, CpuBackend, CHUNK_CELLS};
use crate::backend::{Backend, Lobe, LobeParams, Progress};
use crate::error::BackendError;
use crate::merl::CellSet;
use crate::separable::SeparableLobe;
use rayon::prelude::*;

/// One pass of pair reductions.
pub(super) struct Pass<'a> {
    /// The lobes.
    pub lobes: &'a [Lobe],
    /// Per lobe, the index of its group in `weights`.
    pub group: &'a [usize],
    /// Per group, the weight of every cell of `cells`.
    pub weights: &'a [&'a [f64]],
    /// The cells.
    pub cells: &'a [u32],
    /// Block pairs `[bi, bj]` of lobe rows to reduce.
    pub blocks: &'a [[u32; 2]],
    /// The reduction.
    pub op: PairOp,
}

/// The full `n x n` sums of `pass` (entries outside its blocks 0).
pub(super) fn reduce(
    cpu: &CpuBackend,
    pass: &Pass<'_>,
    progress: Progress<'_>,
) -> Result<Vec<f64>, BackendError> {
    let Pass {
        lobes,
        group,
        weights,
        cells,
        blocks,
        op,
    } = *pass;
    let n = lobes.len();
    if group.len() != n || group.iter().any(|&g| g >= weights.len()) {
        return Err(BackendError::Invalid(format!(
            "reduce_pairs: {} group indices for {n} lobes and {} weight sets",
            group.len(),
            weights.len()
        )));
    }
    if let Some(w) = weights.iter().find(|w| w.len() != cells.len()) {
        return Err(BackendError::Invalid(format!(
            "reduce_pairs: {} weights for {} cells",
            w.len(),
            cells.len()
        )));
    }
    let n_pad = n.div_ceil(BLOCK) * BLOCK;
    let mut out = vec![0f64; n * n];
    let mut sums = vec![[[0f64; BLOCK]; BLOCK]; blocks.len()];
    let mut buf = vec![0f32; n_pad * CHUNK_CELLS];
    // Analytic lobes in separable form (alpha + G(c) beta[i][j]), rounded once to f32
    // as the GPU kernel reads them: a value is then two products and a sum per cell.
    let seps: Vec<Option<(f32, Vec<f32>)>> = cpu.install(|| {
        lobes
            .par_iter()
            .map(|l| match l {
                Lobe::Analytic(p) => {
                    let sp = SeparableLobe::new(&cpu.tables, p);
                    Some((sp.alpha as f32, sp.beta.iter().map(|&b| b as f32).collect()))
                }
                Lobe::Measured { .. } | Lobe::Neural { .. } => None,
            })
            .collect()
    });
    let total = cells.len() as u64;
    let mut done = 0u64;
    for (k, cc) in cells.chunks(CHUNK_CELLS).enumerate() {
        let len = cc.len();
        let at = k * CHUNK_CELLS;
        let scale: Vec<Vec<f64>> = weights
            .iter()
            .map(|w| w[at..at + len].iter().map(|&w| op.row_scale(w)).collect())
            .collect();
        // Per group and cell, as the GPU's cell texel: (i * 90 + j, G(c) x row scale, row
        // scale), f64 rounded once to f32.
        let factors: Vec<Vec<(usize, f32, f32)>> = scale
            .iter()
            .map(|sc| {
                cc.iter()
                    .zip(sc)
                    .map(|(&c, &s)| {
                        let (e, g) = cpu.tables.cell_factor(c as usize);
                        (e, (g * s) as f32, s as f32)
                    })
                    .collect()
            })
            .collect();
        cpu.install(|| -> Result<(), BackendError> {
            let mut other = Vec::new();
            let mut analytic = Vec::new();
            for (row, ((lobe, sep), &g)) in buf[..n * len]
                .chunks_mut(len)
                .zip(lobes.iter().zip(&seps).zip(group))
            {
                match sep {
                    Some(sep) => analytic.push((sep, &factors[g], row)),
                    None => other.push((lobe, Some(&scale[g][..]), row)),
                }
            }
            analytic
                .into_par_iter()
                .for_each(|((alpha, beta), f, row)| fill_analytic(beta, *alpha, f, row));
            fill_rows_each(other, cc)?;
            buf[n * len..n_pad * len].fill(0.0);
            let rows: Vec<&[f32]> = buf[..n_pad * len].chunks(len).collect();
            sums.par_iter_mut()
                .zip(blocks.par_iter())
                .for_each(|(acc, &[bi, bj])| {
                    let a = std::array::from_fn(|r| rows[bi as usize * BLOCK + r]);
                    let b = std::array::from_fn(|q| rows[bj as usize * BLOCK + q]);
                    block_reduce_same_len(op, a, b, acc);
                });
            Ok(())
        })?;
        done += len as u64;
        progress(done, total);
    }
    for (acc, &b) in sums.iter().zip(blocks) {
        add_block(&mut out, n, b, |r, q| acc[r][q]);
    }
    Ok(out)
}

/// Lobes of one pass of [`grams_per_channel`] at most (three channels, padded); above, a
/// pass per channel (the block sums grow with the square of the lobes).
const PER_CHANNEL_PASS_MAX_LOBES: usize = 4096;

/// [`Backend::grams_per_channel`] on the CPU: one pass for the three channels, each
/// channel's lobes with its own weights (the same bits as [`Backend::gram`] per channel).
pub(super) fn grams_per_channel(
    cpu: &CpuBackend,
    lobes: [Vec<Lobe>; 3],
    cells: [&CellSet; 3],
    basis: usize,
    progress: Progress<'_>,
) -> Result<[Vec<f64>; 3], BackendError> {
    let n = lobes[0].len();
    let n_pad = n.div_ceil(BLOCK) * BLOCK;
    let same_cells = cells.iter().all(|c| c.cells == cells[0].cells);
    if lobes.iter().any(|l| l.len() != n) || !same_cells {
        return Err(BackendError::Invalid(
            "grams_per_channel: the channels have different lobes counts or cells".into(),
        ));
    }
    if 3 * n_pad > PER_CHANNEL_PASS_MAX_LOBES {
        let mut out: [Vec<f64>; 3] = Default::default();
        for ((o, l), c) in out.iter_mut().zip(&lobes).zip(cells) {
            *o = cpu.gram(l, c, basis, progress)?;
        }
        return Ok(out);
    }
    // Padding: a cheap analytic lobe whose sums are never read.
    const PAD: Lobe = Lobe::Analytic(LobeParams {
        kd: 0.0,
        ks: 0.0,
        f0: 0.0,
        n: 0.0,
    });
    let mut all: Vec<Lobe> = Vec::with_capacity(3 * n_pad);
    let mut group = Vec::with_capacity(3 * n_pad);
    let mut blocks = Vec::new();
    let per = gram_blocks(n, basis);
    for (c, l) in lobes.into_iter().enumerate() {
        all.extend(l);
        all.resize((c + 1) * n_pad, PAD);
        group.resize((c + 1) * n_pad, c);
        let off = (c * n_pad / BLOCK) as u32;
        blocks.extend(per.iter().map(|&[bi, bj]| [bi + off, bj + off]));
    }
    let weights = [&cells[0].weights[..], &cells[1].weights, &cells[2].weights];
    let pass = Pass {
        lobes: &all,
        group: &group,
        weights: &weights,
        cells: &cells[0].cells,
        blocks: &blocks,
        op: PairOp::Dot,
    };
    let big = reduce(cpu, &pass, progress)?;
    let w = 3 * n_pad;
    Ok(std::array::from_fn(|c| {
        let o = c * n_pad;
        let mut g = vec![0.0; n * n];
        for i in 0..n {
            g[i * n..(i + 1) * n].copy_from_slice(&big[(o + i) * w + o..(o + i) * w + o + n]);
        }
        g
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::Nbrdf;
    use crate::merl::{Mask, Weighting};
    use std::sync::Arc;

    /// A network with seeded pseudo-random weights.
    fn net(seed: u64) -> Arc<Nbrdf> {
        Arc::new(crate::brdf::seeded_for_tests(seed))
    }

    /// Channel `c`'s lobes: three networks and two analytic lobes.
    fn lobes(nets: &[Arc<Nbrdf>], c: usize) -> Vec<Lobe> {
        let mut v: Vec<Lobe> = nets
            .iter()
            .map(|n| Lobe::Neural {
                net: n.clone(),
                channel: Some(c),
            })
            .collect();
        for i in 0..2 {
            v.push(Lobe::Analytic(LobeParams {
                kd: 0.1 * (c + 1) as f32,
                ks: 0.2 + 0.1 * i as f32,
                f0: 0.05,
                n: 40.0 * (i + 1) as f32,
            }));
        }
        v
    }

    /// One pass for three channels with their own weights gives each channel's Gram of a
    /// pass of its own, bit for bit.
    #[test]
    fn one_pass_per_channel_is_a_pass_per_channel_to_the_bit() {
        let cpu = CpuBackend::new();
        let nets: Vec<_> = (0..3).map(net).collect();
        let cells = CellSet::new(Mask::Evaluation, Weighting::SolidAngle, 3);
        assert!(cells.len() > CHUNK_CELLS, "more than one chunk");
        let per: [CellSet; 3] = std::array::from_fn(|c| {
            let mut w = cells.clone();
            for (s, x) in w.weights.iter_mut().enumerate() {
                *x *= 1.0 + ((s * (c + 2)) % 7) as f64;
            }
            w
        });
        let all: [Vec<Lobe>; 3] = std::array::from_fn(|c| lobes(&nets, c));
        let n = all[0].len();
        let one = cpu
            .grams_per_channel(all.clone(), [&per[0], &per[1], &per[2]], n, &|_, _| {})
            .unwrap();
        for c in 0..3 {
            let own = cpu.gram(&all[c], &per[c], n, &|_, _| {}).unwrap();
            assert_eq!(one[c], own, "channel {c}");
        }
    }
}
