//! The step's budget ([`VerifyConfig::step_points`](super::VerifyConfig::step_points)): what a
//! registration costs, and the candidates a step could not afford, registered by the next steps.
//!
//! A step registers its candidates in their order while their cost fits the budget (its best
//! always); the others are *deferred* unless the step found its loop: kept with the query's
//! place and cloud, and registered, oldest query first, by the next steps before their own
//! candidates, within the budget (the first always, so that none waits forever), except the
//! look-alikes' backlog: an own place without a start (the hypotheses) of a query whose step
//! registered nothing that met the quality checks waits for what the step's own best candidate
//! leaves of the budget (the first always only on a step with none of its own, see
//! [`LoopDetector::run_deferred`]), so that a step runs its own best or such a backlog
//! registration without a start, not both. Most steps of a drive register nothing (no
//! revisit), so their budget clears the backlog a few steps later. A deferred registration
//! goes through the same gate and checks as at its own step (against the query's pose and the
//! detector's state when it runs); its loop, when the
//! query has none yet, is reported with the step that registered it
//! ([`Detection::released`](super::Detection::released)), and its registration supports the
//! next steps' loops as its own step's would have.

use alloc::collections::VecDeque;
use alloc::sync::Arc;
use alloc::vec::Vec;

use super::verify::{loop_length_score, met_quality, QueryPlace};
use super::{loop_of, Candidate, LoopDetector};
use crate::db::DbError;
use crate::reg::{self, PreparedCloud};

/// Queries whose deferred candidates are kept at most: a new one drops the oldest.
pub const DEFERRED_QUERIES: usize = 8;

/// Steps a query's deferred candidates wait at most: older ones are dropped.
pub const DEFERRED_STEPS: u32 = 8;

/// The candidates of one query its step deferred.
#[derive(Debug, Clone)]
pub(super) struct Deferred {
    at: QueryPlace,
    /// The query's prepared cloud, kept from the end of its step (the cache may evict it).
    cloud: Option<Arc<PreparedCloud>>,
    /// The candidates its step registered, as the gate left them (the deferred ones' neighbours).
    done: Vec<Candidate>,
    /// The candidates waiting, best first, each with whether it was chosen by pose.
    waiting: VecDeque<(Candidate, bool)>,
}

/// The deferred candidates, oldest query first.
#[derive(Debug, Clone, Default)]
pub(super) struct Queue {
    queries: VecDeque<Deferred>,
    /// Candidates dropped without a registration (the queue full, or too old).
    dropped: usize,
    /// Candidates not registered because their query found its loop.
    looped: usize,
}

impl LoopDetector {
    /// The work of registering own or map place `id` with the query cloud `q`, in points: the
    /// two clouds' fine points times the registrations it runs, one from a known start (the
    /// odometry's, [`LoopDetector::odometry_start`], or a neighbour's among `led`, the
    /// candidates registered before it), else one per yaw hypothesis. None when the place has
    /// no cloud.
    ///
    /// # Errors
    /// As [`LoopDetector::try_cloud`].
    pub(super) fn registration_cost(
        &self,
        q: &PreparedCloud,
        at: Option<&QueryPlace>,
        anchored: Option<([f64; 12], f64, f64)>,
        id: u32,
        led: &[u32],
    ) -> Result<Option<usize>, DbError> {
        let v = &self.config.verify;
        let points = match self.prepared.get(&id) {
            Some((_, c)) => c.fine.len(),
            None => match self.try_cloud(id)? {
                // An unreadable cloud is no cloud (as [`LoopDetector::prepared_cloud`]).
                Some(bytes) => match reg::cloud_points(&bytes) {
                    Ok(n) => n,
                    Err(_) => return Ok(None),
                },
                None => return Ok(None),
            },
        };
        let known = self.known_start(at, anchored, id, led);
        let runs = if known { 1 } else { v.hypotheses.max(1) };
        Ok(Some((q.fine.len() + points).saturating_mul(runs)))
    }

    /// Whether own or map place `id` registers with the query `at` from a known start (one
    /// registration, not one per yaw hypothesis): the odometry's or a neighbour's among `led`
    /// ([`LoopDetector::registration_cost`]).
    fn known_start(
        &self,
        at: Option<&QueryPlace>,
        anchored: Option<([f64; 12], f64, f64)>,
        id: u32,
        led: &[u32],
    ) -> bool {
        let v = &self.config.verify;
        v.gate.min_agreement <= 1
            && (led.iter().any(|&l| self.neighbours(l, id))
                || at
                    .filter(|_| v.odometry_check)
                    .and_then(|at| self.odometry_start(at, anchored, id))
                    .is_some())
    }

