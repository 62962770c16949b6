"""Type stubs of the compiled extension `solid._solid` (checked by mypy.stubtest).

Every public function, method and property has a docstring (arguments, returns, raises): the
API reference of the documentation site is generated from them (tests/test_docs.py checks).
"""
# Written by `make stubs` (tools/stubgen.py) from stubs/*.pyi and the core's parameter tables: edit those.

import os
from collections.abc import Callable, Iterable, Sequence
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
    "DatabaseError",
    "Database",
    "Match",
    "LoopDetector",
    "Loop",
    "MapAnchor",
    "Candidate",
    "Detection",
    "DetectorConfig",
    "DEFAULT_RADIUS",
    "DEFAULT_POSE_TOLERANCE_M",
    "DEFAULT_POSE_TOLERANCE_DEG",
    "VERIFIED_THRESHOLD",
    "Scores",
    "score_candidates",
    "encode_place",
    "decode_place",
    "RegistrationConfig",
    "PreparedCloud",
    "Hypothesis",
    "Registration",
    "AcceptanceGate",
    "register",
    "hypothesis_yaws",
    "encode_cloud",
    "decode_cloud",
]

__version__: str

class SolidError(ValueError):
    """Base class of the errors raised by solid (a ValueError).

    Raised as itself for input that cannot be read as asked: a points array of the wrong shape,
    not C-contiguous or misaligned, descriptors of different configurations, vectors of the wrong
    length. Every message says what is wrong and how to fix it.

    The error contract of the whole API: a value out of range (a negative or too large integer,
    NaN where a number is needed, an unknown name) raises ConfigError naming the argument, never
    OverflowError; a bool where a number is expected, or a value of the wrong type, raises
    TypeError; a corrupt or foreign file or place raises DatabaseError; running out of memory
    raises MemoryError (nothing is changed), never an abort; I/O failures raise the matching
    OSError.
    """

class ConfigError(SolidError):
    """An invalid parameter (of a configuration, a detector, a pose, ...), argument value or preset name; the message names it."""


@final
class SolidConfig:
    """SOLiD parameters (docs/spec.md §1), immutable and hashable.

    Nothing is clamped: an invalid value raises ConfigError naming the parameter. Usually made
    from a sensor preset, `SolidConfig.preset("hdl64")`, rather than field by field.
    """
    # generated from the core's parameter table by tools/stubgen.py (make stubs): do not edit
    def __new__(
        cls,
        *,
        n_range: int = 40,
        n_azimuth: int = 60,
        n_elevation: int,
        fov_up: float,
        fov_down: float,
        min_range: float = 3.0,
        max_range: float = 80.0,
        voxel_size: float = 0.5,
    ) -> SolidConfig:
        """`SolidConfig(...)`: parameters by keyword (None: the default).

        Args:
            n_range: Range bins over [0, max_range): the length of R-SOLiD (an integer in 1..=1024; default 40).
            n_azimuth: Azimuth bins over [0°, 360°): the length of A-SOLiD (an integer in 1..=3600; default 60).
            n_elevation: Elevation bins over [fov_down, fov_up) (the sensor's channels) (an integer in 1..=1024; required).
            fov_up: Upper edge of the vertical field of view, degrees (a finite angle in [-90, 90] degrees; required).
            fov_down: Lower edge of the vertical field of view, degrees, below fov_up (a finite angle in [-90, 90] degrees; required).
            min_range: Points at or within this distance (metres, 3-D) are dropped (a finite value >= 0 metres; default 3.0).
            max_range: Points at or beyond this distance (metres, 3-D) are dropped (a finite value above min_range; default 80.0).
            voxel_size: Voxel edge in metres for downsampling (0: none) (a finite value >= 0 metres (0 disables downsampling); default 0.5).

        Raises:
            ConfigError: A value out of its range (named in the message).
            TypeError: An unknown parameter, or a value of the wrong type.
        """
    @staticmethod
    def preset(
        name: str,
        *,
        n_range: int | None = None,
        n_azimuth: int | None = None,
        n_elevation: int | None = None,
        fov_up: float | None = None,
        fov_down: float | None = None,
        min_range: float | None = None,
        max_range: float | None = None,
        voxel_size: float | None = None,
    ) -> SolidConfig:
        """A sensor preset (docs/spec.md §4), with overrides (None: the preset's).

        Args:
            name: A preset name (`solid.presets()`): "hdl64", "hdl32", "vlp16", "os1-64", "avia", "aeva".
            n_range: Range bins over [0, max_range): the length of R-SOLiD (an integer in 1..=1024; default 40).
            n_azimuth: Azimuth bins over [0°, 360°): the length of A-SOLiD (an integer in 1..=3600; default 60).
            n_elevation: Elevation bins over [fov_down, fov_up) (the sensor's channels) (an integer in 1..=1024; required).
            fov_up: Upper edge of the vertical field of view, degrees (a finite angle in [-90, 90] degrees; required).
            fov_down: Lower edge of the vertical field of view, degrees, below fov_up (a finite angle in [-90, 90] degrees; required).
            min_range: Points at or within this distance (metres, 3-D) are dropped (a finite value >= 0 metres; default 3.0).
            max_range: Points at or beyond this distance (metres, 3-D) are dropped (a finite value above min_range; default 80.0).
            voxel_size: Voxel edge in metres for downsampling (0: none) (a finite value >= 0 metres (0 disables downsampling); default 0.5).

        Returns:
            The validated parameters.

        Raises:
            ConfigError: An unknown preset name (the message lists them) or an invalid value.
            TypeError: An unknown parameter, or a value of the wrong type.
        """
    def replace(
        self,
        *,
        n_range: int | None = None,
        n_azimuth: int | None = None,
        n_elevation: int | None = None,
        fov_up: float | None = None,
        fov_down: float | None = None,
        min_range: float | None = None,
        max_range: float | None = None,
        voxel_size: float | None = None,
    ) -> SolidConfig:
        """A copy with some parameters changed (None: unchanged); this one is immutable.

        Args:
            n_range: Range bins over [0, max_range): the length of R-SOLiD (an integer in 1..=1024; default 40).
            n_azimuth: Azimuth bins over [0°, 360°): the length of A-SOLiD (an integer in 1..=3600; default 60).
            n_elevation: Elevation bins over [fov_down, fov_up) (the sensor's channels) (an integer in 1..=1024; required).
            fov_up: Upper edge of the vertical field of view, degrees (a finite angle in [-90, 90] degrees; required).
            fov_down: Lower edge of the vertical field of view, degrees, below fov_up (a finite angle in [-90, 90] degrees; required).
            min_range: Points at or within this distance (metres, 3-D) are dropped (a finite value >= 0 metres; default 3.0).
            max_range: Points at or beyond this distance (metres, 3-D) are dropped (a finite value above min_range; default 80.0).
            voxel_size: Voxel edge in metres for downsampling (0: none) (a finite value >= 0 metres (0 disables downsampling); default 0.5).

        Returns:
            The validated new parameters.

        Raises:
            ConfigError: A value out of its range (named in the message).
            TypeError: An unknown parameter, or a value of the wrong type.
        """
    def to_dict(self) -> dict[str, Any]:
        """The parameters by name (n_range, n_azimuth, n_elevation, fov_up, fov_down, min_range, max_range, voxel_size): what `SolidConfig(**d)` takes back.

        Returns:
            A new dict.
        """
    @property
    def n_range(self) -> int:
        """Range bins over [0, max_range): the length of R-SOLiD (an integer in 1..=1024; default 40)."""
    @property
    def n_azimuth(self) -> int:
        """Azimuth bins over [0°, 360°): the length of A-SOLiD (an integer in 1..=3600; default 60)."""
    @property
    def n_elevation(self) -> int:
        """Elevation bins over [fov_down, fov_up) (the sensor's channels) (an integer in 1..=1024; required)."""
    @property
    def fov_up(self) -> float:
        """Upper edge of the vertical field of view, degrees (a finite angle in [-90, 90] degrees; required)."""
    @property
    def fov_down(self) -> float:
        """Lower edge of the vertical field of view, degrees, below fov_up (a finite angle in [-90, 90] degrees; required)."""
    @property
    def min_range(self) -> float:
        """Points at or within this distance (metres, 3-D) are dropped (a finite value >= 0 metres; default 3.0)."""
    @property
    def max_range(self) -> float:
        """Points at or beyond this distance (metres, 3-D) are dropped (a finite value above min_range; default 80.0)."""
    @property
    def voxel_size(self) -> float:
        """Voxel edge in metres for downsampling (0: none) (a finite value >= 0 metres (0 disables downsampling); default 0.5)."""
    # end of generated
    @property
    def base_preset(self) -> str | None:
        """The preset this configuration was made from (`SolidConfig.preset(name, ...)`), or None.
        It chooses the loop detector's default threshold; it is not part of equality or the fingerprint.
        """
    @property
    def fingerprint(self) -> int:
        """64-bit FNV-1a hash of every parameter (docs/spec.md §1): descriptors are comparable
                only when their configurations' fingerprints are equal.
        """
    def __eq__(self, value: object, /) -> bool: ...
    def __ne__(self, value: object, /) -> bool: ...
    def __hash__(self) -> int: ...
    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]: ...


def _config_from_dict(d: dict[str, Any]) -> SolidConfig: ...


