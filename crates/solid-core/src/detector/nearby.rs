//! Candidates chosen by pose: when the query has a pose, the own session's eligible places nearest
//! to where its odometry puts it are verified beside the descriptor's best
//! ([`VerifyConfig::pose_candidates`](crate::detector::VerifyConfig::pose_candidates)). Among
//! look-alike places the descriptor's few best rarely hold the true one; the odometry still says
//! roughly where the query is.

use alloc::vec::Vec;

use nalgebra::Matrix3;

use super::anchor::{Reach, Via};
use super::verify::{registered, reject, QueryPlace};
use super::{Candidate, LoopDetector};
use crate::compare::cosine_distance;
use crate::db::DbError;
use crate::heading_refined;
use crate::reg::{self, Rejection};

impl LoopDetector {
    /// Puts the step's candidates in the order verification takes them: the descriptor's first
    /// `verify.candidates`, then up to `verify.pose_candidates` more (twice that unanchored after
    /// a long path: [`LoopDetector::nearest_by_pose`]) of the own session's places
    /// `..eligible` nearest to the query's pose (added to the list when the descriptor's ranking
    /// lacks them), then the rest. Returns where the candidates chosen by pose begin and how
    /// many to verify (`(head, n)`: `head..n` were chosen by pose; the descriptor may rank fewer
    /// than `verify.candidates`).
    pub(super) fn add_pose_candidates(
        &self,
        r: &[f32],
        a: &[f32],
        pose: Option<&[f64; 12]>,
        travelled: f64,
        eligible: usize,
        cands: &mut Vec<Candidate>,
    ) -> Result<(usize, usize), DbError> {
        let v = &self.config.verify;
        let head = v.candidates.min(cands.len());
        let Some(q) = pose.filter(|_| v.pose_candidates > 0) else {
            return Ok((head, head));
        };
        let near = self.nearest_by_pose(q, travelled, eligible, &cands[..head])?;
        let mut picked = Vec::new();
        picked
            .try_reserve_exact(near.len())
            .map_err(|_| DbError::OutOfMemory)?;
        for id in near {
            match cands[head..].iter().position(|c| c.id == id) {
                Some(i) => picked.push(cands.remove(head + i)),
                None => picked.push(self.candidate_of(r, a, id)?),
            }
        }
        let n = head + picked.len();
        cands
            .try_reserve(picked.len())
            .map_err(|_| DbError::OutOfMemory)?;
        cands.splice(head..head, picked);
        Ok((head, n))
    }

