//! The JSON sidecar of a saved `.npy` matrix or tile (`d.npy` -> `d.names.json`): the
//! material names in row order, the settings, the collection fingerprint, the tile's
//! rows, the `.npy`'s size and XXH3-64 checksum, and a checksum of all of that.
//!
//! Format `brdf-basis-matrix/2`. The `checksum` field is the XXH3-64 of the sidecar's
//! other fields (in the compact JSON this module writes), so a sidecar whose names were
//! reordered or whose settings were edited by hand no longer matches, and because the
//! `.npy` checksum is one of those fields, it binds the names to the matrix bytes.
//! Sidecars of format `/1` (whose checksum covered only the `.npy`, and missed sign
//! flips) are refused with what to do.

use super::MatrixFileError;
use crate::atomic::OutputSet;
use crate::distance::{LobeKind, Metric, ValidDistanceParams};
use crate::error::OutputError;
use crate::merl::{Mask, Weighting};
use std::path::{Path, PathBuf};

/// Format tag of [`MatrixSidecar`].
pub const SIDECAR_FORMAT: &str = "brdf-basis-matrix/2";

/// The format tag of the sidecars written before the checksum covered the sidecar.
const SIDECAR_FORMAT_1: &str = "brdf-basis-matrix/1";

/// Serde through `Display`/`FromStr` (the command-line spellings).
mod spelled {
    use serde::{Deserialize, Deserializer, Serializer};

    pub(super) fn serialize<T: std::fmt::Display, S: Serializer>(
        v: &T,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        s.collect_str(v)
    }

    pub(super) fn deserialize<'de, T, D>(d: D) -> Result<T, D::Error>
    where
        T: std::str::FromStr,
        T::Err: std::fmt::Display,
        D: Deserializer<'de>,
    {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

/// The settings a matrix was computed with (written as their command-line spellings).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MatrixSettings {
    /// The metric.
    #[serde(with = "spelled")]
    pub metric: Metric,
    /// The lobe.
    #[serde(with = "spelled")]
    pub lobe: LobeKind,
    /// The weighting.
    #[serde(with = "spelled")]
    pub weighting: Weighting,
    /// The mask.
    #[serde(with = "spelled")]
    pub mask: Mask,
    /// Grid stride.
    pub stride: usize,
    /// Materials per super-block of the banded computation.
    pub band_rows: usize,
}

impl MatrixSettings {
    /// The settings of validated distance parameters.
    pub fn of(p: &ValidDistanceParams, band_rows: usize) -> Self {
        Self {
            metric: p.metric(),
            lobe: p.lobe(),
            weighting: p.weighting(),
            mask: p.mask(),
            stride: p.stride(),
            band_rows,
        }
    }

    /// In words, how `self` differs from `other` (`--metric brdf-it vs euclidean, ...`);
    /// empty when they are equal.
    pub fn differences(&self, other: &Self) -> String {
        let mut out = Vec::new();
        let mut diff = |what: &str, a: String, b: String| {
            if a != b {
                out.push(format!("{what} {a} vs {b}"));
            }
        };
        diff(
            "--metric",
            self.metric.to_string(),
            other.metric.to_string(),
        );
        diff("--lobe", self.lobe.to_string(), other.lobe.to_string());
        diff(
            "--weighting",
            self.weighting.to_string(),
            other.weighting.to_string(),
        );
        diff("--mask", self.mask.to_string(), other.mask.to_string());
        diff(
            "--stride",
            self.stride.to_string(),
            other.stride.to_string(),
        );
        diff(
            "--band-rows",
            self.band_rows.to_string(),
            other.band_rows.to_string(),
        );
        out.join(", ")
    }
}

/// Which rows of the whole matrix a tile holds.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TileInfo {
    /// 1-based tile index `I`.
    pub index: usize,
    /// Number of tiles `N`.
    pub count: usize,
    /// First material row held.
    pub row_start: usize,
    /// One past the last row held.
    pub row_end: usize,
}