@final
class DetectorConfig:
    """The loop detector's parameters (docs/spec.md §8), immutable.

    The defaults come from the Rust core, the one place they are written; prefer
    `DetectorConfig.preset(name)`, which takes the loop threshold measured for that sensor.
    """
    # generated from the core's parameter table by tools/stubgen.py (make stubs): do not edit
    def __new__(
        cls,
        *,
        exclude_frames: int = 50,
        exclude_meters: float = 30.0,
        exclude_seconds: float = 0.0,
        threshold: float = 0.034,
        top_k: int = 10,
        rerank: bool = False,
        verify: bool = True,
        verify_candidates: int = 5,
        pose_candidates: int = 2,
        pose_candidate_min_information: float = 3.0,
        verify_hypotheses: int = 4,
        verify_fan_deg: float = 25.0,
        cloud_bits: int = 8,
        cache_bytes: int = 268435456,
        verify_threads: int = 1,
        verify_step_points: int = 60000,
        odometry_check: bool = True,
        odometry_translation_m: float = 1.0,
        odometry_drift: float = 0.01,
        odometry_rotation_deg: float = 3.0,
        odometry_rotation_deg_per_m: float = 0.15,
        odometry_rotation_max_deg: float = 30.0,
        unique: bool = True,
        unique_ratio: float = 0.5,
        support_window: int = 20,
        min_support: int = 1,
        loop_reset_m: float = 200.0,
        lookalike_m: float = 10.0,
        lookalike_margin: float = 0.2,
        placement_loops: int = 3,
        placement_m: float = 15.0,
        registration: RegistrationConfig | dict[str, Any] | None = None,
        gate: AcceptanceGate | dict[str, Any] | None = None,
    ) -> DetectorConfig:
        """`DetectorConfig(...)`: parameters by keyword (None: the default).

        Args:
            exclude_frames: Skip the places of the own session added in the last this many steps (an integer >= 0; default 50; formerly exclude_recent).
            exclude_meters: Also skip own places fewer than this many metres back along the path, for scans with a pose (0: off) (a finite number >= 0; default 30.0).
            exclude_seconds: Also skip own places fewer than this many seconds back, for scans with a timestamp (0: off) (a finite number >= 0; default 0.0).
            threshold: Without verification, the largest R-SOLiD cosine distance accepted as a loop (a number in [0, 1] (a cosine distance); default 0.034).
            top_k: Candidates each step returns (an integer in 1..=1000; default 10).
            rerank: Re-rank the candidates by R-SOLiD plus rotation-aligned A-SOLiD distance (a bool; default False).
            verify: Verify the best candidates by registering the places' clouds; a loop then carries its pose (a bool; default True).
            verify_candidates: Candidates registered per step (an integer in 1..=1000; default 5).
            pose_candidates: Places nearest to the query's pose (own session, within reach of the gate and the odometry check) registered beside the descriptor's candidates, and, unless the latest loop gives the nearest place the shorter path, one more per typical step it may be off by after the path (odometry_translation_m + odometry_drift · path), at most as many more (0: none) (an integer in 0..=1000; default 2).
            pose_candidate_min_information: Smallest translation information (the gate's degeneracy.translation, per correspondence) a candidate chosen by pose must reach: its registration started where the odometry puts the query (a finite number >= 0; default 3.0).
            verify_hypotheses: Initial yaws per registration, at most (0°, the A-SOLiD minima, then the fan) (an integer in 1..=16; default 4).
            verify_fan_deg: The fixed ± yaw fan added to the hypotheses, degrees (0: none) (degrees in [0, 180]; default 25.0).
            cloud_bits: Bits per axis of the compact clouds stored with the places (an integer in 1..=16; default 8).
            cache_bytes: Memory for prepared clouds kept between steps, bytes (an integer >= 0; default 268435456).
            verify_threads: Threads registering a step's candidates at once (0: one per core; the default 1: a step registers few candidates under its budget, and a second thread shortened its mean wall time by 1.0-1.25x, docs/performance.md#threads) (an integer in 0..=256; default 1).
            verify_step_points: Work budget of one step, in points: each candidate costs its registrations (1 from a known start, else its hypotheses) times the two clouds' points; the best is always registered, the rest deferred to the next steps (an integer >= 1; default 60000).
            odometry_check: Reject a verified loop whose pose disagrees with the poses of its two places (same session) beyond the drift bounds, unless its neighbours vouch for it (min_support) (a bool; default True).
            odometry_translation_m: Translation a loop may differ from the poses' relative pose by at no path, metres (a finite number >= 0; default 1.0).
            odometry_drift: Translation the odometry may drift per metre travelled between the two places (a fraction), beside the displacement the rotation difference predicts along the path (a finite number >= 0; default 0.01).
            odometry_rotation_deg: Rotation a loop may differ from the poses' relative rotation by at no path, degrees (degrees in [0, 180]; default 3.0).
            odometry_rotation_deg_per_m: Rotation the odometry may drift per metre travelled between the two places, degrees (a finite number >= 0; default 0.15).
            odometry_rotation_max_deg: Ceiling of the rotation a loop may differ from the poses' relative rotation by, whatever the path, degrees (degrees in [0, 180]; default 30.0).
            unique: Reject verified candidates of a step that disagree with another verified one through the poses (a bool; default True).
            unique_ratio: Of two disagreeing candidates, keep the one whose distance from the poses' relative pose is under this fraction of the other's (0: reject both) (a number in [0, 1]; default 0.5).
            support_window: Consistency over time: the previous steps that may support a loop (0: off) (an integer >= 0; default 20).
            min_support: Fewest of the previous support_window steps whose verified candidates must agree with a loop; a loop the odometry check turns down passes when this many of them agree with it through their short paths (0: off) (an integer >= 0; default 1).
            loop_reset_m: Metres of path after an accepted loop during which the odometry check and the places chosen by pose go through that loop (0: off) (a finite number >= 0; default 200.0).
            lookalike_m: Reject a loop when an own place farther than this from its place, about as close by descriptor, fits the drift bounds too (0: off) (a finite number >= 0; default 10.0).
            lookalike_margin: How much larger a look-alike's R-SOLiD distance may be than the loop's candidate's (a number in [0, 1]; default 0.2).
            placement_loops: Loops into a map are accepted once this many queries' loops into it agree with each other over a turn (the session is placed in the map; the loops held before are released then), then when they agree with that placement (0: off) (an integer >= 0; default 3).
            placement_m: Metres of the session's path the loops that place it in the map must span, and the most between two of them facing 45° apart (the turn they must hold; 0: no span, the turn anywhere among them) (a finite number >= 0; default 15.0).
            registration: The registration parameters (an object, or a dict of overrides of the current ones).
            gate: The acceptance gate (an object, or a dict of overrides of the current one).

        Raises:
            ConfigError: A value out of its range (named in the message).
            TypeError: An unknown parameter, or a value of the wrong type.
        """
    @staticmethod
    def preset(
        name: str,
        *,
        exclude_frames: int | None = None,
        exclude_meters: float | None = None,
        exclude_seconds: float | None = None,
        threshold: float | None = None,
        top_k: int | None = None,
        rerank: bool | None = None,
        verify: bool | None = None,
        verify_candidates: int | None = None,
        pose_candidates: int | None = None,
        pose_candidate_min_information: float | None = None,
        verify_hypotheses: int | None = None,
        verify_fan_deg: float | None = None,
        cloud_bits: int | None = None,
        cache_bytes: int | None = None,
        verify_threads: int | None = None,
        verify_step_points: int | None = None,
        odometry_check: bool | None = None,
        odometry_translation_m: float | None = None,
        odometry_drift: float | None = None,
        odometry_rotation_deg: float | None = None,
        odometry_rotation_deg_per_m: float | None = None,
        odometry_rotation_max_deg: float | None = None,
        unique: bool | None = None,
        unique_ratio: float | None = None,
        support_window: int | None = None,
        min_support: int | None = None,
        loop_reset_m: float | None = None,
        lookalike_m: float | None = None,
        lookalike_margin: float | None = None,
        placement_loops: int | None = None,
        placement_m: float | None = None,
        registration: RegistrationConfig | dict[str, Any] | None = None,
        gate: AcceptanceGate | dict[str, Any] | None = None,
    ) -> DetectorConfig:
        """The detector defaults of a sensor preset (its measured loop threshold), with overrides (None: the preset's).

        Args:
            name: A preset name (`solid.presets()`): "hdl64", "hdl32", "vlp16", "os1-64", "avia", "aeva".
            exclude_frames: Skip the places of the own session added in the last this many steps (an integer >= 0; default 50; formerly exclude_recent).
            exclude_meters: Also skip own places fewer than this many metres back along the path, for scans with a pose (0: off) (a finite number >= 0; default 30.0).
            exclude_seconds: Also skip own places fewer than this many seconds back, for scans with a timestamp (0: off) (a finite number >= 0; default 0.0).
            threshold: Without verification, the largest R-SOLiD cosine distance accepted as a loop (a number in [0, 1] (a cosine distance); default 0.034).
            top_k: Candidates each step returns (an integer in 1..=1000; default 10).
            rerank: Re-rank the candidates by R-SOLiD plus rotation-aligned A-SOLiD distance (a bool; default False).
            verify: Verify the best candidates by registering the places' clouds; a loop then carries its pose (a bool; default True).
            verify_candidates: Candidates registered per step (an integer in 1..=1000; default 5).
            pose_candidates: Places nearest to the query's pose (own session, within reach of the gate and the odometry check) registered beside the descriptor's candidates, and, unless the latest loop gives the nearest place the shorter path, one more per typical step it may be off by after the path (odometry_translation_m + odometry_drift · path), at most as many more (0: none) (an integer in 0..=1000; default 2).
            pose_candidate_min_information: Smallest translation information (the gate's degeneracy.translation, per correspondence) a candidate chosen by pose must reach: its registration started where the odometry puts the query (a finite number >= 0; default 3.0).
            verify_hypotheses: Initial yaws per registration, at most (0°, the A-SOLiD minima, then the fan) (an integer in 1..=16; default 4).
            verify_fan_deg: The fixed ± yaw fan added to the hypotheses, degrees (0: none) (degrees in [0, 180]; default 25.0).
            cloud_bits: Bits per axis of the compact clouds stored with the places (an integer in 1..=16; default 8).
            cache_bytes: Memory for prepared clouds kept between steps, bytes (an integer >= 0; default 268435456).
            verify_threads: Threads registering a step's candidates at once (0: one per core; the default 1: a step registers few candidates under its budget, and a second thread shortened its mean wall time by 1.0-1.25x, docs/performance.md#threads) (an integer in 0..=256; default 1).
            verify_step_points: Work budget of one step, in points: each candidate costs its registrations (1 from a known start, else its hypotheses) times the two clouds' points; the best is always registered, the rest deferred to the next steps (an integer >= 1; default 60000).
            odometry_check: Reject a verified loop whose pose disagrees with the poses of its two places (same session) beyond the drift bounds, unless its neighbours vouch for it (min_support) (a bool; default True).
            odometry_translation_m: Translation a loop may differ from the poses' relative pose by at no path, metres (a finite number >= 0; default 1.0).
            odometry_drift: Translation the odometry may drift per metre travelled between the two places (a fraction), beside the displacement the rotation difference predicts along the path (a finite number >= 0; default 0.01).
            odometry_rotation_deg: Rotation a loop may differ from the poses' relative rotation by at no path, degrees (degrees in [0, 180]; default 3.0).
            odometry_rotation_deg_per_m: Rotation the odometry may drift per metre travelled between the two places, degrees (a finite number >= 0; default 0.15).
            odometry_rotation_max_deg: Ceiling of the rotation a loop may differ from the poses' relative rotation by, whatever the path, degrees (degrees in [0, 180]; default 30.0).
            unique: Reject verified candidates of a step that disagree with another verified one through the poses (a bool; default True).
            unique_ratio: Of two disagreeing candidates, keep the one whose distance from the poses' relative pose is under this fraction of the other's (0: reject both) (a number in [0, 1]; default 0.5).
            support_window: Consistency over time: the previous steps that may support a loop (0: off) (an integer >= 0; default 20).
            min_support: Fewest of the previous support_window steps whose verified candidates must agree with a loop; a loop the odometry check turns down passes when this many of them agree with it through their short paths (0: off) (an integer >= 0; default 1).
            loop_reset_m: Metres of path after an accepted loop during which the odometry check and the places chosen by pose go through that loop (0: off) (a finite number >= 0; default 200.0).
            lookalike_m: Reject a loop when an own place farther than this from its place, about as close by descriptor, fits the drift bounds too (0: off) (a finite number >= 0; default 10.0).
            lookalike_margin: How much larger a look-alike's R-SOLiD distance may be than the loop's candidate's (a number in [0, 1]; default 0.2).
            placement_loops: Loops into a map are accepted once this many queries' loops into it agree with each other over a turn (the session is placed in the map; the loops held before are released then), then when they agree with that placement (0: off) (an integer >= 0; default 3).
            placement_m: Metres of the session's path the loops that place it in the map must span, and the most between two of them facing 45° apart (the turn they must hold; 0: no span, the turn anywhere among them) (a finite number >= 0; default 15.0).
            registration: The registration parameters (an object, or a dict of overrides of the current ones).
            gate: The acceptance gate (an object, or a dict of overrides of the current one).

        Returns:
            The validated parameters.

        Raises:
            ConfigError: An unknown preset name (the message lists them) or an invalid value.
            TypeError: An unknown parameter, or a value of the wrong type.
        """
    def replace(
        self,
        *,
        exclude_frames: int | None = None,
        exclude_meters: float | None = None,
        exclude_seconds: float | None = None,
        threshold: float | None = None,
        top_k: int | None = None,
        rerank: bool | None = None,
        verify: bool | None = None,
        verify_candidates: int | None = None,
        pose_candidates: int | None = None,
        pose_candidate_min_information: float | None = None,
        verify_hypotheses: int | None = None,
        verify_fan_deg: float | None = None,
        cloud_bits: int | None = None,
        cache_bytes: int | None = None,
        verify_threads: int | None = None,
        verify_step_points: int | None = None,
        odometry_check: bool | None = None,
        odometry_translation_m: float | None = None,
        odometry_drift: float | None = None,
        odometry_rotation_deg: float | None = None,
        odometry_rotation_deg_per_m: float | None = None,
        odometry_rotation_max_deg: float | None = None,
        unique: bool | None = None,
        unique_ratio: float | None = None,
        support_window: int | None = None,
        min_support: int | None = None,
        loop_reset_m: float | None = None,
        lookalike_m: float | None = None,
        lookalike_margin: float | None = None,
        placement_loops: int | None = None,
        placement_m: float | None = None,
        registration: RegistrationConfig | dict[str, Any] | None = None,
        gate: AcceptanceGate | dict[str, Any] | None = None,
    ) -> DetectorConfig:
        """A copy with some parameters changed (None: unchanged); this one is immutable.

        Args:
            exclude_frames: Skip the places of the own session added in the last this many steps (an integer >= 0; default 50; formerly exclude_recent).
            exclude_meters: Also skip own places fewer than this many metres back along the path, for scans with a pose (0: off) (a finite number >= 0; default 30.0).
            exclude_seconds: Also skip own places fewer than this many seconds back, for scans with a timestamp (0: off) (a finite number >= 0; default 0.0).
            threshold: Without verification, the largest R-SOLiD cosine distance accepted as a loop (a number in [0, 1] (a cosine distance); default 0.034).
            top_k: Candidates each step returns (an integer in 1..=1000; default 10).
            rerank: Re-rank the candidates by R-SOLiD plus rotation-aligned A-SOLiD distance (a bool; default False).
            verify: Verify the best candidates by registering the places' clouds; a loop then carries its pose (a bool; default True).
            verify_candidates: Candidates registered per step (an integer in 1..=1000; default 5).
            pose_candidates: Places nearest to the query's pose (own session, within reach of the gate and the odometry check) registered beside the descriptor's candidates, and, unless the latest loop gives the nearest place the shorter path, one more per typical step it may be off by after the path (odometry_translation_m + odometry_drift · path), at most as many more (0: none) (an integer in 0..=1000; default 2).
            pose_candidate_min_information: Smallest translation information (the gate's degeneracy.translation, per correspondence) a candidate chosen by pose must reach: its registration started where the odometry puts the query (a finite number >= 0; default 3.0).
            verify_hypotheses: Initial yaws per registration, at most (0°, the A-SOLiD minima, then the fan) (an integer in 1..=16; default 4).
            verify_fan_deg: The fixed ± yaw fan added to the hypotheses, degrees (0: none) (degrees in [0, 180]; default 25.0).
            cloud_bits: Bits per axis of the compact clouds stored with the places (an integer in 1..=16; default 8).
            cache_bytes: Memory for prepared clouds kept between steps, bytes (an integer >= 0; default 268435456).
            verify_threads: Threads registering a step's candidates at once (0: one per core; the default 1: a step registers few candidates under its budget, and a second thread shortened its mean wall time by 1.0-1.25x, docs/performance.md#threads) (an integer in 0..=256; default 1).
            verify_step_points: Work budget of one step, in points: each candidate costs its registrations (1 from a known start, else its hypotheses) times the two clouds' points; the best is always registered, the rest deferred to the next steps (an integer >= 1; default 60000).
            odometry_check: Reject a verified loop whose pose disagrees with the poses of its two places (same session) beyond the drift bounds, unless its neighbours vouch for it (min_support) (a bool; default True).
            odometry_translation_m: Translation a loop may differ from the poses' relative pose by at no path, metres (a finite number >= 0; default 1.0).
            odometry_drift: Translation the odometry may drift per metre travelled between the two places (a fraction), beside the displacement the rotation difference predicts along the path (a finite number >= 0; default 0.01).
            odometry_rotation_deg: Rotation a loop may differ from the poses' relative rotation by at no path, degrees (degrees in [0, 180]; default 3.0).
            odometry_rotation_deg_per_m: Rotation the odometry may drift per metre travelled between the two places, degrees (a finite number >= 0; default 0.15).
            odometry_rotation_max_deg: Ceiling of the rotation a loop may differ from the poses' relative rotation by, whatever the path, degrees (degrees in [0, 180]; default 30.0).
            unique: Reject verified candidates of a step that disagree with another verified one through the poses (a bool; default True).
            unique_ratio: Of two disagreeing candidates, keep the one whose distance from the poses' relative pose is under this fraction of the other's (0: reject both) (a number in [0, 1]; default 0.5).
            support_window: Consistency over time: the previous steps that may support a loop (0: off) (an integer >= 0; default 20).
            min_support: Fewest of the previous support_window steps whose verified candidates must agree with a loop; a loop the odometry check turns down passes when this many of them agree with it through their short paths (0: off) (an integer >= 0; default 1).
            loop_reset_m: Metres of path after an accepted loop during which the odometry check and the places chosen by pose go through that loop (0: off) (a finite number >= 0; default 200.0).
            lookalike_m: Reject a loop when an own place farther than this from its place, about as close by descriptor, fits the drift bounds too (0: off) (a finite number >= 0; default 10.0).
            lookalike_margin: How much larger a look-alike's R-SOLiD distance may be than the loop's candidate's (a number in [0, 1]; default 0.2).
            placement_loops: Loops into a map are accepted once this many queries' loops into it agree with each other over a turn (the session is placed in the map; the loops held before are released then), then when they agree with that placement (0: off) (an integer >= 0; default 3).
            placement_m: Metres of the session's path the loops that place it in the map must span, and the most between two of them facing 45° apart (the turn they must hold; 0: no span, the turn anywhere among them) (a finite number >= 0; default 15.0).
            registration: The registration parameters (an object, or a dict of overrides of the current ones).
            gate: The acceptance gate (an object, or a dict of overrides of the current one).

        Returns:
            The validated new parameters.

        Raises:
            ConfigError: A value out of its range (named in the message).
            TypeError: An unknown parameter, or a value of the wrong type.
        """
    def to_dict(self) -> dict[str, Any]:
        """The parameters by name (exclude_frames, exclude_meters, exclude_seconds, threshold, top_k, rerank, verify, verify_candidates, pose_candidates, pose_candidate_min_information, verify_hypotheses, verify_fan_deg, cloud_bits, cache_bytes, verify_threads, verify_step_points, odometry_check, odometry_translation_m, odometry_drift, odometry_rotation_deg, odometry_rotation_deg_per_m, odometry_rotation_max_deg, unique, unique_ratio, support_window, min_support, loop_reset_m, lookalike_m, lookalike_margin, placement_loops, placement_m, registration, gate): what `DetectorConfig(**d)` takes back.

        Returns:
            A new dict.
        """
    @property
    def exclude_frames(self) -> int:
        """Skip the places of the own session added in the last this many steps (an integer >= 0; default 50; formerly exclude_recent)."""
    @property
    def exclude_meters(self) -> float:
        """Also skip own places fewer than this many metres back along the path, for scans with a pose (0: off) (a finite number >= 0; default 30.0)."""
    @property
    def exclude_seconds(self) -> float:
        """Also skip own places fewer than this many seconds back, for scans with a timestamp (0: off) (a finite number >= 0; default 0.0)."""
    @property
    def threshold(self) -> float:
        """Without verification, the largest R-SOLiD cosine distance accepted as a loop (a number in [0, 1] (a cosine distance); default 0.034)."""
    @property
    def top_k(self) -> int:
        """Candidates each step returns (an integer in 1..=1000; default 10)."""
    @property
    def rerank(self) -> bool:
        """Re-rank the candidates by R-SOLiD plus rotation-aligned A-SOLiD distance (a bool; default False)."""
    @property
    def verify(self) -> bool:
        """Verify the best candidates by registering the places' clouds; a loop then carries its pose (a bool; default True)."""
    @property
    def verify_candidates(self) -> int:
        """Candidates registered per step (an integer in 1..=1000; default 5)."""
    @property
    def pose_candidates(self) -> int:
        """Places nearest to the query's pose (own session, within reach of the gate and the odometry check) registered beside the descriptor's candidates, and, unless the latest loop gives the nearest place the shorter path, one more per typical step it may be off by after the path (odometry_translation_m + odometry_drift · path), at most as many more (0: none) (an integer in 0..=1000; default 2)."""
    @property
    def pose_candidate_min_information(self) -> float:
        """Smallest translation information (the gate's degeneracy.translation, per correspondence) a candidate chosen by pose must reach: its registration started where the odometry puts the query (a finite number >= 0; default 3.0)."""
    @property
    def verify_hypotheses(self) -> int:
        """Initial yaws per registration, at most (0°, the A-SOLiD minima, then the fan) (an integer in 1..=16; default 4)."""
    @property
    def verify_fan_deg(self) -> float:
        """The fixed ± yaw fan added to the hypotheses, degrees (0: none) (degrees in [0, 180]; default 25.0)."""
    @property
    def cloud_bits(self) -> int:
        """Bits per axis of the compact clouds stored with the places (an integer in 1..=16; default 8)."""
    @property
    def cache_bytes(self) -> int:
        """Memory for prepared clouds kept between steps, bytes (an integer >= 0; default 268435456)."""
    @property
    def verify_threads(self) -> int:
        """Threads registering a step's candidates at once (0: one per core; the default 1: a step registers few candidates under its budget, and a second thread shortened its mean wall time by 1.0-1.25x, docs/performance.md#threads) (an integer in 0..=256; default 1)."""
    @property
    def verify_step_points(self) -> int:
        """Work budget of one step, in points: each candidate costs its registrations (1 from a known start, else its hypotheses) times the two clouds' points; the best is always registered, the rest deferred to the next steps (an integer >= 1; default 60000)."""
    @property
    def odometry_check(self) -> bool:
        """Reject a verified loop whose pose disagrees with the poses of its two places (same session) beyond the drift bounds, unless its neighbours vouch for it (min_support) (a bool; default True)."""
    @property
    def odometry_translation_m(self) -> float:
        """Translation a loop may differ from the poses' relative pose by at no path, metres (a finite number >= 0; default 1.0)."""
    @property
    def odometry_drift(self) -> float:
        """Translation the odometry may drift per metre travelled between the two places (a fraction), beside the displacement the rotation difference predicts along the path (a finite number >= 0; default 0.01)."""
    @property
    def odometry_rotation_deg(self) -> float:
        """Rotation a loop may differ from the poses' relative rotation by at no path, degrees (degrees in [0, 180]; default 3.0)."""
    @property
    def odometry_rotation_deg_per_m(self) -> float:
        """Rotation the odometry may drift per metre travelled between the two places, degrees (a finite number >= 0; default 0.15)."""
    @property
    def odometry_rotation_max_deg(self) -> float:
        """Ceiling of the rotation a loop may differ from the poses' relative rotation by, whatever the path, degrees (degrees in [0, 180]; default 30.0)."""
    @property
    def unique(self) -> bool:
        """Reject verified candidates of a step that disagree with another verified one through the poses (a bool; default True)."""
    @property
    def unique_ratio(self) -> float:
        """Of two disagreeing candidates, keep the one whose distance from the poses' relative pose is under this fraction of the other's (0: reject both) (a number in [0, 1]; default 0.5)."""
    @property
    def support_window(self) -> int:
        """Consistency over time: the previous steps that may support a loop (0: off) (an integer >= 0; default 20)."""
    @property
    def min_support(self) -> int:
        """Fewest of the previous support_window steps whose verified candidates must agree with a loop; a loop the odometry check turns down passes when this many of them agree with it through their short paths (0: off) (an integer >= 0; default 1)."""
    @property
    def loop_reset_m(self) -> float:
        """Metres of path after an accepted loop during which the odometry check and the places chosen by pose go through that loop (0: off) (a finite number >= 0; default 200.0)."""
    @property
    def lookalike_m(self) -> float:
        """Reject a loop when an own place farther than this from its place, about as close by descriptor, fits the drift bounds too (0: off) (a finite number >= 0; default 10.0)."""
    @property
    def lookalike_margin(self) -> float:
        """How much larger a look-alike's R-SOLiD distance may be than the loop's candidate's (a number in [0, 1]; default 0.2)."""
    @property
    def placement_loops(self) -> int:
        """Loops into a map are accepted once this many queries' loops into it agree with each other over a turn (the session is placed in the map; the loops held before are released then), then when they agree with that placement (0: off) (an integer >= 0; default 3)."""
    @property
    def placement_m(self) -> float:
        """Metres of the session's path the loops that place it in the map must span, and the most between two of them facing 45° apart (the turn they must hold; 0: no span, the turn anywhere among them) (a finite number >= 0; default 15.0)."""
    # end of generated
    @property
    def registration(self) -> RegistrationConfig:
        """The registration parameters."""
    @property
    def gate(self) -> AcceptanceGate:
        """The acceptance gate; its `max_translation` is the largest loop, metres."""
    def __eq__(self, other: object, /) -> bool: ...
    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]: ...


