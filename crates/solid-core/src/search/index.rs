//! The index that holds every search over the same rows, and the automatic choice among them.

use core::sync::atomic::{AtomicU32, Ordering::Relaxed};

use super::kdtree::{Walk, MAX_OFFSET_DIM};
use super::{
    check_out, check_query, scan, scan_threads, sketch_rows, Best, Exclude, Neighbor, OnlineIndex,
    Rows, Sketch,
};
use crate::Error;

/// How [`Index::search`] finds the neighbours. Every plan returns the same results.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Plan {
    /// One linear pass computing every distance ([`brute_force`](super::brute_force)).
    Brute,
    /// The online kd-tree index ([`OnlineIndex`]).
    KdTree,
    /// The sketch ([`Sketch`]), without falling back to brute force.
    Sketch,
    /// The kd-tree under a work budget, then the sketch, then brute force, each from where the
    /// previous one stopped paying (see [`Index::search`]).
    #[default]
    Auto,
}

/// What a search should return.
#[derive(Debug, Clone, Copy)]
pub struct Request<'a> {
    /// Number of neighbours.
    pub k: usize,
    /// Which entries may be returned.
    pub exclude: Exclude<'a>,
    /// Only neighbours at most this far are returned (`f32::INFINITY`: no bound). A caller that
    /// accepts only matches within a threshold (a loop detector) passes it, so that every plan
    /// can skip rows beyond it from the start.
    pub max_distance: f32,
    /// How to search.
    pub plan: Plan,
    /// What [`Plan::Auto`] saw on earlier queries of the same rows (`None`: every query on its
    /// own).
    pub observed: Option<&'a Observed>,
}

impl Request<'_> {
    /// The `k` nearest of every entry, with [`Plan::Auto`].
    pub const fn nearest(k: usize) -> Request<'static> {
        Request {
            k,
            exclude: Exclude::NONE,
            max_distance: f32::INFINITY,
            plan: Plan::Auto,
            observed: None,
        }
    }
}

/// What [`Plan::Auto`] has seen on the earlier queries of one set of rows. When the kd-tree's
/// walk ran out of its normal budget on [`AUTO_MISSES`] queries in a row (queries from places
/// the rows do not hold, whose walk only delays the sketch), the walk shrinks to the few leaves
/// nearest the query ([`AUTO_PRIME_BASE`]), enough to hand the sketch a first k-th distance.
/// When the sketch gave up on as many queries in a row (rows too alike for its bytes: a
/// database of near-duplicates), the sketch is skipped and the kd-tree walks deeper instead (on
/// such rows it is the only thing that can beat brute force), brute force taking what the walk
/// did not finish; the deep walk goes on while its recent cost, counted in brute-force passes
/// ([`AUTO_TREE_ROW_COST`]; a walk that did not finish also costs the pass that follows it),
/// averages less than one pass, and brute force runs alone otherwise. The normal walk is tried
/// again on every [`AUTO_RETRY_EVERY`]th query (a walk that runs out costs a tenth of a pass or
/// less). A skipped sketch is tried again on the next query whose number is a multiple of
/// [`AUTO_RETRY_EVERY`], and each time it fails again the interval doubles, up to
/// [`AUTO_RETRY_MAX`] (queries 16, 32, 64, 128, 256, 384, …); a skipped deep walk three
/// quarters of the way between the sketch's tries (queries 12, 24, 48, 96, 224, 352, …). Such a
/// retry that fails costs one or two brute-force passes: on near-duplicates (queries of more
/// copies, 500 of them, k = 1 and 10, `auto` and brute force interleaved, two runs each),
/// retries every 16th query made `auto` 1.05–1.10× as slow as brute force at 10k entries and
/// 1.11–1.26× at 100k, doubling up to 128 1.01–1.03× and 1.05–1.07×. The price: on rows or
/// queries that change, a sketch or deep walk skipped for long comes back up to 128 queries
/// late, brute force running meanwhile. Keep one per database; threads may share
/// it (the counts are loaded and stored, not locked: two threads updating at once may lose a
/// count, which only delays a change of plan).
#[derive(Debug, Default)]
pub struct Observed {
    queries: AtomicU32,
    walk_misses: AtomicU32,
    /// The recent cost of the deep walk in [`DEEP_PASS`]ths of a brute-force pass (a moving
    /// average over about the last eight walks).
    deep_cost: AtomicU32,
    sketch_misses: AtomicU32,
}

/// One brute-force pass in [`Observed::deep_cost`]'s unit.
const DEEP_PASS: u32 = 1024;

