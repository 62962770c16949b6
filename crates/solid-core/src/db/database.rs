//! [`Database`]: the entries and their exact search.
//!
//! Per entry without a pose the database holds 298 bytes (`memory_bytes` counts them; the issue
//! that set the budget measured 682 before): the R-SOLiD as added (`4·n_range`) and the scale
//! that normalises it (4), the search sketch (`n_range` bytes and 12), the kd-tree (6), the
//! session (4), the timestamp (8) and the A-SOLiD at 8 bits with its scale (`n_azimuth` + 4);
//! entries added by [`Database::add_batch`] without `index` hold no sketch or kd-tree (240 bytes)
//! until [`Database::build_index`]. A pose costs 104 bytes for the entries that have one. On
//! Linux with `std`, columns of 4 MiB and more ask the kernel for transparent huge pages (`madvise`, as numpy does for its large
//! arrays): faster bulk adds and scans, memory taken in steps of 2 MiB.

use alloc::vec;
use alloc::vec::Vec;

use super::clouds::Clouds;
use super::room;
use super::{DbError, Method};
use crate::math::inverse_step;
use crate::search::{self, Exclude, Index, Neighbor, Observed, Plan, Request, Rows, SKETCH_BLOCK};
use crate::{Config, Descriptor, Error};
use core::sync::atomic::{AtomicUsize, Ordering::Relaxed};

/// After a bulk add that left the index behind ([`Database::add_batch`] without `index`), building
/// it is due once the searches have scanned the entries beyond it, by brute force, this many times
/// the rows the build would index ([`Database::index_due`]): about what a build costs in passes of
/// brute force over the same rows. So a few searches never pay for an index, many pay for it
/// once, and no number of searches costs more than about twice the cheaper of the two (the
/// renter's rule: rent until the rent paid would have bought it). Measured (release probe,
/// `build_index` from nothing ÷ the median `search_with` by brute force over every entry, 15
/// queries back to back, HKU copies and near-duplicates, 2-core AMD EPYC): 30–32 at 10,000
/// entries, 72–84 at 100,000 (rows that stay in the cache between the searches), 27–44 at
/// 1,000,000.
pub const INDEX_AFTER_PASSES: usize = 40;

/// Options of [`Database::search_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchOptions {
    /// Number of neighbours.
    pub k: usize,
    /// Skip the most recent entries (the last `exclude_recent` ids).
    pub exclude_recent: usize,
    /// Skip entries whose timestamp is greater than this (entries without a time are kept).
    pub not_newer_than: Option<f64>,
    /// Return only neighbours at most this far (`f32::INFINITY`: no bound). A caller that
    /// accepts only matches within a threshold passes it: every method then skips more.
    pub max_distance: f32,
    /// Search method.
    pub method: Method,
}

impl Default for SearchOptions {
    fn default() -> Self {
        SearchOptions {
            k: 1,
            exclude_recent: 0,
            not_newer_than: None,
            max_distance: f32::INFINITY,
            method: Method::Auto,
        }
    }
}

/// The results of [`Database::search_batch`]: `k` slots per query, nearest first.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchResults {
    /// Slots per query.
    pub k: usize,
    /// Ids, `queries × k`, row-major; [`BatchResults::NONE`] in the slots of a query with
    /// fewer than `k` neighbours.
    pub ids: Vec<u32>,
    /// Distances, `queries × k`; infinity in empty slots.
    pub distances: Vec<f32>,
}

impl BatchResults {
    /// The id of an empty slot.
    pub const NONE: u32 = u32::MAX;

    /// The neighbours of query `i`.
    ///
    /// # Panics
    /// When `i` is not a query of the batch.
    pub fn neighbors(&self, i: usize) -> impl Iterator<Item = Neighbor> + '_ {
        let range = i * self.k..(i + 1) * self.k;
        self.ids[range.clone()]
            .iter()
            .zip(&self.distances[range])
            .take_while(|(&id, _)| id != Self::NONE)
            .map(|(&id, &distance)| Neighbor { id, distance })
    }
}

/// A database of places, searchable exactly at every size (see the module documentation).
#[derive(Debug, Clone)]
pub struct Database {
    pub(super) config: Config,
    pub(super) fingerprint: u64,
    pub(super) sessions: Vec<u32>,
    pub(super) timestamps: Vec<f64>,
    /// The poses of the entries that have one, by increasing id.
    poses: Vec<(u32, [f64; 12])>,
    /// R-SOLiDs as added, row-major.
    r: Vec<f32>,
    /// Per entry, `1 / ‖r‖` ([`search::inverse_norm`]): the search compares `r × scale`.
    r_scale: Vec<f32>,
    /// A-SOLiDs at 8 bits per value (see [`Database::a`]).
    a_codes: Vec<u8>,
    /// Per entry, the A-SOLiD's step (see [`Database::a`]).
    a_scale: Vec<f32>,
    /// The online kd-tree over ids `0..perm.len()` (a prefix: a bulk add may leave it behind
    /// until [`Database::build_index`]).
    perm: Vec<u32>,
    splits: Vec<u16>,
    /// The search sketch of the entries `0..sketched()` ([`search::Sketch`]; a prefix of whole
    /// blocks, or every entry, as [`Index::new`] reads it).
    codes: Vec<u8>,
    params: Vec<f32>,
    /// What the automatic search has seen on this database's queries.
    observed: Observed,
    /// Rows the searches scanned by brute force only because they were beyond the index, since
    /// it last covered every entry ([`Database::index_due`]).
    unindexed: Tally,
    /// Whether the searches build the index when it is due ([`super::IndexPolicy::BySearches`]).
    pub(super) index_by_searches: bool,
    /// The compact clouds of the entries that have one (for verification).
    pub(super) clouds: Clouds,
}

impl Database {
    /// An empty database for descriptors made with `config`.
    ///
    /// # Errors
    /// [`DbError::Core`] when `config` is invalid.
    pub fn new(config: Config) -> Result<Database, DbError> {
        config.validate()?;
        Ok(Database {
            config,
            fingerprint: config.fingerprint(),
            sessions: Vec::new(),
            timestamps: Vec::new(),
            poses: Vec::new(),
            r: Vec::new(),
            r_scale: Vec::new(),
            a_codes: Vec::new(),
            a_scale: Vec::new(),
            perm: Vec::new(),
            splits: Vec::new(),
            codes: Vec::new(),
            params: Vec::new(),
            observed: Observed::timed(),
            unindexed: Tally::default(),
            index_by_searches: false,
            clouds: Clouds::default(),
        })
    }