def _detector_config_from_dict(params: dict[str, Any]) -> DetectorConfig: ...


def _removed_detector_keys() -> dict[str, str]:
    """The parameters DetectorConfig no longer has, each with why and what replaces it (the
    core's table; ``solid.config.REMOVED_DETECTOR_KEYS``). Setting one is refused naming this.
    """


def _param_table(name: str) -> list[dict[str, Any]]:
    """The core's parameter table of "SolidConfig", "DetectorConfig", "RegistrationConfig" or
    "AcceptanceGate": one dict per field (name, aliases, type, min/max or choices, expected,
    required, default, doc), in order. The command line and tools/stubgen.py read it.
    """


@final
class RegistrationConfig:
    """Registration parameters, immutable; invalid values raise ConfigError naming the parameter.

    The defaults were chosen by measurement on hku1-avia (see the Rust documentation of
    `solid_lidar::reg`): GICP with a Geman-McClure kernel, coarse 1 m voxels with 3 m
    correspondences, then 0.5 m / 1 m.
    """
    # generated from the core's parameter table by tools/stubgen.py (make stubs): do not edit
    def __new__(
        cls,
        *,
        voxel_size: float = 0.5,
        coarse_voxel_size: float = 1.0,
        min_range: float = 1.0,
        max_range: float = 200.0,
        neighbors: int = 10,
        max_correspondence: float = 1.0,
        coarse_max_correspondence: float = 3.0,
        max_iterations: int = 20,
        rotation_eps_deg: float = 0.1,
        translation_eps: float = 0.001,
        factor: str = 'gicp',
        kernel: str = 'geman-mcclure',
        schedule: str = 'coarse-fine',
        kernel_scale: float = 0.5,
        inlier_distance: float = 0.5,
    ) -> RegistrationConfig:
        """`RegistrationConfig(...)`: parameters by keyword (None: the default).

        Args:
            voxel_size: Voxel edge of the fine level, metres (0 keeps every point in range) (a finite value >= 0 metres (0 disables downsampling); default 0.5).
            coarse_voxel_size: Voxel edge of the coarse level, metres (0: no coarse level) (0 (no coarse level), or a finite value above voxel_size and >= max_range / 2^19; default 1.0).
            min_range: Points at or within this distance (metres, sensor frame) are dropped (a finite value >= 0 metres; default 1.0).
            max_range: Points at or beyond this distance are dropped (a finite value above min_range; default 200.0).
            neighbors: Neighbours (the point included) of each local covariance (an integer in 5..=64; default 10).
            max_correspondence: Largest correspondence distance at the fine level, metres (a finite value > 0 metres; default 1.0).
            coarse_max_correspondence: Largest correspondence distance at the coarse level, metres (a finite value > 0 metres; default 3.0).
            max_iterations: Largest number of Gauss-Newton iterations per level (an integer in 1..=1000; default 20).
            rotation_eps_deg: A level has converged when an update rotates by less than this, degrees (and translates by less than translation_eps) (a finite value > 0 degrees; default 0.1).
            translation_eps: A level has converged when an update translates by less than this, metres (and rotates by less than rotation_eps_deg) (a finite value > 0 metres; default 0.001).
            factor: The residual: plane-to-plane GICP or point-to-plane ICP ("gicp" or "point-to-plane"; default 'gicp').
            kernel: The robust kernel ("geman-mcclure" or "none"; default 'geman-mcclure').
            schedule: Which pose the fine level starts from: the coarse level's result (coarse-fine), the lower fine-level cost of the start and that result (keep-start), or both, keeping the lower final cost (both) ("coarse-fine", "keep-start" or "both"; default 'coarse-fine').
            kernel_scale: Kernel scale as a fraction of the level's maximum correspondence distance (a value in (0, 10]; default 0.5).
            inlier_distance: Distance (metres) within which a point overlaps the other cloud (overlaps, RMSE) (a finite value > 0 metres; default 0.5).

        Raises:
            ConfigError: A value out of its range (named in the message).
            TypeError: An unknown parameter, or a value of the wrong type.
        """
    def replace(
        self,
        *,
        voxel_size: float | None = None,
        coarse_voxel_size: float | None = None,
        min_range: float | None = None,
        max_range: float | None = None,
        neighbors: int | None = None,
        max_correspondence: float | None = None,
        coarse_max_correspondence: float | None = None,
        max_iterations: int | None = None,
        rotation_eps_deg: float | None = None,
        translation_eps: float | None = None,
        factor: str | None = None,
        kernel: str | None = None,
        schedule: str | None = None,
        kernel_scale: float | None = None,
        inlier_distance: float | None = None,
    ) -> RegistrationConfig:
        """A copy with some parameters changed (None: unchanged); this one is immutable.

        Args:
            voxel_size: Voxel edge of the fine level, metres (0 keeps every point in range) (a finite value >= 0 metres (0 disables downsampling); default 0.5).
            coarse_voxel_size: Voxel edge of the coarse level, metres (0: no coarse level) (0 (no coarse level), or a finite value above voxel_size and >= max_range / 2^19; default 1.0).
            min_range: Points at or within this distance (metres, sensor frame) are dropped (a finite value >= 0 metres; default 1.0).
            max_range: Points at or beyond this distance are dropped (a finite value above min_range; default 200.0).
            neighbors: Neighbours (the point included) of each local covariance (an integer in 5..=64; default 10).
            max_correspondence: Largest correspondence distance at the fine level, metres (a finite value > 0 metres; default 1.0).
            coarse_max_correspondence: Largest correspondence distance at the coarse level, metres (a finite value > 0 metres; default 3.0).
            max_iterations: Largest number of Gauss-Newton iterations per level (an integer in 1..=1000; default 20).
            rotation_eps_deg: A level has converged when an update rotates by less than this, degrees (and translates by less than translation_eps) (a finite value > 0 degrees; default 0.1).
            translation_eps: A level has converged when an update translates by less than this, metres (and rotates by less than rotation_eps_deg) (a finite value > 0 metres; default 0.001).
            factor: The residual: plane-to-plane GICP or point-to-plane ICP ("gicp" or "point-to-plane"; default 'gicp').
            kernel: The robust kernel ("geman-mcclure" or "none"; default 'geman-mcclure').
            schedule: Which pose the fine level starts from: the coarse level's result (coarse-fine), the lower fine-level cost of the start and that result (keep-start), or both, keeping the lower final cost (both) ("coarse-fine", "keep-start" or "both"; default 'coarse-fine').
            kernel_scale: Kernel scale as a fraction of the level's maximum correspondence distance (a value in (0, 10]; default 0.5).
            inlier_distance: Distance (metres) within which a point overlaps the other cloud (overlaps, RMSE) (a finite value > 0 metres; default 0.5).

        Returns:
            The validated new parameters.

        Raises:
            ConfigError: A value out of its range (named in the message).
            TypeError: An unknown parameter, or a value of the wrong type.
        """
    def to_dict(self) -> dict[str, Any]:
        """The parameters by name (voxel_size, coarse_voxel_size, min_range, max_range, neighbors, max_correspondence, coarse_max_correspondence, max_iterations, rotation_eps_deg, translation_eps, factor, kernel, schedule, kernel_scale, inlier_distance): what `RegistrationConfig(**d)` takes back.

        Returns:
            A new dict.
        """
    @property
    def voxel_size(self) -> float:
        """Voxel edge of the fine level, metres (0 keeps every point in range) (a finite value >= 0 metres (0 disables downsampling); default 0.5)."""
    @property
    def coarse_voxel_size(self) -> float:
        """Voxel edge of the coarse level, metres (0: no coarse level) (0 (no coarse level), or a finite value above voxel_size and >= max_range / 2^19; default 1.0)."""
    @property
    def min_range(self) -> float:
        """Points at or within this distance (metres, sensor frame) are dropped (a finite value >= 0 metres; default 1.0)."""
    @property
    def max_range(self) -> float:
        """Points at or beyond this distance are dropped (a finite value above min_range; default 200.0)."""
    @property
    def neighbors(self) -> int:
        """Neighbours (the point included) of each local covariance (an integer in 5..=64; default 10)."""
    @property
    def max_correspondence(self) -> float:
        """Largest correspondence distance at the fine level, metres (a finite value > 0 metres; default 1.0)."""
    @property
    def coarse_max_correspondence(self) -> float:
        """Largest correspondence distance at the coarse level, metres (a finite value > 0 metres; default 3.0)."""
    @property
    def max_iterations(self) -> int:
        """Largest number of Gauss-Newton iterations per level (an integer in 1..=1000; default 20)."""
    @property
    def rotation_eps_deg(self) -> float:
        """A level has converged when an update rotates by less than this, degrees (and translates by less than translation_eps) (a finite value > 0 degrees; default 0.1)."""
    @property
    def translation_eps(self) -> float:
        """A level has converged when an update translates by less than this, metres (and rotates by less than rotation_eps_deg) (a finite value > 0 metres; default 0.001)."""
    @property
    def factor(self) -> str:
        """The residual: plane-to-plane GICP or point-to-plane ICP ("gicp" or "point-to-plane"; default 'gicp')."""
    @property
    def kernel(self) -> str:
        """The robust kernel ("geman-mcclure" or "none"; default 'geman-mcclure')."""
    @property
    def schedule(self) -> str:
        """Which pose the fine level starts from: the coarse level's result (coarse-fine), the lower fine-level cost of the start and that result (keep-start), or both, keeping the lower final cost (both) ("coarse-fine", "keep-start" or "both"; default 'coarse-fine')."""
    @property
    def kernel_scale(self) -> float:
        """Kernel scale as a fraction of the level's maximum correspondence distance (a value in (0, 10]; default 0.5)."""
    @property
    def inlier_distance(self) -> float:
        """Distance (metres) within which a point overlaps the other cloud (overlaps, RMSE) (a finite value > 0 metres; default 0.5)."""
    # end of generated
    def __eq__(self, value: object, /) -> bool: ...
    def __ne__(self, value: object, /) -> bool: ...