/// How far [`Plan::Auto`] walks the kd-tree on one query.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Depth {
    /// Not at all: brute force alone.
    Skip,
    /// Over the few leaves nearest the query ([`AUTO_PRIME_BASE`]), the sketch following (the
    /// normal walk is being skipped).
    Short,
    /// Under the normal budget, the sketch following.
    Normal,
    /// Under the deep budget, brute force following (the sketch is being skipped).
    Deep,
}

impl Observed {
    /// Nothing observed yet.
    pub const fn new() -> Self {
        Observed {
            queries: AtomicU32::new(0),
            walk_misses: AtomicU32::new(0),
            deep_cost: AtomicU32::new(0),
            sketch_misses: AtomicU32::new(0),
        }
    }

    /// How to walk the kd-tree on the next query (and counts the query).
    fn plan(&self) -> Depth {
        let q = self.queries.load(Relaxed);
        self.queries.store(q.wrapping_add(1), Relaxed);
        let sketch = retry_every(self.sketch_misses.load(Relaxed));
        if q.is_multiple_of(sketch) {
            if self.walk_misses.load(Relaxed) < AUTO_MISSES || q.is_multiple_of(AUTO_RETRY_EVERY) {
                Depth::Normal
            } else {
                Depth::Short
            }
        } else if self.deep_cost.load(Relaxed) < DEEP_PASS || q % sketch == sketch / 4 * 3 {
            Depth::Deep
        } else {
            Depth::Skip
        }
    }

    fn record(count: &AtomicU32, finished: bool) {
        let v = if finished {
            0
        } else {
            count.load(Relaxed).saturating_add(1)
        };
        count.store(v, Relaxed);
    }

    /// Adds a deep walk that cost `passes` brute-force passes to the moving average (each walk
    /// weighs an eighth: walks on near-duplicates vary, 0.3 to 1.9 passes at 1M entries around
    /// a mean of 0.78, and with a quarter a few dear walks in a row turned the walk off for long
    /// stretches: `auto` took 0.98–1.02× brute force's time there for k = 1, with an eighth
    /// 0.86×).
    ///
    /// A walk cheaper than a pass while the average says the walk is dear (a retry, on rows or
    /// queries that changed) starts the average again from it: averaged in, a walk that had
    /// cost three passes came back after nine such retries.
    ///
    /// The first walk (the average still 0: no walk costs nothing) sets the average. From 0, an
    /// eighth at a time, it took about ten walks of 1.4 passes (100k near-duplicates, k = 1)
    /// before the walk was skipped. Measured over the first 144 queries of a fresh database of
    /// near-duplicates (`benches/search_peers.py`'s protocol, 8 runs each): 1M entries, k = 1,
    /// 0.76–0.81× brute force's time against 0.99–1.02× from 0; 100k 1.05–1.10× against
    /// 1.05–1.12×; 10k no change.
    fn record_deep(&self, passes: f64) {
        let sample = (passes * f64::from(DEEP_PASS)).min(f64::from(16 * DEEP_PASS)) as u32;
        let old = self.deep_cost.load(Relaxed);
        let new = if old == 0 || (sample < DEEP_PASS && old >= DEEP_PASS) {
            sample
        } else {
            old - old / 8 + sample / 8
        };
        self.deep_cost.store(new, Relaxed);
    }
}

impl Clone for Observed {
    /// A fresh record: what one set of rows showed says nothing about a copy that changes.
    fn clone(&self) -> Self {
        Observed::new()
    }
}

/// [`Observed`] skips a step after this many failures in a row...
pub const AUTO_MISSES: u32 = 4;
/// ...tries it again on the next query whose number is a multiple of this (a skipped sketch or
/// deep walk: after each retry that fails, twice as long)...
pub const AUTO_RETRY_EVERY: u32 = 16;
/// ...up to this many queries (with 256, a database whose queries turned from near-duplicates to
/// stored places took up to 256 queries of brute force to come back to the kd-tree).
pub const AUTO_RETRY_MAX: u32 = 128;

/// The interval of [`Observed`]'s retries of a step that failed `misses` times in a row: 1 (run
/// it on every query) below [`AUTO_MISSES`], then [`AUTO_RETRY_EVERY`], doubling with each
/// retry that failed, up to [`AUTO_RETRY_MAX`].
fn retry_every(misses: u32) -> u32 {
    if misses < AUTO_MISSES {
        return 1;
    }
    let doublings = (misses - AUTO_MISSES).min((AUTO_RETRY_MAX / AUTO_RETRY_EVERY).ilog2());
    AUTO_RETRY_EVERY << doublings
}

