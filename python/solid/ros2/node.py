"""The ROS 2 node (``solid ros2 run``; docs/ros2.md has the topics, parameters and layouts).

Threads: the executor's callbacks only pair each cloud with its odometry (by stamp) and put the
keyframe on a bounded queue; one worker takes keyframes off it, runs the detector, the pose graph
and every publisher. When the queue is full the oldest waiting keyframe is dropped (the newest
says where the robot is now), logged and counted; the counts go out on ``~/status``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import _solid
from ..arrays import F32, F64
from ..config import PipelineConfig
from ..datasets.poses import matrix_to_quat, quat_to_matrix
from ..datasets.rosbag import pointcloud2_to_cloud
from ..errors import ReadError
from ..pipeline import DEFAULT_FOV_CENTER, input_points
from .core import HINT, config_from_parameters, loop_frame, parameter_defaults, placement, stamp_ns

try:
    import rclpy
    from geometry_msgs.msg import Point, Pose, PoseStamped, PoseWithCovarianceStamped, TransformStamped
    from nav_msgs.msg import Odometry, Path as PathMsg
    from rcl_interfaces.msg import ParameterDescriptor
    from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
    from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import PointCloud2
    from std_msgs.msg import ColorRGBA, String
    from std_srvs.srv import Trigger
    from visualization_msgs.msg import Marker, MarkerArray
except ImportError as e:  # pragma: no cover - the [ros2] extra is not installed
    raise ImportError(f"{HINT} ({e})") from None

__all__ = ["INPUT_QOS", "NODE_PARAMETERS", "RELIABLE_HISTORY", "SolidNode", "input_qos", "run"]

#: The node's own parameters (everything else is the pipeline configuration's): name → (default, doc).
NODE_PARAMETERS: dict[str, tuple[Any, str]] = {
    "preset": ("", "sensor preset whose defaults the configuration starts from (`solid presets`); or give config"),
    "config": ("", "a configuration file (`solid config dump`) to start from instead of a preset"),
    "cloud_topic": ("/cloud_registered_body", "keyframe clouds (sensor_msgs/PointCloud2) in the odometry's child frame"),
    "odom_topic": ("/Odometry", "their poses (nav_msgs/Odometry), matched to the clouds by stamp"),
    "map": ("", "a saved map (.soliddb): relocalization mode, the session is placed in it"),
    "save_file": ("solid_session.soliddb", "where the ~/save_map service writes the map"),
    "map_frame": ("map", "frame of the corrected trajectory, map -> odom and the markers"),
    "queue_size": (10, "keyframes waiting for the detector before the oldest is dropped"),
    "input_qos": (
        "sensor_data",
        "QoS of the cloud and odometry subscriptions: sensor_data (best effort, for live sensors) or reliable "
        "(recordings played back: nothing lost on the way; the publisher must be reliable)",
    ),
    "robust": ("gnc-tls", "the pose-graph back-end's treatment of loop edges (solid.slam.ROBUST_SCHEMES)"),
}

#: The values of the parameter input_qos.
INPUT_QOS = ("sensor_data", "reliable")
#: Messages a reliable input (and ``solid ros2 play``'s publishers) keeps for resending: 40 s of
#: keyframes at 2.5 a second, a bounded memory for large clouds.
RELIABLE_HISTORY = 100

#: Odometry messages kept for pairing, and clouds waiting for their odometry.
_ODOM_KEPT = 400
_PENDING_CLOUDS = 20


def _latched(depth: int = 1) -> QoSProfile:
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _reliable(depth: int) -> QoSProfile:
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE)


def input_qos(kind: str) -> QoSProfile:
    """The QoS of the node's inputs (the parameter ``input_qos``).

    ``sensor_data``: best effort and volatile, as a sensor driver publishes (a history of 20 rather
    than ROS's 5: a moment of a busy machine between two callbacks does not lose a keyframe); what
    the middleware loses stays lost. ``reliable``: reliable and volatile, a history of
    :data:`RELIABLE_HISTORY`: every message a reliable publisher sends after it has matched the
    node arrives (the middleware resends what is lost); a best-effort publisher is incompatible
    (rclpy warns of it). The overload policy (the bounded queue) is the same for both."""
    if kind == "sensor_data":
        return QoSProfile(depth=20, reliability=ReliabilityPolicy.BEST_EFFORT, durability=DurabilityPolicy.VOLATILE)
    if kind == "reliable":
        return QoSProfile(depth=RELIABLE_HISTORY, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
    raise _solid.ConfigError(f"input_qos must be one of {', '.join(INPUT_QOS)}, got {kind!r}")


def msg_stamp_ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def to_stamp(msg_stamp: Any, ns: int) -> Any:
    msg_stamp.sec = ns // 1_000_000_000
    msg_stamp.nanosec = ns % 1_000_000_000
    return msg_stamp


def pose_matrix(pose: Any) -> F64:
    """geometry_msgs/Pose → 4×4."""
    q, p = pose.orientation, pose.position
    T = np.eye(4)
    T[:3, :3] = quat_to_matrix(np.array([[q.x, q.y, q.z, q.w]]))[0]
    T[:3, 3] = (p.x, p.y, p.z)
    return T


def fill_pose(pose: Any, T: F64) -> Any:
    """4×4 → geometry_msgs/Pose (in place)."""
    qx, qy, qz, qw = (float(v) for v in matrix_to_quat(T[None, :3, :3])[0])
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in T[:3, 3])
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = qx, qy, qz, qw
    return pose


def covariance_list(cov: F64 | None) -> list[float]:
    """A 6×6 covariance (translation first, ROS's order) as the 36 row-major values; unknown: -1
    first (ROS's convention), the rest 0."""
    if cov is None:
        return [-1.0] + [0.0] * 35
    return [float(v) for v in np.asarray(cov, dtype=np.float64).reshape(36)]


def rotation_first_to_ros(cov: F64) -> F64:
    """A covariance in (rotation, translation) order (GTSAM's, MapAnchor's) in ROS's (translation, rotation)."""
    k = [3, 4, 5, 0, 1, 2]
    return np.asarray(cov)[np.ix_(k, k)]


@dataclass
class Keyframe:
    stamp_ns: int
    cloud: Any  # sensor_msgs/PointCloud2
    T_odom: F64
    received: float  # time.monotonic() when the later of cloud and odometry arrived


@dataclass
class Counts:
    clouds: int = 0
    odometry: int = 0
    keyframes: int = 0
    skipped: int = 0  # closer than input.subsample_m to the previous keyframe
    dropped: int = 0  # overload: the oldest waiting keyframe dropped
    unpaired: int = 0  # no odometry with the cloud's stamp
    rejected: int = 0  # no x/y/z, unknown frame, stamp out of order
    loops: int = 0
    map_loops: int = 0
    optimizations: int = 0  # the back-end's runs, and how long the last took
    backend_ms: float | None = None
    latency_ms: list[float] = field(default_factory=list)
    step_ms: list[float] = field(default_factory=list)  # the detector's step alone


class SolidNode(Node):
    """The node; ``stop()`` ends its worker. See the module docstring and docs/ros2.md."""

    def __init__(self, name: str = "solid") -> None:
        super().__init__(name, automatically_declare_parameters_from_overrides=False)
        dyn = ParameterDescriptor(dynamic_typing=True)
        for pname, (default, doc) in NODE_PARAMETERS.items():
            self.declare_parameter(pname, default, ParameterDescriptor(description=doc))
        preset = self.get_parameter("preset").value or None
        cfg_file = self.get_parameter("config").value or None
        base = PipelineConfig.load(cfg_file) if cfg_file else None
        map_file = self.get_parameter("map").value or None
        self.map_db = _solid.Database.load(map_file) if map_file else None
        if base is not None and preset is not None and preset != base.preset_name:
            raise _solid.ConfigError(f"preset {preset} contradicts the preset {base.preset_name!r} of {cfg_file}")
        if base is None and preset is None and self.map_db is not None:
            # As `solid detect --map`: the map's own configuration (its preset's when it is one).
            preset = next((n for n, c in _solid.presets().items() if c == self.map_db.config), None)
            if preset is None:
                base = PipelineConfig(descriptor=self.map_db.config, detector=_solid.DetectorConfig())
        defaults = parameter_defaults(preset, base)
        for pname, v in defaults.items():
            self.declare_parameter(pname, v, dyn)
        values = {p: self.get_parameter(p).value for p in defaults}
        self.config = config_from_parameters(preset, values, base)
        if self.map_db is not None and self.map_db.config != self.config.descriptor:
            raise _solid.ConfigError(f"{map_file} was built with {self.map_db.config!r}; the parameters ask for {self.config.descriptor!r}")
        self.queue_size = int(self.get_parameter("queue_size").value)
        if self.queue_size < 1:
            raise _solid.ConfigError(f"queue_size must be >= 1, got {self.queue_size}")
        self.input_qos = str(self.get_parameter("input_qos").value)
        input_qos(self.input_qos)  # a bad value stops the node before anything starts
        self.map_frame = str(self.get_parameter("map_frame").value)
        self.robust = str(self.get_parameter("robust").value)
        from ..slam import ROBUST_SCHEMES

        if self.robust not in ROBUST_SCHEMES:
            raise _solid.ConfigError(f"robust must be one of {', '.join(ROBUST_SCHEMES)}, got {self.robust!r}")
        opts = self.config.input
        self.fov_center = DEFAULT_FOV_CENTER if opts.fov is not None and opts.fov_center is None else opts.fov_center
        if self.map_db is not None:
            self.detector = _solid.LoopDetector.from_database(self.map_db, detector=self.config.detector)
        else:
            self.detector = _solid.LoopDetector(self.config.descriptor, detector=self.config.detector)
        self.map_size = int(self.detector.session_start)
        self.backend_proc: Any = None
        if self.map_db is None:
            try:
                from ..slam import require_gtsam

                require_gtsam()
            except ImportError:
                self.get_logger().warning('no pose-graph back-end (pip install "solid-lidar[slam]"): ~/path is the odometry, map -> odom the identity')
            else:
                import multiprocessing

                from .backend import serve

                ctx = multiprocessing.get_context("spawn")
                self.backend_conn, child = ctx.Pipe()
                self.backend_proc = ctx.Process(target=serve, args=(child, self.robust), name="solid-backend", daemon=True)
                self.backend_proc.start()
                child.close()

        # State shared between the callbacks and the worker (under self.lock).
        self.lock = threading.Condition()
        self.queue: deque[Keyframe] = deque()
        self.counts = Counts()
        self.odoms: OrderedDict[int, tuple[F64, str, str]] = OrderedDict()
        self.pending: OrderedDict[int, tuple[Any, float]] = OrderedDict()
        self.odom_frame: str | None = None
        self.body_frame: str | None = None
        self.stopping = False
        self.last_error: str | None = None
        self.logged: dict[str, float] = {}  # kind of error -> when last logged
        # The worker's own state.
        self.stamps: list[int] = []
        self.odom_poses: list[F64] = []
        self.traj = threading.Lock()  # guards corrected and T_map_odom (worker and back-end thread)
        self.corrected: F64 = np.zeros((0, 4, 4))
        self.job: tuple[F64, list[Any]] | None = None
        self.T_map_odom: F64 | None = None if self.map_db is not None else np.eye(4)
        self.support: dict[str, Any] = {}
        self.loop_list: list[Any] = []
        self.last_pose: F64 | None = None
        self.travelled = 0.0
        self.kept_bin = -1
        self.last_stamp: int | None = None

        sensor = MutuallyExclusiveCallbackGroup()
        qos = input_qos(self.input_qos)
        self.create_subscription(PointCloud2, self.get_parameter("cloud_topic").value, self.on_cloud, qos, callback_group=sensor)
        self.create_subscription(Odometry, self.get_parameter("odom_topic").value, self.on_odometry, qos, callback_group=sensor)
        self.pub_loops = self.create_publisher(Odometry, "~/loops", _reliable(100))
        self.pub_path = self.create_publisher(PathMsg, "~/path", _latched())
        self.pub_tf = self.create_publisher(TransformStamped, "~/map_to_odom", _latched())
        self.pub_markers = self.create_publisher(MarkerArray, "~/markers", _latched())
        self.pub_status = self.create_publisher(String, "~/status", _latched(10))
        self.pub_placement = self.create_publisher(PoseWithCovarianceStamped, "~/placement", _latched())
        self.pub_config = self.create_publisher(String, "~/config", _latched())
        self.pub_config.publish(String(data=self.config.dumps()))
        self.create_service(Trigger, "~/save_map", self.on_save, callback_group=MutuallyExclusiveCallbackGroup())
        self.create_timer(1.0, self.publish_status, callback_group=MutuallyExclusiveCallbackGroup())
        self.worker = threading.Thread(target=self._work, name="solid-detector", daemon=True)
        self.worker.start()
        self.backend_thread = threading.Thread(target=self._backend, name="solid-backend", daemon=True)
        if self.backend_proc is not None:
            self.backend_thread.start()
        mode = f"relocalization in {map_file} ({self.map_size} places)" if self.map_db is not None else "loops within the session"
        self.get_logger().info(
            f"solid {_solid.__version__}: {mode}; preset {self.config.preset_name}; clouds on {self.get_parameter('cloud_topic').value}, "
            f"odometry on {self.get_parameter('odom_topic').value} ({self.input_qos} QoS); queue of {self.queue_size}"
        )

    # ---- callbacks (never block: pair, queue, return) -----------------------------------------

    def _reject(self, message: str, kind: str) -> None:
        """Count and log a message the node cannot use (lock held): each kind of error at most
        every 5 s, so that a stream of bad messages does not flood the log."""
        self.counts.rejected += 1
        self.last_error = message
        now = time.monotonic()
        if now - self.logged.get(kind, -math.inf) >= 5.0:
            self.logged[kind] = now
            self.get_logger().error(message)

    def on_odometry(self, msg: Any) -> None:
        ns = msg_stamp_ns(msg.header.stamp)
        T = pose_matrix(msg.pose.pose)
        with self.lock:
            self.counts.odometry += 1
            if self.odom_frame is None:
                self.odom_frame, self.body_frame = msg.header.frame_id, msg.child_frame_id
            elif (msg.header.frame_id, msg.child_frame_id) != (self.odom_frame, self.body_frame):
                self._reject(
                    f"odometry in frame {msg.header.frame_id!r} of {msg.child_frame_id!r}: unknown frames (the first odometry was "
                    f"{self.odom_frame!r} of {self.body_frame!r}); send one odometry source",
                    "odometry frames",
                )
                return
            self.odoms[ns] = (T, msg.header.frame_id, msg.child_frame_id)
            while len(self.odoms) > _ODOM_KEPT:
                self.odoms.popitem(last=False)
            waiting = self.pending.pop(ns, None)
            if waiting is not None:
                self._enqueue(Keyframe(ns, waiting[0], T, time.monotonic()))

    def on_cloud(self, msg: Any) -> None:
        ns = msg_stamp_ns(msg.header.stamp)
        with self.lock:
            self.counts.clouds += 1
            if self.body_frame is not None and msg.header.frame_id != self.body_frame:
                self._reject(
                    f"cloud in frame {msg.header.frame_id!r}, but the odometry gives the pose of {self.body_frame!r}: unknown frame "
                    "(send the clouds in the odometry's child frame, e.g. FAST-LIO's /cloud_registered_body, not /cloud_registered)",
                    "cloud frame",
                )
                return
            odom = self.odoms.get(ns)
            if odom is not None:
                self._enqueue(Keyframe(ns, msg, odom[0], time.monotonic()))
                return
            self.pending[ns] = (msg, time.monotonic())
            while len(self.pending) > _PENDING_CLOUDS:
                old, _ = self.pending.popitem(last=False)
                self.counts.unpaired += 1
                self.get_logger().warning(
                    f"no odometry with the stamp of the cloud at {old / 1e9:.9f} s: dropped (clouds and odometry are matched by exact stamp)",
                    throttle_duration_sec=5.0,
                )

    def _enqueue(self, kf: Keyframe) -> None:
        """Put a keyframe on the queue (lock held); when full, the oldest waiting one is dropped."""
        if len(self.queue) >= self.queue_size:
            old = self.queue.popleft()
            self.counts.dropped += 1
            self.get_logger().warning(
                f"overload: the detector is {self.queue_size} keyframes behind; dropped the keyframe at {old.stamp_ns / 1e9:.9f} s "
                f"({self.counts.dropped} dropped so far)",
                throttle_duration_sec=2.0,
            )
        self.queue.append(kf)
        self.lock.notify_all()  # the worker and the back-end thread wait on this condition

    def on_save(self, request: Any, response: Any) -> Any:
        path = Path(str(self.get_parameter("save_file").value))
        try:
            from ..commands import clip_record

            db = self.detector.database
            db.metadata = json.dumps({"clip": clip_record(self.config.input, self.fov_center)})
            db.save(path)
            response.success = True
            response.message = f"saved {len(db)} places to {path.resolve()}"
        except Exception as e:  # the service reports every failure to its caller
            response.success = False
            response.message = f"could not save the map to {path}: {type(e).__name__}: {e}"
        self.get_logger().info(response.message)
        return response

    # ---- the worker -------------------------------------------------------------------------------

    def stop(self) -> None:
        with self.lock:
            self.stopping = True
            self.lock.notify_all()
        if self.backend_proc is not None:
            self.backend_proc.kill()  # an optimisation in progress is of no use any more
            self.backend_proc.join(timeout=0.3)
        self.worker.join(timeout=0.5)

    def _work(self) -> None:
        while True:
            with self.lock:
                while not self.queue and not self.stopping:
                    self.lock.wait()
                if self.stopping:
                    return
                kf = self.queue.popleft()
            try:
                self._step(kf)
            except Exception as e:
                if self.stopping or not self.context.ok():
                    return  # shutting down (Ctrl-C): the step's publications had nowhere to go
                if isinstance(e, (ReadError, _solid.SolidError, ValueError)):
                    with self.lock:
                        self._reject(f"keyframe at {kf.stamp_ns / 1e9:.9f} s: {e}", re.sub(r"[0-9.]+", "#", str(e)))  # the kind: the message, numbers aside
                else:  # a bug: say so, keep serving
                    self.get_logger().error(f"keyframe at {kf.stamp_ns / 1e9:.9f} s: {type(e).__name__}: {e}")

    def _step(self, kf: Keyframe) -> None:
        if self.last_stamp is not None and kf.stamp_ns <= self.last_stamp:
            raise ValueError(
                f"stamp out of order: {kf.stamp_ns / 1e9:.9f} s is not after the previous keyframe's {self.last_stamp / 1e9:.9f} s "
                "(a bag played twice, or clocks reset?); keyframe ignored"
            )
        opts = self.config.input
        if opts.subsample_m is not None:
            # As the offline input.subsample_m: a keyframe where the path travelled reaches the
            # next multiple of subsample_m (the first always).
            if self.last_pose is not None:
                self.travelled += float(np.linalg.norm(kf.T_odom[:3, 3] - self.last_pose[:3, 3]))
            self.last_pose = kf.T_odom
            k = math.floor(self.travelled / opts.subsample_m + 1e-9)
            if self.stamps and k <= self.kept_bin:
                self.last_stamp = kf.stamp_ns
                with self.lock:
                    self.counts.skipped += 1
                return
            self.kept_bin = k
        where = f"cloud at {kf.stamp_ns / 1e9:.9f} s"
        pts: F32 = pointcloud2_to_cloud(kf.cloud, where, xyz_only=True).points
        xyz = input_points(pts, opts, self.fov_center)
        t0 = time.monotonic()
        d = self.detector.detect(xyz, kf.stamp_ns * 1e-9, kf.T_odom[:3])
        step_ms = (time.monotonic() - t0) * 1e3
        self.last_stamp = kf.stamp_ns
        self.stamps.append(kf.stamp_ns)
        self.odom_poses.append(kf.T_odom)
        lp = d.loop
        # The step's loop, then the loops into the map that its placement released (held since
        # their own keyframes: Detection.released).
        found = ([lp] if lp is not None else []) + list(getattr(d, "released", ()))
        for x in found:
            self.loop_list.append(x)
            with self.lock:
                self.counts.loops += 1
                self.counts.map_loops += int(int(x.candidate) < self.map_size)
            self.publish_loop(x)
        if any(int(x.candidate) < self.map_size for x in found) or getattr(d, "placement", None) is not None:
            placed = placement(self.detector, lp if lp is not None and int(lp.candidate) < self.map_size else None, kf.T_odom)
            if placed is not None:
                self.T_map_odom, self.support = placed
                self.support["stamp_ns"] = kf.stamp_ns
                self.publish_placement(kf.stamp_ns)
        self.update_trajectory(new_loop=lp is not None and int(lp.candidate) >= self.map_size and lp.pose is not None)
        self.publish_trajectory(kf.stamp_ns)
        if lp is not None or len(self.stamps) % 10 == 1:
            self.publish_markers(kf.stamp_ns)
        with self.lock:
            self.counts.keyframes += 1
            self.counts.latency_ms.append((time.monotonic() - kf.received) * 1e3)
            self.counts.step_ms.append(step_ms)
        self.publish_status()

    # ---- the back-end and what is published ---------------------------------------------------

    def update_trajectory(self, new_loop: bool) -> None:
        """The corrected keyframe poses in the map frame: the pose graph's latest optimum, the
        later keyframes chained on by odometry (map → odom of the last optimised keyframe). A
        loop within the session hands the graph to the back-end, which optimises behind."""
        with self.traj:
            n = self.corrected.shape[0]
            if self.T_map_odom is not None:
                if self.map_db is not None:
                    self.corrected = self.T_map_odom @ np.stack(self.odom_poses)
                else:
                    self.corrected = np.concatenate([self.corrected, self.T_map_odom @ np.stack(self.odom_poses[n:])])
        if new_loop and self.backend_proc is not None:
            from .backend import loop_record

            with self.lock:
                # Only the latest graph waits: the back-end never falls behind by more than one.
                self.job = (np.stack(self.odom_poses), [loop_record(lp) for lp in self.loop_list])
                self.lock.notify_all()

    def _backend(self) -> None:
        """Send the latest graph to the back-end's process, take its optimum in."""
        while True:
            with self.lock:
                while self.job is None and not self.stopping:
                    self.lock.wait()
                if self.stopping:
                    return
                job, self.job = self.job, None
            assert job is not None
            t0 = time.monotonic()
            try:
                self.backend_conn.send(job)
                optimum = self.backend_conn.recv()
            except (EOFError, OSError, BrokenPipeError):
                if not self.stopping:
                    self.get_logger().error("the pose-graph back-end's process ended; the path is no longer corrected")
                return
            P = job[0]
            n = len(P)
            with self.traj:
                self.T_map_odom = optimum[-1] @ np.linalg.inv(P[-1])
                m = self.corrected.shape[0]
                later = np.stack(self.odom_poses[n:m]) if m > n else np.zeros((0, 4, 4))
                self.corrected = np.concatenate([optimum, self.T_map_odom @ later])
            with self.lock:
                self.counts.optimizations += 1
                self.counts.backend_ms = round((time.monotonic() - t0) * 1e3, 1)
            ns = self.stamps[n - 1]
            try:
                self.publish_trajectory(ns)
                self.publish_markers(ns)
            except Exception:
                if self.stopping or not self.context.ok():
                    return
                raise

    def _header(self, header: Any, ns: int, frame: str) -> Any:
        to_stamp(header.stamp, ns)
        header.frame_id = frame
        return header

    def publish_loop(self, lp: Any) -> None:
        q, c = int(lp.query), int(lp.candidate)
        q_ns = self.stamps[q - self.map_size]
        if c >= self.map_size:
            c_ns: int | None = self.stamps[c - self.map_size]
            c_name = loop_frame("keyframe", c - self.map_size, c_ns)
        else:
            c_ns = stamp_ns(float(self.detector.map.timestamps[c]))
            c_name = loop_frame("map", c, c_ns)
        m = Odometry()
        self._header(m.header, q_ns, loop_frame("keyframe", q - self.map_size, q_ns))
        m.child_frame_id = c_name
        if lp.pose is not None:
            fill_pose(m.pose.pose, np.asarray(lp.pose))
            m.pose.covariance = covariance_list(np.linalg.inv(np.asarray(lp.information)))
        else:
            m.pose.pose.orientation.w = 1.0
            m.pose.covariance = covariance_list(None)
        self.pub_loops.publish(m)

    def publish_placement(self, ns: int) -> None:
        assert self.T_map_odom is not None
        m = PoseWithCovarianceStamped()
        self._header(m.header, ns, self.map_frame)
        fill_pose(m.pose.pose, self.T_map_odom)
        cov = self.support.get("covariance")
        m.pose.covariance = covariance_list(None if cov is None else rotation_first_to_ros(cov))
        self.pub_placement.publish(m)
        self.get_logger().info(
            f"placed in the map at {ns / 1e9:.3f} s by {self.support['loops']} loop(s): odom origin at "
            f"({self.T_map_odom[0, 3]:.2f}, {self.T_map_odom[1, 3]:.2f}, {self.T_map_odom[2, 3]:.2f})",
            throttle_duration_sec=10.0,
        )

    def publish_trajectory(self, ns: int) -> None:
        # Built and published under the lock: the worker's and the back-end's publications
        # leave in the order of what they publish.
        with self.traj:
            self._publish_trajectory(ns, self.corrected, self.T_map_odom)

    def _publish_trajectory(self, ns: int, corrected: F64, Tm: F64 | None) -> None:
        if Tm is None:
            return
        path = PathMsg()
        self._header(path.header, ns, self.map_frame)
        for k, T in enumerate(corrected):
            ps = PoseStamped()
            self._header(ps.header, self.stamps[k], self.map_frame)
            fill_pose(ps.pose, T)
            path.poses.append(ps)
        self.pub_path.publish(path)
        tf = TransformStamped()
        self._header(tf.header, ns, self.map_frame)
        tf.child_frame_id = self.odom_frame or "odom"
        qx, qy, qz, qw = (float(v) for v in matrix_to_quat(Tm[None, :3, :3])[0])
        tf.transform.translation.x, tf.transform.translation.y, tf.transform.translation.z = (float(v) for v in Tm[:3, 3])
        tf.transform.rotation.x, tf.transform.rotation.y, tf.transform.rotation.z, tf.transform.rotation.w = qx, qy, qz, qw
        self.pub_tf.publish(tf)

    def _position(self, place: int, corrected: F64) -> Point | None:
        """A place's position in the map frame (a map place's stored pose, a keyframe's corrected one)."""
        if place < self.map_size:
            T = np.asarray(self.detector.map.poses[place])
            t = T[:3, 3]
        elif place - self.map_size < len(corrected):
            t = corrected[place - self.map_size][:3, 3]
        else:
            return None
        if not np.isfinite(t).all():
            return None
        return Point(x=float(t[0]), y=float(t[1]), z=float(t[2]))

    def publish_markers(self, ns: int) -> None:
        with self.traj:
            self._publish_markers(ns, self.corrected)

    def _publish_markers(self, ns: int, corrected: F64) -> None:
        places = Marker()
        self._header(places.header, ns, self.map_frame)
        places.ns, places.id, places.type, places.action = "places", 0, Marker.SPHERE_LIST, Marker.ADD
        places.scale.x = places.scale.y = places.scale.z = 0.3
        places.color = ColorRGBA(r=0.2, g=0.6, b=1.0, a=0.8)
        places.pose.orientation.w = 1.0
        for k in range(len(corrected)):
            p = self._position(self.map_size + k, corrected)
            if p is not None:
                places.points.append(p)
        edges = Marker()
        self._header(edges.header, ns, self.map_frame)
        edges.ns, edges.id, edges.type, edges.action = "loops", 0, Marker.LINE_LIST, Marker.ADD
        edges.scale.x = 0.08
        edges.color = ColorRGBA(r=1.0, g=0.3, b=0.1, a=1.0)
        edges.pose.orientation.w = 1.0
        for lp in list(self.loop_list):
            a, b = self._position(int(lp.query), corrected), self._position(int(lp.candidate), corrected)
            if a is not None and b is not None:
                edges.points.extend([a, b])
        arr = MarkerArray()
        arr.markers = [places, edges]
        self.pub_markers.publish(arr)

    def status(self) -> dict[str, Any]:
        with self.lock:
            c = self.counts
            timings = {name: _summary(getattr(c, name)) for name in ("latency_ms", "step_ms")}
            doc: dict[str, Any] = {
                "clouds": c.clouds,
                "odometry": c.odometry,
                "keyframes": c.keyframes,
                "skipped": c.skipped,
                "dropped": c.dropped,
                "unpaired": c.unpaired,
                "rejected": c.rejected,
                "loops": c.loops,
                "map_loops": c.map_loops,
                "optimizations": c.optimizations,
                "backend_ms": c.backend_ms,
                "pending": len(self.pending),
                "queued": len(self.queue),
                "queue_size": self.queue_size,
                **timings,
                "placed": None,
                "last_error": self.last_error,
            }
        if self.map_db is not None and self.T_map_odom is not None:
            s = self.support
            doc["placed"] = {"stamp": s.get("stamp_ns", 0) / 1e9, "loops": s.get("loops"), "metres": s.get("metres")}
        return doc

    def publish_status(self) -> None:
        self.pub_status.publish(String(data=json.dumps(self.status())))


def _summary(ms: list[float]) -> dict[str, float] | None:
    """Last, median, 95th percentile and largest of a list of milliseconds (None when empty)."""
    if not ms:
        return None
    a = np.asarray(ms)
    return {"last": round(float(a[-1]), 1), "median": round(float(np.median(a)), 1), "p95": round(float(np.percentile(a, 95)), 1), "max": round(float(a.max()), 1)}


def _list_parameters() -> str:
    lines = ["node parameters:"]
    lines += [f"  {k} (default {v[0]!r}): {v[1]}" for k, v in NODE_PARAMETERS.items()]
    lines.append("configuration parameters (the avia preset's defaults shown; the same tables as `solid config dump`):")
    lines += [f"  {k}: {json.dumps(v)}" for k, v in parameter_defaults("avia").items()]
    return "\n".join(lines)


def run(argv: Sequence[str]) -> int:
    """``solid ros2 run [--list-parameters] [--ros-args ...]``: run the node until Ctrl-C (SIGINT)
    or SIGTERM."""
    argv = list(argv)
    ros_args = argv[argv.index("--ros-args") :] if "--ros-args" in argv else []
    own = argv[: len(argv) - len(ros_args)]
    ap = argparse.ArgumentParser(
        prog="solid ros2 run",
        description="The SOLiD loop-closure node (docs/ros2.md). ROS arguments follow --ros-args, e.g. "
        "--ros-args -p preset:=avia -p cloud_topic:=/cloud_registered_body --params-file solid.yaml",
    )
    ap.add_argument("--list-parameters", action="store_true", help="print every parameter with its default and exit")
    a = ap.parse_args(own)
    if a.list_parameters:
        print(_list_parameters())
        return 0
    # No DDS type objects (see fastdds.xml) unless the user has a Fast DDS profile of their own.
    os.environ.setdefault("FASTDDS_DEFAULT_PROFILES_FILE", str(Path(__file__).with_name("fastdds.xml")))
    rclpy.init(args=["solid", *ros_args])
    node: SolidNode | None = None
    try:
        node = SolidNode()
        executor = MultiThreadedExecutor(num_threads=3)
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (_solid.ConfigError, _solid.DatabaseError, OSError, ValueError) as e:
        print(f"solid ros2 run: error: {e}", file=sys.stderr)
        return 1
    finally:
        if node is not None:
            node.stop()
            node.destroy_node()
        if rclpy.ok():
            rclpy.try_shutdown()
    return 0

