//! The `fit` JSON schema (SPEC-cli): one type written by `fit` and `reproduce` and read by
//! `render --fit`, `plot --fit` and the tests.
//!
//! ```json
//! {"basis": [names], "weighting", "mask",
//!  "targets": [{"material", "lambertian": [r, g, b],
//!               "coefficients": {"<basis name>": [r, g, b], ...}, "mae", "residual": [r, g, b]}]}
//! ```
//!
//! The Lambertian term sits beside the basis coefficients, so a basis material may be
//! called anything, `lambertian` included.

use crate::collection::Collection;
use crate::fit::{FitParams, TargetFit};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Errors reading a `fit` JSON file.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum FitFileError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The file is not a `fit` JSON (names the line and column of the problem).
    #[error("{path}: not a `fit` JSON file: {message}")]
    Parse {
        /// File.
        path: PathBuf,
        /// serde's message, with line and column.
        message: String,
    },
    /// The file holds no fit of the material asked for.
    #[error("{path}: no fit of `{}` (fitted: {available})", crate::error::short_name(.material))]
    NoTarget {
        /// File.
        path: PathBuf,
        /// Material asked for.
        material: String,
        /// The targets in the file, comma-separated (at most 10).
        available: String,
    },
    /// A target lacks the coefficient of a basis material.
    #[error("{path}: the fit of `{}` has no coefficient for basis material `{}`", crate::error::short_name(.material), crate::error::short_name(.basis))]
    MissingCoefficient {
        /// File.
        path: PathBuf,
        /// Target.
        material: String,
        /// Basis material.
        basis: String,
    },
}

/// The fit of one target as written to JSON.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitTarget {
    /// Target material.
    pub material: String,
    /// Lambertian (white diffuse) coefficient, RGB.
    pub lambertian: [f64; 3],
    /// Coefficient of each basis material, RGB, by name.
    pub coefficients: BTreeMap<String, [f64; 3]>,
    /// Weighted mean absolute error over the fit mask, averaged over channels.
    pub mae: f64,
    /// `sqrt(sum_s w_s r_s^2)` per channel.
    pub residual: [f64; 3],
    /// Largest scaled KKT violation per channel (diagnostic; optional on input).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kkt: Option<[f64; 3]>,
    /// Solver iterations per channel (diagnostic; optional on input).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iterations: Option<[usize; 3]>,
}

/// A `fit` JSON file.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitFile {
    /// Basis materials, in column order.
    pub basis: Vec<String>,
    /// `uniform` or `solid-angle`.
    pub weighting: String,
    /// `evaluation` or `valid`.
    pub mask: String,
    /// One entry per fitted target.
    pub targets: Vec<FitTarget>,
}

impl FitTarget {
    /// From a library fit with basis `names` (in column order).
    pub fn new(names: &[String], f: &TargetFit) -> Self {
        FitTarget {
            material: f.material.clone(),
            lambertian: f.coefficients[0],
            coefficients: names
                .iter()
                .cloned()
                .zip(f.coefficients[1..].iter().copied())
                .collect(),
            mae: f.mae,
            residual: f.residual,
            kkt: Some(f.kkt),
            iterations: Some(f.iterations),
        }
    }

    /// Coefficient table in column order (Lambertian, then `basis`): what
    /// [`crate::eval::shade::combination_brdf`] takes. `None` names the missing material.
    pub fn columns(&self, basis: &[String]) -> Result<Vec<[f64; 3]>, String> {
        let mut out = vec![self.lambertian];
        for b in basis {
            out.push(*self.coefficients.get(b).ok_or_else(|| b.clone())?);
        }
        Ok(out)
    }
}

impl FitFile {
    /// The fits of `targets` by `basis` (collection indices) with parameters `p`.
    pub fn new(coll: &Collection, basis: &[usize], fits: &[TargetFit], p: &FitParams) -> Self {
        let names: Vec<String> = basis
            .iter()
            .map(|&b| coll.materials()[b].name.clone())
            .collect();
        FitFile {
            targets: fits.iter().map(|f| FitTarget::new(&names, f)).collect(),
            basis: names,
            weighting: p.weighting.to_string(),
            mask: p.mask.to_string(),
        }
    }

    /// Reads and parses `path`.
    pub fn read(path: &Path) -> Result<Self, FitFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| FitFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        serde_json::from_str(&text).map_err(|e| FitFileError::Parse {
            path: path.to_path_buf(),
            message: e.to_string(),
        })
    }

    /// The fit of `material` and its coefficient table in column order (Lambertian,
    /// then [`FitFile::basis`]); `path` names the file in errors.
    pub fn columns_of(
        &self,
        material: &str,
        path: &Path,
    ) -> Result<(&FitTarget, Vec<[f64; 3]>), FitFileError> {
        let t = self
            .targets
            .iter()
            .find(|t| t.material == material)
            .ok_or_else(|| FitFileError::NoTarget {
                path: path.to_path_buf(),
                material: material.to_string(),
                available: self
                    .targets
                    .iter()
                    .take(10)
                    .map(|t| crate::error::short_name(&t.material).to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
            })?;
        let cols = t
            .columns(&self.basis)
            .map_err(|basis| FitFileError::MissingCoefficient {
                path: path.to_path_buf(),
                material: material.to_string(),
                basis,
            })?;
        Ok((t, cols))
    }
}

/// Serde helper for an `f64` that may be `+inf` (e.g. a Davies-Bouldin index with two
/// medoids at distance 0): written as `null`, read back as `+inf`.
pub mod inf_as_null {
    use serde::{Deserialize, Deserializer, Serializer};

    /// Writes a finite value as a number, anything else as `null`.
    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            s.serialize_f64(*v)
        } else {
            s.serialize_none()
        }
    }

    /// Reads a number, or `null` as `+inf`.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
    }
}

/// `empirical.json` (SPEC-cli `select`, empirical).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EmpiricalFile {
    /// Always `empirical`.
    pub method: String,
    /// Contributions of each material.
    pub histogram: BTreeMap<String, usize>,
    /// For each target, the materials that contributed to its fit.
    pub contributors: BTreeMap<String, Vec<String>>,
    /// The basis: materials contributing to more than the threshold.
    pub basis: Vec<String>,
}

impl From<&crate::select::empirical::Empirical> for EmpiricalFile {
    fn from(e: &crate::select::empirical::Empirical) -> Self {
        EmpiricalFile {
            method: "empirical".into(),
            histogram: e.histogram.clone(),
            contributors: e.contributors.clone(),
            basis: e.basis.clone(),
        }
    }
}
