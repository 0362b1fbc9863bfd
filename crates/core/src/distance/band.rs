//! Banded computation of a distance matrix: the matrix is cut into square super-blocks of
//! `band_rows` materials, and each super-block pair `(a, b)`, `a <= b`, is one back-end
//! call over the lobes of block `a` followed by those of block `b` (only `a`'s for the
//! diagonal). Both back-ends sum every pair in one canonical order that depends only on
//! the two lobes and the cells ([`crate::backend::cpu`]), never on the other rows of the
//! call, so the band size and the tiling change no value: a tile (`--tile I/N`, any
//! contiguous range of material rows, for any `N` up to the number of materials) holds
//! exactly the bytes the whole matrix holds, on every deterministic back-end. Memory stays
//! bounded by the call size (`2 x band_rows` lobes) plus the output.

use super::{cell_set, lobes, DistanceMatrix, Metric, ValidDistanceParams};
use crate::backend::{Backend, PairOp, Progress, BLOCK};
use crate::collection::{Collection, MaterialData};
use crate::error::DistanceError;
use std::ops::Range;

/// Default materials per super-block (`--band-rows`): large enough that a GPU call is
/// big, small enough that a call's scratch (`(2 x 1024)^2` f64 and the block sums) stays
/// near 100 MB. A collection of at most this many materials is one back-end call.
pub const DEFAULT_BAND_ROWS: usize = 1024;

/// Checks a super-block size: a positive multiple of the back-end block side (4).
pub fn check_band_rows(band_rows: usize) -> Result<(), DistanceError> {
    if band_rows == 0 || !band_rows.is_multiple_of(BLOCK) {
        return Err(DistanceError::UnknownOption {
            what: "band rows",
            found: band_rows.to_string(),
            expected: "a positive multiple of 4",
        });
    }
    Ok(())
}

/// Number of super-blocks of `n` materials.
pub fn super_blocks(n: usize, band_rows: usize) -> usize {
    n.div_ceil(band_rows.max(1))
}

/// Pairs `(i, j)`, `i < j < n`, in the rows `0..r`: row `i` computes `n - 1 - i`.
fn pairs_before(n: usize, r: usize) -> u128 {
    let (n, r) = (n as u128, r as u128);
    r * (n - 1) - r * r.saturating_sub(1) / 2
}

