"""See a run in 3-D: trajectories, places, loops and a loop's two clouds, in rerun's viewer.

``solid view RUN_FOLDER`` (or :func:`view`) reads a run folder of ``solid eval``, ``solid detect``
or ``solid optimize`` (with or without ``--map``) and writes a rerun recording (``.rrd``) that
opens in rerun's viewer, native (``rerun run.rrd``) or web (``rerun --web-viewer run.rrd``), or
sends it to a viewer it spawns. Needs the ``viewer`` extra: ``pip install 'solid-lidar[viewer]'``
(``rerun-sdk``, the version this module was tested with is :data:`RERUN_VERSION`).

One layout for every producer: :class:`Layout` names the entity paths and the timelines, and the
``log_*`` functions write them, so that ``solid view``, a script over ``solid.slam`` or a ROS 2
node log the same things to the same places:

- ``world/places``: the places of the run's map (``--map``: the prior session's places), points.
- ``world/odometry/path``, ``world/optimized/path``: the trajectories as line strips (static);
  ``world/odometry/pose``, ``world/optimized/pose``: the pose at each frame on the timelines
  (a ``Transform3D`` per frame with its axes), so the viewer's time slider scrubs the run.
- ``world/loops/<kind>/<query>-<candidate>``: one segment per loop, logged at its query's time,
  coloured by its kind (:data:`LOOP_COLOURS`): what ``eval`` said (``correct``,
  ``beyond_radius``, ``pose_false``), what ``optimize`` did (``kept``, ``dropped``) or
  ``accepted`` (``detect``, no truth); ``map``, a loop into the map that anchored an optimize run. ``<query>`` and ``<candidate>`` are frame numbers of the
  recording, or ``map<id>`` for a place of the map.
- ``loop/<query>-<candidate>/before/{query,candidate}`` and ``.../after/{query,candidate}``: the two
  scans of a chosen loop in the query's sensor frame, as read (before) and with the candidate
  moved by the loop's pose ``T_query_candidate`` (after): aligned when the pose is right.

Timelines: ``time`` (seconds since the run's first frame, where the recording has times) and
``frame`` (the frame number in the recording). Positions are in the frame of the run's poses
(the sensor's world: calibration applied), in the map's world for a run against a map.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from .arrays import F64

__all__ = [
    "LOOP_COLOURS",
    "LoopEdge",
    "RERUN_VERSION",
    "Layout",
    "RunView",
    "counts",
    "log_loop",
    "log_loop_clouds",
    "log_places",
    "log_trajectory",
    "read_run",
    "require_rerun",
    "view",
]

#: The rerun-sdk release this module was written and tested against (the ``viewer`` extra pins it).
RERUN_VERSION = "0.41.0"

#: RGB of each kind of loop edge.
LOOP_COLOURS: dict[str, tuple[int, int, int]] = {
    "correct": (40, 180, 60),
    "beyond_radius": (240, 170, 0),
    "pose_false": (220, 30, 30),
    "kept": (40, 180, 60),
    "dropped": (220, 30, 30),
    "accepted": (30, 120, 230),
    "map": (170, 60, 220),
}

_TRAJECTORY_COLOURS = {"odometry": (150, 150, 150), "optimized": (30, 120, 230)}


class Layout:
    """The entity paths and timelines of a solid recording (one place decides them)."""

    PLACES = "world/places"
    LOOPS = "world/loops"
    CLOUDS = "loop"
    TIME = "time"
    FRAME = "frame"

    @staticmethod
    def path(trajectory: str) -> str:
        """The line strip of a whole trajectory ("odometry", "optimized", ...)."""
        return f"world/{trajectory}/path"

    @staticmethod
    def pose(trajectory: str) -> str:
        """The pose of a trajectory at each frame (on the timelines)."""
        return f"world/{trajectory}/pose"

    @staticmethod
    def loop(kind: str, query: str, candidate: str) -> str:
        """One loop edge, by its kind and the names of its two ends."""
        return f"world/loops/{kind}/{query}-{candidate}"

    @staticmethod
    def clouds(query: str, candidate: str, stage: str, side: str) -> str:
        """One scan of a chosen loop: ``stage`` "before" or "after", ``side`` "query" or "candidate"."""
        return f"loop/{query}-{candidate}/{stage}/{side}"

    @staticmethod
    def blueprint(loop: tuple[str, str] | None = None) -> Any:
        """The viewer's panels: the world (trajectories, places, loops) and, for a chosen loop
        (its query and candidate names), its clouds before and after its pose, side by side."""
        rrb = require_rerun().blueprint
        world = rrb.Spatial3DView(origin="world", name="trajectories, places and loops")
        if loop is None:
            return rrb.Blueprint(world)
        q, c = loop
        base = f"{Layout.CLOUDS}/{q}-{c}"
        clouds = rrb.Vertical(
            rrb.Spatial3DView(origin=f"{base}/before", name=f"loop {q}-{c}: the two scans as read"),
            rrb.Spatial3DView(origin=f"{base}/after", name=f"loop {q}-{c}: candidate moved by the loop's pose"),
        )
        return rrb.Blueprint(rrb.Horizontal(world, clouds, column_shares=[3, 2]))


def require_rerun() -> Any:
    """The ``rerun`` module, or an ImportError that says how to install it."""
    try:
        import rerun
    except ImportError:
        raise ImportError(
            "solid view needs rerun-sdk: pip install 'solid-lidar[viewer]' "
            f"(or pip install rerun-sdk=={RERUN_VERSION})"
        ) from None
    return rerun


def _as4(P: npt.ArrayLike) -> F64:
    A = np.asarray(P, dtype=np.float64)
    if A.shape[-2:] == (4, 4):
        return A
    out = np.broadcast_to(np.eye(4), (*A.shape[:-2], 4, 4)).copy()
    out[..., :3, :] = A
    return out


def _set_time(rec: Any, time_s: float | None, frame: int | None) -> None:
    """The recording's clock for what is logged next: ``time`` (seconds) and ``frame``."""
    if time_s is not None and math.isfinite(time_s):
        rec.set_time(Layout.TIME, duration=float(time_s))
    if frame is not None:
        rec.set_time(Layout.FRAME, sequence=int(frame))


