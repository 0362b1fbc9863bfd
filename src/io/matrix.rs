//! Distance matrices on disk: NumPy `.npy` (float64, C order) and CSV.

use crate::atomic::write_atomic;
use crate::distance::DistanceMatrix;
use crate::error::OutputError;
use std::path::Path;

/// Writes an `N x N` float64 `.npy` (format 1.0, little-endian, C order), atomically.
pub fn write_npy(path: &Path, m: &DistanceMatrix) -> Result<(), OutputError> {
    let n = m.names().len();
    write_atomic(path, |w| {
        let mut header =
            format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({n}, {n}), }}");
        let total = 10 + header.len() + 1;
        header.push_str(&" ".repeat(total.next_multiple_of(64) - total));
        header.push('\n');
        w.write_all(b"\x93NUMPY\x01\x00")?;
        w.write_all(&(header.len() as u16).to_le_bytes())?;
        w.write_all(header.as_bytes())?;
        for v in m.as_full() {
            w.write_all(&v.to_le_bytes())?;
        }
        Ok(())
    })
}

/// Reads an `N x N` float64 `.npy` written by [`write_npy`] (for round-trip tests and
/// scripts); returns `(n, data)`.
pub fn read_npy(path: &Path) -> Result<(usize, Vec<f64>), OutputError> {
    let bad = |message: &str| OutputError::Encode {
        path: path.to_path_buf(),
        message: message.into(),
    };
    let bytes = std::fs::read(path).map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(bad("not a .npy file"));
    }
    let hl = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(
        bytes
            .get(10..10 + hl)
            .ok_or_else(|| bad("truncated header"))?,
    )
    .map_err(|_| bad("bad header"))?;
    if !header.contains("'<f8'") || !header.contains("False") {
        return Err(bad("expected little-endian float64 in C order"));
    }
    let shape = header
        .split("'shape': (")
        .nth(1)
        .and_then(|s| s.split(',').next())
        .ok_or_else(|| bad("no shape"))?;
    let n: usize = shape.trim().parse().map_err(|_| bad("bad shape"))?;
    let data: Vec<f64> = bytes[10 + hl..]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
        .collect();
    if data.len() != n * n {
        return Err(bad("data length does not match the shape"));
    }
    Ok((n, data))
}

/// Writes the matrix as CSV: header `material,<names...>`, then one row per material
/// (values printed with 17 significant digits, round-trip exact), atomically.
pub fn write_csv(path: &Path, m: &DistanceMatrix) -> Result<(), OutputError> {
    write_atomic(path, |w| {
        let mut wr = csv::Writer::from_writer(w);
        let mut head = vec!["material".to_string()];
        head.extend(m.names().iter().cloned());
        wr.write_record(&head)?;
        for (i, name) in m.names().iter().enumerate() {
            let mut rec = vec![name.clone()];
            rec.extend(m.row(i).iter().map(|v| format!("{v:.17e}")));
            wr.write_record(&rec)?;
        }
        wr.flush()?;
        Ok(())
    })
}

// ---------------------------------------------------------------------------------------
// Saved matrices and tiles: a `.npy` with a JSON sidecar, loading with validation, merge.
// ---------------------------------------------------------------------------------------

use crate::distance::Tile;
use std::io::{Read, Write};
use std::path::PathBuf;

/// FNV-1a, 64 bit, over 8-byte little-endian words (the tail bytes one by one), so that
/// hashing is independent of how the input is split between calls.
#[derive(Clone, Debug)]
pub struct Fnv64 {
    h: u64,
    pending: [u8; 8],
    len: usize,
}

impl Default for Fnv64 {
    fn default() -> Self {
        Self::new()
    }
}

impl Fnv64 {
    const PRIME: u64 = 0x0000_0100_0000_01b3;

    /// A fresh hash.
    pub fn new() -> Self {
        Self {
            h: 0xcbf2_9ce4_8422_2325,
            pending: [0; 8],
            len: 0,
        }
    }

