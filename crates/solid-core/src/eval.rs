//! Scoring loop-closure candidates against poses: the protocol of [spec §5](crate::spec#5-evaluating-loop-closure-against-poses) (feature `alloc`).
//!
//! This is the crate's one implementation of the protocol: the Python package's `solid eval`,
//! the simulator demo and the Rust tests all score through [`score`]. It scores what a detector
//! (or a baseline) decided — per query its ranked candidate ids, the score of its best candidate
//! and the heading it estimated — and does no search of its own.
//!
//! Definitions ([spec §5](crate::spec#5-evaluating-loop-closure-against-poses)), with `eligible` the entries a query could be matched with (ids
//! `0..eligible`: the prior map plus its own session minus the exclusion window):
//! - a query is **GT-positive** when some eligible entry lies within `radius` metres;
//! - its top-1 is **correct** when the best candidate lies within `radius` (**place-correct**)
//!   and, when the detector estimated a metric pose for it, that pose is within the pose
//!   tolerance ([`Truth`], default 1 m and 5°) of the true `inv(T_world_query)·T_world_candidate`:
//!   a loop is only worth having when the pose handed to a pose graph is right. An accepted
//!   top-1 that is not correct is **place-false** (the candidate lies beyond `radius`) or
//!   **pose-false** (the place is right, the pose is not);
//! - **Recall@N** = GT-positive queries with a correct candidate among their first N / GT-positive
//!   queries;
//! - the **precision-recall curve** accepts a query's top-1 when its score ≤ τ, for τ over every
//!   observed top-1 score: precision = correct accepted / accepted, recall = correct accepted /
//!   GT-positive queries; **F1 max** is the largest 2PR/(P+R) on it;
//! - **AUC** = P(a correct top-1 scores lower than an incorrect one), ties one half;
//! - **rotation error** = |ψ_est − ψ_true| wrapped into [0°, 180°] over correct top-1s, with
//!   ψ_true = yaw(R_queryᵀ·R_candidate) ([spec §3](crate::spec#3-comparing-descriptors)).
//!
//! ```
//! use solid_lidar::eval::{score, Queries, NO_CANDIDATE};
//!
//! // Three places on a line, 1 m apart; query 2 may match 0 and 1; its best candidate is 1.
//! let mut poses = [[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]; 3];
//! for (i, p) in poses.iter_mut().enumerate() {
//!     p[3] = i as f64;
//! }
//! let q = Queries {
//!     query: &[2],
//!     eligible: &[2],
//!     k: 2,
//!     ids: &[1, 0],
//!     score: &[0.1],
//!     heading_deg: &[0.0],
//!     pose: &[],
//! };
//! let e = score(&q, &poses, 1.5).unwrap();
//! assert!(e.gt_positive[0] && e.correct[0]);
//! assert_eq!(e.recall_at(1), Some(1.0));
//! assert_eq!(NO_CANDIDATE, u32::MAX);
//! ```

use alloc::vec::Vec;

use crate::Error;

pub use crate::angle::wrap180;
use crate::angle::yaw_degrees;

/// Padding of [`Queries::ids`] where a query has fewer than `k` candidates.
pub const NO_CANDIDATE: u32 = u32::MAX;

/// Default radius (metres) within which a match is correct ([spec §5](crate::spec#5-evaluating-loop-closure-against-poses)).
pub const DEFAULT_RADIUS: f64 = 5.0;

/// What counts as a correct loop: its candidate within `radius` metres of the query and its
/// estimated pose (when it has one) within `translation_m` and `rotation_deg` of the true one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Truth {
    /// A candidate is the same place within this many metres.
    pub radius: f64,
    /// Largest translation error (metres) of a correct loop's pose.
    pub translation_m: f64,
    /// Largest rotation error (degrees) of a correct loop's pose.
    pub rotation_deg: f64,
}

