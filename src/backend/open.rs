//! Choosing a back-end: `auto` (a hardware GPU when there is one, else the CPU
//! back-end), `gpu` (any adapter, software ones included) or `cpu`.

use super::cpu::CpuBackend;
use super::Backend;
use crate::backend::gpu::{GpuBackend, GpuContext};
use crate::error::GpuError;

/// Which back-end to run on (spellings `auto`, `gpu`, `cpu`: [`BackendChoice::as_str`],
/// which [`Display`](std::fmt::Display) writes; the command line parses them by the
/// `clap::ValueEnum` derive of the `cli` feature, whose names a unit test checks).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
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
        BackendChoice::Gpu => Ok(Box::new(GpuBackend::new()?)),
        BackendChoice::Auto => match GpuContext::new() {
            Ok(ctx) if !ctx.is_software() => Ok(Box::new(GpuBackend::with_context(ctx)?)),
            _ => Ok(Box::new(CpuBackend::new())),
        },
    }
}

#[cfg(all(test, feature = "cli"))]
mod tests {
    use super::*;

    #[test]
    fn choices_print_as_their_flag_values() {
        use clap::ValueEnum;
        for c in BackendChoice::value_variants() {
            let name = c.to_possible_value().expect("named").get_name().to_string();
            assert_eq!(c.to_string(), name);
        }
    }
}