    /// Adds bytes.
    pub fn write(&mut self, mut bytes: &[u8]) {
        if self.len > 0 {
            let take = (8 - self.len).min(bytes.len());
            self.pending[self.len..self.len + take].copy_from_slice(&bytes[..take]);
            self.len += take;
            bytes = &bytes[take..];
            if self.len < 8 {
                return;
            }
            self.h = (self.h ^ u64::from_le_bytes(self.pending)).wrapping_mul(Self::PRIME);
            self.len = 0;
        }
        let words = bytes.chunks_exact(8);
        let rest = words.remainder();
        for w in words {
            let w = u64::from_le_bytes([w[0], w[1], w[2], w[3], w[4], w[5], w[6], w[7]]);
            self.h = (self.h ^ w).wrapping_mul(Self::PRIME);
        }
        self.pending[..rest.len()].copy_from_slice(rest);
        self.len = rest.len();
    }

    /// The hash of everything written.
    pub fn finish(&self) -> u64 {
        let mut h = self.h;
        for &b in &self.pending[..self.len] {
            h = (h ^ b as u64).wrapping_mul(Self::PRIME);
        }
        (h ^ self.len as u64).wrapping_mul(Self::PRIME)
    }
}

/// Errors of saved matrices, tiles and merging. Each names the file and, for a bad
/// entry, the row and column (index and material).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MatrixFileError {
    /// I/O failure.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// Not a readable `.npy`, CSV or sidecar.
    #[error("{path}: {message}")]
    Format {
        /// File.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A `.npy` without its names sidecar.
    #[error("{npy}: no names sidecar `{sidecar}`: a saved .npy matrix is read together with the JSON sidecar `brdf-basis distance` writes beside it (or give a .csv, whose header holds the names)")]
    NoSidecar {
        /// The matrix.
        npy: PathBuf,
        /// The sidecar looked for.
        sidecar: PathBuf,
    },
    /// The `.npy` is not the one its sidecar describes.
    #[error("{npy} does not match its sidecar {sidecar} ({what}): the pair was not written together (interrupted or mixed copies); compute the matrix again")]
    Mismatch {
        /// The matrix.
        npy: PathBuf,
        /// The sidecar.
        sidecar: PathBuf,
        /// Which check failed.
        what: String,
    },
    /// Not square.
    #[error("{path}: the matrix is not square: {message}")]
    NotSquare {
        /// File.
        path: PathBuf,
        /// Shape found.
        message: String,
    },
    /// A bad entry.
    #[error("{path}: entry at row {row} (`{row_name}`), column {col} (`{col_name}`) is {value}: {reason}")]
    Entry {
        /// File.
        path: PathBuf,
        /// Row index (0-based).
        row: usize,
        /// Row material.
        row_name: String,
        /// Column index (0-based).
        col: usize,
        /// Column material.
        col_name: String,
        /// The value.
        value: f64,
        /// Why it is refused.
        reason: String,
    },
    /// Names that do not fit the matrix.
    #[error("{path}: {message}")]
    Names {
        /// File.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Tiles that do not assemble into one matrix.
    #[error("cannot merge tiles: {0}")]
    Merge(String),
    /// Writing failed.
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// The settings a matrix was computed with (all as their command-line spellings).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct MatrixSettings {
    /// `brdf-it` or `euclidean`.
    pub metric: String,
    /// `specular` or `full`.
    pub lobe: String,
    /// `uniform` or `solid-angle`.
    pub weighting: String,
    /// `evaluation` or `valid`.
    pub mask: String,
    /// Grid stride.
    pub stride: usize,
    /// Materials per super-block of the banded computation.
    pub band_rows: usize,
}

impl MatrixSettings {
    /// The settings of validated distance parameters.
    pub fn of(p: &crate::distance::ValidDistanceParams, band_rows: usize) -> Self {
        Self {
            metric: p.metric.to_string(),
            lobe: p.lobe.to_string(),
            weighting: p.weighting.to_string(),
            mask: p.mask.to_string(),
            stride: p.stride,
            band_rows,
        }
    }
}

/// Which rows of the whole matrix a tile holds.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
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
pub struct MatrixSidecar {
    /// Format tag, `brdf-basis-matrix/1`.
    pub format: String,
    /// Number of materials `N` (the matrix is `N x N`, a tile `rows x N`).
    pub n: usize,
    /// Material names in row order.
    pub names: Vec<String>,
    /// Settings it was computed with.
    pub settings: MatrixSettings,
    /// [`crate::distance::collection_fingerprint`] of the collection.
    pub collection_fingerprint: String,
    /// Rows held when this is a tile.
    pub tile: Option<TileInfo>,
    /// Bytes of the `.npy` file.
    pub npy_bytes: u64,
    /// [`Fnv64`] of the `.npy` file's bytes, 16 hex digits.
    pub npy_fnv64: String,
}

/// Format tag of [`MatrixSidecar`].
pub const SIDECAR_FORMAT: &str = "brdf-basis-matrix/1";

/// The sidecar path of a `.npy`: `d.npy` -> `d.names.json`.
pub fn sidecar_path(npy: &Path) -> PathBuf {
    npy.with_extension("names.json")
}

struct HashingWriter<'a> {
    inner: &'a mut dyn Write,
    hash: Fnv64,
    bytes: u64,
}

