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
//! let copy = Database::from_bytes(&db.to_bytes().unwrap()).unwrap();
//! assert_eq!(copy.len(), 5);
//! ```
//!
//! The code is split by what it owns: [`Database`] (storage and search), [`mod@format`] (the file
//! format) and [`wire`] (one place on the wire). The database holds places; the loop detector
//! that decides loops over it lives in [`crate::detector`] and is re-exported here
//! ([`LoopDetector`], [`DetectorConfig`], ...) so that `solid_lidar::db::LoopDetector` keeps working.

use crate::Error;

pub mod clouds;
mod database;
mod exclusion;
pub mod format;
mod index_policy;
mod lean;
mod room;
pub mod wire;

pub use crate::checksum::crc32;
pub use crate::detector::{
    Candidate, Detection, Loop, LoopDetector, MapAnchor, PlacementChange, PoseSource, Scan,
    Verification, UNVERIFIED_SCORE, VERIFIED_THRESHOLD,
};
pub use crate::detector::{
    DetectorConfig, VerifyConfig, DEFAULT_EXCLUDE_FRAMES, DEFAULT_EXCLUDE_METERS,
    DEFAULT_MAX_LOOP_DISTANCE, DEFAULT_POSE_CANDIDATES, DEFAULT_POSE_CANDIDATE_MIN_INFORMATION,
    DEFAULT_RERANK, DEFAULT_TOP_K, DEFAULT_VERIFY_CANDIDATES, MAX_TOP_K, MAX_VERIFY_THREADS,
};
pub use crate::error::DbError;
pub(crate) use database::entry_limit;
#[cfg(test)]
pub(crate) use database::tests_limit;
pub use database::{
    check_pose, check_session, BatchResults, Database, MergeAnchor, SearchOptions,
    INDEX_AFTER_PASSES,
};
pub use exclusion::visible_own_places;
pub use index_policy::IndexPolicy;
pub use wire::{decode_place, encode_place, Place};

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

/// [`Error::LengthMismatch`] unless `left == right`: `what` names the two lengths.
pub(crate) fn same_len(what: &'static str, left: usize, right: usize) -> Result<(), Error> {
    if left == right {
        Ok(())
    } else {
        Err(Error::LengthMismatch { what, left, right })
    }
}
