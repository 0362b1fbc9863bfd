//! CIELAB and the CIEDE2000 colour difference (SPEC 11).
//!
//! Display values (SPEC 7's mapping, in `[0, 1]`) are taken as sRGB-encoded: decoded by the
//! sRGB transfer curve (IEC 61966-2-1), converted to CIE XYZ by the sRGB primaries (D65),
//! then to CIELAB with the D65 white of the sRGB standard (its XYZ of RGB = (1, 1, 1)).
//! [`ciede2000`] follows Sharma, Wu & Dalal (2005), "The CIEDE2000 Color-Difference
//! Formula: Implementation Notes, Supplementary Test Data, and Mathematical Observations",
//! with `k_L = k_C = k_H = 1`; the tests check it against their published pairs.

/// A CIELAB colour `(L*, a*, b*)`.
pub type Lab = [f64; 3];

/// sRGB to XYZ (D65), rows X, Y, Z (IEC 61966-2-1).
pub(crate) const SRGB_TO_XYZ: [[f64; 3]; 3] = [
    [0.4124, 0.3576, 0.1805],
    [0.2126, 0.7152, 0.0722],
    [0.0193, 0.1192, 0.9505],
];

/// The sRGB decoding curve: an encoded value in `[0, 1]` to linear.
pub(crate) fn srgb_decode(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        super::fastmath::srgb_pow().pow((v + 0.055) / 1.055)
    }
}

/// CIELAB's `f` of `t` given `t`'s cube root `root` (used above the threshold only).
#[inline]
fn lab_f_of(t: f64, root: f64) -> f64 {
    const D: f64 = 6.0 / 29.0;
    if t > D * D * D {
        root
    } else {
        t / (3.0 * D * D) + 4.0 / 29.0
    }
}

fn lab_f(t: f64) -> f64 {
    lab_f_of(t, super::fastmath::cube_root().pow(t))
}

/// The ratios `X / X_n`, `Y / Y_n`, `Z / Z_n` of linear sRGB `lin`.
#[inline]
fn white_ratios(lin: [f64; 3]) -> [f64; 3] {
    let xyz = SRGB_TO_XYZ.map(|row| row[0] * lin[0] + row[1] * lin[1] + row[2] * lin[2]);
    let white = SRGB_TO_XYZ.map(|row| row[0] + row[1] + row[2]);
    [0, 1, 2].map(|i| xyz[i] / white[i])
}

/// CIELAB from CIELAB's `f` of the three white ratios.
#[inline]
fn lab_of(f: [f64; 3]) -> Lab {
    [
        116.0 * f[1] - 16.0,
        500.0 * (f[0] - f[1]),
        200.0 * (f[1] - f[2]),
    ]
}

/// CIELAB (D65 white: the XYZ of sRGB white) of an sRGB-encoded colour in `[0, 1]^3`.
pub fn srgb_to_lab(rgb: [f64; 3]) -> Lab {
    let lin = rgb.map(|v| srgb_decode(v.clamp(0.0, 1.0)));
    lab_of(white_ratios(lin).map(lab_f))
}

/// `srgb_decode(v.clamp(0, 1))` of every value (the same bits), the powers four at a time.
pub(crate) fn srgb_decode_all(rgb: &[f64]) -> Vec<f64> {
    let v: Vec<f64> = rgb.iter().map(|v| v.clamp(0.0, 1.0)).collect();
    let z: Vec<f64> = v.iter().map(|&v| (v + 0.055) / 1.055).collect();
    let mut p = vec![0.0; z.len()];
    super::fastmath::srgb_pow().pow_slice(&z, &mut p);
    // `srgb_decode`'s branches.
    v.iter()
        .zip(&p)
        .map(|(&v, &p)| if v <= 0.04045 { v / 12.92 } else { p })
        .collect()
}

/// [`srgb_to_lab`] of every colour of `rgb` (interleaved, three values a colour): the same
/// bits, the powers four at a time.
pub fn srgb_to_lab_all(rgb: &[f64]) -> Vec<Lab> {
    assert_eq!(rgb.len() % 3, 0, "three values a colour");
    lab_from_linear_all(&srgb_decode_all(rgb))
}