/// The material rows of tile `index` (1-based) of `count`, for any `count` up to the
/// number of materials `n`: contiguous rows, balanced by the number of pairs each row
/// computes (row `i` computes `n - 1 - i`), every tile at least one row. The rows need
/// not line up with the super-blocks: a pair's value does not depend on the other rows
/// of its back-end call (the canonical summation order of [`crate::backend::cpu`]), so
/// any tiling holds exactly the bytes of the whole matrix.
pub fn tile_rows(n: usize, index: usize, count: usize) -> Result<Range<usize>, DistanceError> {
    if count == 0 || index == 0 || index > count {
        return Err(DistanceError::UnknownOption {
            what: "tile",
            found: format!("{index}/{count}"),
            expected: "I/N with 1 <= I <= N",
        });
    }
    if count > n {
        return Err(DistanceError::TooManyTiles {
            count,
            materials: n,
        });
    }
    let total = pairs_before(n, n);
    // Bound k: the first row r whose preceding pairs reach k/count of the total, kept
    // strictly increasing and leaving one row for every later tile.
    let bound = |k: usize| -> usize {
        if k == 0 {
            return 0;
        }
        if k == count {
            return n;
        }
        let target = total * k as u128 / count as u128;
        // pairs_before is increasing in r: binary search the first r with
        // pairs_before(r) >= target.
        let (mut lo, mut hi) = (0usize, n);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if pairs_before(n, mid) >= target {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        lo.max(k).min(n - (count - k))
    };
    let mut bounds: Vec<usize> = (0..=count).map(bound).collect();
    for k in 1..count {
        if bounds[k] <= bounds[k - 1] {
            bounds[k] = bounds[k - 1] + 1;
        }
    }
    Ok(bounds[index - 1]..bounds[index])
}

/// Computes every pair `(i, j)`, `i < j`, with `i` in the material rows `rows` and `j`
/// anywhere after `i`, and hands each value to `sink(i, j, v)`. The rows are cut into
/// chunks of `band_rows` from `rows.start`; each chunk is one diagonal call, then one
/// call per `band_rows` columns after it (a chunk not a multiple of 4 long is padded with
/// copies of its first lobe, whose values are dropped). For `rows = 0..N` these are
/// exactly the super-block calls of the whole matrix.
pub(crate) fn distance_rows(
    backend: &dyn Backend,
    coll: &Collection,
    p: &ValidDistanceParams,
    band_rows: usize,
    rows: Range<usize>,
    progress: Progress<'_>,
    sink: &mut dyn FnMut(usize, usize, f64),
) -> Result<(), DistanceError> {
    check_band_rows(band_rows)?;
    let n = coll.len();
    let rows = rows.start.min(n)..rows.end.min(n);
    match p.metric() {
        Metric::Euclidean => {
            let params: Vec<(f64, f64)> = coll
                .materials()
                .iter()
                .map(|m| match &m.data {
                    MaterialData::Analytic(a) => Ok((a.f0, a.n)),
                    MaterialData::Measured(_) | MaterialData::Rgl(_) | MaterialData::Neural(_) => {
                        Err(DistanceError::NoParameters(m.name.clone()))
                    }
                })
                .collect::<Result<_, _>>()?;
            for i in rows {
                for j in i + 1..n {
                    sink(
                        i,
                        j,
                        (params[i].0 - params[j].0).hypot(params[i].1 - params[j].1),
                    );
                }
            }
            progress(1, 1);
        }
        Metric::BrdfIt => {
            let cells = cell_set(coll, p);
            if cells.is_empty() {
                return Err(DistanceError::Backend(crate::error::BackendError::Invalid(
                    crate::merl::no_cells_reason(p.mask(), p.stride(), "the collection"),
                )));
            }
            let all = lobes(coll, p.lobe());
            let chunks: Vec<Range<usize>> = rows
                .clone()
                .step_by(band_rows)
                .map(|a| a..(a + band_rows).min(rows.end))
                .collect();
            let col_chunks = |ra: &Range<usize>| {
                (ra.end..n)
                    .step_by(band_rows)
                    .map(move |b| b..(b + band_rows).min(n))
            };
            let calls: u64 = chunks
                .iter()
                .map(|ra| 1 + col_chunks(ra).count() as u64)
                .sum();
            let per_call = cells.len() as u64;
            let total = calls * per_call;
            let mut done_calls = 0u64;
            for ra in &chunks {
                let sub = &all[ra.clone()];
                let len = sub.len();
                let base = done_calls * per_call;
                let pr = |d: u64, _t: u64| progress(base + d, total);
                let full = backend.reduce_pairs(
                    sub,
                    &cells,
                    &crate::backend::all_blocks(len),
                    PairOp::L1,
                    &pr,
                )?;
                for (r, i) in ra.clone().enumerate() {
                    for (q, j) in ra.clone().enumerate().skip(r + 1) {
                        sink(i, j, full[r * len + q]);
                    }
                }
                done_calls += 1;
                progress(done_calls * per_call, total);
                // The chunk padded to whole back-end blocks (only a tile's last chunk can
                // be short), so that the cross blocks do not mix rows and columns.
                let la = ra.len().div_ceil(BLOCK) * BLOCK;
                let mut padded = sub.to_vec();
                padded.resize(la, sub[0].clone());
                for rb in col_chunks(ra) {
                    let mut sub = padded.clone();
                    sub.extend_from_slice(&all[rb.clone()]);
                    let len = sub.len();
                    let (ba, bt) = ((la / BLOCK) as u32, len.div_ceil(BLOCK) as u32);
                    let cross: Vec<[u32; 2]> = (0..ba)
                        .flat_map(|x| (ba..bt).map(move |y| [x, y]))
                        .collect();
                    let base = done_calls * per_call;
                    let pr = |d: u64, _t: u64| progress(base + d, total);
                    let full = backend.reduce_pairs(&sub, &cells, &cross, PairOp::L1, &pr)?;
                    for (r, i) in ra.clone().enumerate() {
                        for (q, j) in rb.clone().enumerate() {
                            sink(i, j, full[r * len + la + q]);
                        }
                    }
                    done_calls += 1;
                    progress(done_calls * per_call, total);
                }
            }
        }
    }
    Ok(())
}

/// The whole matrix, computed band by band into one `N x N` array (no condensed copy).
pub fn distance_matrix_banded(
    backend: &dyn Backend,
    coll: &Collection,
    p: &ValidDistanceParams,
    band_rows: usize,
    progress: Progress<'_>,
) -> Result<DistanceMatrix, DistanceError> {
    let n = coll.len();
    if n < 2 {
        return Err(DistanceError::TooFew(n));
    }
    let mut data = vec![0.0; n * n];
    distance_rows(
        backend,
        coll,
        p,
        band_rows,
        0..n,
        progress,
        &mut |i, j, v| {
            data[i * n + j] = v;
            data[j * n + i] = v;
        },
    )?;
    DistanceMatrix::from_full(coll.names(), data)
}

/// One tile of a matrix: rows `rows` of the `N x N` matrix from column `rows.start` on,
/// row-major `rows.len() x (N - rows.start)` (the columns left of the band belong to
/// earlier tiles, by symmetry; the band's own square is filled on both sides of the
/// diagonal).
#[derive(Clone, Debug, PartialEq)]
pub struct Tile {
    /// 1-based tile index.
    pub index: usize,
    /// Number of tiles.
    pub count: usize,
    /// Material rows held.
    pub rows: Range<usize>,
    /// Number of materials `N`.
    pub n: usize,
    /// `rows.len() x (N - rows.start)`, row-major: entry `(i, j)` at
    /// `(i - rows.start) * (N - rows.start) + (j - rows.start)`.
    pub data: Vec<f64>,
}

/// Computes tile `index` (1-based) of `count`.
pub fn distance_tile(
    backend: &dyn Backend,
    coll: &Collection,
    p: &ValidDistanceParams,
    band_rows: usize,
    index: usize,
    count: usize,
    progress: Progress<'_>,
) -> Result<Tile, DistanceError> {
    let n = coll.len();
    if n < 2 {
        return Err(DistanceError::TooFew(n));
    }
    check_band_rows(band_rows)?;
    let rows = tile_rows(n, index, count)?;
    let r0 = rows.start;
    let w = n - r0;
    let mut data = vec![0.0; rows.len() * w];
    distance_rows(
        backend,
        coll,
        p,
        band_rows,
        rows.clone(),
        progress,
        &mut |i, j, v| {
            data[(i - r0) * w + (j - r0)] = v;
            if j < rows.end {
                data[(j - r0) * w + (i - r0)] = v;
            }
        },
    )?;
    Ok(Tile {
        index,
        count,
        rows,
        n,
        data,
    })
}
