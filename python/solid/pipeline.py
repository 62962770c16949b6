"""The loop-closure pipeline: one code path for ``solid detect``, ``eval``, ``demo`` and the maps.

:class:`LoopClosurePipeline` reads a dataset, applies the input options of its
:class:`~solid.config.PipelineConfig`, describes the scans on every core, and feeds them in order
to one :class:`solid.LoopDetector`, keeping every :class:`solid.Detection` (the ranked candidates
and the accepted loop of each step). Everything downstream uses that record: ``loops.csv`` lists
the accepted loops, and the evaluation scores the same candidates against poses
(:mod:`solid.evaluation`, docs/spec.md §5) — there is no second search or heading anywhere::

    import solid
    from solid.config import PipelineConfig
    from solid.pipeline import LoopClosurePipeline

    ds = solid.datasets.open_dataset("hku1-avia", poses="odom_poses.txt")
    result = LoopClosurePipeline(ds, PipelineConfig.preset("avia")).run()
    print(len(result.loops()), "loops")
    ev = result.evaluate(radius=3.0)
    print(ev.metrics()["recall_at_1"])
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence as AbcSequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from . import _solid
from . import io as sio
from .config import PipelineConfig
from .evaluation import POSE_COLUMNS

__all__ = [
    "Dataset",
    "open_dataset",
    "LOOP_COLUMNS",
    "LoopClosurePipeline",
    "PipelineResult",
    "auto_fov_center",
    "parse_frames",
    "select_frames",
]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]

#: Columns of ``loops.csv`` (one row per accepted loop), in order. ``query``/``candidate`` are ids
#: in the detector's database (a prior map's places first); ``*_frame`` the frame number in the
#: query's own recording (empty for a map place); times in seconds (empty when unknown). A verified
#: loop has its pose ``T_query_candidate`` (``p_query ≈ T·p_candidate``, docs/spec.md §3) as
#: ``x,y,z`` and the unit quaternion ``qx,qy,qz,qw``, with the registration's ``fitness`` and
#: ``rmse`` (metres).
LOOP_COLUMNS = (
    "query",
    "candidate",
    "distance",
    "score",
    "heading_deg",
    "query_time",
    "candidate_time",
    "query_session",
    "candidate_session",
    "query_frame",
    "candidate_frame",
    *POSE_COLUMNS,
)


class Dataset(Protocol):
    """What the pipeline reads: ``solid.datasets.open_dataset`` gives one, and so does the simulator."""

    timestamps: F64 | None
    poses: F64 | None

    def __len__(self) -> int: ...
    def __getitem__(self, i: int) -> F32: ...
    def __iter__(self) -> Iterator[F32]: ...


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
                    raise _solid.ConfigError(f"frames: frame {i} is out of range for {n} scans")
                idx = [i % n]
        except ValueError:
            raise _solid.ConfigError(f"frames: cannot parse {part!r} (use e.g. 0:60,284:314)") from None
        for i in idx:
            if i not in seen:
                seen.add(i)
                out.append(i)
    if not out:
        raise _solid.ConfigError(f"frames {spec!r} selects no scans")
    return out


def select_frames(n: int, poses: F64 | None, frames: str | None, subsample_m: float | None) -> list[int]:
    """The dataset indices the pipeline reads, in order (``input.frames``, then ``subsample_m``)."""
    idx = parse_frames(frames, n) if frames else list(range(n))
    if subsample_m is not None:
        if poses is None:
            raise _solid.ConfigError("input.subsample_m needs poses")
        keep = sio.subsample_by_distance(poses[idx], subsample_m)
        idx = [idx[int(k)] for k in keep]
    return idx


def auto_fov_center(points: npt.NDArray[Any], width_deg: float) -> float:
    """The centre (degrees, 0 = +x, counter-clockwise) of the ``width_deg`` sector holding the most
    points of a scan: where to clip when the user gave no centre, so that a sensor whose +x is
    blocked (or points elsewhere) is not clipped to an empty sector."""
    p = np.asarray(points)
    if p.shape[0] == 0:
        return 0.0
    az = np.degrees(np.arctan2(p[:, 1].astype(np.float64), p[:, 0].astype(np.float64))) % 360.0
    hist = np.bincount(np.minimum(az.astype(np.int64), 359), minlength=360).astype(np.float64)
    w = max(1, min(360, int(round(width_deg))))
    windows = np.convolve(np.r_[hist, hist[: w - 1]], np.ones(w), mode="valid")[:360]
    start = int(np.argmax(windows))
    centre = (start + w / 2.0) % 360.0
    return float(centre - 360.0 if centre > 180.0 else centre)


@dataclass
class PipelineResult:
    """What one run decided, step by step, and what it needs to be scored and written."""

    config: PipelineConfig
    detections: list[Any]
    database: Any
    frames: list[int]
    frame_ids: I64
    timestamps: F64 | None
    poses: F64 | None
    map_size: int
    session: int
    fov_center: float | None
    timings: dict[str, float] = field(default_factory=dict)

    def queries(self) -> list[Any]:
        """The steps that had a database to search (docs/spec.md §5 skips the others)."""
        return [d for d in self.detections if d.eligible > 0]

    def loops(self) -> list[Any]:
        """The accepted loops (``solid.Loop``), in query order."""
        return [d.loop for d in self.detections if d.loop is not None]

    def frame_of(self, entry_id: int) -> int | None:
        """The recording frame number of a database entry of this session (None for map places)."""
        k = entry_id - self.map_size
        return int(self.frame_ids[k]) if 0 <= k < len(self.frame_ids) else None

    def loop_rows(self) -> list[dict[str, Any]]:
        """``loops.csv`` rows (:data:`LOOP_COLUMNS`)."""
        times = np.asarray(self.database.timestamps)
        sessions = np.asarray(self.database.sessions)
        return [loop_row(lp, times, sessions, self.frame_of) for lp in self.loops()]

    def evaluate(self, radius: float | None = None, name: str = "SOLiD") -> Any:
        """docs/spec.md §5 scores of this run's candidates against the poses of every place (the map's
        stored poses and this recording's), at ``radius`` (default: the config's)."""
        from .evaluation import evaluate_detections

        det = self.config.detector
        return evaluate_detections(
            name,
            self.detections,
            self.database,
            radius=self.config.radius if radius is None else radius,
            # With verification, the scores of the loops that passed the gate lie in [0, 1].
            threshold=_solid.VERIFIED_THRESHOLD if det.verify else det.threshold,
            frame_of=self.frame_of,
        )


def _fmt_opt(v: float | int | None, fmt: str = ".6f") -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    return format(v, fmt) if isinstance(v, float) else str(v)


def loop_row(lp: Any, times: F64, sessions: npt.NDArray[np.uint32], frame_of: Callable[[int], int | None]) -> dict[str, Any]:
    """One ``loops.csv`` row; eval's ``queries.csv`` formats the same fields the same way."""
    from .evaluation import pose_columns

    q, c = int(lp.query), int(lp.candidate)
    return {
        "query": q,
        "candidate": c,
        "distance": f"{lp.distance:.6f}",
        "score": f"{lp.score:.6f}",
        "heading_deg": f"{lp.heading:.3f}",
        "query_time": _fmt_opt(float(times[q])) if q < len(times) else "",
        "candidate_time": _fmt_opt(float(times[c])),
        "query_session": int(sessions[q]) if q < len(sessions) else "",
        "candidate_session": int(sessions[c]),
        "query_frame": _fmt_opt(frame_of(q)),
        "candidate_frame": _fmt_opt(frame_of(c)),
        **pose_columns(lp.pose, lp.fitness, lp.rmse),
    }


