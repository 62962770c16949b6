"""ROS 1 bags, ROS 2 bags (sqlite3 or MCAP storage) and MCAP files, read with the optional
``rosbags`` package (``pip install solid-lidar[ros]``).

Two message types carry scans:

* ``sensor_msgs/PointCloud2`` (reader ``rosbag:pointcloud2``): any field layout, x y z first.
* Livox ``CustomMsg`` of ``livox_ros_driver`` and ``livox_ros_driver2`` (reader
  ``rosbag:livox``), how Avia, Mid-360 and HAP users record: columns x y z reflectivity tag line
  offset_time. Their definitions are registered with rosbags' type system, so a bag that does not
  embed them (old ROS 2 bags) reads too.

A scan's timestamp is the time the message was logged in the bag. Any damage to the bag (a
truncated chunk, a bad index, an undecodable message) is a :class:`ReadError` naming the bag.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from ..arrays import F32
from ..errors import ReadError
from ._common import Cloud, cloud_from_records, stack_columns


HINT: Final = "reading ROS bags and MCAP needs the optional 'rosbags' package: pip install solid-lidar[ros]"
POINTCLOUD2: Final = "sensor_msgs/msg/PointCloud2"

_LIVOX_POINT = """\
uint32 offset_time
float32 x
float32 y
float32 z
uint8 reflectivity
uint8 tag
uint8 line
"""
_LIVOX_MSG = """\
std_msgs/Header header
uint64 timebase
uint32 point_num
uint8 lidar_id
uint8[3] rsvd
CustomPoint[] points
"""
LIVOX_PACKAGES: Final = ("livox_ros_driver", "livox_ros_driver2")
LIVOX_TYPES: Final = tuple(f"{p}/msg/CustomMsg" for p in LIVOX_PACKAGES)
#: Registry name of the reader for each message type.
READER_OF: Final = {POINTCLOUD2: "rosbag:pointcloud2", **{t: "rosbag:livox" for t in LIVOX_TYPES}}

_PC2_TYPES: Final = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


def is_bag(path: Path) -> bool:
    """A ``.bag``, ``.mcap`` or ``.db3`` file, or a ROS 2 bag folder (with ``metadata.yaml``)."""
    return path.suffix.lower() in (".bag", ".mcap", ".db3") or (path.is_dir() and (path / "metadata.yaml").is_file())


def _rosbags() -> Any:
    try:
        from rosbags import highlevel
    except ImportError:
        raise ImportError(HINT) from None
    return highlevel


def livox_types() -> dict[str, Any]:
    """rosbags type definitions of both Livox drivers' ``CustomMsg`` and ``CustomPoint``."""
    from rosbags.typesys import get_types_from_msg

    types: dict[str, Any] = {}
    for pkg in LIVOX_PACKAGES:
        types.update(get_types_from_msg(_LIVOX_POINT, f"{pkg}/msg/CustomPoint"))
        types.update(get_types_from_msg(_LIVOX_MSG, f"{pkg}/msg/CustomMsg"))
    return types


def _typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.LATEST)
    ts.register(livox_types())
    return ts


def pointcloud2_to_cloud(msg: Any, where: str = "PointCloud2", xyz_only: bool = False) -> Cloud:
    """Decode a ``sensor_msgs/PointCloud2`` message object (rosbags' deserialised form)."""
    endian = ">" if msg.is_bigendian else "<"
    names: list[str] = []
    formats: list[Any] = []
    offsets: list[int] = []
    step = int(msg.point_step)
    for f in msg.fields:
        code = _PC2_TYPES.get(int(f.datatype))
        if code is None:
            raise ReadError(where, f"PointCloud2 field {f.name!r} has unknown datatype {f.datatype}")
        count = int(f.count)
        if count < 1 or int(f.offset) < 0 or int(f.offset) + count * int(code[1]) > step:
            raise ReadError(where, f"PointCloud2 field {f.name!r} (offset {f.offset}, count {count}) lies outside the {step} B point")
        names.append(str(f.name))
        formats.append((endian + code, (count,)) if count > 1 else endian + code)
        offsets.append(int(f.offset))
    h, w = int(msg.height), int(msg.width)
    if len(set(names)) != len(names):
        raise ReadError(where, f"PointCloud2 has duplicate field names ({' '.join(names)})")
    if h < 0 or w < 0 or step < 1:
        raise ReadError(where, f"PointCloud2 has height {h}, width {w}, point_step {step}")
    dt = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": step})
    buf = np.asarray(msg.data, dtype=np.uint8)
    row = int(msg.row_step)
    if row < w * step or (h > 0 and buf.size < row * (h - 1) + w * step):
        raise ReadError(where, f"PointCloud2 data has {buf.size} B, too few for {h}×{w} points of {step} B (row_step {row})")
    if row == w * step:
        rec = np.frombuffer(buf.tobytes()[: h * w * step], dtype=dt)
    else:
        rows = [np.frombuffer(buf[r * row : r * row + w * step].tobytes(), dtype=dt) for r in range(h)]
        rec = np.concatenate(rows) if rows else np.zeros(0, dtype=dt)
    return cloud_from_records(where, rec, xyz_only)


