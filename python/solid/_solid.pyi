"""Type stubs of the compiled extension `solid._solid` (checked by mypy.stubtest)."""

import os
from collections.abc import Iterable, Sequence
from os import PathLike
from typing import Any, final

import numpy as np
import numpy.typing as npt

__all__ = [
    "__version__",
    "SolidError",
    "ConfigError",
    "SolidConfig",
    "Descriptor",
    "describe",
    "describe_batch",
    "distance",
    "heading",
    "presets",
    "preset_sensors",
    "_config_from_dict",
    "DatabaseError",
    "Database",
    "Match",
    "LoopDetector",
    "Loop",
    "Candidate",
    "Detection",
    "DetectorConfig",
    "_detector_config_from_dict",
    "DEFAULT_RADIUS",
    "Scores",
    "score_candidates",
    "_SIM_SENSORS",
    "_SIM_TRAJECTORIES",
    "encode_place",
    "decode_place",
    "_SimWorld",
    "_SimSensor",
    "_sim_world",
    "_sim_sensor",
    "_sim_scan",
    "_sim_scans",
    "_sim_trajectory",
    "_sim_route",
    "_sim_spin",
    "_sim_write_sequence",
    "_sim_write_scans",
    "_lzf_decompress_into",
    "_lzf_max_decompressed_len",
]

__version__: str

class SolidError(ValueError):
    """Base class of the errors raised by solid (a ValueError)."""

class ConfigError(SolidError):
    """An invalid configuration parameter or preset name."""

@final
class SolidConfig:
    """SOLiD parameters (SPEC §1), immutable; invalid values raise ConfigError naming the parameter."""

    def __new__(
        cls,
        *,
        fov_up: float,
        fov_down: float,
        n_elevation: int,
        n_range: int | None = None,
        n_azimuth: int | None = None,
        min_range: float | None = None,
        max_range: float | None = None,
        voxel_size: float | None = None,
    ) -> SolidConfig: ...
    @staticmethod
    def preset(name: str, **overrides: float) -> SolidConfig: ...
    def replace(self, **overrides: float) -> SolidConfig: ...
    @property
    def base_preset(self) -> str | None: ...
    def to_dict(self) -> dict[str, Any]: ...
    @property
    def n_range(self) -> int: ...
    @property
    def n_azimuth(self) -> int: ...
    @property
    def n_elevation(self) -> int: ...
    @property
    def fov_up(self) -> float: ...
    @property
    def fov_down(self) -> float: ...
    @property
    def min_range(self) -> float: ...
    @property
    def max_range(self) -> float: ...
    @property
    def voxel_size(self) -> float: ...
    @property
    def fingerprint(self) -> int: ...
    def __eq__(self, value: object, /) -> bool: ...
    def __ne__(self, value: object, /) -> bool: ...
    def __hash__(self) -> int: ...
    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]: ...

@final
class Descriptor:
    """One scan's SOLiD descriptor: R-SOLiD (``r``) and A-SOLiD (``a``) with point counts."""

    def __new__(
        cls,
        r: npt.ArrayLike,
        a: npt.ArrayLike,
        config: SolidConfig,
        n_points: int = 0,
        n_in_range: int = 0,
        n_kept: int = 0,
    ) -> Descriptor: ...
    @property
    def r(self) -> npt.NDArray[np.float32]: ...
    @property
    def a(self) -> npt.NDArray[np.float32]: ...
    @property
    def n_points(self) -> int: ...
    @property
    def n_in_range(self) -> int: ...
    @property
    def n_kept(self) -> int: ...
    @property
    def config(self) -> SolidConfig: ...
    def distance(self, other: Descriptor) -> float: ...
    def heading(self, candidate: Descriptor, refine: bool = True) -> float: ...
    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]: ...

def describe(points: npt.NDArray[np.float32] | npt.NDArray[np.float64], config: SolidConfig) -> Descriptor: ...
def describe_batch(
    scans: Iterable[npt.NDArray[np.float32] | npt.NDArray[np.float64]],
    config: SolidConfig,
    threads: int | None = None,
) -> list[Descriptor]: ...
def distance(a: Descriptor, b: Descriptor) -> float: ...
def heading(query: Descriptor, candidate: Descriptor, refine: bool = True) -> float: ...
def presets() -> dict[str, SolidConfig]: ...
def preset_sensors() -> dict[str, str]: ...
def _config_from_dict(d: dict[str, Any]) -> SolidConfig: ...

