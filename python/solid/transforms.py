"""Geometry on scans and poses, and the angle conventions of docs/spec.md §3, each in one place.

Scan transforms (:func:`clip_fov`, :func:`occlude_sector`, :func:`rotate_z`) work on any
``(N, >=3)`` array and keep its extra columns; :func:`auto_fov_center` picks where to clip;
:func:`subsample_by_distance` picks frames by distance travelled. The conventions: angles in
degrees, counter-clockwise about +z, 0 = +x; :func:`wrap_degrees` brings an angle into
(−180, 180]; :func:`yaw_degrees` is the yaw of a rotation in that range; :func:`quaternion` is a
rotation as ``(qx, qy, qz, qw)`` with ``qw >= 0``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from ._solid import ConfigError
from .arrays import F64, I64

__all__ = [
    "auto_fov_center",
    "azimuth_degrees",
    "clip_fov",
    "occlude_sector",
    "quaternion",
    "rotate_z",
    "subsample_by_distance",
    "wrap_degrees",
    "yaw_degrees",
]


def wrap_degrees(d: npt.ArrayLike) -> F64:
    """Angles (degrees) wrapped into (−180, 180]."""
    w = np.mod(np.asarray(d, dtype=np.float64) + 180.0, 360.0) - 180.0
    return np.asarray(np.where(w == -180.0, 180.0, w), dtype=np.float64)


def yaw_degrees(R: npt.ArrayLike) -> F64:
    """Yaw (rotation about z, degrees, (−180, 180]) of rotation matrices (..., 3, 3)."""
    m = np.asarray(R, dtype=np.float64)
    y = np.degrees(np.arctan2(m[..., 1, 0], m[..., 0, 0]))
    # atan2 is already in [−180, 180]; only its closed end moves (a full wrap would round small yaws).
    return np.asarray(np.where(y <= -180.0, y + 360.0, y), dtype=np.float64)


def quaternion(R: npt.ArrayLike) -> tuple[float, float, float, float]:
    """(qx, qy, qz, qw) of a rotation matrix, qw >= 0 (Shepperd's method)."""
    m = np.asarray(R, dtype=np.float64)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q = ((m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s)
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = (0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s)
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = ((m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = ((m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s)
    n = math.sqrt(sum(v * v for v in q))
    sign = -1.0 if q[3] < 0 else 1.0
    x, y, z, w = (sign * v / n for v in q)
    return x, y, z, w


def azimuth_degrees(points: npt.NDArray[Any]) -> F64:
    """Azimuth of each point (degrees, [−180, 180], 0 = +x, counter-clockwise)."""
    return np.degrees(np.arctan2(points[:, 1].astype(np.float64), points[:, 0].astype(np.float64)))


def clip_fov(points: npt.NDArray[Any], width_deg: float, center_deg: float = 0.0) -> npt.NDArray[Any]:
    """Keep points whose azimuth lies within ±width/2 of ``center_deg`` (0 = +x forward, CCW)."""
    if not 0.0 < width_deg <= 360.0 or not math.isfinite(center_deg):
        raise ConfigError(f"width_deg must be in (0, 360] and center_deg finite, got {width_deg}, {center_deg}")
    if width_deg >= 360.0:
        return points.copy()
    off = wrap_degrees(azimuth_degrees(points) - center_deg)
    return points[np.abs(off) <= width_deg / 2.0]


def occlude_sector(points: npt.NDArray[Any], width_deg: float, center_deg: float = 0.0) -> npt.NDArray[Any]:
    """Remove the points whose azimuth lies within ±width/2 of ``center_deg`` (a blocked sector)."""
    if not 0.0 <= width_deg <= 360.0 or not math.isfinite(center_deg):
        raise ConfigError(f"width_deg must be in [0, 360] and center_deg finite, got {width_deg}, {center_deg}")
    if width_deg == 0.0:
        return points.copy()
    off = wrap_degrees(azimuth_degrees(points) - center_deg)
    return points[np.abs(off) > width_deg / 2.0]


def auto_fov_center(points: npt.NDArray[Any], width_deg: float) -> float:
    """The centre (degrees, 0 = +x, counter-clockwise) of the ``width_deg`` sector holding the most
    points of a scan: where to clip when the user gave no centre, so that a sensor whose +x is
    blocked (or points elsewhere) is not clipped to an empty sector."""
    p = np.asarray(points)
    if p.shape[0] == 0:
        return 0.0
    az = azimuth_degrees(p) % 360.0
    hist = np.bincount(np.minimum(az.astype(np.int64), 359), minlength=360).astype(np.float64)
    w = max(1, min(360, int(round(width_deg))))
    windows = np.convolve(np.r_[hist, hist[: w - 1]], np.ones(w), mode="valid")[:360]
    start = int(np.argmax(windows))
    return float(wrap_degrees((start + w / 2.0) % 360.0))


def rotate_z(points: npt.NDArray[Any], degrees: float) -> npt.NDArray[Any]:
    """Rotate points counter-clockwise (seen from above) about +z; extra columns are kept.

    ``rotate_z(p, psi)`` is the query of docs/spec.md §3 whose heading relative to ``p`` is ``psi``.
    """
    t = math.radians(degrees)
    c, s = math.cos(t), math.sin(t)
    out = points.copy()
    x = points[:, 0].astype(np.float64)
    y = points[:, 1].astype(np.float64)
    out[:, 0] = c * x - s * y
    out[:, 1] = s * x + c * y
    return out


def subsample_by_distance(poses: npt.ArrayLike, step_m: float) -> I64:
    """Indices of frames kept when sampling one frame every ``step_m`` metres of travel.

    Frame 0 is kept; then the first frame at which the travelled path length (sum of distances
    between consecutive positions) reaches each next multiple of ``step_m``.
    """
    P = np.asarray(poses, dtype=np.float64)
    if P.ndim != 3 or P.shape[1:] not in ((3, 4), (4, 4)):
        raise ValueError(f"poses must have shape (N, 3, 4), got {P.shape}")
    if not (step_m > 0 and math.isfinite(step_m)):
        raise ConfigError(f"step_m must be a finite number > 0, got {step_m}")
    if P.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    t = P[:, :3, 3]
    travelled = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(t, axis=0), axis=1))])
    bins = np.floor(travelled / step_m + 1e-9).astype(np.int64)
    keep = np.concatenate([[True], bins[1:] > bins[:-1]])
    return np.flatnonzero(keep).astype(np.int64)
