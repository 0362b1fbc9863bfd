//! NumPy `.npy` files of 2-D little-endian float64 arrays in C order: one writer, one
//! reader; a reader of small 1-D or 2-D float32 arrays (network weights,
//! [`read_npy_f32`]); and one header parser that reads the header as what it is (a Python dict
//! literal), so headers written by NumPy or other tools with other key orders, quotes or
//! spacing, and format versions 1.0 to 3.0, are accepted.
//!
//! Every file written or read is hashed on the way ([`crate::hash`], XXH3-64: the value
//! `xxhsum -H3 FILE` prints), so the sidecar of a saved matrix can record and check it.

use super::MatrixFileError;
use crate::atomic::{write_atomic, OutputSet};
use crate::error::OutputError;
use crate::hash::{Hasher, HashingWriter};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::Path;

pub(crate) use crate::npy_format::parse_header_dict;
use crate::npy_format::read_header_text;
use crate::npy_format::NpyF32;

/// Size and checksum of a `.npy` file as written or read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NpyDigest {
    /// Bytes of the file.
    pub bytes: u64,
    /// XXH3-64 of the file's bytes.
    pub xxh3: u64,
}

/// A 2-D float64 array read from a `.npy`.
#[derive(Clone, Debug, PartialEq)]
pub struct Npy2d {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Row-major values, `rows * cols` of them.
    pub data: Vec<f64>,
    /// Size and checksum of the file.
    pub digest: NpyDigest,
}

/// The `.npy` (format 1.0) header of a `rows x cols` little-endian float64 C-order array,
/// padded to a multiple of 64 bytes (as NumPy writes it).
#[doc(hidden)]
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

/// Writes the header and the values of a `rows x cols` array to `w`, hashing them.
fn fill(w: &mut dyn Write, rows: usize, cols: usize, data: &[f64]) -> std::io::Result<NpyDigest> {
    let mut hw = HashingWriter::new(w);
    hw.write_all(&npy_header(rows, cols))?;
    let mut buf = Vec::with_capacity(1 << 16);
    for chunk in data.chunks(1 << 13) {
        buf.clear();
        for v in chunk {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        hw.write_all(&buf)?;
    }
    let (bytes, xxh3) = hw.digest();
    Ok(NpyDigest { bytes, xxh3 })
}

fn check_len(path: &Path, rows: usize, cols: usize, data: &[f64]) -> Result<(), OutputError> {
    if rows.checked_mul(cols) != Some(data.len()) {
        return Err(OutputError::Encode {
            path: path.to_path_buf(),
            message: format!("{} values for a {rows} x {cols} array", data.len()),
        });
    }
    Ok(())
}

/// Writes a `rows x cols` float64 `.npy` atomically; returns its size and checksum.
pub fn write_npy_2d(
    path: &Path,
    rows: usize,
    cols: usize,
    data: &[f64],
) -> Result<NpyDigest, OutputError> {
    check_len(path, rows, cols, data)?;
    let mut out = None;
    write_atomic(path, |w| {
        out = Some(fill(w, rows, cols, data)?);
        Ok(())
    })?;
    Ok(out.expect("write_atomic ran the writer"))
}

/// Stages a `rows x cols` float64 `.npy` in `set` (renamed into place at its commit);
/// returns its size and checksum.
pub(crate) fn stage_npy_2d(
    set: &mut OutputSet,
    path: &Path,
    rows: usize,
    cols: usize,
    data: &[f64],
) -> Result<NpyDigest, OutputError> {
    check_len(path, rows, cols, data)?;
    let mut out = None;
    set.stage(path, |w| {
        out = Some(fill(w, rows, cols, data)?);
        Ok(())
    })?;
    Ok(out.expect("stage ran the writer"))
}

/// A parsed `.npy` header of a 2-D little-endian float64 C-order array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NpyHeader {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Bytes before the data (magic, version, length and header).
    pub data_offset: u64,
}

/// Reads and parses the header of the `.npy` at the start of `r`, hashing the bytes read.
fn read_header(
    r: &mut impl Read,
    path: &Path,
    hash: &mut Hasher,
) -> Result<NpyHeader, MatrixFileError> {
    let bad = |message: String| MatrixFileError::Format {
        path: path.to_path_buf(),
        message,
    };
    let (text, data_offset) = read_header_text(r, hash).map_err(bad)?;
    let (rows, cols) = parse_header_dict(&text).map_err(bad)?;
    Ok(NpyHeader {
        rows,
        cols,
        data_offset,
    })
}