class LoopClosurePipeline:
    """Runs one :class:`solid.LoopDetector` over a dataset (see the module docstring).

    ``map`` (a :class:`solid.Database`, e.g. from ``solid map build``) makes the run query this
    recording against a prior session: the map's places are candidates from the first scan on and
    never excluded; the recording's own scans are added as a new session, with the exclusion
    window applying among them. ``progress`` is called with the number of scans done; ``on_scan``
    with each scan as described (after the input options), e.g. to describe it for a baseline.
    """

    def __init__(
        self,
        dataset: Any,
        config: PipelineConfig,
        *,
        map: Any | None = None,
        threads: int | None = None,
        progress: Callable[[int], None] | None = None,
        on_scan: Callable[[int, F32], None] | None = None,
        chunk: int = 64,
    ) -> None:
        if threads is not None and threads < 1:
            raise _solid.ConfigError(f"threads must be >= 1, got {threads}")
        if chunk < 1:
            raise _solid.ConfigError(f"chunk must be >= 1, got {chunk}")
        self.dataset = dataset
        self.config = config
        self.map = map
        self.threads = threads
        self.progress = progress
        self.on_scan = on_scan
        self.chunk = chunk
        if map is not None and map.config != config.descriptor:
            raise _solid.DatabaseError(
                f"the map was built with {map.config!r}, this run uses {config.descriptor!r}: "
                "descriptors of different configurations cannot be compared"
            )

    def _detector(self) -> Any:
        if self.map is not None:
            return _solid.LoopDetector.from_database(self.map, detector=self.config.detector)
        return _solid.LoopDetector(self.config.descriptor, detector=self.config.detector)

    def run(self) -> PipelineResult:
        ds = self.dataset
        opts = self.config.input
        poses_all: F64 | None = None if getattr(ds, "poses", None) is None else np.asarray(ds.poses, dtype=np.float64)
        times_all: F64 | None = None if getattr(ds, "timestamps", None) is None else np.asarray(ds.timestamps, dtype=np.float64)
        idx = select_frames(len(ds), poses_all, opts.frames, opts.subsample_m)
        det = self._detector()
        detections: list[Any] = []
        batch: list[F32] = []
        batch_idx: list[int] = []
        fov_center = opts.fov_center
        t_detect = 0.0

        def flush() -> None:
            nonlocal t_detect
            if not batch:
                return
            t0 = time.perf_counter()
            ts = None if times_all is None else [float(times_all[i]) for i in batch_idx]
            ps = None if poses_all is None else [poses_all[i] for i in batch_idx]
            # The detector describes (and, when it verifies, prepares the clouds of) the batch on
            # every core, then runs its steps in order.
            detections.extend(det.detect_many(batch, ts, ps, threads=self.threads))
            t_detect += time.perf_counter() - t0
            if self.progress is not None:
                self.progress(len(batch))
            batch.clear()
            batch_idx.clear()

        for i, pts in zip(idx, _iter_selected(ds, idx)):
            if opts.fov is not None:
                if fov_center is None:
                    fov_center = auto_fov_center(pts, opts.fov)
                pts = sio.clip_fov(pts, opts.fov, fov_center)
            if opts.occlude is not None:
                pts = sio.occlude_sector(pts, opts.occlude, opts.occlude_center)
            xyz = np.ascontiguousarray(pts[:, :3])
            if self.on_scan is not None:
                self.on_scan(i, xyz)
            batch.append(xyz)
            batch_idx.append(i)
            if len(batch) >= self.chunk:
                flush()
        flush()
        frame_ids = np.asarray(getattr(ds, "frame_ids", np.arange(len(ds))), dtype=np.int64)[idx]
        return PipelineResult(
            config=self.config,
            detections=detections,
            database=det.database,
            frames=idx,
            frame_ids=frame_ids,
            timestamps=None if times_all is None else times_all[idx],
            poses=None if poses_all is None else poses_all[idx],
            map_size=int(det.session_start),
            session=int(det.session),
            fov_center=fov_center,
            timings={"detect_s": t_detect},
        )


