//! [`Database`]: the entries and their exact search.

use alloc::vec;
use alloc::vec::Vec;

use super::clouds::Clouds;
use super::{DbError, Method};
use crate::search::{self, Exclude, Neighbor};
use crate::{Config, Descriptor, Error};

/// [`Method::Auto`] uses the kd-tree index from this many candidate entries on, brute force
/// below. Measured with `benches/benches/search.rs` (top-1, 40 range bins): on real HKU
/// descriptors the index costs about the same as brute force at 1,000 entries and wins 3-5x for
/// novel places and 10-40x for revisits from 10,000 on; on random descriptor-shaped vectors
/// (no structure) it loses about 1.5x for novel places at every size.
pub const AUTO_KDTREE_MIN: usize = 2048;

/// Options of [`Database::search_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchOptions {
    /// Number of neighbours.
    pub k: usize,
    /// Skip the most recent entries (the last `exclude_recent` ids).
    pub exclude_recent: usize,
    /// Skip entries whose timestamp is greater than this (entries without a time are kept).
    pub not_newer_than: Option<f64>,
    /// Search method.
    pub method: Method,
}

impl Default for SearchOptions {
    fn default() -> Self {
        SearchOptions {
            k: 1,
            exclude_recent: 0,
            not_newer_than: None,
            method: Method::Auto,
        }
    }
}

/// A database of places, searchable exactly at every size (see the module documentation).
#[derive(Debug, Clone)]
pub struct Database {
    pub(super) config: Config,
    pub(super) fingerprint: u64,
    pub(super) sessions: Vec<u32>,
    pub(super) timestamps: Vec<f64>,
    pub(super) poses: Vec<Option<[f64; 12]>>,
    pub(super) r: Vec<f32>,
    pub(super) a: Vec<f32>,
    pub(super) normed: Vec<f32>,
    pub(super) perm: Vec<u32>,
    pub(super) splits: Vec<u16>,
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
            a: Vec::new(),
            normed: Vec::new(),
            perm: Vec::new(),
            splits: Vec::new(),
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
    /// As [`Database::add`].
    pub fn add_with_cloud(
        &mut self,
        d: &Descriptor,
        session: u32,
        timestamp: f64,
        pose: Option<[f64; 12]>,
        cloud: Option<&[u8]>,
    ) -> Result<u32, DbError> {
        self.check_fingerprint(d.fingerprint)?;
        self.add_entry(&d.r, &d.a, session, timestamp, pose, cloud)
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
        self.add_entry(r, a, session, timestamp, pose, None)
    }

