//! Breaks of the session's odometry: steps it cannot have made.
//!
//! An odometry that breaks down for a stretch (a LIO losing track, a wheel slipping) makes a
//! few steps far longer than the session's own: a keyframe 30 m from the last where the
//! vehicle moves 6 m. The path across such a step is no short path of known drift: the poses
//! on its two sides are related only by the loops between them, as a session's poses are to a
//! map's. A step is a break when it is more than [`BREAK_RATIO`] times the session's typical
//! step (the median of its last [`BREAK_HISTORY`] steps with poses), longer than that by more
//! than the gate's largest loop (a smaller error the drift bounds and the neighbours' vouching
//! absorb), and, when the timestamps say, [`BREAK_RATIO`] times as fast as the session's
//! typical speed: frames subsampled (a keyframe selection that skips a stretch) make one long
//! step in a long time, not a break.

use super::verify::QueryPlace;
use super::{Candidate, LoopDetector};

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
    /// Each break: the metres travelled before and after its step, in order.
    at: alloc::vec::Vec<[f64; 2]>,
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
        let typical = |k: usize| {
            let mut xs: alloc::vec::Vec<f64> = self
                .steps
                .iter()
                .map(|s| s[k])
                .filter(|x| !x.is_nan())
                .collect();
            if xs.len() < BREAK_MIN_STEPS {
                return None;
            }
            xs.sort_by(f64::total_cmp);
            Some(xs[xs.len() / 2])
        };
        let long = typical(0).is_some_and(|t| m > BREAK_RATIO * t && m - t > largest);
        let fast = speed.is_nan() || typical(1).is_none_or(|t| speed > BREAK_RATIO * t);
        let broke = long && fast;
        if broke {
            self.at.push([before, after]);
        } else {
            // A break's step is no measure of the session's steps.
            if self.steps.len() == BREAK_HISTORY {
                self.steps.pop_front();
            }
            self.steps.push_back([m, speed]);
        }
        broke
    }

    /// Whether the path between `a` and `b` metres travelled crosses a break (false when either
    /// is NaN: a map's place, or no pose).
    pub(super) fn crossed(&self, a: f64, b: f64) -> bool {
        let (lo, hi) = (a.min(b), a.max(b));
        !a.is_nan() && !b.is_nan() && self.at.iter().any(|&[x, y]| lo <= x && y <= hi)
    }

    /// How many breaks the session's odometry has had.
    pub(super) fn count(&self) -> usize {
        self.at.len()
    }
}

impl LoopDetector {
    /// Whether the path between two own places (metres travelled) crosses a break of the
    /// odometry.
    pub(super) fn crosses_break(&self, a: f64, b: f64) -> bool {
        self.breaks.crossed(a, b)
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
    }
}