    /// Up to `pose_candidates` ids (up to twice that, below) of own-session places `..eligible`
    /// with a pose, not in `taken`, nearest to `q`, each within reach: the gate's largest loop
    /// plus the odometry check's translation bound after the path between the two, without the
    /// rotation's allowance (a deliberate narrowing: with it every place of a long path would be
    /// within reach; the check of a candidate chosen by pose adds it).
    fn nearest_by_pose(
        &self,
        q: &[f64; 12],
        travelled: f64,
        eligible: usize,
        taken: &[Candidate],
    ) -> Result<Vec<u32>, DbError> {
        let v = &self.config.verify;
        // Room for the widened count (below): at most twice `pose_candidates`.
        let most = 2 * v.pose_candidates;
        let mut best: Vec<(f64, u32)> = Vec::new();
        best.try_reserve_exact(most + 1)
            .map_err(|_| DbError::OutOfMemory)?;
        let at = QueryPlace {
            id: 0,
            pose: Some(*q),
            travelled,
            eligible,
        };
        // Through the latest anchor when its path is the shorter ([`LoopDetector::expected`]).
        let anchored = self.anchored(&at);
        for id in (self.session_start..eligible.min(self.session_start + self.travelled.len()))
            .map(|k| k as u32)
        {
            if taken.iter().any(|c| c.id == id) {
                continue;
            }
            // Within reach of where the odometry puts the query, without the rotation's
            // allowance (which would put every place of a long path within reach).
            let Reach::Within(d) = self.reach(&at, anchored, id, 0.0) else {
                continue;
            };
            let at = best.partition_point(|&(e, _)| e <= d);
            if at < most {
                best.insert(at, (d, id));
                best.truncate(most);
            }
        }
        // The places the odometry cannot tell apart: one more per typical step of the session
        // that the odometry may be off by after the path to the nearest (the odometry check's
        // translation bound, `odometry_translation_m + odometry_drift · path`), at most
        // `pose_candidates` more, unless the anchor gives that place the shorter path. Where a
        // loop anchors the odometry the nearest few hold the true place; after a lap without
        // one, the odometry drifted by more than a step and the nearest are its neighbours a
        // step or two off (docs/performance.md, r19-drift). With keyframes closer than about
        // half the translation bound at no path (`odometry_translation_m`, 1 m: hku1's 0.2 m),
        // every step the anchor does not hold gets them (hku1: 1.07x the CPU a step).
        let n = best.first().map_or(0, |&(_, id)| {
            let step = self.breaks.typical();
            let Some((_, path, via)) = self.expected_via(&at, anchored, id) else {
                return v.pose_candidates;
            };
            let shorter = via == Via::Anchor { shorter: true };
            if step.is_nan() || step <= 0.0 || path.is_nan() || shorter {
                return v.pose_candidates;
            }
            let off = v.odometry_translation_m + v.odometry_drift * path;
            let more = libm::floor(off / step).min(v.pose_candidates as f64);
            v.pose_candidates + more as usize
        });
        best.truncate(n);
        Ok(best.into_iter().map(|(_, id)| id).collect())
    }

    /// The checks of the candidates chosen by pose that passed the gate (or failed only its
    /// length): chosen where the odometry puts the query and registered from there, a place
    /// whose clouds leave the translation loose ends where the odometry says (a slide along a
    /// corridor), and where the odometry has drifted a look-alike next to its position fits as
    /// well as the true place would. So the registration must reach
    /// `pose_candidate_min_information` and pass the odometry check as the descriptor's
    /// candidates do: within its bounds after the displacement the rotation the loop and the
    /// poses differ by predicts ([`LoopDetector::agrees_with_odometry`]), which after a lap is
    /// where the true place lies, a look-alike beside the drifted position a step or more off
    /// it. (Without the rotation's allowance, until r19-drift, every true place chosen by pose
    /// after the four-module corridors' 744 m lap drifting 1 % was turned down: 10.8-15.7 m
    /// off the odometry, 0.6-2.0 m off that displacement.)
    ///
    /// Returns the indices in `by_pose` of the candidates that passed the odometry check here
    /// (with it on): the odometry check after the gate takes them as agreeing
    /// ([`LoopDetector::check_after_gate_with`]) instead of asking again.
    pub(super) fn check_pose_candidates(
        &self,
        at: &QueryPlace,
        by_pose: &mut [Candidate],
    ) -> Vec<usize> {
        let v = &self.config.verify;
        let mut agreed = Vec::new();
        for (i, c) in by_pose.iter_mut().enumerate() {
            if !registered(c) {
                continue;
            }
            let info = c
                .verification
                .map_or(f64::NAN, |r| r.registration.degeneracy.translation);
            // A NaN information never passes.
            if info.is_nan() || info < v.pose_candidate_min_information {
                reject(c, Rejection::DegenerateTranslation);
            } else if v.odometry_check {
                if self.agrees_with_odometry(at, c, true) {
                    agreed.push(i);
                } else {
                    reject(c, Rejection::OdometryDisagrees);
                }
            }
        }
        agreed
    }

