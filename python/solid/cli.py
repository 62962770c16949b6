"""The ``solid`` command line: parses the arguments and dispatches to :mod:`solid.commands`.

Run ``solid --help`` or ``solid <command> --help`` for the options and examples. Exit codes: 0 on
success, 2 for a usage error (an unknown option, a value out of range), 1 for any other failure
(a missing or corrupt file, an invalid parameter), reported as one line on stderr (``--debug``
shows the traceback instead), 130 when interrupted.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import traceback
from collections.abc import Callable, Sequence as AbcSequence, Set as AbcSet
from pathlib import Path
from typing import Any, NoReturn, TextIO

__all__ = ["build_parser", "main"]

_SPEC = "docs/spec.md"

_EPILOG_MAIN = f"""\
examples:
  solid presets
  solid describe 000000.bin --preset hdl64
  solid detect  ~/data/kitti/00 --preset hdl64
  solid eval    hku1-avia --poses odom_poses.txt --preset avia --radius 3 --baseline scancontext
  solid eval    ~/kitti/00 --poses poses.txt --calib calib.txt --preset hdl64 --radius 10
  solid map build run1/ --preset avia --poses run1/poses.txt -o run1.soliddb
  solid eval    run2/ --poses run2/poses.txt --map run1.soliddb
  solid optimize run/ --poses odom.txt --preset avia -o out/   # loops + odometry → a consistent trajectory
  solid config dump --preset avia --max-range 40 > avia40.json
  solid bench   ~/data/kitti/00/velodyne --preset hdl64
  solid ros2 run --ros-args -p preset:=avia     # the ROS 2 node (docs/ros2.md)

