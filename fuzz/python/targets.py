"""Fuzz targets of the Python readers: one per area, each with seeds made at run time from the
shared data (``../shared/data``, or ``$SOLID_SHARED/data``; nothing is copied into the repository).

A target takes the bytes of one file, writes them where the reader expects a file, reads it
through the public API (``solid.io``, so that the same targets run against older versions too)
and classifies the outcome:

* ``clean``: points that keep the contract (float32, C-contiguous, (N, >=3)) or the package's
  ``ReadError`` naming the file;
* anything else raises :class:`Wrong` (another exception type leaked, a broken array, a
  ``ReadError`` that does not name the file).

Used by ``fuzz.py`` (atheris, coverage-guided) and ``mutate.py`` (a fixed, seeded mutation run
that prints the table area | cases tried | handled cleanly | wrong).
"""

from __future__ import annotations

import io as _io
import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from solid import io as sio

REPO = Path(__file__).resolve().parents[2]


def shared_data() -> Path:
    env = os.environ.get("SOLID_SHARED")
    return (Path(env) if env else REPO.parent / "shared") / "data"


class Wrong(Exception):
    """The reader broke its contract on this input."""


WORK = Path(tempfile.mkdtemp(prefix="solid-fuzz-"))


def _check_points(p: Any, where: str) -> None:
    if not isinstance(p, np.ndarray) or p.dtype != np.float32 or p.ndim != 2 or p.shape[1] < 3 or not p.flags.c_contiguous:
        raise Wrong(f"{where}: broken points {type(p).__name__} {getattr(p, 'dtype', None)} {getattr(p, 'shape', None)}")


def _guard(path: Path, fn: Callable[[], None]) -> None:
    try:
        fn()
    except sio.ReadError as e:
        if path.name not in str(e):
            raise Wrong(f"ReadError without the file name: {e}") from None
    except Wrong:
        raise
    except Exception as e:
        raise Wrong(f"{type(e).__name__}: {str(e)[:200]}") from e


def _scan(ext: str, **kw: Any) -> Callable[[bytes], None]:
    def target(data: bytes) -> None:
        path = WORK / f"case{ext}"
        path.write_bytes(data)

        def run() -> None:
            _check_points(sio.read_cloud(path, **kw).points, path.name)

        _guard(path, run)

    return target


def _poses(data: bytes) -> None:
    path = WORK / "poses.txt"
    path.write_bytes(data)

    def run() -> None:
        P, t = sio.load_poses(path)
        if P.ndim != 3 or P.shape[1:] != (3, 4) or not np.isfinite(P).all():
            raise Wrong(f"broken poses {P.shape}")
        sio.load_timestamps(path)

    _guard(path, run)


def _bag(ext: str) -> Callable[[bytes], None]:
    def target(data: bytes) -> None:
        path = WORK / f"case{ext}"
        path.write_bytes(data)

        def run() -> None:
            for p in sio.Dataset(path, xyz_only=False):
                _check_points(p, path.name)

        _guard(path, run)

    return target


# --------------------------------------------------------------------------------------------
# seeds, made from the shared data at run time


def _small_clouds() -> list[np.ndarray]:
    d = shared_data()
    out = [sio.read_points(d / "hku1-avia/Scans/000000.pcd")[:64]]
    out.append(np.fromfile(d / "kitti00/velodyne/000000.bin", dtype="<f4").reshape(-1, 4)[:64])
    return [np.ascontiguousarray(c, dtype=np.float32) for c in out]


def _written(write: Callable[[Path, np.ndarray, str], None], ext: str, kinds: tuple[str, ...]) -> list[bytes]:
    seeds = []
    for c in _small_clouds():
        for kind in kinds:
            p = WORK / f"seed{ext}"
            write(p, c, kind)
            seeds.append(p.read_bytes())
    return seeds


def seeds_pcd() -> list[bytes]:
    d = shared_data()
    seeds = _written(lambda p, c, k: sio.write_pcd(p, c, data=k), ".pcd", ("ascii", "binary", "binary_compressed"))  # type: ignore[arg-type]
    raw = (d / "hku1-avia/Scans/000000.pcd").read_bytes()
    seeds.append(raw[: raw.index(b"DATA") + 200])
    return seeds


def seeds_ply() -> list[bytes]:
    return _written(lambda p, c, k: sio.write_ply(p, c, data=k), ".ply", ("ascii", "binary_little_endian", "binary_big_endian"))  # type: ignore[arg-type]


def seeds_npy() -> list[bytes]:
    seeds = []
    for c in _small_clouds():
        b = _io.BytesIO()
        np.save(b, c)
        seeds.append(b.getvalue())
        rec = np.zeros(c.shape[0], dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("t", "<f8")])
        rec["x"], rec["y"], rec["z"] = c[:, 0], c[:, 1], c[:, 2]
        b = _io.BytesIO()
        np.save(b, rec)
        seeds.append(b.getvalue())
    return seeds


