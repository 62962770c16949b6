//! Verification of a detector step's candidates: the query's cloud registered with theirs from
//! a few yaw hypotheses, checked by the gate, and scored; the prepared clouds kept in a cache.

use alloc::sync::Arc;
use alloc::vec::Vec;

use super::{Candidate, LoopDetector, Verification};
use crate::db::{DbError, VerifyConfig};
use crate::reg::{self, Hypothesis, PreparedCloud};

impl LoopDetector {
    /// Registers the query's cloud with its best candidates' and scores every candidate (see
    /// [`VerifyConfig`]); candidates end sorted by score.
    pub(super) fn verify_candidates(
        &mut self,
        a_query: &[f32],
        query: Option<&PreparedCloud>,
        cands: &mut [Candidate],
    ) -> Result<(), DbError> {
        let v = self.config.verify;
        for c in cands.iter_mut() {
            c.score = UNVERIFIED_SCORE + c.distance / 2.0;
        }
        if let Some(q) = query {
            // The clouds first (the cache needs `&mut self`), then the registrations, which are
            // independent of each other: in parallel where threads exist.
            let mut jobs: Vec<(usize, Arc<PreparedCloud>)> = Vec::new();
            let mut work = 0usize;
            for (i, c) in cands.iter().enumerate().take(v.candidates) {
                if let Some(cp) = self.prepared_cloud(c.id) {
                    // The step's budget (VerifyConfig::step_points): the best always fits.
                    let cost = (q.fine.len() + cp.fine.len()).saturating_mul(v.hypotheses);
                    work = work.saturating_add(cost);
                    if !jobs.is_empty() && work > v.step_points {
                        break;
                    }
                    jobs.push((i, cp));
                }
            }
            let db = &self.db;
            let verify_one = |&(i, ref cp): &(usize, Arc<PreparedCloud>)| {
                verify_pair(&v, a_query, &db.a(cands[i].id), q, cp)
            };
            let results: Vec<Option<Verification>> = run_jobs(&jobs, v.threads, verify_one)?;
            for ((i, _), r) in jobs.iter().zip(results) {
                let c = &mut cands[*i];
                c.verification = r;
                if let Some(r) = r.filter(|r| r.accepted) {
                    c.score = loop_length_score(&r.registration);
                    c.heading_deg = r.registration.yaw_degrees();
                }
            }
        }
        cands.sort_by(|x, y| x.score.total_cmp(&y.score));
        Ok(())
    }

    /// The prepared cloud of place `id`: from the cache, or prepared from its stored compact
    /// cloud (then cached). None when the place has no usable cloud.
    fn prepared_cloud(&mut self, id: u32) -> Option<Arc<PreparedCloud>> {
        self.clock += 1;
        if let Some((stamp, c)) = self.prepared.get_mut(&id) {
            *stamp = self.clock;
            return Some(Arc::clone(c));
        }
        let points = reg::decode_cloud(self.db.cloud(id)?).ok()?;
        let c = Arc::new(
            PreparedCloud::from_downsampled(&points, &self.config.verify.registration).ok()?,
        );
        self.remember(id, Arc::clone(&c));
        Some(c)
    }

    /// Caches a prepared cloud, evicting the least recently used ones beyond the budget.
    pub(super) fn remember(&mut self, id: u32, c: Arc<PreparedCloud>) {
        self.clock += 1;
        self.prepared_bytes += c.heap_bytes();
        if let Some((_, old)) = self.prepared.insert(id, (self.clock, c)) {
            self.prepared_bytes -= old.heap_bytes();
        }
        while self.prepared_bytes > self.config.verify.cache_bytes && self.prepared.len() > 1 {
            let oldest = self
                .prepared
                .iter()
                .filter(|(&k, _)| k != id)
                .min_by_key(|(_, (stamp, _))| *stamp)
                .map(|(&k, _)| k);
            let Some(k) = oldest else { break };
            if let Some((_, old)) = self.prepared.remove(&k) {
                self.prepared_bytes -= old.heap_bytes();
            }
        }
    }
}

