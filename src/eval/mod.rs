//! Evaluation: renders and error metrics.

pub mod image_error;
pub mod render;
pub mod shade;