/// Default [`Truth::translation_m`].
pub const DEFAULT_POSE_TOLERANCE_M: f64 = 1.0;
/// Default [`Truth::rotation_deg`].
pub const DEFAULT_POSE_TOLERANCE_DEG: f64 = 5.0;

impl Truth {
    /// The truth at `radius` with the default pose tolerance.
    pub const fn at(radius: f64) -> Truth {
        Truth {
            radius,
            translation_m: DEFAULT_POSE_TOLERANCE_M,
            rotation_deg: DEFAULT_POSE_TOLERANCE_DEG,
        }
    }
}

/// The candidates a detector produced, one row per query (struct of arrays).
#[derive(Debug, Clone, Copy)]
pub struct Queries<'a> {
    /// Id of each query (its index into the poses).
    pub query: &'a [u32],
    /// Each query could be matched with the ids `0..eligible` (must be > 0).
    pub eligible: &'a [u32],
    /// Candidates per query (row length of `ids`).
    pub k: usize,
    /// Ranked candidate ids, `k` per query, best first, padded with [`NO_CANDIDATE`].
    pub ids: &'a [u32],
    /// The score of each query's best candidate (lower is better; NaN when it has none).
    pub score: &'a [f64],
    /// The heading each query's best candidate was given, degrees ([spec §3](crate::spec#3-comparing-descriptors)).
    pub heading_deg: &'a [f64],
    /// The metric pose `T_query_candidate` estimated for each query's best candidate, row-major
    /// 4×4 (NaN where there is none); empty when no query has one.
    pub pose: &'a [[f64; 16]],
}

/// Per-query outcomes and the summary metrics of [spec §5](crate::spec#5-evaluating-loop-closure-against-poses) (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// `radius` of the evaluation, metres.
    pub radius: f64,
    /// The pose tolerance of a correct loop.
    pub truth: Truth,
    /// Whether some eligible entry lies within `radius` of the query.
    pub gt_positive: Vec<bool>,
    /// Whether the best candidate lies within `radius` and its estimated pose, if any, within
    /// the tolerance of [`Evaluation::truth`].
    pub correct: Vec<bool>,
    /// Whether the best candidate lies within `radius` (whatever its pose).
    pub place_correct: Vec<bool>,
    /// 1-based rank of the first candidate within `radius` (0: none).
    pub first_hit: Vec<u32>,
    /// Distance in metres from the query to its best candidate (NaN: no candidate).
    pub candidate_distance_m: Vec<f64>,
    /// ψ_true between the query and its best candidate, degrees (NaN: no candidate).
    pub true_heading_deg: Vec<f64>,
    /// The scores (copied from the input).
    pub score: Vec<f64>,
    /// The estimated headings (copied from the input).
    pub heading_deg: Vec<f64>,
    /// Translation error (metres) of each query's estimated pose against the true
    /// `inv(T_world_query)·T_world_candidate` (NaN: no pose).
    pub pose_error_m: Vec<f64>,
    /// Rotation error (degrees) of each query's estimated pose (NaN: no pose).
    pub pose_error_deg: Vec<f64>,
}

fn same(what: &'static str, left: usize, right: usize) -> Result<(), Error> {
    if left != right {
        return Err(Error::LengthMismatch { what, left, right });
    }
    Ok(())
}

/// Scores `q` against `poses` (row-major 3×4 `T_world_sensor`, one per entry id, all in one
/// world frame) at `radius` metres, with the default pose tolerance ([`score_with`]).
///
/// # Errors
/// As [`score_with`].
pub fn score(q: &Queries<'_>, poses: &[[f64; 12]], radius: f64) -> Result<Evaluation, Error> {
    score_with(q, poses, &Truth::at(radius))
}

