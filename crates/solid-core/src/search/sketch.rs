//! The sketch: every row quantised to one byte per value, scanned to prove rows too far before
//! computing their distance (see the parent module).
//!
//! Row `c` is stored as `lo`, `step` and `dim` codes `k_d` in `0..=255` with
//! `c_d = lo + step·k_d + e_d`, plus `err ≥ ‖e‖₂`. For a query `q`,
//! `q·c = lo·Σq + step·(q·k) + q·e` and `|q·e| ≤ ‖q‖₂·err` (Cauchy–Schwarz), so
//! `1 − lo·Σq − step·(q·k) − ‖q‖₂·err`, less a margin for the `f32` rounding of that expression
//! and of the exact distance, is a lower bound of the distance that [`brute_force`] computes. A row
//! whose bound exceeds the current k-th distance cannot be a neighbour; every other row gets its
//! exact distance, so the results are the brute-force results, bit for bit.
//!
//! Layout: rows in blocks of [`SKETCH_BLOCK`]; a block's codes are value-major
//! (`codes[block][d][lane]`), so that the 16 dot products of a block run side by side in vector
//! registers; its parameters are `lo[16]`, `step[16]`, `err[16]`.
//!
//! [`brute_force`]: super::brute_force

use super::{check_out, check_query, dist, n_rows, scan, Best, Cost, Exclude, Neighbor};
use crate::Error;

/// Rows per block of a [`Sketch`] (the codes of a block are interleaved).
pub const SKETCH_BLOCK: usize = 16;

/// `f32` parameters per row: `lo`, `step`, `err`.
const PARAMS: usize = 3;

/// Unit roundoff of `f32`.
const U: f32 = f32::EPSILON / 2.0;

/// Blocks scanned before the first check of how many rows the sketch failed to rule out, and
/// between two later checks.
const CHECK_FIRST: usize = 16;
const CHECK_EVERY: usize = 64;

