//! [`GpuBackend`]: the [`Backend`] trait on a wgpu device.

use super::neural::lobe_rows;
use super::pairwise::{KernelShape, PairPlan, PairwiseKernel, PlanLimits, RowLayout};
use super::tabulate::TabulateKernel;
use super::GpuContext;
use brdf_basis_core::backend::{Backend, Lobe, PairOp, Progress};
use brdf_basis_core::brdf::LobeParams;
use brdf_basis_core::error::{BackendError, GpuError};
use brdf_basis_core::merl::CellSet;
use brdf_basis_core::nnls::pgd::PgdParams;
use brdf_basis_core::nnls::{GramBatch, NnlsSolution};

/// The GPU back-end: a context and its compiled kernels, built once and reused.
#[derive(Debug)]
pub struct GpuBackend {
    ctx: GpuContext,
    tab: TabulateKernel,
    pair: PairwiseKernel,
    pgd: super::pgd::PgdKernel,
    weighted: super::weighted::WeightedKernel,
    flip: super::flip::FlipKernel,
}

impl GpuBackend {
    /// Opens the default adapter and compiles the kernels.
    pub fn new() -> Result<Self, GpuError> {
        Self::with_context(GpuContext::new()?)
    }

    /// Uses a caller's context (device and queue), compiling the kernels on it.
    pub fn with_context(ctx: GpuContext) -> Result<Self, GpuError> {
        let tab = TabulateKernel::new(&ctx)?;
        let pair = PairwiseKernel::new();
        let pgd = super::pgd::PgdKernel::new(&ctx)?;
        Ok(Self {
            ctx,
            tab,
            pair,
            pgd,
            weighted: super::weighted::WeightedKernel::new(),
            flip: super::flip::FlipKernel::default(),
        })
    }

    /// Drops device memory kept between calls (the pairwise kernel's value texture).
    pub fn release_memory(&self) {
        self.pair.release_memory();
    }

    /// The context.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// The pairwise plan this back-end would use for `n` materials, `n_measured` of them
    /// measured, over `cells` cells.
    pub fn plan(&self, n: usize, n_measured: usize, cells: usize) -> Result<PairPlan, GpuError> {
        let rows = RowLayout::rows_for(n - n_measured, n_measured);
        PairPlan::new(
            n - n_measured,
            n_measured,
            cells,
            &PlanLimits::of(&self.ctx),
            KernelShape::choose(rows, self.ctx.is_software()),
        )
    }
}

impl GpuBackend {
    /// The pairwise plan for `lobes` over `cells` cells: [`Self::plan`] with the packed
    /// rows of their [`RowLayout`] (measured tables, then neural rows from a whole texel
    /// on).
    pub fn plan_for(&self, lobes: &[Lobe], cells: usize) -> Result<PairPlan, GpuError> {
        let layout = RowLayout::new(lobes);
        PairPlan::new(
            layout.analytic.len(),
            layout.packed_rows(),
            cells,
            &PlanLimits::of(&self.ctx),
            KernelShape::choose(layout.n_rows, self.ctx.is_software()),
        )
    }
}

impl Backend for GpuBackend {
    fn name(&self) -> String {
        format!(
            "gpu: {} ({:?}, {})",
            self.ctx.info.name, self.ctx.info.backend, self.ctx.info.driver
        )
    }

