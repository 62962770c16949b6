//! The index that holds every search over the same rows, and the automatic choice among them.

use super::kdtree::{Walk, MAX_OFFSET_DIM};
use super::{check_out, check_query, scan, Best, Exclude, Neighbor, OnlineIndex, Sketch};
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
}

impl Request<'_> {
    /// The `k` nearest of every entry, with [`Plan::Auto`].
    pub const fn nearest(k: usize) -> Request<'static> {
        Request {
            k,
            exclude: Exclude::NONE,
            max_distance: f32::INFINITY,
            plan: Plan::Auto,
        }
    }
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

/// The kd-tree's budget under [`Plan::Auto`]: it may compute the distances of
/// `candidates / AUTO_TREE_SHARE + AUTO_TREE_PER_K · k + AUTO_TREE_BASE` rows, and never more than
/// `candidates / AUTO_TREE_MAX_SHARE`. A distance in the tree costs 10–30 rows of the sketch (a
/// jump to another row: more as the rows outgrow the caches), so a fruitless walk adds at most
/// about a quarter to the sketch's pass. Measured on realistic databases
/// (`benches/benches/search.rs`): queries near stored places need a median of 400–1,000 rows
/// for k = 1 at 10k to 1M entries, and 2.5 times that for k = 10.
const AUTO_TREE_SHARE: usize = 128;
const AUTO_TREE_PER_K: usize = 64;
const AUTO_TREE_BASE: usize = 256;
const AUTO_TREE_MAX_SHARE: usize = 16;

/// Every search over one set of L2-normalised rows: brute force, the online kd-tree index and the
/// sketch, viewing caller-owned buffers (see [`OnlineIndex`] and [`Sketch`]).
#[derive(Debug, Clone, Copy)]
pub struct Index<'a> {
    tree: OnlineIndex<'a>,
    sketch: Sketch<'a>,
    rows: &'a [f32],
    dim: usize,
}

impl<'a> Index<'a> {
    /// Views the online index (`perm`, `splits`, as [`online_insert`](super::online_insert)
    /// maintains them) and the sketch (`codes`, `params`, as
    /// [`sketch_encode`](super::sketch_encode) fills them) of every row of `rows`.
    ///
    /// # Errors
    /// As [`OnlineIndex::new`] and [`Sketch::new`].
    pub fn new(
        rows: &'a [f32],
        dim: usize,
        perm: &'a [u32],
        splits: &'a [u16],
        codes: &'a [u8],
        params: &'a [f32],
    ) -> Result<Index<'a>, Error> {
        Ok(Index {
            tree: OnlineIndex::new(rows, dim, perm, splits)?,
            sketch: Sketch::new(rows, dim, codes, params)?,
            rows,
            dim,
        })
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.sketch.len()
    }

    /// `true` when the index holds no entry.
    pub fn is_empty(&self) -> bool {
        self.sketch.is_empty()
    }

    /// Exact k-NN of the L2-normalised `query`: the `min(k, candidates)` nearest allowed entries
    /// within `max_distance`, written to `out` nearest first (ties by lower id): the same results
    /// as [`brute_force`](super::brute_force) (then cut at `max_distance`) with every plan.
    ///
    /// [`Plan::Auto`] computes every distance below 256 candidates or when `k` is above an
    /// eighth of them. Otherwise it walks the kd-tree until it has computed about
    /// `candidates / 128 + 64 k + 256` distances (at most a sixteenth of the candidates): queries
    /// near stored places end there. If the walk did not finish, the sketch scans every
    /// candidate, ruling out rows farther than the walk's k-th distance so far; and if a quarter
    /// of the rows scanned still need their exact distance (rows too alike for the bytes to tell
    /// apart), brute force takes the rest.
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
        check_query(query, self.dim)?;
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
        let all_rows = |best: &mut Best<'_>, cost: &mut Cost, bound: f32| {
            cost.exact_rows += candidates;
            scan(
                self.rows, self.dim, 0, candidates, query, exclude, bound, best,
            );
        };
        if req.k > 0 && candidates > 0 {
            match req.plan {
                Plan::Brute => all_rows(&mut best, &mut cost, bound),
                Plan::Sketch => self
                    .sketch
                    .scan(query, exclude, bound, false, &mut best, &mut cost),
                Plan::KdTree => {
                    self.walk(query, exclude, bound, usize::MAX, &mut best, &mut cost);
                }
                Plan::Auto => {
                    if candidates < AUTO_BRUTE_BELOW || req.k > candidates / 8 {
                        all_rows(&mut best, &mut cost, bound);
                    } else {
                        let budget = (candidates / AUTO_TREE_SHARE
                            + AUTO_TREE_PER_K * req.k
                            + AUTO_TREE_BASE)
                            .min(candidates / AUTO_TREE_MAX_SHARE);
                        if !self.walk(query, exclude, bound, budget, &mut best, &mut cost) {
                            // Start again over every row, with the walk's k-th distance as
                            // the bound: no true neighbour is farther.
                            let bound = best.limit(bound);
                            best.clear();
                            self.sketch
                                .scan(query, exclude, bound, true, &mut best, &mut cost);
                        }
                    }
                }
            }
        }
        Ok(Found {
            len: best.finish(),
            cost,
        })
    }

    /// Walks the kd-tree within `budget` distances; `true` when it finished (exact results).
    fn walk(
        &self,
        query: &[f32],
        exclude: &Exclude<'_>,
        bound: f32,
        budget: usize,
        best: &mut Best<'_>,
        cost: &mut Cost,
    ) -> bool {
        let mut off = [0f64; MAX_OFFSET_DIM];
        let mut walk = Walk::new(query, exclude, bound, budget, &mut off);
        self.tree.walk(&mut walk, best);
        cost.tree_rows += walk.rows;
        !walk.stopped()
    }
}
