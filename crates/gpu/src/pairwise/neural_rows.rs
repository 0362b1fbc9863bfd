//! Neural rows of a pairwise reduction, written on the device: per chunk of cells the
//! neural kernel ([`crate::neural`]) evaluates the networks at the chunk's
//! cells and stores their row blocks, scaled by the cells' row scales, straight into the
//! value texture's packed region (after the measured tables, [`super::RowLayout`]), where
//! the pairwise kernel reads them: nothing per cell goes through the host but the cell
//! indices and row scales.

use super::{PairPlan, RowLayout};
use crate::neural::{lobe_rows, NeuralCells, NeuralKernel, NeuralRows, NeuralTarget};
use crate::GpuContext;
use brdf_basis_core::backend::{Lobe, PairOp};
use brdf_basis_core::error::GpuError;

/// The neural row blocks of one reduction, uploaded once, and the per-chunk buffers.
pub(super) struct NeuralPass<'a> {
    kernel: &'a NeuralKernel,
    rows: NeuralRows,
    cells: NeuralCells,
    view: wgpu::TextureView,
    base: usize,
    row_stride: usize,
}

impl<'a> NeuralPass<'a> {
    /// The pass for `layout`'s neural lobes (`None` without any), writing into `texture`
    /// (the value texture of `plan`, created with storage binding).
    pub(super) fn new(
        ctx: &GpuContext,
        kernel: &'a NeuralKernel,
        lobes: &[Lobe],
        layout: &RowLayout,
        plan: &PairPlan,
        texture: &wgpu::Texture,
    ) -> Result<Option<Self>, GpuError> {
        if layout.neural.is_empty() {
            return Ok(None);
        }
        let (nets, rows) = lobe_rows(layout.neural.iter().map(|&i| &lobes[i]));
        let nets: Vec<&[f32]> = nets.iter().map(|n| n.weights()).collect();
        let mut padded: Vec<Option<_>> = rows.into_iter().map(Some).collect();
        padded.resize(padded.len().div_ceil(4) * 4, None);
        let first_block = (layout.neural_start - layout.measured_start) / 4;
        Ok(Some(Self {
            kernel,
            rows: kernel.prepare(ctx, &nets, &padded)?,
            cells: NeuralCells::new(ctx, plan.chunk),
            view: texture.create_view(&wgpu::TextureViewDescriptor::default()),
            base: plan.measured_base() + first_block * plan.row_stride,
            row_stride: plan.row_stride,
        }))
    }

    /// Evaluates the neural rows at the chunk's cells `cc` (weights `cw`, scaled as `op`
    /// scales rows) into the value texture: submitted before the chunk's reductions.
    pub(super) fn chunk(
        &mut self,
        ctx: &GpuContext,
        op: PairOp,
        cc: &[u32],
        cw: &[f64],
    ) -> Result<(), GpuError> {
        let scales: Vec<f32> = cw.iter().map(|&w| op.row_scale(w) as f32).collect();
        self.cells.write(ctx, cc, Some(&scales));
        let mut enc = ctx.encoder();
        let target = NeuralTarget {
            view: &self.view,
            base: self.base,
            row_stride: self.row_stride,
        };
        self.kernel
            .encode(ctx, &mut enc, &self.rows, &self.cells, target);
        crate::neural::submit(ctx, enc)
    }
}