    /// The configuration every entry was described with.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.sessions.len()
    }

    /// `true` when the database holds no entry.
    pub fn is_empty(&self) -> bool {
        self.sessions.is_empty()
    }

    /// Adds a descriptor; returns its id (ids count from 0 in insertion order).
    /// `timestamp` NaN means none; `pose` is a row-major 3×4 `[R|t]`.
    ///
    /// # Errors
    /// [`DbError::ConfigMismatch`] when the descriptor was made with another config; otherwise
    /// as [`Database::add_vectors`].
    pub fn add(
        &mut self,
        d: &Descriptor,
        session: u32,
        timestamp: f64,
        pose: Option<[f64; 12]>,
    ) -> Result<u32, DbError> {
        self.check_fingerprint(d.fingerprint)?;
        self.add_vectors(&d.r, &d.a, session, timestamp, pose)
    }

    /// [`Database::add`] with the place's compact cloud for verification (the wire form of
    /// [`crate::reg::encode_cloud`]; see [`super::clouds`]).
    ///
    /// # Errors
    /// As [`Database::add`]; on error nothing is added.
    pub fn add_with_cloud(
        &mut self,
        d: &Descriptor,
        session: u32,
        timestamp: f64,
        pose: Option<[f64; 12]>,
        cloud: Option<&[u8]>,
    ) -> Result<u32, DbError> {
        self.check_fingerprint(d.fingerprint)?;
        let id = self.len();
        self.clouds.push(id, cloud)?;
        self.add_vectors(&d.r, &d.a, session, timestamp, pose)
            .inspect_err(|_| self.clouds.truncate(id))
    }

    /// Adds raw vectors (the caller vouches that they come from this database's config).
    ///
    /// # Errors
    /// [`DbError::Core`] with [`Error::LengthMismatch`] for vectors of the wrong length, or with
    /// [`Error::InvalidParameter`] for negative or non-finite values in the vectors, an infinite
    /// timestamp, or a pose that is not finite or not a rotation (see [`check_pose`]);
    /// [`DbError::Full`] beyond `u32::MAX` entries.
    pub fn add_vectors(
        &mut self,
        r: &[f32],
        a: &[f32],
        session: u32,
        timestamp: f64,
        pose: Option<[f64; 12]>,
    ) -> Result<u32, DbError> {
        let (nr, na) = (self.config.n_range, self.config.n_azimuth);
        if r.len() != nr {
            return Err(Error::LengthMismatch {
                what: "r_solid vs config n_range",
                left: r.len(),
                right: nr,
            }
            .into());
        }
        if a.len() != na {
            return Err(Error::LengthMismatch {
                what: "a_solid vs config n_azimuth",
                left: a.len(),
                right: na,
            }
            .into());
        }
        let poses = pose.as_ref().map(core::slice::from_ref);
        self.add_batch(r, a, session, Some(&[timestamp]), poses, true)
    }

    /// Adds `N` entries at once from `r` (`N × n_range`, row-major) and `a` (`N × n_azimuth`),
    /// all in `session`, with `timestamps` (`N`, NaN: none; `None`: none for all) and `poses`
    /// (`N` row-major 3×4 `[R|t]`; `None`: none). Returns the id of the first (the others
    /// follow). Everything is checked before anything is added. With `index`, the search sketch
    /// and the kd-tree are brought up to date; without, the entries are only stored (checked,
    /// normalised and quantised) and searches stay exact, computing the distances of the entries
    /// beyond the index, until something builds them ([`Database::build_index`], a single add, an
    /// indexed bulk add, a merge): the fastest way to load many entries. [`Database::index_due`]
    /// says when the searches have scanned them about as often as building the index costs.
    ///
    /// # Errors
    /// [`DbError::Core`] with [`Error::LengthMismatch`] when the lengths disagree, or with
    /// [`Error::InvalidParameter`] for a negative or non-finite value in the vectors, an infinite
    /// timestamp or a pose that is not a rotation; [`DbError::Full`] beyond `u32::MAX` entries;
    /// [`DbError::OutOfMemory`]. On error nothing is added.
    pub fn add_batch(
        &mut self,
        r: &[f32],
        a: &[f32],
        session: u32,
        timestamps: Option<&[f64]>,
        poses: Option<&[[f64; 12]]>,
        index: bool,
    ) -> Result<u32, DbError> {
        let (nr, na) = (self.config.n_range, self.config.n_azimuth);
        let m = r.len() / nr;
        let expect = |what: &'static str, left: usize, right: usize| {
            if left == right {
                Ok(())
            } else {
                Err(DbError::Core(Error::LengthMismatch { what, left, right }))
            }
        };
        expect("r_solid values vs a multiple of n_range", r.len(), m * nr)?;
        expect("a_solid rows vs r_solid rows", a.len(), m * na)?;
        if let Some(t) = timestamps {
            expect("timestamps vs rows", t.len(), m)?;
            if let Some(&bad) = t.iter().find(|t| t.is_infinite()) {
                return Err(Error::InvalidParameter {
                    name: "timestamp",
                    value: bad,
                    expected: "a finite time in seconds (NaN for none)",
                }
                .into());
            }
        }
        if let Some(p) = poses {
            expect("poses vs rows", p.len(), m)?;
        }
        let first = self.len();
        if first + m >= u32::MAX as usize {
            return Err(DbError::Full);
        }
        for p in poses.unwrap_or(&[]) {
            check_pose(p)?;
        }
        self.reserve(m, poses.map_or(0, <[_]>::len), index)?;
        // The vectors are checked as they are written; on a bad value nothing is added.
        let sketched = self.sketched();
        self.append_vectors(r, a)?;
        if m > 0 {
            self.cut_sketch(sketched);
        }
        // Nothing below can fail: the memory is reserved.
        self.sessions.extend(core::iter::repeat_n(session, m));
        match timestamps {
            Some(t) => self.timestamps.extend_from_slice(t),
            None => self.timestamps.extend(core::iter::repeat_n(f64::NAN, m)),
        }
        if let Some(p) = poses {
            self.poses
                .extend(p.iter().enumerate().map(|(i, p)| ((first + i) as u32, *p)));
        }
        if index {
            self.build_index()?;
        }
        Ok(first as u32)
    }

    /// Reserves room for `m` more entries (`with_pose` of them with a pose, and with `index` the
    /// room of their sketch and kd-tree), so that adding them cannot fail half-way.
    fn reserve(&mut self, m: usize, with_pose: usize, index: bool) -> Result<(), DbError> {
        let (nr, na) = (self.config.n_range, self.config.n_azimuth);
        let oom = |_| DbError::OutOfMemory;
        room::reserve(&mut self.sessions, m).map_err(oom)?;
        room::reserve(&mut self.timestamps, m).map_err(oom)?;
        self.poses.try_reserve(with_pose).map_err(oom)?;
        room::reserve(&mut self.r, m * nr).map_err(oom)?;
        room::reserve(&mut self.r_scale, m).map_err(oom)?;
        room::reserve(&mut self.a_codes, m * na).map_err(oom)?;
        room::reserve(&mut self.a_scale, m).map_err(oom)?;
        if index {
            self.reserve_index(self.len() + m)?;
        }
        Ok(())
    }

    /// Reserves the room of the sketch and the kd-tree of `n` entries.
    fn reserve_index(&mut self, n: usize) -> Result<(), DbError> {
        let oom = |_| DbError::OutOfMemory;
        let (nc, np) = search::sketch_len(n, self.config.n_range);
        let extra = n.saturating_sub(self.perm.len());
        room::reserve(&mut self.perm, extra).map_err(oom)?;
        let extra = n.saturating_sub(self.splits.len());
        room::reserve(&mut self.splits, extra).map_err(oom)?;
        let extra = nc.saturating_sub(self.codes.len());
        room::reserve(&mut self.codes, extra).map_err(oom)?;
        let extra = np.saturating_sub(self.params.len());
        room::reserve(&mut self.params, extra).map_err(oom)?;
        Ok(())
    }

    /// Appends vectors (room reserved), checking them on the way: the raw R-SOLiDs and their
    /// scales ([`search::inverse_norm`]) and the quantised A-SOLiDs, written in place into the
    /// reserved room by the tasks that compute them (chunks of rows shared among threads with
    /// `parallel`; see [`room`]) and added to the columns only when every chunk is written. The
    /// sketch and the kd-tree are left to [`Database::build_index`]. On an error nothing is
    /// added.
    fn append_vectors(&mut self, r: &[f32], a: &[f32]) -> Result<(), Error> {
        let (nr, na) = (self.config.n_range, self.config.n_azimuth);
        let m = r.len() / nr;
        // Every column's room splits into as many chunks as the input (what `commit` relies on;
        // the callers checked the lengths).
        assert!(
            r.len() == m * nr && a.len() == m * na,
            "append_vectors: the vectors do not match the rows"
        );
        let chunks = r
            .chunks(CHUNK_ROWS * nr)
            .zip(a.chunks(CHUNK_ROWS * na))
            .zip(room::spare(&mut self.r, m * nr).chunks_mut(CHUNK_ROWS * nr))
            .zip(room::spare(&mut self.r_scale, m).chunks_mut(CHUNK_ROWS))
            .zip(room::spare(&mut self.a_codes, m * na).chunks_mut(CHUNK_ROWS * na))
            .zip(room::spare(&mut self.a_scale, m).chunks_mut(CHUNK_ROWS));
        in_chunks(
            chunks,
            m,
            |(((((r, a), r_out), scale), a_codes), a_scale)| {
                room::copied(r_out, r);
                ChunkOut {
                    r,
                    a,
                    scale: room::zeroed(scale),
                    a_codes: room::zeroed(a_codes),
                    a_scale: room::zeroed(a_scale),
                }
                .fill(nr, na)
            },
        )?;
        #[allow(unsafe_code)]
        // SAFETY: the chunks cover every slot of each `room::spare` above, and each chunk
        // wrote all of its slots (`room::copied`, `room::zeroed`) before any could fail.
        unsafe {
            room::commit(&mut self.r, m * nr);
            room::commit(&mut self.r_scale, m);
            room::commit(&mut self.a_codes, m * na);
            room::commit(&mut self.a_scale, m);
        }
        Ok(())
    }

    /// Entries the sketch covers (a prefix; see [`Index::new`]): true because the sketch is cut
    /// back to whole blocks whenever entries are added ([`Database::cut_sketch`]).
    fn sketched(&self) -> usize {
        search::sketch_rows(self.params.len()).min(self.len())
    }

    /// Cuts the sketch back to the whole blocks of its first `rows` entries: what new entries need
    /// until they are sketched (the sketch's length says how many entries it covers, and the
    /// lanes past the end of its last block are zeros, not their sketch).
    fn cut_sketch(&mut self, rows: usize) {
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

    /// Brings the search sketch and the kd-tree up to every entry (after
    /// [`Database::add_batch`] without `index`); does nothing when they are up to date.
    ///
    /// # Errors
    /// [`DbError::OutOfMemory`].
    pub fn build_index(&mut self) -> Result<(), DbError> {
        let (n, from) = (self.len(), self.perm.len());
        if from == n && self.sketched() == n {
            return Ok(());
        }
        self.reserve_index(n)?;
        if self.sketched() < n {
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

    /// Entries both the kd-tree and the sketch cover (a prefix of the ids).
    fn indexed(&self) -> usize {
        self.perm.len().min(self.sketched())
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
    fn unindexed_rows(&self, req: &Request<'_>) -> usize {
        let candidates = self.len().min(req.exclude.before_id);
        if req.k == 0 {
            return 0; // nothing is scanned
        }
        let indexed = match req.plan {
            Plan::Brute => return 0,
            Plan::Auto if search::auto_is_brute(candidates, req.k) => return 0,
            Plan::KdTree => self.perm.len(),
            Plan::Sketch => self.sketched(),
            Plan::Auto => self.indexed(),
        };
        candidates.saturating_sub(indexed)
    }

    /// The rows the searches compare.
    fn rows(&self) -> Result<Rows<'_>, Error> {
        Rows::scaled(&self.r, self.config.n_range, &self.r_scale)
    }

    /// Every search over the entries.
    fn index(&self) -> Result<Index<'_>, Error> {
        Index::new(
            self.rows()?,
            &self.perm,
            &self.splits,
            &self.codes,
            &self.params,
        )
    }

    pub(super) fn check_fingerprint(&self, got: u64) -> Result<(), DbError> {
        if got != self.fingerprint {
            return Err(DbError::ConfigMismatch {
                expected: self.fingerprint,
                got,
            });
        }
        Ok(())
    }

    /// The `k` nearest entries to the R-SOLiD `query_r` ([spec §3](crate::spec#3-comparing-descriptors)), nearest first, ties by lower
    /// id, skipping the `exclude_recent` most recent entries.
    ///
    /// # Errors
    /// [`DbError::Core`] for a query of the wrong length or with negative or non-finite values.
    pub fn search(
        &self,
        query_r: &[f32],
        k: usize,
        exclude_recent: usize,
        method: Method,
    ) -> Result<Vec<Neighbor>, DbError> {
        self.search_with(
            query_r,
            &SearchOptions {
                k,
                exclude_recent,
                method,
                ..SearchOptions::default()
            },
        )
    }

    /// [`Database::search`] for a descriptor, checking that it was made with this database's
    /// config.
    ///
    /// # Errors
    /// [`DbError::ConfigMismatch`] for another config; otherwise as [`Database::search`].
    pub fn search_descriptor(
        &self,
        d: &Descriptor,
        k: usize,
        exclude_recent: usize,
        method: Method,
    ) -> Result<Vec<Neighbor>, DbError> {
        self.check_fingerprint(d.fingerprint)?;
        self.search(&d.r, k, exclude_recent, method)
    }

    /// The general search: see [`SearchOptions`].
    ///
    /// # Errors
    /// [`DbError::Core`] for a query of the wrong length or with negative or non-finite values,
    /// a NaN `not_newer_than` (it would compare false with every time: no limit is `None`), or
    /// (name `max_distance`) a NaN bound.
    pub fn search_with(
        &self,
        query_r: &[f32],
        opts: &SearchOptions,
    ) -> Result<Vec<Neighbor>, DbError> {
        let mut q = vec![0.0f32; self.config.n_range];
        self.normalize_query(query_r, &mut q)?;
        let req = self.request(opts)?;
        let mut out = vec![Neighbor::default(); req.k];
        let found = self.index()?.search(&q, &req, &mut out)?;
        self.unindexed.add(self.unindexed_rows(&req));
        out.truncate(found.len);
        Ok(out)
    }

    /// The `k` nearest entries to each of the R-SOLiDs in `queries_r` (`m × n_range`,
    /// row-major), with the same options for all: the results of [`Database::search_with`] for
    /// every query, in one call. With the `parallel` feature the queries are shared among the
    /// threads of a persistent pool (rayon's), one per core.
    ///
    /// # Errors
    /// As [`Database::search_with`], for the first invalid query; [`Error::LengthMismatch`] when
    /// `queries_r` is not a whole number of R-SOLiDs; [`DbError::OutOfMemory`].
    pub fn search_batch(
        &self,
        queries_r: &[f32],
        opts: &SearchOptions,
    ) -> Result<BatchResults, DbError> {
        let nr = self.config.n_range;
        let m = queries_r.len() / nr;
        if m * nr != queries_r.len() {
            return Err(Error::LengthMismatch {
                what: "queries vs a multiple of n_range",
                left: queries_r.len(),
                right: m * nr,
            }
            .into());
        }
        let req = self.request(opts)?;
        let k = req.k;
        let index = self.index()?;
        let oom = |_| DbError::OutOfMemory;
        let mut normed = Vec::new();
        normed.try_reserve_exact(queries_r.len()).map_err(oom)?;
        normed.resize(queries_r.len(), 0.0);
        for (q, out) in queries_r.chunks_exact(nr).zip(normed.chunks_exact_mut(nr)) {
            self.normalize_query(q, out)?;
        }
        let mut ids = Vec::new();
        let mut distances = Vec::new();
        ids.try_reserve_exact(m * k).map_err(oom)?;
        distances.try_reserve_exact(m * k).map_err(oom)?;
        ids.resize(m * k, BatchResults::NONE);
        distances.resize(m * k, f32::INFINITY);
        let one = |q: &[f32],
                   ids: &mut [u32],
                   dists: &mut [f32],
                   scratch: &mut [Neighbor],
                   observed: &Observed| {
            let req = Request {
                observed: Some(observed),
                ..req
            };
            let found = index.search(q, &req, scratch)?;
            for (j, nb) in scratch[..found.len].iter().enumerate() {
                ids[j] = nb.id;
                dists[j] = nb.distance;
            }
            Ok::<(), Error>(())
        };
        if k > 0 {
            batch::run(&normed, nr, k, &mut ids, &mut distances, one)?;
            self.unindexed
                .add(self.unindexed_rows(&req).saturating_mul(m));
        }
        Ok(BatchResults { k, ids, distances })
    }

    /// The search request of `opts` over this database.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a NaN `not_newer_than` (it would compare false with every
    /// time: no limit is `None`).
    fn request(&self, opts: &SearchOptions) -> Result<Request<'_>, Error> {
        if let Some(t) = opts.not_newer_than.filter(|t| t.is_nan()) {
            return Err(Error::InvalidParameter {
                name: "not_newer_than",
                value: t,
                expected: "a time in seconds (or None for no limit), not NaN",
            });
        }
        let n = self.len();
        let exclude = Exclude {
            before_id: n.saturating_sub(opts.exclude_recent),
            not_newer_than: opts.not_newer_than.map(|t| (&self.timestamps[..], t)),
        };
        Ok(Request {
            k: opts.k.min(exclude.before_id),
            exclude,
            max_distance: opts.max_distance,
            plan: match opts.method {
                Method::Brute => Plan::Brute,
                Method::KdTree => Plan::KdTree,
                Method::Sketch => Plan::Sketch,
                Method::Auto => Plan::Auto,
            },
            observed: Some(&self.observed),
        })
    }

    /// `query_r` checked against the config and L2-normalised into `out`.
    fn normalize_query(&self, query_r: &[f32], out: &mut [f32]) -> Result<(), DbError> {
        let nr = self.config.n_range;
        if query_r.len() != nr {
            return Err(Error::LengthMismatch {
                what: "query r_solid vs config n_range",
                left: query_r.len(),
                right: nr,
            }
            .into());
        }
        check_bins("query r_solid", query_r)?;
        search::normalize(query_r, out)?;
        Ok(())
    }

    /// The cosine distance ([spec §3](crate::spec#3-comparing-descriptors)) from the R-SOLiD `query_r` to every entry, in id order
    /// (for plots and analysis; searches use [`Database::search`]): the distances the searches
    /// compute.
    ///
    /// # Errors
    /// [`DbError::Core`] for a query of the wrong length or with negative or non-finite values;
    /// [`DbError::OutOfMemory`] when the output cannot be allocated.
    pub fn distances(&self, query_r: &[f32]) -> Result<Vec<f32>, DbError> {
        let mut q = vec![0.0f32; self.config.n_range];
        self.normalize_query(query_r, &mut q)?;
        let mut out = Vec::new();
        out.try_reserve_exact(self.len())
            .map_err(|_| DbError::OutOfMemory)?;
        out.resize(self.len(), 0.0);
        self.rows()?.distances(&q, &mut out)?;
        Ok(out)
    }

    /// Appends every entry of `other` (ids shift by `self.len()`; sessions, times and poses kept).
    ///
    /// # Errors
    /// [`DbError::ConfigMismatch`] when the two configs differ; [`DbError::Full`] beyond
    /// `u32::MAX` entries; [`DbError::OutOfMemory`].
    pub fn merge(&mut self, other: &Database) -> Result<(), DbError> {
        self.check_fingerprint(other.fingerprint)?;
        if self.len() + other.len() >= u32::MAX as usize {
            return Err(DbError::Full);
        }
        let base = self.len();
        self.clouds.append(base, &other.clouds)?;
        if let Err(e) = self.reserve(other.len(), other.poses.len(), true) {
            self.clouds.truncate(base);
            return Err(e);
        }
        self.cut_sketch(self.sketched());
        self.sessions.extend_from_slice(&other.sessions);
        self.timestamps.extend_from_slice(&other.timestamps);
        self.poses
            .extend(other.poses.iter().map(|(id, p)| (id + base as u32, *p)));
        // The A-SOLiDs are copied as stored (already quantised), the R-SOLiDs sketched again.
        self.a_codes.extend_from_slice(&other.a_codes);
        self.a_scale.extend_from_slice(&other.a_scale);
        self.r.extend_from_slice(&other.r);
        self.r_scale.extend_from_slice(&other.r_scale);
        self.build_index()
    }

    /// [`Database::merge`], with the sessions of `other` renumbered to follow this database's
    /// (session `s` of `other` becomes `s + max(own sessions) + 1`): merging maps of separate
    /// runs keeps them apart. Returns the offset added.
    ///
    /// # Errors
    /// As [`Database::merge`]; [`DbError::Full`] when a renumbered session would exceed
    /// `u32::MAX`. On error nothing is changed.
    pub fn merge_as_new_sessions(&mut self, other: &Database) -> Result<u32, DbError> {
        let offset = match self.sessions.iter().max() {
            None => 0,
            Some(&m) => m.checked_add(1).ok_or(DbError::Full)?,
        };
        let top = other.sessions.iter().max().copied().unwrap_or(0);
        top.checked_add(offset).ok_or(DbError::Full)?;
        let start = self.len();
        self.merge(other)?;
        for s in &mut self.sessions[start..] {
            *s += offset;
        }
        Ok(offset)
    }

    /// All R-SOLiD vectors as added, row-major (`len() × n_range`).
    pub fn r_all(&self) -> &[f32] {
        &self.r
    }

    /// All A-SOLiD vectors as stored, row-major (`len() × n_azimuth`): see [`Database::a`].
    pub fn a_all(&self) -> Vec<f32> {
        let na = self.config.n_azimuth;
        let mut out = vec![0.0f32; self.a_codes.len()];
        for (i, row) in out.chunks_exact_mut(na).enumerate() {
            self.a_into(i as u32, row);
        }
        out
    }

    /// The R-SOLiD of entry `id`, as added.
    ///
    /// # Panics
    /// When `id >= len()`.
    pub fn r(&self, id: u32) -> &[f32] {
        let nr = self.config.n_range;
        &self.r[id as usize * nr..(id as usize + 1) * nr]
    }

    /// The A-SOLiD of entry `id` as stored: at 8 bits per value, `code × step` with one step
    /// per entry (the largest value / 255), so each value is within half a step (0.2 % of the
    /// entry's largest value) of the one added. Measured on hku1 (`tests/loop_eval.rs`): headings change by at most
    /// 0.06° and Recall@1 not at all.
    ///
    /// # Panics
    /// When `id >= len()`.
    pub fn a(&self, id: u32) -> Vec<f32> {
        let mut out = vec![0.0f32; self.config.n_azimuth];
        self.a_into(id, &mut out);
        out
    }

    /// The values of [`Database::a`], without allocating.
    ///
    /// # Panics
    /// When `id >= len()`.
    pub(super) fn a_values(&self, id: u32) -> impl Iterator<Item = f32> + '_ {
        let na = self.config.n_azimuth;
        let i = id as usize;
        dequantized(&self.a_codes[i * na..(i + 1) * na], self.a_scale[i])
    }

    /// [`Database::a`] into `out` (`n_azimuth` values).
    ///
    /// # Panics
    /// When `id >= len()` or `out` has another length.
    pub fn a_into(&self, id: u32, out: &mut [f32]) {
        let na = self.config.n_azimuth;
        let i = id as usize;
        dequantize_a(&self.a_codes[i * na..(i + 1) * na], self.a_scale[i], out);
    }

    /// The compact cloud stored with entry `id` for verification (the wire form of
    /// [`crate::reg::encode_cloud`]), if any.
    pub fn cloud(&self, id: u32) -> Option<&[u8]> {
        self.clouds.get(id as usize)
    }

    /// Whether any entry has a cloud.
    pub fn has_clouds(&self) -> bool {
        self.clouds.any()
    }

    /// Bytes of all stored clouds (their wire forms).
    pub fn cloud_bytes(&self) -> usize {
        self.clouds.data_len()
    }

    /// Number of entries that have a cloud.
    pub fn clouds_stored(&self) -> usize {
        self.clouds.count()
    }

    /// Per-entry sessions.
    pub fn sessions(&self) -> &[u32] {
        &self.sessions
    }

    /// Per-entry timestamps (NaN: none).
    pub fn timestamps(&self) -> &[f64] {
        &self.timestamps
    }

    /// The pose of entry `id` (row-major 3×4 `[R|t]`), if it was given one.
    pub fn pose(&self, id: u32) -> Option<[f64; 12]> {
        self.poses
            .binary_search_by_key(&id, |(i, _)| *i)
            .ok()
            .map(|at| self.poses[at].1)
    }

    /// Per-entry poses (row-major 3×4 `[R|t]`).
    pub fn poses(&self) -> Vec<Option<[f64; 12]>> {
        let mut out = vec![None; self.len()];
        for (id, p) in &self.poses {
            out[*id as usize] = Some(*p);
        }
        out
    }

    /// Bytes of memory the database holds (every buffer's capacity).
    pub fn memory_bytes(&self) -> usize {
        fn held<T>(v: &Vec<T>) -> usize {
            v.capacity() * core::mem::size_of::<T>()
        }
        held(&self.sessions)
            + held(&self.timestamps)
            + held(&self.poses)
            + held(&self.r)
            + held(&self.r_scale)
            + held(&self.a_codes)
            + held(&self.a_scale)
            + held(&self.perm)
            + held(&self.splits)
            + held(&self.codes)
            + held(&self.params)
            + self.clouds.heap_bytes()
    }

    /// Adds entries read from a file (checked by the reader): the vectors, sessions, timestamps
    /// poses and clouds by id; builds the index.
    pub(super) fn load_entries(
        &mut self,
        r: &[f32],
        a: &[f32],
        sessions: Vec<u32>,
        timestamps: Vec<f64>,
        poses: Vec<(u32, [f64; 12])>,
        clouds: Clouds,
    ) -> Result<(), DbError> {
        self.reserve(sessions.len(), 0, true)?;
        self.sessions = sessions;
        self.timestamps = timestamps;
        self.poses = poses;
        self.clouds = clouds;
        self.append_vectors(r, a)?;
        self.build_index()
    }
}

