"""Scoring loop closures against poses (docs/spec.md §5) and writing the results.

The scoring itself is the Rust core's (``solid_lidar::eval``, bound as
``solid._solid.score_candidates``): this module only gathers what a detector decided — per query
its ranked candidate ids, the score and heading of its best candidate and the entries it could be
matched with — hands it over, and formats what comes back (``metrics.json``, and the rows of
``queries.csv``, whose columns :mod:`solid.records` defines).
:func:`evaluate_detections` scores a :class:`solid.LoopDetector` run (what the pipeline does);
:func:`evaluate_candidates` scores any method given as arrays (the Scan Context baseline).

Definitions (docs/spec.md §5): a query is GT-positive when some place it could be matched with lies within
``radius`` metres; its top-1 is correct when the best candidate does (place-correct) and its
estimated pose, when it has one, lies within the pose tolerance of the true relative pose (default
1 m and 5°). An accepted top-1 that is not correct is place-false or pose-false. Recall@N, the PR curve over
every observed top-1 score (accept when score ≤ τ), F1 max, AUC (P(correct top-1 scores lower than
an incorrect one), ties one half), and the rotation error |ψ_est − ψ_true| over correct top-1s.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence as AbcSequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from . import _solid
from .arrays import B, F64, I64
from .records import QUERY_COLUMNS, fmt_opt, pose_columns

__all__ = ["QUERY_COLUMNS", "Evaluation", "describe_loop_delay", "evaluate_candidates", "evaluate_detections", "loop_delay_steps"]


def _none_if_nan(v: float) -> float | None:
    return None if v is None or (isinstance(v, float) and math.isnan(v)) else float(v)


@dataclass
class Evaluation:
    """One method's candidates on one sequence, scored (see the module docstring)."""

    name: str
    scores: Any
    query: I64
    eligible: I64
    ids: I64
    distance: F64
    score: F64
    heading_deg: F64
    threshold: float | None
    entry_times: F64
    entry_sessions: npt.NDArray[np.uint32]
    pose: F64 | None = None
    fitness: F64 | None = None
    rmse: F64 | None = None
    frame_of: Callable[[int], int | None] = field(repr=False, default=lambda i: None)
    extra: dict[str, Any] = field(default_factory=dict)
    #: Queries left out of the scores (entry ids): :func:`evaluate_detections`'s ``unknown``.
    left_out: I64 = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def radius(self) -> float:
        return float(self.scores.radius)

    @property
    def correct(self) -> B:
        """Place-correct and, where a pose was estimated, pose-correct (docs/spec.md §5)."""
        return np.asarray(self.scores.correct, dtype=bool)

    @property
    def place_correct(self) -> B:
        """The best candidate lies within the radius, whatever its pose."""
        return np.asarray(self.scores.place_correct, dtype=bool)

    @property
    def gt_positive(self) -> B:
        return np.asarray(self.scores.gt_positive, dtype=bool)

    @property
    def accepted(self) -> B:
        """Queries whose top-1 passes the run's threshold (all False without a threshold)."""
        if self.threshold is None:
            return np.zeros(self.query.shape, dtype=bool)
        return np.asarray(self.score <= self.threshold, dtype=bool)

    def recall_at(self, n: int) -> float | None:
        return _none_if_nan(float(self.scores.recall_at(n)))

    def pr(self) -> tuple[F64, F64, F64]:
        """(thresholds, precision, recall) of docs/spec.md §5."""
        t, p, r = self.scores.pr_curve()
        return np.asarray(t), np.asarray(p), np.asarray(r)

    def roc(self) -> tuple[F64, F64, F64]:
        """(thresholds, false-positive rate, true-positive rate) of correct vs incorrect top-1s."""
        t, f, tp = self.scores.roc_curve()
        return np.asarray(t), np.asarray(f), np.asarray(tp)

    def f1_max(self) -> tuple[float | None, float | None]:
        """(F1 max, the threshold that reaches it)."""
        f1, thr = self.scores.f1_max()
        return _none_if_nan(float(f1)), _none_if_nan(float(thr))

    def metrics(self) -> dict[str, Any]:
        """The summary written to ``metrics.json`` (NaN → None)."""
        f1, f1_thr = self.f1_max()
        err = np.asarray(self.scores.rotation_errors(), dtype=np.float64)
        m: dict[str, Any] = {
            "method": self.name,
            "radius_m": self.radius,
            "pose_tolerance_m": float(self.scores.pose_tolerance_m),
            "pose_tolerance_deg": float(self.scores.pose_tolerance_deg),
            "queries": int(self.query.size),
            "gt_queries": int(self.scores.n_gt),
            "correct_top1": int(self.correct.sum()),
            "place_correct_top1": int(self.place_correct.sum()),
            "recall_at_1": self.recall_at(1),
            "recall_at_5": self.recall_at(5) if self.ids.shape[1] >= 5 else None,
            "f1_max": f1,
            "f1_threshold": f1_thr,
            "auc": _none_if_nan(float(self.scores.auc())),
            "rotation_error_deg_mean": float(err.mean()) if err.size else None,
            "rotation_error_deg_median": float(np.median(err)) if err.size else None,
            "rotation_error_deg_max": float(err.max()) if err.size else None,
        }
        pe_m = np.asarray(self.scores.pose_error_m)
        pe_d = np.asarray(self.scores.pose_error_deg)
        ok = self.accepted & self.correct & np.isfinite(pe_m)
        if ok.any():
            m.update(
                {
                    "pose_error_m_median": float(np.median(pe_m[ok])),
                    "pose_error_deg_median": float(np.median(pe_d[ok])),
                    "pose_error_m_max": float(pe_m[ok].max()),
                    "pose_error_deg_max": float(pe_d[ok].max()),
                    "verified_loops_with_pose": int(ok.sum()),
                }
            )
        acc_pose = self.accepted & np.isfinite(pe_m)
        if acc_pose.any():
            m["pose_error_m_max_all_accepted"] = float(pe_m[acc_pose].max())
        if self.threshold is not None:
            acc, tp, prec, rec = self.scores.at_threshold(self.threshold)
            place_false, pose_false = self.scores.false_at_threshold(self.threshold)
            m.update(
                {
                    "threshold": self.threshold,
                    "accepted": int(acc),
                    "true_accepts": int(tp),
                    "false_accepts": int(acc - tp),
                    "place_false_accepts": int(place_false),
                    "pose_false_accepts": int(pose_false),
                    "precision": _none_if_nan(float(prec)),
                    "recall": _none_if_nan(float(rec)),
                }
            )
        m.update(self.extra)
        return m

    def setting_for(self, threshold: float, verified: bool) -> tuple[str, float] | None:
        """The detector flag and value whose run accepts exactly the top-1s with score ≤
        ``threshold``: without verification ``--threshold`` itself; with it, the gate's largest loop
        (``--gate-max-translation``), since a verified score orders the loops by length: halfway
        from the longest accepted loop's length to the next longer loop the gate passed (the
        longest's own length when there is none), so that neither float rounding nor a
        registration ending a micrometre elsewhere (a start changed by the smaller largest loop)
        moves a loop across it. None when no setting does (``threshold`` reaches candidates the
        gate rejected)."""
        if not verified:
            return "--threshold", float(threshold)
        if threshold > _solid.VERIFIED_THRESHOLD or self.pose is None:
            return None
        pose = self.pose
        passed = np.isfinite(pose[:, 0, 3]) & (self.score < _solid.VERIFIED_THRESHOLD)
        keep = (self.score <= threshold) & passed
        if not keep.any():
            return None

        def lengths(rows: np.ndarray) -> list[float]:
            # The length the gate compares, summed in its order: x² + y² + z², then the square root.
            return [math.sqrt(x * x + y * y + z * z) for x, y, z in pose[rows, :3, 3].tolist()]

        longest = max(lengths(keep))
        longer = [m for m in lengths(passed & ~keep) if m > longest]
        return "--gate-max-translation", (longest + min(longer)) / 2 if longer else longest

    def rows(self) -> list[dict[str, Any]]:
        """``queries.csv`` rows (:data:`QUERY_COLUMNS`)."""
        gt = self.gt_positive
        correct, place = self.correct, self.place_correct
        first = np.asarray(self.scores.first_hit)
        cand_m = np.asarray(self.scores.candidate_distance_m)
        truth = np.asarray(self.scores.true_heading_deg)
        accepted = self.accepted
        pe_m = np.asarray(self.scores.pose_error_m)
        pe_d = np.asarray(self.scores.pose_error_deg)
        out = []
        for i in range(self.query.size):
            q, c = int(self.query[i]), int(self.ids[i, 0])
            has = c >= 0
            pose = None if self.pose is None or not np.isfinite(self.pose[i]).all() else self.pose[i]
            out.append(
                {
                    "query": q,
                    "candidate": c if has else "",
                    "distance": f"{self.distance[i]:.6f}" if has else "",
                    "score": f"{self.score[i]:.6f}" if has else "",
                    "accepted": bool(accepted[i]),
                    "heading_deg": f"{self.heading_deg[i]:.3f}" if has else "",
                    "true_heading_deg": fmt_opt(float(truth[i]), ".3f"),
                    "candidate_distance_m": fmt_opt(float(cand_m[i]), ".3f"),
                    "gt_positive": bool(gt[i]),
                    "correct": bool(correct[i]),
                    "place_correct": bool(place[i]),
                    "first_hit": int(first[i]),
                    "eligible": int(self.eligible[i]),
                    "query_time": fmt_opt(float(self.entry_times[q])),
                    "candidate_time": fmt_opt(float(self.entry_times[c])) if has else "",
                    "query_session": int(self.entry_sessions[q]),
                    "candidate_session": int(self.entry_sessions[c]) if has else "",
                    "query_frame": fmt_opt(self.frame_of(q)),
                    "candidate_frame": fmt_opt(self.frame_of(c)) if has else "",
                    **pose_columns(pose, None if self.fitness is None else float(self.fitness[i]), None if self.rmse is None else float(self.rmse[i])),
                    "pose_error_m": fmt_opt(float(pe_m[i]), ".4f"),
                    "pose_error_deg": fmt_opt(float(pe_d[i]), ".4f"),
                }
            )
        return out


