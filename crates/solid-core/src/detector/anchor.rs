//! Loops as anchors, and look-alikes the odometry cannot rule out.
//!
//! After a lap the odometry may have drifted by as much as a repeating place's period: the
//! look-alike one period away then agrees with it as well as the true place. A confirmed loop
//! `q0 → c0` (pose `L0`) resets that drift: a later query `q` and candidate `c` have the
//! predicted relative pose `inv(T_wq)·T_wq0·L0·inv(T_wc0)·T_wc`, whose drift grows with the short
//! paths `q0 → q` and `c0 → c` only ([`VerifyConfig::loop_reset_m`]). And a loop whose place has
//! look-alikes among the own places that the current bounds cannot rule out is not accepted
//! ([`VerifyConfig::lookalike_m`]).

use alloc::vec::Vec;

use super::verify::{distance, reject, relative, rotation_bound, QueryPlace};
use super::{Candidate, LoopDetector};
use crate::compare::cosine_distance;
use crate::detector::VerifyConfig;
use crate::reg::{invert, mul, pose_to_rows, rows_to_pose, Pose, Rejection};

/// Places joined to one place that [`LoopDetector::joined_with`] follows at most (its passes and
/// the loops of their neighbours: a route driven many times, or a robot standing still).
pub(super) const JOINED_MOST: usize = 64;

/// Where an own place lies from a step's query by the poses ([`LoopDetector::reach`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Reach {
    /// The poses do not say (no pose, a map place or another session's).
    Unknown,
    /// Within reach, this many metres from the query.
    Within(f64),
    /// Too far to give an accepted loop.
    Beyond,
}

/// The path the poses' prediction of a loop goes through ([`LoopDetector::expected_via`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Via {
    /// The two places' poses (no anchor applies, or its path is not the shorter).
    Poses,
    /// The latest anchor: its path is the shorter (`shorter`), or the two places' path crosses
    /// a break of the odometry (the anchor's is the only one).
    Anchor { shorter: bool },
}

/// The latest confirmed loop of the own session: the query's pose and metres travelled, the
/// candidate's id and the loop's pose.
#[derive(Debug, Clone, Copy)]
pub(super) struct Anchor {
    pub query: [f64; 12],
    pub travelled: f64,
    pub candidate: u32,
    pub pose: Pose,
}

impl LoopDetector {
    /// The metres travelled at own place `id` (None for a map place or one without).
    pub(super) fn travelled_at(&self, id: u32) -> Option<f64> {
        let k = (id as usize).checked_sub(self.session_start)?;
        self.travelled.get(k).copied().filter(|t| !t.is_nan())
    }

    /// The query's pose as the latest anchor puts it in the candidates' frame
    /// (`T_wc0·inv(L0)·inv(T_wq0)·T_wq`), the metres the query travelled since and where the
    /// anchor's candidate lies along the path: None without a recent enough anchor.
    pub(super) fn anchored(&self, at: &QueryPlace) -> Option<([f64; 12], f64, f64)> {
        let v = &self.config.verify;
        let a = self.anchor.filter(|_| v.loop_reset_m > 0.0)?;
        let q = at.pose?;
        let since = libm::fabs(at.travelled - a.travelled);
        if since.is_nan() || since > v.loop_reset_m {
            return None;
        }
        let c0 = self.known_pose(a.candidate)?;
        let t0 = self.travelled_at(a.candidate)?;
        let moved = relative(&a.query, &q);
        let p = mul(&mul(&rows_to_pose(&c0), &invert(&a.pose)), &moved);
        Some((pose_to_rows(&p), since, t0))
    }

    /// The relative pose the poses predict between the query and own place `c`, and the metres
    /// of path its drift grows with: through the anchor when `anchor` and its path is the
    /// shorter, else the two places' poses (None without poses, across sessions, or when every
    /// path crosses a break of the odometry: [`breaks`](super::breaks)).
    pub(super) fn expected(&self, at: &QueryPlace, c: u32, anchor: bool) -> Option<(Pose, f64)> {
        self.expected_through(at, anchor.then(|| self.anchored(at)).flatten(), c)
    }