def log_trajectory(rec: Any, name: str, poses: npt.ArrayLike, times: npt.ArrayLike | None = None, frames: npt.ArrayLike | None = None) -> None:
    """A trajectory (poses ``T_world_sensor``, (N, 3, 4) or (N, 4, 4); NaN rows skipped): its path
    (static) and its pose at each frame on the ``time`` (``times``, seconds) and ``frame``
    (``frames``, default 0..N-1) timelines."""
    rr = require_rerun()
    from .transforms import quaternion

    P = _as4(poses)
    ok = np.asarray(np.isfinite(P.reshape(len(P), -1)).all(axis=1), dtype=bool)
    P = P[ok]
    fr = (np.arange(ok.size) if frames is None else np.asarray(frames, dtype=np.int64))[ok]
    colour = _TRAJECTORY_COLOURS.get(name, (200, 200, 200))
    rec.log(Layout.path(name), rr.LineStrips3D([P[:, :3, 3]], colors=[colour]), static=True)
    if not len(P):
        return
    quats = np.stack([quaternion(R) for R in P[:, :3, :3]])  # x y z w
    indexes = [rr.TimeColumn(Layout.FRAME, sequence=fr)]
    if times is not None:
        t = np.asarray(times, dtype=np.float64)[ok]
        if np.isfinite(t).all():
            indexes.append(rr.TimeColumn(Layout.TIME, duration=t))
    rec.send_columns(Layout.pose(name), indexes=indexes, columns=rr.Transform3D.columns(translation=P[:, :3, 3], quaternion=quats))
    rec.log(Layout.pose(name), rr.TransformAxes3D(axis_length=1.0), static=True)


def log_places(rec: Any, positions: npt.ArrayLike) -> None:
    """The places of a map (their positions, (N, 3); NaN rows skipped), static."""
    rr = require_rerun()
    X = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    rec.log(Layout.PLACES, rr.Points3D(X[np.isfinite(X).all(axis=1)], colors=[(120, 120, 120)], radii=0.15), static=True)


def log_loop(rec: Any, kind: str, query: str, candidate: str, a: npt.ArrayLike, b: npt.ArrayLike, time_s: float | None = None, frame: int | None = None) -> None:
    """One loop edge from ``a`` (the query's position) to ``b`` (the candidate's), of ``kind``
    (a key of :data:`LOOP_COLOURS`), logged at the query's time and frame."""
    rr = require_rerun()
    _set_time(rec, time_s, frame)
    seg = np.stack([np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)])
    rec.log(Layout.loop(kind, query, candidate), rr.LineStrips3D([seg], colors=[LOOP_COLOURS.get(kind, (255, 255, 255))], radii=0.05))


