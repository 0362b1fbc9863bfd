//! Table-driven f64 powers and `log1p` for the per-pixel scoring (issue 48, item 3).
//!
//! The scoring of one render calls a power four times per channel and pixel (the display
//! mapping `v^(1/2.2)`, the sRGB decoding `z^2.4`, CIELAB's cube root) and the log-RMSE a
//! `log1p` per cell and channel of every fit. The C library's `pow` (13 ns a call on the
//! project's 2-core machine) and `log1p` are correctly rounded in nearly every case and
//! general; these are neither, and four to five times faster, scalar, without a branch on
//! the common path:
//!
//! * `x^y` for a fixed `y` ([`FixedPow`]) splits `x = 2^e m`, `m` in `[1, 2)`, and `m` at the
//!   nearest of 257 table points `c_j = 1 + j / 256` as `m = c_j (1 + t)`, `|t| <= 1/512`:
//!   `x^y = (2^e)^y c_j^y (1 + t)^y`, the first two factors from tables the C library fills
//!   once per process (correctly rounded in nearly every case), the last by its binomial
//!   series to `t^6` (truncation below 1e-18 relative).
//! * `log1p(u)` for `u >= 0` ([`ln_1p`]): `w = 1 + u` rounded, `log(w) = e ln 2 + ln c_j +
//!   log(1 + t)` (the series to `t^7`), plus the rounding's correction `(u - (w - 1)) / w`.
//! * CIEDE2000's `atan2`, `exp` and `sin` ([`atan2`], [`exp_normal`], [`sin_small`]):
//!   fdlibm's `atan` reduction and polynomial with the quadrants by selects, `exp` by a
//!   table of `2^(j/64)` and a series to `r^6`, `sin` on `[0, pi/3]` by its Taylor series;
//!   branch-free on their domains, so that a loop over them vectorises (`color`'s
//!   `ciede2000_slice`), each within 2 ulp of the C library's.
//!
//! The first two are within 3 units in the last place of the correctly rounded value on
//! every input (the unit tests measure the largest difference from the C library over
//! millions of inputs, each kind of input included). Plain multiplies and adds (no fused
//! multiply-add), so the same bits on every x86-64 processor; inputs off the fast path
//! (zero, subnormal, infinite, NaN, negative, or too large) go to the C library.

use std::sync::OnceLock;

/// Picks the AVX2 build of a loop where the processor has it, else the portable build: the
/// same operations in the same order (no fused multiply-add), so the same bits.
macro_rules! dispatch {
    ($portable:ident, $avx2:ident, $($arg:expr),*) => {{
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the processor supports AVX2 (checked above).
                unsafe { $avx2($($arg),*) }
            } else {
                $portable($($arg),*)
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            $portable($($arg),*)
        }
    }};
}

pub(crate) use dispatch;

/// Table points per octave of the mantissa.
const POINTS: usize = 256;

/// `x^y` for one fixed exponent `y` (module docs).
pub(crate) struct FixedPow {
    y: f64,
    /// Per table point `j` (257 of them; the rest pads the table to a power of two, so
    /// that a masked index needs no bounds check and the loops vectorise): `c_j^y`.
    mant_pow: Box<[f64; 512]>,
    /// `1 / c_j`, padded likewise.
    mant_inv: Box<[f64; 512]>,
    /// `(2^e)^y` for `e` in `-1022..=1023`, at index `e + 1022`.
    scale: Box<[f64; 2048]>,
    /// The binomial coefficients `C(y, k)`, `k = 1..=6`.
    coef: [f64; 6],
}

impl FixedPow {
    /// The tables of `x^y`.
    pub(crate) fn new(y: f64) -> Self {
        assert!(
            y > 0.0 && y.is_finite(),
            "FixedPow takes a positive finite exponent"
        );
        let (mut mant_pow, mut mant_inv) = (Box::new([0.0; 512]), Box::new([0.0; 512]));
        for j in 0..=POINTS {
            let c = 1.0 + j as f64 / POINTS as f64;
            (mant_pow[j], mant_inv[j]) = (c.powf(y), 1.0 / c);
        }
        let mut scale = Box::new([0.0; 2048]);
        for (e, s) in (-1022..=1023).zip(scale.iter_mut()) {
            *s = 2f64.powi(e).powf(y);
        }
        let mut coef = [0.0; 6];
        let mut c = 1.0;
        for (k, slot) in coef.iter_mut().enumerate() {
            c *= (y - k as f64) / (k as f64 + 1.0);
            *slot = c;
        }
        Self {
            y,
            mant_pow,
            mant_inv,
            scale,
            coef,
        }
    }

