//! RGL-EPFL measured materials (`.bsdf` files of the RGL material database; Dupuy & Jakob
//! 2018, doi:10.1145/3272127.3275059): the `tensor_file` container ([`TensorFile`]), the
//! evaluation of the paper's adaptive parameterisation ([`RglBsdf`]), and a material that
//! holds both the exact evaluation and its tabulation on the MERL grid (SPEC 9).
//!
//! Units: the files' `rgb` tables give `f cos theta_o` divided by the sampling density
//! (see [`RglBsdf`]); [`RglBsdf::eval`] returns reflectance `f` per steradian, the unit of
//! a MERL table's values times its channel scales (SPEC 2), which is what
//! [`crate::merl::MerlTable`] holds. No rescaling is applied.

mod bsdf;
mod tensor;

pub use bsdf::*;
pub use tensor::*;

use crate::error::RglError;
use crate::merl::MerlTable;
use crate::merl::{cell_directions, geometric_validity, N_CELLS};
use rayon::prelude::*;
use std::path::Path;
use std::sync::Arc;

/// Largest `.bsdf` file read (the RGL database's isotropic RGB files are 0.6-1 MB, its
/// anisotropic spectral ones tens of MB).
pub const MAX_BSDF_BYTES: u64 = 1 << 30;

/// An RGL-EPFL material: its exact evaluation and its table on the MERL grid (computed
/// once, when it is loaded).
#[derive(Debug)]
pub struct RglMaterial {
    bsdf: RglBsdf,
    table: Arc<MerlTable>,
    clamped: usize,
}

impl RglMaterial {
    /// Reads, validates and tabulates a `.bsdf` file.
    pub fn load(path: &Path) -> Result<Self, RglError> {
        Self::new(read(path)?, path)
    }

    /// Tabulates an evaluation on the MERL grid (cell centres of SPEC 2, in parallel).
    /// Cells below the horizon are invalid (-1). A negative value in a valid cell is
    /// stored as 0, so that the cell stays valid: SPEC 2 makes a cell with a negative
    /// channel invalid, which would remove it from every distance and fit of a collection
    /// holding this material. Negative values are real in these files: the RGB tables are
    /// linear sRGB converted from spectra, and a saturated colour outside the sRGB gamut
    /// has a negative channel (`cg_sunflower_rgb`: blue below 0 in 79% of its table, down
    /// to -0.1; `cc_ibiza_sunset_rgb`: 9%, down to -0.01).
    ///
    /// A value beyond the f32 range of the table (or not finite) is refused, naming
    /// `path`, the `rgb` field and the cell (audit 2, T13): a table of f32 would hold an
    /// infinity there, and every distance to the material would be infinite.
    pub fn new(bsdf: RglBsdf, path: &Path) -> Result<Self, RglError> {
        let valid = geometric_validity();
        let cells: Vec<[f64; 3]> = (0..N_CELLS)
            .into_par_iter()
            .map(|cell| {
                if !valid[cell] {
                    return [-1.0; 3];
                }
                let (wi, wo) = cell_directions(cell);
                bsdf.eval(wi, wo)
            })
            .collect();
        let limit = f64::from(f32::MAX);
        if let Some((cell, v)) = cells.iter().enumerate().find_map(|(c, v)| {
            v.iter()
                .find(|x| x.abs() > limit || x.is_nan())
                .map(|&x| (c, x))
        }) {
            let (wi, wo) = cell_directions(cell);
            let deg = |d: [f64; 3]| (d[2].acos().to_degrees(), d[1].atan2(d[0]).to_degrees());
            let ((ti, pi), (to, po)) = (deg(wi), deg(wo));
            return Err(RglError::OutOfRange {
                path: path.to_path_buf(),
                value: v,
                at: format!("theta_i, phi_i, theta_o, phi_o = {ti:.2}, {pi:.2}, {to:.2}, {po:.2}"),
            });
        }
        let cells: Vec<[f32; 3]> = cells.iter().map(|v| v.map(|x| x as f32)).collect();
        let mut rgb = vec![0f32; 3 * N_CELLS];
        let mut clamped = 0;
        for (cell, v) in cells.iter().enumerate() {
            if valid[cell] && v.iter().any(|&x| x < 0.0) {
                clamped += 1;
            }
            for c in 0..3 {
                rgb[c * N_CELLS + cell] = if valid[cell] { v[c].max(0.0) } else { -1.0 };
            }
        }
        Ok(Self {
            bsdf,
            table: Arc::new(MerlTable { rgb }),
            clamped,
        })
    }

    /// RGB reflectance `f(wi, wo)` at unit directions (local frame, z = normal), exact
    /// (not the table): 0 below the horizon.
    pub fn eval_dirs(&self, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
        self.bsdf.eval(wi, wo)
    }

    /// The tabulation on the MERL grid.
    pub fn table(&self) -> &Arc<MerlTable> {
        &self.table
    }

    /// The evaluation.
    pub fn bsdf(&self) -> &RglBsdf {
        &self.bsdf
    }

    /// Valid grid cells where some channel evaluated negative and was stored as 0.
    pub fn clamped_cells(&self) -> usize {
        self.clamped
    }
}

/// Reads and validates a `.bsdf` file (no tabulation). A FIFO or a device is refused from
/// its metadata, before it is opened.
pub fn read(path: &Path) -> Result<RglBsdf, RglError> {
    let io = |source| RglError::Io {
        path: path.to_path_buf(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(RglError::NotRegular {
            path: path.to_path_buf(),
            kind: crate::merl::file_kind(&meta),
        });
    }
    if meta.len() > MAX_BSDF_BYTES {
        return Err(RglError::TooLarge {
            path: path.to_path_buf(),
            bytes: meta.len(),
            max: MAX_BSDF_BYTES,
        });
    }
    let bytes = std::fs::read(path).map_err(io)?;
    parse(bytes, path)
}

/// Parses and validates the bytes of a `.bsdf` file (`path` names it in errors).
pub fn parse(bytes: Vec<u8>, path: &Path) -> Result<RglBsdf, RglError> {
    let tf = TensorFile::parse(bytes, path)?;
    RglBsdf::from_tensor(&tf, path)
}
