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

import sys
import time
import warnings
from collections.abc import Callable, Iterator, Sequence as AbcSequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Protocol, Union

import numpy as np

from . import _solid
from .arrays import F32, F64, I64
from .config import PipelineConfig
from .datasets.selection import iter_selected, select_frames
from .evaluation import evaluate_detections
from .records import LOOP_COLUMNS, loop_row
from .transforms import clip_fov, occlude_sector

__all__ = ["DEFAULT_FOV_CENTER", "input_points", "LOOP_COLUMNS", "LoopClosurePipeline", "PipelineResult", "Progress", "ScanSource", "check_run", "progress_bar"]

#: The centre of ``input.fov`` when none is given (degrees; 0 = +x, the sensor's forward axis): the
#: same for every run, so that a map and the runs queried against it clip the same sector.
DEFAULT_FOV_CENTER = 0.0

#: What a long call takes as ``progress``: a callable given the number of scans done since its
#: last call, ``True`` (a progress bar on stderr), ``False`` (none) or ``None`` (a bar when stderr
#: is a terminal: interactive use).
Progress = Union[Callable[[int], None], bool, None]


def input_points(pts: F32, opts: Any, fov_center: float | None, *, clipped: bool = False) -> F32:
    """What the detector is given of one scan: its x y z after the input options' sector clip
    (``opts.fov`` around ``fov_center``; skipped when ``clipped``, the caller having done it) and
    occlusion. The pipeline and the ROS 2 node (:mod:`solid.ros2`) prepare every scan with it."""
    if not clipped and opts.fov is not None and fov_center is not None:
        pts = clip_fov(pts, opts.fov, fov_center)
    if opts.occlude is not None:
        pts = occlude_sector(pts, opts.occlude, opts.occlude_center)
    return np.ascontiguousarray(pts[:, :3])


@contextmanager
def progress_bar(progress: Progress, total: int | None, desc: str) -> Iterator[Callable[[int], None] | None]:
    """The callable a long call reports its scans to, for a ``progress`` argument (:data:`Progress`)."""
    if callable(progress):
        yield progress
        return
    if progress is False or (progress is None and not sys.stderr.isatty()):
        yield None
        return
    from tqdm import tqdm

    with tqdm(total=total, desc=desc, unit="scan", file=sys.stderr, dynamic_ncols=True, leave=False) as bar:

        def update(n: int) -> None:
            bar.update(n)

        yield update


def check_run(dataset: Any, config: PipelineConfig) -> list[int]:
    """Every check a run needs, before its first scan is read: the frames and subsampling select
    something, and every selected frame has its pose and time when the files give them. Returns
    the frames the run reads."""
    poses = getattr(dataset, "poses", None)
    times = getattr(dataset, "timestamps", None)
    opts = config.input
    idx = select_frames(len(dataset), None if poses is None else np.asarray(poses, dtype=np.float64), opts.frames, opts.subsample_m)
    for what, a in (("poses", poses), ("timestamps", times)):
        if a is not None and idx and not np.isfinite(np.asarray(a, dtype=np.float64)[idx].reshape(len(idx), -1)).all():
            raise _solid.ConfigError(f"a selected frame has no row in the {what} file")
    return idx


class ScanSource(Protocol):
    """What the pipeline reads: a :class:`solid.datasets.Dataset` is one, and so is a simulated
    :class:`solid.sim.Sequence`."""

    timestamps: F64 | None
    poses: F64 | None

    def __len__(self) -> int: ...
    def __getitem__(self, i: int) -> F32: ...
    def __iter__(self) -> Iterator[F32]: ...


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
    #: The session's placement in the map (``solid.MapAnchor``; None without a map, or before
    #: consistent loops into it placed the session: docs/spec.md §8, placement).
    map_anchor: Any = None
    #: One anchor per stretch of the session's odometry between breaks that loops into the map
    #: placed (``LoopDetector.map_anchors``, in order; the last is ``map_anchor``).
    map_anchors: list[Any] = field(default_factory=list)

    def queries(self) -> list[Any]:
        """The steps that had a database to search (docs/spec.md §5 skips the others)."""
        return [d for d in self.detections if d.eligible > 0]

    def loops(self) -> list[Any]:
        """The accepted loops (``solid.Loop``), in query order: each step's loop and the loops into
        the map a later step released (``Detection.released``: held until the session's placement
        in the map, docs/spec.md §8)."""
        out = [d.loop for d in self.detections if d.loop is not None]
        late = [lp for d in self.detections for lp in d.released]
        return sorted(out + late, key=lambda lp: int(lp.query)) if late else out

    def frame_of(self, entry_id: int) -> int | None:
        """The recording frame number of a database entry of this session (None for map places)."""
        k = entry_id - self.map_size
        return int(self.frame_ids[k]) if 0 <= k < len(self.frame_ids) else None

    def loop_rows(self) -> list[dict[str, Any]]:
        """``loops.csv`` rows (:data:`LOOP_COLUMNS`)."""
        times = np.asarray(self.database.timestamps)
        sessions = np.asarray(self.database.sessions)
        return [loop_row(lp, times, sessions, self.frame_of) for lp in self.loops()]

    def evaluate(self, radius: float | None = None, name: str = "SOLiD", unknown: AbcSequence[int] = ()) -> Any:
        """docs/spec.md §5 scores of this run's candidates against the poses of every place (the map's
        stored poses and this recording's), at ``radius`` (default: the config's); ``unknown``: the
        places whose pose is unknown, left out (:func:`solid.evaluation.evaluate_detections`)."""
        det = self.config.detector
        return evaluate_detections(
            name,
            self.detections,
            self.database,
            radius=self.config.radius if radius is None else radius,
            pose_tolerance_m=self.config.pose_tolerance_m,
            pose_tolerance_deg=self.config.pose_tolerance_deg,
            # With verification, the scores of the loops that passed the gate lie in [0, 1].
            threshold=_solid.VERIFIED_THRESHOLD if det.verify else det.threshold,
            frame_of=self.frame_of,
            unknown=unknown,
        )


