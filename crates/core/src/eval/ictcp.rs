//! ICtCp (ITU-R BT.2100, PQ) and the ΔE_ITP colour difference (ITU-R BT.2124; issue 50,
//! item 4: Kavoosighafi et al. 2025 found it the best predictor of human judgments of
//! BRDF renders).
//!
//! Conventions, where the standards leave a choice for display-referred images:
//! * the input is what CIELAB takes ([`super::color`]): display values in `[0, 1]` read as
//!   sRGB-encoded, decoded by the sRGB curve to linear BT.709 RGB;
//! * the display's white (linear `(1, 1, 1)`) is [`DISPLAY_WHITE`] = 100 cd/m² (an SDR
//!   display's reference white), as PQ is absolute;
//! * linear sRGB to XYZ by the sRGB standard's matrix (IEC 61966-2-1, the one CIELAB uses
//!   here), XYZ to linear BT.2020 by the inverse of BT.2020's normalised primary matrix (its
//!   primaries and D65 white): colour-science's conversion; then BT.2100's LMS, PQ and
//!   ICtCp matrices;
//! * `ΔE_ITP = 720 sqrt(ΔI² + ΔT² + ΔP²)` with `T = Ct / 2`, `P = Cp` (BT.2124): 1 is
//!   about a just noticeable difference.

use std::sync::OnceLock;

/// The luminance of the display's white, cd/m².
pub const DISPLAY_WHITE: f64 = 100.0;

/// An ICtCp colour `(I, Ct, Cp)`.
pub type Ictcp = [f64; 3];

/// The normalised primary matrix (linear RGB to XYZ, Y of white 1) of the primaries
/// `xy` (red, green, blue) and white `w`.
fn primary_matrix(xy: [[f64; 2]; 3], w: [f64; 2]) -> [[f64; 3]; 3] {
    let col = |[x, y]: [f64; 2]| [x / y, 1.0, (1.0 - x - y) / y];
    let p = xy.map(col); // p[k] = XYZ of primary k at Y = 1
    let m = [0, 1, 2].map(|r| [p[0][r], p[1][r], p[2][r]]);
    let s = mul_vec(&inverse(&m), col(w));
    [0, 1, 2].map(|r| [m[r][0] * s[0], m[r][1] * s[1], m[r][2] * s[2]])
}

fn inverse(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let c = |r: usize, k: usize| {
        let (r1, r2, k1, k2) = ((r + 1) % 3, (r + 2) % 3, (k + 1) % 3, (k + 2) % 3);
        m[r1][k1] * m[r2][k2] - m[r1][k2] * m[r2][k1]
    };
    let det = m[0][0] * c(0, 0) + m[0][1] * c(0, 1) + m[0][2] * c(0, 2);
    // inverse[k][r] = cofactor(r, k) / det
    [0, 1, 2].map(|k| [0, 1, 2].map(|r| c(r, k) / det))
}

fn mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    [0, 1, 2].map(|r| [0, 1, 2].map(|k| a[r][0] * b[0][k] + a[r][1] * b[1][k] + a[r][2] * b[2][k]))
}

fn mul_vec(a: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|r| a[r][0] * v[0] + a[r][1] * v[1] + a[r][2] * v[2])
}

/// Linear sRGB (BT.709 primaries) to linear BT.2020 RGB (module docs).
fn bt709_to_bt2020() -> &'static [[f64; 3]; 3] {
    static M: OnceLock<[[f64; 3]; 3]> = OnceLock::new();
    M.get_or_init(|| {
        const D65: [f64; 2] = [0.3127, 0.3290];
        let m2020 = primary_matrix([[0.708, 0.292], [0.170, 0.797], [0.131, 0.046]], D65);
        mul(&inverse(&m2020), &super::color::SRGB_TO_XYZ)
    })
}

