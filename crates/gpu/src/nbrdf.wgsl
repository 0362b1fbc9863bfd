// Neural BRDFs (Sztrajman et al. 2021, SPEC 9) on the MERL grid: every network of a chunk
// evaluated at every cell of the chunk, written four rows to a texel of an rgba32float
// texture (texel out_base + b * row_stride + c holds rows 4b .. 4b + 3 at cell c: the
// layout of the pairwise kernel's measured row blocks, so the pairwise pass reads the rows
// without a host round trip).
//
//   f = max(expm1(a2 . fc3 + b3), 0),  a2 = relu(a1 . fc2 + b2),  a1 = relu(x . fc1 + b1),
//   x = (sin th, 0, cos th, sin td cos pd, sin td sin pd, cos td).
//
// Weights: NET_VEC4 vec4 per network in the kernel layout of neural.rs
// (`kernel_weights`: fc1's five non-zero input rows as 6 vec4 of 4 hidden units each, b1,
// fc2 transposed (per hidden unit of layer 2, its 21 input weights as 6 vec4), then per
// unit of layer 2 (fc3[j][0..3], b2[j]), then b3).
//
// Inputs: the features texture holds (sin td cos pd, sin td sin pd, cos td) of each
// (theta_d, phi_d) cell pair at texel j * 180 + k and (sin th, cos th) of row i at texel
// D_CELLS + i (.xy), computed in f64 on the host and rounded once; their rounding errors
// (f64 value - f32 value, rounded) at texel 2 D_CELLS + j * 180 + k and in .zw of texel
// D_CELLS + i. A cell index decodes as
// (i, jk) = (cell / D_CELLS, cell % D_CELLS); the same decoding serves arbitrary points
// (point p is passed as p * D_CELLS + p, with its features at texels p and D_CELLS + p).
//
// One invocation: one cell of one row block: it evaluates the (at most 4) distinct
// networks of the block's rows and stores one texel, each row its channel (or the mean of
// R, G, B) times the cell's row scale. Work per invocation is bounded: at most 4 networks,
// loops of at most 21 iterations, nested at most twice (441) in the double-f32 pass
// (lavapipe silently ends loops after 65,535). No workgroup memory or barrier.
//
// exp(z) - 1 is an accurate expm1 (Cody-Waite reduction z = n ln 2 + r, a degree-8
// polynomial for expm1(r), |r| <= ln 2 / 2): a plain f32 exp(z) - 1 loses the relative
// accuracy of small values to cancellation.
//
// Each value comes with an estimate of the f32 pass's rounding error (the one of the CPU
// twin, `recheck_windows` in crates/core/src/brdf/nbrdf.rs, here per cell: one unit roundoff per
// magnitude sum of the units live at the cell, carried to z by the absolute weights).
// Where the estimate is not within half of SPEC 9's tolerance (5e-4 relative above 1e-3,
// 1e-6 below), the network is run again in double-f32 arithmetic (a value as an unevaluated
// sum hi + lo of two f32; Dekker's exact product by splitting, Knuth's exact sum), inputs
// included (their f32 rounding errors come as lo parts in the features texture): about
// 44 significant bits, far beyond what SPEC 9 needs. Every rounded intermediate of those
// exact transformations is multiplied by `one` (1.0 from the uniforms, opaque to the
// shader compiler), so that no algebraic simplification can fold `(a + b) - a` into `b`.

// Keep in sync with `NeuralParams` in neural.rs.
struct NeuralParams {
    n_cells: u32,
    row_stride: u32,
    out_base: u32,
    // 1.0 (f32 bits): see the header.
    one_bits: u32,
}

// One row block: the distinct networks its rows use (`count` of them, their weights in
// `w`), per row the slot of its network (4: a padding row, value 0) and its channel (0,
// 1, 2; 3: the mean), and the block's index in the output texture. Keep in sync with
// `BlockDesc` in neural.rs.
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

// Double-f32 arithmetic (see the header): a value is vec2(hi, lo), |lo| <= ulp(hi) / 2.
// (a + b) exactly, as (s, e).
fn two_sum(a: f32, b: f32) -> vec2<f32> {
    let one = bitcast<f32>(p.one_bits);
    let s = (a + b) * one;
    let bb = (s - a) * one;
    let e = (a - (s - bb)) + (b - bb);
    return vec2<f32>(s, e);
}