    /// [`LoopDetector::expected`] through `anchored` ([`LoopDetector::anchored`] of `at`, None:
    /// through the two places' poses), for the callers that look at many places in one step.
    pub(super) fn expected_through(
        &self,
        at: &QueryPlace,
        anchored: Option<([f64; 12], f64, f64)>,
        c: u32,
    ) -> Option<(Pose, f64)> {
        self.expected_via(at, anchored, c)
            .map(|(pose, path, _)| (pose, path))
    }

    /// [`LoopDetector::expected_through`] and the path it went through: whether the latest
    /// anchor gives place `c` the shorter path is decided here only (the odometry check's
    /// rotation allowance and the widened pose candidates ask it).
    pub(super) fn expected_via(
        &self,
        at: &QueryPlace,
        anchored: Option<([f64; 12], f64, f64)>,
        c: u32,
    ) -> Option<(Pose, f64, Via)> {
        let q = at.pose?;
        let tc = self.travelled_at(c);
        let pc = self.known_pose(c)?;
        (c as usize).checked_sub(self.session_start)?;
        let global = tc.map_or(0.0, |t| libm::fabs(at.travelled - t));
        let global = if global.is_nan() { 0.0 } else { global };
        let broken = tc.is_some_and(|t| self.crosses_break(at.travelled, t));
        if let (Some((qa, since, t0)), Some(t)) = (anchored, tc) {
            // Through the anchor's place, or another pass of it that an accepted loop joined to
            // it when that one is nearer along the path to `c`: on a route's third pass the
            // anchor is a loop into the second, and the first pass lies a lap from it along the
            // path but one loop away.
            let (qa, t0, path) = self.nearest_base(qa, t0, since, t);
            let through = !self.crosses_break(at.travelled - since, at.travelled)
                && !self.crosses_break(t0, t);
            let shorter = path < global;
            if through && (shorter || broken) {
                return Some((relative(&qa, &pc), path, Via::Anchor { shorter }));
            }
        }
        (!broken).then(|| (relative(&q, &pc), global, Via::Poses))
    }

    /// Whether own place `c` lies within reach of the query `at` by the poses (through
    /// `anchored`, [`LoopDetector::anchored`] of `at`, when its path is the shorter, as the
    /// odometry check does): no farther than the gate's largest loop plus what the odometry
    /// check allows after the path between them, with `turn` of the rotation's allowance at the
    /// rotation's bound ([`LoopDetector::within_drift`]). A loop's length is at least the poses'
    /// distance less its offset from them, so a place beyond could give no loop the gate and that
    /// check accept: it is not worth registering.
    pub(super) fn reach(
        &self,
        at: &QueryPlace,
        anchored: Option<([f64; 12], f64, f64)>,
        c: u32,
        turn: f64,
    ) -> Reach {
        let Some((e, path)) = self.expected_through(at, anchored, c) else {
            return Reach::Unknown;
        };
        let v = &self.config.verify;
        let d = libm::sqrt(e[0][3] * e[0][3] + e[1][3] * e[1][3] + e[2][3] * e[2][3]);
        let swing = turn * rotation_bound(v, path).to_radians() * path / 2.0;
        let reach = v.gate.max_translation + v.odometry_translation_m + v.odometry_drift * path;
        if d <= reach + swing {
            Reach::Within(d)
        } else {
            Reach::Beyond
        }
    }

    /// Remembers the step's loop as the anchor of the next steps (own-session loops with poses).
    pub(super) fn anchor_on(&mut self, at: &QueryPlace, c: &Candidate) {
        let (Some(q), Some(r)) = (at.pose, c.verification.filter(|r| r.accepted)) else {
            return;
        };
        if self.travelled_at(c.id).is_some() && self.known_pose(c.id).is_some() {
            self.anchor = Some(Anchor {
                query: q,
                travelled: at.travelled,
                candidate: c.id,
                pose: r.registration.pose,
            });
            self.anchor_bases = self.joined_with(c.id);
        }
    }