const M1: f64 = 2610.0 / 16384.0;
const M2: f64 = 2523.0 / 4096.0 * 128.0;
const C1: f64 = 3424.0 / 4096.0;
const C2: f64 = 2413.0 / 4096.0 * 32.0;
const C3: f64 = 2392.0 / 4096.0 * 32.0;
/// `M2 = 78 + M2_FRAC`: `z^M2` as `z^78` (repeated products) times `z^M2_FRAC` (the
/// table-driven power; [`super::fastmath::FixedPow`]'s series is for small exponents).
const M2_FRAC: f64 = M2 - 78.0;

fn pow_m1() -> &'static super::fastmath::FixedPow {
    static P: OnceLock<super::fastmath::FixedPow> = OnceLock::new();
    P.get_or_init(|| super::fastmath::FixedPow::new(M1))
}

fn pow_m2_frac() -> &'static super::fastmath::FixedPow {
    static P: OnceLock<super::fastmath::FixedPow> = OnceLock::new();
    P.get_or_init(|| super::fastmath::FixedPow::new(M2_FRAC))
}

/// PQ's rational step of `y = (c / 10000)^M1`: the base of the final power.
#[inline]
fn pq_base(y: f64) -> f64 {
    (C1 + C2 * y) / (1.0 + C3 * y)
}

/// BT.2100's PQ inverse EOTF of an absolute luminance `c` (cd/m², clamped at 0): within a
/// few units in the last place of `((C1 + C2 Y^m1) / (1 + C3 Y^m1))^m2`, `Y = c / 10000`.
fn pq(c: f64) -> f64 {
    let z = pq_base(pow_m1().pow(c.max(0.0) / 10000.0));
    z.powi(78) * pow_m2_frac().pow(z)
}

/// The LMS of BT.2100 of linear BT.2020 RGB `[r, g, b]` (cd/m²).
#[inline]
fn lms([r, g, b]: [f64; 3]) -> [f64; 3] {
    [
        (1688.0 * r + 2146.0 * g + 262.0 * b) / 4096.0,
        (683.0 * r + 2951.0 * g + 462.0 * b) / 4096.0,
        (99.0 * r + 309.0 * g + 3688.0 * b) / 4096.0,
    ]
}

/// ICtCp of PQ-encoded LMS.
#[inline]
fn ictcp_of([l, m, s]: [f64; 3]) -> Ictcp {
    [
        0.5 * l + 0.5 * m,
        (6610.0 * l - 13613.0 * m + 7003.0 * s) / 4096.0,
        (17933.0 * l - 17390.0 * m - 543.0 * s) / 4096.0,
    ]
}

/// ICtCp of an sRGB-encoded display colour in `[0, 1]^3` (module docs).
pub fn srgb_to_ictcp(rgb: [f64; 3]) -> Ictcp {
    let lin = rgb.map(|v| super::color::srgb_decode(v.clamp(0.0, 1.0)) * DISPLAY_WHITE);
    ictcp_of(lms(mul_vec(bt709_to_bt2020(), lin)).map(pq))
}

/// [`srgb_to_ictcp`] of every colour of `rgb` (interleaved, three values a colour): the
/// same bits, the powers four at a time.
pub fn srgb_to_ictcp_all(rgb: &[f64]) -> Vec<Ictcp> {
    assert_eq!(rgb.len() % 3, 0, "three values a colour");
    ictcp_from_linear_all(&super::color::srgb_decode_all(rgb))
}

/// ICtCp of decoded colours (`color::srgb_decode_all` of `rgb`): [`srgb_to_ictcp_all`]
/// given the linear values, so that CIELAB can share the decoding.
pub(crate) fn ictcp_from_linear_all(lin: &[f64]) -> Vec<Ictcp> {
    let mut y = Vec::with_capacity(lin.len());
    for p in lin.chunks_exact(3) {
        let c = lms(mul_vec(
            bt709_to_bt2020(),
            [
                p[0] * DISPLAY_WHITE,
                p[1] * DISPLAY_WHITE,
                p[2] * DISPLAY_WHITE,
            ],
        ));
        y.extend(c.map(|c| c.max(0.0) / 10000.0));
    }
    let mut out = vec![0.0; y.len()];
    pow_m1().pow_slice(&y, &mut out);
    let z: Vec<f64> = out.iter().map(|&y| pq_base(y)).collect();
    pow_m2_frac().pow_slice(&z, &mut out);
    z.chunks_exact(3)
        .zip(out.chunks_exact(3))
        .map(|(z, f)| ictcp_of([0, 1, 2].map(|i| z[i].powi(78) * f[i])))
        .collect()
}

