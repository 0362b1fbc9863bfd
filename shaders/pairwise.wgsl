// Pairwise weighted L1: for a BLOCK x BLOCK block of material pairs (rows pre-multiplied
// by the cell weights, so w |a - b| = |w a - w b|), one workgroup reduces one run of
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
        acc0 = acc0 + abs(vec4<f32>(vals[ra + c]) - bv);
        acc1 = acc1 + abs(vec4<f32>(vals[ra + s + c]) - bv);
        acc2 = acc2 + abs(vec4<f32>(vals[ra + 2u * s + c]) - bv);
        acc3 = acc3 + abs(vec4<f32>(vals[ra + 3u * s + c]) - bv);
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
