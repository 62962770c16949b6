//! The parameters of a [`super::LoopDetector`]: [`DetectorConfig`] and its [`VerifyConfig`], with
//! their defaults and checks.

use crate::params::{field, Field, Kind, Params, Removed, FINITE};
use crate::reg::{self, Gate, RegConfig};
use crate::{Error, Preset, PRESETS};

/// The parameters of a [`LoopDetector`](super::LoopDetector). Their defaults, ranges and docs are
/// written once, here and in [`DetectorConfig::FIELDS`]; the
/// Python package reads them from here.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectorConfig {
    /// Skip the places of the own session added in the last `exclude_frames` steps ([spec §5](crate::spec#5-evaluating-loop-closure-against-poses):
    /// query q sees frames `< q − exclude_frames`). Default 50.
    pub exclude_frames: usize,
    /// Also skip places of the own session fewer than this many metres back along the path,
    /// for every scan that has a pose (a scan without one is excluded by frames and seconds
    /// only); 0 turns it off. Default [`DEFAULT_EXCLUDE_METERS`].
    pub exclude_meters: f64,
    /// Also skip places of the own session fewer than this many seconds back, for every scan
    /// that has a timestamp (they must then not decrease within a session); 0 turns it off (the
    /// default: a time window means another distance at every speed).
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
    /// Verification of the best candidates by registering the places' clouds.
    pub verify: VerifyConfig,
}

