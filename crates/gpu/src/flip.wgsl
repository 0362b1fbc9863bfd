// LDR FLIP of a batch of 8-bit image pairs (flip.rs; the CPU twin is
// brdf_basis_core::eval::flip): three passes, one invocation per pixel of each image
// (ycxcz, horizontal) or of each pair (vertical_error). Every filter sums its taps in
// the twin's order from 0.0; the per-pixel maths are the twin's formulas with WGSL's
// pow. Buffers, P = width * height, image i of pair p at (2 p + i):
//   images  u32 per pixel (R | G << 8 | B << 16), [2 p + i][pixel]
//   input   f32 [2 p + i][Y, Cx, Cz, Yn][pixel]
//   horiz   f32 [2 p + i][Y, Cx, Cz1, Cz2, dg Yn, ddg Yn, g Yn][pixel]
//   map     f32 [p][pixel]
//   taps    f32: g_y, g_cx, g_cz1, g_cz2 (2 rs + 1 each), f_g, f_dg, f_ddg (2 rf + 1 each)

// Keep in sync with `FlipUniforms` in flip.rs.
struct FlipUniforms {
    width: u32,
    height: u32,
    pairs: u32,
    rs: u32,
    rf: u32,
    cmax: f32,
    pccmax: f32,
    _pad: u32,
};

@group(0) @binding(0) var<uniform> u: FlipUniforms;
@group(0) @binding(1) var<storage, read> taps: array<f32>;
@group(0) @binding(2) var<storage, read> images: array<u32>;
@group(0) @binding(3) var<storage, read_write> input: array<f32>;
@group(0) @binding(4) var<storage, read_write> horiz: array<f32>;
@group(0) @binding(5) var<storage, read_write> map: array<f32>;

const INV_WHITE = vec3<f32>(1.0521569, 1.0, 0.9183577);
const WHITE = vec3<f32>(0.9504285, 1.0, 1.0889004);

fn invocation(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.x + gid.y * groups.x * 64u;
}

fn srgb_decode(c: f32) -> f32 {
    if (c <= 0.04045) {
        return c / 12.92;
    }
    return pow((c + 0.055) / 1.055, 2.4);
}

fn linear_rgb_to_xyz(c: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        (10135552.0 / 24577794.0) * c.x + (8788810.0 / 24577794.0) * c.y + (4435075.0 / 24577794.0) * c.z,
        (2613072.0 / 12288897.0) * c.x + (8788810.0 / 12288897.0) * c.y + (887015.0 / 12288897.0) * c.z,
        (1425312.0 / 73733382.0) * c.x + (8788810.0 / 73733382.0) * c.y + (70074185.0 / 73733382.0) * c.z);
}

fn xyz_to_linear_rgb(c: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        3.2410033 * c.x + -1.5373989 * c.y + -0.49861587 * c.z,
        -0.9692243 * c.x + 1.8759301 * c.y + 0.041554224 * c.z,
        0.055639423 * c.x + -0.2040112 * c.y + 1.0571489 * c.z);
}

// x^y for x >= 0 with C's edges (0^y = 0 for y > 0, 0^0 = 1).
fn pow0(x: f32, y: f32) -> f32 {
    if (x > 0.0) {
        return pow(x, y);
    }
    return select(0.0, 1.0, y == 0.0);
}

fn lab_f(t: f32) -> f32 {
    let delta = 6.0 / 29.0;
    if (t > delta * delta * delta) {
        return pow(t, 1.0 / 3.0);
    }
    return (1.0 / (3.0 * delta * delta)) * t + 4.0 / 29.0;
}

// Filtered YCxCz to linear RGB, clamped, to CIELAB, Hunt-adjusted.
fn hunt_lab(ycxcz: vec3<f32>) -> vec3<f32> {
    let yv = (ycxcz.x + 16.0) / 116.0;
    let xyz = vec3<f32>((yv + ycxcz.y / 500.0) * WHITE.x, yv * WHITE.y, (yv - ycxcz.z / 200.0) * WHITE.z);
    let rgb = clamp(xyz_to_linear_rgb(xyz), vec3<f32>(0.0), vec3<f32>(1.0));
    let t = linear_rgb_to_xyz(rgb) * INV_WHITE;
    let f = vec3<f32>(lab_f(t.x), lab_f(t.y), lab_f(t.z));
    let l = 116.0 * f.y - 16.0;
    return vec3<f32>(l, 0.01 * l * (500.0 * (f.x - f.y)), 0.01 * l * (200.0 * (f.y - f.z)));
}

@compute @workgroup_size(64)
fn ycxcz(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let plane = u.width * u.height;
    let idx = invocation(gid, groups);
    if (idx >= 2u * u.pairs * plane) {
        return;
    }
    let img = idx / plane;
    let pix = idx % plane;
    let v = images[idx];
    let s = vec3<f32>(f32(v & 255u), f32((v >> 8u) & 255u), f32((v >> 16u) & 255u)) / 255.0;
    let lin = vec3<f32>(srgb_decode(s.x), srgb_decode(s.y), srgb_decode(s.z));
    let t = linear_rgb_to_xyz(lin) * INV_WHITE;
    let y = 116.0 * t.y - 16.0;
    let base = img * 4u * plane + pix;
    input[base] = y;
    input[base + plane] = 500.0 * (t.x - t.y);
    input[base + 2u * plane] = 200.0 * (t.y - t.z);
    input[base + 3u * plane] = y * (1.0 / 116.0) + 16.0 / 116.0;
}

