//! Choosing a back-end: `auto` (on a hardware GPU, each operation on the back-end
//! measured faster for it: [`AutoBackend`]; else the CPU back-end), `gpu` (any adapter,
//! software ones included) or `cpu`.

use crate::backend::cpu::CpuBackend;
#[cfg(feature = "gpu")]
use crate::backend::gpu::{GpuBackend, GpuContext};
use crate::backend::Backend;
#[cfg(feature = "gpu")]
use crate::backend::{Lobe, PairOp, Progress};
#[cfg(feature = "gpu")]
use crate::error::BackendError;
use crate::error::GpuError;
#[cfg(feature = "gpu")]
use crate::merl::CellSet;

/// Which back-end [`AutoBackend`] runs each operation on, and the measurement behind it
/// (NVIDIA H200 and its 16 host cores, scripts/gpu-bench.sh, docs/performance.md):
/// `(operation, back-end, why)`.
pub const AUTO_ROUTES: [(&str, &str, &str); 5] = [
    (
        "pairwise reductions of analytic and measured lobes (BRDF_it, Gram)",
        "gpu",
        "11.8x the CPU back-end at N = 1,000; 16x at N = 10,000",
    ),
    (
        "pairwise reductions with neural lobes",
        "cpu",
        "the CPU back-end's AVX-512 network kernel: BRDF_it of the 100 MERL networks 0.17 s against 0.28 s",
    ),
    (
        "batched NNLS (projected gradient)",
        "gpu",
        "1.43x the CPU back-end's targets/s at 100,000 x 10",
    ),
    (
        "weighted systems (SPEC 11 fits)",
        "gpu",
        "10,000 NBRDF targets x 3 channels: 639 targets/s against 18",
    ),
    (
        "tabulation to host memory",
        "cpu",
        "host-bound on the GPU (the readback): 0.49 s against the CPU back-end's 0.33 s for 100 materials x RGB",
    ),
];

/// `auto` on a machine with a hardware GPU: pairwise reductions of analytic and measured
/// lobes, weighted systems and batched NNLS on the GPU; neural lobes and tabulation into host memory on the
/// CPU ([`AUTO_ROUTES`]). Results follow the
/// determinism contract either way (docs/determinism.md).
#[cfg(feature = "gpu")]
#[derive(Debug)]
pub struct AutoBackend {
    gpu: GpuBackend,
    cpu: CpuBackend,
}

#[cfg(feature = "gpu")]
impl AutoBackend {
    /// Both back-ends, the GPU one on `ctx`.
    pub fn with_context(ctx: GpuContext) -> Result<Self, GpuError> {
        Ok(Self {
            gpu: GpuBackend::with_context(ctx)?,
            cpu: CpuBackend::new(),
        })
    }

    /// The GPU back-end.
    pub fn gpu(&self) -> &GpuBackend {
        &self.gpu
    }
}

#[cfg(feature = "gpu")]
impl Backend for AutoBackend {
    fn name(&self) -> String {
        format!(
            "auto: {} (pairwise, weighted systems, NNLS) and {} (tabulation, neural lobes)",
            self.gpu.name(),
            self.cpu.name()
        )
    }

    fn tabulate(&self, lobes: &[Lobe], cells: &[u32]) -> Result<Vec<f32>, BackendError> {
        self.cpu.tabulate(lobes, cells)
    }

    fn reduce_pairs(
        &self,
        lobes: &[Lobe],
        cells: &CellSet,
        blocks: &[[u32; 2]],
        op: PairOp,
        progress: Progress<'_>,
    ) -> Result<Vec<f64>, BackendError> {
        match lobes.iter().any(|l| matches!(l, Lobe::Neural { .. })) {
            true => self.cpu.reduce_pairs(lobes, cells, blocks, op, progress),
            false => self.gpu.reduce_pairs(lobes, cells, blocks, op, progress),
        }
    }

    fn weighted_systems(
        &self,
        basis: &[Lobe],
        targets: &[Lobe],
        cells: &CellSet,
        weight: crate::backend::weighted::TargetWeight,
        progress: Progress<'_>,
    ) -> Result<crate::backend::weighted::WeightedSystems, BackendError> {
        self.gpu
            .weighted_systems(basis, targets, cells, weight, progress)
    }

    fn weighted_systems_per_channel(
        &self,
        basis: [&[Lobe]; 3],
        targets: [&[Lobe]; 3],
        cells: &CellSet,
        weight: crate::backend::weighted::TargetWeight,
        progress: Progress<'_>,
    ) -> Result<[crate::backend::weighted::WeightedSystems; 3], BackendError> {
        self.gpu
            .weighted_systems_per_channel(basis, targets, cells, weight, progress)
    }

    fn grams_per_channel(
        &self,
        lobes: [Vec<Lobe>; 3],
        cells: [&CellSet; 3],
        basis: usize,
        progress: Progress<'_>,
    ) -> Result<[Vec<f64>; 3], BackendError> {
        match lobes
            .iter()
            .flatten()
            .any(|l| matches!(l, Lobe::Neural { .. }))
        {
            true => self.cpu.grams_per_channel(lobes, cells, basis, progress),
            false => self.gpu.grams_per_channel(lobes, cells, basis, progress),
        }
    }

    fn nnls_pgd(
        &self,
        batch: &crate::nnls::GramBatch<'_>,
        params: &crate::nnls::pgd::PgdParams,
    ) -> Result<Vec<crate::nnls::NnlsSolution>, BackendError> {
        self.gpu.nnls_pgd(batch, params)
    }
}

/// Which back-end to run on (spellings `auto`, `gpu`, `cpu`: [`BackendChoice::as_str`],
/// which [`Display`](std::fmt::Display) writes; the command line's names are the same,
/// which a unit test of `brdf-basis-cli` checks).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BackendChoice {
    /// On a hardware GPU, each operation on the back-end measured faster for it
    /// (`brdf-basis info` prints which); else the CPU back-end (faster than a software
    /// rasteriser: ~18 G abs-diffs/s on 2 cores against ~4 for lavapipe).
    #[default]
    Auto,
    /// The GPU back-end on the best adapter, software ones (lavapipe) included (refused
    /// when the library is built without its `gpu` feature).
    Gpu,
    /// The multi-threaded CPU back-end.
    Cpu,
}

impl BackendChoice {
    /// The command-line spelling: `auto`, `gpu` or `cpu`.
    pub fn as_str(self) -> &'static str {
        match self {
            BackendChoice::Auto => "auto",
            BackendChoice::Gpu => "gpu",
            BackendChoice::Cpu => "cpu",
        }
    }
}

impl std::fmt::Display for BackendChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Opens the chosen back-end.
pub fn open(choice: BackendChoice) -> Result<Box<dyn Backend>, GpuError> {
    match choice {
        BackendChoice::Cpu => Ok(Box::new(CpuBackend::new())),
        #[cfg(feature = "gpu")]
        BackendChoice::Gpu => Ok(Box::new(GpuBackend::new()?)),
        #[cfg(feature = "gpu")]
        BackendChoice::Auto => match GpuContext::new() {
            Ok(ctx) if !ctx.is_software() => Ok(Box::new(AutoBackend::with_context(ctx)?)),
            _ => Ok(Box::new(CpuBackend::new())),
        },
        #[cfg(not(feature = "gpu"))]
        BackendChoice::Gpu => Err(GpuError::Device(
            "this build has no GPU back-end (brdf-basis without its `gpu` feature)".into(),
        )),
        #[cfg(not(feature = "gpu"))]
        BackendChoice::Auto => Ok(Box::new(CpuBackend::new())),
    }
}