def _poses_of(database: Any) -> F64:
    P = np.asarray(database.poses, dtype=np.float64)
    return P


def evaluate_candidates(
    name: str,
    query: npt.ArrayLike,
    eligible: npt.ArrayLike,
    ids: npt.ArrayLike,
    distance: npt.ArrayLike,
    score: npt.ArrayLike,
    heading_deg: npt.ArrayLike,
    poses: npt.ArrayLike,
    *,
    radius: float,
    pose_tolerance_m: float = _solid.DEFAULT_POSE_TOLERANCE_M,
    pose_tolerance_deg: float = _solid.DEFAULT_POSE_TOLERANCE_DEG,
    threshold: float | None = None,
    entry_times: npt.ArrayLike | None = None,
    entry_sessions: npt.ArrayLike | None = None,
    frame_of: Callable[[int], int | None] | None = None,
    pose: npt.ArrayLike | None = None,
    fitness: npt.ArrayLike | None = None,
    rmse: npt.ArrayLike | None = None,
) -> Evaluation:
    """Score any method's candidates (docs/spec.md §5).

    ``query`` (Q,) entry ids; ``eligible`` (Q,) each query may be matched with ids
    ``0..eligible``; ``ids`` (Q, k) ranked candidate ids (−1 where missing); ``distance``,
    ``score`` and ``heading_deg`` (Q,) of each best candidate (the PR curve sweeps ``score``);
    ``poses`` (N, 3, 4) of every entry id, in one frame. ``pose`` (Q, 4, 4), optional: the
    metric ``T_query_candidate`` estimated for each best candidate (NaN where none), scored
    against the poses (translation and rotation error): a top-1 whose pose is off by more than
    ``pose_tolerance_m`` or ``pose_tolerance_deg`` is not correct.
    """
    P = np.ascontiguousarray(poses, dtype=np.float64)
    if P.ndim != 3 or P.shape[1:] != (3, 4):
        raise _solid.SolidError(f"poses must have shape (N, 3, 4), got {P.shape}")
    n = P.shape[0]
    q = np.ascontiguousarray(query, dtype=np.int64)
    el = np.ascontiguousarray(eligible, dtype=np.int64)
    I = np.ascontiguousarray(ids, dtype=np.int64)
    if I.ndim != 2 or I.shape[0] != q.shape[0]:
        raise _solid.SolidError(f"ids must have shape ({q.shape[0]}, k), got {I.shape}")
    d = np.ascontiguousarray(distance, dtype=np.float64)
    s = np.ascontiguousarray(score, dtype=np.float64)
    h = np.ascontiguousarray(heading_deg, dtype=np.float64)
    needed = np.unique(np.r_[q, I[I >= 0]])
    if needed.size and (needed[0] < 0 or needed[-1] >= n):
        raise _solid.SolidError(f"entry ids must be in [0, {n}) (one pose per entry), got {int(needed[0] if needed[0] < 0 else needed[-1])}")
    bad = needed[~np.isfinite(P[needed, :, 3]).all(axis=1)] if needed.size else needed
    if bad.size:
        raise _solid.SolidError(
            f"{bad.size} places have no pose (first: entry {int(bad[0])}): every query and candidate needs one "
            "(give --poses; a map must be built with --poses)"
        )
    # Entries without poses that no query can reach stay out of the ground truth.
    P = np.where(np.isfinite(P), P, 1e300)
    est = None if pose is None else np.ascontiguousarray(pose, dtype=np.float64)
    scores = _solid.score_candidates(q, el, I, s, h, P, float(radius), est, float(pose_tolerance_m), float(pose_tolerance_deg))
    return Evaluation(
        name=name,
        scores=scores,
        query=q,
        eligible=el,
        ids=I,
        distance=d,
        score=s,
        heading_deg=h,
        threshold=threshold,
        entry_times=np.full(n, np.nan) if entry_times is None else np.asarray(entry_times, dtype=np.float64),
        entry_sessions=np.zeros(n, np.uint32) if entry_sessions is None else np.asarray(entry_sessions, dtype=np.uint32),
        frame_of=frame_of or (lambda i: None),
        pose=est,
        fitness=None if fitness is None else np.asarray(fitness, dtype=np.float64),
        rmse=None if rmse is None else np.asarray(rmse, dtype=np.float64),
    )


