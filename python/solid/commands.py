"""What the ``solid`` commands do, callable from Python: run the pipeline and write its results.

Every function here runs :class:`solid.pipeline.LoopClosurePipeline` once and writes into a fresh
output folder (:mod:`solid.outputs`): ``config.json`` (the whole pipeline configuration),
``loops.csv`` (the accepted loops), and for evaluations ``metrics.json``, ``queries.csv`` and the
plots. ``metrics.json`` records the configuration and the absolute paths of every input.
"""

from __future__ import annotations

import argparse
import math
import os
import json
import shlex
import time
import warnings
from collections.abc import Callable, Sequence as AbcSequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import _solid
from .config import InputOptions, PipelineConfig, descriptor_fields, detector_fields
from .datasets import Dataset, detect_format, open_dataset, read_points
from .datasets.selection import iter_selected
from .evaluation import Evaluation, loop_delay_steps
from .outputs import Output, atomic_write_bytes, output_folder, write_csv, write_json
from .pipeline import DEFAULT_FOV_CENTER, LoopClosurePipeline, PipelineResult, Progress, check_run
from .records import LOOP_COLUMNS, QUERY_COLUMNS, fmt_opt, pose_columns
from .transforms import quaternion

__all__ = [
    "Inputs",
    "bench",
    "build_map",
    "config_and_map",
    "describe_scan",
    "detect",
    "evaluate",
    "make_config",
    "map_info",
    "merge_maps",
    "upgrade_map",
    "open_recording",
    "optimize",
    "write_g2o",
]


@dataclass(frozen=True)
class Inputs:
    """Where the data came from, recorded with absolute paths."""

    sequence: Path
    reader: str | None = None
    poses: Path | None = None
    timestamps: Path | None = None
    calib: Path | None = None
    map: Path | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        def ab(p: Path | None) -> str | None:
            return None if p is None else str(Path(p).absolute())

        d: dict[str, Any] = {
            "sequence": ab(self.sequence),
            "reader": self.reader,
            "poses": ab(self.poses),
            "timestamps": ab(self.timestamps),
            "calib": ab(self.calib),
            "map": ab(self.map),
        }
        d.update(self.extra)
        return d


def open_recording(
    sequence: Path | str,
    *,
    format: str | None = None,
    topic: str | None = None,
    poses: Path | str | None = None,
    timestamps: Path | str | None = None,
    calib: Path | str | None = None,
    map: Path | None = None,
    frames: str | None = None,
) -> tuple[Dataset, Inputs]:
    """Opens a recording for the pipeline (:func:`solid.datasets.open_dataset`; only the
    ``frames`` a run reads need poses); returns it and the record of its inputs: the reader
    chosen and the absolute paths of every file used."""
    ds = open_dataset(sequence, format=format, topic=topic, poses=poses, timestamps=timestamps, calib=calib, frames=frames)
    inputs = Inputs(
        sequence=Path(ds.path),
        reader=ds.reader,
        poses=ds.pose_source,
        timestamps=ds.timestamp_source,
        calib=ds.calib_source,
        map=map,
        extra={"topic": ds.topic} if ds.is_bag else {},  # so that a run's bag opens again alike (solid view)
    )
    return ds, inputs


def make_config(args: argparse.Namespace, base: Any | None = None) -> Any:
    """The pipeline configuration: ``base``, else ``--config FILE``, else ``--preset``; then the
    flags."""
    if base is not None:
        pass
    elif getattr(args, "config", None) is not None:
        base = PipelineConfig.load(args.config)
        if args.preset is not None and args.preset != base.preset_name:
            raise _solid.ConfigError(f"--preset {args.preset} contradicts the preset {base.preset_name!r} of {args.config}")
    elif args.preset is not None:
        base = PipelineConfig.preset(args.preset)
    else:
        raise _solid.ConfigError("give --preset NAME (see `solid presets`) or --config FILE")
    desc = {k: getattr(args, k) for k in descriptor_fields() if getattr(args, k, None) is not None}
    det: dict[str, Any] = {k: getattr(args, k) for k in detector_fields() if getattr(args, k, None) is not None}
    gate = {f: getattr(args, "gate_" + f) for f in base.detector.gate.to_dict() if getattr(args, "gate_" + f, None) is not None}
    if gate:
        det["gate"] = gate  # overrides of the configuration's gate
    if getattr(args, "threshold", None) is not None and det.get("verify", base.detector.verify):
        raise _solid.ConfigError(
            "--threshold applies without verification (--no-verify): a verified loop is accepted by the gate; "
            "tighten it with --gate-min-fitness and the other --gate-* options"
        )
    inp = {}
    for key in ("fov", "fov_center", "occlude", "occlude_center", "frames", "subsample_m"):
        v = getattr(args, key, None)
        if v is not None:
            inp[key] = v
    cfg = base
    if desc:
        cfg = cfg.replace(descriptor=cfg.descriptor.replace(**desc))
    if det:
        cfg = cfg.replace(detector=cfg.detector.replace(**det))
    if inp:
        cfg = cfg.replace(input=InputOptions(**{**cfg.input.to_dict(), **inp}))
    evaluation = {k: getattr(args, k) for k in ("radius", "pose_tolerance_m", "pose_tolerance_deg") if getattr(args, k, None) is not None}
    if evaluation:
        cfg = cfg.replace(**evaluation)
    return cfg


def config_and_map(args: argparse.Namespace) -> tuple[Any, Any]:
    """The pipeline configuration and the ``--map`` database (or None). Without ``--preset`` and
    ``--config``, a map's own descriptor configuration is used (and its preset's detector
    defaults when it is a preset's); otherwise the two must agree."""
    if getattr(args, "map", None) is None:
        return make_config(args), None
    m = _solid.Database.load(args.map)
    if args.preset is None and args.config is None:
        base = next(
            (PipelineConfig.preset(n) for n, c in _solid.presets().items() if c == m.config),
            PipelineConfig(descriptor=m.config, detector=_solid.DetectorConfig()),
        )
        cfg = make_config(args, base)
    else:
        cfg = make_config(args)
    if m.config != cfg.descriptor:
        raise _solid.ConfigError(f"{args.map} was built with {m.config!r}; this run asks for {cfg.descriptor!r}")
    check_map_clip(args.map, m, cfg.input)
    return cfg, m


def config_of_reused_loops(args: argparse.Namespace) -> Any | None:
    """The configuration of ``solid optimize --loops RUN`` given without ``--preset`` and
    ``--config``: no scan is read, so none is needed; the run's own ``config.json`` (beside its g2o
    file) is taken when it has one, so that ``--frames`` and the input options select the same
    frames, else a preset's (unused: only the input options matter). None when a preset or a
    config was given."""
    if getattr(args, "loops", None) is None or args.preset is not None or args.config is not None:
        return None
    g2o = reused_loops(args.loops)
    saved = g2o.parent / "config.json"
    # Elsewhere any preset does: its descriptor and detector are not used.
    base = PipelineConfig.load(saved) if g2o.name in ("graph.g2o", "loops.g2o") and saved.is_file() else PipelineConfig.preset("hdl64")
    return make_config(args, base)


def _run(
    dataset: Any,
    config: PipelineConfig,
    map_db: Any | None,
    threads: int | None,
    progress: Progress,
    on_scan: Callable[[int, Any], None] | None = None,
) -> PipelineResult:
    return LoopClosurePipeline(dataset, config, map=map_db, threads=threads, progress=progress, on_scan=on_scan).run()


def _summary(result: PipelineResult, inputs: Inputs, command: str) -> dict[str, Any]:
    t = result.timings
    n = len(result.frames)
    total = t.get("detect_s", 0.0)
    doc: dict[str, Any] = {
        "command": command,
        "solid_version": _solid.__version__,
        "inputs": inputs.to_dict(),
        "config": result.config.to_dict(),
        "frames": n,
        "map_places": result.map_size,
        "session": result.session,
        "loops": len(result.loops()),
        "fov_center_deg": result.fov_center,
        "timing": {
            "detect_s": round(total, 4),
            "hz": round(n / total, 1) if total > 0 else None,
        },
    }
    excl = exclusion_in_metres(result)
    if excl is not None:
        doc["exclusion_median_m"] = excl
    doc["loop_delay_steps"] = loop_delay_steps(result.config.detector)
    doc["rejections"] = rejection_counts(result)
    measured = measured_drift(result)
    if measured is not None:
        doc["odometry_drift_measured"] = measured
    if result.map_size:
        doc["map_anchor"] = anchor_dict(result)
    return doc


ODOMETRY_COLUMNS = ("frame", "source", "chain_frame", "pose")


