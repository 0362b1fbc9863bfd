// Tabulation: value of lobe `row` at cell `c` of a list of grid cells, optionally
// multiplied by the cell's weight. One value per invocation: no loop, so no invocation
// comes near lavapipe's 65,535-iteration limit.
//
// (N.H)^n is exp2(n log2 cos theta_h) with log2 cos theta_h tabulated in f64 on the host
// and rounded once: relative error ~1e-6 for n up to 1e5, where pow(cos, n) in f32 loses
// everything near the peak.

// Keep in sync with `TabParams` in src/gpu/tabulate.rs.
struct TabParams {
    n_cells: u32,
    n_lobes: u32,
    weighted: u32,
    row_stride: u32,
}

@group(0) @binding(0) var<uniform> p: TabParams;
@group(0) @binding(1) var<storage, read> tables: array<f32, 720>;
@group(0) @binding(2) var<storage, read> lobes: array<Lobe>;
@group(0) @binding(3) var<storage, read> rows: array<u32>;
@group(0) @binding(4) var<storage, read> cells: array<u32>;
@group(0) @binding(5) var<storage, read> weights: array<f32>;
@group(0) @binding(6) var<storage, read_write> out: array<f32>;

fn lobe_value(l: Lobe, cell: u32) -> f32 {
    let i = cell / 16200u;
    let j = (cell / 180u) % 90u;
    let k = cell % 180u;
    let cos_d = tables[T_COS_D + j];
    let max_cos = tables[T_COS_H + i] * cos_d + tables[T_SIN_H + i] * tables[T_SIN_D + j] * tables[T_ABS_COS_P + k];
    let fresnel = l.f0 + (1.0 - l.f0) * tables[T_SCHLICK_D + j];
    let peak = exp2(l.n * tables[T_LOG2_COS_H + i]);
    let spec = (l.n + 1.0) * peak * fresnel * INV_8PI / (cos_d * max_cos);
    return l.kd * INV_PI + l.ks * spec;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    let l = gid.y;
    if (c >= p.n_cells || l >= p.n_lobes) {
        return;
    }
    var v = lobe_value(lobes[l], cells[c]);
    if (p.weighted != 0u) {
        v = v * weights[c];
    }
    out[rows[l] * p.row_stride + c] = v;
}
