//! FLIP's colour conversions and the branch-free powers its per-pixel rows use.

use super::{INV_WHITE, WHITE};

pub(super) fn hyab(x: [f32; 3], y: [f32; 3]) -> f32 {
    (x[0] - y[0]).abs() + ((x[1] - y[1]) * (x[1] - y[1]) + (x[2] - y[2]) * (x[2] - y[2])).sqrt()
}

/// Linear sRGB to XYZ (D65), FLIP's matrix (exact fractions of the sRGB primaries).
#[inline(always)]
pub(super) fn linear_rgb_to_xyz([r, g, b]: [f32; 3]) -> [f32; 3] {
    const M: [[f32; 3]; 3] = [
        [
            10135552.0 / 24577794.0,
            8788810.0 / 24577794.0,
            4435075.0 / 24577794.0,
        ],
        [
            2613072.0 / 12288897.0,
            8788810.0 / 12288897.0,
            887015.0 / 12288897.0,
        ],
        [
            1425312.0 / 73733382.0,
            8788810.0 / 73733382.0,
            70074185.0 / 73733382.0,
        ],
    ];
    // Written out, not `M.map`: `array::map` is not inlined into the vectorised rows.
    [
        M[0][0] * r + M[0][1] * g + M[0][2] * b,
        M[1][0] * r + M[1][1] * g + M[1][2] * b,
        M[2][0] * r + M[2][1] * g + M[2][2] * b,
    ]
}

/// XYZ to linear sRGB (D65), FLIP's matrix.
#[inline(always)]
pub(super) fn xyz_to_linear_rgb([x, y, z]: [f32; 3]) -> [f32; 3] {
    const M: [[f32; 3]; 3] = [
        [3.241_003_3, -1.537_398_9, -0.498_615_87],
        [-0.969_224_3, 1.875_930_1, 0.041_554_224],
        [0.055_639_423, -0.204_011_2, 1.057_148_9],
    ];
    [
        M[0][0] * x + M[0][1] * y + M[0][2] * z,
        M[1][0] * x + M[1][1] * y + M[1][2] * z,
        M[2][0] * x + M[2][1] * y + M[2][2] * z,
    ]
}

/// CIELAB of XYZ with libm's cube root (for the constants; the per-pixel path uses
/// [`xyz_to_lab`]).
pub(super) fn xyz_to_lab_exact(xyz: [f32; 3]) -> [f32; 3] {
    lab_from(xyz, |t| t.powf(1.0 / 3.0))
}

/// CIELAB of XYZ (D65 white), cube roots by [`pow_fast`].
#[inline(always)]
pub(super) fn xyz_to_lab(xyz: [f32; 3]) -> [f32; 3] {
    lab_from(xyz, |t| pow_fast(t, 1.0 / 3.0))
}

#[inline(always)]
pub(super) fn lab_from(xyz: [f32; 3], cbrt: impl Fn(f32) -> f32) -> [f32; 3] {
    const DELTA: f32 = 6.0 / 29.0;
    let cube = DELTA * DELTA * DELTA;
    let factor = 1.0 / (3.0 * DELTA * DELTA);
    let term = 4.0 / 29.0;
    // Both arms are evaluated, so the row vectorises: the root of a value below the knee
    // is discarded.
    let f = |i: usize| {
        let t = xyz[i] * INV_WHITE[i];
        let lin = factor * t + term;
        let root = cbrt(t.max(cube));
        if t > cube {
            root
        } else {
            lin
        }
    };
    let f = [f(0), f(1), f(2)];
    [
        116.0 * f[1] - 16.0,
        500.0 * (f[0] - f[1]),
        200.0 * (f[1] - f[2]),
    ]
}

/// `log2 x` for finite `x > 0` (subnormals included), branch-free: the mantissa reduced to
/// `[sqrt(1/2), sqrt 2)` and `log2 m = 2 / ln 2 atanh((m - 1) / (m + 1))` by its series to
/// the 9th power (truncation below 1e-9).
#[inline(always)]
pub(super) fn log2_fast(x: f32) -> f32 {
    let small = x < f32::MIN_POSITIVE;
    let xs = if small { x * 8_388_608.0 } else { x }; // 2^23
    let bits = xs.to_bits();
    let mut e = ((bits >> 23) & 0xff) as i32 - 127 - if small { 23 } else { 0 };
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    let big = m > std::f32::consts::SQRT_2;
    m = if big { 0.5 * m } else { m };
    e += i32::from(big);
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    const C1: f32 = 2.0 / std::f32::consts::LN_2;
    const C3: f32 = C1 / 3.0;
    const C5: f32 = C1 / 5.0;
    const C7: f32 = C1 / 7.0;
    const C9: f32 = C1 / 9.0;
    e as f32 + t * (C1 + t2 * (C3 + t2 * (C5 + t2 * (C7 + t2 * C9))))
}

/// `2^y`, branch-free: 0 below 2^-126, infinity from 2^128; otherwise `2^n 2^f` with `n`
/// the nearest integer and `2^f`, `|f| <= 1/2`, by its Taylor series to the 7th power
/// (truncation below 6e-9).
#[inline(always)]
pub(super) fn exp2_fast(y: f32) -> f32 {
    let yc = y.clamp(-126.0, 127.0);
    // Round to nearest by the 1.5 * 2^23 trick: the sum's low mantissa bits hold `n` (no
    // call to `round` and no float-to-int conversion, so the row vectorises).
    let shifted = yc + 12_582_912.0;
    let n = shifted - 12_582_912.0;
    let n_int = shifted.to_bits().wrapping_sub(0x4b40_0000);
    let f = yc - n;
    let u = f * std::f32::consts::LN_2;
    let p = 1.0
        + u * (1.0
            + u * (0.5
                + u * (1.0 / 6.0
                    + u * (1.0 / 24.0
                        + u * (1.0 / 120.0 + u * (1.0 / 720.0 + u * (1.0 / 5040.0)))))));
    let scale = f32::from_bits(n_int.wrapping_add(127) << 23);
    let v = p * scale;
    if y < -126.0 {
        0.0
    } else if y >= 128.0 {
        f32::INFINITY
    } else {
        v
    }
}

/// `x^y` for `x >= 0` as C's `powf` defines the edges (`0^0 = 1`, `0^y = 0` for `y > 0`,
/// infinity for `y < 0`), by `exp2(y log2 x)`.
#[inline(always)]
pub(super) fn pow_fast(x: f32, y: f32) -> f32 {
    let v = exp2_fast(y * log2_fast(x.max(f32::from_bits(1))));
    if x > 0.0 {
        v
    } else if y > 0.0 {
        0.0
    } else if y == 0.0 {
        1.0
    } else {
        f32::INFINITY
    }
}

/// Filtered YCxCz back to linear RGB, clamped, to CIELAB, Hunt-adjusted.
#[inline(always)]
pub(super) fn hunt_lab_of_ycxcz([y, cx, cz]: [f32; 3]) -> [f32; 3] {
    let yv = (y + 16.0) / 116.0;
    let xyz = [
        (yv + cx / 500.0) * WHITE[0],
        yv * WHITE[1],
        (yv - cz / 200.0) * WHITE[2],
    ];
    let [r, g, b] = xyz_to_linear_rgb(xyz);
    let rgb = [r.clamp(0.0, 1.0), g.clamp(0.0, 1.0), b.clamp(0.0, 1.0)];
    let [l, a, b] = xyz_to_lab(linear_rgb_to_xyz(rgb));
    [l, 0.01 * l * a, 0.01 * l * b]
}