def seeds_npz() -> list[bytes]:
    seeds = []
    for c in _small_clouds():
        for save in (np.savez, np.savez_compressed):
            b = _io.BytesIO()
            save(b, points=c)
            seeds.append(b.getvalue())
    return seeds


def seeds_bin() -> list[bytes]:
    d = shared_data()
    seeds = []
    for rel, rec in (
        ("kitti00/velodyne/000000.bin", 16),
        ("misc/nclt_2012-01-15_1326652795280148_hdl32e.bin", 8),
        ("solid-samples/helipr_aeva/000000.bin", 29),
        ("solid-samples/helipr_avia/000000.bin", 19),
    ):
        seeds.append((d / rel).read_bytes()[: 96 * rec])
    return seeds


def seeds_poses() -> list[bytes]:
    d = shared_data()
    kitti = b"".join((d / "kitti00/poses_00.txt").read_bytes().splitlines(keepends=True)[:20])
    odom = b"".join((d / "hku1-avia/odom_poses.txt").read_bytes().splitlines(keepends=True)[:20])
    tum = b"".join(f"{t} 1.0 2.0 3.0 0 0 0.3826834 0.9238795\n".encode() for t in range(20))
    return [kitti, odom, tum]


LIVOX = "livox_ros_driver/msg/CustomMsg"


def _bag_seeds(kind: str) -> list[bytes]:
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    msgtype = "sensor_msgs/msg/PointCloud2"
    c = _small_clouds()[0][:16]

    def message(ts: Any, sec: int) -> Any:
        from solid.datasets.rosbag import cloud_to_pointcloud2

        rec = np.ascontiguousarray(c[:, :3], dtype="<f4").view([("x", "<f4"), ("y", "<f4"), ("z", "<f4")]).ravel()
        return cloud_to_pointcloud2(ts, rec, sec, "l")

    def livox(ts: Any, sec: int) -> Any:
        types = ts.types
        point = types["livox_ros_driver/msg/CustomPoint"]
        stamp = types["builtin_interfaces/msg/Time"](sec=sec, nanosec=0)
        hdr = types["std_msgs/msg/Header"](seq=sec, stamp=stamp, frame_id="livox")
        pts = [point(offset_time=i, x=float(p[0]), y=float(p[1]), z=float(p[2]), reflectivity=1, tag=0, line=i % 6) for i, p in enumerate(c)]
        return types[LIVOX](header=hdr, timebase=sec, point_num=len(pts), lidar_id=0, rsvd=np.zeros(3, np.uint8), points=pts)

    if kind == "ros1":
        seeds = []
        ts = get_typestore(Stores.ROS1_NOETIC)
        kinds = [(msgtype, message)]
        try:
            from solid.datasets.rosbag import livox_types
        except ImportError:  # a version without Livox support: PointCloud2 seeds only
            pass
        else:
            ts.register(livox_types())
            kinds.append((LIVOX, livox))
        for mt, make in kinds:
            p = WORK / "seed.bag"
            p.unlink(missing_ok=True)
            with Writer1(p) as w:
                conn = w.add_connection("/points", mt, typestore=ts)
                for i in range(2):
                    w.write(conn, (i + 1) * 10**9, ts.serialize_ros1(make(ts, i + 1), mt))
            seeds.append(p.read_bytes())
        return seeds
    d = WORK / "seed_mcap"
    if d.exists():
        for f in d.iterdir():
            f.unlink()
        d.rmdir()
    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Writer2(d, version=9, storage_plugin=StoragePlugin.MCAP) as w2:
        conn = w2.add_connection("/points", msgtype, typestore=ts)
        for i in range(2):
            w2.write(conn, (i + 1) * 10**9, ts.serialize_cdr(message(ts, i + 1), msgtype))
    return [next(d.glob("*.mcap")).read_bytes()]


@dataclass(frozen=True)
class Area:
    name: str
    target: Callable[[bytes], None]
    seeds: Callable[[], list[bytes]]


AREAS: dict[str, Area] = {
    a.name: a
    for a in (
        Area("pcd", _scan(".pcd"), seeds_pcd),
        Area("ply", _scan(".ply"), seeds_ply),
        Area("npy", _scan(".npy"), seeds_npy),
        Area("npz", _scan(".npz"), seeds_npz),
        Area("bin", _scan(".bin"), seeds_bin),
        Area("poses", _poses, seeds_poses),
        Area("rosbag1", _bag(".bag"), lambda: _bag_seeds("ros1")),
        Area("mcap", _bag(".mcap"), lambda: _bag_seeds("mcap")),
    )
}
