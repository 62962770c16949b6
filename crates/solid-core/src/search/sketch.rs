//! The sketch: every row quantised to one byte per value, scanned to prove rows too far before
//! computing their distance (see the parent module).
//!
//! Row `c` is stored as `lo`, `step` and `dim` codes `k_d` in `0..=255` with
//! `c_d = lo + step·k_d + e_d`, plus `err ≥ ‖e‖₂`. A query `q` is split once into two 7-bit
//! integer vectors and a remainder, `q = s₁·p + s₂·p' + r` with `|p_d|, |p'_d| ≤ 64` and
//! `s₂ = s₁ / 128`, so that `q·k = s₁·(p·k) + s₂·(p'·k) + r·k` takes two integer dot products
//! (on AVX2, `vpmaddubsw`: bytes times signed bytes, no saturation below 255·64·2). Then
//! `q·c = lo·Σq + step·(q·k) + q·e`, `|q·e| ≤ ‖q‖₂·err` (Cauchy–Schwarz) and
//! `step·|r·k| ≤ (255·step)·‖r‖₁`, so `1 − lo·Σq − step·(s₁·(p·k) + s₂·(p'·k))`, less those
//! two terms and a margin for the `f32` rounding of that expression and of the exact distance,
//! is a lower bound of the distance that [`brute_force`] computes. A row whose bound exceeds
//! the current k-th distance cannot be a neighbour; every other row gets its exact distance, so
//! the results are the brute-force results, bit for bit.
//!
//! Layout: rows in blocks of [`SKETCH_BLOCK`]; a block's codes are grouped by four values,
//! `codes[block][group][lane][4]` (the last group padded with zeros), so that one 256-bit
//! register holds four values of eight rows; its parameters are `lo[16]`, `step[16]`, `err[16]`.
//!
//! [`brute_force`]: super::brute_force
mod encode;

use encode::{check_sketch, padded};
pub use encode::{sketch_encode, sketch_len, sketch_rows};

use super::{exact_knn, scan, Best, Cost, Exclude, Neighbor, Probe, Rows};
use crate::Error;
use core::ops::Range;

/// Rows per block of a [`Sketch`] (the codes of a block are interleaved).
pub const SKETCH_BLOCK: usize = 16;

/// `f32` parameters per row: `lo`, `step`, `err`.
const PARAMS: usize = 3;

/// Unit roundoff of `f32`.
const U: f32 = f32::EPSILON / 2.0;

/// The sketch checks how many rows it failed to rule out after 16 blocks, 32, 64, then every 64
/// blocks, over the blocks since the previous check (the first rows are costly while the k-th
/// distance is still loose; what counts is whether it stays costly).
const CHECK_FIRST: usize = 16;
const CHECK_EVERY: usize = 64;

/// The sketch gives up when more than one row in this many needed its exact distance.
const GIVE_UP_SHARE: usize = 8;

/// A sketch of L2-normalised rows (see the module documentation), viewing caller-owned buffers
/// that [`sketch_encode`] filled.
#[derive(Debug, Clone, Copy)]
pub struct Sketch<'a> {
    rows: Rows<'a>,
    codes: &'a [u8],
    params: &'a [f32],
}