def log_loop_clouds(rec: Any, query: str, candidate: str, query_points: npt.ArrayLike, candidate_points: npt.ArrayLike, T_query_candidate: npt.ArrayLike) -> None:
    """The two scans of a loop in the query's frame: as read (``before``) and with the candidate
    moved by the loop's pose (``after``), static; query orange, candidate blue."""
    rr = require_rerun()
    q = np.asarray(query_points, dtype=np.float32)[:, :3]
    c = np.asarray(candidate_points, dtype=np.float32)[:, :3]
    T = _as4(T_query_candidate)
    moved = (c.astype(np.float64) @ T[:3, :3].T + T[:3, 3]).astype(np.float32)
    for stage, cand in (("before", c), ("after", moved)):
        rec.log(Layout.clouds(query, candidate, stage, "query"), rr.Points3D(q, colors=[(250, 140, 20)], radii=0.03), static=True)
        rec.log(Layout.clouds(query, candidate, stage, "candidate"), rr.Points3D(cand, colors=[(30, 120, 230)], radii=0.03), static=True)


# ---- reading a run folder ------------------------------------------------------------------------


@dataclass
class LoopEdge:
    """One loop of a run: its ends (frame numbers of the recording, or a map place), its kind
    and, when verified, its pose ``T_query_candidate``."""

    kind: str
    query_frame: int
    candidate_frame: int | None
    candidate_place: int | None
    query_time: float | None
    pose: F64 | None

    def names(self) -> tuple[str, str]:
        c = f"map{self.candidate_place}" if self.candidate_place is not None else str(self.candidate_frame)
        return str(self.query_frame), c


@dataclass
class RunView:
    """What :func:`view` logs, read from a run folder (:func:`read_run`)."""

    folder: Path
    command: str
    frame_ids: npt.NDArray[np.int64]
    times: F64 | None
    trajectories: dict[str, F64]
    loops: list[LoopEdge]
    places: F64 | None = None
    t0: float = 0.0
    dataset: Any = None
    notes: list[str] = field(default_factory=list)

    def position(self, frame: int, trajectory: str) -> F64:
        k = int(np.searchsorted(self.frame_ids, frame))
        if k >= len(self.frame_ids) or self.frame_ids[k] != frame:
            raise ValueError(f"{self.folder}: frame {frame} is not one of the run's frames")
        return self.trajectories[trajectory][k, :3, 3]


def _csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def _loop_pose(row: dict[str, str]) -> F64 | None:
    from .datasets.poses import quat_to_matrix

    if row.get("verified") != "True" or not row.get("qw"):
        return None
    T = np.eye(4)
    T[:3, :3] = quat_to_matrix(np.array([[float(row[k]) for k in ("qx", "qy", "qz", "qw")]]))[0]
    T[:3, 3] = [float(row[k]) for k in ("x", "y", "z")]
    return T


def _opt_float(s: str | None) -> float | None:
    return float(s) if s not in (None, "") else None