/// A count that searches (sharing `&Database`) add to: loaded and stored, not locked, as
/// [`Observed`]'s (two searches at once may lose one's rows, which only delays a build).
#[derive(Debug, Default)]
struct Tally(AtomicUsize);

impl Tally {
    fn get(&self) -> usize {
        self.0.load(Relaxed)
    }

    fn add(&self, rows: usize) {
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

/// Rows of a chunk that one task of [`Database::append_vectors`] or
/// [`Database::extend_sketch`] writes (a whole number of sketch blocks).
const CHUNK_ROWS: usize = 64 * SKETCH_BLOCK;

/// Runs `fill` on every chunk of a batch of `m` rows: shared among the pool's threads (with
/// `parallel`) from two chunks on, stopping at the first error.
fn in_chunks<I, F>(chunks: I, m: usize, fill: F) -> Result<(), Error>
where
    I: Iterator + Send,
    I::Item: Send,
    F: Fn(I::Item) -> Result<(), Error> + Sync + Send,
{
    #[cfg(feature = "parallel")]
    if let Some(threads) = (m >= 2 * CHUNK_ROWS).then(crate::pool::work).flatten() {
        use rayon::iter::{ParallelBridge, ParallelIterator};
        return threads.install(|| chunks.par_bridge().try_for_each(fill));
    }
    let _ = m;
    chunks.into_iter().try_for_each(fill)
}

/// The input rows of a chunk and where their scales and A-SOLiD codes go.
struct ChunkOut<'a> {
    r: &'a [f32],
    a: &'a [f32],
    scale: &'a mut [f32],
    a_codes: &'a mut [u8],
    a_scale: &'a mut [f32],
}

impl<'a> ChunkOut<'a> {
    /// The R-SOLiD scales and the quantised A-SOLiDs, checking every value (compiled for AVX2
    /// as well, which `std` picks when the CPU has it: the same operations, so the same bits).
    fn fill(&mut self, nr: usize, na: usize) -> Result<(), Error> {
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        if std::is_x86_feature_detected!("avx2") {
            #[allow(unsafe_code)]
            // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
            // calling a function compiled with `#[target_feature(enable = "avx2")]`.
            return unsafe { self.fill_avx2(nr, na) };
        }
        self.fill_dims(nr, na)
    }

    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[target_feature(enable = "avx2")]
    fn fill_avx2(&mut self, nr: usize, na: usize) -> Result<(), Error> {
        self.fill_dims(nr, na)
    }