@compute @workgroup_size(64)
fn horizontal(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let plane = u.width * u.height;
    let idx = invocation(gid, groups);
    if (idx >= 2u * u.pairs * plane) {
        return;
    }
    let img = idx / plane;
    let pix = idx % plane;
    let x = i32(pix % u.width);
    let row = pix - pix % u.width;
    let src = img * 4u * plane + row;
    let sw = 2u * u.rs + 1u;
    let fw = 2u * u.rf + 1u;
    var hy = 0.0;
    var hcx = 0.0;
    var hcz1 = 0.0;
    var hcz2 = 0.0;
    for (var t = 0u; t < sw; t++) {
        let xx = u32(clamp(x + i32(t) - i32(u.rs), 0, i32(u.width) - 1));
        hy += taps[t] * input[src + xx];
        hcx += taps[sw + t] * input[src + plane + xx];
        let cz = input[src + 2u * plane + xx];
        hcz1 += taps[2u * sw + t] * cz;
        hcz2 += taps[3u * sw + t] * cz;
    }
    var hdx = 0.0;
    var hddx = 0.0;
    var hg = 0.0;
    for (var t = 0u; t < fw; t++) {
        let xx = u32(clamp(x + i32(t) - i32(u.rf), 0, i32(u.width) - 1));
        let yn = input[src + 3u * plane + xx];
        hdx += taps[4u * sw + fw + t] * yn;
        hddx += taps[4u * sw + 2u * fw + t] * yn;
        hg += taps[4u * sw + t] * yn;
    }
    let out = img * 7u * plane + pix;
    horiz[out] = hy;
    horiz[out + plane] = hcx;
    horiz[out + 2u * plane] = hcz1;
    horiz[out + 3u * plane] = hcz2;
    horiz[out + 4u * plane] = hdx;
    horiz[out + 5u * plane] = hddx;
    horiz[out + 6u * plane] = hg;
}

// Hunt-adjusted CIELAB (xyz), edge and point strength (w) of image `img` at `pix`: the
// vertical pass over its horizontal planes, then the per-pixel maths.
fn perceived(img: u32, pix: u32) -> array<vec4<f32>, 2> {
    let plane = u.width * u.height;
    let x = pix % u.width;
    let y = i32(pix / u.width);
    let base = img * 7u * plane + x;
    let sw = 2u * u.rs + 1u;
    let fw = 2u * u.rf + 1u;
    var fy = 0.0;
    var fcx = 0.0;
    var fcz1 = 0.0;
    var fcz2 = 0.0;
    for (var t = 0u; t < sw; t++) {
        let yy = u32(clamp(y + i32(t) - i32(u.rs), 0, i32(u.height) - 1));
        let at = base + yy * u.width;
        fy += taps[t] * horiz[at];
        fcx += taps[sw + t] * horiz[at + plane];
        fcz1 += taps[2u * sw + t] * horiz[at + 2u * plane];
        fcz2 += taps[3u * sw + t] * horiz[at + 3u * plane];
    }
    var dx = 0.0;
    var ddx = 0.0;
    var dy = 0.0;
    var ddy = 0.0;
    for (var t = 0u; t < fw; t++) {
        let yy = u32(clamp(y + i32(t) - i32(u.rf), 0, i32(u.height) - 1));
        let at = base + yy * u.width;
        let g = taps[4u * sw + t];
        dx += g * horiz[at + 4u * plane];
        ddx += g * horiz[at + 5u * plane];
        let hg = horiz[at + 6u * plane];
        dy += taps[4u * sw + fw + t] * hg;
        ddy += taps[4u * sw + 2u * fw + t] * hg;
    }
    let lab = hunt_lab(vec3<f32>(fy, fcx, fcz1 + fcz2));
    let edge = sqrt(dx * dx + dy * dy);
    let point = sqrt(ddx * ddx + ddy * ddy);
    return array<vec4<f32>, 2>(vec4<f32>(lab, 0.0), vec4<f32>(edge, point, 0.0, 0.0));
}

@compute @workgroup_size(64)
fn vertical_error(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let plane = u.width * u.height;
    let idx = invocation(gid, groups);
    if (idx >= u.pairs * plane) {
        return;
    }
    let p = idx / plane;
    let pix = idx % plane;
    let r = perceived(2u * p, pix);
    let t = perceived(2u * p + 1u, pix);
    let d = abs(r[0].x - t[0].x) + sqrt((r[0].y - t[0].y) * (r[0].y - t[0].y) + (r[0].z - t[0].z) * (r[0].z - t[0].z));
    let c = pow0(d, 0.7);
    var colour: f32;
    if (c < u.pccmax) {
        colour = c * (0.95 / u.pccmax);
    } else {
        colour = 0.95 + ((c - u.pccmax) / (u.cmax - u.pccmax)) * (1.0 - 0.95);
    }
    let fe = max(abs(r[1].x - t[1].x), abs(r[1].y - t[1].y));
    let feature = sqrt(0.70710677 * fe);
    map[idx] = pow0(colour, 1.0 - feature);
}
