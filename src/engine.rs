//! Choosing a back-end: `auto` (a hardware GPU when there is one, else the CPU
//! back-end), `gpu` (any adapter, software ones included) or `cpu`.

use crate::backend::cpu::CpuBackend;
use crate::backend::Backend;
use crate::error::GpuError;
use crate::gpu::{GpuBackend, GpuContext};

/// Which back-end to run on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
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

impl std::str::FromStr for BackendChoice {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "auto" => Ok(Self::Auto),
            "gpu" => Ok(Self::Gpu),
            "cpu" => Ok(Self::Cpu),
            _ => Err(format!("unknown backend `{s}` (expected auto, gpu or cpu)")),
        }
    }
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
