//! [`SolidDatabase`]: places (descriptors with a session, a timestamp and an optional pose),
//! exact k-nearest search, and the checksummed file format.

use std::ffi::c_char;
use std::sync::{Arc, RwLock};

use solid_lidar::db::{Database, Method};

use crate::config::SolidConfig;
use crate::{guard, new_handle, nonnull, out, pose_3x4, put, read, release, slice, slice_mut};
use crate::{string, write};
use crate::{Failure, SolidStatus};

/// A growable database of places with exact search at every size.
///
/// Threads: may be shared; searches run in parallel, an add waits for them and runs alone.
/// A detector made from it shares its places without copying them; an add after that makes
/// the database its own copy first (the detector keeps the places it was made over).
pub struct SolidDatabase {
    pub(crate) db: RwLock<Arc<Database>>,
}

impl From<Database> for SolidDatabase {
    fn from(db: Database) -> SolidDatabase {
        SolidDatabase {
            db: RwLock::new(Arc::new(db)),
        }
    }
}

/// One neighbour found by [`solid_database_search`].
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct SolidNeighbor {
    /// The entry's id (ids count from 0 in the order of adding).
    pub id: u32,
    /// Cosine distance of the R-SOLiDs, in [0, 1].
    pub distance: f32,
}

/// Makes an empty database for descriptors of `config` (copied) in `*out`; release it with
/// [`solid_database_free`].
#[no_mangle]
pub unsafe extern "C" fn solid_database_new(
    config: *const SolidConfig,
    out_database: *mut *mut SolidDatabase,
) -> SolidStatus {
    new_handle("solid_database_new", out_database, "out_database", || {
        Ok(Database::new(nonnull(config, "config")?.cfg)?.into())
    })
}

/// Releases a database (NULL: nothing).
#[no_mangle]
pub unsafe extern "C" fn solid_database_free(database: *mut SolidDatabase) {
    release(database);
}

/// Reads a database file written by [`solid_database_save`] (or the Python and Rust APIs) into
/// `*out`. A foreign, truncated or corrupted file is refused (`SOLID_STATUS_FORMAT`).
#[no_mangle]
pub unsafe extern "C" fn solid_database_load(
    path: *const c_char,
    out_database: *mut *mut SolidDatabase,
) -> SolidStatus {
    new_handle("solid_database_load", out_database, "out_database", || {
        Ok(Database::load(string(path, "path")?)?.into())
    })
}

/// Writes the database to `path` atomically (a temporary file renamed over it: a crash leaves
/// the old file or the new one, whole). Only a regular file is replaced: a FIFO, a device, a
/// socket or a directory at `path` is refused (`SOLID_STATUS_IO`) and left as it is.
#[no_mangle]
pub unsafe extern "C" fn solid_database_save(
    database: *const SolidDatabase,
    path: *const c_char,
) -> SolidStatus {
    guard("solid_database_save", || {
        let d = nonnull(database, "database")?;
        read(&d.db)?.save(string(path, "path")?)?;
        Ok(())
    })
}

/// Number of entries.
#[no_mangle]
pub unsafe extern "C" fn solid_database_len(
    database: *const SolidDatabase,
    len: *mut usize,
) -> SolidStatus {
    guard("solid_database_len", || {
        let n = read(&nonnull(database, "database")?.db)?.len();
        put(len, "len", n)
    })
}

/// Adds a place: its R-SOLiD (`r_len` = `n_range` values) and A-SOLiD (`a_len` = `n_azimuth`
/// values) from `solid_describe` with this database's configuration, its `session` (robot or
/// run), `timestamp` (seconds; NaN: none) and `pose` (NULL, or `T_world_sensor` as a row-major
/// 4x4: 16 doubles). Writes its id to `*id` when `id` is not NULL. On error nothing is added.
#[no_mangle]
pub unsafe extern "C" fn solid_database_add(
    database: *const SolidDatabase,
    r: *const f32,
    r_len: usize,
    a: *const f32,
    a_len: usize,
    session: u32,
    timestamp: f64,
    pose: *const f64,
    id: *mut u32,
) -> SolidStatus {
    guard("solid_database_add", || {
        let d = nonnull(database, "database")?;
        let (r, a) = (slice(r, r_len, "r")?, slice(a, a_len, "a")?);
        let pose = optional_pose(pose, "pose")?;
        let new = Arc::make_mut(&mut *write(&d.db)?).add_vectors(r, a, session, timestamp, pose)?;
        if let Some(id) = id.as_mut() {
            *id = new;
        }
        Ok(())
    })
}

