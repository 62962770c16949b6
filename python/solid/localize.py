"""Relocalization as a job of its own: where a new session lies in a saved map.

A detector over a prior map (``LoopDetector.from_database``) places the session in the map's world
when mutually consistent loops into the map support one transform (docs/spec.md §8, placement):
``LoopDetector.map_anchor``. This module reports that placement — when the session was placed,
where (``T_map_odom``, the transform from the session's pose frame into the map's world), how sure
(the supporting loops, the metres of path they span, the spread of their placements) — for a
stream (:class:`Localizer`), a finished run (:func:`placement_of_run`) and ``solid localize``.
``solid optimize --map``, ``solid eval --map`` and the ROS 2 node start from the same anchor.

An anchor maps one stretch of the session's odometry: the frames from :attr:`Placement.from_frame`
to :attr:`Placement.to_frame`. After a break of the odometry (a step it cannot have made: a LIO
losing track, docs/loops.md#breakdowns) the poses lie in another frame, which the anchor does not
map; each stretch that loops into the map placed has its own (:attr:`Localizer.stretches`,
:func:`placements_of_run`), and the ``map → odom`` of now is :attr:`Localizer.current`.

>>> import solid
>>> from solid import sim
>>> from solid.config import PipelineConfig
>>> world = sim.World(seed=1)
>>> lap, second = sim.session_routes(world, spacing=5.0)
>>> cfg = PipelineConfig.preset("vlp16", radius=5.0)
>>> mapper = solid.LoopDetector(cfg.descriptor, detector=cfg.detector)
>>> _ = mapper.detect_many(sim.simulate(world, sim.Sensor("vlp16"), lap).scans, poses=sim.Session.of(lap).trajectory.poses)
>>> loc = Localizer(mapper.database, cfg)
>>> mine = sim.Session.of(second[:26])           # the new session's poses, in its own frame
>>> for points, pose in zip(sim.simulate(world, sim.Sensor("vlp16"), second[:26]).scans, mine.trajectory.poses):
...     _ = loc.add(points, pose=pose)
>>> p = loc.placement
>>> p.loops >= 3 and p.metres >= 15.0
True
>>> truth = sim.Session.of(lap)
>>> bool(np.allclose(p.transform[:3], mine.anchor(truth), atol=0.3))    # T_map_odom
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from . import _solid
from .config import PipelineConfig

__all__ = ["Localizer", "Placement", "frame_anchors_of_run", "placement_of_run", "placements_of_run"]

F64 = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Placement:
    """Where a session is placed in a map (``LoopDetector.map_anchor``, as a report).

    ``transform`` is ``T_map_odom`` (4×4): it maps the session's pose frame into the map's world
    (what a ROS ``map → odom`` transform carries); ``loops`` mutually consistent loops into the
    map support it, spanning ``metres`` of the session's path from frame ``first_frame`` to
    ``last_frame``; ``placed_frame`` / ``placed_time`` say when the session was placed (the step
    whose loop into the map was the first released); ``covariance`` (6×6, rotation in radians
    then translation in metres, or None) is the spread of the supporting loops' placements, not a
    calibrated uncertainty. The transform maps the poses of one stretch of the session's odometry
    between breaks: frames ``from_frame`` to ``to_frame`` (None: through the latest frame, so
    that it is the ``map → odom`` of now, :attr:`current`); poses of other frames lie in other
    frames of the odometry, which it does not place."""

    transform: F64
    loops: int
    metres: float
    first_frame: int | None
    last_frame: int | None
    placed_frame: int | None
    placed_time: float | None
    covariance: F64 | None
    from_frame: int | None = None
    to_frame: int | None = None

    @property
    def current(self) -> bool:
        """Whether it maps the current frame of the odometry (no break since its stretch)."""
        return self.to_frame is None

    @property
    def frames(self) -> str:
        """The frames it maps, as text ("12–40", "46–the last")."""
        return frame_range(self.from_frame, self.to_frame)

    def places(self, frame: int) -> bool:
        """Whether it maps the pose of recording frame ``frame`` (one of its stretch's)."""
        lo = 0 if self.from_frame is None else self.from_frame
        return frame >= lo and (self.to_frame is None or frame <= self.to_frame)

    @property
    def sigma_translation_m(self) -> float | None:
        """√(trace of the translation block of :attr:`covariance`), metres (None without one)."""
        return None if self.covariance is None else math.sqrt(max(0.0, float(np.trace(self.covariance[3:, 3:]))))

    @property
    def sigma_rotation_deg(self) -> float | None:
        """√(trace of the rotation block of :attr:`covariance`), degrees (None without one)."""
        return None if self.covariance is None else math.degrees(math.sqrt(max(0.0, float(np.trace(self.covariance[:3, :3])))))

    def map_pose(self, pose: npt.ArrayLike) -> F64:
        """A pose of the session (``T_odom_sensor``, 3×4 or 4×4, of a frame it :meth:`places`)
        in the map's world (4×4)."""
        p = np.asarray(pose, dtype=np.float64)
        T = np.eye(4)
        T[: p.shape[0], :] = p
        out: F64 = self.transform @ T
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ``placed``, the fields above (matrices as nested lists), the two sigmas."""
        return {
            "placed": True,
            "transform": self.transform.tolist(),
            "loops": self.loops,
            "metres": round(self.metres, 3),
            "first_frame": self.first_frame,
            "last_frame": self.last_frame,
            "placed_frame": self.placed_frame,
            "placed_time": self.placed_time,
            "sigma_translation_m": _round(self.sigma_translation_m),
            "sigma_rotation_deg": _round(self.sigma_rotation_deg),
            "covariance": None if self.covariance is None else self.covariance.tolist(),
            "from_frame": self.from_frame,
            "to_frame": self.to_frame,
        }


def _round(v: float | None) -> float | None:
    return None if v is None else round(v, 4)


def _placement(anchor: Any, frame_of: Any, placed_frame: int | None, placed_time: float | None) -> Placement | None:
    """The one conversion of a ``solid.MapAnchor`` (None: not placed) into a :class:`Placement`;
    ``frame_of`` maps a detector id to the recording's frame."""
    if anchor is None:
        return None
    cov = anchor.covariance
    to = anchor.to_query
    return Placement(
        transform=np.asarray(anchor.transform, dtype=np.float64),
        loops=int(anchor.loops),
        metres=float(anchor.metres),
        first_frame=frame_of(int(anchor.first_query)),
        last_frame=frame_of(int(anchor.last_query)),
        placed_frame=placed_frame,
        placed_time=placed_time,
        covariance=None if cov is None else np.asarray(cov, dtype=np.float64),
        from_frame=frame_of(int(anchor.from_query)),
        to_frame=None if to is None else frame_of(int(to)),
    )


def placement_of_run(result: Any) -> Placement | None:
    """The placement of a finished run against a map (a :class:`solid.pipeline.PipelineResult`
    with ``map_anchor``): None when the run was not placed. It was placed at the step whose
    ``Detection.placement`` says so (the loops into the map held before it are released then)."""
    base = int(result.map_size)
    placed = next((d for d in result.detections if d.placement == "placed"), None)
    frame = None if placed is None else result.frame_of(int(placed.query))
    t = None
    if placed is not None and result.timestamps is not None:
        t = float(result.timestamps[int(placed.query) - base])
    return _placement(result.map_anchor, result.frame_of, frame, t)


def frame_range(from_frame: int | None, to_frame: int | None) -> str:
    """The frames of a stretch of the odometry as text: ``from_frame`` (None: 0) to ``to_frame``
    (None: "the last")."""
    return f"{from_frame or 0}–{'the last' if to_frame is None else to_frame}"


def frame_spans(frame_ids: Any, indices: Any) -> str:
    """Frames of a run (``indices`` into it) as the recording's frame numbers (``frame_ids``, the
    run's), one :func:`frame_range` per stretch of frames next to each other in the run (one
    number for a frame alone): "0–7, 20–25"."""
    ks = sorted({int(k) for k in indices})
    spans: list[list[int]] = []
    for k in ks:
        if spans and k == spans[-1][1] + 1:
            spans[-1][1] = k
        else:
            spans.append([k, k])
    ids = [int(f) for f in frame_ids]
    return ", ".join(str(ids[a]) if a == b else frame_range(ids[a], ids[b]) for a, b in spans)


def placements_of_run(result: Any) -> list[Placement]:
    """One :class:`Placement` per stretch of the run's odometry between breaks that loops into
    the map placed (``result.map_anchors``), in order; the last is :func:`placement_of_run`'s.
    An earlier one was made at the first step from its first supporting frame on whose
    ``placement`` says "placed" or "revised" (the step that placed its stretch before the
    break, or the placement after the breaks that released its loops)."""
    base = int(result.map_size)
    out = []
    for a in result.map_anchors:
        made = next((d for d in result.detections if d.placement is not None and int(d.query) >= int(a.first_query)), None)
        frame = None if made is None else result.frame_of(int(made.query))
        t = None if made is None or result.timestamps is None else float(result.timestamps[int(made.query) - base])
        p = _placement(a, result.frame_of, frame, t)
        assert p is not None
        out.append(p)
    last = placement_of_run(result)
    if out and last is not None:
        out[-1] = last
    return out


def frame_anchors_of_run(result: Any) -> F64:
    """Each frame's ``T_map_odom`` (N, 4, 4, one per frame of the run, in order): the transform of
    the placement whose stretch of the odometry holds the frame (:func:`placements_of_run`), all
    NaN for a frame no placement maps (a stretch between breaks no loop into the map placed, or
    every frame when the run was not placed). ``solid localize`` writes it as ``anchors.kitti``,
    which ``solid map merge --anchor`` applies place by place."""
    ids = np.asarray(result.frame_ids, dtype=np.int64)
    out = np.full((len(ids), 4, 4), np.nan)
    for p in placements_of_run(result):
        out[[p.places(int(f)) for f in ids]] = p.transform
    return out


class Localizer:
    """A session placed in a saved map, scan by scan (a stream, a live sensor).

    ``map`` is a :class:`solid.Database` with poses (``solid map build`` with ``--poses``) or the
    path of one; ``config`` a :class:`solid.config.PipelineConfig` (or a preset's name) whose
    descriptor the map was built with. Give each scan with its pose in the session's own frame
    (the odometry's ``T_odom_sensor``): the placement needs it. :attr:`placement` is None until
    consistent loops into the map place the session; :attr:`history` holds one :class:`Placement`
    per supporting set (the first placement, then each revision to a set that outgrew it), each
    updated as its set grows. A placement maps one stretch of the odometry between breaks
    (:attr:`Placement.from_frame` … :attr:`Placement.to_frame`): :attr:`current` is the one that
    maps the current frame (the ``map → odom`` to publish now; None after a break until the
    stretch after it is placed), :attr:`stretches` holds one per placed stretch."""

    def __init__(self, map: Any, config: PipelineConfig | str | None = None) -> None:
        db = _solid.Database.load(Path(map)) if isinstance(map, (str, Path)) else map
        if config is None:
            config = next((PipelineConfig.preset(n) for n, c in _solid.presets().items() if c == db.config), None)
            if config is None:
                config = PipelineConfig(descriptor=db.config, detector=_solid.DetectorConfig())
        elif isinstance(config, str):
            config = PipelineConfig.preset(config)
        if db.config != config.descriptor:
            raise _solid.DatabaseError(f"the map was built with {db.config!r}, this localizer uses {config.descriptor!r}")
        self.config = config
        self.detector = _solid.LoopDetector.from_database(db, detector=config.detector)
        self.history: list[Placement] = []
        self._frames = 0
        # When each stretch's anchor first appeared (by its stretch's first query id): frame, time.
        self._made: dict[int, tuple[int, float | None]] = {}

    @property
    def placement(self) -> Placement | None:
        """The latest placement (the latest of :attr:`history`), or None before the first."""
        return self.history[-1] if self.history else None

    @property
    def current(self) -> Placement | None:
        """The placement of the current frame of the odometry (the ``map → odom`` of now): the
        latest, unless a break of the odometry has come since its stretch (then None until the
        stretch after the break is placed)."""
        p = self.placement
        return p if p is not None and p.current else None

    @property
    def stretches(self) -> list[Placement]:
        """One placement per stretch of the odometry between breaks that loops into the map placed,
        in order (``LoopDetector.map_anchors``; the last is :attr:`placement`)."""
        start = int(self.detector.session_start)
        out = []
        for a in self.detector.map_anchors:
            frame, t = self._made.get(int(a.from_query), (None, None))
            p = _placement(a, lambda q: q - start, frame, t)
            assert p is not None
            out.append(p)
        if out and self.placement is not None:
            out[-1] = self.placement
        return out

    def add(self, points: npt.ArrayLike, *, pose: npt.ArrayLike | None = None, timestamp: float | None = None) -> Placement | None:
        """One scan (its points, ``pose`` ``T_odom_sensor``, ``timestamp``): the detector's step
        against the map; returns the placement after it (None: not placed yet)."""
        frame = self._frames
        step = self.detector.detect(points, timestamp=timestamp, pose=pose)
        self._frames += 1
        anchor = self.detector.map_anchor
        last = self.placement
        if anchor is None:
            return last
        for a in self.detector.map_anchors:
            self._made.setdefault(int(a.from_query), (frame, timestamp))
        start = int(self.detector.session_start)
        revised = last is None or step.placement is not None
        when = (frame, timestamp) if revised or last is None else (last.placed_frame, last.placed_time)
        now = _placement(anchor, lambda q: q - start, *when)
        assert now is not None
        if revised:
            self.history.append(now)
        else:
            self.history[-1] = now
        return now
