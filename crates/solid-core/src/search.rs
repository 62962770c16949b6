//! Exact nearest-neighbour search over R-SOLiD vectors ([spec §3](crate::spec#3-comparing-descriptors)), allocation-free.
//!
//! Every search compares an L2-normalised query with **L2-normalised** rows ([`Rows`]: stored
//! normalised, see [`normalize_rows`], or raw with the scale that normalises each, see
//! [`inverse_norm`]), so that the cosine distance of [spec §3](crate::spec#3-comparing-descriptors) is `1 − q·c` and its order equals the
//! Euclidean order (`‖q − c‖² = 2 − 2 q·c`). An all-zero vector stays all-zero after
//! normalisation and is at distance 1 from everything, as [spec §3](crate::spec#3-comparing-descriptors) says. Distances are clamped
//! into `[0, 1]`.
//!
//! Every search answers the same question and returns the same neighbours with the same
//! distances, in the same order (ties broken by the lower id), because every distance that is
//! returned is computed by the same function ([`normalized_distance`]); the searches differ only
//! in which rows they can prove too far without computing their distance:
//! - [`brute_force`]: one linear pass over the rows (no proof needed).
//! - [`KdTree`]: a kd-tree built in place over a caller-owned permutation of row ids (plus one
//!   `u16` per entry for the split dimensions); neither build nor query allocates.
//! - [`online_insert`] / [`OnlineIndex::search`]: an index that grows one entry at a time and always
//!   answers exactly over every entry added so far. It is the logarithmic method (Bentley & Saxe):
//!   the ids `0..n` are cut into blocks whose sizes are the powers of two of `n`'s binary
//!   representation, each block a static [`KdTree`] over its own part of the shared permutation.
//!   An insert rebuilds only the block the new entry completes (amortised `O(log² n)` work).
//! - [`Sketch`]: a linear pass over one byte per value instead of four (each row quantised to
//!   8 bits with its own scale, plus the norm of its quantisation error); a row's distance is
//!   computed only when the bytes cannot prove it too far.
//! - [`Index`]: all of the above over the same rows, with [`Plan::Auto`] choosing: the kd-tree
//!   under a work budget (it answers queries near stored places after a few hundred rows), then
//!   the sketch from the best distance the tree found (its cost does not depend on the query),
//!   then brute force from where the sketch stops paying (rows so alike that the bytes cannot
//!   tell them apart).
//!
//! Candidates can be restricted with [`Exclude`]: only ids below a bound (which excludes the most
//! recent entries of a loop detector) and only entries not newer than a time; and, through
//! [`Request::max_distance`], to those within a distance (a loop detector's threshold), which
//! lets every method skip more.
//!
//! ```
//! use solid_lidar::search::{brute_force, inverse_norm, normalize_rows, Exclude, KdTree, Neighbor, Rows};
//!
//! let raw = [1.0f32, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0];
//! let dim = 2;
//! let mut normed = [0.0f32; 8];
//! normalize_rows(&raw, dim, &mut normed).unwrap();
//! let rows = Rows::normalized(&normed, dim).unwrap();
//! let query = [1.0f32, 0.0];
//! let mut out = [Neighbor::default(); 2];
//! let n = brute_force(rows, &query, 2, &Exclude::NONE, &mut out).unwrap();
//! assert_eq!(n, 2);
//! assert_eq!((out[0].id, out[1].id), (0, 2)); // exact match, then 45°
//!
//! // The same rows kept raw, with a scale per row.
//! let scale: Vec<f32> = raw.chunks(dim).map(|r| inverse_norm(r).unwrap()).collect();
//! let raw_rows = Rows::scaled(&raw, dim, &scale).unwrap();
//! let (mut perm, mut splits) = ([0u32; 4], [0u16; 4]);
//! let tree = KdTree::build(raw_rows, &mut perm, &mut splits).unwrap();
//! let mut out2 = [Neighbor::default(); 2];
//! tree.search(&query, 2, &Exclude::NONE, &mut out2).unwrap();
//! assert_eq!((out2[0].id, out2[1].id), (0, 2));
//! ```

use crate::Error;

mod index;
mod kdtree;
mod sketch;

pub use index::{
    auto_is_brute, auto_tree_row_cost, Cost, Found, Index, Observed, Plan, Request, AUTO_MISSES,
    AUTO_PRIME_BASE, AUTO_PRIME_PER_K, AUTO_RETRY_EVERY, AUTO_RETRY_MAX, AUTO_TREE_ROW_COST,
};
pub use kdtree::{
    online_extend, online_extend_rows, online_extend_scratch_len, online_extend_with,
    online_insert, online_rebuild, KdTree, OnlineIndex, LEAF_SIZE,
};
pub use sketch::{sketch_encode, sketch_len, sketch_rows, Sketch, SKETCH_BLOCK};

/// One search result: an entry's id and its cosine distance to the query.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Neighbor {
    /// The entry's id (its row index).
    pub id: u32,
    /// Cosine distance in `[0, 1]` ([spec §3](crate::spec#3-comparing-descriptors)): `1 − q·c` of the normalised vectors.
    pub distance: f32,
}

impl Neighbor {
    /// `true` when `self` ranks strictly before `other`: smaller distance, or equal distance and
    /// lower id.
    #[inline]
    fn before(&self, other: &Neighbor) -> bool {
        self.distance < other.distance || (self.distance == other.distance && self.id < other.id)
    }
}

