"""``solid ros2 play``: publish a recording to the node at its recorded rate (no ``ros2 bag play`` needed).

Two kinds of source:

* a bag (ROS 1 ``.bag``, ROS 2 folder or ``.mcap``/``.db3``, read with ``rosbags``): its
  ``sensor_msgs/PointCloud2`` and ``nav_msgs/Odometry`` messages (``--cloud-topic`` and
  ``--odom-topic`` pick the topics; by default every topic of those types), paced by their log
  times and republished, header stamps and frames unchanged, on ``/cloud_registered_body`` and
  ``/Odometry`` (the node's default topics; ``--cloud-out``/``--odom-out`` change them);
* a folder of keyframes that ``solid detect`` reads, with ``--poses`` (and ``--timestamps``
  unless the folder has ``times.txt``): each scan becomes a PointCloud2 (x y z) in frame
  ``--cloud-frame`` and its pose an Odometry of ``--odom-frame``, stamped with its time, as a
  LiDAR-inertial odometry (FAST-LIO) would publish them.

The player waits (``--wait`` seconds) until the node subscribes, so that nothing is lost to
discovery; ``--rate`` scales the pace (2: twice as fast) and ``--max-gap`` shortens the pauses
(of a recording, or between the parts of a ``--frames`` selection). It publishes reliably (a
history of 100 messages to resend from) and, before it exits, waits (at most ``--wait`` seconds)
until the subscribers have acknowledged every message: a node subscribed with
``input_qos:=reliable`` receives all of them; one with the default sensor-data QoS (best effort,
as for a live sensor) may lose some on the way.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..arrays import F64
from ..datasets.rosbag import POINTCLOUD2, is_bag
from .node import RELIABLE_HISTORY, fill_pose, to_stamp

import rclpy
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.duration import Duration
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import PointCloud2, PointField

__all__ = ["cloud_message", "odometry_message", "play_main"]

ODOMETRY = "nav_msgs/msg/Odometry"


def cloud_message(points: Any, ns: int, frame: str) -> Any:
    """A PointCloud2 of float32 x y z (and intensity, from a fourth column) stamped ``ns``."""
    pts = np.ascontiguousarray(np.asarray(points, dtype=np.float32)[:, : min(4, np.asarray(points).shape[1])])
    m = PointCloud2()
    to_stamp(m.header.stamp, ns)
    m.header.frame_id = frame
    names = ["x", "y", "z", "intensity"][: pts.shape[1]]
    m.fields = [PointField(name=n, offset=4 * k, datatype=PointField.FLOAT32, count=1) for k, n in enumerate(names)]
    m.height, m.width = 1, pts.shape[0]
    m.is_bigendian, m.is_dense = False, True
    m.point_step = 4 * pts.shape[1]
    m.row_step = m.point_step * m.width
    m.data = pts.tobytes()
    return m


def odometry_message(T: F64, ns: int, frame: str, child: str) -> Any:
    m = Odometry()
    to_stamp(m.header.stamp, ns)
    m.header.frame_id = frame
    m.child_frame_id = child
    fill_pose(m.pose.pose, T)
    return m


def _from_bag_message(msg: Any, msgtype: str) -> Any:
    """rosbags' message object (ROS 1 or 2) → the rclpy message."""
    if msgtype == POINTCLOUD2:
        m = PointCloud2()
        m.fields = [PointField(name=f.name, offset=int(f.offset), datatype=int(f.datatype), count=int(f.count)) for f in msg.fields]
        m.height, m.width, m.is_bigendian, m.is_dense = int(msg.height), int(msg.width), bool(msg.is_bigendian), bool(msg.is_dense)
        m.point_step, m.row_step = int(msg.point_step), int(msg.row_step)
        m.data = np.asarray(msg.data, dtype=np.uint8).tobytes()
    else:
        m = Odometry()
        m.child_frame_id = msg.child_frame_id
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z = float(p.x), float(p.y), float(p.z)
        m.pose.pose.orientation.x, m.pose.pose.orientation.y = float(q.x), float(q.y)
        m.pose.pose.orientation.z, m.pose.pose.orientation.w = float(q.z), float(q.w)
        m.pose.covariance = [float(v) for v in msg.pose.covariance]
    m.header.stamp.sec, m.header.stamp.nanosec = int(msg.header.stamp.sec), int(msg.header.stamp.nanosec)
    m.header.frame_id = msg.header.frame_id
    return m


def bag_messages(path: Path, cloud_topic: str | None, odom_topic: str | None) -> Iterator[tuple[int, str, Any]]:
    """``(log time ns, "cloud"|"odom", rclpy message)`` of a bag's clouds and odometry, in log order."""
    from ..datasets.rosbag import close_reader, guarded_items, open_reader
    from ..errors import ReadError

    reader = open_reader(path)
    try:
        want = {POINTCLOUD2: cloud_topic, ODOMETRY: odom_topic}
        conns = [c for c in reader.connections if c.msgtype in want and want[c.msgtype] in (None, c.topic)]
        for kind in (POINTCLOUD2, ODOMETRY):
            if not any(c.msgtype == kind for c in conns):
                topics = ", ".join(sorted(f"{c.topic} ({c.msgtype})" for c in reader.connections)) or "none"
                named = f"topic {want[kind]!r} of " if want[kind] else ""
                raise ReadError(path, f"no {named}{kind} messages; topics: {topics}")
        for conn, t, raw in guarded_items(path, lambda: reader.messages(connections=conns)):
            kind = "cloud" if conn.msgtype == POINTCLOUD2 else "odom"
            yield int(t), kind, _from_bag_message(reader.deserialize(raw, conn.msgtype), conn.msgtype)
    finally:
        close_reader(reader)


