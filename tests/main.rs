//! Integration tests: one binary to keep link times low.
//!
//! GPU tests run on any wgpu adapter (lavapipe in CI), print `SKIP (no adapter)` when
//! there is none, and fail when `BRDF_BASIS_REQUIRE_GPU=1` is set and no adapter is found.

#![allow(clippy::result_large_err)]

mod common;

mod acquisition;
mod acquisition_objectives;
mod audit2;
mod audit2_s3;
mod audit2_s4;
mod cli;
mod collection;
mod determinism;
mod distance;
mod empirical_objective;
mod figures;
mod fingerprints;
mod fit;
mod flip_gpu;
mod flip_peer;
mod gpu_kernels;
mod grid;
mod hardening;
mod hardening3;
mod hygiene;
mod inputs;
mod integrity;
mod kmedoids;
mod leftovers;
mod measured;
mod merl100_f64;
mod nbrdf;
mod nbrdf_gpu;
mod objectives;
mod output_aliases;
mod outputs;
mod public_paths;
mod readme;
mod reproduce;
mod reproduce_appearance;
mod requests;
mod rgl;
mod saved_matrix;
mod scale;
mod select_defects;
mod selection;
mod settings;
mod shaders;
mod slurm;
mod tiles;
mod weighted;
mod workflow;