/// The work a search did, by kind (for benchmarks and for callers that tune their plan).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Cost {
    /// Distances computed by the kd-tree.
    pub tree_rows: usize,
    /// Rows bounded from their sketch bytes.
    pub sketch_rows: usize,
    /// Distances computed outside the kd-tree (rows the sketch could not rule out, and brute
    /// force).
    pub exact_rows: usize,
}

/// The answer of [`Index::search`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Found {
    /// Number of neighbours written to the output, nearest first.
    pub len: usize,
    /// The work it took.
    pub cost: Cost,
}

/// Below this many candidates [`Plan::Auto`] computes every distance.
const AUTO_BRUTE_BELOW: usize = 256;

/// The kd-tree's normal budget under [`Plan::Auto`]: it may compute the distances of
/// `candidates / AUTO_TREE_SHARE + AUTO_TREE_PER_K · k + AUTO_TREE_BASE` rows, and never more than
/// `candidates / AUTO_TREE_MAX_SHARE`. A distance in the tree costs about 100 rows of the sketch
/// and 5–15 of brute force (a jump to another row), so a fruitless walk adds at most about 40 %
/// to the sketch's pass (measured: 0.6 ms before a 1.3 ms sketch over a million rows), more at
/// 10k entries, where the cap lets it take as long as the sketch; [`Observed`] skips a walk that
/// keeps running out. Measured on realistic databases (`benches/benches/search.rs`,
/// `Cost::tree_rows` of `Plan::KdTree`): queries near stored places need a median of 390 / 480 /
/// 980 rows for k = 1 at 10k / 100k / 1M entries (largest of 48: 1,251 / 4,814 / 4,082), and 2.5
/// times that for k = 10.
const AUTO_TREE_SHARE: usize = 256;
const AUTO_TREE_PER_K: usize = 64;
const AUTO_TREE_BASE: usize = 512;
const AUTO_TREE_MAX_SHARE: usize = 16;

/// The short walk before the sketch while the normal walk is being skipped ([`Observed`]) computes
/// `AUTO_PRIME_BASE + AUTO_PRIME_PER_K · k` distances, the leaves nearest the query, whose k-th
/// distance lets the sketch rule rows out from its first block. Without it the sketch starts from
/// an empty heap and, on near-duplicates at 10k entries, gave up at its first check. Measured
/// (release probe, 48 queries of another city, k = 1): 1M entries 2.7 ms with the normal walk,
/// 2.2 ms with this one; 10k near-duplicates, queries of another place, 35 → 22 µs.
pub const AUTO_PRIME_BASE: usize = 64;
/// See [`AUTO_PRIME_BASE`].
pub const AUTO_PRIME_PER_K: usize = 4;

/// A distance the kd-tree computes costs about as much as this many rows of brute force on one
/// thread (a jump to another row, and the walk itself) over fewer than 32,768 rows, one more for
/// every doubling of the rows from there (the rows the walk jumps among outgrow the core's caches);
/// against brute force over `t` threads (the scans of 65,536 rows and more), `t` times as many:
/// [`auto_tree_row_cost`]. Measured on near-duplicate databases (release probe, 48 queries of
/// another copy of the scan, each walk and each scan run once after 32 MB of other memory was
/// written, as between a detector's queries: the walk's time ÷ its distances against brute
/// force's time ÷ its rows, median, k = 1 / 10): 8.1 / 6.9 at 10k entries (brute force on one
/// thread), 19.6 / 17.0 at 100k and 27.4 / 25.8 at 1M (on two), where the rule gives 8, 20 and
/// 26. (Run back to back on the same query, with warm caches, the walk looks cheaper: 6.4 / 5.8,
/// 16.3 / 15.1 and 14.2 / 12.7.)
///
/// When the sketch is being skipped ([`Observed`]), the deep walk may compute as many distances
/// as two brute-force passes cost, and goes on while its walks average less than one pass. On
/// near-duplicates a walk computes a mean of 15.5 % / 7.0 % / 3.0 % of the rows at 10k / 100k /
/// 1M entries for k = 1 and 23.5 % / 10.7 % / 4.8 % for k = 10: 1.24 / 1.41 / 0.78 and 1.88 /
/// 2.15 / 1.23 passes by this rule, against 1.36 / 1.31 / 0.79 and 1.90 / 1.94 / 1.23 measured
/// (the walk's total time ÷ brute force's, caches cold as above). With 6 for every size, the
/// deep walk went on at 1M entries for k = 10, and `auto` took 1.20× brute force's time there;
/// with this rule 1.03× (and 1.05–1.07× at 10k and 100k, where the walk and the sketch were
/// then tried again on every 16th query).
pub const AUTO_TREE_ROW_COST: usize = 8;