/// Which entries a search may return.
#[derive(Debug, Clone, Copy)]
pub struct Exclude<'a> {
    /// Only entries with `id < before_id` are candidates (`usize::MAX`: every entry). A loop
    /// detector that skips its `e` most recent of `n` entries uses `before_id = n − e`.
    pub before_id: usize,
    /// Per-entry timestamps (indexed by id) and the newest allowed time: entries whose timestamp
    /// is greater than the bound are skipped. Entries with a NaN timestamp (no time) are kept.
    pub not_newer_than: Option<(&'a [f64], f64)>,
}

impl Exclude<'_> {
    /// No exclusion: every entry is a candidate.
    pub const NONE: Exclude<'static> = Exclude {
        before_id: usize::MAX,
        not_newer_than: None,
    };

    /// Excludes the `exclude_recent` most recent of `n_entries` entries (ids `n − e .. n`).
    pub const fn recent(n_entries: usize, exclude_recent: usize) -> Exclude<'static> {
        Exclude {
            before_id: n_entries.saturating_sub(exclude_recent),
            not_newer_than: None,
        }
    }

    #[inline]
    fn allows(&self, id: usize) -> bool {
        if id >= self.before_id {
            return false;
        }
        match self.not_newer_than {
            // `!(t > bound)` keeps NaN timestamps.
            Some((times, bound)) => times[id].is_nan() || times[id] <= bound,
            None => true,
        }
    }

    fn check(&self, n: usize) -> Result<(), Error> {
        if let Some((times, _)) = self.not_newer_than {
            if times.len() < n {
                return Err(Error::LengthMismatch {
                    what: "timestamps vs entries",
                    left: times.len(),
                    right: n,
                });
            }
        }
        Ok(())
    }
}

/// L2-normalises `v` into `out` (same length). Returns `Ok(false)` when `v` is all zeros (then
/// `out` is all zeros too), `Ok(true)` otherwise. The norm is computed in `f64`.
///
/// # Errors
/// [`Error::LengthMismatch`] when `out.len() != v.len()`; [`Error::Empty`] when `v` is empty;
/// [`Error::InvalidParameter`] (name `descriptor`) when `v` holds a NaN or infinite value.
pub fn normalize(v: &[f32], out: &mut [f32]) -> Result<bool, Error> {
    if v.len() != out.len() {
        return Err(Error::LengthMismatch {
            what: "descriptor vs output",
            left: v.len(),
            right: out.len(),
        });
    }
    if v.is_empty() {
        return Err(Error::Empty { what: "descriptor" });
    }
    let mut sum = 0.0f64;
    for &x in v {
        if !x.is_finite() {
            return Err(Error::InvalidParameter {
                name: "descriptor",
                value: x as f64,
                expected: "finite values",
            });
        }
        sum += (x as f64) * (x as f64);
    }
    if sum == 0.0 {
        out.fill(0.0);
        return Ok(false);
    }
    let inv = 1.0 / crate::math::sqrt(sum);
    for (o, &x) in out.iter_mut().zip(v) {
        *o = ((x as f64) * inv) as f32;
    }
    Ok(true)
}

/// L2-normalises every row of the row-major `rows` (rows of `dim` values) into `out`.
///
/// # Errors
/// As [`normalize`], plus [`Error::InvalidParameter`] (name `dim`) when `dim` is 0 or does not
/// divide `rows.len()`, and [`Error::LengthMismatch`] when `out.len() != rows.len()`.
pub fn normalize_rows(rows: &[f32], dim: usize, out: &mut [f32]) -> Result<(), Error> {
    n_rows(rows, dim)?;
    if out.len() != rows.len() {
        return Err(Error::LengthMismatch {
            what: "rows vs output",
            left: rows.len(),
            right: out.len(),
        });
    }
    for (r, o) in rows.chunks_exact(dim).zip(out.chunks_exact_mut(dim)) {
        normalize(r, o)?;
    }
    Ok(())
}

/// Dot product with eight independent accumulators (vectorisable, fixed summation order).
#[inline(always)]
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let ca = a.chunks_exact(8);
    let cb = b.chunks_exact(8);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..8 {
            acc[i] += x[i] * y[i];
        }
    }
    let mut tail = 0.0f32;
    for (x, y) in ra.iter().zip(rb) {
        tail += x * y;
    }
    (((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]))) + tail
}

/// `1 − q·c` clamped into `[0, 1]`; NaN (only from non-finite input) counts as 1.
#[inline(always)]
fn dist(q: &[f32], c: &[f32]) -> f32 {
    clamp_distance(1.0 - dot(q, c))
}

/// Clamps a distance into `[0, 1]`; NaN counts as 1.
#[inline(always)]
fn clamp_distance(d: f32) -> f32 {
    if d >= 0.0 {
        if d <= 1.0 {
            d
        } else {
            1.0
        }
    } else if d < 0.0 {
        0.0
    } else {
        1.0
    }
}

/// The cosine distance between two L2-normalised vectors exactly as every search computes it:
/// `1 − q·c`, clamped into `[0, 1]`. All-zero vectors are at distance 1.
///
/// # Errors
/// [`Error::LengthMismatch`] when the lengths differ.
pub fn normalized_distance(q: &[f32], c: &[f32]) -> Result<f32, Error> {
    if q.len() != c.len() {
        return Err(Error::LengthMismatch {
            what: "query vs candidate",
            left: q.len(),
            right: c.len(),
        });
    }
    Ok(dist(q, c))
}

