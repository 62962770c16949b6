"""The rows a run writes: the columns of ``loops.csv`` and ``queries.csv`` and how a field is formatted.

:data:`LOOP_COLUMNS` (one row per accepted loop, :func:`loop_row`) and :data:`QUERY_COLUMNS` (one
row per evaluated query, :meth:`solid.evaluation.Evaluation.rows`) share their loop fields and
format them the same way (:func:`fmt_opt`, :func:`pose_columns`), so that the accepted rows of
``queries.csv`` are, in those fields, exactly the rows of ``loops.csv`` for the same run.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from .arrays import F64
from .transforms import quaternion

__all__ = ["LOOP_COLUMNS", "POSE_COLUMNS", "QUERY_COLUMNS", "fmt_opt", "loop_row", "pose_columns"]


#: The columns of a loop's pose (``loops.csv`` and ``queries.csv``), filled by :func:`pose_columns`.
POSE_COLUMNS = ("verified", "x", "y", "z", "qx", "qy", "qz", "qw", "fitness", "rmse")

#: When, in which session and at which frame of its recording each side of a loop was seen.
_PLACE_COLUMNS = ("query_time", "candidate_time", "query_session", "candidate_session", "query_frame", "candidate_frame")

#: Columns of ``loops.csv`` (one row per accepted loop), in order. ``query``/``candidate`` are ids
#: in the detector's database (a prior map's places first); ``*_frame`` the frame number in the
#: query's own recording (empty for a map place); times in seconds (empty when unknown). A verified
#: loop has its pose ``T_query_candidate`` (``p_query ≈ T·p_candidate``, docs/spec.md §3) as
#: ``x,y,z`` and the unit quaternion ``qx,qy,qz,qw``, with the registration's ``fitness`` and
#: ``rmse`` (metres).
LOOP_COLUMNS = (
    "query",
    "candidate",
    "distance",
    "score",
    "heading_deg",
    *_PLACE_COLUMNS,
    *POSE_COLUMNS,
)

#: Columns of ``queries.csv`` (one row per query), in order. The first block is the issue's
#: contract; ``accepted`` is at the run's threshold, ``score`` is what the PR curve thresholds.
#: Rows with ``accepted`` true carry, in their columns shared with ``loops.csv``, exactly the rows
#: of ``solid detect`` for the same configuration.
QUERY_COLUMNS = (
    "query",
    "candidate",
    "distance",
    "score",
    "accepted",
    "heading_deg",
    "true_heading_deg",
    "candidate_distance_m",
    "gt_positive",
    "correct",
    "place_correct",
    "first_hit",
    "eligible",
    *_PLACE_COLUMNS,
    *POSE_COLUMNS,
    "pose_error_m",
    "pose_error_deg",
)


def fmt_opt(v: float | int | None, fmt: str = ".6f") -> str:
    """A CSV field that may be missing: empty for None or NaN, ``fmt`` for a float, else ``str``."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    return format(v, fmt) if isinstance(v, float) else str(v)


def pose_columns(pose: npt.ArrayLike | None, fitness: float | None, rmse: float | None) -> dict[str, Any]:
    """The ``verified,x,y,z,qx,qy,qz,qw,fitness,rmse`` columns of a loop (empty without a pose):
    the pose ``T_query_candidate`` of a verified loop as translation and unit quaternion."""
    if pose is None:
        return {"verified": False} | {k: "" for k in POSE_COLUMNS[1:]}
    P = np.asarray(pose, dtype=np.float64)
    qx, qy, qz, qw = quaternion(P[:3, :3])
    return {
        "verified": True,
        "x": f"{P[0, 3]:.6f}",
        "y": f"{P[1, 3]:.6f}",
        "z": f"{P[2, 3]:.6f}",
        "qx": f"{qx:.9f}",
        "qy": f"{qy:.9f}",
        "qz": f"{qz:.9f}",
        "qw": f"{qw:.9f}",
        "fitness": fmt_opt(fitness, ".4f"),
        "rmse": fmt_opt(rmse, ".4f"),
    }


def loop_row(lp: Any, times: F64, sessions: npt.NDArray[np.uint32], frame_of: Callable[[int], int | None]) -> dict[str, Any]:
    """One ``loops.csv`` row; eval's ``queries.csv`` formats the same fields the same way."""
    q, c = int(lp.query), int(lp.candidate)
    return {
        "query": q,
        "candidate": c,
        "distance": f"{lp.distance:.6f}",
        "score": f"{lp.score:.6f}",
        "heading_deg": f"{lp.heading:.3f}",
        "query_time": fmt_opt(float(times[q])) if q < len(times) else "",
        "candidate_time": fmt_opt(float(times[c])),
        "query_session": int(sessions[q]) if q < len(sessions) else "",
        "candidate_session": int(sessions[c]),
        "query_frame": fmt_opt(frame_of(q)),
        "candidate_frame": fmt_opt(frame_of(c)),
        **pose_columns(lp.pose, lp.fitness, lp.rmse),
    }