// (a + b) exactly for |a| >= |b|.
fn fast_two_sum(a: f32, b: f32) -> vec2<f32> {
    let one = bitcast<f32>(p.one_bits);
    let s = (a + b) * one;
    return vec2<f32>(s, b - (s - a));
}

// a = hi + lo with hi of 12 significant bits (Veltkamp).
fn split(a: f32) -> vec2<f32> {
    let one = bitcast<f32>(p.one_bits);
    let c = (4097.0 * a) * one;
    let hi = c - (c - a) * one;
    return vec2<f32>(hi, a - hi);
}

// (a b) exactly, as (p, e) (Dekker: the partial products of the halves are exact).
fn two_prod(a: f32, b: f32) -> vec2<f32> {
    let one = bitcast<f32>(p.one_bits);
    let q = (a * b) * one;
    let x = split(a);
    let y = split(b);
    let e = ((x.x * y.x - q) + x.x * y.y + x.y * y.x) + x.y * y.y;
    return vec2<f32>(q, e);
}

fn df_add(a: vec2<f32>, b: vec2<f32>) -> vec2<f32> {
    let s = two_sum(a.x, b.x);
    return fast_two_sum(s.x, s.y + (a.y + b.y));
}

// a (double-f32) times b (f32).
fn df_mul(a: vec2<f32>, b: f32) -> vec2<f32> {
    let q = two_prod(a.x, b);
    return fast_two_sum(q.x, q.y + a.y * b);
}

// Weight `u` (0..21) of the vec4 row starting at `at`.
fn wu(at: u32, u: u32) -> f32 {
    return blk.w[at + u / 4u][u % 4u];
}

// The network in `slot` in double-f32 at inputs x = (hi, lo) per feature: the raw RGB
// output exp(z) - 1, z rounded to hi + lo.
fn network_df(slot: u32, x: array<vec2<f32>, 5>) -> vec3<f32> {
    let o = slot * NET_VEC4;
    var a1: array<vec2<f32>, 21>;
    for (var j = 0u; j < HIDDEN; j = j + 1u) {
        var s = vec2<f32>(wu(o + B1, j), 0.0);
        for (var r = 0u; r < 5u; r = r + 1u) {
            s = df_add(s, df_mul(x[r], wu(o + W1 + 6u * r, j)));
        }
        a1[j] = select(vec2<f32>(0.0), s, s.x > 0.0);
    }
    var z = array<vec2<f32>, 3>(vec2<f32>(blk.w[o + B3].x, 0.0), vec2<f32>(blk.w[o + B3].y, 0.0),
        vec2<f32>(blk.w[o + B3].z, 0.0));
    for (var k = 0u; k < HIDDEN; k = k + 1u) {
        let wb = blk.w[o + W3B2 + k];
        var s = vec2<f32>(wb.w, 0.0);
        for (var j = 0u; j < HIDDEN; j = j + 1u) {
            s = df_add(s, df_mul(a1[j], wu(o + W2T + 6u * k, j)));
        }
        if (s.x > 0.0) {
            for (var c = 0u; c < 3u; c = c + 1u) {
                z[c] = df_add(z[c], df_mul(s, wb[c]));
            }
        }
    }
    var f: vec3<f32>;
    for (var c = 0u; c < 3u; c = c + 1u) {
        // expm1(hi + lo) = expm1(hi) + exp(hi) lo to first order (|lo| <= ulp(hi) / 2).
        let e = expm1_acc(z[c].x);
        f[c] = e + (1.0 + e) * z[c].y;
    }
    return f;
}

// Whether a value f of the f32 pass, with error estimate `e` of its z, may be off by
// more than half of SPEC 9's tolerance (values clamped at 0 afterwards).
fn recheck(f: f32, e: f32) -> bool {
    // expm1_acc's error (a few ulps) and the estimate's own roundings, with margin.
    let err = e * (1.0 + max(f, 0.0)) * 1.01 + 1e-6 * abs(f);
    var tol = 1e-6;
    if (f > 1.001e-3) {
        tol = 4.995e-4 * f;
    } else if (f > 0.999e-3) {
        tol = 4.99e-7;
    }
    // Below -2e both the value and the exact one are negative: 0 once clamped.
    return f > -2.0 * e && err > 0.5 * tol;
}