    /// Remembers the latest of `released` (loops of earlier queries released at this step: the
    /// neighbours vouched for them) as the anchor of the next steps, as [`LoopDetector::anchor_on`]
    /// does a step's own loop, when its query is later than the anchor's.
    pub(super) fn anchor_released(&mut self, released: &[super::Loop]) {
        for lp in released {
            let (Some(q), Some(t), Some(pose)) = (
                self.known_pose(lp.query),
                self.travelled_at(lp.query),
                lp.pose,
            ) else {
                continue;
            };
            let later = self.anchor.is_none_or(|a| t > a.travelled);
            if later
                && self.travelled_at(lp.candidate).is_some()
                && self.known_pose(lp.candidate).is_some()
            {
                self.anchor = Some(Anchor {
                    query: q,
                    travelled: t,
                    candidate: lp.candidate,
                    pose,
                });
                self.anchor_bases = self.joined_with(lp.candidate);
            }
        }
    }

    /// The anchored query pose `qa` (`since` metres after the anchor) moved to the anchor's base
    /// nearest along the path to a place at `t` metres: the anchor's place at `t0`, or one of
    /// [`LoopDetector::anchor_bases`](super::LoopDetector) nearer. `(pose, its place's metres,
    /// the path through it)`.
    fn nearest_base(&self, qa: [f64; 12], t0: f64, since: f64, t: f64) -> ([f64; 12], f64, f64) {
        let c0 = self.anchor.and_then(|a| self.known_pose(a.candidate));
        let nearer = self.nearer_pass(&self.anchor_bases, t, libm::fabs(t - t0));
        let Some(((r, tj, pj), c0)) = nearer.zip(c0) else {
            return (qa, t0, since + libm::fabs(t - t0));
        };
        // The query where the anchor puts it, seen from place j instead of the anchor's place:
        // T_wj · T_j←c0 · T_c0←w · qa.
        let from_c0 = mul(&invert(&rows_to_pose(&c0)), &rows_to_pose(&qa));
        let q = mul(&mul(&rows_to_pose(&pj), &invert(r)), &from_c0);
        (pose_to_rows(&q), tj, since + libm::fabs(t - tj))
    }