    fn tabulate(&self, lobes: &[Lobe], cells: &[u32]) -> Result<Vec<f32>, BackendError> {
        // Analytic lobes only (the common case): straight into the rows, no second copy.
        let all_analytic: Option<Vec<LobeParams>> = lobes
            .iter()
            .map(|l| match l {
                Lobe::Analytic(p) => Some(*p),
                Lobe::Measured { .. } | Lobe::Neural { .. } => None,
            })
            .collect();
        if let Some(params) = all_analytic {
            return Ok(self.tab.tabulate(&self.ctx, &params, cells)?);
        }
        let analytic: Vec<(usize, LobeParams)> = lobes
            .iter()
            .enumerate()
            .filter_map(|(i, l)| {
                if let Lobe::Analytic(p) = l {
                    Some((i, *p))
                } else {
                    None
                }
            })
            .collect();
        let params: Vec<LobeParams> = analytic.iter().map(|a| a.1).collect();
        let vals = self.tab.tabulate(&self.ctx, &params, cells)?;
        let n = cells.len();
        let mut out = vec![0f32; lobes.len() * n];
        for (r, (i, _)) in analytic.iter().enumerate() {
            out[i * n..(i + 1) * n].copy_from_slice(&vals[r * n..(r + 1) * n]);
        }
        // Neural rows by the neural kernel, every network once per row block.
        let neural: Vec<usize> = (0..lobes.len())
            .filter(|&i| matches!(lobes[i], Lobe::Neural { .. }))
            .collect();
        if !neural.is_empty() {
            let (nets, rows) = lobe_rows(neural.iter().map(|&i| &lobes[i]));
            let weights: Vec<&[f32]> = nets.iter().map(|w| w.weights()).collect();
            let vals = self
                .pair
                .neural_kernel(&self.ctx)?
                .tabulate(&self.ctx, &weights, &rows, cells)?;
            if neural.len() == lobes.len() {
                // Neural lobes only: the kernel's rows are the output.
                return Ok(vals);
            }
            for (r, &i) in neural.iter().enumerate() {
                out[i * n..(i + 1) * n].copy_from_slice(&vals[r * n..(r + 1) * n]);
            }
        }
        // Measured rows on the host, per run of cells.
        const RUN: usize = 1 << 14;
        let mut runs: Vec<Vec<(&Lobe, &mut [f32])>> =
            (0..n.div_ceil(RUN)).map(|_| Vec::new()).collect();
        for (row, l) in out.chunks_mut(n.max(1)).zip(lobes) {
            if let Lobe::Measured { .. } = l {
                for (run, part) in runs.iter_mut().zip(row.chunks_mut(RUN)) {
                    run.push((l, part));
                }
            }
        }
        {
            use rayon::prelude::*;
            runs.into_par_iter()
                .zip(cells.par_chunks(RUN))
                .try_for_each(|(rows, cc)| {
                    brdf_basis_core::backend::cpu::fill_rows(rows, cc, None)
                })?;
        }
        Ok(out)
    }

    fn reduce_pairs(
        &self,
        lobes: &[Lobe],
        cells: &CellSet,
        blocks: &[[u32; 2]],
        op: PairOp,
        progress: Progress<'_>,
    ) -> Result<Vec<f64>, BackendError> {
        let plan = self.plan_for(lobes, cells.len())?;
        Ok(self
            .pair
            .run(&self.ctx, lobes, cells, blocks, op, &plan, progress)?)
    }

    fn weighted_systems_per_channel(
        &self,
        basis: [&[Lobe]; 3],
        targets: [&[Lobe]; 3],
        cells: &CellSet,
        weight: brdf_basis_core::backend::weighted::TargetWeight,
        progress: Progress<'_>,
    ) -> Result<[brdf_basis_core::backend::weighted::WeightedSystems; 3], BackendError> {
        let [a, b, c] =
            [0, 1, 2].map(|c| self.weighted_systems(basis[c], targets[c], cells, weight, progress));
        Ok([a?, b?, c?])
    }

    fn weighted_systems(
        &self,
        basis: &[Lobe],
        targets: &[Lobe],
        cells: &CellSet,
        weight: brdf_basis_core::backend::weighted::TargetWeight,
        progress: Progress<'_>,
    ) -> Result<brdf_basis_core::backend::weighted::WeightedSystems, BackendError> {
        Ok(self.weighted.run(
            &self.ctx,
            &self.tab,
            || self.pair.neural_kernel(&self.ctx),
            basis,
            targets,
            cells,
            weight,
            progress,
        )?)
    }

    fn flip_maps(
        &self,
        kernels: &brdf_basis_core::eval::flip::FlipKernels,
        pairs: &[(&[u8], &[u8])],
        width: usize,
        height: usize,
    ) -> Result<Vec<Vec<f32>>, BackendError> {
        Ok(self.flip.maps(&self.ctx, kernels, pairs, width, height)?)
    }

    fn nnls_pgd(
        &self,
        batch: &GramBatch<'_>,
        params: &PgdParams,
    ) -> Result<Vec<NnlsSolution>, BackendError> {
        if batch.m() > brdf_basis_core::nnls::pgd::PGD_KERNEL_COLUMNS {
            return brdf_basis_core::nnls::pgd::solve_batch(batch, params)
                .map_err(|e| BackendError::Invalid(e.to_string()));
        }
        Ok(self.pgd.solve_batch(&self.ctx, batch, params)?)
    }
}
