//! The bound pass: register tiles of gradients, the per-task kernel (portable and AVX2),
//! the per-set memo and the accumulators of chunk sums.

use super::*;

/// Targets per register tile, candidates per block, targets per cache tile and
/// candidates per parallel task of [`Screen::bounds`].
pub(super) const TT: usize = 4;
pub(super) const CB: usize = 4;
pub(super) const TB: usize = 64;
pub(super) const CT: usize = 64;

/// `acc[a][b] = sum_k x[k][a] y[k * lp + t0 + b]` for `k` in order (the sums of
/// [`ChanState::unchanged_adding`]'s gradient, entry by entry).
#[inline(always)]
pub(super) fn tile(x: &[[f64; CB]], y: &[f64], lp: usize, t0: usize) -> [[f64; TT]; CB] {
    let mut acc = [[0.0f64; TT]; CB];
    for (k, xk) in x.iter().enumerate() {
        let yk: [f64; TT] = y[k * lp + t0..k * lp + t0 + TT].try_into().expect("tile");
        for a in 0..CB {
            for b in 0..TT {
                acc[a][b] += xk[a] * yk[b];
            }
        }
    }
    acc
}

/// The chunk sums of the bounds of one task's candidates and, at the loose level, their
/// rows of signs: with AVX2 where the CPU has it (the same operations, so the same numbers,
/// in wider registers).
pub(super) fn task_bounds(
    sc: &Screen<'_>,
    task: &[usize],
    tight: bool,
) -> (Vec<Vec<f64>>, Vec<u64>) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked above).
        return unsafe {
            if tight {
                task_bounds_avx2::<true>(sc, task)
            } else {
                task_bounds_avx2::<false>(sc, task)
            }
        };
    }
    if tight {
        task_bounds_body::<true>(sc, task)
    } else {
        task_bounds_body::<false>(sc, task)
    }
}

/// [`task_bounds_body`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn task_bounds_avx2<const TIGHT: bool>(
    sc: &Screen<'_>,
    task: &[usize],
) -> (Vec<Vec<f64>>, Vec<u64>) {
    task_bounds_body::<TIGHT>(sc, task)
}

