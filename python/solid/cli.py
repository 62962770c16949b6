"""The ``solid`` command line: describe scans, detect loops, evaluate against poses, benchmark.

Run ``solid --help`` or ``solid <command> --help`` for the options and examples. Exit codes: 0 on
success, 2 for a usage error (bad or missing arguments), 1 for any other failure (a missing or
corrupt file, an invalid parameter), reported as one line on stderr (``--debug`` shows the
traceback instead).
"""

from __future__ import annotations

import argparse
import csv
import io as _io
import json
import math
import os
import sys
import time
import traceback
from collections.abc import Iterator, Sequence as AbcSequence
from pathlib import Path
from typing import Any, NoReturn, TextIO

import numpy as np
import numpy.typing as npt

from . import io as sio

__all__ = ["main"]

CONFIG_FIELDS = (
    "n_range",
    "n_azimuth",
    "n_elevation",
    "fov_up",
    "fov_down",
    "min_range",
    "max_range",
    "voxel_size",
)
_INT_FIELDS = {"n_range", "n_azimuth", "n_elevation"}

F32 = npt.NDArray[np.float32]


class UserError(Exception):
    """A problem with the user's input: reported as one line, exit code 1."""


# --------------------------------------------------------------------------------------------
# argument parsing

_EPILOG_MAIN = """\
examples:
  solid presets
  solid describe 000000.bin --preset hdl64
  solid detect  ~/data/kitti/00 --preset hdl64 --output out/
  solid eval    ~/data/kitti/00 --poses poses.txt --calib calib.txt --preset hdl64 --radius 10 --baseline scancontext
  solid eval    hku1-avia --poses odom_poses.txt --preset avia --exclude 50 --radius 3
  solid config dump --preset avia --max-range 40 > avia40.json
  solid eval    hku1-avia --poses odom_poses.txt --config avia40.json
  solid bench   ~/data/kitti/00/velodyne --preset hdl64

A SEQUENCE is a folder of scans (.bin .pcd .ply .npy .npz, natural order; a velodyne/ or Scans/
sub-folder is used when present), a ROS 1 bag, a ROS 2 bag folder or an MCAP file
(pip install solid-lidar[ros]). Exit codes: 0 ok, 1 failure, 2 usage error.
"""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        self.print_usage(sys.stderr)
        self.exit(2, f"{self.prog}: error: {message}\n")


def _add_config_args(p: argparse.ArgumentParser, preset_required: bool = False) -> None:
    g = p.add_argument_group("descriptor configuration (SPEC §1; flags override --config, which overrides --preset)")
    g.add_argument("--preset", help="sensor preset (see `solid presets`), e.g. hdl64, vlp16, avia")
    g.add_argument("--config", type=Path, metavar="FILE", help="JSON written by `solid config dump`")
    for name in CONFIG_FIELDS:
        g.add_argument(
            "--" + name.replace("_", "-"),
            type=int if name in _INT_FIELDS else float,
            default=None,
            metavar="N" if name in _INT_FIELDS else "X",
        )


def _add_reader_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("reading")
    g.add_argument("--format", choices=[f for f in sio.FORMATS], help="force the scan reader (default: from the path)")
    g.add_argument("--topic", help="PointCloud2 topic of a bag (default: the only one)")


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    p.add_argument("--debug", action="store_true", help="show tracebacks for errors")