/// Number of rows of `rows` with `dim` columns, checking the layout.
fn n_rows(rows: &[f32], dim: usize) -> Result<usize, Error> {
    if dim == 0 || dim > u16::MAX as usize || !rows.len().is_multiple_of(dim) {
        return Err(Error::InvalidParameter {
            name: "dim",
            value: dim as f64,
            expected: "1..=65535 and a divisor of rows.len()",
        });
    }
    let n = rows.len() / dim;
    if n > u32::MAX as usize {
        return Err(Error::InvalidParameter {
            name: "rows",
            value: n as f64,
            expected: "at most 2^32 - 1 entries",
        });
    }
    Ok(n)
}

/// The vectors a search compares: `n` rows of `dim` values, row-major, id = row index. Either
/// L2-normalised already ([`Rows::normalized`]) or raw with a scale per row that normalises them
/// ([`Rows::scaled`], with [`inverse_norm`]): a store that must give back the vectors exactly as
/// they were added keeps one copy, not a raw and a normalised one.
///
/// The distance to a normalised query `q` is `1 − q·c` clamped into `[0, 1]`, with
/// `q·c = dot(q, row)` for normalised rows and `dot(q, row) × scale` for scaled ones, the dot
/// product always summed in the same order ([`normalized_distance`]).
#[derive(Debug, Clone, Copy)]
pub struct Rows<'a> {
    data: &'a [f32],
    dim: usize,
    n: usize,
    scale: Option<&'a [f32]>,
}

impl<'a> Rows<'a> {
    /// Asks the cache for row `i` and its scale, a hint that never faults (a no-op without
    /// x86_64's SSE): the kd-tree's walk jumps among rows at random, and asked for all at once,
    /// their misses overlap instead of following one another (see `KdTree::rec`).
    #[inline]
    pub(crate) fn prefetch(&self, i: usize) {
        #[cfg(all(target_arch = "x86_64", target_feature = "sse"))]
        #[allow(unsafe_code)]
        // SAFETY: SSE is enabled (the cfg); a prefetch reads nothing and never faults, whatever
        // the address (these are computed with wrapping arithmetic and may lie past the end).
        unsafe {
            use core::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let row = self.data.as_ptr().wrapping_add(i * self.dim).cast::<i8>();
            let bytes = self.dim * core::mem::size_of::<f32>();
            // A line at every 64 bytes from the start, and the line of the last byte: every line
            // the row spans.
            for at in (0..bytes).step_by(64).chain([bytes.saturating_sub(1)]) {
                _mm_prefetch::<_MM_HINT_T0>(row.wrapping_add(at));
            }
            if let Some(scale) = self.scale {
                _mm_prefetch::<_MM_HINT_T0>(scale.as_ptr().wrapping_add(i).cast::<i8>());
            }
        }
        let _ = i;
    }

    /// L2-normalised rows (see [`normalize_rows`]).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a `dim` that is 0, above 65535 or does not divide
    /// `data.len()`, or for more than `u32::MAX` rows.
    pub fn normalized(data: &'a [f32], dim: usize) -> Result<Rows<'a>, Error> {
        Ok(Rows {
            data,
            dim,
            n: n_rows(data, dim)?,
            scale: None,
        })
    }

    /// Raw rows, compared as `row × scale[i]` (`scale[i]` = [`inverse_norm`] of row `i`; only the
    /// first `data.len() / dim` scales are used).
    ///
    /// # Errors
    /// As [`Rows::normalized`]; [`Error::BufferTooSmall`] when `scale` has fewer values than
    /// there are rows.
    pub fn scaled(data: &'a [f32], dim: usize, scale: &'a [f32]) -> Result<Rows<'a>, Error> {
        let n = n_rows(data, dim)?;
        if scale.len() < n {
            return Err(Error::BufferTooSmall {
                buffer: "scale",
                needed: n,
                got: scale.len(),
            });
        }
        Ok(Rows {
            data,
            dim,
            n,
            scale: Some(&scale[..n]),
        })
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.n
    }