/// The score of a candidate that passed the gate: its loop's length `|t|` mapped into `[0, 1)`
/// as `|t| / (1 + |t|)`, so that a step's nearest verified place is its loop (the shortest loop
/// constrains a pose graph best: it has the most overlap) and sweeping the scores sweeps the
/// loops by length (docs/performance.md#loop-length-score).
fn loop_length_score(r: &reg::Registration) -> f64 {
    let t = r.translation();
    let len = libm::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    len / (1.0 + len)
}

/// Score of a candidate that was not verified or failed the gate: above every verified score.
pub const UNVERIFIED_SCORE: f64 = 1.5;

/// With verification, the scores of candidates that passed the gate lie in `[0, 1]`: accepting
/// the scores up to this threshold accepts exactly the verified loops.
pub const VERIFIED_THRESHOLD: f64 = 1.0;

/// The initial yaws for registering a candidate (degrees, at most `max` and 16): 0°, the A-SOLiD
/// minima ([`reg::hypothesis_yaws`]), then `±fan_deg`, skipping any within one azimuth bin of a
/// yaw already chosen.
fn yaw_hypotheses(
    a_query: &[f32],
    a_candidate: &[f32],
    max: usize,
    fan_deg: f64,
    out: &mut [f64; 16],
) -> Result<usize, DbError> {
    let max = max.min(out.len());
    let mut m = reg::hypothesis_yaws(a_query, a_candidate, &mut out[..max])?;
    let bin = 360.0 / a_query.len() as f64;
    if fan_deg > 0.0 {
        for y in [fan_deg, -fan_deg] {
            let near = out[..m].iter().any(|&x| {
                let d = libm::fabs(x - y) % 360.0;
                d.min(360.0 - d) < bin
            });
            if m < max && !near {
                out[m] = y;
                m += 1;
            }
        }
    }
    Ok(m)
}

/// Registers one candidate from its yaw hypotheses and checks the gate; None when the clouds
/// cannot be registered (for example, one of them is empty).
fn verify_pair(
    v: &VerifyConfig,
    a_query: &[f32],
    a_candidate: &[f32],
    query: &PreparedCloud,
    candidate: &PreparedCloud,
) -> Result<Option<Verification>, DbError> {
    let mut yaws = [0.0f64; 16];
    let m = yaw_hypotheses(a_query, a_candidate, v.hypotheses, v.fan_deg, &mut yaws)?;
    let mut hyps = [Hypothesis::default(); 16];
    let Ok(h) = reg::register_hypotheses(
        query,
        candidate,
        &yaws[..m],
        &reg::IDENTITY,
        &v.registration,
        &mut hyps[..m],
    ) else {
        return Ok(None);
    };
    let tried = &hyps[..h.count];
    let check = v.gate.check(&h.registration, tried, h.best);
    Ok(Some(Verification {
        registration: h.registration,
        accepted: check.is_ok(),
        rejection: check.err(),
        hypotheses: h.count,
        agreement: reg::agreement(
            tried,
            h.best,
            v.gate.agree_translation,
            v.gate.agree_rotation_deg,
        ),
    }))
}

/// `f` of every job, in order, the first error in job order: shared among the threads of this
/// process's pool `solid-verify` of `threads` threads (0: one per core; see `crate::pool`) with
/// `parallel`, one after the other without it.
fn run_jobs<J: Sync, R: Send>(
    jobs: &[J],
    threads: usize,
    f: impl Fn(&J) -> Result<R, DbError> + Sync,
) -> Result<Vec<R>, DbError> {
    #[cfg(feature = "parallel")]
    if jobs.len() > 1 {
        if let Some(pool) = crate::pool::pool_of("solid-verify", threads)
            .ok()
            .filter(|p| p.current_num_threads() > 1)
        {
            use rayon::prelude::*;
            let results: Vec<Result<R, DbError>> =
                pool.install(|| jobs.par_iter().map(&f).collect());
            return results.into_iter().collect();
        }
    }
    let _ = threads;
    jobs.iter().map(f).collect()
}
