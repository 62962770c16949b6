"""PLY: ``ascii``, ``binary_little_endian`` and ``binary_big_endian`` vertex lists (other
elements are skipped; list properties are allowed after the vertices); and a writer."""

from __future__ import annotations

from collections.abc import Sequence as AbcSequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, Literal

import numpy as np
import numpy.typing as npt

from ..arrays import PathLike
from ..errors import ReadError
from ..outputs import atomic_write_bytes
from ._common import Cloud, cloud_from_records, read_bytes, stack_columns
from ._write import columns_to_write, unknown_kind

_TYPES: Final = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}
_MAX_HEADER: Final = 1 << 20


@dataclass
class _Element:
    name: str
    count: int
    props: list[tuple[str, str]] = field(default_factory=list)
    has_list: bool = False


def _header(path: PathLike, data: bytes) -> tuple[list[str], int]:
    """The header's lines after ``ply`` and the offset of the body (after the ``end_header`` line)."""
    if not data.startswith(b"ply"):
        raise ReadError(path, "not a PLY file (no 'ply' magic)")
    lines: list[str] = []
    pos = 0
    while True:
        nl = data.find(b"\n", pos, _MAX_HEADER)
        if nl < 0:
            raise ReadError(path, "PLY header has no end_header line (truncated?)")
        try:
            line = data[pos:nl].decode("ascii").strip()
        except UnicodeDecodeError:
            raise ReadError(path, "PLY header is not ASCII") from None
        pos = nl + 1
        if line == "end_header":
            return lines[1:], pos
        lines.append(line)


def read(path: PathLike, xyz_only: bool) -> Cloud:
    """Read the vertices of a PLY file (see the module docstring)."""
    data = read_bytes(path)
    lines, start = _header(path, data)
    body = memoryview(data)[start:]
    fmt = None
    elements: list[_Element] = []
    for line in lines:
        parts = line.split()
        if not parts or parts[0] in ("comment", "obj_info"):
            continue
        if parts[0] == "format":
            if len(parts) < 2:
                raise ReadError(path, "malformed PLY format line")
            fmt = parts[1]
        elif parts[0] == "element":
            try:
                if len(parts) != 3:
                    raise ValueError
                elements.append(_Element(parts[1], int(parts[2])))
            except ValueError:
                raise ReadError(path, f"malformed PLY element line {line!r}") from None
            if elements[-1].count < 0:
                raise ReadError(path, f"PLY element {parts[1]!r} has a negative count {parts[2]}")
        elif parts[0] == "property":
            if not elements:
                raise ReadError(path, "PLY property before any element")
            if len(parts) >= 2 and parts[1] == "list":
                elements[-1].has_list = True
                elements[-1].props.append((parts[-1], "list"))
                continue
            if len(parts) != 3 or parts[1] not in _TYPES:
                raise ReadError(path, f"unsupported PLY property line {line!r}")
            elements[-1].props.append((parts[2], _TYPES[parts[1]]))
        else:
            raise ReadError(path, f"unknown PLY header line {line!r}")
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise ReadError(path, f"unsupported PLY format {fmt!r}")
    vi = next((i for i, e in enumerate(elements) if e.name == "vertex"), None)
    if vi is None:
        raise ReadError(path, "PLY file has no vertex element")
    for e in elements[: vi + 1]:
        if e.has_list:
            raise ReadError(path, f"PLY element {e.name!r} before or at the vertices has a list property")
    vert = elements[vi]
    names = [p[0] for p in vert.props]
    if len(set(names)) != len(names):
        raise ReadError(path, f"PLY vertex has duplicate property names ({' '.join(names)})")
    if fmt == "ascii":
        return _ascii(path, bytes(body), elements, vi, xyz_only)
    endian = "<" if fmt == "binary_little_endian" else ">"
    offset = 0
    for e in elements[:vi]:
        offset += e.count * np.dtype([(n, endian + t) for n, t in e.props]).itemsize
    dt = np.dtype([(n, endian + t) for n, t in vert.props])
    need = offset + vert.count * dt.itemsize
    if len(body) < need:
        raise ReadError(path, f"truncated PLY binary data: {len(body)} B, need {need} B for {vert.count} vertices")
    rec = np.frombuffer(body, dtype=dt, count=vert.count, offset=offset)
    return cloud_from_records(path, rec, xyz_only)


def _ascii(path: PathLike, body: bytes, elements: list[_Element], vi: int, xyz_only: bool) -> Cloud:
    vert = elements[vi]
    text = body.split(b"\n")
    skip = sum(e.count for e in elements[:vi])
    rows = [ln for ln in text[skip:] if ln.strip()]
    if len(rows) < vert.count:
        raise ReadError(path, f"PLY ascii data has {len(rows)} vertex lines, expected {vert.count}")
    try:
        vals = np.array(b" ".join(rows[: vert.count]).split(), dtype=np.float64)
    except ValueError:
        raise ReadError(path, "PLY ascii data contains a value that is not a number") from None
    nprop = len(vert.props)
    if vals.size != vert.count * nprop:
        raise ReadError(path, f"PLY ascii vertex data has {vals.size} values, expected {vert.count * nprop}")
    table = vals.reshape(vert.count, nprop)
    names = [p[0] for p in vert.props]
    lower = [n.lower() for n in names]
    for a in "xyz":
        if a not in lower:
            raise ReadError(path, f"PLY vertex has no property {a}")
    cols: list[npt.NDArray[Any]] = [table[:, lower.index(a)] for a in "xyz"]
    fnames = ["x", "y", "z"]
    if not xyz_only:
        for i, n in enumerate(names):
            if n.lower() not in ("x", "y", "z"):
                cols.append(table[:, i])
                fnames.append(n)
    return stack_columns(cols, fnames)


def write_ply(
    path: PathLike,
    points: npt.ArrayLike,
    fields: AbcSequence[str] | None = None,
    data: Literal["ascii", "binary_little_endian", "binary_big_endian"] = "binary_little_endian",
) -> None:
    """Write an (N, C) array as a PLY vertex list with float properties."""
    pts, names = columns_to_write(points, fields)
    n, c = pts.shape
    head = f"ply\nformat {data} 1.0\ncomment written by solid\nelement vertex {n}\n"
    head += "".join(f"property float {nm}\n" for nm in names) + "end_header\n"
    if data == "ascii":
        body = "".join(" ".join(repr(float(v)) for v in row) + "\n" for row in pts.astype(np.float64)).encode()
    elif data == "binary_little_endian":
        body = pts.astype("<f4").tobytes()
    elif data == "binary_big_endian":
        body = pts.astype(">f4").tobytes()
    else:
        raise unknown_kind("PLY format", data, ("ascii", "binary_little_endian", "binary_big_endian"))
    atomic_write_bytes(Path(path), head.encode("ascii") + body)