    /// `x^y`.
    #[inline]
    pub(crate) fn pow(&self, x: f64) -> f64 {
        if !on_path(x) {
            return x.powf(self.y);
        }
        self.pow_normal(x)
    }

    /// `x^y` for `x` on the fast path ([`on_path`]; any other input gives a finite value
    /// of no meaning).
    #[inline(always)]
    fn pow_normal(&self, x: f64) -> f64 {
        let bits = x.to_bits();
        let e = ((bits >> 52) & 0x7ff) as usize; // biased, 1..=2046
        let frac = bits & ((1u64 << 52) - 1);
        // The nearest table point: the top 8 bits of the fraction, rounded.
        let j = ((frac + (1u64 << 43)) >> 44) as usize;
        let m = f64::from_bits(frac | (1023u64 << 52));
        let (cy, inv_c) = (self.mant_pow[j & 511], self.mant_inv[j & 511]);
        let t = (m - (1.0 + j as f64 / POINTS as f64)) * inv_c;
        let k = &self.coef;
        let series = t * (k[0] + t * (k[1] + t * (k[2] + t * (k[3] + t * (k[4] + t * k[5])))));
        self.scale[(e.wrapping_sub(1)) & 2047] * cy * (1.0 + series)
    }

    /// `out[i] = xs[i]^y` ([`Self::pow`] of each, the same bits), four or eight at a time
    /// where the processor has AVX2.
    pub(crate) fn pow_slice(&self, xs: &[f64], out: &mut [f64]) {
        assert_eq!(xs.len(), out.len());
        dispatch!(pow_slice_portable, pow_slice_avx2, self, xs, out);
        for (o, &x) in out.iter_mut().zip(xs) {
            if !on_path(x) && x != 0.0 {
                *o = x.powf(self.y);
            }
        }
    }
}

/// Whether `x` takes [`FixedPow`]'s fast path: positive, normal and finite.
#[inline(always)]
fn on_path(x: f64) -> bool {
    (f64::MIN_POSITIVE..=f64::MAX).contains(&x)
}

/// Every input on the fast path, the others stand-ins fixed by the caller.
#[inline(always)]
fn pow_slice_body(p: &FixedPow, xs: &[f64], out: &mut [f64]) {
    for (o, &x) in out.iter_mut().zip(xs) {
        let r = p.pow_normal(if on_path(x) { x } else { 1.0 });
        // x^y = +0 at x = +-0 for the positive y used here (checked at construction).
        *o = if x == 0.0 { 0.0 } else { r };
    }
}

fn pow_slice_portable(p: &FixedPow, xs: &[f64], out: &mut [f64]) {
    pow_slice_body(p, xs, out)
}

/// # Safety
/// The processor must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn pow_slice_avx2(p: &FixedPow, xs: &[f64], out: &mut [f64]) {
    pow_slice_body(p, xs, out)
}

/// The display mapping's power at gamma 2.2 (`x^(1/2.2)`, [`super::image_error::DisplayParams`]).
pub(crate) fn display_pow() -> &'static FixedPow {
    static P: OnceLock<FixedPow> = OnceLock::new();
    P.get_or_init(|| FixedPow::new(1.0 / 2.2))
}

/// The sRGB decoding's power (`x^2.4`).
pub(crate) fn srgb_pow() -> &'static FixedPow {
    static P: OnceLock<FixedPow> = OnceLock::new();
    P.get_or_init(|| FixedPow::new(2.4))
}

/// The cube root of CIELAB (`x^(1/3)`).
pub(crate) fn cube_root() -> &'static FixedPow {
    static P: OnceLock<FixedPow> = OnceLock::new();
    P.get_or_init(|| FixedPow::new(1.0 / 3.0))
}

/// `ln(c_j)` and `1 / c_j` for the table points of [`ln_1p`], padded as [`FixedPow`]'s.
struct LogTables {
    ln: Box<[f64; 512]>,
    inv: Box<[f64; 512]>,
}