@final
class AcceptanceGate:
    """Thresholds a registration must meet to be accepted as a loop (measured defaults).

    Tuned for precision on hku1-avia and the simulator: with the defaults, none of 843 wrong
    registrations of hku1's top-5 candidates passes, 373 of 462 correct ones do.
    """
    # generated from the core's parameter table by tools/stubgen.py (make stubs): do not edit
    def __new__(
        cls,
        *,
        require_converged: bool = False,
        min_fitness: float = 0.35,
        min_structure_fitness: float = 0.35,
        max_rmse: float = 0.3,
        min_translation_information: float = 1.5,
        min_rotation_information: float = 0.0,
        min_marginal_translation_information: float = 1.2,
        min_agreement: int = 1,
        max_translation: float = ...,
        agree_translation: float = 0.5,
        agree_rotation_deg: float = 2.0,
    ) -> AcceptanceGate:
        """`AcceptanceGate(...)`: parameters by keyword (None: the default).

        Args:
            require_converged: Require the fine level to have converged (a bool; default False).
            min_fitness: Smallest accepted fitness (the smaller of the two overlaps) (a finite number; default 0.35).
            min_structure_fitness: Smallest accepted overlap of the structure (points off the ground) (a finite number; default 0.35).
            max_rmse: Largest accepted inlier RMSE, metres (a finite number; default 0.3).
            min_translation_information: Smallest accepted translation information (degeneracy.translation) (a finite number; default 1.5).
            min_rotation_information: Smallest accepted rotation information (degeneracy.rotation) (a finite number; default 0.0).
            min_marginal_translation_information: Smallest accepted translation information with the rotation marginalised, per correspondence (degeneracy.marginal_translation) (a finite number; default 1.2).
            min_agreement: Fewest initial yaws (the best included) that must reach the best pose (an integer >= 0; default 1).
            max_translation: Largest accepted length of the translation, metres (metres > 0 (infinity: no limit); default inf).
            agree_translation: Two hypotheses agree when their translations differ by at most this, metres (and their rotations by agree_rotation_deg) (a finite number; default 0.5).
            agree_rotation_deg: Two hypotheses agree when their rotations differ by at most this, degrees (and their translations by agree_translation) (a finite number; default 2.0).

        Raises:
            ConfigError: A value out of its range (named in the message).
            TypeError: An unknown parameter, or a value of the wrong type.
        """
    def replace(
        self,
        *,
        require_converged: bool | None = None,
        min_fitness: float | None = None,
        min_structure_fitness: float | None = None,
        max_rmse: float | None = None,
        min_translation_information: float | None = None,
        min_rotation_information: float | None = None,
        min_marginal_translation_information: float | None = None,
        min_agreement: int | None = None,
        max_translation: float | None = None,
        agree_translation: float | None = None,
        agree_rotation_deg: float | None = None,
    ) -> AcceptanceGate:
        """A copy with some parameters changed (None: unchanged); this one is immutable.

        Args:
            require_converged: Require the fine level to have converged (a bool; default False).
            min_fitness: Smallest accepted fitness (the smaller of the two overlaps) (a finite number; default 0.35).
            min_structure_fitness: Smallest accepted overlap of the structure (points off the ground) (a finite number; default 0.35).
            max_rmse: Largest accepted inlier RMSE, metres (a finite number; default 0.3).
            min_translation_information: Smallest accepted translation information (degeneracy.translation) (a finite number; default 1.5).
            min_rotation_information: Smallest accepted rotation information (degeneracy.rotation) (a finite number; default 0.0).
            min_marginal_translation_information: Smallest accepted translation information with the rotation marginalised, per correspondence (degeneracy.marginal_translation) (a finite number; default 1.2).
            min_agreement: Fewest initial yaws (the best included) that must reach the best pose (an integer >= 0; default 1).
            max_translation: Largest accepted length of the translation, metres (metres > 0 (infinity: no limit); default inf).
            agree_translation: Two hypotheses agree when their translations differ by at most this, metres (and their rotations by agree_rotation_deg) (a finite number; default 0.5).
            agree_rotation_deg: Two hypotheses agree when their rotations differ by at most this, degrees (and their translations by agree_translation) (a finite number; default 2.0).

        Returns:
            The validated new parameters.

        Raises:
            ConfigError: A value out of its range (named in the message).
            TypeError: An unknown parameter, or a value of the wrong type.
        """
    def to_dict(self) -> dict[str, Any]:
        """The parameters by name (require_converged, min_fitness, min_structure_fitness, max_rmse, min_translation_information, min_rotation_information, min_marginal_translation_information, min_agreement, max_translation, agree_translation, agree_rotation_deg): what `AcceptanceGate(**d)` takes back.

        Returns:
            A new dict.
        """
    @property
    def require_converged(self) -> bool:
        """Require the fine level to have converged (a bool; default False)."""
    @property
    def min_fitness(self) -> float:
        """Smallest accepted fitness (the smaller of the two overlaps) (a finite number; default 0.35)."""
    @property
    def min_structure_fitness(self) -> float:
        """Smallest accepted overlap of the structure (points off the ground) (a finite number; default 0.35)."""
    @property
    def max_rmse(self) -> float:
        """Largest accepted inlier RMSE, metres (a finite number; default 0.3)."""
    @property
    def min_translation_information(self) -> float:
        """Smallest accepted translation information (degeneracy.translation) (a finite number; default 1.5)."""
    @property
    def min_rotation_information(self) -> float:
        """Smallest accepted rotation information (degeneracy.rotation) (a finite number; default 0.0)."""
    @property
    def min_marginal_translation_information(self) -> float:
        """Smallest accepted translation information with the rotation marginalised, per correspondence (degeneracy.marginal_translation) (a finite number; default 1.2)."""
    @property
    def min_agreement(self) -> int:
        """Fewest initial yaws (the best included) that must reach the best pose (an integer >= 0; default 1)."""
    @property
    def max_translation(self) -> float:
        """Largest accepted length of the translation, metres (metres > 0 (infinity: no limit); default inf)."""
    @property
    def agree_translation(self) -> float:
        """Two hypotheses agree when their translations differ by at most this, metres (and their rotations by agree_rotation_deg) (a finite number; default 0.5)."""
    @property
    def agree_rotation_deg(self) -> float:
        """Two hypotheses agree when their rotations differ by at most this, degrees (and their translations by agree_translation) (a finite number; default 2.0)."""
    # end of generated
    def __eq__(self, other: object, /) -> bool: ...
    def check(self, registration: Registration) -> str | None:
        """Why `registration` is rejected, if it is.
        Args:
            registration: A result of `register`.
        Returns:
            None when it passes every threshold, else the first failed check ("low overlap",
            "degenerate translation", ...).
        """
    def accepts(self, registration: Registration) -> bool:
        """Whether `registration` passes every threshold.
        Args:
            registration: A result of `register`.
        Returns:
            True when `check` finds nothing.
        """
    def agreement(self, registration: Registration) -> int:
        """How many hypotheses reached the best one's pose (within this gate's tolerances).
        Args:
            registration: A result of `register` with `yaws`.
        Returns:
            The count, the best included; 0 without hypotheses.
        """


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
    ) -> Descriptor:
        """`Descriptor(...)`: a descriptor from stored vectors.

                Args:
                    r: R-SOLiD, `config.n_range` finite non-negative values.
                    a: A-SOLiD, `config.n_azimuth` finite non-negative values.
                    config: The configuration the vectors were computed with.
                    n_points: Points in the scan (informative).
                    n_in_range: Points left after the range filter (informative).
                    n_kept: Points binned, after voxel downsampling (informative).

                Raises:
                    SolidError: A vector of the wrong length, or with a negative or non-finite value.
                    TypeError: A vector that is not a 1-D sequence of numbers.
        """
    @property
    def r(self) -> npt.NDArray[np.float32]:
        """R-SOLiD, shape (n_range,), float32 (a new array on each access)."""
    @property
    def a(self) -> npt.NDArray[np.float32]:
        """A-SOLiD, shape (n_azimuth,), float32 (a new array on each access)."""
    @property
    def n_points(self) -> int:
        """Points passed in, before any filtering."""
    @property
    def n_in_range(self) -> int:
        """Points that were finite and within (min_range, max_range) (docs/spec.md §2 steps 1–2)."""
    @property
    def n_kept(self) -> int:
        """Points binned: voxel centroids after downsampling, else `n_in_range`."""
    @property
    def config(self) -> SolidConfig:
        """The configuration the descriptor was computed with."""
    def distance(self, other: Descriptor) -> float:
        """Cosine distance of the R-SOLiDs (docs/spec.md §3); the same as `solid.distance(self, other)`.

                Args:
                    other: A descriptor made with the same configuration.

                Returns:
                    The distance in [0, 1]: small for the same place; 1 when either scan was empty.

                Raises:
                    SolidError: The descriptors come from different configurations.
        """
    def heading(self, candidate: Descriptor, refine: bool = True) -> float:
        """Heading of this scan relative to `candidate` (docs/spec.md §3); the same as
                `solid.heading(self, candidate, refine)`.

                Args:
                    candidate: A descriptor of the same place made with the same configuration.
                    refine: Refine the best shift to a fraction of a bin (parabolic fit); if False the
                        result is a multiple of 360°/n_azimuth.

                Returns:
                    ψ in degrees, in (-180, 180]: this scan ≈ the candidate rotated by ψ counter-clockwise
                    about +z.

                Raises:
                    SolidError: The descriptors come from different configurations.
        """
    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]: ...


def describe(points: npt.NDArray[np.float32] | npt.NDArray[np.float64], config: SolidConfig) -> Descriptor:
    """Computes the SOLiD descriptor of one scan (docs/spec.md §2), with the GIL released.

        The array is read in place, never copied or converted: columns 0, 1, 2 are x, y, z in metres
        in the sensor frame (x forward, y left, z up); further columns (intensity, time, ...) are
        ignored. Non-finite points and points outside (min_range, max_range) are dropped; an empty
        scan is valid and gives all-zero vectors.

        Args:
            points: A C-contiguous float32 or float64 numpy array of shape (N, >=3).
            config: The descriptor configuration.

        Returns:
            The descriptor, with its point counts.

        Raises:
            TypeError: `points` is not a numpy array, or its dtype is not float32 or float64.
            SolidError: The shape is not (N, >=3), or the array is Fortran-ordered, a strided view
                or misaligned (the message says how to convert it).
    """


