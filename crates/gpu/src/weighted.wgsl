// Per-target weighted normal equations (SPEC 11; brdf_basis_core::backend::weighted): for target t
// and the m = K + 1 columns (the Lambertian 1 / pi, then K basis lobes), the sums over a
// run of cells of W f_i f_j (i <= j), W f_i y and W y^2, with W = w_s phi(y) the
// objective's weight at the target's value y; the last value of each system (STRIDE counts
// it) is the count of cells whose weight left f32's range. The host unrolls the template for K
// (weighted.rs, `kernel_source`): it prepends `const K` and `const STRIDE`
// and expands the lines that start with a marker.
//
// Rows come four to a texel of the packed texture `rows` (texel (r / 4) * chunk + c, channel
// r % 4: analytic rows packed by the tabulation kernel, measured rows by the host, neural
// rows by the neural kernel, all on the device). One invocation: one target and one run of
// at most run_len (1,024) cells, summed in f32 in cell order; the runs' partial sums are
// added in f64 on the device (pairwise/reduce_f64.wgsl). The workgroup's 64 targets read the
// same basis texels at the same cell (the texture cache serves them). No loop runs more
// than run_len iterations, far below lavapipe's 65,535; no barrier.

// Keep in sync with `WeightedParams` in weighted.rs.
struct WeightedParams {
    n_cells: u32,
    n_targets: u32,
    run_len: u32,
    n_runs: u32,
    chunk: u32,
    weight: u32,
    eps: f32,
    lambert: f32,
}

@group(0) @binding(0) var<uniform> p: WeightedParams;
@group(0) @binding(1) var rows: texture_2d<f32>;
// Packed row of basis lobe j at j, of target t at K + t.
@group(0) @binding(2) var<storage, read> row_of: array<u32>;
// Per cell of the chunk: (cell weight w_s, cos theta_i).
@group(0) @binding(3) var<storage, read> cellw: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read_write> partial: array<f32>;

fn fetch(r: u32, c: u32) -> f32 {
    let t = textureLoad(rows, texel_coord((r / 4u) * p.chunk + c), 0);
    return t[r % 4u];
}

// The objective's factor phi (brdf_basis_core::backend::weighted, `TargetWeight::phi`).
fn phi(y: f32, cos_i: f32) -> f32 {
    let yp = max(y, 0.0);
    if (p.weight == 1u) {
        let d = yp + p.eps;
        return 1.0 / (d * d);
    }
    if (p.weight == 2u) {
        let c = max(cos_i, 0.0);
        let q = c / (1.0 + yp * c);
        return q * q;
    }
    return 1.0;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = gid.x;
    let run = gid.y;
    if (t >= p.n_targets) {
        return;
    }
    let yrow = row_of[K + t];
    //@BASIS
    //@DECLARE
    let start = run * p.run_len;
    let end = min(start + p.run_len, p.n_cells);
    var lost: f32 = 0.0;
    // 2^64 under relative and log (weighted.rs, `YY_SCALE`), 1 under l2.
    let yscale = select(1.0, 18446744073709551616.0, p.weight != 0u);
    for (var c = start; c < end; c = c + 1u) {
        let y = fetch(yrow, c);
        let cw = cellw[c];
        let wgt = cw.x * phi(y, cw.y);
        // f32's range: a weight the f64 reference forms as a positive normal number (every
        // relative one, a log one where cos theta_i > 0) that is here 0, subnormal or
        // infinite, or too small for its Lambertian term W / pi^2 to stay normal, marks
        // the target for the host's f64 reference (weighted.rs, `FLAG`).
        if (cw.x > 0.0 && (p.weight == 1u || (p.weight == 2u && cw.y > 0.0))
            && !(wgt * p.lambert * p.lambert >= 1.1754944e-38 && wgt <= 3.4028235e38)) {
            lost = lost + 1.0;
        }
        let f0 = p.lambert;
        //@FETCH
        //@ACCUMULATE
    }
    let o = (t * p.n_runs + run) * STRIDE;
    //@STORE
}