/// Scores `q` against `poses` (row-major 3×4 `T_world_sensor`, one per entry id, all in one
/// world frame) by `truth`.
///
/// # Errors
/// [`Error::LengthMismatch`] when the rows of `q` disagree in length; [`Error::InvalidParameter`]
/// for a radius or tolerance that is not finite and positive, a query or candidate id outside the
/// poses, a candidate that is not eligible, an `eligible` of 0 or beyond the poses, or a
/// non-finite position.
pub fn score_with(
    q: &Queries<'_>,
    poses: &[[f64; 12]],
    truth: &Truth,
) -> Result<Evaluation, Error> {
    let (radius, tol) = (truth.radius, *truth);
    let nq = q.query.len();
    same("eligible vs queries", q.eligible.len(), nq)?;
    same("score vs queries", q.score.len(), nq)?;
    same("heading_deg vs queries", q.heading_deg.len(), nq)?;
    if !q.pose.is_empty() {
        same("pose vs queries", q.pose.len(), nq)?;
    }
    if q.k == 0 && nq > 0 {
        return Err(Error::invalid("k", 0.0, "at least 1"));
    }
    same("ids vs queries x k", q.ids.len(), nq * q.k)?;
    if !(radius.is_finite() && radius > 0.0) {
        return Err(Error::invalid(
            "radius",
            radius,
            "a finite number of metres > 0",
        ));
    }
    for (name, v) in [
        ("pose_tolerance_m", truth.translation_m),
        ("pose_tolerance_deg", truth.rotation_deg),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::invalid(name, v, "a finite number > 0"));
        }
    }
    let n = poses.len();
    if let Some(p) = poses
        .iter()
        .find(|p| !(p[3].is_finite() && p[7].is_finite() && p[11].is_finite()))
    {
        return Err(Error::invalid(
            "poses",
            p[3] + p[7] + p[11],
            "finite positions",
        ));
    }
    let pos = |i: usize| [poses[i][3], poses[i][7], poses[i][11]];
    let grid = Grid::new(poses, radius)?;
    let mut e = Evaluation {
        radius,
        truth: *truth,
        gt_positive: Vec::new(),
        correct: Vec::new(),
        place_correct: Vec::new(),
        first_hit: Vec::new(),
        candidate_distance_m: Vec::new(),
        true_heading_deg: Vec::new(),
        score: q.score.to_vec(),
        heading_deg: q.heading_deg.to_vec(),
        pose_error_m: Vec::new(),
        pose_error_deg: Vec::new(),
    };
    for i in 0..nq {
        let (query, eligible) = (q.query[i] as usize, q.eligible[i] as usize);
        if query >= n {
            return Err(Error::invalid(
                "query",
                query as f64,
                "an id below the number of poses",
            ));
        }
        if eligible == 0 || eligible > n {
            return Err(Error::invalid(
                "eligible",
                eligible as f64,
                "1..=number of poses (queries with no database are skipped, spec §5)",
            ));
        }
        let row = &q.ids[i * q.k..(i + 1) * q.k];
        let mut first_hit = 0u32;
        for (rank, &c) in row.iter().enumerate() {
            if c == NO_CANDIDATE {
                continue;
            }
            if c as usize >= eligible {
                return Err(Error::invalid(
                    "ids",
                    f64::from(c),
                    "candidate ids below the query's eligible bound",
                ));
            }
            if first_hit == 0 && dist(pos(query), pos(c as usize)) <= radius {
                first_hit = rank as u32 + 1;
            }
        }
        let best = row[0];
        let (cand_m, truth) = if best == NO_CANDIDATE {
            (f64::NAN, f64::NAN)
        } else {
            let b = best as usize;
            (
                dist(pos(query), pos(b)),
                true_heading(&poses[query], &poses[b]),
            )
        };
        e.gt_positive
            .push(grid.any_within(pos(query), eligible, radius));
        e.first_hit.push(first_hit);
        e.candidate_distance_m.push(cand_m);
        e.true_heading_deg.push(truth);
        let (em, ed) = match q.pose.get(i) {
            Some(est) if best != NO_CANDIDATE && est.iter().all(|v| v.is_finite()) => {
                pose_error(est, &poses[query], &poses[best as usize])
            }
            _ => (f64::NAN, f64::NAN),
        };
        // NaN errors (no pose) pass: a loop without a metric pose is judged by its place.
        let pose_ok = !(em > tol.translation_m || ed > tol.rotation_deg);
        e.place_correct.push(cand_m <= radius);
        e.correct.push(cand_m <= radius && pose_ok);
        e.pose_error_m.push(em);
        e.pose_error_deg.push(ed);
    }
    Ok(e)
}

