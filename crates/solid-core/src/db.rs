//! A growable, persistent database of places and an online loop detector (feature `alloc`).
//!
//! [`Database`] stores, per entry, a session (robot or run), a timestamp, an optional pose, the
//! R-SOLiD and A-SOLiD vectors, and the normalised R-SOLiD in an online index
//! ([`crate::search::online_insert`]) so that every search is exact over every entry added so
//! far. [`Database::to_bytes`] / [`Database::from_bytes`] (and, with `std`, [`Database::save`] /
//! [`Database::load`]) give a checksummed little-endian file format. [`LoopDetector`] wraps a
//! database for online loop closure, and [`encode_place`] / [`decode_place`] give a compact wire
//! form for exchanging one place between robots.
//!
//! ```
//! use solid_lidar::db::{Database, Method};
//! use solid_lidar::Config;
//!
//! let cfg = Config::preset("hdl64").unwrap();
//! let mut db = Database::new(cfg).unwrap();
//! let mut r = vec![0.0f32; cfg.n_range];
//! let a = vec![1.0f32; cfg.n_azimuth];
//! for i in 0..5 {
//!     r[i] = 1.0;
//!     db.add_vectors(&r, &a, 0, f64::NAN, None).unwrap();
//! }
//! let hits = db.search(&r, 2, 0, Method::Auto).unwrap();
//! assert_eq!(hits[0].id, 4);
//! let copy = Database::from_bytes(&db.to_bytes()).unwrap();
//! assert_eq!(copy.len(), 5);
//! ```
//!
//! # File format (version 1)
//! All numbers little-endian.
//! ```text
//! offset  size        field
//! 0       8           magic  "SOLiDdb\0"
//! 8       4   u32     format version (1)
//! 12      4   u32     flags (0)
//! 16      4×u32       n_range, n_azimuth, n_elevation, 0
//! 32      5×f64       fov_up, fov_down, min_range, max_range, voxel_size
//! 72      8   u64     config fingerprint (Config::fingerprint)
//! 80      8   u64     entry count n
//! 88      n×112       per entry: u32 session, u32 flags (bit 0: has pose), f64 timestamp
//!                     (NaN = none), 12×f64 pose (row-major 3×4 [R|t], zeros when absent)
//! ...     n×Nr×f32    R-SOLiD vectors, entry after entry
//! ...     n×Na×f32    A-SOLiD vectors
//! end-4   4   u32     CRC-32 (IEEE) of every byte before it
//! ```

use alloc::format;
use alloc::string::String;
use alloc::vec;
use alloc::vec::Vec;
use core::fmt;

use crate::search::{self, Exclude, Neighbor};
use crate::{heading_refined, Config, Descriptor, Error};

/// Everything that can go wrong in the database, the loop detector and the wire form.
#[non_exhaustive]
#[derive(Debug)]
pub enum DbError {
    /// An error of the core (a bad vector length, a non-finite value, an invalid config, ...).
    Core(Error),
    /// A descriptor, database or place made with another configuration.
    ConfigMismatch {
        /// Fingerprint of this database's config.
        expected: u64,
        /// Fingerprint of what was offered.
        got: u64,
    },
    /// Bytes that are not a valid database or place: foreign, truncated, corrupted or newer.
    Format {
        /// The file, when the bytes came from one.
        file: Option<String>,
        /// What is wrong, in words.
        reason: String,
    },
    /// The file could not be read or written.
    #[cfg(feature = "std")]
    Io {
        /// The file.
        file: String,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// More than `u32::MAX` entries.
    Full,
}

impl From<Error> for DbError {
    fn from(e: Error) -> Self {
        DbError::Core(e)
    }
}

impl fmt::Display for DbError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DbError::Core(e) => e.fmt(f),
            DbError::ConfigMismatch { expected, got } => write!(
                f,
                "config mismatch: the database uses config fingerprint {expected:#018x}, \
                 this one has {got:#018x} (descriptors from different configs are not comparable)"
            ),
            DbError::Format {
                file: Some(file),
                reason,
            } => write!(f, "cannot load {file}: {reason}"),
            DbError::Format { file: None, reason } => write!(f, "invalid data: {reason}"),
            #[cfg(feature = "std")]
            DbError::Io { file, source } => write!(f, "{file}: {source}"),
            DbError::Full => write!(f, "database full: at most 2^32 - 1 entries"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for DbError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            DbError::Core(e) => Some(e),
            DbError::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// How [`Database::search`] searches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// One linear pass over every entry ([`search::brute_force`]).
    Brute,
    /// The online kd-tree index ([`search::OnlineIndex`]).
    KdTree,
    /// The faster of the two for the database's size (see [`AUTO_KDTREE_MIN`]).
    Auto,
}

impl Method {
    /// Parses `"brute"`, `"kdtree"` or `"auto"`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] (name `method`) for any other name.
    pub fn parse(name: &str) -> Result<Method, Error> {
        match name {
            "brute" => Ok(Method::Brute),
            "kdtree" => Ok(Method::KdTree),
            "auto" => Ok(Method::Auto),
            _ => Err(Error::InvalidParameter {
                name: "method",
                value: f64::NAN,
                expected: "\"brute\", \"kdtree\" or \"auto\"",
            }),
        }
    }
}

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
    config: Config,
    fingerprint: u64,
    sessions: Vec<u32>,
    timestamps: Vec<f64>,
    poses: Vec<Option<[f64; 12]>>,
    r: Vec<f32>,
    a: Vec<f32>,
    normed: Vec<f32>,
    perm: Vec<u32>,
    splits: Vec<u16>,
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