def write_own_odometry(path: Path, result: PipelineResult) -> dict[str, Any] | None:
    """The detector's own odometry of a run without poses (``Detection.pose`` where
    ``pose_source`` is "chained" or "started", docs/loops.md#without-poses) as CSV: the frame, the
    source, the chain's frame (a new one after each break: poses of different chain frames are
    not related) and the pose ``T_world_sensor`` as the 12 numbers of a KITTI row. Returns the
    summary's ``own_odometry`` (poses, chain frames, scans without a pose), or None (and writes
    nothing) when the run had given poses or no verification."""
    rows, frames, unlinked = [], -1, 0
    for d in result.detections:
        src = d.pose_source
        if src == "given":
            return None
        if src == "started":
            frames += 1
        if d.pose is None:
            unlinked += frames >= 0
            continue
        p = np.asarray(d.pose)[:3, :].reshape(-1)
        rows.append({"frame": result.frame_of(d.query), "source": src, "chain_frame": frames, "pose": " ".join(f"{v:.9g}" for v in p)})
    if not rows:
        return None
    write_csv(path, ODOMETRY_COLUMNS, rows)
    return {"poses": len(rows), "chain_frames": frames + 1, "without_pose": unlinked, "file": path.name}


def anchor_dict(result: Any) -> dict[str, Any] | None:
    """The session's placement in the map for ``summary.json`` (None: not placed): ``transform``
    (T_map_world, 4×4 rows), the supporting ``loops`` and the ``metres`` they span, the recording
    frames of the first and latest, and ``covariance`` (6×6 rows, rotation then translation)."""
    from .localize import placement_of_run

    p = placement_of_run(result)
    return None if p is None else p.to_dict()


def anchor_scope(result: Any) -> dict[str, Any]:
    """The frames the run's placement (``result.map_anchor``) maps — one stretch of the odometry
    between breaks — and, when that is not every frame (the odometry broke), ``notes`` (a list)
    saying so: ``from_frame``, ``to_frame`` (None: through the last), ``stretches`` (how many stretches
    loops into the map placed, each with its own anchor: ``solid localize --json``)."""
    from .localize import placement_of_run

    p = placement_of_run(result)
    if p is None:
        return {}
    out: dict[str, Any] = {"from_frame": p.from_frame, "to_frame": p.to_frame, "stretches": len(result.map_anchors)}
    # The run's first frame (a recording's frames need not be numbered from 0: --frames, or files
    # numbered from where a cut of a longer drive begins).
    first = int(result.frame_ids[0]) if len(result.frame_ids) else 0
    if (first if p.from_frame is None else p.from_frame) > first or p.to_frame is not None:
        out["notes"] = [
            f"the odometry broke: the anchor places frames {p.frames} only, the "
            "other frames lie in other frames of the odometry (each stretch's anchor: solid localize --json, stretches; docs/loops.md#breakdowns)"
        ]
    return out


def partial_anchor(result: Any, what: str) -> str | None:
    """What ``anchor.txt`` says (:data:`PARTIAL_ANCHOR`) when the run's odometry broke, so that
    one transform does not map every frame (``what``: the frames it maps); None otherwise."""
    if not anchor_scope(result).get("notes") and len(result.map_anchors) < 2:
        return None
    return f"it maps {what} only: the odometry broke ({len(result.map_anchors)} of its stretches placed, each with its own anchor)"


def optimize_stretches_note(run: Any, result: Any) -> str:
    """What ``optimize --map`` says when the odometry broke and several stretches were placed:
    each started at its own anchor; frames of a stretch no anchor placed, at the nearest's."""
    note = (
        f"the odometry broke: the optimisation started each of the {run.stretches} stretches loops into the map placed at its own anchor "
        "(anchor.txt holds the first frame's, anchors.kitti each frame's for solid map merge --anchor; docs/loops.md#breakdowns)"
    )
    if run.borrowed:
        from .localize import frame_spans

        spans = frame_spans(result.frame_ids, run.borrowed)
        note += f"; frames {spans} ({len(run.borrowed)}) lie in stretches no anchor placed and started at the nearest placed stretch's"
    return note


def why_no_anchor(result: Any) -> str:
    """Why ``solid optimize --map`` gives no anchor (``metrics.json`` ``anchor_none``, printed
    after "anchor: none"): no verified loop into the map, none that agree on one transform, or
    the optimum kept none of them (the detector's placement, ``map_anchor``, is then not used)."""
    from . import slam

    _, ok = slam.map_loops(result)
    if not ok:
        return "no verified loop into the map"
    if slam.anchor_of_run(result) is None:
        return f"the {len(ok)} verified loops into the map agree on no one transform"
    placed = " (the detector's placement, map_anchor, is not used)" if result.map_anchor is not None else ""
    return f"no verified loop into the map kept: the optimum kept none of the {len(ok)}, so nothing ties the session to the map{placed}"


def describe_anchor(result: Any) -> str:
    """One line saying where (whether) the session was placed in the map."""
    a = anchor_dict(result)
    if a is None:
        return "not placed in the map: too few loops into it agree with each other (no loop into the map is accepted before)"
    t = a["transform"]
    notes = anchor_scope(result).get("notes", [])
    return (
        f"placed in the map from frame {a['first_frame']} by {a['loops']} consistent loops over {a['metres']:.0f} m "
        f"(map <- session translation {t[0][3]:.2f}, {t[1][3]:.2f}, {t[2][3]:.2f} m; summary.json map_anchor)"
        + "".join(f"; {n}" for n in notes)
    )


#: How :attr:`solid.Candidate.rejection` names the odometry check's rejections.
ODOMETRY_REJECTION = "disagrees with the odometry"


def rejection_counts(result: PipelineResult) -> dict[str, int]:
    """How many registered candidates of the run each reason turned down (the reasons of
    :attr:`solid.Candidate.rejection`, by name; ``summary.json``/``metrics.json``
    ``rejections``): where the run's candidates went."""
    counts: dict[str, int] = {}
    for d in result.detections:
        for c in d.candidates:
            r = c.rejection
            if r is not None:
                r = r.split(": ", 1)[-1] if r.startswith("place ") else r  # "place N: its stored cloud ..."
                counts[r] = counts.get(r, 0) + 1
    return dict(sorted(counts.items()))


#: How :attr:`solid.Candidate.rejection` begins for a loop held until loops agree on a placement
#: (into a map, or across a break of the odometry).
NOT_PLACED_REJECTION = "not placed yet"


def measured_drift(result: PipelineResult) -> dict[str, float] | None:
    """The odometry's drift as the run's accepted loops within the session measure it: each loop's
    offset from the relative pose the poses predict, beyond the odometry check's constant part
    (``odometry_translation_m``, ``odometry_rotation_deg``; the translation also beyond the
    displacement the rotation the two differ by predicts, ``ω × arm``, as the check allows: docs/spec.md
    §8), per metre of path between its two places; the 90th percentile over the loops (``drift``:
    a fraction of the path, ``rotation_deg_per_m``), the largest rotation offset
    (``rotation_max_deg``) and how many (``loops``). None without poses or loops within the
    session."""
    P = result.poses
    if P is None or len(P) < 2:
        return None
    P = np.asarray(P, dtype=np.float64)
    path = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P[:, :, 3], axis=0), axis=1))]
    d = result.config.detector
    trans, rot, turned = [], [], []
    for lp in result.loops():
        q, c = lp.query - result.map_size, lp.candidate - result.map_size
        if lp.pose is None or not (0 <= c < len(P) and 0 <= q < len(P)) or path[q] - path[c] <= 0:
            continue
        Rq, Rc = P[q, :, :3], P[c, :, :3]
        R_exp, t_exp = Rq.T @ Rc, Rq.T @ (P[c, :, 3] - P[q, :, 3])
        T = np.asarray(lp.pose, dtype=np.float64)
        cos = (np.trace(R_exp.T @ T[:3, :3]) - 1.0) / 2.0
        deg = float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
        walked = float(path[q] - path[c])
        m = float(np.linalg.norm(t_exp - T[:3, 3] - np.asarray(_solid._drift_swing(R_exp, T[:3, :3], P[c : q + 1, :, 3], Rq))))
        trans.append(max(0.0, m - d.odometry_translation_m) / walked)
        rot.append(max(0.0, deg - d.odometry_rotation_deg) / walked)
        turned.append(deg)
    if not trans:
        return None
    return {
        "loops": len(trans),
        "drift": float(np.quantile(trans, 0.9)),
        "rotation_deg_per_m": float(np.quantile(rot, 0.9)),
        "rotation_max_deg": float(max(turned)),
    }


