//! The parameters of a [`super::LoopDetector`]: [`DetectorConfig`] and its [`VerifyConfig`], with
//! their defaults and checks.

use crate::reg::{self, Gate, RegConfig};
use crate::{Error, PRESETS};

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
    /// Verification of the best candidates by registering the places' clouds.
    pub verify: VerifyConfig,
}

/// How a [`LoopDetector`] verifies its best candidates: it registers the query's cloud with each
/// candidate's ([`crate::reg`]) from several initial yaws and accepts a loop only when the
/// registration passes the [`Gate`]. A verified loop carries the metric pose `T_query_candidate`
/// (SPEC §3) and its heading is that pose's yaw.
///
/// With verification on, a candidate's score is `1 − fitness` when it passed the gate (in
/// `[0, 1]`) and `1.5 + distance / 2` otherwise (in `[1.5, 2]`): candidates are ranked by it, a
/// step's best candidate is a loop exactly when it passed the gate, and a precision-recall curve
/// over the scores first sweeps the verified loops by overlap, then the rest by R-SOLiD distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VerifyConfig {
    /// Verify at all (the scans' points must then be given, see [`LoopDetector::detect_scan`]).
    pub enabled: bool,
    /// How many of the step's best candidates (by R-SOLiD distance) are registered.
    pub candidates: usize,
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
    /// Threads that register a step's candidates at once (0: one per core; 1: the calling
    /// thread). Needs the `std` feature; without it, candidates are registered one by one.
    pub threads: usize,
    /// The registration parameters (the stored clouds use its `voxel_size`).
    pub registration: RegConfig,
    /// What a registration must meet to be a loop; its `max_translation` is the largest loop
    /// (metres between the places).
    pub gate: Gate,
}

/// Default [`Gate::max_translation`] of a detector: a loop joins places at most this many metres
/// apart (the default radius of SPEC §5).
pub const DEFAULT_MAX_LOOP_DISTANCE: f64 = crate::eval::DEFAULT_RADIUS;

impl Default for VerifyConfig {
    fn default() -> Self {
        VerifyConfig {
            enabled: true,
            candidates: DEFAULT_VERIFY_CANDIDATES,
            hypotheses: 4,
            fan_deg: 25.0,
            cloud_bits: 8,
            cache_bytes: 256 << 20,
            threads: 0,
            registration: RegConfig::default(),
            gate: Gate {
                max_translation: DEFAULT_MAX_LOOP_DISTANCE,
                ..Gate::default()
            },
        }
    }
}

/// Default [`VerifyConfig::candidates`].
pub const DEFAULT_VERIFY_CANDIDATES: usize = 5;

impl VerifyConfig {
    /// Checks every parameter.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the first invalid one.
    pub fn validate(&self) -> Result<(), Error> {
        if self.candidates == 0 || self.candidates > MAX_TOP_K {
            return Err(Error::invalid(
                "verify_candidates",
                self.candidates as f64,
                "an integer in 1..=1000",
            ));
        }
        if !(1..=16).contains(&self.hypotheses) {
            return Err(Error::invalid(
                "verify_hypotheses",
                self.hypotheses as f64,
                "an integer in 1..=16",
            ));
        }
        if !(self.fan_deg.is_finite() && (0.0..=180.0).contains(&self.fan_deg)) {
            return Err(Error::invalid(
                "verify_fan_deg",
                self.fan_deg,
                "degrees in [0, 180]",
            ));
        }
        if !(1..=16).contains(&self.cloud_bits) {
            return Err(Error::invalid(
                "cloud_bits",
                f64::from(self.cloud_bits),
                "an integer in 1..=16",
            ));
        }
        if let Err(reg::RegError::Core(e)) = self.registration.validate() {
            return Err(e);
        }
        let g = &self.gate;
        if g.max_translation.is_nan() || g.max_translation <= 0.0 {
            return Err(Error::invalid(
                "max_loop_distance",
                g.max_translation,
                "metres > 0 (infinity: no limit)",
            ));
        }
        for (name, v) in [
            ("min_fitness", g.min_fitness),
            ("min_structure_fitness", g.min_structure_fitness),
            ("max_rmse", g.max_rmse),
            ("min_translation_information", g.min_translation_information),
            ("min_rotation_information", g.min_rotation_information),
        ] {
            if v.is_nan() {
                return Err(Error::invalid(name, v, "a number"));
            }
        }
        Ok(())
    }
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
        if !(0.0..=1.0).contains(&self.threshold) {
            return Err(Error::invalid(
                "threshold",
                self.threshold,
                "a number in [0, 1] (a cosine distance)",
            ));
        }
        if !(self.exclude_meters.is_finite() && self.exclude_meters >= 0.0) {
            return Err(Error::invalid(
                "exclude_meters",
                self.exclude_meters,
                "a finite number >= 0",
            ));
        }
        if !(self.exclude_seconds.is_finite() && self.exclude_seconds >= 0.0) {
            return Err(Error::invalid(
                "exclude_seconds",
                self.exclude_seconds,
                "a finite number >= 0",
            ));
        }
        if self.top_k == 0 || self.top_k > MAX_TOP_K {
            return Err(Error::invalid(
                "top_k",
                self.top_k as f64,
                "an integer in 1..=1000",
            ));
        }
        self.verify.validate()
    }
}
