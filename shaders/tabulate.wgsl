// Tabulation: value of lobe l at cell c of a list of grid cells, optionally multiplied by
// the cell's weight. Lobes come in separable form (src/separable.rs): value =
// alpha_l + G(c) beta_l[i][j], with beta tabulated in f64 on the host and rounded once
// (no exp2 or pow on the GPU: (N.H)^n for n up to 1e5 is exact to f32 rounding). One
// invocation computes the cell factor G once and then LPI lobes: at most LPI loop
// iterations, far below lavapipe's 65,535.

// Keep in sync with `TabParams` in src/gpu/tabulate.rs.
struct TabParams {
    n_cells: u32,
    n_lobes: u32,
    weighted: u32,
    row_stride: u32,
}

const LPI: u32 = 16u;
const NIJ: u32 = 8100u;

@group(0) @binding(0) var<uniform> p: TabParams;
@group(0) @binding(1) var<storage, read> tables: array<f32, 720>;
@group(0) @binding(2) var<storage, read> alphas: array<f32>;
@group(0) @binding(3) var<storage, read> rows: array<u32>;
@group(0) @binding(4) var<storage, read> cells: array<u32>;
@group(0) @binding(5) var<storage, read> weights: array<f32>;
@group(0) @binding(6) var<storage, read_write> out: array<f32>;
@group(0) @binding(7) var<storage, read> betas: array<f32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    if (c >= p.n_cells) {
        return;
    }
    let cell = cells[c];
    let i = cell / 16200u;
    let j = (cell / 180u) % 90u;
    let k = cell % 180u;
    let cos_d = tables[T_COS_D + j];
    let max_cos = tables[T_COS_H + i] * cos_d + tables[T_SIN_H + i] * tables[T_SIN_D + j] * tables[T_ABS_COS_P + k];
    var w = 1.0;
    if (p.weighted != 0u) {
        w = weights[c];
    }
    let gw = w / (cos_d * max_cos);
    let e = i * 90u + j;
    let l0 = gid.y * LPI;
    for (var t = 0u; t < LPI; t = t + 1u) {
        let l = l0 + t;
        if (l >= p.n_lobes) {
            break;
        }
        out[rows[l] * p.row_stride + c] = alphas[l] * w + betas[l * NIJ + e] * gw;
    }
}