class LoopClosurePipeline:
    """Runs one :class:`solid.LoopDetector` over a dataset (see the module docstring).

    ``map`` (a :class:`solid.Database`, e.g. from ``solid map build``) makes the run query this
    recording against a prior session: the map's places are candidates from the first scan on and
    never excluded; the recording's own scans are added as a new session, with the exclusion
    window applying among them. ``progress`` (:data:`Progress`) hears of every scan done: a
    callable is called with the number done since its last call, ``True`` shows a bar on stderr,
    ``None`` (the default) shows one in interactive use. ``on_scan`` is called with each scan as
    described (after the input options), e.g. to describe it for a baseline. Everything is checked
    before the first scan is read (:func:`check_run`); Ctrl-C raises ``KeyboardInterrupt`` within
    a step.
    """

    def __init__(
        self,
        dataset: Any,
        config: PipelineConfig,
        *,
        map: Any | None = None,
        threads: int | None = None,
        progress: Progress = None,
        on_scan: Callable[[int, F32], None] | None = None,
        chunk: int = 64,
    ) -> None:
        if threads is not None and threads < 0:
            raise _solid.ConfigError(f"threads must be >= 0 (0: one per core), got {threads}")
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
        check_run(dataset, config)

    def _detector(self) -> Any:
        if self.map is not None:
            return _solid.LoopDetector.from_database(self.map, detector=self.config.detector)
        return _solid.LoopDetector(self.config.descriptor, detector=self.config.detector)

    def run(self) -> PipelineResult:
        ds = self.dataset
        opts = self.config.input
        poses_all: F64 | None = None if getattr(ds, "poses", None) is None else np.asarray(ds.poses, dtype=np.float64)
        times_all: F64 | None = None if getattr(ds, "timestamps", None) is None else np.asarray(ds.timestamps, dtype=np.float64)
        idx = check_run(ds, self.config)
        with progress_bar(self.progress, len(idx), "scans") as report:
            return self._run(ds, idx, poses_all, times_all, report)

    def _run(self, ds: Any, idx: list[int], poses_all: F64 | None, times_all: F64 | None, report: Callable[[int], None] | None) -> PipelineResult:
        opts = self.config.input
        det = self._detector()
        detections: list[Any] = []
        batch: list[F32] = []
        batch_idx: list[int] = []
        fov_center = DEFAULT_FOV_CENTER if opts.fov is not None and opts.fov_center is None else opts.fov_center
        t_detect = 0.0

        def flush() -> None:
            nonlocal t_detect
            if not batch:
                return
            t0 = time.perf_counter()
            ts = None if times_all is None else [float(times_all[i]) for i in batch_idx]
            ps = None if poses_all is None else [poses_all[i] for i in batch_idx]
            # The detector describes (and, when it verifies, prepares the clouds of) the batch on
            # every core, then runs its steps in order, reporting each.
            detections.extend(det.detect_many(batch, ts, ps, threads=self.threads, progress=report))
            t_detect += time.perf_counter() - t0
            batch.clear()
            batch_idx.clear()

        for k, (i, pts) in enumerate(zip(idx, iter_selected(ds, idx))):
            if opts.fov is not None and fov_center is not None:
                clipped = clip_fov(pts, opts.fov, fov_center)
                # Empty, or nearly (a tenth of what a sensor seeing all around would put there).
                if k == 0 and clipped.shape[0] < 0.1 * pts.shape[0] * opts.fov / 360.0:
                    warnings.warn(
                        f"the first scan has {clipped.shape[0]} of its {pts.shape[0]} points within the --fov {opts.fov:g}° sector centred on "
                        f"{fov_center:g}° (0 = +x); give --fov-center (input.fov_center) where the sensor sees",
                        UserWarning,
                        stacklevel=2,
                    )
                pts = clipped
            xyz = input_points(pts, opts, fov_center, clipped=True)
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
            map_anchor=det.map_anchor,
            map_anchors=list(det.map_anchors),
            fov_center=fov_center,
            timings={"detect_s": t_detect},
        )
