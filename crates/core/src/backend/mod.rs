//! The compute back-end trait that the algorithms call, and its CPU implementation.
//!
//! Algorithms describe *what* to reduce over the grid ([`Lobe`]s over a [`CellSet`]);
//! a back-end decides *how* (blocked multi-threaded loops in [`cpu`]; GPU kernels in the
//! crate `brdf-basis-gpu`, which implements the same trait). Both stream the grid in chunks of cells so that memory stays bounded
//! whatever the number of cells.

mod blocks;
pub mod cpu;
pub mod weighted;

pub use blocks::*;

use crate::brdf::Nbrdf;
use crate::error::BackendError;
use crate::merl::{CellSet, MerlTable};
use std::sync::Arc;

use crate::brdf::LobeParams;

/// One function on the grid to tabulate or compare.
#[derive(Clone, Debug)]
pub enum Lobe {
    /// An analytic lobe, evaluated where needed.
    Analytic(LobeParams),
    /// A measured table: the mean of the three channels (`channel = None`) or one channel.
    Measured {
        /// The table.
        table: Arc<MerlTable>,
        /// `None`: mean over R, G, B; `Some(c)`: channel c.
        channel: Option<usize>,
    },
    /// A neural BRDF (SPEC 9), evaluated per chunk of cells where needed (never stored
    /// as a whole table): the mean of the three channels (`channel = None`) or one channel.
    Neural {
        /// The network.
        net: Arc<Nbrdf>,
        /// `None`: mean over R, G, B; `Some(c)`: channel c.
        channel: Option<usize>,
    },
}

impl Lobe {
    /// Value at a flat cell, in f64, from the f64 model (the reference for every kernel).
    pub fn eval_f64(&self, tables: &crate::merl::GridTables, cell: usize) -> f64 {
        match self {
            Lobe::Analytic(p) => {
                let (i, j, k) = crate::merl::unflat(cell);
                p.kd as f64 * std::f64::consts::FRAC_1_PI
                    + p.ks as f64 * tables.rho_s(i, j, k, p.f0 as f64, p.n as f64)
            }
            Lobe::Measured { table, channel } => match channel {
                Some(c) => table.value(*c, cell) as f64,
                None => (0..3).map(|c| table.value(c, cell) as f64).sum::<f64>() / 3.0,
            },
            Lobe::Neural { net, channel } => {
                let (th, td, pd) = crate::merl::cell_angles(cell);
                let v = net.eval_f64(th, td, pd);
                match channel {
                    Some(c) => v[*c],
                    None => v.iter().sum::<f64>() / 3.0,
                }
            }
        }
    }

    /// Whether the lobe is analytic (tabulated from its parameters; every other kind is
    /// packed row by row per chunk of cells).
    pub fn is_analytic(&self) -> bool {
        matches!(self, Lobe::Analytic(_))
    }
}

/// Progress reporting for long reductions: called with (done, total) in cells.
pub type Progress<'a> = &'a (dyn Fn(u64, u64) + Sync);

/// A compute back-end.
pub trait Backend: Send + Sync {
    /// Human-readable name (`cpu (2 threads, avx2)`, `gpu: llvmpipe (Vulkan, ...)`).
    fn name(&self) -> String;

    /// Tabulates `lobes` over `cells`: returns `values[l * cells.len() + c]` in f32.
    fn tabulate(&self, lobes: &[Lobe], cells: &[u32]) -> Result<Vec<f32>, BackendError>;

    /// Reduces `op` over `cells` (with their weights) for every lobe pair in the listed
    /// `BLOCK x BLOCK` block pairs; returns the full symmetric `n x n` matrix (f64) with
    /// the entries of those blocks filled and the rest 0.
    fn reduce_pairs(
        &self,
        lobes: &[Lobe],
        cells: &CellSet,
        blocks: &[[u32; 2]],
        op: PairOp,
        progress: Progress<'_>,
    ) -> Result<Vec<f64>, BackendError>;

    /// Weighted pairwise L1 distances `sum_s w_s |L_i(s) - L_j(s)|` over `cells` for all
    /// `i < j`, condensed (row-major upper triangle), accumulated in f64.
    fn pairwise_l1(
        &self,
        lobes: &[Lobe],
        cells: &CellSet,
        progress: Progress<'_>,
    ) -> Result<Vec<f64>, BackendError> {
        let full = self.reduce_pairs(
            lobes,
            cells,
            &blocks::all_blocks(lobes.len()),
            PairOp::L1,
            progress,
        )?;
        Ok(blocks::condensed_of(&full, lobes.len()))
    }