    /// `true` when there is no row.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Values per row.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// The first `n` rows (all of them when `n` is larger).
    pub fn prefix(&self, n: usize) -> Rows<'a> {
        let n = n.min(self.n);
        Rows {
            data: &self.data[..n * self.dim],
            dim: self.dim,
            n,
            scale: self.scale.map(|s| &s[..n]),
        }
    }

    /// The distance of the L2-normalised `query` to every row, into `out[..len()]`: the distances
    /// every search computes.
    ///
    /// # Errors
    /// [`Error::LengthMismatch`] when `query.len()` differs from `dim`;
    /// [`Error::BufferTooSmall`] when `out` is shorter than the rows.
    pub fn distances(&self, query: &[f32], out: &mut [f32]) -> Result<(), Error> {
        check_query(query, self.dim)?;
        if out.len() < self.n {
            return Err(Error::BufferTooSmall {
                buffer: "out",
                needed: self.n,
                got: out.len(),
            });
        }
        for (i, o) in out[..self.n].iter_mut().enumerate() {
            *o = self.dist(query, i);
        }
        Ok(())
    }

    /// Row `i` as stored.
    #[inline(always)]
    fn row(&self, i: usize) -> &'a [f32] {
        &self.data[i * self.dim..(i + 1) * self.dim]
    }

    /// Row `i` as stored and the scale that normalises it (1 for normalised rows).
    #[inline(always)]
    fn raw_row(&self, i: usize) -> (&'a [f32], f32) {
        (self.row(i), self.scale.map_or(1.0, |s| s[i]))
    }

    /// Value `d` of normalised row `i`.
    #[inline(always)]
    fn coord(&self, i: usize, d: usize) -> f32 {
        let v = self.data[i * self.dim + d];
        match self.scale {
            Some(s) => v * s[i],
            None => v,
        }
    }

    /// The distance of the normalised query to row `i`.
    #[inline(always)]
    fn dist(&self, q: &[f32], i: usize) -> f32 {
        match self.scale {
            Some(s) => clamp_distance(1.0 - dot(q, self.row(i)) * s[i]),
            None => dist(q, self.row(i)),
        }
    }

    /// The distances of the normalised query to rows `i..i + 4`, from their dot products as
    /// `dot4` computes them (summed exactly as [`dot`] sums them), clamped as [`dist`] clamps.
    #[inline(always)]
    fn dist4(
        &self,
        q: &[f32],
        i: usize,
        dist4: impl Fn(&[f32], &[f32], usize, [f32; 4]) -> [f32; 4],
    ) -> [f32; 4] {
        let dim = self.dim;
        let scale = match self.scale {
            Some(s) => [s[i], s[i + 1], s[i + 2], s[i + 3]],
            None => [1.0; 4],
        };
        dist4(q, &self.data[i * dim..(i + 4) * dim], dim, scale)
    }
}

/// The distances of `q` to the four consecutive rows of `group` (`4 × dim` values), the rows
/// multiplied by `scale`: each exactly `clamp(1 − dot × scale)` (a scale of 1 changes nothing).
#[inline(always)]
fn dist4(q: &[f32], group: &[f32], dim: usize, scale: [f32; 4]) -> [f32; 4] {
    let (r0, rest) = group.split_at(dim);
    let (r1, rest) = rest.split_at(dim);
    let (r2, r3) = rest.split_at(dim);
    let dots = [dot(q, r0), dot(q, r1), dot(q, r2), dot(q, r3)];
    core::array::from_fn(|j| clamp_distance(1.0 - dots[j] * scale[j]))
}

/// [`dist4`] with AVX2 registers: each row's eight lanes in one 256-bit register, the four rows'
/// lanes summed together by shuffles with the same additions in the same order as [`dot`], then
/// scaled, subtracted and clamped four at a time (so the same bits; `tests/search_props.rs`
/// compares them). Loads go through `bytemuck`, so nothing here is `unsafe`.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
mod avx2 {
    use core::arch::x86_64::{
        __m128, __m256, _mm256_add_ps, _mm256_castps256_ps128, _mm256_extractf128_ps,
        _mm256_mul_ps, _mm256_setzero_ps, _mm_add_ps, _mm_hadd_ps, _mm_max_ps, _mm_min_ps,
        _mm_mul_ps, _mm_prefetch, _mm_set1_ps, _mm_setzero_ps, _mm_sub_ps, _MM_HINT_T0,
    };

    #[inline(always)]
    fn load(s: &[f32]) -> __m256 {
        let s: &[f32; 8] = s.try_into().unwrap_or(&[0.0; 8]);
        bytemuck::cast(*s)
    }

    /// Groups of four rows ahead of the one being compared that [`prefetch_ahead`] asks the
    /// cache for: the hardware prefetcher alone left one core reading a 1M-row scan at 12 GB/s
    /// (160 MB in 13.4 ms); asking 2.5 KB ahead (4 groups of 40-value rows) took it to 10.7 ms
    /// (2 groups: 11.5, 8: 11.7, 16: 12.1; one thread, same window).
    const PREFETCH_GROUPS: usize = 4;

