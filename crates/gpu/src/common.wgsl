// Shared definitions of every brdf-basis kernel. Each kernel is compiled as
// common.wgsl + <kernel>.wgsl (see lib.rs).

// Offsets into the grid-table buffer (T_LEN f32). Keep in sync with `TABLE_*` in
// lib.rs.
const T_COS_H: u32 = 0u;
const T_SIN_H: u32 = 90u;
const T_COS_D: u32 = 180u;
const T_SIN_D: u32 = 270u;
const T_ABS_COS_P: u32 = 360u;
const T_LEN: u32 = 540u;

// Packed lobe values (pairwise/, tabulate.rs): texel k of an rgba32float texture of width
// TEX_W holds rows 4b .. 4b + 3 at cell c of a chunk, k = b * chunk + c. Keep in sync with
// `TEX_W` in lib.rs.
const TEX_W: u32 = 4096u;

fn texel_coord(k: u32) -> vec2<u32> {
    return vec2<u32>(k % TEX_W, k / TEX_W);
}