/// Translation (metres) and rotation (degrees) error of an estimated `T_query_candidate`
/// (row-major 4×4) against the true `inv(T_world_query)·T_world_candidate` (SPEC §3).
pub fn pose_error(est: &[f64; 16], query: &[f64; 12], candidate: &[f64; 12]) -> (f64, f64) {
    // True: R = R_qᵀ R_c, t = R_qᵀ (t_c − t_q).
    let rq = |i: usize, j: usize| query[4 * i + j];
    let rc = |i: usize, j: usize| candidate[4 * i + j];
    let dt = [
        candidate[3] - query[3],
        candidate[7] - query[7],
        candidate[11] - query[11],
    ];
    let r_true = |i: usize, j: usize| -> f64 { (0..3).map(|k| rq(k, i) * rc(k, j)).sum() };
    let t_true = |i: usize| -> f64 { (0..3).map(|k| rq(k, i) * dt[k]).sum() };
    let r_est = |i: usize, j: usize| est[4 * i + j];
    let (ex, ey, ez) = (est[3] - t_true(0), est[7] - t_true(1), est[11] - t_true(2));
    let m = libm::sqrt(ex * ex + ey * ey + ez * ez);
    // trace(R_estᵀ R_true) = Σ_ij R_est[i][j] R_true[i][j]
    let tr: f64 = (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .map(|(i, j)| r_est(i, j) * r_true(i, j))
        .sum();
    let c = ((tr - 1.0) / 2.0).clamp(-1.0, 1.0);
    (m, libm::acos(c).to_degrees())
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    let (x, y, z) = (a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    libm::sqrt(x * x + y * y + z * z)
}

/// ψ_true = yaw(R_qᵀ·R_c) in degrees, `(−180, 180]` ([spec §3](crate::spec#3-comparing-descriptors)).
pub fn true_heading(query: &[f64; 12], candidate: &[f64; 12]) -> f64 {
    // (R_qᵀ R_c)[r][s] = Σ_k R_q[k][r] R_c[k][s]
    let m = |r: usize, s: usize| -> f64 {
        (0..3)
            .map(|k| query[4 * k + r] * candidate[4 * k + s])
            .sum()
    };
    yaw_degrees(m(0, 0), m(1, 0))
}

impl Evaluation {
    /// Number of queries.
    pub fn len(&self) -> usize {
        self.correct.len()
    }

    /// `true` when there are no queries.
    pub fn is_empty(&self) -> bool {
        self.correct.is_empty()
    }

    /// Number of GT-positive queries.
    pub fn n_gt(&self) -> usize {
        self.gt_positive.iter().filter(|&&g| g).count()
    }

    /// Recall@`n`; `None` when no query is GT-positive.
    pub fn recall_at(&self, n: usize) -> Option<f64> {
        let gt = self.n_gt();
        if gt == 0 {
            return None;
        }
        let hits = self
            .gt_positive
            .iter()
            .zip(&self.first_hit)
            .filter(|&(&g, &h)| g && h != 0 && h as usize <= n)
            .count();
        Some(hits as f64 / gt as f64)
    }

    /// Indices of the queries that have a candidate, by increasing score (ties by index).
    fn by_score(&self) -> Vec<usize> {
        let mut order: Vec<usize> = (0..self.len())
            .filter(|&i| !self.score[i].is_nan())
            .collect();
        order.sort_by(|&a, &b| self.score[a].total_cmp(&self.score[b]).then(a.cmp(&b)));
        order
    }

    /// `(threshold, correct, incorrect)` accepted at each distinct top-1 score, increasing.
    fn cumulative(&self) -> Vec<(f64, usize, usize)> {
        let order = self.by_score();
        let mut out = Vec::new();
        let (mut tp, mut fp) = (0usize, 0usize);
        for (k, &i) in order.iter().enumerate() {
            if self.correct[i] {
                tp += 1;
            } else {
                fp += 1;
            }
            if k + 1 == order.len() || self.score[order[k + 1]] != self.score[i] {
                out.push((self.score[i], tp, fp));
            }
        }
        out
    }

    /// The precision-recall curve: `(thresholds, precision, recall)`, one point per distinct
    /// top-1 score, increasing.
    pub fn pr_curve(&self) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let gt = self.n_gt();
        let (mut thr, mut p, mut r) = (Vec::new(), Vec::new(), Vec::new());
        for (t, tp, fp) in self.cumulative() {
            thr.push(t);
            p.push(tp as f64 / (tp + fp) as f64);
            r.push(if gt > 0 { tp as f64 / gt as f64 } else { 0.0 });
        }
        (thr, p, r)
    }

    /// `(F1 max, its threshold)`; `None` for an empty curve.
    pub fn f1_max(&self) -> Option<(f64, f64)> {
        let (thr, p, r) = self.pr_curve();
        let mut best: Option<(f64, f64)> = None;
        for i in 0..thr.len() {
            let s = p[i] + r[i];
            let f1 = if s > 0.0 { 2.0 * p[i] * r[i] / s } else { 0.0 };
            if best.is_none_or(|(b, _)| f1 > b) {
                best = Some((f1, thr[i]));
            }
        }
        best
    }

    /// Precision and recall when accepting top-1s with a score ≤ `threshold`:
    /// `(accepted, correct accepted, precision (NaN: none accepted), recall (NaN: no GT))`.
    pub fn at_threshold(&self, threshold: f64) -> (usize, usize, f64, f64) {
        let (mut acc, mut tp) = (0usize, 0usize);
        for i in 0..self.len() {
            if self.score[i] <= threshold {
                acc += 1;
                tp += usize::from(self.correct[i]);
            }
        }
        let gt = self.n_gt();
        let precision = if acc > 0 {
            tp as f64 / acc as f64
        } else {
            f64::NAN
        };
        let recall = if gt > 0 {
            tp as f64 / gt as f64
        } else {
            f64::NAN
        };
        (acc, tp, precision, recall)
    }

    /// The wrong top-1s accepted with a score ≤ `threshold`: `(place-false, pose-false)`, those
    /// whose candidate lies beyond the radius and those whose place is right but whose pose is
    /// outside the tolerance.
    pub fn false_at_threshold(&self, threshold: f64) -> (usize, usize) {
        let (mut place, mut pose) = (0usize, 0usize);
        for i in 0..self.len() {
            if self.score[i] <= threshold && !self.correct[i] {
                if self.place_correct[i] {
                    pose += 1;
                } else {
                    place += 1;
                }
            }
        }
        (place, pose)
    }

    /// The ROC curve of correct against incorrect top-1s: `(thresholds, false-positive rate,
    /// true-positive rate)`, starting at `(−∞, 0, 0)`.
    pub fn roc_curve(&self) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let steps = self.cumulative();
        let (npos, nneg) = steps.last().map_or((0, 0), |&(_, tp, fp)| (tp, fp));
        let rate = |x: usize, n: usize| if n > 0 { x as f64 / n as f64 } else { 0.0 };
        let (mut thr, mut fpr, mut tpr) = (
            alloc::vec![f64::NEG_INFINITY],
            alloc::vec![0.0],
            alloc::vec![0.0],
        );
        for (t, tp, fp) in steps {
            thr.push(t);
            fpr.push(rate(fp, nneg));
            tpr.push(rate(tp, npos));
        }
        (thr, fpr, tpr)
    }

    /// P(a correct top-1 scores lower than an incorrect one), ties one half (Mann–Whitney U);
    /// `None` when either class is empty.
    pub fn auc(&self) -> Option<f64> {
        let order = self.by_score();
        let npos = order.iter().filter(|&&i| self.correct[i]).count();
        let nneg = order.len() - npos;
        if npos == 0 || nneg == 0 {
            return None;
        }
        // Walk groups of equal scores: each correct one beats every incorrect one of a higher
        // score and ties half of those of its own score.
        let (mut u, mut neg_seen, mut k) = (0.0f64, 0usize, 0usize);
        while k < order.len() {
            let mut j = k;
            let (mut p, mut n) = (0usize, 0usize);
            while j < order.len() && self.score[order[j]] == self.score[order[k]] {
                if self.correct[order[j]] {
                    p += 1;
                } else {
                    n += 1;
                }
                j += 1;
            }
            u += p as f64 * ((nneg - neg_seen - n) as f64 + 0.5 * n as f64);
            neg_seen += n;
            k = j;
        }
        Some(u / (npos as f64 * nneg as f64))
    }

    /// |ψ_est − ψ_true| wrapped into [0°, 180°] for every correct top-1, in query order.
    pub fn rotation_errors(&self) -> Vec<f64> {
        (0..self.len())
            .filter(|&i| self.correct[i])
            .map(|i| wrap180(self.heading_deg[i] - self.true_heading_deg[i]).abs())
            .collect()
    }
}