/// How a [`LoopDetector`](super::LoopDetector) verifies its best candidates: it registers the query's cloud with each
/// candidate's ([`crate::reg`]) from several initial yaws and accepts a loop only when the
/// registration passes the [`Gate`]. A verified loop carries the metric pose `T_query_candidate`
/// (SPEC §3) and its heading is that pose's yaw.
///
/// With verification on, a candidate's score is its loop's length `|t| / (1 + |t|)` when it
/// passed the gate (in `[0, 1)`) and `1.5 + distance / 2` otherwise (in `[1.5, 2]`): candidates
/// are ranked by it, a step's loop is its nearest verified place, and a precision-recall curve
/// over the scores first sweeps the verified loops by length, then the rest by R-SOLiD distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VerifyConfig {
    /// Verify at all (the scans' points must then be given, see [`LoopDetector::detect_scan`](super::LoopDetector::detect_scan)).
    pub enabled: bool,
    /// How many of the step's best candidates (by R-SOLiD distance) are registered. With the
    /// odometry check and poses, one of the own session that the poses put beyond reach of an
    /// accepted loop (as for `pose_candidates`, with the rotation's allowance the check gives
    /// the descriptor's candidates) is not registered: it could not be accepted.
    pub candidates: usize,
    /// Candidates chosen by pose, registered beside the descriptor's `candidates` when the
    /// query has a pose: the own session's eligible places nearest to the query's position,
    /// each within reach of an accepted loop (the gate's `max_translation` plus the odometry
    /// check's drift bounds after the path between the two). Among look-alike places the
    /// descriptor's best rarely hold the true one; the odometry says roughly where it is. One
    /// more per typical step of the session the odometry may be off by after the path to the
    /// nearest (`odometry_translation_m + odometry_drift · path`), at most this many more, unless
    /// the latest loop (the anchor) gives the shorter path: after a lap without a loop the
    /// nearest few are the true place's neighbours. 0: none.
    pub pose_candidates: usize,
    /// Smallest [`crate::reg::Degeneracy::translation`] a candidate chosen by pose must reach,
    /// above the gate's: it was chosen where the odometry puts the query and registered from
    /// there, so a translation the clouds leave loose (along a corridor) ends where the
    /// odometry says, drift included; the descriptor's candidates keep the gate's threshold.
    pub pose_candidate_min_information: f64,
    /// At most this many initial yaws per candidate: 0°, the A-SOLiD minima, then ±`fan_deg`.
    pub hypotheses: usize,
    /// The fixed yaw fan added to the hypotheses (degrees; 0: none). On a narrow field of view
    /// the A-SOLiD cost often has a single minimum near 0°.
    pub fan_deg: f64,
    /// Bits per axis of the stored clouds within their voxel ([`crate::reg::encode_cloud`]).
    pub cloud_bits: u8,
    /// Memory for prepared clouds kept between steps (bytes); older ones are prepared again
    /// from the stored compact cloud when needed.
    pub cache_bytes: usize,
    /// Threads that register a step's candidates at once (0: one per core; 1, the default: the
    /// calling thread; at most [`MAX_VERIFY_THREADS`]). Needs the `parallel` feature (a default);
    /// without it, candidates are registered one by one. One by default: under its budget
    /// ([`VerifyConfig::step_points`]) a step registers one or two candidates, in two rounds
    /// (the neighbours after the candidates they start from), and on an idle 2-core machine a
    /// second thread shortened the mean step by 1.17-1.25× on a Livox walk and not at all on a
    /// 360° drive (docs/performance.md#threads): a core the robot's other processes keep.
    pub threads: usize,
    /// The work one step may spend registering, in points: each candidate costs the query's
    /// plus its own fine points times the registrations it runs (one from a known start, the
    /// odometry's or a registered neighbour's, otherwise one per yaw hypothesis; a follower of a
    /// cluster left out still counts one). The best candidate is always registered, the
    /// next ones while the sum stays within this. The others are *deferred* unless the step
    /// found its loop: the next steps register them first, oldest query first, within their
    /// budget (the first whatever it costs); an own place without a start, of a query whose
    /// step registered nothing that met the quality checks, only within what the step's own
    /// best candidate without a start leaves of it (it waits for a step with budget to spare),
    /// with the same checks, and a loop
    /// found for a query without one is reported by the step that found it ([`Detection::released`](super::Detection::released)). At most
    /// [`DEFERRED_QUERIES`](super::DEFERRED_QUERIES) queries wait, each at most
    /// [`DEFERRED_STEPS`](super::DEFERRED_STEPS) steps (older ones are dropped); without a next
    /// step ([`LoopDetector::query_scan`](super::LoopDetector::query_scan)) they stay
    /// unverified.
    pub step_points: usize,
    /// The registration parameters (the stored clouds use its `voxel_size`).
    pub registration: RegConfig,
    /// What a registration must meet to be a loop; its `max_translation` is the largest loop
    /// (metres between the places).
    pub gate: Gate,
    /// Check a verified loop against the poses, when the query and the candidate both have one
    /// and belong to the same session: its registered `T_query_candidate` must lie within the
    /// drift bounds below of `inv(T_world_query)·T_world_candidate`, or the candidate is
    /// rejected ([`Rejection::OdometryDisagrees`](crate::reg::Rejection::OdometryDisagrees)) and
    /// the next one may win. A false loop between look-alike places is metres to tens of metres
    /// off the poses; a drifting odometry drifts with the path. A loop the check turns down
    /// still passes when its neighbours vouch for it (see [`VerifyConfig::min_support`]): the
    /// odometry drifted beyond these bounds, or broke down on the way.
    pub odometry_check: bool,
    /// Translation a loop may differ from the poses' relative pose by at no path (metres): the
    /// registration's own error and the odometry's noise.
    pub odometry_translation_m: f64,
    /// Translation the odometry may drift per metre travelled between the two places (a
    /// fraction: 0.01 allows 1 m of disagreement after 100 m), its scale error. Beside it, the
    /// rotation `ω` the loop and the poses differ by (within its bound) displaces the query as a
    /// rotation drift at a constant rate per metre would: by `ω × arm`, `arm` from the path's
    /// centroid to the place (through the two places' poses; at most `angle · path / 2`, the
    /// straight path's; through an anchor, any direction up to that). The check measures the
    /// translation after that displacement.
    pub odometry_drift: f64,
    /// Rotation a loop may differ from the poses' relative rotation by at no path (degrees).
    pub odometry_rotation_deg: f64,
    /// Rotation the odometry may drift per metre travelled between the two places (degrees).
    pub odometry_rotation_deg_per_m: f64,
    /// The rotation bound's ceiling (degrees): an odometry that turned further off than this
    /// is not one to check a loop against, so no path allows more. Between look-alike
    /// corridors that meet at right angles, a path long enough lets the per-metre bound reach
    /// 90° and a loop into the other corridor through.
    pub odometry_rotation_max_deg: f64,
    /// Uniqueness: when the query has a pose, a candidate that passed is rejected
    /// ([`Rejection::Ambiguous`](crate::reg::Rejection::Ambiguous)) when another candidate of
    /// the step passed too and the two disagree through their places' poses (the drift bounds
    /// above, the path being the metres between the two candidates): look-alike places and
    /// slid registrations, of which at most one is right. A candidate whose pose lies much
    /// nearer the poses' relative pose than the other's (`unique_ratio`) is kept.
    pub unique: bool,
    /// Of two candidates that disagree, the one whose distance (metres) from the poses' relative
    /// pose is less than this fraction of the other's is kept (0: both are rejected). With the
    /// places chosen by pose, the true place is often verified beside a look-alike or a slid
    /// registration of a neighbour; the odometry tells them apart.
    pub unique_ratio: f64,
    /// Consistency over time: a candidate that passed the gate (and the odometry check) is a
    /// loop only when at least `min_support` of the previous `support_window` steps had a
    /// candidate that passed too and agrees with it (see [`VerifyConfig::min_support`]).
    /// Backward-looking: a step's loop is final at that step, and the first `min_support` steps
    /// of a revisit give none. 0 turns it off.
    pub support_window: usize,
    /// Fewest of the previous `support_window` steps that must support a loop. Step q' supports
    /// loop (q, c) when one of its verified candidates c' agrees with it: when the four places
    /// have poses, through the poses (`inv(T_wq)·T_wq'·T_q'c'·inv(T_wc')·T_wc` against `T_qc`
    /// within the drift bounds above, the path being the metres between q and q' plus between
    /// c and c'); without, when c' lies within `2·support_window` places of c. 0 turns it off.
    ///
    /// The same neighbours decide a loop within the session that the odometry check turned
    /// down: it passes when a set of mutually consistent registered loops holding it (each pair
    /// through the short paths between their queries and between their places, the odometry
    /// bounds without the rotation's allowance, as for the placement in a map) holds
    /// `min_support + 1` distinct queries of the last `support_window` steps, more than twice
    /// the queries of any consistent set that disagrees with it among the other loops of the
    /// same queries and the loops of those steps that agree with the odometry. An odometry that drifts beyond its bounds, or breaks down for a stretch, keeps its
    /// short stretches: it costs the first loop of each revisit, as the support does.
    pub min_support: usize,
    /// Metres of the query's path after an accepted loop (with poses) during which the odometry
    /// check, uniqueness and the places chosen by pose go through that loop: the relative pose
    /// `inv(T_wq)·T_wq0·L0·inv(T_wc0)·T_wc` predicted from loop `q0 → c0` (pose `L0`), its
    /// drift bounds after the path `q0 → q` plus `c0 → c` (when shorter than the path between
    /// the two places). After a lap the odometry can be a repeating place's period off; a loop
    /// resets it. 0: off.
    pub loop_reset_m: f64,
    /// A loop is rejected ([`Rejection::LookAlike`](crate::reg::Rejection::LookAlike)) when an
    /// own place the query may match, more than this many metres from the loop's place (by the
    /// poses), with an R-SOLiD distance to the query at most `lookalike_margin` above the
    /// loop's, is a place the loop's pose, taken as a loop to it, would join to the query within
    /// the odometry check's bounds too (the same check, the rotation's allowance in the
    /// direction the rotation drift moves the query; through the anchor of `loop_reset_m` when
    /// there is one): the bounds cannot tell which of the two the query sees. 0: off.
    pub lookalike_m: f64,
    /// How much farther (R-SOLiD cosine distance) than the loop's candidate a look-alike may be.
    pub lookalike_margin: f64,
    /// Loops into another session's places (a prior map) are accepted by the session's
    /// placement in the map: its first loops only once this many distinct queries' loops into
    /// the map agree with each other through the short paths between them (pairwise
    /// consistency within five times the odometry bounds' drift above), over `placement_m`
    /// metres of the path, with a turn of at least 45° among their queries; the loops held
    /// until then are released with the placement
    /// ([`Detection::released`](crate::detector::Detection::released)); later ones when they
    /// agree with it. A look-alike repeats a stretch, not a stretch with a turn. 0: off (loops
    /// into the map then pass as within one session, by the support of the previous steps).
    pub placement_loops: usize,
    /// Metres of the session's path the loops that place it in the map must span, and the most
    /// between two of them facing 45° apart (the turn they must hold; 0: no span, the turn
    /// anywhere among them).
    pub placement_m: f64,
}