def _iter_selected(ds: Any, idx: AbcSequence[int]) -> Iterator[F32]:
    """Scans idx[0], idx[1], ... read once each: streamed in order when the selection is every
    scan (bags read sequentially), by index otherwise."""
    if list(idx) == list(range(len(ds))):
        yield from iter(ds)
        return
    if getattr(ds, "is_bag", False):
        want = {i: k for k, i in enumerate(idx)}
        buf: dict[int, F32] = {}
        nxt = 0
        for i, pts in enumerate(ds):
            if i in want:
                buf[want[i]] = pts
                while nxt in buf:
                    yield buf.pop(nxt)
                    nxt += 1
            if nxt == len(idx):
                return
        return
    for i in idx:
        yield ds[i]


def open_dataset(
    path: Path | str,
    *,
    format: str | None = None,
    topic: str | None = None,
    poses: Path | str | None = None,
    timestamps: Path | str | None = None,
    calib: Path | str | None = None,
) -> tuple[Any, dict[str, Any]]:
    """Opens a recording for the pipeline (:func:`solid.datasets.open_dataset`); returns it and a
    record of what was read: the reader chosen and the absolute paths of every file used."""
    from .datasets import open_dataset as _open

    ds = _open(path, format=format, topic=topic, poses=poses, timestamps=timestamps, calib=calib)
    info = {
        "sequence": Path(ds.path),
        "reader": ds.reader,
        "poses": ds.pose_source,
        "timestamps": ds.timestamp_source,
        "calib": ds.calib_source,
    }
    return ds, info