/// The JSON sidecar of a saved `.npy` matrix or tile (`d.npy` -> `d.names.json`).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MatrixSidecar {
    /// Format tag, [`SIDECAR_FORMAT`].
    pub format: String,
    /// Number of materials `N` (the matrix is `N x N`, a tile `rows x (N - first row)`).
    pub n: usize,
    /// Material names in row order.
    pub names: Vec<String>,
    /// Settings it was computed with.
    pub settings: MatrixSettings,
    /// [`crate::collection::Collection::fingerprint`] of the collection.
    pub collection_fingerprint: String,
    /// Rows held when this is a tile.
    pub tile: Option<TileInfo>,
    /// Bytes of the `.npy` file.
    pub npy_bytes: u64,
    /// XXH3-64 of the `.npy` file's bytes, 16 hex digits (`xxhsum -H3 FILE`).
    pub npy_xxh3: String,
    /// XXH3-64 of the other fields ([`MatrixSidecar::content_checksum`]), 16 hex digits.
    pub checksum: String,
}

/// The fields the sidecar checksum covers, in their written order.
#[derive(serde::Serialize)]
struct Content<'a> {
    format: &'a str,
    n: usize,
    names: &'a [String],
    settings: &'a MatrixSettings,
    collection_fingerprint: &'a str,
    tile: &'a Option<TileInfo>,
    npy_bytes: u64,
    npy_xxh3: &'a str,
}

impl MatrixSidecar {
    /// A sidecar of the current format, its checksum computed.
    pub fn new(
        names: Vec<String>,
        settings: MatrixSettings,
        collection_fingerprint: String,
        n: usize,
        tile: Option<TileInfo>,
        npy: super::npy::NpyDigest,
    ) -> Self {
        let mut s = Self {
            format: SIDECAR_FORMAT.into(),
            n,
            names,
            settings,
            collection_fingerprint,
            tile,
            npy_bytes: npy.bytes,
            npy_xxh3: crate::hash::hex(npy.xxh3),
            checksum: String::new(),
        };
        s.checksum = s.content_checksum();
        s
    }

    /// The XXH3-64 of every field but `checksum`, as 16 hex digits: what `checksum`
    /// must hold.
    pub fn content_checksum(&self) -> String {
        let content = Content {
            format: &self.format,
            n: self.n,
            names: &self.names,
            settings: &self.settings,
            collection_fingerprint: &self.collection_fingerprint,
            tile: &self.tile,
            npy_bytes: self.npy_bytes,
            npy_xxh3: &self.npy_xxh3,
        };
        let bytes = serde_json::to_vec(&content).expect("a sidecar serialises");
        crate::hash::hex_of(&bytes)
    }

    /// Whether the `.npy` described has this size and checksum.
    pub fn describes(&self, npy: super::npy::NpyDigest) -> bool {
        self.npy_bytes == npy.bytes && self.npy_xxh3 == crate::hash::hex(npy.xxh3)
    }
}

/// The sidecar path of a `.npy`: `d.npy` -> `d.names.json`.
pub fn sidecar_path(npy: &Path) -> PathBuf {
    npy.with_extension("names.json")
}

fn sidecar_text(path: &Path, side: &MatrixSidecar) -> Result<String, OutputError> {
    let mut side = side.clone();
    side.checksum = side.content_checksum();
    serde_json::to_string_pretty(&side)
        .map(|t| t + "\n")
        .map_err(|e| OutputError::Encode {
            path: path.to_path_buf(),
            message: e.to_string(),
        })
}

/// Stages the sidecar of the `.npy` at `npy` in `set` (its checksum recomputed).
pub fn stage_sidecar(
    set: &mut OutputSet,
    npy: &Path,
    side: &MatrixSidecar,
) -> Result<(), OutputError> {
    let path = sidecar_path(npy);
    let text = sidecar_text(&path, side)?;
    set.stage(&path, |w| w.write_all(text.as_bytes()))
}