    /// Asks for the cache lines of the group [`PREFETCH_GROUPS`] after `group` (4 rows). A hint
    /// only: addresses past the end are never read (prefetches do not fault).
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn prefetch_ahead(group: &[f32]) {
        let bytes = core::mem::size_of_val(group);
        let ahead = group
            .as_ptr()
            .wrapping_add(PREFETCH_GROUPS * group.len())
            .cast::<i8>();
        for line in (0..bytes).step_by(64) {
            _mm_prefetch::<_MM_HINT_T0>(ahead.wrapping_add(line));
        }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn dist4(q: &[f32], group: &[f32], dim: usize, scale: [f32; 4]) -> [f32; 4] {
        let whole = dim / 8 * 8;
        let (r0, rest) = group.split_at(dim);
        let (r1, rest) = rest.split_at(dim);
        let (r2, r3) = rest.split_at(dim);
        let mut acc = [_mm256_setzero_ps(); 4];
        let chunks = q
            .chunks_exact(8)
            .zip(r0.chunks_exact(8))
            .zip(r1.chunks_exact(8))
            .zip(r2.chunks_exact(8))
            .zip(r3.chunks_exact(8));
        for ((((qq, c0), c1), c2), c3) in chunks {
            let qq = load(qq);
            for (a, c) in acc.iter_mut().zip([c0, c1, c2, c3]) {
                *a = _mm256_add_ps(*a, _mm256_mul_ps(qq, load(c)));
            }
        }
        // Per row: (a0 + a4, a1 + a5, a2 + a6, a3 + a7), then ((x0 + x1) + (x2 + x3)).
        let halves: [__m128; 4] = core::array::from_fn(|j| {
            _mm_add_ps(
                _mm256_castps256_ps128(acc[j]),
                _mm256_extractf128_ps::<1>(acc[j]),
            )
        });
        let mut dots = _mm_hadd_ps(
            _mm_hadd_ps(halves[0], halves[1]),
            _mm_hadd_ps(halves[2], halves[3]),
        );
        if whole < dim {
            let mut tails = [0.0f32; 4];
            for (j, t) in tails.iter_mut().enumerate() {
                for d in whole..dim {
                    *t += q[d] * group[j * dim + d];
                }
            }
            dots = _mm_add_ps(dots, bytemuck::cast(tails));
        }
        let one = _mm_set1_ps(1.0);
        let d = _mm_sub_ps(one, _mm_mul_ps(dots, bytemuck::cast(scale)));
        // `min` returns its second operand for a NaN (a distance of 1, as `clamp_distance`);
        // `max(0, x)` returns x for x = ±0 (keeping the sign of a zero, as the scalar clamp).
        bytemuck::cast(_mm_max_ps(_mm_setzero_ps(), _mm_min_ps(d, one)))
    }
}

/// `1 / ‖v‖₂` (computed in `f64`), the scale that normalises `v` in [`Rows::scaled`]; 0 for an
/// all-zero vector (which is then at distance 1 from everything), and for a vector so small
/// (‖v‖ below about 2.9e-39, subnormal values) that its scale would overflow `f32`: it is
/// treated as all-zero rather than given infinite or NaN values.
///
/// # Errors
/// [`Error::InvalidParameter`] (name `descriptor`) when `v` holds a NaN or infinite value.
#[inline(always)]
pub fn inverse_norm(v: &[f32]) -> Result<f32, Error> {
    let [sum] = square_sums([v]);
    // Squares of finite `f32` values cannot overflow an `f64` sum: a non-finite sum means a
    // non-finite value.
    if !sum.is_finite() {
        let bad = v
            .iter()
            .find(|x| !x.is_finite())
            .copied()
            .unwrap_or(f32::NAN);
        return Err(Error::InvalidParameter {
            name: "descriptor",
            value: f64::from(bad),
            expected: "finite values",
        });
    }
    Ok(norm_scale(sum))
}

/// The [`inverse_norm`] of a vector whose [`square_sums`] is the finite `sum`. Without a branch,
/// so that the compiler computes several at once: `1/√0 = ∞` and a scale that overflows `f32`
/// both give 0.
#[inline(always)]
pub(crate) fn norm_scale(sum: f64) -> f32 {
    let scale = (1.0 / crate::math::sqrt(sum)) as f32;
    if scale.is_finite() {
        scale
    } else {
        0.0
    }
}

/// `Σ x²` of each of `N` vectors of one length, in `f64`, as [`inverse_norm`] sums it: four
/// partial sums so that the compiler vectorises, the values past the last whole group of four
/// going first into the first sums. The vectors are interleaved group by group, so that one's
/// additions need not wait for its previous ones: four rows of 40 values at a time took 8.9 ns a
/// row where one at a time took 14 (release probe, AMD EPYC, AVX2, the 40 known when compiling;
/// 10.4 ns when known only at run time), with the same bits.
#[inline(always)]
pub(crate) fn square_sums<const N: usize>(v: [&[f32]; N]) -> [f64; N] {
    let mut part = [[0.0f64; 4]; N];
    let full = v.first().map_or(0, |v| v.len()) / 4 * 4;
    for (p, v) in part.iter_mut().zip(v) {
        for (p, &x) in p.iter_mut().zip(&v[full..]) {
            *p += f64::from(x) * f64::from(x);
        }
    }
    // Cut to whole groups, and read as arrays of four, so that the compiler sees every group
    // of every vector in bounds and keeps each vector's sums in one register (with the length
    // known only at run time, slices of four took 14.7 ns a row, these arrays 10.4).
    let v = v.map(|v| &v[..full]);
    for c in (0..full).step_by(4) {
        for (p, v) in part.iter_mut().zip(v) {
            let group: &[f32; 4] = v[c..c + 4].try_into().unwrap_or(&[0.0; 4]);
            for (p, &x) in p.iter_mut().zip(group) {
                *p += f64::from(x) * f64::from(x);
            }
        }
    }
    part.map(|p| (p[0] + p[1]) + (p[2] + p[3]))
}

fn check_query(query: &[f32], dim: usize) -> Result<(), Error> {
    if query.len() != dim {
        return Err(Error::LengthMismatch {
            what: "query vs rows dimension",
            left: query.len(),
            right: dim,
        });
    }
    Ok(())
}

fn check_out(out: &[Neighbor], k: usize) -> Result<(), Error> {
    if out.len() < k {
        return Err(Error::BufferTooSmall {
            buffer: "out",
            needed: k,
            got: out.len(),
        });
    }
    Ok(())
}

/// The k best candidates so far: a binary max-heap (worst at the root) in the caller's buffer.
struct Best<'s> {
    heap: &'s mut [Neighbor],
    len: usize,
}

