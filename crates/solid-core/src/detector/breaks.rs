//! Breaks of the session's odometry: steps it cannot have made.
//!
//! An odometry that breaks down for a stretch (a LIO losing track, a wheel slipping) makes a
//! few steps far longer than the session's own: a keyframe 30 m from the last where the
//! vehicle moves 6 m. The path across such a step is no short path of known drift: the poses
//! on its two sides are related only by the loops between them, as a session's poses are to a
//! map's. A step is a break when it is more than [`BREAK_RATIO`] times the session's typical
//! step (the median of its last [`BREAK_HISTORY`] steps with poses), longer than that by more
//! than the gate's largest loop (a smaller error leaves the loops over it off the odometry by
//! less than a loop's length: beyond the drift bounds they are vouched for by each other as
//! any loop the odometry does not hold, `consistency::vouch`), and, when the timestamps say,
//! [`BREAK_RATIO`] times as fast as the session's typical speed: frames subsampled (a keyframe
//! selection that skips a stretch) make one long step in a long time, not a break. Without the
//! caller's poses, the start of each of the detector's own chain frames is a break too
//! (`Breaks::frame`): loops across it are vouched for in the same way. One relation reaches
//! across breaks: a placement in a map made after a break releases the loops held before it
//! that agree with it through the session's typical step in place of each broken one
//! (`LoopDetector::bridged`): a straight stretch before a break waits for the turn after it.

use super::verify::{relative, QueryPlace};
use super::{Candidate, LoopDetector};
use crate::reg::{invert, mul, Pose, IDENTITY};

/// How many times the session's typical step (and speed) a break's step is at least.
pub(super) const BREAK_RATIO: f64 = 3.0;

/// Steps the typical step is the median of (the most recent).
pub(super) const BREAK_HISTORY: usize = 32;

/// Steps with poses a session makes before a break can be told from its typical step.
const BREAK_MIN_STEPS: usize = 4;

/// The odometry's steps and its breaks.
#[derive(Debug, Clone, Default)]
pub(super) struct Breaks {
    /// The last [`BREAK_HISTORY`] steps with poses: metres, and metres per second (NaN without
    /// time), oldest first.
    steps: alloc::collections::VecDeque<[f64; 2]>,
    /// Each break: the metres travelled before and after its step, and the session's typical
    /// step then (the median of the recent steps' metres; 0 before any), in order.
    at: alloc::vec::Vec<[f64; 3]>,
}

impl Breaks {
    /// Notes the session's step from `before` to `after` metres travelled in `seconds` (NaN:
    /// unknown); `largest` is the gate's largest loop. Returns whether it is a break.
    pub(super) fn note(&mut self, before: f64, after: f64, seconds: f64, largest: f64) -> bool {
        let m = after - before;
        if !m.is_finite() {
            return false;
        }
        let speed = if seconds > 0.0 { m / seconds } else { f64::NAN };
        let typical = |k: usize| self.median(k, BREAK_MIN_STEPS);
        let long = typical(0).is_some_and(|t| m > BREAK_RATIO * t && m - t > largest);
        let fast = speed.is_nan() || typical(1).is_none_or(|t| speed > BREAK_RATIO * t);
        let broke = long && fast;
        if broke {
            let step = typical(0).unwrap_or(0.0);
            self.at.push([before, after, step]);
        } else {
            // A break's step is no measure of the session's steps.
            if self.steps.len() == BREAK_HISTORY {
                self.steps.pop_front();
            }
            self.steps.push_back([m, speed]);
        }
        broke
    }

    /// Notes a break where nothing relates the poses on its two sides: the detector's own
    /// odometry starts a new frame (a link failed, or the caller's poses follow the chain's, or
    /// the chain follows them) after `before` metres travelled. How far the session moved across
    /// it is unknown: its typical step (the median of the recent steps), and at least the next
    /// metre value above `before`, so that the break lies between the places on its two sides.
    /// Returns the metres travelled after it (`before` when NaN: no pose before, no break).
    pub(super) fn frame(&mut self, before: f64) -> f64 {
        if before.is_nan() {
            return before;
        }
        let step = self.median(0, 1).unwrap_or(0.0);
        let after = (before + step).max(before.next_up());
        self.at.push([before, after, step]);
        after
    }

