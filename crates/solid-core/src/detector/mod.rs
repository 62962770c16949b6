//! [`LoopDetector`]: online loop closure over a [`Database`].
//!
//! Each scan is searched against the places added before it, except the most recent ones of its
//! own session ([`DetectorConfig`]: by frames, by metres travelled and by seconds; [spec §5](crate::spec#5-evaluating-loop-closure-against-poses)), then
//! added. Places of other sessions (a prior map, another robot) are never excluded. Every step
//! returns its ranked [`Candidate`]s, so that an evaluation scores exactly what the detector
//! decided ([`crate::eval`]).

use alloc::collections::{BTreeMap, VecDeque};
use alloc::sync::Arc;
use alloc::vec;
use alloc::vec::Vec;

use crate::compare::aligned_distance;
use crate::db::{check_pose, entry_limit, visible_own_places};
use crate::db::{Database, DbError, Method, SearchOptions};
use crate::reg::{self, PreparedCloud, Registration, Rejection};
use crate::{heading_refined, Config, Descriptor, Error};
use crate::{Coord, Points};

mod config;
pub use config::*;

mod anchor;
mod breaks;
mod chain;
mod consistency;
mod defer;
mod nearby;
mod verify;

pub use chain::PoseSource;
pub use consistency::MapAnchor;
pub use defer::{DEFERRED_QUERIES, DEFERRED_STEPS};
pub use verify::{path_arm, rotation_displacement, UNVERIFIED_SCORE, VERIFIED_THRESHOLD};

/// One candidate of a detector step, in the detector's ranking order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Id of the database entry.
    pub id: u32,
    /// Cosine distance of the R-SOLiDs ([spec §3](crate::spec#3-comparing-descriptors)).
    pub distance: f64,
    /// Heading of the query relative to this candidate, degrees in `(−180, 180]` ([spec §3](crate::spec#3-comparing-descriptors),
    /// refined).
    pub heading_deg: f64,
    /// What ranks the candidates and what a precision-recall curve sweeps: the R-SOLiD distance,
    /// or with verification the score of [`VerifyConfig`].
    pub score: f64,
    /// The registration of this candidate, when it was verified.
    pub verification: Option<Verification>,
}

/// The outcome of verifying one candidate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Verification {
    /// The best registration over the initial yaws tried.
    pub registration: Registration,
    /// Whether it passed the gate.
    pub accepted: bool,
    /// Why the gate rejected it.
    pub rejection: Option<Rejection>,
    /// Initial yaws tried.
    pub hypotheses: usize,
    /// How many of them reached the best pose.
    pub agreement: usize,
}

/// One detected loop closure: the best candidate of a step, when its score passes the threshold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Loop {
    /// Id of the query (the entry the step added; for [`LoopDetector::query`], the id it would
    /// get, `len()`).
    pub query: u32,
    /// Id of the matched database entry.
    pub candidate: u32,
    /// Cosine distance of the R-SOLiDs ([spec §3](crate::spec#3-comparing-descriptors)).
    pub distance: f64,
    /// Heading of the query relative to the candidate, degrees in `(−180, 180]` ([spec §3](crate::spec#3-comparing-descriptors),
    /// refined).
    pub heading_deg: f64,
    /// The score the loop was accepted with (see [`Candidate::score`]).
    pub score: f64,
    /// The metric pose `T_query_candidate` (`p_query ≈ T·p_candidate`, SPEC §3) of a verified
    /// loop; `heading_deg` is its yaw.
    pub pose: Option<reg::Pose>,
    /// Overlap of a verified loop's registration ([`Registration::fitness`]).
    pub fitness: Option<f64>,
    /// Inlier RMSE (metres) of a verified loop's registration.
    pub rmse: Option<f64>,
    /// The information matrix of `pose` for a pose graph ([`Registration::information`]).
    pub information: Option<reg::Information>,
}

/// Everything one detector step decided.
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    /// Id of the query.
    pub query: u32,
    /// The candidates were drawn from the entries `0..eligible` (the others were excluded as
    /// too recent); 0 means the step had no database to search.
    pub eligible: u32,
    /// Up to `top_k` candidates, best first; with verification and a pose, also the places
    /// chosen by pose ([`VerifyConfig::pose_candidates`]).
    pub candidates: Vec<Candidate>,
    /// The loop, when the best candidate's score is at most the threshold.
    pub accepted: Option<Loop>,
    /// Loops of earlier queries reported late, in query order: loops into the map held until
    /// this step's placement of the session in the map (or its revision) found them consistent
    /// with it (spec §8, placement), loops the neighbours' vouching waited for, loops the
    /// previous steps did not support that a later step's loop agrees with (spec §8, support),
    /// and the loops of candidates a step's budget deferred to this one
    /// ([`VerifyConfig::step_points`]).
    pub released: Vec<Loop>,
    /// The candidates (ids) this step's budget deferred ([`VerifyConfig::step_points`]): not
    /// registered yet (`verification` None among `candidates`), registered by the next steps,
    /// and a loop of theirs is reported with the step that registers it (`released`). Empty
    /// when the step found its loop (the query needs no other).
    pub deferred: Vec<u32>,
    /// Whether this step placed the session in the map, or revised the placement.
    pub placement: Option<PlacementChange>,
    /// The pose `T_world_sensor` (row-major 3×4) the step's checks used for the query: the
    /// caller's, or without one the detector's own odometry ([`PoseSource`], spec §8); None when
    /// the step had neither (verification off, or no cloud).
    pub pose: Option<[f64; 12]>,
    /// Where `pose` came from.
    pub pose_source: Option<PoseSource>,
}