impl<'s> Best<'s> {
    fn new(heap: &'s mut [Neighbor]) -> Self {
        Best { heap, len: 0 }
    }

    #[inline]
    fn full(&self) -> bool {
        self.len == self.heap.len()
    }

    /// The distance a candidate must beat to enter, when the heap is full.
    #[inline]
    fn worst(&self) -> Option<f32> {
        if self.full() && self.len > 0 {
            Some(self.heap[0].distance)
        } else {
            None
        }
    }

    /// The largest distance a candidate may have and still enter: the k-th distance so far when
    /// the heap is full, and never more than `bound` (a candidate at exactly this distance may
    /// still enter by its lower id).
    #[inline]
    fn limit(&self, bound: f32) -> f32 {
        match self.worst() {
            Some(w) if w < bound => w,
            _ => bound,
        }
    }

    /// Empties the heap (keeping its buffer).
    fn clear(&mut self) {
        self.len = 0;
    }

    #[inline]
    fn offer(&mut self, cand: Neighbor) {
        let k = self.heap.len();
        if self.len < k {
            // Sift up.
            let mut i = self.len;
            self.heap[i] = cand;
            self.len += 1;
            while i > 0 {
                let p = (i - 1) / 2;
                if self.heap[p].before(&self.heap[i]) {
                    self.heap.swap(p, i);
                    i = p;
                } else {
                    break;
                }
            }
        } else if k > 0 && cand.before(&self.heap[0]) {
            self.heap[0] = cand;
            sift_down(self.heap, 0, k);
        }
    }

    /// Sorts the heap nearest first and returns how many entries it holds.
    fn finish(self) -> usize {
        let n = self.len;
        let h = &mut self.heap[..n];
        let mut end = n;
        while end > 1 {
            end -= 1;
            h.swap(0, end);
            sift_down(h, 0, end);
        }
        n
    }
}

/// Restores the max-heap property below `i` in `h[..len]`.
#[inline]
fn sift_down(h: &mut [Neighbor], mut i: usize, len: usize) {
    loop {
        let l = 2 * i + 1;
        if l >= len {
            break;
        }
        let r = l + 1;
        let big = if r < len && h[l].before(&h[r]) { r } else { l };
        if h[i].before(&h[big]) {
            h.swap(i, big);
            i = big;
        } else {
            break;
        }
    }
}

/// Exact k-NN by one linear pass over all rows.
///
/// `query` must be L2-normalised (see [`normalize`]). The `min(k, candidates)` nearest rows
/// are written to `out[..]` nearest first (ties by lower id) and their number is returned.
///
/// # Errors
/// [`Error::LengthMismatch`] when `query.len()` differs from the rows' dimension or the
/// timestamps of `exclude` are fewer than the rows; [`Error::BufferTooSmall`] when
/// `out.len() < k`.
pub fn brute_force(
    rows: Rows<'_>,
    query: &[f32],
    k: usize,
    exclude: &Exclude<'_>,
    out: &mut [Neighbor],
) -> Result<usize, Error> {
    check_query(query, rows.dim)?;
    check_out(out, k)?;
    exclude.check(rows.n)?;
    let mut best = Best::new(&mut out[..k]);
    scan(rows, 0, rows.n, query, exclude, f32::INFINITY, &mut best);
    Ok(best.finish())
}

/// Offers the allowed ids of `lo..hi` whose distance is at most `bound` to `best`, computing
/// every distance (with AVX2 when `std` detects it: the same operations, so the same bits).
#[inline]
fn scan(
    rows: Rows<'_>,
    lo: usize,
    hi: usize,
    query: &[f32],
    exclude: &Exclude<'_>,
    bound: f32,
    best: &mut Best<'_>,
) {
    #[cfg(feature = "parallel")]
    {
        let hi = hi.min(exclude.before_id).min(rows.n);
        // The parts after the first start from empty heaps: the neighbours `best` holds already
        // (a finished kd-tree walk before the rows past the tree) bound them all the same.
        let bound = best.limit(bound);
        let part = |lo: usize, hi: usize, best: &mut Best<'_>, _: &mut Cost| {
            scan_part(rows, lo, hi, query, exclude, bound, best);
            true
        };
        if split_scan(lo, hi, 4, best, &mut Cost::default(), part).is_some() {
            return;
        }
    }
    scan_part(rows, lo, hi, query, exclude, bound, best)
}

/// Scans of at least this many rows are shared among the threads (`parallel`): a search over a
/// million rows is bound by memory, which two cores read faster than one.
#[cfg(feature = "parallel")]
const PARALLEL_SCAN: usize = 1 << 16;

/// A shared scan is cut in parts of this many rows (cut on multiples of the caller's alignment),
/// which the threads take one after another until none is left: on a machine whose other cores
/// are busy with other work, the threads that are free take more parts instead of all waiting
/// for the slowest one, and the searching thread starts at once instead of waiting for a woken
/// one.
#[cfg(feature = "parallel")]
const PARALLEL_PART: usize = 1 << 13;

/// Most threads that join the searching one in a shared scan (each keeps its neighbours on the
/// searching thread's stack).
#[cfg(feature = "parallel")]
const PARALLEL_HELPERS: usize = 15;

/// Largest `k` for which a scan is shared (each part's neighbours live on the stack).
#[cfg(feature = "parallel")]
const PARALLEL_SCAN_MAX_K: usize = 64;