def describe_batch(
    scans: Iterable[npt.NDArray[np.float32] | npt.NDArray[np.float64]],
    config: SolidConfig,
    threads: int | None = None,
) -> list[Descriptor]:
    """Describes many scans in parallel, with the GIL released; the same results as `describe`
        on each.

        Args:
            scans: Point arrays, each as `describe` accepts (float32 and float64 may be mixed).
            config: The descriptor configuration.
            threads: Worker threads, at most one per core; None or 0 one per core, 1 the
                calling thread. The workers persist from one call to the next, each keeping its
                scratch buffers.

        Returns:
            One descriptor per scan, in order.

        Raises:
            TypeError: `scans` is not iterable, or an element is not a float32/float64 numpy array.
            SolidError: An element has the wrong shape or layout (named as `scans[i]`), or
                `threads` is negative.
    """


def distance(a: Descriptor, b: Descriptor) -> float:
    """Cosine distance between two descriptors' R-SOLiDs (docs/spec.md §3).

        Args:
            a: One descriptor.
            b: Another, made with the same configuration.

        Returns:
            The distance in [0, 1]: small for the same place; 1 when either scan was empty.

        Raises:
            SolidError: The descriptors come from different configurations.
    """


def heading(query: Descriptor, candidate: Descriptor, refine: bool = True) -> float:
    """Heading of `query` relative to `candidate` from their A-SOLiDs (docs/spec.md §3).

        Args:
            query: The scan taken now.
            candidate: An earlier scan of the same place, made with the same configuration.
            refine: Refine the best circular shift to a fraction of a bin (parabolic fit); if False
                the result is a multiple of 360°/n_azimuth.

        Returns:
            ψ in degrees, in (-180, 180]: the query scan ≈ the candidate rotated by ψ
            counter-clockwise about +z (`p_query ≈ Rz(ψ) · p_candidate`; with poses,
            ψ = yaw(R_queryᵀ · R_candidate)).

        Raises:
            SolidError: The descriptors come from different configurations.
    """


def presets() -> dict[str, SolidConfig]:
    """Every sensor preset (docs/spec.md §4).

        Returns:
            A new dict from preset name to its configuration, in the order of the spec's table.
    """


def preset_sensors() -> dict[str, str]:
    """The sensor each preset describes.

        Returns:
            A new dict from preset name to the sensor's name ("Velodyne HDL-64E (KITTI)", ...).
    """


class DatabaseError(SolidError):
    """A database, place or loop-detector error: config mismatch, corrupt, truncated, foreign or
    newer-version file (the message names the file and the reason)."""


@final
class Match:
    """One search result."""
    @property
    def id(self) -> int:
        """The entry's id in its database (insertion order, from 0)."""
    @property
    def distance(self) -> float:
        """Cosine distance of the R-SOLiDs, in [0, 1]."""
    def __eq__(self, other: object, /) -> bool: ...


@final
class Database:
    """Places with exact search at every size (a kd-tree, a byte sketch and brute force: `method`
    "auto" chooses, every method returns the same neighbours), batch add and search, merge, save
    and load. A-SOLiDs are kept at 8 bits per value (see `a`); about 300 bytes per entry, plus
    the compact clouds of places stored for verification.

    `save` writes a temporary file of its own next to the target and renames it over the
    target: concurrent saves to one path all succeed and leave one of them, whole; a save killed
    midway leaves the old file. `load` reads regular files only (a FIFO or a device is refused
    before it is opened) and checks the header against the file's size before reading the body.

    Safe to share between threads: searches run in parallel, an add or a merge waits for them
    and runs alone, and so does the search that builds an index left to the searches (see
    `add_batch`; that one search takes as long as `build_index`: pass `index=True` where no
    search may wait). A process forked while another thread adds, merges or builds the index finds
    its copy locked (as with any lock held across `fork`): fork while no thread does, or use
    `multiprocessing`'s `forkserver` or `spawn` start method.

    `LoopDetector.from_database` shares the places with the database instead of copying them:
    whichever changes them first (an add, a merge, `build_index`, a metadata change on the
    database) makes its own copy then.
    """
    def __new__(cls, cfg: SolidConfig) -> Database:
        """`Database(cfg)`: an empty database.

                Args:
                    cfg: The configuration of every descriptor the database will hold.
        """
    def add(
        self,
        descriptor: Descriptor,
        session: int = 0,
        timestamp: float | None = None,
        pose: npt.ArrayLike | None = None,
        cloud: bytes | bytearray | memoryview | None = None,
    ) -> int:
        """Adds one place, with the GIL released.

                Args:
                    descriptor: A descriptor made with the database's configuration.
                    session: The robot or run it comes from (0 to 2^32 - 2: the session after the last must be numbered).
                    timestamp: Seconds, or None for none (stored as NaN).
                    pose: `T_world_sensor` as a 3×4 array or 12 floats (row-major [R|t]), or None.
                    cloud: The place's compact cloud for verification (`solid.encode_cloud` or
                        `PreparedCloud.encode`, as `cloud` returns it), or None.

                Returns:
                    The new entry's id.

                Raises:
                    DatabaseError: The descriptor was made with another configuration, or the
                        cloud is not a valid compact cloud (its checksum).
                    ConfigError: A session outside 0..2**32-1, an infinite timestamp, or a pose
                        that is not finite or whose 3×3 part is not a rotation.
                    SolidError: A pose that is not 12 values or a 3×4 array.
                    TypeError: A session that is not an integer (a bool included).
        """
    def add_batch(
        self,
        r: npt.NDArray[np.float32] | npt.NDArray[np.float64],
        a: npt.NDArray[np.float32] | npt.NDArray[np.float64],
        session: int = 0,
        timestamps: npt.NDArray[np.float64] | None = None,
        poses: npt.NDArray[np.float64] | None = None,
        index: bool | None = None,
    ) -> int:
        """Adds N places at once from arrays, with the GIL released; everything is checked before
        anything is added.

        Args:
            r: R-SOLiDs, shape (N, n_range), float32 (read in place) or float64, C-contiguous.
            a: A-SOLiDs, shape (N, n_azimuth), float32 or float64, C-contiguous.
            session: The robot or run they come from (0 to 2^32 - 2: the session after the last must be numbered).
            timestamps: Seconds, shape (N,), float64 (NaN: none), or None for none.
            poses: `T_world_sensor` of each, float64 of shape (N, 3, 4), (N, 4, 4) or (N, 12)
                (row-major [R|t]), or None.
            index: When to bring the search sketch and the kd-tree up to date. Until then the
                entries are only stored (checked, normalised, A-SOLiDs quantised: the fastest way
                to load many) and searches stay exact, computing the distance of every entry
                beyond the index. None (the default): the first search that finds the index due
                builds it, alone, before searching: once the searches have scanned the entries
                beyond it about as many times over as building it costs (40 times the rows the
                build indexes; for a first bulk add into an empty database, 40 searches or a
                `search_batch` of 40 queries), so a few searches never pay for an index and many
                pay for it once. True: now. False: at `build_index`, the next `add`, an indexed
                `add_batch` or a `merge`. The last `add_batch` decides for every entry still
                waiting.

        Returns:
            The id of the first new entry (the others follow).

        Raises:
            SolidError: An array of the wrong shape or layout.
            ConfigError: A negative or non-finite descriptor value, an infinite timestamp, a
                session outside 0..2**32-1, or a pose that is not a rotation.
            TypeError: An argument that is not a float array.
        """
    def build_index(self, sketch: bool | None = None) -> None:
        """Extends the search sketch and the kd-tree over every entry (after `add_batch`, before
        the searches build them); nothing to do when they are up to date. A loaded map's index is
        the kd-tree alone: its searches are mostly for the places it holds, which the kd-tree
        answers, and the sketch (52 bytes a place with the presets) would only speed up searches
        for other places (docs/performance.md#maps-at-scale).

        Args:
            sketch: True builds the sketch too (a loaded map's searches for places it does not
                hold, about 2.5× faster at a million places, for 52 MiB more); False frees it;
                None keeps the database's choice (on for a new database, off for a loaded one).
                The search results are the same either way.
        """
    def index_pending(self) -> int:
        """The entries the search sketch and the kd-tree do not cover yet: those left by
        `add_batch`, and up to 15 before them (the sketch covers whole blocks of 16), scanned by
        brute force until the index is built.

        Returns:
            A count of entries (0 when the index is up to date).
        """
    def memory_bytes(self) -> int:
        """The memory the database holds.

        Returns:
            Bytes: every buffer's capacity (about 300 a place without a pose, 104 more with one;
                about 240 for places added with `add_batch` until the index is built).
        """
    def search(
        self,
        descriptor: Descriptor | npt.ArrayLike,
        k: int = 1,
        exclude_recent: int = 0,
        method: str = "auto",
        not_newer_than: float | None = None,
        max_distance: float | None = None,
    ) -> list[Match]:
        """The `k` nearest entries by cosine distance, exactly (docs/spec.md §3), GIL released.

                Args:
                    descriptor: A descriptor made with the database's configuration, or an R-SOLiD as a
                        1-D sequence of `n_range` floats.
                    k: How many neighbours.
                    exclude_recent: Leave out the most recently added entries (the last `exclude_recent`
                        ids), as a loop detector does.
                    method: "auto" (the kd-tree under a work budget, then the byte sketch, then brute
                        force, each from where the previous one stops paying; on a database whose
                        sketch keeps failing, rows too alike for its bytes, a deeper kd-tree walk
                        replaces it), "brute", "kdtree" or "sketch": the same neighbours either way.
                    not_newer_than: Leave out entries whose timestamp is greater (entries without one are
                        kept).
                    max_distance: Return only matches at most this far (a loop threshold), or None; every
                        method skips more with it.

                Returns:
                    Up to `k` matches, nearest first, ties by lower id.

                Raises:
                    DatabaseError: The descriptor was made with another configuration.
                    SolidError: An R-SOLiD of the wrong length.
                    ConfigError: An R-SOLiD with negative or non-finite values, an unknown
                        `method`, a negative `k` or `exclude_recent`, a NaN `not_newer_than` (None
                        means no limit), or a NaN `max_distance`.
                    TypeError: `descriptor` is neither a Descriptor nor a sequence of floats.
        """
    def search_batch(
        self,
        queries: npt.NDArray[np.float32] | npt.NDArray[np.float64] | Sequence[Descriptor],
        k: int = 1,
        exclude_recent: int = 0,
        method: str = "auto",
        not_newer_than: float | None = None,
        max_distance: float | None = None,
    ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float32]]:
        """`search` for many queries in one call: the GIL released once, the queries shared among
        every core.

        Args:
            queries: R-SOLiDs, shape (M, n_range), float32 or float64, or Descriptors made with the
                database's configuration.
            k: How many neighbours per query.
            exclude_recent: As in `search`.
            method: As in `search`.
            not_newer_than: As in `search`.
            max_distance: As in `search`.

        Returns:
            Ids, shape (M, k), int64 (-1 in empty slots), and distances, shape (M, k), float32 (inf
            in empty slots); row i holds what `search(queries[i], ...)` returns, nearest first.

        Raises:
            DatabaseError: A Descriptor made with another configuration.
            SolidError: An array of the wrong shape.
            ConfigError: A query with negative or non-finite values, an unknown `method`, a
                negative `k` or `exclude_recent`, a NaN `not_newer_than` or `max_distance`.
            TypeError: `queries` is neither an array nor a sequence of Descriptors.
        """
    def distances(self, descriptor: Descriptor | npt.ArrayLike) -> npt.NDArray[np.float32]:
        """The cosine distance from the query to every entry, in id order (for plots and analysis;
        `search` finds the nearest).

        Args:
            descriptor: A descriptor made with the database's configuration, or an R-SOLiD as a 1-D
                sequence of `n_range` floats.

        Returns:
            float32 array of shape (N,).

        Raises:
            DatabaseError: The descriptor was made with another configuration.
            SolidError: An R-SOLiD of the wrong length.
            TypeError: `descriptor` is neither a Descriptor nor a sequence of floats.
        """
    def merge(self, other: Database, new_sessions: bool = False, anchor: npt.ArrayLike | None = None) -> None:
        """Appends every entry of `other` (another robot's or run's map), keeping their order,
        timestamps and poses; their ids follow this database's. Nothing changes on error.

        Args:
            other: A database with the same configuration (it may be this one); it is not changed.
            new_sessions: Renumber the sessions of `other` to follow this database's, so that maps of
                separate runs stay apart.
            anchor: ``T_map_other`` (3×4 or 4×4): every pose of `other` is carried into this map's
                world (``X ↦ T·X``) as it is merged (``solid map merge --anchor``). Or one per place
                of `other`, an array of shape (len(other), 3, 4) or (len(other), 4, 4): each place's
                pose carried by its own (a session whose odometry broke: one anchor per stretch,
                ``anchors.kitti``); a place whose transform is all NaN is merged without a pose.
                float32 is read as float64.

        Raises:
            DatabaseError: `other` has another configuration.
            ConfigError: `anchor` is not a finite rigid transform; of an array of them, one is not
                (the message names its place) or there is not one per place of `other` (it names
                both counts).
            SolidError: `anchor` is of none of the shapes above.
            TypeError: an array of transforms is neither float64 nor float32.
            ValueError: a 4×4 of the array does not end with the row [0, 0, 0, 1], or the array's
                transforms are not 3×4 or 4×4.
        """
    def save(self, path: str | PathLike[str], version: int = 4, *, replace: bool = True) -> None:
        """Writes the database to `path` (docs/spec.md §9), atomically: a temporary file in the
                same folder, then a rename. Written as it is encoded: no copy of the whole file in
                memory. Only a regular file is ever replaced: a FIFO, a device, a socket or a
                directory at `path` (also through a symbolic link) is refused.

                Args:
                    path: The file to write (a regular file there is replaced, unless `replace` is
                        False).
                    version: The file format: 4 (the current one: a pose's rotation as a unit
                        quaternion, read back within 1e-12), 3 for readers before format 4 (poses
                        as matrices), or 2 for older readers (which keeps no `metadata`).
                    replace: False: refuse when anything exists at `path`, also when it appears
                        during the save (the file is linked into place, which never replaces
                        anything): of concurrent saves to one path exactly one succeeds.

                Raises:
                    ConfigError: Another version.
                    DatabaseError: A stored cloud read from the file this map was loaded from is
                        corrupt, or that file changed since it was loaded (it is never written
                        again under a fresh checksum); nothing is written.
                    FileExistsError: `path` is not a regular file, or exists and `replace` is False;
                        nothing is written.
                    OSError: The file cannot be written (the subclass matches the cause, with `filename`).
        """
    @staticmethod
    def summary(path: str | PathLike[str]) -> dict[str, Any]:
        """What a database file holds, read from its header, section table and small sections
        alone in formats 3 and 4 (neither descriptors nor clouds: fast at any size); older files are read
        whole.

        Args:
            path: The file to read.

        Returns:
            A dict: ``version``, ``config`` (SolidConfig), ``fingerprint``, ``places``,
            ``places_with_cloud``, ``cloud_bytes``, ``sessions`` (per session, by number: a dict of
            ``session``, ``places``, ``with_pose``, ``first_time`` and ``last_time``, NaN when it has
            no timestamp) and ``metadata``.

        Raises:
            DatabaseError: As `load`.
            OSError: As `load`.
        """
    @property
    def metadata(self) -> str:
        """Free-form text saved with the database (format 3 on): `solid map build` records there how
        its scans were clipped, as JSON. "" when none; set it to replace it (at most 1 MiB)."""
    @metadata.setter
    def metadata(self, text: str) -> None:
        """Replaces the text saved with the database.

        Args:
            text: The new text, at most 1 MiB of UTF-8.

        Raises:
            ConfigError: The text is longer than 1 MiB.
        """
    @staticmethod
    def load(path: str | PathLike[str]) -> Database:
        """Reads a database written by `save`, checking everything (docs/spec.md §9).

                A file in format 3 or 4 is read in one pass, section by section, and its stored clouds
                stay in the file: the database keeps it open and reads a place's cloud when
                verification (or `cloud`) asks for it, checking that cloud's checksum then. Its
                search index (the kd-tree alone, see `build_index`) is left to the first search
                or detector.

                Args:
                    path: The file to read.

                Returns:
                    The database.

                Raises:
                    DatabaseError: Not a solid database, a newer format version, truncated, corrupted
                        (checksum), or invalid content; the message names the file and the reason.
                    OSError: The file cannot be read (FileNotFoundError, PermissionError, ...).
        """
    def to_bytes(self, version: int = 4) -> bytes:
        """The database in its file format (docs/spec.md §9).

                Args:
                    version: The file format: 4 (the current one), 3 or 2 for older readers.

                Returns:
                    The bytes `save` would write.

                Raises:
                    ConfigError: Another version.
                    DatabaseError: A stored cloud read from the map's file is corrupt.
        """
    @staticmethod
    def from_bytes(data: bytes | bytearray | memoryview) -> Database:
        """A database from bytes made by `to_bytes`, checked as `load` checks a file.

                Args:
                    data: The bytes: bytes, bytearray or memoryview.

                Returns:
                    The database.

                Raises:
                    DatabaseError: The bytes are not a valid database (the message says why).
                    MemoryError: The entries do not fit in memory.
                    TypeError: `data` is not bytes, bytearray or memoryview.
        """
    def __len__(self) -> int: ...
    @property
    def config(self) -> SolidConfig:
        """The configuration every entry was described with."""
    @property
    def r(self) -> npt.NDArray[np.float32]:
        """Every R-SOLiD, shape (N, n_range), float32 (a copy)."""
    @property
    def a(self) -> npt.NDArray[np.float32]:
        """Every A-SOLiD as kept, shape (N, n_azimuth), float32 (a copy): 8 bits per value with one
        step per entry, so each value is within half a step (0.2 % of the entry's largest value) of
        the one added."""
    @property
    def ids(self) -> npt.NDArray[np.int64]:
        """Entry ids 0..N, int64."""
    @property
    def cloud_bytes(self) -> int:
        """Bytes of the compact clouds stored for verification (0: none)."""
    @property
    def clouds_stored(self) -> int:
        """Number of places that have a stored cloud."""
    def cloud(self, id: int) -> bytes | None:
        """The compact cloud stored with a place for verification.

        Args:
            id: The place's id.

        Returns:
            Its wire form (decode it with `solid.decode_cloud`), or None when it has none. A map
            loaded from a file in format 3 or 4 reads it from the file now.

        Raises:
            DatabaseError: The stored cloud is corrupt (its checksum), named by place and file,
                or the file was truncated or written since the map was loaded (named).
            OSError: The file cannot be read.
            ConfigError: No place has this id (negative, beyond 64 bits, or `len(db)` and up).
            TypeError: An id that is not an integer (or a bool).
        """
    @property
    def sessions(self) -> npt.NDArray[np.uint32]:
        """Each entry's session, uint32."""
    @property
    def timestamps(self) -> npt.NDArray[np.float64]:
        """Each entry's timestamp, float64 (NaN where none was given)."""
    @property
    def poses(self) -> npt.NDArray[np.float64]:
        """Each entry's pose, shape (N, 3, 4), float64 (all NaN where none was given)."""


