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

use super::{check_out, check_query, scan, Best, Cost, Exclude, Neighbor, Rows};
use crate::Error;

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

/// Lengths of the code buffer (bytes) and of the parameter buffer (`f32`s) of a sketch of `n`
/// rows of `dim` values: whole blocks of [`SKETCH_BLOCK`] rows, `dim` bytes rounded up to a
/// multiple of 4 and 12 parameter bytes per row.
pub fn sketch_len(n: usize, dim: usize) -> (usize, usize) {
    let rows = n.div_ceil(SKETCH_BLOCK) * SKETCH_BLOCK;
    (rows * padded(dim), rows * PARAMS)
}

/// Rows whose parameters a sketch's `params` values hold (whole blocks): the sketch covers that
/// many rows, or all of them when there are fewer (see [`Index::new`](super::Index::new)).
pub fn sketch_rows(params: usize) -> usize {
    params / PARAMS
}

/// `dim` rounded up to a whole number of groups of four values.
fn padded(dim: usize) -> usize {
    dim.next_multiple_of(4)
}

/// Where parameter `p` (0: `lo`, 1: `step`, 2: `err`) of lane `lane` sits in its block's
/// parameters.
#[inline(always)]
fn param(p: usize, lane: usize) -> usize {
    p * SKETCH_BLOCK + lane
}

/// Where value `d` of lane `lane` sits in its block's codes.
#[inline(always)]
fn at(d: usize, lane: usize) -> usize {
    ((d / 4) * SKETCH_BLOCK + lane) * 4 + d % 4
}

fn check_sketch(n: usize, dim: usize, codes: usize, params: usize) -> Result<(), Error> {
    let (nc, np) = sketch_len(n, dim);
    if codes < nc {
        return Err(Error::BufferTooSmall {
            buffer: "codes",
            needed: nc,
            got: codes,
        });
    }
    if params < np {
        return Err(Error::BufferTooSmall {
            buffer: "params",
            needed: np,
            got: params,
        });
    }
    Ok(())
}

/// Encodes rows `from..n` of `rows` into the sketch buffers, which must be at least
/// [`sketch_len`]`(n, dim)` long; rows before `from` are left as they are, so a growing database
/// encodes each new row once. Unused lanes of the last block are zeroed. Allocates nothing.
///
/// # Errors
/// [`Error::InvalidParameter`] for a `from` beyond the rows; [`Error::BufferTooSmall`] when a
/// buffer is too short.
pub fn sketch_encode(
    rows: Rows<'_>,
    from: usize,
    codes: &mut [u8],
    params: &mut [f32],
) -> Result<(), Error> {
    let (n, dim) = (rows.len(), rows.dim());
    if from > n {
        return Err(Error::InvalidParameter {
            name: "from",
            value: from as f64,
            expected: "at most the number of rows",
        });
    }
    check_sketch(n, dim, codes.len(), params.len())?;
    let first = from / SKETCH_BLOCK;
    let blocks = n.div_ceil(SKETCH_BLOCK);
    let width = padded(dim) * SKETCH_BLOCK;
    let codes = &mut codes[first * width..blocks * width];
    let params = &mut params[first * PARAMS * SKETCH_BLOCK..blocks * PARAMS * SKETCH_BLOCK];
    let block = |(b, (codes, params)): (usize, (&mut [u8], &mut [f32]))| {
        let start = (first + b) * SKETCH_BLOCK;
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        if std::is_x86_feature_detected!("avx2") {
            #[allow(unsafe_code)]
            // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
            // calling a function compiled with `#[target_feature(enable = "avx2")]`.
            unsafe {
                encode_block_avx2(rows, start, from, codes, params);
            }
            return;
        }
        encode_block(rows, start, from, codes, params);
    };
    #[cfg(feature = "parallel")]
    if let Some(threads) = (blocks - first >= PARALLEL_BLOCKS)
        .then(crate::pool::work)
        .flatten()
    {
        use rayon::iter::{IndexedParallelIterator, ParallelIterator};
        use rayon::slice::ParallelSliceMut;
        threads.install(|| {
            codes
                .par_chunks_mut(width)
                .zip(params.par_chunks_mut(PARAMS * SKETCH_BLOCK))
                .enumerate()
                .with_min_len(PARALLEL_BLOCKS / 4)
                .for_each(block)
        });
        return Ok(());
    }
    codes
        .chunks_mut(width)
        .zip(params.chunks_mut(PARAMS * SKETCH_BLOCK))
        .enumerate()
        .for_each(block);
    Ok(())
}

