//! File input and output: `.npy`, CSV matrices, images, JSON (written through
//! [`crate::atomic`]).

pub mod image;
pub mod json;
pub mod matrix;