fn log_tables() -> &'static LogTables {
    static T: OnceLock<LogTables> = OnceLock::new();
    T.get_or_init(|| {
        let (mut ln, mut inv) = (Box::new([0.0; 512]), Box::new([0.0; 512]));
        for j in 0..=POINTS {
            let c = 1.0 + j as f64 / POINTS as f64;
            (ln[j], inv[j]) = (c.ln(), 1.0 / c);
        }
        LogTables { ln, inv }
    })
}

/// `ln 2` split so that `e * LN2_HI` is exact for `|e| < 2^20`.
const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);

/// The upper end of [`ln_1p`]'s fast path (below 2^52, where `w - 1` is exact).
const LN_1P_MAX: f64 = 4.5e15;

/// `log(1 + u)` (module docs); exact for `u = 0` (either sign).
#[inline]
pub(crate) fn ln_1p(u: f64) -> f64 {
    if !(u > 0.0 && u < LN_1P_MAX) {
        return u.ln_1p();
    }
    ln_1p_positive(log_tables(), u)
}

/// [`ln_1p`] for `u` in `(0, LN_1P_MAX)` (any other input gives a finite value of no
/// meaning).
#[inline(always)]
fn ln_1p_positive(tab: &LogTables, u: f64) -> f64 {
    let w = 1.0 + u;
    // The part of `u` that `1 + u` rounded off (exact: `w - 1` is exact for `w < 2^53`, and
    // `u - (w - 1)` is exact by Sterbenz's lemma or because `w - 1 = 0`).
    let delta = u - (w - 1.0);
    let bits = w.to_bits();
    let eb = (bits >> 52) & 0x7ff; // w >= 1: biased exponent 1023..=1075
    let frac = bits & ((1u64 << 52) - 1);
    let j = ((frac + (1u64 << 43)) >> 44) as usize & 511;
    let m = f64::from_bits(frac | (1023u64 << 52));
    let inv_c = tab.inv[j];
    let t = (m - (1.0 + j as f64 / POINTS as f64)) * inv_c;
    // log(1 + t) = t - t^2/2 + t^3/3 - ... to t^7 (truncation below 1e-20).
    let series = t - t
        * t
        * (0.5
            - t * (1.0 / 3.0 - t * (0.25 - t * (1.0 / 5.0 - t * (1.0 / 6.0 - t * (1.0 / 7.0))))));
    // delta / w, to a relative 2^-17 (|t| <= 1/512 squared): a correction below half a unit
    // of w, so far below a unit of the result.
    let inv_w = inv_c * f64::from_bits((2046u64.wrapping_sub(eb) & 0x7ff) << 52) * (1.0 - t);
    let ef = eb as f64 - 1023.0;
    ef * LN2_HI + (tab.ln[j] + (series + (ef * LN2_LO + delta * inv_w)))
}

/// `out[i] = log(1 + xs[i])` ([`ln_1p`] of each, the same bits), four at a time where the
/// processor has AVX2.
pub(crate) fn ln_1p_slice(xs: &[f64], out: &mut [f64]) {
    assert_eq!(xs.len(), out.len());
    let tab = log_tables();
    dispatch!(ln_1p_slice_portable, ln_1p_slice_avx2, tab, xs, out);
    for (o, &u) in out.iter_mut().zip(xs) {
        if !(0.0..LN_1P_MAX).contains(&u) {
            *o = u.ln_1p();
        }
    }
}

#[inline(always)]
fn ln_1p_slice_body(tab: &LogTables, xs: &[f64], out: &mut [f64]) {
    for (o, &u) in out.iter_mut().zip(xs) {
        let on = u > 0.0 && u < LN_1P_MAX;
        let r = ln_1p_positive(tab, if on { u } else { 1.0 });
        *o = if u == 0.0 { u } else { r };
    }
}

fn ln_1p_slice_portable(tab: &LogTables, xs: &[f64], out: &mut [f64]) {
    ln_1p_slice_body(tab, xs, out)
}

/// # Safety
/// The processor must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn ln_1p_slice_avx2(tab: &LogTables, xs: &[f64], out: &mut [f64]) {
    ln_1p_slice_body(tab, xs, out)
}

