//! The kd-tree and the online index made of kd-trees (see the parent module).

use super::{exact_knn, Best, Exclude, Neighbor, Rows};
use crate::Error;

/// Largest number of entries a kd-tree node scans linearly instead of splitting.
pub const LEAF_SIZE: usize = 12;

/// Points sampled per node to choose the split dimension (the widest spread among them).
const SPLIT_SAMPLE: usize = 32;

/// Margin by which the kd-tree's lower bound must exceed the current worst distance before a
/// subtree is skipped: covers the `f32` rounding of normalisation and of the dot product, so that
/// pruning never drops a neighbour that [`brute_force`](super::brute_force) would return.
#[inline]
fn prune_margin(dim: usize) -> f64 {
    (dim as f64 + 64.0) * 1.2e-7
}

/// A kd-tree over [`Rows`], built in place in caller-owned buffers.
///
/// The tree is implicit: a node is a range of the permutation; its split entry sits at the middle
/// of the range, the entries before it have a split coordinate `<=` the split value and those after
/// it `>=`. The split dimension of the node whose middle is position `m` is `splits[m]`. Ranges of
/// at most [`LEAF_SIZE`] entries are scanned linearly.
///
/// Queries are exact: a subtree is skipped only when `(q_d − s)² / 2`, a lower bound of the
/// distance of everything in it, exceeds the current k-th distance by more than the rounding
/// margin; with equal distances the lower id wins, exactly as in
/// [`brute_force`](super::brute_force).
#[derive(Debug, Clone, Copy)]
pub struct KdTree<'a> {
    rows: Rows<'a>,
    perm: &'a [u32],
    splits: &'a [u16],
}

