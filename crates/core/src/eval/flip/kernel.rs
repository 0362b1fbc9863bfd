//! FLIP's separable filters over a mask's region, the per-pixel maths, and the dispatch to
//! the AVX2 build of both.

use super::math::*;
use super::{FlipKernels, INV_WHITE, PT, QC, QF};
use std::cell::RefCell;

/// The region an error over `mask` needs: per row of the mask's rows, the span of columns
/// holding its pixels; the rows and columns the filters read.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Region {
    /// `(row, first column, end column)` of every row with a mask pixel, in row order.
    pub(super) spans: Vec<(usize, usize, usize)>,
    /// Rows the filters read, `[start, end)`.
    pub(super) rows: (usize, usize),
    /// Columns the vertical pass reads, `[start, end)`.
    pub(super) cols: (usize, usize),
}

impl Region {
    pub(super) fn of(mask: &[bool], w: usize, h: usize, reach: usize) -> Self {
        let mut spans = vec![];
        let (mut c0, mut c1) = (w, 0);
        for y in 0..h {
            let row = &mask[y * w..(y + 1) * w];
            if let (Some(a), Some(b)) = (row.iter().position(|&m| m), row.iter().rposition(|&m| m))
            {
                spans.push((y, a, b + 1));
                c0 = c0.min(a);
                c1 = c1.max(b + 1);
            }
        }
        let rows = match (spans.first(), spans.last()) {
            (Some(f), Some(l)) => (f.0.saturating_sub(reach), (l.0 + reach + 1).min(h)),
            _ => (0, 0),
        };
        Self {
            spans,
            rows,
            cols: (c0.min(c1), c1),
        }
    }

    /// Pixels in the spans (the length of a prepared reference's planes).
    pub(super) fn len(&self) -> usize {
        self.spans.iter().map(|&(_, a, b)| b - a).sum()
    }
}

/// The 8-bit sRGB decoding table: `k / 255` decoded to linear, as FLIP reads 8-bit input.
pub(super) fn srgb_table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|k| {
            let s = k as f32 / 255.0;
            if s <= 0.04045 {
                s / 12.92
            } else {
                ((s + 0.055) / 1.055).powf(2.4)
            }
        })
    })
}

/// Scratch planes of one thread (the horizontal pass's outputs and the YCxCz input),
/// reused across calls.
#[derive(Default)]
pub(super) struct Scratch {
    /// Linear RGB of the rows read, then YCxCz and the normalised luminance.
    linear: [Vec<f32>; 3],
    input: [Vec<f32>; 4],
    horizontal: [Vec<f32>; 7],
    padded: Vec<f32>,
    /// One image's filtered planes over the region's spans, compact in span order: Y, Cx,
    /// Cz after the CSF filters, then the features dx, ddx, dy, ddy.
    planes: [Vec<f32>; 7],
    cz2: Vec<f32>,
    /// The test image's errors over the spans.
    pub(super) errors: Vec<f32>,
}

