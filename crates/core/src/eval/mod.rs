//! Evaluation: renders and error metrics.

pub mod appearance;
pub mod color;
pub(crate) mod fastmath;
pub mod flip;
pub mod ictcp;
pub mod image_error;
pub mod render;
pub mod shade;
