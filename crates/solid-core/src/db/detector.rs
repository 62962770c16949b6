//! [`LoopDetector`]: online loop closure over a [`Database`].
//!
//! Each scan is searched against the places added before it, except the most recent ones of its
//! own session ([`DetectorConfig`]: by frames, by metres travelled and by seconds; [spec §5](crate::spec#5-evaluating-loop-closure-against-poses)), then
//! added. Places of other sessions (a prior map, another robot) are never excluded. Every step
//! returns its ranked [`Candidate`]s, so that an evaluation scores exactly what the detector
//! decided ([`crate::eval`]).

use alloc::vec;
use alloc::vec::Vec;

use super::database::check_pose;
use super::{Database, DbError, Method, SearchOptions};
use crate::compare::aligned_distance;
use crate::{heading_refined, Config, Descriptor, Error, PRESETS};

/// The parameters of a [`LoopDetector`]. This is the only place their defaults are written; the
/// Python package reads them from here.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectorConfig {
    /// Skip the places of the own session added in the last `exclude_frames` steps ([spec §5](crate::spec#5-evaluating-loop-closure-against-poses):
    /// query q sees frames `< q − exclude_frames`). Default 50.
    pub exclude_frames: usize,
    /// Also skip places of the own session fewer than this many metres back along the path
    /// (needs a pose with every scan); 0 turns it off (the default).
    pub exclude_meters: f64,
    /// Also skip places of the own session fewer than this many seconds back (needs
    /// non-decreasing timestamps); 0 turns it off (the default).
    pub exclude_seconds: f64,
    /// A step's best candidate is a loop when its score is at most this (the score is the
    /// R-SOLiD cosine distance, [spec §3](crate::spec#3-comparing-descriptors)). Default: the preset's measured threshold
    /// ([`crate::Preset::loop_threshold`]).
    pub threshold: f64,
    /// Candidates each step returns: the `top_k` nearest by R-SOLiD distance, re-ranked when
    /// `rerank` is set. Default 10.
    pub top_k: usize,
    /// Re-rank the candidates by R-SOLiD distance plus rotation-aligned A-SOLiD distance
    /// ([`DEFAULT_RERANK`]).
    pub rerank: bool,
}

/// Default [`DetectorConfig::exclude_frames`] ([spec §5](crate::spec#5-evaluating-loop-closure-against-poses)).
pub const DEFAULT_EXCLUDE_FRAMES: usize = 50;
/// Default [`DetectorConfig::top_k`].
pub const DEFAULT_TOP_K: usize = 10;
/// Largest [`DetectorConfig::top_k`].
pub const MAX_TOP_K: usize = 1000;

/// Whether [`LoopDetector`] re-ranks by A-SOLiD alignment by default: no.
///
/// Re-ranking the top 10 by R-SOLiD distance + rotation-aligned A-SOLiD distance was measured
/// through the pipeline ([spec §5](crate::spec#5-evaluating-loop-closure-against-poses)): on the HKU Livox Avia walk (exclude 50) it changes Recall@1 at
/// 3 m from 0.621 to 0.621 and at 5 m from 0.490 to 0.535 (`tests/loop_eval.rs`); on the
/// simulator's same-direction revisits it changes nothing (0.98-0.99 for every sensor); but on a
/// street driven back the other way with a full 360° HDL-64E (world 0, exclude 25, radius 5 m) it
/// drops Recall@1 from 0.746 to 0.537 (`tests/test_sim.py`). A small gain on one walk does not
/// pay for losing a fifth of the reverse revisits, so it is off; `rerank = true` turns it on.
pub const DEFAULT_RERANK: bool = false;

impl Default for DetectorConfig {
    /// The defaults with the loop threshold of no particular sensor (the largest of the
    /// presets'); prefer [`DetectorConfig::for_preset`].
    fn default() -> Self {
        DetectorConfig {
            exclude_frames: DEFAULT_EXCLUDE_FRAMES,
            exclude_meters: 0.0,
            exclude_seconds: 0.0,
            threshold: PRESETS.iter().map(|p| p.loop_threshold).fold(0.0, f64::max),
            top_k: DEFAULT_TOP_K,
            rerank: DEFAULT_RERANK,
        }
    }
}