/// Default [`Gate::max_translation`] of a detector: a loop joins places at most this many metres
/// apart. A detector parameter of its own, not the evaluation radius (which happens to be 5 m too).
pub const DEFAULT_MAX_LOOP_DISTANCE: f64 = 5.0;

impl Default for VerifyConfig {
    fn default() -> Self {
        VerifyConfig {
            enabled: true,
            candidates: DEFAULT_VERIFY_CANDIDATES,
            pose_candidates: DEFAULT_POSE_CANDIDATES,
            pose_candidate_min_information: DEFAULT_POSE_CANDIDATE_MIN_INFORMATION,
            hypotheses: 4,
            fan_deg: 25.0,
            cloud_bits: 8,
            cache_bytes: 256 << 20,
            threads: 1,
            step_points: DEFAULT_STEP_POINTS,
            registration: RegConfig::default(),
            gate: Gate {
                max_translation: DEFAULT_MAX_LOOP_DISTANCE,
                ..Gate::default()
            },
            odometry_check: true,
            odometry_translation_m: 1.0,
            odometry_drift: 0.01,
            odometry_rotation_deg: 3.0,
            odometry_rotation_deg_per_m: 0.15,
            odometry_rotation_max_deg: 30.0,
            unique: true,
            unique_ratio: 0.5,
            support_window: 20,
            min_support: 1,
            loop_reset_m: DEFAULT_LOOP_RESET_M,
            lookalike_m: DEFAULT_LOOKALIKE_M,
            lookalike_margin: DEFAULT_LOOKALIKE_MARGIN,
            placement_loops: DEFAULT_PLACEMENT_LOOPS,
            placement_m: DEFAULT_PLACEMENT_M,
        }
    }
}

