//! Exact nearest-neighbour search over R-SOLiD vectors ([spec §3](crate::spec#3-comparing-descriptors)), allocation-free.
//!
//! Every search works on **L2-normalised** rows (see [`normalize`] and [`normalize_rows`]) stored
//! row-major in one contiguous `&[f32]`, so that the cosine distance of [spec §3](crate::spec#3-comparing-descriptors) is
//! `1 − q·c` and its order equals the Euclidean order (`‖q − c‖² = 2 − 2 q·c`). An all-zero
//! vector stays all-zero after normalisation and is at distance 1 from everything, as [spec §3](crate::spec#3-comparing-descriptors)
//! says. Distances are clamped into `[0, 1]`.
//!
//! Three exact searches answer the same question and return the same neighbours in the same
//! order (ties broken by the lower id):
//! - [`brute_force`]: one linear pass over the rows, with dot products accumulated in eight
//!   independent lanes so that the compiler vectorises them.
//! - [`KdTree`]: a kd-tree built in place over a caller-owned permutation of row ids (plus one
//!   `u16` per entry for the split dimensions); neither build nor query allocates.
//! - [`online_insert`] / [`OnlineIndex::search`]: an index that grows one entry at a time and always
//!   answers exactly over every entry added so far. It is the logarithmic method (Bentley & Saxe):
//!   the ids `0..n` are cut into blocks whose sizes are the powers of two of `n`'s binary
//!   representation, each block a static [`KdTree`] over its own part of the shared permutation.
//!   An insert rebuilds only the block the new entry completes (amortised `O(log² n)` work).
//!
//! Candidates can be restricted with [`Exclude`]: only ids below a bound (which excludes the most
//! recent entries of a loop detector) and only entries not newer than a time.
//!
//! ```
//! use solid_lidar::search::{brute_force, normalize_rows, Exclude, KdTree, Neighbor};
//!
//! let raw = [1.0f32, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0];
//! let dim = 2;
//! let mut rows = [0.0f32; 8];
//! normalize_rows(&raw, dim, &mut rows).unwrap();
//! let query = [1.0f32, 0.0];
//! let mut out = [Neighbor::default(); 2];
//! let n = brute_force(&rows, dim, &query, 2, &Exclude::NONE, &mut out).unwrap();
//! assert_eq!(n, 2);
//! assert_eq!((out[0].id, out[1].id), (0, 2)); // exact match, then 45°
//!
//! let (mut perm, mut splits) = ([0u32; 4], [0u16; 4]);
//! let tree = KdTree::build(&rows, dim, &mut perm, &mut splits).unwrap();
//! let mut out2 = [Neighbor::default(); 2];
//! tree.search(&query, 2, &Exclude::NONE, &mut out2).unwrap();
//! assert_eq!(out, out2);
//! ```

use crate::Error;

/// Largest number of entries a kd-tree node scans linearly instead of splitting.
pub const LEAF_SIZE: usize = 12;

