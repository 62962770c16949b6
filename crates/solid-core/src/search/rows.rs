//! The rows a search compares ([`Rows`]) and the one distance every search computes
//! ([`normalized_distance`]): dot products in a fixed summation order, portable and AVX2.

use super::{check_query, n_rows};
use crate::Error;

/// Dot product with eight independent accumulators (vectorisable, fixed summation order).
#[inline(always)]
pub(super) fn dot(a: &[f32], b: &[f32]) -> f32 {
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
pub(super) fn dist(q: &[f32], c: &[f32]) -> f32 {
    clamp_distance(1.0 - dot(q, c))
}

/// Clamps a distance into `[0, 1]`; NaN counts as 1.
#[inline(always)]
pub(super) fn clamp_distance(d: f32) -> f32 {
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
    pub(super) data: &'a [f32],
    pub(super) dim: usize,
    pub(super) n: usize,
    pub(super) scale: Option<&'a [f32]>,
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

    /// L2-normalised rows (see [`normalize_rows`](super::normalize_rows)).
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
        Error::check_buffer("scale", n, scale.len())?;
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
        Error::check_buffer("out", self.n, out.len())?;
        for (i, o) in out[..self.n].iter_mut().enumerate() {
            *o = self.dist(query, i);
        }
        Ok(())
    }

    /// Row `i` as stored.
    #[inline(always)]
    pub(super) fn row(&self, i: usize) -> &'a [f32] {
        &self.data[i * self.dim..(i + 1) * self.dim]
    }

    /// Row `i` as stored and the scale that normalises it (1 for normalised rows).
    #[inline(always)]
    pub(super) fn raw_row(&self, i: usize) -> (&'a [f32], f32) {
        (self.row(i), self.scale.map_or(1.0, |s| s[i]))
    }

    /// Value `d` of normalised row `i`.
    #[inline(always)]
    pub(super) fn coord(&self, i: usize, d: usize) -> f32 {
        let v = self.data[i * self.dim + d];
        match self.scale {
            Some(s) => v * s[i],
            None => v,
        }
    }

    /// The distance of the normalised query to row `i`.
    #[inline(always)]
    pub(super) fn dist(&self, q: &[f32], i: usize) -> f32 {
        match self.scale {
            Some(s) => clamp_distance(1.0 - dot(q, self.row(i)) * s[i]),
            None => dist(q, self.row(i)),
        }
    }

    /// The distances of the normalised query to rows `i..i + 4`, from their dot products as
    /// `dot4` computes them (summed exactly as [`dot`] sums them), clamped as [`dist`] clamps.
    #[inline(always)]
    pub(super) fn dist4(
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
pub(super) fn dist4(q: &[f32], group: &[f32], dim: usize, scale: [f32; 4]) -> [f32; 4] {
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
pub(super) mod avx2 {
    use core::arch::x86_64::{
        __m128, __m256, _mm256_add_ps, _mm256_castps256_ps128, _mm256_extractf128_ps,
        _mm256_mul_ps, _mm256_setzero_ps, _mm_add_ps, _mm_hadd_ps, _mm_max_ps, _mm_min_ps,
        _mm_mul_ps, _mm_prefetch, _mm_set1_ps, _mm_setzero_ps, _mm_sub_ps, _MM_HINT_T0,
    };

    #[inline(always)]
    pub(super) fn load(s: &[f32]) -> __m256 {
        let s: &[f32; 8] = s.try_into().unwrap_or(&[0.0; 8]);
        bytemuck::cast(*s)
    }

    /// Groups of four rows ahead of the one being compared that [`prefetch_ahead`] asks the
    /// cache for, ahead of the hardware prefetcher; 4 was the fastest distance tried
    /// (docs/performance.md#brute-force).
    const PREFETCH_GROUPS: usize = 4;

    /// Asks for the cache lines of the group [`PREFETCH_GROUPS`] after `group` (4 rows). A hint
    /// only: addresses past the end are never read (prefetches do not fault).
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(in crate::search) fn prefetch_ahead(group: &[f32]) {
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
    pub(in crate::search) fn dist4(
        q: &[f32],
        group: &[f32],
        dim: usize,
        scale: [f32; 4],
    ) -> [f32; 4] {
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
/// additions need not wait for its previous ones (faster, the same bits: docs/performance.md#database).
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
    // of every vector in bounds and keeps each vector's sums in one register (slices of four were
    // slower when the length is known only at run time).
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