/// Default [`VerifyConfig::candidates`].
pub const DEFAULT_VERIFY_CANDIDATES: usize = 5;

/// Default [`VerifyConfig::pose_candidates`]: among look-alikes the descriptor's candidates rarely
/// hold the true place, the two nearest the odometry's position do (more after a long path,
/// [`VerifyConfig::pose_candidates`]); their checks (`pose_candidate_min_information`, the
/// odometry check with the displacement the rotation predicts) keep them right under a drifting
/// odometry (docs/performance.md#loops-a-pose-graph-can-trust,
/// docs/performance.md#after-a-lap-without-a-loop-the-places-the-odometry-cannot-tell-apart-r19-drift).
pub const DEFAULT_POSE_CANDIDATES: usize = 2;

/// Default [`VerifyConfig::pose_candidate_min_information`]
/// (docs/performance.md#loops-a-pose-graph-can-trust).
pub const DEFAULT_POSE_CANDIDATE_MIN_INFORMATION: f64 = 3.0;

/// Default [`VerifyConfig::loop_reset_m`] (docs/performance.md#loops-a-pose-graph-can-trust).
pub const DEFAULT_LOOP_RESET_M: f64 = 200.0;

/// Default [`VerifyConfig::lookalike_m`] (docs/performance.md#loops-a-pose-graph-can-trust).
pub const DEFAULT_LOOKALIKE_M: f64 = 10.0;

/// Default [`VerifyConfig::lookalike_margin`] (docs/performance.md#loops-a-pose-graph-can-trust).
pub const DEFAULT_LOOKALIKE_MARGIN: f64 = 0.2;

/// Default [`VerifyConfig::placement_loops`] (docs/performance.md#loops-into-a-map).
pub const DEFAULT_PLACEMENT_LOOPS: usize = 3;

/// Default [`VerifyConfig::placement_m`] (docs/performance.md#loops-into-a-map).
pub const DEFAULT_PLACEMENT_M: f64 = 15.0;

/// Default [`VerifyConfig::step_points`]: on a 360° sensor (about 12k fine points a cloud) the
/// best candidate and one or two seeded ones a step, the rest deferred; on a narrow one (the
/// Avia's 1-2k) every default candidate (docs/performance.md#deferred-candidates-the-budget-in-registrations-run-r12-budget).
pub const DEFAULT_STEP_POINTS: usize = 60_000;