impl Write for HashingWriter<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let k = self.inner.write(buf)?;
        self.hash.write(&buf[..k]);
        self.bytes += k as u64;
        Ok(k)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// The `.npy` (format 1.0) header of a `rows x cols` little-endian float64 C-order array,
/// padded to a multiple of 64 bytes (as NumPy writes it).
pub fn npy_header(rows: usize, cols: usize) -> Vec<u8> {
    let mut header =
        format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({rows}, {cols}), }}");
    let total = 10 + header.len() + 1;
    header.push_str(&" ".repeat(total.next_multiple_of(64) - total));
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out
}

/// Writes a `rows x cols` float64 `.npy` atomically; returns `(bytes, fnv64)` of the file.
pub fn write_npy_2d(
    path: &Path,
    rows: usize,
    cols: usize,
    data: &[f64],
) -> Result<(u64, u64), OutputError> {
    let mut out = (0, 0);
    write_atomic(path, |w| {
        let mut hw = HashingWriter {
            inner: w,
            hash: Fnv64::new(),
            bytes: 0,
        };
        hw.write_all(&npy_header(rows, cols))?;
        let mut buf = Vec::with_capacity(1 << 16);
        for chunk in data.chunks(1 << 13) {
            buf.clear();
            for v in chunk {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            hw.write_all(&buf)?;
        }
        out = (hw.bytes, hw.hash.finish());
        Ok(())
    })?;
    Ok(out)
}

fn write_sidecar(npy: &Path, side: &MatrixSidecar) -> Result<(), OutputError> {
    crate::io::json::write_json(&sidecar_path(npy), side)
}

/// Writes `m` as `.npy` and then its sidecar (names, settings, fingerprint, the `.npy`'s
/// size and checksum), each atomically: an interrupted write leaves either the old pair or
/// a new `.npy` that no longer matches its sidecar, which [`load_saved_matrix`] refuses.
pub fn write_npy_with_sidecar(
    path: &Path,
    m: &DistanceMatrix,
    settings: &MatrixSettings,
    fingerprint: &str,
) -> Result<(), OutputError> {
    let n = m.names().len();
    let (bytes, hash) = write_npy_2d(path, n, n, m.as_full())?;
    write_sidecar(
        path,
        &MatrixSidecar {
            format: SIDECAR_FORMAT.into(),
            n,
            names: m.names().to_vec(),
            settings: settings.clone(),
            collection_fingerprint: fingerprint.into(),
            tile: None,
            npy_bytes: bytes,
            npy_fnv64: format!("{hash:016x}"),
        },
    )
}

/// Writes a tile as `.npy` (`rows x (N - first row)`: the band from its diagonal block
/// rightwards) and its sidecar (with the tile's index, count and rows).
pub fn write_tile(
    path: &Path,
    tile: &Tile,
    names: &[String],
    settings: &MatrixSettings,
    fingerprint: &str,
) -> Result<(), OutputError> {
    let (bytes, hash) = write_npy_2d(path, tile.rows.len(), tile.n - tile.rows.start, &tile.data)?;
    write_sidecar(
        path,
        &MatrixSidecar {
            format: SIDECAR_FORMAT.into(),
            n: tile.n,
            names: names.to_vec(),
            settings: settings.clone(),
            collection_fingerprint: fingerprint.into(),
            tile: Some(TileInfo {
                index: tile.index,
                count: tile.count,
                row_start: tile.rows.start,
                row_end: tile.rows.end,
            }),
            npy_bytes: bytes,
            npy_fnv64: format!("{hash:016x}"),
        },
    )
}

/// Reads a sidecar.
pub fn read_sidecar(npy: &Path) -> Result<MatrixSidecar, MatrixFileError> {
    let sp = sidecar_path(npy);
    let text = match std::fs::read_to_string(&sp) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(MatrixFileError::NoSidecar {
                npy: npy.to_path_buf(),
                sidecar: sp,
            })
        }
        Err(source) => return Err(MatrixFileError::Io { path: sp, source }),
    };
    let side: MatrixSidecar = serde_json::from_str(&text).map_err(|e| MatrixFileError::Format {
        path: sp.clone(),
        message: format!("not a brdf-basis matrix sidecar: {e}"),
    })?;
    if side.format != SIDECAR_FORMAT {
        return Err(MatrixFileError::Format {
            path: sp,
            message: format!("format `{}`, expected `{SIDECAR_FORMAT}`", side.format),
        });
    }
    Ok(side)
}

