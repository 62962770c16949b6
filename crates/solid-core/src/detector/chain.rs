//! The detector's own odometry, for steps without the caller's pose (spec §8,
//! docs/loops.md#without-poses).
//!
//! A step without a pose registers its scan with the previous keyframe of its session, once from
//! the previous relative motion (constant velocity), and when there is none or that start fails
//! the gate's quality checks, from the yaw hypotheses a candidate without a start gets (the
//! detector's `verify_pair`: 0°, the A-SOLiD minima, ±`fan_deg`). It chains the result onto the previous
//! keyframe's pose: `T_w_query = T_w_prev · inv(T_query_prev)`. Every check that uses the
//! odometry then uses that pose as it would the caller's (the odometry start of a registration,
//! the reach, the odometry bound, the neighbours' vouching, the look-alikes, the placement into a
//! map).
//!
//! A link is held to the gate's quality checks with its overlap floors (`min_fitness`,
//! `min_structure_fitness`) counted over the part of the two views they share at the link's pose
//! ([`shared_view`](super::verify::shared_view), from the two scans' A-SOLiDs): a narrow view
//! that turns between keyframes cannot match what one of them sees and the other does not (a
//! 90° VLP-16 turning 21.5° at a street corner matched 0.31 of its points at the true pose, 0.56
//! of the 0.54 the two views shared). A whole view shares everything: the gate's floors.
//!
//! A link whose registration fails those checks (no overlap after a fast turn or a
//! gap, a degenerate corridor, a cloud too small) is not bridged: one such scan stays without a
//! pose, and after two in a row the chain starts again, in a new frame whose origin is that scan
//! ([`PoseSource::Started`], the identity). The odometry relates nothing across the frame's
//! start: it is a break of the odometry ([`breaks`](super::breaks), the metres travelled across
//! it taken as the session's typical step), and loops across it are what loops across any
//! break are: registered, and accepted when the loops across it place each other
//! ([`LoopDetector::vouch`]). A caller's pose after steps of the chain's own frame (or
//! the chain after the caller's poses) also starts a frame, across a break.

use alloc::sync::Arc;

use super::nearby::weakest_translation;
use super::verify::{met_quality, relative, seeded, verify_pair_from, verify_yaws, QueryPlace};
use super::{LoopDetector, Step, Trail};
use crate::db::DbError;
use crate::detector::VerifyConfig;
use crate::reg::{self, invert, mul, pose_to_rows, rows_to_pose, Pose, PreparedCloud, Rejection};

/// Where a step's pose ([`super::Detection::pose`]) came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PoseSource {
    /// The caller gave it.
    Given,
    /// The detector's own odometry: the scan registered with the previous keyframe of its
    /// session, chained onto that keyframe's pose.
    Chained,
    /// The detector's own odometry starts a frame here (the identity): the session's first scan
    /// without a pose, or the first after a link that failed the registration's quality checks.
    /// No odometry relates this frame to the places before it: its start is a break of the
    /// odometry, across which loops are accepted when they place each other.
    Started,
}

/// The state of the own odometry.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Chain {
    /// The current frame (how many the chain started before it): a frame's start is a break
    /// of the odometry.
    pub frame: u32,
    /// The current frame is the caller's (its poses were given).
    given: bool,
    /// The current step could not be linked: it has no pose, and no own place with one is
    /// related to it.
    unlinked: bool,
}

/// Whether a link registered from the previous motion `start` that met the gate's quality
/// checks but for the information along some direction (a corridor, a wall) is kept: that
/// direction keeps the motion, so the result must stay within the odometry check's bounds at no
/// path (`odometry_translation_m`; `odometry_rotation_deg` when the rotation is the weak part) of
/// the start, else it slid (a corridor's corner turned by the motion's start).
fn held(v: &VerifyConfig, start: &Pose, r: &super::Verification) -> bool {
    let weak_rotation = match r.rejection {
        Some(Rejection::DegenerateTranslation | Rejection::WeakMarginalTranslation) => false,
        Some(Rejection::DegenerateRotation) => true,
        _ => return false,
    };
    reg::pose_distance(start, &r.registration.pose).is_some_and(|(m, deg)| {
        m <= v.odometry_translation_m && (!weak_rotation || deg <= v.odometry_rotation_deg)
    })
}

