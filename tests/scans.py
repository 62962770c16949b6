"""Minimal readers of the shared scan formats (shared/data/README.md) for the core tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt


def read_xyz(path: Path) -> npt.NDArray[np.float64]:
    """x, y, z of a shared scan as a C-contiguous (N, 3) float64 array."""
    name = str(path)
    raw = path.read_bytes()
    if name.endswith(".pcd"):
        marker = b"DATA binary\n"
        at = raw.index(marker)
        header = raw[:at].decode("ascii")
        fields = next(ln for ln in header.splitlines() if ln.startswith("FIELDS")).split()[1:]
        body = np.frombuffer(raw, dtype="<f4", offset=at + len(marker))
        xyz = body.reshape(-1, len(fields))[:, :3]
    elif "helipr_aeva" in name:
        xyz = np.frombuffer(raw, dtype=np.dtype([("xyz", "<f4", 3), ("rest", "V17")]))["xyz"]
    elif "helipr_avia" in name:
        xyz = np.frombuffer(raw, dtype=np.dtype([("xyz", "<f4", 3), ("rest", "V7")]))["xyz"]
    elif "nclt" in name:
        rec = np.frombuffer(raw, dtype=np.dtype([("xyz", "<u2", 3), ("i", "u1"), ("l", "u1")]))
        return np.ascontiguousarray(rec["xyz"].astype(np.float64) * 0.005 - 100.0)
    else:
        xyz = np.frombuffer(raw, dtype="<f4").reshape(-1, 4)[:, :3]
    return np.ascontiguousarray(xyz, dtype=np.float64)


def read_kitti(path: Path) -> npt.NDArray[np.float32]:
    """A KITTI `.bin` as its (N, 4) float32 array."""
    return np.fromfile(path, dtype="<f4").reshape(-1, 4)