/// ΔE_ITP (ITU-R BT.2124) of two ICtCp colours.
pub fn delta_e_itp(x: Ictcp, y: Ictcp) -> f64 {
    let (di, dt, dp) = (x[0] - y[0], 0.5 * (x[1] - y[1]), x[2] - y[2]);
    720.0 * (di * di + dt * dt + dp * dp).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The BT.709 to BT.2020 matrix of ITU-R BT.2087 (to its 4 published decimals: the sRGB
    /// standard's rounded matrix moves it by less than 1e-4), and its rows summing to 1 to
    /// that matrix's rounding (white stays nearly white).
    #[test]
    fn bt709_to_bt2020_is_bt2087s_matrix() {
        let want = [
            [0.6274, 0.3293, 0.0433],
            [0.0691, 0.9195, 0.0114],
            [0.0164, 0.0880, 0.8956],
        ];
        let m = bt709_to_bt2020();
        for r in 0..3 {
            for k in 0..3 {
                assert!((m[r][k] - want[r][k]).abs() < 1e-4, "{r} {k}: {}", m[r][k]);
            }
            assert!((m[r].iter().sum::<f64>() - 1.0).abs() < 1e-3);
        }
    }

    /// The batch form gives the scalar form's bits.
    #[test]
    fn srgb_to_ictcp_all_is_srgb_to_ictcp_of_each() {
        let rgb: Vec<f64> = (0..3000)
            .map(|i| ((i as f64 * 0.618_033_988_75) % 1.0).powi(1 + (i % 5)))
            .chain([0.0, 1.0, 0.04045, -0.2, 1.5, 0.0])
            .collect();
        for (c, got) in rgb.chunks_exact(3).zip(srgb_to_ictcp_all(&rgb)) {
            let want = srgb_to_ictcp([c[0], c[1], c[2]]);
            assert_eq!(got.map(f64::to_bits), want.map(f64::to_bits), "{c:?}");
        }
    }

    /// Hand-checked values: black is PQ's floor, white at 100 cd/m² has PQ 0.508 (BT.2100's
    /// table: 100 cd/m² = 0.5081), and greys have no chroma to the sRGB matrix's rounding.
    #[test]
    fn black_white_and_grey() {
        let k = srgb_to_ictcp([0.0; 3]);
        let floor = (3424.0f64 / 4096.0).powf(2523.0 / 4096.0 * 128.0);
        assert!((k[0] - floor).abs() < 1e-15 && k[1].abs() < 1e-15 && k[2].abs() < 1e-15);
        let w = srgb_to_ictcp([1.0; 3]);
        assert!((w[0] - 0.508).abs() < 1e-3, "{w:?}");
        for v in [0.1, 0.5, 1.0] {
            let g = srgb_to_ictcp([v; 3]);
            assert!(g[1].abs() < 1e-3 && g[2].abs() < 1e-3, "{v}: {g:?}");
        }
        assert_eq!(delta_e_itp(w, w), 0.0);
        let (a, b) = (
            srgb_to_ictcp([0.5, 0.2, 0.1]),
            srgb_to_ictcp([0.52, 0.2, 0.1]),
        );
        assert_eq!(delta_e_itp(a, b), delta_e_itp(b, a));
        // A small step in red is a few JNDs; a hue swap is far more.
        let d = delta_e_itp(a, b);
        assert!(d > 0.5 && d < 10.0, "{d}");
        assert!(delta_e_itp(a, srgb_to_ictcp([0.1, 0.2, 0.5])) > 10.0 * d);
    }
}
