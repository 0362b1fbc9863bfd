//! Saved distance matrices: writing a matrix as `.npy` + sidecar, a tile, or CSV, and
//! loading one back with every check ([`load_saved_matrix`]).

use super::mmap::MappedF64;
use super::npy::{map_npy_2d, read_npy_2d, stage_npy_2d, write_npy_2d};
use super::sidecar::{
    read_sidecar, sidecar_path, stage_sidecar, MatrixSettings, MatrixSidecar, TileInfo,
};
use super::MatrixFileError;
use crate::atomic::{write_atomic, OutputSet};
use crate::distance::{check_entries, DistanceMatrix, Tile};
use crate::error::OutputError;
use std::path::Path;

/// Stages `m` as `.npy` and its sidecar (names, settings, fingerprint, the `.npy`'s size
/// and checksum) in `set`: both are renamed into place together at its commit.
pub fn stage_npy_with_sidecar(
    set: &mut OutputSet,
    path: &Path,
    m: &DistanceMatrix,
    settings: &MatrixSettings,
    fingerprint: &str,
) -> Result<MatrixSidecar, OutputError> {
    let n = m.names().len();
    let digest = stage_npy_2d(set, path, n, n, m.as_full())?;
    let side = MatrixSidecar::new(
        m.names().to_vec(),
        *settings,
        fingerprint.into(),
        n,
        None,
        digest,
    );
    stage_sidecar(set, path, &side)?;
    Ok(side)
}

/// Writes `m` as `.npy` and its sidecar, renamed into place together
/// ([`stage_npy_with_sidecar`] on a set of its own).
pub fn write_npy_with_sidecar(
    path: &Path,
    m: &DistanceMatrix,
    settings: &MatrixSettings,
    fingerprint: &str,
) -> Result<(), OutputError> {
    let mut set = OutputSet::new();
    stage_npy_with_sidecar(&mut set, path, m, settings, fingerprint)?;
    set.commit()
}

/// Stages a tile as `.npy` (`rows x (N - first row)`: the band from its diagonal block
/// rightwards) and its sidecar (with the tile's index, count and rows) in `set`.
pub fn stage_tile(
    set: &mut OutputSet,
    path: &Path,
    tile: &Tile,
    names: &[String],
    settings: &MatrixSettings,
    fingerprint: &str,
) -> Result<MatrixSidecar, OutputError> {
    let digest = stage_npy_2d(
        set,
        path,
        tile.rows.len(),
        tile.n - tile.rows.start,
        &tile.data,
    )?;
    let side = MatrixSidecar::new(
        names.to_vec(),
        *settings,
        fingerprint.into(),
        tile.n,
        Some(TileInfo {
            index: tile.index,
            count: tile.count,
            row_start: tile.rows.start,
            row_end: tile.rows.end,
        }),
        digest,
    );
    stage_sidecar(set, path, &side)?;
    Ok(side)
}

/// Writes a tile and its sidecar, renamed into place together ([`stage_tile`]).
pub fn write_tile(
    path: &Path,
    tile: &Tile,
    names: &[String],
    settings: &MatrixSettings,
    fingerprint: &str,
) -> Result<(), OutputError> {
    let mut set = OutputSet::new();
    stage_tile(&mut set, path, tile, names, settings, fingerprint)?;
    set.commit()
}

/// Writes an `N x N` float64 `.npy` without a sidecar (format 1.0, little-endian,
/// C order), atomically.
pub fn write_npy(path: &Path, m: &DistanceMatrix) -> Result<(), OutputError> {
    let n = m.names().len();
    write_npy_2d(path, n, n, m.as_full()).map(|_| ())
}

/// The CSV text of a matrix: header `material,<names...>`, then one row per material
/// (values printed with 17 significant digits, round-trip exact).
pub fn csv_bytes(m: &DistanceMatrix) -> std::io::Result<Vec<u8>> {
    let mut out = Vec::new();
    {
        let mut wr = csv::Writer::from_writer(&mut out);
        let mut head = vec!["material".to_string()];
        head.extend(m.names().iter().cloned());
        wr.write_record(&head)?;
        for (i, name) in m.names().iter().enumerate() {
            let mut rec = vec![name.clone()];
            rec.extend(m.row(i).iter().map(|v| format!("{v:.17e}")));
            wr.write_record(&rec)?;
        }
        wr.flush()?;
    }
    Ok(out)
}

/// Writes the matrix as CSV ([`csv_bytes`]), atomically.
pub fn write_csv(path: &Path, m: &DistanceMatrix) -> Result<(), OutputError> {
    let bytes = csv_bytes(m).map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    write_atomic(path, |w| w.write_all(&bytes))
}

/// A saved matrix read back: the validated matrix and, for a `.npy`, its sidecar.
#[derive(Clone, Debug)]
pub struct SavedMatrix {
    /// The matrix (for a `.npy`, read in place from the mapped file where possible:
    /// [`DistanceMatrix::is_mapped`]).
    pub matrix: DistanceMatrix,
    /// The sidecar (`None` for a CSV).
    pub sidecar: Option<MatrixSidecar>,
}