    /// The cost ([`LoopDetector::registration_cost`]) of the step's own best candidate among
    /// `cands` (the step of query `at`, its cloud `q`): the first the poses leave within reach
    /// that has a cloud; None when the step will register none of its own.
    ///
    /// # Errors
    /// As [`LoopDetector::try_cloud`].
    pub(super) fn own_best_cost(
        &self,
        q: &PreparedCloud,
        at: &QueryPlace,
        cands: &[Candidate],
    ) -> Result<Option<usize>, DbError> {
        let beyond = self.beyond_reach(Some(at), cands)?;
        let anchored = self.anchored(at);
        for (c, _) in cands.iter().zip(&beyond).filter(|&(_, &b)| !b) {
            match self.registration_cost(q, Some(at), anchored, c.id, &[]) {
                // From a known start (one registration): the backlog keeps the earlier rule.
                Ok(Some(_)) if self.known_start(Some(at), anchored, c.id, &[]) => return Ok(None),
                Ok(Some(cost)) => return Ok(Some(cost)),
                Ok(None) | Err(DbError::Format { .. }) => {}
                Err(e) => return Err(e),
            }
        }
        Ok(None)
    }

    /// Keeps the candidates `over` (indices in `cands`) of the step's query `at` for the next
    /// steps; `cands` as the gate left them, those from `by_pose` on chosen by pose.
    pub(super) fn defer(
        &mut self,
        at: QueryPlace,
        cands: &[Candidate],
        over: &[usize],
        by_pose: usize,
    ) -> Result<(), DbError> {
        if over.is_empty() {
            return Ok(());
        }
        let mut waiting = VecDeque::new();
        waiting
            .try_reserve_exact(over.len())
            .map_err(|_| DbError::OutOfMemory)?;
        waiting.extend(over.iter().map(|&i| (cands[i], i >= by_pose)));
        let mut done = Vec::new();
        done.try_reserve_exact(cands.len())
            .map_err(|_| DbError::OutOfMemory)?;
        done.extend(cands.iter().filter(|c| c.verification.is_some()).copied());
        let q = &mut self.deferred;
        if q.queries.len() == DEFERRED_QUERIES {
            if let Some(d) = q.queries.pop_front() {
                q.dropped += d.waiting.len();
            }
        }
        q.queries.try_reserve(1).map_err(|_| DbError::OutOfMemory)?;
        q.queries.push_back(Deferred {
            at,
            cloud: None,
            done,
            waiting,
        });
        Ok(())
    }

    /// At the end of query `id`'s step: keeps its prepared cloud `cloud` with its deferred
    /// candidates, or drops them when the step found its loop (`looped`: the query needs no
    /// other, and the loop's registration supports the next steps). Returns the ids of the
    /// candidates kept waiting ([`Detection::deferred`](super::Detection::deferred)).
    ///
    /// # Errors
    /// [`DbError::OutOfMemory`] when the list cannot be allocated.
    pub(super) fn end_deferring(
        &mut self,
        id: u32,
        cloud: Option<&Arc<PreparedCloud>>,
        looped: bool,
    ) -> Result<Vec<u32>, DbError> {
        let q = &mut self.deferred;
        if q.queries.back().is_none_or(|d| d.at.id != id) {
            return Ok(Vec::new());
        }
        match (cloud.filter(|_| !looped), q.queries.back_mut()) {
            (Some(c), Some(d)) => {
                d.cloud = Some(Arc::clone(c));
                let mut ids = Vec::new();
                ids.try_reserve_exact(d.waiting.len())
                    .map_err(|_| DbError::OutOfMemory)?;
                ids.extend(d.waiting.iter().map(|(c, _)| c.id));
                Ok(ids)
            }
            _ => {
                let n = q.queries.pop_back().map_or(0, |d| d.waiting.len());
                q.looped += n;
                Ok(Vec::new())
            }
        }
    }

    /// Candidates deferred and not registered: dropped because the queue was full or their
    /// query too old ([`DEFERRED_QUERIES`], [`DEFERRED_STEPS`]), since the detector was made.
    pub fn deferred_dropped(&self) -> usize {
        self.deferred.dropped
    }

