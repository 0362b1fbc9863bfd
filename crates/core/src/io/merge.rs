//! Merging tiles (`distance --tile I/N`) into the whole matrix: [`plan_merge`] checks
//! that the sidecars describe one tiling of one matrix, [`write_merged`] checks each
//! tile's bytes and streams the matrix into an [`OutputSet`] (so an error or a signal
//! leaves no temporary file), and [`merge_tiles`] does both and commits.

use super::npy::{npy_header, read_npy_header, scan_npy_2d, NpyDigest, NpyRows};
use super::sidecar::{
    collection_difference, read_sidecar, sidecar_path, stage_sidecar, MatrixSidecar,
};
use super::MatrixFileError;
use crate::atomic::OutputSet;
use crate::distance::{entry_fault, BadEntry};
use crate::hash::HashingWriter;
use std::io::Write;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// A tile file and its (checked) sidecar.
#[derive(Clone, Debug)]
pub struct TileFile {
    /// The `.npy`.
    pub path: PathBuf,
    /// Its sidecar.
    pub sidecar: MatrixSidecar,
}

impl TileFile {
    /// Reads the sidecar of the tile at `path` ([`read_sidecar`]).
    pub fn open(path: &Path) -> Result<Self, MatrixFileError> {
        Ok(Self {
            path: path.to_path_buf(),
            sidecar: read_sidecar(path)?,
        })
    }
}

/// One tile in the merge, in row order.
#[derive(Clone, Debug)]
pub struct PlannedTile {
    /// The `.npy`.
    pub path: PathBuf,
    /// Rows of the whole matrix it holds.
    pub rows: Range<usize>,
    /// Size and checksum its sidecar records.
    pub npy_bytes: u64,
    /// XXH3-64 its sidecar records (16 hex digits).
    pub npy_xxh3: String,
}

/// The tiles of one matrix, checked against each other and ordered by rows.
#[derive(Clone, Debug)]
pub struct MergePlan {
    /// The merged matrix's sidecar content (its `.npy` size and checksum not yet known).
    pub template: MatrixSidecar,
    /// The tiles, by rows.
    pub tiles: Vec<PlannedTile>,
}

impl MergePlan {
    /// Number of materials.
    pub fn n(&self) -> usize {
        self.template.n
    }
}

