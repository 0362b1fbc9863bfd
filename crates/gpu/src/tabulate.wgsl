// Tabulation into a packed texture (read back by Backend::tabulate): texel b * chunk + c
// of an rgba32float texture (width TEX_W, see texel_coord) holds rows 4b .. 4b + 3 at cell
// c, the layout of the pairwise kernel's measured row blocks.
// Lobes come in separable form (crates/core/src/separable.rs): value = w (alpha_l + G(c) beta_l[i][j])
// with w the cell's row scale and beta tabulated in f64 on the host and rounded once (no
// exp2 or pow on the GPU: (N.H)^n for n up to 1e5 is exact to f32 rounding).
//
// One invocation: one cell, BPI blocks of 4 rows, one texel fetch of four betas per block
// (plus one of four alphas when a lobe has a diffuse term). Padding rows have alpha 0 and
// an all-zero beta table; measured rows are packed by the host. Every loop runs at most
// BPI iterations, far below lavapipe's 65,535.
//
// Tables live in textures and uniform buffers, not storage buffers: on lavapipe a texel
// fetch is vector code, while a storage load, or a uniform load at an index it cannot
// prove uniform, is a per-lane loop.

// Keep in sync with `PackParams` in tabulate.rs.
struct PackParams {
    n_cells: u32,
    chunk: u32,
    first_block: u32,
    n_blocks: u32,
}

const BPI: u32 = 8u;
const NIJ: u32 = 8100u;

@group(0) @binding(0) var<uniform> pp: PackParams;
@group(0) @binding(1) var<uniform> tables: array<vec4<f32>, T_LEN / 4u>;
@group(0) @binding(2) var<storage, read> cells: array<u32>;
@group(0) @binding(3) var<storage, read> weights: array<f32>;
@group(0) @binding(4) var packed: texture_storage_2d<rgba32float, write>;
// Row block b of a group: texel b * (NIJ + 1) + e (width TEX_W) holds the four rows'
// beta[e], texel b * (NIJ + 1) + NIJ their alphas.
@group(0) @binding(5) var beta_tex: texture_2d<f32>;

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
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
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