/// CIELAB of decoded colours ([`srgb_decode_all`] of `rgb`): [`srgb_to_lab_all`] given
/// the linear values, so that ICtCp can share the decoding.
pub(crate) fn lab_from_linear_all(lin: &[f64]) -> Vec<Lab> {
    let mut t = Vec::with_capacity(lin.len());
    for l in lin.chunks_exact(3) {
        t.extend_from_slice(&white_ratios([l[0], l[1], l[2]]));
    }
    let mut root = vec![0.0; t.len()];
    super::fastmath::cube_root().pow_slice(&t, &mut root);
    t.chunks_exact(3)
        .zip(root.chunks_exact(3))
        .map(|(t, r)| lab_of([0, 1, 2].map(|i| lab_f_of(t[i], r[i]))))
        .collect()
}

/// `25^7`, CIEDE2000's chroma constant.
const POW25_7: f64 = 6_103_515_625.0;

/// `x^7` as `x (x^2) (x^2)^2`: the multiplications, in their order, of the `powi(7)` that
/// the textbook form uses.
#[inline(always)]
fn pow7(x: f64) -> f64 {
    let x2 = x * x;
    (x * x2) * (x2 * x2)
}

/// The CIEDE2000 colour difference of two CIELAB colours (`k_L = k_C = k_H = 1`).
///
/// Rewrites of the textbook form for speed, each exact in exact arithmetic and within
/// rounding of it in f64 (the unit tests hold it to the textbook form, kept there, to
/// 1e-13, and to Sharma et al.'s pairs):
/// * the chromas are `sqrt(a^2 + b^2)` (CIELAB components are far from overflow) instead
///   of `hypot`;
/// * the hue difference and the mean hue come from the hue vectors `(a', b')` instead of
///   one `atan2` per colour: with `p = C1' C2'`, `d = p cos(dh)` (the dot product) and
///   `x = p sin(dh)` (the cross product), `dH = 2 sqrt(p) sin(dh / 2) = sqrt(2) x /
///   sqrt(p + d)` (or `sign(x) sqrt(2 (p - d))` past a right angle, where `p + d` cancels);
///   the mean hue is the direction of the bisector of the two unit hue vectors (their sum,
///   or their difference turned a right angle past a right angle): the textbook's rules
///   for the mean of two angles, the `+-360` branches included;
/// * `T`'s four cosines come from the bisector's cosine and sine by the multiple-angle and
///   angle-sum identities.
///
/// What is left of the transcendental functions: one `atan2` (the mean hue in degrees, for
/// `d theta`'s Gaussian), one `exp` and one `sin` (the textbook: two `atan2`, four `cos`,
/// two `sin`, one `exp`), each the project's own (`fastmath::atan2`,
/// `fastmath::exp_normal`, `fastmath::sin_small`: within 1 or 2 ulp of
/// the C library's, branch-free), so that [`ciede2000_slice`] vectorises and gives this
/// function's bits. A neutral colour (`C1' C2' = 0`) takes the textbook's hue rules, with
/// the C library's `atan2` and `sin_cos`.
pub fn ciede2000(x: Lab, y: Lab) -> f64 {
    let d = ciede2000_hued(x, y);
    if d.is_nan() {
        ciede2000_neutral(x, y)
    } else {
        d
    }
}

/// [`ciede2000`] of every pair `(x[i], y[i])` into `out[i]` (the same bits), four pairs at a
/// time where the processor has AVX2. Callers sum `out` in their own order.
pub fn ciede2000_slice(x: &[Lab], y: &[Lab], out: &mut [f64]) {
    assert!(x.len() == y.len() && x.len() == out.len());
    super::fastmath::dispatch!(ciede2000_slice_portable, ciede2000_slice_avx2, x, y, out);
    // Neutral colours (and NaN inputs) by the scalar form.
    for ((o, &a), &b) in out.iter_mut().zip(x).zip(y) {
        if o.is_nan() {
            *o = ciede2000_neutral(a, b);
        }
    }
}

/// Pairs per block of [`ciede2000_slice_body`]: its six columns on the stack.
const BLOCK: usize = 64;