def build_parser() -> argparse.ArgumentParser:
    """The argparse parser of the ``solid`` command."""
    try:
        from importlib.metadata import version as _dist_version

        version = _dist_version("solid-lidar")
    except Exception:  # not installed as a distribution (e.g. a source checkout)
        version = "unknown"

    parser = _Parser(
        prog="solid",
        description="SOLiD LiDAR place recognition: descriptors, loop detection and evaluation.",
        epilog=_EPILOG_MAIN,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"solid {version}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    fmt = argparse.RawDescriptionHelpFormatter

    p = sub.add_parser(
        "describe",
        help="print the descriptor of one scan as JSON",
        formatter_class=fmt,
        epilog="examples:\n  solid describe 000000.bin --preset hdl64\n  solid describe scan.pcd --preset avia --max-range 40 -o d.json\n",
    )
    p.add_argument("scan", type=Path, help="a scan file")
    p.add_argument("-o", "--output", type=Path, help="write the JSON here instead of stdout")
    _add_config_args(p)
    _add_reader_args(p)
    _add_common(p)

    p = sub.add_parser(
        "detect",
        help="run the online loop detector over a sequence; writes loops.csv",
        formatter_class=fmt,
        epilog="examples:\n  solid detect ~/kitti/00 --preset hdl64 --output out/\n"
        "  solid detect run.bag --topic /points --preset os1-64 --threshold 0.08\n",
    )
    p.add_argument("sequence", type=Path)
    p.add_argument("-o", "--output", type=Path, default=Path("solid_results"), help="output folder (default: solid_results)")
    p.add_argument("--exclude", type=int, default=50, help="ignore the N most recent frames (default 50)")
    p.add_argument("--threshold", type=float, default=0.1, help="accept a loop when the cosine distance ≤ this (default 0.1)")
    p.add_argument("--top-k", type=int, default=10, help="candidates the detector considers (default 10)")
    p.add_argument("--timestamps", type=Path, help="timestamps file (one per line)")
    p.add_argument("--no-rerank", action="store_true", help="do not re-rank candidates by A-SOLiD alignment")
    _add_config_args(p)
    _add_reader_args(p)
    _add_common(p)

    p = sub.add_parser(
        "eval",
        help="evaluate loop closure against poses (SPEC §5): metrics.json, CSV, PR/ROC plots",
        formatter_class=fmt,
        epilog="examples:\n"
        "  solid eval hku1-avia --poses odom_poses.txt --preset avia --exclude 50 --radius 3 --baseline scancontext\n"
        "  solid eval ~/kitti/00 --poses poses.txt --calib calib.txt --preset hdl64 --radius 10 --fov 60\n"
        "  solid eval ~/kitti/00 --poses poses.txt --preset hdl64 --frames 0:1000 --subsample-m 1\n"
        "\nThe exclusion window counts frames of the evaluated selection (after --frames/--subsample-m).\n"
        "A relative --poses path that does not exist is looked up inside SEQUENCE.\n",
    )
    p.add_argument("sequence", type=Path)
    p.add_argument("--poses", type=Path, required=True, help="KITTI 3×4 rows or TUM (t x y z qx qy qz qw), one per scan")
    p.add_argument(
        "--calib",
        type=Path,
        metavar="FILE",
        help="sensor → pose-frame extrinsic: a KITTI calib.txt ('Tr:' line; KITTI poses are camera poses) or 12 numbers",
    )
    p.add_argument("--exclude", type=int, default=50, help="exclusion window in frames (default 50)")
    p.add_argument("--radius", type=float, default=5.0, help="a match is correct within this many metres (default 5)")
    p.add_argument("-o", "--output", type=Path, default=None, help="output folder (default: solid_results/<sequence>)")
    p.add_argument("--baseline", action="append", choices=["scancontext"], default=[], help="also evaluate this baseline")
    p.add_argument("--sc-max-range", type=float, default=None, help="Scan Context max range (default: the SOLiD max_range)")
    p.add_argument("--sc-height-offset", type=float, default=2.0, help="added to z before max height (default 2.0 m)")
    p.add_argument("--frames", default=None, metavar="SPEC", help="frames to use, e.g. 0:60,284:314 (Python slices)")
    p.add_argument("--subsample-m", type=float, default=None, metavar="M", help="keep one frame per M metres travelled")
    p.add_argument("--fov", type=float, default=None, metavar="DEG", help="clip every scan to this horizontal FOV")
    p.add_argument("--fov-center", type=float, default=0.0, metavar="DEG", help="centre of --fov (default 0 = +x)")
    p.add_argument("--occlude", type=float, default=None, metavar="DEG", help="remove a sector this wide from every scan")
    p.add_argument("--occlude-center", type=float, default=0.0, metavar="DEG")
    p.add_argument("--threshold", type=float, default=0.03, help="loop detector distance threshold (default 0.03)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--threads", type=int, default=None, help="threads for describing (default: all cores)")
    _add_config_args(p)
    _add_reader_args(p)
    _add_common(p)

    p = sub.add_parser(
        "demo",
        help="simulate a drive with a loop under a narrow FOV and score SOLiD against the truth",
        formatter_class=fmt,
        epilog="examples:\n  solid demo\n  solid demo --sensor os1-64 --fov 120 -o demo_out\n",
    )
    p.add_argument("-o", "--output", type=Path, default=Path("solid_demo"), help="output folder (default: solid_demo)")
    p.add_argument("--sensor", choices=["hdl64", "vlp16", "os1-64", "avia", "aeva"], default="hdl64", help="simulated sensor (default hdl64)")
    p.add_argument("--fov", type=float, default=60.0, metavar="DEG", help="horizontal field of view (default 60)")
    p.add_argument("--seed", type=int, default=3, help="world seed (default 3)")
    p.add_argument("--laps", type=float, default=1.5, help="laps around the block (default 1.5)")
    p.add_argument("--threshold", type=float, default=0.03, help="loop detector distance threshold (default 0.03)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    _add_common(p)

    p = sub.add_parser("presets", help="list the sensor presets", formatter_class=fmt, epilog="example:\n  solid presets --json\n")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    _add_common(p)

    p = sub.add_parser("config", help="configuration files", formatter_class=fmt)
    csub = p.add_subparsers(dest="config_command", metavar="ACTION", parser_class=_Parser)
    csub.required = True
    d = csub.add_parser(
        "dump",
        help="print a configuration as JSON (to edit and pass back with --config)",
        formatter_class=fmt,
        epilog="example:\n  solid config dump --preset avia --max-range 40 > avia40.json\n",
    )
    _add_config_args(d)
    _add_common(d)

    p = sub.add_parser(
        "bench",
        help="time reading, describing and searching on your data (prints Hz)",
        formatter_class=fmt,
        epilog="examples:\n  solid bench ~/kitti/00/velodyne --preset hdl64\n  solid bench scans/ --preset avia --frames 200 --db-size 5000\n",
    )
    p.add_argument("sequence", type=Path)
    p.add_argument("--frames", type=int, default=200, help="scans to load (default 200)")
    p.add_argument("--db-size", type=int, default=None, help="search a database of this many entries (descriptors repeated)")
    p.add_argument("--threads", type=int, default=None, help="threads for the batch describe (default: all cores)")
    _add_config_args(p)
    _add_reader_args(p)
    _add_common(p)
    return parser


# --------------------------------------------------------------------------------------------
# helpers


def _solid() -> Any:
    import solid

    return solid


def config_dict(cfg: Any) -> dict[str, Any]:
    """The SPEC §1 fields of a SolidConfig as a plain dictionary."""
    return {f: getattr(cfg, f) for f in CONFIG_FIELDS}


def make_config(args: argparse.Namespace, required: bool = True) -> tuple[Any, str | None]:
    """SolidConfig from --preset, then --config FILE, then the per-field flags."""
    solid = _solid()
    fields: dict[str, Any] = {}
    preset: str | None = args.preset
    if args.config is not None:
        try:
            doc = json.loads(Path(args.config).read_text())
        except FileNotFoundError:
            raise UserError(f"{args.config}: no such file") from None
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise UserError(f"{args.config}: not a JSON configuration ({e})") from None
        if not isinstance(doc, dict):
            raise UserError(f"{args.config}: expected a JSON object")
        unknown = set(doc) - set(CONFIG_FIELDS) - {"preset"}
        if unknown:
            raise UserError(f"{args.config}: unknown keys {', '.join(sorted(unknown))} (allowed: preset, {', '.join(CONFIG_FIELDS)})")
        if preset is None:
            preset = doc.get("preset")
        fields.update({k: v for k, v in doc.items() if k != "preset"})
    for f in CONFIG_FIELDS:
        v = getattr(args, f, None)
        if v is not None:
            fields[f] = v
    if preset is None:
        if not required and not fields:
            return None, None
        missing = [f for f in ("fov_up", "fov_down", "n_elevation") if f not in fields]
        if missing:
            raise UserError("give --preset NAME (see `solid presets`) or a --config file with a preset")
        try:
            return solid.SolidConfig(**fields), None
        except TypeError as e:
            raise UserError(f"bad configuration: {e}") from None
    names = sorted(solid.presets())
    if preset not in names:
        raise UserError(f"unknown preset {preset!r}; one of: {', '.join(names)}")
    try:
        return solid.SolidConfig.preset(preset, **fields), preset
    except TypeError as e:
        raise UserError(f"bad configuration: {e}") from None


def _progress(args: argparse.Namespace, total: int | None, desc: str, unit: str = "scan") -> Any:
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, disable=bool(args.quiet), file=sys.stderr, dynamic_ncols=True, leave=False)


def _open_sequence(args: argparse.Namespace, poses: Path | None = None, timestamps: Path | None = None) -> sio.Sequence:
    return sio.Sequence(args.sequence, poses=poses, timestamps=timestamps, format=args.format, topic=args.topic)


def parse_frames(spec: str, n: int) -> list[int]:
    """Frame selection ``"0:60,284:314,300"`` (Python slices and indices, in that order, no repeats)."""
    out: list[int] = []
    seen: set[int] = set()
    for part in spec.split(","):
        part = part.strip()
        if not part:
            continue
        try:
            if ":" in part:
                bits = [int(b) if b.strip() else None for b in part.split(":")]
                if len(bits) > 3:
                    raise ValueError
                idx = list(range(n))[slice(*bits)]
            else:
                i = int(part)
                if not -n <= i < n:
                    raise UserError(f"--frames: frame {i} is out of range for {n} scans")
                idx = [i % n]
        except ValueError:
            raise UserError(f"--frames: cannot parse {part!r} (use e.g. 0:60,284:314)") from None
        for i in idx:
            if i not in seen:
                seen.add(i)
                out.append(i)
    if not out:
        raise UserError(f"--frames {spec!r} selects no scans")
    return out


def _iter_selected(seq: sio.Sequence, idx: AbcSequence[int]) -> Iterator[F32]:
    """Scans idx[0], idx[1], ... read once each (bags are streamed, folders read by index)."""
    if seq.is_bag:
        want = {i: k for k, i in enumerate(idx)}
        buf: dict[int, F32] = {}
        nxt = 0
        for i, pts in enumerate(seq):
            if i in want:
                buf[want[i]] = pts
                while nxt in buf:
                    yield buf.pop(nxt)
                    nxt += 1
            if nxt == len(idx):
                return
    else:
        for i in idx:
            yield seq[i]


def _write_text(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    sio._atomic_write_bytes(path, text.encode())


def _short(v: float) -> float:
    """A float32 value as the shortest decimal that reads back to the same float32."""
    return float(str(np.float32(v)))


# --------------------------------------------------------------------------------------------
# commands


def cmd_describe(args: argparse.Namespace, out: TextIO) -> int:
    solid = _solid()
    cfg, preset = make_config(args)
    pts = sio.read_points(args.scan, args.format, xyz_only=True)
    t0 = time.perf_counter()
    d = solid.describe(pts, cfg)
    dt = time.perf_counter() - t0
    doc = {
        "file": str(args.scan),
        "format": args.format or sio.detect_format(args.scan),
        "preset": preset,
        "config": config_dict(cfg),
        "n_points": int(d.n_points),
        "n_in_range": int(d.n_in_range),
        "n_kept": int(d.n_kept),
        "describe_ms": round(dt * 1e3, 3),
        "r": [_short(v) for v in np.asarray(d.r)],
        "a": [_short(v) for v in np.asarray(d.a)],
    }
    text = json.dumps(doc, indent=1) + "\n"
    if args.output is not None:
        _write_text(args.output, text)
    else:
        out.write(text)
    return 0


def cmd_demo(args: argparse.Namespace, out: TextIO) -> int:
    from . import sim

    m = sim.run_demo(
        args.output,
        seed=args.seed,
        sensor=args.sensor,
        h_fov=args.fov,
        laps=args.laps,
        threshold=args.threshold,
        plots=not args.no_plots,
    )
    out.write(sim.demo_summary(m))
    return 0


def cmd_presets(args: argparse.Namespace, out: TextIO) -> int:
    solid = _solid()
    ps = solid.presets()
    if args.json:
        out.write(json.dumps({n: config_dict(c) for n, c in ps.items()}, indent=1) + "\n")
        return 0
    sensors: dict[str, str] = solid.preset_sensors() if hasattr(solid, "preset_sensors") else {}
    head = f"{'name':<8} {'fov_up':>7} {'fov_down':>8} {'n_elev':>6} {'n_range':>7} {'n_azim':>6} {'min_r':>5} {'max_r':>6} {'voxel':>5}  sensor"
    out.write(head + "\n")
    for n, c in ps.items():
        out.write(
            f"{n:<8} {c.fov_up:>7g} {c.fov_down:>8g} {c.n_elevation:>6d} {c.n_range:>7d} {c.n_azimuth:>6d} "
            f"{c.min_range:>5g} {c.max_range:>6g} {c.voxel_size:>5g}  {sensors.get(n, '')}\n"
        )
    return 0


def cmd_config(args: argparse.Namespace, out: TextIO) -> int:
    solid = _solid()
    cfg, preset = make_config(args, required=False)
    if cfg is None:
        cfg = solid.SolidConfig.preset("hdl64")
        preset = "hdl64"
    doc: dict[str, Any] = {"preset": preset} if preset else {}
    doc.update(config_dict(cfg))
    out.write(json.dumps(doc, indent=2) + "\n")
    return 0


def _describe_all(args: argparse.Namespace, seq: sio.Sequence, idx: list[int], cfg: Any, sc_cfg: Any | None) -> tuple[F32, F32, npt.NDArray[np.float64] | None]:
    solid = _solid()
    from . import scancontext as sc

    R: list[F32] = []
    A: list[F32] = []
    S: list[npt.NDArray[np.float64]] = []
    batch: list[F32] = []
    threads = getattr(args, "threads", None)

    def flush() -> None:
        if not batch:
            return
        for d in solid.describe_batch(batch, cfg, threads=threads):
            R.append(np.asarray(d.r, dtype=np.float32))
            A.append(np.asarray(d.a, dtype=np.float32))
        batch.clear()

    with _progress(args, len(idx), "describe") as bar:
        for pts in _iter_selected(seq, idx):
            if args.fov is not None:
                pts = sio.clip_fov(pts, args.fov, args.fov_center)
            if args.occlude is not None:
                pts = sio.occlude_sector(pts, args.occlude, args.occlude_center)
            batch.append(np.ascontiguousarray(pts[:, :3]))
            if sc_cfg is not None:
                S.append(sc.describe(pts, sc_cfg))
            if len(batch) >= 64:
                flush()
            bar.update(1)
        flush()
    return np.stack(R), np.stack(A), (np.stack(S) if sc_cfg is not None else None)


def cmd_eval(args: argparse.Namespace, out: TextIO) -> int:
    from . import evaluation as ev
    from . import scancontext as sc

    cfg, preset = make_config(args)
    if args.exclude < 0:
        raise UserError("--exclude must be >= 0")
    if not args.radius > 0:
        raise UserError("--radius must be > 0")
    seq = _open_sequence(args, poses=args.poses)
    assert seq.poses is not None
    idx = parse_frames(args.frames, len(seq)) if args.frames else list(range(len(seq)))
    if args.subsample_m is not None:
        keep = sio.subsample_by_distance(seq.poses[idx], args.subsample_m)
        idx = [idx[int(k)] for k in keep]
    if len(idx) <= args.exclude + 1:
        raise UserError(f"{len(idx)} frames leave no query with an exclusion window of {args.exclude}")
    poses = seq.poses[idx]
    if args.calib is not None:
        poses = sio.sensor_poses(poses, sio.load_extrinsic(args.calib))
    sc_cfg = None
    if "scancontext" in args.baseline:
        sc_cfg = sc.ScanContextConfig(
            max_range=args.sc_max_range if args.sc_max_range is not None else float(cfg.max_range),
            height_offset=args.sc_height_offset,
        )
    t0 = time.perf_counter()
    R, A, S = _describe_all(args, seq, idx, cfg, sc_cfg)
    t_desc = time.perf_counter() - t0
    nq = len(ev.query_indices(len(idx), args.exclude))
    with _progress(args, nq, "search SOLiD", "query") as bar:
        main_ev = ev.evaluate_solid(R, A, poses, exclude=args.exclude, radius=args.radius, progress=bar.update)
    main_ev.extra["describe_hz"] = round(len(idx) / t_desc, 1) if t_desc > 0 else None
    baselines = []
    if S is not None:
        with _progress(args, nq, "search Scan Context", "query") as bar:
            b = sc.evaluate_scancontext(S, poses, exclude=args.exclude, radius=args.radius, progress=bar.update)
        assert sc_cfg is not None
        b.extra["config"] = {"n_ring": sc_cfg.n_ring, "n_sector": sc_cfg.n_sector, "max_range": sc_cfg.max_range, "height_offset": sc_cfg.height_offset}
        baselines.append(b)
    out_dir = args.output if args.output is not None else Path("solid_results") / Path(args.sequence).resolve().name
    extra: dict[str, Any] = {
        "sequence": str(args.sequence),
        "poses": str(args.poses),
        "preset": preset,
        "config": config_dict(cfg),
        "frames_evaluated": len(idx),
    }
    if args.fov is not None:
        extra["fov_clip_deg"] = [args.fov, args.fov_center]
    if args.occlude is not None:
        extra["occluded_sector_deg"] = [args.occlude, args.occlude_center]
    if args.subsample_m is not None:
        extra["subsample_m"] = args.subsample_m
    if args.calib is not None:
        extra["calib"] = str(args.calib)
    written = ev.write_report(out_dir, main_ev, baselines, extra=extra, plots=not args.no_plots)
    _print_table(out, [main_ev, *baselines])
    out.write(f"wrote {', '.join(str(p) for p in written.values())}\n")
    return 0


def _print_table(out: TextIO, evals: AbcSequence[Any]) -> None:
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
        cells = []
        for k, _ in keys:
            v = m[k]
            cells.append(f"{'n/a':>10}" if v is None else (f"{v:>10d}" if isinstance(v, int) else f"{v:>10.3f}"))
        out.write(f"{e.name:<14}" + "".join(cells) + "\n")


def cmd_detect(args: argparse.Namespace, out: TextIO) -> int:
    solid = _solid()
    if not hasattr(solid, "LoopDetector"):
        raise UserError("this build of solid has no LoopDetector")
    cfg, _ = make_config(args)
    seq = _open_sequence(args, timestamps=args.timestamps)
    kwargs: dict[str, Any] = {"exclude_recent": args.exclude, "threshold": args.threshold, "top_k": args.top_k}
    if args.no_rerank:
        kwargs["rerank"] = False
    det = solid.LoopDetector(cfg, **kwargs)
    rows: list[tuple[int, int, float, float]] = []
    t0 = time.perf_counter()
    with _progress(args, len(seq), "detect") as bar:
        for i, pts in enumerate(seq):
            ts = None if seq.timestamps is None else float(seq.timestamps[i])
            loop = det.add(pts, timestamp=ts)
            if loop is not None:
                rows.append((int(loop.query), int(loop.candidate), float(loop.distance), float(loop.heading)))
                bar.set_postfix(loops=len(rows), refresh=False)  # shown at the next regular redraw
            bar.update(1)
    dt = time.perf_counter() - t0
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["query", "candidate", "distance", "heading_deg"])
    for q, c, d, h in rows:
        w.writerow([q, c, f"{d:.6f}", f"{h:.3f}"])
    path = Path(args.output) / "loops.csv"
    _write_text(path, buf.getvalue())
    rate = len(seq) / dt if dt > 0 else math.inf
    out.write(f"{len(seq)} scans, {len(rows)} loops (threshold {args.threshold}, exclude {args.exclude}), {rate:.1f} Hz\n")
    out.write(f"wrote {path}\n")
    return 0


def cmd_bench(args: argparse.Namespace, out: TextIO) -> int:
    solid = _solid()
    cfg, preset = make_config(args)
    seq = _open_sequence(args)
    n = min(args.frames, len(seq))
    if n < 1:
        raise UserError("--frames must be >= 1")
    t0 = time.perf_counter()
    scans: list[F32] = []
    with _progress(args, n, "read") as bar:
        for pts in _iter_selected(seq, list(range(n))):
            scans.append(np.ascontiguousarray(pts[:, :3]))
            bar.update(1)
    t_read = time.perf_counter() - t0
    npts = sum(s.shape[0] for s in scans)
    descs = []
    t0 = time.perf_counter()
    with _progress(args, n, "describe") as bar:
        for s in scans:
            descs.append(solid.describe(s, cfg))
            bar.update(1)
    t_desc = time.perf_counter() - t0
    t0 = time.perf_counter()
    solid.describe_batch(scans, cfg, threads=args.threads)
    t_batch = time.perf_counter() - t0
    R = np.stack([np.asarray(d.r, dtype=np.float32) for d in descs])
    db_size = args.db_size or n
    reps = -(-db_size // n)
    Rdb = np.tile(R, (reps, 1))[:db_size]
    lines = [
        f"sequence   {args.sequence} ({n} scans, {npts / n:,.0f} points/scan), preset {preset}",
        f"read       {n / t_read:10.1f} Hz   ({t_read / n * 1e3:.2f} ms/scan, {npts / t_read / 1e6:.1f} Mpoints/s)",
        f"describe   {n / t_desc:10.1f} Hz   ({t_desc / n * 1e3:.3f} ms/scan, single thread)",
        f"batch      {n / t_batch:10.1f} Hz   (describe_batch, threads={args.threads or 'all'})",
    ]
    nq = min(n, 200)
    if hasattr(solid, "Database"):
        db = solid.Database(cfg)
        t0 = time.perf_counter()
        for i in range(db_size):
            db.add(descs[i % n])
        t_add = time.perf_counter() - t0
        t0 = time.perf_counter()
        for d in descs[:nq]:
            db.search(d, k=1)
        t_s = time.perf_counter() - t0
        lines.append(f"db add     {db_size / t_add:10.1f} Hz   ({db_size} entries)")
        lines.append(f"search     {nq / t_s:10.1f} Hz   (solid.Database, top-1 over {db_size} entries)")
    U = Rdb / np.maximum(np.linalg.norm(Rdb, axis=1, keepdims=True), 1e-30)
    t0 = time.perf_counter()
    for r in R[:nq]:
        int(np.argmax(U @ (r / max(float(np.linalg.norm(r)), 1e-30))))
    t_np = time.perf_counter() - t0
    lines.append(f"search     {nq / t_np:10.1f} Hz   (numpy brute force baseline, top-1 over {db_size} entries)")
    out.write("\n".join(lines) + "\n")
    return 0


# --------------------------------------------------------------------------------------------
# entry point


def main(argv: AbcSequence[str] | None = None) -> int:
    """Run the ``solid`` command; returns the exit code (argparse exits with 2 on usage errors)."""
    parser = build_parser()
    args = parser.parse_args(None if argv is None else list(argv))
    out = sys.stdout
    handlers = {
        "describe": cmd_describe,
        "demo": cmd_demo,
        "detect": cmd_detect,
        "eval": cmd_eval,
        "presets": cmd_presets,
        "config": cmd_config,
        "bench": cmd_bench,
    }
    try:
        return handlers[args.command](args, out)
    except KeyboardInterrupt:
        print("solid: interrupted", file=sys.stderr)
        return 130
    except (UserError, ValueError, OSError, ImportError) as e:
        if getattr(args, "debug", False):
            traceback.print_exc()
        msg = str(e) or type(e).__name__
        if isinstance(e, OSError) and e.filename and str(e.filename) not in msg:
            msg = f"{e.filename}: {msg}"
        print(f"solid {args.command}: error: {msg.splitlines()[0] if msg else type(e).__name__}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
