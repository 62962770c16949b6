"""Scan readers (re-exported from :mod:`solid.datasets`) and the transforms of the paper's experiments.

The readers, the sequence class and the pose, timestamp and extrinsic loaders live in
:mod:`solid.datasets` (one module per format, behind an explicit registry); this module keeps
their historical names: :class:`Sequence` is :class:`solid.datasets.Dataset`, and
:func:`read_cloud`, :func:`read_points`, :func:`detect_format`, :class:`ReadError`, ... are the
same objects. Every reader returns a C-contiguous ``numpy.float32`` array of shape ``(N, C)``
with ``C >= 3``: columns 0, 1, 2 are x, y, z in metres (sensor frame), further columns are the
file's other numeric fields in file order (see :attr:`Cloud.fields`). Any malformed, truncated
or inconsistent file raises :class:`ReadError` (a :class:`solid.SolidError`, hence a
``ValueError``) whose message names the file and what is wrong.

The transforms (:func:`clip_fov`, :func:`occlude_sector`, :func:`rotate_z`,
:func:`subsample_by_distance`) work on any (N, >=3) array.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from .datasets import FORMATS, SCAN_EXTENSIONS, Cloud, Dataset, ReadError, detect_format, read_cloud, read_points
from .datasets._common import natural_key
from .datasets._write import atomic_write_bytes
from .datasets.lzf import lzf_compress, lzf_decompress
from .datasets.pcd import write_pcd
from .datasets.ply import write_ply
from .datasets.poses import load_extrinsic, load_poses, load_timestamps, sensor_poses, yaw_degrees
from .datasets.rosbag import pointcloud2_to_cloud

__all__ = [
    "FORMATS",
    "SCAN_EXTENSIONS",
    "Cloud",
    "ReadError",
    "Sequence",
    "clip_fov",
    "detect_format",
    "load_extrinsic",
    "load_poses",
    "load_timestamps",
    "lzf_compress",
    "lzf_decompress",
    "natural_key",
    "occlude_sector",
    "pointcloud2_to_cloud",
    "read_cloud",
    "read_points",
    "rotate_z",
    "sensor_poses",
    "subsample_by_distance",
    "write_pcd",
    "write_ply",
    "yaw_degrees",
]

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]

#: A recording: :class:`solid.datasets.Dataset` under its historical name.
Sequence = Dataset
#: Kept for callers of the private name.
_atomic_write_bytes = atomic_write_bytes


# --------------------------------------------------------------------------------------------
# transforms


def _azimuth_deg(points: npt.NDArray[Any]) -> F64:
    return np.degrees(np.arctan2(points[:, 1].astype(np.float64), points[:, 0].astype(np.float64)))


def _wrap180(d: npt.NDArray[Any]) -> F64:
    """Wrap angles (degrees) into (−180, 180]."""
    w = np.mod(np.asarray(d, dtype=np.float64) + 180.0, 360.0) - 180.0
    return np.asarray(np.where(w == -180.0, 180.0, w), dtype=np.float64)


def clip_fov(points: npt.NDArray[Any], width_deg: float, center_deg: float = 0.0) -> npt.NDArray[Any]:
    """Keep points whose azimuth lies within ±width/2 of ``center_deg`` (0 = +x forward, CCW)."""
    if not 0.0 < width_deg <= 360.0 or not math.isfinite(center_deg):
        raise ValueError(f"width_deg must be in (0, 360] and center_deg finite, got {width_deg}, {center_deg}")
    if width_deg >= 360.0:
        return points.copy()
    off = _wrap180(_azimuth_deg(points) - center_deg)
    return points[np.abs(off) <= width_deg / 2.0]


def occlude_sector(points: npt.NDArray[Any], width_deg: float, center_deg: float = 0.0) -> npt.NDArray[Any]:
    """Remove the points whose azimuth lies within ±width/2 of ``center_deg`` (a blocked sector)."""
    if not 0.0 <= width_deg <= 360.0 or not math.isfinite(center_deg):
        raise ValueError(f"width_deg must be in [0, 360] and center_deg finite, got {width_deg}, {center_deg}")
    if width_deg == 0.0:
        return points.copy()
    off = _wrap180(_azimuth_deg(points) - center_deg)
    return points[np.abs(off) > width_deg / 2.0]


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
    if not step_m > 0:
        raise ValueError(f"step_m must be > 0, got {step_m}")
    if P.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    t = P[:, :3, 3]
    travelled = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(t, axis=0), axis=1))])
    bins = np.floor(travelled / step_m + 1e-9).astype(np.int64)
    keep = np.concatenate([[True], bins[1:] > bins[:-1]])
    return np.flatnonzero(keep).astype(np.int64)
