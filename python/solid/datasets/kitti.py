"""KITTI odometry: ``.bin`` scans of float32 x, y, z, reflectance (16 B per point), and the
sequence folder around them.

A KITTI sequence folder (``sequences/NN/``) holds ``velodyne/NNNNNN.bin``, ``times.txt`` (one
time per frame, seconds) and ``calib.txt`` (its ``Tr:`` line is the Velodyne → left camera
transform); the ground-truth camera poses live in ``poses/NN.txt`` two levels up. Opening such a
folder uses all of them (``ds.pose_source`` and ``ds.calib_source`` say which files); scan file
names are frame numbers, so a folder holding a subset of the frames takes its rows of the full
poses and times files.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..arrays import PathLike
from ._bin import BinLayout, plausible_coords
from ..errors import ReadError
from ._common import Cloud

_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("reflectance", "<f4")])


def _plausible(rec: npt.NDArray[np.void]) -> npt.NDArray[np.bool_]:
    ok: npt.NDArray[np.bool_] = plausible_coords(rec["x"], rec["y"], rec["z"]) & np.isfinite(rec["reflectance"])
    return ok


def _decode(path: PathLike, data: bytes, xyz_only: bool) -> Cloud:
    if len(data) % 16 != 0:
        raise ReadError(
            path,
            f"size {len(data)} B is not a multiple of 16 B, the KITTI record (float32 x y z reflectance); "
            "truncated, or another layout: pass format=",
        )
    a = np.frombuffer(data, dtype="<f4").reshape(-1, 4)
    if xyz_only:
        return Cloud(np.ascontiguousarray(a[:, :3], dtype=np.float32), ("x", "y", "z"))
    return Cloud(a.astype(np.float32, copy=True), ("x", "y", "z", "reflectance"))


LAYOUT = BinLayout("kitti", _DTYPE, "KITTI (float32 x y z reflectance)", _plausible, _decode)


def sequence_files(root: Path) -> dict[str, Path]:
    """The files of a KITTI sequence folder that exist: ``times``, ``calib`` and ``poses``."""
    found: dict[str, Path] = {}
    if (root / "times.txt").is_file():
        found["times"] = root / "times.txt"
    if (root / "calib.txt").is_file():
        found["calib"] = root / "calib.txt"
    gt = root.parent.parent / "poses" / f"{root.name}.txt"
    if root.parent.name == "sequences" and gt.is_file():
        found["poses"] = gt
    return found


def is_sequence(root: Path) -> bool:
    """A folder with ``velodyne/`` and ``calib.txt`` or ``times.txt`` beside it."""
    return (root / "velodyne").is_dir() and ((root / "calib.txt").is_file() or (root / "times.txt").is_file())
