//! The `tensor_file` container of RGL-EPFL `.bsdf` files (the format Mitsuba's
//! `TensorFile` reads): the magic `tensor_file\0`, a u8 major and a u8 minor version, a
//! u32 field count, then per field a u16 name length, the name, a u16 dimension count, a
//! u8 dtype, a u64 byte offset (from the start of the file) and one u64 per dimension.
//! All little-endian; each field's data is contiguous, last dimension fastest.
//!
//! Everything is checked before it is used: a header that ends early, a shape whose
//! element count or byte size overflows, data past the end of the file, a name given
//! twice. Errors name the file and the field.

use crate::error::RglError;
use std::collections::HashMap;
use std::path::Path;

/// The 12 magic bytes.
pub const MAGIC: &[u8; 12] = b"tensor_file\0";

/// Element types of the container (Mitsuba's `Struct::Type` numbering).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dtype {
    /// u8 (code 1).
    U8,
    /// i8 (code 2).
    I8,
    /// u16 (code 3).
    U16,
    /// i16 (code 4).
    I16,
    /// u32 (code 5).
    U32,
    /// i32 (code 6).
    I32,
    /// u64 (code 7).
    U64,
    /// i64 (code 8).
    I64,
    /// f16 (code 9).
    F16,
    /// f32 (code 10).
    F32,
    /// f64 (code 11).
    F64,
}

impl Dtype {
    /// The type of a dtype code, if it is one.
    pub fn from_code(code: u8) -> Option<Self> {
        use Dtype::*;
        Some(match code {
            1 => U8,
            2 => I8,
            3 => U16,
            4 => I16,
            5 => U32,
            6 => I32,
            7 => U64,
            8 => I64,
            9 => F16,
            10 => F32,
            11 => F64,
            _ => return None,
        })
    }

    /// Bytes per element.
    pub fn size(self) -> u64 {
        use Dtype::*;
        match self {
            U8 | I8 => 1,
            U16 | I16 | F16 => 2,
            U32 | I32 | F32 => 4,
            U64 | I64 | F64 => 8,
        }
    }

    /// Name in messages.
    pub fn name(self) -> &'static str {
        use Dtype::*;
        match self {
            U8 => "uint8",
            I8 => "int8",
            U16 => "uint16",
            I16 => "int16",
            U32 => "uint32",
            I32 => "int32",
            U64 => "uint64",
            I64 => "int64",
            F16 => "float16",
            F32 => "float32",
            F64 => "float64",
        }
    }
}

/// One field of the container: its type, shape and where its bytes are.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Field {
    /// Element type.
    pub dtype: Dtype,
    /// Shape, last dimension fastest.
    pub shape: Vec<u64>,
    /// Byte offset of the data from the start of the file.
    pub offset: u64,
    /// Number of elements (the product of `shape`, checked).
    pub count: u64,
}

/// A parsed container: its version, fields in file order and the file's bytes.
#[derive(Clone, Debug)]
pub struct TensorFile {
    /// (major, minor) version of the container.
    pub version: (u8, u8),
    /// Field names in file order.
    pub order: Vec<String>,
    fields: HashMap<String, Field>,
    bytes: Vec<u8>,
}

/// A cursor over the header that refuses to read past the end.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
    path: &'a Path,
}