    /// Adds raw vectors (the caller vouches that they come from this database's config).
    ///
    /// # Errors
    /// [`DbError::Core`] with [`Error::LengthMismatch`] for vectors of the wrong length, or with
    /// [`Error::InvalidParameter`] for non-finite values (in the vectors or the pose);
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
        if let Some(bad) = a.iter().find(|v| !v.is_finite()) {
            return Err(Error::InvalidParameter {
                name: "a_solid",
                value: f64::from(*bad),
                expected: "finite values",
            }
            .into());
        }
        if let Some(p) = &pose {
            if let Some(bad) = p.iter().find(|v| !v.is_finite()) {
                return Err(Error::InvalidParameter {
                    name: "pose",
                    value: *bad,
                    expected: "finite values",
                }
                .into());
            }
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

    fn check_fingerprint(&self, got: u64) -> Result<(), DbError> {
        if got != self.fingerprint {
            return Err(DbError::ConfigMismatch {
                expected: self.fingerprint,
                got,
            });
        }
        Ok(())
    }

    /// The `k` nearest entries to the R-SOLiD `query_r` (SPEC §3), nearest first, ties by lower
    /// id, skipping the `exclude_recent` most recent entries.
    ///
    /// # Errors
    /// [`DbError::Core`] for a query of the wrong length or with non-finite values.
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
    /// [`DbError::Core`] for a query of the wrong length or with non-finite values.
    pub fn search_with(
        &self,
        query_r: &[f32],
        opts: &SearchOptions,
    ) -> Result<Vec<Neighbor>, DbError> {
        let nr = self.config.n_range;
        if query_r.len() != nr {
            return Err(Error::LengthMismatch {
                what: "query r_solid vs config n_range",
                left: query_r.len(),
                right: nr,
            }
            .into());
        }
        let mut q = vec![0.0f32; nr];
        search::normalize(query_r, &mut q)?;
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

    /// Serialises the database in the file format of the module documentation.
    pub fn to_bytes(&self) -> Vec<u8> {
        let n = self.len();
        let c = &self.config;
        let mut out =
            Vec::with_capacity(HEADER_LEN + n * ENTRY_LEN + (self.r.len() + self.a.len()) * 4 + 4);
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
        for v in [c.n_range, c.n_azimuth, c.n_elevation, 0] {
            out.extend_from_slice(&(v as u32).to_le_bytes());
        }
        for v in [c.fov_up, c.fov_down, c.min_range, c.max_range, c.voxel_size] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.fingerprint.to_le_bytes());
        out.extend_from_slice(&(n as u64).to_le_bytes());
        for i in 0..n {
            out.extend_from_slice(&self.sessions[i].to_le_bytes());
            let (flags, pose) = match &self.poses[i] {
                Some(p) => (1u32, *p),
                None => (0u32, [0.0; 12]),
            };
            out.extend_from_slice(&flags.to_le_bytes());
            out.extend_from_slice(&self.timestamps[i].to_le_bytes());
            for v in pose {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        for v in self.r.iter().chain(&self.a) {
            out.extend_from_slice(&v.to_le_bytes());
        }
        let crc = crc32(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    /// Reads a database written by [`Database::to_bytes`], checking everything: the magic, the
    /// version, the length, the checksum, the config and every value.
    ///
    /// # Errors
    /// [`DbError::Format`] (with `file: None`) naming what is wrong: not a SOLiD database,
    /// a newer format version, truncated, trailing bytes, checksum mismatch, invalid config,
    /// non-finite values.
    pub fn from_bytes(bytes: &[u8]) -> Result<Database, DbError> {
        let bad = |reason: String| DbError::Format { file: None, reason };
        if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
            return Err(bad(String::from(
                "not a SOLiD database (wrong magic number at the start of the file)",
            )));
        }
        if bytes.len() < HEADER_LEN + 4 {
            return Err(bad(format!(
                "truncated: {} bytes, shorter than the {}-byte header",
                bytes.len(),
                HEADER_LEN + 4
            )));
        }
        let mut rd = Reader { b: bytes, at: 8 };
        let version = rd.u32();
        if version > FORMAT_VERSION {
            return Err(bad(format!(
                "format version {version} is newer than this library reads (up to {FORMAT_VERSION}); \
                 upgrade solid"
            )));
        }
        if version == 0 {
            return Err(bad(String::from("invalid format version 0")));
        }
        let flags = rd.u32();
        if flags != 0 {
            return Err(bad(format!("unknown header flags {flags:#x}")));
        }
        let (n_range, n_azimuth, n_elevation, _pad) = (rd.u32(), rd.u32(), rd.u32(), rd.u32());
        let config = Config {
            n_range: n_range as usize,
            n_azimuth: n_azimuth as usize,
            n_elevation: n_elevation as usize,
            fov_up: rd.f64(),
            fov_down: rd.f64(),
            min_range: rd.f64(),
            max_range: rd.f64(),
            voxel_size: rd.f64(),
        };
        let fingerprint = rd.u64();
        let count = rd.u64();
        // Length check before the checksum, so that a truncated file says "truncated".
        let per_entry = (n_range as u64 + n_azimuth as u64) * 4 + ENTRY_LEN as u64;
        let expected = count
            .checked_mul(per_entry)
            .and_then(|v| v.checked_add((HEADER_LEN + 4) as u64));
        let expected = match expected {
            Some(e) if e <= usize::MAX as u64 => e as usize,
            _ => {
                return Err(bad(format!(
                    "corrupted header: entry count {count} is impossible"
                )))
            }
        };
        if bytes.len() < expected {
            return Err(bad(format!(
                "truncated: the header announces {count} entries ({expected} bytes) but there are only {} bytes",
                bytes.len()
            )));
        }
        if bytes.len() > expected {
            return Err(bad(format!(
                "{} unexpected bytes after the end of the data ({expected} bytes expected)",
                bytes.len() - expected
            )));
        }
        let body = &bytes[..expected - 4];
        let stored = u32::from_le_bytes([
            bytes[expected - 4],
            bytes[expected - 3],
            bytes[expected - 2],
            bytes[expected - 1],
        ]);
        let actual = crc32(body);
        if stored != actual {
            return Err(bad(format!(
                "checksum mismatch (stored {stored:#010x}, computed {actual:#010x}): the file is corrupted"
            )));
        }
        if let Err(e) = config.validate() {
            return Err(bad(format!("invalid config in header: {e}")));
        }
        if config.fingerprint() != fingerprint {
            return Err(bad(format!(
                "config fingerprint {fingerprint:#018x} does not match the stored config ({:#018x})",
                config.fingerprint()
            )));
        }
        if count >= u32::MAX as u64 {
            return Err(bad(format!("too many entries ({count})")));
        }
        let n = count as usize;
        let mut db = Database::new(config)?;
        db.sessions.reserve_exact(n);
        db.timestamps.reserve_exact(n);
        db.poses.reserve_exact(n);
        for i in 0..n {
            db.sessions.push(rd.u32());
            let eflags = rd.u32();
            db.timestamps.push(rd.f64());
            let mut pose = [0.0; 12];
            for v in &mut pose {
                *v = rd.f64();
            }
            match eflags {
                0 => db.poses.push(None),
                1 => {
                    if pose.iter().any(|v| !v.is_finite()) {
                        return Err(bad(format!("entry {i}: non-finite pose")));
                    }
                    db.poses.push(Some(pose));
                }
                _ => return Err(bad(format!("entry {i}: unknown flags {eflags:#x}"))),
            }
        }
        let (nr, na) = (config.n_range, config.n_azimuth);
        db.r = (0..n * nr).map(|_| rd.f32()).collect();
        db.a = (0..n * na).map(|_| rd.f32()).collect();
        if let Some(p) = db.r.iter().chain(&db.a).position(|v| !v.is_finite()) {
            let (which, entry) = if p < n * nr {
                ("R-SOLiD", p / nr)
            } else {
                ("A-SOLiD", (p - n * nr) / na)
            };
            return Err(bad(format!(
                "entry {entry}: non-finite value in its {which}"
            )));
        }
        db.normed = vec![0.0; n * nr];
        search::normalize_rows(&db.r, nr, &mut db.normed)?;
        db.perm = (0..n as u32).collect();
        db.splits = vec![0; n];
        search::online_rebuild(&db.normed, nr, &mut db.perm, &mut db.splits)?;
        Ok(db)
    }

    /// Writes the database to `path` atomically: into a temporary file in the same directory,
    /// flushed to disk, then renamed over `path`.
    ///
    /// # Errors
    /// [`DbError::Io`] naming the file when writing or renaming fails (the temporary file is
    /// removed).
    #[cfg(feature = "std")]
    pub fn save<P: AsRef<std::path::Path>>(&self, path: P) -> Result<(), DbError> {
        use std::io::Write;
        let path = path.as_ref();
        let io = |source| DbError::Io {
            file: path.display().to_string(),
            source,
        };
        let name = path
            .file_name()
            .ok_or_else(|| io(std::io::Error::other("the path names no file")))?;
        let mut tmp_name = std::ffi::OsString::from(".");
        tmp_name.push(name);
        tmp_name.push(format!(".{}.tmp", std::process::id()));
        let tmp = path.with_file_name(tmp_name);
        let bytes = self.to_bytes();
        let write = || -> std::io::Result<()> {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(&bytes)?;
            f.sync_all()?;
            drop(f);
            std::fs::rename(&tmp, path)
        };
        if let Err(e) = write() {
            let _ = std::fs::remove_file(&tmp);
            return Err(io(e));
        }
        // Make the rename durable where the platform allows it (best effort).
        if let Some(dir) = path.parent() {
            let dir = if dir.as_os_str().is_empty() {
                std::path::Path::new(".")
            } else {
                dir
            };
            if let Ok(d) = std::fs::File::open(dir) {
                let _ = d.sync_all();
            }
        }
        Ok(())
    }

    /// Reads a database saved by [`Database::save`].
    ///
    /// # Errors
    /// [`DbError::Io`] naming the file when it cannot be read (for example, it does not exist);
    /// [`DbError::Format`] naming the file and the reason when its content is not a valid
    /// database (see [`Database::from_bytes`]).
    #[cfg(feature = "std")]
    pub fn load<P: AsRef<std::path::Path>>(path: P) -> Result<Database, DbError> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let bytes = match std::fs::read(path) {
            Ok(b) => b,
            Err(source) => return Err(DbError::Io { file, source }),
        };
        Database::from_bytes(&bytes).map_err(|e| match e {
            DbError::Format { reason, .. } => DbError::Format {
                file: Some(file),
                reason,
            },
            other => other,
        })
    }
}

const MAGIC: [u8; 8] = *b"SOLiDdb\0";
const FORMAT_VERSION: u32 = 1;
const HEADER_LEN: usize = 88;
const ENTRY_LEN: usize = 4 + 4 + 8 + 96;

/// A little-endian reader over bytes whose length was checked beforehand.
struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut v = [0u8; N];
        v.copy_from_slice(&self.b[self.at..self.at + N]);
        self.at += N;
        v
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
    fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
}

const CRC_TABLE: [u32; 256] = {
    let mut t = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
            k += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
};

/// CRC-32 (IEEE 802.3, the one of zlib and PNG) of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c = CRC_TABLE[((c ^ b as u32) & 0xff) as usize] ^ (c >> 8);
    }
    !c
}