def cloud_to_pointcloud2(ts: Any, records: npt.NDArray[np.void], sec: int, frame_id: str) -> Any:
    """The ``sensor_msgs/PointCloud2`` message (of typestore ``ts``, ROS 1 or 2) that holds one
    row of points: ``records``, a little-endian structured array, each named field a column at
    its offset; stamped ``sec`` seconds. The inverse of :func:`pointcloud2_to_cloud`, for writing bags."""
    types = ts.types
    code_of = {v: k for k, v in _PC2_TYPES.items()}
    pf = types["sensor_msgs/msg/PointField"]
    fields = [pf(name=n, offset=off, datatype=code_of[dt.str[1:]], count=1) for n, (dt, off, *_) in (records.dtype.fields or {}).items()]
    hdr_t = types["std_msgs/msg/Header"]
    stamp = types["builtin_interfaces/msg/Time"](sec=sec, nanosec=0)
    # ROS 1 headers carry a sequence number, ROS 2's do not.
    hdr = hdr_t(seq=sec, stamp=stamp, frame_id=frame_id) if "seq" in hdr_t.__dataclass_fields__ else hdr_t(stamp=stamp, frame_id=frame_id)
    step, n = records.dtype.itemsize, len(records)
    return types[POINTCLOUD2](
        header=hdr, height=1, width=n, fields=fields, is_bigendian=False, point_step=step, row_step=step * n,
        data=np.frombuffer(records.tobytes(), np.uint8), is_dense=True,
    )

_LIVOX_NAMES: Final = ("offset_time", "x", "y", "z", "reflectivity", "tag", "line")
_LIVOX_COLUMNS: Final = ("x", "y", "z", "reflectivity", "tag", "line", "offset_time")