/// How [`load_saved_matrix_with`] holds the values of a `.npy` matrix (a CSV is always
/// parsed into memory).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MatrixLoad {
    /// Read in place from a read-only memory map of the file ([`super::mmap`]): the
    /// matrix needs no memory of its own beyond the pages the kernel caches (file-backed,
    /// reclaimable). Falls back to [`MatrixLoad::Read`] where the file cannot be mapped
    /// (see `map_npy_2d`).
    #[default]
    Map,
    /// Read into memory of the matrix's own.
    Read,
}

/// Relative tolerance of the symmetry check of a loaded matrix:
/// `|D_ij - D_ji| <= SYMMETRY_TOL * max(|D_ij|, |D_ji|)`; pairs within it are replaced by
/// their mean (exact for the matrices `distance` writes, which are exactly symmetric).
pub const SYMMETRY_TOL: f64 = 1e-9;

/// Loads a saved matrix for clustering: a `.npy` with its sidecar (format, checksum of
/// the sidecar, size and checksum of the `.npy` must match) or a `.csv` (header
/// `material,<names...>`, one row per material). Checks that it is square, finite,
/// non-negative, zero on the diagonal, symmetric within [`SYMMETRY_TOL`], with unique
/// names matching its size; every error names the file and the offending row and column.
/// A `.npy` is memory-mapped and read in place ([`MatrixLoad::Map`]).
pub fn load_saved_matrix(path: &Path) -> Result<SavedMatrix, MatrixFileError> {
    load_saved_matrix_with(path, MatrixLoad::Map)
}

/// [`load_saved_matrix`] with the values of a `.npy` held as `how` says; the checks,
/// errors and values are the same either way.
pub fn load_saved_matrix_with(
    path: &Path,
    how: MatrixLoad,
) -> Result<SavedMatrix, MatrixFileError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    match ext.as_str() {
        "npy" => {
            let (names, data, side) = load_npy(path, how)?;
            let matrix = match data {
                NpyValues::Read(data) => validate_matrix(path, names, data)?,
                NpyValues::Mapped(values) => validate_mapped(path, names, values)?,
            };
            Ok(SavedMatrix {
                matrix,
                sidecar: Some(side),
            })
        }
        "csv" => {
            let (names, data) = read_csv_matrix(path)?;
            Ok(SavedMatrix {
                matrix: validate_matrix(path, names, data)?,
                sidecar: None,
            })
        }
        _ => Err(MatrixFileError::Format {
            path: path.to_path_buf(),
            message: "a saved matrix must end in .npy (with its .names.json sidecar) or .csv"
                .into(),
        }),
    }
}

/// The values of a `.npy` matrix: read into memory, or in place in the mapped file.
enum NpyValues {
    Read(Vec<f64>),
    Mapped(MappedF64),
}

fn load_npy(
    path: &Path,
    how: MatrixLoad,
) -> Result<(Vec<String>, NpyValues, MatrixSidecar), MatrixFileError> {
    let side = read_sidecar(path)?;
    if side.tile.is_some() {
        return Err(MatrixFileError::Format {
            path: path.to_path_buf(),
            message: "this is a tile of a matrix, not a whole matrix: assemble the tiles with `brdf-basis merge TILE... --out FILE.npy` first".into(),
        });
    }
    let mapped = match how {
        MatrixLoad::Map => map_npy_2d(path)?,
        MatrixLoad::Read => None,
    };
    let (rows, cols, digest, data) = match mapped {
        Some(m) => (m.rows, m.cols, m.digest, NpyValues::Mapped(m.values)),
        None => {
            let npy = read_npy_2d(path)?;
            (npy.rows, npy.cols, npy.digest, NpyValues::Read(npy.data))
        }
    };
    if rows != cols {
        return Err(MatrixFileError::NotSquare {
            path: path.to_path_buf(),
            message: format!("shape ({rows}, {cols})"),
        });
    }
    let mismatch = |what: String| MatrixFileError::Mismatch {
        npy: path.to_path_buf(),
        sidecar: sidecar_path(path),
        what,
    };
    if !side.describes(digest) {
        return Err(mismatch(format!(
            "file has {} bytes, checksum {}; the sidecar records {} bytes, checksum {}",
            digest.bytes,
            crate::hash::hex(digest.xxh3),
            side.npy_bytes,
            side.npy_xxh3
        )));
    }
    if side.n != rows {
        return Err(mismatch(format!(
            "matrix is {rows} x {rows}, the sidecar says N = {}",
            side.n
        )));
    }
    Ok((side.names.clone(), data, side))
}

