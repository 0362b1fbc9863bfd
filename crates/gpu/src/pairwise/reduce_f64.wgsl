// Adds the pairwise kernel's per-lane f32 partial sums (pairwise.wgsl,
// pairwise_tiled.wgsl) into f64 totals on the device, in the order the host
// would add them (pairwise/mod.rs, `accumulate`): for each value k of a
// register block, lane-runs in order. f32 -> f64 is exact and an f64 addition is correctly
// rounded on every conformant device, so the totals equal the host's bit for bit; only
// the totals are read back (bytes per pair: 8 instead of 4 per lane-run).
//
// Needs wgpu's SHADER_F64 (GpuContext::has_f64); without it the host adds the partials.
// One invocation per value of the dispatch's register blocks; its loop runs lane_runs
// (at most MAX_CHUNK / 1,024 = 256) iterations, far below lavapipe's 65,535.

// Keep in sync with `ReduceParams` in pairwise/reduce.rs.
struct ReduceParams {
    // Values per register block (side x side).
    ss: u32,
    // Lane-runs per register block in the partials (runs x lanes).
    lane_runs: u32,
    // Register blocks in this dispatch.
    count: u32,
    // Index in `sums` of this dispatch's first block's first value.
    sum_base: u32,
    // Invocations per row of the 2D dispatch (x groups x 64).
    row: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> rp: ReduceParams;
@group(0) @binding(1) var<storage, read> partial: array<f32>;
@group(0) @binding(2) var<storage, read_write> sums: array<f64>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let idx = gid.y * rp.row + gid.x;
    if (idx >= rp.count * rp.ss) {
        return;
    }
    let blk = idx / rp.ss;
    let k = idx % rp.ss;
    let base = blk * rp.lane_runs * rp.ss + k;
    var s = sums[rp.sum_base + idx];
    for (var lr = 0u; lr < rp.lane_runs; lr = lr + 1u) {
        s = s + f64(partial[base + lr * rp.ss]);
    }
    sums[rp.sum_base + idx] = s;
}