/// Points sampled per node to choose the split dimension (the widest spread among them).
const SPLIT_SAMPLE: usize = 32;

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
    let inv = 1.0 / libm::sqrt(sum);
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
#[inline]
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
#[inline]
fn dist(q: &[f32], c: &[f32]) -> f32 {
    let d = 1.0 - dot(q, c);
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
    if dim == 0 || dim > u16::MAX as usize || rows.len() % dim != 0 {
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
/// `rows` holds L2-normalised vectors of `dim` values, row-major; the id of a row is its index.
/// `query` must be L2-normalised too (see [`normalize`]). The `min(k, candidates)` nearest
/// neighbours are written to `out[..]` nearest first (ties by lower id) and their number is
/// returned.
///
/// # Errors
/// [`Error::InvalidParameter`] for a `dim` that is 0, above 65535 or does not divide
/// `rows.len()`; [`Error::LengthMismatch`] when `query.len() != dim` or the timestamps of
/// `exclude` are fewer than the rows; [`Error::BufferTooSmall`] when `out.len() < k`.
pub fn brute_force(
    rows: &[f32],
    dim: usize,
    query: &[f32],
    k: usize,
    exclude: &Exclude<'_>,
    out: &mut [Neighbor],
) -> Result<usize, Error> {
    let n = n_rows(rows, dim)?;
    check_query(query, dim)?;
    check_out(out, k)?;
    exclude.check(n)?;
    let mut best = Best::new(&mut out[..k]);
    scan(rows, dim, 0, n, query, exclude, &mut best);
    Ok(best.finish())
}

/// Offers ids `lo..hi` to `best`.
#[inline]
fn scan(
    rows: &[f32],
    dim: usize,
    lo: usize,
    hi: usize,
    query: &[f32],
    exclude: &Exclude<'_>,
    best: &mut Best<'_>,
) {
    if best.heap.is_empty() {
        return;
    }
    let hi = hi.min(exclude.before_id);
    if lo >= hi {
        return;
    }
    let block = &rows[lo * dim..hi * dim];
    let timed = exclude.not_newer_than.is_some();
    let mut worst = best.worst();
    for (i, row) in block.chunks_exact(dim).enumerate() {
        let d = dist(query, row);
        if let Some(w) = worst {
            if d > w {
                continue;
            }
        }
        let id = lo + i;
        if timed && !exclude.allows(id) {
            continue;
        }
        best.offer(Neighbor {
            id: id as u32,
            distance: d,
        });
        worst = best.worst();
    }
}

/// Margin by which the kd-tree's lower bound must exceed the current worst distance before a
/// subtree is skipped: covers the `f32` rounding of normalisation and of the dot product, so that
/// pruning never drops a neighbour that [`brute_force`] would return.
#[inline]
fn prune_margin(dim: usize) -> f64 {
    (dim as f64 + 64.0) * 1.2e-7
}

/// A kd-tree over L2-normalised rows, built in place in caller-owned buffers.
///
/// The tree is implicit: a node is a range of the permutation; its split entry sits at the middle
/// of the range, the entries before it have a split coordinate `<=` the split value and those after
/// it `>=`. The split dimension of the node whose middle is position `m` is `splits[m]`. Ranges of
/// at most [`LEAF_SIZE`] entries are scanned linearly.
///
/// Queries are exact: a subtree is skipped only when `(q_d − s)² / 2`, a lower bound of the
/// distance of everything in it, exceeds the current k-th distance by more than the rounding
/// margin; with equal distances the lower id wins, exactly as in [`brute_force`].
#[derive(Debug, Clone, Copy)]
pub struct KdTree<'a> {
    rows: &'a [f32],
    dim: usize,
    perm: &'a [u32],
    splits: &'a [u16],
}

impl<'a> KdTree<'a> {
    /// Builds a tree over every row of `rows` (ids `0..n`): fills `perm[..n]` with the ids and
    /// arranges them, writing split dimensions into `splits[..n]`. Allocates nothing.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a bad `dim` (see [`brute_force`]);
    /// [`Error::BufferTooSmall`] when `perm` or `splits` is shorter than the number of rows.
    pub fn build(
        rows: &'a [f32],
        dim: usize,
        perm: &'a mut [u32],
        splits: &'a mut [u16],
    ) -> Result<KdTree<'a>, Error> {
        let n = n_rows(rows, dim)?;
        check_buffers(n, perm.len(), splits.len())?;
        let (perm, splits) = (&mut perm[..n], &mut splits[..n]);
        for (i, p) in perm.iter_mut().enumerate() {
            *p = i as u32;
        }
        build_rec(rows, dim, perm, splits);
        Ok(KdTree {
            rows,
            dim,
            perm,
            splits,
        })
    }

    /// Views buffers that [`KdTree::build`] (or [`online_insert`], for one block) has arranged,
    /// without rebuilding. `perm` and `splits` must be the exact ranges that were built.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a bad `dim`; [`Error::LengthMismatch`] when `perm` and
    /// `splits` differ in length; [`Error::InvalidParameter`] (name `perm`) when an id in `perm`
    /// is not a row of `rows`.
    pub fn from_built(
        rows: &'a [f32],
        dim: usize,
        perm: &'a [u32],
        splits: &'a [u16],
    ) -> Result<KdTree<'a>, Error> {
        let n = n_rows(rows, dim)?;
        if perm.len() != splits.len() {
            return Err(Error::LengthMismatch {
                what: "perm vs splits",
                left: perm.len(),
                right: splits.len(),
            });
        }
        if let Some(&bad) = perm.iter().find(|&&p| p as usize >= n) {
            return Err(Error::InvalidParameter {
                name: "perm",
                value: bad as f64,
                expected: "ids of existing rows",
            });
        }
        Ok(KdTree {
            rows,
            dim,
            perm,
            splits,
        })
    }

    /// Number of entries in the tree.
    pub fn len(&self) -> usize {
        self.perm.len()
    }

    /// `true` when the tree holds no entry.
    pub fn is_empty(&self) -> bool {
        self.perm.is_empty()
    }

    /// Exact k-NN: the same contract and the same results as [`brute_force`] over the tree's
    /// entries (`query` L2-normalised; `out[..k]` is the heap; nearest first, ties by lower id).
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
        exclude.check(self.rows.len() / self.dim)?;
        let mut best = Best::new(&mut out[..k]);
        if k > 0 {
            self.search_into(query, exclude, &mut best);
        }
        Ok(best.finish())
    }

    fn search_into(&self, query: &[f32], exclude: &Exclude<'_>, best: &mut Best<'_>) {
        let mut off = [0f64; MAX_OFFSET_DIM];
        let tracked = if self.dim <= MAX_OFFSET_DIM {
            self.dim
        } else {
            0
        };
        let mut walk = Walk {
            query,
            exclude,
            eps: prune_margin(self.dim),
            off: &mut off[..tracked],
        };
        self.rec(0, self.perm.len(), 0.0, &mut walk, best);
    }

    #[inline]
    fn consider(&self, id: u32, query: &[f32], exclude: &Exclude<'_>, best: &mut Best<'_>) {
        let i = id as usize;
        if !exclude.allows(i) {
            return;
        }
        let d = dist(query, &self.rows[i * self.dim..(i + 1) * self.dim]);
        best.offer(Neighbor { id, distance: d });
    }

    /// Visits the node `perm[lo..hi]`, whose cell is at squared Euclidean distance at least
    /// `rd` from the query (Arya & Mount's incremental bound: `rd = Σ_d off[d]²`).
    fn rec(&self, lo: usize, hi: usize, rd: f64, walk: &mut Walk<'_>, best: &mut Best<'_>) {
        let n = hi - lo;
        if n <= LEAF_SIZE {
            for &id in &self.perm[lo..hi] {
                self.consider(id, walk.query, walk.exclude, best);
            }
            return;
        }
        let mid = lo + n / 2;
        let pid = self.perm[mid];
        let d = self.splits[mid] as usize;
        let s = self.rows[pid as usize * self.dim + d];
        self.consider(pid, walk.query, walk.exclude, best);
        let diff = walk.query[d] as f64 - s as f64;
        let (near, far) = if diff <= 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.rec(near.0, near.1, rd, walk, best);
        if far.0 < far.1 {
            // Every entry of the far cell has its coordinate d beyond s: its offset along d is
            // at least |diff|, which replaces the cell's previous offset along d.
            let old = walk.off.get(d).copied().unwrap_or(0.0);
            let far_rd = if walk.off.is_empty() {
                diff * diff
            } else {
                rd - old * old + diff * diff
            };
            let skip = match best.worst() {
                // Distances are at most 1; while the k-th is 1 a tie at 1 with a lower id may
                // still be ahead, so never skip then. NaN bounds never skip.
                Some(w) if w < 1.0 => 0.5 * far_rd > w as f64 + walk.eps,
                _ => false,
            };
            if !skip {
                if let Some(o) = walk.off.get_mut(d) {
                    *o = diff;
                }
                self.rec(far.0, far.1, far_rd, walk, best);
                if let Some(o) = walk.off.get_mut(d) {
                    *o = old;
                }
            }
        }
    }
}