fn read_csv_matrix(path: &Path) -> Result<(Vec<String>, Vec<f64>), MatrixFileError> {
    let bad = |message: String| MatrixFileError::Format {
        path: path.to_path_buf(),
        message,
    };
    let file = std::fs::File::open(path).map_err(|source| MatrixFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut rd = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .from_reader(std::io::BufReader::new(file));
    let head = rd
        .headers()
        .map_err(|e| bad(format!("unreadable header: {e}")))?
        .clone();
    if head.get(0).map(str::trim) != Some("material") {
        return Err(bad(
            "the header must be `material,<name 1>,...,<name N>`".into()
        ));
    }
    let names: Vec<String> = head.iter().skip(1).map(|s| s.trim().to_string()).collect();
    let n = names.len();
    let mut data = Vec::with_capacity(n * n);
    let mut row = 0usize;
    for rec in rd.records() {
        let rec = rec.map_err(|e| bad(format!("unreadable row: {e}")))?;
        let line = rec.position().map_or(row + 2, |p| p.line() as usize);
        if row >= n {
            return Err(MatrixFileError::NotSquare {
                path: path.to_path_buf(),
                message: format!("line {line}: more than the {n} rows the header names"),
            });
        }
        let name = rec.get(0).unwrap_or("").trim();
        if name != names[row] {
            return Err(MatrixFileError::Names {
                path: path.to_path_buf(),
                message: format!(
                    "line {line}: row {row} is named `{name}`, but column {row} of the header is `{}`",
                    names[row]
                ),
            });
        }
        if rec.len() != n + 1 {
            return Err(MatrixFileError::NotSquare {
                path: path.to_path_buf(),
                message: format!(
                    "line {line}: row {row} (`{name}`) has {} values, the header names {n} materials",
                    rec.len() - 1
                ),
            });
        }
        for (col, field) in rec.iter().skip(1).enumerate() {
            let v: f64 = field.trim().parse().map_err(|_| {
                bad(format!(
                    "line {line}: row {row} (`{name}`), column {col} (`{}`): `{field}` is not a number",
                    names[col]
                ))
            })?;
            data.push(v);
        }
        row += 1;
    }
    if row != n {
        return Err(MatrixFileError::NotSquare {
            path: path.to_path_buf(),
            message: format!("{row} rows, but the header names {n} materials"),
        });
    }
    Ok((names, data))
}

/// Checks that `names` are unique, non-empty and at least 2; the message says what is
/// wrong.
pub(crate) fn check_matrix_names(names: &[String]) -> Result<(), String> {
    let n = names.len();
    if n < 2 {
        return Err(format!(
            "a distance matrix needs at least 2 materials, found {n}"
        ));
    }
    let mut seen = std::collections::HashMap::with_capacity(n);
    for (i, name) in names.iter().enumerate() {
        if name.is_empty() {
            return Err(format!("material {i} has an empty name"));
        }
        if let Some(j) = seen.insert(name.as_str(), i) {
            return Err(format!(
                "material `{name}` is named twice (rows {j} and {i})"
            ));
        }
    }
    Ok(())
}

/// The checks of [`load_saved_matrix`] on `names` and a row-major `N x N` array
/// ([`check_entries`] within [`SYMMETRY_TOL`]); pairs within the tolerance are replaced
/// by their mean.
pub(crate) fn validate_matrix(
    path: &Path,
    names: Vec<String>,
    mut data: Vec<f64>,
) -> Result<DistanceMatrix, MatrixFileError> {
    check_values(path, &names, &data)?;
    symmetrize(names.len(), &mut data);
    Ok(DistanceMatrix::from_checked(names, data))
}

/// [`validate_matrix`] on values read in place: they stay in the mapped file, and only
/// when a pair within the tolerance differs are the pages holding such pairs copied
/// (privately: the file is not changed) to hold their mean.
fn validate_mapped(
    path: &Path,
    names: Vec<String>,
    mut values: MappedF64,
) -> Result<DistanceMatrix, MatrixFileError> {
    let n = names.len();
    check_values(path, &names, values.values())?;
    let data = values.values();
    let exact = (0..n).all(|i| (i + 1..n).all(|j| data[i * n + j] == data[j * n + i]));
    if !exact {
        values
            .with_writable(|data| symmetrize(n, data))
            .map_err(|source| MatrixFileError::Io {
                path: path.to_path_buf(),
                source,
            })?;
    }
    values
        .unchanged_quick()
        .map_err(|message| MatrixFileError::Changed {
            path: path.to_path_buf(),
            message,
        })?;
    Ok(DistanceMatrix::from_checked_shared(
        names,
        std::sync::Arc::new(values),
    ))
}

/// The checks of [`validate_matrix`], without changing anything.
fn check_values(path: &Path, names: &[String], data: &[f64]) -> Result<(), MatrixFileError> {
    let n = names.len();
    let names_err = |message: String| MatrixFileError::Names {
        path: path.to_path_buf(),
        message,
    };
    if n * n != data.len() {
        return Err(names_err(format!(
            "{} names for a matrix of {} entries",
            n,
            data.len()
        )));
    }
    check_matrix_names(names).map_err(names_err)?;
    check_entries(n, data, SYMMETRY_TOL)
        .map_err(|e| MatrixFileError::entry(path, names, e, SYMMETRY_TOL))
}

/// Replaces every pair `D_ij != D_ji` by its mean.
fn symmetrize(n: usize, data: &mut [f64]) {
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (data[i * n + j], data[j * n + i]);
            if a != b {
                let m = 0.5 * (a + b);
                data[i * n + j] = m;
                data[j * n + i] = m;
            }
        }
    }
}
