"""Datasets: scans, their timestamps, poses and calibration, from any supported recording.

::

    ds = solid.datasets.open_dataset("dataset/sequences/00")   # KITTI: velodyne/, times.txt, calib.txt
    print(ds.reader, len(ds), ds.pose_source)                   # "kitti", 4541, .../poses/00.txt
    for points in ds:                                           # float32 (N, 3), x y z
        ...

Readers are registered by name in :data:`READERS` (see :func:`available`); ``format=`` forces one.
Otherwise the content decides: the extension for ``.pcd``, ``.ply``, ``.npy``, ``.npz`` and bags,
and for a ``.bin`` (which says nothing about itself) a sniffer that decodes a sample of records
with every layout whose record size divides the file size and keeps the one whose values are
plausible (see :mod:`solid.datasets._bin`). Folder and file names never choose a reader. A file
whose size contradicts its reader is a :class:`ReadError` naming the size and the format.

What a dataset knows (``open_dataset``):

* a KITTI sequence folder (``velodyne/`` beside ``times.txt``/``calib.txt``): its times, its
  calibration, and ``../../poses/NN.txt`` when present (:mod:`.kitti`);
* a folder of scans (or a folder holding ``velodyne/``, ``Scans/``, ``scans/``,
  ``velodyne_points/data/``, ``pointclouds/`` or ``lidar/``), in natural order, with the
  ``times.txt`` beside such a sub-folder as its timestamps; NCLT and HeLiPR scans are named by
  their time (µs, ns), which become the timestamps;
* a ROS 1 bag, ROS 2 bag or MCAP file with ``sensor_msgs/PointCloud2`` or Livox ``CustomMsg``
  (:mod:`.rosbag`);
* one scan file (a dataset of one scan).

Poses and timestamps files, and how their rows meet the scans (by frame number, by time with
interpolation), are described in :mod:`.poses`. Every reader raises :class:`ReadError` (a
:class:`solid.SolidError`, hence a ``ValueError``) naming the file and the problem; a missing
file is a ``FileNotFoundError``. Which frames of a dataset a run reads (``--frames``,
``subsample_m``) is :mod:`.selection`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Final, TypedDict, TypeVar, overload

import numpy as np

from ..arrays import F32, F64, I64, PathLike
from . import helipr, kitti, nclt, npy, pcd, ply, rosbag
from ._bin import BinLayout, sniff
from ..errors import ConfigError, ReadError
from ._common import Cloud, file_size, natural_key, read_bytes
from .selection import parse_frames
from .poses import (
    interpolate_poses,
    load_extrinsic,
    load_poses,
    load_timestamps,
    match_rows,
    resolve,
    take_rows,
    sensor_poses_in_sensor_world,
)

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "FORMATS",
    "READERS",
    "SCAN_EXTENSIONS",
    "Cloud",
    "Dataset",
    "OpenOptions",
    "ReadError",
    "Reader",
    "available",
    "detect_format",
    "natural_key",
    "open_dataset",
    "read_cloud",
    "read_points",
]


T = TypeVar("T")


@dataclass(frozen=True)
class Reader:
    """One registered reader: what it reads and how."""

    name: str
    description: str
    extensions: tuple[str, ...]
    read: Callable[[PathLike, bool], Cloud] | None = None
    layout: BinLayout | None = None
    #: The reader's datasets name scans by their time, in these units (seconds per unit).
    name_time_scale: float | None = None

    @property
    def is_bag(self) -> bool:
        return self.read is None and self.layout is None

    def read_file(self, path: PathLike, xyz_only: bool, data: bytes | None = None) -> Cloud:
        """Read one scan file (whose bytes may be given); any failure is a :class:`ReadError` naming it."""
        if self.is_bag:
            raise ReadError(path, f"{self.name} reads bags, which hold many scans: use solid.datasets.open_dataset")
        layout, read = self.layout, self.read
        if layout is not None:
            return guarded(path, self.name, lambda: layout.read(path, read_bytes(path) if data is None else data, xyz_only))
        assert read is not None
        return guarded(path, self.name, lambda: read(path, xyz_only))


def guarded(path: PathLike, what: str, fn: Callable[[], T]) -> T:
    """``fn()``, where any failure other than a :class:`ReadError`, ``OSError`` or
    ``MemoryError`` becomes a :class:`ReadError` naming ``path`` (the readers' error contract)."""
    try:
        return fn()
    except (ReadError, OSError, MemoryError):
        raise
    except Exception as e:
        raise ReadError(path, f"cannot read as {what}: {type(e).__name__}: {e}") from None


def _bin(layout: BinLayout, description: str, scale: float | None = None) -> Reader:
    return Reader(layout.name, description, (".bin",), layout=layout, name_time_scale=scale)


#: Every reader by name (the values ``format=`` takes, besides ``"rosbag"``).
READERS: Final[dict[str, Reader]] = {
    r.name: r
    for r in (
        _bin(kitti.LAYOUT, "KITTI .bin: float32 x y z reflectance (16 B records)"),
        _bin(nclt.LAYOUT, "NCLT velodyne_sync .bin: uint16 x y z scaled, intensity, laser id (8 B)", nclt.NAME_TIME_SCALE),
        _bin(helipr.AEVA, "HeLiPR Aeva Aeries II .bin (29 B records)", helipr.NAME_TIME_SCALE),
        _bin(helipr.AVIA, "HeLiPR Livox Avia .bin (19 B records)", helipr.NAME_TIME_SCALE),
        _bin(helipr.OUSTER, "HeLiPR Ouster OS2-128 .bin (26 B records)", helipr.NAME_TIME_SCALE),
        _bin(helipr.VELODYNE, "HeLiPR Velodyne VLP-16 .bin (22 B records)", helipr.NAME_TIME_SCALE),
        Reader("pcd", "PCD v0.7: ascii, binary, binary_compressed (LZF)", (".pcd",), read=pcd.read),
        Reader("ply", "PLY vertices: ascii, binary little/big endian", (".ply",), read=ply.read),
        Reader("npy", "numpy .npy: (N, >=3) array or fields x y z", (".npy",), read=lambda p, x: npy.read(p, "npy", x)),
        Reader("npz", "numpy .npz: the array 'points' (or its only array)", (".npz",), read=lambda p, x: npy.read(p, "npz", x)),
        Reader("rosbag:pointcloud2", "ROS 1/ROS 2 bag or MCAP, sensor_msgs/PointCloud2 (needs rosbags)", (".bag", ".db3", ".mcap")),
        Reader("rosbag:livox", "ROS 1/ROS 2 bag or MCAP, Livox CustomMsg (livox_ros_driver[2]; needs rosbags)", (".bag", ".db3", ".mcap")),
    )
}
#: Values ``format=`` accepts: every reader, and ``rosbag`` (a bag, whichever message type it holds).
FORMATS: Final = (*READERS, "rosbag")
#: The ``.bin`` layouts the sniffer tries, in the order that breaks ties.
BIN_LAYOUTS: Final = tuple(r.layout for r in READERS.values() if r.layout is not None)
#: File extensions a folder scan picks up.
SCAN_EXTENSIONS: Final = (".bin", ".pcd", ".ply", ".npy", ".npz")
_BY_EXTENSION: Final = {".pcd": "pcd", ".ply": "ply", ".npy": "npy", ".npz": "npz"}
_SCAN_FOLDERS: Final = ("velodyne", "Scans", "scans", "velodyne_points/data", "pointclouds", "lidar")


def available() -> dict[str, str]:
    """Every reader's registry name with a one-line description."""
    return {name: r.description for name, r in READERS.items()}


def _forced(format: str) -> Reader | None:
    """The reader ``format=`` names (``None`` for ``"rosbag"``); ``ValueError`` when unknown."""
    f = format.lower()
    if f == "rosbag":
        return None
    if f not in READERS:
        raise ValueError(f"unknown format {format!r}; one of {', '.join(FORMATS)}")
    return READERS[f]


def _file_reader(path: Path, data: bytes | None = None) -> Reader:
    """The reader for one scan file, from its extension or (``.bin``) its content."""
    ext = path.suffix.lower()
    if ext in _BY_EXTENSION:
        return READERS[_BY_EXTENSION[ext]]
    if ext == ".bin":
        return READERS[sniff(path, read_bytes(path) if data is None else data, BIN_LAYOUTS).name]
    if rosbag.is_bag(path):
        raise ReadError(path, "a bag holds many scans: open it with solid.datasets.open_dataset")
    raise ReadError(path, f"cannot tell the point-cloud format from the extension {ext!r}; pass format=")


def detect_format(path: PathLike) -> str:
    """The registry name of the reader :func:`read_cloud` would use (a ``.bin`` is sniffed)."""
    p = Path(path)
    if rosbag.is_bag(p):
        return "rosbag"
    file_size(p)  # exists, and is a regular file
    return _file_reader(p).name


def read_cloud(path: PathLike, format: str | None = None, *, xyz_only: bool = False) -> Cloud:
    """Read one scan file: points (N, C) float32, x y z first, and the names of the columns.

    ``format`` forces a reader (a registry name, see :func:`available`); otherwise the
    extension, or for ``.bin`` the content, decides. ``xyz_only`` drops the other columns.
    """
    p = Path(path)
    reader = _forced(format) if format is not None else None
    if reader is None:
        if format is not None or rosbag.is_bag(p):
            raise ReadError(p, "a bag holds many scans: open it with solid.datasets.open_dataset")
        file_size(p)
        if p.suffix.lower() == ".bin":
            data = read_bytes(p)
            layout = guarded(p, ".bin", lambda: sniff(p, data, BIN_LAYOUTS))
            return READERS[layout.name].read_file(p, xyz_only, data)
        reader = _file_reader(p)
    return reader.read_file(p, xyz_only)


def read_points(path: PathLike, format: str | None = None, *, xyz_only: bool = False) -> F32:
    """Read one scan file as a float32 (N, C >= 3) array, x y z first. See :func:`read_cloud`."""
    return read_cloud(path, format, xyz_only=xyz_only).points


def _scan_folder(root: Path) -> Path:
    for sub in _SCAN_FOLDERS:
        if (root / sub).is_dir():
            return root / sub
    return root


def _frame_numbers(files: list[Path]) -> I64 | None:
    """The frame numbers in the scans' names (``000100.bin`` → 100), or ``None`` if not all are."""
    stems = [f.stem for f in files]
    if not stems or not all(s.isascii() and s.isdigit() for s in stems):
        return None
    numbers = [int(s) for s in stems]
    if max(numbers) >= 2**63:
        return None
    return np.array(numbers, dtype=np.int64)


class OpenOptions(TypedDict, total=False):
    """How :class:`Dataset` (``open_dataset``) reads a recording; every key is optional.

    Attributes:
        format: force a reader (see :func:`available`; ``"rosbag"`` for a bag of either type).
        topic: the bag topic to read (needed when a bag has several point-cloud topics).
        poses: a poses file (KITTI rows, TUM or 4×4 rows; see :mod:`solid.datasets.poses`); for a
            bag, also a ``nav_msgs/Odometry`` topic of it (``"/odom"``: its poses interpolated at
            the scans' log times, which its messages' log times share).
        timestamps: a timestamps file (one time per scan, seconds; or per frame, see above).
        calib: the sensor → pose-frame extrinsic (a KITTI ``calib.txt`` or 12/16 numbers), applied
            to ``poses``.
        xyz_only: scans as (N, 3) x y z (True, the default) or with every column of the file.
        frames: the scans a run will read (``"0:60,284:314"``, :func:`.selection.parse_frames`):
            only they need a row in ``poses``/``timestamps`` (the others get NaN).
    """

    format: str | None
    topic: str | None
    poses: PathLike | None
    timestamps: PathLike | None
    calib: PathLike | None
    xyz_only: bool
    frames: str | None


class Dataset:
    """A recording and its scans, timestamps and poses (``open_dataset(path, ...)`` is another name).

    Attributes:
        path: absolute path of the sequence (folder, bag or file).
        reader: registry name of the reader of its scans (``"kitti"``, ``"pcd"``, ``"rosbag:livox"``, ...).
        timestamps: float64 (N,) seconds, or ``None``.
        poses: float64 (N, 3, 4) sensor poses ``T_world_sensor`` [R|t], calibration applied, or ``None``.
        pose_source, timestamp_source, calib_source: absolute paths of the files used, or ``None``.
        frame_ids: int64 (N,): frame numbers from the scans' file names when they all are numbers
            (``000100.bin`` → 100), else the scan's index (a bag's message index).
        files: the scan files (empty for a bag).
    """

    def __init__(self, path: PathLike, **options: Unpack[OpenOptions]) -> None:
        """Opens a recording (folder of scans, KITTI sequence, bag, or one scan file).

        Args:
            path: the sequence folder, bag, MCAP file or scan file.
            **options: how to read it, by keyword (:class:`OpenOptions`: ``format``, ``topic``,
                ``poses``, ``timestamps``, ``calib``, ``xyz_only``, ``frames``).

        Raises:
            FileNotFoundError: ``path`` or a given file does not exist.
            ReadError: the recording or a file is malformed, or the files do not fit together.
            ValueError: an unknown ``format``.
            TypeError: an option that :class:`OpenOptions` does not name.
        """
        unknown = sorted(set(options) - set(OpenOptions.__annotations__))
        if unknown:
            raise TypeError(f"Dataset() got an unexpected keyword argument {unknown[0]!r}")
        format, topic, frames = options.get("format"), options.get("topic"), options.get("frames")
        poses, timestamps, calib = options.get("poses"), options.get("timestamps"), options.get("calib")
        self.path = Path(os.path.abspath(path))
        if not self.path.exists():
            raise FileNotFoundError(f"{self.path}: no such file or folder")
        self.format = format
        self.topic = topic
        self.xyz_only = options.get("xyz_only", True)
        self.files: list[Path] = []
        self.scan_folder = self.path if self.path.is_dir() else self.path.parent
        self.timestamps: F64 | None = None
        self.poses: F64 | None = None
        self.pose_source: Path | None = None
        self.timestamp_source: Path | None = None
        self.calib_source: Path | None = None
        self._bag: rosbag.Bag | None = None
        forced = _forced(format) if format is not None else None
        found: dict[str, Path] = {}
        numbers: I64 | None = None
        if (format is not None and (forced is None or forced.is_bag)) or (format is None and rosbag.is_bag(self.path)):
            msgtype = None
            if forced is not None:
                msgtype = rosbag.POINTCLOUD2 if forced.name == "rosbag:pointcloud2" else None
            self._bag = rosbag.Bag(self.path, topic, msgtype)
            if forced is not None and self._bag.reader_name != forced.name:
                raise ReadError(self.path, f"topic {self._bag.topic} holds {self._bag.msgtype}, not what {forced.name} reads")
            self.reader = self._bag.reader_name
            self.topic = self._bag.topic
            n = len(self._bag)
            self.timestamps = np.array(self._bag.times_ns, dtype=np.float64) * 1e-9
            root = self.scan_folder
        else:
            if topic is not None:
                raise ConfigError(f"{self.path}: topic= ({topic!r}) applies to a bag; this is not one")
            if self.path.is_dir():
                self.scan_folder = _scan_folder(self.path)
                files = [p for p in self.scan_folder.iterdir() if p.is_file() and p.suffix.lower() in SCAN_EXTENSIONS]
                if not files:
                    raise ReadError(self.scan_folder, f"no scans ({', '.join(SCAN_EXTENSIONS)}) in this folder")
                exts = sorted({p.suffix.lower() for p in files})
                if len(exts) > 1:
                    raise ReadError(self.scan_folder, f"mixed scan types {', '.join(exts)} in one folder")
                self.files = sorted(files, key=lambda p: natural_key(p.name))
                root = self.path
                if kitti.is_sequence(self.path):
                    found = kitti.sequence_files(self.path)
                elif self.scan_folder != self.path and (self.path / "times.txt").is_file():
                    # A recording folder with its scans in Scans/ (or velodyne/) and their times beside.
                    found["times"] = self.path / "times.txt"
            else:
                self.files = [self.path]
                root = self.path.parent
            if forced is None:
                first = next((f for f in self.files if f.stat().st_size > 0), self.files[0])
                forced = _file_reader(first)
            self.reader = forced.name
            n = len(self.files)
            numbers = _frame_numbers(self.files)
            if forced.name_time_scale is not None and numbers is not None and timestamps is None:
                self.timestamps = numbers.astype(np.float64) * forced.name_time_scale
        self._reader = READERS[self.reader]
        self._n = n
        self.frame_ids: I64 = numbers if numbers is not None else np.arange(n, dtype=np.int64)
        # Only the scans a run reads need a pose and a time (the frames are checked first).
        self._wanted = parse_frames(frames, n) if frames else None

        if timestamps is not None:
            self.timestamp_source = resolve(timestamps, root, "timestamps")
        elif "times" in found:
            self.timestamp_source = found["times"]
        if self.timestamp_source is not None:
            t = load_timestamps(self.timestamp_source)
            self.timestamps = take_rows(t, match_rows(self.timestamp_source, t.shape[0], n, numbers, "timestamps", self._wanted))

        odometry_topic = poses is not None and self._bag is not None and str(poses).startswith("/") and not Path(poses).exists()
        if odometry_topic:
            # A topic of the bag (nav_msgs/Odometry): its poses at the scans' times.
            assert self._bag is not None and self.timestamps is not None
            self.pose_source = Path(str(poses))
            t_odo, P_odo = rosbag.read_odometry(self.path, str(poses))
            self.poses = interpolate_poses(self.path, t_odo, P_odo, self.timestamps)
        elif poses is not None:
            self.pose_source = resolve(poses, root, "poses")
        elif "poses" in found:
            self.pose_source = found["poses"]
            self.calib_source = found.get("calib")  # KITTI's own poses are the camera's
        if calib is not None:
            if self.pose_source is None:
                raise ValueError("calib= needs poses (the calibration turns the poses into sensor poses)")
            self.calib_source = resolve(calib, root, "calibration")
        if self.pose_source is not None:
            if not odometry_topic:
                self.poses = self._load_poses(self.pose_source, numbers)
            if self.calib_source is not None and self.poses is not None:
                self.poses = sensor_poses_in_sensor_world(self.poses, load_extrinsic(self.calib_source))

    def _load_poses(self, src: Path, numbers: I64 | None) -> F64:
        P, tum_t = load_poses(src)
        if tum_t is not None and self.timestamps is not None:
            return interpolate_poses(src, tum_t, P, self.timestamps)
        if tum_t is not None and P.shape[0] != self._n:
            raise ReadError(
                src,
                f"{P.shape[0]} TUM poses for {self._n} scans, and the scans have no timestamps to match "
                "them by: pass timestamps=",
            )
        rows = match_rows(src, P.shape[0], self._n, numbers, "poses", self._wanted)
        if tum_t is not None:
            self.timestamps = take_rows(tum_t, rows)
            self.timestamp_source = src
        return take_rows(P, rows)

    @property
    def is_bag(self) -> bool:
        """Whether the scans come from a bag (read sequentially: random access is slow)."""
        return self._bag is not None

    def __len__(self) -> int:
        return self._n

    @overload
    def __getitem__(self, i: int) -> F32: ...
    @overload
    def __getitem__(self, i: slice) -> list[F32]: ...
    def __getitem__(self, i: int | slice) -> F32 | list[F32]:
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(self._n))]
        i = int(i)
        if i < 0:
            i += self._n
        if not 0 <= i < self._n:
            raise IndexError(f"scan {i} out of range for a dataset of {self._n}")
        if self._bag is not None:
            for k, pts in enumerate(self._bag.points(self.xyz_only)):
                if k == i:
                    return pts
            raise ReadError(self.path, f"the bag ended before scan {i}")
        return self._reader.read_file(self.files[i], self.xyz_only).points

    def __iter__(self) -> Iterator[F32]:
        if self._bag is not None:
            yield from self._bag.points(self.xyz_only)
        else:
            for f in self.files:
                yield self._reader.read_file(f, self.xyz_only).points

    def name(self, i: int) -> str:
        """A label for scan ``i``: its file name, or ``topic@timestamp_ns`` for a bag."""
        if self._bag is not None:
            return f"{self.topic}@{self._bag.times_ns[i]}"
        return self.files[i].name

    def positions(self) -> F64:
        """(N, 3) translations of the poses (raises if there are none)."""
        if self.poses is None:
            raise ValueError(f"{self.path}: this dataset has no poses")
        return np.ascontiguousarray(self.poses[:, :, 3])

    def __repr__(self) -> str:
        return f"Dataset({str(self.path)!r}, reader={self.reader!r}, scans={self._n})"


#: Opens a recording: another name of :class:`Dataset` (its constructor takes the arguments).
open_dataset = Dataset