/// From this many blocks on, `sketch_encode` shares them among the threads (`parallel`).
#[cfg(feature = "parallel")]
const PARALLEL_BLOCKS: usize = 1024;

/// [`encode_block`] compiled for AVX2: the same operations in the same order (no FMA), so the
/// same bits, with eight `f32` values per instruction.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx2")]
fn encode_block_avx2(
    rows: Rows<'_>,
    start: usize,
    from: usize,
    codes: &mut [u8],
    params: &mut [f32],
) {
    encode_block(rows, start, from, codes, params);
}

/// Encodes the rows of the block starting at row `start` (those from `from` on): first the
/// range of every row, then their codes, then their error bounds, so that one row's chain of
/// dependent minima, maxima, divisions and square root overlaps the next rows' instead of
/// holding up its own codes. With [`row_range`]'s loop, `sketch_encode` of 10,000 HKU rows on
/// one thread took 0.35 ms instead of 0.61 (release probe, AMD EPYC), with the same bits.
#[inline(always)]
fn encode_block(rows: Rows<'_>, start: usize, from: usize, codes: &mut [u8], params: &mut [f32]) {
    let mut ranges = [(0.0f32, 0.0f32); SKETCH_BLOCK];
    for (lane, range) in ranges.iter_mut().enumerate() {
        let i = start + lane;
        if i >= from && i < rows.len() {
            *range = row_range(rows, i);
        }
    }
    // Then the codes, with what each row's error bound needs.
    let mut errors = [None; SKETCH_BLOCK];
    for (lane, (&range, error)) in ranges.iter().zip(&mut errors).enumerate() {
        let i = start + lane;
        if i >= from {
            *error = encode_row(rows, i, lane, range, codes, params);
        }
    }
    // Then the error bounds (a square root each), in a loop of their own for the same reason.
    for (lane, (error, &(lo, hi))) in errors.iter().zip(&ranges).enumerate() {
        if let Some((sum, step)) = *error {
            params[param(2, lane)] = error_bound(sum, lo, hi, step, rows.dim());
        }
    }
}

/// The least and the largest of the normalised values of row `i` as `f32` computes them
/// (`raw × scale`); a NaN is skipped, as `f32::min` does (the row's squared errors then sum to
/// NaN, which [`error_bound`] turns into an infinite error).
#[inline(always)]
fn row_range(rows: Rows<'_>, i: usize) -> (f32, f32) {
    // Lanes of eight, so that the compiler vectorises.
    let (raw, scale) = rows.raw_row(i);
    let (mut lo8, mut hi8) = ([f32::INFINITY; 8], [f32::NEG_INFINITY; 8]);
    let eights = raw.chunks_exact(8);
    // Plain comparisons, which compile to single min/max instructions, in a loop over the lanes:
    // a closure given each lane's index made the compiler blend the comparisons through packed
    // masks instead (0.55 ms for the 10,000 rows above instead of 0.35).
    #[inline(always)]
    fn take(lo: &mut [f32; 8], hi: &mut [f32; 8], values: &[f32], scale: f32) {
        for ((lo, hi), &v) in lo.iter_mut().zip(hi.iter_mut()).zip(values) {
            let x = v * scale;
            *lo = if x < *lo { x } else { *lo };
            *hi = if x > *hi { x } else { *hi };
        }
    }
    take(&mut lo8, &mut hi8, eights.remainder(), scale);
    for c in eights {
        take(&mut lo8, &mut hi8, c, scale);
    }
    let lo = lo8.iter().fold(f32::INFINITY, |m, &v| m.min(v));
    let hi = hi8.iter().fold(f32::NEG_INFINITY, |m, &v| m.max(v));
    (lo, hi)
}