/// A uniform 3-D grid of cell size `radius` over the entry positions, for "is some entry with
/// id < eligible within radius".
struct Grid {
    /// `(cell, id)` sorted: ids of one cell are contiguous and increasing.
    cells: Vec<([i64; 3], u32)>,
    positions: Vec<[f64; 3]>,
    inv: f64,
}

impl Grid {
    fn new(poses: &[[f64; 12]], radius: f64) -> Result<Grid, Error> {
        let inv = 1.0 / radius;
        let positions: Vec<[f64; 3]> = poses.iter().map(|p| [p[3], p[7], p[11]]).collect();
        let mut cells: Vec<([i64; 3], u32)> = Vec::new();
        cells.try_reserve_exact(positions.len()).map_err(|_| {
            Error::invalid(
                "poses",
                positions.len() as f64,
                "fewer poses (out of memory)",
            )
        })?;
        for (i, p) in positions.iter().enumerate() {
            cells.push((cell(p, inv), i as u32));
        }
        cells.sort_unstable();
        Ok(Grid {
            cells,
            positions,
            inv,
        })
    }

    fn any_within(&self, p: [f64; 3], eligible: usize, radius: f64) -> bool {
        let c = cell(&p, self.inv);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    // Saturating: the outermost cells (see `cell`) have no neighbour beyond.
                    let key = [
                        c[0].saturating_add(dx),
                        c[1].saturating_add(dy),
                        c[2].saturating_add(dz),
                    ];
                    let lo = self.cells.partition_point(|e| e.0 < key);
                    for &(k, id) in &self.cells[lo..] {
                        if k != key || id as usize >= eligible {
                            break;
                        }
                        if dist(p, self.positions[id as usize]) <= radius {
                            return true;
                        }
                    }
                }
            }
        }
        false
    }
}

