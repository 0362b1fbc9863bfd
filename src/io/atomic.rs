//! Atomic file output (re-exported from [`crate::atomic`], which sits at the bottom of
//! the crate so that the `.binary` writer in `merl` can use it without importing `io`).

pub use crate::atomic::{
    check_not_input, check_output_path, remove_pending, write_atomic, OutputSet,
};