/// Lengths of the code buffer (bytes) and of the parameter buffer (`f32`s) of a sketch of `n`
/// rows of `dim` values: whole blocks of [`SKETCH_BLOCK`] rows, `dim` bytes and 12 parameter
/// bytes per row.
pub fn sketch_len(n: usize, dim: usize) -> (usize, usize) {
    let rows = n.div_ceil(SKETCH_BLOCK) * SKETCH_BLOCK;
    (rows * dim, rows * PARAMS)
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

/// Encodes rows `from..n` of `rows` (`n = rows.len() / dim`) into the sketch buffers, which must
/// be at least [`sketch_len`]`(n, dim)` long; rows before `from` are left as they are, so a
/// growing database encodes each new row once. Unused lanes of the last block are zeroed.
/// Allocates nothing.
///
/// # Errors
/// [`Error::InvalidParameter`] for a bad `dim` (see [`brute_force`](super::brute_force)) or a
/// `from` beyond the rows; [`Error::BufferTooSmall`] when a buffer is too short.
pub fn sketch_encode(
    rows: &[f32],
    dim: usize,
    from: usize,
    codes: &mut [u8],
    params: &mut [f32],
) -> Result<(), Error> {
    let n = n_rows(rows, dim)?;
    if from > n {
        return Err(Error::InvalidParameter {
            name: "from",
            value: from as f64,
            expected: "at most the number of rows",
        });
    }
    check_sketch(n, dim, codes.len(), params.len())?;
    for i in from..n {
        encode_row(&rows[i * dim..(i + 1) * dim], i, codes, params);
    }
    let end = n.div_ceil(SKETCH_BLOCK) * SKETCH_BLOCK;
    for i in n.max(from)..end {
        let (b, lane) = (i / SKETCH_BLOCK, i % SKETCH_BLOCK);
        for d in 0..dim {
            codes[(b * dim + d) * SKETCH_BLOCK + lane] = 0;
        }
        for p in 0..PARAMS {
            params[(b * PARAMS + p) * SKETCH_BLOCK + lane] = 0.0;
        }
    }
    Ok(())
}

/// Writes the codes and parameters of row `i`.
fn encode_row(row: &[f32], i: usize, codes: &mut [u8], params: &mut [f32]) {
    let dim = row.len();
    let (b, lane) = (i / SKETCH_BLOCK, i % SKETCH_BLOCK);
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for &x in row {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    let step = (hi - lo) / 255.0;
    let mut err2 = 0.0f64;
    for (d, &x) in row.iter().enumerate() {
        let k = if step > 0.0 {
            libm::roundf((x - lo) / step).clamp(0.0, 255.0)
        } else {
            0.0
        };
        codes[(b * dim + d) * SKETCH_BLOCK + lane] = k as u8;
        let e = f64::from(x) - (f64::from(lo) + f64::from(step) * f64::from(k));
        err2 += e * e;
    }
    // Rounded up, so that `err ≥ ‖e‖₂`; a row with a non-finite value gets an infinite error,
    // which no bound can rule out.
    let err = libm::sqrt(err2) * (1.0 + 1e-6);
    let err = if err.is_finite() && lo.is_finite() && step.is_finite() {
        err as f32
    } else {
        f32::INFINITY
    };
    let at = |p: usize| (b * PARAMS + p) * SKETCH_BLOCK + lane;
    params[at(0)] = if lo.is_finite() { lo } else { 0.0 };
    params[at(1)] = if step.is_finite() { step } else { 0.0 };
    params[at(2)] = err;
}

/// A sketch of L2-normalised rows (see the module documentation), viewing caller-owned buffers
/// that [`sketch_encode`] filled.
#[derive(Debug, Clone, Copy)]
pub struct Sketch<'a> {
    rows: &'a [f32],
    dim: usize,
    n: usize,
    codes: &'a [u8],
    params: &'a [f32],
}

impl<'a> Sketch<'a> {
    /// Views the sketch of every row of `rows` in `codes` and `params` (as [`sketch_encode`] left
    /// them).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a bad `dim`; [`Error::BufferTooSmall`] when a buffer is
    /// shorter than [`sketch_len`] says.
    pub fn new(
        rows: &'a [f32],
        dim: usize,
        codes: &'a [u8],
        params: &'a [f32],
    ) -> Result<Sketch<'a>, Error> {
        let n = n_rows(rows, dim)?;
        check_sketch(n, dim, codes.len(), params.len())?;
        Ok(Sketch {
            rows,
            dim,
            n,
            codes,
            params,
        })
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.n
    }

    /// `true` when the sketch holds no row.
    pub fn is_empty(&self) -> bool {
        self.n == 0
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
        check_query(query, self.dim)?;
        check_out(out, k)?;
        exclude.check(self.n)?;
        let mut best = Best::new(&mut out[..k]);
        let mut cost = Cost::default();
        self.scan(query, exclude, f32::INFINITY, false, &mut best, &mut cost);
        Ok(best.finish())
    }

    /// Offers every allowed row within `bound` that the bytes cannot rule out to `best`. With
    /// `give_up`, switches to brute force for the remaining rows once more than a quarter of the
    /// rows scanned so far needed their exact distance (the bytes do not pay then).
    pub(super) fn scan(
        &self,
        query: &[f32],
        exclude: &Exclude<'_>,
        bound: f32,
        give_up: bool,
        best: &mut Best<'_>,
        cost: &mut Cost,
    ) {
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        if std::is_x86_feature_detected!("avx2") {
            #[allow(unsafe_code)]
            // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
            // calling a function compiled with `#[target_feature(enable = "avx2")]`.
            return unsafe { self.scan_avx2(query, exclude, bound, give_up, best, cost) };
        }
        self.scan_impl(query, exclude, bound, give_up, best, cost)
    }

    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[target_feature(enable = "avx2")]
    fn scan_avx2(
        &self,
        query: &[f32],
        exclude: &Exclude<'_>,
        bound: f32,
        give_up: bool,
        best: &mut Best<'_>,
        cost: &mut Cost,
    ) {
        self.scan_impl(query, exclude, bound, give_up, best, cost)
    }

    /// The body of [`Sketch::scan`], inlined into each of its compiled copies.
    #[inline(always)]
    fn scan_impl(
        &self,
        query: &[f32],
        exclude: &Exclude<'_>,
        bound: f32,
        give_up: bool,
        best: &mut Best<'_>,
        cost: &mut Cost,
    ) {
        let end = self.n.min(exclude.before_id);
        if best.heap.is_empty() || end == 0 {
            return;
        }
        let dim = self.dim;
        let bounds = Bounds::new(query);
        let timed = exclude.not_newer_than.is_some();
        let blocks = end.div_ceil(SKETCH_BLOCK);
        let mut limit = best.limit(bound);
        for b in 0..blocks {
            let check = b == CHECK_FIRST || (b > 0 && b % CHECK_EVERY == 0);
            if give_up && check && 4 * cost.exact_rows > cost.sketch_rows {
                let from = b * SKETCH_BLOCK;
                cost.exact_rows += end - from;
                scan(self.rows, dim, from, end, query, exclude, bound, best);
                return;
            }
            let codes = &self.codes[b * dim * SKETCH_BLOCK..(b + 1) * dim * SKETCH_BLOCK];
            let params = &self.params[b * PARAMS * SKETCH_BLOCK..(b + 1) * PARAMS * SKETCH_BLOCK];
            let lb = bounds.block(query, codes, params);
            let first = b * SKETCH_BLOCK;
            let lanes = (end - first).min(SKETCH_BLOCK);
            cost.sketch_rows += lanes;
            let mut hits = 0u32;
            for (lane, &l) in lb.iter().enumerate() {
                hits |= u32::from(l <= limit) << lane;
            }
            hits &= (1u32 << lanes) - 1;
            while hits != 0 {
                let id = first + hits.trailing_zeros() as usize;
                hits &= hits - 1;
                if timed && !exclude.allows(id) {
                    continue;
                }
                cost.exact_rows += 1;
                let d = dist(query, &self.rows[id * dim..(id + 1) * dim]);
                if d <= limit {
                    best.offer(Neighbor {
                        id: id as u32,
                        distance: d,
                    });
                    limit = best.limit(bound);
                }
            }
        }
    }
}

