//! Banded computation of a distance matrix: the matrix is cut into square super-blocks of
//! `band_rows` materials, and each super-block pair `(a, b)`, `a <= b`, is one back-end
//! call over the lobes of block `a` followed by those of block `b` (only `a`'s for the
//! diagonal). A pair's value therefore depends only on the two super-blocks it sits in,
//! never on how many super-block rows are computed together: a tile (`--tile I/N`, a
//! contiguous range of super-block rows) holds exactly the bytes the whole matrix holds,
//! on every deterministic back-end. Memory stays bounded by the call size (`2 x band_rows`
//! lobes) plus the output.

use super::{cell_set, lobes, DistanceMatrix, Metric, ValidDistanceParams};
use crate::backend::{blocks, Backend, PairOp, Progress, BLOCK};
use crate::collection::{Collection, MaterialData};
use crate::error::DistanceError;
use std::ops::Range;

/// Default materials per super-block (`--band-rows`): large enough that a GPU call is
/// big, small enough that a call's scratch (`(2 x 1024)^2` f64 and the block sums) stays
/// near 100 MB. A collection of at most this many materials is one back-end call.
pub const DEFAULT_BAND_ROWS: usize = 1024;

/// Checks a super-block size: a positive multiple of the back-end block side (4).
pub fn check_band_rows(band_rows: usize) -> Result<(), DistanceError> {
    if band_rows == 0 || band_rows % BLOCK != 0 {
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

/// The super-block range of tile `index` (1-based) of `count`: contiguous super-block
/// rows, balanced by the number of super-block pairs each row computes (row `a` computes
/// `nb - a` pairs), every tile non-empty.
pub fn tile_blocks(
    n: usize,
    band_rows: usize,
    index: usize,
    count: usize,
) -> Result<Range<usize>, DistanceError> {
    check_band_rows(band_rows)?;
    let nb = super_blocks(n, band_rows);
    if count == 0 || index == 0 || index > count {
        return Err(DistanceError::UnknownOption {
            what: "tile",
            found: format!("{index}/{count}"),
            expected: "I/N with 1 <= I <= N",
        });
    }
    if count > nb {
        return Err(DistanceError::TooManyTiles {
            count,
            bands: nb,
            materials: n,
            band_rows,
        });
    }
    // Cumulative pair counts: cum[a] = pairs of rows 0..a.
    let total: usize = (0..nb).map(|a| nb - a).sum();
    let mut bounds = vec![0usize; count + 1];
    bounds[count] = nb;
    let mut cum = 0usize;
    let mut a = 0usize;
    for (k, b) in bounds.iter_mut().enumerate().take(count).skip(1) {
        let target = total * k / count;
        while a < nb && cum + (nb - a) <= target {
            cum += nb - a;
            a += 1;
        }
        // Keep every tile non-empty on both sides.
        *b = a.max(k).min(nb - (count - k));
    }
    for k in 1..count {
        if bounds[k] <= bounds[k - 1] {
            bounds[k] = bounds[k - 1] + 1;
        }
    }
    Ok(bounds[index - 1]..bounds[index])
}

/// Material rows of super-blocks `blocks`.
pub fn block_rows(n: usize, band_rows: usize, blocks: Range<usize>) -> Range<usize> {
    (blocks.start * band_rows).min(n)..(blocks.end * band_rows).min(n)
}

/// Computes every pair `(i, j)`, `i < j`, with `i` in the super-block rows `rows` and
/// `j` anywhere after `i`, and hands each value to `sink(i, j, v)`.
pub fn distance_band(
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
    let nb = super_blocks(n, band_rows);
    let range = |a: usize| a * band_rows..((a + 1) * band_rows).min(n);
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
            for i in block_rows(n, band_rows, rows.clone()) {
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
                    crate::merl::grid::no_cells_reason(p.mask(), p.stride(), "the collection"),
                )));
            }
            let all = lobes(coll, p.lobe());
            let calls: u64 = rows.clone().map(|a| (nb - a) as u64).sum();
            let per_call = cells.len() as u64;
            let total = calls * per_call;
            let mut done_calls = 0u64;
            for a in rows {
                for b in a..nb {
                    let (ra, rb) = (range(a), range(b));
                    let base = done_calls * per_call;
                    let pr = |d: u64, _t: u64| progress(base + d, total);
                    if a == b {
                        let sub = &all[ra.clone()];
                        let len = sub.len();
                        let full = backend.reduce_pairs(
                            sub,
                            &cells,
                            &blocks::all_blocks(len),
                            PairOp::L1,
                            &pr,
                        )?;
                        for (r, i) in ra.clone().enumerate() {
                            for (q, j) in ra.clone().enumerate().skip(r + 1) {
                                sink(i, j, full[r * len + q]);
                            }
                        }
                    } else {
                        let la = ra.len();
                        let mut sub = all[ra.clone()].to_vec();
                        sub.extend_from_slice(&all[rb.clone()]);
                        let len = sub.len();
                        // `la` is a multiple of BLOCK (only the last super-block is short,
                        // and it is never `a` here): cross blocks only.
                        let (ba, bt) = ((la / BLOCK) as u32, len.div_ceil(BLOCK) as u32);
                        let cross: Vec<[u32; 2]> = (0..ba)
                            .flat_map(|x| (ba..bt).map(move |y| [x, y]))
                            .collect();
                        let full = backend.reduce_pairs(&sub, &cells, &cross, PairOp::L1, &pr)?;
                        for (r, i) in ra.clone().enumerate() {
                            for (q, j) in rb.clone().enumerate() {
                                sink(i, j, full[r * len + la + q]);
                            }
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
    let nb = super_blocks(n, band_rows);
    distance_band(
        backend,
        coll,
        p,
        band_rows,
        0..nb,
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
    let blocks = tile_blocks(n, band_rows, index, count)?;
    let rows = block_rows(n, band_rows, blocks.clone());
    let r0 = rows.start;
    let w = n - r0;
    let mut data = vec![0.0; rows.len() * w];
    distance_band(
        backend,
        coll,
        p,
        band_rows,
        blocks,
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
