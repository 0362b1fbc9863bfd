//! Distance matrices on disk: NumPy `.npy` (float64, C order) and CSV.

use super::atomic::write_atomic;
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
