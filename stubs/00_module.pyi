"""Type stubs of the compiled extension `solid._solid` (checked by mypy.stubtest).

Every public function, method and property has a docstring (arguments, returns, raises): the
API reference of the documentation site is generated from them (tests/test_docs.py checks).
"""

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
