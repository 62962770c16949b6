//! [`SolidDetector`]: online loop closure. Each scan is described (and, when verification is on,
//! its cloud prepared), searched against the earlier places except the most recent ones, and
//! added; a loop carries the candidate, the distance and, when verified by registration, the pose
//! `T_query_candidate` with an information matrix for a pose graph.

use std::ffi::c_char;
use std::sync::{Arc, RwLock};

use solid_lidar::db::{Database, Loop, LoopDetector, Scan};

use crate::config::{SolidConfig, SolidDetectorConfig};
use crate::database::{entry, optional_pose, SolidDatabase};
use crate::{flat_pose, guard, new_handle, nonnull, out, points, put, read, release, string};
use crate::{with_points, write};
use crate::{Failure, SolidPoints, SolidStatus};

/// A loop detector and its database of places.
///
/// Threads: may be shared. [`solid_detector_prepare`] runs in parallel with other prepares and
/// reads; adding a scan waits for them and runs alone (the steps of one detector are ordered).
pub struct SolidDetector {
    det: RwLock<LoopDetector>,
}

/// A scan described and prepared by [`solid_detector_prepare`], ready for
/// [`solid_detector_add_scan`] on the same detector.
///
/// Threads: owned by one thread at a time; it may be handed to another thread.
pub struct SolidScan {
    scan: Scan,
}

/// One detected loop closure.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct SolidLoop {
    /// Id of the query place (the scan just added).
    pub query: u32,
    /// Id of the matched earlier place.
    pub candidate: u32,
    /// Cosine distance of the R-SOLiDs (docs/spec.md §3).
    pub distance: f64,
    /// Heading of the query relative to the candidate, degrees in (-180, 180]: the yaw of `pose`
    /// when verified, else the A-SOLiD estimate.
    pub heading_deg: f64,
    /// The score the loop was accepted with: the distance, or with verification `|t| / (1 + |t|)`
    /// (the loop's length mapped into [0, 1)).
    pub score: f64,
    /// Whether registration verified the loop; `pose`, `information`, `fitness` and `rmse` are
    /// NaN when it did not.
    pub verified: bool,
    /// `T_query_candidate`, row-major 4x4: `p_query = pose * p_candidate` (points in the
    /// sensor frames of the two scans). A pose-graph factor between the places' poses
    /// `T_world_query` and `T_world_candidate` measures `inv(T_world_query) * T_world_candidate`.
    pub pose: [f64; 16],
    /// The 6x6 information matrix of `pose`, row-major, translation first (x, y, z, then
    /// rotation about x, y, z in radians: g2o's order; GTSAM's Pose3 puts rotation first), for
    /// the error `Exp(xi) = inv(pose) * inv(T_world_query) * T_world_candidate` (on the right of
    /// the measurement, as g2o's EDGE_SE3:QUAT and GTSAM's BetweenFactor): the registration's
    /// Gauss-Newton Hessian carried over and scaled so that true loops' errors weigh as chi-square
    /// with 6 degrees of freedom (docs/slam.md), the same matrix as `solid detect --g2o` writes.
    pub information: [f64; 36],
    /// Overlap of the registered clouds, in [0, 1].
    pub fitness: f64,
    /// Inlier RMSE of the registration (metres).
    pub rmse: f64,
}

impl SolidLoop {
    fn from_loop(lp: &Loop) -> SolidLoop {
        let mut out = SolidLoop {
            query: lp.query,
            candidate: lp.candidate,
            distance: lp.distance,
            heading_deg: lp.heading_deg,
            score: lp.score,
            verified: false,
            pose: [f64::NAN; 16],
            information: [f64::NAN; 36],
            fitness: f64::NAN,
            rmse: f64::NAN,
        };
        if let Some(pose) = &lp.pose {
            let rmse = lp.rmse.unwrap_or(0.0);
            if let Some(info) = &lp.information {
                out.information = flat6(info);
            }
            out.verified = true;
            out.pose = flat_pose(pose);
            out.fitness = lp.fitness.unwrap_or(f64::NAN);
            out.rmse = rmse;
        }
        out
    }
}

