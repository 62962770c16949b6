//! A kd-tree over 3-D points, built in place over a caller-owned permutation.
//!
//! The same design as [`crate::search::KdTree`] (which works on R-SOLiD rows): the tree is
//! implicit, a node is a range of the permutation whose split entry sits at its middle, entries
//! before it have a split coordinate `<=` the split value and entries after it `>=`; the split
//! axis of the node whose middle is position `m` is `axes[m]`. Building partitions with
//! `select_nth_unstable_by(total_cmp)`, so NaN coordinates and long runs of equal coordinates
//! (voxel centroids on a grid, a LiDAR's flat ground) neither panic nor unbalance the tree.
//! Queries recurse on index ranges and allocate nothing.
//!
//! Exactness: for finite points every query returns exactly what a linear scan would (ties broken
//! by lower id). A point with a NaN coordinate is never returned, and when a split value is NaN
//! both sides are visited, so NaN points cost time but never hide finite neighbours.

use core::cmp::Ordering;
use core::ops::Range;

use crate::Error;

/// Largest number of entries a node scans linearly instead of splitting. 16 (was 8): a leaf's
/// nearest is found before one offer, so a longer scan costs less than the nodes above it
/// (docs/performance.md#the-nearest-point-walk-a-nodes-own-point-with-its-far-side-r14-speed).
pub const LEAF_SIZE: usize = 16;

/// One neighbour found by a query: the point's index and its squared Euclidean distance.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Nearest {
    /// Index of the point in the slice the tree was built over.
    pub id: u32,
    /// Squared distance to the query, in squared metres.
    pub d2: f64,
}

impl Nearest {
    /// Takes `(id, d2)` when it beats the current best; while no point is held (`id ==
    /// u32::MAX`, never a real id) `d2` is the strict upper bound of a query.
    #[inline(always)]
    fn offer(&mut self, id: u32, d2: f64) {
        if d2 < self.d2 || (d2 == self.d2 && id < self.id && self.id != u32::MAX) {
            *self = Nearest { id, d2 };
        }
    }

    #[inline]
    fn before(&self, other: &Nearest) -> bool {
        self.d2 < other.d2 || (self.d2 == other.d2 && self.id < other.id)
    }
}

/// A kd-tree over `points` (x, y, z each), viewing caller-owned `perm` and `axes` buffers.
#[derive(Debug, Clone, Copy)]
pub struct KdTree3<'a> {
    points: &'a [[f64; 3]],
    perm: &'a [u32],
    axes: &'a [u8],
    /// `perm` is the identity (the points were stored in the tree's order): a walk reads the
    /// points at its positions directly, without the permutation.
    ordered: bool,
}

