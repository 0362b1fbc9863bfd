//! File input and output: atomic writes, `.npy`, CSV matrices, images.

pub mod atomic;
pub mod image;
pub mod json;
pub mod matrix;
