//! The command line's integration tests (they run the `brdf-basis` binary): one binary
//! to keep link times low.
//!
//! GPU tests run on any wgpu adapter (lavapipe in CI), print `SKIP (no adapter)` when
//! there is none, and fail when `BRDF_BASIS_REQUIRE_GPU=1` is set and no adapter is found.

#![allow(clippy::result_large_err)]

mod common;

mod acquisition;
mod audit2;
mod audit2_s3;
mod audit2_s4;
mod cli;
mod determinism;
mod doors;
mod empirical_objective;
mod figures;
mod fingerprints;
mod hardening;
mod hardening3;
mod inputs;
mod integrity;
mod kmedoids;
mod leftovers;
mod merl100_f64;
mod nbrdf;
mod objectives;
mod output_aliases;
mod outputs;
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
mod slurm;
mod tiles;
mod workflow;