/// Degrees between the starts of a link's last attempt, the motion turned across the fan
/// (`verify_fan_deg` either way): the registration's basin in yaw is narrow where little of the
/// view is shared (a 90° view turning 16-21° between keyframes 3 m apart converged from starts
/// within about 5° of the truth; the descriptor's headings and the fan's ends missed the start
/// and the end of each turn, so the chain broke at every corner of the look-alike city).
const FAN_STEP_DEG: f64 = 8.0;

/// The yaws 0, ±[`FAN_STEP_DEG`], ±2·[`FAN_STEP_DEG`], … within ±`fan_deg` (at most `out`'s
/// length less one), then `straight` (the yaw that takes the motion's turn out: the turn's end)
/// unless a yaw already chosen lies within half a step of it; how many.
fn fan(fan_deg: f64, straight: f64, out: &mut [f64; 16]) -> usize {
    let mut n = 1;
    out[0] = 0.0;
    let mut y = FAN_STEP_DEG;
    while y <= fan_deg && n + 3 <= out.len() {
        out[n] = y;
        out[n + 1] = -y;
        n += 2;
        y += FAN_STEP_DEG;
    }
    if out[..n]
        .iter()
        .all(|&y| libm::fabs(y - straight) > FAN_STEP_DEG / 2.0)
    {
        out[n] = straight;
        n += 1;
    }
    n
}

/// A link registered from the previous motion `start` keeps the motion along the direction its
/// clouds constrain least ([`weakest_translation`]: a corridor's axis) when it departs from it
/// there by more than the odometry check's constant part (`odometry_translation_m`): along a
/// corridor that repeats, the registration stalls or slides by a module as readily as it finds
/// the true step (the simulator's corridors, 2 m steps: 8-30 of 479 links from the motion ended
/// 1.5-5 m off, each along that direction, where no right link departed from the motion there by
/// more than 0.38 m, nor on hku1's 312). At keyframes a few tenths of a second apart the motion
/// cannot change by a metre from one step to the next: the registration's answer there is the
/// look-alike's. Only while the registration turns as the motion did (within
/// `odometry_rotation_deg`): where the turn changed (a street corner at keyframes 6 m apart, or
/// after a wrong link) the motion's translation is no better than its rotation.
fn keep_the_motion(
    v: &VerifyConfig,
    start: &Pose,
    mut r: super::Verification,
) -> super::Verification {
    // A turn that changed (the registration turned otherwise than the motion) is no constant
    // motion: the motion's translation is as wrong as its rotation.
    let turned_alike = reg::pose_distance(start, &r.registration.pose)
        .is_some_and(|(_, deg)| deg <= v.odometry_rotation_deg);
    let Some(u) = weakest_translation(&r.registration).filter(|_| turned_alike) else {
        return r;
    };
    let p = &mut r.registration.pose;
    let along: f64 = (0..3).map(|i| u[i] * (p[i][3] - start[i][3])).sum();
    if libm::fabs(along) > v.odometry_translation_m {
        for (i, row) in p.iter_mut().take(3).enumerate() {
            row[3] -= along * u[i];
        }
    }
    r
}

/// The frame of a scan the chain could not link: none.
pub(super) const UNLINKED: u32 = u32::MAX;

/// The identity pose, row-major 3×4.
const ORIGIN: [f64; 12] = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];

impl LoopDetector {
    /// The step's pose: the caller's (`s.pose`), or, with verification and a cloud, the own
    /// odometry's (`s` then gets it, with its trail). Completes the query's cloud when it links.
    /// Returns where the pose came from (None: the step has none).
    pub(super) fn odometry_of(
        &mut self,
        a_query: &[f32],
        s: &mut Step,
        cloud: &mut Option<Arc<PreparedCloud>>,
    ) -> Result<Option<super::PoseSource>, DbError> {
        self.chain.unlinked = false;
        if s.pose.is_some() {
            if !self.chain.given {
                if self.known.iter().any(Option::is_some) {
                    let travelled = self.new_frame();
                    let p = s.pose.unwrap_or(ORIGIN);
                    s.trail = Trail {
                        position: Some([p[3], p[7], p[11]]),
                        travelled,
                        clock: s.trail.clock,
                    };
                }
                self.chain.given = true;
            }
            return Ok(Some(PoseSource::Given));
        }
        // The path as it stands now (a batch's steps were worked out before the chain's).
        s.trail = self.trail.after(s.timestamp, None);
        if !self.config.verify.enabled || cloud.is_none() {
            return Ok(None);
        }
        let (pose, source) =
            match self.link(a_query, cloud)? {
                Some(pose) => {
                    s.trail = self.trail.after(s.timestamp, Some(&pose));
                    (pose, PoseSource::Chained)
                }
                // One scan the chain cannot link is skipped: it stays without a pose (and matches no
                // place of the chain: nothing checks its loops), the next links over it.
                None if self.own.len().checked_sub(1).is_some_and(|k| {
                    self.known_pose((self.session_start + k) as u32).is_some()
                }) =>
                {
                    self.chain.unlinked = true;
                    return Ok(None);
                }
                None => {
                    let travelled = if self.known.is_empty() {
                        self.trail.travelled
                    } else {
                        self.new_frame()
                    };
                    self.chain.given = false;
                    let travelled = if travelled.is_nan() { 0.0 } else { travelled };
                    s.trail = Trail {
                        position: Some([0.0; 3]),
                        travelled,
                        clock: s.trail.clock,
                    };
                    (ORIGIN, PoseSource::Started)
                }
            };
        s.pose = Some(pose);
        Ok(Some(source))
    }