    /// The session's typical step: the median of the recent steps' metres (0 before any).
    pub(super) fn typical(&self) -> f64 {
        self.median(0, 1).unwrap_or(0.0)
    }

    /// The median of the recent steps' metres (`k` 0) or speeds (`k` 1), when at least `least`
    /// of them are known.
    fn median(&self, k: usize, least: usize) -> Option<f64> {
        let mut xs: alloc::vec::Vec<f64> = self
            .steps
            .iter()
            .map(|s| s[k])
            .filter(|x| !x.is_nan())
            .collect();
        if xs.len() < least.max(1) {
            return None;
        }
        xs.sort_by(f64::total_cmp);
        Some(xs[xs.len() / 2])
    }

    /// Whether the path between `a` and `b` metres travelled crosses a break (false when either
    /// is NaN: a map's place, or no pose).
    pub(super) fn crossed(&self, a: f64, b: f64) -> bool {
        self.between(a, b).next().is_some()
    }

    /// The breaks the path between `a` and `b` metres travelled crosses, in order (none when
    /// either is NaN).
    pub(super) fn between(&self, a: f64, b: f64) -> impl Iterator<Item = [f64; 3]> + '_ {
        let (lo, hi) = (a.min(b), a.max(b));
        // The breaks follow each other along the path (each one's end at most the next one's
        // start): those from the first starting at `lo` on, while they end by `hi`.
        let first = if a.is_nan() || b.is_nan() {
            self.at.len()
        } else {
            self.at.partition_point(|&[x, _, _]| x < lo)
        };
        self.at[first..]
            .iter()
            .take_while(move |&&[_, y, _]| y <= hi)
            .copied()
    }

    /// How many breaks the session's odometry has had.
    pub(super) fn count(&self) -> usize {
        self.at.len()
    }

    /// The stretch of odometry between breaks that holds `t` metres travelled: the metres where
    /// it begins (the end of the last break before it; None: the session's start) and where it
    /// ends (the start of the next break; None: it goes on through the latest step).
    pub(super) fn stretch(&self, t: f64) -> (Option<f64>, Option<f64>) {
        let k = self.at.partition_point(|&[_, y, _]| y <= t);
        let begin = k.checked_sub(1).map(|j| self.at[j][1]);
        (begin, self.at.get(k).map(|&[x, _, _]| x))
    }
}

impl LoopDetector {
    /// Whether the path between two own places (metres travelled) crosses a break of the
    /// odometry.
    pub(super) fn crosses_break(&self, a: f64, b: f64) -> bool {
        self.breaks.crossed(a, b)
    }

    /// The relative pose `inv(T_wa)·T_wb` of two own places by the poses, when a path the
    /// odometry holds joins them (no break between them).
    pub(super) fn related(&self, a: u32, b: u32) -> Option<Pose> {
        let (pa, pb) = (self.known_pose(a)?, self.known_pose(b)?);
        if let (Some(x), Some(y)) = (self.travelled_at(a), self.travelled_at(b)) {
            if self.crosses_break(x, y) {
                return None;
            }
        }
        Some(relative(&pa, &pb))
    }