/// `atan(0.5)` and `atan(1)` split in two (fdlibm's `atanhi`, `atanlo`).
const ATAN_HI: [f64; 2] = [
    f64::from_bits(0x3fdd_ac67_0561_bb4f),
    f64::from_bits(0x3fe9_21fb_5444_2d18),
];
const ATAN_LO: [f64; 2] = [
    f64::from_bits(0x3c7a_2b7f_222f_65e2),
    f64::from_bits(0x3c81_a626_3314_5c07),
];
/// fdlibm's minimax polynomial of `(x - atan x) / x^3` in `x^2` on `|x| < 7/16`.
const ATAN_POLY: [f64; 11] = [
    f64::from_bits(0x3fd5_5555_5555_550d),
    f64::from_bits(0xbfc9_9999_9998_ebc4),
    f64::from_bits(0x3fc2_4924_9200_83ff),
    f64::from_bits(0xbfbc_71c6_fe23_1671),
    f64::from_bits(0x3fb7_45cd_c54c_206e),
    f64::from_bits(0xbfb3_b0f2_af74_9a6d),
    f64::from_bits(0x3fb1_0d66_a0d0_3d51),
    f64::from_bits(0xbfad_de2d_52de_fd9a),
    f64::from_bits(0x3fa9_7b4b_2476_0deb),
    f64::from_bits(0xbfa2_b444_2c6a_6c2f),
    f64::from_bits(0x3f90_ad3a_e322_da11),
];
/// `pi / 2` and `pi` split in two (the low parts: what the rounded high parts lack).
const PIO2_HI: f64 = f64::from_bits(0x3ff9_21fb_5444_2d18);
const PIO2_LO: f64 = f64::from_bits(0x3c91_a626_3314_5c07);
const PI_HI: f64 = f64::from_bits(0x4009_21fb_5444_2d18);
const PI_LO: f64 = f64::from_bits(0x3ca1_a626_3314_5c07);

/// `atan2(y, x)` in radians for finite `y` and `x`, without a branch: the ratio `t` of the
/// smaller to the larger of `|y|`, `|x|` (in `[0, 1]`), fdlibm's `atan` of it (its
/// reduction by `atan(1/2)` or `atan(1)` above `7/16`, chosen by selects, and its minimax
/// polynomial), then `pi/2 - a` where `|y| > |x|`, `pi - a` where `x` is negative (its
/// sign bit: `-0` included, as the C library) and the sign of `y`. Plain multiplies, adds
/// and one division each way, so a loop over it vectorises and gives the same bits on
/// every x86-64 processor.
///
/// Within 2 units in the last place of the C library's `atan2` (glibc) over the unit
/// tests' 5 million inputs of every quadrant and octant, magnitudes `1e-6` to `1e6` (ratios
/// `1e-12` to `1e12`), CIEDE2000's sums of two unit vectors, the axes and the reduction's
/// band ends (largest seen: 2 ulp, where `pi/2 - a` or `pi - a` adds its rounding). Subnormal ratios, zeros (`atan2(+-0, +-0)` as the C library) and
/// infinities in neither argument are its domain's ends; non-finite inputs are not.
#[inline(always)]
pub(crate) fn atan2(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let swap = ay > ax;
    let (num, den) = if swap { (ax, ay) } else { (ay, ax) };
    let t = num / if den == 0.0 { 1.0 } else { den };
    // fdlibm's reduction: t below 7/16 as it is; below 11/16 by atan(1/2)
    // ((2t - 1) / (2 + t)); up to 1 by atan(1) ((t - 1) / (t + 1)). One division: the
    // first as (1 t - 0) / (1 + 0 t), exactly t.
    let (low, mid) = (t < 0.4375, t < 0.6875);
    let (p, q, s) = if low {
        (1.0, 0.0, 0.0)
    } else if mid {
        (2.0, 1.0, 1.0)
    } else {
        (1.0, 1.0, 1.0)
    };
    let r = (p * t - q) / (p + s * t);
    let (hi, lo) = if mid {
        (ATAN_HI[0], ATAN_LO[0])
    } else {
        (ATAN_HI[1], ATAN_LO[1])
    };
    let z = r * r;
    let w = z * z;
    let k = &ATAN_POLY;
    let s1 = z * (k[0] + w * (k[2] + w * (k[4] + w * (k[6] + w * (k[8] + w * k[10])))));
    let s2 = w * (k[1] + w * (k[3] + w * (k[5] + w * (k[7] + w * k[9]))));
    let a = if low {
        r - r * (s1 + s2)
    } else {
        hi - ((r * (s1 + s2) - lo) - r)
    };
    let a = if swap { PIO2_HI - (a - PIO2_LO) } else { a };
    let a = if x.is_sign_negative() {
        PI_HI - (a - PI_LO)
    } else {
        a
    };
    if y.is_sign_negative() {
        -a
    } else {
        a
    }
}

