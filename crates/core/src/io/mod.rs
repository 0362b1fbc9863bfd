//! File input and output, written through [`crate::atomic`]: `.npy` ([`npy`]), the
//! sidecar of a saved matrix ([`sidecar`]), saved matrices written and loaded with their
//! checks ([`saved`]), tile merging ([`merge`]), read-only memory maps ([`mmap`]), JSON and images.

mod error;
pub mod image;
pub mod json;
pub mod merge;
pub mod mmap;
pub mod npy;
pub mod saved;
pub mod sidecar;

pub use error::MatrixFileError;