/// `crate::npy_format::read_npy_f32` with the file named in its errors.
pub fn read_npy_f32(path: &Path, max_values: usize) -> Result<NpyF32, MatrixFileError> {
    crate::npy_format::read_npy_f32(path, max_values).map_err(|message| MatrixFileError::Format {
        path: path.to_path_buf(),
        message,
    })
}

/// Reads only the header of a `.npy` (no hashing of the data).
pub(crate) fn read_npy_header(path: &Path) -> Result<NpyHeader, MatrixFileError> {
    let mut f = std::fs::File::open(path).map_err(|source| MatrixFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_header(&mut f, path, &mut Hasher::new())
}

/// Streams a 2-D float64 C-order `.npy`, checking that it holds exactly the values its
/// shape announces, and hashing it.
pub fn read_npy_2d(path: &Path) -> Result<Npy2d, MatrixFileError> {
    let mut data = Vec::new();
    let (h, digest) = scan_npy_2d(path, |chunk| {
        data.extend_from_slice(chunk);
        Ok(())
    })?;
    Ok(Npy2d {
        rows: h.rows,
        cols: h.cols,
        data,
        digest,
    })
}

/// Streams a 2-D float64 C-order `.npy`, handing its values to `sink` in row-major
/// chunks (any size), and returns the header and the file's size and checksum. A file
/// shorter or longer than its shape says is refused, with the sizes expected and found.
pub(crate) fn scan_npy_2d(
    path: &Path,
    mut sink: impl FnMut(&[f64]) -> Result<(), MatrixFileError>,
) -> Result<(NpyHeader, NpyDigest), MatrixFileError> {
    let io = |source| MatrixFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let bad = |message: String| MatrixFileError::Format {
        path: path.to_path_buf(),
        message,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let file_len = file.metadata().map_err(io)?.len();
    let mut f = std::io::BufReader::with_capacity(1 << 20, file);
    let mut hash = Hasher::new();
    let h = read_header(&mut f, path, &mut hash)?;
    let (count, expected) = check_file_len(path, &h, file_len)?;
    let mut buf = vec![0u8; 1 << 16];
    let mut vals = Vec::with_capacity(buf.len() / 8);
    let mut done = 0usize;
    while done < count {
        let want = ((count - done) * 8).min(buf.len());
        f.read_exact(&mut buf[..want]).map_err(|_| {
            bad(format!(
                "the file ended while being read: {done} of {count} values (the file changed?)"
            ))
        })?;
        hash.write(&buf[..want]);
        vals.clear();
        vals.extend(
            buf[..want]
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]])),
        );
        sink(&vals)?;
        done += want / 8;
    }
    let mut rest = [0u8; 1];
    if f.read(&mut rest).map_err(io)? != 0 {
        return Err(bad(format!(
            "more bytes than the {count} values of shape ({}, {}) (the file changed?)",
            h.rows, h.cols
        )));
    }
    Ok((
        h,
        NpyDigest {
            bytes: expected,
            xxh3: hash.finish(),
        },
    ))
}

/// The number of values of the array `h` describes and the file size it needs; refuses a
/// file of `file_len` bytes that is shorter or longer, with the sizes expected and found.
fn check_file_len(
    path: &Path,
    h: &NpyHeader,
    file_len: u64,
) -> Result<(usize, u64), MatrixFileError> {
    let bad = |message: String| MatrixFileError::Format {
        path: path.to_path_buf(),
        message,
    };
    let count = h
        .rows
        .checked_mul(h.cols)
        .filter(|c| c.checked_mul(8).is_some())
        .ok_or_else(|| bad(format!("shape ({}, {}) is too large", h.rows, h.cols)))?;
    let expected = (8 * count as u64)
        .checked_add(h.data_offset)
        .ok_or_else(|| bad(format!("shape ({}, {}) is too large", h.rows, h.cols)))?;
    if file_len != expected {
        let found = file_len.saturating_sub(h.data_offset);
        return Err(bad(format!(
            "the file has {file_len} bytes, but a ({}, {}) float64 array needs {expected} ({} bytes of header and {count} values of 8 bytes); it holds {found} bytes of data{}",
            h.rows,
            h.cols,
            h.data_offset,
            if found.is_multiple_of(8) {
                format!(" ({} values)", found / 8)
            } else {
                format!(" ({} values and {} stray bytes)", found / 8, found % 8)
            }
        )));
    }
    Ok((count, expected))
}