/// One detected loop closure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Loop {
    /// Id of the query (the entry just added by [`LoopDetector::add`]; for
    /// [`LoopDetector::query`], the id it would get, `len()`).
    pub query: u32,
    /// Id of the matched database entry.
    pub candidate: u32,
    /// Cosine distance of the R-SOLiDs (SPEC §3).
    pub distance: f64,
    /// Heading of the query relative to the candidate, degrees in `(−180, 180]` (SPEC §3,
    /// refined).
    pub heading_deg: f64,
}

/// An online loop-closure detector: each new scan is searched against the scans added before it,
/// except the `exclude_recent` most recent (SPEC §5), then added.
#[derive(Debug, Clone)]
pub struct LoopDetector {
    db: Database,
    /// Entries skipped as too recent to count as a loop.
    pub exclude_recent: usize,
    /// Largest R-SOLiD distance accepted as a loop.
    pub threshold: f64,
    /// Candidates considered by the A-SOLiD re-ranking (1: no re-ranking).
    pub top_k: usize,
    /// Re-rank the `top_k` nearest by R-SOLiD distance plus rotation-aligned A-SOLiD distance.
    pub rerank: bool,
}

impl LoopDetector {
    /// A detector for scans described with `config`.
    ///
    /// # Errors
    /// [`DbError::Core`] when `config` is invalid, or (name `threshold`) when `threshold` is not
    /// a finite number, or (name `top_k`) when `top_k` is 0.
    pub fn new(
        config: Config,
        exclude_recent: usize,
        threshold: f64,
        top_k: usize,
    ) -> Result<LoopDetector, DbError> {
        if !threshold.is_finite() {
            return Err(Error::InvalidParameter {
                name: "threshold",
                value: threshold,
                expected: "a finite number (cosine distance, in [0, 1])",
            }
            .into());
        }
        if top_k == 0 {
            return Err(Error::InvalidParameter {
                name: "top_k",
                value: 0.0,
                expected: "at least 1",
            }
            .into());
        }
        Ok(LoopDetector {
            db: Database::new(config)?,
            exclude_recent,
            threshold,
            top_k,
            rerank: DEFAULT_RERANK,
        })
    }

