"""What the ROS 2 node needs that is not ROS: its parameters mapped onto the pipeline
configuration's tables, the layout of its loop messages, and the placement of a session in a
prior map (re-exported by :mod:`solid.ros2`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .. import _solid
from ..arrays import F64
from ..config import InputOptions, PipelineConfig

__all__ = ["HINT", "SECTIONS", "config_from_parameters", "loop_frame", "parameter_defaults", "parse_loop_frame", "placement", "stamp_ns"]

HINT = 'the ROS 2 node needs the optional ROS 2 wheels: pip install "solid-lidar[ros2]"'

#: The sections of the pipeline configuration the node takes as parameters (``section.field``;
#: the detector's ``registration`` and ``gate`` one level deeper). The evaluation section scores
#: offline runs against ground truth and has no place in a node.
SECTIONS = ("descriptor", "detector", "input")


def _flatten(prefix: str, d: dict[str, Any], out: dict[str, Any]) -> None:
    for k, v in d.items():
        if isinstance(v, dict):
            _flatten(f"{prefix}{k}.", v, out)
        else:
            out[prefix + k] = v


def parameter_defaults(preset: str | None, base: PipelineConfig | None = None) -> dict[str, Any]:
    """Every configuration parameter of the node (``descriptor.n_range``, ``detector.gate.min_fitness``,
    ``input.fov``, ...) and its default: ``base``'s values, else the preset's. The names and
    defaults are those of :meth:`PipelineConfig.to_dict`, itself read from the core's parameter
    tables (``solid config dump`` writes the same). ``None`` is a default that is not set."""
    cfg = base if base is not None else PipelineConfig.preset(preset) if preset is not None else None
    if cfg is None:
        raise _solid.ConfigError("give the parameter preset (see `solid presets`) or config (a file from `solid config dump`)")
    doc = cfg.to_dict()
    out: dict[str, Any] = {}
    for sec in SECTIONS:
        _flatten(f"{sec}.", doc[sec], out)
    return out


def config_from_parameters(preset: str | None, values: dict[str, Any], base: PipelineConfig | None = None) -> PipelineConfig:
    """The pipeline configuration of the parameters ``values`` (``section.field`` → value, as
    :func:`parameter_defaults` names them; ``None`` for one not set), on top of ``base`` or the
    preset. Checked by the core as a configuration file is: a value out of range or of the wrong
    type is a ConfigError naming it."""
    defaults = parameter_defaults(preset, base)
    unknown = sorted(set(values) - set(defaults))
    if unknown:
        raise _solid.ConfigError(f"unknown parameters {', '.join(unknown)} (see `solid ros2 run --list-parameters`)")
    doc: dict[str, Any] = {"preset": base.preset_name if base is not None else preset}
    start = base if base is not None else PipelineConfig.preset(str(preset))
    tree = {sec: dict(start.to_dict()[sec]) for sec in SECTIONS}
    for name, v in values.items():
        sec, *path = name.split(".")
        node = tree[sec]
        for key in path[:-1]:
            child = dict(node[key])
            node[key] = child
            node = child
        node[path[-1]] = v
    doc.update(tree)
    if tree["input"].get("frames") is not None:
        raise _solid.ConfigError("input.frames selects scans of a recording; a node takes every keyframe it is sent (use input.subsample_m)")
    cfg = PipelineConfig.from_dict(doc, "parameters")
    InputOptions(**cfg.input.to_dict())
    return cfg


def loop_frame(kind: str, place: int, stamp_ns: int | None) -> str:
    """The frame name that identifies one side of a loop in its message (docs/ros2.md):
    ``"keyframe/ID/SEC.NANOSEC"`` (``kind`` "keyframe") or ``"map/ID/SEC.NANOSEC"`` (a place of
    the prior map); the stamp is left empty when the place has none."""
    if stamp_ns is None:
        return f"{kind}/{place}/"
    return f"{kind}/{place}/{stamp_ns // 1_000_000_000}.{stamp_ns % 1_000_000_000:09d}"


def parse_loop_frame(frame: str) -> tuple[str, int, int | None]:
    """``(kind, id, stamp in ns or None)`` of a :func:`loop_frame` name."""
    kind, place, stamp = frame.split("/")
    if not stamp:
        return kind, int(place), None
    sec, nsec = stamp.split(".")
    return kind, int(place), int(sec) * 1_000_000_000 + int(nsec)


def stamp_ns(seconds: float) -> int | None:
    """A time in seconds as whole nanoseconds (None when not finite)."""
    return int(round(seconds * 1e9)) if math.isfinite(seconds) else None


def placement(detector: Any, map_loop: Any | None, T_odom_query: F64 | None) -> tuple[F64, dict[str, Any]] | None:
    """Where the session is placed in the prior map: ``(T_map_odom 4×4, support)``, or None
    before it is placed. ``support`` holds ``loops`` (how many loops support it), ``metres`` and
    ``covariance`` (6×6, rotation first, or None) when known.

    The detector's own anchor (``LoopDetector.map_anchor``: mutually consistent loops into the
    map, docs/loops.md) is used when the core provides one; until then the placement is that of
    the latest verified loop into the map: ``T_map_odom = T_map_candidate · T_loop⁻¹ · T_odom_query⁻¹``
    (``T_loop`` = ``T_query_candidate``). An anchor whose stretch of the odometry a break ended
    (``MapAnchor.to_query`` set) maps an earlier frame of the odometry, not the current one: None
    then, until the stretch after the break is placed."""
    if hasattr(type(detector), "map_anchor"):
        anchor = detector.map_anchor
        if anchor is None or getattr(anchor, "to_query", None) is not None:
            return None
        cov = None if anchor.covariance is None else np.asarray(anchor.covariance, dtype=np.float64)
        support = {"loops": int(anchor.loops), "metres": float(anchor.metres), "covariance": cov}
        return np.asarray(anchor.transform, dtype=np.float64), support
    if map_loop is None or map_loop.pose is None or T_odom_query is None:
        return None
    T_map_candidate = np.eye(4)
    T_map_candidate[:3] = detector.map.poses[int(map_loop.candidate)]
    if not np.isfinite(T_map_candidate).all():
        return None
    T = T_map_candidate @ np.linalg.inv(np.asarray(map_loop.pose)) @ np.linalg.inv(T_odom_query)
    return T, {"loops": 1, "metres": None, "covariance": None}