/// Largest dimension for which queries keep per-dimension cell offsets (on the stack) for the
/// incremental bound; above it they fall back to the single-split bound `(q_d − s)²`.
const MAX_OFFSET_DIM: usize = 1024;

/// The per-query state of a kd-tree walk.
struct Walk<'q> {
    query: &'q [f32],
    exclude: &'q Exclude<'q>,
    eps: f64,
    /// Offsets of the current cell from the query along each dimension (empty: not tracked).
    off: &'q mut [f64],
}

fn check_buffers(n: usize, perm: usize, splits: usize) -> Result<(), Error> {
    if perm < n {
        return Err(Error::BufferTooSmall {
            buffer: "perm",
            needed: n,
            got: perm,
        });
    }
    if splits < n {
        return Err(Error::BufferTooSmall {
            buffer: "splits",
            needed: n,
            got: splits,
        });
    }
    Ok(())
}

/// Chooses the dimension with the widest spread among up to [`SPLIT_SAMPLE`] evenly spaced
/// entries of `perm` (ties: the lowest dimension).
fn widest_dim(rows: &[f32], dim: usize, perm: &[u32]) -> usize {
    let n = perm.len();
    let step = (n / SPLIT_SAMPLE).max(1);
    let mut best_d = 0;
    let mut best_spread = -1.0f32;
    for d in 0..dim {
        let mut lo = f32::INFINITY;
        let mut hi = f32::NEG_INFINITY;
        let mut i = 0;
        while i < n {
            let v = rows[perm[i] as usize * dim + d];
            lo = lo.min(v);
            hi = hi.max(v);
            i += step;
        }
        let spread = hi - lo;
        if spread > best_spread {
            best_spread = spread;
            best_d = d;
        }
    }
    best_d
}

