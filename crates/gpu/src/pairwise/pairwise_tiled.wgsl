// The pairwise kernel for hardware GPUs: the entry point below is appended to the
// definitions of pairwise.wgsl (parameters, bindings, `source`, `rows`, `step`;
// shape.rs, `kernel_source`), so both kernels read the same
// value texture and write the same per-lane partial sums, in the same canonical order.
//
// One workgroup of 256 invocations owns one tile of 32 x 32 lobe pairs (rows of register
// block `blocks[b].x`, columns of `blocks[b].y`, 8 texels of 4 rows each) and one
// canonical run of 8 x run_iters cells. Per batch of 64 cells (8 iterations of each of
// the run's 8 canonical lanes) the workgroup stages the tile's row values of those cells
// in workgroup memory (2 x 512 texels: each texel fetched and tabulated once per batch
// instead of once per invocation), then invocation (lane l, register block g) adds
// op(a, b) for its 4 x 8 pairs over the batch's cells of lane l, in cell order. So each
// f32 accumulator is the sum of one (pair, canonical lane) over cells l, l + 8, l + 16,
// ... in that order: the CPU back-end's and the register kernel's sums.
//
// A cell past the chunk's end is staged as zero rows: op(0, 0) = 0 and acc + 0 = acc (acc
// is never -0: it starts at +0 and +0 + -0 = +0). Every loop is bounded by run_iters <=
// MAX_RUN_ITERS (1,024), far below lavapipe's 65,535 iterations; the batch loop's exit
// depends only on uniform values, so every barrier is reached by the whole workgroup.

const TT: u32 = 8u;
const SIDE: u32 = 32u;
const STEPS: u32 = 8u;
const BATCH: u32 = 64u;
const WG: u32 = 256u;

var<workgroup> tile_a: array<vec4<f32>, 512>;
var<workgroup> tile_b: array<vec4<f32>, 512>;

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_index) li: u32, @builtin(workgroup_id) wid: vec3<u32>) {
    let run = wid.x;
    let b = wid.y + p.block_offset;
    let blk = blocks[min(b, p.n_blocks - 1u)];
    let lane = li % 8u;
    let g = li / 8u;
    // This invocation's 4 x 8 pairs: rows of texel ta, columns of texels tb and tb + 1.
    let ta = g / 4u;
    let tb = (g % 4u) * 2u;
    let run_start = run * 8u * p.run_iters;
    var acc_0_0 = vec4<f32>(0.0);
    var acc_0_1 = vec4<f32>(0.0);
    var acc_1_0 = vec4<f32>(0.0);
    var acc_1_1 = vec4<f32>(0.0);
    var acc_2_0 = vec4<f32>(0.0);
    var acc_2_1 = vec4<f32>(0.0);
    var acc_3_0 = vec4<f32>(0.0);
    var acc_3_1 = vec4<f32>(0.0);
    let batches = p.run_iters / STEPS;
    for (var bt = 0u; bt < batches; bt = bt + 1u) {
        let first = run_start + bt * BATCH;
        if (first >= p.n_cells) {
            break;
        }
        // Stage: item = cell of the batch x 8 + texel of the tile, two per invocation.
        for (var q = 0u; q < 2u; q = q + 1u) {
            let item = li + WG * q;
            let c = first + item / TT;
            let tx = item % TT;
            var va = vec4<f32>(0.0);
            var vb = vec4<f32>(0.0);
            if (c < p.n_cells) {
                let info = textureLoad(cell_info, texel_coord(c), 0);
                let e = u32(info.x);
                va = rows(source(blk.x * TT + tx), c, e, info.y, info.z);
                vb = rows(source(blk.y * TT + tx), c, e, info.y, info.z);
            }
            tile_a[item] = va;
            tile_b[item] = vb;
        }
        workgroupBarrier();
        for (var s = 0u; s < STEPS; s = s + 1u) {
            let cb = (s * 8u + lane) * TT;
            let a = tile_a[cb + ta];
            let b0 = tile_b[cb + tb];
            let b1 = tile_b[cb + tb + 1u];
            acc_0_0 = step(acc_0_0, a.x, b0);
            acc_0_1 = step(acc_0_1, a.x, b1);
            acc_1_0 = step(acc_1_0, a.y, b0);
            acc_1_1 = step(acc_1_1, a.y, b1);
            acc_2_0 = step(acc_2_0, a.z, b0);
            acc_2_1 = step(acc_2_1, a.z, b1);
            acc_3_0 = step(acc_3_0, a.w, b0);
            acc_3_1 = step(acc_3_1, a.w, b1);
        }
        workgroupBarrier();
    }
    if (b < p.n_blocks) {
        // Partials of (block, run, lane): SIDE x SIDE values, row-major (a, b) in the tile.
        let o = (((b - p.block_offset) * p.n_runs + run) * 8u + lane) * SIDE * SIDE
            + ta * 4u * SIDE + tb * 4u;
        store4(o, acc_0_0);
        store4(o + 4u, acc_0_1);
        store4(o + SIDE, acc_1_0);
        store4(o + SIDE + 4u, acc_1_1);
        store4(o + 2u * SIDE, acc_2_0);
        store4(o + 2u * SIDE + 4u, acc_2_1);
        store4(o + 3u * SIDE, acc_3_0);
        store4(o + 3u * SIDE + 4u, acc_3_1);
    }
}

fn store4(o: u32, v: vec4<f32>) {
    partial[o] = v.x;
    partial[o + 1u] = v.y;
    partial[o + 2u] = v.z;
    partial[o + 3u] = v.w;
}