/// The `k` entries nearest to the R-SOLiD `r` (`r_len` = `n_range` values), nearest first, ties
/// by lower id, skipping the `exclude_recent` most recently added: writes up to `k` neighbours to
/// `neighbors` (room for `k`) and their number to `*found`. Exact at every size.
#[no_mangle]
pub unsafe extern "C" fn solid_database_search(
    database: *const SolidDatabase,
    r: *const f32,
    r_len: usize,
    k: usize,
    exclude_recent: usize,
    neighbors: *mut SolidNeighbor,
    found: *mut usize,
) -> SolidStatus {
    guard("solid_database_search", || {
        let d = nonnull(database, "database")?;
        let r = slice(r, r_len, "r")?;
        let dst = slice_mut(neighbors, k, "neighbors")?;
        let found = out(found, "found")?;
        let hits = read(&d.db)?.search(r, k, exclude_recent, Method::Auto)?;
        for (o, h) in dst.iter_mut().zip(&hits) {
            *o = SolidNeighbor {
                id: h.id,
                distance: h.distance,
            };
        }
        *found = hits.len();
        Ok(())
    })
}

/// What the database holds about entry `id`: its session, timestamp (NaN: none) and, when `pose`
/// is not NULL, its pose as a row-major 4x4 (16 doubles; all NaN when it has none).
#[no_mangle]
pub unsafe extern "C" fn solid_database_entry(
    database: *const SolidDatabase,
    id: u32,
    session: *mut u32,
    timestamp: *mut f64,
    pose: *mut f64,
) -> SolidStatus {
    guard("solid_database_entry", || {
        let d = nonnull(database, "database")?;
        let db = read(&d.db)?;
        let place = |i: u32| {
            let k = i as usize;
            (db.sessions()[k], db.timestamps()[k], db.pose(i))
        };
        entry(db.len(), id, place, session, timestamp, pose)
    })
}

/// Writes what a database of `len` places holds about place `id` (see
/// [`solid_database_entry`]): `place(id)` gives its session, timestamp and pose.
pub(crate) unsafe fn entry(
    len: usize,
    id: u32,
    place: impl FnOnce(u32) -> (u32, f64, Option<[f64; 12]>),
    session: *mut u32,
    timestamp: *mut f64,
    pose: *mut f64,
) -> Result<(), Failure> {
    if id as usize >= len {
        return Err(Failure::arg(format!(
            "id {id} out of range: the database has {len} entries"
        )));
    }
    let (s, t) = (out(session, "session")?, out(timestamp, "timestamp")?);
    let p = slice_mut(pose, if pose.is_null() { 0 } else { 16 }, "pose")?;
    let (place_session, place_time, place_pose) = place(id);
    (*s, *t) = (place_session, place_time);
    if !p.is_empty() {
        match place_pose {
            Some(m) => {
                p[..12].copy_from_slice(&m);
                p[12..].copy_from_slice(&[0.0, 0.0, 0.0, 1.0]);
            }
            None => p.fill(f64::NAN),
        }
    }
    Ok(())
}

/// A pose argument: NULL, or a row-major 4x4 rigid transform.
pub(crate) unsafe fn optional_pose(
    pose: *const f64,
    name: &str,
) -> Result<Option<[f64; 12]>, Failure> {
    if pose.is_null() {
        return Ok(None);
    }
    let m: &[f64; 16] = &*pose.cast();
    pose_3x4(m, name).map(Some)
}