/// What a detector step did to the session's placement in its map ([`LoopDetector::map_anchor`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlacementChange {
    /// The session was placed (its first placement).
    Placed,
    /// A larger consistent set that disagrees with the placement replaced it.
    Revised,
}

/// The loop of candidate `c` for `query` (its registration when it passed the gate, which
/// gives a verified loop its score and heading, as the step's ranking does).
fn loop_of(c: &Candidate, query: u32) -> Loop {
    let reg = c
        .verification
        .filter(|v| v.accepted)
        .map(|v| v.registration);
    Loop {
        query,
        candidate: c.id,
        distance: c.distance,
        heading_deg: reg.map_or(c.heading_deg, |r| r.yaw_degrees()),
        score: reg.map_or(c.score, |r| verify::loop_length_score(&r)),
        pose: reg.map(|r| r.pose),
        fitness: reg.map(|r| r.fitness),
        rmse: reg.map(|r| r.rmse),
        information: reg.map(|r| r.information()),
    }
}

/// An online loop-closure detector (see the module documentation).
#[derive(Debug, Clone)]
pub struct LoopDetector {
    /// The prior map (ids `0..session_start`): shared, never changed by the detector.
    map: Arc<Database>,
    /// The places this detector added (ids from `session_start` on, `session_start` less here;
    /// look a place up by its id through [`LoopDetector::part`]).
    own: Database,
    config: DetectorConfig,
    /// Session of the scans this detector adds.
    session: u32,
    /// Id of the first entry of the own session (the prior map's length): entries below it are
    /// never excluded.
    session_start: usize,
    /// Metres travelled along the own session's path at each of its entries (NaN before its
    /// first pose).
    travelled: Vec<f64>,
    /// The latest timestamp of the own session at each of its entries (NaN before its first).
    latest_time: Vec<f64>,
    /// Where the own session's path stands after its last entry.
    trail: Trail,
    /// Prepared clouds of recent places, for verification (least recently used evicted).
    prepared: BTreeMap<u32, (u64, Arc<PreparedCloud>)>,
    /// Bytes held by `prepared`.
    prepared_bytes: usize,
    /// Use counter for `prepared`.
    clock: u64,
    /// The candidates (id, pose) that passed the gate and the odometry check in each of the
    /// last `support_window` steps, by query id: the support of the next loops.
    recent: VecDeque<(u32, Vec<(u32, reg::Pose)>)>,
    /// The latest loop accepted with poses: later steps' odometry checks go through it.
    anchor: Option<anchor::Anchor>,
    /// The session's placement in its map (loops into the map's places).
    placement: consistency::Placement,
    /// The own odometry's steps and breaks.
    breaks: breaks::Breaks,
    /// The own odometry: every own place's pose as the checks know it (the caller's or the
    /// chain's) and the frame it is in (`chain::UNLINKED`: a scan the chain could not link).
    known: Vec<Option<([f64; 12], u32)>>,
    /// The chain's state: the current frame and how the last link moved.
    chain: chain::Chain,
    /// Candidates over a step's budget, registered by the next steps.
    deferred: defer::Queue,
    /// The own places each accepted loop between two own places joined, both ways, with the
    /// loop's pose from the first to the second (`T_a←b`): the same place on another pass.
    joined: BTreeMap<u32, Vec<(u32, reg::Pose)>>,
    /// The places joined to the anchor's place ([`LoopDetector::joined_with`]) with the pose from
    /// the anchor's place to each: the anchor's path reaches an earlier pass through them.
    anchor_bases: Vec<(u32, reg::Pose)>,
}

/// One scan ready for a detector step: its descriptor and, for verification, its prepared cloud
/// ([`LoopDetector::prepare_scan`]).
#[derive(Debug, Clone)]
pub struct Scan {
    /// The descriptor.
    pub descriptor: Descriptor,
    /// The prepared cloud (None: the step cannot verify).
    pub cloud: Option<PreparedCloud>,
}

/// What a step needs to know about the query before it is added.
#[derive(Debug, Clone, Copy)]
struct Step {
    timestamp: f64,
    pose: Option<[f64; 12]>,
    /// The session's path after this scan.
    trail: Trail,
}

/// Where a session's path stands: the position of its last pose, the metres travelled through
/// its poses and its latest timestamp (NaN before the first). Scans without a pose (time) leave
/// it as it is, so the values stored per place never decrease.
#[derive(Debug, Clone, Copy)]
struct Trail {
    position: Option<[f64; 3]>,
    travelled: f64,
    clock: f64,
}

impl Trail {
    const START: Trail = Trail {
        position: None,
        travelled: f64::NAN,
        clock: f64::NAN,
    };