// The clamped RGB output of the block's network in `slot` at a cell of features h = (sin th,
// cos th), d = (sin td cos pd, sin td sin pd, cos td), and their f32 rounding errors hl, dl.
fn network(slot: u32, h: vec2<f32>, d: vec3<f32>, hl: vec2<f32>, dl: vec3<f32>) -> vec3<f32> {
    let o = slot * NET_VEC4;
    let z = vec4<f32>(0.0);
    var a: array<vec4<f32>, 6>;
    // Per layer-1 unit: 2 a1 + M1 where a1 > 0 (M1: the unit's magnitude sum), else 0.
    var g1: array<vec4<f32>, 6>;
    let ah = abs(h);
    let ad = abs(d);
    for (var g = 0u; g < 6u; g = g + 1u) {
        var s = blk.w[o + B1 + g];
        s = s + h.x * blk.w[o + W1 + g];
        s = s + h.y * blk.w[o + W1 + 6u + g];
        s = s + d.x * blk.w[o + W1 + 12u + g];
        s = s + d.y * blk.w[o + W1 + 18u + g];
        s = s + d.z * blk.w[o + W1 + 24u + g];
        a[g] = max(s, z);
        let m1 = abs(blk.w[o + B1 + g]) + ah.x * abs(blk.w[o + W1 + g])
            + ah.y * abs(blk.w[o + W1 + 6u + g]) + ad.x * abs(blk.w[o + W1 + 12u + g])
            + ad.y * abs(blk.w[o + W1 + 18u + g]) + ad.z * abs(blk.w[o + W1 + 24u + g]);
        g1[g] = select(z, 2.0 * a[g] + m1, s > z);
    }
    var acc = blk.w[o + B3];
    // The error estimate of z per channel, in units of the unit roundoff.
    var est = abs(acc.xyz);
    for (var j = 0u; j < HIDDEN; j = j + 1u) {
        let w = o + W2T + 6u * j;
        let wb = blk.w[o + W3B2 + j];
        let s = wb.w + ((dot(a[0], blk.w[w]) + dot(a[1], blk.w[w + 1u]))
            + (dot(a[2], blk.w[w + 2u]) + dot(a[3], blk.w[w + 3u]))
            + (dot(a[4], blk.w[w + 4u]) + dot(a[5], blk.w[w + 5u])));
        acc = acc + max(s, 0.0) * wb;
        let m = 2.0 * abs(wb.w) + ((dot(g1[0], abs(blk.w[w])) + dot(g1[1], abs(blk.w[w + 1u])))
            + (dot(g1[2], abs(blk.w[w + 2u])) + dot(g1[3], abs(blk.w[w + 3u])))
            + (dot(g1[4], abs(blk.w[w + 4u])) + dot(g1[5], abs(blk.w[w + 5u]))));
        // A unit that is 0 in f32 carries an error only when its exact sum may be positive.
        if (s > -1e-5 * m) {
            est = est + m * abs(wb.xyz);
        }
    }
    let f = vec3<f32>(expm1_acc(acc.x), expm1_acc(acc.y), expm1_acc(acc.z));
    let e = est * 5.9604645e-8;
    if (recheck(f.x, e.x) || recheck(f.y, e.y) || recheck(f.z, e.z)) {
        let x = array<vec2<f32>, 5>(vec2<f32>(h.x, hl.x), vec2<f32>(h.y, hl.y),
            vec2<f32>(d.x, dl.x), vec2<f32>(d.y, dl.y), vec2<f32>(d.z, dl.z));
        return max(network_df(slot, x), vec3<f32>(0.0));
    }
    return max(f, vec3<f32>(0.0));
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
    let dl = textureLoad(features, texel_coord(2u * D_CELLS + cell % D_CELLS), 0).xyz;
    let ht = textureLoad(features, texel_coord(D_CELLS + cell / D_CELLS), 0);
    var v = vec4<f32>(0.0);
    for (var s = 0u; s < 4u; s = s + 1u) {
        if (s >= desc.count) {
            break;
        }
        let f = network(s, ht.xy, d, ht.zw, dl);
        let m = vec4<f32>(f, (f.x + f.y + f.z) * (1.0 / 3.0));
        let pick = vec4<f32>(m[min(desc.chan.x, 3u)], m[min(desc.chan.y, 3u)],
            m[min(desc.chan.z, 3u)], m[min(desc.chan.w, 3u)]);
        v = select(v, pick, desc.slot == vec4<u32>(s));
    }
    textureStore(out, texel_coord(p.out_base + desc.block * p.row_stride + c), v * scales[c]);
}