    /// [`ChunkOut::fill_impl`], compiled a second time for the default dimensions (every
    /// preset's) as constants, so that the compiler unrolls each row's loops: the stored-only
    /// add of 10,000 HKU entries took 0.29 ms instead of 0.33 on one thread.
    #[inline(always)]
    fn fill_dims(&mut self, nr: usize, na: usize) -> Result<(), Error> {
        use crate::config::{DEFAULT_N_AZIMUTH, DEFAULT_N_RANGE};
        if (nr, na) == (DEFAULT_N_RANGE, DEFAULT_N_AZIMUTH) {
            self.fill_impl(DEFAULT_N_RANGE, DEFAULT_N_AZIMUTH)
        } else {
            self.fill_impl(nr, na)
        }
    }

    /// Rows at a time: first what each row needs (its sum of squares, its A-SOLiD's step), then
    /// the scales and codes from those, so that one row's chain of dependent operations (sums,
    /// maxima, a square root, divisions) overlaps the next rows' instead of holding up its own
    /// codes. With [`a_top`]'s one maximum of bits for three checks, the stored-only add of 10,000
    /// HKU entries took 0.29 ms instead of 0.43 on one thread, 0.18 instead of 0.25 on two
    /// (release probe, AMD EPYC), with the same bits.
    #[inline(always)]
    fn fill_impl(&mut self, nr: usize, na: usize) -> Result<(), Error> {
        const ROWS: usize = 64;
        for (rows, scales) in self.r.chunks(ROWS * nr).zip(self.scale.chunks_mut(ROWS)) {
            let mut sums = [0.0f64; ROWS];
            let sums = &mut sums[..scales.len()];
            // Four rows at a time, then one at a time.
            let mut groups = rows.chunks_exact(4 * nr);
            let mut out = sums.chunks_exact_mut(4);
            for (g, out) in (&mut groups).zip(&mut out) {
                let (r0, rest) = g.split_at(nr);
                let (r1, rest) = rest.split_at(nr);
                let (r2, r3) = rest.split_at(nr);
                out.copy_from_slice(&search::square_sums([r0, r1, r2, r3]));
            }
            for (row, out) in groups
                .remainder()
                .chunks_exact(nr)
                .zip(out.into_remainder())
            {
                *out = search::square_sums([row])[0];
            }
            // A non-finite value makes its row's sum non-finite; negative ones are looked for
            // without a branch per value. Either way `check_bins` names the first bad value.
            let bad = rows.iter().fold(false, |neg, &x| neg | (x < 0.0));
            if bad || !sums.iter().all(|s| s.is_finite()) {
                for row in rows.chunks_exact(nr) {
                    check_bins("r_solid", row)?;
                }
            }
            for (scale, &sum) in scales.iter_mut().zip(sums.iter()) {
                *scale = search::norm_scale(sum);
            }
        }
        for ((rows, codes), steps) in self
            .a
            .chunks(ROWS * na)
            .zip(self.a_codes.chunks_mut(ROWS * na))
            .zip(self.a_scale.chunks_mut(ROWS))
        {
            // The largest values first, then the steps and their inverses in a loop of their own
            // (which the compiler vectorises), then the codes.
            let (mut top, mut inv) = ([0.0f32; ROWS], [0.0f32; ROWS]);
            for (row, top) in rows.chunks_exact(na).zip(&mut top) {
                // `a_top` refuses exactly what `check_bins` names.
                *top = a_top(row).map_or_else(|| check_bins("a_solid", row).map(|()| 0.0), Ok)?;
            }
            for ((step, inv), &top) in steps.iter_mut().zip(&mut inv).zip(&top) {
                *step = a_step(top);
                *inv = inverse_step(*step);
            }
            for ((row, codes), &inv) in rows
                .chunks_exact(na)
                .zip(codes.chunks_exact_mut(na))
                .zip(&inv)
            {
                quantize_a_with(row, inv, codes);
            }
        }
        Ok(())
    }
}

/// Quantises one A-SOLiD to 8 bits per value into `codes`; returns its step (see
/// [`Database::a`]): `max / 255`, codes rounded half up; `None` when a value is negative or not
/// finite (what descriptors never hold, SPEC §3).
#[cfg(test)]
fn quantize_a(a: &[f32], codes: &mut [u8]) -> Option<f32> {
    let step = a_step(a_top(a)?);
    quantize_a_with(a, inverse_step(step), codes);
    Some(step)
}

/// The largest value of an A-SOLiD (at least `+0.0`); `None` when a value is negative or not
/// finite. Found on the values' bits, read as `u32`: those of non-negative finite values are in
/// the order of the values and below infinity's, and those of every negative value (but `-0.0`,
/// read as `+0.0`), infinity and NaN are at or above infinity's; so one maximum, in eight lanes,
/// both finds the largest value and checks them all. A last group of eight overlaps the one
/// before (which changes no maximum) instead of a tail of single values.
#[inline(always)]
fn a_top(a: &[f32]) -> Option<f32> {
    const NEGATIVE_ZERO: u32 = 0x8000_0000;
    let mut top = [0u32; 8];
    let mut take = |group: &[f32]| {
        for (t, &v) in top.iter_mut().zip(group) {
            let bits = v.to_bits();
            *t = (*t).max(if bits == NEGATIVE_ZERO { 0 } else { bits });
        }
    };
    if a.len() >= 8 {
        let groups = a.chunks_exact(8);
        let tail = !groups.remainder().is_empty();
        groups.for_each(&mut take);
        if tail {
            take(&a[a.len() - 8..]);
        }
    } else {
        // Zeros change no maximum.
        let mut padded = [0.0f32; 8];
        padded[..a.len()].copy_from_slice(a);
        take(&padded);
    }
    let top = top.iter().fold(0, |m, &t| m.max(t));
    (top < f32::INFINITY.to_bits()).then(|| f32::from_bits(top))
}

/// The step of the 8-bit codes of an A-SOLiD whose largest value is `top` (see
/// [`Database::a`]): `top / 255`; its values are quantised by [`quantize_a_with`].
#[inline(always)]
fn a_step(top: f32) -> f32 {
    top / 255.0
}

/// The codes of an A-SOLiD, given [`inverse_step`] of its [`a_step`]: rounded half up, saturated
/// into `0..=255`.
#[inline(always)]
fn quantize_a_with(a: &[f32], inv: f32, codes: &mut [u8]) {
    for (c, &v) in codes.iter_mut().zip(a) {
        *c = crate::math::to_u8(v * inv + 0.5);
    }
}

/// The values of a quantised A-SOLiD (see [`a_step`]).
fn dequantize_a(codes: &[u8], step: f32, out: &mut [f32]) {
    for (o, v) in out.iter_mut().zip(dequantized(codes, step)) {
        *o = v;
    }
}

/// The values of quantised A-SOLiD codes, without allocating.
fn dequantized(codes: &[u8], step: f32) -> impl Iterator<Item = f32> + '_ {
    codes.iter().map(move |&c| f32::from(c) * step)
}