# --- search, database, loop detector, wire form (engine.rs) ---

class DatabaseError(SolidError):
    """A database, place or loop-detector error: config mismatch, corrupt, truncated, foreign or
    newer-version file (the message names the file and the reason)."""

@final
class Match:
    """One search result."""
    @property
    def id(self) -> int: ...
    @property
    def distance(self) -> float: ...
    def __eq__(self, other: object, /) -> bool: ...

@final
class Loop:
    """A detected loop closure."""
    @property
    def query(self) -> int: ...
    @property
    def candidate(self) -> int: ...
    @property
    def distance(self) -> float: ...
    @property
    def heading(self) -> float: ...
    @property
    def score(self) -> float: ...
    def __eq__(self, other: object, /) -> bool: ...

@final
class Candidate:
    """One candidate of a detector step, in the detector's order."""
    @property
    def id(self) -> int: ...
    @property
    def distance(self) -> float: ...
    @property
    def heading(self) -> float: ...
    @property
    def score(self) -> float: ...
    def __eq__(self, other: object, /) -> bool: ...

@final
class Detection:
    """Everything one detector step decided."""
    @property
    def query(self) -> int: ...
    @property
    def eligible(self) -> int: ...
    @property
    def candidates(self) -> list[Candidate]: ...
    @property
    def loop(self) -> Loop | None: ...

@final
class DetectorConfig:
    """The loop detector's parameters; defaults come from the core."""
    def __new__(
        cls,
        *,
        exclude_frames: int = ...,
        exclude_meters: float = ...,
        exclude_seconds: float = ...,
        threshold: float = ...,
        top_k: int = ...,
        rerank: bool = ...,
    ) -> DetectorConfig: ...
    @staticmethod
    def preset(
        name: str,
        *,
        exclude_frames: int = ...,
        exclude_meters: float = ...,
        exclude_seconds: float = ...,
        threshold: float = ...,
        top_k: int = ...,
        rerank: bool = ...,
    ) -> DetectorConfig: ...
    def replace(
        self,
        *,
        exclude_frames: int = ...,
        exclude_meters: float = ...,
        exclude_seconds: float = ...,
        threshold: float = ...,
        top_k: int = ...,
        rerank: bool = ...,
    ) -> DetectorConfig: ...
    def to_dict(self) -> dict[str, Any]: ...
    @property
    def exclude_frames(self) -> int: ...
    @property
    def exclude_meters(self) -> float: ...
    @property
    def exclude_seconds(self) -> float: ...
    @property
    def threshold(self) -> float: ...
    @property
    def top_k(self) -> int: ...
    @property
    def rerank(self) -> bool: ...
    def __eq__(self, other: object, /) -> bool: ...
    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]: ...

def _detector_config_from_dict(params: dict[str, Any]) -> DetectorConfig: ...

@final
class Database:
    """Places with exact search at every size (online kd-tree index), merge, save and load."""
    def __new__(cls, cfg: SolidConfig) -> Database: ...
    def add(
        self,
        descriptor: Descriptor,
        session: int = 0,
        timestamp: float | None = None,
        pose: npt.ArrayLike | None = None,
    ) -> int: ...
    def search(
        self,
        descriptor: Descriptor | npt.ArrayLike,
        k: int = 1,
        exclude_recent: int = 0,
        method: str = "auto",
        not_newer_than: float | None = None,
    ) -> list[Match]: ...
    def distances(self, descriptor: Descriptor | npt.ArrayLike) -> npt.NDArray[np.float32]: ...
    def merge(self, other: Database, new_sessions: bool = False) -> None: ...
    def save(self, path: str | PathLike[str]) -> None: ...
    @staticmethod
    def load(path: str | PathLike[str]) -> Database: ...
    def to_bytes(self) -> bytes: ...
    @staticmethod
    def from_bytes(data: bytes) -> Database: ...
    def __len__(self) -> int: ...
    @property
    def config(self) -> SolidConfig: ...
    @property
    def r(self) -> npt.NDArray[np.float32]: ...
    @property
    def a(self) -> npt.NDArray[np.float32]: ...
    @property
    def ids(self) -> npt.NDArray[np.int64]: ...
    @property
    def sessions(self) -> npt.NDArray[np.uint32]: ...
    @property
    def timestamps(self) -> npt.NDArray[np.float64]: ...
    @property
    def poses(self) -> npt.NDArray[np.float64]: ...

