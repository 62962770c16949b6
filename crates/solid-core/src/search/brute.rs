//! Brute force ([`brute_force`]): the k best of a linear pass, kept in a heap in the caller's
//! buffer, with the scan shared among the pool's threads for long passes (`parallel`).

#[cfg(all(feature = "std", target_arch = "x86_64"))]
use super::rows::avx2;
use super::rows::dist4;
#[cfg(feature = "parallel")]
use super::Cost;
use super::{exact_knn, Exclude, Neighbor, Rows};
use crate::Error;
use core::ops::Range;

/// The k best candidates so far: a binary max-heap (worst at the root) in the caller's buffer.
pub(super) struct Best<'s> {
    pub(super) heap: &'s mut [Neighbor],
    pub(super) len: usize,
}

impl<'s> Best<'s> {
    pub(super) fn new(heap: &'s mut [Neighbor]) -> Self {
        Best { heap, len: 0 }
    }

    #[inline]
    pub(super) fn full(&self) -> bool {
        self.len == self.heap.len()
    }

    /// The distance a candidate must beat to enter, when the heap is full.
    #[inline]
    pub(super) fn worst(&self) -> Option<f32> {
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
    pub(super) fn limit(&self, bound: f32) -> f32 {
        match self.worst() {
            Some(w) if w < bound => w,
            _ => bound,
        }
    }

    /// Empties the heap (keeping its buffer).
    pub(super) fn clear(&mut self) {
        self.len = 0;
    }

    #[inline]
    pub(super) fn offer(&mut self, cand: Neighbor) {
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
    pub(super) fn finish(self) -> usize {
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
pub(super) fn sift_down(h: &mut [Neighbor], mut i: usize, len: usize) {
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
/// `query` must be L2-normalised (see [`normalize`](super::normalize)). The `min(k, candidates)` nearest rows
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
    exact_knn(query, rows.dim, rows.n, k, exclude, out, |best| {
        let p = Probe {
            query,
            exclude,
            bound: f32::INFINITY,
        };
        scan(rows, 0..rows.n, p, best);
    })
}

/// What a scan looks for: the rows nearest `query` among those `exclude` allows, at a distance
/// of at most `bound`.
#[derive(Clone, Copy)]
pub(super) struct Probe<'a> {
    pub(super) query: &'a [f32],
    pub(super) exclude: &'a Exclude<'a>,
    pub(super) bound: f32,
}

/// Offers the rows of `ids` that `p` finds to `best`, computing every distance (with AVX2 when
/// `std` detects it: the same operations, so the same bits).
#[inline]
pub(super) fn scan(rows: Rows<'_>, ids: Range<usize>, p: Probe<'_>, best: &mut Best<'_>) {
    #[cfg(feature = "parallel")]
    {
        let hi = ids.end.min(p.exclude.before_id).min(rows.n);
        // The parts after the first start from empty heaps: the neighbours `best` holds already
        // (a finished kd-tree walk before the rows past the tree) bound them all the same.
        let p = Probe {
            bound: best.limit(p.bound),
            ..p
        };
        let part = |lo: usize, hi: usize, best: &mut Best<'_>, _: &mut Cost| {
            scan_part(rows, lo..hi, p, best);
            true
        };
        if split_scan(ids.start, hi, 4, best, &mut Cost::default(), part).is_some() {
            return;
        }
    }
    scan_part(rows, ids, p, best)
}

/// Scans of at least this many rows are shared among the threads (`parallel`): a search over a
/// million rows is bound by memory, which two cores read faster than one.
#[cfg(feature = "parallel")]
pub(super) const PARALLEL_SCAN: usize = 1 << 16;

/// A shared scan is cut in parts of this many rows (cut on multiples of the caller's alignment),
/// which the threads take one after another until none is left: on a machine whose other cores
/// are busy with other work, the threads that are free take more parts instead of all waiting
/// for the slowest one, and the searching thread starts at once instead of waiting for a woken
/// one.
#[cfg(feature = "parallel")]
pub(super) const PARALLEL_PART: usize = 1 << 13;

/// Most threads that join the searching one in a shared scan (each keeps its neighbours on the
/// searching thread's stack).
#[cfg(feature = "parallel")]
pub(super) const PARALLEL_HELPERS: usize = 15;

/// Largest `k` for which a scan is shared (each part's neighbours live on the stack).
#[cfg(feature = "parallel")]
pub(super) const PARALLEL_SCAN_MAX_K: usize = 64;

/// The threads whose helpers a scan of `rows` rows for `k` neighbours shares its parts with, and
/// how many threads it then runs on ([`split_scan`]'s rule); `None`: this thread alone.
#[cfg(feature = "parallel")]
pub(super) fn scan_helpers(rows: usize, k: usize) -> Option<(crate::pool::Threads, usize)> {
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
/// idle machine: a `rayon::join` from outside the pool put this thread to sleep until the woken
/// workers had done everything, and woke it again: docs/performance.md#brute-force). When no part
/// is left it waits, spinning, for the parts the others are still scanning (each a few tens of
/// microseconds), not for a wake-up.
#[cfg(feature = "parallel")]
pub(super) fn split_scan<F>(
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

/// [`scan`] on this thread.
#[inline]
pub(super) fn scan_part(rows: Rows<'_>, ids: Range<usize>, p: Probe<'_>, best: &mut Best<'_>) {
    avx2_or!(
        scan_avx2(rows, ids, p, best),
        scan_impl(rows, ids, p, best, dist4)
    )
}

#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx2")]
pub(super) fn scan_avx2(rows: Rows<'_>, ids: Range<usize>, p: Probe<'_>, best: &mut Best<'_>) {
    if rows.dim == COMMON_DIM {
        // The same function with the dimension a constant: its loop unrolled.
        return scan_impl(rows, ids, p, best, |q, g, _, s| {
            avx2::prefetch_ahead(g);
            avx2::dist4(q, g, COMMON_DIM, s)
        });
    }
    scan_impl(rows, ids, p, best, |q, g, d, s| {
        avx2::prefetch_ahead(g);
        avx2::dist4(q, g, d, s)
    })
}

/// The R-SOLiD length of every preset (`n_range` = 40), for which the AVX2 scan has a copy of its
/// own.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
pub(super) const COMMON_DIM: usize = 40;

/// The body of [`scan`], inlined into each of its compiled copies: four rows at a time (their
/// distances from `dist4`), and a row is offered only when its distance is within the current
/// limit.
#[inline(always)]
pub(super) fn scan_impl(
    rows: Rows<'_>,
    ids: Range<usize>,
    p: Probe<'_>,
    best: &mut Best<'_>,
    dist4: impl Fn(&[f32], &[f32], usize, [f32; 4]) -> [f32; 4],
) {
    if best.heap.is_empty() {
        return;
    }
    let Probe {
        query,
        exclude,
        bound,
    } = p;
    let lo = ids.start;
    let hi = ids.end.min(exclude.before_id).min(rows.n);
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