    /// The trail after a scan with this timestamp (NaN: none) and pose.
    fn after(self, timestamp: f64, pose: Option<&[f64; 12]>) -> Trail {
        let (position, travelled) = match (pose, self.position) {
            (Some(p), Some(q)) => {
                let (dx, dy, dz) = (p[3] - q[0], p[7] - q[1], p[11] - q[2]);
                let step = libm::sqrt(dx * dx + dy * dy + dz * dz);
                (Some([p[3], p[7], p[11]]), self.travelled + step)
            }
            (Some(p), None) => (Some([p[3], p[7], p[11]]), 0.0),
            (None, _) => (self.position, self.travelled),
        };
        let clock = if timestamp.is_nan() {
            self.clock
        } else {
            timestamp
        };
        Trail {
            position,
            travelled,
            clock,
        }
    }
}

impl LoopDetector {
    /// A detector with an empty database, for scans described with `config`.
    ///
    /// # Errors
    /// [`DbError::Core`] naming the invalid parameter of `config` or `detector`.
    pub fn new(config: Config, detector: DetectorConfig) -> Result<LoopDetector, DbError> {
        LoopDetector::with_database(Database::new(config)?, detector)
    }

    /// A detector over an existing database (a prior map, other sessions): its entries are
    /// candidates from the first step on and are never excluded as recent. The detector's own
    /// scans get the session after the largest one in the database. An index that a bulk add
    /// left behind ([`Database::add_batch`] without `index`) is built first: a detector searches
    /// on every step.
    ///
    /// # Errors
    /// [`DbError::Core`] naming the invalid parameter of `detector`; [`DbError::Full`] when the
    /// database already uses session `u32::MAX`; [`DbError::OutOfMemory`] when the index does
    /// not fit.
    pub fn with_database(
        mut db: Database,
        detector: DetectorConfig,
    ) -> Result<LoopDetector, DbError> {
        db.build_index()?;
        LoopDetector::with_map(Arc::new(db), detector)
    }

    /// [`LoopDetector::with_database`] over a map shared with its other holders, without copying
    /// it: the detector only reads the map and keeps the places it adds apart (searched together
    /// with the map's, ids following them), so the map stays as it was given. A map whose index
    /// is incomplete is indexed first, which copies it when it is shared: build its index
    /// ([`Database::build_index`]) before sharing it.
    ///
    /// # Errors
    /// As [`LoopDetector::with_database`].
    pub fn with_map(
        mut map: Arc<Database>,
        detector: DetectorConfig,
    ) -> Result<LoopDetector, DbError> {
        detector.validate()?;
        let session = match map.sessions().iter().max() {
            None => 0,
            // The session after the map's last must be numbered (below `u32::MAX`), or every
            // step would be refused after it changed the detector.
            Some(&s) => s
                .checked_add(1)
                .filter(|&n| crate::db::check_session(n).is_ok())
                .ok_or(DbError::Full)?,
        };
        if map.index_pending() > 0 {
            Arc::make_mut(&mut map).build_index()?;
        }
        let db = Database::new(*map.config())?;
        Ok(LoopDetector {
            session_start: map.len(),
            map,
            own: db,
            config: detector,
            session,
            travelled: Vec::new(),
            latest_time: Vec::new(),
            trail: Trail::START,
            prepared: BTreeMap::new(),
            prepared_bytes: 0,
            clock: 0,
            recent: VecDeque::new(),
            anchor: None,
            placement: consistency::Placement::default(),
            breaks: breaks::Breaks::default(),
            known: Vec::new(),
            chain: chain::Chain::default(),
            deferred: defer::Queue::default(),
            joined: BTreeMap::new(),
            anchor_bases: Vec::new(),
        })
    }

    /// The prior map the detector was made over (shared, as given: the places the detector adds
    /// are not in it; empty for [`LoopDetector::new`]).
    pub fn map(&self) -> &Arc<Database> {
        &self.map
    }

    /// The places the detector added, in order (place `session_start() + i` is entry `i`).
    pub fn places(&self) -> &Database {
        &self.own
    }

    /// Number of places: the prior map's and every scan added so far.
    pub fn len(&self) -> usize {
        self.session_start + self.own.len()
    }

    /// `true` when the detector has no place at all.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The database of every place (the prior map and every scan added so far) as one new
    /// database: a copy of the descriptors (a loaded map's clouds stay in its file).
    ///
    /// # Errors
    /// [`DbError::OutOfMemory`].
    pub fn to_database(&self) -> Result<Database, DbError> {
        let mut all = Database::clone(&self.map);
        all.merge(&self.own)?;
        Ok(all)
    }

    /// Every place as one database shared without a copy while the detector has added none (the
    /// prior map itself), else [`LoopDetector::to_database`].
    ///
    /// # Errors
    /// As [`LoopDetector::to_database`].
    pub fn shared_database(&self) -> Result<Arc<Database>, DbError> {
        if self.own.is_empty() {
            return Ok(Arc::clone(&self.map));
        }
        self.to_database().map(Arc::new)
    }

    /// Consumes the detector, returning every place as one database (the map is copied only when
    /// someone else still shares it).
    ///
    /// # Errors
    /// As [`LoopDetector::to_database`].
    pub fn into_database(self) -> Result<Database, DbError> {
        let mut all = Arc::try_unwrap(self.map).unwrap_or_else(|m| Database::clone(&m));
        all.merge(&self.own)?;
        Ok(all)
    }