impl Cursor<'_> {
    fn take(&mut self, n: usize, what: &dyn Fn() -> String) -> Result<&[u8], RglError> {
        match self.pos.checked_add(n) {
            Some(end) if end <= self.bytes.len() => {
                let s = &self.bytes[self.pos..end];
                self.pos = end;
                Ok(s)
            }
            _ => Err(RglError::Truncated {
                path: self.path.to_path_buf(),
                what: what(),
                needed: self.pos as u64 + n as u64,
                len: self.bytes.len() as u64,
            }),
        }
    }

    fn u8(&mut self, what: &dyn Fn() -> String) -> Result<u8, RglError> {
        Ok(self.take(1, what)?[0])
    }

    fn u16(&mut self, what: &dyn Fn() -> String) -> Result<u16, RglError> {
        let b = self.take(2, what)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    fn u32(&mut self, what: &dyn Fn() -> String) -> Result<u32, RglError> {
        let b = self.take(4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn u64(&mut self, what: &dyn Fn() -> String) -> Result<u64, RglError> {
        let b = self.take(8, what)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
}

impl TensorFile {
    /// Parses the container from the bytes of a file (`path` names it in errors).
    pub fn parse(bytes: Vec<u8>, path: &Path) -> Result<Self, RglError> {
        let mut c = Cursor {
            bytes: &bytes,
            pos: 0,
            path,
        };
        // A file that does not start like the magic is not a tensor file; one that stops
        // inside the magic is a truncated one.
        let head = &bytes[..bytes.len().min(MAGIC.len())];
        if head.is_empty() || !MAGIC.starts_with(head) {
            return Err(RglError::Magic {
                path: path.to_path_buf(),
            });
        }
        c.take(MAGIC.len(), &|| "the 12-byte magic `tensor_file\\0`".into())?;
        let major = c.u8(&|| "the major version".into())?;
        let minor = c.u8(&|| "the minor version".into())?;
        if major != 1 {
            return Err(RglError::Version {
                path: path.to_path_buf(),
                major,
                minor,
            });
        }
        let n = c.u32(&|| "the field count".into())?;
        // The whole header first (a file cut inside it is "truncated", whatever its
        // fields say), then each field's type and extent. Each field takes at least 13
        // header bytes, so a count the file cannot hold fails on the first missing byte,
        // never on a huge allocation.
        let mut raw_fields = Vec::new();
        for k in 0..n {
            let len = c.u16(&|| format!("the name length of field {}", k + 1))?;
            let raw = c.take(len as usize, &|| format!("the name of field {}", k + 1))?;
            // Bytes outside printable ASCII escaped (`\xff`): the names the format uses are
            // ASCII, and a corrupt header's are shown as the bytes they are.
            let name = raw.escape_ascii().to_string();
            let what = |s: &str| {
                let name = name.clone();
                let s = s.to_string();
                move || format!("{s} of field `{}`", crate::error::field_name(&name))
            };
            let ndim = c.u16(&what("the dimension count"))?;
            let code = c.u8(&what("the dtype"))?;
            let offset = c.u64(&what("the data offset"))?;
            let mut shape = Vec::with_capacity(ndim.min(64) as usize);
            for d in 0..ndim {
                shape.push(c.u64(&what(&format!("dimension {}", d + 1)))?);
            }
            raw_fields.push((name, code, offset, shape));
        }
        let mut order = Vec::new();
        let mut fields = HashMap::new();
        for (name, code, offset, shape) in raw_fields {
            let dtype = Dtype::from_code(code).ok_or_else(|| RglError::UnknownDtype {
                path: path.to_path_buf(),
                field: name.clone(),
                code,
            })?;
            let overflow = || RglError::Overflow {
                path: path.to_path_buf(),
                field: name.clone(),
                shape: shape.clone(),
            };
            let count = shape
                .iter()
                .try_fold(1u64, |a, &d| a.checked_mul(d))
                .ok_or_else(overflow)?;
            let size = count.checked_mul(dtype.size()).ok_or_else(overflow)?;
            let end = offset.checked_add(size).ok_or_else(overflow)?;
            if end > bytes.len() as u64 {
                return Err(RglError::PastEnd {
                    path: path.to_path_buf(),
                    field: name.clone(),
                    offset,
                    size,
                    len: bytes.len() as u64,
                });
            }
            if fields.contains_key(&name) {
                return Err(RglError::DuplicateField {
                    path: path.to_path_buf(),
                    field: name,
                });
            }
            order.push(name.clone());
            fields.insert(
                name,
                Field {
                    dtype,
                    shape,
                    offset,
                    count,
                },
            );
        }
        Ok(Self {
            version: (major, minor),
            order,
            fields,
            bytes,
        })
    }

    /// The field `name`, if present.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.get(name)
    }

    /// The raw bytes of a field (in bounds: checked by [`TensorFile::parse`]).
    pub fn data(&self, f: &Field) -> &[u8] {
        let start = f.offset as usize;
        &self.bytes[start..start + (f.count * f.dtype.size()) as usize]
    }

    /// A float32 field's values.
    pub fn f32s(&self, f: &Field) -> Vec<f32> {
        self.data(f)
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect()
    }
}