impl DetectorConfig {
    /// The defaults with the loop threshold measured for a sensor preset.
    ///
    /// # Errors
    /// [`Error::UnknownPreset`] for a name that is not a preset.
    pub fn for_preset(name: &str) -> Result<DetectorConfig, Error> {
        let p = PRESETS
            .iter()
            .find(|p| p.name == name)
            .ok_or(Error::UnknownPreset)?;
        Ok(DetectorConfig {
            threshold: p.loop_threshold,
            ..DetectorConfig::default()
        })
    }

    /// Checks every parameter.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the first invalid one: `threshold` outside `[0, 1]`,
    /// `exclude_meters` or `exclude_seconds` negative or not finite, `top_k` outside
    /// `1..=1000`.
    pub fn validate(&self) -> Result<(), Error> {
        let bad = |name, value, expected| {
            Err(Error::InvalidParameter {
                name,
                value,
                expected,
            })
        };
        if !(0.0..=1.0).contains(&self.threshold) {
            return bad(
                "threshold",
                self.threshold,
                "a number in [0, 1] (a cosine distance)",
            );
        }
        if !(self.exclude_meters.is_finite() && self.exclude_meters >= 0.0) {
            return bad(
                "exclude_meters",
                self.exclude_meters,
                "a finite number >= 0",
            );
        }
        if !(self.exclude_seconds.is_finite() && self.exclude_seconds >= 0.0) {
            return bad(
                "exclude_seconds",
                self.exclude_seconds,
                "a finite number >= 0",
            );
        }
        if self.top_k == 0 || self.top_k > MAX_TOP_K {
            return bad("top_k", self.top_k as f64, "an integer in 1..=1000");
        }
        Ok(())
    }
}

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
    /// What the detector's threshold is compared with (today the R-SOLiD distance): the value a
    /// precision-recall curve sweeps.
    pub score: f64,
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
    /// The score the threshold accepted (see [`Candidate::score`]).
    pub score: f64,
}

/// Everything one detector step decided.
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    /// Id of the query.
    pub query: u32,
    /// The candidates were drawn from the entries `0..eligible` (the others were excluded as
    /// too recent); 0 means the step had no database to search.
    pub eligible: u32,
    /// Up to `top_k` candidates, best first.
    pub candidates: Vec<Candidate>,
    /// The loop, when the best candidate's score is at most the threshold.
    pub accepted: Option<Loop>,
}

/// An online loop-closure detector (see the module documentation).
#[derive(Debug, Clone)]
pub struct LoopDetector {
    db: Database,
    config: DetectorConfig,
    /// Session of the scans this detector adds.
    session: u32,
    /// Id of the first entry of the own session: entries below it (a prior map) are never
    /// excluded.
    session_start: usize,
    /// Metres travelled along the own session's path at each of its entries (NaN without poses).
    travelled: Vec<f64>,
    /// Position of the own session's last entry, when it had a pose.
    last_position: Option<[f64; 3]>,
}

/// What a step needs to know about the query before it is added.
#[derive(Debug, Clone, Copy)]
struct Step {
    timestamp: f64,
    pose: Option<[f64; 12]>,
    travelled: f64,
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
    /// scans get the session after the largest one in the database.
    ///
    /// # Errors
    /// [`DbError::Core`] naming the invalid parameter of `detector`; [`DbError::Full`] when the
    /// database already uses session `u32::MAX`.
    pub fn with_database(db: Database, detector: DetectorConfig) -> Result<LoopDetector, DbError> {
        detector.validate()?;
        let session = match db.sessions().iter().max() {
            None => 0,
            Some(&s) => s.checked_add(1).ok_or(DbError::Full)?,
        };
        Ok(LoopDetector {
            session_start: db.len(),
            db,
            config: detector,
            session,
            travelled: Vec::new(),
            last_position: None,
        })
    }