    /// The part of the detector's places that holds place `id`, and its id there.
    fn part(&self, id: u32) -> (&Database, u32) {
        match (id as usize).checked_sub(self.session_start) {
            Some(own) => (&self.own, own as u32),
            None => (&self.map, id),
        }
    }

    /// The pose stored with place `id`, if any: a map place's, or the one the caller gave with
    /// an own place (the pose the detector's own odometry gave a step is its
    /// [`Detection::pose`]).
    pub fn pose(&self, id: u32) -> Option<[f64; 12]> {
        let (db, i) = self.part(id);
        db.pose(i)
    }

    /// The pose the checks use for place `id`: a map place's stored pose; an own place's pose
    /// (the caller's or the own odometry's; None for a scan the chain could not link). Poses on
    /// the two sides of a break of the odometry (a frame the chain started) are related by no
    /// path ([`breaks`]).
    pub(super) fn known_pose(&self, id: u32) -> Option<[f64; 12]> {
        match (id as usize).checked_sub(self.session_start) {
            Some(k) => self
                .known
                .get(k)
                .copied()
                .flatten()
                .filter(|&(_, frame)| frame != chain::UNLINKED)
                .map(|(p, _)| p),
            None => self.map.pose(id),
        }
    }

    /// The session of place `id` and its timestamp (NaN: none).
    ///
    /// # Panics
    /// When `id >= len()`.
    pub fn entry(&self, id: u32) -> (u32, f64) {
        let (db, i) = self.part(id);
        (db.sessions()[i as usize], db.timestamps()[i as usize])
    }

    /// The R-SOLiD of place `id` as stored ([`Database::r`]).
    ///
    /// # Panics
    /// When `id >= len()`.
    pub fn r(&self, id: u32) -> &[f32] {
        let (db, i) = self.part(id);
        db.r(i)
    }

    /// The A-SOLiD of place `id` as stored ([`Database::a`]).
    ///
    /// # Panics
    /// When `id >= len()`.
    pub fn a(&self, id: u32) -> Vec<f32> {
        let (db, i) = self.part(id);
        db.a(i)
    }

