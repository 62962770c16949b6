//! Encoding the sketch: each row's `lo`, `step`, codes and error bound, block by block
//! (portable and AVX2 copies of the same code, shared among the pool's threads with `parallel`).

use super::{PARAMS, SKETCH_BLOCK, U};
use crate::search::Rows;
use crate::Error;

/// Lengths of the code buffer (bytes) and of the parameter buffer (`f32`s) of a sketch of `n`
/// rows of `dim` values: whole blocks of [`SKETCH_BLOCK`] rows, `dim` bytes rounded up to a
/// multiple of 4 and 12 parameter bytes per row.
pub fn sketch_len(n: usize, dim: usize) -> (usize, usize) {
    let rows = n.div_ceil(SKETCH_BLOCK) * SKETCH_BLOCK;
    (rows * padded(dim), rows * PARAMS)
}

/// Rows whose parameters a sketch's `params` values hold (whole blocks): the sketch covers that
/// many rows, or all of them when there are fewer (see [`Index::new`](crate::search::Index::new)).
pub fn sketch_rows(params: usize) -> usize {
    params / PARAMS
}

/// `dim` rounded up to a whole number of groups of four values.
pub(super) fn padded(dim: usize) -> usize {
    dim.next_multiple_of(4)
}

/// Where parameter `p` (0: `lo`, 1: `step`, 2: `err`) of lane `lane` sits in its block's
/// parameters.
#[inline(always)]
pub(super) fn param(p: usize, lane: usize) -> usize {
    p * SKETCH_BLOCK + lane
}

/// Where value `d` of lane `lane` sits in its block's codes.
#[inline(always)]
pub(super) fn at(d: usize, lane: usize) -> usize {
    ((d / 4) * SKETCH_BLOCK + lane) * 4 + d % 4
}

pub(super) fn check_sketch(n: usize, dim: usize, codes: usize, params: usize) -> Result<(), Error> {
    let (nc, np) = sketch_len(n, dim);
    Error::check_buffer("codes", nc, codes)?;
    Error::check_buffer("params", np, params)
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
        avx2_or!(
            encode_block_avx2(rows, start, from, codes, params),
            encode_block(rows, start, from, codes, params)
        );
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
pub(super) const PARALLEL_BLOCKS: usize = 1024;

avx2_copy!(
    /// [`encode_block`] compiled for AVX2: the same operations in the same order (no FMA), so
    /// the same bits, with eight `f32` values per instruction.
    encode_block_avx2 = encode_block(
        rows: Rows<'_>,
        start: usize,
        from: usize,
        codes: &mut [u8],
        params: &mut [f32],
    )
);

/// Encodes the rows of the block starting at row `start` (those from `from` on): first the
/// range of every row, then their codes, then their error bounds, so that one row's chain of
/// dependent minima, maxima, divisions and square root overlaps the next rows' instead of
/// holding up its own codes (with [`row_range`]'s loop: faster, the same bits; see
/// docs/performance.md#sketch).
#[inline(always)]
pub(super) fn encode_block(
    rows: Rows<'_>,
    start: usize,
    from: usize,
    codes: &mut [u8],
    params: &mut [f32],
) {
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
pub(super) fn row_range(rows: Rows<'_>, i: usize) -> (f32, f32) {
    // Lanes of eight, so that the compiler vectorises.
    let (raw, scale) = rows.raw_row(i);
    let (mut lo8, mut hi8) = ([f32::INFINITY; 8], [f32::NEG_INFINITY; 8]);
    let eights = raw.chunks_exact(8);
    // Plain comparisons, which compile to single min/max instructions, in a loop over the lanes:
    // a closure given each lane's index made the compiler blend the comparisons through packed
    // masks instead, which was slower.
    #[inline(always)]
    pub(super) fn take(lo: &mut [f32; 8], hi: &mut [f32; 8], values: &[f32], scale: f32) {
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
pub(super) fn encode_row(
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
pub(super) const MAX_BOUNDED_DIM: usize = 1 << 16;

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
pub(super) fn error_bound(sum: f32, lo: f32, hi: f32, step: f32, dim: usize) -> f32 {
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

#[cfg(all(test, feature = "std", target_arch = "x86_64"))]
pub(super) mod tests {
    use super::{encode_block, encode_block_avx2, sketch_len, Rows, PARAMS, SKETCH_BLOCK};

    /// The AVX2 copy of the encoding writes the portable copy's bits: random rows of the
    /// presets' length and of one with a partial last group, a zero row, rows with a NaN or an
    /// infinity, a last partial block.
    #[test]
    pub(super) fn avx2_encoding_gives_the_portable_bits() {
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
pub(super) mod bound_tests {
    use super::{at, encode_block, sketch_len, Rows, PARAMS, SKETCH_BLOCK};

    /// The stored error bounds the exact error of every row, and closely: normalised rows,
    /// rows whose values differ by a few units in their last place (where the `f32` rounding is
    /// as large as the quantisation error), rows not normalised, lengths from 1 to 1,024.
    #[test]
    pub(super) fn the_stored_error_bounds_the_exact_one_closely() {
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