def advice(metrics: dict[str, Any], detector: Any) -> list[str]:
    """Lines that tell a user what a run's figures suggest trying: when the odometry check turned
    down many registered candidates against few loops, the odometry may drift more than its
    bounds assume, and the drift the accepted loops measure (``odometry_drift_measured``) says by
    how much (docs/loops.md#when-the-odometry-drifts); when many waited for a placement, the
    session was not placed in its map, or its odometry broke down (docs/loops.md#breakdowns)."""
    rejections = metrics.get("rejections", {})
    n = int(rejections.get(ODOMETRY_REJECTION, 0))
    loops = int(metrics.get("loops", 0))
    lines = []
    if detector.odometry_check and n >= 10 and n > 2 * loops:
        line = (
            f"note: the odometry check turned down {n} registered candidates against {loops} loops accepted. If the odometry "
            f"drifts more than its bounds assume ({detector.odometry_drift:g} of the path, {detector.odometry_rotation_deg_per_m:g}°/m), "
            "true revisits are among them: try a larger --odometry-drift and --odometry-rotation-deg-per-m"
        )
        m = metrics.get("odometry_drift_measured")
        if m is not None:
            line += (
                f"; the {m['loops']} accepted loops measure it at {m['drift']:.3g} of the path and {m['rotation_deg_per_m']:.3g}°/m "
                f"(90th percentile), up to {m['rotation_max_deg']:.3g}° off (the ceiling: {detector.odometry_rotation_max_deg:g}°)"
            )
            wider = [
                f"--{name} {value:.2g}"
                for name, value, now in (
                    ("odometry-drift", m["drift"], detector.odometry_drift),
                    ("odometry-rotation-deg-per-m", m["rotation_deg_per_m"], detector.odometry_rotation_deg_per_m),
                    ("odometry-rotation-max-deg", m["rotation_max_deg"], detector.odometry_rotation_max_deg),
                )
                if value > now
            ]
            if wider:
                line += ": " + " ".join(wider)
        lines.append(line + " (docs/loops.md#when-the-odometry-drifts)")
    held = sum(int(v) for k, v in rejections.items() if k.startswith(NOT_PLACED_REJECTION))
    if held >= 10 and held > 2 * loops:
        lines.append(
            f"note: {held} registered candidates waited for a placement against {loops} loops accepted: loops into a map, and "
            "loops across a break of the odometry (a step far longer and faster than the session's own), are accepted only once "
            f"{detector.placement_loops} of them agree over {detector.placement_m:g} m with no rival as large. With a map, the "
            "session may not visit it; without one, check the odometry for jumps (docs/loops.md#breakdowns)"
        )
    return lines


def exclusion_in_metres(result: PipelineResult) -> float | None:
    """The median path length, in metres, that the frame exclusion window covers on this run
    (how far back ``exclude_frames`` reaches); None without poses."""
    k = result.config.detector.exclude_frames
    P = result.poses
    if P is None or k == 0 or len(P) <= k:
        return None
    steps = np.linalg.norm(np.diff(P[:, :, 3], axis=0), axis=1)
    cum = np.r_[0.0, np.cumsum(steps)]
    return float(np.median(cum[k:] - cum[:-k]))


def _write_common(out: Output, result: PipelineResult) -> None:
    result.config.dump(out.work / "config.json")
    write_csv(out.work / "loops.csv", LOOP_COLUMNS, result.loop_rows())


def detect(
    dataset: Any,
    config: PipelineConfig,
    inputs: Inputs,
    *,
    output: Path | None = None,
    map_db: Any | None = None,
    threads: int | None = None,
    progress: Progress = None,
    g2o: Path | None = None,
) -> tuple[PipelineResult, Path]:
    """``solid detect``: the accepted loops in ``loops.csv``, the run in ``summary.json``; with
    ``g2o``, the run's pose graph in that file too (:func:`write_g2o`)."""
    if g2o is not None and Path(g2o).exists():
        raise FileExistsError(f"{g2o} exists: choose another file name or remove it")
    result = _run(dataset, config, map_db, threads, progress)
    with output_folder(output, "detect", inputs.sequence.name) as out:
        _write_common(out, result)
        doc = _summary(result, inputs, "detect")
        own = write_own_odometry(out.work / "odometry.csv", result)
        if own is not None:
            doc["own_odometry"] = own
        write_json(out.work / "summary.json", doc)
        if g2o is not None:
            write_g2o(out.work / "loops.g2o", result, calib=_extrinsic(inputs))
    if g2o is not None:
        atomic_write_bytes(Path(g2o), (out.final / "loops.g2o").read_bytes())
    return result, out.final


def localize(
    dataset: Any,
    config: PipelineConfig,
    inputs: Inputs,
    map_db: Any,
    *,
    output: Path | None = None,
    threads: int | None = None,
    progress: Progress = None,
) -> tuple[PipelineResult, dict[str, Any], Path | None]:
    """``solid localize``: the recording run against a saved map and its placement there
    (:func:`solid.localize.placement_of_run`) as a dict (``placed`` False when not placed); with
    ``output``, a folder with ``placement.json``, ``loops.csv``, ``config.json`` and, when placed,
    ``anchor.txt`` (``T_map_odom`` as one KITTI 3×4 row: ``solid map merge --anchor``'s file) and
    ``anchors.kitti`` (each frame's, :func:`solid.localize.frame_anchors_of_run`).
    The placement maps the frames ``from_frame``–``to_frame`` (one stretch of the odometry between
    breaks; ``to_frame`` None: through the last frame); ``stretches`` lists the placement of each
    stretch that loops into the map placed (one, unless the odometry broke). When the placement
    does not map every frame, ``partial_anchor`` says so (else None), as does ``anchor.txt``
    (:data:`PARTIAL_ANCHOR`), and ``solid map merge`` takes ``anchors.kitti`` instead."""
    from .localize import placement_of_run, placements_of_run

    if getattr(dataset, "poses", None) is None:
        raise _solid.ConfigError("placing a session in a map needs its poses (its odometry): give --poses")
    result = _run(dataset, config, map_db, threads, progress)
    p = placement_of_run(result)
    base = result.map_size
    doc: dict[str, Any] = {"placed": False} if p is None else p.to_dict()
    doc.update(
        frames=len(result.frames),
        map_places=base,
        loops_into_map=sum(1 for lp in result.loops() if int(lp.candidate) < base),
        loops_in_session=sum(1 for lp in result.loops() if int(lp.candidate) >= base),
        rejections=rejection_counts(result),
        stretches=[s.to_dict() for s in placements_of_run(result)],
    )
    if p is not None:
        doc["partial_anchor"] = partial_anchor(result, f"frames {p.frames}")
    if output is None:
        return result, doc, None
    with output_folder(output, "localize", inputs.sequence.name) as out:
        _write_common(out, result)
        write_json(out.work / "placement.json", _summary(result, inputs, "localize") | {"placement": doc})
        if p is not None:
            from .localize import frame_anchors_of_run

            write_anchor_files(out.work, p.transform, frame_anchors_of_run(result), doc["partial_anchor"], inputs.sequence.name)
    return result, doc, out.final


def write_g2o(path: Path, result: PipelineResult, calib: Any | None = None, noise: Any | None = None) -> int:
    """The run's whole pose graph in g2o's text form (:class:`solid.slam.PoseGraph`): a
    ``VERTEX_SE3:QUAT`` per frame (id = its frame index, as in ``loops.csv``; initial value = its
    pose), ``EDGE_SE3:QUAT`` odometry edges between consecutive frames (``noise``, a
    :class:`solid.slam.OdometryNoise`) and one per verified loop with the registration's
    information (:attr:`solid.Loop.information`). With ``calib`` (the sensor → pose-frame
    extrinsic, 4×4), in the frame of the given poses. Without poses, the loop edges alone (ids
    still frame indices). Returns the edges written."""
    from . import slam

    graph = slam.graph_from_run(result, noise)
    if calib is not None:
        graph = graph.in_frame(calib)
    return graph.write_g2o(path)


@dataclass
class EvalRun:
    """What ``solid eval`` produced."""

    result: PipelineResult
    evaluations: list[Evaluation]
    folder: Path
    metrics: dict[str, Any]


