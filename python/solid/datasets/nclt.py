"""NCLT ``velodyne_sync`` scans: packed 8 B records, uint16 x, y, z (metres = raw × 0.005 − 100),
uint8 intensity, uint8 laser id (0..31, a Velodyne HDL-32E). File names are the scan times in
microseconds."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..arrays import PathLike
from ._bin import BinLayout
from ._common import Cloud, records

_DTYPE = np.dtype([("x", "<u2"), ("y", "<u2"), ("z", "<u2"), ("intensity", "u1"), ("laser_id", "u1")])
assert _DTYPE.itemsize == 8


def _plausible(rec: npt.NDArray[np.void]) -> npt.NDArray[np.bool_]:
    return np.asarray(rec["laser_id"] < 32)


def _decode(path: PathLike, data: bytes, xyz_only: bool) -> Cloud:
    rec = records(path, data, _DTYPE, "NCLT velodyne_sync (uint16 x y z, uint8 intensity, laser id)")
    width = 3 if xyz_only else 5
    out = np.empty((rec.shape[0], width), dtype=np.float32)
    for i, a in enumerate("xyz"):
        # metres = raw * 0.005 - 100, computed in float64 then rounded once to float32
        out[:, i] = rec[a] * 0.005 - 100.0
    if xyz_only:
        return Cloud(out, ("x", "y", "z"))
    out[:, 3] = rec["intensity"]
    out[:, 4] = rec["laser_id"]
    return Cloud(out, ("x", "y", "z", "intensity", "laser_id"))


LAYOUT = BinLayout("nclt", _DTYPE, "NCLT velodyne_sync", _plausible, _decode)

#: NCLT names scans by their time in microseconds.
NAME_TIME_SCALE = 1e-6
