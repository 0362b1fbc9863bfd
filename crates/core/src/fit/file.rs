//! The `fit` JSON schema (SPEC-cli): one type written by `fit` and `reproduce` and read by
//! `render --fit`, `plot --fit` and the tests.
//!
//! ```json
//! {"collection_fingerprint": "<16 hex digits>", "collection_size": N,
//!  "basis": [names], "weighting", "mask",
//!  "targets": [{"material", "lambertian": [r, g, b],
//!               "coefficients": {"<basis name>": [r, g, b], ...}, "mae", "residual": [r, g, b]}]}
//! ```
//!
//! The Lambertian term sits beside the basis coefficients, so a basis material may be
//! called anything, `lambertian` included. The file carries the fingerprint and size of
//! the collection it was fitted on ([`Collection::fingerprint`]); a reader given another
//! collection refuses it ([`FitFile::check_collection`]), since the same names may
//! stand for other materials there.

use crate::collection::Collection;
use crate::fit::{FitParams, TargetFit};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Largest `fit` JSON read (a fit of 10,000 targets by a basis of 20 is about 20 MB).
pub const MAX_FIT_FILE_BYTES: u64 = 1 << 30;

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
    /// The file was fitted on another collection than the one given.
    #[error("{path}: fitted on another collection ({file_size} materials, fingerprint {file_fingerprint}) than the one given ({given_size} materials, fingerprint {given_fingerprint}): the same names may stand for other materials there; give the collection the fit was made on, or fit again")]
    OtherCollection {
        /// File.
        path: PathBuf,
        /// Fingerprint recorded in the file.
        file_fingerprint: String,
        /// Size recorded in the file.
        file_size: usize,
        /// Fingerprint of the collection given.
        given_fingerprint: String,
        /// Its size.
        given_size: usize,
    },
    /// The file records no collection fingerprint.
    #[error("{path}: records no collection fingerprint (written by an older brdf-basis), so it cannot be checked against the collection given; fit again with `brdf-basis fit`")]
    NoFingerprint {
        /// File.
        path: PathBuf,
    },
    /// The file is a fit from samples (`fit --samples`): its target is not a material of
    /// any collection, so there is nothing to compare its reconstruction with.
    #[error("{path}: a fit from samples (`{}`, {samples} samples): its target was fitted from measured samples and has no material in the collection to compare with (a collection material of the same name is another material); to render or plot the fit, export it with `brdf-basis fit --samples {} --export DIR` and give `DIR/{}` as the collection, with `--material {}`", .fitted_from, .fitted_from, .file, .material)]
    FromSamples {
        /// File.
        path: PathBuf,
        /// The samples file it was fitted from.
        fitted_from: String,
        /// Number of samples.
        samples: usize,
        /// The target's name.
        material: String,
        /// The file `--export` writes for it.
        file: String,
    },
    /// A basis material of the file is not in the collection.
    #[error("{path}: basis material: {source}")]
    Basis {
        /// File.
        path: PathBuf,
        /// The lookup error.
        source: crate::error::CollectionError,
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
    /// Relative residual under the objective's weights (SPEC 11's `rho_W`; optional on
    /// input).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub objective_residual: Option<f64>,
    /// The appearance metrics of the fit (SPEC 11; optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub appearance: Option<crate::eval::appearance::Appearance>,
}