thread_local! {
    pub(super) static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

/// `out[k][x] = sum_t w[k][t] rows[t][x]`, taps in order from 0.0: `K` filters over the same
/// taps (`rows[t]`: the input shifted to tap `t`), blocks of `L` outputs, then of 8, then
/// single ones. A block keeps its sums in registers over all taps (one load per tap and
/// block, no store until the end; 16 lanes: wider blocks spill to the stack, measured
/// slower). Every lane sums its taps in the same order as the tail's scalar loop, so the
/// paths agree to the bit.
#[inline(always)]
pub(super) fn conv<const K: usize, const L: usize>(
    mut out: [&mut [f32]; K],
    w: [&[f32]; K],
    rows: &[&[f32]],
) {
    let n = out[0].len();
    let mut x = conv_blocks::<K, L>(&mut out, &w, rows, 0, n);
    if L > 8 {
        x = conv_blocks::<K, 8>(&mut out, &w, rows, x, n);
    }
    for xx in x..n {
        for k in 0..K {
            let mut a = 0f32;
            for (t, row) in rows.iter().enumerate() {
                a += w[k][t] * row[xx];
            }
            out[k][xx] = a;
        }
    }
}

/// [`conv`]'s blocks of `L` outputs from `x` while one fits before `n`; returns where they
/// stopped.
#[inline(always)]
pub(super) fn conv_blocks<const K: usize, const L: usize>(
    out: &mut [&mut [f32]; K],
    w: &[&[f32]; K],
    rows: &[&[f32]],
    mut x: usize,
    n: usize,
) -> usize {
    while x + L <= n {
        let mut acc = [[0f32; L]; K];
        for (t, row) in rows.iter().enumerate() {
            let s: &[f32; L] = row[x..x + L].try_into().expect("block");
            for k in 0..K {
                let wt = w[k][t];
                for l in 0..L {
                    acc[k][l] += wt * s[l];
                }
            }
        }
        for k in 0..K {
            out[k][x..x + L].copy_from_slice(&acc[k]);
        }
        x += L;
    }
    x
}

/// The filtered planes of the 8-bit image `rgb8` (`w x h`, interleaved) over `region`, into
/// `s.planes`: [`to_ycxcz`], [`horizontal`], [`vertical`].
#[inline(always)]
pub(super) fn filter_image(
    k: &FlipKernels,
    rgb8: &[u8],
    w: usize,
    h: usize,
    region: &Region,
    s: &mut Scratch,
) {
    to_ycxcz(rgb8, w, region, s);
    horizontal(k, w, region, s);
    vertical(k, h, region, s);
}

/// YCxCz and the normalised luminance of every pixel of the rows `region` reads, into
/// `s.input` (whole rows: the horizontal pass reads up to a radius beyond the columns,
/// clamped at the edge).
#[inline(always)]
fn to_ycxcz(rgb8: &[u8], w: usize, region: &Region, s: &mut Scratch) {
    let table = srgb_table();
    let (r0, r1) = region.rows;
    let np = (r1 - r0) * w;
    for p in s.input.iter_mut().chain(s.linear.iter_mut()) {
        p.resize(np, 0.0);
    }
    // The table lookups (a gather) apart from the maths, which then vectorises.
    let [lr, lg, lb] = &mut s.linear;
    let (lr, lg, lb) = (&mut lr[..np], &mut lg[..np], &mut lb[..np]);
    for (i, px) in rgb8[3 * r0 * w..3 * r1 * w].chunks_exact(3).enumerate() {
        lr[i] = table[px[0] as usize];
        lg[i] = table[px[1] as usize];
        lb[i] = table[px[2] as usize];
    }
    let [yy, cx, cz, yn] = &mut s.input;
    let (yy, cx, cz, yn) = (&mut yy[..np], &mut cx[..np], &mut cz[..np], &mut yn[..np]);
    for i in 0..np {
        let xyz = linear_rgb_to_xyz([lr[i], lg[i], lb[i]]);
        let t = [
            xyz[0] * INV_WHITE[0],
            xyz[1] * INV_WHITE[1],
            xyz[2] * INV_WHITE[2],
        ];
        let y = 116.0 * t[1] - 16.0;
        yy[i] = y;
        cx[i] = 500.0 * (t[0] - t[1]);
        cz[i] = 200.0 * (t[1] - t[2]);
        yn[i] = y * (1.0 / 116.0) + 16.0 / 116.0;
    }
}

/// The horizontal pass over the region's columns, edge-clamped, taps in order: `s.input`
/// to `s.horizontal` (Y, Cx, Cz's two halves; the luminance's first and second
/// derivatives and Gaussian).
#[inline(always)]
fn horizontal(k: &FlipKernels, w: usize, region: &Region, s: &mut Scratch) {
    let (c0, c1) = region.cols;
    let cw = c1 - c0;
    let n_rows = region.rows.1 - region.rows.0;
    for p in s.horizontal.iter_mut() {
        p.resize(n_rows * cw, 0.0);
    }
    let (sr, fr) = (k.spatial_radius, k.feature_radius);
    let pad = sr.max(fr);
    for row in 0..n_rows {
        let span = row * cw..(row + 1) * cw;
        let [hy, hcx, hcz1, hcz2, hdx, hddx, hg] = &mut s.horizontal;
        for (ch, src) in s.input.iter().enumerate() {
            let line = &src[row * w..(row + 1) * w];
            // padded[i] = line[clamp(c0 + i - pad)], i in [0, cw + 2 pad): left of the
            // image its first pixel, inside a copy, right of it its last pixel.
            let padded = &mut s.padded;
            padded.clear();
            let lo = pad.saturating_sub(c0).min(cw + 2 * pad);
            let hi = (w + pad - c0).clamp(lo, cw + 2 * pad);
            padded.resize(lo, line[0]);
            padded.extend_from_slice(&line[c0 + lo - pad..c0 + hi - pad]);
            padded.resize(cw + 2 * pad, line[w - 1]);
            let r = if ch < 3 { sr } else { fr };
            let taps: Vec<&[f32]> = (0..2 * r + 1).map(|t| &padded[pad - r + t..]).collect();
            match ch {
                0 => conv::<1, 16>([&mut hy[span.clone()]], [&k.g_y], &taps),
                1 => conv::<1, 16>([&mut hcx[span.clone()]], [&k.g_cx], &taps),
                2 => conv::<2, 16>(
                    [&mut hcz1[span.clone()], &mut hcz2[span.clone()]],
                    [&k.g_cz1, &k.g_cz2],
                    &taps,
                ),
                _ => conv::<3, 16>(
                    [
                        &mut hdx[span.clone()],
                        &mut hddx[span.clone()],
                        &mut hg[span.clone()],
                    ],
                    [&k.f_dg, &k.f_ddg, &k.f_g],
                    &taps,
                ),
            }
        }
    }
}

/// The vertical pass over each span, edge-clamped rows, taps in order: `s.horizontal` to
/// `s.planes`, compact in span order.
#[inline(always)]
fn vertical(k: &FlipKernels, h: usize, region: &Region, s: &mut Scratch) {
    let (sr, fr) = (k.spatial_radius, k.feature_radius);
    let (r0, c0) = (region.rows.0, region.cols.0);
    let cw = region.cols.1 - c0;
    let len = region.len();
    for p in s.planes.iter_mut() {
        p.resize(len, 0.0);
    }
    let mut at = 0;
    let cz2 = &mut s.cz2;
    let [hy, hcx, hcz1, hcz2, hdx, hddx, hg] = &s.horizontal;
    let [py, pcx, pcz, pdx, pddx, pdy, pddy] = &mut s.planes;
    for &(y, a, b) in &region.spans {
        let n = b - a;
        let off = a - c0;
        // The tap rows of a plane for output row `y` and radius `r`, clamped to the image.
        let rows = |r: usize| {
            (0..2 * r + 1).map(move |t| ((y + t).clamp(r, h - 1 + r) - r - r0) * cw + off)
        };
        fn slices(plane: &[f32], starts: impl Iterator<Item = usize>, n: usize) -> Vec<&[f32]> {
            starts.map(|s| &plane[s..s + n]).collect()
        }
        let column = |plane, r| slices(plane, rows(r), n);
        let out = at..at + n;
        conv::<1, 16>([&mut py[out.clone()]], [&k.g_y], &column(hy, sr));
        conv::<1, 16>([&mut pcx[out.clone()]], [&k.g_cx], &column(hcx, sr));
        conv::<1, 16>([&mut pcz[out.clone()]], [&k.g_cz1], &column(hcz1, sr));
        cz2.resize(n, 0.0f32);
        conv::<1, 16>([&mut cz2[..n]], [&k.g_cz2], &column(hcz2, sr));
        for (o, &v) in pcz[out.clone()].iter_mut().zip(&cz2[..n]) {
            *o += v;
        }
        conv::<1, 16>([&mut pdx[out.clone()]], [&k.f_g], &column(hdx, fr));
        conv::<1, 16>([&mut pddx[out.clone()]], [&k.f_g], &column(hddx, fr));
        conv::<2, 16>(
            [&mut pdy[out.clone()], &mut pddy[out.clone()]],
            [&k.f_dg, &k.f_ddg],
            &column(hg, fr),
        );
        at += n;
    }
}

/// Hunt-adjusted CIELAB of filtered YCxCz, and edge and point strengths of the filtered
/// features, over `n` pixels: what a pixel's error compares.
pub(super) struct Perceived {
    pub(super) lab: [Vec<f32>; 3],
    pub(super) edge: Vec<f32>,
    pub(super) point: Vec<f32>,
}

#[inline(always)]
pub(super) fn perceive(planes: &[Vec<f32>; 7], n: usize) -> Perceived {
    let mut lab: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let (mut edge, mut point) = (vec![0.0; n], vec![0.0; n]);
    let [l, a, b] = &mut lab;
    let (l, a, b) = (&mut l[..n], &mut a[..n], &mut b[..n]);
    let (e, p) = (&mut edge[..n], &mut point[..n]);
    let px = Pixels::of(planes, n);
    for i in 0..n {
        let v = px.perceived(i);
        l[i] = v[0];
        a[i] = v[1];
        b[i] = v[2];
        e[i] = v[3];
        p[i] = v[4];
    }
    Perceived { lab, edge, point }
}

/// The filtered planes of one image, sliced to `n` (so that indexing needs no checks).
pub(super) struct Pixels<'a> {
    y: &'a [f32],
    cx: &'a [f32],
    cz: &'a [f32],
    dx: &'a [f32],
    ddx: &'a [f32],
    dy: &'a [f32],
    ddy: &'a [f32],
}