def _livox_points(raw: bytes | memoryview, cdr: bool, where: str) -> npt.NDArray[np.void]:
    """The ``points`` of a serialised Livox ``CustomMsg`` as a structured array, read in place.

    ROS 1: packed 19 B points after the header, timebase, point_num, lidar_id, rsvd and the
    array length. ROS 2 (CDR, relative alignment): the same fields aligned, points every 20 B.
    The bytes must end where the array ends (a message of another layout is refused).
    """
    raw = bytes(raw)
    if cdr:
        if len(raw) < 4:
            raise ReadError(where, "CustomMsg shorter than its CDR header")
        endian, base = ("<" if raw[1] == 1 else ">"), 4
    else:
        endian, base = "<", 0

    def aligned(pos: int, n: int) -> int:
        return pos if not cdr else base + -(-(pos - base) // n) * n

    try:
        pos = base + (8 if cdr else 12)  # stamp (ROS 1: seq too)
        (n_id,) = struct.unpack_from(endian + "I", raw, pos)
        pos = aligned(pos + 4 + n_id, 8) + 8  # frame_id, timebase
        pos = aligned(pos, 4) + 8  # point_num, lidar_id, rsvd[3]
        pos = aligned(pos, 4)
        (n,) = struct.unpack_from(endian + "I", raw, pos)
    except struct.error:
        raise ReadError(where, f"CustomMsg of {len(raw)} B ends inside its header") from None
    pos += 4
    stride = 20 if cdr else 19
    need = pos + (stride * n - (stride - 19) if n else 0)
    if not need <= len(raw) <= need + (3 if cdr else 0):
        raise ReadError(where, f"CustomMsg of {len(raw)} B does not hold its {n} points of {stride} B (need {need} B)")
    dt = np.dtype(
        {
            "names": list(_LIVOX_NAMES),
            "formats": [endian + "u4", endian + "f4", endian + "f4", endian + "f4", "u1", "u1", "u1"],
            "offsets": [0, 4, 8, 12, 16, 17, 18],
            "itemsize": stride,
        }
    )
    body = raw[pos:need] + bytes(stride - 19) if n else b""
    return np.frombuffer(body, dtype=dt, count=n)


def livox_to_cloud(raw: bytes | memoryview, cdr: bool, where: str = "CustomMsg", xyz_only: bool = False) -> Cloud:
    """Decode a serialised Livox ``CustomMsg``: columns x y z reflectivity tag line offset_time."""
    rec = _livox_points(raw, cdr, where)
    names = _LIVOX_COLUMNS[:3] if xyz_only else _LIVOX_COLUMNS
    return stack_columns([rec[n] for n in names], list(names))


class Bag:
    """The scans of one topic of a bag: log times on opening, messages decoded while iterating."""

    def __init__(self, path: Path, topic: str | None, msgtype: str | None) -> None:
        self.path = path
        self.topic = topic
        self.msgtype = msgtype
        reader, conns = self._open()
        try:
            self.topic = conns[0].topic
            self.msgtype = conns[0].msgtype
            self.times_ns = [int(t) for _, t, _ in guarded_items(path, lambda: reader.messages(connections=conns))]
        finally:
            close_reader(reader)

    @property
    def reader_name(self) -> str:
        return READER_OF[self.msgtype or POINTCLOUD2]

    def _open(self) -> tuple[Any, list[Any]]:
        reader = open_reader(self.path)
        try:
            return reader, self._connections(reader)
        except BaseException:
            close_reader(reader)
            raise

    def _connections(self, reader: Any) -> list[Any]:
        wanted = (self.msgtype,) if self.msgtype else tuple(READER_OF)
        cands = [c for c in reader.connections if c.msgtype in wanted]
        if self.topic is not None:
            cands = [c for c in cands if c.topic == self.topic]
        if not cands:
            topics = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
            want = f"topic {self.topic!r} with " if self.topic else ""
            kinds = " or ".join(sorted({t.split("/")[0] + "/" + t.split("/")[-1] for t in wanted}))
            raise ReadError(self.path, f"no {want}{kinds} messages; topics: {', '.join(topics) or 'none'}")
        topics = sorted({c.topic for c in cands})
        if len(topics) > 1:
            raise ReadError(self.path, f"several point-cloud topics ({', '.join(topics)}); pass topic=")
        if {c.msgtype for c in cands} - set(reader.typestore.fielddefs):
            reader.typestore.register(livox_types())
        return cands

    def __len__(self) -> int:
        return len(self.times_ns)

    def clouds(self, xyz_only: bool) -> Iterator[Cloud]:
        reader, conns = self._open()
        try:
            for conn, t, raw in guarded_items(self.path, lambda: reader.messages(connections=conns)):
                where = f"{self.path} [{conn.topic} @ {t}]"
                try:
                    if conn.msgtype == POINTCLOUD2:
                        yield pointcloud2_to_cloud(reader.deserialize(raw, conn.msgtype), where, xyz_only)
                    else:
                        yield livox_to_cloud(raw, reader.is2, where, xyz_only)
                except ReadError:
                    raise
                except Exception as e:
                    raise ReadError(where, f"undecodable message: {type(e).__name__}: {e}") from None
        finally:
            close_reader(reader)

    def points(self, xyz_only: bool) -> Iterator[F32]:
        for c in self.clouds(xyz_only):
            yield c.points


ODOMETRY: Final = "nav_msgs/msg/Odometry"


def read_odometry(path: Path, topic: str) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The poses of a ``nav_msgs/Odometry`` topic of a bag: each message's log time in seconds
    (the clock of the scans' times, which are their log times too) and its pose (N, 3, 4)
    ``T_world_body`` [R|t] (``pose.pose``: position and orientation)."""
    from .poses import quat_to_matrix

    reader = open_reader(path)
    try:
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns or conns[0].msgtype != ODOMETRY:
            odom = sorted({c.topic for c in reader.connections if c.msgtype == ODOMETRY})
            held = f"holds {conns[0].msgtype}" if conns else "is not in the bag"
            raise ReadError(path, f"topic {topic!r} {held}; its {ODOMETRY} topics: {', '.join(odom) or 'none'}")
        times: list[float] = []
        rows: list[list[float]] = []
        for conn, t, raw in guarded_items(path, lambda: reader.messages(connections=conns)):
            try:
                pose = reader.deserialize(raw, conn.msgtype).pose.pose
                p, q = pose.position, pose.orientation
                rows.append([p.x, p.y, p.z, q.x, q.y, q.z, q.w])
            except Exception as e:
                raise ReadError(f"{path} [{topic} @ {t}]", f"undecodable message: {type(e).__name__}: {e}") from None
            times.append(int(t) * 1e-9)
    finally:
        close_reader(reader)
    if not rows:
        raise ReadError(path, f"topic {topic!r} has no messages")
    a = np.asarray(rows, dtype=np.float64)
    P = np.zeros((len(a), 3, 4))
    P[:, :, :3] = quat_to_matrix(a[:, 3:7])
    P[:, :, 3] = a[:, :3]
    return np.asarray(times, dtype=np.float64), P


def open_reader(path: Path) -> Any:
    """rosbags' ``AnyReader`` of a bag of either ROS version, open (the Livox types registered);
    close it with :func:`close_reader`."""
    hl = _rosbags()
    try:
        reader = hl.AnyReader([path], default_typestore=_typestore())
        reader.open()
    except Exception as e:
        raise ReadError(path, f"cannot open the bag: {type(e).__name__}: {e}") from None
    return reader


def guarded_items(path: Path, start: Callable[[], Iterator[Any]]) -> Iterator[Any]:
    """The items of ``start()``, with any error of rosbags' reading turned into a :class:`ReadError`."""
    try:
        it = start()
    except Exception as e:
        raise ReadError(path, f"damaged bag: {type(e).__name__}: {e}") from None
    while True:
        try:
            item = next(it)
        except StopIteration:
            return
        except Exception as e:
            raise ReadError(path, f"damaged bag: {type(e).__name__}: {e}") from None
        yield item


def close_reader(reader: Any) -> None:
    try:
        reader.close()
    except Exception:
        pass