/// The threads whose helpers a scan of `rows` rows for `k` neighbours shares its parts with, and
/// how many threads it then runs on ([`split_scan`]'s rule); `None`: this thread alone.
#[cfg(feature = "parallel")]
fn scan_helpers(rows: usize, k: usize) -> Option<(crate::pool::Threads, usize)> {
    if rows < PARALLEL_SCAN || !(1..=PARALLEL_SCAN_MAX_K).contains(&k) {
        return None;
    }
    crate::pool::scan_helpers().map(|t| (t, t.count().min(PARALLEL_HELPERS + 1)))
}

/// The threads a scan of `rows` rows for `k` neighbours runs on ([`split_scan`]'s rule).
pub(crate) fn scan_threads(rows: usize, k: usize) -> usize {
    #[cfg(feature = "parallel")]
    if let Some((_, threads)) = scan_helpers(rows, k) {
        return threads;
    }
    let _ = (rows, k);
    1
}

/// Runs `part` over `lo..hi` in parts of [`PARALLEL_PART`] rows (cut on multiples of `align`),
/// which this thread and the pool's take in turn, the other threads' parts into heaps of their
/// own whose neighbours then go into `best` (which may hold neighbours of other ids already);
/// `None` (nothing done) when the range is short or `k` large. Returns whether every part
/// finished its preferred way.
///
/// This thread scans from the start, while the pool's threads wake (tens of microseconds on an
/// idle machine: a `rayon::join` from outside the pool put this thread to sleep until two woken
/// workers had done everything, and woke it again, costing a 100,000-row scan about 40 % more
/// than the same scan run back to back). When no part is left it waits, spinning, for the parts
/// the others are still scanning (each a few tens of microseconds), not for a wake-up.
#[cfg(feature = "parallel")]
fn split_scan<F>(
    lo: usize,
    hi: usize,
    align: usize,
    best: &mut Best<'_>,
    cost: &mut Cost,
    part: F,
) -> Option<bool>
where
    F: Fn(usize, usize, &mut Best<'_>, &mut Cost) -> bool + Sync,
{
    use core::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

    let k = best.heap.len();
    let (pool, threads) = scan_helpers(hi.saturating_sub(lo), k)?;
    // Part i covers ids lo..first for i = 0, then the multiples of `step` from `first` on.
    let step = (PARALLEL_PART / align).max(1) * align;
    let first = ((lo / step + 1) * step).min(hi);
    let parts = 1 + (hi - first).div_ceil(step);
    let range = |i: usize| {
        if i == 0 {
            (lo, first)
        } else {
            (first + (i - 1) * step, (first + i * step).min(hi))
        }
    };
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let all_preferred = AtomicBool::new(true);
    // Takes parts until none is left; returns when every part this thread took is done.
    // Counts a part done when dropped: also when the part panics, so that the spin below ends
    // and the scope hands the panic to this thread instead of spinning forever.
    struct Done<'a>(&'a AtomicUsize);
    impl Drop for Done<'_> {
        fn drop(&mut self) {
            self.0.fetch_add(1, Ordering::Release);
        }
    }
    let work = |best: &mut Best<'_>, cost: &mut Cost| loop {
        let i = next.fetch_add(1, Ordering::Relaxed);
        if i >= parts {
            break;
        }
        let (a, b) = range(i);
        let _done = Done(&done);
        if !part(a, b, best, cost) {
            all_preferred.store(false, Ordering::Relaxed);
        }
    };
    struct Helper {
        heap: [Neighbor; PARALLEL_SCAN_MAX_K],
        len: usize,
        cost: Cost,
    }
    let mut helpers: [Helper; PARALLEL_HELPERS] = core::array::from_fn(|_| Helper {
        heap: [Neighbor::default(); PARALLEL_SCAN_MAX_K],
        len: 0,
        cost: Cost::default(),
    });
    let helpers = &mut helpers[..threads - 1];
    pool.in_place_scope(|scope| {
        for h in helpers.iter_mut() {
            let work = &work;
            scope.spawn(move |_| {
                let mut own = Best::new(&mut h.heap[..k]);
                work(&mut own, &mut h.cost);
                h.len = own.len;
            });
        }
        work(best, cost);
        // The parts the helpers still scan; the scope then finds their jobs finished instead of
        // putting this thread to sleep (a helper that never woke in time is waited for there).
        // This thread took its last part when none was left to take: every part is taken.
        let mut spins = 0u32;
        while done.load(Ordering::Acquire) < parts {
            if spins < 1 << 14 {
                spins += 1;
                core::hint::spin_loop();
            } else {
                // A helper taken off its core mid-part (a loaded machine): give the core away.
                std::thread::yield_now();
            }
        }
    });
    for h in helpers.iter() {
        for &n in &h.heap[..h.len] {
            best.offer(n);
        }
        cost.tree_rows += h.cost.tree_rows;
        cost.sketch_rows += h.cost.sketch_rows;
        cost.exact_rows += h.cost.exact_rows;
    }
    Some(all_preferred.load(Ordering::Relaxed))
}