/// Writes the codes and parameters but the error of row `i` into lane `lane` of its block, from
/// the row's normalised values taken exactly and its [`row_range`] `(lo, hi)`, and returns what
/// [`error_bound`] needs besides: the `f32` sum of the squared errors, and the step. Rows beyond
/// the end (of a last, partial block) get zeros, their error too, and `None`.
#[inline(always)]
fn encode_row(
    rows: Rows<'_>,
    i: usize,
    lane: usize,
    (lo, hi): (f32, f32),
    codes: &mut [u8],
    params: &mut [f32],
) -> Option<(f32, f32)> {
    let dim = rows.dim();
    for d in dim..padded(dim) {
        codes[at(d, lane)] = 0;
    }
    if i >= rows.len() {
        for d in 0..dim {
            codes[at(d, lane)] = 0;
        }
        for p in 0..PARAMS {
            params[param(p, lane)] = 0.0;
        }
        return None;
    }
    // Lanes of eight (and four below), so that the compiler vectorises; the row's values are
    // `raw × scale` (normalised), taken in whole groups of four as the codes are laid out.
    let (raw, scale) = rows.raw_row(i);
    // Any `lo`, `step` and codes will do: the error is measured against what is stored, from
    // the exact normalised values, so the codes may come from rounded ones (the cast rounds half
    // up and saturates into 0..=255).
    let step = (hi - lo) / 255.0;
    let inv = crate::math::inverse_step(step);
    // Each value's code, and the square of its error as `f32` computes it into eight lanes (see
    // [`error_bound`] for how far that may be from the exact error).
    let mut sq = [0.0f32; 8];
    let code = |v: f32| {
        let x = v * scale;
        // Round half up, saturating into 0..=255 (NaN to 0).
        let k = crate::math::floor_to_u8((x - lo) * inv + 0.5);
        (k, x - (lo + step * f32::from(k)))
    };
    // Eight values (two groups of four) at a time, so that the compiler vectorises, then the
    // last ones (the padding codes of a partial group were zeroed above).
    let eights = raw.chunks_exact(8);
    let rest = eights.remainder();
    for (h, eight) in eights.enumerate() {
        let mut k = [0u8; 8];
        for (j, &v) in eight.iter().enumerate() {
            let (kj, e) = code(v);
            k[j] = kj;
            sq[j] += e * e;
        }
        let at = (2 * h * SKETCH_BLOCK + lane) * 4;
        codes[at..at + 4].copy_from_slice(&k[..4]);
        let at = at + SKETCH_BLOCK * 4;
        codes[at..at + 4].copy_from_slice(&k[4..]);
    }
    let base = raw.len() - rest.len();
    for (j, &v) in rest.iter().enumerate() {
        let (kj, e) = code(v);
        codes[at(base + j, lane)] = kj;
        sq[j] += e * e;
    }
    let sum = ((sq[0] + sq[4]) + (sq[1] + sq[5])) + ((sq[2] + sq[6]) + (sq[3] + sq[7]));
    params[param(0, lane)] = if lo.is_finite() { lo } else { 0.0 };
    params[param(1, lane)] = if step.is_finite() { step } else { 0.0 };
    Some((sum, step))
}

/// Rows of more than this many values get an infinite error (are never ruled out): the bound of
/// [`error_bound`] holds while `(dim + 8)·u ≤ 0.01`. ([`Rows`] refuses rows of more than 65,535
/// values, so no row reaches it today: it keeps the proof true should that limit grow.)
const MAX_BOUNDED_DIM: usize = 1 << 16;