def evaluate(
    dataset: Any,
    config: PipelineConfig,
    inputs: Inputs,
    *,
    output: Path | None = None,
    map_db: Any | None = None,
    scancontext: Any | None = None,
    plots: bool = True,
    threads: int | None = None,
    progress: Progress = None,
    command_hint: AbcSequence[str] | None = None,
    extra: dict[str, Any] | None = None,
    write_more: Callable[[Path, PipelineResult, list[Evaluation]], None] | None = None,
    anchor: Any | None = None,
) -> EvalRun:
    """``solid eval``: the pipeline's own candidates scored against poses (docs/spec.md §5).

    ``scancontext`` (a :class:`solid.scancontext.ScanContextConfig`) adds the baseline, asked the
    same questions (the same queries, each with the same places to choose from). ``extra`` is
    added to ``metrics.json``; ``write_more(folder, result, evaluations)`` writes further files
    into the output folder before it appears. Against a map, the session is placed in the map's
    world first (:func:`place_in_map` with ``anchor``: a path (``str`` or ``os.PathLike``) is an
    anchor file, :func:`run_anchor`, read and checked against the run's frame count before the
    run; per-frame anchors, from a file or an (N, 4, 4) array, are written to the folder as
    :data:`ANCHORS_FILE`), and ``metrics.json`` says how (``anchor``, its ``notes`` a list). A
    frame no per-frame anchor places (a row of NaN) is left out of the scores, and so is a query
    with a candidate of such a frame (``unknown`` of :func:`solid.evaluation.evaluate_detections`):
    listed in ``anchor.per_frame`` (``unplaced_frames``, ``left_out_queries``) and its notes.
    """
    if getattr(dataset, "poses", None) is None:
        raise _solid.ConfigError("evaluation needs poses (give --poses)")
    sc_desc: list[Any] = []
    on_scan = None
    if scancontext is not None:
        if map_db is not None:
            raise _solid.ConfigError("the Scan Context baseline cannot be evaluated against a map (a map stores SOLiD only)")
        from . import scancontext as sc

        def on_scan(i: int, pts: Any) -> None:
            sc_desc.append(sc.describe(pts, scancontext))

    # An anchor file is read, and per-frame anchors (the file's or an array) checked against the
    # run's frame count by one check, before the run.
    given = Path(anchor) if map_db is not None and isinstance(anchor, (str, os.PathLike)) and anchor != "same" else None
    notes: list[str] = []
    if given is not None:
        anchor, notes = run_anchor(given, len(check_run(dataset, config)))
    elif map_db is not None and anchor is not None and not isinstance(anchor, str) and np.ndim(anchor) == 3:
        _check_anchor_frames(anchor, len(check_run(dataset, config)), None)
    result = _run(dataset, config, map_db, threads, progress, on_scan)
    placed = None
    each = None
    unknown: list[int] = []
    if map_db is not None:
        result, placed = place_in_map(result, anchor)
        if placed.get("per_frame") is not None:
            each = np.asarray(anchor, dtype=np.float64)  # the rows given, NaN where none places a frame
            from . import slam

            # The places of the frames no anchor places (place_in_map listed them the same way).
            unknown = [result.map_size + k for k in slam.nearest_placed(each)[1]]
        if given is not None:
            placed["file"] = str(given.absolute())
        if notes or placed.get("notes"):
            placed["notes"] = notes + placed.get("notes", [])
    main = result.evaluate(unknown=unknown)
    if main.left_out.size and placed is not None:
        _note_left_out(placed, result, main.left_out, unknown)
    if main.query.size == 0 and main.left_out.size:
        raise _solid.ConfigError(f"no query left: each of the {main.left_out.size} is of a frame no anchor places or has a candidate there (give anchors that place more frames)")
    if main.query.size == 0:
        raise _solid.ConfigError(
            f"no query: none of the {len(result.frames)} frames has a place to be matched with "
            f"(exclude {config.detector.exclude_frames} frames"
            + (f" and {config.detector.exclude_meters:g} m of path" if config.detector.exclude_meters > 0 and result.poses is not None else "")
            + " leaves none; the path of --frames with gaps runs straight across them); use fewer --exclude-frames, "
            "a smaller --exclude-m or more frames"
        )
    evals = [main]
    if scancontext is not None:
        from . import scancontext as sc

        qs = main.query
        base = sc.evaluate_scancontext(
            np.stack(sc_desc),
            np.asarray(result.database.poses),
            radius=config.radius,
            queries=qs,
            eligible=main.eligible,
            cfg=scancontext,
        )
        evals.append(base)
    metrics = _summary(result, inputs, "eval")
    metrics.update(main.metrics())
    f1, best = main.f1_max()
    if best is not None:
        metrics["best_threshold"] = best
    if placed is not None:
        metrics["anchor"] = placed
    if extra:
        metrics.update(extra)
    if len(evals) > 1:
        metrics["baselines"] = {e.name.lower().replace(" ", ""): e.metrics() for e in evals[1:]}
    with output_folder(output, "eval", inputs.sequence.name) as out:
        _write_common(out, result)
        write_csv(out.work / "queries.csv", QUERY_COLUMNS, main.rows())
        for e in evals[1:]:
            write_csv(out.work / f"queries_{e.name.lower().replace(' ', '')}.csv", QUERY_COLUMNS, e.rows())
        setting = None if best is None else main.setting_for(best, config.detector.verify)
        if best is not None:
            metrics["accepted_at_best_threshold"] = int((main.score <= best).sum())
        if setting is not None:
            metrics["best_setting"] = {setting[0].lstrip("-").replace("-", "_"): setting[1]}
        if setting is not None and command_hint is not None:
            metrics["best_threshold_command"] = " ".join(
                [*map(shlex.quote, command_hint), "--config", shlex.quote(str(out.final / "config.json")), setting[0], repr(setting[1])]
            )
        write_json(out.work / "metrics.json", metrics)
        if each is not None:
            # The per-frame anchors applied, for `solid view` of this run.
            write_frame_anchors(out.work, each, inputs.sequence.name)
        if plots:
            _plots(out, result, evals, inputs)
        if write_more is not None:
            write_more(out.work, result, evals)
    return EvalRun(result, evals, out.final, metrics)


def _note_left_out(placed: dict[str, Any], result: PipelineResult, left_out: Any, unknown: list[int]) -> None:
    """Lists in ``placed`` (metrics.json ``anchor``) the queries :func:`evaluate` left out of the
    scores (``per_frame.left_out_queries``, their frames), with a note for those of placed frames
    (a candidate of theirs is a place of a frame no anchor places)."""
    from .localize import frame_spans

    k = np.asarray(left_out, dtype=np.int64) - result.map_size
    placed["per_frame"]["left_out_queries"] = [int(result.frame_ids[i]) for i in k]
    others = sorted(set(k.tolist()) - {u - result.map_size for u in unknown})
    if others:
        placed.setdefault("notes", []).append(
            f"{len(others)} queries of placed frames (frames {frame_spans(result.frame_ids, others)}) are left out too: a candidate of "
            "theirs is a place of a frame no anchor places (metrics.json anchor.per_frame.left_out_queries)"
        )


def _plots(out: Output, result: PipelineResult, evals: list[Evaluation], inputs: Inputs) -> None:
    from . import plots

    main = evals[0]
    d = result.config.detector
    excl = f"exclude {d.exclude_frames} frames"
    if d.exclude_meters > 0:
        excl += f", {d.exclude_meters:g} m"
    if d.exclude_seconds > 0:
        excl += f", {d.exclude_seconds:g} s"
    sub = f"{inputs.sequence.name}: {excl}, radius {main.radius:g} m, {main.query.size} queries"
    plots.plot_pr_roc(out.work, evals, sub)
    P = np.asarray(result.database.poses, dtype=np.float64)
    plots.plot_trajectory(out.work / "trajectory.png", main, P, np.asarray(result.database.sessions), sub)
    plots.plot_distance_matrix(out.work / "distances.png", main, result.database, sub)
    plots.plot_heading(out.work / "heading.png", main, sub)


def build_map(
    dataset: Any,
    config: PipelineConfig,
    output_file: Path,
    *,
    threads: int | None = None,
    progress: Progress = None,
    session_of: Any | None = None,
    detect: bool = False,
) -> tuple[Any, PipelineResult]:
    """``solid map build``: every scan becomes a place (with its pose and time when known, and
    its compact cloud when the detector verifies), saved as a database file (written atomically;
    an existing file is refused). A map needs no detection within its own session: no scan is
    searched or verified against the others unless ``detect`` is set (``--detect``)."""
    out = Path(output_file)
    if out.exists():
        raise FileExistsError(f"{out} exists: choose another file name or remove it")
    if not detect:
        # Every own place excluded as recent: each step only describes, prepares and stores.
        config = config.replace(detector=config.detector.replace(exclude_frames=max(len(dataset), 1), exclude_meters=0.0, exclude_seconds=0.0))
    result = _run(dataset, config, None, threads, progress)
    db = result.database
    db.metadata = json.dumps({"clip": clip_record(config.input, result.fov_center)})
    db.save(out, replace=False)  # never over a map written meanwhile (no-replace link)
    return db, result


