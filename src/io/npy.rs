//! NumPy `.npy` files of 2-D little-endian float64 arrays in C order: one writer, one
//! reader, and a header parser that reads the header as what it is (a Python dict
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
pub fn stage_npy_2d(
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

/// A value of the header's dict literal.
#[derive(Debug, PartialEq)]
enum PyValue {
    Str(String),
    Bool(bool),
    Tuple(Vec<u64>),
}

/// A tiny parser of the Python literal NumPy writes as the header:
/// `{'descr': '<f8', 'fortran_order': False, 'shape': (3, 3), }`, with either quote,
/// any spacing, keys in any order and an optional trailing comma.
struct Literal<'a> {
    s: &'a [u8],
    at: usize,
}

impl<'a> Literal<'a> {
    fn skip_ws(&mut self) {
        while self.at < self.s.len() && self.s[self.at].is_ascii_whitespace() {
            self.at += 1;
        }
    }

    fn peek(&mut self) -> Option<u8> {
        self.skip_ws();
        self.s.get(self.at).copied()
    }

    fn expect(&mut self, c: u8) -> Result<(), String> {
        match self.peek() {
            Some(x) if x == c => {
                self.at += 1;
                Ok(())
            }
            Some(x) => Err(format!(
                "expected `{}` at character {}, found `{}`",
                c as char, self.at, x as char
            )),
            None => Err(format!("expected `{}`, the header ends", c as char)),
        }
    }

    fn string(&mut self) -> Result<String, String> {
        let q = match self.peek() {
            Some(q @ (b'\'' | b'"')) => q,
            _ => return Err(format!("expected a quoted string at character {}", self.at)),
        };
        self.at += 1;
        let start = self.at;
        while self.at < self.s.len() && self.s[self.at] != q {
            if self.s[self.at] == b'\\' {
                return Err("escapes in header strings are not supported".into());
            }
            self.at += 1;
        }
        if self.at >= self.s.len() {
            return Err("unterminated string".into());
        }
        let out = String::from_utf8_lossy(&self.s[start..self.at]).into_owned();
        self.at += 1;
        Ok(out)
    }

    fn word(&mut self) -> &'a [u8] {
        self.skip_ws();
        let start = self.at;
        while self.at < self.s.len() && (self.s[self.at].is_ascii_alphanumeric()) {
            self.at += 1;
        }
        &self.s[start..self.at]
    }

    fn tuple(&mut self) -> Result<Vec<u64>, String> {
        self.expect(b'(')?;
        let mut out = Vec::new();
        loop {
            if self.peek() == Some(b')') {
                self.at += 1;
                return Ok(out);
            }
            let w = self.word();
            // NumPy may write `3L` (Python 2).
            let digits = w.strip_suffix(b"L").unwrap_or(w);
            let v = std::str::from_utf8(digits)
                .ok()
                .and_then(|d| d.parse::<u64>().ok())
                .ok_or_else(|| {
                    format!(
                        "`{}` is not a dimension (a whole number)",
                        String::from_utf8_lossy(w)
                    )
                })?;
            out.push(v);
            match self.peek() {
                Some(b',') => self.at += 1,
                Some(b')') => {}
                _ => return Err("expected `,` or `)` in the shape".into()),
            }
        }
    }

    fn value(&mut self) -> Result<PyValue, String> {
        match self.peek() {
            Some(b'\'' | b'"') => Ok(PyValue::Str(self.string()?)),
            Some(b'(') => Ok(PyValue::Tuple(self.tuple()?)),
            _ => match self.word() {
                b"True" => Ok(PyValue::Bool(true)),
                b"False" => Ok(PyValue::Bool(false)),
                w => Err(format!(
                    "unexpected value `{}` at character {}",
                    String::from_utf8_lossy(w),
                    self.at
                )),
            },
        }
    }

    fn dict(&mut self) -> Result<Vec<(String, PyValue)>, String> {
        self.expect(b'{')?;
        let mut out: Vec<(String, PyValue)> = Vec::new();
        loop {
            if self.peek() == Some(b'}') {
                self.at += 1;
                break;
            }
            let k = self.string()?;
            self.expect(b':')?;
            let v = self.value()?;
            if out.iter().any(|(x, _)| *x == k) {
                return Err(format!("key `{k}` appears twice"));
            }
            out.push((k, v));
            match self.peek() {
                Some(b',') => self.at += 1,
                Some(b'}') => {}
                _ => return Err("expected `,` or `}` after a value".into()),
            }
        }
        if self.peek().is_some() {
            return Err(format!(
                "text after the closing `}}` at character {}",
                self.at
            ));
        }
        Ok(out)
    }
}