    /// Whether own place `id` is a scan the chain could not link, or the query is one (and the
    /// place has a pose, an own place's or a map's): no odometry relates the two, nor any loop
    /// of theirs to another loop, so no loop between them is accepted (it is not registered).
    /// A map place only without the placement (`placement_loops` 0): nothing would judge the
    /// query's loop into the map but the gate (a corridor grid's Avia session without poses got
    /// a wrong loop into the map so, 94 m off, at the step the chain skipped:
    /// `tools/session_measure.py '{}' 1 avia nopose 2`). With it, the query is related to the
    /// placement through the keyframe before it, one typical step off
    /// ([`LoopDetector::unlinked_query`]), and its loops into the map are judged by the
    /// placement (held until there is one: `consistency::check_placement`).
    pub(super) fn unlinked(&self, id: u32) -> bool {
        match self.place_frame(id) {
            Some(frame) => self.chain.unlinked || frame == UNLINKED,
            None => {
                self.chain.unlinked
                    && self.in_map(id)
                    && self.known_pose(id).is_some()
                    && !self.placement_loops_on()
            }
        }
    }

    /// For a query the own odometry could not link (`at` without a pose, at its step or a
    /// later one that registers its deferred candidates): the pose and metres travelled of the
    /// keyframe before it (the previous own place, which has a pose in the chain's frame: else
    /// the chain would have started a new frame at the query) and the session's typical step,
    /// how far the query may lie from that keyframe (as across a break of the odometry,
    /// [`LoopDetector::bridged`]). None for any other query.
    pub(super) fn unlinked_query(&self, at: &QueryPlace) -> Option<([f64; 12], f64, f64)> {
        let now = at.id as usize == self.len() && self.chain.unlinked;
        if at.pose.is_some() || !(now || self.unlinked_place(at.id)) {
            return None;
        }
        let prev = at.id.checked_sub(1)?;
        if self.place_frame(prev).is_none_or(|f| f == UNLINKED) {
            return None;
        }
        Some((
            self.known_pose(prev)?,
            self.travelled_at(prev)?,
            self.breaks.typical(),
        ))
    }

    /// Whether own place `id` is a scan the chain could not link (whatever the query).
    pub(super) fn unlinked_place(&self, id: u32) -> bool {
        self.place_frame(id) == Some(UNLINKED)
    }

    /// The frame of own place `id` with a pose (None: a map place, or no pose).
    fn place_frame(&self, id: u32) -> Option<u32> {
        (id as usize)
            .checked_sub(self.session_start)
            .and_then(|k| self.known.get(k).copied().flatten())
            .map(|(_, frame)| frame)
    }

    /// What [`LoopDetector::known`] holds for the step just added with `pose`: the pose in the
    /// current frame; for a scan the chain could not link, no frame (it is related to no place,
    /// and no later query to it).
    pub(super) fn known_entry(&self, pose: Option<[f64; 12]>) -> Option<([f64; 12], u32)> {
        match pose {
            Some(p) => Some((p, self.chain.frame)),
            None if self.chain.unlinked => Some((ORIGIN, UNLINKED)),
            None => None,
        }
    }