#[inline(always)]
fn ciede2000_slice_body(x: &[Lab], y: &[Lab], out: &mut [f64]) {
    let mut cols = [[0.0; BLOCK]; 6];
    for ((x, y), out) in x
        .chunks(BLOCK)
        .zip(y.chunks(BLOCK))
        .zip(out.chunks_mut(BLOCK))
    {
        // The colours as columns, so that the loop below loads whole vectors.
        let n = out.len();
        for (i, (a, b)) in x.iter().zip(y).enumerate() {
            for c in 0..3 {
                cols[c][i] = a[c];
                cols[3 + c][i] = b[c];
            }
        }
        let [l1, a1, b1, l2, a2, b2] = &cols;
        let (l1, a1, b1) = (&l1[..n], &a1[..n], &b1[..n]);
        let (l2, a2, b2) = (&l2[..n], &a2[..n], &b2[..n]);
        for i in 0..n {
            out[i] = ciede2000_hued([l1[i], a1[i], b1[i]], [l2[i], a2[i], b2[i]]);
        }
    }
}

fn ciede2000_slice_portable(x: &[Lab], y: &[Lab], out: &mut [f64]) {
    ciede2000_slice_body(x, y, out)
}

/// # Safety
/// The processor must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn ciede2000_slice_avx2(x: &[Lab], y: &[Lab], out: &mut [f64]) {
    ciede2000_slice_body(x, y, out)
}

/// [`ciede2000`] where `C1' C2' > 0`, NaN where it is 0 (a neutral colour) or an input is
/// NaN: straight-line code, every branch of the textbook a select.
#[inline(always)]
fn ciede2000_hued(x: Lab, y: Lab) -> f64 {
    use super::fastmath::atan2;
    use std::f64::consts::{PI, SQRT_2};
    let deg = PI / 180.0;
    let [l1, a1, b1] = x;
    let [l2, a2, b2] = y;
    let c1 = (a1 * a1 + b1 * b1).sqrt();
    let c2 = (a2 * a2 + b2 * b2).sqrt();
    let c_mean = 0.5 * (c1 + c2);
    let c7 = pow7(c_mean);
    let g = 0.5 * (1.0 - (c7 / (c7 + POW25_7)).sqrt());
    let (a1p, a2p) = ((1.0 + g) * a1, (1.0 + g) * a2);
    let (c1p, c2p) = ((a1p * a1p + b1 * b1).sqrt(), (a2p * a2p + b2 * b2).sqrt());
    let p = c1p * c2p;
    let dot = a1p * a2p + b1 * b2;
    let cross = a1p * b2 - b1 * a2p;
    let (u1, u2) = ([a1p / c1p, b1 / c1p], [a2p / c2p, b2 / c2p]);
    let near = dot >= 0.0;
    // Within a right angle: the bisector is the sum of the unit hue vectors. Past it: the
    // chord turned a right angle, towards the side the hue turns (the sign of the cross
    // product; +0 at exactly 180 degrees with the textbook's sign of h2' - h1').
    let dh_big = if near {
        SQRT_2 * cross / (p + dot).sqrt()
    } else {
        (2.0 * (p - dot)).sqrt().copysign(cross)
    };
    let (d0, d1) = (u2[0] - u1[0], u2[1] - u1[1]);
    let turned = if cross.is_sign_negative() {
        [-d1, d0]
    } else {
        [d1, -d0]
    };
    let v = if near {
        [u1[0] + u2[0], u1[1] + u2[1]]
    } else {
        turned
    };
    let r = (v[0] * v[0] + v[1] * v[1]).sqrt();
    let h = atan2(v[1], v[0]) / deg;
    let hp_mean = if h < 0.0 { h + 360.0 } else { h };
    let t = hue_weight(v[0] / r, v[1] / r);
    let d = ciede2000_rest([l1, l2], [c1p, c2p], dh_big, hp_mean, t);
    if p == 0.0 {
        f64::NAN
    } else {
        d
    }
}

/// [`ciede2000`] by the textbook's rules for the hues (any pair; meant for a neutral
/// colour, `C1' C2' = 0`: no hue difference, and the mean hue the sum of the hues, the
/// neutral one's 0).
#[cold]
fn ciede2000_neutral(x: Lab, y: Lab) -> f64 {
    use std::f64::consts::PI;
    let deg = PI / 180.0;
    let [l1, a1, b1] = x;
    let [l2, a2, b2] = y;
    let c1 = (a1 * a1 + b1 * b1).sqrt();
    let c2 = (a2 * a2 + b2 * b2).sqrt();
    let c_mean = 0.5 * (c1 + c2);
    let c7 = pow7(c_mean);
    let g = 0.5 * (1.0 - (c7 / (c7 + POW25_7)).sqrt());
    let (a1p, a2p) = ((1.0 + g) * a1, (1.0 + g) * a2);
    let (c1p, c2p) = ((a1p * a1p + b1 * b1).sqrt(), (a2p * a2p + b2 * b2).sqrt());
    let hue = |b: f64, a: f64| {
        if a == 0.0 && b == 0.0 {
            0.0
        } else {
            let h = b.atan2(a) / deg;
            if h < 0.0 {
                h + 360.0
            } else {
                h
            }
        }
    };
    let hp_mean = hue(b1, a1p) + hue(b2, a2p);
    let (s, c) = (hp_mean * deg).sin_cos();
    ciede2000_rest([l1, l2], [c1p, c2p], 0.0, hp_mean, hue_weight(c, s))
}

