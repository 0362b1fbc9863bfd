//! The library's integration tests: one binary to keep link times low (the command
//! line's are crates/cli/tests).
//!
//! GPU tests run on any wgpu adapter (lavapipe in CI), print `SKIP (no adapter)` when
//! there is none, and fail when `BRDF_BASIS_REQUIRE_GPU=1` is set and no adapter is found.

#![allow(clippy::result_large_err)]

mod common;

mod acquisition_objectives;
mod collection;
mod distance;
mod fit;
mod flip_gpu;
mod flip_peer;
mod gpu_kernels;
mod grid;
mod hygiene;
mod measured;
mod nbrdf_gpu;
mod public_paths;
mod shaders;
mod weighted;
