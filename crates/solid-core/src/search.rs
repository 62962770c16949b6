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

/// `$avx2`, a call of a function compiled with `#[target_feature(enable = "avx2")]`, when `std`
/// detects AVX2 on x86_64; `$portable` otherwise. The copies do the same operations, so they give
/// the same bits.
macro_rules! avx2_or {
    ($avx2:expr, $portable:expr) => {
        match () {
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            #[allow(unsafe_code)]
            // SAFETY: the CPU supports AVX2 (checked by the guard), the only requirement for
            // calling a function compiled with `#[target_feature(enable = "avx2")]`.
            () if std::is_x86_feature_detected!("avx2") => unsafe { $avx2 },
            () => $portable,
        }
    };
}

/// Defines `$avx2`, the function (or method, `self.$inner`) `$inner` inlined and compiled for
/// AVX2, for [`avx2_or`].
macro_rules! avx2_copy {
    ($(#[$doc:meta])* $avx2:ident = self.$inner:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)?) => {
        $(#[$doc])*
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        #[target_feature(enable = "avx2")]
        fn $avx2(&self, $($arg: $ty),*) $(-> $ret)? {
            self.$inner($($arg),*)
        }
    };
    ($(#[$doc:meta])* $avx2:ident = $inner:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)?) => {
        $(#[$doc])*
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        #[target_feature(enable = "avx2")]
        fn $avx2($($arg: $ty),*) $(-> $ret)? {
            $inner($($arg),*)
        }
    };
}

mod brute;
mod index;
mod kdtree;
mod rows;
mod sketch;

pub use brute::brute_force;
pub(crate) use brute::scan_threads;
#[cfg(feature = "parallel")]
use brute::split_scan;
use brute::{scan, Best, Probe};
pub use rows::{inverse_norm, normalized_distance, Rows};
#[cfg(feature = "alloc")]
pub(crate) use rows::{norm_scale, square_sums};

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

/// The checks every search starts with: the query has the rows' dimension `dim`, `out` holds
/// `k` neighbours and `exclude` covers the `n` rows.
fn check_search(
    query: &[f32],
    dim: usize,
    n: usize,
    k: usize,
    exclude: &Exclude<'_>,
    out: &[Neighbor],
) -> Result<(), Error> {
    check_query(query, dim)?;
    Error::check_buffer("out", k, out.len())?;
    exclude.check(n)
}

/// An exact k-NN over `n` rows of dimension `dim` after [`check_search`]: `fill` offers rows
/// to the `k` best, kept in `out`; returns how many it found.
#[inline]
fn exact_knn(
    query: &[f32],
    dim: usize,
    n: usize,
    k: usize,
    exclude: &Exclude<'_>,
    out: &mut [Neighbor],
    fill: impl FnOnce(&mut Best<'_>),
) -> Result<usize, Error> {
    check_search(query, dim, n, k, exclude, out)?;
    let mut best = Best::new(&mut out[..k]);
    fill(&mut best);
    Ok(best.finish())
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
