// Neural BRDFs (Sztrajman et al. 2021, SPEC 9) on the MERL grid: every network of a chunk
// evaluated at every cell of the chunk, written four rows to a texel of an rgba32float
// texture (texel out_base + b * row_stride + c holds rows 4b .. 4b + 3 at cell c: the
// layout of the pairwise kernel's measured row blocks, so the pairwise pass reads the rows
// without a host round trip).
//
//   f = max(expm1(a2 . fc3 + b3), 0),  a2 = relu(a1 . fc2 + b2),  a1 = relu(x . fc1 + b1),
//   x = (sin th, 0, cos th, sin td cos pd, sin td sin pd, cos td).
//
// Weights: NET_VEC4 vec4 per network in the kernel layout of src/backend/gpu/neural.rs
// (`kernel_weights`: fc1's five non-zero input rows as 6 vec4 of 4 hidden units each, b1,
// fc2 transposed (per hidden unit of layer 2, its 21 input weights as 6 vec4), then per
// unit of layer 2 (fc3[j][0..3], b2[j]), then b3).
//
// Inputs: the features texture holds (sin td cos pd, sin td sin pd, cos td) of each
// (theta_d, phi_d) cell pair at texel j * 180 + k and (sin th, cos th) of row i at texel
// D_CELLS + i, computed in f64 on the host and rounded once. A cell index decodes as
// (i, jk) = (cell / D_CELLS, cell % D_CELLS); the same decoding serves arbitrary points
// (point p is passed as p * D_CELLS + p, with its features at texels p and D_CELLS + p).
//
// One invocation: one cell of one row block: it evaluates the (at most 4) distinct
// networks of the block's rows and stores one texel, each row its channel (or the mean of
// R, G, B) times the cell's row scale. Work per invocation is bounded: at most 4 networks,
// loops of at most 21 iterations (lavapipe silently ends loops after 65,535). No
// workgroup memory or barrier.
//
// exp(z) - 1 is an accurate expm1 (Cody-Waite reduction z = n ln 2 + r, a degree-8
// polynomial for expm1(r), |r| <= ln 2 / 2): a plain f32 exp(z) - 1 loses the relative
// accuracy of small values to cancellation.

// Keep in sync with `NeuralParams` in src/backend/gpu/neural.rs.
struct NeuralParams {
    n_cells: u32,
    row_stride: u32,
    out_base: u32,
    _pad0: u32,
}

// One row block: the distinct networks its rows use (`count` of them, their weights in
// `w`), per row the slot of its network (4: a padding row, value 0) and its channel (0,
// 1, 2; 3: the mean), and the block's index in the output texture. Keep in sync with
// `BlockDesc` in src/backend/gpu/neural.rs.
struct BlockDesc {
    slot: vec4<u32>,
    chan: vec4<u32>,
    count: u32,
    block: u32,
    _pad0: u32,
    _pad1: u32,
}

// A block's uniform region: its descriptor and the weights of its (at most 4) networks,
// NET_VEC4 vec4 each. In a uniform buffer every weight index is uniform across the
// dispatch (lavapipe loads it once and broadcasts it; a storage-buffer load is a per-lane
// loop there).
struct BlockUniform {
    desc: BlockDesc,
    w: array<vec4<f32>, 736>,
}

const NET_VEC4: u32 = 184u;
const W1: u32 = 0u;
const B1: u32 = 30u;
const W2T: u32 = 36u;
const W3B2: u32 = 162u;
const B3: u32 = 183u;
const HIDDEN: u32 = 21u;
const D_CELLS: u32 = 16200u;

@group(0) @binding(0) var<uniform> p: NeuralParams;
@group(0) @binding(1) var<uniform> blk: BlockUniform;
@group(0) @binding(2) var<storage, read> cells: array<u32>;
@group(0) @binding(3) var<storage, read> scales: array<f32>;
@group(0) @binding(4) var features: texture_2d<f32>;
@group(0) @binding(5) var out: texture_storage_2d<rgba32float, write>;

// exp(z) - 1 to a few f32 ulps, relative, for z in [-30, 88] (clamped: below, the value
// is -1 to f32 precision; above, it overflows f32).
fn expm1_acc(z_in: f32) -> f32 {
    let z = clamp(z_in, -30.0, 88.0);
    let n = round(z * 1.4426950408889634);
    // ln 2 = LN2_HI + LN2_LO, LN2_HI with 15 significant bits: n * LN2_HI is exact.
    let r = (z - n * 0.693145751953125) - n * 1.428606765330187e-6;
    let q = 1.0 / 2.0 + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (1.0 / 120.0 + r * (1.0 / 720.0
        + r * (1.0 / 5040.0 + r * (1.0 / 40320.0))))));
    let e = r + r * r * q;
    if (n == 0.0) {
        return e;
    }
    let t = ldexp(1.0, i32(n));
    return t * e + (t - 1.0);
}

// The clamped RGB output of the block's network in `slot` at a cell of features h = (sin th, cos th),
// d = (sin td cos pd, sin td sin pd, cos td).
fn network(slot: u32, h: vec2<f32>, d: vec3<f32>) -> vec3<f32> {
    let o = slot * NET_VEC4;
    let z = vec4<f32>(0.0);
    var a: array<vec4<f32>, 6>;
    for (var g = 0u; g < 6u; g = g + 1u) {
        var s = blk.w[o + B1 + g];
        s = s + h.x * blk.w[o + W1 + g];
        s = s + h.y * blk.w[o + W1 + 6u + g];
        s = s + d.x * blk.w[o + W1 + 12u + g];
        s = s + d.y * blk.w[o + W1 + 18u + g];
        s = s + d.z * blk.w[o + W1 + 24u + g];
        a[g] = max(s, z);
    }
    var acc = blk.w[o + B3];
    for (var j = 0u; j < HIDDEN; j = j + 1u) {
        let w = o + W2T + 6u * j;
        let wb = blk.w[o + W3B2 + j];
        let s = wb.w + ((dot(a[0], blk.w[w]) + dot(a[1], blk.w[w + 1u]))
            + (dot(a[2], blk.w[w + 2u]) + dot(a[3], blk.w[w + 3u]))
            + (dot(a[4], blk.w[w + 4u]) + dot(a[5], blk.w[w + 5u])));
        acc = acc + max(s, 0.0) * wb;
    }
    return max(vec3<f32>(expm1_acc(acc.x), expm1_acc(acc.y), expm1_acc(acc.z)), vec3<f32>(0.0));
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    if (c >= p.n_cells) {
        return;
    }
    let desc = blk.desc;
    let cell = cells[c];
    let d = textureLoad(features, texel_coord(cell % D_CELLS), 0).xyz;
    let h = textureLoad(features, texel_coord(D_CELLS + cell / D_CELLS), 0).xy;
    var v = vec4<f32>(0.0);
    for (var s = 0u; s < 4u; s = s + 1u) {
        if (s >= desc.count) {
            break;
        }
        let f = network(s, h, d);
        let m = vec4<f32>(f, (f.x + f.y + f.z) * (1.0 / 3.0));
        let pick = vec4<f32>(m[min(desc.chan.x, 3u)], m[min(desc.chan.y, 3u)],
            m[min(desc.chan.z, 3u)], m[min(desc.chan.w, 3u)]);
        v = select(v, pick, desc.slot == vec4<u32>(s));
    }
    textureStore(out, texel_coord(p.out_base + desc.block * p.row_stride + c), v * scales[c]);
}
