//! Keeping the [`Database`]'s index (the online kd-tree and the search sketch) up to date: its
//! room, its build after bulk adds, and when that build is due.

use core::sync::atomic::{AtomicUsize, Ordering::Relaxed};

use super::fill::{in_chunks, CHUNK_ROWS};
use super::query::SearchOptions;
use super::Database;
use crate::db::room;
use crate::db::DbError;
use crate::search::{self, Plan, Request, Rows, SKETCH_BLOCK};
use crate::Error;
use alloc::vec::Vec;

/// After a bulk add that left the index behind ([`Database::add_batch`] without `index`), building
/// it is due once the searches have scanned the entries beyond it, by brute force, this many times
/// the rows the build would index ([`Database::index_due`]): about what a build costs in passes of
/// brute force over the same rows. So a few searches never pay for an index, many pay for it
/// once, and no number of searches costs more than about twice the cheaper of the two (the
/// renter's rule: rent until the rent paid would have bought it). The ratio measured between the
/// two: docs/performance.md#database.
pub const INDEX_AFTER_PASSES: usize = 40;

impl Database {
    /// Reserves the room of the sketch and the kd-tree of `n` entries.
    pub(super) fn reserve_index(&mut self, n: usize) -> Result<(), DbError> {
        let oom = |_| DbError::OutOfMemory;
        let extra = n.saturating_sub(self.perm.len());
        room::reserve(&mut self.perm, extra).map_err(oom)?;
        let extra = n.saturating_sub(self.splits.len());
        room::reserve(&mut self.splits, extra).map_err(oom)?;
        if !self.sketch {
            return Ok(());
        }
        let (nc, np) = search::sketch_len(n, self.config.n_range);
        let extra = nc.saturating_sub(self.codes.len());
        room::reserve(&mut self.codes, extra).map_err(oom)?;
        let extra = np.saturating_sub(self.params.len());
        room::reserve(&mut self.params, extra).map_err(oom)?;
        Ok(())
    }

    /// Whether the index includes the search sketch: yes for a new database; no for a map loaded
    /// from a file, whose index is the kd-tree alone. A map's searches are mostly of the places it
    /// holds, which the kd-tree's walk answers alone; the sketch (`n_range + 12` bytes a place, 52
    /// with the presets' 40 range bins) only speeds up searches for places it does not hold,
    /// which brute force answers without it (the same results either way; measured:
    /// docs/performance.md#maps-at-scale). Turning it off frees the sketch; turning it on leaves
    /// it to the next [`Database::build_index`] (or the searches that build the index).
    pub fn set_sketch(&mut self, on: bool) {
        if !on {
            self.codes = Vec::new();
            self.params = Vec::new();
        }
        self.sketch = on;
    }

    /// Whether the index includes the search sketch ([`Database::set_sketch`]).
    pub fn has_sketch(&self) -> bool {
        self.sketch
    }

    /// Entries the sketch covers (a prefix; see [`Index::new`](crate::search::Index::new)): true because the sketch is cut
    /// back to whole blocks whenever entries are added ([`Database::cut_sketch`]).
    pub(super) fn sketched(&self) -> usize {
        search::sketch_rows(self.params.len()).min(self.len())
    }

    /// Cuts the sketch back to the whole blocks of its first `rows` entries: what new entries need
    /// until they are sketched (the sketch's length says how many entries it covers, and the
    /// lanes past the end of its last block are zeros, not their sketch).
    pub(super) fn cut_sketch(&mut self, rows: usize) {
        let (nc, np) = search::sketch_len(rows / SKETCH_BLOCK * SKETCH_BLOCK, self.config.n_range);
        self.codes.truncate(nc);
        self.params.truncate(np);
    }

    /// Encodes the sketch of the entries beyond it (room reserved; it ends on a whole block, see
    /// [`Database::cut_sketch`]), written in place as [`Database::append_vectors`] writes: chunks
    /// of whole blocks, each laid out as a sketch of its own rows.
    fn extend_sketch(&mut self) -> Result<(), Error> {
        let nr = self.config.n_range;
        let n = self.len();
        let from = self.sketched();
        debug_assert!(
            from.is_multiple_of(SKETCH_BLOCK),
            "the sketch ends inside a block"
        );
        let (nc, np) = search::sketch_len(n, nr);
        let (code_len, param_len) = (nc - self.codes.len(), np - self.params.len());
        let (code_chunk, param_chunk) = search::sketch_len(CHUNK_ROWS, nr);
        let m = n - from;
        let chunks = self.r[from * nr..]
            .chunks(CHUNK_ROWS * nr)
            .zip(self.r_scale[from..].chunks(CHUNK_ROWS))
            .zip(room::spare(&mut self.codes, code_len).chunks_mut(code_chunk))
            .zip(room::spare(&mut self.params, param_len).chunks_mut(param_chunk));
        // `CHUNK_ROWS` is a whole number of blocks: the room splits as the rows do.
        assert!(
            code_len.div_ceil(code_chunk) == m.div_ceil(CHUNK_ROWS)
                && param_len.div_ceil(param_chunk) == m.div_ceil(CHUNK_ROWS),
            "extend_sketch: the sketch's room does not match the rows"
        );
        in_chunks(chunks, m, |(((r, scale), codes), params)| {
            let (codes, params) = (room::zeroed(codes), room::zeroed(params));
            search::sketch_encode(Rows::scaled(r, nr, scale)?, 0, codes, params)
        })?;
        #[allow(unsafe_code)]
        // SAFETY: the chunks cover every slot of each `room::spare` above, and each chunk
        // zeroed all of its slots before anything could fail (and nothing is committed unless
        // every chunk succeeded).
        unsafe {
            room::commit(&mut self.codes, code_len);
            room::commit(&mut self.params, param_len);
        }
        Ok(())
    }

