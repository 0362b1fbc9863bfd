// Pairwise reductions over grid cells. OP = 0: weighted L1 (rows pre-multiplied by the
// cell weights, so w |a - b| = |w a - w b|); OP = 1: weighted dot products for Gram
// matrices (rows pre-multiplied by sqrt(w)). For a BLOCK x BLOCK block of lobe pairs (from
// a caller-given list), one workgroup of WG lanes reduces one run of WG * run_iters
// cells: lane l takes cells l, l + WG, ..., keeps 16 f32 accumulators in registers and
// writes them out; the host sums lanes and runs in f64. No workgroup memory and no
// barrier: on lavapipe a barrier turns the shader into coroutines and cost ~40 % of the
// time. Every loop is bounded by run_iters <= MAX_RUN_ITERS (src/gpu/pairwise.rs), far
// below lavapipe's 65,535-iteration limit.

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


@compute @workgroup_size(WG)
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
    if (b < p.n_blocks) {
        let o = (((b - p.block_offset) * p.n_runs + run) * WG + lid.x) * 16u;
        for (var q = 0u; q < 4u; q = q + 1u) {
            partial[o + q] = acc0[q];
            partial[o + 4u + q] = acc1[q];
            partial[o + 8u + q] = acc2[q];
            partial[o + 12u + q] = acc3[q];
        }
    }
}