/// Checks that `tiles` are the tiles `1..N` of one tiling of one matrix: same collection
/// (fingerprint and names), same settings, same count, each index once, rows covering
/// the matrix in order, names unique. Errors name the files and say what differs.
///
/// About 100 lines: one check per way tiles can disagree, each with its own message.
pub fn plan_merge(tiles: &[TileFile]) -> Result<MergePlan, MatrixFileError> {
    let merr = MatrixFileError::Merge;
    let first = tiles.first().ok_or_else(|| merr("no tile given".into()))?;
    let info = |t: &TileFile| {
        t.sidecar.tile.clone().ok_or_else(|| {
            merr(format!(
                "{} is a whole matrix, not a tile (written without --tile)",
                t.path.display()
            ))
        })
    };
    let i0 = info(first)?;
    let count = i0.count;
    let mut by_index: Vec<Option<usize>> = vec![None; count];
    for (k, t) in tiles.iter().enumerate() {
        let ti = info(t)?;
        let (a, b) = (first.path.display(), t.path.display());
        if let Some(what) = collection_difference(&t.sidecar, &first.sidecar) {
            return Err(merr(format!(
                "{b} comes from another collection than {a} ({what})"
            )));
        }
        if t.sidecar.settings != first.sidecar.settings {
            return Err(merr(format!(
                "{b} was computed with other settings than {a} ({})",
                t.sidecar.settings.differences(&first.sidecar.settings)
            )));
        }
        if ti.count != count {
            return Err(merr(format!(
                "{b} is tile {}/{} but {a} is tile {}/{count}: tiles of different tilings",
                ti.index, ti.count, i0.index
            )));
        }
        if ti.index == 0 || ti.index > count {
            return Err(merr(format!(
                "{b}: tile index {} out of 1..{count}",
                ti.index
            )));
        }
        if let Some(prev) = by_index[ti.index - 1] {
            return Err(merr(format!(
                "tile {}/{count} is given twice: {} and {b}",
                ti.index,
                tiles[prev].path.display()
            )));
        }
        by_index[ti.index - 1] = Some(k);
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
                .map(|t| t.path.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let n = first.sidecar.n;
    let mut planned = Vec::with_capacity(count);
    let mut next_row = 0usize;
    for k in by_index.into_iter().flatten() {
        let t = &tiles[k];
        let ti = info(t)?;
        if ti.row_start != next_row || ti.row_end <= ti.row_start || ti.row_end > n {
            return Err(merr(format!(
                "{} holds rows {}..{}, expected rows starting at {next_row}",
                t.path.display(),
                ti.row_start,
                ti.row_end
            )));
        }
        next_row = ti.row_end;
        planned.push(PlannedTile {
            path: t.path.clone(),
            rows: ti.row_start..ti.row_end,
            npy_bytes: t.sidecar.npy_bytes,
            npy_xxh3: t.sidecar.npy_xxh3.clone(),
        });
    }
    if next_row != n || first.sidecar.names.len() != n {
        return Err(merr(format!(
            "the tiles cover rows 0..{next_row} of {n} ({} names)",
            first.sidecar.names.len()
        )));
    }
    super::saved::check_matrix_names(&first.sidecar.names)
        .map_err(|m| merr(format!("{}: {m}", sidecar_path(&planned[0].path).display())))?;
    let mut template = first.sidecar.clone();
    template.tile = None;
    Ok(MergePlan {
        template,
        tiles: planned,
    })
}

/// Size and modification time of a file, to notice a tile rewritten during the merge.
fn stamp(path: &Path) -> Result<(u64, Option<std::time::SystemTime>), MatrixFileError> {
    let meta = std::fs::metadata(path).map_err(|source| MatrixFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if !meta.is_file() {
        return Err(MatrixFileError::Format {
            path: path.to_path_buf(),
            message: format!(
                "is {}, not a regular .npy file",
                crate::merl::file_kind(&meta)
            ),
        });
    }
    Ok((meta.len(), meta.modified().ok()))
}

/// Reads a whole tile once: its shape, its size and checksum against its sidecar, then
/// every entry (finite, non-negative, zero diagonal).
fn verify_tile(
    t: &PlannedTile,
    n: usize,
    names: &[String],
) -> Result<(u64, Option<std::time::SystemTime>), MatrixFileError> {
    let before = stamp(&t.path)?;
    let mismatch = |what: String| MatrixFileError::Mismatch {
        npy: t.path.clone(),
        sidecar: sidecar_path(&t.path),
        what,
    };
    let (r0, r1) = (t.rows.start, t.rows.end);
    let w = n - r0;
    let h = read_npy_header(&t.path)?;
    if h.rows != r1 - r0 || h.cols != w {
        return Err(mismatch(format!(
            "shape ({}, {}), expected ({}, {w})",
            h.rows,
            h.cols,
            r1 - r0
        )));
    }
    // The checksum is checked before the entries: a damaged tile is reported as such.
    let mut bad: Option<BadEntry> = None;
    let mut at = 0usize;
    let (_, digest) = scan_npy_2d(&t.path, |vals| {
        if bad.is_none() {
            for (k, &v) in vals.iter().enumerate() {
                let (i, j) = (r0 + (at + k) / w, r0 + (at + k) % w);
                if let Some(fault) = entry_fault(i, j, v) {
                    bad = Some(BadEntry {
                        row: i,
                        col: j,
                        value: v,
                        fault,
                    });
                    break;
                }
            }
        }
        at += vals.len();
        Ok(())
    })?;
    if digest.bytes != t.npy_bytes || crate::hash::hex(digest.xxh3) != t.npy_xxh3 {
        return Err(mismatch("size or checksum differs".into()));
    }
    if let Some(e) = bad {
        return Err(MatrixFileError::entry(&t.path, names, e, 0.0));
    }
    Ok(before)
}

/// Output rows assembled at once: at most this many bytes of the merged matrix are held
/// in memory (at least one row).
pub const MERGE_CHUNK_BYTES: usize = 256 << 20;

/// Streams rows `rows` (inside tile `t`) of the merged matrix into `w`: columns before
/// the tile's first row from the earlier tiles (transposed), the rest from its own rows.
fn write_rows(
    w: &mut dyn Write,
    plan: &MergePlan,
    files: &mut [NpyRows],
    t: usize,
    rows: Range<usize>,
    buf: &mut Vec<f64>,
) -> Result<(), MatrixFileError> {
    let n = plan.n();
    let (a, b) = (rows.start, rows.end);
    let r0 = plan.tiles[t].rows.start;
    buf.clear();
    buf.resize((b - a) * n, 0.0);
    let mut seg = vec![0.0; b - a];
    for (tile, file) in plan.tiles[..t].iter().zip(files.iter_mut()) {
        let s0 = tile.rows.start;
        for (r, j) in tile.rows.clone().enumerate() {
            file.read_at(r, a - s0, &mut seg)?;
            for (i, &v) in seg.iter().enumerate() {
                buf[i * n + j] = v;
            }
        }
    }
    for i in a..b {
        files[t].read_at(i - r0, 0, &mut buf[(i - a) * n + r0..(i - a + 1) * n])?;
    }
    let mut bytes = Vec::with_capacity(8 * n);
    for row in buf.chunks(n) {
        bytes.clear();
        for v in row {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        w.write_all(&bytes).map_err(|source| MatrixFileError::Io {
            path: plan.tiles[t].path.clone(),
            source,
        })?;
    }
    Ok(())
}

/// Checks every tile of `plan` (size and checksum against its sidecar, shape, entries)
/// and stages the merged `.npy` at `out` and its sidecar in `set`; returns the sidecar.
/// Memory holds at most [`MERGE_CHUNK_BYTES`] of the matrix (and one row). A tile that
/// changes while it is read is refused.
pub fn write_merged(
    plan: &MergePlan,
    set: &mut OutputSet,
    out: &Path,
) -> Result<MatrixSidecar, MatrixFileError> {
    let chunk = (MERGE_CHUNK_BYTES / 8 / plan.n().max(1)).max(1);
    write_merged_in_chunks(plan, set, out, chunk)
}

/// [`write_merged`] assembling `chunk` rows at a time.
fn write_merged_in_chunks(
    plan: &MergePlan,
    set: &mut OutputSet,
    out: &Path,
    chunk: usize,
) -> Result<MatrixSidecar, MatrixFileError> {
    let n = plan.n();
    let names = &plan.template.names;
    let stamps: Vec<_> = plan
        .tiles
        .iter()
        .map(|t| verify_tile(t, n, names))
        .collect::<Result<_, _>>()?;
    let mut files: Vec<NpyRows> = plan
        .tiles
        .iter()
        .map(|t| NpyRows::open(&t.path))
        .collect::<Result<_, _>>()?;
    let mut failure: Option<MatrixFileError> = None;
    let mut digest = None;
    let staged = set.stage(out, |w| {
        let mut hw = HashingWriter::new(w);
        hw.write_all(&npy_header(n, n))?;
        let mut buf = Vec::new();
        for (t, tile) in plan.tiles.iter().enumerate() {
            let mut a = tile.rows.start;
            while a < tile.rows.end {
                let b = (a + chunk).min(tile.rows.end);
                if let Err(e) = write_rows(&mut hw, plan, &mut files, t, a..b, &mut buf) {
                    failure = Some(e);
                    return Err(std::io::Error::other("merge failed"));
                }
                a = b;
            }
        }
        let (bytes, xxh3) = hw.digest();
        digest = Some(NpyDigest { bytes, xxh3 });
        Ok(())
    });
    if let Some(e) = failure {
        return Err(e);
    }
    staged?;
    for (t, before) in plan.tiles.iter().zip(stamps) {
        if stamp(&t.path)? != before {
            return Err(MatrixFileError::Format {
                path: t.path.clone(),
                message: "the tile changed while it was merged; merge again".into(),
            });
        }
    }
    let digest = digest.expect("stage ran the writer");
    let mut side = plan.template.clone();
    side.npy_bytes = digest.bytes;
    side.npy_xxh3 = crate::hash::hex(digest.xxh3);
    side.checksum = side.content_checksum();
    stage_sidecar(set, out, &side)?;
    Ok(side)
}

/// Assembles tiles into the whole matrix and writes it with its sidecar
/// ([`plan_merge`], [`write_merged`]); both files are renamed into place together, and
/// nothing is left behind on an error.
pub fn merge_tiles(tiles: &[PathBuf], out: &Path) -> Result<MatrixSidecar, MatrixFileError> {
    let files: Vec<TileFile> = tiles
        .iter()
        .map(|t| TileFile::open(t))
        .collect::<Result<_, _>>()?;
    let plan = plan_merge(&files)?;
    let mut set = OutputSet::new();
    let side = write_merged(&plan, &mut set, out)?;
    set.commit()?;
    Ok(side)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::cpu::CpuBackend;
    use crate::collection::Collection;
    use crate::distance::{distance_matrix_banded, distance_tile, DistanceParams};
    use crate::io::saved::{write_npy_with_sidecar, write_tile};
    use crate::io::sidecar::MatrixSettings;

    #[test]
    fn merging_in_chunks_of_any_size_gives_the_whole_matrix_byte_for_byte() {
        let coll = Collection::embedded_default();
        let p = DistanceParams::default()
            .stride(9)
            .check(&coll)
            .expect("params");
        let cpu = CpuBackend::new();
        let band = 4;
        let settings = MatrixSettings::of(&p, band);
        let fp = coll.fingerprint();
        let dir = tempfile::tempdir().expect("dir");
        let whole = dir.path().join("whole.npy");
        let d = distance_matrix_banded(&cpu, &coll, &p, band, &|_, _| {}).expect("d");
        write_npy_with_sidecar(&whole, &d, &settings, &fp).expect("whole");
        let tiles: Vec<TileFile> = (1..=3)
            .map(|i| {
                let t = distance_tile(&cpu, &coll, &p, band, i, 3, &|_, _| {}).expect("tile");
                let path = dir.path().join(format!("t{i}.npy"));
                write_tile(&path, &t, &coll.names(), &settings, &fp).expect("write");
                TileFile::open(&path).expect("open")
            })
            .collect();
        let plan = plan_merge(&tiles).expect("plan");
        for chunk in [1, 2, 3, 7, 1000] {
            let out = dir.path().join(format!("m{chunk}.npy"));
            let mut set = OutputSet::new();
            write_merged_in_chunks(&plan, &mut set, &out, chunk).expect("merge");
            set.commit().expect("commit");
            assert_eq!(
                std::fs::read(&out).expect("m"),
                std::fs::read(&whole).expect("w"),
                "chunk {chunk}"
            );
            assert_eq!(
                std::fs::read(sidecar_path(&out)).expect("m"),
                std::fs::read(sidecar_path(&whole)).expect("w"),
                "chunk {chunk}"
            );
        }
    }
}
