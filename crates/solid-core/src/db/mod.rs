//! A growable, persistent database of places and an online loop detector (feature `alloc`).
//!
//! [`Database`] stores, per entry, a session (robot or run), a timestamp, an optional pose, the
//! R-SOLiD and A-SOLiD vectors, and the R-SOLiD in a [`crate::search::Index`] (an online kd-tree
//! and a byte sketch) so that every search is exact over every entry added so far; entries can
//! be added and searched one at a time or in batches ([`Database::add_batch`],
//! [`Database::search_batch`]; a bulk add may leave the index to be built when the searches have
//! paid for it, [`Database::index_due`], by the searches themselves, [`IndexPolicy`]). [`Database::to_bytes`] / [`Database::from_bytes`] (and, with `std`, [`Database::save`] /
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
//! The code is split by what it owns: [`Database`] (storage and search), [`mod@format`] (the file
//! format), [`LoopDetector`] (online loop closure) and [`wire`] (one place on the wire).

use alloc::string::String;
use core::fmt;

use crate::Error;

pub mod clouds;
mod database;
mod detector;
mod detector_config;
pub mod format;
mod index_policy;
mod room;
pub mod wire;

pub use database::{check_pose, BatchResults, Database, SearchOptions, INDEX_AFTER_PASSES};
pub use detector::{
    Candidate, Detection, Loop, LoopDetector, Scan, Verification, UNVERIFIED_SCORE,
    VERIFIED_THRESHOLD,
};
pub use detector_config::{
    DetectorConfig, VerifyConfig, DEFAULT_EXCLUDE_FRAMES, DEFAULT_MAX_LOOP_DISTANCE,
    DEFAULT_RERANK, DEFAULT_TOP_K, DEFAULT_VERIFY_CANDIDATES, MAX_TOP_K,
};
pub use format::crc32;
pub use index_policy::IndexPolicy;
pub use wire::{decode_place, encode_place, Place};

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
    /// More than `u32::MAX` entries (or sessions).
    Full,
    /// Memory for the operation could not be allocated (nothing was changed).
    OutOfMemory,
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
            DbError::OutOfMemory => write!(f, "out of memory"),
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

/// How [`Database::search`] searches; every method returns the same results (see
/// [`crate::search::Plan`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// One linear pass computing every distance ([`crate::search::brute_force`]).
    Brute,
    /// The online kd-tree index ([`crate::search::OnlineIndex`]).
    KdTree,
    /// The byte sketch ([`crate::search::Sketch`]).
    Sketch,
    /// The kd-tree under a budget, then the sketch, then brute force
    /// ([`crate::search::Plan::Auto`]).
    Auto,
}

impl Method {
    /// Parses `"brute"`, `"kdtree"`, `"sketch"` or `"auto"`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] (name `method`) for any other name.
    pub fn parse(name: &str) -> Result<Method, Error> {
        match name {
            "brute" => Ok(Method::Brute),
            "kdtree" => Ok(Method::KdTree),
            "sketch" => Ok(Method::Sketch),
            "auto" => Ok(Method::Auto),
            _ => Err(Error::InvalidParameter {
                name: "method",
                value: f64::NAN,
                expected: "\"brute\", \"kdtree\", \"sketch\" or \"auto\"",
            }),
        }
    }
}