    /// Brings the kd-tree and the search sketch (when the index has one: [`Database::set_sketch`])
    /// up to every entry (after [`Database::add_batch`] without `index`, or a load); does nothing
    /// when they are up to date.
    ///
    /// # Errors
    /// [`DbError::OutOfMemory`].
    pub fn build_index(&mut self) -> Result<(), DbError> {
        let (n, from) = (self.len(), self.perm.len());
        let sketch_due = self.sketch && self.sketched() < n;
        if from == n && !sketch_due {
            return Ok(());
        }
        self.reserve_index(n)?;
        if sketch_due {
            self.extend_sketch()?;
        }
        if from < n {
            self.perm.resize(n, 0);
            self.splits.resize(n, 0);
            let rows = Rows::scaled(&self.r, self.config.n_range, &self.r_scale)?;
            // Scratch for the faster build of large blocks; without memory for it, the slower
            // build.
            let mut keys = Vec::new();
            if keys
                .try_reserve_exact(search::online_extend_scratch_len(n, from))
                .is_ok()
            {
                keys.resize(keys.capacity(), 0);
            }
            search::online_extend_with(rows, from, &mut self.perm, &mut self.splits, &mut keys)?;
        }
        // Every entry is indexed: the searches' count starts again.
        self.unindexed = Tally::default();
        Ok(())
    }

    /// Entries the index (the kd-tree and the search sketch) does not cover yet: those of a bulk
    /// add without `index` ([`Database::add_batch`]), which the searches scan by brute force.
    pub fn index_pending(&self) -> usize {
        self.len() - self.indexed()
    }

    /// Entries both the kd-tree and the sketch (when the index has one) cover (a prefix of the
    /// ids).
    fn indexed(&self) -> usize {
        if self.sketch {
            self.perm.len().min(self.sketched())
        } else {
            self.perm.len()
        }
    }

    /// Whether [`Database::build_index`] is due before `queries` more searches with `opts`: when
    /// the searches since the index last covered every entry, with these, scan the entries beyond
    /// it [`INDEX_AFTER_PASSES`] times the rows the build would index. A store that adds in bulk
    /// without `index` and builds when this says so pays for an index only when its searches
    /// would have cost about as much without it. `false` when nothing is pending, and for
    /// searches that scan nothing beyond the index: brute force, `auto` when it computes every
    /// distance (fewer than 256 candidates, or `k` above an eighth of them), `k = 0`, and
    /// exclusions that leave only indexed entries.
    pub fn index_due(&self, opts: &SearchOptions, queries: usize) -> bool {
        let Ok(req) = self.request(opts) else {
            return false; // the search itself reports the bad option
        };
        let rows = self.unindexed_rows(&req);
        if rows == 0 {
            return false;
        }
        let build =
            search::online_extend_rows(self.len(), self.perm.len()).max(self.index_pending());
        self.unindexed
            .get()
            .saturating_add(queries.saturating_mul(rows))
            >= INDEX_AFTER_PASSES.saturating_mul(build)
    }

    /// Rows of one search with `req` that brute force covers only because they are beyond the
    /// index: 0 for a plan that uses no index.
    pub(super) fn unindexed_rows(&self, req: &Request<'_>) -> usize {
        let candidates = self.len().min(req.exclude.before_id);
        if req.k == 0 {
            return 0; // nothing is scanned
        }
        let indexed = match req.plan {
            Plan::Brute => return 0,
            Plan::Auto if search::auto_is_brute(candidates, req.k) => return 0,
            Plan::KdTree => self.perm.len(),
            // Without a sketch, building the index does not spare this plan any row.
            Plan::Sketch if !self.sketch => return 0,
            Plan::Sketch => self.sketched(),
            Plan::Auto => self.indexed(),
        };
        candidates.saturating_sub(indexed)
    }
}

/// A count that searches (sharing `&Database`) add to: loaded and stored, not locked, as
/// [`Observed`](crate::search::Observed)'s (two searches at once may lose one's rows, which only delays a build).
#[derive(Debug, Default)]
pub(super) struct Tally(AtomicUsize);

impl Tally {
    pub(super) fn get(&self) -> usize {
        self.0.load(Relaxed)
    }

    pub(super) fn add(&self, rows: usize) {
        // Searches of an indexed database add nothing: they leave the shared line alone.
        if rows > 0 {
            self.0.store(self.get().saturating_add(rows), Relaxed);
        }
    }
}

impl Clone for Tally {
    fn clone(&self) -> Self {
        Tally(AtomicUsize::new(self.get()))
    }
}