impl<'a> KdTree<'a> {
    /// Builds a tree over every row of `rows` (ids `0..n`): fills `perm[..n]` with the ids and
    /// arranges them, writing split dimensions into `splits[..n]`. Allocates nothing.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`] when `perm` or `splits` is shorter than the number of rows.
    pub fn build(
        rows: Rows<'a>,
        perm: &'a mut [u32],
        splits: &'a mut [u16],
    ) -> Result<KdTree<'a>, Error> {
        let n = rows.len();
        check_buffers(n, perm.len(), splits.len())?;
        let (perm, splits) = (&mut perm[..n], &mut splits[..n]);
        for (i, p) in perm.iter_mut().enumerate() {
            *p = i as u32;
        }
        build_rec(rows, perm, splits, &mut []);
        Ok(KdTree { rows, perm, splits })
    }

    /// Views buffers that [`KdTree::build`] (or [`online_insert`], for one block) has arranged,
    /// without rebuilding. `perm` and `splits` must be the exact ranges that were built.
    ///
    /// # Errors
    /// [`Error::LengthMismatch`] when `perm` and `splits` differ in length;
    /// [`Error::InvalidParameter`] (name `perm`) when an id in `perm` is not a row of `rows`.
    pub fn from_built(
        rows: Rows<'a>,
        perm: &'a [u32],
        splits: &'a [u16],
    ) -> Result<KdTree<'a>, Error> {
        let n = rows.len();
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
        Ok(KdTree { rows, perm, splits })
    }

    /// Number of entries in the tree.
    pub fn len(&self) -> usize {
        self.perm.len()
    }

    /// `true` when the tree holds no entry.
    pub fn is_empty(&self) -> bool {
        self.perm.is_empty()
    }

    /// Exact k-NN: the same contract and the same results as [`brute_force`](super::brute_force) over the tree's
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
        let n = self.rows.len();
        walk_search(self.rows, n, query, k, exclude, out, |walk, best| {
            self.rec(0, self.perm.len(), 0.0, walk, best);
        })
    }

    #[inline]
    fn consider(&self, id: u32, walk: &mut Walk<'_>, best: &mut Best<'_>) {
        let i = id as usize;
        if !walk.exclude.allows(i) {
            return;
        }
        walk.rows += 1;
        let d = self.rows.dist(walk.query, i);
        if d <= walk.bound {
            best.offer(Neighbor { id, distance: d });
        }
    }

    /// Visits the node `perm[lo..hi]`, whose cell is at squared Euclidean distance at least
    /// `rd` from the query (Arya & Mount's incremental bound: `rd = Σ_d off[d]²`). Returns
    /// early, leaving `walk.rows > walk.budget`, once the walk has computed more distances than
    /// its budget.
    pub(super) fn rec(
        &self,
        lo: usize,
        hi: usize,
        rd: f64,
        walk: &mut Walk<'_>,
        best: &mut Best<'_>,
    ) {
        if walk.rows > walk.budget {
            return;
        }
        let n = hi - lo;
        if n <= LEAF_SIZE {
            // The leaf's rows are asked for at once, and so are the two children's split rows
            // below: their cache misses overlap (docs/performance.md#kd-tree).
            for &id in &self.perm[lo..hi] {
                self.rows.prefetch(id as usize);
            }
            for &id in &self.perm[lo..hi] {
                self.consider(id, walk, best);
            }
            return;
        }
        let mid = lo + n / 2;
        for (a, b) in [(lo, mid), (mid + 1, hi)] {
            if b - a > LEAF_SIZE {
                self.rows.prefetch(self.perm[a + (b - a) / 2] as usize);
            }
        }
        let pid = self.perm[mid];
        let d = self.splits[mid] as usize;
        let s = self.rows.coord(pid as usize, d);
        self.consider(pid, walk, best);
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
            // Distances are at most 1; while the limit is 1 a tie at 1 with a lower id may still
            // be ahead, so never skip then.
            let limit = best.limit(walk.bound);
            let skip = limit < 1.0 && 0.5 * far_rd > limit as f64 + walk.eps;
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
pub(super) const MAX_OFFSET_DIM: usize = 1024;

/// The per-query state of a kd-tree walk.
pub(super) struct Walk<'q> {
    query: &'q [f32],
    exclude: &'q Exclude<'q>,
    eps: f64,
    /// Offsets of the current cell from the query along each dimension (empty: not tracked).
    off: &'q mut [f64],
    /// Only rows at most this far are offered.
    bound: f32,
    /// Distances computed so far.
    pub(super) rows: usize,
    /// The walk stops once `rows` exceeds this.
    pub(super) budget: usize,
}

impl<'q> Walk<'q> {
    /// A walk from the root; `off` is the stack space for the cell offsets.
    pub(super) fn new(
        query: &'q [f32],
        exclude: &'q Exclude<'q>,
        bound: f32,
        budget: usize,
        off: &'q mut [f64; MAX_OFFSET_DIM],
    ) -> Self {
        let tracked = if query.len() <= MAX_OFFSET_DIM {
            query.len()
        } else {
            0
        };
        Walk {
            query,
            exclude,
            eps: prune_margin(query.len()),
            off: &mut off[..tracked],
            bound,
            rows: 0,
            budget,
        }
    }

    /// `true` when the walk stopped on its budget (its results are then incomplete).
    pub(super) fn stopped(&self) -> bool {
        self.rows > self.budget
    }
}

/// An exact k-NN over `n` entries of `rows` by a walk without a budget: `visit` walks them.
fn walk_search(
    rows: Rows<'_>,
    n: usize,
    query: &[f32],
    k: usize,
    exclude: &Exclude<'_>,
    out: &mut [Neighbor],
    visit: impl FnOnce(&mut Walk<'_>, &mut Best<'_>),
) -> Result<usize, Error> {
    exact_knn(query, rows.dim(), n, k, exclude, out, |best| {
        if k > 0 {
            let mut off = [0f64; MAX_OFFSET_DIM];
            let mut walk = Walk::new(query, exclude, f32::INFINITY, usize::MAX, &mut off);
            visit(&mut walk, best);
        }
    })
}