impl VerifyConfig {
    /// The grid edge the places' compact clouds are stored on (metres): the registration's
    /// `voxel_size`, or 0.1 m (`UNDOWNSAMPLED_GRID`) when it is 0 (every point kept).
    pub fn cloud_grid(&self) -> f64 {
        if self.registration.voxel_size > 0.0 {
            self.registration.voxel_size
        } else {
            UNDOWNSAMPLED_GRID
        }
    }

    /// Checks the registration parameters and the gate (the detector's own fields are in
    /// [`DetectorConfig::FIELDS`]).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the first invalid one.
    pub fn validate(&self) -> Result<(), Error> {
        if let Err(reg::RegError::Core(e)) = self.registration.validate() {
            return Err(e);
        }
        self.gate.validate()
    }
}

/// Default [`DetectorConfig::exclude_frames`] ([spec §5](crate::spec#5-evaluating-loop-closure-against-poses)).
pub const DEFAULT_EXCLUDE_FRAMES: usize = 50;
/// Default [`DetectorConfig::exclude_meters`]: 50 keyframes are 10 m of a walk and 50 m of a drive;
/// metres of path mean the same on both. 30 m keeps a walk's return to its start and drops the
/// places where its path only folds back (docs/performance.md#exclusion).
pub const DEFAULT_EXCLUDE_METERS: f64 = 30.0;
/// Default [`DetectorConfig::top_k`].
pub const DEFAULT_TOP_K: usize = 10;
/// Largest [`DetectorConfig::top_k`].
pub const MAX_TOP_K: usize = 1000;

/// Whether [`LoopDetector`](super::LoopDetector) re-ranks by A-SOLiD alignment by default: no, it loses reverse
/// revisits for a small gain elsewhere (docs/performance.md#rerank).
pub const DEFAULT_RERANK: bool = false;

impl Default for DetectorConfig {
    /// The defaults with the loop threshold of no particular sensor (the largest of the
    /// presets'); prefer [`DetectorConfig::for_preset`].
    fn default() -> Self {
        DetectorConfig {
            exclude_frames: DEFAULT_EXCLUDE_FRAMES,
            exclude_meters: DEFAULT_EXCLUDE_METERS,
            exclude_seconds: 0.0,
            threshold: PRESETS.iter().map(|p| p.loop_threshold).fold(0.0, f64::max),
            top_k: DEFAULT_TOP_K,
            rerank: DEFAULT_RERANK,
            verify: VerifyConfig::default(),
        }
    }
}

impl DetectorConfig {
    /// The defaults with the loop threshold measured for a sensor preset.
    ///
    /// # Errors
    /// [`Error::UnknownPreset`] for a name that is not a preset.
    pub fn for_preset(name: &str) -> Result<DetectorConfig, Error> {
        Preset::find(name).map(|p| DetectorConfig::for_base_preset(Some(p)))
    }

    /// The defaults for scans described with a config made from the preset `base`: that
    /// sensor's measured loop threshold; a config made from no preset (`None`) gets
    /// [`DetectorConfig::default`]. How a config remembers its preset is the caller's (the
    /// Python `SolidConfig.base_preset` keeps it through `replace` and pickling).
    pub fn for_base_preset(base: Option<&Preset>) -> DetectorConfig {
        match base {
            Some(p) => DetectorConfig {
                threshold: p.loop_threshold,
                ..DetectorConfig::default()
            },
            None => DetectorConfig::default(),
        }
    }

    /// Checks every parameter: each against its range in [`DetectorConfig::FIELDS`], then the
    /// registration parameters and the gate.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the first invalid one.
    pub fn validate(&self) -> Result<(), Error> {
        self.check_fields()?;
        self.verify.validate()
    }
}

/// The grid of the stored clouds when the registration keeps every point (`voxel_size` 0):
/// each point within `0.1 / 2^cloud_bits` metres of where it was.
pub const UNDOWNSAMPLED_GRID: f64 = 0.1;

/// A count of anything (frames, bytes).
const COUNT: Kind = Kind::at_least(0);

/// The most threads a step may register with ([`VerifyConfig::threads`]): a pool's threads are
/// started at once, so an unbounded count would start without end (more than any machine's
/// cores; 0 already means one per core).
pub const MAX_VERIFY_THREADS: usize = 256;