    /// A detector over an existing database (a prior map).
    pub fn with_database(
        db: Database,
        exclude_recent: usize,
        threshold: f64,
        top_k: usize,
    ) -> Self {
        LoopDetector {
            db,
            exclude_recent,
            threshold,
            top_k: top_k.max(1),
            rerank: DEFAULT_RERANK,
        }
    }

    /// The database of every scan added so far.
    pub fn database(&self) -> &Database {
        &self.db
    }

    /// Consumes the detector, returning its database.
    pub fn into_database(self) -> Database {
        self.db
    }

    /// Searches `d` against every entry but the `exclude_recent` most recent, then adds it.
    /// Returns the best candidate when its distance is at most `threshold`.
    ///
    /// # Errors
    /// [`DbError::ConfigMismatch`] for a descriptor made with another config; as
    /// [`Database::add`] otherwise.
    pub fn add(&mut self, d: &Descriptor, timestamp: f64) -> Result<Option<Loop>, DbError> {
        self.db.check_fingerprint(d.fingerprint)?;
        let found = self.best(&d.r, &d.a, self.exclude_recent)?;
        let id = self.db.add(d, 0, timestamp, None)?;
        Ok(self.accept(found, id))
    }

    /// Searches `d` against every entry without adding it (localisation in a prior map); no
    /// entry is excluded.
    ///
    /// # Errors
    /// As [`LoopDetector::add`].
    pub fn query(&self, d: &Descriptor) -> Result<Option<Loop>, DbError> {
        self.db.check_fingerprint(d.fingerprint)?;
        let found = self.best(&d.r, &d.a, 0)?;
        Ok(self.accept(found, self.db.len() as u32))
    }