fn check_buffers(n: usize, perm: usize, splits: usize) -> Result<(), Error> {
    Error::check_buffer("perm", n, perm)?;
    Error::check_buffer("splits", n, splits)
}

/// Chooses the dimension with the widest spread among up to [`SPLIT_SAMPLE`] evenly spaced
/// entries of `perm` (ties: the lowest dimension). Compiled for AVX2 as well, which `std` picks
/// when the CPU has it, and for the default dimension as a constant (the same operations, so
/// the same choice): faster builds, the same trees (docs/performance.md#kd-tree).
fn widest_dim(rows: Rows<'_>, perm: &[u32]) -> usize {
    avx2_or!(widest_dim_avx2(rows, perm), widest_dim_dims(rows, perm))
}

avx2_copy!(widest_dim_avx2 = widest_dim_dims(rows: Rows<'_>, perm: &[u32]) -> usize);

/// [`widest_dim_impl`] for the rows' dimension, the default one as a constant.
#[inline(always)]
fn widest_dim_dims(rows: Rows<'_>, perm: &[u32]) -> usize {
    use crate::config::DEFAULT_N_RANGE;
    if rows.dim() == DEFAULT_N_RANGE {
        widest_dim_impl(rows, perm, DEFAULT_N_RANGE)
    } else {
        widest_dim_impl(rows, perm, rows.dim())
    }
}

#[inline(always)]
fn widest_dim_impl(rows: Rows<'_>, perm: &[u32], dim: usize) -> usize {
    let n = perm.len();
    let step = (n / SPLIT_SAMPLE).max(1);
    let mut best_d = 0;
    let mut best_spread = -1.0f32;
    // Row by row (each sampled row read once per block of dimensions, not once per dimension:
    // 1M rows built 2× faster), the ranges of a block of dimensions in arrays on the stack.
    const BLOCK: usize = 64;
    for d0 in (0..dim).step_by(BLOCK) {
        let width = (dim - d0).min(BLOCK);
        let (mut lo, mut hi) = ([f32::INFINITY; BLOCK], [f32::NEG_INFINITY; BLOCK]);
        let mut i = 0;
        while i < n {
            let (raw, scale) = rows.raw_row(perm[i] as usize);
            // `raw × scale` is `Rows::coord` (the scale is 1 for normalised rows).
            let values = raw[d0..d0 + width].iter().map(|&v| v * scale);
            for ((lo, hi), v) in lo.iter_mut().zip(hi.iter_mut()).zip(values) {
                *lo = lo.min(v);
                *hi = hi.max(v);
            }
            i += step;
        }
        for (j, (lo, hi)) in lo.iter().zip(&hi).take(width).enumerate() {
            let spread = hi - lo;
            if spread > best_spread {
                best_spread = spread;
                best_d = d0 + j;
            }
        }
    }
    best_d
}

fn build_rec(rows: Rows<'_>, perm: &mut [u32], splits: &mut [u16], keys: &mut [u64]) {
    let n = perm.len();
    if n <= LEAF_SIZE {
        return;
    }
    let d = widest_dim(rows, perm);
    let mid = n / 2;
    if keys.len() >= n && n >= KEYED_FROM {
        select_keyed(rows, d, mid, perm, &mut keys[..n]);
    } else {
        perm.select_nth_unstable_by(mid, |&a, &b| {
            rows.coord(a as usize, d)
                .total_cmp(&rows.coord(b as usize, d))
        });
    }
    splits[mid] = d as u16;
    let (lp, rp) = perm.split_at_mut(mid);
    let (ls, rs) = splits.split_at_mut(mid);
    let (lk, rk) = if keys.len() >= n {
        let (l, r) = keys[..n].split_at_mut(mid);
        (l, &mut r[1..])
    } else {
        (&mut [][..], &mut [][..])
    };
    #[cfg(feature = "parallel")]
    if let Some(threads) = (n >= PARALLEL_BUILD).then(crate::pool::work).flatten() {
        threads.join(
            || build_rec(rows, lp, ls, lk),
            || build_rec(rows, &mut rp[1..], &mut rs[1..], rk),
        );
        return;
    }
    build_rec(rows, lp, ls, lk);
    build_rec(rows, &mut rp[1..], &mut rs[1..], rk);
}

/// Nodes from this size on are split through [`select_keyed`] when there is scratch for it.
/// 64 builds fastest of the sizes tried (docs/performance.md#kd-tree).
const KEYED_FROM: usize = 64;

/// Puts the entry with the `mid`-th smallest value of dimension `d` at `perm[mid]`, those not
/// greater before it and those not smaller after it, as `select_nth_unstable_by` on the values
/// does, but on keys gathered once into `keys` (the value's bits in total order, then the id):
/// comparisons then read a contiguous array instead of two rows each (1M rows: the selections
/// took a quarter of the build).
fn select_keyed(rows: Rows<'_>, d: usize, mid: usize, perm: &mut [u32], keys: &mut [u64]) {
    for (k, &id) in keys.iter_mut().zip(perm.iter()) {
        *k = (u64::from(total_order_bits(rows.coord(id as usize, d))) << 32) | u64::from(id);
    }
    keys.select_nth_unstable(mid);
    for (id, &k) in perm.iter_mut().zip(keys.iter()) {
        *id = k as u32;
    }
}

/// The bits of `x` as an unsigned integer whose order is `f32::total_cmp`'s.
#[inline]
fn total_order_bits(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 {
        !b
    } else {
        b | (1 << 31)
    }
}

/// Nodes of at least this many entries build their two halves on two threads (`parallel`).
#[cfg(feature = "parallel")]
const PARALLEL_BUILD: usize = 8192;

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

/// The blocks over `n` entries that the blocks over `from` entries did not have: what growing
/// from `from` to `n` rebuilds.
fn rebuilt(n: usize, from: usize) -> impl Iterator<Item = (usize, usize)> {
    blocks(n).filter(move |b| !blocks(from).any(|old| old == *b))
}

/// Adds the newest row to an online index: [`online_extend`] from `rows.len() − 1`.
///
/// The index over the rows (ids `0..n`, `n` counting the row just appended) lives in
/// `perm[..n]` and `splits[..n]`; call this once after each row is appended, in order. It
/// rebuilds the one block that the new entry completes (sizes are powers of two, so an entry is
/// rebuilt `O(log n)` times in its life). Allocates nothing.
///
/// # Errors
/// [`Error::InvalidParameter`] when `rows` is empty; [`Error::BufferTooSmall`] when `perm` or
/// `splits` is shorter than the number of rows.
pub fn online_insert(rows: Rows<'_>, perm: &mut [u32], splits: &mut [u16]) -> Result<(), Error> {
    if rows.is_empty() {
        return Err(Error::InvalidParameter {
            name: "rows",
            value: 0.0,
            expected: "at least the entry being inserted",
        });
    }
    online_extend(rows, rows.len() - 1, perm, splits)
}

/// Brings an online index over the first `from` rows up to all rows: rebuilds the blocks of the
/// new size that the old size did not have (every block for `from = 0`, for example after
/// loading a database; the one completed block for one new row). Allocates nothing; see
/// [`online_extend_with`] for the faster build of large blocks with a scratch buffer.
///
/// # Errors
/// [`Error::InvalidParameter`] when `from` is beyond the rows; [`Error::BufferTooSmall`] when
/// `perm` or `splits` is shorter than the number of rows.
pub fn online_extend(
    rows: Rows<'_>,
    from: usize,
    perm: &mut [u32],
    splits: &mut [u16],
) -> Result<(), Error> {
    online_extend_with(rows, from, perm, splits, &mut [])
}

/// [`online_extend`] with `keys`, scratch of [`online_extend_scratch_len`] values (any content;
/// shorter scratch is used for the blocks it covers), into which each large node gathers its
/// split values so that choosing the median reads one array instead of rows at random: building
/// 1M rows took about a third less time. The index is the same but for the order of entries
/// with equal values. Allocates nothing.
///
/// # Errors
/// As [`online_extend`].
pub fn online_extend_with(
    rows: Rows<'_>,
    from: usize,
    perm: &mut [u32],
    splits: &mut [u16],
    keys: &mut [u64],
) -> Result<(), Error> {
    let n = rows.len();
    if from > n {
        return Err(Error::InvalidParameter {
            name: "from",
            value: from as f64,
            expected: "at most the number of rows",
        });
    }
    check_buffers(n, perm.len(), splits.len())?;
    for (a, b) in rebuilt(n, from) {
        let p = &mut perm[a..b];
        for (i, v) in p.iter_mut().enumerate() {
            *v = (a + i) as u32;
        }
        let keys = if keys.len() >= b - a {
            &mut keys[..b - a]
        } else {
            &mut []
        };
        build_rec(rows, p, &mut splits[a..b], keys);
    }
    Ok(())
}

/// The scratch [`online_extend_with`] uses from `from` rows to `n`: the largest block it
/// rebuilds, or 0 when every block is too small to gain from it.
pub fn online_extend_scratch_len(n: usize, from: usize) -> usize {
    rebuilt(n, from.min(n))
        .map(|(a, b)| b - a)
        .filter(|&len| len >= KEYED_FROM)
        .max()
        .unwrap_or(0)
}

/// The rows [`online_extend`] builds from `from` rows to `n`: those of the blocks it rebuilds (for
/// `from = 0`, all `n`; for one new row, the block it completes).
pub fn online_extend_rows(n: usize, from: usize) -> usize {
    rebuilt(n, from.min(n)).map(|(a, b)| b - a).sum()
}

/// Builds every block of the online index over all rows from scratch: [`online_extend`] from 0.
///
/// # Errors
/// [`Error::BufferTooSmall`] when `perm` or `splits` is shorter than the number of rows.
pub fn online_rebuild(rows: Rows<'_>, perm: &mut [u32], splits: &mut [u16]) -> Result<(), Error> {
    online_extend(rows, 0, perm, splits)
}

/// A view of an online index (see [`online_insert`]) for searching.
#[derive(Debug, Clone, Copy)]
pub struct OnlineIndex<'a> {
    rows: Rows<'a>,
    perm: &'a [u32],
    splits: &'a [u16],
}

impl<'a> OnlineIndex<'a> {
    /// Views the index that [`online_insert`] or [`online_rebuild`] maintains in `perm[..n]` and
    /// `splits[..n]` over the `n` rows of `rows`.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`] when `perm` or `splits` is shorter than the number of rows.
    pub fn new(
        rows: Rows<'a>,
        perm: &'a [u32],
        splits: &'a [u16],
    ) -> Result<OnlineIndex<'a>, Error> {
        let n = rows.len();
        check_buffers(n, perm.len(), splits.len())?;
        Ok(OnlineIndex {
            rows,
            perm: &perm[..n],
            splits: &splits[..n],
        })
    }

    /// Exact k-NN over every entry: the same results as [`brute_force`](super::brute_force) over
    /// the same rows.
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
        walk_search(self.rows, n, query, k, exclude, out, |walk, best| {
            self.walk(walk, best);
        })
    }

    /// Walks every block below `exclude.before_id` (largest first) until the walk's budget runs
    /// out.
    pub(super) fn walk(&self, walk: &mut Walk<'_>, best: &mut Best<'_>) {
        for (a, b) in blocks(self.perm.len()) {
            if a >= walk.exclude.before_id || walk.stopped() {
                break;
            }
            let tree = KdTree {
                rows: self.rows,
                perm: &self.perm[a..b],
                splits: &self.splits[a..b],
            };
            tree.rec(0, b - a, 0.0, walk, best);
        }
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.perm.len()
    }

    /// `true` when the index holds no entry.
    pub fn is_empty(&self) -> bool {
        self.perm.is_empty()
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
}
