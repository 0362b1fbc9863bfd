//! Choosing a back-end: `auto` (a hardware GPU when there is one, else the CPU
//! back-end), `gpu` (any adapter, software ones included) or `cpu`.

use crate::backend::cpu::CpuBackend;
use crate::backend::Backend;
use crate::error::GpuError;
use crate::gpu::{GpuBackend, GpuContext};

/// Which back-end to run on (spellings `auto`, `gpu`, `cpu` from the `clap::ValueEnum`
/// derive, the one parser of option values).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum BackendChoice {
    /// A hardware GPU if there is one, else the CPU back-end (faster than a software
    /// rasteriser: ~18 G abs-diffs/s on 2 cores against ~4 for lavapipe).
    #[default]
    Auto,
    /// The GPU back-end on the best adapter, software ones (lavapipe) included.
    Gpu,
    /// The multi-threaded CPU back-end.
    Cpu,
}

/// Opens the chosen back-end.
pub fn open_backend(choice: BackendChoice) -> Result<Box<dyn Backend>, GpuError> {
    match choice {
        BackendChoice::Cpu => Ok(Box::new(CpuBackend::new())),
        BackendChoice::Gpu => Ok(Box::new(GpuBackend::new()?)),
        BackendChoice::Auto => match GpuContext::new() {
            Ok(ctx) if !ctx.is_software() => Ok(Box::new(GpuBackend::with_context(ctx)?)),
            _ => Ok(Box::new(CpuBackend::new())),
        },
    }
}
