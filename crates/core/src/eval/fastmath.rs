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
//!
//! Both are within 3 units in the last place of the correctly rounded value on every input
//! (the unit tests measure the largest difference from the C library over millions of
//! inputs, each kind of input included). Plain multiplies and adds (no fused
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