impl<'a> Sketch<'a> {
    /// Views the sketch of every row of `rows` in `codes` and `params` (as [`sketch_encode`] left
    /// them).
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`] when a buffer is shorter than [`sketch_len`] says.
    pub fn new(rows: Rows<'a>, codes: &'a [u8], params: &'a [f32]) -> Result<Sketch<'a>, Error> {
        check_sketch(rows.len(), rows.dim(), codes.len(), params.len())?;
        Ok(Sketch {
            rows,
            codes,
            params,
        })
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// `true` when the sketch holds no row.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// Exact k-NN: the same contract and the same results as [`brute_force`](super::brute_force)
    /// over the same rows.
    ///
    /// # Errors
    /// [`Error::LengthMismatch`] when `query.len()` differs from the rows' dimension or the
    /// timestamps of `exclude` are fewer than the rows; [`Error::BufferTooSmall`] when
    /// `out.len() < k`.
    pub fn search(
        &self,
        query: &[f32],
        k: usize,
        exclude: &Exclude<'_>,
        out: &mut [Neighbor],
    ) -> Result<usize, Error> {
        let (dim, n) = (self.rows.dim(), self.rows.len());
        exact_knn(query, dim, n, k, exclude, out, |best| {
            let p = Probe {
                query,
                exclude,
                bound: f32::INFINITY,
            };
            let _ = self.scan(p, 0, false, best, &mut Cost::default());
        })
    }

    /// Offers every allowed row of ids `from..` within `bound` that the bytes cannot rule out to
    /// `best`. With `give_up`, switches to brute force for the remaining rows once more than an
    /// eighth of the rows scanned since the previous check needed their exact distance (the
    /// bytes do not pay then: an exact distance out of order costs a few sequential ones);
    /// returns `false` then. With `parallel`, a long scan is cut into parts that the pool's
    /// threads share, their neighbours merged.
    pub(super) fn scan(
        &self,
        p: Probe<'_>,
        from: usize,
        give_up: bool,
        best: &mut Best<'_>,
        cost: &mut Cost,
    ) -> bool {
        let end = self.rows.len().min(p.exclude.before_id);
        // The parts after the first start from empty heaps: the neighbours `best` holds already
        // bound them all the same.
        let p = Probe {
            bound: best.limit(p.bound),
            ..p
        };
        // A part on this thread.
        let part = |from: usize, to: usize, best: &mut Best<'_>, cost: &mut Cost| {
            avx2_or!(
                self.scan_avx2(p, from..to, give_up, best, cost),
                self.scan_impl(p, from..to, give_up, best, cost)
            )
        };
        #[cfg(feature = "parallel")]
        if let Some(done) = super::split_scan(from, end, SKETCH_BLOCK, best, cost, part) {
            return done;
        }
        part(from, end, best, cost)
    }

    avx2_copy!(
        scan_avx2 = self.scan_impl(
            p: Probe<'_>, ids: Range<usize>, give_up: bool, best: &mut Best<'_>, cost: &mut Cost
        ) -> bool
    );

    /// [`Sketch::scan`] over the ids `ids` on this thread, inlined into each of its compiled
    /// copies.
    #[inline(always)]
    fn scan_impl(
        &self,
        p: Probe<'_>,
        ids: Range<usize>,
        give_up: bool,
        best: &mut Best<'_>,
        cost: &mut Cost,
    ) -> bool {
        let (from, end) = (ids.start, ids.end);
        if best.heap.is_empty() || from >= end {
            return true;
        }
        let Probe {
            query,
            exclude,
            bound,
        } = p;
        let dim = self.rows.dim();
        let bounds = Bounds::new(query);
        let timed = exclude.not_newer_than.is_some();
        let mut limit = best.limit(bound);
        let (mut scanned, mut exact) = (0usize, 0usize);
        // Rows scanned and exact distances at the previous check.
        let (mut scanned_then, mut exact_then) = (0usize, 0usize);
        let first_block = from / SKETCH_BLOCK;
        for b in first_block..end.div_ceil(SKETCH_BLOCK) {
            let done = b - first_block;
            let check = done == CHECK_FIRST
                || done == 2 * CHECK_FIRST
                || (done > 0 && done.is_multiple_of(CHECK_EVERY));
            if give_up && check {
                // The k rows that fill the heap come free in each interval.
                let exact_since = (exact - exact_then).saturating_sub(best.heap.len());
                if GIVE_UP_SHARE * exact_since > scanned - scanned_then {
                    let rest = (b * SKETCH_BLOCK).max(from);
                    cost.sketch_rows += scanned;
                    cost.exact_rows += exact + (end - rest);
                    scan(self.rows, rest..end, p, best);
                    return false;
                }
                (scanned_then, exact_then) = (scanned, exact);
            }
            let width = padded(dim) * SKETCH_BLOCK;
            let codes = &self.codes[b * width..(b + 1) * width];
            let params = &self.params[b * PARAMS * SKETCH_BLOCK..(b + 1) * PARAMS * SKETCH_BLOCK];
            let lb = block(&bounds, codes, params);
            let first = b * SKETCH_BLOCK;
            let mut hits = 0u32;
            for (lane, &l) in lb.iter().enumerate() {
                hits |= u32::from(l <= limit) << lane;
            }
            // Only the lanes of ids `from..end`.
            let lo = from.saturating_sub(first);
            let hi = (end - first).min(SKETCH_BLOCK);
            hits &= ((1u32 << hi) - 1) & !((1u32 << lo) - 1);
            scanned += hi - lo;
            while hits != 0 {
                let id = first + hits.trailing_zeros() as usize;
                hits &= hits - 1;
                if timed && !exclude.allows(id) {
                    continue;
                }
                exact += 1;
                let d = self.rows.dist(query, id);
                if d <= limit {
                    best.offer(Neighbor {
                        id: id as u32,
                        distance: d,
                    });
                    limit = best.limit(bound);
                }
            }
        }
        cost.sketch_rows += scanned;
        cost.exact_rows += exact;
        true
    }
}

/// Groups of four values whose query words [`Bounds`] keeps on the stack (dimensions up to 256);
/// beyond, the words are computed as they are needed (the same words).
const KEPT_GROUPS: usize = 64;

/// The per-query constants of the lower bound.
struct Bounds<'q> {
    q: &'q [f32],
    /// `Σ q_d`.
    sum: f32,
    /// `‖q‖₂`, rounded up.
    norm: f32,
    /// The two scales of the integer query vectors.
    s1: f32,
    s2: f32,
    /// The integer query vectors, four bytes per group (for the first [`KEPT_GROUPS`]).
    hi: [i32; KEPT_GROUPS],
    lo: [i32; KEPT_GROUPS],
    /// Per unit of a row's magnitude `|lo| + 255·step`: `‖r‖₁` of the remainder plus a margin
    /// for rounding.
    per_magnitude: f32,
}

impl<'q> Bounds<'q> {
    fn new(q: &'q [f32]) -> Self {
        let (mut sum, mut l1, mut l2, mut top) = (0.0f32, 0.0f64, 0.0f64, 0.0f32);
        for &x in q {
            sum += x;
            l1 += f64::from(x.abs());
            l2 += f64::from(x) * f64::from(x);
            top = top.max(x.abs());
        }
        let s1 = top / 64.0;
        let s2 = s1 / 128.0;
        let mut b = Bounds {
            q,
            sum,
            norm: (crate::math::sqrt(l2) * (1.0 + 1e-6)) as f32,
            s1,
            s2,
            hi: [0; KEPT_GROUPS],
            lo: [0; KEPT_GROUPS],
            per_magnitude: 0.0,
        };
        let mut rest = 0.0f64;
        for d in 0..q.len() {
            let (_, _, r) = b.split(d);
            rest += r.abs();
        }
        for g in 0..KEPT_GROUPS.min(q.len().div_ceil(4)) {
            (b.hi[g], b.lo[g]) = b.words(g);
        }
        // Rounding of the few products and sums of the bound, of `Σq` and of the exact
        // distance: each below `(dim + 2)·u` times `‖q‖₁` times the row's magnitude; counted
        // four times over.
        let rounding = 4.0 * (q.len() as f64 + 4.0) * f64::from(U) * (l1 + 1.0);
        b.per_magnitude = ((rest * (1.0 + 1e-9) + 1e-30) + rounding) as f32;
        b
    }

    /// Value `d` of the query as `s₁·p + s₂·p' + r`: `(p, p', r)`, with `r` exact (products of
    /// an `f32` by a small integer are exact in `f64`).
    #[inline(always)]
    fn split(&self, d: usize) -> (i8, i8, f64) {
        let x = f64::from(self.q[d]);
        if self.s1 == 0.0 {
            return (0, 0, x);
        }
        let p = libm::round(x / f64::from(self.s1)).clamp(-64.0, 64.0);
        let r1 = x - f64::from(self.s1) * p;
        let p2 = libm::round(r1 / f64::from(self.s2)).clamp(-64.0, 64.0);
        (p as i8, p2 as i8, r1 - f64::from(self.s2) * p2)
    }

    /// The two integer query words of group `g` (four signed bytes each; zero past the end).
    #[inline(always)]
    fn words(&self, g: usize) -> (i32, i32) {
        let (mut hi, mut lo) = ([0u8; 4], [0u8; 4]);
        for j in 0..4 {
            let d = 4 * g + j;
            if d < self.q.len() {
                let (p, p2, _) = self.split(d);
                (hi[j], lo[j]) = (p as u8, p2 as u8);
            }
        }
        (i32::from_le_bytes(hi), i32::from_le_bytes(lo))
    }

    #[inline(always)]
    fn word(&self, g: usize) -> (i32, i32) {
        if g < KEPT_GROUPS {
            (self.hi[g], self.lo[g])
        } else {
            self.words(g)
        }
    }

    /// Lower bounds of the distances to the 16 rows of a block from their integer dot products
    /// with the two query vectors (1 at most).
    #[inline(always)]
    fn finish(&self, dots: [[i32; SKETCH_BLOCK]; 2], params: &[f32]) -> [f32; SKETCH_BLOCK] {
        let (lo, rest) = params.split_at(SKETCH_BLOCK);
        let (step, err) = rest.split_at(SKETCH_BLOCK);
        let mut lb = [0.0f32; SKETCH_BLOCK];
        for r in 0..SKETCH_BLOCK {
            let qk = self.s1 * dots[0][r] as f32 + self.s2 * dots[1][r] as f32;
            let approx = lo[r] * self.sum + step[r] * qk;
            let magnitude = lo[r].abs() + 255.0 * step[r];
            let slack = err[r] * self.norm + self.per_magnitude * magnitude + 64.0 * U;
            lb[r] = (1.0 - approx - slack).min(1.0);
        }
        lb
    }
}

/// The lower bounds of one block (16 rows), with AVX2 when `std` detects it (the same integer
/// dot products either way).
#[inline(always)]
fn block(b: &Bounds<'_>, codes: &[u8], params: &[f32]) -> [f32; SKETCH_BLOCK] {
    b.finish(avx2_or!(avx2::dots(b, codes), dots(b, codes)), params)
}

/// The integer dot products of the 16 rows of a block with the two query vectors.
#[inline(always)]
fn dots(b: &Bounds<'_>, codes: &[u8]) -> [[i32; SKETCH_BLOCK]; 2] {
    let mut acc = [[0i32; SKETCH_BLOCK]; 2];
    for (g, group) in codes.chunks_exact(4 * SKETCH_BLOCK).enumerate() {
        let (hi, lo) = b.word(g);
        let (hi, lo) = (hi.to_le_bytes(), lo.to_le_bytes());
        for (lane, k) in group.chunks_exact(4).enumerate() {
            for j in 0..4 {
                let k = i32::from(k[j]);
                acc[0][lane] += k * i32::from(hi[j] as i8);
                acc[1][lane] += k * i32::from(lo[j] as i8);
            }
        }
    }
    acc
}

/// [`dots`] with AVX2: `vpmaddubsw` multiplies the code bytes by the signed query bytes and adds
/// pairs (at most 255·64·2, no saturation), `vpmaddwd` by ones adds the pairs into one 32-bit
/// sum per row and group. Loads go through `bytemuck`, so nothing here is `unsafe`.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
mod avx2 {
    use super::{Bounds, SKETCH_BLOCK};
    use core::arch::x86_64::{
        __m256i, _mm256_add_epi32, _mm256_madd_epi16, _mm256_maddubs_epi16, _mm256_set1_epi16,
        _mm256_set1_epi32, _mm256_setzero_si256,
    };

    #[inline(always)]
    fn load(s: &[u8]) -> __m256i {
        let s: &[u8; 32] = s.try_into().unwrap_or(&[0; 32]);
        bytemuck::cast(*s)
    }

    #[target_feature(enable = "avx2")]
    pub(super) fn dots(b: &Bounds<'_>, codes: &[u8]) -> [[i32; SKETCH_BLOCK]; 2] {
        let ones = _mm256_set1_epi16(1);
        let mut acc = [_mm256_setzero_si256(); 4];
        for (g, group) in codes.chunks_exact(4 * SKETCH_BLOCK).enumerate() {
            let (hi, lo) = b.word(g);
            let (hi, lo) = (_mm256_set1_epi32(hi), _mm256_set1_epi32(lo));
            let (c0, c1) = (load(&group[..32]), load(&group[32..]));
            let sum = |acc: __m256i, c: __m256i, p: __m256i| {
                _mm256_add_epi32(acc, _mm256_madd_epi16(_mm256_maddubs_epi16(c, p), ones))
            };
            acc[0] = sum(acc[0], c0, hi);
            acc[1] = sum(acc[1], c1, hi);
            acc[2] = sum(acc[2], c0, lo);
            acc[3] = sum(acc[3], c1, lo);
        }
        let lanes: [[i32; 8]; 4] = bytemuck::cast(acc);
        let mut out = [[0i32; SKETCH_BLOCK]; 2];
        out[0][..8].copy_from_slice(&lanes[0]);
        out[0][8..].copy_from_slice(&lanes[1]);
        out[1][..8].copy_from_slice(&lanes[2]);
        out[1][8..].copy_from_slice(&lanes[3]);
        out
    }
}