/// A `fit` JSON file.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitFile {
    /// [`Collection::fingerprint`] of the collection fitted (absent in files written
    /// before it was recorded; such files are refused by [`FitFile::check_collection`]).
    #[serde(default)]
    pub collection_fingerprint: Option<String>,
    /// Number of materials of that collection.
    #[serde(default)]
    pub collection_size: Option<usize>,
    /// Basis materials, in column order.
    pub basis: Vec<String>,
    /// `uniform` or `solid-angle`.
    pub weighting: String,
    /// `evaluation` or `valid`.
    pub mask: String,
    /// One entry per fitted target.
    pub targets: Vec<FitTarget>,
    /// `fit --samples` (SPEC 10): the number of samples fitted (each target's `residual`
    /// and `mae` are then on the samples); absent for a fit on the grid.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<usize>,
    /// `fit --samples`: the samples file fitted from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fitted_from: Option<String>,
    /// The fit objective (SPEC 11): `l2`, `relative` or `log` (absent in older files: `l2`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub objective: Option<String>,
    /// `eps` of the `relative` objective.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eps: Option<f64>,
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
            objective_residual: Some(f.objective_residual),
            appearance: None,
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
            collection_fingerprint: Some(coll.fingerprint()),
            collection_size: Some(coll.len()),
            targets: fits.iter().map(|f| FitTarget::new(&names, f)).collect(),
            basis: names,
            weighting: p.weighting.to_string(),
            mask: p.mask.to_string(),
            samples: None,
            fitted_from: None,
            objective: Some(p.objective.kind().name().into()),
            eps: p.objective.eps(),
        }
    }

    /// Reads and parses `path`.
    /// Only a regular file of at most [`MAX_FIT_FILE_BYTES`] is read (a FIFO or a
    /// device is refused before it is opened, so reading never blocks).
    pub fn read(path: &Path) -> Result<Self, FitFileError> {
        use crate::error::CollectionError;
        let text =
            crate::collection::read_regular(path, MAX_FIT_FILE_BYTES).map_err(|e| match e {
                CollectionError::Io { source, .. } => FitFileError::Io {
                    path: path.to_path_buf(),
                    source,
                },
                CollectionError::NotRegular { kind, .. } => FitFileError::Parse {
                    path: path.to_path_buf(),
                    message: format!("is {kind}, not a regular file"),
                },
                other => FitFileError::Parse {
                    path: path.to_path_buf(),
                    message: other.to_string(),
                },
            })?;
        let file: Self = serde_json::from_slice(&text).map_err(|e| FitFileError::Parse {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        file.check_values().map_err(|message| FitFileError::Parse {
            path: path.to_path_buf(),
            message,
        })?;
        Ok(file)
    }

    /// What `fit` never writes (audit 3, U7: a hand-edited file rendered as if fitted):
    /// an unknown `objective`, an `eps` that the objective refuses, a negative or
    /// non-finite coefficient. The message names the field (and the target).
    fn check_values(&self) -> Result<(), String> {
        use crate::backend::weighted::ObjectiveKind;
        if let Some(o) = &self.objective {
            if o.parse::<ObjectiveKind>().is_err() {
                let names: Vec<&str> = ObjectiveKind::ALL.iter().map(|k| k.name()).collect();
                return Err(format!(
                    "field `objective` is `{o}`, not one of {}",
                    names.join(", ")
                ));
            }
        }
        if let Some(e) = self.eps {
            // The objective's one rule of `eps` (what `fit` checks before it writes one).
            if let Err(why) = crate::backend::weighted::TargetWeight::relative(e) {
                return Err(format!("field `eps` is {e:e}: {why}"));
            }
        }
        for t in &self.targets {
            // `None`: the Lambertian term (a basis material may be named `lambertian`).
            let named = std::iter::once((None, &t.lambertian))
                .chain(t.coefficients.iter().map(|(b, c)| (Some(b.as_str()), c)));
            for (basis, c) in named {
                if let Some(v) = c.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
                    let field = match basis {
                        None => "`lambertian`".to_string(),
                        Some(b) => format!("`coefficients` of `{b}`"),
                    };
                    return Err(format!(
                        "target `{}`: field {field} holds {v}; a fit's coefficients are finite and non-negative",
                        t.material
                    ));
                }
            }
        }
        Ok(())
    }

    /// Refuses the file unless it was fitted on `coll` (same fingerprint and size);
    /// `path` names the file in errors.
    pub fn check_collection(&self, coll: &Collection, path: &Path) -> Result<(), FitFileError> {
        let (Some(fp), Some(size)) = (&self.collection_fingerprint, self.collection_size) else {
            return Err(FitFileError::NoFingerprint {
                path: path.to_path_buf(),
            });
        };
        let given = coll.fingerprint();
        if *fp != given || size != coll.len() {
            return Err(FitFileError::OtherCollection {
                path: path.to_path_buf(),
                file_fingerprint: fp.clone(),
                file_size: size,
                given_fingerprint: given,
                given_size: coll.len(),
            });
        }
        Ok(())
    }

    /// Refuses a fit from samples (`fit --samples`, [`FitFile::samples`] or
    /// [`FitFile::fitted_from`] set): its target is no collection material, and one that
    /// shares its name (the samples file's stem) is another material.
    pub fn refuse_samples_fit(&self, path: &Path) -> Result<(), FitFileError> {
        if self.samples.is_none() && self.fitted_from.is_none() {
            return Ok(());
        }
        let material = self
            .targets
            .first()
            .map_or_else(|| "samples".into(), |t| t.material.clone());
        Err(FitFileError::FromSamples {
            path: path.to_path_buf(),
            fitted_from: self.fitted_from.clone().unwrap_or_else(|| "?".into()),
            samples: self.samples.unwrap_or(0),
            file: crate::fit::export::export_file_names(&[material.as_str()]).remove(0),
            material,
        })
    }

    /// The fitted BRDF of `material`: the file at `path` read, refused if it is a fit
    /// from samples ([`FitFile::refuse_samples_fit`]), checked against `coll`
    /// ([`FitFile::check_collection`]), its basis resolved in `coll` and the combination
    /// formed ([`crate::eval::shade::combination_brdf`]).
    pub fn combination_from(
        path: &Path,
        coll: &Collection,
        material: &str,
    ) -> Result<crate::eval::shade::BrdfFn, FitFileError> {
        let file = Self::read(path)?;
        file.refuse_samples_fit(path)?;
        file.check_collection(coll, path)?;
        let (_, coef) = file.columns_of(material, path)?;
        let basis: Vec<usize> = file
            .basis
            .iter()
            .map(|n| coll.index_of(n))
            .collect::<Result<_, _>>()
            .map_err(|source| FitFileError::Basis {
                path: path.to_path_buf(),
                source,
            })?;
        Ok(crate::eval::shade::combination_brdf(coll, &basis, &coef))
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
                    .map(|t| t.material.as_str())
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

#[cfg(test)]
mod tests {
    use super::*;

    fn file(lambertian: [f64; 3], named_lambertian: [f64; 3]) -> FitFile {
        let target = FitTarget {
            material: "t".into(),
            lambertian,
            coefficients: [("lambertian".to_string(), named_lambertian)].into(),
            mae: 0.0,
            residual: [0.0; 3],
            kkt: None,
            iterations: None,
            objective_residual: None,
            appearance: None,
        };
        FitFile {
            collection_fingerprint: None,
            collection_size: None,
            basis: vec!["lambertian".into()],
            weighting: "uniform".into(),
            mask: "evaluation".into(),
            targets: vec![target],
            samples: None,
            fitted_from: None,
            objective: Some("relative".into()),
            eps: Some(0.01),
        }
    }

    /// Audit 3, U7: a basis material named `lambertian` is named as a basis material,
    /// not as the Lambertian term, when its coefficient is refused.
    #[test]
    fn a_refused_coefficient_names_its_field_even_for_a_basis_named_lambertian() {
        assert_eq!(file([0.1; 3], [0.2; 3]).check_values(), Ok(()));
        let e = file([0.1; 3], [0.2, -1.0, 0.2]).check_values().unwrap_err();
        assert!(
            e.contains("field `coefficients` of `lambertian` holds -1"),
            "{e}"
        );
        let e = file([0.1, f64::INFINITY, 0.1], [0.2; 3])
            .check_values()
            .unwrap_err();
        assert!(
            e.contains("target `t`: field `lambertian` holds inf"),
            "{e}"
        );
        let mut f = file([0.1; 3], [0.2; 3]);
        f.eps = Some(f64::NAN);
        let e = f.check_values().unwrap_err();
        assert!(
            e.contains("field `eps` is NaN: the relative objective's eps must be a positive number, not NaN"),
            "{e}"
        );
        // The objective's own range (before: any positive number was read, an eps that
        // no fit accepts included).
        f.eps = Some(1e-200);
        let e = f.check_values().unwrap_err();
        assert!(
            e.contains("field `eps` is 1e-200: the relative objective's eps must lie between 1e-100 and 1e100, not 1e-200"),
            "{e}"
        );
        f.eps = Some(0.02);
        assert!(f.check_values().is_ok());
    }
}