impl<'a> Pixels<'a> {
    #[inline(always)]
    fn of(planes: &'a [Vec<f32>; 7], n: usize) -> Self {
        let [y, cx, cz, dx, ddx, dy, ddy] = planes;
        Self {
            y: &y[..n],
            cx: &cx[..n],
            cz: &cz[..n],
            dx: &dx[..n],
            ddx: &ddx[..n],
            dy: &dy[..n],
            ddy: &ddy[..n],
        }
    }

    /// Hunt-adjusted CIELAB, edge and point strength of pixel `i`.
    #[inline(always)]
    fn perceived(&self, i: usize) -> [f32; 5] {
        let [l, a, b] = hunt_lab_of_ycxcz([self.y[i], self.cx[i], self.cz[i]]);
        let edge = (self.dx[i] * self.dx[i] + self.dy[i] * self.dy[i]).sqrt();
        let point = (self.ddx[i] * self.ddx[i] + self.ddy[i] * self.ddy[i]).sqrt();
        [l, a, b, edge, point]
    }
}

/// The error of one pixel from the two images' perceived values.
#[inline(always)]
pub(super) fn pixel_error(k: &FlipKernels, r: [f32; 5], t: [f32; 5]) -> f32 {
    let d = hyab([r[0], r[1], r[2]], [t[0], t[1], t[2]]);
    let c = pow_fast(d, QC);
    let colour = if c < k.pccmax {
        c * (PT / k.pccmax)
    } else {
        PT + ((c - k.pccmax) / (k.cmax - k.pccmax)) * (1.0 - PT)
    };
    let fe = (r[3] - t[3]).abs().max((r[4] - t[4]).abs());
    // q_f = 0.5: a square root.
    const { assert!(QF == 0.5) };
    let feature = (std::f32::consts::FRAC_1_SQRT_2 * fe).sqrt();
    pow_fast(colour, 1.0 - feature)
}

