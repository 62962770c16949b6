//! [`SolidDetector`]: online loop closure. Each scan is described (and, when verification is on,
//! its cloud prepared), searched against the earlier places except the most recent ones, and
//! added; a loop carries the candidate, the distance and, when verified by registration, the pose
//! `T_query_candidate` with an information matrix for a pose graph.

use std::ffi::c_char;
use std::sync::{Arc, RwLock};

use solid_lidar::db::{
    Database, Detection, Loop, LoopDetector, MapAnchor, PlacementChange, PoseSource, Scan,
};

use crate::config::{SolidConfig, SolidDetectorConfig};
use crate::database::{entry, optional_pose, SolidDatabase};
use crate::{flat_pose, guard, new_handle, nonnull, out, points, put, read, release, slice_mut};
use crate::{string, with_points, write};
use crate::{Failure, SolidPoints, SolidStatus};

/// A loop detector and its database of places.
///
/// Threads: may be shared. [`solid_detector_prepare`] runs in parallel with other prepares and
/// reads; adding a scan waits for them and runs alone (the steps of one detector are ordered).
pub struct SolidDetector {
    det: RwLock<LoopDetector>,
    /// What the latest step reported beside its loop (None before the first), written while
    /// the step holds `det` for writing.
    last: RwLock<Option<LastStep>>,
}

/// The latest step's report: [`solid_detector_last_step`] and [`solid_detector_released`].
struct LastStep {
    step: SolidStep,
    released: Vec<SolidLoop>,
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

/// Where a step's pose came from ([`SolidStep`]).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolidPoseSource {
    /// The step had no pose: none was given and the detector's own odometry had none
    /// (verification off, or a link it could not make: the scan is related to no place).
    None = 0,
    /// The caller gave it.
    Given = 1,
    /// The detector's own odometry (without the caller's pose): the scan registered with the
    /// previous keyframe of its session and chained onto that keyframe's pose.
    Chained = 2,
    /// The detector's own odometry starts a frame here (the identity): the session's first scan
    /// without a pose, or the first after a link that failed. No odometry relates this frame to
    /// the places before it.
    Started = 3,
}

/// What a step did to the session's placement in its prior map ([`SolidStep`]).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolidPlacement {
    /// Nothing.
    None = 0,
    /// The session was placed in the map (its first placement, [`solid_detector_map_anchor`]).
    Placed = 1,
    /// A larger consistent set of loops that disagrees with the placement replaced it.
    Revised = 2,
}

/// What a detector step reported beside its loop ([`solid_detector_last_step`]).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct SolidStep {
    /// Id of the step's query (the scan it added).
    pub query: u32,
    /// Where `pose` came from.
    pub pose_source: SolidPoseSource,
    /// The pose `T_world_sensor` (row-major 4x4) the step's checks used for the query: the
    /// caller's or, without one, the detector's own odometry (docs/loops.md#without-poses);
    /// NaN when `pose_source` is `SOLID_POSE_SOURCE_NONE`.
    pub pose: [f64; 16],
    /// Whether the step placed the session in the map or revised the placement.
    pub placement: SolidPlacement,
    /// Number of loops of earlier queries this step released ([`solid_detector_released`] gives
    /// them): loops into the map held until a placement agreed with them, loops the
    /// neighbours' vouching waited for, and loops of candidates an earlier step's budget
    /// deferred to this one.
    pub released: usize,
    /// Number of this step's candidates its budget (`verify_step_points`) deferred: not
    /// registered yet; the next steps register them and release a loop of theirs (0 when the
    /// step found its loop).
    pub deferred: usize,
}

impl SolidStep {
    fn from_detection(d: &Detection) -> SolidStep {
        let pose_source = match d.pose_source {
            Some(PoseSource::Given) => SolidPoseSource::Given,
            Some(PoseSource::Chained) => SolidPoseSource::Chained,
            Some(PoseSource::Started) => SolidPoseSource::Started,
            None => SolidPoseSource::None,
        };
        let mut pose = [f64::NAN; 16];
        if let Some(m) = &d.pose {
            pose[..12].copy_from_slice(m);
            pose[12..].copy_from_slice(&[0.0, 0.0, 0.0, 1.0]);
        }
        SolidStep {
            query: d.query,
            pose_source,
            pose,
            placement: match d.placement {
                Some(PlacementChange::Placed) => SolidPlacement::Placed,
                Some(PlacementChange::Revised) => SolidPlacement::Revised,
                None => SolidPlacement::None,
            },
            released: d.released.len(),
            deferred: d.deferred.len(),
        }
    }
}