impl<'a> KdTree3<'a> {
    /// Builds a tree over every point: fills `perm[..n]` with the indices `0..n` and arranges
    /// them, writing split axes into `axes[..n]`. Allocates nothing; `O(n log n)`.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`] when `perm` or `axes` is shorter than `points`;
    /// [`Error::InvalidParameter`] (name `points`) for more than `u32::MAX` points.
    pub fn build(
        points: &'a [[f64; 3]],
        perm: &'a mut [u32],
        axes: &'a mut [u8],
    ) -> Result<KdTree3<'a>, Error> {
        let n = points.len();
        if n > u32::MAX as usize {
            return Err(Error::InvalidParameter {
                name: "points",
                value: n as f64,
                expected: "at most 2^32 - 1 points",
            });
        }
        Error::check_buffer("perm", n, perm.len())?;
        Error::check_buffer("axes", n, axes.len())?;
        let (perm, axes) = (&mut perm[..n], &mut axes[..n]);
        for (i, p) in perm.iter_mut().enumerate() {
            *p = i as u32;
        }
        build_rec(points, perm, axes);
        Ok(KdTree3 {
            points,
            perm,
            axes,
            ordered: false,
        })
    }

    /// Views buffers that [`KdTree3::build`] arranged over `points` (the crate keeps them
    /// together, so they always match); `ordered` when `perm` is the identity (the points were
    /// then stored in the tree's order).
    pub(crate) fn from_parts(
        points: &'a [[f64; 3]],
        perm: &'a [u32],
        axes: &'a [u8],
        ordered: bool,
    ) -> Self {
        debug_assert!(!ordered || perm.iter().enumerate().all(|(i, &p)| p as usize == i));
        KdTree3 {
            points,
            perm,
            axes,
            ordered,
        }
    }

    /// Number of points in the tree.
    pub fn len(&self) -> usize {
        self.perm.len()
    }

    /// `true` when the tree holds no point.
    pub fn is_empty(&self) -> bool {
        self.perm.is_empty()
    }

    /// The points the tree was built over.
    pub fn points(&self) -> &'a [[f64; 3]] {
        self.points
    }

    /// The nearest point to `q` whose squared distance is below `max_d2` (pass
    /// `f64::INFINITY` for no bound), or `None`. Ties go to the lower id.
    pub fn nearest(&self, q: [f64; 3], max_d2: f64) -> Option<Nearest> {
        let mut best = Nearest {
            id: u32::MAX,
            d2: max_d2,
        };
        if !self.perm.is_empty() {
            self.walk_from(&q, &mut best);
        }
        (best.id != u32::MAX).then_some(best)
    }

    /// The `k` nearest points to `q` (fewer when the tree is smaller), written to `out[..]`
    /// nearest first (ties by lower id); returns how many.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`] when `out.len() < k`.
    pub fn knn(&self, q: [f64; 3], k: usize, out: &mut [Nearest]) -> Result<usize, Error> {
        self.knn_near(q, k, out, 0..0)
    }

    /// [`KdTree3::knn`] that first measures the points at positions `seeds` of the tree's order
    /// (clamped to it): the same answer, found sooner when they are near `q` — for a query at
    /// a point of the tree, the points beside it in the tree's order, which share its leaf.
    /// The walk then skips them (each point is offered once).
    ///
    /// # Errors
    /// As [`KdTree3::knn`].
    pub fn knn_near(
        &self,
        q: [f64; 3],
        k: usize,
        out: &mut [Nearest],
        seeds: Range<usize>,
    ) -> Result<usize, Error> {
        Error::check_buffer("out", k, out.len())?;
        let n = self.perm.len();
        let skip = seeds.start.min(n)..seeds.end.min(n);
        let mut heap = Heap {
            h: &mut out[..k],
            len: 0,
            skip: skip.clone(),
        };
        if k > 0 && n > 0 {
            for pos in skip {
                let id = self.perm[pos];
                heap.offer(Nearest {
                    id,
                    d2: dist2(&q, &self.points[id as usize]),
                });
            }
            self.walk_from(&q, &mut heap);
        }
        Ok(heap.finish())
    }

    /// [`KdTree3::walk`] of the whole tree, without the permutation when it is the identity.
    #[inline(always)]
    fn walk_from<F: Found>(&self, q: &[f64; 3], found: &mut F) {
        if self.ordered {
            self.walk::<F, true>(q, found);
        } else {
            self.walk::<F, false>(q, found);
        }
    }

    /// The id of the point at position `pos` of the tree's order.
    #[inline(always)]
    fn id<const ORDERED: bool>(&self, pos: usize) -> u32 {
        if ORDERED {
            pos as u32
        } else {
            self.perm[pos]
        }
    }

    /// Offers to `found` every point of the tree that may be nearer than its bound.
    #[inline(always)]
    fn walk<F: Found, const ORDERED: bool>(&self, q: &[f64; 3], found: &mut F) {
        self.walk_node::<F, ORDERED>(0, self.perm.len(), q, found);
    }

    /// Offers to `found` every point of the node `lo..hi` of the tree's order that may be nearer
    /// than its bound, nearer side first. (An explicit stack of far sides instead of the
    /// recursion ran fewer instructions and took longer, as measured before:
    /// docs/performance.md#registration.)
    fn walk_node<F: Found, const ORDERED: bool>(
        &self,
        lo: usize,
        hi: usize,
        q: &[f64; 3],
        found: &mut F,
    ) {
        let n = hi - lo;
        if n <= LEAF_SIZE {
            if ORDERED {
                found.offer_run(lo, &self.points[lo..hi], q);
            } else {
                for (pos, &id) in (lo..hi).zip(&self.perm[lo..hi]) {
                    found.offer(pos, id, dist2(q, &self.points[id as usize]));
                }
            }
            return;
        }
        let mid = lo + n / 2;
        let id = self.id::<ORDERED>(mid);
        // The axis is 0, 1 or 2 (`build_rec`); `min` lets the indexing below go unchecked.
        let axis = usize::from(self.axes[mid]).min(2);
        let p = &self.points[id as usize];
        let diff = q[axis] - p[axis];
        let (near, far) = if diff <= 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.walk_node::<F, ORDERED>(near.0, near.1, q, found);
        // The node's own point and its far side, unless certainly too far (also when the bound
        // is NaN, and on a tie, which the lower id may win). The point lies on the splitting
        // plane: no nearer than it, so offered only here, where the bound is the near side's
        // (the answer does not depend on the order of the offers: the nearest by distance,
        // then by lower id).
        if (diff * diff).partial_cmp(&found.bound()) != Some(Ordering::Greater) {
            found.offer(mid, id, dist2(q, p));
            self.walk_node::<F, ORDERED>(far.0, far.1, q, found);
        }
    }
}