@final
class LoopDetector:
    """Online loop closure: each scan is searched against the places it may be matched with (a
    prior map, and its own session minus the exclusion window), then added."""
    def __new__(
        cls,
        cfg: SolidConfig,
        exclude_recent: int | None = None,
        threshold: float | None = None,
        top_k: int | None = None,
        rerank: bool | None = None,
        *,
        exclude_meters: float | None = None,
        exclude_seconds: float | None = None,
        detector: DetectorConfig | None = None,
    ) -> LoopDetector: ...
    @staticmethod
    def from_database(
        database: Database,
        exclude_recent: int | None = None,
        threshold: float | None = None,
        top_k: int | None = None,
        rerank: bool | None = None,
        *,
        exclude_meters: float | None = None,
        exclude_seconds: float | None = None,
        detector: DetectorConfig | None = None,
    ) -> LoopDetector: ...
    def add(
        self,
        points_or_descriptor: Descriptor | npt.ArrayLike,
        timestamp: float | None = None,
        pose: npt.ArrayLike | None = None,
    ) -> Loop | None: ...
    def detect(
        self,
        points_or_descriptor: Descriptor | npt.ArrayLike,
        timestamp: float | None = None,
        pose: npt.ArrayLike | None = None,
    ) -> Detection: ...
    def detect_many(
        self,
        descriptors: Sequence[Descriptor],
        timestamps: Sequence[float | None] | npt.ArrayLike | None = None,
        poses: Sequence[npt.ArrayLike | None] | npt.ArrayLike | None = None,
    ) -> list[Detection]: ...
    def candidates(
        self,
        points_or_descriptor: Descriptor | npt.ArrayLike,
        k: int | None = None,
        timestamp: float | None = None,
        pose: npt.ArrayLike | None = None,
    ) -> list[Candidate]: ...
    def query(self, points_or_descriptor: Descriptor | npt.ArrayLike) -> Loop | None: ...
    def __len__(self) -> int: ...
    @property
    def database(self) -> Database: ...
    @property
    def config(self) -> DetectorConfig: ...
    @property
    def session(self) -> int: ...
    @property
    def session_start(self) -> int: ...
    @property
    def exclude_recent(self) -> int: ...
    @property
    def threshold(self) -> float: ...
    @property
    def top_k(self) -> int: ...
    @property
    def rerank(self) -> bool: ...

# --- SPEC §5 scoring (eval.rs) ---

DEFAULT_RADIUS: float