    fn add_entry(
        &mut self,
        r: &[f32],
        a: &[f32],
        session: u32,
        timestamp: f64,
        pose: Option<[f64; 12]>,
        cloud: Option<&[u8]>,
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
        check_bins("r_solid", r)?;
        check_bins("a_solid", a)?;
        if timestamp.is_infinite() {
            return Err(Error::InvalidParameter {
                name: "timestamp",
                value: timestamp,
                expected: "a finite time in seconds (NaN for none)",
            }
            .into());
        }
        if let Some(p) = &pose {
            check_pose(p)?;
        }
        let id = self.len();
        if id >= u32::MAX as usize {
            return Err(DbError::Full);
        }
        let start = self.normed.len();
        self.normed.resize(start + nr, 0.0);
        if let Err(e) = search::normalize(r, &mut self.normed[start..]) {
            self.normed.truncate(start);
            return Err(e.into());
        }
        if let Err(e) = self.clouds.push(id, cloud) {
            self.normed.truncate(start);
            return Err(e);
        }
        self.r.extend_from_slice(r);
        self.a.extend_from_slice(a);
        self.sessions.push(session);
        self.timestamps.push(timestamp);
        self.poses.push(pose);
        self.perm.push(id as u32);
        self.splits.push(0);
        search::online_insert(&self.normed, nr, &mut self.perm, &mut self.splits)?;
        Ok(id as u32)
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
                not_newer_than: None,
                method,
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
    /// or a NaN `not_newer_than` (it would compare false with every time: no limit is `None`).
    pub fn search_with(
        &self,
        query_r: &[f32],
        opts: &SearchOptions,
    ) -> Result<Vec<Neighbor>, DbError> {
        let nr = self.config.n_range;
        if let Some(t) = opts.not_newer_than.filter(|t| t.is_nan()) {
            return Err(Error::InvalidParameter {
                name: "not_newer_than",
                value: t,
                expected: "a time in seconds (or None for no limit), not NaN",
            }
            .into());
        }
        let q = self.normalized_query(query_r)?;
        let n = self.len();
        let exclude = Exclude {
            before_id: n.saturating_sub(opts.exclude_recent),
            not_newer_than: opts.not_newer_than.map(|t| (&self.timestamps[..], t)),
        };
        let k = opts.k.min(exclude.before_id);
        let mut out = vec![Neighbor::default(); k];
        let use_tree = match opts.method {
            Method::Brute => false,
            Method::KdTree => true,
            Method::Auto => exclude.before_id >= AUTO_KDTREE_MIN,
        };
        let got = if use_tree {
            search::OnlineIndex::new(&self.normed, nr, &self.perm, &self.splits)?
                .search(&q, k, &exclude, &mut out)?
        } else {
            search::brute_force(&self.normed, nr, &q, k, &exclude, &mut out)?
        };
        out.truncate(got);
        Ok(out)
    }

    /// `query_r` checked against the config and L2-normalised.
    fn normalized_query(&self, query_r: &[f32]) -> Result<Vec<f32>, DbError> {
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
        let mut q = vec![0.0f32; nr];
        search::normalize(query_r, &mut q)?;
        Ok(q)
    }

    /// The cosine distance ([spec §3](crate::spec#3-comparing-descriptors)) from the R-SOLiD `query_r` to every entry, in id order
    /// (for plots and analysis; searches use [`Database::search`]).
    ///
    /// # Errors
    /// [`DbError::Core`] for a query of the wrong length or with negative or non-finite values;
    /// [`DbError::OutOfMemory`] when the output cannot be allocated.
    pub fn distances(&self, query_r: &[f32]) -> Result<Vec<f32>, DbError> {
        let nr = self.config.n_range;
        let q = self.normalized_query(query_r)?;
        let mut out = Vec::new();
        out.try_reserve_exact(self.len())
            .map_err(|_| DbError::OutOfMemory)?;
        for row in self.normed.chunks_exact(nr) {
            out.push(search::normalized_distance(&q, row)?);
        }
        Ok(out)
    }

    /// Appends every entry of `other` (ids shift by `self.len()`; sessions, times and poses kept).
    ///
    /// # Errors
    /// [`DbError::ConfigMismatch`] when the two configs differ; [`DbError::Full`] beyond
    /// `u32::MAX` entries.
    pub fn merge(&mut self, other: &Database) -> Result<(), DbError> {
        self.check_fingerprint(other.fingerprint)?;
        if self.len() + other.len() >= u32::MAX as usize {
            return Err(DbError::Full);
        }
        let base = self.len();
        self.clouds.append(base, &other.clouds, other.len())?;
        self.sessions.extend_from_slice(&other.sessions);
        self.timestamps.extend_from_slice(&other.timestamps);
        self.poses.extend_from_slice(&other.poses);
        self.r.extend_from_slice(&other.r);
        self.a.extend_from_slice(&other.a);
        self.normed.extend_from_slice(&other.normed);
        let n = self.len();
        self.perm.extend((base..n).map(|i| i as u32));
        self.splits.resize(n, 0);
        search::online_rebuild(
            &self.normed,
            self.config.n_range,
            &mut self.perm,
            &mut self.splits,
        )?;
        Ok(())
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

    /// All R-SOLiD vectors, row-major (`len() × n_range`).
    pub fn r_all(&self) -> &[f32] {
        &self.r
    }

    /// All A-SOLiD vectors, row-major (`len() × n_azimuth`).
    pub fn a_all(&self) -> &[f32] {
        &self.a
    }

    /// The R-SOLiD of entry `id`.
    ///
    /// # Panics
    /// When `id >= len()`.
    pub fn r(&self, id: u32) -> &[f32] {
        let nr = self.config.n_range;
        &self.r[id as usize * nr..(id as usize + 1) * nr]
    }

    /// The A-SOLiD of entry `id`.
    ///
    /// # Panics
    /// When `id >= len()`.
    pub fn a(&self, id: u32) -> &[f32] {
        let na = self.config.n_azimuth;
        &self.a[id as usize * na..(id as usize + 1) * na]
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
        (0..self.len())
            .filter(|&i| self.clouds.get(i).is_some())
            .count()
    }

    /// Per-entry sessions.
    pub fn sessions(&self) -> &[u32] {
        &self.sessions
    }

    /// Per-entry timestamps (NaN: none).
    pub fn timestamps(&self) -> &[f64] {
        &self.timestamps
    }

    /// Per-entry poses (row-major 3×4 `[R|t]`).
    pub fn poses(&self) -> &[Option<[f64; 12]>] {
        &self.poses
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