/// What one distance of a kd-tree walk over `candidates` rows costs in rows of brute force over
/// them, for `k` neighbours (see [`AUTO_TREE_ROW_COST`]).
pub fn auto_tree_row_cost(candidates: usize, k: usize) -> usize {
    let past_cache = candidates.max(1).ilog2().saturating_sub(14) as usize;
    (AUTO_TREE_ROW_COST + past_cache) * scan_threads(candidates, k)
}

/// Every search over one set of rows: brute force, the online kd-tree index and the sketch,
/// viewing caller-owned buffers (see [`OnlineIndex`] and [`Sketch`]). The kd-tree and the sketch
/// may each cover only the first rows (a store that adds many rows at once can build them
/// later): the rows beyond the kd-tree are searched through the sketch, those beyond the sketch
/// by brute force, so every plan stays exact.
#[derive(Debug, Clone, Copy)]
pub struct Index<'a> {
    tree: OnlineIndex<'a>,
    sketch: Sketch<'a>,
    rows: Rows<'a>,
}

impl<'a> Index<'a> {
    /// Views the online index of the first `perm.len()` rows (`perm`, `splits`, as
    /// [`online_insert`](super::online_insert) maintains them) and the sketch of the first rows
    /// that `params` holds, `min(rows, params.len() / 3)` (`codes`, `params`, as
    /// [`sketch_encode`](super::sketch_encode) fills them for those rows: a sketch cut back to
    /// whole blocks of [`SKETCH_BLOCK`](super::SKETCH_BLOCK) rows leaves the rows beyond to
    /// brute force).
    ///
    /// # Errors
    /// [`Error::LengthMismatch`] when `perm` and `splits` differ in length;
    /// [`Error::InvalidParameter`] (name `perm`) when they are longer than the rows; as
    /// [`Sketch::new`] otherwise (`codes` too short for the rows that `params` holds).
    pub fn new(
        rows: Rows<'a>,
        perm: &'a [u32],
        splits: &'a [u16],
        codes: &'a [u8],
        params: &'a [f32],
    ) -> Result<Index<'a>, Error> {
        if perm.len() != splits.len() {
            return Err(Error::LengthMismatch {
                what: "perm vs splits",
                left: perm.len(),
                right: splits.len(),
            });
        }
        if perm.len() > rows.len() {
            return Err(Error::InvalidParameter {
                name: "perm",
                value: perm.len() as f64,
                expected: "an online index of at most the rows",
            });
        }
        Ok(Index {
            tree: OnlineIndex::new(rows.prefix(perm.len()), perm, splits)?,
            sketch: Sketch::new(rows.prefix(sketch_rows(params.len())), codes, params)?,
            rows,
        })
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// `true` when the index holds no entry.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// Exact k-NN of the L2-normalised `query`: the `min(k, candidates)` nearest allowed entries
    /// within `max_distance`, written to `out` nearest first (ties by lower id): the same results
    /// as [`brute_force`](super::brute_force) (then cut at `max_distance`) with every plan.
    ///
    /// [`Plan::Auto`] computes every distance below 256 candidates or when `k` is above an
    /// eighth of them. Otherwise it walks the kd-tree until it has computed about
    /// `candidates / 256 + 64 k + 512` distances (at most a 16th of the candidates): queries near
    /// stored places end there. If the walk did not finish, the sketch scans every candidate,
    /// ruling out rows farther than the walk's k-th distance so far; and if an eighth of the rows
    /// scanned still need their exact distance (rows too alike for the bytes to tell apart),
    /// brute force takes the rest. Rows beyond the kd-tree go through the sketch (with the same
    /// fallback) after a finished walk; [`Plan::KdTree`] computes their distances. With
    /// [`Request::observed`], steps that keep failing are skipped ([`Observed`]): a walk that
    /// keeps running out of budget (queries from places the rows do not hold) shrinks to the
    /// few leaves nearest the query, which hand the sketch its first k-th distance.
    ///
    /// # Errors
    /// [`Error::LengthMismatch`] when `query.len()` differs from the rows' dimension or the
    /// timestamps of `exclude` are fewer than the rows; [`Error::BufferTooSmall`] when
    /// `out.len() < k`; [`Error::InvalidParameter`] (name `max_distance`) when it is NaN.
    pub fn search(
        &self,
        query: &[f32],
        req: &Request<'_>,
        out: &mut [Neighbor],
    ) -> Result<Found, Error> {
        check_query(query, self.rows.dim())?;
        check_out(out, req.k)?;
        req.exclude.check(self.len())?;
        if req.max_distance.is_nan() {
            return Err(Error::InvalidParameter {
                name: "max_distance",
                value: f64::NAN,
                expected: "a distance (or infinity for no bound)",
            });
        }
        let (exclude, bound) = (&req.exclude, req.max_distance);
        let mut best = Best::new(&mut out[..req.k]);
        let mut cost = Cost::default();
        let candidates = self.len().min(exclude.before_id);
        // Ids `tree_end..` are not in the kd-tree.
        let tree_end = self.tree.len();
        let rows = |from: usize, best: &mut Best<'_>, cost: &mut Cost| {
            cost.exact_rows += candidates.saturating_sub(from);
            scan(self.rows, from, candidates, query, exclude, bound, best);
        };
        if req.k > 0 && candidates > 0 {
            match req.plan {
                Plan::Brute => rows(0, &mut best, &mut cost),
                Plan::Sketch => {
                    let _ = self
                        .sketch
                        .scan(query, 0, exclude, bound, false, &mut best, &mut cost);
                    rows(self.sketch.len(), &mut best, &mut cost);
                }
                Plan::KdTree => {
                    self.walk(query, exclude, bound, usize::MAX, &mut best, &mut cost);
                    rows(tree_end, &mut best, &mut cost);
                }
                Plan::Auto => {
                    if candidates < AUTO_BRUTE_BELOW || req.k > candidates / 8 {
                        rows(0, &mut best, &mut cost);
                    } else {
                        self.auto(query, req, candidates, &mut best, &mut cost);
                    }
                }
            }
        }
        Ok(Found {
            len: best.finish(),
            cost,
        })
    }

    /// [`Plan::Auto`] over `candidates` rows (see [`Index::search`]).
    fn auto(
        &self,
        query: &[f32],
        req: &Request<'_>,
        candidates: usize,
        best: &mut Best<'_>,
        cost: &mut Cost,
    ) {
        let (exclude, mut bound) = (&req.exclude, req.max_distance);
        let walk = req.observed.map_or(Depth::Normal, Observed::plan);
        // What one kd-tree distance costs in rows of brute force over these candidates.
        let tree_row = auto_tree_row_cost(candidates, req.k);
        let budget = match walk {
            Depth::Skip => 0,
            Depth::Short => AUTO_PRIME_BASE + AUTO_PRIME_PER_K * req.k,
            Depth::Normal => {
                (candidates / AUTO_TREE_SHARE + AUTO_TREE_PER_K * req.k + AUTO_TREE_BASE)
                    .min(candidates / AUTO_TREE_MAX_SHARE)
            }
            Depth::Deep => 2 * candidates / tree_row,
        };
        let mut from = 0;
        if walk != Depth::Skip {
            let finished = self.walk(query, exclude, bound, budget, best, cost);
            match (req.observed, walk) {
                (Some(o), Depth::Normal) => Observed::record(&o.walk_misses, finished),
                (Some(o), Depth::Deep) => {
                    let walked = (cost.tree_rows * tree_row) as f64 / candidates as f64;
                    o.record_deep(walked + if finished { 0.0 } else { 1.0 });
                }
                _ => {}
            }
            if finished {
                // The tree's rows are done; the others follow.
                from = self.tree.len();
            } else {
                // Start again over every row, with the walk's k-th distance as the bound: no
                // true neighbour is farther.
                bound = best.limit(bound);
                best.clear();
            }
        }
        if from >= candidates {
            return;
        }
        if matches!(walk, Depth::Normal | Depth::Short) && from < self.sketch.len() {
            let done = self
                .sketch
                .scan(query, from, exclude, bound, true, best, cost);
            if let Some(o) = req.observed {
                Observed::record(&o.sketch_misses, done);
            }
            // The rows beyond the sketch (`scan` stops at its end).
            from = self.sketch.len();
        }
        if from < candidates {
            cost.exact_rows += candidates - from;
            scan(self.rows, from, candidates, query, exclude, bound, best);
        }
    }

    /// Walks the kd-tree within `budget` distances; `true` when it finished (exact results over
    /// the tree's rows).
    fn walk(
        &self,
        query: &[f32],
        exclude: &Exclude<'_>,
        bound: f32,
        budget: usize,
        best: &mut Best<'_>,
        cost: &mut Cost,
    ) -> bool {
        if self.tree.is_empty() {
            return true;
        }
        let mut off = [0f64; MAX_OFFSET_DIM];
        let mut walk = Walk::new(query, exclude, bound, budget, &mut off);
        self.tree.walk(&mut walk, best);
        cost.tree_rows += walk.rows;
        !walk.stopped()
    }
}
