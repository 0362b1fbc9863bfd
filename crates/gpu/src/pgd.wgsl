// Batched accelerated projected gradient (FISTA with gradient restart) for NNLS targets
// that share one diagonally scaled Gram matrix G~ (m <= 32, unit diagonal): one target per
// invocation, the CPU twin is `fista` in crates/core/src/nnls/pgd.rs. Each dispatch advances every
// unfinished target by at most STEPS steps; state lives in `state` between dispatches, so
// no invocation runs more than STEPS x (m^2 + 4m) loop iterations (far below lavapipe's
// 65,535). The host prepends `const M` (= m, see `kernel_source` in pgd.rs):
// constant trip counts let the loops unroll, so the arrays stay in registers instead of
// lavapipe's per-lane memory emulation.

// Keep in sync with `PgdUniforms` in pgd.rs.
struct PgdUniforms {
    m: u32,
    n_targets: u32,
    steps: u32,
    max_iter: u32,
    inv_l: f32,
    tol: f32,
    _pad0: u32,
    _pad1: u32,
}

// Per-target state layout (f32): x[32], gx[32], v[32], gv[32], t, iterations, done, pad.
const S_X: u32 = 0u;
const S_GX: u32 = 32u;
const S_V: u32 = 64u;
const S_GV: u32 = 96u;
const S_T: u32 = 128u;
const S_IT: u32 = 129u;
const S_DONE: u32 = 130u;
const S_LEN: u32 = 132u;

@group(0) @binding(0) var<uniform> p: PgdUniforms;
// The scaled Gram matrix, row-major M x M. A uniform buffer: with M a constant every
// loop below unrolls, every index is a constant, and lavapipe reads one scalar.
@group(0) @binding(1) var<uniform> gs: array<vec4<f32>, 256>;
@group(0) @binding(2) var<storage, read> hs: array<f32>;
@group(0) @binding(3) var<storage, read_write> state: array<f32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let tg = gid.x + gid.y * 65535u * 64u;
    if (tg >= p.n_targets) {
        return;
    }
    let base = tg * S_LEN;
    if (state[base + S_DONE] != 0.0) {
        return;
    }
    let m = M;
    var x: array<f32, M>;
    var gx: array<f32, M>;
    var v: array<f32, M>;
    var gv: array<f32, M>;
    var h: array<f32, M>;
    var xn: array<f32, M>;
    var gxn: array<f32, M>;
    for (var i = 0u; i < m; i = i + 1u) {
        x[i] = state[base + S_X + i];
        gx[i] = state[base + S_GX + i];
        v[i] = state[base + S_V + i];
        gv[i] = state[base + S_GV + i];
        h[i] = hs[tg * m + i];
    }
    var t = state[base + S_T];
    var it = u32(state[base + S_IT]);
    var done = 0.0;
    var hmax = 0.0;
    for (var i = 0u; i < m; i = i + 1u) {
        hmax = max(hmax, abs(h[i]));
    }
    for (var step = 0u; step < p.steps; step = step + 1u) {
        if (it >= p.max_iter) {
            done = 1.0;
            break;
        }
        it = it + 1u;
        for (var i = 0u; i < m; i = i + 1u) {
            xn[i] = max(v[i] - (gv[i] - h[i]) * p.inv_l, 0.0);
        }
        var s = hmax;
        for (var i = 0u; i < m; i = i + 1u) {
            var acc = 0.0;
            for (var j = 0u; j < m; j = j + 1u) {
                let k = i * m + j;
                acc = fma(gs[k / 4u][k % 4u], xn[j], acc);
            }
            gxn[i] = acc;
            s = s + xn[i];
        }
        // Scaled KKT violation (crates/core/src/nnls/mod.rs kkt_scaled).
        var worst = 0.0;
        for (var i = 0u; i < m; i = i + 1u) {
            let g = gxn[i] - h[i];
            worst = max(worst, select(max(-g, 0.0), abs(g), xn[i] > 0.0));
        }
        if (s <= 0.0 || worst <= p.tol * s) {
            for (var i = 0u; i < m; i = i + 1u) {
                x[i] = xn[i];
                gx[i] = gxn[i];
            }
            done = 1.0;
            break;
        }
        var restart = 0.0;
        for (var i = 0u; i < m; i = i + 1u) {
            restart = restart + (v[i] - xn[i]) * (xn[i] - x[i]);
        }
        if (restart > 0.0) {
            t = 1.0;
            for (var i = 0u; i < m; i = i + 1u) {
                v[i] = xn[i];
                gv[i] = gxn[i];
            }
        } else {
            let tn = 0.5 * (1.0 + sqrt(1.0 + 4.0 * t * t));
            let beta = (t - 1.0) / tn;
            for (var i = 0u; i < m; i = i + 1u) {
                v[i] = xn[i] + beta * (xn[i] - x[i]);
                gv[i] = gxn[i] + beta * (gxn[i] - gx[i]);
            }
            t = tn;
        }
        for (var i = 0u; i < m; i = i + 1u) {
            x[i] = xn[i];
            gx[i] = gxn[i];
        }
    }
    for (var i = 0u; i < m; i = i + 1u) {
        state[base + S_X + i] = x[i];
        state[base + S_GX + i] = gx[i];
        state[base + S_V + i] = v[i];
        state[base + S_GV + i] = gv[i];
    }
    state[base + S_T] = t;
    state[base + S_IT] = f32(it);
    state[base + S_DONE] = done;
}