def evaluate_detections(
    name: str,
    detections: AbcSequence[Any],
    database: Any,
    *,
    radius: float,
    threshold: float | None,
    frame_of: Callable[[int], int | None] | None = None,
    pose_tolerance_m: float = _solid.DEFAULT_POSE_TOLERANCE_M,
    pose_tolerance_deg: float = _solid.DEFAULT_POSE_TOLERANCE_DEG,
    unknown: AbcSequence[int] = (),
) -> Evaluation:
    """Score the steps of a :class:`solid.LoopDetector` run (``Detection`` objects) against the
    poses stored with the database's places; steps with nothing eligible are skipped (docs/spec.md §5).
    A loop into the map that a later step released (``Detection.released``: held until the
    session's placement) is scored as its own query's loop. ``unknown``: entry ids whose pose in
    the scoring world is unknown (places of frames no anchor places, ``solid eval --anchor
    anchors.kitti``): none is a true place of a query, and a step whose query or any ranked
    candidate is one is left out (``Evaluation.left_out``), since whether it is right is unknown."""
    steps = [d for d in detections if d.eligible > 0]
    late = {int(lp.query): lp for d in detections for lp in getattr(d, "released", ())}
    k = max((len(d.candidates) for d in steps), default=1)
    ids = np.full((len(steps), max(k, 1)), -1, dtype=np.int64)
    dist = np.full(len(steps), np.nan)
    score = np.full(len(steps), np.nan)
    head = np.full(len(steps), np.nan)
    pose = np.full((len(steps), 4, 4), np.nan)
    fit = np.full(len(steps), np.nan)
    rms = np.full(len(steps), np.nan)
    for i, d in enumerate(steps):
        for j, c in enumerate(d.candidates):
            ids[i, j] = c.id
        if d.candidates:
            best = d.candidates[0]
            dist[i], score[i], head[i] = best.distance, best.score, best.heading
            if best.accepted:
                pose[i] = best.pose
                fit[i], rms[i] = best.fitness, best.rmse
        lp = late.get(int(d.query))
        if lp is not None:
            others = [c.id for c in d.candidates if c.id != lp.candidate]
            ids[i] = -1
            ids[i, : min(k, 1 + len(others))] = ([lp.candidate] + others)[:k]
            dist[i], score[i], head[i] = lp.distance, lp.score, lp.heading
            pose[i] = lp.pose
            fit[i], rms[i] = lp.fitness, lp.rmse
    every = np.array([d.query for d in steps], dtype=np.int64)
    query = every
    eligible = np.array([d.eligible for d in steps], dtype=np.int64)
    poses = _poses_of(database)
    gone = np.asarray(unknown, dtype=np.int64).reshape(-1)
    if gone.size and ((gone < 0) | (gone >= len(poses))).any():
        raise _solid.ConfigError(f"unknown: entry ids must lie in [0, {len(poses)}) (the database's entries), got {gone.min()}..{gone.max()}")
    out = np.isin(query, gone) | np.isin(ids, gone).any(axis=1)
    if gone.size:
        poses = poses.copy()
        poses[gone] = np.nan  # no true place of any query (evaluate_candidates)
        keep = ~out
        query, eligible, ids, dist, score, head, pose, fit, rms = (a[keep] for a in (query, eligible, ids, dist, score, head, pose, fit, rms))
    ev = evaluate_candidates(
        name,
        query,
        eligible,
        ids,
        dist,
        score,
        head,
        poses,
        radius=radius,
        pose_tolerance_m=pose_tolerance_m,
        pose_tolerance_deg=pose_tolerance_deg,
        threshold=threshold,
        entry_times=np.asarray(database.timestamps),
        entry_sessions=np.asarray(database.sessions),
        frame_of=frame_of,
        pose=pose,
        fitness=fit,
        rmse=rms,
    )
    ev.left_out = every[out]
    return ev


def loop_delay_steps(detector: Any) -> dict[str, int]:
    """How late a confirmed loop can come (docs/spec.md §8 step 4, support): the first loop of
    a revisit arrives at least ``min`` steps into it, on the support of steps at most ``window``
    back; both 0 when support over time (or verification) is off.

    >>> from solid import DetectorConfig
    >>> loop_delay_steps(DetectorConfig(support_window=20, min_support=2))
    {'min': 2, 'window': 20}
    >>> loop_delay_steps(DetectorConfig(min_support=0))
    {'min': 0, 'window': 0}
    """
    on = bool(detector.verify) and detector.min_support > 0 and detector.support_window > 0
    return {"min": int(detector.min_support), "window": int(detector.support_window)} if on else {"min": 0, "window": 0}


def describe_loop_delay(delay: dict[str, int]) -> str:
    """The printed line of :func:`loop_delay_steps`."""
    if delay["min"] == 0:
        return "loops are not delayed (support over time off)"
    return (
        f"support over time: a revisit's first loop comes at least {delay['min']} step(s) into it, "
        f"on evidence at most {delay['window']} steps back"
    )
