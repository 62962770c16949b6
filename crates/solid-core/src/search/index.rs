//! The index that holds every search over the same rows, and the automatic choice among them.

use core::sync::atomic::{AtomicU32, Ordering::Relaxed};

use super::kdtree::{Walk, MAX_OFFSET_DIM};
use super::{
    check_search, scan, scan_threads, sketch_rows, Best, Exclude, Neighbor, OnlineIndex, Probe,
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

/// What [`Plan::Auto`] has seen on the earlier queries of one set of rows. When the kd-tree's walk
/// ran out of its normal budget on [`AUTO_MISSES`] queries in a row (queries from places the rows
/// do not hold, whose walk only delays the sketch), the walk shrinks to the few leaves nearest the
/// query ([`AUTO_PRIME_BASE`]), enough to hand the sketch a first k-th distance. When the sketch
/// gave up on as many queries in a row (rows too alike for its bytes: a database of
/// near-duplicates), the sketch is skipped and the kd-tree walks deeper instead (on such rows it is
/// the only thing that can beat brute force), brute force taking what the walk did not finish; the
/// deep walk goes on while its recent cost, counted in brute-force passes (timed against brute
/// force's passes with [`Observed::timed`] once a pass of at least 4,096 rows was timed, by
/// [`AUTO_TREE_ROW_COST`]'s rule otherwise; a walk that did not finish also costs the pass that
/// follows it), averages less than one pass, and brute force runs alone otherwise. The normal walk
/// is tried again on every [`AUTO_RETRY_EVERY`]th query (a walk that runs out costs a tenth of a
/// pass or less). A skipped sketch is tried again on the next query whose number is a multiple of
/// [`AUTO_RETRY_EVERY`], and each time it fails again the interval doubles, up to
/// [`AUTO_RETRY_MAX`] (queries 16, 32, 64, 128, 256, 384, …); a skipped deep walk three quarters of
/// the way between the sketch's tries (queries 12, 24, 48, 96, 224, 352, …), with a budget of one
/// pass instead of two (a dearer walk is no use; one that runs out costs two passes, not three; the
/// budget is counted in distances, by the rule). A retried deep walk under half a pass (rows or
/// queries that changed) starts the average again from it. The price: on rows or queries that
/// change, a sketch or deep walk skipped for long comes back up to 128 queries late, brute force
/// running meanwhile. Why these intervals: docs/performance.md#auto-plan.
///
/// Keep one per database; threads may share it (the counts are loaded and stored, not locked:
/// two threads updating at once may lose a count, which only delays a change of plan).
/// `Default` is [`Observed::new`], untimed.
#[derive(Debug, Default)]
pub struct Observed {
    queries: AtomicU32,
    walk_misses: AtomicU32,
    /// The recent cost of the deep walk in [`DEEP_PASS`]ths of a brute-force pass (a moving
    /// average over about the last eight walks).
    deep_cost: AtomicU32,
    sketch_misses: AtomicU32,
    /// Whether the walks and the scans are timed ([`Observed::timed`]).
    timed: bool,
    /// The recent time of one row of brute force in nanoseconds (`f32` bits, see
    /// [`Observed::note_scan`]; 0: none yet).
    row_ns: AtomicU32,
    /// The brute-force passes timed so far.
    scans: AtomicU32,
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
    /// Nothing observed yet; the cost of a walk is counted by [`auto_tree_row_cost`]'s rule, so
    /// that the same queries always take the same steps.
    pub const fn new() -> Self {
        Observed {
            queries: AtomicU32::new(0),
            walk_misses: AtomicU32::new(0),
            deep_cost: AtomicU32::new(0),
            sketch_misses: AtomicU32::new(0),
            timed: false,
            row_ns: AtomicU32::new(0),
            scans: AtomicU32::new(0),
        }
    }

    /// Nothing observed yet; with a clock (the `std` feature) the walks and the brute-force scans
    /// of [`Plan::Auto`] are timed, and a walk's cost is its time against a pass of brute force's
    /// (the time per row: the fastest of the first 4 passes timed, then a moving average). What a
    /// walk costs against brute force depends on the machine more than the rule allows, and on the
    /// walk (docs/performance.md#auto-plan). Without a clock, as [`Observed::new`].
    pub const fn timed() -> Self {
        let mut o = Observed::new();
        o.timed = cfg!(feature = "std");
        o
    }

    /// What a walk over `candidates` rows that computed `distances` in `ns` nanoseconds (when
    /// timed) cost in passes of brute force over them: its time against the scans' when both
    /// were timed, by the rule (`tree_row`, [`auto_tree_row_cost`]) otherwise.
    fn passes(&self, ns: Option<f64>, distances: usize, tree_row: usize, candidates: usize) -> f64 {
        let row = f64::from(load_ns(&self.row_ns));
        match ns {
            Some(ns) if row > 0.0 => ns / (row * candidates as f64),
            _ => (distances * tree_row) as f64 / candidates as f64,
        }
    }

    /// Adds a brute-force pass over `rows` rows that took `ns` nanoseconds to the time per row:
    /// the fastest of the first [`TIMED_FIRST`] passes, then a moving average (weight an eighth;
    /// a pass counts as at most four times the average). A thread descheduled during a scan
    /// only makes it look slower, and a time per row set too high makes walks look cheap (see
    /// docs/performance.md#auto-plan). One time per row serves every query: a database growing past
    /// 65,536 rows, or queries of k above 64, mix passes on one thread and on several until the
    /// average catches up.
    fn note_scan(&self, ns: f64, rows: usize) {
        if rows == 0 {
            return;
        }
        let sample = (ns / rows as f64) as f32;
        let old = load_ns(&self.row_ns);
        let first = self.scans.load(Relaxed);
        self.scans.store(first.saturating_add(1), Relaxed);
        let new = if old == 0.0 || (first < TIMED_FIRST && sample < old) {
            sample
        } else if first < TIMED_FIRST {
            old
        } else {
            old + (sample.min(4.0 * old) - old) / 8.0
        };
        if new.is_finite() && new > 0.0 {
            self.row_ns.store(new.to_bits(), Relaxed);
        }
    }

    /// Whether the deep walk is being skipped (its average is a pass or more): a deep walk now is
    /// a retry.
    fn deep_skipped(&self) -> bool {
        self.deep_cost.load(Relaxed) >= DEEP_PASS
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
        } else if !self.deep_skipped() || q % sketch == sketch / 4 * 3 {
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
    /// weighs an eighth: walks vary, and a larger weight let a few dear walks in a row turn the walk
    /// off for long stretches). A walk under half a pass while the average says the walk is dear (a
    /// retry, on rows or queries that changed) starts the average again from it. The first walk (the
    /// average still 0: no walk costs nothing) sets the average. Measurements behind each of these:
    /// docs/performance.md#auto-plan.
    fn record_deep(&self, passes: f64) {
        let sample = ((passes * f64::from(DEEP_PASS)).min(f64::from(16 * DEEP_PASS)) as u32).max(1);
        let old = self.deep_cost.load(Relaxed);
        let new = if old == 0 || (sample < DEEP_PASS / 2 && old >= DEEP_PASS) {
            sample
        } else {
            old - old / 8 + sample / 8
        };
        self.deep_cost.store(new, Relaxed);
    }
}

impl Clone for Observed {
    /// A fresh record, timed or not as this one: what one set of rows showed says nothing about
    /// a copy that changes.
    fn clone(&self) -> Self {
        if self.timed {
            Observed::timed()
        } else {
            Observed::new()
        }
    }
}

fn load_ns(cell: &AtomicU32) -> f32 {
    f32::from_bits(cell.load(Relaxed))
}

/// Brute-force scans of at least this many rows are timed by [`Observed::timed`] (shorter ones
/// take too little time to tell).
const TIMED_SCAN: usize = 4096;
/// The time per row of brute force is the fastest of this many first passes, then an average.
const TIMED_FIRST: u32 = 4;

/// A clock where the crate has one (`std`): `start(true)` is the time now, `ns` the
/// nanoseconds since.
#[cfg(feature = "std")]
mod clock {
    pub(super) type Start = Option<std::time::Instant>;
    pub(super) fn start(on: bool) -> Start {
        on.then(std::time::Instant::now)
    }
    pub(super) fn ns(start: Start) -> Option<f64> {
        start.map(|s| s.elapsed().as_nanos() as f64)
    }
}

/// No clock without `std`: nothing is timed.
#[cfg(not(feature = "std"))]
mod clock {
    pub(super) type Start = Option<()>;
    pub(super) fn start(_: bool) -> Start {
        None
    }
    pub(super) fn ns(_: Start) -> Option<f64> {
        None
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

/// Whether [`Plan::Auto`] computes every distance, using neither the kd-tree nor the sketch:
/// below 256 candidates, or when `k` is above an eighth of them.
pub fn auto_is_brute(candidates: usize, k: usize) -> bool {
    candidates < AUTO_BRUTE_BELOW || k > candidates / 8
}

/// The kd-tree's normal budget under [`Plan::Auto`]: it may compute the distances of
/// `candidates / AUTO_TREE_SHARE + AUTO_TREE_PER_K · k + AUTO_TREE_BASE` rows, and never more than
/// `candidates / AUTO_TREE_MAX_SHARE`. A distance in the tree costs about 100 rows of the sketch
/// and 5–15 of brute force (a jump to another row): a fruitless walk adds a fraction of the
/// sketch's pass, more at 10k entries, where the cap lets it take as long as the sketch;
/// [`Observed`] skips a walk that keeps running out. The budget covers what queries near stored
/// places need (docs/performance.md#auto-plan).
const AUTO_TREE_SHARE: usize = 256;
const AUTO_TREE_PER_K: usize = 64;
const AUTO_TREE_BASE: usize = 512;
const AUTO_TREE_MAX_SHARE: usize = 16;

/// The short walk before the sketch while the normal walk is being skipped ([`Observed`]) computes
/// `AUTO_PRIME_BASE + AUTO_PRIME_PER_K · k` distances, the leaves nearest the query, whose k-th
/// distance lets the sketch rule rows out from its first block. Without it the sketch starts from
/// an empty heap and, on near-duplicates at 10k entries, gave up at its first check (see
/// docs/performance.md#auto-plan).
pub const AUTO_PRIME_BASE: usize = 64;
/// See [`AUTO_PRIME_BASE`].
pub const AUTO_PRIME_PER_K: usize = 4;

/// A distance the kd-tree computes costs about as much as this many rows of brute force on one
/// thread (a jump to another row, and the walk itself) over fewer than 32,768 rows, one more for
/// every doubling of the rows from there (the rows the walk jumps among outgrow the core's caches);
/// against brute force over `t` threads (the scans of 65,536 rows and more), `t` times as many:
/// [`auto_tree_row_cost`], which matches the measured cost (docs/performance.md#auto-plan).
///
/// When the sketch is being skipped ([`Observed`]), the deep walk may compute as many distances
/// as two brute-force passes cost (one on a retry), and goes on while its walks average less
/// than one pass. [`Observed::timed`] counts a walk's cost by its time instead.
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
        check_search(query, self.rows.dim(), self.len(), req.k, &req.exclude, out)?;
        if req.max_distance.is_nan() {
            return Err(Error::InvalidParameter {
                name: "max_distance",
                value: f64::NAN,
                expected: "a distance (or infinity for no bound)",
            });
        }
        let (exclude, bound) = (&req.exclude, req.max_distance);
        let probe = Probe {
            query,
            exclude,
            bound,
        };
        let mut best = Best::new(&mut out[..req.k]);
        let mut cost = Cost::default();
        let candidates = self.len().min(exclude.before_id);
        // Ids `tree_end..` are not in the kd-tree.
        let tree_end = self.tree.len();
        let rows = |from: usize, best: &mut Best<'_>, cost: &mut Cost| {
            cost.exact_rows += candidates.saturating_sub(from);
            scan(self.rows, from..candidates, probe, best);
        };
        if req.k > 0 && candidates > 0 {
            match req.plan {
                Plan::Brute => rows(0, &mut best, &mut cost),
                Plan::Sketch => {
                    let _ = self.sketch.scan(probe, 0, false, &mut best, &mut cost);
                    rows(self.sketch.len(), &mut best, &mut cost);
                }
                Plan::KdTree => {
                    self.walk(query, exclude, bound, usize::MAX, &mut best, &mut cost);
                    rows(tree_end, &mut best, &mut cost);
                }
                Plan::Auto => {
                    if auto_is_brute(candidates, req.k) {
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
        let timed = req.observed.is_some_and(|o| o.timed);
        let budget = match walk {
            Depth::Skip => 0,
            Depth::Short => AUTO_PRIME_BASE + AUTO_PRIME_PER_K * req.k,
            Depth::Normal => {
                (candidates / AUTO_TREE_SHARE + AUTO_TREE_PER_K * req.k + AUTO_TREE_BASE)
                    .min(candidates / AUTO_TREE_MAX_SHARE)
            }
            // A pass's worth of distances on a retry (a walk dearer than that is no use), two
            // otherwise (so that a walk a little dearer than a pass, while the walks average
            // less, is not cut short and then paid twice).
            Depth::Deep => {
                let retry = req.observed.is_some_and(Observed::deep_skipped);
                candidates / tree_row * if retry { 1 } else { 2 }
            }
        };
        let mut from = 0;
        if walk != Depth::Skip {
            let start = clock::start(timed && walk == Depth::Deep);
            let finished = self.walk(query, exclude, bound, budget, best, cost);
            let walk_ns = clock::ns(start);
            match (req.observed, walk) {
                (Some(o), Depth::Normal) => Observed::record(&o.walk_misses, finished),
                (Some(o), Depth::Deep) => {
                    let walked = o.passes(walk_ns, cost.tree_rows, tree_row, candidates);
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
        let probe = Probe {
            query,
            exclude,
            bound,
        };
        if matches!(walk, Depth::Normal | Depth::Short) && from < self.sketch.len() {
            let (start, exact, sketched) = (
                clock::start(timed && from == 0),
                cost.exact_rows,
                cost.sketch_rows,
            );
            let done = self.sketch.scan(probe, from, true, best, cost);
            let ns = clock::ns(start);
            if let Some(o) = req.observed {
                Observed::record(&o.sketch_misses, done);
                // A sketch over every row that gave up at its first checks ran brute force over the
                // rows: timed as a pass (the rows it scanned first add a few per cent; a sketch
                // that scanned more before giving up is not a pass: on 30,000 spread rows before
                // 10,000 near-duplicates it took four times a pass's time a row).
                let rows = cost.exact_rows - exact;
                let long = rows >= TIMED_SCAN && 8 * (cost.sketch_rows - sketched) <= rows;
                if let (Some(ns), false) = (ns, done || !long) {
                    o.note_scan(ns, rows);
                }
            }
            // The rows beyond the sketch (`scan` stops at its end).
            from = self.sketch.len();
        }
        if from < candidates {
            cost.exact_rows += candidates - from;
            // Whole passes only (the rows beyond the kd-tree run on fewer threads).
            let start = clock::start(timed && from == 0 && candidates >= TIMED_SCAN);
            scan(self.rows, from..candidates, probe, best);
            if let (Some(o), Some(ns)) = (req.observed, clock::ns(start)) {
                o.note_scan(ns, candidates);
            }
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

#[cfg(test)]
mod timing_tests {
    use super::{
        auto_tree_row_cost, load_ns, Index, Observed, Relaxed, Request, AUTO_MISSES, DEEP_PASS,
    };
    use crate::search::{online_rebuild, sketch_encode, sketch_len, Neighbor, Rows};

    #[test]
    fn a_timed_walk_costs_its_time_against_the_scans() {
        let (n, k) = (100_000, 1);
        let rule = auto_tree_row_cost(n, k);
        let o = Observed::timed();
        // Nothing timed yet: the rule, whatever the walk's time.
        assert_eq!(
            o.passes(Some(1e9), 500, rule, n),
            (500 * rule) as f64 / n as f64
        );
        // Brute force at 10 ns a row: a walk of 0.5 ms is half a pass, however many distances.
        o.note_scan(10.0 * 4096.0, 4096);
        assert_eq!(o.passes(Some(5e5), 500, rule, n), 0.5);
        assert_eq!(o.passes(Some(5e5), 50_000, rule, n), 0.5);
        // Untimed (no clock, or Observed::new): the rule.
        assert_eq!(o.passes(None, 500, rule, n), (500 * rule) as f64 / n as f64);
        // A clone starts again, timed as the original.
        let c = o.clone();
        assert!(c.timed == o.timed && load_ns(&c.row_ns) == 0.0);
    }

    #[test]
    fn only_a_retry_under_half_a_pass_starts_the_deep_walk_again() {
        let o = Observed::new();
        o.record_deep(2.0);
        assert!(o.deep_skipped());
        o.record_deep(0.6);
        assert!(o.deep_skipped(), "a retry of 0.6 passes is averaged in");
        o.record_deep(0.4);
        assert_eq!(
            o.deep_cost.load(Relaxed),
            (0.4 * f64::from(DEEP_PASS)) as u32
        );
        assert!(!o.deep_skipped());
    }

    #[test]
    fn the_time_per_row_is_the_fastest_first_pass_then_an_average() {
        let o = Observed::timed();
        let scan = |ns_a_row: f64| o.note_scan(ns_a_row * 4096.0, 4096);
        o.note_scan(0.0, 0);
        assert_eq!(load_ns(&o.row_ns), 0.0, "an empty scan counts for nothing");
        // A first scan whose thread was descheduled is undone by the next ones...
        scan(400.0);
        assert_eq!(load_ns(&o.row_ns), 400.0);
        scan(2.5);
        scan(3.0);
        scan(2.75);
        assert_eq!(load_ns(&o.row_ns), 2.5);
        // ...and from the fifth on, passes are averaged in, a slow one counting at most four
        // times the average.
        scan(2.0);
        assert_eq!(load_ns(&o.row_ns), 2.5 + (2.0 - 2.5) / 8.0);
        let old = load_ns(&o.row_ns);
        scan(1e6);
        assert_eq!(load_ns(&o.row_ns), old + (4.0 * old - old) / 8.0);
    }

    #[test]
    fn only_a_timed_record_times_the_searches() {
        // Near-duplicates (one place under 0.1 % noise): brute force follows the sketch on the
        // first queries, over most rows: long enough to be timed.
        let (n, dim) = (8_000, 24);
        let mut rng = crate::math::XorShift32(0x2545_f491);
        let mut next = move || (rng.next_u32() % 1_000_000) as f32 / 1e6;
        let place: Vec<f32> = (0..dim).map(|_| 0.5 + next()).collect();
        let mut data: Vec<f32> = (0..n)
            .flat_map(|_| {
                place
                    .iter()
                    .map(|v| v * (1.0 + 1e-3 * next()))
                    .collect::<Vec<_>>()
            })
            .collect();
        for row in data.chunks_exact_mut(dim) {
            let norm = row.iter().map(|v| v * v).sum::<f32>().sqrt();
            row.iter_mut().for_each(|v| *v /= norm);
        }
        let rows = Rows::normalized(&data, dim).unwrap();
        let (mut perm, mut splits) = (vec![0u32; n], vec![0u16; n]);
        online_rebuild(rows, &mut perm, &mut splits).unwrap();
        let (nc, np) = sketch_len(n, dim);
        let (mut codes, mut params) = (vec![0u8; nc], vec![0f32; np]);
        sketch_encode(rows, 0, &mut codes, &mut params).unwrap();
        let index = Index::new(rows, &perm, &splits, &codes, &params).unwrap();
        let q = &data[..dim];
        for (o, timed) in [
            (Observed::new(), false),
            (Observed::timed(), cfg!(feature = "std")),
        ] {
            for _ in 0..4 {
                let req = Request {
                    observed: Some(&o),
                    ..Request::nearest(1)
                };
                index.search(q, &req, &mut [Neighbor::default()]).unwrap();
            }
            assert_eq!(load_ns(&o.row_ns) > 0.0, timed);
        }
        // A deep walk (the sketch being skipped) counted by its time: against brute force at a
        // millisecond a row, it cost next to nothing, the pass that follows it if it ran out
        // aside; by the rule, the distances it computed.
        let deep = |o: &Observed| {
            o.sketch_misses.store(AUTO_MISSES, Relaxed);
            o.queries.store(AUTO_MISSES + 1, Relaxed);
            o.deep_cost.store(0, Relaxed);
            o.row_ns.store(1e6f32.to_bits(), Relaxed);
            let req = Request {
                observed: Some(o),
                ..Request::nearest(1)
            };
            let found = index.search(q, &req, &mut [Neighbor::default()]).unwrap();
            let ran_out = found.cost.exact_rows > 0;
            let cost = f64::from(o.deep_cost.load(Relaxed)) / f64::from(DEEP_PASS);
            (found.cost.tree_rows, cost - if ran_out { 1.0 } else { 0.0 })
        };
        let rule = auto_tree_row_cost(n, 1);
        let (rows, walked) = deep(&Observed::new());
        assert!(
            rows > 0 && (walked - (rows * rule) as f64 / n as f64).abs() < 0.01,
            "{rows} {walked}"
        );
        let (rows, walked) = deep(&Observed::timed());
        assert!(rows > 0, "{rows}");
        if cfg!(feature = "std") {
            assert!(walked < 0.01, "{rows} {walked}");
        }
    }
}
