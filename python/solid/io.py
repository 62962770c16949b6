"""Reading and writing point clouds, poses and timestamps: the public face of :mod:`solid.datasets`.

Every name here is the :mod:`solid.datasets` object of that name (one module per format, behind an
explicit registry); this module gathers the ones a user reads and writes files with. Every reader
returns a C-contiguous ``numpy.float32`` array of shape ``(N, C)`` with ``C >= 3``: columns 0, 1,
2 are x, y, z in metres (sensor frame), further columns are the file's other numeric fields in
file order (see :attr:`Cloud.fields`). Any malformed, truncated or inconsistent file raises
:class:`ReadError` (a :class:`solid.SolidError`, hence a ``ValueError``) whose message names the
file and what is wrong. :func:`open_dataset` opens a whole recording as a :class:`Dataset`.

The transforms that used to be reached from here (``clip_fov``, ``rotate_z``, ...) live in
:mod:`solid.transforms`; their old names here still work, with a ``DeprecationWarning``, as does
``Sequence`` (now :class:`Dataset`).
"""

from __future__ import annotations

import warnings

from .datasets import (
    FORMATS,
    SCAN_EXTENSIONS,
    Cloud,
    Dataset,
    ReadError,
    detect_format,
    natural_key,
    open_dataset,
    read_cloud,
    read_points,
)
from .datasets.lzf import lzf_compress, lzf_decompress
from .datasets.pcd import write_pcd
from .datasets.ply import write_ply
from .datasets.poses import load_extrinsic, load_poses, load_timestamps, sensor_poses
from .datasets.rosbag import pointcloud2_to_cloud

__all__ = [
    "FORMATS",
    "SCAN_EXTENSIONS",
    "Cloud",
    "Dataset",
    "ReadError",
    "detect_format",
    "load_extrinsic",
    "load_poses",
    "load_timestamps",
    "lzf_compress",
    "lzf_decompress",
    "natural_key",
    "open_dataset",
    "pointcloud2_to_cloud",
    "read_cloud",
    "read_points",
    "sensor_poses",
    "write_pcd",
    "write_ply",
]

#: Names this module used to hold: old name -> (module, name) where it lives now.
_MOVED = {
    "Sequence": ("solid.datasets", "Dataset"),
    "clip_fov": ("solid.transforms", "clip_fov"),
    "occlude_sector": ("solid.transforms", "occlude_sector"),
    "rotate_z": ("solid.transforms", "rotate_z"),
    "subsample_by_distance": ("solid.transforms", "subsample_by_distance"),
    "yaw_degrees": ("solid.transforms", "yaw_degrees"),
}


def __getattr__(name: str) -> object:
    if name in _MOVED:
        import importlib

        module, new = _MOVED[name]
        warnings.warn(f"solid.io.{name} is {module}.{new}", DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(module), new)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