/// Where the detector's session lies in its prior map ([`solid_detector_map_anchor`]): the
/// placement that mutually consistent loops into the map support (docs/spec.md §8).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct SolidMapAnchor {
    /// `T_map_world`, row-major 4x4: maps the session's pose frame ("odom") into the map's
    /// frame, fitted to the latest supporting loops.
    pub transform: [f64; 16],
    /// Distinct queries that support it: those of the set of registrations into the map that placed
    /// it (one the gate turned down counts when it agrees) and of the loops accepted on it since.
    pub loops: usize,
    /// Metres of the session's path they span.
    pub metres: f64,
    /// Id of the first supporting query.
    pub first_query: u32,
    /// Id of the latest supporting query.
    pub last_query: u32,
    /// The spread of the supporting loops' placements about `transform`: 6x6 row-major,
    /// rotation (radians) first, then translation (metres); NaN with fewer than two loops.
    pub covariance: [f64; 36],
}

impl SolidMapAnchor {
    fn from_anchor(a: &MapAnchor) -> SolidMapAnchor {
        SolidMapAnchor {
            transform: flat_pose(&a.transform),
            loops: a.loops,
            metres: a.metres,
            first_query: a.first_query,
            last_query: a.last_query,
            covariance: a.covariance.as_ref().map_or([f64::NAN; 36], flat6),
        }
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
            last: RwLock::new(None),
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
    let mut det = write(&d.det)?;
    let detection = det.detect_scan(scan, timestamp, pose)?;
    *write(&d.last)? = Some(LastStep {
        step: SolidStep::from_detection(&detection),
        released: detection
            .released
            .iter()
            .map(SolidLoop::from_loop)
            .collect(),
    });
    drop(det);
    if let Some(f) = found.as_mut() {
        *f = detection.accepted.is_some();
    }
    if let (Some(lp), Some(o)) = (&detection.accepted, loop_out.as_mut()) {
        *o = SolidLoop::from_loop(lp);
    }
    Ok(())
}

/// What the latest step on this detector reported beside its loop (see [`SolidStep`]): the
/// pose its checks used and where it came from, what it did to the placement in the map, how
/// many held loops it released. Steps run one at a time; with several threads adding, "latest"
/// is the last one to finish. Fails (`SOLID_STATUS_INVALID_ARGUMENT`) before the first step.
#[no_mangle]
pub unsafe extern "C" fn solid_detector_last_step(
    detector: *const SolidDetector,
    step: *mut SolidStep,
) -> SolidStatus {
    guard("solid_detector_last_step", || {
        let d = nonnull(detector, "detector")?;
        let o = out(step, "step")?;
        let last = read(&d.last)?;
        let l = last
            .as_ref()
            .ok_or_else(|| Failure::arg("no scan was added yet"))?;
        *o = l.step;
        Ok(())
    })
}

/// The loops that the latest step released (`SolidStep.released` of them, in query order):
/// loops of earlier queries, held until the session's placement in the map (or its revision)
/// found them consistent with it, until their neighbours vouched for them, or deferred by their
/// step's budget (docs/spec.md §8). Each is that earlier query's
/// loop, as the step's own loop is the step's; a pose graph adds them as it adds the others.
/// Writes them to `loops` (room for `capacity`) and their number to `*count`; a `capacity`
/// below their number is `SOLID_STATUS_BUFFER_TOO_SMALL` (the message says how many). They are
/// kept until the next step.
#[no_mangle]
pub unsafe extern "C" fn solid_detector_released(
    detector: *const SolidDetector,
    loops: *mut SolidLoop,
    capacity: usize,
    count: *mut usize,
) -> SolidStatus {
    guard("solid_detector_released", || {
        let d = nonnull(detector, "detector")?;
        let last = read(&d.last)?;
        let released = last.as_ref().map_or(&[][..], |l| &l.released[..]);
        if capacity < released.len() {
            return Err(Failure::new(
                SolidStatus::BufferTooSmall,
                format!(
                    "the step released {} loops: loops has room for {capacity}",
                    released.len()
                ),
            ));
        }
        let n = out(count, "count")?;
        slice_mut(loops, released.len(), "loops")?.copy_from_slice(released);
        *n = released.len();
        Ok(())
    })
}

/// The session's placement in the detector's prior map: when mutually consistent loops into
/// the map have placed it, `*placed` is true and `*anchor` holds the placement; otherwise
/// `*placed` is false and `*anchor` is not written (NULL allowed then). Without a map, never
/// placed. A step that places or revises it says so in `SolidStep.placement`.
#[no_mangle]
pub unsafe extern "C" fn solid_detector_map_anchor(
    detector: *const SolidDetector,
    anchor: *mut SolidMapAnchor,
    placed: *mut bool,
) -> SolidStatus {
    guard("solid_detector_map_anchor", || {
        let a = read(&nonnull(detector, "detector")?.det)?.map_anchor();
        let p = out(placed, "placed")?;
        if let Some(a) = &a {
            *out(anchor, "anchor")? = SolidMapAnchor::from_anchor(a);
        }
        *p = a.is_some();
        Ok(())
    })
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
