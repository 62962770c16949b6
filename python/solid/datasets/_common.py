"""What every reader shares: the :class:`Cloud` it returns, and the checks and conversions that
turn raw records into a float32 (N, C) array with x, y, z first. The readers' error,
:class:`~solid.errors.ReadError`, is defined in :mod:`solid.errors`."""

from __future__ import annotations

import os
import re
import stat
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ..arrays import F32, PathLike
from ..errors import ReadError


@dataclass(frozen=True)
class Cloud:
    """Points read from a file: ``points`` (N, C) float32 and the names of its C columns."""

    points: F32
    fields: tuple[str, ...]


def file_size(path: PathLike, what: str = "point-cloud file") -> int:
    """Size of a regular file in bytes; a folder, FIFO or device is a :class:`ReadError` (before
    anything is read: a FIFO would block the reader)."""
    st = os.stat(path)
    if stat.S_ISDIR(st.st_mode):
        raise ReadError(path, f"is a folder, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        raise ReadError(path, "is not a regular file (a FIFO, device or socket)")
    return st.st_size


def read_bytes(path: PathLike) -> bytes:
    """The whole of a regular file (never a blocking read of a FIFO; see :func:`file_size`)."""
    file_size(path)
    with open(path, "rb") as f:
        return f.read()


def stack_columns(cols: list[npt.NDArray[Any]], names: list[str]) -> Cloud:
    """Stack 1-D columns (x, y, z first) into a C-contiguous float32 (N, C) array."""
    n = cols[0].shape[0] if cols else 0
    out = np.empty((n, len(cols)), dtype=np.float32)
    with np.errstate(over="ignore"):  # a float64 beyond float32's range is stored as ±inf
        for i, c in enumerate(cols):
            out[:, i] = c
    return Cloud(out, tuple(names))


def unique_names(names: list[str]) -> list[str]:
    """Field names made unique without colliding with any other name of the file.

    The second ``t`` of ``x y z t_1 t t`` becomes ``t_2`` (``t_1`` is the file's own field);
    PCL's padding fields ``_`` become ``_1``, ``_2``, ...
    """
    taken = set(names)
    seen: set[str] = set()
    out: list[str] = []
    for n in names:
        if n not in seen:
            seen.add(n)
            out.append(n)
            continue
        k = 1
        while f"{n}_{k}" in taken:
            k += 1
        new = f"{n}_{k}"
        taken.add(new)
        out.append(new)
    return out


def check_real(path: PathLike, name: str, dtype: np.dtype[Any]) -> None:
    """A column must hold real numbers (integers or floats); complex, text, objects are refused."""
    base = dtype.base
    if base.kind not in "biuf":
        raise ReadError(path, f"field {name!r} has dtype {base}, expected real numbers")


def records(path: PathLike, data: bytes, dtype: np.dtype[Any], what: str) -> npt.NDArray[Any]:
    """``data`` as packed records of ``dtype``; a size that is not a whole number of them names both."""
    size = dtype.itemsize
    if len(data) % size != 0:
        raise ReadError(
            path,
            f"size {len(data)} B is not a multiple of the {size} B {what} record "
            f"(truncated, or another layout: pass format=)",
        )
    return np.frombuffer(data, dtype=dtype)


def cloud_from_records(path: PathLike, rec: npt.NDArray[Any], xyz_only: bool) -> Cloud:
    """A structured array (one field per column, x y z found case-insensitively) as a :class:`Cloud`."""
    names = rec.dtype.names
    fields = rec.dtype.fields
    if names is None or fields is None:
        raise ReadError(path, "expected named fields")
    lower: dict[str, str] = {}
    for n in names:
        lower.setdefault(n.lower(), n)
    missing = [a for a in "xyz" if a not in lower]
    if missing:
        raise ReadError(path, f"no field named {', '.join(missing)} (fields: {' '.join(names)})")
    for a in "xyz":
        sub = fields[lower[a]][0]
        check_real(path, a, sub)
        if sub.shape:
            raise ReadError(path, f"field {a} must have one value per point, has {sub.shape}")
    cols: list[npt.NDArray[Any]] = [rec[lower[a]] for a in "xyz"]
    out_names = ["x", "y", "z"]
    if not xyz_only:
        used = {lower[a] for a in "xyz"}
        for n in names:
            if n in used or n.startswith("_"):
                continue
            sub = fields[n][0]
            check_real(path, n, sub)
            if sub.shape:
                flat = rec[n].reshape(rec.shape[0], -1)
                for k in range(flat.shape[1]):
                    cols.append(flat[:, k])
                    out_names.append(f"{n}_{k}")
            else:
                cols.append(rec[n])
                out_names.append(n)
    return stack_columns(cols, out_names)


_DIGITS = re.compile(r"(\d+)")


def natural_key(name: str) -> tuple[tuple[int, int | str], ...]:
    """Sort key that orders ``2.bin`` before ``10.bin``."""
    return tuple((0, int(t)) if t.isdigit() else (1, t.lower()) for t in _DIGITS.split(name) if t)