/// Asks for the cache lines of `v` (a hint; no effect on any value).
#[inline(always)]
pub(super) fn prefetch(v: &[f64]) {
    #[cfg(target_arch = "x86_64")]
    for k in (0..v.len()).step_by(8) {
        // SAFETY: a prefetch of an address inside `v` (SSE, in the x86_64 baseline).
        unsafe {
            std::arch::x86_64::_mm_prefetch(
                v.as_ptr().add(k).cast::<i8>(),
                std::arch::x86_64::_MM_HINT_T0,
            );
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = v;
}

/// `sig = S x` for the symmetric `ni x ni` matrix `S` (by its rows, as `axpy`s), and
/// `x . sig`.
#[inline(always)]
pub(super) fn schur1(sm: &[f64], x: &[f64], sig: &mut [f64]) -> f64 {
    let ni = x.len();
    sig.fill(0.0);
    for (row, &xl) in sm.chunks_exact(ni.max(1)).zip(x) {
        for (sv, &r) in sig.iter_mut().zip(row) {
            *sv += r * xl;
        }
    }
    x.iter().zip(&*sig).map(|(a, b)| a * b).sum()
}

/// Per group of targets with the same passive set ([`Targets`]), per candidate of a task:
/// `a_I . S a_I` and `S a_I` (`1 + ni` values), computed on first use. One arena per task,
/// reused from channel to channel: only the slots used are written.
#[derive(Default)]
pub(super) struct Memo {
    /// Per group and candidate (`group * CT + candidate`): the offset of its values in
    /// `vals` (`u32::MAX`: not computed yet).
    pub(super) at: Vec<u32>,
    pub(super) vals: Vec<f64>,
    pub(super) x: Vec<f64>,
}

impl Memo {
    /// Forgets every value, for `groups` groups.
    pub(super) fn reset(&mut self, groups: usize) {
        self.at.clear();
        self.at.resize(groups * CT, u32::MAX);
        self.vals.clear();
    }

    /// `(a_I . S a_I, S a_I)` of candidate `ca` (`< CT`, row `arow` of `a`) for group `gr`
    /// of `d`.
    #[inline(always)]
    pub(super) fn get(&mut self, d: &Targets, gr: usize, ca: usize, arow: &[f64]) -> (f64, &[f64]) {
        let (lo, hi) = (d.goff[gr], d.goff[gr + 1]);
        let ni = hi - lo;
        let key = gr * CT + ca;
        let mut o = self.at[key] as usize;
        if self.at[key] == u32::MAX {
            o = self.vals.len();
            self.at[key] = u32::try_from(o).expect("memo arena below 2^32 values");
            self.x.clear();
            self.x
                .extend(d.inact[lo..hi].iter().map(|&r| arow[r as usize]));
            let sm = &d.s[d.gsoff[gr]..d.gsoff[gr] + ni * ni];
            self.vals.resize(o + 1 + ni, 0.0);
            let (q, sig) = self.vals[o..].split_first_mut().expect("1 + ni");
            *q = schur1(sm, &self.x, sig);
        }
        (self.vals[o], &self.vals[o + 1..o + 1 + ni])
    }
}

/// Calls `f(ca, i, C_ct, w)` for each pair of a task's candidate `ca` (`rows(ca)`: its bits
/// over the materials) and a live target at position `i` whose bit is set in `mask` (but
/// the candidate's own), with its gradient ([`with_gradients`]): word by word of targets,
/// so that the coefficients of 64 targets stay in cache across the task's candidates, then
/// candidate by candidate (for each candidate, the targets come in increasing order).
#[inline(always)]
pub(super) fn pairs_by_word<'r>(
    task: &[usize],
    blocks: &[Block<'_>],
    rows: impl Fn(usize) -> &'r [u64],
    mask: &[u64],
    (live, live_pos, yt, nk): (&[usize], &[usize], &[f64], usize),
    ids: &mut Vec<u32>,
    mut f: impl FnMut(usize, usize, f64, f64),
) {
    for (wi, &m) in mask.iter().enumerate() {
        if m == 0 {
            continue;
        }
        // The cosines of the next word's pairs, one row segment per candidate: too many
        // streams for the hardware prefetcher.
        if let Some(&mn) = mask.get(wi + 1) {
            for ca in 0..task.len() {
                let (blk, a) = (&blocks[ca / CB], ca % CB);
                let b = rows(ca)[wi + 1] & mn;
                let row = blk.rows[a];
                for byte in 0..8 {
                    if (b >> (8 * byte)) & 0xff != 0 {
                        // Materials `t..t + 8`: cosines `t + 1..=t + 8`, one or two lines.
                        let t = (wi + 1) * 64 + 8 * byte;
                        let hi = (t + 8).min(row.len() - 1);
                        prefetch(&row[t + 1..=t + 1]);
                        prefetch(&row[hi..=hi]);
                    }
                }
            }
        }
        for (ca, &cand) in task.iter().enumerate() {
            let (blk, a) = (&blocks[ca / CB], ca % CB);
            let mut b = rows(ca)[wi] & m;
            if blk.zero[a] || b == 0 {
                continue;
            }
            ids.clear();
            while b != 0 {
                let t = wi * 64 + b.trailing_zeros() as usize;
                b &= b - 1;
                if t != cand {
                    ids.push(live_pos[t] as u32);
                }
            }
            with_gradients(blk, a, (live, yt, nk), ids, |i, cjt, w| f(ca, i, cjt, w));
        }
    }
}

/// Calls `f(i, C_ct, w)` for each live position `i` of `ids` (target `t`), with the gradient
/// `w = C_ct - sum_k C_ck y_tk` of candidate `a` of `blk` (coefficients `yt`, row-major with
/// `nk` per target), each summed in the order of [`tile`]'s entries (so equal to them bit for
/// bit), four targets at a time.
#[inline(always)]
pub(super) fn with_gradients(
    blk: &Block<'_>,
    a: usize,
    (live, yt, nk): (&[usize], &[f64], usize),
    ids: &[u32],
    mut f: impl FnMut(usize, f64, f64),
) {
    let row = blk.rows[a];
    let mut quads = ids.chunks_exact(4);
    for q in &mut quads {
        let i: [usize; 4] = std::array::from_fn(|b| q[b] as usize);
        let y: [&[f64]; 4] = std::array::from_fn(|b| &yt[i[b] * nk..(i[b] + 1) * nk]);
        let mut acc = [0.0f64; 4];
        for (k, xk) in blk.xg.iter().enumerate() {
            for b in 0..4 {
                acc[b] += xk[a] * y[b][k];
            }
        }
        for b in 0..4 {
            let cjt = row[live[i[b]] + 1];
            f(i[b], cjt, cjt - acc[b]);
        }
    }
    for &i in quads.remainder() {
        let i = i as usize;
        let mut acc = 0.0;
        for (xk, &yk) in blk.xg.iter().zip(&yt[i * nk..(i + 1) * nk]) {
            acc += xk[a] * yk;
        }
        let cjt = row[live[i] + 1];
        f(i, cjt, cjt - acc);
    }
}

/// A running sum of one candidate's bound adjustments, added to its chunk sum whenever the
/// chunk changes (chunks come in increasing order): each chunk sum takes a few additions,
/// whatever the number of pairs.
pub(super) struct Acc {
    pub(super) chunk: usize,
    pub(super) sum: f64,
}

impl Acc {
    const NONE: Self = Self {
        chunk: usize::MAX,
        sum: 0.0,
    };

    #[inline(always)]
    pub(super) fn add(&mut self, chunks: &mut [f64], k: usize, v: f64) {
        if k != self.chunk {
            self.flush(chunks);
            self.chunk = k;
        }
        self.sum += v;
    }

    #[inline(always)]
    pub(super) fn flush(&mut self, chunks: &mut [f64]) {
        if self.chunk != usize::MAX {
            chunks[self.chunk] += self.sum;
        }
        *self = Self::NONE;
    }
}

/// The body of [`task_bounds`], per channel: every chunk sum starts from the `q_t` of its
/// targets (every pair unchanged), and each pair whose optimum may change adds `lb - q_t`.
/// Loose level: the fresh targets' gradients by register tiles (their signs set in the
/// rows), then the carried targets' positive pairs; tight level: every positive pair from
/// the signs ([`Memo`] per passive set and candidate, then [`pair_bound`]).
///
/// Long function: the screen's innermost kernel, inlined into its two levels (`TIGHT`)
/// with register tiles unrolled by hand; a call boundary inside would cost the tiles
/// their registers.
#[inline(always)]
pub(super) fn task_bounds_body<const TIGHT: bool>(
    sc: &Screen<'_>,
    task: &[usize],
) -> (Vec<Vec<f64>>, Vec<u64>) {
    let Screen {
        obj,
        live,
        cols,
        ref tg,
        ref proj,
        basis_nonneg,
        margin_dual,
        xsum,
        ref live_pos,
        words,
        ref old,
        ..
    } = *sc;
    let nl = live.len();
    let nk = cols.len();
    let nchunks = nl.div_ceil(CHUNK);
    let nt = task.len();
    let mut chunks = vec![vec![0.0; nchunks]; nt];
    let mut rows: Vec<u64> = if TIGHT {
        Vec::new()
    } else {
        vec![0; nt * 3 * words]
    };
    // Per chunk, the sum of the `q_t` it starts from: every partial sum of the chunk is at
    // most twice it in magnitude, which bounds the rounding of the adjusted sums.
    let mut slack = vec![vec![0.0; nchunks]; nt];
    let mut memo = Memo::default();
    let mut accs: Vec<Acc> = (0..nt).map(|_| Acc::NONE).collect();
    let mut ids: Vec<u32> = Vec::new();
    for (c, d) in tg.iter().enumerate() {
        if TIGHT {
            memo.reset(d.goff.len() - 1);
        }
        let g = obj.view(c);
        let bs = &proj[c];
        let p = bs.nz.len();
        let blocks: Vec<Block<'_>> = task
            .chunks(CB)
            .map(|blk| {
                let nb = blk.len();
                let j: [usize; CB] = std::array::from_fn(|a| blk[a.min(nb - 1)] + 1);
                let xg: Vec<[f64; CB]> = cols
                    .iter()
                    .map(|&k| std::array::from_fn(|a| g.at(j[a], k)))
                    .collect();
                let nc: [f64; CB] = std::array::from_fn(|a| 1.0 - bs.nrm[j[a]]);
                Block {
                    nb,
                    own: std::array::from_fn(|a| live_pos[j[a] - 1]),
                    zero: std::array::from_fn(|a| g.at(j[a], j[a]) == 0.0),
                    nc,
                    rows: std::array::from_fn(|a| g.row(j[a])),
                    nonneg: std::array::from_fn(|a| {
                        basis_nonneg[c] && xg.iter().all(|x| x[a] >= 0.0)
                    }),
                    ea: std::array::from_fn(|a| {
                        let r = &bs.a[j[a] * p..(j[a] + 1) * p];
                        let anorm = r.iter().map(|x| x * x).sum::<f64>().sqrt();
                        bs.e64 * (bs.sk + bs.kappa * anorm)
                    }),
                    xg,
                }
            })
            .collect();
        // Every pair starts at `q_t` (unchanged); a changed pair adds `lb - q_t`.
        let chunk_sum = |k: usize, own: usize| -> f64 {
            let end = ((k + 1) * CHUNK).min(nl);
            (k * CHUNK..end)
                .filter(|&i| i != own && d.active[i])
                .map(|i| d.share[i] * d.q[i])
                .sum()
        };
        let base: Vec<f64> = (0..nchunks).map(|k| chunk_sum(k, usize::MAX)).collect();
        for (ca, ch) in chunks.iter_mut().enumerate() {
            let own = live_pos[task[ca]];
            for (k, (v, sl)) in ch.iter_mut().zip(slack[ca].iter_mut()).enumerate() {
                let b = if own / CHUNK == k {
                    chunk_sum(k, own)
                } else {
                    base[k]
                };
                *v += b;
                *sl += b;
            }
        }
        if TIGHT {
            // Every positive pair, from the signs.
            let rows = |ca: usize| {
                let signs = sc.signs(task[ca]).expect("the loose level first");
                &signs[c * words..(c + 1) * words]
            };
            let data = (live, &live_pos[..], &d.yt[..], nk);
            pairs_by_word(
                task,
                &blocks,
                rows,
                &d.liveact,
                data,
                &mut ids,
                |ca, i, cjt, w| {
                    let (blk, a) = (&blocks[ca / CB], ca % CB);
                    let j = task[ca] + 1;
                    let arow = &bs.a[j * p..(j + 1) * p];
                    let t = live[i];
                    let (quad, sig) = if d.tight[i] {
                        memo.get(d, d.grp[i] as usize, ca, arow)
                    } else {
                        (0.0, &[][..])
                    };
                    let lb = pair_bound(
                        &Pair {
                            w,
                            cjt,
                            s2: blk.nc[a],
                            arow,
                            ea: blk.ea[a],
                            nonneg: blk.nonneg[a],
                        },
                        d,
                        i,
                        bs,
                        (g.row(t + 1), t + 1),
                        margin_dual,
                        xsum,
                        (quad, sig),
                    );
                    accs[ca].add(&mut chunks[ca], i / CHUNK, d.share[i] * (lb - d.q[i]));
                },
            );
            for (acc, ch) in accs.iter_mut().zip(chunks.iter_mut()) {
                acc.flush(ch);
            }
            continue;
        }
        // Per candidate of each block, the loose bound's coefficients ([`LooseCoef`]).
        let coefs: Vec<[LooseCoef; CB]> = blocks
            .iter()
            .map(|blk| {
                std::array::from_fn(|a| {
                    LooseCoef::new(blk.nonneg[a], blk.nc[a], bs.e64 * bs.sk, xsum)
                })
            })
            .collect();
        // The loose bound of one pair with a positive gradient `w`, target `i`, candidate
        // `a` of block `bi`.
        let loose = |bi: usize, a: usize, i: usize, w: f64| -> f64 {
            let q = d.q[i];
            d.share[i] * (coefs[bi][a].bound(q, w, d.werr[i], margin_dual) - q)
        };
        // The carried signs that hold.
        if let Some(o) = old {
            for (ca, &cand) in task.iter().enumerate() {
                let orow = &o.rows(cand)[c * words..(c + 1) * words];
                let nrow = &mut rows[(ca * 3 + c) * words..(ca * 3 + c + 1) * words];
                for ((n, &r), &m) in nrow.iter_mut().zip(orow).zip(&d.keep) {
                    *n = r & m;
                }
            }
        }
        // The fresh targets, by register tiles.
        let (lf, fresh) = (d.lf, &d.fresh);
        let nf = fresh.iter().take_while(|&&i| i != u32::MAX).count();
        for t0 in (0..lf).step_by(TB) {
            let t1 = (t0 + TB).min(lf);
            // The candidates' cosines with the next tile's targets: one stream per
            // candidate, too many for the hardware prefetcher to follow (when the tile's
            // targets lie close together).
            if t1 < nf {
                let lo = live[fresh[t1] as usize] + 1;
                let hi = live[fresh[(t1 + TB).min(nf) - 1] as usize] + 1;
                if hi - lo < 4 * TB {
                    for blk in &blocks {
                        for row in &blk.rows[..blk.nb] {
                            prefetch(&row[lo..=hi]);
                        }
                    }
                }
            }
            for (bi, blk) in blocks.iter().enumerate() {
                for u0 in (t0..t1).step_by(TT) {
                    let gw = tile(&blk.xg, &d.y, lf, u0);
                    let pos: [usize; TT] = std::array::from_fn(|b| fresh[u0 + b] as usize);
                    let valid: u32 = (0..TT).fold(0, |m, b| m | (u32::from(pos[b] < nl) << b));
                    let tix: [usize; TT] =
                        std::array::from_fn(|b| if pos[b] < nl { live[pos[b]] + 1 } else { 0 });
                    // Live targets are increasing: four in a row are one load per row.
                    let run = valid == (1 << TT) - 1 && tix[TT - 1] == tix[0] + (TT - 1);
                    let hm: [f64; TT] =
                        std::array::from_fn(|b| if pos[b] < nl { d.hmax[pos[b]] } else { 0.0 });
                    let ys: [f64; TT] =
                        std::array::from_fn(|b| if pos[b] < nl { d.ysum[pos[b]] } else { 0.0 });
                    for (a, gwa) in gw.iter().enumerate().take(blk.nb) {
                        if blk.zero[a] {
                            continue;
                        }
                        let row = blk.rows[a];
                        let cj: [f64; TT] = if run {
                            row[tix[0]..tix[0] + TT].try_into().expect("tile")
                        } else {
                            std::array::from_fn(|b| row[tix[b]])
                        };
                        let w: [f64; TT] = std::array::from_fn(|b| cj[b] - gwa[b]);
                        let thr: [f64; TT] =
                            std::array::from_fn(|b| KKT_TOL * (hm[b].max(cj[b].abs()) + ys[b]));
                        // Branch-free (about one pair in ten goes on, at random): the pairs
                        // with a positive gradient. Not `>`: a NaN gradient is not
                        // "unchanged", as in the test of `ChanState::q_adding`.
                        #[allow(clippy::neg_cmp_op_on_partial_ord)]
                        let up: [bool; TT] = std::array::from_fn(|b| !(w[b] <= thr[b]));
                        let mut m = up
                            .iter()
                            .enumerate()
                            .fold(0u32, |m, (b, &u)| m | (u32::from(u) << b))
                            & valid;
                        if m == 0 {
                            continue;
                        }
                        let ca = bi * CB + a;
                        let nrow = &mut rows[(ca * 3 + c) * words..(ca * 3 + c + 1) * words];
                        let own = blk.own[a];
                        while m != 0 {
                            let b = m.trailing_zeros() as usize;
                            m &= m - 1;
                            let t = tix[b] - 1;
                            nrow[t / 64] |= 1 << (t % 64);
                            // The candidate's own target does not count.
                            if pos[b] != own {
                                let v = loose(bi, a, pos[b], w[b]);
                                accs[ca].add(&mut chunks[ca], pos[b] / CHUNK, v);
                            }
                        }
                    }
                }
            }
        }
        for (acc, ch) in accs.iter_mut().zip(chunks.iter_mut()) {
            acc.flush(ch);
        }
        // The carried targets' positive pairs.
        if let Some(o) = old {
            let rows = |ca: usize| &o.rows(task[ca])[c * words..(c + 1) * words];
            let data = (live, &live_pos[..], &d.yt[..], nk);
            pairs_by_word(
                task,
                &blocks,
                rows,
                &d.keep,
                data,
                &mut ids,
                |ca, i, _, w| {
                    let v = loose(ca / CB, ca % CB, i, w);
                    accs[ca].add(&mut chunks[ca], i / CHUNK, v);
                },
            );
            for (acc, ch) in accs.iter_mut().zip(chunks.iter_mut()) {
                acc.flush(ch);
            }
        }
    }
    let round = 4.0 * (CHUNK + 1) as f64 * f64::EPSILON;
    for (ch, sl) in chunks.iter_mut().zip(&slack) {
        for (v, &b) in ch.iter_mut().zip(sl) {
            *v = (*v - round * b).max(0.0);
        }
    }
    (chunks, rows)
}
