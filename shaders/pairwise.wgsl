// Pairwise reductions over grid cells. OP = 0: weighted L1 (rows pre-multiplied by the
// cell weights, so w |a - b| = |w a - w b|); OP = 1: weighted dot products for Gram
// matrices (rows pre-multiplied by sqrt(w)). For a BLOCK x BLOCK block of lobe pairs
// (from a caller-given list), one workgroup reduces one run of
// WG * run_iters cells. Lane l takes cells l, l + WG, ... (coalesced loads), keeps 16
// f32 accumulators in registers, and the 64 lanes are summed once through workgroup
// memory at the end. Every loop is bounded by run_iters <= MAX_RUN_ITERS (src/gpu/pairwise.rs),
// far below lavapipe's 65,535-iteration limit.

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
@group(0) @binding(1) var<storage, read> vals: array<f32>;
@group(0) @binding(2) var<storage, read> blocks: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read_write> partial: array<f32>;

override OP: u32 = 0u;

var<workgroup> red: array<vec4<f32>, 256>;

@compute @workgroup_size(64)
fn main(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let run = wid.x;
    let b = wid.y + p.block_offset;
    let blk = blocks[min(b, p.n_blocks - 1u)];
    let s = p.row_stride;
    let ra = blk.x * BLOCK * s;
    let rb = blk.y * BLOCK * s;
    var acc0 = vec4<f32>(0.0);
    var acc1 = vec4<f32>(0.0);
    var acc2 = vec4<f32>(0.0);
    var acc3 = vec4<f32>(0.0);
    let start = run * p.run_iters * WG + lid.x;
    for (var t = 0u; t < p.run_iters; t = t + 1u) {
        let c = start + t * WG;
        if (c >= p.n_cells) {
            break;
        }
        let bv = vec4<f32>(vals[rb + c], vals[rb + s + c], vals[rb + 2u * s + c], vals[rb + 3u * s + c]);
        let a0 = vec4<f32>(vals[ra + c]);
        let a1 = vec4<f32>(vals[ra + s + c]);
        let a2 = vec4<f32>(vals[ra + 2u * s + c]);
        let a3 = vec4<f32>(vals[ra + 3u * s + c]);
        if (OP == 0u) {
            acc0 = acc0 + abs(a0 - bv);
            acc1 = acc1 + abs(a1 - bv);
            acc2 = acc2 + abs(a2 - bv);
            acc3 = acc3 + abs(a3 - bv);
        } else {
            acc0 = fma(a0, bv, acc0);
            acc1 = fma(a1, bv, acc1);
            acc2 = fma(a2, bv, acc2);
            acc3 = fma(a3, bv, acc3);
        }
    }
    red[lid.x * 4u + 0u] = acc0;
    red[lid.x * 4u + 1u] = acc1;
    red[lid.x * 4u + 2u] = acc2;
    red[lid.x * 4u + 3u] = acc3;
    workgroupBarrier();
    if (lid.x < 16u && b < p.n_blocks) {
        let r = lid.x / 4u;
        let q = lid.x % 4u;
        var sum = 0.0;
        for (var l = 0u; l < WG; l = l + 1u) {
            sum = sum + red[l * 4u + r][q];
        }
        partial[(b * p.n_runs + run) * 16u + lid.x] = sum;
    }
}