    /// Starts a new frame of the own odometry: a break of the odometry after the session's
    /// last pose. Returns the metres travelled after it ([`breaks::Breaks::frame`](super::breaks)).
    fn new_frame(&mut self) -> f64 {
        self.chain.frame += 1;
        self.breaks.frame(self.trail.travelled)
    }

    /// The query's pose chained onto the previous keyframe's (None: there is no previous
    /// keyframe with a pose in the current frame and a cloud, or no start gave a registration
    /// that met the gate's quality checks).
    fn link(
        &mut self,
        a_query: &[f32],
        cloud: &mut Option<Arc<PreparedCloud>>,
    ) -> Result<Option<[f64; 12]>, DbError> {
        let Some(last) = self.own.len().checked_sub(1) else {
            return Ok(None);
        };
        let start = self.session_start;
        let at = |k: usize| (start + k) as u32;
        // The previous keyframe, or over one the chain could not link, the one before it.
        let Some(k) = (last.saturating_sub(1)..=last)
            .rev()
            .find(|&k| self.known_pose(at(k)).is_some())
        else {
            return Ok(None);
        };
        let id = at(k);
        let prev = self.known_pose(id).unwrap_or(ORIGIN);
        let Some(cp) = self.prepared_cloud(id)? else {
            return Ok(None);
        };
        let Some(q) = cloud.as_mut() else {
            return Ok(None);
        };
        if !q.is_complete() {
            let mut c = PreparedCloud::clone(q);
            c.complete()?;
            *q = Arc::new(c);
        }
        // Constant velocity: the previous relative motion `T_prev_prevprev`, as a start for
        // `T_query_prev`.
        let motion = k
            .checked_sub(1)
            .and_then(|j| self.known_pose(at(j)))
            .map(|before| relative(&prev, &before))
            .map(|m| if k < last { mul(&m, &m) } else { m });
        let v = self.config.verify;
        let a_prev = self.a(id);
        let views = Some((a_query, a_prev.as_slice()));
        let seeded_link = match &motion {
            Some(m) => seeded(&v, q, &cp, m, views)?
                .filter(|r| met_quality(r) || held(&v, m, r))
                .map(|r| keep_the_motion(&v, m, r)),
            None => None,
        };
        // The hypotheses turn about the previous motion (a turn at constant speed).
        let base = motion.unwrap_or(reg::IDENTITY);
        let found = match seeded_link {
            Some(r) => Some(r),
            None => {
                verify_pair_from(&v, (a_query, &a_prev), q, &cp, &base, true)?.filter(met_quality)
            }
        };
        // The turn changed between the keyframes (its start or its end): the motion turned by
        // every [`FAN_STEP_DEG`] within the fan, and the motion without its turn (a turn of
        // 35-43° between keyframes 6 m apart, a 90° view, ended beyond the fan's reach).
        let found = match (found, &motion) {
            (Some(r), _) => Some(r),
            (None, Some(m)) => {
                let mut yaws = [0.0f64; 16];
                let straight = -crate::angle::yaw_degrees(m[0][0], m[1][0]);
                let n = fan(v.fan_deg, straight, &mut yaws);
                verify_yaws(&v, &yaws[..n], q, &cp, m, views)?.filter(met_quality)
            }
            (None, None) => None,
        };
        Ok(found.map(|r| {
            let pose = mul(&rows_to_pose(&prev), &invert(&r.registration.pose));
            pose_to_rows(&pose)
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::{fan, FAN_STEP_DEG};

    #[test]
    fn the_fan_turns_the_motion_every_step_and_takes_its_turn_out() {
        let mut out = [0.0f64; 16];
        // A motion turned by 35°: the fan's ±24° and -35° (the turn's end).
        let n = fan(25.0, -35.0, &mut out);
        assert_eq!(
            &out[..n],
            &[0.0, 8.0, -8.0, 16.0, -16.0, 24.0, -24.0, -35.0]
        );
        // A straight motion (or one the fan already covers): the fan alone.
        assert_eq!(fan(25.0, 0.0, &mut out), 7);
        assert_eq!(fan(25.0, 22.0, &mut out), 7);
        assert_eq!(fan(25.0, 30.0, &mut out), 8);
        // The widest fan leaves room for the turn's end.
        let n = fan(180.0, 170.0, &mut out);
        assert_eq!(n, 16);
        assert_eq!(out[n - 1], 170.0);
        assert_eq!(out[n - 2], -7.0 * FAN_STEP_DEG);
    }
}