/// Streams a 2-D float64 C-order `.npy`: returns `(rows, cols, data, bytes, fnv64)`.
pub fn read_npy_2d(path: &Path) -> Result<(usize, usize, Vec<f64>, u64, u64), MatrixFileError> {
    let io = |source| MatrixFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let bad = |message: String| MatrixFileError::Format {
        path: path.to_path_buf(),
        message,
    };
    let mut f = std::io::BufReader::with_capacity(1 << 20, std::fs::File::open(path).map_err(io)?);
    let mut hash = Fnv64::new();
    let mut magic = [0u8; 8];
    f.read_exact(&mut magic)
        .map_err(|_| bad("not a .npy file (too short)".into()))?;
    if &magic[..6] != b"\x93NUMPY" {
        return Err(bad("not a .npy file (no NumPy magic)".into()));
    }
    hash.write(&magic);
    let hl = if magic[6] == 1 {
        let mut b = [0u8; 2];
        f.read_exact(&mut b).map_err(io)?;
        hash.write(&b);
        u16::from_le_bytes(b) as usize
    } else {
        let mut b = [0u8; 4];
        f.read_exact(&mut b).map_err(io)?;
        hash.write(&b);
        u32::from_le_bytes(b) as usize
    };
    let mut header = vec![0u8; hl];
    f.read_exact(&mut header)
        .map_err(|_| bad("truncated header".into()))?;
    hash.write(&header);
    let header = String::from_utf8_lossy(&header).into_owned();
    if !header.contains("'<f8'") || !header.contains("'fortran_order': False") {
        return Err(bad(format!(
            "expected little-endian float64 in C order, header is {}",
            header.trim()
        )));
    }
    let shape = header
        .split("'shape': (")
        .nth(1)
        .and_then(|s| s.split(')').next())
        .ok_or_else(|| bad("no shape in the header".into()))?;
    let dims: Vec<usize> = shape
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().map_err(|_| bad(format!("bad shape ({shape})"))))
        .collect::<Result<_, _>>()?;
    let (rows, cols) = match dims[..] {
        [r, c] => (r, c),
        _ => {
            return Err(MatrixFileError::NotSquare {
                path: path.to_path_buf(),
                message: format!("shape ({shape}) is not two-dimensional"),
            })
        }
    };
    let count = rows
        .checked_mul(cols)
        .ok_or_else(|| bad(format!("shape ({shape}) is too large")))?;
    let mut data = Vec::with_capacity(count);
    let mut buf = vec![0u8; 1 << 16];
    let mut bytes = (10 + if magic[6] == 1 { 0 } else { 2 } + hl) as u64;
    while data.len() < count {
        let want = ((count - data.len()) * 8).min(buf.len());
        f.read_exact(&mut buf[..want]).map_err(|_| {
            bad(format!(
                "data ends after {} of {count} values of shape ({shape})",
                data.len()
            ))
        })?;
        hash.write(&buf[..want]);
        bytes += want as u64;
        data.extend(
            buf[..want]
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]])),
        );
    }
    let mut rest = Vec::new();
    f.read_to_end(&mut rest).map_err(io)?;
    if !rest.is_empty() {
        return Err(bad(format!(
            "{} bytes after the {count} values of shape ({shape})",
            rest.len()
        )));
    }
    Ok((rows, cols, data, bytes, hash.finish()))
}

