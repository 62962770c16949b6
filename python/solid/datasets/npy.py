"""numpy ``.npy`` and ``.npz`` files: an (N, >=3) real array (x y z first), or a structured array
with fields named x, y, z. In an ``.npz``, the array named ``points``, ``xyz``, ``pc`` or
``arr_0``, else its only array. Pickled objects are never loaded.

The header is read and checked first: a shape whose data the file cannot hold is refused before
anything is allocated.
"""

from __future__ import annotations

import zipfile
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from ..arrays import PathLike
from ..errors import ReadError
from ._common import Cloud, check_real, cloud_from_records, file_size

_NPZ_KEYS = ("points", "xyz", "pc", "arr_0")


def _read_array(path: PathLike, f: IO[bytes], available: int) -> npt.NDArray[Any]:
    """One ``.npy`` stream: header checked against the ``available`` bytes, then the data."""
    fmt = np.lib.format
    try:
        version = fmt.read_magic(f)
        if version == (1, 0):
            shape, fortran, dtype = fmt.read_array_header_1_0(f)
        elif version in ((2, 0), (3, 0)):
            shape, fortran, dtype = fmt.read_array_header_2_0(f)
        else:
            raise ValueError(f"unsupported .npy version {version}")
    except Exception as e:  # numpy's header parser raises many kinds on damaged input
        raise ReadError(path, f"not a valid .npy header: {type(e).__name__}: {e}") from None
    if dtype.hasobject:
        raise ReadError(path, f"array of dtype {dtype} holds Python objects; only numbers are read")
    count = 1
    for d in shape:
        count *= int(d)
    need = count * dtype.itemsize
    have = available - f.tell()
    if need > have:
        raise ReadError(path, f"header declares shape {shape} of {dtype} ({need} B) but the file holds {have} B")
    data = f.read(need)
    if len(data) != need:
        raise ReadError(path, f"truncated array data: {len(data)} of {need} B")
    arr = np.frombuffer(data, dtype=dtype, count=count)
    return arr.reshape(shape, order="F" if fortran else "C")


def _load(path: PathLike, kind: str) -> npt.NDArray[Any]:
    size = file_size(path)
    if kind == "npy":
        with open(path, "rb") as f:
            return _read_array(path, f, size)
    try:
        with zipfile.ZipFile(path) as z:
            keys = {n[:-4]: n for n in z.namelist() if n.endswith(".npy")}
            key = next((k for k in _NPZ_KEYS if k in keys), None)
            if key is None:
                if len(keys) != 1:
                    raise ReadError(path, f"npz has arrays {sorted(keys)}; expected one, or one named 'points'")
                key = next(iter(keys))
            info = z.getinfo(keys[key])
            # deflate expands at most 1032:1; a member claiming more is a lie
            most = info.compress_size * (1 if info.compress_type == zipfile.ZIP_STORED else 1032)
            with z.open(info) as f:
                return _read_array(path, f, min(info.file_size, most))
    except ReadError:
        raise
    except Exception as e:  # zipfile and zlib raise many kinds on damaged archives
        raise ReadError(path, f"not a valid .npz archive: {type(e).__name__}: {e}") from None


def read(path: PathLike, kind: str, xyz_only: bool) -> Cloud:
    """Read an ``.npy`` (``kind="npy"``) or ``.npz`` (``kind="npz"``) point array."""
    arr = _load(path, kind)
    if arr.dtype.names is not None:
        return cloud_from_records(path, arr.reshape(-1), xyz_only)
    if arr.ndim != 2 or arr.shape[1] < 3:
        raise ReadError(path, f"array has shape {arr.shape}, expected (N, >=3)")
    check_real(path, "points", arr.dtype)
    a = arr[:, :3] if xyz_only else arr
    names = ("x", "y", "z") + tuple(f"f{i}" for i in range(3, a.shape[1]))
    return Cloud(np.ascontiguousarray(a, dtype=np.float32), names)