/// Checks that a descriptor vector holds what descriptors hold: finite, non-negative values
/// (SPEC §3; the cosine distance is in [0, 1] only for those).
fn check_bins(name: &'static str, v: &[f32]) -> Result<(), Error> {
    match v.iter().find(|x| !super::format::is_bin_value(**x)) {
        Some(bad) => Err(Error::InvalidParameter {
            name,
            value: f64::from(*bad),
            expected: "finite, non-negative values",
        }),
        None => Ok(()),
    }
}

/// The worker side of [`Database::search_batch`].
mod batch {
    use super::{Error, Neighbor, Observed};
    use alloc::vec;

    /// Queries handed to a worker at a time (small enough to balance, large enough to amortise).
    const CHUNK: usize = 16;

    /// Runs `one` for every query (`queries`: rows of `dim`), writing `k` slots per query. Each
    /// worker keeps its own [`Observed`] for the queries it takes (runs of consecutive queries):
    /// shared, the record of two workers on queries of different kinds would undo each other.
    pub(super) fn run<F>(
        queries: &[f32],
        dim: usize,
        k: usize,
        ids: &mut [u32],
        dists: &mut [f32],
        one: F,
    ) -> Result<(), Error>
    where
        F: Fn(&[f32], &mut [u32], &mut [f32], &mut [Neighbor], &Observed) -> Result<(), Error>
            + Sync,
    {
        let chunk = |observed: &mut Observed,
                     (q, (ids, dists)): (&[f32], (&mut [u32], &mut [f32]))| {
            let mut scratch = vec![Neighbor::default(); k];
            for ((q, ids), dists) in q
                .chunks_exact(dim)
                .zip(ids.chunks_exact_mut(k))
                .zip(dists.chunks_exact_mut(k))
            {
                one(q, ids, dists, &mut scratch, observed)?;
            }
            Ok(())
        };
        let parts = queries
            .chunks(CHUNK * dim)
            .zip(ids.chunks_mut(CHUNK * k).zip(dists.chunks_mut(CHUNK * k)));
        #[cfg(feature = "parallel")]
        if let Some(threads) = crate::pool::work() {
            use rayon::prelude::*;
            let parts: alloc::vec::Vec<_> = parts.collect();
            return threads.install(|| {
                parts
                    .into_par_iter()
                    .try_for_each_init(Observed::timed, chunk)
            });
        }
        let mut observed = Observed::timed();
        parts
            .into_iter()
            .try_for_each(|part| chunk(&mut observed, part))
    }
}