/// An upper bound of the exact `‖e‖₂` of a row (`e_d = c_d − (lo + step·k_d)`, with
/// `c_d = v_d·scale` the exact normalised value), from `sum`, the `f32` sum of the squares of
/// the errors as [`encode_row`] computes them in `f32`, and the row's `lo` and `hi` (the least
/// and largest `x_d = fl(v_d·scale)`); infinite for a row with a non-finite value.
///
/// Proof. With `u = 2⁻²⁴` and round-to-nearest, write `m = max(|lo|, |hi|)`, so `|x_d| ≤ m`; then
/// `255·step ≤ 2m(1+3u)` and `k_d ≤ 255`. The computed error is `ẽ = fl(x − s)`,
/// `s = fl(lo + p)`, `p = fl(step·k)`, `x = fl(c)`; unfolding the four roundings,
/// `e − ẽ = −(x − c) + (p − step·k) + (s − lo − p) − (ẽ − (x − s))`, whose terms are at most
/// `u|c| ≤ 1.0001·u·m`, `u·255·step ≤ 2.0001·u·m`, `u(|lo| + p) ≤ 3.0001·u·m` and `u|ẽ|`. So
/// `‖e‖ ≤ (1+u)‖ẽ‖ + 6.0003·u·m·√dim` (the triangle inequality over the vector). Each square
/// of `sum` goes through at most `t = dim + 8` roundings (its product, the adds of its lane, the
/// three that join the lanes), so `‖ẽ‖² ≤ sum / (1 − γ_t)` with `γ_t = t·u/(1 − t·u)`; for
/// `t·u ≤ 0.01`, `(1+u)/√(1−γ_t) ≤ 1 + (0.53·t + 2.1)·u < 1 + 2·t·u`, the factor below.
/// Underflow adds at most `2⁻¹⁵⁰` to a rounding's error: in `x`, `p`, `s`, `ẽ` (and a subnormal
/// `step`, whose `255·step` is then within `255·2⁻¹⁵⁰` of `2m(1+3u)`) at most `√dim·2⁻¹⁴⁸` to the
/// error's norm, and in the squares `dim·2⁻¹⁵⁰` to `sum`, so at most `√(dim·2⁻¹⁵⁰) ≤ 2⁻⁶⁷` to its
/// square root (`dim ≤ 2¹⁶`): both below the `2⁻⁶⁰` added. The few `f64` operations here round
/// by `2⁻⁵³` each, well inside the slack of both terms, and the last product by `1 + 2⁻²²` keeps
/// the cast to `f32` (to nearest) above the `f64` bound. The proof assumes the default
/// floating-point modes (a process that treats subnormal inputs as zero could break it for rows
/// with subnormal values, which descriptors never hold).
fn error_bound(sum: f32, lo: f32, hi: f32, step: f32, dim: usize) -> f32 {
    if !(sum.is_finite() && lo.is_finite() && hi.is_finite() && step.is_finite())
        || dim > MAX_BOUNDED_DIM
    {
        return f32::INFINITY;
    }
    let (u, t, n) = (f64::from(U), (dim + 8) as f64, dim as f64);
    let m = f64::from(lo.abs().max(hi.abs()));
    let bound = crate::math::sqrt(f64::from(sum)) * (1.0 + 2.0 * t * u)
        + 6.5 * u * m * crate::math::sqrt(n)
        + 1.0 / (1u64 << 60) as f64;
    // A bound beyond `f32` saturates to infinity in the cast.
    (bound * (1.0 + 1.0 / f64::from(1u32 << 22))) as f32
}

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
        check_query(query, self.rows.dim())?;
        check_out(out, k)?;
        exclude.check(self.rows.len())?;
        let mut best = Best::new(&mut out[..k]);
        let mut cost = Cost::default();
        let _ = self.scan(
            query,
            0,
            exclude,
            f32::INFINITY,
            false,
            &mut best,
            &mut cost,
        );
        Ok(best.finish())
    }

    /// Offers every allowed row of ids `from..` within `bound` that the bytes cannot rule out to
    /// `best`. With `give_up`, switches to brute force for the remaining rows once more than an
    /// eighth of the rows scanned since the previous check needed their exact distance (the
    /// bytes do not pay then: an exact distance out of order costs a few sequential ones);
    /// returns `false` then. With `parallel`, a long scan is cut into parts that the pool's
    /// threads share, their neighbours merged.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn scan(
        &self,
        query: &[f32],
        from: usize,
        exclude: &Exclude<'_>,
        bound: f32,
        give_up: bool,
        best: &mut Best<'_>,
        cost: &mut Cost,
    ) -> bool {
        let end = self.rows.len().min(exclude.before_id);
        // The parts after the first start from empty heaps: the neighbours `best` holds already
        // bound them all the same.
        let bound = best.limit(bound);
        let part = |from: usize, to: usize, best: &mut Best<'_>, cost: &mut Cost| {
            self.scan_part(query, from, to, exclude, bound, give_up, best, cost)
        };
        #[cfg(feature = "parallel")]
        if let Some(done) = super::split_scan(from, end, SKETCH_BLOCK, best, cost, part) {
            return done;
        }
        part(from, end, best, cost)
    }

    /// [`Sketch::scan`] over ids `from..to`, on this thread.
    #[allow(clippy::too_many_arguments)]
    fn scan_part(
        &self,
        query: &[f32],
        from: usize,
        to: usize,
        exclude: &Exclude<'_>,
        bound: f32,
        give_up: bool,
        best: &mut Best<'_>,
        cost: &mut Cost,
    ) -> bool {
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        if std::is_x86_feature_detected!("avx2") {
            #[allow(unsafe_code)]
            // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
            // calling a function compiled with `#[target_feature(enable = "avx2")]`.
            return unsafe { self.scan_avx2(query, from, to, exclude, bound, give_up, best, cost) };
        }
        self.scan_impl(query, from, to, exclude, bound, give_up, best, cost)
    }

    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    fn scan_avx2(
        &self,
        query: &[f32],
        from: usize,
        to: usize,
        exclude: &Exclude<'_>,
        bound: f32,
        give_up: bool,
        best: &mut Best<'_>,
        cost: &mut Cost,
    ) -> bool {
        self.scan_impl(query, from, to, exclude, bound, give_up, best, cost)
    }

    /// The body of [`Sketch::scan_part`], inlined into each of its compiled copies.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn scan_impl(
        &self,
        query: &[f32],
        from: usize,
        end: usize,
        exclude: &Exclude<'_>,
        bound: f32,
        give_up: bool,
        best: &mut Best<'_>,
        cost: &mut Cost,
    ) -> bool {
        if best.heap.is_empty() || from >= end {
            return true;
        }
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
                    scan(self.rows, rest, end, query, exclude, bound, best);
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
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    if std::is_x86_feature_detected!("avx2") {
        #[allow(unsafe_code)]
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for calling a
        // function compiled with `#[target_feature(enable = "avx2")]`.
        return b.finish(unsafe { avx2::dots(b, codes) }, params);
    }
    b.finish(dots(b, codes), params)
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

#[cfg(all(test, feature = "std", target_arch = "x86_64"))]
mod tests {
    use super::{encode_block, encode_block_avx2, sketch_len, Rows, PARAMS, SKETCH_BLOCK};

    /// The AVX2 copy of the encoding writes the portable copy's bits: random rows of the
    /// presets' length and of one with a partial last group, a zero row, rows with a NaN or an
    /// infinity, a last partial block.
    #[test]
    fn avx2_encoding_gives_the_portable_bits() {
        if !std::is_x86_feature_detected!("avx2") {
            eprintln!("no AVX2 on this CPU: nothing to compare");
            return;
        }
        let mut rng = crate::math::XorShift32(0x2545_f491);
        for dim in [40usize, 13] {
            let n = 5 * SKETCH_BLOCK + 3;
            let mut raw: Vec<f32> = (0..n * dim)
                .map(|_| (rng.next_u32() % 10_000) as f32 * 1e-3)
                .collect();
            raw[2 * dim..3 * dim].fill(0.0);
            raw[5 * dim + 3] = f32::NAN;
            raw[7 * dim] = f32::INFINITY;
            let scale: Vec<f32> = (0..n).map(|i| 0.01 + i as f32 * 1e-4).collect();
            let rows = Rows::scaled(&raw, dim, &scale).unwrap();
            let (nc, np) = sketch_len(n, dim);
            let (width, pw) = (nc / n.div_ceil(SKETCH_BLOCK), PARAMS * SKETCH_BLOCK);
            let (mut c1, mut p1) = (vec![1u8; nc], vec![1.0f32; np]);
            let (mut c2, mut p2) = (vec![2u8; nc], vec![2.0f32; np]);
            for b in 0..n.div_ceil(SKETCH_BLOCK) {
                let (c, p) = (b * width..(b + 1) * width, b * pw..(b + 1) * pw);
                encode_block(
                    rows,
                    b * SKETCH_BLOCK,
                    0,
                    &mut c1[c.clone()],
                    &mut p1[p.clone()],
                );
                #[allow(unsafe_code)]
                // SAFETY: the CPU supports AVX2 (checked above).
                unsafe {
                    encode_block_avx2(rows, b * SKETCH_BLOCK, 0, &mut c2[c], &mut p2[p]);
                }
            }
            assert_eq!(c1, c2, "codes, dim {dim}");
            let bits = |p: &[f32]| p.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&p1), bits(&p2), "parameters, dim {dim}");
        }
    }
}