def dataset_messages(path: Path, a: argparse.Namespace) -> Iterator[tuple[int, str, Any]]:
    """``(time ns, kind, message)`` of a keyframe folder: odometry then cloud of each scan."""
    from ..datasets import open_dataset
    from ..datasets.selection import iter_selected, parse_frames
    from ..errors import ReadError

    ds = open_dataset(path, poses=a.poses, timestamps=a.timestamps, xyz_only=False, frames=a.frames)
    if ds.poses is None:
        raise ReadError(path, "the node needs a pose per keyframe: give --poses")
    if ds.timestamps is None:
        raise ReadError(path, "no timestamps: give --timestamps (a time per scan, seconds)")
    idx = parse_frames(a.frames, len(ds)) if a.frames else list(range(len(ds)))
    P = np.asarray(ds.poses, dtype=np.float64)
    for i, pts in zip(idx, iter_selected(ds, idx)):
        ns = int(round(float(ds.timestamps[i]) * 1e9))
        T = np.eye(4)
        T[:3] = P[i]
        yield ns, "odom", odometry_message(T, ns, a.odom_frame, a.cloud_frame)
        yield ns, "cloud", cloud_message(pts, ns, a.cloud_frame)


def play_main(argv: Sequence[str]) -> int:
    ap = argparse.ArgumentParser(prog="solid ros2 play", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("source", type=Path, help="a bag, or a folder of keyframes (with --poses)")
    ap.add_argument("--rate", type=float, default=1.0, help="pace relative to the recording (default 1)")
    ap.add_argument("--max-gap", type=float, default=None, help="shorten every pause of the recording to at most this many seconds")
    ap.add_argument("--wait", type=float, default=10.0, help="seconds to wait for the node to subscribe, and at the end for its acknowledgements (default 10)")
    ap.add_argument("--cloud-topic", help="a bag's PointCloud2 topic (default: every one)")
    ap.add_argument("--odom-topic", help="a bag's Odometry topic (default: every one)")
    ap.add_argument("--cloud-out", default="/cloud_registered_body", help="topic the clouds are published on")
    ap.add_argument("--odom-out", default="/Odometry", help="topic the odometry is published on")
    ap.add_argument("--poses", help="a folder's poses file (KITTI rows, TUM, 4×4 rows)")
    ap.add_argument("--timestamps", help="a folder's timestamps file")
    ap.add_argument("--frames", help="play only these scans of a folder, e.g. 0:45,262:314")
    ap.add_argument("--cloud-frame", default="body", help="a folder's cloud frame (default body, FAST-LIO's)")
    ap.add_argument("--odom-frame", default="camera_init", help="a folder's odometry frame (default camera_init, FAST-LIO's)")
    ap.add_argument("--quiet", action="store_true")
    a, ros_args = ap.parse_known_args(list(argv))
    if not (a.rate > 0 and math.isfinite(a.rate)):
        ap.error(f"--rate must be > 0, got {a.rate}")
    if not a.source.exists():
        ap.error(f"{a.source}: no such file or folder")
    bag = is_bag(a.source)
    if not bag and a.timestamps is None and (a.source / "times.txt").is_file():
        a.timestamps = str(a.source / "times.txt")
    messages = bag_messages(a.source, a.cloud_topic, a.odom_topic) if bag else dataset_messages(a.source, a)
    rclpy.init(args=["solid_play", *ros_args])
    node = Node("solid_play")
    # Reliable: a reliable subscriber (the node with input_qos:=reliable) gets every message,
    # resent from the last 100 if lost; best-effort subscribers (sensor data) are served too.
    qos = QoSProfile(depth=RELIABLE_HISTORY, reliability=ReliabilityPolicy.RELIABLE)
    pubs = {"cloud": node.create_publisher(PointCloud2, a.cloud_out, qos), "odom": node.create_publisher(Odometry, a.odom_out, qos)}
    sent = {"cloud": 0, "odom": 0}
    try:
        deadline = time.monotonic() + a.wait
        while any(p.get_subscription_count() == 0 for p in pubs.values()) and time.monotonic() < deadline:
            time.sleep(0.05)
        missing = [p.topic_name for p in pubs.values() if p.get_subscription_count() == 0]
        if missing:
            node.get_logger().warning(f"no subscriber on {', '.join(missing)} after {a.wait:g} s; playing anyway")
        prev: int | None = None
        clock = 0.0  # seconds of the recording played, pauses shortened to --max-gap
        t0_wall = time.monotonic()
        for t, kind, msg in messages:
            if prev is None:
                t0_wall = time.monotonic()
            else:
                gap = max(0.0, (t - prev) * 1e-9)
                clock += gap if a.max_gap is None else min(gap, a.max_gap)
            prev = t
            delay = t0_wall + clock / a.rate - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            pubs[kind].publish(msg)
            sent[kind] += 1
        # The last messages must reach reliable subscribers before the publishers go.
        unacked = [p.topic_name for p in pubs.values() if not p.wait_for_all_acked(Duration(seconds=a.wait))]
        if unacked:
            node.get_logger().warning(f"messages on {', '.join(unacked)} not acknowledged after {a.wait:g} s")
        time.sleep(0.2)  # and best-effort ones, which acknowledge nothing
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    if not a.quiet:
        print(f"solid ros2 play: published {sent['cloud']} clouds and {sent['odom']} odometry messages")
    return 0
