//! MERL `.binary` files (SPEC 2): three little-endian int32 dimensions (90, 90, 180), then
//! 3 x 1,458,000 little-endian float64, channel-planar (R, then G, then B). Stored value x
//! channel scale = reflectance; negative values mark missing cells.

use super::grid::{self, N_CELLS, N_PD, N_TD, N_TH};
use crate::error::{MerlError, OutputError};
use std::path::Path;

/// Channel scales: stored value x scale = reflectance (R, G, B).
pub const SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];
/// Size in bytes of a MERL `.binary` file.
pub const FILE_BYTES: u64 = 12 + 3 * 8 * N_CELLS as u64;

/// A measured BRDF on the MERL grid, in f32 reflectance units, channel-planar
/// (`rgb[c * N_CELLS + cell]`). A negative value marks an invalid cell (all three
/// channels are negative together).
#[derive(Clone, Debug)]
pub struct MerlTable {
    /// Reflectance, channel-planar, negative = invalid.
    pub rgb: Vec<f32>,
}

impl MerlTable {
    /// Whether `cell` holds a measurement (no channel negative).
    #[inline]
    pub fn is_valid(&self, cell: usize) -> bool {
        self.rgb[cell] >= 0.0
            && self.rgb[N_CELLS + cell] >= 0.0
            && self.rgb[2 * N_CELLS + cell] >= 0.0
    }

    /// Reflectance of channel `c` at `cell` (negative when invalid).
    #[inline]
    pub fn value(&self, c: usize, cell: usize) -> f32 {
        self.rgb[c * N_CELLS + cell]
    }

    /// Number of valid cells.
    pub fn valid_count(&self) -> usize {
        (0..N_CELLS).filter(|&i| self.is_valid(i)).count()
    }
}

/// Reads and validates a MERL `.binary` file. Cells that are negative in any channel, or
/// below the horizon on the grid, become invalid (all channels -1). A file whose size or
/// modification time changes while it is read (rewritten in place by another program) is
/// refused: what was read may mix the old and the new table.
pub fn read_binary(path: &Path) -> Result<MerlTable, MerlError> {
    let io = |source| MerlError::Io {
        path: path.to_path_buf(),
        source,
    };
    // From metadata first: a FIFO or a device is never opened (reading one could block
    // forever), and a file of the wrong size is never read into memory.
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(MerlError::NotRegular {
            path: path.to_path_buf(),
            kind: file_kind(&meta),
        });
    }
    if meta.len() != FILE_BYTES {
        // Read the header (if any) for the more telling message about dimensions.
        let mut head = Vec::with_capacity(12);
        std::io::Read::read_to_end(
            &mut std::io::Read::take(std::fs::File::open(path).map_err(io)?, 12),
            &mut head,
        )
        .map_err(io)?;
        parse_header(&head, meta.len(), path)?;
    }
    let mut file = std::fs::File::open(path).map_err(io)?;
    let before = file.metadata().map_err(io)?;
    if !before.is_file() {
        // Replaced by something else between the two looks.
        return Err(MerlError::NotRegular {
            path: path.to_path_buf(),
            kind: file_kind(&before),
        });
    }
    let mut bytes = Vec::with_capacity(FILE_BYTES as usize);
    std::io::Read::read_to_end(
        &mut std::io::Read::take(&mut file, FILE_BYTES + 1),
        &mut bytes,
    )
    .map_err(io)?;
    let after = file.metadata().map_err(io)?;
    if stamp(&before) != stamp(&after) || bytes.len() as u64 != before.len() {
        return Err(MerlError::Changed {
            path: path.to_path_buf(),
        });
    }
    parse_binary(&bytes, path)
}

/// What changes when a file is written: size, modification and status-change times.
fn stamp(m: &std::fs::Metadata) -> (u64, Option<std::time::SystemTime>, (i64, i64)) {
    #[cfg(unix)]
    let ctime = {
        use std::os::unix::fs::MetadataExt;
        (m.ctime(), m.ctime_nsec())
    };
    #[cfg(not(unix))]
    let ctime = (0, 0);
    (m.len(), m.modified().ok(), ctime)
}