    fn accept(&self, found: Option<(Neighbor, f64)>, query: u32) -> Option<Loop> {
        let (nb, heading_deg) = found?;
        let distance = f64::from(nb.distance);
        (distance <= self.threshold).then_some(Loop {
            query,
            candidate: nb.id,
            distance,
            heading_deg,
        })
    }

    /// The best candidate and its heading, before thresholding.
    fn best(
        &self,
        r: &[f32],
        a: &[f32],
        exclude: usize,
    ) -> Result<Option<(Neighbor, f64)>, DbError> {
        if a.len() != self.db.config.n_azimuth {
            return Err(Error::LengthMismatch {
                what: "a_solid vs config n_azimuth",
                left: a.len(),
                right: self.db.config.n_azimuth,
            }
            .into());
        }
        let k = if self.rerank { self.top_k } else { 1 };
        let cands = self.db.search(r, k, exclude, Method::Auto)?;
        let best = if self.rerank && cands.len() > 1 {
            let mut best = cands[0];
            let mut best_score = f64::INFINITY;
            for c in &cands {
                let score = f64::from(c.distance) + aligned_distance(a, self.db.a(c.id));
                if score < best_score {
                    best_score = score;
                    best = *c;
                }
            }
            best
        } else {
            match cands.first() {
                Some(c) => *c,
                None => return Ok(None),
            }
        };
        let h = heading_refined(a, self.db.a(best.id))?;
        Ok(Some((best, h.degrees)))
    }
}

