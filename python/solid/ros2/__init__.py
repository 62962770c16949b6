"""A ROS 2 node: keyframes in, loops, a corrected trajectory and map → odom out (docs/ros2.md).

``pip install "solid-lidar[ros2]"`` installs ROS 2's Python client (``rclpy`` with Fast DDS) and
the message packages from PyPI; no ROS installation is needed. Two commands::

    solid ros2 run  [--ros-args -p preset:=avia --params-file solid.yaml ...]   # the node
    solid ros2 play BAG_OR_FOLDER [--rate 1.0 ...]                              # feed it a recording

(``python -m solid.ros2 run ...`` is the same.) This module holds what needs no ROS: the mapping
of ROS 2 parameters onto the pipeline configuration's tables (:func:`parameter_defaults`,
:func:`config_from_parameters`: the same tables as the command line's flags, read from the core)
and the placement of a session in a prior map (:func:`placement`). The node is
:mod:`solid.ros2.node`, the player :mod:`solid.ros2.play`.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from .core import HINT, config_from_parameters, loop_frame, parameter_defaults, parse_loop_frame, placement

__all__ = ["HINT", "config_from_parameters", "loop_frame", "main", "parameter_defaults", "parse_loop_frame", "placement"]


def main(argv: Sequence[str] | None = None) -> int:
    """``solid ros2 run|play ...`` (the rest of the arguments, ROS's ``--ros-args`` among them,
    go to the node or the player)."""
    args = list(sys.argv[1:] if argv is None else argv)
    usage = "usage: solid ros2 {run,play} ...   (solid ros2 run --help, solid ros2 play --help; docs/ros2.md)"
    if not args or args[0] in ("-h", "--help"):
        print(usage)
        return 0 if args else 2
    cmd, rest = args[0], args[1:]
    try:
        if cmd == "run":
            from .node import run

            return run(rest)
        if cmd == "play":
            from .play import play_main

            return play_main(rest)
    except ImportError as e:
        print(f"solid ros2 {cmd}: error: {e}\n{HINT}", file=sys.stderr)
        return 1
    print(f"solid ros2: unknown command {cmd!r}\n{usage}", file=sys.stderr)
    return 2
