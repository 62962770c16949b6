"""A reader of the node's loop topic built on Eclipse Cyclone DDS (PyPI ``cyclonedds``), not ROS.

``python tests/dds_reader.py DOMAIN TOPIC OUT SECONDS``: reads ``nav_msgs/Odometry`` samples of
the ROS 2 topic TOPIC (DDS topic ``rt`` + TOPIC, type ``nav_msgs::msg::dds_::Odometry_``) for
at most SECONDS and appends one JSON line per sample to OUT as it arrives: first ``{"ready": true}``
once the reader exists, ``{"matched": N}`` once it has matched a writer (the node's), then the
samples. Used by
tests/test_ros2.py to show that the node speaks ROS 2 on the wire, to a DDS that is not its own.
"""


import json
import sys
import time
from dataclasses import dataclass, field

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float64, int32, uint32
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration


@dataclass
class Time_(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Header_(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time_ = field(default_factory=Time_)
    frame_id: str = ""


@dataclass
class Point_(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion_(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Pose_(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point_ = field(default_factory=Point_)
    orientation: Quaternion_ = field(default_factory=Quaternion_)


@dataclass
class PoseWithCovariance_(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose_ = field(default_factory=Pose_)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)  # type: ignore[type-arg,assignment,valid-type]


@dataclass
class Vector3_(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Twist_(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3_ = field(default_factory=Vector3_)
    angular: Vector3_ = field(default_factory=Vector3_)


@dataclass
class TwistWithCovariance_(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist_ = field(default_factory=Twist_)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)  # type: ignore[type-arg,assignment,valid-type]


@dataclass
class Odometry_(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header_ = field(default_factory=Header_)
    child_frame_id: str = ""
    pose: PoseWithCovariance_ = field(default_factory=PoseWithCovariance_)
    twist: TwistWithCovariance_ = field(default_factory=TwistWithCovariance_)


def main() -> int:
    domain, topic, out, seconds = int(sys.argv[1]), sys.argv[2], sys.argv[3], float(sys.argv[4])
    dp = DomainParticipant(domain)
    t = Topic(dp, "rt" + topic, Odometry_)
    qos = Qos(Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepLast(1000))
    reader = DataReader(dp, t, qos=qos)
    end = time.monotonic() + seconds
    with open(out, "a", encoding="utf-8") as f:
        print(json.dumps({"ready": True}), file=f, flush=True)
        matched = 0
        while time.monotonic() < end:
            if not matched:
                matched = reader.get_subscription_matched_status().current_count  # type: ignore[no-untyped-call]
                if matched:
                    print(json.dumps({"matched": matched}), file=f, flush=True)
            for s in reader.take(N=100):
                if not isinstance(s, Odometry_):  # invalid samples (a writer gone) carry no data
                    continue
                p, q = s.pose.pose.position, s.pose.pose.orientation
                row = {
                    "frame_id": s.header.frame_id,
                    "child_frame_id": s.child_frame_id,
                    "stamp_ns": int(s.header.stamp.sec) * 1_000_000_000 + int(s.header.stamp.nanosec),
                    "pose": [p.x, p.y, p.z, q.x, q.y, q.z, q.w],
                    "covariance": [float(v) for v in s.pose.covariance],  # type: ignore[attr-defined]
                }
                print(json.dumps(row), file=f, flush=True)
            time.sleep(0.02)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