    /// The database of every place (the prior map and every scan added so far).
    pub fn database(&self) -> &Database {
        &self.db
    }

    /// Consumes the detector, returning its database.
    pub fn into_database(self) -> Database {
        self.db
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
    /// than the previous one when excluding by seconds; otherwise as [`Database::add`]. On
    /// error nothing is added.
    pub fn detect(
        &mut self,
        d: &Descriptor,
        timestamp: f64,
        pose: Option<[f64; 12]>,
    ) -> Result<Detection, DbError> {
        self.db.check_fingerprint(d.fingerprint)?;
        let step = self.step(timestamp, pose, self.last_position, self.last_travelled())?;
        self.detect_checked(d, step)
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
        let (mut last_position, mut last_travelled) = (self.last_position, self.last_travelled());
        for (i, d) in descriptors.iter().enumerate() {
            self.db.check_fingerprint(d.fingerprint)?;
            let t = timestamps.get(i).copied().unwrap_or(f64::NAN);
            let p = poses.get(i).copied().flatten();
            let s = self.step(t, p, last_position, last_travelled)?;
            // The time and path checks need the previous scan of this batch.
            if self.config.exclude_seconds > 0.0 && i > 0 {
                let prev = steps.last().map_or(f64::NAN, |s: &Step| s.timestamp);
                if s.timestamp < prev {
                    return Err(backwards_time(s.timestamp, prev));
                }
            }
            last_position = p.map(|p| [p[3], p[7], p[11]]).or(last_position);
            last_travelled = s.travelled;
            steps.push(s);
        }
        let mut out = Vec::new();
        out.try_reserve_exact(n).map_err(|_| DbError::OutOfMemory)?;
        for (d, s) in descriptors.iter().zip(steps) {
            out.push(self.detect_checked(d, s)?);
        }
        Ok(out)
    }

    /// [`LoopDetector::detect`] without the details: the loop, if any.
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
        self.db.check_fingerprint(d.fingerprint)?;
        let step = self.step(timestamp, pose, self.last_position, self.last_travelled())?;
        let eligible = self.eligible(&step)?;
        self.rank(&d.r, &d.a, eligible, k)
    }

    /// Searches `d` against every place without adding it (localisation in a prior map): no
    /// place is excluded. Returns the best candidate when its score passes the threshold.
    ///
    /// # Errors
    /// [`DbError::ConfigMismatch`] for a descriptor made with another config.
    pub fn query(&self, d: &Descriptor) -> Result<Option<Loop>, DbError> {
        self.db.check_fingerprint(d.fingerprint)?;
        let cands = self.rank(&d.r, &d.a, self.db.len(), self.config.top_k)?;
        Ok(self.accept(&cands, self.db.len() as u32))
    }

    fn last_travelled(&self) -> f64 {
        self.travelled.last().copied().unwrap_or(0.0)
    }

    /// Checks the timestamp and pose of the next scan and works out its path length.
    fn step(
        &self,
        timestamp: f64,
        pose: Option<[f64; 12]>,
        last_position: Option<[f64; 3]>,
        last_travelled: f64,
    ) -> Result<Step, DbError> {
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
        if self.config.exclude_seconds > 0.0 {
            if timestamp.is_nan() {
                return Err(Error::InvalidParameter {
                    name: "timestamp",
                    value: timestamp,
                    expected: "a timestamp with every scan (exclude_seconds is set)",
                }
                .into());
            }
            let own = &self.db.timestamps()[self.session_start..];
            if let Some(&prev) = own.last() {
                if timestamp < prev {
                    return Err(backwards_time(timestamp, prev));
                }
            }
        }
        let travelled = match (pose, last_position) {
            (Some(p), Some(q)) => {
                let (dx, dy, dz) = (p[3] - q[0], p[7] - q[1], p[11] - q[2]);
                last_travelled + libm::sqrt(dx * dx + dy * dy + dz * dz)
            }
            (Some(_), None) if self.db.len() == self.session_start => 0.0,
            _ => f64::NAN,
        };
        if self.config.exclude_meters > 0.0 && travelled.is_nan() {
            return Err(Error::InvalidParameter {
                name: "pose",
                value: f64::NAN,
                expected: "a pose with every scan (exclude_meters is set)",
            }
            .into());
        }
        Ok(Step {
            timestamp,
            pose,
            travelled,
        })
    }