    /// Of `passes` (places joined to one place, each with the pose from it:
    /// [`LoopDetector::joined_with`]), the one with a pose nearest along the path to a place at
    /// `t` metres, nearer than `than` metres and with no break of the odometry between them:
    /// its pose from the place, its metres and its pose in the world.
    fn nearer_pass<'p>(
        &self,
        passes: &'p [(u32, Pose)],
        t: f64,
        than: f64,
    ) -> Option<(&'p Pose, f64, [f64; 12])> {
        let mut best: Option<(&'p Pose, f64, [f64; 12])> = None;
        for (j, r) in passes {
            let (Some(tj), Some(pj)) = (self.travelled_at(*j), self.known_pose(*j)) else {
                continue;
            };
            let metres = libm::fabs(t - tj);
            if metres < best.map_or(than, |b| libm::fabs(t - b.1)) && !self.crosses_break(tj, t) {
                best = Some((r, tj, pj));
            }
        }
        best
    }

    /// Joins own places `a` and `b` by an accepted loop's pose `pose` (`T_a←b`: the same place);
    /// places of another session or of the map are not recorded.
    pub(super) fn join(&mut self, a: u32, b: u32, pose: &Pose) {
        let own = |id: u32| (id as usize) >= self.session_start && (id as usize) < self.len();
        if a == b || !own(a) || !own(b) {
            return;
        }
        // At most JOINED_MOST a place (what `joined_with` follows), both ways or not at all.
        let room = |x: u32, y: u32| {
            self.joined
                .get(&x)
                .is_none_or(|l| l.len() < JOINED_MOST && !l.iter().any(|(k, _)| *k == y))
        };
        if !room(a, b) || !room(b, a) {
            return;
        }
        for x in [a, b] {
            if self.joined.entry(x).or_default().try_reserve(1).is_err() {
                return;
            }
        }
        for (x, y, p) in [(a, b, *pose), (b, a, invert(pose))] {
            self.joined.entry(x).or_default().push((y, p));
        }
    }

    /// The own places the accepted loops joined to `id`, directly or through others (one place's
    /// passes), without `id`, each with the pose from `id` to it (`T_id←j`, the loops' poses
    /// composed); at most [`JOINED_MOST`].
    pub(super) fn joined_with(&self, id: u32) -> Vec<(u32, Pose)> {
        let mut out: Vec<(u32, Pose)> = Vec::new();
        let new = |out: &Vec<(u32, Pose)>, j: u32| j != id && !out.iter().any(|(k, _)| *k == j);
        for (j, p) in self.joined.get(&id).map_or(&[][..], |l| l.as_slice()) {
            if out.len() == JOINED_MOST || out.try_reserve(1).is_err() {
                return out;
            }
            if new(&out, *j) {
                out.push((*j, *p));
            }
        }
        let mut next = 0;
        while next < out.len() {
            let (j, to_j) = out[next];
            next += 1;
            for (k, p) in self.joined.get(&j).map_or(&[][..], |l| l.as_slice()) {
                if out.len() == JOINED_MOST || out.try_reserve(1).is_err() {
                    return out;
                }
                if new(&out, *k) {
                    out.push((*k, mul(&to_j, p)));
                }
            }
        }
        out
    }

    /// How own place `c2` lies from own place `c` (`T_c←c2`) through a place `j` joined to `c`
    /// by accepted loops ([`LoopDetector::joined_with`]) and the odometry from `j` to `c2`, and
    /// the metres of path from `j` to `c2`, when that path is shorter than the one from `c` to
    /// `c2`: another pass of a place lies a lap away along the path but one loop away.
    pub(super) fn joined_between(&self, c: u32, c2: u32) -> Option<(Pose, f64)> {
        if !self.joined.contains_key(&c) {
            return None;
        }
        let (tc, tc2, pc2) = (
            self.travelled_at(c)?,
            self.travelled_at(c2)?,
            self.known_pose(c2)?,
        );
        let passes = self.joined_with(c);
        let (t_c_j, tj, pj) = self.nearer_pass(&passes, tc2, libm::fabs(tc - tc2))?;
        Some((mul(t_c_j, &relative(&pj, &pc2)), libm::fabs(tj - tc2)))
    }

    /// Rejects each passed candidate that has a look-alike ([`LoopDetector::lookalike`]).
    pub(super) fn reject_lookalikes(
        &self,
        at: &QueryPlace,
        r_query: &[f32],
        cands: &mut [Candidate],
    ) {
        for c in cands.iter_mut() {
            if c.verification.is_some_and(|r| r.accepted) && self.lookalike(at, r_query, c) {
                reject(c, Rejection::LookAlike);
            }
        }
    }

    /// Whether registered candidate `c` has a look-alike: an own place `..eligible` more than
    /// `lookalike_m` from it that the loop's pose, taken as a loop to that place, would join to
    /// the query within the odometry check's bounds too ([`LoopDetector::odometry_holds`], the
    /// rotation's allowance in its direction), and whose descriptor is within
    /// `lookalike_margin` of the candidate's distance to the query: the odometry (or the anchor)
    /// cannot tell which of the two the query sees.
    pub(super) fn lookalike(&self, at: &QueryPlace, r_query: &[f32], c: &Candidate) -> bool {
        let v: &VerifyConfig = &self.config.verify;
        if v.lookalike_m <= 0.0 || at.pose.is_none() {
            return false;
        }
        let (Some(r), Some(pc)) = (c.verification, self.known_pose(c.id)) else {
            return false;
        };
        let t = r.registration.pose;
        (self.session_start..at.eligible).any(|k| {
            let id = k as u32;
            id != c.id
                && self
                    .known_pose(id)
                    .is_some_and(|p2| distance(&p2, &pc) > v.lookalike_m)
                && self.odometry_holds(at, id, &t, true) == Some(true)
                && cosine_distance(r_query, self.r(id))
                    .is_ok_and(|d| d <= c.distance + v.lookalike_margin)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::verify::tests::{
        detector_with_path, lap_odometry, lap_truth, pose, rejection, square_lap, verified,
    };
    use super::*;
    use crate::reg;

    #[test]
    fn poses_convert_and_invert() {
        let (s, c) = libm::sincos(0.3);
        let p = [c, -s, 0.0, 1.0, s, c, 0.0, -2.0, 0.0, 0.0, 1.0, 0.5];
        let t = rows_to_pose(&p);
        assert_eq!(pose_to_rows(&t), p);
        let i = mul(&t, &invert(&t));
        assert!(reg::pose_distance(&i, &reg::IDENTITY).is_some_and(|(m, d)| m < 1e-12 && d < 1e-9));
    }

    #[test]
    fn a_loop_joining_two_passes_relates_their_places_through_it() {
        // Pass 1: places 0-9 at x = 0..9; pass 2: places 10-19 over the same street, but the
        // odometry drifted 12 m: x = 12..21. A loop accepted from place 15 to place 5 (the
        // identity: the same place) joins the passes.
        let det0 = super::super::verify::tests::detector_along(
            20,
            |i| {
                let x = if i < 10 {
                    f64::from(i)
                } else {
                    f64::from(i - 10) + 12.0
                };
                (pose(0.0, x, 0.0), f64::NAN)
            },
            |_| {},
        );
        let mut det = det0.clone();
        det.join(15, 5, &reg::IDENTITY);
        assert_eq!(det.joined_with(5).len(), 1);
        // Place 3 seen from place 15: through place 5 (2 m of path) 2 m behind it, not 14 m as
        // the drifted poses say (and place 15's own path to place 3 is 24 m).
        let (t_15_3, path) = det.joined_between(15, 3).unwrap();
        assert!(
            (t_15_3[0][3] + 2.0).abs() < 1e-9 && (path - 2.0).abs() < 1e-9,
            "{t_15_3:?} {path}"
        );
        assert!(det0.joined_between(15, 3).is_none());
        // A query at place 15's pose registered to place 15 (the identity) and to place 6 (1 m
        // ahead of it) at their true poses: the two passes' candidates agree through the loop,
        // not through the drifted poses (11 m apart for 1 m).
        let q = pose(0.0, 17.0, 0.0);
        let ahead = relative(&pose(0.0, 0.0, 0.0), &pose(0.0, 1.0, 0.0));
        let (me, other) = ((&q, 15, &reg::IDENTITY), (&q, 6, &ahead));
        assert_eq!(det.agree_through_poses(me, other), Some(true));
        assert_eq!(det0.agree_through_poses(me, other), Some(false));
    }

    #[test]
    fn joins_compose_their_poses_through_turned_passes() {
        // Three passes of one place, each seen turned: the true poses below; loops 2 → 1 and
        // 1 → 0 joined with their true poses. Place 0 seen from place 2 is the two loops
        // composed, T_2←1 · T_1←0, whatever the odometry says.
        let truth = [
            pose(0.0, 0.0, 0.0),
            pose(90.0, 0.5, 0.2),
            pose(-150.0, -0.3, 0.4),
        ];
        let mut det = detector_with_path(3, |_| {});
        det.join(1, 0, &relative(&truth[1], &truth[0]));
        det.join(2, 1, &relative(&truth[2], &truth[1]));
        let from_2 = det.joined_with(2);
        assert_eq!(from_2.iter().map(|(j, _)| *j).collect::<Vec<_>>(), [1, 0]);
        let t_2_0 = from_2[1].1;
        let want = relative(&truth[2], &truth[0]);
        assert!(reg::pose_distance(&t_2_0, &want).is_some_and(|(m, deg)| m < 1e-9 && deg < 1e-6));
        // And back: place 2 seen from place 0.
        let t_0_2 = det
            .joined_with(0)
            .into_iter()
            .find(|(j, _)| *j == 2)
            .unwrap()
            .1;
        let back = relative(&truth[0], &truth[2]);
        assert!(reg::pose_distance(&t_0_2, &back).is_some_and(|(m, deg)| m < 1e-9 && deg < 1e-6));
        // A join is recorded once, both ways.
        det.join(0, 1, &relative(&truth[0], &truth[1]));
        assert_eq!(det.joined_with(1).len(), 2);
    }

    #[test]
    fn a_loop_released_late_anchors_the_next_steps_when_it_is_the_latest() {
        let mut det = detector_with_path(40, |_| {});
        let truth =
            |q: u32, c: u32| relative(&pose(0.0, f64::from(q), 0.0), &pose(0.0, f64::from(c), 0.0));
        let released = [
            super::super::loop_of(&verified(2, truth(30, 2)), 30),
            super::super::loop_of(&verified(3, truth(31, 3)), 31),
        ];
        det.anchor_released(&released);
        let a = det.anchor.unwrap();
        assert_eq!((a.candidate, a.travelled), (3, 31.0));
        // An older loop released later does not replace it.
        det.anchor_released(&[super::super::loop_of(&verified(1, truth(29, 1)), 29)]);
        assert_eq!(det.anchor.unwrap().candidate, 3);
    }

    #[test]
    fn an_anchor_tightens_the_bounds_and_look_alikes_within_them_are_rejected() {
        // 40 places 1 m apart along x, all with the same descriptor (look-alikes of each
        // other); the query back at x = 40 after 2,000 m of path: the odometry allows 21 m.
        let mut det = detector_with_path(40, |v| {
            v.support_window = 0;
            v.unique = false;
        });
        let q = QueryPlace {
            id: det.len() as u32,
            pose: Some(pose(0.0, 40.0, 0.0)),
            travelled: 2000.0,
            eligible: det.len(),
        };
        let r = alloc::vec![1.0f32; det.map().config().n_range];
        let truth = |c: f64| relative(&q.pose.unwrap(), &pose(0.0, c, 0.0));
        // A true loop to place 2: places 13–22 lie where its pose would put the query within
        // the bound too, and look the same.
        let mut cands = [verified(2, truth(2.0))];
        det.check_after_gate(&q, &r, &mut cands).unwrap();
        assert_eq!(rejection(&cands[0]), Some(Rejection::LookAlike));
        // Off: kept.
        det.config.verify.lookalike_m = 0.0;
        let mut cands = [verified(2, truth(2.0)), verified(2, truth(15.0))];
        det.check_after_gate(&q, &r, &mut cands).unwrap();
        assert_eq!((rejection(&cands[0]), rejection(&cands[1])), (None, None));
        // After a loop one step back (query at x = 40, 1 m of path before, to place 1): the
        // bound through it is 1 m + 1 % of 2 m; the loop 13 m off disagrees, the true one is
        // kept, and the look-alikes 11 m and more away are ruled out.
        det.config.verify.lookalike_m = VerifyConfig::default().lookalike_m;
        let q0 = pose(0.0, 39.0, 0.0);
        det.anchor = Some(Anchor {
            query: q0,
            travelled: 1999.0,
            candidate: 1,
            pose: relative(&q0, &pose(0.0, 1.0, 0.0)),
        });
        let mut cands = [verified(2, truth(2.0)), verified(2, truth(15.0))];
        det.check_after_gate(&q, &r, &mut cands).unwrap();
        assert_eq!(rejection(&cands[0]), None);
        assert_eq!(rejection(&cands[1]), Some(Rejection::OdometryDisagrees));
        // Too old an anchor is not used.
        det.config.verify.loop_reset_m = 0.5;
        let mut cands = [verified(2, truth(15.0))];
        det.check_after_gate(&q, &r, &mut cands).unwrap();
        assert_eq!(rejection(&cands[0]), Some(Rejection::LookAlike));
    }

    #[test]
    fn a_look_alike_is_a_place_the_odometry_check_would_take_the_same_pose_to() {
        // After a square lap whose heading drifted 16° (verify's `square_lap`, 0.08°/m), every
        // place looking the same: the true loop into place 2 is 9 m off the poses, where the
        // rotation drift put the query. Places 13-16, 11-14 m from place 2, lie within a
        // quarter of the allowance in any direction (9-10 m) of where the same pose would put
        // the query: as look-alikes they turned it down. Taken in its direction (the
        // odometry check's form) the drift explains the true place alone.
        let mut det = square_lap(0.08, |v| {
            v.support_window = 0;
            v.unique = false;
        });
        let q = QueryPlace {
            id: 203,
            pose: Some(lap_odometry(0.08, 203)),
            travelled: 203.0,
            eligible: 190,
        };
        let r = alloc::vec![1.0f32; det.map().config().n_range];
        let right = relative(&lap_truth(203.0), &lap_truth(2.0));
        let mut cands = [verified(2, right)];
        det.check_after_gate(&q, &r, &mut cands).unwrap();
        assert_eq!(rejection(&cands[0]), None);
        // A look-alike within the bound's reach of place 2 still is one.
        det.config.verify.lookalike_m = 1.5;
        let mut cands = [verified(2, right)];
        det.check_after_gate(&q, &r, &mut cands).unwrap();
        assert_eq!(rejection(&cands[0]), Some(Rejection::LookAlike));
    }
}