/// A 2-D float64 array of a `.npy` read in place from a memory map of the file
/// ([`super::mmap`]).
#[derive(Debug)]
pub struct MappedNpy2d {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// The row-major values, `rows * cols` of them, in the mapped file.
    pub values: super::mmap::MappedF64,
    /// Size and checksum of the file.
    pub digest: NpyDigest,
}

/// [`read_npy_2d`] without reading the values into memory: maps the file, checks its
/// header and size exactly as [`read_npy_2d`] does (the same errors), hashes it through
/// the mapping, and returns the values in place. `Ok(None)` when the file cannot be read
/// in place (no `mmap` on this platform, the kernel refused the map, an empty file, data
/// not aligned for `f64`, a big-endian machine): read it with [`read_npy_2d`] instead.
pub(crate) fn map_npy_2d(path: &Path) -> Result<Option<MappedNpy2d>, MatrixFileError> {
    let io = |source| MatrixFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let file_len = file.metadata().map_err(io)?.len();
    let Ok(map) = super::mmap::MappedFile::map(&file, file_len) else {
        return Ok(None);
    };
    drop(file);
    let mut hash = Hasher::new();
    let mut head = map.bytes();
    let h = read_header(&mut head, path, &mut hash)?;
    let (count, _) = check_file_len(path, &h, map.bytes().len() as u64)?;
    let offset = usize::try_from(h.data_offset).expect("the header lies in the mapping");
    let values = match super::mmap::MappedF64::new(map, offset, count) {
        Ok(v) => v,
        Err(_) => return Ok(None),
    };
    // The header's bytes are hashed; the values' bytes follow them to the end.
    let mut values = values;
    hash.write(values.bytes());
    // A file changed under the hashing would only show as a checksum mismatch: say so.
    values
        .unchanged_quick()
        .map_err(|message| MatrixFileError::Changed {
            path: path.to_path_buf(),
            message,
        })?;
    values.set_checksum(hash.finish());
    Ok(Some(MappedNpy2d {
        rows: h.rows,
        cols: h.cols,
        values,
        digest: NpyDigest {
            bytes: file_len,
            xxh3: hash.finish(),
        },
    }))
}

/// Random access to the values of a 2-D float64 `.npy` (header already checked).
pub struct NpyRows {
    file: std::fs::File,
    header: NpyHeader,
    path: std::path::PathBuf,
    buf: Vec<u8>,
}