    /// The stored cloud of place `id` ([`Database::try_cloud`]).
    ///
    /// # Errors
    /// As [`Database::try_cloud`].
    pub fn try_cloud(&self, id: u32) -> Result<Option<alloc::borrow::Cow<'_, [u8]>>, DbError> {
        let (db, i) = self.part(id);
        db.try_cloud(i)
    }

    /// The parameters.
    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    /// Changes the parameters (the database and the exclusion state are kept).
    ///
    /// # Errors
    /// [`DbError::Core`] naming the invalid parameter; the old parameters stay.
    pub fn set_config(&mut self, detector: DetectorConfig) -> Result<(), DbError> {
        detector.validate()?;
        self.config = detector;
        Ok(())
    }

    /// The session of the scans this detector adds.
    pub fn session(&self) -> u32 {
        self.session
    }

    /// Id of the first scan of the own session (the number of prior-map entries).
    pub fn session_start(&self) -> usize {
        self.session_start
    }

    /// Searches `d` against the eligible places, then adds it. `timestamp` is seconds (NaN:
    /// none); `pose` the row-major 3×4 `T_world_sensor` (stored with the place; needed by
    /// exclusion by metres).
    ///
    /// # Errors
    /// [`DbError::ConfigMismatch`] for a descriptor made with another config;
    /// [`DbError::Core`] for an infinite timestamp, a non-finite pose or one whose 3×3 part is
    /// not a rotation, a missing pose or timestamp that the exclusion needs, a timestamp older
    /// than the previous one when excluding by seconds; otherwise as [`Database::add`]
    /// ([`DbError::Full`] when the place's id would be `u32::MAX` or more, the map's places
    /// counted). On error nothing is added, and the detector is as it was before the call
    /// (its odometry's steps and breaks, its chain, support window, anchor and placement):
    /// everything that refuses a place is checked before the step changes anything. Only a
    /// failure that no input check foresees (out of memory, a map's file that cannot be read)
    /// can leave part of the step behind (its odometry step, the registrations it made).
    pub fn detect(
        &mut self,
        d: &Descriptor,
        timestamp: f64,
        pose: Option<[f64; 12]>,
    ) -> Result<Detection, DbError> {
        self.own.check_fingerprint(d.fingerprint)?;
        self.no_verification("detect")?;
        let step = self.step(timestamp, pose, self.trail)?;
        // The fingerprint is checked above (first, as before the place's other checks).
        self.own.check_vectors(&d.r, &d.a)?;
        self.room(1)?;
        self.detect_checked(d, None, step)
    }

    /// Checks what adding `d`'s place would refuse ([`Database::add_vectors`]: its vectors'
    /// lengths and values), before a step changes anything: a step notes the odometry's step,
    /// links the chain, registers candidates and holds placement hypotheses before it adds
    /// the place, and none of that may stay behind when the add fails.
    fn admit(&self, d: &Descriptor) -> Result<(), DbError> {
        self.own.check_fingerprint(d.fingerprint)?;
        self.own.check_vectors(&d.r, &d.a)
    }

    /// Checks that `n` more places fit: [`DbError::Full`] when the last one's id would be
    /// `u32::MAX` or more (the map's places and the own ones together: the own places' ids follow the
    /// map's).
    fn room(&self, n: usize) -> Result<(), DbError> {
        match self.len().checked_add(n) {
            Some(last) if last < entry_limit() => Ok(()),
            _ => Err(DbError::Full),
        }
    }

    /// Refuses a descriptor-only call when verification is on (it needs the scan's points).
    fn no_verification(&self, what: &'static str) -> Result<(), DbError> {
        if self.config.verify.enabled {
            return Err(Error::InvalidParameter {
                name: "verify",
                value: 1.0,
                expected: match what {
                    "query" => "verification off for query() with a descriptor; with verification on, use query_scan() with the scan's points",
                    _ => "verification off for a descriptor-only step; with verification on, give the scan's points (prepare_scan, then detect_scan / detect_scans)",
                },
            }
            .into());
        }
        Ok(())
    }

    /// Describes a scan and, when verification is on, prepares its cloud: everything a step
    /// needs from the points. Needs only `&self`, so scans can be prepared in parallel.
    ///
    /// # Errors
    /// As [`crate::describe`] and [`PreparedCloud::new`], as [`DbError::Core`].
    pub fn prepare_scan<T: Coord>(&self, points: Points<'_, T>) -> Result<Scan, DbError> {
        let descriptor = crate::Describer::new(*self.own.config())?.describe(points)?;
        let cloud = self.prepare_cloud(points)?;
        Ok(Scan { descriptor, cloud })
    }

    /// The prepared cloud a step needs for verification (None when verification is off).
    ///
    /// # Errors
    /// As [`PreparedCloud::new`], as [`DbError::Core`].
    pub fn prepare_cloud<T: Coord>(
        &self,
        points: Points<'_, T>,
    ) -> Result<Option<PreparedCloud>, DbError> {
        if !self.config.verify.enabled {
            return Ok(None);
        }
        // Deferred: completed when the step registers it, or when it is a candidate later.
        PreparedCloud::deferred(points, &self.config.verify.registration)
            .map(Some)
            .map_err(DbError::from)
    }

    /// [`LoopDetector::detect`] for a prepared scan: with verification on, its best candidates
    /// are registered and its compact cloud is stored with the place.
    ///
    /// # Errors
    /// As [`LoopDetector::detect`].
    pub fn detect_scan(
        &mut self,
        scan: Scan,
        timestamp: f64,
        pose: Option<[f64; 12]>,
    ) -> Result<Detection, DbError> {
        self.detect_scans(alloc::vec![scan], &[timestamp], &[pose])
            .map(|mut v| v.remove(0))
    }

    /// [`LoopDetector::detect_scan`] for many scans in order. Every input is checked before the
    /// first scan is added, so on error nothing is added.
    ///
    /// # Errors
    /// As [`LoopDetector::detect_many`].
    pub fn detect_scans(
        &mut self,
        scans: Vec<Scan>,
        timestamps: &[f64],
        poses: &[Option<[f64; 12]>],
    ) -> Result<Vec<Detection>, DbError> {
        self.detect_scans_each(scans, timestamps, poses, &mut |_| true)
    }

    /// [`LoopDetector::detect_scans`] that calls `each(i)` before step `i` (after every input
    /// was checked): when it returns false, the steps stop there and the detections of the
    /// steps before it are returned (each step is whole). For interrupts and progress.
    ///
    /// # Errors
    /// As [`LoopDetector::detect_many`].
    pub fn detect_scans_each(
        &mut self,
        scans: Vec<Scan>,
        timestamps: &[f64],
        poses: &[Option<[f64; 12]>],
        each: &mut dyn FnMut(usize) -> bool,
    ) -> Result<Vec<Detection>, DbError> {
        let (descriptors, clouds): (Vec<Descriptor>, Vec<Option<PreparedCloud>>) =
            scans.into_iter().map(|s| (s.descriptor, s.cloud)).unzip();
        self.detect_all(&descriptors, clouds, timestamps, poses, each)
    }

    /// [`LoopDetector::detect`] for many scans in order, in one call. Every input is checked
    /// before the first scan is added, so on error nothing is added.
    ///
    /// # Errors
    /// [`DbError::Core`] with [`Error::LengthMismatch`] when `timestamps` or `poses` is neither
    /// empty nor as long as `descriptors`; otherwise as [`LoopDetector::detect`].
    pub fn detect_many(
        &mut self,
        descriptors: &[Descriptor],
        timestamps: &[f64],
        poses: &[Option<[f64; 12]>],
    ) -> Result<Vec<Detection>, DbError> {
        self.no_verification("detect_many")?;
        self.detect_all(descriptors, Vec::new(), timestamps, poses, &mut |_| true)
    }

    fn detect_all(
        &mut self,
        descriptors: &[Descriptor],
        clouds: Vec<Option<PreparedCloud>>,
        timestamps: &[f64],
        poses: &[Option<[f64; 12]>],
        each: &mut dyn FnMut(usize) -> bool,
    ) -> Result<Vec<Detection>, DbError> {
        let n = descriptors.len();
        for (what, len) in [("timestamps", timestamps.len()), ("poses", poses.len())] {
            if len != 0 && len != n {
                return Err(Error::LengthMismatch {
                    what,
                    left: len,
                    right: n,
                }
                .into());
            }
        }
        let mut steps = Vec::new();
        steps
            .try_reserve_exact(n)
            .map_err(|_| DbError::OutOfMemory)?;
        // The time and path checks need the previous scans of this batch.
        let mut trail = self.trail;
        for (i, d) in descriptors.iter().enumerate() {
            self.admit(d)?;
            let t = timestamps.get(i).copied().unwrap_or(f64::NAN);
            let p = poses.get(i).copied().flatten();
            let s = self.step(t, p, trail)?;
            trail = s.trail;
            steps.push(s);
        }
        self.room(n)?;
        let mut out = Vec::new();
        out.try_reserve_exact(n).map_err(|_| DbError::OutOfMemory)?;
        let mut clouds = clouds.into_iter();
        for (i, (d, s)) in descriptors.iter().zip(steps).enumerate() {
            if !each(i) {
                break;
            }
            out.push(self.detect_checked(d, clouds.next().flatten(), s)?);
        }
        Ok(out)
    }

    /// [`LoopDetector::detect`] without the details: the loop, if any (verification off).
    ///
    /// # Errors
    /// As [`LoopDetector::detect`].
    pub fn add(&mut self, d: &Descriptor, timestamp: f64) -> Result<Option<Loop>, DbError> {
        Ok(self.detect(d, timestamp, None)?.accepted)
    }

    /// The candidates `d` would get if it were added now (with this timestamp and pose), without
    /// adding it; at most `k` of them.
    ///
    /// # Errors
    /// As [`LoopDetector::detect`].
    pub fn candidates(
        &self,
        d: &Descriptor,
        k: usize,
        timestamp: f64,
        pose: Option<[f64; 12]>,
    ) -> Result<Vec<Candidate>, DbError> {
        self.own.check_fingerprint(d.fingerprint)?;
        let step = self.step(timestamp, pose, self.trail)?;
        let eligible = self.eligible(&step)?;
        self.rank(&d.r, &d.a, eligible, k)
    }

    /// Searches `d` against every place without adding it (localisation in a prior map): no
    /// place is excluded. Returns the best candidate when its score passes the threshold.
    ///
    /// # Errors
    /// [`DbError::ConfigMismatch`] for a descriptor made with another config.
    pub fn query(&self, d: &Descriptor) -> Result<Option<Loop>, DbError> {
        self.own.check_fingerprint(d.fingerprint)?;
        self.no_verification("query")?;
        let cands = self.rank(&d.r, &d.a, self.len(), self.config.top_k)?;
        Ok(self.accept(&cands, self.len() as u32))
    }

    /// [`LoopDetector::query`] for a prepared scan, verified when verification is on (without
    /// adding the scan).
    ///
    /// # Errors
    /// As [`LoopDetector::query`].
    pub fn query_scan(&mut self, scan: &Scan) -> Result<Option<Loop>, DbError> {
        let d = &scan.descriptor;
        self.own.check_fingerprint(d.fingerprint)?;
        let mut cands = self.rank(&d.r, &d.a, self.len(), self.config.top_k)?;
        if self.config.verify.enabled {
            let n = self.config.verify.candidates;
            self.verify_candidates((&d.r, &d.a), scan.cloud.as_ref(), None, (n, n), &mut cands)?;
        }
        Ok(self.accept(&cands, self.len() as u32))
    }

    /// Checks the timestamp and pose of the next scan (`trail`: the session's path before it)
    /// and works out the path after it.
    fn step(&self, timestamp: f64, pose: Option<[f64; 12]>, trail: Trail) -> Result<Step, DbError> {
        if timestamp.is_infinite() {
            return Err(Error::InvalidParameter {
                name: "timestamp",
                value: timestamp,
                expected: "a finite number of seconds (NaN: none)",
            }
            .into());
        }
        if let Some(p) = &pose {
            check_pose(p)?;
        }
        // Exclusion by seconds needs time to run forward; a scan without one is not checked.
        if self.config.exclude_seconds > 0.0 && timestamp < trail.clock {
            return Err(Error::InvalidParameter {
                name: "timestamp",
                value: timestamp,
                expected: "timestamps that do not decrease within a session (exclude_seconds is on: set it to 0 to ignore time)",
            }
            .into());
        }
        Ok(Step {
            timestamp,
            pose,
            trail: trail.after(timestamp, pose.as_ref()),
        })
    }

    /// Number of entries the step may search: ids `0..eligible` (every other session's, and its
    /// own session's first [`visible_own_places`]).
    fn eligible(&self, s: &Step) -> Result<usize, DbError> {
        let start = self.session_start;
        let c = &self.config;
        Ok(start
            + visible_own_places(
                self.own.len(),
                c.exclude_frames,
                c.exclude_meters,
                c.exclude_seconds,
                // The query's own place on the path, only when it says where (when) it is.
                (
                    &self.travelled,
                    if s.pose.is_some() {
                        s.trail.travelled
                    } else {
                        f64::NAN
                    },
                ),
                (&self.latest_time, s.timestamp),
            ))
    }

    fn detect_checked(
        &mut self,
        d: &Descriptor,
        cloud: Option<PreparedCloud>,
        s: Step,
    ) -> Result<Detection, DbError> {
        // Everything that can refuse the place is checked before the step changes anything
        // (`admit`, `room`); the memory of its records reserved.
        self.travelled
            .try_reserve(1)
            .map_err(|_| DbError::OutOfMemory)?;
        self.latest_time
            .try_reserve(1)
            .map_err(|_| DbError::OutOfMemory)?;
        self.known
            .try_reserve(1)
            .map_err(|_| DbError::OutOfMemory)?;
        let v = self.config.verify;
        let (mut cloud, stored) = match cloud {
            Some(c) if v.enabled => {
                let bytes = reg::encode_cloud(&c.fine.points, v.cloud_grid(), v.cloud_bits)
                    .map_err(DbError::from)?;
                (Some(Arc::new(c)), Some(bytes))
            }
            _ => (None, None),
        };
        // Without the caller's pose, the detector's own odometry (chain.rs).
        let given = s.pose;
        let mut s = s;
        let source = self.odometry_of(&d.a, &mut s, &mut cloud)?;
        let eligible = self.eligible(&s)?;
        // The step into the query, when the odometry could not have made it, is a break (a
        // frame the chain started is one already).
        if s.pose.is_some() && !self.breaks.crossed(self.trail.travelled, s.trail.travelled) {
            let seconds = s.timestamp - self.trail.clock;
            let largest = self.config.verify.gate.max_translation;
            let (before, after) = (self.trail.travelled, s.trail.travelled);
            self.breaks.note(before, after, seconds, largest);
        }
        let mut candidates = self.rank(&d.r, &d.a, eligible, self.config.top_k)?;
        if v.enabled {
            let at = verify::QueryPlace {
                id: self.len() as u32,
                pose: s.pose,
                travelled: s.trail.travelled,
                eligible,
            };
            let (r, a, p) = (&d.r, &d.a, s.pose.as_ref());
            let n = self.add_pose_candidates(r, a, p, at.travelled, eligible, &mut candidates)?;
            let q = cloud.as_deref();
            if let Some(c) = self.verify_candidates((r, a), q, Some(at), n, &mut candidates)? {
                cloud = Some(Arc::new(c));
            }
            if let Some(c) = candidates.first() {
                self.anchor_on(&at, c);
            }
        }
        let id = self
            .own
            .add_with_cloud(d, self.session, s.timestamp, given, stored.as_deref())?
            + self.session_start as u32;
        self.known.push(self.known_entry(s.pose));
        self.travelled.push(s.trail.travelled);
        self.latest_time.push(s.trail.clock);
        self.trail = s.trail;
        let accepted = self.accept(&candidates, id);
        let deferred = self.end_deferring(id, cloud.as_ref(), accepted.is_some())?;
        if let Some(c) = cloud {
            self.remember(id, c);
        }
        let (released, placement) = self.placement_news(accepted.is_some().then_some(id));
        self.anchor_released(&released);
        for lp in accepted.iter().chain(&released) {
            if let Some(pose) = lp.pose {
                self.join(lp.query, lp.candidate, &pose);
            }
        }
        Ok(Detection {
            query: id,
            eligible: eligible as u32,
            accepted,
            candidates,
            released,
            deferred,
            placement,
            pose: s.pose,
            pose_source: source,
        })
    }

    fn accept(&self, cands: &[Candidate], query: u32) -> Option<Loop> {
        let c = cands.first()?;
        let ok = if self.config.verify.enabled {
            c.verification.is_some_and(|v| v.accepted)
        } else {
            c.score <= self.config.threshold
        };
        ok.then(|| loop_of(c, query))
    }

    /// The `k` best candidates among ids `0..eligible`, in the detector's order.
    fn rank(
        &self,
        r: &[f32],
        a: &[f32],
        eligible: usize,
        k: usize,
    ) -> Result<Vec<Candidate>, DbError> {
        let na = self.own.config().n_azimuth;
        crate::db::same_len("a_solid vs config n_azimuth", a.len(), na)?;
        // The map's places are all eligible, the own session's first `eligible - start`; the
        // two searches merged in the search's order (distance, then lower id) are one search.
        let start = self.session_start;
        let opts = |exclude_recent| SearchOptions {
            k,
            exclude_recent,
            method: Method::Auto,
            ..SearchOptions::default()
        };
        let mut found = self.map.search_with(r, &opts(0))?;
        let own = eligible - start;
        if own > 0 {
            let mine = self.own.search_with(r, &opts(self.own.len() - own))?;
            found.extend(mine.into_iter().map(|mut nb| {
                nb.id += start as u32;
                nb
            }));
            found.sort_by(|x, y| x.distance.total_cmp(&y.distance).then(x.id.cmp(&y.id)));
            found.truncate(k);
        }
        let mut ranked = Vec::new();
        ranked
            .try_reserve_exact(found.len())
            .map_err(|_| DbError::OutOfMemory)?;
        let mut ca = vec![0.0f32; na];
        for nb in found {
            let (db, i) = self.part(nb.id);
            db.a_into(i, &mut ca);
            let ca = &ca[..];
            let distance = f64::from(nb.distance);
            let key = if self.config.rerank {
                distance + aligned_distance(a, ca)?
            } else {
                distance
            };
            let c = Candidate {
                id: nb.id,
                distance,
                heading_deg: heading_refined(a, ca)?.degrees,
                score: distance,
                verification: None,
            };
            ranked.push((key, c));
        }
        // Stable: equal keys keep the search's order (distance, then lower id).
        ranked.sort_by(|x, y| x.0.total_cmp(&y.0));
        Ok(ranked.into_iter().map(|(_, c)| c).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::tests_limit;
    use crate::detector::nearby::tests::corridor;
    use crate::detector::verify::tests::{pose, with_r};

    /// The corridor seen from x (facing +x).
    fn seen(x: f64) -> Vec<f64> {
        let world = corridor(&[-13.0, -4.5, 3.0, 11.5]);
        world.iter().flat_map(|p| [p[0] - x, p[1], p[2]]).collect()
    }

    /// Place `i`'s descriptor: nearest to the places next to it.
    fn descriptor(c: &Config, i: usize) -> Descriptor {
        let mut r = alloc::vec![1.0f32; c.n_range];
        r[i % c.n_range] += 1.0;
        r[(i + 1) % c.n_range] += 0.5;
        with_r(c, r)
    }

    #[test]
    fn a_map_whose_last_session_leaves_no_number_for_the_next_is_refused() {
        // The session after u32::MAX - 1 would be u32::MAX, which no place may carry: refused
        // when the detector is made, not at every step after it changed the detector.
        let c = Config::preset("hdl64").unwrap();
        let d = crate::detector::verify::tests::flat(&c, 1.0);
        for (last, ok) in [(u32::MAX - 2, true), (u32::MAX - 1, false)] {
            let mut db = Database::new(c).unwrap();
            db.add(&d, last, f64::NAN, None).unwrap();
            let det = LoopDetector::with_map(Arc::new(db), DetectorConfig::default());
            assert_eq!(det.is_ok(), ok, "last session {last}");
            if !ok {
                assert!(matches!(det, Err(DbError::Full)));
            }
        }
    }

    #[test]
    fn a_step_the_full_database_refuses_leaves_the_detector_as_it_was() {
        let c = Config::preset("hdl64").unwrap();
        let mut dc = DetectorConfig {
            exclude_frames: 2,
            exclude_meters: 0.0,
            exclude_seconds: 0.0,
            ..DetectorConfig::default()
        };
        dc.verify.enabled = true;
        // Along the corridor 1 m a step and back (loops, an anchor, the support window), with
        // the caller's poses and with the detector's own odometry; the step at 7 refused once.
        let xs: Vec<f64> = (0..8).chain((0..6).rev()).map(f64::from).collect();
        for given in [true, false] {
            let scan = |det: &LoopDetector, i: usize| Scan {
                descriptor: descriptor(&c, xs[i] as usize),
                cloud: det
                    .prepare_cloud(Points::new(&seen(xs[i]), 3).unwrap())
                    .unwrap(),
            };
            let at = |i: usize| given.then(|| pose(0.0, xs[i], 0.0));
            let run = |refused: Option<usize>| {
                let mut det = LoopDetector::new(c, dc).unwrap();
                let mut out = Vec::new();
                for i in 0..xs.len() {
                    if refused == Some(i) {
                        let before = alloc::format!("{det:?}");
                        tests_limit::set(Some(det.len() + 1));
                        let refused = det.detect_scan(scan(&det, i), i as f64, at(i));
                        let batch = det.detect_scans(alloc::vec![scan(&det, i)], &[], &[at(i)]);
                        tests_limit::set(None);
                        assert!(matches!(refused, Err(DbError::Full)), "{refused:?}");
                        assert!(matches!(batch, Err(DbError::Full)), "{batch:?}");
                        assert_eq!(alloc::format!("{det:?}"), before, "given {given}");
                    }
                    out.push(det.detect_scan(scan(&det, i), i as f64, at(i)).unwrap());
                }
                (out, det)
            };
            let (once, det) = run(None);
            assert!(
                once.iter().any(|d| d.accepted.is_some()),
                "no loop: {once:?}"
            );
            let (refused, again) = run(Some(7));
            assert_eq!(refused, once, "given {given}");
            assert_eq!(alloc::format!("{again:?}"), alloc::format!("{det:?}"));
        }
        // Without verification: a descriptor the database refuses (a negative value) changes
        // nothing either (the break notes the odometry's step).
        dc.verify.enabled = false;
        let mut det = LoopDetector::new(c, dc).unwrap();
        for i in 0..4 {
            det.detect(&descriptor(&c, i), f64::NAN, Some(pose(0.0, i as f64, 0.0)))
                .unwrap();
        }
        let before = alloc::format!("{det:?}");
        let mut bad = descriptor(&c, 4);
        bad.r[3] = -1.0;
        let far = Some(pose(0.0, 40.0, 0.0));
        assert!(det.detect(&bad, f64::NAN, far).is_err());
        bad.a.pop();
        assert!(det.detect(&bad, f64::NAN, far).is_err());
        tests_limit::set(Some(det.len() + 1));
        assert!(matches!(
            det.detect(&descriptor(&c, 4), f64::NAN, far),
            Err(DbError::Full)
        ));
        tests_limit::set(None);
        assert_eq!(alloc::format!("{det:?}"), before);
    }
}