#[cfg(test)]
mod bound_tests {
    use super::{at, encode_block, sketch_len, Rows, PARAMS, SKETCH_BLOCK};

    /// The stored error bounds the exact error of every row, and closely: normalised rows,
    /// rows whose values differ by a few units in their last place (where the `f32` rounding is
    /// as large as the quantisation error), rows not normalised, lengths from 1 to 1,024.
    #[test]
    fn the_stored_error_bounds_the_exact_one_closely() {
        let mut rng = crate::math::XorShift32(0x9e37_79b9);
        let mut next = move || f64::from(rng.next_u32() % 1_000_000) / 1e6;
        let n = 3 * SKETCH_BLOCK;
        let mut worst = 0.0f64;
        for dim in [1usize, 3, 8, 40, 61, 1024] {
            for kind in 0..4 {
                let raw: Vec<f32> = (0..n * dim)
                    .map(|_| match kind {
                        0 => (next() * 10.0) as f32,
                        // 1000 plus a few units in the last place.
                        1 => 1000.0 + (next() * 4.0).floor() as f32 * 6.103_515_6e-5,
                        _ => (next() * 2.0 - 0.5) as f32,
                    })
                    .collect();
                let scale: Vec<f32> = raw
                    .chunks_exact(dim)
                    .map(|row| {
                        let norm = row
                            .iter()
                            .map(|&v| f64::from(v).powi(2))
                            .sum::<f64>()
                            .sqrt();
                        match kind {
                            2 => 1e3,
                            3 => 1e-3,
                            _ => (1.0 / norm) as f32,
                        }
                    })
                    .collect();
                let rows = Rows::scaled(&raw, dim, &scale).unwrap();
                let (nc, np) = sketch_len(n, dim);
                let (mut codes, mut params) = (vec![0u8; nc], vec![0.0f32; np]);
                let (cw, pw) = (nc / (n / SKETCH_BLOCK), PARAMS * SKETCH_BLOCK);
                for b in 0..n / SKETCH_BLOCK {
                    let (c, p) = (&mut codes[b * cw..][..cw], &mut params[b * pw..][..pw]);
                    encode_block(rows, b * SKETCH_BLOCK, 0, c, p);
                }
                for i in 0..n {
                    let (b, lane) = (i / SKETCH_BLOCK, i % SKETCH_BLOCK);
                    let p = |j: usize| f64::from(params[b * pw + j * SKETCH_BLOCK + lane]);
                    let (lo, step, err) = (p(0), p(1), p(2));
                    let row = &raw[i * dim..][..dim];
                    let s = f64::from(scale[i]);
                    let (mut e2, mut m) = (0.0f64, 0.0f64);
                    for (d, &v) in row.iter().enumerate() {
                        let k = f64::from(codes[b * cw + at(d, lane)]);
                        // Exact in `f64` but for the last subtraction (2⁻⁵³ of the values).
                        let e = f64::from(v) * s - (lo + step * k);
                        e2 += e * e;
                        m = m.max((f64::from(v) * s).abs());
                    }
                    let exact = e2.sqrt();
                    let slack = 1e-15 * m * (dim as f64).sqrt();
                    assert!(
                        err >= exact * (1.0 - 1e-12) - slack,
                        "dim {dim}, kind {kind}, row {i}: {err} < {exact}"
                    );
                    // At most 6.5·u·m·√dim and a relative 2(dim + 8)·u above (1e-4 at 1,024).
                    let over = (err - exact) / (exact + m * (dim as f64).sqrt());
                    assert!(
                        over < 1.2e-4,
                        "dim {dim}, kind {kind}, row {i}: {err} vs {exact}"
                    );
                    worst = worst.max(over);
                }
            }
        }
        assert!(worst > 0.0);
    }
}