/// A row-major 6×6 matrix as 36 numbers.
fn flat6(m: &[[f64; 6]; 6]) -> [f64; 36] {
    core::array::from_fn(|k| m[k / 6][k % 6])
}

impl From<LoopDetector> for SolidDetector {
    fn from(det: LoopDetector) -> SolidDetector {
        SolidDetector {
            det: RwLock::new(det),
        }
    }
}

/// Makes a detector with an empty database for scans described with `config`, with the
/// parameters `detector_config` (both copied), in `*out`; release it with
/// [`solid_detector_free`].
#[no_mangle]
pub unsafe extern "C" fn solid_detector_new(
    config: *const SolidConfig,
    detector_config: *const SolidDetectorConfig,
    out_detector: *mut *mut SolidDetector,
) -> SolidStatus {
    new_handle("solid_detector_new", out_detector, "out_detector", || {
        let cfg = nonnull(config, "config")?.cfg;
        let dcfg = nonnull(detector_config, "detector_config")?.cfg;
        Ok(LoopDetector::new(cfg, dcfg)?.into())
    })
}

/// Makes a detector over `database` (a prior map, other sessions), sharing its places without
/// copying them: they are candidates from the first scan on and never excluded as recent; the
/// detector's scans form a new session and are kept by the detector, apart from `database`,
/// which stays as it was (an add to it afterwards does not reach the detector).
#[no_mangle]
pub unsafe extern "C" fn solid_detector_from_database(
    database: *const SolidDatabase,
    detector_config: *const SolidDetectorConfig,
    out_detector: *mut *mut SolidDetector,
) -> SolidStatus {
    new_handle(
        "solid_detector_from_database",
        out_detector,
        "out_detector",
        || {
            let dcfg = nonnull(detector_config, "detector_config")?.cfg;
            let map = shared_indexed(nonnull(database, "database")?)?;
            Ok(LoopDetector::with_map(map, dcfg)?.into())
        },
    )
}

/// The database's places to share with a detector, its index built first in place (a detector
/// searches on every step), so that the detector does not copy them to build it.
fn shared_indexed(d: &SolidDatabase) -> Result<Arc<Database>, Failure> {
    let mut db = write(&d.db)?;
    if db.index_pending() > 0 {
        Arc::make_mut(&mut db).build_index()?;
    }
    Ok(Arc::clone(&db))
}

/// Releases a detector (NULL: nothing).
#[no_mangle]
pub unsafe extern "C" fn solid_detector_free(detector: *mut SolidDetector) {
    release(detector);
}

/// Describes a scan and, when verification is on, prepares its cloud: the heavy part of a step,
/// which may run on any thread while the detector adds other scans. Writes the scan to `*out`:
/// pass it to [`solid_detector_add_scan`] or release it with [`solid_scan_free`].
#[no_mangle]
pub unsafe extern "C" fn solid_detector_prepare(
    detector: *const SolidDetector,
    points_in: *const SolidPoints,
    out_scan: *mut *mut SolidScan,
) -> SolidStatus {
    new_handle("solid_detector_prepare", out_scan, "out_scan", || {
        let scan = prepare(nonnull(detector, "detector")?, points_in)?;
        Ok(SolidScan { scan })
    })
}

unsafe fn prepare(d: &SolidDetector, points_in: *const SolidPoints) -> Result<Scan, Failure> {
    let pts = points(points_in)?;
    let det = read(&d.det)?;
    Ok(with_points!(pts, |p| det.prepare_scan(p))?)
}

/// Releases a prepared scan that was not added (NULL: nothing).
#[no_mangle]
pub unsafe extern "C" fn solid_scan_free(scan: *mut SolidScan) {
    release(scan);
}