def read_run(folder: Path | str) -> RunView:
    """The trajectories, places and loops of a run folder of ``solid eval``, ``solid detect`` or
    ``solid optimize``; the recording is opened again (from the absolute paths the run recorded)
    for its poses, times and scans."""
    from . import _solid
    from .commands import folder_anchor, open_recording
    from .config import PipelineConfig
    from .localize import frame_spans
    from .pipeline import check_run

    folder = Path(folder)
    meta_file = next((folder / n for n in ("metrics.json", "summary.json") if (folder / n).is_file()), None)
    if meta_file is None or not (folder / "config.json").is_file():
        raise FileNotFoundError(f"{folder}: not a run folder of solid eval, detect or optimize (no metrics.json or summary.json with config.json)")
    meta = json.loads(meta_file.read_text(encoding="utf-8"))
    command = str(meta.get("command", "eval"))
    inputs = meta["inputs"]
    config = PipelineConfig.load(folder / "config.json")
    ds, _ = open_recording(
        inputs["sequence"],
        poses=inputs.get("poses"),
        timestamps=inputs.get("timestamps"),
        calib=inputs.get("calib"),
        topic=inputs.get("topic"),
        frames=config.input.frames,
    )
    idx = check_run(ds, config)
    frame_ids = np.asarray(getattr(ds, "frame_ids", np.arange(len(ds))), dtype=np.int64)[idx]
    if ds.poses is None:
        raise ValueError(f"{folder}: the run has no poses, so nothing places it in 3-D (give --poses to {command})")
    odometry = _as4(np.asarray(ds.poses, dtype=np.float64)[idx])
    times = None if ds.timestamps is None else np.asarray(ds.timestamps, dtype=np.float64)[idx]
    map_size = int(meta.get("map_places") or 0)
    notes: list[str] = []

    # A run against a map: its session in the map's world (one transform, or one per frame when
    # the odometry broke: anchors.kitti, a frame no anchor places left out), the map's places.
    T_map: F64 = np.eye(4)
    places = None
    if map_size:
        a = meta.get("anchor")
        held = folder_anchor(folder, len(odometry))
        if held is not None:
            T_map, said = held
            notes += said
            unplaced = np.flatnonzero(np.isnan(T_map).all(axis=(1, 2))) if T_map.ndim == 3 else np.zeros(0, dtype=np.intp)
            if unplaced.size:
                notes.append(
                    f"{len(unplaced)} of {len(odometry)} frames no anchor places (frames {frame_spans(frame_ids, unplaced)}): "
                    "left out of the trajectory"
                )
        elif isinstance(a, dict) and a.get("T_map_session") is not None:
            T_map = _as4(np.asarray(a["T_map_session"]))
            notes += a.get("notes", [])
        else:
            notes.append("the run does not say where its session lies in the map's world: drawn as given")
        if inputs.get("map") and Path(inputs["map"]).is_file():
            db = _solid.Database.load(inputs["map"])
            places = _as4(np.asarray(db.poses, dtype=np.float64)[:map_size])[:, :3, 3]
        else:
            notes.append(f"the map {inputs.get('map')} is not there: its places are not drawn")
    trajectories = {"odometry": T_map @ odometry}
    extrinsic = None if inputs.get("calib") is None else _as4(_calib(inputs["calib"]))

    def from_input_frame(P: F64) -> F64:
        """Poses written in the frame of --poses, back in the sensor's world."""
        return P if extrinsic is None else np.linalg.inv(extrinsic) @ P @ extrinsic

    loops: list[LoopEdge] = []
    if command == "optimize":
        from .datasets.poses import load_poses

        name = "trajectory_map.kitti" if map_size and (folder / "trajectory_map.kitti").is_file() else "trajectory.kitti"
        P, _ = load_poses(folder / name)
        trajectories["optimized"] = from_input_frame(_as4(P))
        if name == "trajectory.kitti":
            trajectories["optimized"] = T_map @ trajectories["optimized"]
        loops += _optimize_loops(folder, map_size)
    elif (folder / "queries.csv").is_file():
        for r in _csv(folder / "queries.csv"):
            if r["accepted"] != "True":
                continue
            kind = "correct" if r["correct"] == "True" else ("beyond_radius" if r["place_correct"] != "True" else "pose_false")
            loops.append(_edge(r, kind, map_size))
    else:
        loops += [_edge(r, "accepted", map_size) for r in _csv(folder / "loops.csv")]
    t0 = float(times[0]) if times is not None and len(times) and math.isfinite(times[0]) else 0.0
    return RunView(folder, command, frame_ids, times, trajectories, loops, places, t0, ds, notes)


def _calib(path: str) -> F64:
    from .datasets.poses import load_extrinsic

    return np.asarray(load_extrinsic(path), dtype=np.float64)


def _edge(r: dict[str, str], kind: str, map_size: int) -> LoopEdge:
    cand = int(r["candidate"])
    in_map = cand < map_size
    return LoopEdge(
        kind=kind,
        query_frame=int(r["query_frame"]),
        candidate_frame=None if in_map else int(r["candidate_frame"]),
        candidate_place=cand if in_map else None,
        query_time=_opt_float(r.get("query_time")),
        pose=_loop_pose(r),
    )


def _optimize_loops(folder: Path, map_size: int) -> list[LoopEdge]:
    """The loops of an optimize run: each edge of ``loop_edges.csv`` with what the optimum did
    (kept or dropped), and the loops into the map (``loops.csv``; they anchor the session)."""
    rows = _csv(folder / "loops.csv")
    by_pair = {(r["query_frame"], r["candidate_frame"]): r for r in rows}
    out: list[LoopEdge] = []
    edges = folder / "loop_edges.csv"
    if edges.is_file():
        for e in _csv(edges):
            r = by_pair.get((e["query_frame"], e["candidate_frame"]))
            row = dict(r) if r is not None else {"candidate": str(map_size), **e}
            row.setdefault("query_time", "")
            out.append(_edge(row, "kept" if e["kept"] == "True" else "dropped", map_size))
    out += [_edge(r, "map", map_size) for r in rows if int(r["candidate"]) < map_size]
    return out


