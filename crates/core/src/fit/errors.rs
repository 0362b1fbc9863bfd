//! A fit's errors on the grid (`fit::fit`): per channel and target, the residual, MAE,
//! the target's L1 norm and energy, from separable cell moments when every lobe is
//! analytic, else cell by cell in f64.

use super::{channel_lobe, separable_lobes, LAMBERTIAN};
use crate::backend::cpu::CpuBackend;
use crate::backend::Lobe;
use crate::collection::Collection;
use crate::merl::{CellSet, GridTables};
use crate::nnls::NnlsSolution;
use crate::separable::{CellMoments, SeparableLobe};
use rayon::prelude::*;

/// Grid errors of one channel's fit of one target.
pub(crate) struct ChannelErrors {
    /// `sqrt(sum_s w_s r_s^2)`.
    pub(crate) residual: f64,
    /// `sum_s w_s |r_s|`.
    pub(crate) mae: f64,
    /// `sum_s w_s |b_s|` (the target's own weighted L1 norm).
    pub(crate) l1: f64,
    /// `sum_s w_s b_s^2` (the target's weighted energy).
    pub(crate) energy: f64,
}

/// The errors of channel `c` of every target's fit `sols` on the grid, in f64: from the
/// separable cell moments when every lobe is analytic (and `moments` were built), else
/// cell by cell.
#[allow(clippy::too_many_arguments)]
pub(super) fn grid_errors(
    coll: &Collection,
    basis: &[usize],
    targets: &[usize],
    sols: &[NnlsSolution],
    cells: &CellSet,
    moments: Option<&CellMoments>,
    c: usize,
    cpu: &CpuBackend,
) -> Vec<ChannelErrors> {
    let mut lobes = vec![LAMBERTIAN];
    lobes.extend(
        basis
            .iter()
            .map(|&b| channel_lobe(&coll.materials()[b].data, c)),
    );
    match (moments, separable_lobes(&lobes)) {
        (Some(mom), Some(cols)) => {
            // Every lobe analytic: one multiply-add per cell from per-(i, j) tables.
            let refs: Vec<&SeparableLobe> = cols.iter().collect();
            let t = GridTables::new();
            targets
                .par_iter()
                .zip(sols)
                .map(|(&ti, s)| {
                    let target = match channel_lobe(&coll.materials()[ti].data, c) {
                        Lobe::Analytic(tp) => SeparableLobe::new(&t, &tp),
                        Lobe::Measured { .. } | Lobe::Neural { .. } => {
                            unreachable!("moments exist only when every material is analytic")
                        }
                    };
                    let e = mom.errors(&SeparableLobe::combination(&refs, &s.x), &target);
                    let zero = mom.errors(&SeparableLobe::combination(&[], &[]), &target);
                    ChannelErrors {
                        residual: e.squared.sqrt(),
                        mae: e.absolute,
                        l1: zero.absolute,
                        energy: zero.squared,
                    }
                })
                .collect()
        }
        _ => {
            // On the grid, in f64, cell by cell, a block of cells at a time (no column of the
            // whole grid in f64: megabytes each, a page fault and a clearing per page), each
            // sum carried from block to block in cell order: the bits of one pass.
            const BLOCK: usize = 1 << 13;
            let sources: Vec<_> = lobes
                .iter()
                .map(|l| cpu.block_source(l, &cells.cells))
                .collect();
            let target_lobes: Vec<Lobe> = targets
                .iter()
                .map(|&t| channel_lobe(&coll.materials()[t].data, c))
                .collect();
            let target_sources: Vec<_> = target_lobes
                .iter()
                .map(|l| cpu.block_source(l, &cells.cells))
                .collect();
            let mut sums = vec![[0.0; 4]; targets.len()];
            for (bi, (cc, w)) in cells
                .cells
                .chunks(BLOCK)
                .zip(cells.weights.chunks(BLOCK))
                .enumerate()
            {
                let off = bi * BLOCK;
                let cols: Vec<Vec<f64>> = sources
                    .iter()
                    .map(|s| cpu.block_values(s, cc, off))
                    .collect();
                let refs: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
                sums.par_iter_mut()
                    .zip(&target_sources)
                    .zip(sols)
                    .for_each_init(Vec::new, |fit, ((acc, src), s)| {
                        let b = cpu.block_values(src, cc, off);
                        cell_error_sums(&refs, &s.x, &b, w, acc, fit);
                    });
            }
            sums.into_iter()
                .map(|[sq, ab, l1, energy]| ChannelErrors {
                    residual: sq.sqrt(),
                    mae: ab,
                    l1,
                    energy,
                })
                .collect()
        }
    }
}

/// The grid error sums of the combination `sum_k x_k cols_k` against the target values
/// `b`, cell by cell in f64, with cell weights `w`: `[sum w r^2, sum w |r|, sum w |b|,
/// sum w b^2]`, carried on over the cells given (blocks of cells in cell order give the
/// bits of one pass over all of them). The fitted values are formed column by column in
/// `fit` (per cell the products added in column order: a sum over the columns, the same
/// bits; the loops over cells vectorise).
fn cell_error_sums(
    cols: &[&[f64]],
    x: &[f64],
    b: &[f64],
    w: &[f64],
    s: &mut [f64; 4],
    fit: &mut Vec<f64>,
) {
    fit.clear();
    fit.resize(b.len(), -0.0);
    add_columns(fit, cols.iter().zip(x).map(|(c, &a)| (&c[..b.len()], a)));
    let [mut sq, mut ab, mut l1, mut energy] = *s;
    for ((&bv, &w), &fitv) in b.iter().zip(w).zip(fit.iter()) {
        let r = fitv - bv;
        sq += w * r * r;
        ab += w * r.abs();
        l1 += w * bv.abs();
        energy += w * bv * bv;
    }
    *s = [sq, ab, l1, energy];
}

/// `fit[i] += a * col[i]` for each `(col, a)` in order, per cell the same additions in the
/// same order as one column at a time (so the same bits), four columns per pass over
/// `fit` (a quarter of the passes through memory; the loop over cells vectorises). A
/// column shorter than `fit` leaves the cells past its end as they are.
pub(crate) fn add_columns<'a>(fit: &mut [f64], cols: impl Iterator<Item = (&'a [f64], f64)>) {
    let cols: Vec<(&[f64], f64)> = cols.collect();
    for group in cols.chunks(4) {
        let len = group
            .iter()
            .map(|(c, _)| c.len())
            .min()
            .unwrap_or(0)
            .min(fit.len());
        match *group {
            [(c0, a0), (c1, a1), (c2, a2), (c3, a3)] => {
                for (i, f) in fit[..len].iter_mut().enumerate() {
                    *f = *f + a0 * c0[i] + a1 * c1[i] + a2 * c2[i] + a3 * c3[i];
                }
            }
            _ => {
                for &(c, a) in group {
                    for (f, &v) in fit.iter_mut().zip(c) {
                        *f += a * v;
                    }
                }
                continue;
            }
        }
        // Cells past the shortest column: one column at a time, as before.
        for &(c, a) in group {
            for (f, &v) in fit[len..].iter_mut().zip(c.get(len..).unwrap_or(&[])) {
                *f += a * v;
            }
        }
    }
}