/// `2^(j/64)`, `j = 0..64`, correctly rounded (50-digit decimal arithmetic).
const EXP2_64THS: [f64; 64] = {
    const B: [u64; 64] = [
        0x3ff0000000000000,
        0x3ff02c9a3e778061,
        0x3ff059b0d3158574,
        0x3ff0874518759bc8,
        0x3ff0b5586cf9890f,
        0x3ff0e3ec32d3d1a2,
        0x3ff11301d0125b51,
        0x3ff1429aaea92de0,
        0x3ff172b83c7d517b,
        0x3ff1a35beb6fcb75,
        0x3ff1d4873168b9aa,
        0x3ff2063b88628cd6,
        0x3ff2387a6e756238,
        0x3ff26b4565e27cdd,
        0x3ff29e9df51fdee1,
        0x3ff2d285a6e4030b,
        0x3ff306fe0a31b715,
        0x3ff33c08b26416ff,
        0x3ff371a7373aa9cb,
        0x3ff3a7db34e59ff7,
        0x3ff3dea64c123422,
        0x3ff4160a21f72e2a,
        0x3ff44e086061892d,
        0x3ff486a2b5c13cd0,
        0x3ff4bfdad5362a27,
        0x3ff4f9b2769d2ca7,
        0x3ff5342b569d4f82,
        0x3ff56f4736b527da,
        0x3ff5ab07dd485429,
        0x3ff5e76f15ad2148,
        0x3ff6247eb03a5585,
        0x3ff6623882552225,
        0x3ff6a09e667f3bcd,
        0x3ff6dfb23c651a2f,
        0x3ff71f75e8ec5f74,
        0x3ff75feb564267c9,
        0x3ff7a11473eb0187,
        0x3ff7e2f336cf4e62,
        0x3ff82589994cce13,
        0x3ff868d99b4492ed,
        0x3ff8ace5422aa0db,
        0x3ff8f1ae99157736,
        0x3ff93737b0cdc5e5,
        0x3ff97d829fde4e50,
        0x3ff9c49182a3f090,
        0x3ffa0c667b5de565,
        0x3ffa5503b23e255d,
        0x3ffa9e6b5579fdbf,
        0x3ffae89f995ad3ad,
        0x3ffb33a2b84f15fb,
        0x3ffb7f76f2fb5e47,
        0x3ffbcc1e904bc1d2,
        0x3ffc199bdd85529c,
        0x3ffc67f12e57d14b,
        0x3ffcb720dcef9069,
        0x3ffd072d4a07897c,
        0x3ffd5818dcfba487,
        0x3ffda9e603db3285,
        0x3ffdfc97337b9b5f,
        0x3ffe502ee78b3ff6,
        0x3ffea4afa2a490da,
        0x3ffefa1bee615a27,
        0x3fff50765b6e4540,
        0x3fffa7c1819e90d8,
    ];
    let mut t = [0.0; 64];
    let mut j = 0;
    while j < 64 {
        t[j] = f64::from_bits(B[j]);
        j += 1;
    }
    t
};

/// `64 / ln 2`, and `ln 2 / 64` split so that `k * LN2_64_HI` is exact for `|k| < 2^20`.
const INV_LN2_64: f64 = 92.332_482_616_893_66;
const LN2_64_HI: f64 = f64::from_bits(0x3f86_2e42_fef0_0000);
const LN2_64_LO: f64 = f64::from_bits(0x3d74_73de_6af2_78ed);

/// `e^z` for `z` in `[-708, 709]` (any other input gives a value of no meaning),
/// without a branch: `z = (64 e + j) ln2/64 + r`, `k = 64 e + j` the nearest integer to
/// `64 z / ln 2` (by adding and subtracting `1.5 2^52`), `|r| <= ln2/128` (`k ln2/64`
/// subtracted in two parts, the first exact), `e^z = 2^e 2^(j/64) (1 + r + ... + r^6/6!)`
/// (truncation below 3e-20 relative), `2^(j/64)` from a table of 64, `2^e` from its bits.
///
/// Within 2 units in the last place of the C library's `exp` over the unit tests' 3 million
/// inputs (largest seen: 1 ulp).
#[inline(always)]
pub(crate) fn exp_normal(z: f64) -> f64 {
    const SHIFT: f64 = 6_755_399_441_055_744.0; // 1.5 2^52
    let kd = z * INV_LN2_64 + SHIFT;
    let bits = kd.to_bits(); // low 52 bits: 2^51 + k
    let kf = kd - SHIFT;
    let r = (z - kf * LN2_64_HI) - kf * LN2_64_LO;
    // 2^e from the bits of k / 64 (2^51 / 64 shifted past the top drops out).
    let scale = f64::from_bits(((bits >> 6).wrapping_add(1023)) << 52);
    let s = EXP2_64THS[(bits & 63) as usize] * scale;
    let p = r + r
        * r
        * (0.5 + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (1.0 / 120.0 + r * (1.0 / 720.0)))));
    s + s * p
}