/// Picks the AVX2 build of a kernel where the processor has it (and a test has not asked
/// for the portable one), else the portable build: both run the same operations in the
/// same order on every lane (no FMA contraction), so they give the same bits.
macro_rules! dispatch {
    ($portable:ident, $avx2:ident, $($arg:expr),*) => {{
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") && !scalar_only() {
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

/// The perceived values of one image over `region` ([`filter_image`], then [`perceive`]).
pub(super) fn perceive_image(
    k: &FlipKernels,
    rgb8: &[u8],
    w: usize,
    h: usize,
    region: &Region,
    s: &mut Scratch,
) -> Perceived {
    dispatch!(
        perceive_image_portable,
        perceive_image_avx2,
        k,
        rgb8,
        w,
        h,
        region,
        s
    )
}

pub(super) fn perceive_image_portable(
    k: &FlipKernels,
    rgb8: &[u8],
    w: usize,
    h: usize,
    region: &Region,
    s: &mut Scratch,
) -> Perceived {
    filter_image(k, rgb8, w, h, region, s);
    perceive(&s.planes, region.len())
}

/// # Safety
/// The processor must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn perceive_image_avx2(
    k: &FlipKernels,
    rgb8: &[u8],
    w: usize,
    h: usize,
    region: &Region,
    s: &mut Scratch,
) -> Perceived {
    filter_image(k, rgb8, w, h, region, s);
    perceive(&s.planes, region.len())
}

/// The error of every pixel of the spans of the test image `rgb8` against the reference's
/// perceived values `r`, into `s.errors`: the test filtered, then perceived and compared
/// pixel by pixel (fused: the test's perceived values are never stored).
pub(super) fn test_errors(
    k: &FlipKernels,
    r: &Perceived,
    rgb8: &[u8],
    w: usize,
    h: usize,
    region: &Region,
    s: &mut Scratch,
) {
    dispatch!(
        test_errors_portable,
        test_errors_avx2,
        k,
        r,
        rgb8,
        w,
        h,
        region,
        s
    )
}

#[inline(always)]
pub(super) fn test_errors_body(
    k: &FlipKernels,
    r: &Perceived,
    rgb8: &[u8],
    w: usize,
    h: usize,
    region: &Region,
    s: &mut Scratch,
) {
    filter_image(k, rgb8, w, h, region, s);
    let n = region.len();
    s.errors.resize(n, 0.0);
    let out = &mut s.errors[..n];
    let t = Pixels::of(&s.planes, n);
    let (rl, ra, rb, re, rp) = (
        &r.lab[0][..n],
        &r.lab[1][..n],
        &r.lab[2][..n],
        &r.edge[..n],
        &r.point[..n],
    );
    for (i, o) in out.iter_mut().enumerate() {
        *o = pixel_error(k, [rl[i], ra[i], rb[i], re[i], rp[i]], t.perceived(i));
    }
}

pub(super) fn test_errors_portable(
    k: &FlipKernels,
    r: &Perceived,
    rgb8: &[u8],
    w: usize,
    h: usize,
    region: &Region,
    s: &mut Scratch,
) {
    test_errors_body(k, r, rgb8, w, h, region, s)
}

/// # Safety
/// The processor must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn test_errors_avx2(
    k: &FlipKernels,
    r: &Perceived,
    rgb8: &[u8],
    w: usize,
    h: usize,
    region: &Region,
    s: &mut Scratch,
) {
    test_errors_body(k, r, rgb8, w, h, region, s)
}

/// Whether a test asked this thread for the portable kernels.
pub(super) fn scalar_only() -> bool {
    SCALAR_ONLY.with(|c| c.get())
}

thread_local! {
    pub(super) static SCALAR_ONLY: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}