def encode_place(descriptor: Descriptor, quantized: bool = False) -> bytes:
    """Encodes one place for exchange between robots (docs/spec.md §10).

        Args:
            descriptor: The place.
            quantized: One byte per bin (square-root companded) instead of float32.

        Returns:
            420 bytes as float32 or 128 bytes quantised, for the default 40 + 60 bins.

        Raises:
            ConfigError: A vector with a negative or non-finite value (no descriptor holds one),
                named as r_solid or a_solid.
    """


def decode_place(data: bytes | bytearray | memoryview, cfg: SolidConfig) -> Descriptor:
    """Decodes a place made by `encode_place`. Point counts are not transmitted (they read 0).

        Args:
            data: The encoded place: bytes, bytearray or memoryview.
            cfg: The configuration the receiver uses; the place must have been made with it.

        Returns:
            The descriptor (approximate vectors when the place was quantised).

        Raises:
            DatabaseError: Not a place, an unknown version, a wrong length, a checksum mismatch, a
                negative or non-finite value, or a place made with another configuration (checked
                by fingerprint).
            TypeError: `data` is not bytes, bytearray or memoryview.
    """


@final
class MapAnchor:
    """Where a detector's session lies in its prior map (`LoopDetector.map_anchor`): the placement
    that mutually consistent loops into the map support (docs/spec.md §8)."""
    @property
    def transform(self) -> npt.NDArray[np.float64]:
        """T_map_world, (4, 4) float64: maps the session's pose frame ("odom") into the map's frame
        (fitted to the latest supporting loops)."""
    @property
    def loops(self) -> int:
        """Distinct queries that support it: those of the set of registrations into the map that placed it (one the gate turned down counts when it agrees) and of the loops accepted on it since."""
    @property
    def metres(self) -> float:
        """Metres of the session's path they span."""
    @property
    def first_query(self) -> int:
        """Id of the first supporting query."""
    @property
    def last_query(self) -> int:
        """Id of the latest supporting query."""
    @property
    def from_query(self) -> int:
        """Id of the first query of the stretch of the session's odometry (between breaks) that
        the anchor places: `transform` maps that stretch's poses only."""
    @property
    def to_query(self) -> int | None:
        """Id of the last query of that stretch when a break of the odometry ended it; None: the
        stretch goes on (`transform` is the map -> odom of now)."""
    @property
    def covariance(self) -> npt.NDArray[np.float64] | None:
        """The spread of the supporting loops' placements about `transform`, (6, 6) float64
        ((rotation in radians, translation in metres) order), or None with fewer than two."""
    def __eq__(self, other: object, /) -> bool: ...

@final
class Loop:
    """A detected loop closure: the best candidate of a detector step, when its score passes the threshold."""
    @property
    def query(self) -> int:
        """Id of the query scan (for `LoopDetector.query`, the id it would get)."""
    @property
    def candidate(self) -> int:
        """Id of the matched database entry."""
    @property
    def distance(self) -> float:
        """Cosine distance of the R-SOLiDs."""
    @property
    def heading(self) -> float:
        """Heading of the query relative to the candidate (refined), degrees in (-180, 180]."""
    @property
    def score(self) -> float:
        """The score the loop was accepted with: the R-SOLiD distance, or with verification
        |t| / (1 + |t|), |t| the length of its pose's translation (metres)."""
    @property
    def verified(self) -> bool:
        """Whether the loop was verified by registration (then it has a pose)."""
    @property
    def pose(self) -> npt.NDArray[np.float64] | None:
        """`T_query_candidate`, (4, 4) float64, of a verified loop: `p_query ≈ pose @ p_candidate`
        (docs/spec.md §3); its yaw is `heading`. None when the loop was not verified."""
    @property
    def fitness(self) -> float | None:
        """Overlap of the verifying registration (None when not verified)."""
    @property
    def rmse(self) -> float | None:
        """Inlier RMSE of the verifying registration, metres (None when not verified)."""
    @property
    def information(self) -> npt.NDArray[np.float64] | None:
        """The (6, 6) information matrix of `pose` for a pose graph (translation first, g2o's
        order; the error on the right of the measurement, as g2o's EDGE_SE3:QUAT and GTSAM's
        BetweenFactor): the registration's Hessian carried over and calibrated (docs/slam.md).
        None when the loop was not verified."""
    def __eq__(self, other: object, /) -> bool: ...


@final
class Candidate:
    """One candidate of a detector step, in the detector's ranking order."""
    @property
    def id(self) -> int:
        """Id of the database entry."""
    @property
    def distance(self) -> float:
        """Cosine distance of the R-SOLiDs, in [0, 1]."""
    @property
    def heading(self) -> float:
        """Heading of the query relative to this candidate (refined), degrees in (-180, 180]."""
    @property
    def score(self) -> float:
        """What ranks the candidates and what a precision-recall curve sweeps: the R-SOLiD
        distance, or with verification |t| / (1 + |t|) for a candidate that passed the gate (|t|
        the length of its pose's translation) and 1.5 + distance / 2 otherwise."""
    @property
    def verified(self) -> bool:
        """Whether this candidate was registered."""
    @property
    def accepted(self) -> bool:
        """Whether its registration passed the gate."""
    @property
    def rejection(self) -> str | None:
        """Why the gate, or the detector's checks after it (odometry, look-alike, uniqueness, support, placement), rejected its registration (None when accepted or not registered); a candidate whose stored cloud is corrupt or unreadable is not registered and says so, naming the place ("place 12: its stored cloud is corrupt or unreadable")."""
    @property
    def pose(self) -> npt.NDArray[np.float64] | None:
        """`T_query_candidate` (4, 4) of its registration (None when not registered)."""
    @property
    def fitness(self) -> float | None:
        """Overlap of its registration (None when not registered)."""
    @property
    def structure_fitness(self) -> float | None:
        """Overlap of its registration's points off horizontal surfaces (None when not registered)."""
    @property
    def rmse(self) -> float | None:
        """Inlier RMSE of its registration, metres (None when not registered)."""
    @property
    def degeneracy_translation(self) -> float | None:
        """Smallest eigenvalue of the translation block of its registration's information matrix."""
    @property
    def agreement(self) -> tuple[int, int] | None:
        """(initial yaws that reached the best pose, yaws tried), or None when not registered."""
    def __eq__(self, other: object, /) -> bool: ...


@final
class Detection:
    """Everything one detector step decided (docs/spec.md §8)."""
    @property
    def query(self) -> int:
        """Id of the query (the entry the step added)."""
    @property
    def eligible(self) -> int:
        """The candidates were drawn from the entries 0..eligible (the others were too recent); 0: nothing to search yet."""
    @property
    def candidates(self) -> list[Candidate]:
        """Up to `top_k` candidates, best first; with verification and a pose, also the places chosen by pose (`pose_candidates`, up to twice that after a long path without a loop)."""
    @property
    def loop(self) -> Loop | None:
        """The loop, when the best candidate's score is at most the threshold; else None."""
    @property
    def released(self) -> list[Loop]:
        """Loops of earlier queries reported late, in query order: loops into the map held until this step placed the session in the map (or revised the placement) and found them consistent with it (docs/spec.md §8, placement), loops the neighbours' vouching waited for (docs/loops.md#when-the-odometry-drifts), the loops the previous steps did not support that a later step's loop agrees with (docs/spec.md §8, support), and the loops of candidates a step's budget deferred to this one (`verify_step_points`, docs/spec.md §8, budget)."""
    @property
    def deferred(self) -> list[int]:
        """Ids of the candidates this step's budget deferred (`verify_step_points`, docs/spec.md §8, budget): unverified among `candidates`; the next steps register them, and a loop of theirs comes in `released` of the step that does. Empty when the step found its loop."""
    @property
    def placement(self) -> str | None:
        """What this step did to the session's placement in its map (`LoopDetector.map_anchor`): "placed" (the first placement), "revised" (a larger consistent set that disagreed replaced it), or None."""
    @property
    def pose(self) -> npt.NDArray[np.float64] | None:
        """T_world_sensor (4, 4) the step's checks used for the query: the caller's, or without one
        the detector's own odometry (the scan registered with the previous keyframe, chained;
        docs/loops.md#without-poses); None when the step had neither (verification off)."""
    @property
    def pose_source(self) -> str | None:
        """Where `pose` came from: "given" (the caller's), "chained" (the own odometry), "started"
        (the own odometry starts a frame here, the identity: the first scan without a pose, or the
        first after a link that failed the registration's quality checks; no odometry relates it
        to the places before); None without a pose."""