/// A saved matrix read back: the validated matrix and, for a `.npy`, its sidecar.
#[derive(Clone, Debug)]
pub struct SavedMatrix {
    /// The matrix.
    pub matrix: DistanceMatrix,
    /// The sidecar (`None` for a CSV).
    pub sidecar: Option<MatrixSidecar>,
}

/// Relative tolerance of the symmetry check of a loaded matrix:
/// `|D_ij - D_ji| <= SYMMETRY_TOL * max(|D_ij|, |D_ji|)`; pairs within it are replaced by
/// their mean (exact for the matrices `distance` writes, which are exactly symmetric).
pub const SYMMETRY_TOL: f64 = 1e-9;

/// Loads a saved matrix for clustering: a `.npy` with its sidecar (sizes and checksum
/// must match) or a `.csv` (header `material,<names...>`, one row per material). Checks
/// that it is square, finite, non-negative, zero on the diagonal, symmetric within
/// [`SYMMETRY_TOL`], with unique names matching its size; every error names the file and
/// the offending row and column.
pub fn load_saved_matrix(path: &Path) -> Result<SavedMatrix, MatrixFileError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let (names, data, sidecar) = match ext.as_str() {
        "npy" => {
            let side = read_sidecar(path)?;
            let (rows, cols, data, bytes, hash) = read_npy_2d(path)?;
            let mismatch = |what: String| MatrixFileError::Mismatch {
                npy: path.to_path_buf(),
                sidecar: sidecar_path(path),
                what,
            };
            if side.tile.is_some() {
                return Err(MatrixFileError::Format {
                    path: path.to_path_buf(),
                    message: "this is a tile of a matrix, not a whole matrix: assemble the tiles with `brdf-basis merge TILE... --out FILE.npy` first".into(),
                });
            }
            if rows != cols {
                return Err(MatrixFileError::NotSquare {
                    path: path.to_path_buf(),
                    message: format!("shape ({rows}, {cols})"),
                });
            }
            if bytes != side.npy_bytes || format!("{hash:016x}") != side.npy_fnv64 {
                return Err(mismatch(format!(
                    "file has {bytes} bytes, checksum {hash:016x}; the sidecar records {} bytes, checksum {}",
                    side.npy_bytes, side.npy_fnv64
                )));
            }
            if side.n != rows {
                return Err(mismatch(format!(
                    "matrix is {rows} x {rows}, the sidecar says N = {}",
                    side.n
                )));
            }
            (side.names.clone(), data, Some(side))
        }
        "csv" => {
            let (names, data) = read_csv_matrix(path)?;
            (names, data, None)
        }
        _ => {
            return Err(MatrixFileError::Format {
                path: path.to_path_buf(),
                message: "a saved matrix must end in .npy (with its .names.json sidecar) or .csv"
                    .into(),
            })
        }
    };
    let matrix = validate_matrix(path, names, data)?;
    Ok(SavedMatrix { matrix, sidecar })
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