/// Parses the text of a `.npy` header (the dict literal) for a 2-D little-endian
/// float64 C-order array; returns `(rows, cols)`. The message says what is wrong.
pub fn parse_header_dict(text: &str) -> Result<(usize, usize), String> {
    let entries = Literal {
        s: text.as_bytes(),
        at: 0,
    }
    .dict()
    .map_err(|e| format!("unreadable header `{}`: {e}", text.trim()))?;
    let (mut descr, mut fortran, mut shape) = (None, None, None);
    for (k, v) in entries {
        match (k.as_str(), v) {
            ("descr", PyValue::Str(s)) => descr = Some(s),
            ("fortran_order", PyValue::Bool(b)) => fortran = Some(b),
            ("shape", PyValue::Tuple(t)) => shape = Some(t),
            (k @ ("descr" | "fortran_order" | "shape"), v) => {
                return Err(format!("header key `{k}` has an unexpected value {v:?}"))
            }
            (k, _) => return Err(format!("unknown header key `{k}`")),
        }
    }
    let descr = descr.ok_or("the header has no `descr`")?;
    let fortran = fortran.ok_or("the header has no `fortran_order`")?;
    let shape = shape.ok_or("the header has no `shape`")?;
    if descr != "<f8" {
        return Err(format!(
            "data type `{descr}`: expected little-endian float64 (`<f8`)"
        ));
    }
    if fortran {
        return Err("the array is in Fortran order: expected C order".into());
    }
    match shape[..] {
        [r, c] => Ok((
            usize::try_from(r).map_err(|_| "shape too large")?,
            usize::try_from(c).map_err(|_| "shape too large")?,
        )),
        _ => Err(format!(
            "shape ({}) is not two-dimensional",
            shape
                .iter()
                .map(u64::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
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
    let mut magic = [0u8; 8];
    r.read_exact(&mut magic)
        .map_err(|_| bad("not a .npy file (shorter than its 8-byte magic)".into()))?;
    if &magic[..6] != b"\x93NUMPY" {
        return Err(bad("not a .npy file (no NumPy magic)".into()));
    }
    hash.write(&magic);
    let (hl, len_bytes) = match magic[6] {
        1 => {
            let mut b = [0u8; 2];
            r.read_exact(&mut b)
                .map_err(|_| bad("truncated header".into()))?;
            hash.write(&b);
            (u16::from_le_bytes(b) as usize, 2)
        }
        2 | 3 => {
            let mut b = [0u8; 4];
            r.read_exact(&mut b)
                .map_err(|_| bad("truncated header".into()))?;
            hash.write(&b);
            (u32::from_le_bytes(b) as usize, 4)
        }
        v => {
            return Err(bad(format!(
                ".npy format version {v}.{} is not supported (1.0 to 3.0 are)",
                magic[7]
            )))
        }
    };
    if hl > 1 << 20 {
        return Err(bad(format!("header of {hl} bytes: not a matrix header")));
    }
    let mut header = vec![0u8; hl];
    r.read_exact(&mut header).map_err(|_| {
        bad(format!(
            "truncated header: the file ends before the {hl} header bytes it announces"
        ))
    })?;
    hash.write(&header);
    let text =
        std::str::from_utf8(&header).map_err(|_| bad("the header is not UTF-8 text".into()))?;
    let (rows, cols) = parse_header_dict(text).map_err(bad)?;
    Ok(NpyHeader {
        rows,
        cols,
        data_offset: (8 + len_bytes + hl) as u64,
    })
}

/// Reads only the header of a `.npy` (no hashing of the data).
pub fn read_npy_header(path: &Path) -> Result<NpyHeader, MatrixFileError> {
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
pub fn scan_npy_2d(
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
    let count = h
        .rows
        .checked_mul(h.cols)
        .filter(|c| c.checked_mul(8).is_some())
        .ok_or_else(|| bad(format!("shape ({}, {}) is too large", h.rows, h.cols)))?;
    let expected = h.data_offset + 8 * count as u64;
    if file_len != expected {
        let found = file_len.saturating_sub(h.data_offset);
        return Err(bad(format!(
            "the file has {file_len} bytes, but a ({}, {}) float64 array needs {expected} ({} bytes of header and {count} values of 8 bytes); it holds {found} bytes of data{}",
            h.rows,
            h.cols,
            h.data_offset,
            if found % 8 == 0 {
                format!(" ({} values)", found / 8)
            } else {
                format!(" ({} values and {} stray bytes)", found / 8, found % 8)
            }
        )));
    }
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
    fn written_header_is_padded_to_64_bytes() {
        let h = npy_header(10, 7);
        assert_eq!(h.len() % 64, 0);
        let text = std::str::from_utf8(&h[10..]).expect("utf8");
        assert_eq!(parse_header_dict(text), Ok((10, 7)));
    }
}