    /// Candidates deferred and not registered because their step found its loop.
    pub fn deferred_unneeded(&self) -> usize {
        self.deferred.looped
    }

    /// Whether query `id` has candidates its step deferred still waiting.
    pub(super) fn deferring(&self, id: u32) -> bool {
        self.deferred
            .queries
            .iter()
            .any(|d| d.at.id == id && !d.waiting.is_empty())
    }

    /// Candidates deferred by earlier steps and still waiting.
    pub fn deferred_waiting(&self) -> usize {
        self.deferred.queries.iter().map(|d| d.waiting.len()).sum()
    }

    /// Registers the deferred candidates, oldest query first, while their cost fits the step's
    /// budget (the step of query `now`) less `reserve`, the cost of the step's own best
    /// candidate ([`LoopDetector::own_best_cost`], always registered after them): each query's
    /// as its own step would have (the gate, the checks of a candidate chosen by pose, the
    /// checks after the gate), its loop released when it has none yet. The first is
    /// registered whatever it costs on a step without a candidate of its own (`reserve` None).
    /// Otherwise an own place without a known start, of a query whose step registered nothing
    /// that met the quality checks (look-alikes), waits for such a step (a revisit's stretch of
    /// steps is followed by new ground), so that a step runs one registration without a start
    /// (the hypotheses), not its own and a deferred one. The others keep the earlier rule (the
    /// first always, the others within the whole budget): one with a start (the odometry's or
    /// a neighbour's that met the quality checks); one of a query whose step registered a
    /// place that met the quality checks but whose loop a later check held (a revisit whose
    /// odometry broke: the backlog's registrations at the next steps are the support that
    /// overrules the odometry and releases its held loops, and every step of the revisit has
    /// its own candidates); a place of another session (a map's, a neighbour's start counted
    /// whether or not it met the quality checks): a session inside a map has candidates at
    /// every step, so no step with budget to spare would come, and the placement counts what
    /// its steps register (measured: without this exception the anchors of the sessions into
    /// a map count other loops). A query whose loop came since (released) needs no other.
    /// A candidate that waits keeps its place and holds back none after it (its query's or a
    /// later query's); only one over the budget under the earlier rule ends the backlog's turn.
    /// Returns the work spent.
    ///
    /// # Errors
    /// As [`LoopDetector::verify_candidates`].
    pub(super) fn run_deferred(
        &mut self,
        now: u32,
        reserve: Option<usize>,
    ) -> Result<usize, DbError> {
        let v = self.config.verify;
        let mut work = 0usize;
        // Queries whose next candidate waits for budget to spare: they keep their place (oldest
        // first) without blocking the later queries' candidates that keep the earlier rule.
        let mut set_aside: Vec<Deferred> = Vec::new();
        while let Some(mut d) = self.deferred.queries.pop_front() {
            if now.saturating_sub(d.at.id) > DEFERRED_STEPS {
                self.deferred.dropped += d.waiting.len();
                continue;
            }
            // A query whose loop came since (released by a later step's vouching) needs no
            // other, as one whose step found it.
            if self.placement.looped.contains(&d.at.id) {
                self.deferred.looped += d.waiting.len();
                continue;
            }
            let q = match d.cloud.take() {
                Some(q) => Some(q),
                None => self.prepared_cloud(d.at.id)?,
            };
            let Some(mut q) = q else {
                self.deferred.dropped += d.waiting.len();
                continue;
            };
            if !q.is_complete() {
                let mut c = PreparedCloud::clone(&q);
                c.complete()?;
                q = Arc::new(c);
            }
            let anchored = self.anchored(&d.at);
            // Whether the query's step registered a place that met the quality checks (passed
            // the gate, or failed only its `max_translation`): a revisit whose loop a later
            // check held (the odometry, the support), for which the backlog's registrations are
            // the support that releases it.
            let passed = d
                .done
                .iter()
                .any(|c| c.verification.as_ref().is_some_and(met_quality));
            let (mut jobs, mut cands, mut by_pose) = (Vec::new(), Vec::new(), Vec::new());
            // A candidate that waits leaves the query's later ones their turn; one over the
            // budget under the earlier rule ends the step's backlog (`full`).
            let (mut i, mut full) = (0, false);
            while let Some(&(c, pose)) = d.waiting.get(i) {
                // A scan the own odometry could not link: it cannot be accepted.
                if self.unlinked_place(c.id) {
                    d.waiting.remove(i);
                    continue;
                }
                // Only an own place without a start, of a query whose step registered nothing
                // that met the quality checks, on a step whose own best has no start either,
                // waits for what that best leaves of the budget (its neighbours among the
                // query's step's registrations give it no start: none met the quality checks,
                // `register_jobs`); the others keep the earlier rule (see above), its cost (a
                // neighbour's start counted whatever its result) included.
                let other = self.in_map(c.id) || self.entry(c.id).0 != self.session;
                let led: Vec<u32> = cands.iter().map(|c: &Candidate| c.id).collect();
                let wait = reserve.filter(|_| {
                    !passed && !other && !self.known_start(Some(&d.at), anchored, c.id, &led)
                });
                let led: Vec<u32> = if wait.is_some() {
                    led
                } else {
                    d.done.iter().chain(&cands).map(|c| c.id).collect()
                };
                let cost = match self.registration_cost(&q, Some(&d.at), anchored, c.id, &led) {
                    Ok(Some(cost)) => cost,
                    Ok(None) | Err(DbError::Format { .. }) => {
                        d.waiting.remove(i);
                        continue;
                    }
                    Err(e) => return Err(e),
                };
                // The first always fits (one over a whole budget would never), except one that
                // waits: a step runs its own best or the backlog's first without a start.
                if (work > 0 || wait.is_some())
                    && work.saturating_add(cost).saturating_add(wait.unwrap_or(0)) > v.step_points
                {
                    if wait.is_some() {
                        i += 1;
                        continue;
                    }
                    full = true;
                    break;
                }
                d.waiting.remove(i);
                let cp = match self.prepared_cloud(c.id) {
                    Ok(Some(cp)) => cp,
                    Ok(None) | Err(DbError::Format { .. }) => continue,
                    Err(e) => return Err(e),
                };
                work = work.saturating_add(cost);
                jobs.push((cands.len(), cp));
                cands.push(c);
                by_pose.push(pose);
            }
            if !jobs.is_empty() && self.verify_deferred(&d, &q, &jobs, &mut cands, &by_pose)? {
                // Its loop found: the query needs no other.
                self.deferred.looped += d.waiting.len();
                continue;
            }
            if !d.waiting.is_empty() {
                d.cloud = Some(q);
                if !full {
                    set_aside.push(d);
                    continue;
                }
                self.deferred.queries.push_front(d);
                break;
            }
        }
        for d in set_aside.into_iter().rev() {
            self.deferred.queries.push_front(d);
        }
        Ok(work)
    }

