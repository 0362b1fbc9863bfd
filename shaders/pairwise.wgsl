// Pairwise reductions over grid cells. OP = 0: weighted L1 (rows pre-multiplied by the
// cell weights, so w |a - b| = |w a - w b|); OP = 1: weighted dot products for Gram
// matrices (rows pre-multiplied by sqrt(w)).
//
// The lobe values come packed four rows to a texel of an rgba32float texture (filled by
// `pack` in tabulate.wgsl): one texel fetch gives four rows at one cell. One workgroup of
// LANES lanes owns one register block of (4 R) x (4 R) lobe pairs (from a caller-given
// list of block pairs) and one run of LANES x run_iters cells: lane l takes cells l,
// l + LANES, ..., fetches 2 R texels per cell, keeps 4 R x R vec4 accumulators in
// registers and writes them out; the host sums lanes and runs in f64.
//
// Why textures: lavapipe compiles each storage-buffer load into a per-lane scalar loop
// with bounds checks, but a texel fetch into one vector gather, and a 4-channel texel
// gives 4 rows per fetch. No workgroup memory and no barrier (on lavapipe a barrier turns
// the shader into coroutines). The body is unrolled by the host (src/gpu/pairwise.rs,
// `kernel_source`), which prepends `const R` and `const LANES` and expands the `//@`
// lines; every loop is bounded by run_iters <= MAX_RUN_ITERS, far below lavapipe's
// 65,535-iteration limit.

// Keep in sync with `PairParams` in src/gpu/pairwise.rs.
struct PairParams {
    n_cells: u32,
    row_stride: u32,
    run_iters: u32,
    n_runs: u32,
    block_offset: u32,
    n_blocks: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> p: PairParams;
@group(0) @binding(1) var vals: texture_2d<f32>;
@group(0) @binding(2) var<storage, read> blocks: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read_write> partial: array<f32>;

override OP: u32 = 0u;

fn fetch(block: u32, c: u32) -> vec4<f32> {
    return textureLoad(vals, texel_coord(block * p.row_stride + c), 0);
}

// One row's value `a` against four column values `b`.
fn step(acc: vec4<f32>, a: f32, b: vec4<f32>) -> vec4<f32> {
    if (OP == 0u) {
        return acc + abs(vec4<f32>(a) - b);
    }
    return fma(vec4<f32>(a), b, acc);
}

@compute @workgroup_size(LANES)
fn main(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let run = wid.x;
    let b = wid.y + p.block_offset;
    let blk = blocks[min(b, p.n_blocks - 1u)];
    let ra = blk.x * R;
    let rb = blk.y * R;
    let start = run * p.run_iters * LANES + lid.x;
    //@DECLARE
    for (var t = 0u; t < p.run_iters; t = t + 1u) {
        let c = start + t * LANES;
        if (c >= p.n_cells) {
            break;
        }
        //@FETCH
        //@ACCUMULATE
    }
    if (b < p.n_blocks) {
        let o = (((b - p.block_offset) * p.n_runs + run) * LANES + lid.x) * 16u * R * R;
        //@STORE
    }
}
