"""What the writers share: the array they store (they write it with :func:`solid.outputs.atomic_write_bytes`)."""

from __future__ import annotations

from collections.abc import Sequence as AbcSequence

import numpy as np
import numpy.typing as npt

from .._solid import ConfigError, SolidError
from ..arrays import F32


def columns_to_write(points: npt.ArrayLike, fields: AbcSequence[str] | None) -> tuple[F32, list[str]]:
    """The (N, C >= 3) float32 array a writer stores and its field names (x y z, then f3, f4, ...).
    Points of another shape (or not numbers) are a :class:`solid.SolidError`, field names that do
    not match the columns a :class:`solid.ConfigError`."""
    try:
        pts = np.asarray(points, dtype=np.float32)
    except (ValueError, TypeError) as e:
        raise SolidError(f"points must be an (N, >=3) array of numbers: {e}") from None
    if pts.ndim != 2 or pts.shape[1] < 3:
        raise SolidError(f"points must have shape (N, >=3), got {pts.shape}")
    c = pts.shape[1]
    names = list(fields) if fields is not None else ["x", "y", "z"] + [f"f{i}" for i in range(3, c)]
    if len(names) != c:
        raise ConfigError(f"{len(names)} field names for {c} columns")
    return pts, names


def unknown_kind(what: str, kind: object, known: AbcSequence[str]) -> ConfigError:
    """The error of a data kind a writer does not know."""
    return ConfigError(f"unknown {what} {kind!r}: expected one of {', '.join(known)}")