/// CIEDE2000 from the lightnesses, the chromas `C'`, the hue difference `dH`, the mean
/// hue (degrees) and `T`.
#[inline(always)]
fn ciede2000_rest(
    [l1, l2]: [f64; 2],
    [c1p, c2p]: [f64; 2],
    dh_big: f64,
    hp_mean: f64,
    t: f64,
) -> f64 {
    use super::fastmath::{exp_normal, sin_small};
    let deg = std::f64::consts::PI / 180.0;
    let dl = l2 - l1;
    let dc = c2p - c1p;
    let l_mean = 0.5 * (l1 + l2);
    let cp_mean = 0.5 * (c1p + c2p);
    // hp_mean in [0, 720): the exponent in [-317, 0], exp_normal's domain.
    let q = (hp_mean - 275.0) / 25.0;
    let d_theta = 30.0 * exp_normal(-(q * q));
    let cp7 = pow7(cp_mean);
    let rc = 2.0 * (cp7 / (cp7 + POW25_7)).sqrt();
    let l50 = (l_mean - 50.0) * (l_mean - 50.0);
    let sl = 1.0 + 0.015 * l50 / (20.0 + l50).sqrt();
    let sc = 1.0 + 0.045 * cp_mean;
    let sh = 1.0 + 0.015 * cp_mean * t;
    // 2 d_theta in [0, 60] degrees: sin_small's domain.
    let rt = -sin_small(2.0 * d_theta * deg) * rc;
    let (tl, tc, th) = (dl / sl, dc / sc, dh_big / sh);
    (tl * tl + tc * tc + th * th + rt * tc * th).sqrt()
}