@final
class Scores:
    """Per-query outcomes and summary metrics of one scored run (SPEC §5)."""
    @property
    def radius(self) -> float: ...
    @property
    def gt_positive(self) -> npt.NDArray[np.bool_]: ...
    @property
    def correct(self) -> npt.NDArray[np.bool_]: ...
    @property
    def first_hit(self) -> npt.NDArray[np.uint32]: ...
    @property
    def candidate_distance_m(self) -> npt.NDArray[np.float64]: ...
    @property
    def true_heading_deg(self) -> npt.NDArray[np.float64]: ...
    @property
    def n_gt(self) -> int: ...
    def recall_at(self, n: int) -> float: ...
    def pr_curve(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    def roc_curve(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    def f1_max(self) -> tuple[float, float]: ...
    def auc(self) -> float: ...
    def at_threshold(self, threshold: float) -> tuple[int, int, float, float]: ...
    def rotation_errors(self) -> npt.NDArray[np.float64]: ...
    def __len__(self) -> int: ...

def score_candidates(
    query: npt.NDArray[np.int64],
    eligible: npt.NDArray[np.int64],
    ids: npt.NDArray[np.int64],
    score: npt.NDArray[np.float64],
    heading_deg: npt.NDArray[np.float64],
    poses: npt.NDArray[np.float64],
    radius: float,
) -> Scores: ...

def encode_place(descriptor: Descriptor, quantized: bool = False) -> bytes: ...
def decode_place(data: bytes, cfg: SolidConfig) -> Descriptor: ...

# --- simulator (sim.rs), used by solid.sim ---

_SIM_SENSORS: list[str]
_SIM_TRAJECTORIES: list[str]

@final
class _SimWorld:
    @property
    def seed(self) -> int: ...
    @property
    def blocks(self) -> int: ...
    @property
    def block_pitch(self) -> float: ...
    @property
    def roads(self) -> list[float]: ...
    @property
    def bounds(self) -> tuple[float, float, float, float]: ...
    def __len__(self) -> int: ...
    def ground_height(self, x: float, y: float) -> float: ...
    def footprints(self) -> tuple[list[str], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...

@final
class _SimSensor:
    @property
    def name(self) -> str: ...
    @property
    def h_fov(self) -> float: ...
    @property
    def h_centre(self) -> float: ...
    @property
    def min_range(self) -> float: ...
    @property
    def max_range(self) -> float: ...
    @property
    def noise(self) -> float: ...
    @property
    def dropout(self) -> float: ...
    @property
    def seed(self) -> int: ...
    @property
    def vertical_fov(self) -> tuple[float, float]: ...
    @property
    def channels(self) -> int: ...
    def n_rays(self, frame: int = 0) -> int: ...

def _sim_world(
    seed: int = 0,
    blocks: int = 4,
    block_pitch: float = 80.0,
    road_half_width: float = 7.0,
    slope: tuple[float, float] = ...,  # (0.01, -0.006)
    repetition: float = 0.3,
    cell_size: float = 4.0,
) -> _SimWorld: ...
def _sim_sensor(
    name: str,
    h_fov: float | None = None,
    h_centre: float = 0.0,
    min_range: float | None = None,
    max_range: float | None = None,
    noise: float | None = None,
    dropout: float = 0.0,
    seed: int = 0,
    points: int | None = None,
) -> _SimSensor: ...
def _sim_scan(world: _SimWorld, sensor: _SimSensor, pose: npt.NDArray[np.float64], frame: int = 0) -> npt.NDArray[np.float32]: ...
def _sim_scans(
    world: _SimWorld, sensor: _SimSensor, poses: npt.NDArray[np.float64], first_frame: int = 0
) -> list[npt.NDArray[np.float32]]: ...
def _sim_trajectory(
    world: _SimWorld,
    kind: str,
    spacing: float = 1.0,
    laps: float = 1.0,
    lane_offset: float = 1.75,
    corner_radius: float = 8.0,
    speed: float = 10.0,
    mount_height: float = 1.73,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def _sim_route(
    world: _SimWorld,
    waypoints: list[tuple[float, float]],
    spacing: float = 1.0,
    lane_offset: float = 1.75,
    corner_radius: float = 8.0,
    speed: float = 10.0,
    mount_height: float = 1.73,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def _sim_spin(
    world: _SimWorld, x: float, y: float, headings: list[float], mount_height: float = 1.73
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def _sim_write_sequence(
    directory: str | os.PathLike[str],
    world: _SimWorld,
    sensor: _SimSensor,
    poses: npt.NDArray[np.float64],
    times: list[float],
) -> int: ...
def _sim_write_scans(
    directory: str | os.PathLike[str],
    scans: list[npt.NDArray[np.float32]],
    poses: npt.NDArray[np.float64],
    times: list[float],
) -> int: ...
def _lzf_decompress_into(data: bytes, out: npt.NDArray[np.uint8], start: int = 0, stop: int | None = None) -> int:
    """Decode the LZF stream ``data[start:stop]`` into ``out`` (uint8, C-contiguous); returns the bytes written."""

def _lzf_max_decompressed_len(n: int) -> int:
    """The most bytes an LZF stream of ``n`` bytes can decode to."""