/// The per-query constants of the lower bound.
struct Bounds {
    /// `Σ q_d`.
    sum: f32,
    /// `‖q‖₂`, rounded up.
    norm: f32,
    /// Rounding margin per unit of a row's magnitude `|lo| + 255·step`.
    per_magnitude: f32,
}

impl Bounds {
    fn new(q: &[f32]) -> Self {
        let (mut sum, mut l1, mut l2) = (0.0f32, 0.0f64, 0.0f64);
        for &x in q {
            sum += x;
            l1 += f64::from(x.abs());
            l2 += f64::from(x) * f64::from(x);
        }
        // Rounding of `q·k` (a `dim`-term f32 sum), of `Σq`, of the products by `lo` and
        // `step` and of the exact distance: each below `(dim + 2)·u` times `‖q‖₁` times the
        // row's magnitude; counted four times over, plus the subtractions of the bound itself.
        let per_magnitude = 4.0 * (q.len() as f64 + 4.0) * f64::from(U) * (l1 + 1.0);
        Bounds {
            sum,
            norm: (libm::sqrt(l2) * (1.0 + 1e-6)) as f32,
            per_magnitude: per_magnitude as f32,
        }
    }

    /// Lower bounds of the distances of the query to the 16 rows of one block (1 at most).
    #[inline(always)]
    fn block(&self, q: &[f32], codes: &[u8], params: &[f32]) -> [f32; SKETCH_BLOCK] {
        let mut acc = [0.0f32; SKETCH_BLOCK];
        for (&qd, c) in q.iter().zip(codes.chunks_exact(SKETCH_BLOCK)) {
            for (a, &k) in acc.iter_mut().zip(c) {
                *a += qd * f32::from(k);
            }
        }
        let (lo, rest) = params.split_at(SKETCH_BLOCK);
        let (step, err) = rest.split_at(SKETCH_BLOCK);
        let mut lb = [0.0f32; SKETCH_BLOCK];
        for r in 0..SKETCH_BLOCK {
            let approx = lo[r] * self.sum + step[r] * acc[r];
            let magnitude = lo[r].abs() + 255.0 * step[r];
            let slack = err[r] * self.norm + self.per_magnitude * magnitude + 64.0 * U;
            lb[r] = (1.0 - approx - slack).min(1.0);
        }
        lb
    }
}
