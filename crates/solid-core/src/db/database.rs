//! [`Database`]: the entries and their exact search.
//!
//! Per entry without a pose the database holds the R-SOLiD as added (`4·n_range` bytes) and the
//! scale that normalises it (4), the search sketch (`n_range` bytes and 12), the kd-tree (6), the
//! session (4), the timestamp (8) and the A-SOLiD at 8 bits with its scale (`n_azimuth` + 4);
//! entries added by [`Database::add_batch`] without `index` hold no sketch or kd-tree until
//! [`Database::build_index`], and a loaded map's index has no sketch ([`Database::set_sketch`]). A
//! pose costs 104 bytes (60 as a loaded quaternion) for the entries that have one (`memory_bytes`
//! counts them all; sizes for the presets: docs/performance.md#database). Large columns ask for
//! transparent huge pages on Linux (see `room`).

mod fill;
mod index;
mod pose_store;
mod query;

pub use index::INDEX_AFTER_PASSES;
pub use query::{BatchResults, SearchOptions};

use alloc::borrow::Cow;
use alloc::vec;
use alloc::vec::Vec;

use super::clouds::Clouds;
use super::room;
use super::DbError;
use crate::search::Observed;
use crate::{Config, Descriptor, Error};
use fill::{dequantize_a, dequantized, in_chunks, ChunkOut, CHUNK_ROWS};
use index::Tally;
pub(super) use pose_store::PoseStore;