/// The checks of [`load_saved_matrix`] on `names` and a row-major `N x N` array.
pub fn validate_matrix(
    path: &Path,
    names: Vec<String>,
    mut data: Vec<f64>,
) -> Result<DistanceMatrix, MatrixFileError> {
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
    if n < 2 {
        return Err(names_err(format!(
            "a distance matrix needs at least 2 materials, found {n}"
        )));
    }
    let mut seen = std::collections::HashMap::with_capacity(n);
    for (i, name) in names.iter().enumerate() {
        if name.is_empty() {
            return Err(names_err(format!("material {i} has an empty name")));
        }
        if let Some(j) = seen.insert(name.as_str(), i) {
            return Err(names_err(format!(
                "material `{name}` is named twice (rows {j} and {i})"
            )));
        }
    }
    let entry = |i: usize, j: usize, value: f64, reason: &str| MatrixFileError::Entry {
        path: path.to_path_buf(),
        row: i,
        row_name: names[i].clone(),
        col: j,
        col_name: names[j].clone(),
        value,
        reason: reason.into(),
    };
    for i in 0..n {
        for j in 0..n {
            let v = data[i * n + j];
            if !v.is_finite() {
                return Err(entry(i, j, v, "not a finite number"));
            }
            if v < 0.0 {
                return Err(entry(i, j, v, "a distance cannot be negative"));
            }
        }
        if data[i * n + i] != 0.0 {
            return Err(entry(i, i, data[i * n + i], "the diagonal must be 0"));
        }
    }
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (data[i * n + j], data[j * n + i]);
            if a != b {
                if (a - b).abs() > SYMMETRY_TOL * a.abs().max(b.abs()) {
                    return Err(entry(
                        i,
                        j,
                        a,
                        &format!(
                            "the matrix is not symmetric: the entry at row {j}, column {i} is {b} (relative tolerance {SYMMETRY_TOL:e})"
                        ),
                    ));
                }
                let m = 0.5 * (a + b);
                data[i * n + j] = m;
                data[j * n + i] = m;
            }
        }
    }
    DistanceMatrix::from_full(names, data).map_err(|e| MatrixFileError::Format {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Assembles tiles into the whole matrix and writes it with its sidecar. Refuses tiles
/// of different collections, settings or tilings, a missing or doubled tile, tiles whose
/// rows do not cover the matrix and a tile whose data does not match its sidecar, naming
/// the files. Streams: memory holds one tile; the output is written to a temporary file
/// beside `out` and renamed over it only when complete.
pub fn merge_tiles(tiles: &[PathBuf], out: &Path) -> Result<MatrixSidecar, MatrixFileError> {
    let merr = MatrixFileError::Merge;
    if tiles.is_empty() {
        return Err(merr("no tile given".into()));
    }
    let sides: Vec<MatrixSidecar> = tiles
        .iter()
        .map(|t| read_sidecar(t))
        .collect::<Result<_, _>>()?;
    let info = |k: usize| {
        sides[k].tile.clone().ok_or_else(|| {
            merr(format!(
                "{} is a whole matrix, not a tile (written without --tile)",
                tiles[k].display()
            ))
        })
    };
    let first = &sides[0];
    let i0 = info(0)?;
    let count = i0.count;
    let mut by_index: Vec<Option<usize>> = vec![None; count];
    for (k, s) in sides.iter().enumerate() {
        let t = info(k)?;
        let (a, b) = (tiles[0].display(), tiles[k].display());
        if s.collection_fingerprint != first.collection_fingerprint || s.names != first.names {
            return Err(merr(format!(
                "{b} comes from another collection than {a} (fingerprint {} vs {})",
                s.collection_fingerprint, first.collection_fingerprint
            )));
        }
        if s.settings != first.settings {
            return Err(merr(format!(
                "{b} was computed with other settings than {a} ({:?} vs {:?})",
                s.settings, first.settings
            )));
        }
        if t.count != count {
            return Err(merr(format!(
                "{b} is tile {}/{} but {a} is tile {}/{count}: tiles of different tilings",
                t.index, t.count, i0.index
            )));
        }
        if t.index == 0 || t.index > count {
            return Err(merr(format!(
                "{b}: tile index {} out of 1..{count}",
                t.index
            )));
        }
        if let Some(prev) = by_index[t.index - 1] {
            return Err(merr(format!(
                "tile {}/{count} is given twice: {} and {b}",
                t.index,
                tiles[prev].display()
            )));
        }
        by_index[t.index - 1] = Some(k);
    }
    let missing: Vec<String> = (0..count)
        .filter(|&i| by_index[i].is_none())
        .map(|i| format!("{}/{count}", i + 1))
        .collect();
    if !missing.is_empty() {
        return Err(merr(format!(
            "tile(s) {} missing (given: {})",
            missing.join(", "),
            tiles
                .iter()
                .map(|t| t.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let n = first.n;
    let order: Vec<usize> = by_index.into_iter().flatten().collect();
    let mut next_row = 0usize;
    for &k in &order {
        let t = info(k)?;
        if t.row_start != next_row || t.row_end <= t.row_start || t.row_end > n {
            return Err(merr(format!(
                "{} holds rows {}..{}, expected rows starting at {next_row}",
                tiles[k].display(),
                t.row_start,
                t.row_end
            )));
        }
        next_row = t.row_end;
    }
    if next_row != n || first.names.len() != n {
        return Err(merr(format!(
            "the tiles cover rows 0..{next_row} of {n} ({} names)",
            first.names.len()
        )));
    }
    let mut seen = std::collections::HashSet::with_capacity(n);
    if let Some(dup) = first.names.iter().find(|m| !seen.insert(m.as_str())) {
        return Err(merr(format!(
            "{}: material `{dup}` is named twice",
            sidecar_path(&tiles[order[0]]).display()
        )));
    }
    // Streamed: the output file is written in place, tile by tile (its own rows, then
    // the transposed block below them), so memory holds one tile, not the N x N matrix.
    let name = out
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = out.with_file_name(format!(".{name}.merge-{}", std::process::id()));
    let result = (|| -> Result<(u64, u64), MatrixFileError> {
        use std::io::{Seek, SeekFrom};
        let io = |source| MatrixFileError::Io {
            path: out.to_path_buf(),
            source,
        };
        let mut file = std::fs::File::create(&tmp).map_err(io)?;
        let header = npy_header(n, n);
        file.write_all(&header).map_err(io)?;
        let base = header.len() as u64;
        file.set_len(base + (n * n * 8) as u64).map_err(io)?;
        let mut seg: Vec<u8> = Vec::new();
        for &k in &order {
            let t = info(k)?;
            let path = &tiles[k];
            let (r0, r1) = (t.row_start, t.row_end);
            let (rows, cols, tile, bytes, hash) = read_npy_2d(path)?;
            let mismatch = |what: String| MatrixFileError::Mismatch {
                npy: path.clone(),
                sidecar: sidecar_path(path),
                what,
            };
            if bytes != sides[k].npy_bytes || format!("{hash:016x}") != sides[k].npy_fnv64 {
                return Err(mismatch("size or checksum differs".into()));
            }
            let w = n - r0;
            if rows != r1 - r0 || cols != w {
                return Err(mismatch(format!(
                    "shape ({rows}, {cols}), expected ({}, {w})",
                    r1 - r0
                )));
            }
            for (r, i) in (r0..r1).enumerate() {
                for j in r0..n {
                    let v = tile[r * w + (j - r0)];
                    let reason = if !v.is_finite() {
                        "not a finite number"
                    } else if v < 0.0 {
                        "a distance cannot be negative"
                    } else if i == j && v != 0.0 {
                        "the diagonal must be 0"
                    } else {
                        continue;
                    };
                    return Err(MatrixFileError::Entry {
                        path: path.clone(),
                        row: i,
                        row_name: first.names[i].clone(),
                        col: j,
                        col_name: first.names[j].clone(),
                        value: v,
                        reason: reason.into(),
                    });
                }
                seg.clear();
                for v in &tile[r * w..(r + 1) * w] {
                    seg.extend_from_slice(&v.to_le_bytes());
                }
                file.seek(SeekFrom::Start(base + ((i * n + r0) * 8) as u64))
                    .map_err(io)?;
                file.write_all(&seg).map_err(io)?;
            }
            for j in r1..n {
                seg.clear();
                for r in 0..r1 - r0 {
                    seg.extend_from_slice(&tile[r * w + (j - r0)].to_le_bytes());
                }
                file.seek(SeekFrom::Start(base + ((j * n + r0) * 8) as u64))
                    .map_err(io)?;
                file.write_all(&seg).map_err(io)?;
            }
        }
        file.sync_all().map_err(io)?;
        drop(file);
        let mut rd =
            std::io::BufReader::with_capacity(1 << 20, std::fs::File::open(&tmp).map_err(io)?);
        let mut h = Fnv64::new();
        let mut buf = vec![0u8; 1 << 20];
        let mut total = 0u64;
        loop {
            let k = rd.read(&mut buf).map_err(io)?;
            if k == 0 {
                break;
            }
            h.write(&buf[..k]);
            total += k as u64;
        }
        std::fs::rename(&tmp, out).map_err(io)?;
        Ok((total, h.finish()))
    })();
    let (bytes, hash) = match result {
        Ok(v) => v,
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            return Err(e);
        }
    };
    let side = MatrixSidecar {
        format: SIDECAR_FORMAT.into(),
        n,
        names: first.names.clone(),
        settings: first.settings.clone(),
        collection_fingerprint: first.collection_fingerprint.clone(),
        tile: None,
        npy_bytes: bytes,
        npy_fnv64: format!("{hash:016x}"),
    };
    write_sidecar(out, &side)?;
    Ok(side)
}
