"""HeLiPR ``.bin`` scans: the packed records its file player reads, one layout per sensor.

* Aeva Aeries II, 29 B: x y z reflectivity velocity (float32), time_offset_ns (int32),
  line_index (uint8), intensity (float32)
* Livox Avia, 19 B: x y z (float32), reflectivity, tag, line (uint8), offset_time (uint32)
* Ouster OS2-128, 26 B: x y z intensity (float32), t (uint32), reflectivity, ring, ambient (uint16)
* Velodyne VLP-16, 22 B: x y z intensity (float32), ring (uint16), time (float32)

File names are the scan times in nanoseconds.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ._bin import BinLayout, finite_below, plausible_coords

Mask = npt.NDArray[np.bool_]
Rec = npt.NDArray[np.void]

_AEVA = np.dtype(
    [
        ("x", "<f4"),
        ("y", "<f4"),
        ("z", "<f4"),
        ("reflectivity", "<f4"),
        ("velocity", "<f4"),
        ("time_offset_ns", "<i4"),
        ("line_index", "u1"),
        ("intensity", "<f4"),
    ]
)
_AVIA = np.dtype(
    [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("reflectivity", "u1"), ("tag", "u1"), ("line", "u1"), ("offset_time", "<u4")]
)
_OUSTER = np.dtype(
    [
        ("x", "<f4"),
        ("y", "<f4"),
        ("z", "<f4"),
        ("intensity", "<f4"),
        ("t", "<u4"),
        ("reflectivity", "<u2"),
        ("ring", "<u2"),
        ("ambient", "<u2"),
    ]
)
_VELODYNE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("ring", "<u2"), ("time", "<f4")])
assert (_AEVA.itemsize, _AVIA.itemsize, _OUSTER.itemsize, _VELODYNE.itemsize) == (29, 19, 26, 22)


def _xyz(rec: Rec) -> Mask:
    return plausible_coords(rec["x"], rec["y"], rec["z"])


def _aeva(rec: Rec) -> Mask:
    return _xyz(rec) & finite_below(rec["velocity"], 1e4) & finite_below(rec["reflectivity"], 1e6) & finite_below(rec["intensity"], 1e6)


def _avia(rec: Rec) -> Mask:
    return _xyz(rec) & (rec["line"] < 64)


def _ouster(rec: Rec) -> Mask:
    return _xyz(rec) & finite_below(rec["intensity"], 1e6) & (rec["ring"] < 256)


def _velodyne(rec: Rec) -> Mask:
    return _xyz(rec) & finite_below(rec["intensity"], 1e6) & (rec["ring"] < 256) & finite_below(rec["time"], 1e4)


AEVA = BinLayout("helipr-aeva", _AEVA, "HeLiPR Aeva (29 B)", _aeva)
AVIA = BinLayout("helipr-avia", _AVIA, "HeLiPR Avia (19 B)", _avia)
OUSTER = BinLayout("helipr-ouster", _OUSTER, "HeLiPR Ouster (26 B)", _ouster)
VELODYNE = BinLayout("helipr-velodyne", _VELODYNE, "HeLiPR Velodyne (22 B)", _velodyne)
LAYOUTS = (AEVA, AVIA, OUSTER, VELODYNE)

#: HeLiPR names scans by their time in nanoseconds.
NAME_TIME_SCALE = 1e-9