@final
class LoopDetector:
    """Online loop closure (docs/spec.md §8): each scan is searched against the places it may be
    matched with — a prior map, and its own session minus the exclusion window — then added.

    Safe to share between threads: a step (search, then add) runs alone; `query` and the
    getters run in parallel. A process forked while another thread runs a step finds its copy
    locked, as `Database`'s.
    """
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
        verify: bool | None = None,
        detector: DetectorConfig | None = None,
    ) -> LoopDetector:
        """`LoopDetector(cfg, ...)`: a detector with an empty database.

        Args:
            cfg: The configuration scans are described with; its base preset chooses the default
                threshold.
            exclude_recent: Frames of the own session never matched (the robot is still there);
                None: 50. The same as `DetectorConfig.exclude_frames`.
            threshold: Largest score (R-SOLiD cosine distance) accepted as a loop; None: the loop
                threshold of the configuration's base preset (docs/spec.md §4), else the largest preset
                threshold.
            top_k: Candidates each step returns (1..=1000); None: 10.
            rerank: Re-rank the candidates by R-SOLiD distance plus rotation-aligned A-SOLiD distance;
                None: off.
            exclude_meters: Also skip places of the own session fewer than this many metres back along
                the path (every scan then needs a pose); None or 0: off.
            exclude_seconds: Also skip places of the own session fewer than this many seconds back
                (every scan then needs a non-decreasing timestamp); None or 0: off.
            verify: Verify the best candidates by registration (None: on, the default); with it on,
                scans must be given as points.
            detector: Parameters to start from instead of the defaults; the other arguments override
                them.

        Raises:
            ConfigError: A detector parameter out of its range (named in the message).
            TypeError: A parameter of the wrong type.
        """
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
        verify: bool | None = None,
        detector: DetectorConfig | None = None,
    ) -> LoopDetector:
        """A detector over an existing database (a prior map, other sessions), sharing its places
        instead of copying them: they are candidates from the first scan on and are never excluded
        as recent; the detector's own scans get the session after the largest one in the database
        and are kept by the detector, apart from `database`, which stays as it was (an add to it
        afterwards does not reach the detector and makes it its own copy first).

        Args:
            database: The map; its configuration becomes the detector's.
            exclude_recent: Frames of the own session never matched (the robot is still there);
                None: 50. The same as `DetectorConfig.exclude_frames`.
            threshold: Largest score (R-SOLiD cosine distance) accepted as a loop; None: the loop
                threshold of the configuration's base preset (docs/spec.md §4), else the largest preset
                threshold.
            top_k: Candidates each step returns (1..=1000); None: 10.
            rerank: Re-rank the candidates by R-SOLiD distance plus rotation-aligned A-SOLiD distance;
                None: off.
            exclude_meters: Also skip places of the own session fewer than this many metres back along
                the path (every scan then needs a pose); None or 0: off.
            exclude_seconds: Also skip places of the own session fewer than this many seconds back
                (every scan then needs a non-decreasing timestamp); None or 0: off.
            verify: Verify the best candidates by registration (None: on, the default); with it on,
                scans must be given as points.
            detector: Parameters to start from instead of the defaults; the other arguments override
                them.

        Returns:
            The detector.

        Raises:
            ConfigError: A detector parameter out of its range.
            DatabaseError: The database already uses the largest session number.
            TypeError: A parameter of the wrong type.
        """
    def add(
        self,
        points_or_descriptor: Descriptor | npt.ArrayLike,
        timestamp: float | None = None,
        pose: npt.ArrayLike | None = None,
    ) -> Loop | None:
        """Searches one scan against the eligible places, then adds it (GIL released).

        Args:
            points_or_descriptor: The scan's points (as `solid.describe` accepts) or its descriptor,
                made with the detector's configuration.
            timestamp: Seconds, or None.
            pose: `T_world_sensor` as a 3×4 array or 12 floats (row-major [R|t]), or None; stored with
                the place.

        Returns:
            The loop, or None when the best candidate's score is above the threshold (or there is no
            candidate yet).

        Raises:
            DatabaseError: A descriptor made with another configuration.
            ConfigError: An infinite timestamp, a non-finite pose or one that is not a rotation, a pose
                or timestamp missing when the exclusion needs it, a timestamp older than the previous
                one when excluding by seconds. Nothing is added then.
            SolidError: Points of the wrong shape or layout (as `solid.describe`).
            TypeError: Points of the wrong type or dtype.
            SolidError: A pose that is not 12 values or a 3×4 array.
        """
    def detect(
        self,
        points_or_descriptor: Descriptor | npt.ArrayLike,
        timestamp: float | None = None,
        pose: npt.ArrayLike | None = None,
    ) -> Detection:
        """As `add`, returning everything the step decided. With verification on (the default) the
        scan must be given as points: its cloud is prepared, stored with the place and registered
        with the best candidates'; a Descriptor then raises ConfigError.

        Args:
            points_or_descriptor: The scan's points (as `solid.describe` accepts) or its descriptor,
                made with the detector's configuration.
            timestamp: Seconds, or None.
            pose: `T_world_sensor` as a 3×4 array or 12 floats (row-major [R|t]), or None; stored with
                the place.

        Returns:
            The step's query id, eligible entries, ranked candidates and loop.

        Raises:
            DatabaseError: A descriptor made with another configuration.
            ConfigError: An infinite timestamp, a non-finite pose or one that is not a rotation, a pose
                or timestamp missing when the exclusion needs it, a timestamp older than the previous
                one when excluding by seconds. Nothing is added then.
            SolidError: Points of the wrong shape or layout (as `solid.describe`).
            TypeError: Points of the wrong type or dtype.
            SolidError: A pose that is not 12 values or a 3×4 array.
        """
    def detect_many(
        self,
        scans: Sequence[Descriptor] | Sequence[npt.ArrayLike],
        timestamps: Sequence[float | None] | npt.ArrayLike | None = None,
        poses: Sequence[npt.ArrayLike | None] | npt.ArrayLike | None = None,
        threads: int | None = None,
        progress: Callable[[int], object] | None = None,
    ) -> list[Detection]:
        """`detect` for many scans in order, in one call (the GIL is released but for a moment
        between steps): point arrays are described (and, when the detector verifies, their clouds
        prepared) in parallel, then the steps run in order. Every input is checked before the first
        is added: on error nothing is added. Ctrl-C raises KeyboardInterrupt within a step (or a
        few scans of the preparation): the steps done before it are kept, each whole.

        Args:
            scans: Point arrays (as `solid.describe` accepts), or Descriptors made with the
                detector's configuration (verification off).
            threads: Workers describing and preparing the scans (None or 0: one per core).
            progress: Called with 1 after each step (for a progress bar); what it raises stops
                the batch there, as an interrupt does.
            timestamps: One per scan (None entries: none), or None for none at all.
            poses: One per scan (3×4 or 12 floats; None entries: none), an (N, 3, 4) array,
                or None for none at all.

        Returns:
            One Detection per descriptor, in order.

        Raises:
            DatabaseError: A descriptor made with another configuration.
            ConfigError: An infinite timestamp, a non-finite pose or one that is not a rotation, a pose
                or timestamp missing when the exclusion needs it, a timestamp older than the previous
                one when excluding by seconds. Nothing is added then.
            SolidError: Points of the wrong shape or layout (as `solid.describe`).
            TypeError: Points of the wrong type or dtype.
            SolidError: A pose that is not 12 values or a 3×4 array.
            SolidError: `timestamps` or `poses` of another length than `scans`.
        """
    def candidates(
        self,
        points_or_descriptor: Descriptor | npt.ArrayLike,
        k: int | None = None,
        timestamp: float | None = None,
        pose: npt.ArrayLike | None = None,
    ) -> list[Candidate]:
        """The candidates the scan would get if it were added now (with this timestamp and pose),
        without adding it.

        Args:
            points_or_descriptor: The scan's points (as `solid.describe` accepts) or its descriptor,
                made with the detector's configuration.
            timestamp: Seconds, or None.
            pose: `T_world_sensor` as a 3×4 array or 12 floats (row-major [R|t]), or None; stored with
                the place.
            k: At most this many; None: the detector's `top_k`.

        Returns:
            The candidates, best first.

        Raises:
            DatabaseError: A descriptor made with another configuration.
            ConfigError: An infinite timestamp, a non-finite pose or one that is not a rotation, a pose
                or timestamp missing when the exclusion needs it, a timestamp older than the previous
                one when excluding by seconds. Nothing is added then.
            SolidError: Points of the wrong shape or layout (as `solid.describe`).
            TypeError: Points of the wrong type or dtype.
            SolidError: A pose that is not 12 values or a 3×4 array.
        """
    def query(self, points_or_descriptor: Descriptor | npt.ArrayLike) -> Loop | None:
        """Searches one scan against every place without adding it and without excluding any
        (localisation in a prior map); with verification on, its best candidates are registered
        (then the scan must be given as points).

        Args:
            points_or_descriptor: The scan's points or its descriptor.

        Returns:
            The best match as a Loop (its `query` is the id the scan would get), or None when its
            score is above the threshold.

        Raises:
            DatabaseError: A descriptor made with another configuration.
            ConfigError: A Descriptor given to a verifying detector (it needs the points).
            SolidError: Points of the wrong shape or layout.
            TypeError: Points of the wrong type or dtype.
        """
    def __len__(self) -> int: ...
    @property
    def database(self) -> Database:
        """Every place (the prior map and every scan added so far) as a Database of its own: the
        prior map itself, shared, while the detector has added no scan; after that a copy of the
        descriptors made by this call (a loaded map's clouds stay in its file). Later steps do not
        reach it."""
    @property
    def map(self) -> Database:
        """The prior map the detector was made over (`from_database`'s database as it was then;
        empty for a new detector), shared with the detector rather than copied."""
    @property
    def config(self) -> DetectorConfig:
        """The detector's parameters."""
    @property
    def session(self) -> int:
        """The session of the scans this detector adds."""
    @property
    def map_anchor(self) -> MapAnchor | None:
        """Where the session lies in the prior map, once loops into the map have placed it
        (docs/spec.md §8, placement: `placement_loops` mutually consistent loops over `placement_m`
        metres of its path); None before, and for a detector without a map or without poses."""
    @property
    def map_anchors(self) -> list[MapAnchor]:
        """The session's anchors in the map, one per stretch of its odometry between breaks that
        loops into the map placed, in order (`MapAnchor.from_query`); the last is `map_anchor`.
        Empty before the session is placed."""
    @property
    def session_start(self) -> int:
        """Id of the first scan of the own session (the number of prior-map places)."""
    @property
    def exclude_recent(self) -> int:
        """Frames of the own session excluded as too recent."""
    @property
    def threshold(self) -> float:
        """Largest score accepted as a loop."""
    @property
    def top_k(self) -> int:
        """Candidates re-ranked by A-SOLiD alignment."""
    @property
    def rerank(self) -> bool:
        """Whether re-ranking is on."""

def _drift_swing(
    r_expected: npt.NDArray[np.float64],
    r_pose: npt.NDArray[np.float64],
    positions: npt.NDArray[np.float64],
    r_query: npt.NDArray[np.float64],
) -> tuple[float, float, float]:
    """`ω × arm`: the displacement of the query (in its frame) that a rotation drift at a constant
    rate along the path `positions` ((N, 3) in the world, the place's first, the query's last)
    predicts, `ω` the rotation vector of `r_expected · r_poseᵀ` and the arm the place's position
    less the path's centroid, turned into the query's frame by `r_query`: the odometry check's
    allowance for a rotation drift (docs/spec.md §8; `solid.commands.measured_drift` uses it).

    Raises:
        SolidError: A rotation that is not (3, 3), (3, 4) or (4, 4); positions not (N, 3); a NaN
            or infinity.
    """


DEFAULT_RADIUS: float


DEFAULT_POSE_TOLERANCE_M: float


DEFAULT_POSE_TOLERANCE_DEG: float


VERIFIED_THRESHOLD: float