    /// Place `id` as an unverified candidate of the query `(r, a)`.
    pub(super) fn candidate_of(&self, r: &[f32], a: &[f32], id: u32) -> Result<Candidate, DbError> {
        let distance = cosine_distance(r, self.r(id))?;
        Ok(Candidate {
            id,
            distance,
            heading_deg: heading_refined(a, &self.a(id))?.degrees,
            score: distance,
            verification: None,
        })
    }
}

/// The unit direction (in the query's frame) along which `r`'s clouds constrain its
/// translation least: the eigenvector of the smallest eigenvalue of the Hessian's translation
/// block (a corridor's axis). None when the Hessian is not finite.
pub(super) fn weakest_translation(r: &reg::Registration) -> Option<[f64; 3]> {
    let h = &r.hessian;
    // The Hessian is in (rotation, translation) order about the query's origin.
    let htt = Matrix3::from_fn(|a, b| h[3 + a][3 + b]);
    if !htt.iter().all(|x| x.is_finite()) {
        return None;
    }
    let (_, u) = reg::weakest_direction(htt);
    Some([u[0], u[1], u[2]])
}

#[cfg(test)]
pub(super) mod tests {
    use crate::detector::verify::tests::with_r;
    use crate::detector::{DetectorConfig, LoopDetector};
    use crate::{Config, Descriptor};

    /// Row-major 3×4 pose at (x, y), facing +x.
    fn at(x: f64, y: f64) -> [f64; 12] {
        [1.0, 0.0, 0.0, x, 0.0, 1.0, 0.0, y, 0.0, 0.0, 1.0, 0.0]
    }

    fn descriptor(c: &Config, i: u32) -> Descriptor {
        let mut r = alloc::vec![1.0f32; c.n_range];
        r[i as usize % c.n_range] += 1.0;
        with_r(c, r)
    }

    /// A 40 m corridor 6 m wide and 3 m high (walls, floor, ceiling every 0.2 m), with boxes at
    /// the given x positions against its left wall.
    pub(crate) fn corridor(boxes: &[f64]) -> alloc::vec::Vec<[f64; 3]> {
        let mut p = alloc::vec::Vec::new();
        for i in -100..=100 {
            let x = f64::from(i) * 0.2;
            for j in 0..=15 {
                let z = f64::from(j) * 0.2;
                p.push([x, -3.0, z]);
                p.push([x, 3.0, z]);
            }
            for j in -15..=15 {
                let y = f64::from(j) * 0.2;
                p.push([x, y, 0.0]);
                p.push([x, y, 3.0]);
            }
        }
        for &b in boxes {
            for i in 0..=5 {
                for j in 0..=10 {
                    let (u, z) = (f64::from(i) * 0.2, f64::from(j) * 0.2);
                    p.push([b, -3.0 + u, z]);
                    p.push([b + 1.0, -3.0 + u, z]);
                    p.push([b + u, -2.0, z]);
                }
            }
        }
        p
    }