impl NpyRows {
    /// Opens `path` and reads its header.
    pub fn open(path: &Path) -> Result<Self, MatrixFileError> {
        let mut file = std::fs::File::open(path).map_err(|source| MatrixFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let header = read_header(&mut file, path, &mut Hasher::new())?;
        Ok(Self {
            file,
            header,
            path: path.to_path_buf(),
            buf: Vec::new(),
        })
    }

    /// The header.
    pub fn header(&self) -> NpyHeader {
        self.header
    }

    /// Reads `out.len()` values of row `row` from column `col` into `out`.
    pub fn read_at(
        &mut self,
        row: usize,
        col: usize,
        out: &mut [f64],
    ) -> Result<(), MatrixFileError> {
        let at = self.header.data_offset + 8 * (row * self.header.cols + col) as u64;
        self.buf.resize(8 * out.len(), 0);
        let path = &self.path;
        let io = |source| MatrixFileError::Io {
            path: path.clone(),
            source,
        };
        self.file.seek(SeekFrom::Start(at)).map_err(io)?;
        self.file.read_exact(&mut self.buf).map_err(io)?;
        for (o, c) in out.iter_mut().zip(self.buf.chunks_exact(8)) {
            *o = f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::npy_format::parse_header_f32;

    #[test]
    fn headers_in_any_key_order_quote_and_spacing_parse() {
        for h in [
            "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 4), }",
            "{\"shape\": (3, 4), \"fortran_order\": False, \"descr\": \"<f8\"}",
            "{'descr':'<f8','fortran_order':False,'shape':(3,4)}",
            "  { 'fortran_order' : False ,\n 'shape' : ( 3 , 4 , ) , 'descr' : '<f8' }   \n",
            "{'descr': '<f8', 'fortran_order': False, 'shape': (3L, 4L), }",
        ] {
            assert_eq!(parse_header_dict(h), Ok((3, 4)), "{h}");
        }
    }

    #[test]
    fn wrong_headers_say_what_is_wrong() {
        for (h, want) in [
            (
                "{'descr': '>f8', 'fortran_order': False, 'shape': (3, 3)}",
                "`>f8`",
            ),
            (
                "{'descr': '<f8', 'fortran_order': True, 'shape': (3, 3)}",
                "Fortran",
            ),
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': (3,)}",
                "two-dimensional",
            ),
            ("{'descr': '<f8', 'fortran_order': False}", "no `shape`"),
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 3), 'x': 1}",
                "unexpected value",
            ),
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 3)} x",
                "after the closing",
            ),
            ("{'descr': '<f8', 'descr': '<f8'}", "twice"),
        ] {
            let e = parse_header_dict(h).expect_err(h);
            assert!(e.contains(want), "{h}: {e}");
        }
    }

    #[test]
    fn f32_headers_of_one_or_two_dimensions_parse_and_others_say_why_not() {
        assert_eq!(
            parse_header_f32("{'descr': '<f4', 'fortran_order': False, 'shape': (21,), }"),
            Ok(vec![21])
        );
        assert_eq!(
            parse_header_f32("{'descr': '<f4', 'fortran_order': False, 'shape': (6, 21), }"),
            Ok(vec![6, 21])
        );
        for (h, want) in [
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': (3,)}",
                "`<f8`",
            ),
            (
                "{'descr': '>f4', 'fortran_order': False, 'shape': (3,)}",
                "float32",
            ),
            (
                "{'descr': '<f4', 'fortran_order': True, 'shape': (3, 3)}",
                "Fortran",
            ),
            (
                "{'descr': '<f4', 'fortran_order': False, 'shape': ()}",
                "0 dimensions",
            ),
            (
                "{'descr': '<f4', 'fortran_order': False, 'shape': (1, 2, 3)}",
                "3 dimensions",
            ),
        ] {
            let e = parse_header_f32(h).expect_err(h);
            assert!(e.contains(want), "{h}: {e}");
        }
        // The f64 matrix header keeps its messages.
        let e = parse_header_dict("{'descr': '<f4', 'fortran_order': False, 'shape': (3, 3)}")
            .unwrap_err();
        assert!(e.contains("expected little-endian float64 (`<f8`)"), "{e}");
    }

    #[test]
    fn f32_files_round_trip_and_lying_files_are_refused() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("a.npy");
        let data: Vec<f32> = (0..12).map(|i| i as f32 * 0.5 - 1.0).collect();
        let bytes = crate::npy_format::npy_f32_bytes(&[3, 4], &data);
        std::fs::write(&p, &bytes).expect("write");
        let a = read_npy_f32(&p, 100).expect("read");
        assert_eq!((a.shape, a.data), (vec![3, 4], data.clone()));
        for (cut, want) in [
            (bytes.len() - 1, "needs"),
            (5, "magic"),
            (20, "truncated header"),
        ] {
            std::fs::write(&p, &bytes[..cut]).expect("write");
            let e = read_npy_f32(&p, 100).unwrap_err().to_string();
            assert!(e.contains("a.npy") && e.contains(want), "{cut}: {e}");
        }
        let mut long = bytes.clone();
        long.extend_from_slice(&[0; 4]);
        std::fs::write(&p, &long).expect("write");
        assert!(read_npy_f32(&p, 100)
            .unwrap_err()
            .to_string()
            .contains("needs"));
        std::fs::write(&p, &bytes).expect("write");
        assert!(read_npy_f32(&p, 5)
            .unwrap_err()
            .to_string()
            .contains("more than 5"));
    }

    #[test]
    fn written_header_is_padded_to_64_bytes() {
        let h = npy_header(10, 7);
        assert_eq!(h.len() % 64, 0);
        let text = std::str::from_utf8(&h[10..]).expect("utf8");
        assert_eq!(parse_header_dict(text), Ok((10, 7)));
    }
}