    /// Weighted Gram quantities `sum_s w_s L_i(s) L_j(s)` for every pair with `i < basis`
    /// or `j < basis`, and the diagonal: full `n x n`, f64.
    fn gram(
        &self,
        lobes: &[Lobe],
        cells: &CellSet,
        basis: usize,
        progress: Progress<'_>,
    ) -> Result<Vec<f64>, BackendError> {
        self.reduce_pairs(
            lobes,
            cells,
            &blocks::gram_blocks(lobes.len(), basis),
            PairOp::Dot,
            progress,
        )
    }

    /// [`Backend::gram`] of three channels' lobes (the same count each), each over its own
    /// weights of the same cells (SPEC 11's shared weights differ per channel). By default
    /// a pass per channel; the CPU back-end makes them in one pass (a network then runs once
    /// per cell for its three channels), the same bits.
    fn grams_per_channel(
        &self,
        lobes: [Vec<Lobe>; 3],
        cells: [&CellSet; 3],
        basis: usize,
        progress: Progress<'_>,
    ) -> Result<[Vec<f64>; 3], BackendError> {
        let mut out: [Vec<f64>; 3] = Default::default();
        for ((o, l), c) in out.iter_mut().zip(&lobes).zip(cells) {
            *o = self.gram(l, c, basis, progress)?;
        }
        Ok(out)
    }

    /// Every target's weighted normal equations (SPEC 11) for a fit by `basis` plus the
    /// Lambertian column, over `cells`, under `weight` ([`weighted`]). By default the f64
    /// reference ([`weighted::reference`]); the GPU back-end runs its kernel. `progress`
    /// is called with (cells done, cells) after each chunk of cells.
    fn weighted_systems(
        &self,
        basis: &[Lobe],
        targets: &[Lobe],
        cells: &CellSet,
        weight: weighted::TargetWeight,
        progress: Progress<'_>,
    ) -> Result<weighted::WeightedSystems, BackendError> {
        weighted::reference(self, basis, targets, cells, weight, progress)
    }

    /// [`Backend::weighted_systems`] of three channels (`basis[c]`, `targets[c]`, the same
    /// counts each) over the same cells. By default the f64 reference in one pass
    /// ([`weighted::reference_per_channel`]: a network runs once per cell for its three
    /// channels; the same bits as [`weighted::reference`] per channel); a back-end that
    /// overrides [`Backend::weighted_systems`] overrides this too (the GPU back-end: its
    /// kernel per channel).
    fn weighted_systems_per_channel(
        &self,
        basis: [&[Lobe]; 3],
        targets: [&[Lobe]; 3],
        cells: &CellSet,
        weight: weighted::TargetWeight,
        progress: Progress<'_>,
    ) -> Result<[weighted::WeightedSystems; 3], BackendError> {
        weighted::reference_per_channel(self, basis, targets, cells, weight, progress)
    }

    /// The LDR FLIP error map ([`crate::eval::flip`]) of every pair `(reference, test)` of
    /// 8-bit sRGB images (interleaved RGB, `width x height`, row-major) with the filters
    /// of `kernels`, every pixel scored. By default the CPU implementation, pairs in
    /// parallel; the GPU back-end scores the batch on its device.
    fn flip_maps(
        &self,
        kernels: &crate::eval::flip::FlipKernels,
        pairs: &[(&[u8], &[u8])],
        width: usize,
        height: usize,
    ) -> Result<Vec<Vec<f32>>, BackendError> {
        crate::eval::flip::flip_maps(kernels, pairs, width, height)
            .map_err(|e| BackendError::Invalid(e.to_string()))
    }

    /// Batched accelerated projected-gradient NNLS for many targets sharing one Gram
    /// matrix (the CPU solver by default; the GPU back-end runs its f32 kernel).
    fn nnls_pgd(
        &self,
        batch: &crate::nnls::GramBatch<'_>,
        params: &crate::nnls::pgd::PgdParams,
    ) -> Result<Vec<crate::nnls::NnlsSolution>, BackendError> {
        crate::nnls::pgd::solve_batch(batch, params)
            .map_err(|e| BackendError::Invalid(e.to_string()))
    }
}

/// Number of condensed entries for `n` items.
pub(crate) fn condensed_len(n: usize) -> usize {
    n * n.saturating_sub(1) / 2
}

/// Condensed index of `(i, j)`, `i < j < n`.
#[inline]
pub fn condensed_index(n: usize, i: usize, j: usize) -> usize {
    debug_assert!(i < j && j < n);
    i * n - i * (i + 1) / 2 + (j - i - 1)
}