/// One step with a prepared scan: searches it against the eligible places, verifies the best
/// candidates when verification is on, and adds it. `timestamp` is seconds (NaN: none); `pose`
/// NULL or `T_world_sensor` as a row-major 4x4 (16 doubles; stored with the place and used by `exclude_meters`).
/// `scan` is consumed, even on error. When a loop is found, `*found` is true and `*loop_out`
/// holds it; otherwise `*found` is false and `*loop_out` is not written (either may be NULL).
/// On error nothing is added.
#[no_mangle]
pub unsafe extern "C" fn solid_detector_add_scan(
    detector: *mut SolidDetector,
    scan: *mut SolidScan,
    timestamp: f64,
    pose: *const f64,
    loop_out: *mut SolidLoop,
    found: *mut bool,
) -> SolidStatus {
    // Taken first, so that the scan is released on every path.
    let scan = if scan.is_null() {
        None
    } else {
        Some(Box::from_raw(scan))
    };
    guard("solid_detector_add_scan", || {
        let d = nonnull(detector, "detector")?;
        let scan = scan.ok_or_else(|| Failure::arg("scan is NULL"))?.scan;
        step(d, scan, timestamp, pose, loop_out, found)
    })
}

/// One step with the scan's points: [`solid_detector_prepare`] then
/// [`solid_detector_add_scan`] (see both).
#[no_mangle]
pub unsafe extern "C" fn solid_detector_add(
    detector: *mut SolidDetector,
    points_in: *const SolidPoints,
    timestamp: f64,
    pose: *const f64,
    loop_out: *mut SolidLoop,
    found: *mut bool,
) -> SolidStatus {
    guard("solid_detector_add", || {
        let d = nonnull(detector, "detector")?;
        let scan = prepare(d, points_in)?;
        step(d, scan, timestamp, pose, loop_out, found)
    })
}

unsafe fn step(
    d: &SolidDetector,
    scan: Scan,
    timestamp: f64,
    pose: *const f64,
    loop_out: *mut SolidLoop,
    found: *mut bool,
) -> Result<(), Failure> {
    let pose = optional_pose(pose, "pose")?;
    let detection = write(&d.det)?.detect_scan(scan, timestamp, pose)?;
    if let Some(f) = found.as_mut() {
        *f = detection.accepted.is_some();
    }
    if let (Some(lp), Some(o)) = (&detection.accepted, loop_out.as_mut()) {
        *o = SolidLoop::from_loop(lp);
    }
    Ok(())
}

/// Number of places (a prior map's and every scan added).
#[no_mangle]
pub unsafe extern "C" fn solid_detector_len(
    detector: *const SolidDetector,
    len: *mut usize,
) -> SolidStatus {
    guard("solid_detector_len", || {
        let n = read(&nonnull(detector, "detector")?.det)?.len();
        put(len, "len", n)
    })
}

/// The session of the scans this detector adds, and the id of its first scan (the number of
/// places of a prior map).
#[no_mangle]
pub unsafe extern "C" fn solid_detector_session(
    detector: *const SolidDetector,
    session: *mut u32,
    first_id: *mut usize,
) -> SolidStatus {
    guard("solid_detector_session", || {
        let det = read(&nonnull(detector, "detector")?.det)?;
        let (s, f) = (out(session, "session")?, out(first_id, "first_id")?);
        (*s, *f) = (det.session(), det.session_start());
        Ok(())
    })
}

/// What the detector's database holds about place `id` (see `solid_database_entry`).
#[no_mangle]
pub unsafe extern "C" fn solid_detector_entry(
    detector: *const SolidDetector,
    id: u32,
    session: *mut u32,
    timestamp: *mut f64,
    pose: *mut f64,
) -> SolidStatus {
    guard("solid_detector_entry", || {
        let det = read(&nonnull(detector, "detector")?.det)?;
        let place = |i: u32| {
            let (s, t) = det.entry(i);
            (s, t, det.pose(i))
        };
        entry(det.len(), id, place, session, timestamp, pose)
    })
}

/// Writes the detector's database (every place, with the clouds of verification) to `path`, as
/// `solid_database_save`: a map that `solid_database_load` and `solid_detector_from_database`
/// read back. The prior map's descriptors are copied for the time of the call.
#[no_mangle]
pub unsafe extern "C" fn solid_detector_save(
    detector: *const SolidDetector,
    path: *const c_char,
) -> SolidStatus {
    guard("solid_detector_save", || {
        let det = read(&nonnull(detector, "detector")?.det)?;
        det.to_database()?.save(string(path, "path")?)?;
        Ok(())
    })
}