fn cell(p: &[f64; 3], inv: f64) -> [i64; 3] {
    // Saturating float-to-int casts: far-away positions share the outermost cells, which stays
    // correct because distances are checked exactly.
    [
        libm::floor(p[0] * inv) as i64,
        libm::floor(p[1] * inv) as i64,
        libm::floor(p[2] * inv) as i64,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;

    fn line(n: usize) -> Vec<[f64; 12]> {
        (0..n)
            .map(|i| {
                let mut p = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
                p[3] = i as f64;
                p
            })
            .collect()
    }

    #[test]
    fn curves_auc_and_recall_on_a_hand_made_case() {
        // Queries 3, 4, 5 on a line 1 m apart, radius 1.5: each eligible for ids < q - 1.
        let poses = line(6);
        let ids = [1, 0, 2, 0, 0, 3];
        let q = Queries {
            query: &[3, 4, 5],
            eligible: &[2, 3, 4],
            k: 2,
            ids: &ids,
            score: &[0.3, 0.1, 0.2],
            heading_deg: &[0.0, 10.0, 0.0],
            pose: &[],
        };
        let e = score(&q, &poses, 1.5).unwrap();
        // At 1.5 m no eligible entry is near enough (the nearest are 2 m away); at 2.5 m all are.
        assert_eq!(e.gt_positive, vec![false, false, false]);
        let e = score(&q, &poses, 2.5).unwrap();
        assert_eq!(e.gt_positive, vec![true, true, true]);
        assert_eq!(e.correct, vec![true, true, false]);
        assert_eq!(e.first_hit, vec![1, 1, 2]);
        assert_eq!(e.recall_at(1), Some(2.0 / 3.0));
        assert_eq!(e.recall_at(2), Some(1.0));
        let (thr, p, r) = e.pr_curve();
        assert_eq!(thr, vec![0.1, 0.2, 0.3]);
        assert_eq!(p, vec![1.0, 0.5, 2.0 / 3.0]);
        assert_eq!(r, vec![1.0 / 3.0, 1.0 / 3.0, 2.0 / 3.0]);
        // Correct scores {0.3, 0.1}, incorrect {0.2}: one of two pairs ordered right.
        assert_eq!(e.auc(), Some(0.5));
        assert_eq!(e.rotation_errors(), vec![0.0, 10.0]);
        let (acc, tp, prec, _) = e.at_threshold(0.2);
        assert_eq!((acc, tp, prec), (2, 1, 0.5));
    }

    /// Two queries whose one candidate is entry 0 at heading 0, with these scores; no poses.
    fn two_finding_entry_0<'a>(
        query: &'a [u32; 2],
        eligible: &'a [u32; 2],
        score: &'a [f64; 2],
    ) -> Queries<'a> {
        Queries {
            query,
            eligible,
            k: 1,
            ids: &[0, 0],
            score,
            heading_deg: &[0.0, 0.0],
            pose: &[],
        }
    }

    #[test]
    fn ties_count_one_half_and_bad_input_is_refused() {
        let poses = line(4);
        let q = two_finding_entry_0(&[2, 3], &[1, 2], &[0.5, 0.5]);
        let e = score(&q, &poses, 2.5).unwrap();
        assert_eq!(e.correct, vec![true, false]);
        assert_eq!(e.auc(), Some(0.5));
        let wrong = Queries {
            eligible: &[1, 0],
            ..q
        };
        assert!(score(&wrong, &poses, 2.5).is_err());
        let wrong = Queries { ids: &[0, 3], ..q };
        assert!(score(&wrong, &poses, 2.5).is_err());
        assert!(score(&q, &poses, f64::NAN).is_err());
    }

    #[test]
    fn positions_in_the_outermost_grid_cells_never_overflow() {
        // Found by fuzz/fuzz_targets/score.rs: a cell index of i64::MAX (a position 1e300 m out,
        // or a radius of 1e-300 m) overflowed when its neighbours were visited.
        let mut poses = line(3);
        poses[0][3] = 1e300;
        poses[2][7] = -1e300;
        let q = two_finding_entry_0(&[1, 2], &[1, 1], &[0.1, 0.2]);
        for radius in [1.0, 1e-300] {
            let e = score(&q, &poses, radius).unwrap();
            assert_eq!(e.gt_positive, vec![false, false]);
        }
        // Two entries together far out share the saturated cell and are still found.
        poses[1][3] = 1e300;
        let e = score(&q, &poses, 1.0).unwrap();
        assert_eq!(e.gt_positive, vec![true, false]);
    }

    #[test]
    fn wrap_and_true_heading_follow_spec() {
        assert_eq!(wrap180(180.0), 180.0);
        assert_eq!(wrap180(-180.0), 180.0);
        assert_eq!(wrap180(190.0), -170.0);
        // Candidate rotated by -30° in the world, query by 0°: p_query ≈ Rz(-30)·p_cand? ψ =
        // yaw(R_qᵀ R_c) = -30.
        let (s, c) = libm::sincos((-30.0f64).to_radians());
        let cand = [c, -s, 0.0, 0.0, s, c, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let query = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        assert!((true_heading(&query, &cand) + 30.0).abs() < 1e-9);
    }

    #[test]
    fn pose_error_is_zero_for_the_true_pose() {
        // Query at (1, 2, 0) yawed 90°, candidate at (4, 2, 0) yawed 0°: in the query frame the
        // candidate sits at (0, -3, 0) and is turned by -90°.
        let q = [0.0, -1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0, 1.0, 0.0];
        let c = [1.0, 0.0, 0.0, 4.0, 0.0, 1.0, 0.0, 2.0, 0.0, 0.0, 1.0, 0.0];
        let truth = [
            0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, -3.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
        ];
        let (m, d) = pose_error(&truth, &q, &c);
        assert!(m < 1e-12 && d < 1e-6, "{m} {d}");
        let mut off = truth;
        off[3] += 0.3;
        let (m, _) = pose_error(&off, &q, &c);
        assert!((m - 0.3).abs() < 1e-12);
    }

    #[test]
    fn a_loop_at_the_right_place_with_a_wrong_pose_is_pose_false() {
        // Places 1 m apart on a line; queries 2 and 3 both match the place one metre back, the
        // first with its true pose, the second with a pose 3 m off and one turned by 10°.
        let poses = line(5);
        let mut good = [0.0; 16];
        for i in 0..4 {
            good[5 * i] = 1.0;
        }
        good[3] = -1.0;
        let mut far = good;
        far[3] = 2.0;
        let (s, c) = (libm::sin(10f64.to_radians()), libm::cos(10f64.to_radians()));
        let mut turned = good;
        turned[..2].copy_from_slice(&[c, -s]);
        turned[4..6].copy_from_slice(&[s, c]);
        let q = Queries {
            query: &[2, 3, 4],
            eligible: &[2, 3, 4],
            k: 1,
            ids: &[1, 2, 3],
            score: &[0.1, 0.2, 0.3],
            heading_deg: &[0.0, 0.0, 10.0],
            pose: &[good, far, turned],
        };
        let e = score(&q, &poses, 5.0).unwrap();
        assert_eq!(e.place_correct, vec![true, true, true]);
        assert_eq!(e.correct, vec![true, false, false]);
        assert_eq!(e.false_at_threshold(1.0), (0, 2));
        assert_eq!(e.at_threshold(1.0).1, 1);
        // Looser tolerances let them through; tighter radii make them place-false.
        let loose = Truth {
            radius: 5.0,
            translation_m: 4.0,
            rotation_deg: 15.0,
        };
        assert_eq!(
            score_with(&q, &poses, &loose).unwrap().correct,
            vec![true; 3]
        );
        let near = score_with(&q, &poses, &Truth::at(0.5)).unwrap();
        assert_eq!(near.false_at_threshold(1.0), (3, 0));
        let bad = Truth {
            rotation_deg: f64::NAN,
            ..loose
        };
        assert!(score_with(&q, &poses, &bad).is_err());
    }
}