/// What a non-regular file is, in words (for messages).
pub fn file_kind(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "not a regular file"
}

/// Checks the dimensions in the first 12 bytes (when present) and the total length.
fn parse_header(head: &[u8], len: u64, path: &Path) -> Result<(), MerlError> {
    if head.len() >= 12 {
        let dims = [0, 1, 2]
            .map(|i| i32::from_le_bytes(head[4 * i..4 * i + 4].try_into().unwrap_or([0; 4])));
        if dims != [N_TH as i32, N_TD as i32, N_PD as i32] {
            return Err(MerlError::Dims {
                path: path.to_path_buf(),
                dims,
            });
        }
    }
    if len != FILE_BYTES {
        return Err(MerlError::Size {
            path: path.to_path_buf(),
            expected: FILE_BYTES,
            found: len,
        });
    }
    Ok(())
}

/// Parses and validates the bytes of a MERL `.binary` file (`path` names it in errors).
pub fn parse_binary(bytes: &[u8], path: &Path) -> Result<MerlTable, MerlError> {
    parse_header(&bytes[..bytes.len().min(12)], bytes.len() as u64, path)?;
    let raw = &bytes[12..];
    let mut rgb = vec![0f32; 3 * N_CELLS];
    for c in 0..3 {
        for cell in 0..N_CELLS {
            let o = 8 * (c * N_CELLS + cell);
            let v = f64::from_le_bytes(raw[o..o + 8].try_into().unwrap_or([0; 8]));
            // Reflectance is kept in f32: a value it cannot hold is refused here, where
            // the file and the cell are known, not found later as an infinite distance.
            if !v.is_finite() || (v >= 0.0 && v * SCALE[c] > f32::MAX as f64) {
                let (i, j, k) = grid::unflat(cell);
                return Err(MerlError::BadValue {
                    path: path.to_path_buf(),
                    index: c * N_CELLS + cell,
                    channel: c,
                    cell: [i, j, k],
                    value: v,
                });
            }
            rgb[c * N_CELLS + cell] = if v < 0.0 { -1.0 } else { (v * SCALE[c]) as f32 };
        }
    }
    let mut valid = 0usize;
    for cell in 0..N_CELLS {
        let geometric = grid::geometric_validity()[cell];
        let ok = geometric && (0..3).all(|c| rgb[c * N_CELLS + cell] >= 0.0);
        if ok {
            valid += 1;
        } else {
            for c in 0..3 {
                rgb[c * N_CELLS + cell] = -1.0;
            }
        }
    }
    if valid == 0 {
        return Err(MerlError::NoValidCell {
            path: path.to_path_buf(),
        });
    }
    Ok(MerlTable { rgb })
}

/// Writes a MERL `.binary` file atomically from channel-planar reflectance values
/// (`rgb[c * N_CELLS + cell]`, length 3 x 1,458,000). Negative or non-finite values are
/// written as -1 (invalid); others as reflectance / scale.
pub fn write_binary(path: &Path, rgb: &[f32]) -> Result<(), OutputError> {
    assert_eq!(
        rgb.len(),
        3 * N_CELLS,
        "write_binary needs 3 x 1,458,000 values"
    );
    crate::atomic::write_atomic(path, |w| write_binary_to(w, rgb))
}

/// Writes the bytes of a MERL `.binary` file to `w` (see [`write_binary`]).
pub fn write_binary_to(w: &mut dyn std::io::Write, rgb: &[f32]) -> std::io::Result<()> {
    assert_eq!(
        rgb.len(),
        3 * N_CELLS,
        "write_binary_to needs 3 x 1,458,000 values"
    );
    for d in [N_TH as i32, N_TD as i32, N_PD as i32] {
        w.write_all(&d.to_le_bytes())?;
    }
    let mut buf = Vec::with_capacity(8 * N_CELLS);
    for c in 0..3 {
        buf.clear();
        for &v in &rgb[c * N_CELLS..(c + 1) * N_CELLS] {
            let s = if v.is_finite() && v >= 0.0 {
                v as f64 / SCALE[c]
            } else {
                -1.0
            };
            buf.extend_from_slice(&s.to_le_bytes());
        }
        w.write_all(&buf)?;
    }
    Ok(())
}