fn build_rec(rows: &[f32], dim: usize, perm: &mut [u32], splits: &mut [u16]) {
    let n = perm.len();
    if n <= LEAF_SIZE {
        return;
    }
    let d = widest_dim(rows, dim, perm);
    let mid = n / 2;
    perm.select_nth_unstable_by(mid, |&a, &b| {
        rows[a as usize * dim + d].total_cmp(&rows[b as usize * dim + d])
    });
    splits[mid] = d as u16;
    let (lp, rp) = perm.split_at_mut(mid);
    let (ls, rs) = splits.split_at_mut(mid);
    build_rec(rows, dim, lp, ls);
    build_rec(rows, dim, &mut rp[1..], &mut rs[1..]);
}

/// The blocks of the online index over `n` entries: `(start, end)` id ranges, largest first.
fn blocks(n: usize) -> impl Iterator<Item = (usize, usize)> {
    let mut start = 0usize;
    (0..usize::BITS).rev().filter_map(move |bit| {
        let size = 1usize << bit;
        if n & size != 0 {
            let b = (start, start + size);
            start += size;
            Some(b)
        } else {
            None
        }
    })
}

/// Adds the newest row to an online index.
///
/// The index over the first `n` rows of `rows` (ids `0..n`, where `n = rows.len() / dim` counts
/// the row just appended) lives in `perm[..n]` and `splits[..n]`; call this once after each row
/// is appended, in order. It rebuilds the one block that the new entry completes (sizes are
/// powers of two, so an entry is rebuilt `O(log n)` times in its life). Allocates nothing.
///
/// # Errors
/// [`Error::InvalidParameter`] for a bad `dim` (see [`brute_force`]) or when `rows` is empty;
/// [`Error::BufferTooSmall`] when `perm` or `splits` is shorter than the number of rows.
pub fn online_insert(
    rows: &[f32],
    dim: usize,
    perm: &mut [u32],
    splits: &mut [u16],
) -> Result<(), Error> {
    let n = n_rows(rows, dim)?;
    if n == 0 {
        return Err(Error::InvalidParameter {
            name: "rows",
            value: 0.0,
            expected: "at least the entry being inserted",
        });
    }
    check_buffers(n, perm.len(), splits.len())?;
    let size = 1usize << n.trailing_zeros();
    rebuild_block(rows, dim, n - size, n, perm, splits);
    Ok(())
}