    #[test]
    fn the_places_nearest_to_the_query_pose_are_verified_beside_the_descriptors() {
        let c = Config::preset("hdl64").unwrap();
        let mut dc = DetectorConfig::default();
        dc.verify.enabled = false;
        let mut det = LoopDetector::new(c, dc).unwrap();
        // 80 places 1 m apart along x: the query at x = 80 sees the first 30 (the 50-frame
        // window; the 30 m one leaves the same).
        for i in 0..80 {
            det.detect(&descriptor(&c, i), f64::NAN, Some(at(f64::from(i), 0.0)))
                .unwrap();
        }
        dc.verify.candidates = 2;
        dc.verify.pose_candidates = 2;
        det.set_config(dc).unwrap();
        let d = descriptor(&c, 7);
        let eligible = 30;
        let ranked = det.rank(&d.r, &d.a, eligible, 10).unwrap();
        let head: alloc::vec::Vec<u32> = ranked[..2].iter().map(|c| c.id).collect();
        // Back near place 12 after 80 m (a revisit): the odometry may be off by 1 m + 1 % of
        // the 68 m to place 12 = 1.68 m, one typical step (1 m) more than the nearest two
        // cover: places 12, 11 and 13 join.
        let mut cands = ranked.clone();
        let q = at(12.2, 0.5);
        let n = det
            .add_pose_candidates(&d.r, &d.a, Some(&q), 80.0, eligible, &mut cands)
            .unwrap();
        assert_eq!(n, (2, 5));
        assert_eq!(
            cands[..2]
                .iter()
                .map(|c| c.id)
                .collect::<alloc::vec::Vec<_>>(),
            head
        );
        assert_eq!(cands[2].id, 12);
        let mut next = [cands[3].id, cands[4].id];
        next.sort_unstable();
        assert_eq!(next, [11, 13]);
        // After a lap of 400 m the odometry may be off by 4.88 m, more than four steps: at
        // most `pose_candidates` more, four in all.
        let mut lap = ranked.clone();
        let n = det
            .add_pose_candidates(&d.r, &d.a, Some(&q), 400.0, eligible, &mut lap)
            .unwrap();
        assert_eq!(n, (2, 6));
        // A loop 1 m back (query 11.2 → place 11) anchors the odometry: through it place 12 is
        // 2 m of path away, not 388 m; the nearest two hold the true place, none more.
        let mut anchored = det.clone();
        anchored.anchor = Some(crate::detector::anchor::Anchor {
            query: at(11.2, 0.5),
            travelled: 399.0,
            candidate: 11,
            pose: crate::detector::verify::relative(&at(11.2, 0.5), &at(11.0, 0.0)),
        });
        let mut lap = ranked.clone();
        let n = anchored
            .add_pose_candidates(&d.r, &d.a, Some(&q), 400.0, eligible, &mut lap)
            .unwrap();
        assert_eq!(n, (2, 4));
        assert_eq!(lap[2].id, 12);
        // No place repeats, and none is excluded.
        let mut ids: alloc::vec::Vec<u32> = cands.iter().map(|c| c.id).collect();
        assert!(ids.iter().all(|&i| (i as usize) < eligible));
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), cands.len());
        // The descriptor's own pick is not taken twice: near place head[0], the next nearest.
        let mut cands = ranked.clone();
        let near_head = at(f64::from(head[0]), 0.0);
        det.add_pose_candidates(&d.r, &d.a, Some(&near_head), 80.0, eligible, &mut cands)
            .unwrap();
        assert!(!cands[2..4].iter().any(|c| head.contains(&c.id)));
        // Beyond reach (the gate's 5 m, the drift bounds after the path): none.
        let mut cands = ranked.clone();
        let far = at(12.0, 200.0);
        let n = det
            .add_pose_candidates(&d.r, &d.a, Some(&far), 80.0, eligible, &mut cands)
            .unwrap();
        assert_eq!((n, cands.len()), ((2, 2), ranked.len()));
        // Without a pose, or with pose_candidates = 0: the descriptor's only.
        let mut cands = ranked.clone();
        let n = det
            .add_pose_candidates(&d.r, &d.a, None, f64::NAN, eligible, &mut cands)
            .unwrap();
        assert_eq!((n, &cands), ((2, 2), &ranked));
        // The descriptor ranked fewer than `candidates` (here one, as `top_k` 1 gives): those
        // chosen by pose begin right after it, where the caller checks them as such.
        let mut one = ranked[..1].to_vec();
        let n = det
            .add_pose_candidates(&d.r, &d.a, Some(&q), 80.0, eligible, &mut one)
            .unwrap();
        assert_eq!((n, one[1].id), ((1, 4), 12));
        dc.verify.pose_candidates = 0;
        det.set_config(dc).unwrap();
        let n = det
            .add_pose_candidates(&d.r, &d.a, Some(&q), 80.0, eligible, &mut cands)
            .unwrap();
        assert_eq!((n, &cands), ((2, 2), &ranked));
    }
}