/// `1 / (2k + 1)!` for `k = 1..=10`.
const SIN_TAYLOR: [f64; 10] = [
    1.0 / 6.0,
    1.0 / 120.0,
    1.0 / 5_040.0,
    1.0 / 362_880.0,
    1.0 / 39_916_800.0,
    1.0 / 6_227_020_800.0,
    1.0 / 1_307_674_368_000.0,
    1.0 / 355_687_428_096_000.0,
    1.0 / 121_645_100_408_832_000.0,
    1.0 / 51_090_942_171_709_440_000.0,
];

/// `sin x` for `|x| <= pi/3` (CIEDE2000's rotation: `sin(60 deg e^(-q^2))`), without a
/// branch: its Taylor series to `x^21` (truncation below 5e-20), `x - x^3 (1/3! - x^2
/// (1/5! - ...))`. Within 1 unit in the last place of the C library's `sin` over the unit
/// tests' 2 million inputs of `[0, pi/3]` and `[-1e-3, 1e-3]` (largest seen: 1 ulp).
#[inline(always)]
pub(crate) fn sin_small(x: f64) -> f64 {
    let k = &SIN_TAYLOR;
    let z = x * x;
    let tail = k[0]
        - z * (k[1]
            - z * (k[2]
                - z * (k[3]
                    - z * (k[4] - z * (k[5] - z * (k[6] - z * (k[7] - z * (k[8] - z * k[9]))))))));
    x - x * z * tail
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Units in the last place between `got` and `want` (both finite, same sign).
    fn ulps(got: f64, want: f64) -> f64 {
        if got == want {
            return 0.0;
        }
        let ulp = f64::from_bits(want.abs().to_bits() + 1) - want.abs();
        (got - want).abs() / ulp
    }

    /// A xorshift stream of f64 in `[lo, hi)`, log-uniform when `log` is set.
    fn stream(seed: u64) -> impl FnMut(f64, f64, bool) -> f64 {
        let mut s = seed;
        move |lo, hi, log| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let r = (s >> 11) as f64 / (1u64 << 53) as f64;
            if log {
                (lo.ln() + (hi.ln() - lo.ln()) * r).exp()
            } else {
                lo + (hi - lo) * r
            }
        }
    }

    #[test]
    fn fixed_powers_are_within_three_ulps_of_the_c_library() {
        for y in [1.0 / 2.2, 2.4, 1.0 / 3.0] {
            let p = FixedPow::new(y);
            let mut next = stream(0x9e37_79b9_7f4a_7c15);
            let mut worst = 0f64;
            for i in 0..1_000_000 {
                let x = match i % 4 {
                    0 => next(0.0, 1.0, false),
                    1 => next(1e-12, 1.0, true),
                    2 => next(1.0, 1e6, true),
                    // Renders are f32: inputs with 29 trailing zero bits.
                    _ => f64::from(next(1e-8, 1.0, true) as f32),
                };
                worst = worst.max(ulps(p.pow(x), x.powf(y)));
            }
            // Table points, octave ends and the neighbours of both.
            for e in -1022..=1023 {
                for j in 0..=POINTS as u64 {
                    let b = ((e + 1023) as u64) << 52 | (j << 44).min((1u64 << 52) - 1);
                    for x in [
                        f64::from_bits(b),
                        f64::from_bits(b + 1),
                        f64::from_bits(b - 1),
                    ] {
                        let want = x.powf(y);
                        if want.is_finite() && want >= f64::MIN_POSITIVE {
                            worst = worst.max(ulps(p.pow(x), want));
                        }
                    }
                }
            }
            assert!(worst <= 3.0, "y = {y}: {worst} ulps");
        }
    }

    #[test]
    fn fixed_powers_off_the_fast_path_are_the_c_librarys() {
        let p = FixedPow::new(2.4);
        for x in [0.0, -0.0, -1.0, 1e-310, f64::INFINITY, f64::MAX, f64::NAN] {
            let (got, want) = (p.pow(x), x.powf(2.4));
            assert!(got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()));
        }
        assert_eq!(p.pow(1.0), 1.0);
        assert_eq!(FixedPow::new(1.0 / 2.2).pow(1.0), 1.0);
        assert_eq!(cube_root().pow(8.0), 2.0);
        assert_eq!(cube_root().pow(0.125), 0.5);
    }

    #[test]
    fn ln_1p_is_within_three_ulps_of_the_c_library() {
        let mut next = stream(0x2545_f491_4f6c_dd1d);
        let mut worst = 0f64;
        for i in 0..2_000_000 {
            let u = match i % 4 {
                0 => next(0.0, 1.0, false),
                1 => next(1e-300, 1e-6, true),
                2 => next(1e-6, 1e6, true),
                _ => next(1e6, 4e15, true),
            };
            if u > 0.0 {
                worst = worst.max(ulps(ln_1p(u), u.ln_1p()));
            }
        }
        // Around the table points of w, powers of two, and the path's ends.
        for e in 0..52 {
            for j in 0..=POINTS as u64 {
                let b = ((e + 1023) as u64) << 52 | (j << 44).min((1u64 << 52) - 1);
                for w in [
                    f64::from_bits(b),
                    f64::from_bits(b + 1),
                    f64::from_bits(b - 1),
                ] {
                    for u in [w - 1.0, f64::from_bits((w - 1.0).to_bits() + 1)] {
                        if u > 0.0 {
                            worst = worst.max(ulps(ln_1p(u), u.ln_1p()));
                        }
                    }
                }
            }
        }
        for u in [
            f64::MIN_POSITIVE,
            5e-324,
            2f64.powi(-53),
            2f64.powi(-52),
            4.4e15,
        ] {
            worst = worst.max(ulps(ln_1p(u), u.ln_1p()));
        }
        assert!(worst <= 3.0, "{worst} ulps");
        for u in [0.0, -0.0, -0.5, -1.0, 5e15, f64::INFINITY, f64::NAN] {
            let (got, want) = (ln_1p(u), u.ln_1p());
            assert!(got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()));
        }
    }

    /// Units in the last place between `got` and `want` of either sign.
    fn ulps_signed(got: f64, want: f64) -> f64 {
        if got == want {
            return 0.0;
        }
        if got.is_sign_negative() != want.is_sign_negative() {
            return f64::INFINITY;
        }
        ulps(got.abs(), want.abs())
    }

    #[test]
    fn atan2_is_within_two_ulps_of_the_c_library() {
        let mut next = stream(0x5851_f42d_4c95_7f2d);
        let mut worst = 0f64;
        for i in 0..4_000_000 {
            // Magnitudes from 1e-6 to 1e6 (ratios 1e-12 to 1e12), every quadrant; every
            // fourth pair near the diagonal or an axis (the reduction's band ends).
            let (mut y, mut x) = (next(1e-6, 1e6, true), next(1e-6, 1e6, true));
            match i % 8 {
                0 => y = x * next(0.4, 0.5, false),
                1 => y = x * next(0.65, 0.72, false),
                2 => y = x * next(0.98, 1.02, false),
                3 => y = x * next(0.0, 1e-3, false),
                _ => {}
            }
            if i % 3 == 0 {
                (x, y) = (y, x);
            }
            let y = if i & 16 != 0 { -y } else { y };
            let x = if i & 32 != 0 { -x } else { x };
            worst = worst.max(ulps_signed(atan2(y, x), y.atan2(x)));
        }
        // CIEDE2000's case: the sum of two unit vectors.
        for _ in 0..1_000_000 {
            let (p, q) = (next(-3.2, 3.2, false), next(-3.2, 3.2, false));
            let (y, x) = (p.sin() + q.sin(), p.cos() + q.cos());
            worst = worst.max(ulps_signed(atan2(y, x), y.atan2(x)));
        }
        for (y, x) in [
            (0.0, 1.0),
            (-0.0, 1.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (1.0, 0.0),
            (-1.0, 0.0),
            (1.0, -0.0),
            (1.0, 1.0),
            (-1.0, -1.0),
            (0.4375, 1.0),
            (0.6875, 1.0),
            (0.0, 0.0),
            (-0.0, 0.0),
            (0.0, -0.0),
            (-0.0, -0.0),
        ] {
            worst = worst.max(ulps_signed(atan2(y, x), y.atan2(x)));
        }
        eprintln!("atan2: {worst} ulps");
        assert!(worst <= 2.0, "{worst} ulps");
    }

    /// The domain of [`exp_normal`].
    const EXP_MIN: f64 = -708.0;
    const EXP_MAX: f64 = 709.0;

    /// `e^z`: [`exp_normal`] on its domain, the C library's elsewhere.
    fn exp(z: f64) -> f64 {
        if (EXP_MIN..=EXP_MAX).contains(&z) {
            exp_normal(z)
        } else {
            z.exp()
        }
    }

    #[test]
    fn exp_is_within_two_ulps_of_the_c_library() {
        let mut next = stream(0x9e6c_63d0_676a_9a99);
        let mut worst = 0f64;
        for i in 0..3_000_000 {
            let z = match i % 3 {
                // CIEDE2000's Gaussian: -((h - 275) / 25)^2 for h in [0, 720).
                0 => {
                    let q = (next(0.0, 720.0, false) - 275.0) / 25.0;
                    -(q * q)
                }
                1 => next(-1.0, 1.0, false),
                _ => next(EXP_MIN, EXP_MAX, false),
            };
            worst = worst.max(ulps(exp(z), z.exp()));
        }
        for z in [
            0.0,
            -0.0,
            1e-300,
            -1e-300,
            EXP_MIN,
            EXP_MAX,
            0.5f64.ln(),
            1.0,
        ] {
            worst = worst.max(ulps(exp(z), z.exp()));
        }
        eprintln!("exp: {worst} ulps");
        assert!(worst <= 2.0, "{worst} ulps");
        assert_eq!(exp(0.0), 1.0);
        for z in [-800.0, 800.0, f64::NEG_INFINITY, f64::INFINITY] {
            assert_eq!(exp(z), z.exp());
        }
        assert!(exp(f64::NAN).is_nan());
    }

    #[test]
    fn sin_small_is_within_one_ulp_of_the_c_library() {
        let mut next = stream(0xd1b5_4a32_d192_ed03);
        let mut worst = 0f64;
        let third = std::f64::consts::FRAC_PI_3;
        for i in 0..2_000_000 {
            let x = match i % 4 {
                0 => next(0.0, third, false),
                1 => next(1e-300, third, true),
                2 => next(-1e-3, 1e-3, false),
                _ => third * (-(next(0.0, 18.0, false).powi(2))).exp(),
            };
            worst = worst.max(ulps_signed(sin_small(x), x.sin()));
        }
        for x in [0.0, third, -third, f64::MIN_POSITIVE] {
            worst = worst.max(ulps_signed(sin_small(x), x.sin()));
        }
        eprintln!("sin: {worst} ulps");
        assert!(worst <= 1.0, "{worst} ulps");
    }

    /// The slice forms give the scalar forms' bits on every kind of input, in runs of every
    /// length (the vector loops' tails).
    #[test]
    fn slices_give_the_scalar_bits() {
        let mut next = stream(7);
        let specials = [
            0.0,
            -0.0,
            -2.0,
            1e-310,
            f64::INFINITY,
            f64::NAN,
            1.0,
            5e15,
            2.0,
        ];
        let mut xs: Vec<f64> = (0..4099)
            .map(|i| match i % 5 {
                0 => specials[(i / 5) % specials.len()],
                1 => next(1e-9, 1.0, true),
                2 => next(1.0, 1e9, true),
                _ => next(0.0, 1.0, false),
            })
            .collect();
        xs.push(0.5);
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        for n in [0, 1, 3, 4, 5, 7, 8, 9, 31, xs.len()] {
            let x = &xs[..n];
            let mut out = vec![0.0; n];
            for p in [display_pow(), srgb_pow(), cube_root()] {
                p.pow_slice(x, &mut out);
                for (&o, &v) in out.iter().zip(x) {
                    assert!(same(o, p.pow(v)), "{v}: {o} vs {}", p.pow(v));
                }
            }
            ln_1p_slice(x, &mut out);
            for (&o, &v) in out.iter().zip(x) {
                assert!(same(o, ln_1p(v)), "{v}: {o} vs {}", ln_1p(v));
            }
        }
    }
}
