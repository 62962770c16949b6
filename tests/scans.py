"""The shared scans as the core tests want them, read through solid.io."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

from solid import io as sio


def read_xyz(path: Path) -> npt.NDArray[np.float64]:
    """x, y, z of a shared scan as a C-contiguous (N, 3) float64 array."""
    return np.ascontiguousarray(sio.read_points(path, xyz_only=True), dtype=np.float64)


def read_kitti(path: Path) -> npt.NDArray[np.float32]:
    """A KITTI `.bin` as its (N, 4) float32 array, read in place by describe."""
    return sio.read_points(path, "kitti")
