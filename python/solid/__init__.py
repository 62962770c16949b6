"""SOLiD: fast, trustworthy LiDAR place recognition.

Describe a scan with two short vectors (R-SOLiD for place recognition, A-SOLiD for heading),
compare them, and find loop closures::

    import numpy as np
    import solid

    cfg = solid.SolidConfig.preset("hdl64")
    points = np.fromfile("000000.bin", dtype=np.float32).reshape(-1, 4)  # KITTI x y z i
    d = solid.describe(points, cfg)
    print(d.r.shape, d.a.shape, d.n_kept)

The heading convention: ``solid.heading(q, c)`` is the angle ψ (degrees, counter-clockwise about
+z) such that the query scan ≈ the candidate scan rotated by ψ.
"""

from __future__ import annotations

from ._solid import (
    AcceptanceGate,
    Candidate,
    ConfigError,
    Database,
    DatabaseError,
    Descriptor,
    Detection,
    DetectorConfig,
    Hypothesis,
    Loop,
    LoopDetector,
    MapAnchor,
    Match,
    PreparedCloud,
    Registration,
    RegistrationConfig,
    SolidConfig,
    SolidError,
    __version__,
    decode_cloud,
    decode_place,
    describe,
    describe_batch,
    distance,
    encode_cloud,
    encode_place,
    heading,
    hypothesis_yaws,
    preset_sensors,
    presets,
    register,
)

__all__ = [
    "AcceptanceGate",
    "Candidate",
    "ConfigError",
    "Database",
    "DatabaseError",
    "Descriptor",
    "Detection",
    "DetectorConfig",
    "Hypothesis",
    "Loop",
    "LoopDetector",
    "MapAnchor",
    "Match",
    "PreparedCloud",
    "Registration",
    "RegistrationConfig",
    "SolidConfig",
    "SolidError",
    "__version__",
    "decode_cloud",
    "decode_place",
    "describe",
    "describe_batch",
    "distance",
    "encode_cloud",
    "encode_place",
    "heading",
    "hypothesis_yaws",
    "preset_sensors",
    "presets",
    "register",
]

#: The package's submodules, imported on first use (``solid.datasets.open_dataset(...)`` works after
#: a plain ``import solid``) so that ``import solid`` stays light.
_SUBMODULES = frozenset(
    {"commands", "config", "datasets", "errors", "evaluation", "io", "outputs", "pipeline", "plots", "records", "scancontext", "sim", "slam", "transforms"}
)


def __getattr__(name: str) -> object:
    if name in _SUBMODULES:
        import importlib

        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
