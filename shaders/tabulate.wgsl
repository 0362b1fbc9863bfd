// Tabulation: value of lobe l at cell c of a list of grid cells, optionally multiplied by
// the cell's weight. Lobes come in separable form (src/separable.rs): value =
// alpha_l + G(c) beta_l[i][j], with beta tabulated in f64 on the host and rounded once
// (no exp2 or pow on the GPU: (N.H)^n for n up to 1e5 is exact to f32 rounding).
//
// Two entry points share the cell factor:
// * `main` writes rows of a planar buffer (one invocation: one cell, LPI lobes);
// * `pack` fills the analytic row blocks of the packed rgba32float texture the pairwise
//   kernel reads (one invocation: one cell, BPI blocks of 4 rows, one texel fetch per
//   block; padding rows have alpha 0 and an all-zero beta table). Measured rows are
//   packed by the host.
// Every loop runs at most LPI or BPI x 4 iterations, far below lavapipe's 65,535.

// Keep in sync with `TabParams` in src/gpu/tabulate.rs.
struct TabParams {
    n_cells: u32,
    n_lobes: u32,
    weighted: u32,
    row_stride: u32,
}

// Keep in sync with `PackParams` in src/gpu/tabulate.rs.
struct PackParams {
    n_cells: u32,
    chunk: u32,
    first_block: u32,
    n_blocks: u32,
}

const LPI: u32 = 16u;
const BPI: u32 = 8u;
const NIJ: u32 = 8100u;

@group(0) @binding(0) var<uniform> p: TabParams;
// A uniform buffer (lavapipe gathers divergent uniform loads with vector code).
@group(0) @binding(1) var<uniform> tables: array<vec4<f32>, 180>;
@group(0) @binding(2) var<storage, read> alphas: array<f32>;
@group(0) @binding(3) var<storage, read> rows: array<u32>;
@group(0) @binding(4) var<storage, read> cells: array<u32>;
@group(0) @binding(5) var<storage, read> weights: array<f32>;
@group(0) @binding(6) var<storage, read_write> out: array<f32>;
@group(0) @binding(7) var<storage, read> betas: array<f32>;
@group(0) @binding(8) var<uniform> pp: PackParams;
@group(0) @binding(11) var packed: texture_storage_2d<rgba32float, write>;
// Row block b of a group (rows 4b .. 4b + 3): texel b * (NIJ + 1) + e of an rgba32float
// texture of width TEX_W holds the four rows' beta[e], texel b * (NIJ + 1) + NIJ their
// alphas. Textures, not buffers: on lavapipe a texel fetch is vector code, while a
// storage load, or a uniform load at an index it cannot prove uniform, is a per-lane loop.
@group(0) @binding(12) var beta_tex: texture_2d<f32>;

// Whether any row has a non-zero alpha (diffuse term); without, no alpha fetch.
override HAS_ALPHA: bool = true;

fn table(t: u32) -> f32 {
    return tables[t / 4u][t % 4u];
}

// value = alpha * w + beta[e] * g at one cell.
struct CellFactor {
    e: u32,
    w: f32,
    g: f32,
}

fn cell_factor(cell: u32, w: f32) -> CellFactor {
    let i = cell / 16200u;
    let j = (cell / 180u) % 90u;
    let k = cell % 180u;
    let cos_d = table(T_COS_D + j);
    let max_cos = table(T_COS_H + i) * cos_d + table(T_SIN_H + i) * table(T_SIN_D + j) * table(T_ABS_COS_P + k);
    return CellFactor(i * 90u + j, w, w / (cos_d * max_cos));
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    if (c >= p.n_cells) {
        return;
    }
    var w = 1.0;
    if (p.weighted != 0u) {
        w = weights[c];
    }
    let f = cell_factor(cells[c], w);
    let l0 = gid.y * LPI;
    for (var t = 0u; t < LPI; t = t + 1u) {
        let l = l0 + t;
        if (l >= p.n_lobes) {
            break;
        }
        out[rows[l] * p.row_stride + c] = alphas[l] * f.w + betas[l * NIJ + f.e] * f.g;
    }
}


@compute @workgroup_size(64)
fn pack(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let c = gid.x;
    if (c >= pp.n_cells) {
        return;
    }
    let f = cell_factor(cells[c], weights[c]);
    for (var t = 0u; t < BPI; t = t + 1u) {
        let b = wid.y * BPI + t;
        if (b >= pp.n_blocks) {
            break;
        }
        let base = b * (NIJ + 1u);
        var v = textureLoad(beta_tex, texel_coord(base + f.e), 0) * f.g;
        if (HAS_ALPHA) {
            v = fma(textureLoad(beta_tex, texel_coord(base + NIJ), 0), vec4<f32>(f.w), v);
        }
        textureStore(packed, texel_coord((pp.first_block + b) * pp.chunk + c), v);
    }
}