    /// Number of entries the step may search: ids `0..eligible`.
    fn eligible(&self, s: &Step) -> Result<usize, DbError> {
        let (n, start) = (self.db.len(), self.session_start);
        let mut bound = start + (n - start).saturating_sub(self.config.exclude_frames);
        if self.config.exclude_meters > 0.0 {
            // Entries added without a pose (before exclusion by metres was set) count as far.
            let limit = s.travelled - self.config.exclude_meters;
            let far = self
                .travelled
                .partition_point(|&t| t.is_nan() || t <= limit);
            bound = bound.min(start + far);
        }
        if self.config.exclude_seconds > 0.0 {
            let limit = s.timestamp - self.config.exclude_seconds;
            let own = &self.db.timestamps()[start..];
            bound = bound.min(start + own.partition_point(|&t| t <= limit));
        }
        Ok(bound)
    }

    fn detect_checked(&mut self, d: &Descriptor, s: Step) -> Result<Detection, DbError> {
        let eligible = self.eligible(&s)?;
        let candidates = self.rank(&d.r, &d.a, eligible, self.config.top_k)?;
        self.travelled
            .try_reserve(1)
            .map_err(|_| DbError::OutOfMemory)?;
        let id = self.db.add(d, self.session, s.timestamp, s.pose)?;
        self.travelled.push(s.travelled);
        if let Some(p) = s.pose {
            self.last_position = Some([p[3], p[7], p[11]]);
        }
        Ok(Detection {
            query: id,
            eligible: eligible as u32,
            accepted: self.accept(&candidates, id),
            candidates,
        })
    }

    fn accept(&self, cands: &[Candidate], query: u32) -> Option<Loop> {
        let c = cands.first()?;
        (c.score <= self.config.threshold).then_some(Loop {
            query,
            candidate: c.id,
            distance: c.distance,
            heading_deg: c.heading_deg,
            score: c.score,
        })
    }

    /// The `k` best candidates among ids `0..eligible`, in the detector's order.
    fn rank(
        &self,
        r: &[f32],
        a: &[f32],
        eligible: usize,
        k: usize,
    ) -> Result<Vec<Candidate>, DbError> {
        let na = self.db.config().n_azimuth;
        if a.len() != na {
            return Err(Error::LengthMismatch {
                what: "a_solid vs config n_azimuth",
                left: a.len(),
                right: na,
            }
            .into());
        }
        let found = self.db.search_with(
            r,
            &SearchOptions {
                k,
                exclude_recent: self.db.len() - eligible,
                method: Method::Auto,
                ..SearchOptions::default()
            },
        )?;
        let mut ranked = Vec::new();
        ranked
            .try_reserve_exact(found.len())
            .map_err(|_| DbError::OutOfMemory)?;
        let mut ca = vec![0.0f32; na];
        for nb in found {
            self.db.a_into(nb.id, &mut ca);
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
            };
            ranked.push((key, c));
        }
        // Stable: equal keys keep the search's order (distance, then lower id).
        ranked.sort_by(|x, y| x.0.total_cmp(&y.0));
        Ok(ranked.into_iter().map(|(_, c)| c).collect())
    }
}

fn backwards_time(t: f64, _prev: f64) -> DbError {
    Error::InvalidParameter {
        name: "timestamp",
        value: t,
        expected: "timestamps that do not decrease within a session (exclude_seconds is set)",
    }
    .into()
}