/// What a walk of the tree collects: the nearest point ([`Nearest`]) or the k nearest.
trait Found {
    /// Takes point `id` (at position `pos` of the tree's order) at squared distance `d2` if it
    /// is among the wanted.
    fn offer(&mut self, pos: usize, id: u32, d2: f64);
    /// The squared distance a point must not exceed to matter.
    fn bound(&self) -> f64;
    /// Offers the points `run`, at positions (and ids) `lo..` of the tree's order.
    #[inline(always)]
    fn offer_run(&mut self, lo: usize, run: &[[f64; 3]], q: &[f64; 3]) {
        for (pos, p) in (lo..).zip(run) {
            self.offer(pos, pos as u32, dist2(q, p));
        }
    }
}

impl Found for Nearest {
    #[inline(always)]
    fn offer(&mut self, _pos: usize, id: u32, d2: f64) {
        Nearest::offer(self, id, d2);
    }
    #[inline(always)]
    fn bound(&self) -> f64 {
        self.d2
    }
    /// The run's nearest point first (the first of equals: the lowest id), then one offer.
    #[inline(always)]
    fn offer_run(&mut self, lo: usize, run: &[[f64; 3]], q: &[f64; 3]) {
        let (mut best, mut at) = (f64::INFINITY, usize::MAX);
        for (k, p) in run.iter().enumerate() {
            let d2 = dist2(q, p);
            // NaN distances never enter.
            if d2 < best {
                (best, at) = (d2, k);
            }
        }
        if at != usize::MAX {
            Nearest::offer(self, (lo + at) as u32, best);
        }
    }
}

impl Found for Heap<'_> {
    #[inline(always)]
    fn offer(&mut self, pos: usize, id: u32, d2: f64) {
        // The seeds were offered before the walk.
        if !self.skip.contains(&pos) {
            Heap::offer(self, Nearest { id, d2 });
        }
    }
    #[inline(always)]
    fn bound(&self) -> f64 {
        self.worst()
    }
}

#[inline(always)]
fn dist2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let (dx, dy, dz) = (a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    dx * dx + dy * dy + dz * dz
}

/// The k best so far, sorted nearest first in the caller's buffer (k is small: a sorted
/// insertion beats a heap there).
struct Heap<'s> {
    h: &'s mut [Nearest],
    len: usize,
    /// Positions of the tree's order already offered (the seeds of [`KdTree3::knn_near`]).
    skip: Range<usize>,
}

impl Heap<'_> {
    /// The squared distance a candidate must not exceed to matter (infinite until full).
    #[inline]
    fn worst(&self) -> f64 {
        if self.len == self.h.len() {
            self.h[self.len - 1].d2
        } else {
            f64::INFINITY
        }
    }

    #[inline(always)]
    fn offer(&mut self, c: Nearest) {
        // NaN distances (points with a NaN coordinate) never enter.
        if c.d2.is_nan() {
            return;
        }
        let k = self.h.len();
        if self.len == k && !c.before(&self.h[k - 1]) {
            return;
        }
        let mut i = self.len.min(k - 1);
        while i > 0 && c.before(&self.h[i - 1]) {
            self.h[i] = self.h[i - 1];
            i -= 1;
        }
        self.h[i] = c;
        self.len = (self.len + 1).min(k);
    }

    fn finish(self) -> usize {
        self.len
    }
}