def merge_maps(inputs: AbcSequence[Path], output_file: Path, anchors: AbcSequence[Path | str] | None = None) -> Any:
    """``solid map merge``: one database from several, each input's sessions renumbered to follow
    the previous ones (so that runs stay apart). Poses are only comparable within one world:
    ``anchors`` holds, for each map after the first, ``"same"`` when its poses already are in
    the first map's world, or an anchor file by which its poses are carried into the first map's
    world: ``anchor.txt`` of ``solid localize`` or ``solid optimize --map`` (one KITTI 3×4 row,
    ``T_map_session``, that map's world → the first map's world, applied to every place), or
    ``anchors.kitti`` beside it (one row per frame of that run, applied to the place of that
    frame: a session whose odometry broke has one anchor per stretch; a row of NaN leaves its
    place without a pose; the map must hold one place per frame of the run). An ``anchor.txt``
    that says it maps only some frames (the odometry broke) is refused: one transform would
    misplace the other stretches. The merged map's metadata records, per session, the anchor
    applied (:func:`map_anchors`). Two maps with poses and nothing said about their worlds are
    refused; nothing is written when a map is refused."""
    out = Path(output_file)
    if out.exists():
        raise FileExistsError(f"{out} exists: choose another file name or remove it")
    if not inputs:
        raise _solid.ConfigError("give at least one map to merge")
    given = list(anchors or [])
    if given and len(given) != len(inputs) - 1:
        raise _solid.ConfigError(f"give one --anchor per map after the first: {len(inputs) - 1} maps, {len(given)} anchors")

    # Each anchor read before any map is loaded: a wrong file refuses the merge at once.
    transforms = [None if str(a) == "same" else merge_anchor(Path(a)) for a in given]

    def posed(db: Any) -> bool:
        return bool(np.isfinite(np.asarray(db.poses)).all(axis=(1, 2)).any())

    db = _solid.Database.load(inputs[0])
    first_posed = inputs[0] if posed(db) else None
    record = map_anchors(db.metadata)
    for k, p in enumerate(inputs[1:]):
        other = _solid.Database.load(p)
        if map_clip(other.metadata) != map_clip(db.metadata):
            warnings.warn(
                f"{p} records scans clipped as {describe_clip(map_clip(other.metadata))}, {inputs[0]} as "
                f"{describe_clip(map_clip(db.metadata))}: the merged map keeps the latter's record",
                UserWarning,
                stacklevel=2,
            )
        if posed(other):
            if first_posed is not None and not given:
                raise _solid.ConfigError(
                    f"{first_posed} and {p} both hold poses, each in the world of the run that made it, and nothing says "
                    "those worlds are one: give --anchor FILE for each map after the first (anchor.txt of `solid localize` or `solid optimize "
                    "--map` run on that session against the first map, or anchors.kitti beside it), or --anchor same if they are one world "
                    "(one ground truth, one SLAM map); otherwise keep the maps apart"
                )
            first_posed = first_posed or p
        before = set(int(x) for x in db.sessions)
        T = transforms[k] if given else None
        if T is not None and len(T) > 1 and len(T) != len(other):
            raise _solid.ConfigError(
                f"{given[k]} holds {len(T)} transforms, one per frame of the run that wrote it, and {p} holds {len(other)} places: "
                "they must be one per place, so build that map from the same frames of the same recording (solid map build with the "
                "same --frames as the run), or give the one-row anchor.txt when the session's odometry did not break"
            )
        db.merge(other, new_sessions=True, anchor=None if T is None else (T[0] if len(T) == 1 else T))
        if given:
            source = "same" if T is None else str(Path(given[k]).absolute())
            entry: dict[str, Any] = {"source": source}
            if T is None or len(T) == 1:
                entry["T_map_session"] = (np.eye(4) if T is None else T[0])[:3].tolist()
            else:
                # One per place: the distinct transforms (a stretch's each), and the places none placed.
                placed = T[np.isfinite(T).all(axis=(1, 2))]
                distinct = np.unique(np.round(placed[:, :3].reshape(len(placed), 12), 9), axis=0)
                entry["T_map_session"] = None
                entry["per_place"] = {"places": len(T), "without_pose": int(len(T) - len(placed)), "transforms": int(len(distinct))}
            record += [{"session": n} | entry for n in sorted(set(int(x) for x in db.sessions) - before)]
    if record:
        meta = json.loads(db.metadata) if db.metadata else {}
        db.metadata = json.dumps((meta if isinstance(meta, dict) else {}) | {"anchors": record})
    db.save(out, replace=False)  # never over a map written meanwhile (no-replace link)
    return db


def map_anchors(metadata: str) -> list[dict[str, Any]]:
    """The anchors a merged map records (``solid map merge --anchor``): per session after the
    first map's, ``T_map_session`` (the 3×4 its poses were carried by into the first map's
    world; identity for ``same``; None when each place had its own, ``anchors.kitti``: then
    ``per_place`` gives the ``places``, those merged ``without_pose`` and the distinct
    ``transforms``) and ``source`` (the anchor file, or ``"same"``)."""
    try:
        doc = json.loads(metadata) if metadata else {}
    except ValueError:
        return []
    got = doc.get("anchors") if isinstance(doc, dict) else None
    return list(got) if isinstance(got, list) else []


def map_info(path: Path) -> dict[str, Any]:
    """``solid map info``: what a database file holds, from its header, section table and small
    sections alone (format 3 on: neither descriptors nor clouds are read; older files are read
    whole)."""
    s = _solid.Database.summary(path)
    places, with_cloud, cloud_bytes = s["places"], s["places_with_cloud"], s["cloud_bytes"]
    per = [
        {
            "session": x["session"],
            "places": x["places"],
            "with_pose": x["with_pose"],
            "time_span_s": None if math.isnan(x["first_time"]) else [x["first_time"], x["last_time"]],
        }
        for x in s["sessions"]
    ]
    return {
        "file": str(Path(path).absolute()),
        "bytes": Path(path).stat().st_size,
        "format_version": s["version"],
        "places": places,
        "places_with_cloud": with_cloud,
        "cloud_bytes": cloud_bytes,
        "cloud_bytes_per_place": round(cloud_bytes / with_cloud, 1) if with_cloud else None,
        "config": s["config"].to_dict(),
        "fingerprint": f"{s['fingerprint']:#018x}",
        "sessions": per,
        "clip": map_clip(s["metadata"]),
        "anchors": map_anchors(s["metadata"]),
    }


def clip_record(opts: InputOptions, fov_center: float | None) -> dict[str, Any]:
    """How a run clipped its scans (``fov_center``: the centre it used), as a map records it."""
    return {
        "fov_deg": opts.fov,
        "fov_center_deg": fov_center if opts.fov is not None else None,
        "occlude_deg": opts.occlude,
        "occlude_center_deg": opts.occlude_center if opts.occlude is not None else None,
    }


def map_clip(metadata: str) -> dict[str, Any] | None:
    """The clip a map's metadata records (None: not recorded, as in maps of format 2)."""
    try:
        doc = json.loads(metadata) if metadata else {}
    except ValueError:
        return None
    clip = doc.get("clip") if isinstance(doc, dict) else None
    return clip if isinstance(clip, dict) else None


def describe_clip(clip: dict[str, Any] | None) -> str:
    """A clip record in words."""
    if clip is None:
        return "not recorded (a map written before format 3, or by other means)"
    parts = []
    if clip.get("fov_deg") is not None:
        parts.append(f"--fov {clip['fov_deg']:g}° centred on {clip['fov_center_deg']:g}°")
    if clip.get("occlude_deg") is not None:
        parts.append(f"--occlude {clip['occlude_deg']:g}° centred on {clip['occlude_center_deg']:g}°")
    return ", ".join(parts) if parts else "none (full scans)"


def check_map_clip(map_path: Path, map_db: Any, opts: InputOptions) -> None:
    """Warns when a map records another clip than this run's (its places and this run's scans
    would then cover different sectors)."""
    recorded = map_clip(map_db.metadata)
    if recorded is None:
        return
    centre = DEFAULT_FOV_CENTER if opts.fov is not None and opts.fov_center is None else opts.fov_center
    mine = clip_record(opts, centre)
    if recorded != mine:
        warnings.warn(
            f"{map_path} was built with scans clipped as {describe_clip(recorded)}; this run clips them as "
            f"{describe_clip(mine)}: give the same --fov/--fov-center/--occlude options to compare the same sectors",
            UserWarning,
            stacklevel=2,
        )


def upgrade_map(path: Path, output_file: Path | None = None) -> dict[str, Any]:
    """``solid map upgrade``: rewrites a map in the current file format (in place, atomically,
    unless ``output_file`` is given); returns its ``map_info`` before and after."""
    before = map_info(path)
    out = Path(output_file) if output_file is not None else Path(path)
    if output_file is not None and out.exists():
        raise FileExistsError(f"{out} exists: choose another file name or remove it")
    _solid.Database.load(path).save(out, replace=output_file is None)
    return {"before": before, "after": map_info(out)}


def fmt_metric(v: Any) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "n/a"
    return f"{v:d}" if isinstance(v, int) else f"{v:.3f}"


def _short(v: float) -> float:
    """A float32 value as the shortest decimal that reads back to the same float32."""
    return float(str(np.float32(v)))