/// Checks a row-major 3×4 `[R|t]`: finite, and R a rotation (orthonormal, determinant +1, to
/// 1e-3).
///
/// # Errors
/// [`Error::InvalidParameter`] (name `pose`) otherwise.
pub fn check_pose(p: &[f64; 12]) -> Result<(), Error> {
    if let Some(bad) = p.iter().find(|v| !v.is_finite()) {
        return Err(Error::InvalidParameter {
            name: "pose",
            value: *bad,
            expected: "finite values",
        });
    }
    let r = |i: usize, j: usize| p[4 * i + j];
    let mut worst = 0.0f64;
    for i in 0..3 {
        for j in 0..3 {
            let dot: f64 = (0..3).map(|k| r(k, i) * r(k, j)).sum();
            let want = if i == j { 1.0 } else { 0.0 };
            worst = worst.max((dot - want).abs());
        }
    }
    let det = r(0, 0) * (r(1, 1) * r(2, 2) - r(1, 2) * r(2, 1))
        - r(0, 1) * (r(1, 0) * r(2, 2) - r(1, 2) * r(2, 0))
        + r(0, 2) * (r(1, 0) * r(2, 1) - r(1, 1) * r(2, 0));
    if worst > 1e-3 || det < 0.0 {
        return Err(Error::InvalidParameter {
            name: "pose",
            value: worst.max((det - 1.0).abs()),
            expected: "a rotation in the 3x3 part (orthonormal, determinant +1, to 1e-3)",
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{dequantize_a, quantize_a};
    use crate::math::XorShift32;

    /// The AVX2 copy of the checks and quantisation of a bulk add gives the portable copy's
    /// bits (scales, A-SOLiD codes and steps), and the same error for a bad value.
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[test]
    fn avx2_fill_gives_the_portable_bits() {
        use super::ChunkOut;
        if !std::is_x86_feature_detected!("avx2") {
            eprintln!("no AVX2 on this CPU: nothing to compare");
            return;
        }
        let (nr, na, n) = (40, 60, 37);
        let mut rng = XorShift32(0x2545_f491);
        let mut next = move || (rng.next_u32() % 100_000) as f32 * 1e-2;
        let mut r: Vec<f32> = (0..n * nr).map(|_| next()).collect();
        let mut a: Vec<f32> = (0..n * na).map(|_| next()).collect();
        r[3 * nr..4 * nr].fill(0.0);
        a[5 * na..6 * na].fill(0.0);
        a[7 * na + 2] = 1e-40;
        let run = |r: &[f32], a: &[f32], avx2: bool| {
            let (mut scale, mut codes, mut step) = (vec![9.0; n], vec![9u8; n * na], vec![9.0; n]);
            let mut out = ChunkOut {
                r,
                a,
                scale: &mut scale,
                a_codes: &mut codes,
                a_scale: &mut step,
            };
            let res = if avx2 {
                out.fill(nr, na)
            } else {
                out.fill_impl(nr, na)
            };
            let bits = |v: &[f32]| v.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            (
                res.map_err(|e| e.to_string()),
                bits(&scale),
                codes,
                bits(&step),
            )
        };
        assert_eq!(run(&r, &a, true), run(&r, &a, false));
        r[9 * nr + 1] = -1.0;
        let bad = run(&r, &a, true);
        assert!(bad.0.is_err());
        assert_eq!(bad.0, run(&r, &a, false).0);
    }

    /// A bulk add gives each row what the one-row functions give it alone, whatever the
    /// number of rows (every remainder of the groups of four and the blocks of 64) and the
    /// dimensions (the defaults, compiled as constants, and others).
    #[test]
    fn fill_gives_every_row_what_it_gets_alone() {
        use super::ChunkOut;
        use crate::search::inverse_norm;
        let mut rng = XorShift32(0x9e37_79b9);
        let mut next = move || {
            // Zeros one time in eight, then values over six orders of magnitude.
            let x = rng.next_u32();
            if x.is_multiple_of(8) {
                0.0
            } else {
                (x % 1_000_000) as f32 * 1e-3
            }
        };
        for (nr, na) in [(40, 60), (7, 5), (13, 17), (1, 1)] {
            for n in (1..=70).chain([127, 128, 129, 200]) {
                let r: Vec<f32> = (0..n * nr).map(|_| next()).collect();
                let a: Vec<f32> = (0..n * na).map(|_| next()).collect();
                let (mut scale, mut codes, mut step) =
                    (vec![9.0; n], vec![9u8; n * na], vec![9.0; n]);
                ChunkOut {
                    r: &r,
                    a: &a,
                    scale: &mut scale,
                    a_codes: &mut codes,
                    a_scale: &mut step,
                }
                .fill(nr, na)
                .unwrap();
                for i in 0..n {
                    let row = &r[i * nr..(i + 1) * nr];
                    let at = format!("row {i} of {n} ({nr}, {na})");
                    assert_eq!(
                        scale[i].to_bits(),
                        inverse_norm(row).unwrap().to_bits(),
                        "{at}"
                    );
                    let mut alone = vec![0u8; na];
                    let s = quantize_a(&a[i * na..(i + 1) * na], &mut alone).unwrap();
                    assert_eq!(step[i].to_bits(), s.to_bits(), "{at}");
                    assert_eq!(codes[i * na..(i + 1) * na], alone[..], "{at}");
                }
            }
        }
    }

    /// A bulk add with bad values names the first bad value of the first bad R-SOLiD row, and of
    /// the first bad A-SOLiD row only when every R-SOLiD is good: across groups of four rows and
    /// blocks of 64, and within a row.
    #[test]
    fn fill_names_the_first_bad_value() {
        use super::{ChunkOut, Error};
        let (nr, na, n) = (40, 60, 140);
        let named = |r: &[f32], a: &[f32]| {
            let (mut scale, mut codes, mut step) = (vec![0.0; n], vec![0u8; n * na], vec![0.0; n]);
            let out = ChunkOut {
                r,
                a,
                scale: &mut scale,
                a_codes: &mut codes,
                a_scale: &mut step,
            }
            .fill(nr, na);
            match out {
                Err(Error::InvalidParameter { name, value, .. }) => (name, value.to_bits()),
                other => panic!("expected a bad value, got {other:?}"),
            }
        };
        let bits = |v: f32| f64::from(v).to_bits();
        let (mut r, mut a) = (vec![0.5f32; n * nr], vec![0.5f32; n * na]);
        a[3 * na + 7] = -7.0;
        a[2 * na + 59] = f32::INFINITY;
        assert_eq!(named(&r, &a), ("a_solid", bits(f32::INFINITY)));
        r[70 * nr + 1] = f32::NAN;
        assert!(f64::from_bits(named(&r, &a).1).is_nan());
        r[129 * nr + 39] = -1.0;
        r[66 * nr + 5] = -2.0;
        r[66 * nr + 9] = f32::NEG_INFINITY;
        assert_eq!(named(&r, &a), ("r_solid", bits(-2.0)));
        r[66 * nr + 2] = f32::INFINITY;
        assert_eq!(named(&r, &a), ("r_solid", bits(f32::INFINITY)));
        r[1] = -1e-45;
        assert_eq!(named(&r, &a), ("r_solid", bits(-1e-45)));
    }

    /// `a_top` (a maximum of bits) is the largest value, or refuses what is negative or not
    /// finite, as comparisons of the values say, for every length (under eight: padded).
    #[test]
    fn a_top_is_the_largest_value_of_finite_non_negative_values() {
        let special = [
            0.0,
            -0.0,
            f32::MIN_POSITIVE,
            1e-45,
            -1e-45,
            1.0,
            -1.0,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
            f32::from_bits(0x7f80_0001),
            3.5,
        ];
        let mut rng = XorShift32(0x2545_f491);
        for len in 1..=20 {
            for _ in 0..200 {
                let a: Vec<f32> = (0..len)
                    .map(|_| {
                        let x = rng.next_u32();
                        if x.is_multiple_of(4) {
                            special[(x / 4) as usize % special.len()]
                        } else {
                            (x % 1000) as f32 * 0.25
                        }
                    })
                    .collect();
                let valid = a.iter().all(|v| v.is_finite() && *v >= 0.0);
                let top = a.iter().fold(0.0f32, |m, &v| if v > m { v } else { m });
                let want = valid.then_some(top.to_bits());
                assert_eq!(super::a_top(&a).map(f32::to_bits), want, "{a:?}");
            }
        }
    }

    #[test]
    fn quantising_what_was_dequantised_gives_the_same_codes_and_step() {
        // A database saved, loaded and saved again writes the same bytes (the fuzz target
        // db_from_bytes relies on it): largest values from subnormal to 1e37.
        let mut rng = XorShift32(0x2545_f491);
        for i in 0..4000 {
            let x = rng.next_u32();
            let top = if i % 10 == 0 {
                f32::from_bits(1 + x % 0x0080_0000)
            } else {
                (1.0 + (x % 1_000_000) as f32 / 1e6) * 10f32.powi(i % 75 - 38)
            };
            let a: [f32; 6] = [top, 0.5 * top, 0.0, 0.25 * top, 0.7 * top, 0.1 * top];
            let mut codes = [0u8; 6];
            let step = quantize_a(&a, &mut codes).unwrap();
            let mut values = [0.0f32; 6];
            dequantize_a(&codes, step, &mut values);
            let mut again = [0u8; 6];
            assert_eq!(quantize_a(&values, &mut again), Some(step), "top {top}");
            assert_eq!(again, codes, "top {top}");
            // Within half a step, but for subnormal steps (1 / step overflows).
            if top >= 1e-30 {
                for (v, w) in values.iter().zip(&a) {
                    assert!((v - w).abs() <= 0.5 * step * 1.0001, "{v} vs {w}");
                }
            }
        }
    }
}