/// The axis of widest extent of the node's points (ties: the lowest axis; NaN is ignored).
fn widest_axis(points: &[[f64; 3]], perm: &[u32]) -> usize {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for &i in perm {
        let p = &points[i as usize];
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    let mut best = 0;
    for d in 1..3 {
        if hi[d] - lo[d] > hi[best] - lo[best] {
            best = d;
        }
    }
    best
}

fn build_rec(points: &[[f64; 3]], perm: &mut [u32], axes: &mut [u8]) {
    let n = perm.len();
    if n <= LEAF_SIZE {
        return;
    }
    let d = widest_axis(points, perm);
    let mid = n / 2;
    perm.select_nth_unstable_by(mid, |&a, &b| {
        points[a as usize][d].total_cmp(&points[b as usize][d])
    });
    axes[mid] = d as u8;
    let (lp, rp) = perm.split_at_mut(mid);
    let (la, ra) = axes.split_at_mut(mid);
    build_rec(points, lp, la);
    build_rec(points, &mut rp[1..], &mut ra[1..]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;
    use alloc::vec::Vec;

    fn brute(points: &[[f64; 3]], q: [f64; 3], k: usize) -> Vec<Nearest> {
        let mut all: Vec<Nearest> = points
            .iter()
            .enumerate()
            .map(|(i, p)| Nearest {
                id: i as u32,
                d2: dist2(&q, p),
            })
            .filter(|n| !n.d2.is_nan())
            .collect();
        all.sort_by(|a, b| a.d2.total_cmp(&b.d2).then(a.id.cmp(&b.id)));
        all.truncate(k);
        all
    }

    fn cloud(n: usize, seed: u64, grid: f64) -> Vec<[f64; 3]> {
        let mut s = seed;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| {
                let p = [next() * 20.0 - 10.0, next() * 20.0 - 10.0, next() * 4.0];
                if grid > 0.0 {
                    p.map(|v| libm::floor(v / grid) * grid)
                } else {
                    p
                }
            })
            .collect()
    }

    #[test]
    fn queries_equal_a_linear_scan() {
        // Continuous and heavily quantised clouds (many equal coordinates and duplicates).
        for (grid, n) in [(0.0, 1000), (1.0, 1500), (5.0, 300), (0.0, 5)] {
            let pts = cloud(n, 42 + n as u64, grid);
            let (mut perm, mut axes) = (vec![0; n], vec![0; n]);
            let tree = KdTree3::build(&pts, &mut perm, &mut axes).unwrap();
            let mut queries = cloud(50, 7, 0.0);
            // Queries outside the cloud too.
            queries.extend(
                cloud(50, 9, 0.0)
                    .iter()
                    .map(|p| [3.0 * p[0], 2.0 * p[1], 8.0 * p[2] - 10.0]),
            );
            for q in queries.iter().chain(pts.iter().take(20)) {
                for k in [1, 3, 10] {
                    let mut out = vec![Nearest::default(); k];
                    let m = tree.knn(*q, k, &mut out).unwrap();
                    assert_eq!(&out[..m], &brute(&pts, *q, k)[..], "grid {grid} k {k}");
                    // Seeded from any run of positions (empty, past the end, the whole tree):
                    // the same answer.
                    for seeds in [0..0, 3..9, n / 2..n / 2 + 11, n - 2..n + 5, 0..n] {
                        let mut seeded = vec![Nearest::default(); k];
                        let m2 = tree.knn_near(*q, k, &mut seeded, seeds.clone()).unwrap();
                        assert_eq!(&seeded[..m2], &out[..m], "grid {grid} k {k} {seeds:?}");
                    }
                }
                let b = brute(&pts, *q, 1)[0];
                assert_eq!(tree.nearest(*q, f64::INFINITY), Some(b));
                assert_eq!(tree.nearest(*q, b.d2), None, "the bound is strict");
            }
        }
    }

    #[test]
    fn a_tree_over_points_stored_in_its_order_equals_a_linear_scan() {
        // The points rearranged in the tree's order (as a prepared cloud stores them): the walk
        // without the permutation finds what a linear scan does, ties (quantised clouds: many
        // equal distances) to the lowest id, with and without a bound, seeded or not.
        for (grid, n) in [(0.0, 1000), (1.0, 1500), (0.5, 700), (5.0, 300), (0.0, 5)] {
            let raw = cloud(n, 11 + n as u64, grid);
            let (mut perm, mut axes) = (vec![0; n], vec![0; n]);
            let _ = KdTree3::build(&raw, &mut perm, &mut axes).unwrap();
            let pts: Vec<[f64; 3]> = perm.iter().map(|&i| raw[i as usize]).collect();
            let identity: Vec<u32> = (0..n as u32).collect();
            let tree = KdTree3::from_parts(&pts, &identity, &axes, true);
            let unordered = KdTree3 {
                ordered: false,
                ..tree
            };
            let mut queries = cloud(60, 5, 0.0);
            queries.extend(cloud(30, 6, grid));
            queries.extend(pts.iter().step_by(7).copied());
            for q in &queries {
                for k in [1, 4, 10] {
                    let mut out = vec![Nearest::default(); k];
                    let m = tree.knn(*q, k, &mut out).unwrap();
                    assert_eq!(&out[..m], &brute(&pts, *q, k)[..], "grid {grid} k {k}");
                    let mut seeded = vec![Nearest::default(); k];
                    let m2 = tree.knn_near(*q, k, &mut seeded, 2..2 + k).unwrap();
                    assert_eq!(&seeded[..m2], &out[..m]);
                }
                let b = brute(&pts, *q, 1)[0];
                for bound in [f64::INFINITY, 1.0, 0.3, b.d2 + 1e-12] {
                    let want = (b.d2 < bound).then_some(b);
                    assert_eq!(tree.nearest(*q, bound), want, "grid {grid} bound {bound}");
                    assert_eq!(unordered.nearest(*q, bound), want);
                }
                assert_eq!(tree.nearest(*q, b.d2), None, "the bound is strict");
            }
        }
    }

    #[test]
    fn nan_points_are_never_returned_and_hide_nothing() {
        let mut pts = cloud(200, 3, 0.0);
        for i in (0..200).step_by(7) {
            pts[i][i % 3] = f64::NAN;
        }
        let (mut perm, mut axes) = (vec![0; 200], vec![0; 200]);
        let tree = KdTree3::build(&pts, &mut perm, &mut axes).unwrap();
        for q in cloud(30, 9, 0.0) {
            let mut out = vec![Nearest::default(); 5];
            let m = tree.knn(q, 5, &mut out).unwrap();
            assert_eq!(&out[..m], &brute(&pts, q, 5)[..]);
            assert_eq!(tree.nearest(q, f64::INFINITY), Some(brute(&pts, q, 1)[0]));
        }
        // A NaN query finds nothing and does not panic.
        assert_eq!(tree.nearest([f64::NAN, 0.0, 0.0], f64::INFINITY), None);
    }

    #[test]
    fn empty_tree_and_small_buffers() {
        let tree = KdTree3::build(&[], &mut [], &mut []).unwrap();
        assert!(tree.is_empty());
        assert_eq!(tree.nearest([0.0; 3], f64::INFINITY), None);
        assert_eq!(tree.knn([0.0; 3], 0, &mut []), Ok(0));
        let pts = [[0.0; 3]; 4];
        assert!(matches!(
            KdTree3::build(&pts, &mut [0; 3], &mut [0; 4]),
            Err(Error::BufferTooSmall { buffer: "perm", .. })
        ));
        let (mut perm, mut axes) = ([0; 4], [0; 4]);
        let tree = KdTree3::build(&pts, &mut perm, &mut axes).unwrap();
        assert!(matches!(
            tree.knn([0.0; 3], 2, &mut [Nearest::default()]),
            Err(Error::BufferTooSmall { buffer: "out", .. })
        ));
        // All points coincide: the k nearest are the k lowest ids.
        let mut out = [Nearest::default(); 2];
        assert_eq!(tree.knn([0.0; 3], 2, &mut out), Ok(2));
        assert_eq!((out[0].id, out[1].id), (0, 1));
    }
}