/// Whether [`LoopDetector`] re-ranks by A-SOLiD alignment by default.
///
/// Measured on the HKU Livox Avia sequence (SPEC §5, exclude 50, `tests/loop_eval.rs`), top-10
/// re-ranked by R-SOLiD distance + rotation-aligned A-SOLiD distance: Recall@1 within 5 m goes
/// from 0.490 to 0.535 (preset `avia`) and from 0.490 to 0.555 (`avia`, max_range 40); within
/// 3 m from 0.621 to 0.621 and from 0.530 to 0.561. So it is on.
pub const DEFAULT_RERANK: bool = true;

/// Cosine distance between `q` and `c` circularly shifted by the shift that aligns them best
/// (the maximum correlation over all shifts); 1 when either is all zero.
///
/// # Panics
/// When the lengths differ (callers check).
pub fn aligned_distance(q: &[f32], c: &[f32]) -> f64 {
    assert_eq!(q.len(), c.len(), "aligned_distance: lengths differ");
    let n = q.len();
    let nq: f64 = q.iter().map(|&v| f64::from(v) * f64::from(v)).sum();
    let nc: f64 = c.iter().map(|&v| f64::from(v) * f64::from(v)).sum();
    if nq == 0.0 || nc == 0.0 {
        return 1.0;
    }
    let mut best = f64::NEG_INFINITY;
    for s in 0..n {
        // Σⱼ q[j]·c[(j − s) mod n]
        let head: f64 = q[s..]
            .iter()
            .zip(&c[..n - s])
            .map(|(&x, &y)| f64::from(x) * f64::from(y))
            .sum();
        let tail: f64 = q[..s]
            .iter()
            .zip(&c[n - s..])
            .map(|(&x, &y)| f64::from(x) * f64::from(y))
            .sum();
        best = best.max(head + tail);
    }
    (1.0 - best / libm::sqrt(nq * nc)).clamp(0.0, 1.0)
}

/// One place decoded from its wire form.
#[derive(Debug, Clone, PartialEq)]
pub struct Place {
    /// R-SOLiD.
    pub r: Vec<f32>,
    /// A-SOLiD.
    pub a: Vec<f32>,
    /// Fingerprint of the config that made it.
    pub fingerprint: u64,
    /// Whether it travelled quantised (then `r` and `a` are approximations).
    pub quantized: bool,
}

const WIRE_MAGIC: [u8; 2] = *b"SP";
const WIRE_VERSION: u8 = 1;
const WIRE_F32: u8 = 1;
const WIRE_U8: u8 = 2;
const WIRE_HEADER: usize = 16;