A SEQUENCE is a folder of scans (.bin .pcd .ply .npy .npz, natural order; a velodyne/ or Scans/
sub-folder is used when present), a ROS 1 bag, a ROS 2 bag folder or an MCAP file
(pip install solid-lidar[ros]). Results go to a fresh folder: -o DIR (which must not exist or be
empty) or solid_results/<date>_<time>_<command>_<name>/ with solid_results/latest pointing at it.
What is computed: {_SPEC}. Exit codes: 0 ok, 1 failure, 2 usage error, 130 interrupted.
"""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        """A usage error: the reason and where the options are, on one line (not the usage block)."""
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


# ---- a short --help: the options most runs need; --help-all lists every one --------------------

#: Fields of the core's parameter tables that `--help` lists (the rest are under `--help-all`).
_COMMON_TABLE_FIELDS = frozenset({"max_range", "threshold", "verify", "exclude_frames", "exclude_meters"})


def _advanced(action: argparse.Action) -> argparse.Action:
    """Hides `action` from `--help` (not from parsing): `--help-all` shows it."""
    action._full_help = action.help  # type: ignore[attr-defined]
    action.help = argparse.SUPPRESS
    return action


class _HelpAll(argparse.Action):
    """`--help-all`: the help of every option, those `--help` leaves out included."""

    def __init__(self, option_strings: list[str], dest: str = argparse.SUPPRESS, default: Any = argparse.SUPPRESS, help: str | None = None) -> None:
        super().__init__(option_strings, dest, default=default, nargs=0, help=help)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any, option_string: str | None = None) -> None:
        for a in parser._actions:
            if hasattr(a, "_full_help"):
                a.help = a._full_help
        parser.print_help()
        parser.exit()


# ---- value types: a bad value is a usage error (exit 2, one line) ----------------------------


def _number(kind: Callable[[str], Any], what: str, ok: Callable[[Any], bool]) -> Callable[[str], Any]:
    def parse(s: str) -> Any:
        try:
            v = kind(s)
        except (ValueError, OverflowError):
            raise argparse.ArgumentTypeError(f"invalid {kind.__name__} value: {s!r}") from None
        if not ok(v):
            raise argparse.ArgumentTypeError(f"{s!r} is not {what}")
        return v

    parse.__name__ = kind.__name__
    return parse


_BIG = 2**31 - 1
nonneg_int = _number(int, "an integer in 0..2^31-1", lambda v: 0 <= v <= _BIG)
pos_int = _number(int, "an integer in 1..2^31-1", lambda v: 1 <= v <= _BIG)
any_float = _number(float, "a finite number", math.isfinite)
pos_float = _number(float, "a finite number > 0", lambda v: math.isfinite(v) and v > 0)
unit_float = _number(float, "a number in [0, 1]", lambda v: 0.0 <= v <= 1.0)
degrees = _number(float, "degrees in (0, 360]", lambda v: 0 < v <= 360)


# Older spellings of table flags, still accepted.
_FLAG_ALIASES = {
    "exclude_frames": ["--exclude"],
    "exclude_meters": ["--exclude-m"],
    "exclude_seconds": ["--exclude-s"],
    "gate_max_translation": ["--max-loop-distance"],
}


def _table_type(f: dict[str, Any]) -> Callable[[str], Any]:
    """The argparse type of a table field: its range checked, a value outside it a usage error."""
    if f["type"] == "int":
        lo, hi = f["min"], f["max"]
        return _number(int, f["expected"], lambda v: lo <= v <= hi)
    lo, hi, lo_open = f["min"], f["max"], f["min_open"]
    return _number(float, f["expected"], lambda v: (v > lo if lo_open else v >= lo) and v <= hi)


def _add_table_args(g: Any, table: str, per_preset: AbcSet[str] = frozenset(), prefix: str = "", defaults: dict[str, Any] | None = None) -> None:
    """One flag per field of a core parameter table (`--prefix-name-with-dashes`, dest
    `prefix_name`), with its doc line, true default (`defaults` where given, else the table's) and
    range; switches get `--name` and `--no-name`."""
    from .config import default_text, param_table

    for f in param_table(table):
        if defaults is not None and f["name"] in defaults:
            f = {**f, "default": defaults[f["name"]]}
        dest = prefix + f["name"]
        flags = ["--" + dest.replace("_", "-"), *_FLAG_ALIASES.get(dest, [])]
        help = f"{f['doc'].rstrip('.')} (default: {default_text(f, per_preset)})"
        if f["type"] == "bool":
            a = g.add_argument(*flags, dest=dest, action=argparse.BooleanOptionalAction, default=None, help=help)
        elif f["type"] == "str":
            a = g.add_argument(*flags, dest=dest, choices=f["choices"], default=None, help=help)
        else:
            metavar = "N" if f["type"] == "int" else "X"
            a = g.add_argument(*flags, dest=dest, type=_table_type(f), default=None, metavar=metavar, help=help)
        if prefix or f["name"] not in _COMMON_TABLE_FIELDS:
            _advanced(a)


def _add_config_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group(f"descriptor ({_SPEC} §1; flags override --config, which is based on its preset)")
    g.add_argument("--preset", help="sensor preset (see `solid presets`), e.g. hdl64, vlp16, avia")
    g.add_argument("--config", type=Path, metavar="FILE", help="pipeline configuration (JSON from `solid config dump`)")
    from .config import param_table

    _add_table_args(g, "SolidConfig", {f["name"] for f in param_table("SolidConfig")})  # a preset sets them all


def _add_detector_args(p: argparse.ArgumentParser) -> None:
    from .config import per_preset_fields

    from . import _solid

    g = p.add_argument_group(f"loop detector ({_SPEC} §8; every default is the core's)")
    _add_table_args(g, "DetectorConfig", per_preset_fields())
    g = p.add_argument_group(f"the detector's acceptance gate ({_SPEC} §11; with verification)")
    _add_table_args(g, "AcceptanceGate", prefix="gate_", defaults=_solid.DetectorConfig().gate.to_dict())


def _add_truth_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group(f"truth ({_SPEC} §5: a loop is correct when its place is within the radius and its pose within the tolerance)")
    g.add_argument("--radius", type=pos_float, default=None, metavar="M", help="a match is the same place within this many metres (default 5)")
    g.add_argument("--pose-tolerance-m", type=pos_float, default=None, metavar="M", help="a loop's pose is right within this many metres (default 1)")
    g.add_argument("--pose-tolerance-deg", type=pos_float, default=None, metavar="DEG", help="... and this many degrees (default 5)")


def _add_input_args(p: argparse.ArgumentParser, poses_required: bool = False) -> None:
    g = p.add_argument_group("input")
    _advanced(g.add_argument("--format", choices=_formats(), help="force the scan reader (default: chosen from the files' content)"))
    g.add_argument("--topic", help="point-cloud topic of a bag (default: the only one)")
    g.add_argument("--poses", type=Path, required=poses_required, metavar="FILE|TOPIC", help="KITTI 3×4 rows or TUM (t x y z qx qy qz qw); for a bag, also a nav_msgs/Odometry topic of it (e.g. /odom)")
    _advanced(g.add_argument("--timestamps", type=Path, help="timestamps file (one per scan)"))
    g.add_argument("--calib", type=Path, metavar="FILE", help="sensor → pose-frame extrinsic (KITTI calib.txt 'Tr:' line, or 12 numbers)")
    g.add_argument("--frames", default=None, metavar="SPEC", help="frames to use, e.g. 0:60,284:314 (Python slices)")
    _advanced(g.add_argument("--subsample-m", type=pos_float, default=None, metavar="M", help="keep one frame per M metres travelled"))
    g.add_argument("--fov", type=degrees, default=None, metavar="DEG", help="clip every scan to this horizontal FOV")
    _advanced(g.add_argument("--fov-center", type=any_float, default=None, metavar="DEG", help="centre of --fov (default 0 = +x, the same for every run; a warning says when the first scan has nothing there)"))
    _advanced(g.add_argument("--occlude", type=degrees, default=None, metavar="DEG", help="remove a sector this wide from every scan"))
    _advanced(g.add_argument("--occlude-center", type=any_float, default=None, metavar="DEG", help="centre of --occlude (default 0 = +x)"))
    _advanced(g.add_argument("--threads", type=nonneg_int, default=0, help="threads for describing (default 0: one per core)"))


def _formats() -> list[str]:
    from .datasets import FORMATS

    return list(FORMATS)


def _command(sub: Any, name: str, help: str, *examples: str, note: str = "") -> argparse.ArgumentParser:
    """A subcommand of `sub` whose help ends with its examples (and a note after them)."""
    epilog = ""
    if examples:
        epilog = f"example{'s' if len(examples) > 1 else ''}:\n" + "".join(f"  {e}\n" for e in examples)
    parser: argparse.ArgumentParser = sub.add_parser(
        name, help=help, formatter_class=argparse.RawDescriptionHelpFormatter, epilog=epilog + note or None
    )
    return parser


def _actions(sub: Any, name: str, help: str) -> Any:
    """A subcommand `name` made of actions (``solid NAME ACTION``): where the actions are added."""
    actions = sub.add_parser(name, help=help, formatter_class=argparse.RawDescriptionHelpFormatter).add_subparsers(
        dest=f"{name}_command", metavar="ACTION", parser_class=_Parser
    )
    actions.required = True
    return actions


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    p.add_argument("--debug", action="store_true", help="show tracebacks for errors")
    if any(hasattr(a, "_full_help") for a in p._actions):
        p.add_argument("--help-all", action=_HelpAll, help="show every option (--help lists those most runs need)")


def _add_run_head(p: argparse.ArgumentParser, map_help: str) -> None:
    """The first arguments of a command that runs the detector over a recording (detect, eval,
    optimize): the recording, the output folder and a prior map (what it is for: `map_help`)."""
    p.add_argument("sequence", type=Path)
    p.add_argument("-o", "--output", type=Path, default=None, help="output folder (must not exist or be empty)")
    p.add_argument("--map", type=Path, metavar="FILE", help=map_help)


def _add_run_tail(p: argparse.ArgumentParser, *, poses_required: bool) -> None:
    """The option groups of such a command: descriptor, detector, input, common."""
    _add_config_args(p)
    _add_detector_args(p)
    _add_input_args(p, poses_required=poses_required)
    _add_common(p)


def build_parser() -> argparse.ArgumentParser:
    """The argparse parser of the ``solid`` command."""
    try:
        from importlib.metadata import version as _dist_version

        version = _dist_version("solid-lidar")
    except Exception:  # not installed as a distribution (e.g. a source checkout)
        version = "unknown"

    parser = _Parser(
        prog="solid",
        description="SOLiD LiDAR place recognition: descriptors, loop detection, evaluation and maps.",
        epilog=_EPILOG_MAIN,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"solid {version}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    p = _command(
        sub, "describe", "print the descriptor of one scan as JSON",
        "solid describe 000000.bin --preset hdl64", "solid describe scan.pcd --preset avia --max-range 40 -o d.json",
    )
    p.add_argument("scan", type=Path, help="a scan file")
    p.add_argument("-o", "--output", type=Path, help="write the JSON here instead of stdout (a file is replaced atomically; a FIFO or a character device is written through)")
    p.add_argument("--format", choices=_formats(), help="force the scan reader")
    _add_config_args(p)
    _add_common(p)

    p = _command(
        sub, "detect", "run the online loop detector over a sequence; writes loops.csv",
        "solid detect ~/kitti/00 --preset hdl64",
        "solid detect run.bag --topic /points --preset os1-64 --threshold 0.08 -o out/",
        "solid detect run2/ --map run1.soliddb          # against a prior session's map",
    )
    _add_run_head(p, "a map from `solid map build`: query this recording against it")
    p.add_argument("--g2o", type=Path, metavar="FILE", help="also write the pose graph (a vertex per frame, odometry and loop edges; needs --poses) in g2o form (must not exist)")
    _add_run_tail(p, poses_required=False)

    p = _command(
        sub, "localize", "place a recording in a saved map: when, where and how sure (relocalization)",
        "solid localize run1.soliddb run2/ --poses run2/poses.txt",
        "solid localize run1.soliddb run2/ --poses odom.txt --json > placement.json",
        "solid localize run1.soliddb run2/ --poses odom.txt -o loc2/   # writes loc2/anchor.txt, anchors.kitti for `solid map merge --anchor`",
        note="\nThe session is placed when mutually consistent loops into the map agree on one transform\n"
        "(docs/loops.md#relocalization); T_map_odom maps its --poses frame into the map's world.\n",
    )
    p.add_argument("map", type=Path, help="a map from `solid map build` with poses")
    p.add_argument("sequence", type=Path, help="the recording to place (with --poses: its odometry, in its own frame)")
    p.add_argument("-o", "--output", type=Path, default=None, help="also write placement.json, anchor.txt, anchors.kitti, loops.csv here (must not exist or be empty)")
    p.add_argument("--json", action="store_true", help="print the placement as JSON instead of the table")
    _add_run_tail(p, poses_required=True)

    p = _command(
        sub, "eval", f"score the detector's candidates against poses ({_SPEC} §5): metrics, CSV, plots",
        "solid eval hku1-avia --poses odom_poses.txt --preset avia --radius 3 --baseline scancontext",
        "solid eval ~/kitti/00 --poses poses.txt --calib calib.txt --preset hdl64 --radius 10 --fov 60",
        "solid eval run2/ --poses run2/poses.txt --map run1.soliddb",
        note="\nThe exclusion window counts frames of the evaluated selection (after --frames/--subsample-m).\n"
        "A relative --poses path is looked up inside SEQUENCE when it is not in the current folder.\n",
    )
    _add_run_head(p, "a map from `solid map build` (with poses): score against it too")
    w = p.add_mutually_exclusive_group()
    w.add_argument("--anchor", type=Path, metavar="FILE", help="with --map: this session's world → the map's world (anchor.txt of `solid localize` or `solid optimize --map`, or anchors.kitti beside it: each frame's; default: estimated from the verified loops into the map)")
    w.add_argument("--same-world", action="store_true", help="with --map: this session's poses are already in the map's world")
    _add_truth_args(p)
    p.add_argument("--baseline", action="append", choices=["scancontext"], default=[], help="also evaluate this baseline on the same queries")
    _advanced(p.add_argument("--sc-max-range", type=pos_float, default=None, metavar="M", help="Scan Context max range (default 80, as the reference)"))
    _advanced(p.add_argument("--sc-lidar-height", type=any_float, default=None, metavar="M", help="added to z before the max height (default 2.0)"))
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    _add_run_tail(p, poses_required=True)

    p = _command(
        sub, "optimize", "loops + odometry in a robust pose-graph optimisation: a corrected trajectory (pip install solid-lidar[slam])",
        "solid optimize hku1-avia --poses odom_poses.txt --preset avia -o out/",
        "solid optimize run2/ --poses odom.txt --map run1.soliddb -o out2/   # anchored in a saved map",
        "solid optimize seq/ --poses odom.txt --truth gt.txt --preset vlp16   # with ATE/RPE",
        "solid optimize hku1-avia --poses odom_poses.txt --loops out/ --robust cauchy -o out_cauchy/   # the same loops again",
        note="\nWrites trajectory.kitti/.tum (optimised, in the frame of --poses), graph.g2o, loops.csv,\n"
        "trajectory.png, metrics.json; with --map also anchor.txt and trajectory_map.kitti/.tum. See docs/slam.md.\n",
    )
    _add_run_head(p, "a map from `solid map build` (with poses): anchor this session in its world")
    p.add_argument("--truth", type=Path, metavar="FILE", help="ground-truth poses of the recording (KITTI or TUM): ATE and RPE in metrics.json")
    p.add_argument(
        "--loops",
        type=Path,
        metavar="G2O|RUN",
        help="reuse a run's loops instead of running the detector: the g2o file of `solid detect --g2o FILE`, or a run folder "
        "holding graph.g2o (`solid optimize`) or loops.g2o; give the same --poses, --calib and --frames as that run",
    )
    from .slam import ROBUST_SCHEMES, OdometryNoise

    p.add_argument("--robust", choices=ROBUST_SCHEMES, default=None, help=f"robust scheme for the loop edges (default: {ROBUST_SCHEMES[0]}; docs/slam.md)")
    on = OdometryNoise()
    g = p.add_argument_group("odometry noise (σ per axis grows with the step between frames)")
    g.add_argument("--odom-sigma-m", type=pos_float, default=None, metavar="M", help=f"translation σ floor, metres (default {on.translation_floor_m:g})")
    g.add_argument("--odom-sigma-fraction", type=_number(float, "a finite number >= 0", lambda v: math.isfinite(v) and v >= 0), default=None, metavar="F", help=f"translation σ per metre travelled (default {on.translation_fraction:g})")
    g.add_argument("--odom-sigma-deg", type=pos_float, default=None, metavar="DEG", help=f"rotation σ floor, degrees (default {on.rotation_floor_deg:g})")
    g.add_argument("--odom-sigma-deg-per-m", type=_number(float, "a finite number >= 0", lambda v: math.isfinite(v) and v >= 0), default=None, metavar="DEG", help=f"rotation σ per metre travelled, degrees (default {on.rotation_deg_per_m:g})")
    g.add_argument(
        "--odom-noise-scale", type=_noise_scale, default=None, metavar="K|auto",
        help="multiply every odometry σ by K (default auto: 1, unless the optimum then keeps fewer than half of the loops: then the factor they need, fitted so that their median χ² against the odometry is χ²(6)'s; docs/slam.md#drift)",
    )  # fmt: skip
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plot")
    _add_run_tail(p, poses_required=True)

    p = _command(
        sub, "view", "see a run in 3-D: trajectories, places, loops coloured by verdict, a loop's two clouds (pip install solid-lidar[viewer])",
        "solid view solid_results/latest                 # writes solid_results/latest/view.rrd",
        "solid view out/ -o run.rrd --loop 305          # the clouds of the loop whose query is frame 305",
        "solid view out/ --spawn                        # straight into a rerun viewer",
        note="\nOpen the file with `rerun FILE.rrd` (or `rerun --web-viewer FILE.rrd`). See docs/view.md.\n",
    )
    p.add_argument("run", type=Path, help="a run folder of solid eval, detect or optimize")
    p.add_argument("-o", "--output", type=Path, default=None, help="the .rrd file to write (default RUN/view.rrd)")
    p.add_argument("--loop", type=nonneg_int, default=None, metavar="FRAME", help="show the clouds of the loop whose query is this frame (default: the first verified loop)")
    p.add_argument("--no-clouds", action="store_true", help="show no loop's clouds")
    p.add_argument("--spawn", action="store_true", help="send to a rerun viewer started for it instead of writing a file")
    _add_common(p)

    p = _command(
        sub, "demo", "simulate a drive with a loop under a narrow FOV and score SOLiD against the truth",
        "solid demo", "solid demo --sensor os1-64 --fov 120 -o demo_out",
    )
    from .sim import SENSORS

    p.add_argument("-o", "--output", type=Path, default=None, help="output folder (must not exist or be empty)")
    p.add_argument("--sensor", choices=list(SENSORS), default="hdl64", help="simulated sensor (default hdl64)")
    p.add_argument("--fov", type=degrees, default=60.0, metavar="DEG", help="horizontal field of view (default 60)")
    p.add_argument("--seed", type=nonneg_int, default=3, help="world seed (default 3)")
    p.add_argument("--laps", type=pos_float, default=1.5, help="laps around the block (default 1.5)")
    p.add_argument("--threshold", type=unit_float, default=None, help="loop detector threshold (default: the preset's)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    _add_common(p)

    p = _command(sub, "presets", "list the sensor presets", "solid presets --json")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    _add_common(p)

    csub = _actions(sub, "config", "configuration files")
    d = _command(
        csub, "dump", "print a whole pipeline configuration as JSON (to edit and pass back with --config)",
        "solid config dump --preset avia --max-range 40 --exclude-m 20 > avia40.json",
    )
    _add_config_args(d)
    _add_detector_args(d)
    _add_truth_args(d)
    _add_common(d)

    msub = _actions(sub, "map", "saved maps: build one from a recording, merge, inspect, upgrade")
    b = _command(
        msub, "build", "describe every scan of a recording into a map file (places with poses and times)",
        "solid map build run1/ --preset avia --poses run1/poses.txt -o run1.soliddb",
    )
    b.add_argument("sequence", type=Path)
    b.add_argument("-o", "--output", type=Path, required=True, help="the map file to write (must not exist)")
    b.add_argument("--detect", action="store_true", help="also run the loop detector within the session (not needed for a map: off by default)")
    _add_config_args(b)
    _add_input_args(b)
    _add_common(b)
    mm = _command(
        msub, "merge", "merge maps into one (each input's sessions renumbered after the previous ones)",
        "solid map merge run1.soliddb run2.soliddb --anchor same -o both.soliddb",
        "solid optimize run2/ --poses odom.txt --map run1.soliddb -o opt2/   # writes opt2/anchor.txt",
        "solid map merge run1.soliddb run2.soliddb --anchor opt2/anchor.txt -o both.soliddb",
        "solid map merge run1.soliddb run2.soliddb --anchor opt2/anchors.kitti -o both.soliddb   # one per place: the odometry broke",
    )
    mm.add_argument("maps", type=Path, nargs="+")
    mm.add_argument(
        "--anchor",
        action="append",
        default=None,
        metavar="FILE|same",
        help="per map after the first, in order: an anchor file that carries its poses into the first map's world: anchor.txt of "
        "`solid localize` or `solid optimize --map` (one KITTI 3x4 row: that map's world → the first map's, for every place), or "
        "anchors.kitti beside it (one row per frame of that run, applied to its place: a session whose odometry broke, one anchor "
        "per stretch); or 'same' when they already are there (one of them is required when two maps hold poses; the merged map "
        "records them)",
    )
    mm.add_argument("-o", "--output", type=Path, required=True, help="the map file to write (must not exist)")
    _add_common(mm)
    mi = _command(msub, "info", "what a map file holds (read from its header: fast at any size)", "solid map info run1.soliddb")
    mi.add_argument("map", type=Path)
    mi.add_argument("--json", action="store_true", help="print JSON")
    _add_common(mi)
    mu = _command(
        msub, "upgrade", "rewrite a map in the current file format (in place, atomically, unless -o is given)",
        "solid map upgrade old.soliddb",
    )
    mu.add_argument("map", type=Path)
    mu.add_argument("-o", "--output", type=Path, default=None, help="write the upgraded map here instead (must not exist)")
    _add_common(mu)

    p = _command(
        sub, "bench", "time reading, describing and searching on your data (prints Hz)",
        "solid bench ~/kitti/00/velodyne --preset hdl64", "solid bench scans/ --preset avia --scans 200 --db-size 5000",
    )
    p.add_argument("sequence", type=Path)
    p.add_argument("--scans", dest="n_frames", type=pos_int, default=200, help="scans to load, from the first (default 200)")
    p.add_argument("--db-size", type=pos_int, default=None, help="search a database of this many entries (descriptors repeated)")
    p.add_argument("--threads", type=nonneg_int, default=0, help="threads for the batch describe (default 0: one per core)")
    p.add_argument("--format", choices=_formats(), help="force the scan reader")
    p.add_argument("--topic", help="point-cloud topic of a bag")
    _add_config_args(p)
    _add_common(p)

    p = _command(
        sub, "ros2", "the ROS 2 node and a bag player (pip install \"solid-lidar[ros2]\"; docs/ros2.md)",
        "solid ros2 run --ros-args -p preset:=avia", "solid ros2 play run.bag --rate 1",
    )
    p.add_argument("args", nargs=argparse.REMAINDER, help="run|play and their arguments (solid ros2 run --help)")
    return parser


# ---- progress and inputs -----------------------------------------------------------------------


def _progress(args: argparse.Namespace, total: int | None, desc: str, unit: str = "scan") -> Any:
    """A bar that moves with every scan, with its rate and the time left."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, disable=bool(args.quiet), file=sys.stderr, dynamic_ncols=True, leave=False, mininterval=0.2)


def _open(args: argparse.Namespace, err: TextIO, cfg: Any = None) -> tuple[Any, Any]:
    """The dataset and the record of its inputs, every option checked against it before any scan
    is read (:func:`solid.pipeline.check_run`); prints which reader was chosen."""
    from .commands import open_recording
    from .pipeline import check_run

    ds, inputs = open_recording(
        args.sequence,
        format=getattr(args, "format", None),
        topic=getattr(args, "topic", None),
        poses=getattr(args, "poses", None),
        timestamps=getattr(args, "timestamps", None),
        calib=getattr(args, "calib", None),
        map=getattr(args, "map", None),
        frames=None if cfg is None else cfg.input.frames,
    )
    if cfg is not None:
        check_run(ds, cfg)
    if not args.quiet:
        err.write(f"solid: {inputs.sequence}: {len(ds)} scans, reader {inputs.reader}\n")
    return ds, inputs


# ---- commands ----------------------------------------------------------------------------------


def cmd_describe(args: argparse.Namespace, out: TextIO) -> int:
    from .commands import describe_scan, make_config
    from .outputs import atomic_write_bytes

    cfg = make_config(args)
    text = json.dumps(describe_scan(args.scan, cfg, args.format), indent=1) + "\n"
    if args.output is not None:
        atomic_write_bytes(args.output, text.encode(), stream=True)  # -o /dev/stdout, a FIFO: written through
    else:
        out.write(text)
    return 0


def cmd_detect(args: argparse.Namespace, out: TextIO) -> int:
    from . import commands, evaluation

    cfg, map_db = commands.config_and_map(args)
    ds, inputs = _open(args, sys.stderr, cfg)
    with _progress(args, len(ds), "detect") as bar:
        result, folder = commands.detect(ds, cfg, inputs, output=args.output, map_db=map_db, threads=args.threads, progress=bar.update, g2o=args.g2o)
    total = result.timings["detect_s"]
    rate = len(result.frames) / total if total > 0 else math.inf
    d = cfg.detector
    # What applied: the threshold only without verification, a window only with what it counts.
    accept = f"verified, gate's largest loop {d.gate.max_translation:g} m" if d.verify else f"threshold {d.threshold:g}"
    out.write(
        f"{len(result.frames)} scans, {len(result.loops())} loops ({accept}, exclude {d.exclude_frames} frames"
        + (f" / {d.exclude_meters:g} m" if d.exclude_meters and result.poses is not None else "")
        + (f" / {d.exclude_seconds:g} s" if d.exclude_seconds and result.timestamps is not None else "")
        + f"{', map of ' + str(result.map_size) + ' places' if result.map_size else ''}), {rate:.1f} Hz\n"
    )
    out.write(evaluation.describe_loop_delay(evaluation.loop_delay_steps(d)) + "\n")
    if result.map_size and result.poses is not None and d.verify and d.placement_loops:
        out.write(commands.describe_anchor(result) + "\n")
    figures = {"loops": len(result.loops()), "rejections": commands.rejection_counts(result), "odometry_drift_measured": commands.measured_drift(result)}
    for line in commands.advice(figures, d):
        out.write(line + "\n")
    out.write(f"wrote {folder}" + (f" and {args.g2o}" if args.g2o else "") + "\n")
    return 0


def cmd_localize(args: argparse.Namespace, out: TextIO) -> int:
    from . import commands

    cfg, map_db = commands.config_and_map(args)
    ds, inputs = _open(args, sys.stderr, cfg)
    with _progress(args, len(ds), "localize") as bar:
        _, doc, folder = commands.localize(ds, cfg, inputs, map_db, output=args.output, threads=args.threads, progress=bar.update)
    if args.json:
        out.write(json.dumps(doc, indent=1) + "\n")
        return 0
    out.write(_placement_table(doc))
    if folder is not None:
        if doc["placed"] and (len(doc.get("stretches") or []) > 1 or doc.get("partial_anchor")):
            out.write(
                f"note: the odometry broke, so anchor.txt maps only frames {_frames_of(doc)}: to merge this session's map, "
                f"give solid map merge --anchor {folder / commands.ANCHORS_FILE} (each frame's stretch's anchor)\n"
            )
        out.write(f"wrote {folder}\n")
    return 0


def _placement_table(doc: dict[str, Any]) -> str:
    """``solid localize``'s table: when, where and how sure the session is placed."""
    rows = [("frames", f"{doc['frames']} against a map of {doc['map_places']} places")]
    if not doc["placed"]:
        rows.append(("placed", "no: too few loops into the map agree with each other (none is accepted before)"))
    else:
        T = doc["transform"]
        yaw = math.degrees(math.atan2(T[1][0], T[0][0]))
        when = f"at frame {doc['placed_frame']}" + ("" if doc["placed_time"] is None else f" (t = {doc['placed_time']:.2f} s)")
        rows += [
            ("placed", when),
            ("T_map_odom", f"translation {T[0][3]:.2f}, {T[1][3]:.2f}, {T[2][3]:.2f} m, yaw {yaw:.2f}°"),
            ("support", f"{doc['loops']} consistent loops over {doc['metres']:.0f} m (frames {doc['first_frame']}–{doc['last_frame']})"),
        ]
        if doc["sigma_translation_m"] is not None:
            rows.append(("spread", f"{doc['sigma_translation_m']:.3f} m, {doc['sigma_rotation_deg']:.3f}° (of the supporting loops' placements)"))
        stretches = doc.get("stretches") or []
        if len(stretches) > 1 or doc.get("partial_anchor"):
            # The odometry broke: each stretch between breaks lies in its own frame.
            rows.append(("maps frames", _frames_of(doc) + ("" if doc.get("to_frame") is None else ": the odometry broke after, the current frame is not placed")))
            for s in stretches[:-1]:
                S = s["transform"]
                rows.append(
                    (
                        "stretch",
                        f"frames {_frames_of(s)}: translation {S[0][3]:.2f}, {S[1][3]:.2f}, {S[2][3]:.2f} m, "
                        f"yaw {math.degrees(math.atan2(S[1][0], S[0][0])):.2f}°, {s['loops']} loops",
                    )
                )
    rows.append(("loops", f"{doc['loops_into_map']} into the map, {doc['loops_in_session']} within the session"))
    width = max(len(k) for k, _ in rows)
    return "".join(f"{k:<{width}}  {v}\n" for k, v in rows)


def _frames_of(doc: dict[str, Any]) -> str:
    """The frames a placement maps (its stretch of the odometry), as text."""
    from .localize import frame_range

    return frame_range(doc.get("from_frame"), doc.get("to_frame"))


def cmd_eval(args: argparse.Namespace, out: TextIO) -> int:
    from . import commands, evaluation

    cfg, map_db = commands.config_and_map(args)
    ds, inputs = _open(args, sys.stderr, cfg)
    sc_cfg = None
    if "scancontext" in args.baseline:
        from .scancontext import ScanContextConfig

        kw: dict[str, Any] = {}
        if args.sc_max_range is not None:
            kw["max_range"] = args.sc_max_range
        if args.sc_lidar_height is not None:
            kw["lidar_height"] = args.sc_lidar_height
        sc_cfg = ScanContextConfig(**kw)
    hint = ["solid", "detect", str(args.sequence)]
    # The files the detector reads beside the scans (poses feed its metres window): the same run.
    for name in ("format", "topic", "poses", "timestamps", "calib"):
        if getattr(args, name) is not None:
            hint += [f"--{name}", str(getattr(args, name))]
    if map_db is not None:
        hint += ["--map", str(args.map)]
    with _progress(args, len(ds), "eval") as bar:
        run = commands.evaluate(
            ds,
            cfg,
            inputs,
            output=args.output,
            map_db=map_db,
            scancontext=sc_cfg,
            plots=not args.no_plots,
            threads=args.threads,
            progress=bar.update,
            command_hint=hint,
            anchor=_anchor_arg(args),
        )
    _print_table(out, run.evaluations)
    m = run.metrics
    a = m.get("anchor")
    if a is not None:
        how = {
            "placed": f"the detector's placement, {a.get('inlier_loops')} consistent loops into the map (solid localize)",
            "estimated": f"estimated from {a.get('inlier_loops')} of {a.get('cross_session_loops')} verified loops into the map",
            "given": f"from {args.anchor}",
        }
        out.write(f"session placed in the map's world: {how.get(a['source'], a['source'])}\n")
        for note in a.get("notes", []):
            sys.stderr.write(f"note: {note}\n")
    excl = m.get("exclusion_median_m")
    if excl is not None:
        out.write(f"exclusion: {cfg.detector.exclude_frames} frames ≈ {excl:.1f} m travelled on this sequence (median)\n")
    if m.get("accepted") is not None:
        out.write(
            f"at the threshold {m['threshold']:g}: {m['accepted']} loops accepted: {m['accepted'] - m['false_accepts']} correct, "
            f"{m['place_false_accepts']} beyond the {m['radius_m']:g} m radius, {m['pose_false_accepts']} with a pose off by more than "
            f"{m['pose_tolerance_m']:g} m or {m['pose_tolerance_deg']:g}° "
            f"(precision {commands.fmt_metric(m['precision'])}, recall {commands.fmt_metric(m['recall'])}: within the radius)\n"
        )
    out.write(evaluation.describe_loop_delay(m["loop_delay_steps"]) + "\n")
    for line in commands.advice(m, cfg.detector):
        out.write(line + "\n")
    if m.get("best_threshold_command") is not None:
        out.write(f"best F1 {commands.fmt_metric(m['f1_max'])} at threshold {m['best_threshold']:.6g}; to use it:\n  {m['best_threshold_command']}\n")
    elif m.get("best_threshold") is not None:
        out.write(f"best F1 {commands.fmt_metric(m['f1_max'])} at threshold {m['best_threshold']:.6g}, past what the gate accepts: no detector setting reproduces it\n")
    out.write(f"wrote {run.folder}\n")
    return 0


def _noise_scale(text: str) -> float | None:
    """``--odom-noise-scale``: "auto" (None) or a factor > 0."""
    if text == "auto":
        return None
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected auto or a finite number > 0, got {text!r}")
    return v


def cmd_optimize(args: argparse.Namespace, out: TextIO) -> int:
    from . import commands
    from .slam import OdometryNoise, require_gtsam

    require_gtsam()  # before the detector runs: say how to install it at once
    reused = commands.config_of_reused_loops(args)  # --loops reads no scan: no --preset needed
    cfg, map_db = (reused, None) if reused is not None and args.map is None else commands.config_and_map(args)
    ds, inputs = _open(args, sys.stderr)
    d = OdometryNoise()
    noise = OdometryNoise(
        translation_fraction=d.translation_fraction if args.odom_sigma_fraction is None else args.odom_sigma_fraction,
        translation_floor_m=args.odom_sigma_m or d.translation_floor_m,
        rotation_deg_per_m=d.rotation_deg_per_m if args.odom_sigma_deg_per_m is None else args.odom_sigma_deg_per_m,
        rotation_floor_deg=args.odom_sigma_deg or d.rotation_floor_deg,
    )
    with _progress(args, 0 if args.loops else len(ds), "optimize") as bar:
        run = commands.optimize(
            ds, cfg, inputs, output=args.output, map_db=map_db, truth=args.truth, robust=args.robust,
            noise=noise, noise_scale=args.odom_noise_scale, plots=not args.no_plots, threads=args.threads,
            progress=bar.update, loops_from=args.loops,
        )  # fmt: skip
    m = run.metrics
    out.write(f"{len(run.result.frames)} frames, {m['loop_edges']} loop edges within the session ({m['loop_edges_kept']} kept by the {m['robust']} optimum)\n")
    k = m["odometry_noise_scale"]
    if k != 1.0:
        how = "as given" if args.odom_noise_scale is not None else "fitted: with the noise as given the optimum dropped most loops; they say the odometry drifts more than its noise model assumes"
        out.write(f"odometry noise ×{k:.3g} ({how})\n")
    if m["loop_edges"] >= 2 and 2 * m["loop_edges_kept"] < m["loop_edges"]:
        out.write(
            f"note: the optimum kept {m['loop_edges_kept']} of {m['loop_edges']} loops, so the trajectory is mostly the odometry's. "
            "Either most loops are false (check them: loops.csv, trajectory.png), or the odometry drifts more than "
            f"×{k:.3g} its noise model: try --odom-noise-scale with a larger factor, or --robust cauchy (docs/slam.md#drift)\n"
        )
    for name in ("odometry", "optimized"):
        if name in m:
            e = m[name]
            out.write(f"{name:<10} ATE {e['ate_m']:.3f} m, RPE {e['rpe_m']:.3f} m / {e['rpe_deg']:.3f}° per frame\n")
    if "anchor" in m:
        a = m["anchor"]
        out.write(
            f"anchor: none ({m.get('anchor_none') or 'no verified loop into the map'})\n"
            if a is None
            else ("anchor: from the detector's placement in the map (solid localize), refined with " if a.get("source") == "placed" else "anchor: from ")
            + f"{a['inlier_loops']} of {a['cross_session_loops']} loops into the map (in loops.csv; graph.g2o holds the session's own graph, "
            "so `--loops` reuses only its loops within the session)\n"
        )
        for note in [] if a is None else a.get("notes", []):
            out.write(f"note: {note}\n")
    out.write(f"wrote {run.folder}\n")
    return 0


def _anchor_arg(args: argparse.Namespace) -> Any:
    """eval's --anchor FILE (its path: anchor.txt or anchors.kitti, read by
    :func:`solid.commands.run_anchor` against the run's frames), --same-world ("same") or
    neither (None: estimated)."""
    from .commands import anchor_file

    if getattr(args, "anchor", None) is not None:
        if args.map is None:
            raise ValueError("--anchor places a session in a map: give --map too")
        anchor_file(args.anchor)  # a wrong file is refused before the run
        return Path(args.anchor)
    return "same" if getattr(args, "same_world", False) else None


def _print_table(out: TextIO, evals: AbcSequence[Any]) -> None:
    from .commands import fmt_metric

    keys = [
        ("queries", "queries"),
        ("gt_queries", "GT+"),
        ("recall_at_1", "R@1"),
        ("recall_at_5", "R@5"),
        ("f1_max", "F1max"),
        ("auc", "AUC"),
        ("rotation_error_deg_mean", "rot.err°"),
    ]
    out.write(f"{'method':<14}" + "".join(f"{h:>10}" for _, h in keys) + "\n")
    for e in evals:
        m = e.metrics()
        out.write(f"{e.name:<14}" + "".join(f"{fmt_metric(m[k]):>10}" for k, _ in keys) + "\n")


def cmd_view(args: argparse.Namespace, out: TextIO) -> int:
    from . import view

    view.require_rerun()
    run = view.read_run(args.run)
    for note in run.notes:
        sys.stderr.write(f"solid view: {note}\n")
    path = view.view(args.run, args.output, loop=args.loop, clouds=not args.no_clouds, spawn=args.spawn, run=run)
    kinds = ", ".join(f"{n} {k.replace('_', ' ')}" for k, n in view.counts(run.loops).items()) or "none"
    out.write(f"{len(run.frame_ids)} frames, trajectories: {', '.join(run.trajectories)}; loops: {kinds}\n")
    out.write(f"wrote {path}: open it with `rerun {path}`\n" if path is not None else "sent to the rerun viewer\n")
    return 0


def cmd_demo(args: argparse.Namespace, out: TextIO) -> int:
    from . import sim

    if not args.quiet:
        sys.stderr.write(
            f"solid demo: simulating {args.laps:g} laps around a block (world seed {args.seed}) seen by a {args.sensor} "
            f"clipped to a {args.fov:g}° field of view, then detecting loops and scoring them against the true poses\n"
        )
    m = sim.run_demo(
        args.output, seed=args.seed, sensor=args.sensor, h_fov=args.fov, laps=args.laps, threshold=args.threshold, plots=not args.no_plots, progress=not args.quiet
    )
    out.write(sim.demo_summary(m))
    return 0


def cmd_presets(args: argparse.Namespace, out: TextIO) -> int:
    import solid

    ps = solid.presets()
    sensors = solid.preset_sensors()
    if args.json:
        doc = {n: {**c.to_dict(), "loop_threshold": solid.DetectorConfig.preset(n).threshold} for n, c in ps.items()}
        out.write(json.dumps(doc, indent=1) + "\n")
        return 0
    head = f"{'name':<8} {'fov_up':>7} {'fov_down':>8} {'n_elev':>6} {'n_range':>7} {'n_azim':>6} {'min_r':>5} {'max_r':>6} {'voxel':>5} {'loop_thr':>8}  sensor"
    out.write(head + "\n")
    for n, c in ps.items():
        thr = solid.DetectorConfig.preset(n).threshold
        out.write(
            f"{n:<8} {c.fov_up:>7g} {c.fov_down:>8g} {c.n_elevation:>6d} {c.n_range:>7d} {c.n_azimuth:>6d} "
            f"{c.min_range:>5g} {c.max_range:>6g} {c.voxel_size:>5g} {thr:>8g}  {sensors.get(n, '')}\n"
        )
    return 0


def cmd_config(args: argparse.Namespace, out: TextIO) -> int:
    from .commands import make_config

    if args.preset is None and args.config is None:
        args.preset = "hdl64"
    out.write(make_config(args).dumps())
    return 0


def cmd_map(args: argparse.Namespace, out: TextIO) -> int:
    from . import commands

    if args.map_command == "build":
        cfg = commands.make_config(args)
        ds, _ = _open(args, sys.stderr, cfg)
        with _progress(args, len(ds), "map build") as bar:
            db, result = commands.build_map(ds, cfg, args.output, threads=args.threads, progress=bar.update, detect=args.detect)
        with_pose = int(sum(1 for p in db.poses if math.isfinite(float(p[0][0]))))
        out.write(f"{len(db)} places ({with_pose} with poses), session {result.session}: wrote {args.output}\n")
        return 0
    if args.map_command == "merge":
        db = commands.merge_maps(args.maps, args.output, args.anchor)
        given = {str(Path(a).absolute()) for a in args.anchor or [] if a != "same"}
        for r in commands.map_anchors(db.metadata):
            pp = r.get("per_place")
            if pp and r.get("source") in given:
                out.write(
                    f"session {r['session']}: {pp['places'] - pp['without_pose']} of {pp['places']} places carried by their own frame's anchor "
                    f"({pp['transforms']} distinct), {pp['without_pose']} merged without a pose (frames no anchor places)\n"
                )
        out.write(f"{len(db)} places in {len(set(int(s) for s in db.sessions))} sessions: wrote {args.output}\n")
        return 0
    if args.map_command == "upgrade":
        done = commands.upgrade_map(args.map, args.output)
        b, a = done["before"], done["after"]
        out.write(f"{a['file']}: format {b['format_version']} → {a['format_version']}, {b['bytes']} → {a['bytes']} bytes, {a['places']} places\n")
        return 0
    info = commands.map_info(args.map)
    if args.json:
        out.write(json.dumps(info, indent=1) + "\n")
        return 0
    out.write(f"{info['file']}: {info['places']} places, {info['bytes']} bytes (format {info['format_version']}), config fingerprint {info['fingerprint']}\n")
    if info["places_with_cloud"]:
        out.write(f"clouds for verification: {info['places_with_cloud']} places, {info['cloud_bytes_per_place']:.0f} bytes per place\n")
    out.write("config: " + ", ".join(f"{k}={v}" for k, v in info["config"].items()) + "\n")
    out.write(f"scans clipped: {commands.describe_clip(info['clip'])}\n")
    for s in info["sessions"]:
        span = s["time_span_s"]
        span_s = f", times {span[0]:.3f}–{span[1]:.3f} s" if span else ""
        out.write(f"  session {s['session']}: {s['places']} places, {s['with_pose']} with poses{span_s}\n")
    return 0


def cmd_bench(args: argparse.Namespace, out: TextIO) -> int:
    from . import commands

    cfg = commands.make_config(args)
    out.write(commands.bench(args.sequence, cfg, frames=args.n_frames, db_size=args.db_size, threads=args.threads, format=args.format, topic=args.topic) + "\n")
    return 0


# ---- entry point -------------------------------------------------------------------------------


def main(argv: AbcSequence[str] | None = None) -> int:
    """Run the ``solid`` command; returns the exit code (argparse exits with 2 on usage errors)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["ros2"]:
        # The node and the player take ROS's own arguments (--ros-args ...): they parse their own.
        from .ros2 import main as ros2_main

        return ros2_main(argv[1:])
    parser = build_parser()
    args = parser.parse_args(argv)
    out = sys.stdout
    handlers: dict[str, Callable[[argparse.Namespace, TextIO], int]] = {
        "describe": cmd_describe,
        "demo": cmd_demo,
        "detect": cmd_detect,
        "localize": cmd_localize,
        "eval": cmd_eval,
        "optimize": cmd_optimize,
        "view": cmd_view,
        "presets": cmd_presets,
        "config": cmd_config,
        "map": cmd_map,
        "bench": cmd_bench,
    }
    import warnings

    def one_line(message: Any, category: Any, filename: str, lineno: int, file: Any = None, line: Any = None) -> None:
        print(f"solid {args.command}: warning: {message}", file=sys.stderr)

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("default", UserWarning)
            warnings.showwarning = one_line
            code = handlers[args.command](args, out)
            out.flush()  # here, where a reader that left is told apart (below)
            return code
    except KeyboardInterrupt:
        print("solid: interrupted (no partial results were left)", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader left (`solid map info | head`): stop quietly, as a command killed by SIGPIPE
        # would, and keep Python's final flush of stdout from failing again.
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return 141
    except (ValueError, OSError, ImportError, MemoryError, RecursionError) as e:
        if getattr(args, "debug", False):
            traceback.print_exc()
        msg = str(e) or type(e).__name__
        if isinstance(e, MemoryError):
            msg = f"out of memory ({msg})"
        if isinstance(e, OSError) and e.filename and str(e.filename) not in msg:
            msg = f"{e.filename}: {msg}"
        print(f"solid {args.command}: error: {msg.splitlines()[0] if msg else type(e).__name__}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