    /// Registers the deferred candidates `cands` of `d` (`jobs`: their clouds), checks them as
    /// their own step would have, and releases the best one's loop; whether one passed.
    fn verify_deferred(
        &mut self,
        d: &Deferred,
        q: &PreparedCloud,
        jobs: &[(usize, Arc<PreparedCloud>)],
        cands: &mut [Candidate],
        by_pose: &[bool],
    ) -> Result<bool, DbError> {
        let at = d.at;
        let a = self.a(at.id);
        // The candidates chosen by pose follow the descriptor's, as in their step.
        let split = by_pose.iter().position(|&p| p).unwrap_or(by_pose.len());
        self.register_jobs(&a, q, Some(&at), (jobs, split), cands, &d.done)?;
        let agreed = self.check_pose_candidates(&at, &mut cands[split..]);
        let agreed: Vec<usize> = agreed.into_iter().map(|i| split + i).collect();
        let r = self.r(at.id).to_vec();
        self.check_after_gate_with(&at, &r, cands, &agreed)?;
        let best = cands
            .iter()
            .filter(|c| c.verification.is_some_and(|r| r.accepted))
            .min_by(|x, y| {
                let score =
                    |c: &Candidate| c.verification.map(|r| loop_length_score(&r.registration));
                score(x)
                    .partial_cmp(&score(y))
                    .unwrap_or(core::cmp::Ordering::Equal)
            });
        if let Some(c) = best.copied() {
            // The latest loop anchors the odometry checks (a later query's loop stays).
            if self.anchor.is_none_or(|a| a.travelled <= at.travelled) {
                self.anchor_on(&at, &c);
            }
            self.release_late(loop_of(&c, at.id));
        }
        Ok(best.is_some())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detector::nearby::tests::corridor;
    use crate::detector::verify::tests::{pose, with_r};
    use crate::detector::{DetectorConfig, Scan, VerifyConfig};
    use crate::{Config, Descriptor, Points};

    /// A descriptor nearest to place `best`, then to place `next` (the others farther, equal).
    fn descriptor(c: &Config, best: usize, next: usize) -> Descriptor {
        let mut r = alloc::vec![0.0f32; c.n_range];
        r[0] = 1.0;
        r[best + 1] = 0.1;
        r[next + 1] += 0.05;
        with_r(c, r)
    }

    /// The corridor's world seen from x (places 0..9 stand at x = 0..9, facing +x).
    fn seen(x: f64) -> Vec<f64> {
        let world = corridor(&[-13.0, -4.5, 3.0, 11.5]);
        world.iter().flat_map(|p| [p[0] - x, p[1], p[2]]).collect()
    }

    /// A cloud that matches nothing in the corridor (a sphere's shell).
    fn decoy() -> Vec<f64> {
        let mut p = Vec::new();
        for i in 0..40 {
            for j in 0..40 {
                let (t, f) = (f64::from(i) * 0.157, f64::from(j) * 0.0785);
                p.extend([
                    7.0 * libm::cos(t) * libm::sin(f),
                    7.0 * libm::sin(t) * libm::sin(f),
                    7.0 * libm::cos(f),
                ]);
            }
        }
        p
    }

    /// Ten places with clouds along the corridor (place 9's a decoy), then the budget `budget`
    /// (None: the default) and the steps' checks that need no history.
    fn corridor_places(budget: Option<usize>) -> LoopDetector {
        let c = Config::preset("hdl64").unwrap();
        let mut dc = DetectorConfig {
            exclude_frames: 1000,
            exclude_meters: 0.0,
            exclude_seconds: 0.0,
            ..DetectorConfig::default()
        };
        dc.verify.enabled = true;
        let mut det = LoopDetector::new(c, dc).unwrap();
        for i in 0..10u32 {
            let pts = if i == 9 { decoy() } else { seen(f64::from(i)) };
            let scan = det.scan(&c, i as usize, i as usize, &pts);
            det.detect_scan(scan, f64::NAN, Some(pose(0.0, f64::from(i), 0.0)))
                .unwrap();
        }
        dc.exclude_frames = 0;
        let v: &mut VerifyConfig = &mut dc.verify;
        (v.candidates, v.pose_candidates, v.support_window) = (2, 0, 0);
        v.lookalike_m = 0.0;
        if let Some(b) = budget {
            v.step_points = b;
        }
        det.set_config(dc).unwrap();
        det
    }

    impl LoopDetector {
        fn scan(&self, c: &Config, best: usize, next: usize, pts: &[f64]) -> Scan {
            Scan {
                descriptor: descriptor(c, best, next),
                cloud: self.prepare_cloud(Points::new(pts, 3).unwrap()).unwrap(),
            }
        }
    }

    #[test]
    fn a_candidate_over_the_budget_is_registered_by_the_next_step_and_its_loop_released() {
        let c = Config::preset("hdl64").unwrap();
        // The query at x = 10: its best candidate is the decoy (place 9, registered and
        // rejected), its second the true place 8, 2 m behind.
        let step = |det: &mut LoopDetector, x: f64, (best, next)| {
            let scan = det.scan(&c, best, next, &seen(x));
            det.detect_scan(scan, f64::NAN, Some(pose(0.0, x, 0.0)))
                .unwrap()
        };
        let near = |l: &super::super::Loop| {
            let t = l.pose.unwrap();
            l.candidate == 8 && (t[0][3] + 2.0).abs() < 0.1 && t[1][3].abs() < 0.1
        };
        // Within the budget: both registered, place 8 is the step's loop.
        let mut det = corridor_places(None);
        let d = step(&mut det, 10.0, (9, 8));
        assert!(d.accepted.is_some_and(|l| near(&l)), "{:?}", d.accepted);
        // A budget of one seeded registration: the decoy (the best, always registered) uses it,
        // place 8 waits; the next step (a query far from every place) registers it before its
        // own best and releases the loop of query 10.
        let one = {
            let det = corridor_places(None);
            let q = PreparedCloud::deferred(
                Points::new(&seen(10.0), 3).unwrap(),
                &det.config.verify.registration,
            )
            .unwrap();
            det.registration_cost(&q, None, None, 8, &[9])
                .unwrap()
                .unwrap()
        };
        let mut det = corridor_places(Some(one));
        let d = step(&mut det, 10.0, (9, 8));
        let c8 = d.candidates.iter().find(|c| c.id == 8).unwrap();
        assert!(d.accepted.is_none() && c8.verification.is_none(), "{d:?}");
        assert_eq!((det.deferred_waiting(), &d.deferred[..]), (1, &[8][..]));
        let d = step(&mut det, 40.0, (0, 1));
        assert_eq!(d.accepted, None);
        assert_eq!(d.deferred, [1]);
        assert_eq!(d.released.len(), 1, "{:?}", d.released);
        assert!(
            d.released[0].query == 10 && near(&d.released[0]),
            "{:?}",
            d.released
        );
        // Query 10's candidate is done; the step's own second waits in turn.
        assert_eq!((det.deferred_waiting(), det.deferred_dropped()), (1, 0));
        // Reported once: the next steps release nothing more.
        let d = step(&mut det, 41.0, (0, 1));
        assert!(d.released.is_empty());
        // A step that found its loop keeps nothing for later: place 8 first, the decoy waits
        // for nothing.
        let mut det = corridor_places(Some(one));
        let d = step(&mut det, 10.0, (8, 9));
        assert!(d.accepted.is_some_and(|l| near(&l)), "{:?}", d.accepted);
        assert!(d.deferred.is_empty());
        assert_eq!((det.deferred_waiting(), det.deferred_unneeded()), (0, 1));
    }

    #[test]
    fn a_deferred_candidate_waits_only_when_its_query_registered_nothing_that_met_the_quality_checks(
    ) {
        let c = Config::preset("hdl64").unwrap();
        let step = |det: &mut LoopDetector, x: f64, (best, next)| {
            let scan = det.scan(&c, best, next, &seen(x));
            det.detect_scan(scan, f64::NAN, Some(pose(0.0, x, 0.0)))
                .unwrap()
        };
        // Without the odometry check no candidate has the odometry's start (each takes the
        // hypotheses); the gate accepts no loop over 1 m; the budget is one registration of
        // place 8 from the hypotheses.
        let mut dc = *corridor_places(None).config();
        dc.verify.odometry_check = false;
        dc.verify.gate.max_translation = 1.0;
        dc.verify.step_points = {
            let det = corridor_places(None);
            let q = PreparedCloud::deferred(
                Points::new(&seen(10.0), 3).unwrap(),
                &det.config.verify.registration,
            )
            .unwrap();
            det.registration_cost(&q, None, None, 8, &[])
                .unwrap()
                .unwrap()
        };
        // The query at x = 10, its second candidate place 5 (not a neighbour of the best: no
        // start) over the budget. Its best: place 8, 2 m behind (meets the quality checks, too
        // far for the gate), or the decoy (place 9: fails them).
        for (best, met) in [(8, true), (9, false)] {
            let mut det = corridor_places(None);
            det.set_config(dc).unwrap();
            let d = step(&mut det, 10.0, (best, 5));
            let r = d.candidates.iter().find(|c| c.id as usize == best).unwrap();
            let r = r.verification.unwrap();
            assert_eq!(met_quality(&r), met, "{r:?}");
            assert!(d.accepted.is_none(), "{d:?}");
            assert_eq!(d.deferred, [5]);
            // The next step (far from every place) registers its own best from the
            // hypotheses: place 5 is registered first, whatever it costs, when the best of its
            // query met the quality checks (a revisit whose loop a later check held: the
            // backlog is its support); otherwise it waits for a step with budget to spare.
            let d = step(&mut det, 40.0, (0, 1));
            assert_eq!(d.deferred, [1]);
            let waiting = if met { 1 } else { 2 };
            assert_eq!(
                (det.deferred_waiting(), det.deferred_dropped()),
                (waiting, 0),
                "best {best}"
            );
            if !met {
                // A step with no candidate of its own (every place excluded) registers it.
                let mut idle = dc;
                idle.exclude_frames = 1000;
                det.set_config(idle).unwrap();
                let d = step(&mut det, 41.0, (0, 1));
                assert!(d.candidates.is_empty(), "{d:?}");
                assert_eq!((det.deferred_waiting(), det.deferred_dropped()), (1, 0));
            }
        }
    }
}