/// Encodes one place (R-SOLiD, A-SOLiD and config fingerprint) for exchange between robots.
///
/// Layout (little-endian): `"SP"`, version `u8` (1), kind `u8` (1 = float32, 2 = quantised),
/// `u16` n_range, `u16` n_azimuth, `u64` fingerprint, then the payload, then a `u32` CRC-32 of
/// everything before it. Float32 payload: the vectors as `f32` (400 B for Nr = 40, Na = 60; 420 B
/// in all). Quantised payload: per vector an `f32` scale (its maximum) and one `u8` per bin,
/// `round(255 · √(v / max))` (square-root companding keeps relative precision in the sparse far
/// bins): 124 + 4 = 128 B in all for the defaults.
///
/// # Errors
/// [`Error::InvalidParameter`] when a vector is longer than 65535 values, or holds a negative or
/// non-finite value and `quantized` is set (or a non-finite one otherwise); [`Error::Empty`]
/// when a vector is empty.
pub fn encode_place(
    r: &[f32],
    a: &[f32],
    fingerprint: u64,
    quantized: bool,
) -> Result<Vec<u8>, Error> {
    for (name, v) in [("r_solid", r), ("a_solid", a)] {
        if v.is_empty() {
            return Err(Error::Empty { what: name });
        }
        if v.len() > u16::MAX as usize {
            return Err(Error::InvalidParameter {
                name,
                value: v.len() as f64,
                expected: "at most 65535 values",
            });
        }
        if let Some(bad) = v
            .iter()
            .find(|x| !x.is_finite() || (quantized && **x < 0.0))
        {
            return Err(Error::InvalidParameter {
                name,
                value: f64::from(*bad),
                expected: "finite values (non-negative when quantised)",
            });
        }
    }
    let payload = if quantized {
        8 + r.len() + a.len()
    } else {
        4 * (r.len() + a.len())
    };
    let mut out = Vec::with_capacity(WIRE_HEADER + payload + 4);
    out.extend_from_slice(&WIRE_MAGIC);
    out.push(WIRE_VERSION);
    out.push(if quantized { WIRE_U8 } else { WIRE_F32 });
    out.extend_from_slice(&(r.len() as u16).to_le_bytes());
    out.extend_from_slice(&(a.len() as u16).to_le_bytes());
    out.extend_from_slice(&fingerprint.to_le_bytes());
    if quantized {
        for v in [r, a] {
            let max = v.iter().fold(0.0f32, |m, &x| m.max(x));
            out.extend_from_slice(&max.to_le_bytes());
            for &x in v {
                let q = if max > 0.0 {
                    libm::round(255.0 * libm::sqrt(f64::from(x) / f64::from(max))) as u8
                } else {
                    0
                };
                out.push(q);
            }
        }
    } else {
        for &x in r.iter().chain(a) {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    let crc = crc32(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    Ok(out)
}

/// Decodes a place encoded by [`encode_place`].
///
/// # Errors
/// [`DbError::Format`] naming the reason: not a place, an unknown version or kind, a wrong
/// length, a checksum mismatch, non-finite values.
pub fn decode_place(bytes: &[u8]) -> Result<Place, DbError> {
    let bad = |reason: String| DbError::Format { file: None, reason };
    if bytes.len() < WIRE_HEADER + 4 || bytes[..2] != WIRE_MAGIC {
        return Err(bad(String::from(
            "not a SOLiD place (wrong magic or too short)",
        )));
    }
    if bytes[2] != WIRE_VERSION {
        return Err(bad(format!(
            "place format version {} is not supported (this library reads {WIRE_VERSION})",
            bytes[2]
        )));
    }
    let kind = bytes[3];
    let mut rd = Reader { b: bytes, at: 4 };
    let nr = u16::from_le_bytes(rd.take()) as usize;
    let na = u16::from_le_bytes(rd.take()) as usize;
    let fingerprint = rd.u64();
    let payload = match kind {
        WIRE_F32 => 4 * (nr + na),
        WIRE_U8 => 8 + nr + na,
        _ => return Err(bad(format!("unknown place kind {kind}"))),
    };
    let expected = WIRE_HEADER + payload + 4;
    if bytes.len() != expected {
        return Err(bad(format!(
            "wrong length: {} bytes, expected {expected}",
            bytes.len()
        )));
    }
    let stored = u32::from_le_bytes([
        bytes[expected - 4],
        bytes[expected - 3],
        bytes[expected - 2],
        bytes[expected - 1],
    ]);
    if crc32(&bytes[..expected - 4]) != stored {
        return Err(bad(String::from(
            "checksum mismatch: the place is corrupted",
        )));
    }
    let (r, a) = if kind == WIRE_F32 {
        let r: Vec<f32> = (0..nr).map(|_| rd.f32()).collect();
        let a: Vec<f32> = (0..na).map(|_| rd.f32()).collect();
        (r, a)
    } else {
        let mut dequant = |n: usize| -> Vec<f32> {
            let max = rd.f32();
            (0..n)
                .map(|_| {
                    let q = f64::from(rd.take::<1>()[0]) / 255.0;
                    (q * q * f64::from(max)) as f32
                })
                .collect()
        };
        let r = dequant(nr);
        let a = dequant(na);
        (r, a)
    };
    if r.iter().chain(&a).any(|v| !v.is_finite()) {
        return Err(bad(String::from("non-finite value in the place")));
    }
    Ok(Place {
        r,
        a,
        fingerprint,
        quantized: kind == WIRE_U8,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_matches_the_standard_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn wire_sizes() {
        let r = vec![1.0f32; 40];
        let a = vec![2.0f32; 60];
        assert_eq!(encode_place(&r, &a, 7, false).unwrap().len(), 420);
        assert!(encode_place(&r, &a, 7, true).unwrap().len() <= 200);
    }
}