def _loop_ends(run: RunView, e: LoopEdge, trajectory: str) -> tuple[F64, F64]:
    a = run.position(e.query_frame, trajectory)
    if e.candidate_place is not None:
        assert run.places is not None
        return a, run.places[e.candidate_place]
    assert e.candidate_frame is not None
    return a, run.position(e.candidate_frame, trajectory)


def _pick(run: RunView, loop: int | None) -> LoopEdge | None:
    """The loop whose clouds are shown: the one whose query is frame ``loop``, else the first
    verified loop between two frames of the recording (a correct or kept one when there is one)."""
    usable = [e for e in run.loops if e.pose is not None and e.candidate_frame is not None]
    if loop is None:
        good = [e for e in usable if e.kind in ("correct", "kept", "accepted")]
        return (good or usable)[0] if usable else None
    for e in usable:
        if e.query_frame == loop:
            return e
    raise ValueError(f"{run.folder}: no verified loop between two frames has its query at frame {loop} (frames with one: {sorted({e.query_frame for e in usable})[:20]})")


def view(
    folder: Path | str,
    out: Path | str | None = None,
    *,
    loop: int | None = None,
    clouds: bool = True,
    spawn: bool = False,
    run: RunView | None = None,
) -> Path | None:
    """Logs a run folder (:func:`read_run`) in the :class:`Layout`: into the ``.rrd`` file ``out``
    (default ``FOLDER/view.rrd``), or to a viewer it spawns (``spawn=True``; nothing written).
    ``loop`` chooses the loop whose two clouds are shown (its query frame; default the first
    verified one), ``clouds=False`` shows none; ``run``: the folder already read. Returns the file
    written (None when spawned)."""
    rr = require_rerun()
    run = run if run is not None else read_run(folder)
    chosen = _pick(run, loop) if clouds else None
    layout = Layout.blueprint(None if chosen is None else chosen.names())
    rec = rr.RecordingStream("solid", recording_id=str(Path(folder).resolve()))
    path = tmp = None
    if spawn:
        rec.spawn(default_blueprint=layout)
    else:
        # Written beside under a name of its own, then renamed: a failed run leaves no half file.
        path = Path(out) if out is not None else Path(folder) / "view.rrd"
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        rec.save(str(tmp), default_blueprint=layout)
    try:
        _log_run(rec, run, chosen)
        rec.flush()
        if tmp is not None:
            rec.disconnect()
            os.replace(tmp, str(path))
    finally:
        if tmp is not None and tmp.exists():
            tmp.unlink()
    return path


def _log_run(rec: Any, run: RunView, chosen: LoopEdge | None) -> None:
    """Everything of a run, in the :class:`Layout`."""
    rr = require_rerun()
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    times = None if run.times is None else run.times - run.t0
    for name, P in run.trajectories.items():
        log_trajectory(rec, name, P, times, run.frame_ids)
    if run.places is not None:
        log_places(rec, run.places)
    ends = "optimized" if "optimized" in run.trajectories else "odometry"
    for e in run.loops:
        a, b = _loop_ends(run, e, ends)
        if not (np.isfinite(a).all() and np.isfinite(b).all()):
            continue  # an end at a frame no anchor places in the map's world
        t = None if e.query_time is None else e.query_time - run.t0
        q, c = e.names()
        log_loop(rec, e.kind, q, c, a, b, t, e.query_frame)
    if chosen is not None and chosen.candidate_frame is not None and chosen.pose is not None:
        where = {int(f): k for k, f in enumerate(getattr(run.dataset, "frame_ids", np.arange(len(run.dataset))))}
        q, c = chosen.names()
        log_loop_clouds(rec, q, c, run.dataset[where[chosen.query_frame]], run.dataset[where[chosen.candidate_frame]], chosen.pose)


def counts(loops: Sequence[LoopEdge]) -> dict[str, int]:
    """How many loops of each kind."""
    out: dict[str, int] = {}
    for e in loops:
        out[e.kind] = out.get(e.kind, 0) + 1
    return out
