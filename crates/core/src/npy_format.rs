//! The `.npy` format below every module that reads one: the one header parser (a Python
//! dict literal, any key order, quotes and spacing; format versions 1.0 to 3.0), and a
//! reader of small 1-D or 2-D float32 arrays (neural BRDF weights, read by
//! `collection`). [`crate::io::npy`] builds the matrix files on it and re-exports it; it
//! lives here, not in `io`, because `collection` reads float32 sets and `io` sits above
//! `collection` in the module graph.

use crate::hash::Hasher;
use std::io::Read;
use std::path::Path;

/// The bytes of a little-endian float32 C-order `.npy` (format 1.0) of `shape` holding
/// `data`, as NumPy writes it (the neural BRDF layout; tests and benches write sets
/// with it).
#[doc(hidden)]
pub fn npy_f32_bytes(shape: &[usize], data: &[f32]) -> Vec<u8> {
    let dims = match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {dims}, }}");
    let total = 10 + header.len() + 1;
    header.push_str(&" ".repeat(total.next_multiple_of(64) - total));
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// A value of the header's dict literal.
#[derive(Debug, PartialEq)]
pub(crate) enum PyValue {
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

/// The three fields of a `.npy` header's dict literal: `(descr, fortran_order, shape)`.
/// The message says what is wrong.
pub(crate) fn header_fields(text: &str) -> Result<(String, bool, Vec<u64>), String> {
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
    Ok((descr, fortran, shape))
}

pub(crate) fn shape_text(shape: &[u64]) -> String {
    shape
        .iter()
        .map(u64::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// Parses the text of a `.npy` header (the dict literal) for a 2-D little-endian
/// float64 C-order array; returns `(rows, cols)`. The message says what is wrong.
pub(crate) fn parse_header_dict(text: &str) -> Result<(usize, usize), String> {
    let (descr, fortran, shape) = header_fields(text)?;
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
            shape_text(&shape)
        )),
    }
}

/// Parses the text of a `.npy` header for a little-endian float32 C-order array of 1 or
/// 2 dimensions; returns its shape. The message says what is wrong.
pub(crate) fn parse_header_f32(text: &str) -> Result<Vec<usize>, String> {
    let (descr, fortran, shape) = header_fields(text)?;
    if descr != "<f4" {
        return Err(format!(
            "data type `{descr}`: expected little-endian float32 (`<f4`)"
        ));
    }
    if fortran && shape.len() > 1 {
        return Err("the array is in Fortran order: expected C order".into());
    }
    if !(1..=2).contains(&shape.len()) {
        return Err(format!(
            "shape ({}) has {} dimensions: expected 1 or 2",
            shape_text(&shape),
            shape.len()
        ));
    }
    shape
        .iter()
        .map(|&d| usize::try_from(d).map_err(|_| "shape too large".to_string()))
        .collect()
}

/// Reads the magic, version, length and header text of the `.npy` at the start of `r`,
/// hashing the bytes read; returns the text and the offset of the data, or what is wrong.
pub(crate) fn read_header_text(
    r: &mut impl Read,
    hash: &mut Hasher,
) -> Result<(String, u64), String> {
    let bad = |message: String| message;
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
    Ok((text.to_string(), (8 + len_bytes + hl) as u64))
}

/// A 1-D or 2-D float32 array read from a `.npy`.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyF32 {
    /// Its shape (1 or 2 dimensions).
    pub shape: Vec<usize>,
    /// Values in C order.
    pub data: Vec<f32>,
}

/// Reads a little-endian float32 C-order `.npy` of 1 or 2 dimensions, of at most
/// `max_values` values, whole (small arrays: network weights). A file that is not a
/// regular file, shorter or longer than its shape says, or larger than the limit is
/// refused with what is wrong (the caller names the file); the values are returned as stored (NaN included: the
/// caller checks what they mean).
pub(crate) fn read_npy_f32(path: &Path, max_values: usize) -> Result<NpyF32, String> {
    let io = |e: std::io::Error| format!("cannot read: {e}");
    let bad = |message: String| message;
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(bad(format!(
            "is {}, not a regular file",
            crate::merl::file_kind(&meta)
        )));
    }
    // The header is at most 1 MiB (checked by `read_header_text`).
    let limit = (1u64 << 20) + 16 + 4 * max_values as u64;
    if meta.len() > limit {
        return Err(bad(format!(
            "{} bytes: larger than any float32 array of at most {max_values} values",
            meta.len()
        )));
    }
    let bytes = std::fs::read(path).map_err(io)?;
    let mut r = &bytes[..];
    let (text, data_offset) = read_header_text(&mut r, &mut Hasher::new())?;
    let shape = parse_header_f32(&text).map_err(bad)?;
    let count = shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .filter(|&c| c <= max_values)
        .ok_or_else(|| {
            bad(format!(
                "shape ({}) holds more than {max_values} values",
                shape_text(&shape.iter().map(|&d| d as u64).collect::<Vec<_>>())
            ))
        })?;
    let expected = data_offset + 4 * count as u64;
    let file_len = bytes.len() as u64;
    if file_len != expected {
        let found = file_len.saturating_sub(data_offset);
        return Err(bad(format!(
            "the file has {file_len} bytes, but a ({}) float32 array needs {expected} ({data_offset} bytes of header and {count} values of 4 bytes); it holds {found} bytes of data",
            shape_text(&shape.iter().map(|&d| d as u64).collect::<Vec<_>>()),
        )));
    }
    let data = bytes[data_offset as usize..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok(NpyF32 { shape, data })
}
