// Pairwise reductions over grid cells. OP = 0: weighted L1 (rows scaled by the cell
// weights, so w |a - b| = |w a - w b|); OP = 1: weighted dot products for Gram matrices
// (rows scaled by sqrt(w)).
//
// Rows come four to a texel ("row block") of an rgba32float texture `vals` (width TEX_W,
// see texel_coord). An analytic row block is tabulated in registers, cell by cell, from
// its separable form (crates/core/src/separable.rs): texel b * (NIJ + 1) + e holds the four rows'
// beta[e] and texel b * (NIJ + 1) + NIJ their alphas, so the rows at a cell are
// beta[e] g + alpha w, with (e, g, w) read from the `cell_info` texel of the cell (g =
// w / (cos theta_d max(N.wi, N.wo)), computed in f64 by the host). A measured row block
// holds its rows' scaled values per cell of the chunk (packed by the host). Padding
// blocks read an all-zero table.
//
// One workgroup of LANES lanes owns one register block of (4 R) x (4 R) lobe pairs (from
// a caller-given list of block pairs) and LANES / 8 consecutive *canonical runs* of
// 8 x run_iters cells. The canonical order of summation, the same on every back-end and
// shape (the CPU back-end follows it too, so both give the same sums bit for bit): in a
// canonical run, lane l (0..8) takes cells l, l + 8, l + 16, ... and sums them in f32 in
// that order; the host adds the per-lane sums in f64 in (run, lane) order. Each invocation
// fetches 1 + 2 R texels per cell, keeps 4 R x R vec4 accumulators in registers and
// writes them out.
//
// Why textures: lavapipe compiles each storage-buffer load into a per-lane scalar loop
// with bounds checks, but a texel fetch into vector code, and one rgba texel gives four
// rows. No workgroup memory and no barrier (on lavapipe a barrier turns the shader into
// coroutines). The body is unrolled by the host (pairwise/shape.rs, `kernel_source`),
// which prepends `const R` and `const LANES` and expands the lines that start with a
// marker; every loop is bounded by run_iters <= MAX_RUN_ITERS, far below lavapipe's
// 65,535-iteration limit.

// Keep in sync with `PairParams` in pairwise/mod.rs.
struct PairParams {
    n_cells: u32,
    row_stride: u32,
    run_iters: u32,
    n_runs: u32,
    block_offset: u32,
    n_blocks: u32,
    analytic_blocks: u32,
    measured_blocks: u32,
    measured_base: u32,
    zero_base: u32,
    _pad0: u32,
    _pad1: u32,
}

const NIJ: u32 = 8100u;

@group(0) @binding(0) var<uniform> p: PairParams;
@group(0) @binding(1) var vals: texture_2d<f32>;
@group(0) @binding(2) var<storage, read> blocks: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read_write> partial: array<f32>;
@group(0) @binding(4) var cell_info: texture_2d<f32>;

override OP: u32 = 0u;

// Where a row block's values come from: texel of its table (per_cell = 0, indexed by e)
// or of its cell 0 (per_cell = 1, indexed by c); alphas of its rows.
struct Source {
    base: u32,
    per_cell: u32,
    alpha: vec4<f32>,
}

fn source(b: u32) -> Source {
    if (b < p.analytic_blocks) {
        let base = b * (NIJ + 1u);
        return Source(base, 0u, textureLoad(vals, texel_coord(base + NIJ), 0));
    }
    if (b - p.analytic_blocks < p.measured_blocks) {
        return Source(p.measured_base + (b - p.analytic_blocks) * p.row_stride, 1u, vec4<f32>(0.0));
    }
    return Source(p.zero_base, 0u, vec4<f32>(0.0));
}

// The four rows of a block at cell c, whose cell info is (e, g, w): beta g + alpha w,
// each product and the sum rounded to f32 (the CPU back-end's formula; not fma, which
// lavapipe computes as a multiply and an add anyway).
fn rows(s: Source, c: u32, e: u32, g: f32, w: f32) -> vec4<f32> {
    let m = s.per_cell != 0u;
    let t = textureLoad(vals, texel_coord(s.base + select(e, c, m)), 0);
    return t * vec4<f32>(select(g, 1.0, m)) + s.alpha * w;
}

// One row's value `a` against four column values `b` (as the CPU back-end: acc + |a - b|,
// acc + a b with the product rounded).
fn step(acc: vec4<f32>, a: f32, b: vec4<f32>) -> vec4<f32> {
    if (OP == 0u) {
        return acc + abs(vec4<f32>(a) - b);
    }
    return acc + vec4<f32>(a) * b;
}

@compute @workgroup_size(LANES)
fn main(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let run = wid.x;
    let b = wid.y + p.block_offset;
    let blk = blocks[min(b, p.n_blocks - 1u)];
    let ra = blk.x * R;
    let rb = blk.y * R;
    // Canonical run (run * LANES / 8 + lid / 8), lane lid % 8 of it.
    let start = (run * (LANES / 8u) + lid.x / 8u) * p.run_iters * 8u + lid.x % 8u;
    //@SOURCES
    //@DECLARE
    for (var t = 0u; t < p.run_iters; t = t + 1u) {
        let c = start + t * 8u;
        if (c >= p.n_cells) {
            break;
        }
        let info = textureLoad(cell_info, texel_coord(c), 0);
        let e = u32(info.x);
        //@FETCH
        //@ACCUMULATE
    }
    if (b < p.n_blocks) {
        let o = (((b - p.block_offset) * p.n_runs + run) * LANES + lid.x) * 16u * R * R;
        //@STORE
    }
}