    /// The relative pose `inv(T_wa)·T_wb` of two own poses `a` and `b` (at `ta` and `tb` metres
    /// travelled), the metres of path its drift grows with and the metres the relation may be off
    /// beyond that drift. Without a break between them: the poses' relative pose, `|ta − tb|`
    /// and 0. Across breaks, each break's step is taken as the session's typical one then (as
    /// [`Breaks::frame`] does for the metres travelled), along the direction of the session's last
    /// step before it (constant velocity; none known: no motion), with the rotation the odometry
    /// made over it (none across a frame the detector's own odometry started), and may be off by
    /// that typical step (the platform stopped, or moved twice its usual step): the poses on the
    /// two sides are related through the places at the break's two ends (at the end of the last
    /// one, `b` itself when it lies there and is no place yet: the step's query, related before
    /// its place is added). None when a break's end has no own place with a pose.
    pub(super) fn bridged(
        &self,
        a: &[f64; 12],
        ta: f64,
        b: &[f64; 12],
        tb: f64,
    ) -> Option<(Pose, f64, f64)> {
        if !self.crosses_break(ta, tb) {
            return Some((relative(a, b), libm::fabs(ta - tb), 0.0));
        }
        if ta > tb {
            let (p, path, off) = self.bridged(b, tb, a, ta)?;
            return Some((invert(&p), path, off));
        }
        let (mut rel, mut cur, mut t) = (IDENTITY, *a, ta);
        let (mut path, mut off) = (0.0, 0.0);
        // The session's direction of motion in `cur`'s frame, carried across a break.
        let mut heading: Option<[f64; 3]> = None;
        for [x, y, step] in self.breaks.between(ta, tb) {
            let (kx, px) = self.place_at(x, true)?;
            let r = relative(&cur, &px);
            heading = self.heading_at(kx, &px).or_else(|| {
                heading.map(|d| core::array::from_fn(|i| (0..3).map(|k| r[k][i] * d[k]).sum()))
            });
            rel = mul(&rel, &r);
            path += x - t;
            let mut s = IDENTITY;
            if let Some(d) = heading {
                for (i, row) in s.iter_mut().take(3).enumerate() {
                    row[3] = step * d[i];
                }
            }
            // The pose at the break's end, and the frame of the own odometry it lies in: the
            // place there, or `b` itself when it lies there and is no place yet (the step's
            // query, related to the hypotheses before it before its place is added: without
            // it, the first query after a break agreed with nothing before the break, and
            // joining a consistent set first it kept that set from reaching across).
            let (fy, py) = match self.place_at(y, false) {
                Some((ky, py)) => (self.known[ky].map(|(_, f)| f), py),
                None if y == tb => {
                    // Only the step's own place is missing: every earlier one lies before it.
                    debug_assert!(self.travelled.iter().all(|&t| t.is_nan() || t < tb));
                    (Some(self.chain.frame), *b)
                }
                None => return None,
            };
            // The rotation the odometry made over the broken step, when its two ends lie in one
            // frame of it (the caller's poses): a breakdown loses the position sooner than the
            // heading (an IMU, a LiDAR odometry sliding along a corridor), and a turn made while
            // it was broken is a turn. Across a frame the detector's own odometry started, the
            // two frames' rotations are unrelated: none.
            if self.known[kx].map(|(_, f)| f) == fy {
                let turn = relative(&px, &py);
                for (row, from) in s.iter_mut().zip(turn.iter()) {
                    row[..3].copy_from_slice(&from[..3]);
                }
                // The direction of motion, in the frame after the step.
                heading = heading
                    .map(|d| core::array::from_fn(|i| (0..3).map(|k| turn[k][i] * d[k]).sum()));
            }
            rel = mul(&rel, &s);
            path += step;
            off += step;
            (cur, t) = (py, y);
        }
        rel = mul(&rel, &relative(&cur, b));
        Some((rel, path + (tb - t), off))
    }

    /// The own place with a pose at `metres` travelled (the last such when `last`, else the
    /// first), and its pose.
    fn place_at(&self, metres: f64, last: bool) -> Option<(usize, [f64; 12])> {
        let at = |k: &usize| self.travelled[*k] == metres;
        let pose = |k: usize| Some(k).zip(self.known_pose((self.session_start + k) as u32));
        let n = self.travelled.len();
        if last {
            (0..n).rev().filter(at).find_map(pose)
        } else {
            (0..n).filter(at).find_map(pose)
        }
    }

    /// The unit direction, in own place `k`'s frame (pose `p`), of the session's last step into
    /// it from the nearest earlier place with a pose that no break separates from it.
    fn heading_at(&self, k: usize, p: &[f64; 12]) -> Option<[f64; 3]> {
        let t = self.travelled[k];
        let (_, prev) = (0..k)
            .rev()
            .take_while(|&j| !self.crosses_break(self.travelled[j], t))
            .filter(|&j| self.travelled[j] < t)
            .find_map(|j| Some(j).zip(self.known_pose((self.session_start + j) as u32)))?;
        let w = [p[3] - prev[3], p[7] - prev[7], p[11] - prev[11]];
        let d: [f64; 3] = core::array::from_fn(|i| (0..3).map(|k| p[4 * k + i] * w[k]).sum());
        let n = libm::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        (n > 1e-9).then(|| d.map(|x| x / n))
    }

