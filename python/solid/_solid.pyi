"""Type stubs of the compiled extension `solid._solid` (checked by mypy.stubtest)."""

from collections.abc import Iterable
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
        n_range: int = 40,
        n_azimuth: int = 60,
        min_range: float = 3.0,
        max_range: float = 80.0,
        voxel_size: float = 0.5,
    ) -> SolidConfig: ...
    @staticmethod
    def preset(name: str, **overrides: float) -> SolidConfig: ...
    def replace(self, **overrides: float) -> SolidConfig: ...
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