def describe_scan(path: Path, config: PipelineConfig, format: str | None = None) -> dict[str, Any]:
    """``solid describe``: one scan's descriptor as a JSON-ready dict."""
    pts = read_points(path, format, xyz_only=True)
    t0 = time.perf_counter()
    d = _solid.describe(pts, config.descriptor)
    dt = time.perf_counter() - t0
    return {
        "file": str(path),
        "format": format or detect_format(path),
        "preset": config.preset_name,
        "config": config.descriptor.to_dict(),
        "n_points": int(d.n_points),
        "n_in_range": int(d.n_in_range),
        "n_kept": int(d.n_kept),
        "describe_ms": round(dt * 1e3, 3),
        "r": [_short(v) for v in np.asarray(d.r)],
        "a": [_short(v) for v in np.asarray(d.a)],
    }


def bench(
    sequence: Path,
    config: PipelineConfig,
    *,
    frames: int = 200,
    db_size: int | None = None,
    threads: int | None = None,
    format: str | None = None,
    topic: str | None = None,
) -> str:
    """``solid bench``: reading, describing and searching rates on the user's data, with numpy's
    brute-force search timed in the same run as the baseline."""
    seq = Dataset(sequence, format=format, topic=topic)
    n = min(frames, len(seq))
    t0 = time.perf_counter()
    scans = [np.ascontiguousarray(p[:, :3]) for p in iter_selected(seq, list(range(n)))]
    t_read = time.perf_counter() - t0
    npts = sum(s.shape[0] for s in scans)
    cfg = config.descriptor
    t0 = time.perf_counter()
    descs = [_solid.describe(s, cfg) for s in scans]
    t_desc = time.perf_counter() - t0
    t0 = time.perf_counter()
    _solid.describe_batch(scans, cfg, threads=threads)
    t_batch = time.perf_counter() - t0
    size = db_size or n
    db = _solid.Database(cfg)
    t0 = time.perf_counter()
    for i in range(size):
        db.add(descs[i % n])
    t_add = time.perf_counter() - t0
    nq = min(n, 200)
    t0 = time.perf_counter()
    for d in descs[:nq]:
        db.search(d, k=1)
    t_s = time.perf_counter() - t0
    R = np.stack([np.asarray(d.r, dtype=np.float32) for d in descs])
    Rdb = np.tile(R, (-(-size // n), 1))[:size]
    U = Rdb / np.maximum(np.linalg.norm(Rdb, axis=1, keepdims=True), 1e-30)
    t0 = time.perf_counter()
    for r in R[:nq]:
        int(np.argmax(U @ (r / max(float(np.linalg.norm(r)), 1e-30))))
    t_np = time.perf_counter() - t0
    return "\n".join(
        [
            f"sequence   {sequence} ({n} scans, {npts / n:,.0f} points/scan), preset {config.preset_name}",
            f"read       {n / t_read:10.1f} Hz   ({t_read / n * 1e3:.2f} ms/scan, {npts / t_read / 1e6:.1f} Mpoints/s)",
            f"describe   {n / t_desc:10.1f} Hz   ({t_desc / n * 1e3:.3f} ms/scan, single thread)",
            f"batch      {n / t_batch:10.1f} Hz   (describe_batch, threads={threads or 'all'})",
            f"db add     {size / t_add:10.1f} Hz   ({size} entries)",
            f"search     {nq / t_s:10.1f} Hz   (solid.Database, top-1 over {size} entries)",
            f"search     {nq / t_np:10.1f} Hz   (numpy brute force baseline, top-1 over {size} entries, {t_np / t_s:.1f}x solid's time)",
        ]
    )


def _extrinsic(inputs: Inputs) -> Any | None:
    """The sensor → pose-frame extrinsic of a run given with a calibration (None without)."""
    if inputs.calib is None:
        return None
    from .datasets.poses import load_extrinsic

    return load_extrinsic(inputs.calib)


#: The anchor file of one transform per frame of a run (``T_map_odom`` of each frame, KITTI rows;
#: a row of NaN: no anchor places that frame), written beside ``anchor.txt`` by ``solid localize``
#: and ``solid optimize --map``; ``solid map merge --anchor`` applies it place by place.
ANCHORS_FILE = "anchors.kitti"
#: The first line of :data:`ANCHORS_FILE`: what tells it from a trajectory or a poses file, which
#: ``map merge --anchor`` refuses (one row per frame too, but not transforms into the map).
PER_FRAME_ANCHORS = "# solid: T_map_odom of each of the "
#: The comment line by which an ``anchor.txt`` says it maps only some frames of its run (the
#: odometry broke); pose readers skip it, ``solid map merge`` refuses such a file.
PARTIAL_ANCHOR = "# solid: partial anchor: "


def write_anchor_files(folder: Path, first: Any, each: Any, partial: str | None, sequence: str) -> None:
    """``anchor.txt`` (``first``, one KITTI row; when ``partial`` says which frames alone it maps,
    a :data:`PARTIAL_ANCHOR` comment first) and :data:`ANCHORS_FILE` (``each``: one row per frame
    of the run, NaN where no anchor places the frame) in ``folder``."""
    from .slam import as4, write_kitti

    head = "" if partial is None else f"{PARTIAL_ANCHOR}{partial}; {ANCHORS_FILE} beside it holds each frame's (solid map merge --anchor {ANCHORS_FILE})\n"
    write_kitti(folder / "anchor.txt", as4(first)[None], head)
    write_frame_anchors(folder, each, sequence)


def write_frame_anchors(folder: Path, each: Any, sequence: str) -> None:
    """:data:`ANCHORS_FILE` in ``folder``: ``each`` (one ``T_map_odom`` per frame of the run,
    NaN where no anchor places the frame) under its :data:`PER_FRAME_ANCHORS` line."""
    from .slam import write_kitti

    E = np.array(each, dtype=np.float64)
    E[~np.isfinite(E).all(axis=(1, 2))] = np.nan
    none = int(np.isnan(E).all(axis=(1, 2)).sum())
    write_kitti(
        folder / ANCHORS_FILE,
        E,
        f"{PER_FRAME_ANCHORS}{len(E)} frames of {sequence}'s run, in order (solid map merge --anchor applies row k to "
        f"place k of a map built from those frames); {none} rows of nan: frames no anchor places (merged without a pose)\n",
    )


def merge_anchor(path: Path) -> Any:
    """An anchor file for ``solid map merge`` as (K, 4, 4) (:func:`anchor_file`): ``anchor.txt``
    (K = 1; refused when it says it maps only some frames, :data:`PARTIAL_ANCHOR`) or
    :data:`ANCHORS_FILE` (one per frame; a row of NaN: no transform, kept as NaN)."""
    T, partial = anchor_file(path)
    if len(T) == 1 and partial is not None:
        raise _solid.ConfigError(
            f"{path} maps only some frames of its session: {partial}. One transform would misplace the places of the other stretches: "
            f"give --anchor {Path(path).with_name(ANCHORS_FILE)} (each frame's transform, applied to its place; the map must be built from "
            "the same frames of the recording)"
        )
    return T


def anchor_file(path: Path) -> tuple[Any, str | None]:
    """An anchor file as (K, 4, 4), and what an ``anchor.txt`` that maps only some frames of its
    run says of them (its :data:`PARTIAL_ANCHOR` line; else None): ``anchor.txt`` (K = 1) or
    :data:`ANCHORS_FILE` (one per frame; a row of NaN: no transform, kept as NaN). Refused: a
    many-row file that is not :data:`ANCHORS_FILE` (a trajectory or a poses file), a row partly
    not finite, a one-row file of NaN."""
    text = Path(path).read_text(encoding="utf-8")
    lines = [ln.strip() for ln in text.splitlines()]
    partial = next((ln[len(PARTIAL_ANCHOR) :].split(f"; {ANCHORS_FILE} beside it")[0] for ln in lines if ln.startswith(PARTIAL_ANCHOR)), None)
    rows = [ln.split() for ln in lines if ln and not ln.startswith("#")]
    if len(rows) > 1 and not (lines and lines[0].startswith(PER_FRAME_ANCHORS)):
        raise _solid.ConfigError(
            f"{path}: {len(rows)} rows, but not a per-frame anchor file ({ANCHORS_FILE} of solid localize -o or solid optimize --map, "
            f"which starts with {PER_FRAME_ANCHORS.strip()!r}): a trajectory or a poses file is not an anchor; give anchor.txt or {ANCHORS_FILE}"
        )
    if rows and all(len(r) == 12 for r in rows):
        try:
            a = np.array(rows, dtype=np.float64)
        except ValueError:
            raise _solid.ConfigError(f"{path}: an anchor file holds KITTI 3×4 rows of numbers; found a value that is not one") from None
        bad = np.isnan(a).any(axis=1) & ~np.isnan(a).all(axis=1) | np.isinf(a).any(axis=1)
        if bad.any():
            raise _solid.ConfigError(f"{path}: row {int(np.argmax(bad)) + 1} is not finite (a row of nan alone says no transform)")
        T = np.tile(np.eye(4), (len(a), 1, 1))
        T[:, :3] = a.reshape(-1, 3, 4)
        T[np.isnan(a).all(axis=1)] = np.nan
    else:
        T = read_anchor(path)[None]
    if len(T) == 1 and not np.isfinite(T).all():
        raise _solid.ConfigError(f"{path}: its one transform is nan: nothing places that session")
    if not np.isfinite(T).all(axis=(1, 2)).any():
        raise _solid.ConfigError(f"{path}: every row is nan: no row places a frame, so nothing places that session")
    return T, partial


def run_anchor(path: Path, frames: int) -> tuple[Any, list[str]]:
    """An anchor file (:func:`anchor_file`) for the ``frames`` frames of one run (``solid eval
    --anchor``, ``solid view``): ``anchor.txt``'s one transform (4, 4) for every frame, or
    :data:`ANCHORS_FILE`'s one per frame (``frames``, 4, 4; a row of NaN: a frame no anchor
    places; the caller says what it does with those frames), with the notes to print: an
    ``anchor.txt`` that maps only some frames applied to every frame anyway. A per-frame file of
    another frame count is refused, naming both."""
    return _run_anchor(path, *anchor_file(path), frames)


def folder_anchor(folder: Path, frames: int) -> tuple[Any, list[str]] | None:
    """The anchor a run folder holds for its ``frames`` frames (:func:`run_anchor`; None: no
    anchor file): ``anchor.txt``, or :data:`ANCHORS_FILE` beside it when ``anchor.txt`` maps only
    some frames (or is not there). Each file is read once."""
    one, each = folder / "anchor.txt", folder / ANCHORS_FILE
    if one.is_file():
        T, partial = anchor_file(one)
        if partial is None or not each.is_file():
            return _run_anchor(one, T, partial, frames)
    return run_anchor(each, frames) if each.is_file() else None


def _run_anchor(path: Path, T: Any, partial: str | None, frames: int) -> tuple[Any, list[str]]:
    """:func:`run_anchor` of the file ``path`` read (:func:`anchor_file`: ``T``, ``partial``)."""
    notes: list[str] = []
    if len(T) == 1:
        if partial is not None:
            notes.append(
                f"{path} maps only some frames of its session ({partial}), yet is applied to every frame: the frames of the other "
                f"stretches of the odometry are misplaced (give {Path(path).with_name(ANCHORS_FILE)}, each frame's transform, where it is)"
            )
        return T[0], notes
    _check_anchor_frames(T, frames, path)
    return T, notes


def _check_anchor_frames(T: Any, frames: int, path: Path | None) -> None:
    """Refuses per-frame anchors ``T`` (K, 4, 4) of another frame count than the run's ``frames``,
    naming the file ``path`` they were read from (None: given as an array)."""
    if len(T) != frames:
        held = f"{path} holds" if path is not None else "the per-frame anchors given hold"
        raise _solid.ConfigError(
            f"{held} {len(T)} transforms, one per frame of its run, but this run has {frames} frames: "
            "give the anchors of this run (the same recording and --frames)"
        )


def read_anchor(path: Path) -> Any:
    """An anchor file (one KITTI 3×4 row, ``T_map_session``; ``#`` lines are comments) as a 4×4
    matrix."""
    from .datasets.poses import load_poses

    P, _ = load_poses(path)
    if len(P) != 1:
        raise _solid.ConfigError(
            f"{path}: an anchor is one KITTI 3×4 row, found {len(P)} poses (one per frame, {ANCHORS_FILE}, is for solid map merge --anchor; give anchor.txt)"
        )
    T = np.eye(4)
    T[:3] = P[0]
    return T


class _AnchoredDatabase:
    """A database seen with this session's places carried into the map's world by an anchor
    (``T_map_session``); everything else is the database's."""

    def __init__(self, db: Any, T_map_session: Any, map_size: int) -> None:
        from .slam import as4

        self._db = db
        P = as4(np.asarray(db.poses, dtype=np.float64))
        P[map_size:] = as4(T_map_session) @ P[map_size:]
        self.poses = np.ascontiguousarray(P[:, :3, :])

    def __getattr__(self, name: str) -> Any:
        return getattr(self._db, name)

    def __len__(self) -> int:
        return len(self._db)


def place_in_map(result: PipelineResult, anchor: Any) -> tuple[PipelineResult, dict[str, Any]]:
    """A run against a map with its session's poses in the map's world, and how that world was
    known: ``anchor`` is a 4×4 ``T_map_session`` (given) or one per frame of the run ((N, 4, 4),
    :func:`run_anchor` of :data:`ANCHORS_FILE`; a frame of a row of NaN, which no anchor places,
    is carried by the nearest placed frame's, :func:`solid.slam.nearest_placed`, and listed:
    ``per_frame``, ``unplaced_frames``, and a note in ``notes`` (:func:`evaluate` leaves them out
    of the scores); refused when no row places a frame), ``"same"`` (the user says the poses
    already are in the map's world), or None: estimated from the run's verified loops into the
    map (:func:`solid.slam.anchor_of_run`: the detector's placement, or the loops' consensus when
    the run has none), an error when there is none."""
    import dataclasses

    from . import slam

    if isinstance(anchor, str) and anchor == "same":
        return result, {"source": "same world (as given)"}
    base = result.map_size
    if anchor is None:
        if result.poses is None:
            raise _solid.ConfigError("placing a session in a map needs its poses")
        est = slam.anchor_of_run(result)
        if est is None:
            raise _solid.ConfigError(
                "no verified loop into the map, so nothing says where this session lies in the map's world: "
                "give --anchor FILE (anchor.txt of `solid optimize --map`) or --same-world"
            )
        T = est.T_map_session
        how: dict[str, Any] = {
            "source": "placed" if result.map_anchor is not None else "estimated",
            "inlier_loops": est.inliers,
            "cross_session_loops": est.loops,
        }
        how.update(anchor_scope(result))
    else:
        T = slam.as4(np.asarray(anchor, dtype=np.float64))
        how = {"source": "given"}
    if T.ndim == 3:
        # One per frame (anchors.kitti, run_anchor): a frame no anchor places is carried by the
        # nearest placed frame's (a guess across a break of the odometry), and listed; evaluate
        # leaves it out of the scores.
        frames = len(result.frame_ids)
        if len(T) != frames or len(result.database) - base != frames:
            raise _solid.ConfigError(f"{len(T)} per-frame anchors for a run of {frames} frames ({len(result.database) - base} places): give this run's")
        T, borrowed = slam.nearest_placed(T)
        if len(borrowed) == frames:
            raise _solid.ConfigError("the per-frame anchors place no frame of this run: nothing says where the session lies in the map's world")
        how["T_map_session"] = None
        how["per_frame"] = {"frames": frames, "unplaced_frames": [int(result.frame_ids[k]) for k in borrowed]}
        if borrowed:
            from .localize import frame_spans

            how.setdefault("notes", []).append(
                f"{len(borrowed)} of {frames} frames no anchor places (frames {frame_spans(result.frame_ids, borrowed)}) are left out of the "
                "scores: where they lie in the map's world is unknown (metrics.json anchor.per_frame.unplaced_frames)"
            )
    else:
        how["T_map_session"] = T[:3].tolist()
    poses = None if result.poses is None else (T @ slam.as4(result.poses))[:, :3, :]
    return dataclasses.replace(result, database=_AnchoredDatabase(result.database, T, base), poses=poses), how


@dataclass
class OptimizeRun:
    """What ``solid optimize`` produced."""

    result: PipelineResult
    slam: Any
    folder: Path
    metrics: dict[str, Any]


def optimize(
    dataset: Any,
    config: PipelineConfig,
    inputs: Inputs,
    *,
    output: Path | None = None,
    map_db: Any | None = None,
    truth: Path | None = None,
    robust: str | None = None,
    noise: Any | None = None,
    noise_scale: float | None = None,
    plots: bool = True,
    threads: int | None = None,
    progress: Callable[[int], None] | None = None,
    loops_from: Path | None = None,
) -> OptimizeRun:
    """``solid optimize``: the detector's loops and the odometry in a robust pose-graph
    optimisation (:func:`solid.slam.optimize_run`). Writes ``trajectory.kitti`` and
    ``trajectory.tum`` (the optimised poses, one per frame, in the frame of the given poses),
    ``graph.g2o`` (the whole graph, initial values = the given poses), ``loops.csv``,
    ``loop_edges.csv`` (each loop edge of the graph, its robust weight and whether the optimum kept it),
    ``trajectory.png`` (before and after, with the loops) and ``metrics.json``; with ``truth``
    (a pose file of the recording), ATE and RPE of the odometry and of the optimum; with a map,
    ``anchor.txt`` (one KITTI 3×4 row, this session's world → the map's world) and
    ``trajectory_map.kitti``/``.tum`` (the optimised poses in the map's world). With
    ``loops_from`` (a run's g2o file or output folder: :func:`reused_loops`), the detector does
    not run: that run's loop edges join this run's odometry. The odometry noise (``noise``) is
    multiplied by ``noise_scale``, by default as :func:`solid.slam.optimize_run` decides."""
    from . import slam
    from .datasets.poses import load_poses, match_rows

    if getattr(dataset, "poses", None) is None:
        raise _solid.ConfigError("optimize needs the odometry's poses (give --poses)")
    robust = robust or slam.ROBUST_SCHEMES[0]
    slam.require_gtsam()
    T = _extrinsic(inputs)
    if loops_from is None:
        result = _run(dataset, config, map_db, threads, progress)
        run = slam.optimize_run(result, robust=robust, noise=noise, noise_scale=noise_scale)
    else:
        if map_db is not None:
            raise _solid.ConfigError("--loops reuses a run's own loops, and its graph holds none into a map: drop --map, or drop --loops to run the detector against the map")
        result, run = _optimize_reused(dataset, config, loops_from, T, robust, noise, noise_scale)

    def to_input(P: Any) -> Any:
        """Poses of the run's (LiDAR) frame in the frame of the given poses."""
        return P if T is None else T @ P @ slam.inv(T)

    odo, opt = to_input(run.odometry), to_input(run.optimized)
    times = result.timestamps if result.timestamps is not None else np.asarray(result.frame_ids, dtype=np.float64)
    metrics = _summary(result, inputs, "optimize")
    metrics["robust"] = robust
    metrics["odometry_noise"] = vars((noise or slam.OdometryNoise()).scaled(run.noise_scale))
    metrics["odometry_noise_scale"] = run.noise_scale
    loops = run.graph.loops()
    metrics["loop_edges"] = len(loops)
    metrics["loop_edges_kept"] = run.trusted_loops()
    gt = None
    if truth is not None:
        G, _ = load_poses(truth)
        rows = match_rows(Path(truth), len(G), len(dataset), getattr(dataset, "frame_ids", None), "truth")
        gt = slam.as4(G[rows][result.frames])
        for name, P in (("odometry", odo), ("optimized", opt)):
            t, r = slam.relative_pose_error(P, gt)
            metrics[name] = {"ate_m": slam.absolute_trajectory_error(P, gt), "rpe_m": t, "rpe_deg": r}
    if run.anchor is not None:
        metrics["anchor"] = {
            "T_map_session": run.anchor.T_map_session[:3].tolist(),
            "inlier_loops": run.anchor.inliers,
            "cross_session_loops": run.anchor.loops,
            "source": "placed" if result.map_anchor is not None else "estimated",
        }
        metrics["anchor"].update(anchor_scope(result))
        if run.stretches > 1:
            metrics["anchor"]["stretches_started"] = run.stretches
            # Each stretch started at its own anchor: this note replaces anchor_scope's (which
            # says one anchor maps only some frames).
            metrics["anchor"]["notes"] = [optimize_stretches_note(run, result)]
    elif map_db is not None:
        metrics["anchor"] = None
        metrics["anchor_none"] = why_no_anchor(result)
    if loops_from is not None:
        metrics["loops"] = len(loops)
        metrics["loops_from"] = str(Path(loops_from).absolute())
    with output_folder(output, "optimize", inputs.sequence.name) as out:
        if loops_from is None:
            _write_common(out, result)
        else:
            config.dump(out.work / "config.json")
            write_csv(out.work / "loops.csv", LOOP_COLUMNS, _reused_loop_rows(run.graph, result.timestamps))
        graph = run.graph if T is None else run.graph.in_frame(T)
        graph.write_g2o(out.work / "graph.g2o")
        write_csv(
            out.work / "loop_edges.csv",
            ("query_frame", "candidate_frame", "weight", "kept"),
            [
                {"query_frame": int(run.graph.ids[run.graph.edge_from[e]]), "candidate_frame": int(run.graph.ids[run.graph.edge_to[e]]), "weight": f"{w:.6f}", "kept": bool(w > 0.5)}
                for e, w in zip(loops, run.loop_weights)
            ],
        )
        slam.write_kitti(out.work / "trajectory.kitti", opt)
        slam.write_tum(out.work / "trajectory.tum", times, opt)
        if run.anchor is not None and run.map_poses is not None:
            # The anchor in the frame maps store poses in (calibration applied), where `map merge`
            # and `eval --anchor` apply it; the trajectory, like every other, in that of --poses.
            # anchors.kitti: each frame's, the optimum's pose in the map's world over its odometry
            # pose (`map merge --anchor anchors.kitti` puts each place where the optimum has it).
            # A frame of a stretch of the odometry no anchor placed (started at another stretch's,
            # or the one anchor's when it maps only some frames: run.borrowed) has no transform
            # there: nothing ties it to the map. Without the detector's placement nothing says
            # where the stretches are: every frame keeps the optimum's.
            from .localize import frame_anchors_of_run

            each = slam.as4(run.map_poses) @ slam.inv(slam.as4(run.odometry))
            if result.map_anchors:
                each[~np.isfinite(frame_anchors_of_run(result)).all(axis=(1, 2))] = np.nan
            partial = partial_anchor(result, "the first frame's stretch of the odometry")
            write_anchor_files(out.work, run.anchor.T_map_session, each, partial, inputs.sequence.name)
            slam.write_kitti(out.work / "trajectory_map.kitti", to_input(run.map_poses))
            slam.write_tum(out.work / "trajectory_map.tum", times, to_input(run.map_poses))
        write_json(out.work / "metrics.json", metrics)
        if plots:
            from . import plots as pl

            edges = [(int(run.graph.edge_from[e]), int(run.graph.edge_to[e]), bool(w > 0.5)) for e, w in zip(loops, run.loop_weights)]
            pl.plot_before_after(out.work / "trajectory.png", odo, opt, edges, f"{inputs.sequence.name}: robust {robust}", truth=gt)
    return OptimizeRun(result, run, out.final, metrics)


def reused_loops(path: Path) -> Path:
    """The g2o file of a run whose loops ``solid optimize --loops`` reuses: ``path`` itself, or
    in a run's output folder ``graph.g2o`` (``solid optimize``) or ``loops.g2o`` (``solid detect
    --g2o``)."""
    p = Path(path)
    if p.is_dir():
        for name in ("graph.g2o", "loops.g2o"):
            if (p / name).is_file():
                return p / name
        raise _solid.ConfigError(f"{p} holds no graph.g2o (solid optimize) nor loops.g2o (solid detect --g2o)")
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such g2o file or run folder")
    return p


def _optimize_reused(
    dataset: Any, config: PipelineConfig, loops_from: Path, T: Any | None, robust: str, noise: Any | None, noise_scale: float | None
) -> tuple[PipelineResult, Any]:
    """The frames the run selects (no scan is read), optimised with the loops of ``loops_from``
    (:func:`solid.slam.optimize_with_loops_of`)."""
    from . import slam

    idx = check_run(dataset, config)
    poses = np.asarray(dataset.poses, dtype=np.float64)[idx]
    times = None if getattr(dataset, "timestamps", None) is None else np.asarray(dataset.timestamps, dtype=np.float64)[idx]
    ids = np.asarray(getattr(dataset, "frame_ids", np.arange(len(dataset))), dtype=np.int64)[idx]
    result = PipelineResult(config, [], None, idx, ids, times, poses, 0, 0, None)
    path = reused_loops(loops_from)
    try:
        return result, slam.optimize_with_loops_of(path, ids, poses, calib=T, robust=robust, noise=noise, noise_scale=noise_scale)
    except ValueError as e:
        raise _solid.ConfigError(f"{path}: {e}") from None


def _reused_loop_rows(graph: Any, times: Any | None) -> list[dict[str, Any]]:
    """``loops.csv`` rows for loops read from a g2o file: what it holds (the frames, the pose);
    the detector's fields (distance, score, heading, fit) are in the run's own ``loops.csv``."""
    rows = []
    for e in graph.loops():
        i, j = int(graph.edge_from[e]), int(graph.edge_to[e])
        row = {k: "" for k in LOOP_COLUMNS} | pose_columns(graph.measurements[e], None, None)
        row |= {"query": i, "candidate": j, "query_frame": int(graph.ids[i]), "candidate_frame": int(graph.ids[j])}
        if times is not None:
            row |= {"query_time": fmt_opt(float(times[i])), "candidate_time": fmt_opt(float(times[j]))}
        rows.append(row)
    return rows