    /// Whether a candidate is an own place whose every path to the query `at` (through the
    /// two places' poses, or through the latest anchor) crosses a break: the odometry says
    /// nothing about the loop.
    pub(super) fn across_break(&self, at: &QueryPlace, c: &Candidate) -> bool {
        at.pose.is_some()
            && !self.in_map(c.id)
            && self.known_pose(c.id).is_some()
            && self.travelled_at(c.id).is_some()
            && self.expected(at, c.id, true).is_none()
    }

    /// The own queries of the stretch of odometry between breaks that holds `t` metres
    /// travelled (a query's): the first, and the last when a break ended the stretch (None: it
    /// goes on, the current frame of the odometry). Poses of the stretch share one frame; the
    /// poses of two stretches are related by nothing the odometry knows.
    pub(super) fn stretch_queries(&self, t: f64) -> (u32, Option<u32>) {
        let (begin, end) = self.breaks.stretch(t);
        let id = |k: usize| (self.session_start + k) as u32;
        let known = |k: &usize| !self.travelled[*k].is_nan();
        let n = self.travelled.len();
        let first = begin
            .and_then(|b| (0..n).filter(known).find(|&k| self.travelled[k] >= b))
            .unwrap_or(0);
        let last = end.map(|e| {
            (0..n)
                .rev()
                .filter(known)
                .find(|&k| self.travelled[k] <= e)
                .unwrap_or(first)
        });
        (id(first), last.map(id))
    }

    /// How many breaks the session's odometry has had so far (a step it cannot have made: spec §8,
    /// "Breaks").
    pub fn odometry_breaks(&self) -> usize {
        self.breaks.count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_far_beyond_the_sessions_own_is_a_break_but_a_long_step_in_a_long_time_is_not() {
        let mut b = Breaks::default();
        let mut t = 0.0;
        for _ in 0..10 {
            assert!(!b.note(t, t + 6.0, 1.0, 5.0));
            t += 6.0;
        }
        // Frames subsampled: 30 m in 5 s.
        assert!(!b.note(t, t + 30.0, 5.0, 5.0));
        t += 30.0;
        // 30 m in a second.
        assert!(b.note(t, t + 30.5, 1.0, 5.0));
        assert!(b.crossed(t + 40.0, 2.0) && b.crossed(t, t + 30.5));
        assert!(!b.crossed(t + 30.5, t + 50.0) && !b.crossed(2.0, t) && !b.crossed(f64::NAN, 0.0));
        t += 30.5;
        // Without time, the length alone: a long step is a break.
        assert!(b.note(t, t + 30.0, f64::NAN, 5.0));
        // Three times as long, but by less than the largest loop: the bounds absorb it.
        let mut b = Breaks::default();
        for k in 0..10 {
            assert!(!b.note(f64::from(k), f64::from(k + 1), 0.1, 5.0));
        }
        assert!(!b.note(10.0, 14.0, 0.1, 5.0));
        assert!(b.note(14.0, 21.0, 0.1, 5.0));
        assert_eq!(b.count(), 1);
        // The stretches between breaks: before it, after it.
        assert_eq!(b.stretch(3.0), (None, Some(14.0)));
        assert_eq!(
            (b.stretch(14.0), b.stretch(21.0)),
            ((None, Some(14.0)), (Some(21.0), None))
        );
    }

    #[test]
    fn a_frame_the_chain_starts_is_a_break_of_the_sessions_typical_step() {
        let mut b = Breaks::default();
        // Before any step: still a break, between the places on its two sides.
        let after = b.frame(0.0);
        assert!(after > 0.0 && b.crossed(0.0, after) && !b.crossed(after, after + 1.0));
        let mut t = after;
        for _ in 0..5 {
            assert!(!b.note(t, t + 2.0, f64::NAN, 5.0));
            t += 2.0;
        }
        assert_eq!(b.frame(t), t + 2.0);
        assert!(b.crossed(t - 4.0, t + 2.0) && b.crossed(0.0, t + 3.0));
        assert!(!b.crossed(after, t) && !b.crossed(t + 2.0, t + 9.0));
        assert_eq!(b.count(), 2);
        // No pose before: no break.
        assert!(Breaks::default().frame(f64::NAN).is_nan());
    }
}