/// Builds every block of the online index over all rows from scratch (for example after loading
/// a database); equivalent to calling [`online_insert`] after each row, but faster.
///
/// # Errors
/// As [`online_insert`], except that zero rows is fine.
pub fn online_rebuild(
    rows: &[f32],
    dim: usize,
    perm: &mut [u32],
    splits: &mut [u16],
) -> Result<(), Error> {
    let n = n_rows(rows, dim)?;
    check_buffers(n, perm.len(), splits.len())?;
    for (a, b) in blocks(n) {
        rebuild_block(rows, dim, a, b, perm, splits);
    }
    Ok(())
}

fn rebuild_block(
    rows: &[f32],
    dim: usize,
    a: usize,
    b: usize,
    perm: &mut [u32],
    splits: &mut [u16],
) {
    let p = &mut perm[a..b];
    for (i, v) in p.iter_mut().enumerate() {
        *v = (a + i) as u32;
    }
    build_rec(rows, dim, p, &mut splits[a..b]);
}

/// A view of an online index (see [`online_insert`]) for searching.
#[derive(Debug, Clone, Copy)]
pub struct OnlineIndex<'a> {
    rows: &'a [f32],
    dim: usize,
    perm: &'a [u32],
    splits: &'a [u16],
}

impl<'a> OnlineIndex<'a> {
    /// Views the index that [`online_insert`] or [`online_rebuild`] maintains in `perm[..n]` and
    /// `splits[..n]` over the `n` rows of `rows`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a bad `dim` (see [`brute_force`]);
    /// [`Error::BufferTooSmall`] when `perm` or `splits` is shorter than the number of rows.
    pub fn new(
        rows: &'a [f32],
        dim: usize,
        perm: &'a [u32],
        splits: &'a [u16],
    ) -> Result<OnlineIndex<'a>, Error> {
        let n = n_rows(rows, dim)?;
        check_buffers(n, perm.len(), splits.len())?;
        Ok(OnlineIndex {
            rows,
            dim,
            perm: &perm[..n],
            splits: &splits[..n],
        })
    }

    /// Exact k-NN over every entry: the same results as [`brute_force`] over the same rows.
    /// Blocks that lie entirely at or after `exclude.before_id` are not visited.
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
        let n = self.perm.len();
        check_query(query, self.dim)?;
        check_out(out, k)?;
        exclude.check(n)?;
        let mut best = Best::new(&mut out[..k]);
        if k > 0 {
            let mut off = [0f64; MAX_OFFSET_DIM];
            let tracked = if self.dim <= MAX_OFFSET_DIM {
                self.dim
            } else {
                0
            };
            let mut walk = Walk {
                query,
                exclude,
                eps: prune_margin(self.dim),
                off: &mut off[..tracked],
            };
            for (a, b) in blocks(n) {
                if a >= exclude.before_id {
                    break;
                }
                let tree = KdTree {
                    rows: self.rows,
                    dim: self.dim,
                    perm: &self.perm[a..b],
                    splits: &self.splits[a..b],
                };
                tree.rec(0, b - a, 0.0, &mut walk, &mut best);
            }
        }
        Ok(best.finish())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_follow_binary_representation() {
        let mut v = [(0usize, 0usize); 4];
        let mut c = 0;
        for b in blocks(13) {
            v[c] = b;
            c += 1;
        }
        assert_eq!(&v[..c], &[(0, 8), (8, 12), (12, 13)]);
        assert_eq!(blocks(0).count(), 0);
    }

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
        let n = brute_force(&rows, 2, &[0.0, 0.0], 2, &Exclude::NONE, &mut out).unwrap();
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
}