/// Reads the sidecar of the `.npy` at `npy` and checks it: its format (a `/1` sidecar is
/// refused with what to do), one name per row, and its checksum.
pub fn read_sidecar(npy: &Path) -> Result<MatrixSidecar, MatrixFileError> {
    let sp = sidecar_path(npy);
    let text = match crate::collection::read_regular(&sp, 1 << 30) {
        Ok(t) => t,
        Err(crate::error::CollectionError::Io { source, .. })
            if source.kind() == std::io::ErrorKind::NotFound =>
        {
            return Err(MatrixFileError::NoSidecar {
                npy: npy.to_path_buf(),
                sidecar: sp,
            })
        }
        Err(crate::error::CollectionError::Io { source, .. }) => {
            return Err(MatrixFileError::Io { path: sp, source })
        }
        Err(crate::error::CollectionError::NotRegular { kind, .. }) => {
            return Err(MatrixFileError::Format {
                path: sp,
                message: format!("is {kind}, not a regular file"),
            })
        }
        Err(e) => {
            return Err(MatrixFileError::Format {
                path: sp,
                message: format!("cannot be read as a sidecar ({e})"),
            })
        }
    };
    let format = |message: String| MatrixFileError::Format {
        path: sp.clone(),
        message,
    };
    #[derive(serde::Deserialize)]
    struct Tag {
        format: Option<String>,
    }
    let tag: Tag = serde_json::from_slice(&text)
        .map_err(|e| format(format!("not a brdf-basis matrix sidecar: {e}")))?;
    match tag.format.as_deref() {
        Some(SIDECAR_FORMAT) => {}
        Some(SIDECAR_FORMAT_1) => {
            return Err(format(format!(
                "format `{SIDECAR_FORMAT_1}` was written by an older brdf-basis, whose checksum covered neither the names nor the settings; this version reads `{SIDECAR_FORMAT}` only: compute the matrix again with `brdf-basis distance` (tiles: `distance --tile` and `merge`)"
            )))
        }
        Some(other) => {
            return Err(format(format!(
                "format `{other}`, expected `{SIDECAR_FORMAT}`"
            )))
        }
        None => return Err(format("not a brdf-basis matrix sidecar (no `format`)".into())),
    }
    let side: MatrixSidecar = serde_json::from_slice(&text)
        .map_err(|e| format(format!("not a brdf-basis matrix sidecar: {e}")))?;
    if side.names.len() != side.n {
        return Err(MatrixFileError::Names {
            path: sp,
            message: format!(
                "the sidecar of {} lists {} names for N = {} materials",
                npy.display(),
                side.names.len(),
                side.n
            ),
        });
    }
    let want = side.content_checksum();
    if side.checksum != want {
        return Err(format(format!(
            "the sidecar's checksum is {}, but its content hashes to {want}: it was edited or damaged after it was written (names, settings or sizes changed); compute the {} again with `brdf-basis distance{}`",
            side.checksum,
            if side.tile.is_some() { "tile" } else { "matrix" },
            side.tile.as_ref().map_or(String::new(), |t| format!(" --tile {}/{}", t.index, t.count))
        )));
    }
    Ok(side)
}

/// In words, how the collections of two sidecars differ (by fingerprint, else by the
/// first name that differs); `None` when they describe the same collection.
pub(crate) fn collection_difference(a: &MatrixSidecar, b: &MatrixSidecar) -> Option<String> {
    if a.collection_fingerprint != b.collection_fingerprint {
        return Some(format!(
            "collection fingerprint {} ({} materials) vs {} ({} materials)",
            a.collection_fingerprint,
            a.names.len(),
            b.collection_fingerprint,
            b.names.len()
        ));
    }
    if a.names.len() != b.names.len() {
        return Some(format!("{} vs {} materials", a.names.len(), b.names.len()));
    }
    let i = a.names.iter().zip(&b.names).position(|(x, y)| x != y)?;
    Some(format!(
        "material {i} is `{}` vs `{}`",
        a.names[i].escape_debug(),
        b.names[i].escape_debug()
    ))
}