impl Params for DetectorConfig {
    const NAME: &'static str = "DetectorConfig";
    /// Checks removed since they were written to configurations, each with why and what
    /// replaces it (nothing, for these: off, they changed no loop or only lost right ones;
    /// docs/performance.md#the-trust-matrix-issue-41).
    const REMOVED: &'static [Removed] = &[
        Removed {
            name: "pose_candidate_shift_m",
            since: "0.1.0",
            why: "the shifted re-registration of candidates chosen by pose was removed (off, no \
                  loop was wrong and some right ones more); nothing replaces it",
        },
        Removed {
            name: "view_fov_deg",
            since: "0.1.0",
            why: "the view check was removed (off, no loop changed); nothing replaces it",
        },
        Removed {
            name: "view_min_overlap_deg",
            since: "0.1.0",
            why: "the view check was removed (off, no loop changed); nothing replaces it",
        },
    ];
    const FIELDS: &'static [Field<DetectorConfig>] = &[
        field!(DetectorConfig, "exclude_frames", exclude_frames, COUNT, "an integer >= 0",
            "Skip the places of the own session added in the last this many steps.",
            aliases = ["exclude_recent"]),
        field!(DetectorConfig, "exclude_meters", exclude_meters, Kind::closed(0.0, FINITE), "a finite number >= 0",
            "Also skip own places fewer than this many metres back along the path, for scans with a pose (0: off)."),
        field!(DetectorConfig, "exclude_seconds", exclude_seconds, Kind::closed(0.0, FINITE), "a finite number >= 0",
            "Also skip own places fewer than this many seconds back, for scans with a timestamp (0: off)."),
        field!(DetectorConfig, "threshold", threshold, Kind::closed(0.0, 1.0), "a number in [0, 1] (a cosine distance)",
            "Without verification, the largest R-SOLiD cosine distance accepted as a loop."),
        field!(DetectorConfig, "top_k", top_k, Kind::Int { min: 1, max: MAX_TOP_K as u64 }, "an integer in 1..=1000",
            "Candidates each step returns."),
        field!(DetectorConfig, "rerank", rerank, Kind::Bool, "a bool",
            "Re-rank the candidates by R-SOLiD plus rotation-aligned A-SOLiD distance."),
        field!(DetectorConfig, "verify", verify.enabled, Kind::Bool, "a bool",
            "Verify the best candidates by registering the places' clouds; a loop then carries its pose."),
        field!(DetectorConfig, "verify_candidates", verify.candidates, Kind::Int { min: 1, max: MAX_TOP_K as u64 },
            "an integer in 1..=1000", "Candidates registered per step."),
        field!(DetectorConfig, "pose_candidates", verify.pose_candidates, Kind::Int { min: 0, max: MAX_TOP_K as u64 },
            "an integer in 0..=1000", "Places nearest to the query's pose (own session, within reach of the gate and the odometry check) registered beside the descriptor's candidates, and, unless the latest loop gives the nearest place the shorter path, one more per typical step it may be off by after the path (odometry_translation_m + odometry_drift · path), at most as many more (0: none)."),
        field!(DetectorConfig, "pose_candidate_min_information", verify.pose_candidate_min_information, Kind::closed(0.0, FINITE),
            "a finite number >= 0", "Smallest translation information (the gate's degeneracy.translation, per correspondence) a candidate chosen by pose must reach: its registration started where the odometry puts the query."),
        field!(DetectorConfig, "verify_hypotheses", verify.hypotheses, Kind::Int { min: 1, max: 16 },
            "an integer in 1..=16", "Initial yaws per registration, at most (0°, the A-SOLiD minima, then the fan)."),
        field!(DetectorConfig, "verify_fan_deg", verify.fan_deg, Kind::closed(0.0, 180.0), "degrees in [0, 180]",
            "The fixed ± yaw fan added to the hypotheses, degrees (0: none)."),
        field!(DetectorConfig, "cloud_bits", verify.cloud_bits, Kind::Int { min: 1, max: 16 }, "an integer in 1..=16",
            "Bits per axis of the compact clouds stored with the places."),
        field!(DetectorConfig, "cache_bytes", verify.cache_bytes, COUNT, "an integer >= 0",
            "Memory for prepared clouds kept between steps, bytes."),
        field!(DetectorConfig, "verify_threads", verify.threads, Kind::Int { min: 0, max: MAX_VERIFY_THREADS as u64 },
            "an integer in 0..=256", "Threads registering a step's candidates at once (0: one per core; the default 1: a step registers few candidates under its budget, and a second thread shortened its mean wall time by 1.0-1.25x, docs/performance.md#threads)."),
        field!(DetectorConfig, "verify_step_points", verify.step_points, Kind::at_least(1), "an integer >= 1",
            "Work budget of one step, in points: each candidate costs its registrations (1 from a known start, else its hypotheses) times the two clouds' points; the best is always registered, the rest deferred to the next steps."),
        field!(DetectorConfig, "odometry_check", verify.odometry_check, Kind::Bool, "a bool",
            "Reject a verified loop whose pose disagrees with the poses of its two places (same session) beyond the drift bounds, unless its neighbours vouch for it (min_support)."),
        field!(DetectorConfig, "odometry_translation_m", verify.odometry_translation_m, Kind::closed(0.0, FINITE),
            "a finite number >= 0", "Translation a loop may differ from the poses' relative pose by at no path, metres."),
        field!(DetectorConfig, "odometry_drift", verify.odometry_drift, Kind::closed(0.0, FINITE),
            "a finite number >= 0", "Translation the odometry may drift per metre travelled between the two places (a fraction), beside the displacement the rotation difference predicts along the path."),
        field!(DetectorConfig, "odometry_rotation_deg", verify.odometry_rotation_deg, Kind::closed(0.0, 180.0),
            "degrees in [0, 180]", "Rotation a loop may differ from the poses' relative rotation by at no path, degrees."),
        field!(DetectorConfig, "odometry_rotation_deg_per_m", verify.odometry_rotation_deg_per_m, Kind::closed(0.0, FINITE),
            "a finite number >= 0", "Rotation the odometry may drift per metre travelled between the two places, degrees."),
        field!(DetectorConfig, "odometry_rotation_max_deg", verify.odometry_rotation_max_deg, Kind::closed(0.0, 180.0),
            "degrees in [0, 180]", "Ceiling of the rotation a loop may differ from the poses' relative rotation by, whatever the path, degrees."),
        field!(DetectorConfig, "unique", verify.unique, Kind::Bool, "a bool",
            "Reject verified candidates of a step that disagree with another verified one through the poses."),
        field!(DetectorConfig, "unique_ratio", verify.unique_ratio, Kind::closed(0.0, 1.0), "a number in [0, 1]",
            "Of two disagreeing candidates, keep the one whose distance from the poses' relative pose is under this fraction of the other's (0: reject both)."),
        field!(DetectorConfig, "support_window", verify.support_window, COUNT, "an integer >= 0",
            "Consistency over time: the previous steps that may support a loop (0: off)."),
        field!(DetectorConfig, "min_support", verify.min_support, COUNT, "an integer >= 0",
            "Fewest of the previous support_window steps whose verified candidates must agree with a loop; a loop the odometry check turns down passes when this many of them agree with it through their short paths (0: off)."),
        field!(DetectorConfig, "loop_reset_m", verify.loop_reset_m, Kind::closed(0.0, FINITE), "a finite number >= 0",
            "Metres of path after an accepted loop during which the odometry check and the places chosen by pose go through that loop (0: off)."),
        field!(DetectorConfig, "lookalike_m", verify.lookalike_m, Kind::closed(0.0, FINITE), "a finite number >= 0",
            "Reject a loop when an own place farther than this from its place, about as close by descriptor, fits the drift bounds too (0: off)."),
        field!(DetectorConfig, "lookalike_margin", verify.lookalike_margin, Kind::closed(0.0, 1.0), "a number in [0, 1]",
            "How much larger a look-alike's R-SOLiD distance may be than the loop's candidate's."),
        field!(DetectorConfig, "placement_loops", verify.placement_loops, COUNT, "an integer >= 0",
            "Loops into a map are accepted once this many queries' loops into it agree with each other over a turn (the session is placed in the map; the loops held before are released then), then when they agree with that placement (0: off)."),
        field!(DetectorConfig, "placement_m", verify.placement_m, Kind::closed(0.0, FINITE), "a finite number >= 0",
            "Metres of the session's path the loops that place it in the map must span, and the most between two of them facing 45° apart (the turn they must hold; 0: no span, the turn anywhere among them)."),
    ];

    fn defaults() -> DetectorConfig {
        DetectorConfig::default()
    }
}
