//! Result file types of the experiment: the `+inf`-as-`null` serde helper and
//! `empirical.json`. The `fit` JSON is [`crate::fit::file::FitFile`].

use std::collections::BTreeMap;

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