/// CIEDE2000's `T` at the mean hue `h` given by its cosine `c1` and sine `s1`:
/// `1 - 0.17 cos(h - 30) + 0.24 cos(2h) + 0.32 cos(3h + 6) - 0.20 cos(4h - 63)` (degrees in
/// the shifts), by the multiple-angle and angle-sum identities.
fn hue_weight(c1: f64, s1: f64) -> f64 {
    // cos and sin of the shifts 30, 6 and 63 degrees.
    const C30: f64 = 0.866_025_403_784_438_6;
    const S30: f64 = 0.5;
    const C6: f64 = 0.994_521_895_368_273_3;
    const S6: f64 = 0.104_528_463_267_653_47;
    const C63: f64 = 0.453_990_499_739_546_8;
    const S63: f64 = 0.891_006_524_188_367_9;
    let (c2, s2) = (c1 * c1 - s1 * s1, 2.0 * s1 * c1);
    let (c3, s3) = (c2 * c1 - s2 * s1, s2 * c1 + c2 * s1);
    let (c4, s4) = (c2 * c2 - s2 * s2, 2.0 * s2 * c2);
    1.0 - 0.17 * (c1 * C30 + s1 * S30) + 0.24 * c2 + 0.32 * (c3 * C6 - s3 * S6)
        - 0.20 * (c4 * C63 + s4 * S63)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The textbook form (`hypot`, four cosines), as first written: the oracle of the
    /// rewritten [`ciede2000`].
    fn ciede2000_textbook(x: Lab, y: Lab) -> f64 {
        use std::f64::consts::PI;
        let deg = PI / 180.0;
        let [l1, a1, b1] = x;
        let [l2, a2, b2] = y;
        let c1 = a1.hypot(b1);
        let c2 = a2.hypot(b2);
        let c_mean = 0.5 * (c1 + c2);
        let c7 = c_mean.powi(7);
        let g = 0.5 * (1.0 - (c7 / (c7 + 25f64.powi(7))).sqrt());
        let (a1p, a2p) = ((1.0 + g) * a1, (1.0 + g) * a2);
        let (c1p, c2p) = (a1p.hypot(b1), a2p.hypot(b2));
        let hue = |b: f64, a: f64| {
            if a == 0.0 && b == 0.0 {
                0.0
            } else {
                let h = b.atan2(a) / deg;
                if h < 0.0 {
                    h + 360.0
                } else {
                    h
                }
            }
        };
        let (h1p, h2p) = (hue(b1, a1p), hue(b2, a2p));
        let dl = l2 - l1;
        let dc = c2p - c1p;
        let dh = if c1p * c2p == 0.0 {
            0.0
        } else {
            let d = h2p - h1p;
            if d > 180.0 {
                d - 360.0
            } else if d < -180.0 {
                d + 360.0
            } else {
                d
            }
        };
        let dh_big = 2.0 * (c1p * c2p).sqrt() * (0.5 * dh * deg).sin();
        let l_mean = 0.5 * (l1 + l2);
        let cp_mean = 0.5 * (c1p + c2p);
        let hp_mean = if c1p * c2p == 0.0 {
            h1p + h2p
        } else if (h1p - h2p).abs() <= 180.0 {
            0.5 * (h1p + h2p)
        } else if h1p + h2p < 360.0 {
            0.5 * (h1p + h2p + 360.0)
        } else {
            0.5 * (h1p + h2p - 360.0)
        };
        let t = 1.0 - 0.17 * ((hp_mean - 30.0) * deg).cos()
            + 0.24 * (2.0 * hp_mean * deg).cos()
            + 0.32 * ((3.0 * hp_mean + 6.0) * deg).cos()
            - 0.20 * ((4.0 * hp_mean - 63.0) * deg).cos();
        let d_theta = 30.0 * (-((hp_mean - 275.0) / 25.0).powi(2)).exp();
        let cp7 = cp_mean.powi(7);
        let rc = 2.0 * (cp7 / (cp7 + 25f64.powi(7))).sqrt();
        let l50 = (l_mean - 50.0) * (l_mean - 50.0);
        let sl = 1.0 + 0.015 * l50 / (20.0 + l50).sqrt();
        let sc = 1.0 + 0.045 * cp_mean;
        let sh = 1.0 + 0.015 * cp_mean * t;
        let rt = -(2.0 * d_theta * deg).sin() * rc;
        let (tl, tc, th) = (dl / sl, dc / sc, dh_big / sh);
        (tl * tl + tc * tc + th * th + rt * tc * th).sqrt()
    }

    #[test]
    fn ciede2000_is_the_textbook_form_within_rounding() {
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut next = |lo: f64, hi: f64| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            lo + (hi - lo) * ((s >> 11) as f64 / (1u64 << 53) as f64)
        };
        let mut worst = 0f64;
        for i in 0..200_000 {
            let x = [next(0.0, 100.0), next(-128.0, 128.0), next(-128.0, 128.0)];
            // Near pairs (the renders' case), far pairs, and neutral ones.
            let y = match i % 3 {
                0 => [
                    x[0] + next(-2.0, 2.0),
                    x[1] + next(-2.0, 2.0),
                    x[2] + next(-2.0, 2.0),
                ],
                1 => [next(0.0, 100.0), next(-128.0, 128.0), next(-128.0, 128.0)],
                _ => [next(0.0, 100.0), next(-1e-3, 1e-3), 0.0],
            };
            let (got, want) = (ciede2000(x, y), ciede2000_textbook(x, y));
            worst = worst.max((got - want).abs() / want.max(1e-3));
        }
        // The textbook form in f64 is itself only this close to the exact value: its hue
        // difference is a difference of two rounded angles (near pairs lose digits there);
        // the exact values of the worst pairs are checked below.
        assert!(worst < 1e-12, "{worst:e}");
        for h in [0.0, 30.0, 63.0, 90.0, 180.0, 275.0, 359.9] {
            let d = std::f64::consts::PI / 180.0;
            let t = 1.0 - 0.17 * ((h - 30.0) * d).cos()
                + 0.24 * (2.0 * h * d).cos()
                + 0.32 * ((3.0 * h + 6.0) * d).cos()
                - 0.20 * ((4.0 * h - 63.0) * d).cos();
            let (sn, cs) = (h * d).sin_cos();
            assert!((hue_weight(cs, sn) - t).abs() < 1e-15, "{h}");
        }
    }

    /// Hard pairs against their exact CIEDE2000 (the textbook's formula evaluated with 50
    /// significant digits by mpmath 1.3): the twelve near pairs of the test above where the
    /// f64 textbook form strays most from this one (the textbook form itself is off the
    /// exact value by up to 2.2e-13 relative on them, this one by at most 2.1e-14), and six
    /// pairs with hue differences within 1e-9 to 0.05 rad of 180 degrees (the second branch
    /// of the hue difference and of the bisector). Within 5e-14 relative.
    #[test]
    #[allow(clippy::excessive_precision)] // the exact values, to 20 digits
    fn ciede2000_matches_the_exact_value_of_hard_pairs() {
        let pairs: [(Lab, Lab, f64); 18] = [
            (
                [87.97688744694526, 76.49366481320453, -99.8523008795143],
                [87.5016100872779, 76.74626350353635, -101.72724073507709],
                0.61590935422878915257,
            ),
            (
                [80.85860808184428, 79.88556202533243, -69.95070638751852],
                [80.89549794536357, 78.93124322404242, -69.4534650262267],
                0.20519733730522673929,
            ),
            (
                [20.897961533293596, -105.59022634494451, -42.373866776417174],
                [20.8719142259224, -107.42253424322371, -42.39714142384148],
                0.36306177515627521003,
            ),
            (
                [5.40674933379014, 109.12040559999883, -85.64178415666402],
                [5.3429362283775585, 109.64987231606355, -85.37411846771529],
                0.17431887580856468732,
            ),
            (
                [13.472757512471034, 119.25657548062009, -0.18166211686391875],
                [13.356115184964361, 119.07193823668996, -1.0907430886294094],
                0.28194415829953358387,
            ),
            (
                [23.402725233244702, 123.33132608544057, -89.44573830596289],
                [22.947299960041512, 122.24926160175981, -89.7823105525808],
                0.4228574035751562037,
            ),
            (
                [34.41636615599437, 83.10667893433734, -113.56322473772133],
                [34.68866934561746, 83.37142197546899, -112.02523451980286],
                0.59428444872524779318,
            ),
            (
                [96.18720781507139, 48.07947059157041, -99.96777726660181],
                [95.86108570355388, 47.1898152095781, -98.12814747734906],
                0.39313142115936162532,
            ),
            (
                [15.853527050179572, 119.50956913188156, -126.20232370291674],
                [15.798021073095127, 121.36801488622605, -127.7049347171417],
                0.27859898350646565681,
            ),
            (
                [52.787637759975134, -121.05617366357643, -104.82470522894437],
                [52.6888266117791, -122.45851044381835, -105.13209455091197],
                0.2382115746760983081,
            ),
            (
                [49.768784988039236, 81.62129804783063, -123.71933946790696],
                [49.45260905741564, 81.38615067184654, -122.88792814101967],
                0.36547949227141286786,
            ),
            (
                [45.11281268955681, 49.13593524083004, -110.97764521542268],
                [45.1942479143911, 48.63576283683961, -110.9726759498712],
                0.26592050121526721058,
            ),
            (
                [57.374101693382116, 12.824314669760565, -43.96612113991602],
                [57.67816508689039, -14.106746088373836, 48.36273326801439],
                55.345480408266292879,
            ),
            (
                [51.80239127382869, 8.309713075421548, -50.540574294137436],
                [52.10034038010254, -9.140628788327446, 55.59464086420777],
                55.683997538202866271,
            ),
            (
                [74.05402950503736, -11.01479713961357, 2.1690287209631998],
                [73.8155453391269, 12.116274467637277, -2.3859437093351787],
                27.134364466394175953,
            ),
            (
                [26.118464130434923, -2.209756630999141, -18.58226114330135],
                [25.677428862457145, 2.4102905948821216, 20.442907769277685],
                29.839500190641870699,
            ),
            (
                [74.98072230851312, 25.345448524847516, 39.716772602643694],
                [74.25825714531094, -27.92366787991823, -43.6605480299543],
                48.802568735739273987,
            ),
            (
                [57.047151227967, 11.967713628936771, 0.1334630027837446],
                [56.46606399295724, -13.164625218867094, -0.13364474685972602],
                31.236477967489348701,
            ),
        ];
        for (x, y, want) in pairs {
            let got = ciede2000(x, y);
            assert!(
                (got - want).abs() / want < 5e-14,
                "{x:?} {y:?}: {got:e} vs {want:e}"
            );
        }
    }

    /// Pairs and differences published by Sharma, Wu & Dalal (2005), table 1 (to 4 places):
    /// chroma, hue, the arctangent and hue-mean branches, the rotation term, and the
    /// near-black pair.
    #[test]
    fn ciede2000_matches_the_published_test_pairs() {
        let pairs: [(Lab, Lab, f64); 16] = [
            ([50.0, 2.6772, -79.7751], [50.0, 0.0, -82.7485], 2.0425),
            ([50.0, 3.1571, -77.2803], [50.0, 0.0, -82.7485], 2.8615),
            ([50.0, 2.8361, -74.0200], [50.0, 0.0, -82.7485], 3.4412),
            ([50.0, -1.3802, -84.2814], [50.0, 0.0, -82.7485], 1.0000),
            ([50.0, -1.1848, -84.8006], [50.0, 0.0, -82.7485], 1.0000),
            ([50.0, -0.9009, -85.5211], [50.0, 0.0, -82.7485], 1.0000),
            ([50.0, 0.0, 0.0], [50.0, -1.0, 2.0], 2.3669),
            ([50.0, -1.0, 2.0], [50.0, 0.0, 0.0], 2.3669),
            ([50.0, 2.49, -0.001], [50.0, -2.49, 0.0009], 7.1792),
            ([50.0, 2.49, -0.001], [50.0, -2.49, 0.0011], 7.2195),
            ([50.0, 2.5, 0.0], [50.0, 0.0, -2.5], 4.3065),
            ([50.0, 2.5, 0.0], [73.0, 25.0, -18.0], 27.1492),
            (
                [60.2574, -34.0099, 36.2677],
                [60.4626, -34.1751, 39.4387],
                1.2644,
            ),
            (
                [2.0776, 0.0795, -1.1350],
                [0.9033, -0.0636, -0.5514],
                0.9082,
            ),
            ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 0.0),
            ([100.0, 0.005, -0.01], [0.0, 0.0, 0.0], 100.0),
        ];
        for (a, b, want) in pairs {
            let got = ciede2000(a, b);
            assert!((got - want).abs() < 5e-5, "{a:?} {b:?}: {got} vs {want}");
            assert!((ciede2000(b, a) - got).abs() < 1e-12);
        }
    }

    /// The batch form gives the scalar form's bits on near, far, neutral, opposite-hue and
    /// NaN pairs, in runs of every length (the vector loop's tails and blocks).
    #[test]
    fn ciede2000_slice_gives_the_scalar_bits() {
        let mut s = 0x0bad_5eed_1234_5678u64;
        let mut next = |lo: f64, hi: f64| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            lo + (hi - lo) * ((s >> 11) as f64 / (1u64 << 53) as f64)
        };
        let (mut xs, mut ys) = (Vec::new(), Vec::new());
        for i in 0..5_000 {
            let x = [next(0.0, 100.0), next(-128.0, 128.0), next(-128.0, 128.0)];
            let y = match i % 7 {
                0..=2 => [
                    x[0] + next(-2.0, 2.0),
                    x[1] + next(-2.0, 2.0),
                    x[2] + next(-2.0, 2.0),
                ],
                3 => [next(0.0, 100.0), next(-128.0, 128.0), next(-128.0, 128.0)],
                // Opposite hues (the bisector's second branch), exactly and nearly.
                4 => [x[0], -x[1], -x[2] * (1.0 + next(-1e-9, 1e-9))],
                5 => [next(0.0, 100.0), 0.0, 0.0],
                _ => [x[0], x[1] * 1e-170, x[2] * 1e-170],
            };
            xs.push(x);
            ys.push(y);
        }
        xs.extend([
            [50.0, 0.0, 0.0],
            [f64::NAN, 1.0, 1.0],
            [50.0, 2.5, 0.0],
            [0.0; 3],
        ]);
        ys.extend([
            [50.0, -1.0, 2.0],
            [50.0, 1.0, 1.0],
            [50.0, -2.5, 0.0],
            [0.0; 3],
        ]);
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        for n in [0, 1, 3, 4, 5, 63, 64, 65, 130, xs.len()] {
            for k in [0, xs.len() - n] {
                let (x, y) = (&xs[k..k + n], &ys[k..k + n]);
                let mut out = vec![0.0; n];
                ciede2000_slice(x, y, &mut out);
                for ((&o, &a), &b) in out.iter().zip(x).zip(y) {
                    let want = ciede2000(a, b);
                    assert!(same(o, want), "{a:?} {b:?}: {o:e} vs {want:e}");
                }
            }
        }
    }

    /// Pixels per second of [`ciede2000`] one pair at a time and of [`ciede2000_slice`], on
    /// a render's kind of pairs (near colours): `cargo test --release -p brdf-basis-core
    /// --lib ciede2000_rate -- --ignored --nocapture`. Prints; asserts nothing of time.
    #[test]
    #[ignore]
    fn ciede2000_rate() {
        let mut s = 0x1357_9bdf_2468_ace0u64;
        let mut next = |lo: f64, hi: f64| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            lo + (hi - lo) * ((s >> 11) as f64 / (1u64 << 53) as f64)
        };
        let n = 1 << 16;
        let xs: Vec<Lab> = (0..n)
            .map(|_| [next(0.0, 100.0), next(-80.0, 80.0), next(-80.0, 80.0)])
            .collect();
        let ys: Vec<Lab> = xs
            .iter()
            .map(|x| {
                [
                    x[0] + next(-1.0, 1.0),
                    x[1] + next(-1.0, 1.0),
                    x[2] + next(-1.0, 1.0),
                ]
            })
            .collect();
        let mut out = vec![0.0; n];
        let time = |f: &mut dyn FnMut()| {
            let mut best = f64::INFINITY;
            for _ in 0..20 {
                let t = std::time::Instant::now();
                f();
                best = best.min(t.elapsed().as_secs_f64());
            }
            best
        };
        let scalar = time(&mut || {
            for ((o, &a), &b) in out.iter_mut().zip(&xs).zip(&ys) {
                *o = std::hint::black_box(ciede2000(a, b));
            }
        });
        let batch = time(&mut || ciede2000_slice(&xs, &ys, std::hint::black_box(&mut out)));
        eprintln!(
            "CIEDE2000, best of 20 runs of {n} near pairs: scalar {:.1} M pixels/s ({:.1} ns), \
             batch {:.1} M pixels/s ({:.1} ns), {:.2}x",
            n as f64 / scalar / 1e6,
            scalar / n as f64 * 1e9,
            n as f64 / batch / 1e6,
            batch / n as f64 * 1e9,
            scalar / batch
        );
    }

    #[test]
    fn srgb_white_grey_and_black_have_their_lab() {
        let w = srgb_to_lab([1.0; 3]);
        assert!((w[0] - 100.0).abs() < 1e-9 && w[1].abs() < 1e-9 && w[2].abs() < 1e-9);
        assert_eq!(srgb_to_lab([0.0; 3]), [0.0, 0.0, 0.0]);
        // sRGB 0.5 decodes to 0.21404; L* = 116 * 0.21404^(1/3) - 16 = 53.389.
        let g = srgb_to_lab([0.5; 3]);
        assert!((g[0] - 53.389).abs() < 1e-3, "{g:?}");
        // Pure sRGB red: L* 53.24, a* 80.09, b* 67.20 (the standard's values, to 0.05).
        let r = srgb_to_lab([1.0, 0.0, 0.0]);
        assert!(
            (r[0] - 53.24).abs() < 0.05 && (r[1] - 80.09).abs() < 0.1,
            "{r:?}"
        );
    }

    /// The batch form gives [`srgb_to_lab`]'s bits, both branches of the decoding and of
    /// CIELAB's `f` included, and out-of-range values clamped alike.
    #[test]
    fn srgb_to_lab_all_is_srgb_to_lab_of_each() {
        let mut s = 0x1234_5678_9abc_def1u64;
        let mut rgb: Vec<f64> = (0..30_000)
            .map(|i| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                let r = (s >> 11) as f64 / (1u64 << 53) as f64;
                match i % 4 {
                    0 => r * 0.05,
                    1 => r.powi(6),
                    _ => r,
                }
            })
            .collect();
        rgb.extend([0.0, 1.0, 0.04045, -0.5, 2.0, f64::NAN, 0.0, 0.0, 1e-12]);
        let all = srgb_to_lab_all(&rgb);
        for (c, lab) in rgb.chunks_exact(3).zip(&all) {
            let one = srgb_to_lab([c[0], c[1], c[2]]);
            for i in 0..3 {
                assert!(
                    lab[i].to_bits() == one[i].to_bits() || (lab[i].is_nan() && one[i].is_nan()),
                    "{c:?}: {lab:?} vs {one:?}"
                );
            }
        }
    }
}