/// A database of places, searchable exactly at every size (see the module documentation).
#[derive(Debug, Clone)]
pub struct Database {
    pub(super) config: Config,
    pub(super) fingerprint: u64,
    pub(super) sessions: Vec<u32>,
    pub(super) timestamps: Vec<f64>,
    /// The poses of the entries that have one.
    poses: PoseStore,
    /// R-SOLiDs as added, row-major.
    r: Vec<f32>,
    /// Per entry, `1 / ‖r‖` ([`crate::search::inverse_norm`]): the search compares `r × scale`.
    r_scale: Vec<f32>,
    /// A-SOLiDs at 8 bits per value (see [`Database::a`]).
    a_codes: Vec<u8>,
    /// Per entry, the A-SOLiD's step (see [`Database::a`]).
    a_scale: Vec<f32>,
    /// The online kd-tree over ids `0..perm.len()` (a prefix: a bulk add may leave it behind
    /// until [`Database::build_index`]).
    perm: Vec<u32>,
    splits: Vec<u16>,
    /// The search sketch of the entries `0..sketched()` ([`crate::search::Sketch`]; a prefix of whole
    /// blocks, or every entry, as [`Index::new`](crate::search::Index::new) reads it).
    codes: Vec<u8>,
    params: Vec<f32>,
    /// Whether the index includes the sketch ([`Database::set_sketch`]): a new database's does, a
    /// loaded map's does not.
    sketch: bool,
    /// What the automatic search has seen on this database's queries.
    observed: Observed,
    /// Rows the searches scanned by brute force only because they were beyond the index, since
    /// it last covered every entry ([`Database::index_due`]).
    unindexed: Tally,
    /// Whether the searches build the index when it is due ([`super::IndexPolicy::BySearches`]).
    pub(super) index_by_searches: bool,
    /// The compact clouds of the entries that have one (for verification).
    pub(super) clouds: Clouds,
    /// See [`Database::metadata`].
    pub(super) metadata: alloc::string::String,
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
            poses: PoseStore::default(),
            r: Vec::new(),
            r_scale: Vec::new(),
            a_codes: Vec::new(),
            a_scale: Vec::new(),
            perm: Vec::new(),
            splits: Vec::new(),
            codes: Vec::new(),
            params: Vec::new(),
            sketch: true,
            observed: Observed::timed(),
            unindexed: Tally::default(),
            index_by_searches: false,
            clouds: Clouds::default(),
            metadata: alloc::string::String::new(),
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
    /// As [`Database::add`], and [`DbError::Format`] when [`crate::reg::check_cloud`] refuses
    /// the cloud (a corrupt cloud is never stored); on error nothing is added.
    pub fn add_with_cloud(
        &mut self,
        d: &Descriptor,
        session: u32,
        timestamp: f64,
        pose: Option<[f64; 12]>,
        cloud: Option<&[u8]>,
    ) -> Result<u32, DbError> {
        self.check_fingerprint(d.fingerprint)?;
        if let Some(Err(e)) = cloud.filter(|c| !c.is_empty()).map(crate::reg::check_cloud) {
            return Err(DbError::Format {
                file: None,
                reason: alloc::format!("the cloud given with the place is invalid: {e}"),
            });
        }
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
        super::same_len("r_solid vs config n_range", r.len(), nr)?;
        super::same_len("a_solid vs config n_azimuth", a.len(), na)?;
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
        let expect = super::same_len;
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
        check_session(session)?;
        let first = self.len();
        if first + m >= entry_limit() {
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
            for (i, p) in p.iter().enumerate() {
                self.poses.push((first + i) as u32, *p);
            }
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
        self.poses
            .try_reserve(with_pose)
            .map_err(|()| DbError::OutOfMemory)?;
        room::reserve(&mut self.r, m * nr).map_err(oom)?;
        room::reserve(&mut self.r_scale, m).map_err(oom)?;
        room::reserve(&mut self.a_codes, m * na).map_err(oom)?;
        room::reserve(&mut self.a_scale, m).map_err(oom)?;
        if index {
            self.reserve_index(self.len() + m)?;
        }
        Ok(())
    }

    /// Appends vectors (room reserved), checking them on the way: the raw R-SOLiDs and their
    /// scales ([`crate::search::inverse_norm`]) and the quantised A-SOLiDs, written in place into the
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

    /// What [`Database::add_vectors`] checks of one descriptor's vectors, without adding them:
    /// their lengths and values (finite, non-negative).
    ///
    /// # Errors
    /// As [`Database::add_vectors`] for the vectors.
    pub(crate) fn check_vectors(&self, r: &[f32], a: &[f32]) -> Result<(), DbError> {
        super::same_len("r_solid vs config n_range", r.len(), self.config.n_range)?;
        super::same_len(
            "a_solid vs config n_azimuth",
            a.len(),
            self.config.n_azimuth,
        )?;
        check_bins("r_solid", r)?;
        check_bins("a_solid", a)?;
        Ok(())
    }

    pub(crate) fn check_fingerprint(&self, got: u64) -> Result<(), DbError> {
        if got != self.fingerprint {
            return Err(DbError::ConfigMismatch {
                expected: self.fingerprint,
                got,
            });
        }
        Ok(())
    }
    /// Appends every entry of `other` (ids shift by `self.len()`; sessions, times and poses kept).
    ///
    /// # Errors
    /// [`DbError::ConfigMismatch`] when the two configs differ; [`DbError::Full`] beyond
    /// `u32::MAX` entries; [`DbError::OutOfMemory`].
    pub fn merge(&mut self, other: &Database) -> Result<(), DbError> {
        self.merge_with(other, false, None).map(|_| ())
    }

    /// [`Database::merge`], with the sessions of `other` renumbered to follow this database's
    /// (session `s` of `other` becomes `s + max(own sessions) + 1`): merging maps of separate
    /// runs keeps them apart. Returns the offset added.
    ///
    /// # Errors
    /// As [`Database::merge`]; [`DbError::Full`] when a renumbered session would exceed
    /// `u32::MAX`. On error nothing is changed.
    pub fn merge_as_new_sessions(&mut self, other: &Database) -> Result<u32, DbError> {
        self.merge_with(other, true, None)
    }

    /// [`Database::merge`] or, with `new_sessions`, [`Database::merge_as_new_sessions`], with
    /// every pose of `other` carried into this map's world by `anchor` (row-major 3×4
    /// `T_map_other`, `X ↦ T·X`) when given: a run's map anchored to another's (`solid map merge
    /// --anchor`). `other` is not changed. Returns the sessions' offset (0 without
    /// `new_sessions`).
    ///
    /// # Errors
    /// As [`Database::merge_as_new_sessions`]; [`Error::InvalidParameter`] (name `anchor`) when
    /// `anchor` is not finite or not a rotation. On error nothing is changed.
    pub fn merge_with(
        &mut self,
        other: &Database,
        new_sessions: bool,
        anchor: Option<&[f64; 12]>,
    ) -> Result<u32, DbError> {
        self.merge_anchored(other, new_sessions, anchor.map(MergeAnchor::All))
    }

    /// [`Database::merge_with`], the poses of `other` carried by `anchor`: one transform for
    /// every place, or one per place ([`MergeAnchor::PerPlace`]: a session whose odometry broke
    /// has one anchor per stretch between breaks, or a trajectory optimised into the map one per
    /// frame; a place with none keeps no pose). Returns the sessions' offset.
    ///
    /// # Errors
    /// As [`Database::merge_with`] for one transform; for one per place,
    /// [`DbError::AnchorCount`] (both counts) when the list does not hold one entry per place of
    /// `other`, [`DbError::BadAnchor`] (the place's id) when one is not finite or not a rotation.
    /// On error nothing is changed.
    pub fn merge_anchored(
        &mut self,
        other: &Database,
        new_sessions: bool,
        anchor: Option<MergeAnchor<'_>>,
    ) -> Result<u32, DbError> {
        self.check_fingerprint(other.fingerprint)?;
        let named = |e: Error| match e {
            Error::InvalidParameter {
                value, expected, ..
            } => Error::InvalidParameter {
                name: "anchor",
                value,
                expected,
            },
            e => e,
        };
        match anchor {
            Some(MergeAnchor::All(t)) => check_pose(t).map_err(named)?,
            Some(MergeAnchor::PerPlace(ts)) => {
                if ts.len() != other.len() {
                    return Err(DbError::AnchorCount {
                        given: ts.len(),
                        places: other.len(),
                    });
                }
                for (place, t) in ts.iter().enumerate() {
                    if let Some(t) = t {
                        check_pose(t).map_err(|e| DbError::BadAnchor {
                            place,
                            error: named(e),
                        })?;
                    }
                }
            }
            None => {}
        }
        if self.len() + other.len() >= entry_limit() {
            return Err(DbError::Full);
        }
        let offset = match self.sessions.iter().max() {
            Some(&m) if new_sessions => m.checked_add(1).ok_or(DbError::Full)?,
            _ => 0,
        };
        let top = other.sessions.iter().max().copied().unwrap_or(0);
        top.checked_add(offset)
            .filter(|&s| s != NO_SESSION)
            .ok_or(DbError::Full)?;
        let base = self.len();
        self.clouds.append(base, &other.clouds)?;
        let reserved = self.reserve(other.len(), 0, true).and_then(|()| {
            let moved = anchor.is_some();
            (self.poses.reserve_for(&other.poses, moved)).map_err(|()| DbError::OutOfMemory)
        });
        if let Err(e) = reserved {
            self.clouds.truncate(base);
            return Err(e);
        }
        self.cut_sketch(self.sketched());
        self.sessions
            .extend(other.sessions.iter().map(|s| s + offset));
        self.timestamps.extend_from_slice(&other.timestamps);
        let carry = anchor.map(|a| {
            move |id: u32, p: &[f64; 12]| match a {
                MergeAnchor::All(t) => Some(compose(t, p)),
                MergeAnchor::PerPlace(ts) => ts[id as usize].as_ref().map(|t| compose(t, p)),
            }
        });
        let moved = carry.as_ref().map(|f| f as pose_store::Move<'_>);
        self.poses.append(&other.poses, base as u32, moved);
        // The A-SOLiDs are copied as stored (already quantised), the R-SOLiDs sketched again.
        self.a_codes.extend_from_slice(&other.a_codes);
        self.a_scale.extend_from_slice(&other.a_scale);
        self.r.extend_from_slice(&other.r);
        self.r_scale.extend_from_slice(&other.r_scale);
        self.build_index()?;
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
    /// entry's largest value) of the one added: too little to change a heading or a match
    /// (docs/performance.md#database).
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
    /// [`crate::reg::encode_cloud`]), if any, its checksum checked ([`crate::reg::check_cloud`])
    /// each time it is read: a corrupt cloud is never handed out, nor is a cloud that cannot be
    /// read taken for none. A database loaded from a file in format version 3 or 4 reads it from
    /// the file now (clouds on demand).
    ///
    /// # Errors
    /// [`DbError::Format`] naming the place (and the file it is read from) when its cloud is
    /// corrupt; [`DbError::Changed`] naming the file when it was truncated or written since it
    /// was loaded; [`DbError::Io`] when the file cannot be read.
    pub fn cloud(&self, id: u32) -> Result<Option<Cow<'_, [u8]>>, DbError> {
        self.clouds.get(id as usize)
    }

    /// [`Database::cloud`] (its former name, when `cloud` gave `None` for an unreadable cloud).
    ///
    /// # Errors
    /// As [`Database::cloud`].
    pub fn try_cloud(&self, id: u32) -> Result<Option<Cow<'_, [u8]>>, DbError> {
        self.clouds.get(id as usize)
    }

    /// Free-form text stored with the database, such as how its scans were clipped (empty:
    /// none). Saved in format versions 3 and 4 only.
    pub fn metadata(&self) -> &str {
        &self.metadata
    }

    /// Sets [`Database::metadata`] (at most [`super::format::MAX_METADATA`] bytes).
    ///
    /// # Errors
    /// [`DbError::Core`] with [`Error::InvalidParameter`] when it is longer.
    pub fn set_metadata(&mut self, text: &str) -> Result<(), DbError> {
        if text.len() > super::format::MAX_METADATA {
            return Err(Error::InvalidParameter {
                name: "metadata",
                value: text.len() as f64,
                expected: "at most 1 MiB of text",
            }
            .into());
        }
        let mut m = alloc::string::String::new();
        m.try_reserve_exact(text.len())
            .map_err(|_| DbError::OutOfMemory)?;
        m.push_str(text);
        self.metadata = m;
        Ok(())
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

    /// Number of entries that have a pose.
    pub fn poses_stored(&self) -> usize {
        self.poses.len()
    }

    /// Per entry, the scale of its R-SOLiD (see [`Database::r`]).
    pub(super) fn r_scales(&self) -> &[f32] {
        &self.r_scale
    }

    /// The A-SOLiDs' 8-bit codes, row-major (see [`Database::a`]).
    pub(super) fn a_codes(&self) -> &[u8] {
        &self.a_codes
    }

    /// Per entry, the A-SOLiD's step (see [`Database::a`]).
    pub(super) fn a_steps(&self) -> &[f32] {
        &self.a_scale
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
        self.poses.get(id)
    }

    /// The entries with a pose and their poses (row-major 3×4 `[R|t]`), in no set order.
    pub(crate) fn each_pose(&self) -> impl Iterator<Item = (u32, [f64; 12])> + '_ {
        self.poses.each()
    }

    /// Per-entry poses (row-major 3×4 `[R|t]`).
    pub fn poses(&self) -> Vec<Option<[f64; 12]>> {
        let mut out = vec![None; self.len()];
        for (id, p) in self.each_pose() {
            out[id as usize] = Some(p);
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
            + self.poses.heap_bytes()
            + held(&self.r)
            + held(&self.r_scale)
            + held(&self.a_codes)
            + held(&self.a_scale)
            + held(&self.perm)
            + held(&self.splits)
            + held(&self.codes)
            + held(&self.params)
            + self.clouds.heap_bytes()
            + self.metadata.capacity()
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
        self.set_sketch(false);
        self.reserve(sessions.len(), 0, true)?;
        self.sessions = sessions;
        self.timestamps = timestamps;
        self.poses = PoseStore::from_full(poses);
        self.clouds = clouds;
        self.append_vectors(r, a)?;
        self.build_index()
    }
}

/// The columns of a file in format version 3 or 4, as the database holds them (see
/// [`Database::load_columns`]).
pub(super) struct Columns {
    pub(super) sessions: Vec<u32>,
    pub(super) timestamps: Vec<f64>,
    pub(super) poses: PoseStore,
    pub(super) r: Vec<f32>,
    pub(super) r_scale: Vec<f32>,
    pub(super) a_codes: Vec<u8>,
    pub(super) a_scale: Vec<f32>,
    pub(super) clouds: Clouds,
    pub(super) metadata: alloc::string::String,
}

impl Database {
    /// Takes the columns read from a file (checked by the reader, but for the R-SOLiDs: each
    /// value a bin can hold, each scale the one [`crate::search::inverse_norm`] gives, to the
    /// bit); leaves the index to the searches ([`super::IndexPolicy::BySearches`]). Returns the
    /// entry of the first bad R-SOLiD and what is wrong.
    pub(super) fn load_columns(
        &mut self,
        c: Columns,
    ) -> Result<Result<(), (usize, &'static str)>, DbError> {
        let nr = self.config.n_range;
        let bad_row = |row: &[f32], scale: f32| {
            if !row.iter().all(|v| super::format::is_bin_value(*v)) {
                return Some("negative or non-finite value in its R-SOLiD");
            }
            match crate::search::inverse_norm(row) {
                Ok(want) if want.to_bits() == scale.to_bits() => None,
                _ => Some("its stored R-SOLiD norm does not match its values"),
            }
        };
        // In chunks on every core; the first bad entry is looked for only when there is one.
        let chunks =
            c.r.chunks(CHUNK_ROWS * nr)
                .zip(c.r_scale.chunks(CHUNK_ROWS));
        let checked = in_chunks(chunks, c.r_scale.len(), |(rows, scales)| {
            let bad = rows
                .chunks_exact(nr)
                .zip(scales)
                .any(|(r, &s)| bad_row(r, s).is_some());
            if bad {
                Err(Error::Empty { what: "r_solid" })
            } else {
                Ok(())
            }
        });
        if checked.is_err() {
            for (i, (row, &scale)) in c.r.chunks_exact(nr).zip(&c.r_scale).enumerate() {
                if let Some(why) = bad_row(row, scale) {
                    return Ok(Err((i, why)));
                }
            }
        }
        self.sessions = c.sessions;
        self.timestamps = c.timestamps;
        self.poses = c.poses;
        self.r = c.r;
        self.r_scale = c.r_scale;
        self.a_codes = c.a_codes;
        self.a_scale = c.a_scale;
        self.clouds = c.clouds;
        self.metadata = c.metadata;
        self.set_sketch(false);
        // As after a bulk add: the searches build the index once they have paid for it, a
        // detector at its start; a map opened to be summed up, merged or saved never builds it.
        self.index_by_searches = true;
        Ok(Ok(()))
    }
}

/// How many entries a database holds at most, and ids a detector gives at most, plus one: ids
/// are `u32` below `u32::MAX` ([`DbError::Full`]). Tests lower it on their own thread
/// ([`tests_limit`]) to reach a full database.
pub(crate) fn entry_limit() -> usize {
    #[cfg(test)]
    {
        if let Some(n) = tests_limit::LIMIT.with(core::cell::Cell::get) {
            return n;
        }
    }
    u32::MAX as usize
}

/// A lower [`entry_limit`] for the tests of the calling thread.
#[cfg(test)]
pub(crate) mod tests_limit {
    std::thread_local! {
        /// None: `u32::MAX`.
        pub(crate) static LIMIT: core::cell::Cell<Option<usize>> = const { core::cell::Cell::new(None) };
    }

    /// Sets the calling thread's limit (None: the real one).
    pub(crate) fn set(n: Option<usize>) {
        LIMIT.with(|l| l.set(n));
    }
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
/// How [`Database::merge_anchored`] carries the poses of the database merged into this one's
/// world (each a row-major 3×4 `T_map_other`, `X ↦ T·X`).
#[derive(Debug, Clone, Copy)]
pub enum MergeAnchor<'a> {
    /// One transform for every place.
    All(&'a [f64; 12]),
    /// One per place of the database merged, by id: `None` where nothing places it in this
    /// world (the place is merged without a pose).
    PerPlace(&'a [Option<[f64; 12]>]),
}

/// `a·b` of two row-major 3×4 `[R|t]` rigid transforms.
fn compose(a: &[f64; 12], b: &[f64; 12]) -> [f64; 12] {
    use crate::reg::{mul, pose_to_rows, rows_to_pose};
    pose_to_rows(&mul(&rows_to_pose(a), &rows_to_pose(b)))
}

/// 2^32 - 1 is never a session, so that the session a loop detector starts after a map's is
/// always numbered.
pub(super) const NO_SESSION: u32 = u32::MAX;

/// Checks a session number (any but `u32::MAX`, which marks "no session" in a map).
///
/// # Errors
/// [`Error::InvalidParameter`] (name `session`) otherwise.
pub fn check_session(session: u32) -> Result<(), Error> {
    if session == NO_SESSION {
        return Err(Error::InvalidParameter {
            name: "session",
            value: f64::from(session),
            expected: "a session number below 2^32 - 1 (the one after it must be numbered)",
        });
    }
    Ok(())
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