@final
class Scores:
    """Per-query outcomes and the summary metrics of one scored run (docs/spec.md §5), made by
    `score_candidates`; `solid.evaluation` builds reports on it.
    """
    @property
    def radius(self) -> float:
        """Radius in metres within which a place counts as the same."""
    @property
    def gt_positive(self) -> npt.NDArray[np.bool_]:
        """Whether some eligible place lies within the radius, per query (bool array)."""
    @property
    def pose_tolerance_m(self) -> float:
        """Largest translation error (metres) of a correct loop's pose."""
    @property
    def pose_tolerance_deg(self) -> float:
        """Largest rotation error (degrees) of a correct loop's pose."""
    @property
    def correct(self) -> npt.NDArray[np.bool_]:
        """Whether the best candidate lies within the radius and its estimated pose, if any,
        within the pose tolerance, per query (bool array)."""
    @property
    def place_correct(self) -> npt.NDArray[np.bool_]:
        """Whether the best candidate lies within the radius, whatever its pose (bool array)."""
    @property
    def first_hit(self) -> npt.NDArray[np.uint32]:
        """1-based rank of the first candidate within the radius (0: none), per query."""
    @property
    def candidate_distance_m(self) -> npt.NDArray[np.float64]:
        """Metres from each query to its best candidate (NaN: none)."""
    @property
    def true_heading_deg(self) -> npt.NDArray[np.float64]:
        """True heading between each query and its best candidate, degrees (NaN: none)."""
    @property
    def pose_error_m(self) -> npt.NDArray[np.float64]:
        """Translation error of each query's estimated pose against the true
        `inv(T_world_query) @ T_world_candidate`, metres (NaN: no pose)."""
    @property
    def pose_error_deg(self) -> npt.NDArray[np.float64]:
        """Rotation error of each query's estimated pose, degrees (NaN: no pose)."""
    @property
    def n_gt(self) -> int:
        """Number of GT-positive queries."""
    def recall_at(self, n: int) -> float:
        """Recall@n: GT-positive queries with a correct candidate among their first n, over GT-positive queries.

        Args:
            n: How many candidates count (>= 1).

        Returns:
            The recall, NaN without GT-positive queries.
        """
    def pr_curve(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The precision-recall curve: a query's top-1 is accepted when its score <= τ, for τ over
        every observed top-1 score.

        Returns:
            (thresholds, precision, recall), float64 arrays of equal length.
        """
    def roc_curve(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The ROC curve of correct vs incorrect top-1s.

        Returns:
            (thresholds, false-positive rate, true-positive rate), float64 arrays.
        """
    def f1_max(self) -> tuple[float, float]:
        """The largest F1 = 2PR/(P+R) on the precision-recall curve.

        Returns:
            (F1 max, its threshold); (NaN, NaN) for an empty curve.
        """
    def auc(self) -> float:
        """The probability that a correct top-1 scores lower than an incorrect one (ties count one half).

        Returns:
            The AUC, NaN when either class is empty.
        """
    def at_threshold(self, threshold: float) -> tuple[int, int, float, float]:
        """What accepting the top-1s with score <= `threshold` gives.

        Args:
            threshold: The largest accepted score.

        Returns:
            (accepted, correct accepted, precision, recall).
        """
    def false_at_threshold(self, threshold: float) -> tuple[int, int]:
        """The wrong top-1s among those accepted with score <= `threshold`.

        Args:
            threshold: The largest accepted score.

        Returns:
            (place-false: the candidate lies beyond the radius, pose-false: the place is right
            but the estimated pose is outside the tolerance).
        """
    def rotation_errors(self) -> npt.NDArray[np.float64]:
        """|ψ_est − ψ_true| wrapped into [0°, 180°], over the correct top-1s.

        Returns:
            float64 array, degrees.
        """
    def __len__(self) -> int: ...


def score_candidates(
    query: npt.NDArray[np.int64],
    eligible: npt.NDArray[np.int64],
    ids: npt.NDArray[np.int64],
    score: npt.NDArray[np.float64],
    heading_deg: npt.NDArray[np.float64],
    poses: npt.NDArray[np.float64],
    radius: float,
    pose: npt.NDArray[np.float64] | None = None,
    pose_tolerance_m: float = ...,
    pose_tolerance_deg: float = ...,
) -> Scores:
    """Scores what a detector (or a baseline) decided against poses (docs/spec.md §5), with the
    GIL released; `solid.evaluation` wraps it in a friendlier form.

    Args:
        query: Query ids, shape (M,).
        eligible: Per query, the number of entries it could be matched with (ids 0..eligible).
        ids: Per query, its ranked candidate ids, shape (M, k); -1 pads missing candidates.
        score: Per query, its best candidate's score (what a threshold is compared with).
        heading_deg: Per query, the heading estimated for its best candidate, degrees.
        poses: Every frame's pose, shape (N, 3, 4), float64.
        radius: Metres within which a place counts as the same.
        pose: Per query, the metric `T_query_candidate` estimated for its best candidate, shape
            (M, 4, 4), NaN where none; None when no query has one.
        pose_tolerance_m: A top-1 whose pose is off by more than this many metres is not correct
            (default `DEFAULT_POSE_TOLERANCE_M`).
        pose_tolerance_deg: ... nor one off by more than this many degrees (default
            `DEFAULT_POSE_TOLERANCE_DEG`).

    Returns:
        The per-query outcomes and summary metrics.

    Raises:
        SolidError: A negative id (other than the -1 padding of `ids`), `poses` not of shape
            (N, 3, 4), or arrays of inconsistent lengths.
        ConfigError: A radius that is not finite and positive, an id outside the poses, a
            candidate that is not eligible, an `eligible` of 0 (skip queries with no database) or
            beyond the poses, a non-finite position.
    """


@final
class PreparedCloud:
    """A cloud prepared once for registration: voxel levels, kd-trees, local covariances.

    Prepare each place once and pass it to `register` as often as needed; the two clouds of a
    registration must be prepared with the same configuration.
    """

    def __new__(
        cls,
        points: npt.NDArray[np.float32] | npt.NDArray[np.float64],
        config: RegistrationConfig | None = None,
    ) -> PreparedCloud:
        """`PreparedCloud(points, config)`: prepares raw points, with the GIL released.

        Args:
            points: (N, >=3) float32 or float64 array, x, y, z first (sensor frame, metres).
            config: The registration configuration; None: `RegistrationConfig()`.

        Raises:
            TypeError: `points` is not a numpy array or has another dtype.
            SolidError: `points` has the wrong shape or is not C-contiguous.
        """
    @staticmethod
    def decode(data: bytes | bytearray | memoryview, config: RegistrationConfig | None = None) -> PreparedCloud:
        """Decodes a cloud made by `PreparedCloud.encode` and prepares it.

        Args:
            data: The encoded cloud.
            config: The configuration; it must have the sender's voxel sizes, range and neighbours
                for the two clouds to register. None: `RegistrationConfig()`.

        Returns:
            The prepared cloud, as the sender would have prepared the same fine points.

        Raises:
            DatabaseError: Not a cloud, a checksum mismatch, or a bad length.
            TypeError: `data` is not bytes, bytearray or memoryview.
        """
    def encode(self, bits: int = 8) -> bytes:
        """The compact wire form of the fine points, for a robot asked to verify a loop.

        Args:
            bits: Bits per axis for the position within a grid cell (the config's voxel size;
                0.5 m when it is 0), 1..=16.

        Returns:
            The encoded cloud (about 4 bytes a point with 8 bits), CRC-checked.

        Raises:
            ConfigError: `bits` outside 1..=16.
        """
    @property
    def points(self) -> npt.NDArray[np.float64]:
        """The fine points, (N, 3) float64."""
    @property
    def coarse_points(self) -> npt.NDArray[np.float64]:
        """The coarse points, (M, 3) float64 (empty without a coarse level)."""
    @property
    def config(self) -> RegistrationConfig:
        """The configuration it was prepared with."""
    def __len__(self) -> int: ...


@final
class Hypothesis:
    """One initial yaw of a multi-hypothesis registration and where its coarse level ended."""

    @property
    def yaw(self) -> float:
        """The initial yaw, degrees."""
    @property
    def pose(self) -> npt.NDArray[np.float64]:
        """The pose after the coarse level, (4, 4) float64."""
    @property
    def cost(self) -> float:
        """The fine level's robust cost at that pose, normalised to [0, 1] (lower is better)."""
    @property
    def converged(self) -> bool:
        """Whether the coarse level converged."""
    @property
    def iterations(self) -> int:
        """Iterations of the coarse level."""


@final
class Registration:
    """T_query_candidate with p_query ≈ pose @ p_candidate (docs/spec.md §3) and its quality."""

    @property
    def pose(self) -> npt.NDArray[np.float64]:
        """T_query_candidate, (4, 4) float64: p_query ≈ pose @ p_candidate."""
    @property
    def fitness(self) -> float:
        """min(overlap_query, overlap_candidate): symmetric in the two clouds."""
    @property
    def overlap_query(self) -> float:
        """Fraction of the query's fine points within `inlier_distance` of a candidate point."""
    @property
    def overlap_candidate(self) -> float:
        """Fraction of the candidate's fine points within `inlier_distance` of a query point."""
    @property
    def structure_fitness(self) -> float:
        """The fitness over points off horizontal surfaces (the ground of any two places overlaps)."""
    @property
    def rmse(self) -> float:
        """Root mean square distance of the candidate's inliers, metres."""
    @property
    def inliers(self) -> int:
        """Number of candidate inliers."""
    @property
    def iterations(self) -> int:
        """Gauss-Newton iterations, summed over the levels."""
    @property
    def converged(self) -> bool:
        """Whether the fine level met the convergence test."""
    @property
    def degeneracy_rotation(self) -> float:
        """Smallest eigenvalue of the rotation block of the information matrix, per correspondence."""
    @property
    def degeneracy_translation(self) -> float:
        """Smallest eigenvalue of the translation block, per correspondence (low: a corridor)."""
    @property
    def degeneracy_marginal_translation(self) -> float:
        """Smallest eigenvalue of the translation's information with the rotation marginalised
        (Schur complement), per correspondence (low: the translation trades against a rotation)."""
    @property
    def hessian(self) -> npt.NDArray[np.float64]:
        """The Gauss–Newton Hessian JᵀWJ at the fine level at the final pose, (6, 6): rotation
        first, a perturbation on the left in the query's frame, unscaled."""
    @property
    def information(self) -> npt.NDArray[np.float64]:
        """The (6, 6) information matrix of `pose` for a pose graph, translation first (as
        `Loop.information`); zeros when there is no Hessian."""
    @property
    def yaw(self) -> float:
        """Yaw of the pose, degrees in (-180, 180]: the heading of docs/spec.md §3."""
    @property
    def hypotheses(self) -> list[Hypothesis]:
        """Every hypothesis, in the order of `yaws` (empty when no yaws were given)."""
    @property
    def best_hypothesis(self) -> int | None:
        """Index of the best hypothesis (None when no yaws were given)."""


def register(
    query: PreparedCloud | npt.NDArray[np.float32] | npt.NDArray[np.float64],
    candidate: PreparedCloud | npt.NDArray[np.float32] | npt.NDArray[np.float64],
    init: npt.ArrayLike | None = None,
    *,
    yaws: Iterable[float] | None = None,
    config: RegistrationConfig | None = None,
) -> Registration:
    """Registers `candidate` to `query` (GIL released): the pose with p_query ≈ pose @ p_candidate.

    Args:
        query: The query place: a PreparedCloud, or (N, >=3) float32/float64 points.
        candidate: The candidate place, likewise.
        init: Initial guess, (4, 4) rigid transform; None: the identity.
        yaws: Initial yaws (degrees) to try, each applied before `init` (see `hypothesis_yaws`);
            the coarse level runs from each and the fine level continues from the best. None:
            start from `init` only.
        config: The configuration; None: `RegistrationConfig()`. PreparedClouds must have been
            prepared with it.

    Returns:
        The registration. Clouds too small or too different give a result that is not converged
        (and that `AcceptanceGate` rejects), never an error.

    Raises:
        TypeError: Points that are not a numpy array or of another dtype; a malformed `init`.
        SolidError: Points of the wrong shape or not C-contiguous, `init` not (4, 4), empty
            `yaws`, or a PreparedCloud prepared with another configuration.
        ConfigError: `init` is not a finite rigid transform, or a yaw is not finite.
    """


def _register_verifying(
    query: PreparedCloud | npt.NDArray[np.float32] | npt.NDArray[np.float64],
    candidate: PreparedCloud | npt.NDArray[np.float32] | npt.NDArray[np.float64],
    init: npt.ArrayLike | None = None,
    *,
    yaws: Iterable[float] | None = None,
    config: RegistrationConfig | None = None,
    gate: AcceptanceGate | None = None,
) -> Registration:
    """`register` as a verifying detector runs it for a loop candidate, for the convergence-basin
    benchmark (`benches/reg_basin.py`); not part of the public API.

    The fine level (with `yaws`, every level) also stops once its cost has not reached a new low
    for 3 iterations while the candidate's overlap there is below `gate`'s `min_fitness` or `min_structure_fitness`; with
    `yaws`, a candidate whose best hypothesis is clearly below `min_fitness` gives up before the
    fine level (docs/spec.md §11). `gate` None: `AcceptanceGate()`. Arguments and errors as
    `register`'s.
    """

def hypothesis_yaws(query: Descriptor, candidate: Descriptor, n: int = 4) -> list[float]:
    """Initial yaws worth trying for a pair of places: 0° then the A-SOLiD minima.

    Args:
        query: The query's descriptor.
        candidate: The candidate's descriptor (same configuration).
        n: Most yaws to return.

    Returns:
        Degrees, 0 first, then the local minima of the A-SOLiD shift cost (docs/spec.md §3) lowest
        first, skipping any within one azimuth bin of one already chosen.

    Raises:
        SolidError: Descriptors from different configurations.
    """


def encode_cloud(
    points: npt.NDArray[np.float32] | npt.NDArray[np.float64], grid: float = 0.5, bits: int = 8
) -> bytes:
    """Encodes points compactly: Morton-sorted grid cells plus quantised offsets, CRC-checked.

    Args:
        points: (N, >=3) float32 or float64 array.
        grid: Grid edge, metres.
        bits: Bits per axis for the offset within a cell, 1..=16 (error at most grid / 2^(bits+1)).

    Returns:
        The encoded points (their order is not kept).

    Raises:
        ConfigError: A bad `grid` or `bits`, or a non-finite or far-away point.
    """


def decode_cloud(data: bytes | bytearray | memoryview) -> npt.NDArray[np.float64]:
    """Decodes points made by `encode_cloud`.

    Args:
        data: The encoded points.

    Returns:
        The points, (N, 3) float64.

    Raises:
        DatabaseError: Not a cloud, a checksum mismatch, or a bad length.
        TypeError: `data` is not bytes, bytearray or memoryview.
    """


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
    @property
    def layout(self) -> str: ...
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


def _sim_corridor_world(
    seed: int = 0,
    blocks: int = 1,
    modules: int = 4,
    module_length: float = 45.0,
    width: float = 6.0,
    height: float = 3.0,
    jitter: float = 0.15,
    dropout: float = 0.1,
    cell_size: float = 4.0,
) -> _SimWorld: ...


def _sim_room_world(
    seed: int = 0,
    size: tuple[float, float] = ...,  # (6.0, 4.5)
    height: float = 2.6,
    furniture: int = 8,
    cell_size: float = 1.0,
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


def _sim_turn(
    world: _SimWorld,
    x: float,
    y: float,
    start: float = 0.0,
    sweep: float = 330.0,
    step: float = 2.0,
    wobble: float = 0.0,
    seed: int = 0,
    mount_height: float = 1.2,
    period: float = 0.1,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...


def _sim_odometry(
    poses: npt.NDArray[np.float64],
    times: list[float],
    yaw_bias_deg_per_m: float = 0.0,
    yaw_bias_deg_per_frame: float = 0.0,
    scale_error: float = 0.0,
    translation_noise: float = 0.0,
    rotation_noise_deg: float = 0.0,
    seed: int = 0,
    breakdown: tuple[int, int] | None = None,
    breakdown_jump_m: float = 0.0,
    breakdown_climb_m: float = 0.0,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...


def _sim_in_frame(poses: npt.NDArray[np.float64], frame: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]: ...


def _sim_write_poses(path: str | os.PathLike[str], poses: npt.NDArray[np.float64]) -> None: ...


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