/// [`scan`] over `lo..hi` on this thread.
#[inline]
fn scan_part(
    rows: Rows<'_>,
    lo: usize,
    hi: usize,
    query: &[f32],
    exclude: &Exclude<'_>,
    bound: f32,
    best: &mut Best<'_>,
) {
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    if std::is_x86_feature_detected!("avx2") {
        #[allow(unsafe_code)]
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for calling a
        // function compiled with `#[target_feature(enable = "avx2")]`.
        return unsafe { scan_avx2(rows, lo, hi, query, exclude, bound, best) };
    }
    scan_impl(rows, lo, hi, query, exclude, bound, best, dist4)
}

#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx2")]
fn scan_avx2(
    rows: Rows<'_>,
    lo: usize,
    hi: usize,
    query: &[f32],
    exclude: &Exclude<'_>,
    bound: f32,
    best: &mut Best<'_>,
) {
    if rows.dim == COMMON_DIM {
        // The same function with the dimension a constant: its loop unrolled.
        return scan_impl(rows, lo, hi, query, exclude, bound, best, |q, g, _, s| {
            avx2::prefetch_ahead(g);
            avx2::dist4(q, g, COMMON_DIM, s)
        });
    }
    scan_impl(rows, lo, hi, query, exclude, bound, best, |q, g, d, s| {
        avx2::prefetch_ahead(g);
        avx2::dist4(q, g, d, s)
    })
}

/// The R-SOLiD length of every preset (`n_range` = 40), for which the AVX2 scan has a copy of its
/// own.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
const COMMON_DIM: usize = 40;

/// The body of [`scan`], inlined into each of its compiled copies: four rows at a time (their
/// distances from `dist4`), and a row is offered only when its distance is within the current
/// limit.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn scan_impl(
    rows: Rows<'_>,
    lo: usize,
    hi: usize,
    query: &[f32],
    exclude: &Exclude<'_>,
    bound: f32,
    best: &mut Best<'_>,
    dist4: impl Fn(&[f32], &[f32], usize, [f32; 4]) -> [f32; 4],
) {
    if best.heap.is_empty() {
        return;
    }
    let hi = hi.min(exclude.before_id).min(rows.n);
    if lo >= hi {
        return;
    }
    let timed = exclude.not_newer_than.is_some();
    let mut limit = best.limit(bound);
    let mut offer = |id: usize, d: f32, limit: &mut f32| {
        if timed && !exclude.allows(id) {
            return;
        }
        best.offer(Neighbor {
            id: id as u32,
            distance: d,
        });
        *limit = best.limit(bound);
    };
    let mut id = lo;
    while id + 4 <= hi {
        let d = rows.dist4(query, id, &dist4);
        // Distances are clamped, never NaN: plain comparisons, no `min` (which checks for NaN).
        if (d[0] <= limit) | (d[1] <= limit) | (d[2] <= limit) | (d[3] <= limit) {
            for (j, &dj) in d.iter().enumerate() {
                if dj <= limit {
                    offer(id + j, dj, &mut limit);
                }
            }
        }
        id += 4;
    }
    while id < hi {
        let d = rows.dist(query, id);
        if d <= limit {
            offer(id, d, &mut limit);
        }
        id += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heap_keeps_k_best_sorted() {
        let mut buf = [Neighbor::default(); 3];
        let mut best = Best::new(&mut buf);
        for (id, d) in [
            (0u32, 0.5f32),
            (1, 0.1),
            (2, 0.5),
            (3, 0.9),
            (4, 0.1),
            (5, 0.0),
        ] {
            best.offer(Neighbor { id, distance: d });
        }
        assert_eq!(best.finish(), 3);
        let ids: [u32; 3] = [buf[0].id, buf[1].id, buf[2].id];
        assert_eq!(ids, [5, 1, 4]);
    }

    #[test]
    fn zero_vectors_are_at_distance_one() {
        let rows = [0.0f32, 0.0, 1.0, 0.0];
        let mut out = [Neighbor::default(); 2];
        let rows = Rows::normalized(&rows, 2).unwrap();
        let n = brute_force(rows, &[0.0, 0.0], 2, &Exclude::NONE, &mut out).unwrap();
        assert_eq!(n, 2);
        assert_eq!(
            out[0],
            Neighbor {
                id: 0,
                distance: 1.0
            }
        );
        assert_eq!(
            out[1],
            Neighbor {
                id: 1,
                distance: 1.0
            }
        );
    }

    /// A part that panics on a helper thread reaches the searching thread as a panic instead of
    /// leaving it waiting for that part forever.
    #[cfg(feature = "parallel")]
    #[test]
    fn a_panicking_part_reaches_the_searching_thread() {
        use std::sync::atomic::{AtomicBool, Ordering};
        let n = 1 << 18;
        if scan_threads(n, 1) < 2 {
            return; // one thread: nothing is shared
        }
        let searching = std::thread::current().id();
        let panicked = AtomicBool::new(false);
        let mut buf = [Neighbor::default(); 1];
        let mut best = Best::new(&mut buf);
        let mut cost = Cost::default();
        let got = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            split_scan(0, n, 4, &mut best, &mut cost, |_, _, _, _| {
                // Slow parts, so that a helper wakes and takes some; its first one panics.
                std::thread::sleep(std::time::Duration::from_millis(2));
                let helper = std::thread::current().id() != searching;
                assert!(
                    !helper || panicked.swap(true, Ordering::Relaxed),
                    "a helper's part"
                );
                true
            })
        }));
        assert!(panicked.load(Ordering::Relaxed), "no helper took a part");
        assert!(got.is_err());
    }
}
