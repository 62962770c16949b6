"""PCD v0.7 (the Point Cloud Library's format): ``ascii``, ``binary`` and ``binary_compressed``
(LZF, decoded by the core crate) data, any field types and counts; and a writer."""

from __future__ import annotations

from collections.abc import Sequence as AbcSequence
from pathlib import Path
from typing import Any, Final, Literal

import numpy as np
import numpy.typing as npt

from ..arrays import PathLike
from ..errors import ReadError
from ..outputs import atomic_write_bytes
from ._common import Cloud, cloud_from_records, read_bytes, stack_columns, unique_names
from ._write import columns_to_write, unknown_kind
from .lzf import decompress_array, lzf_compress

_TYPES: Final = {
    ("F", 4): "f4",
    ("F", 8): "f8",
    ("I", 1): "i1",
    ("I", 2): "i2",
    ("I", 4): "i4",
    ("I", 8): "i8",
    ("U", 1): "u1",
    ("U", 2): "u2",
    ("U", 4): "u4",
    ("U", 8): "u8",
}
_MAX_HEADER_LINES: Final = 64


def read(path: PathLike, xyz_only: bool) -> Cloud:
    """Read a PCD file (see the module docstring)."""
    data = read_bytes(path)
    header: dict[str, list[str]] = {}
    pos = 0
    data_kind = None
    for _ in range(_MAX_HEADER_LINES):
        nl = data.find(b"\n", pos)
        if nl < 0:
            raise ReadError(path, "PCD header ends before its DATA line (truncated or not a PCD file)")
        try:
            line = data[pos:nl].decode("ascii").strip()
        except UnicodeDecodeError:
            raise ReadError(path, "PCD header is not ASCII (not a PCD file?)") from None
        pos = nl + 1
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        key = parts[0].upper()
        header[key] = parts[1:]
        if key == "DATA":
            if len(parts) != 2:
                raise ReadError(path, f"malformed PCD DATA line {line!r}")
            data_kind = parts[1].lower()
            break
    if data_kind is None:
        raise ReadError(path, f"no DATA line in the first {_MAX_HEADER_LINES} header lines (not a PCD file?)")
    if "VERSION" in header and header["VERSION"] and header["VERSION"][0] not in ("0.7", ".7"):
        raise ReadError(path, f"PCD version {header['VERSION'][0]} is not supported (only v0.7)")
    for k in ("FIELDS", "SIZE", "TYPE"):
        if k not in header:
            raise ReadError(path, f"PCD header has no {k} line")
    names = header["FIELDS"]
    nf = len(names)
    counts_s = header.get("COUNT", ["1"] * nf)
    if len(header["SIZE"]) != nf or len(header["TYPE"]) != nf or len(counts_s) != nf:
        raise ReadError(path, "PCD header: FIELDS, SIZE, TYPE and COUNT have different lengths")
    try:
        sizes = [int(s) for s in header["SIZE"]]
        counts = [int(c) for c in counts_s]
        width = int(header.get("WIDTH", ["-1"])[0])
        height = int(header.get("HEIGHT", ["1"])[0])
        npts = int(header["POINTS"][0]) if "POINTS" in header else width * height
    except (ValueError, IndexError):
        raise ReadError(path, "PCD header has a non-integer SIZE, COUNT, WIDTH, HEIGHT or POINTS") from None
    if npts < 0 or any(c < 1 for c in counts):
        raise ReadError(path, "PCD header has a negative POINTS or a COUNT below 1")
    if width >= 0 and width * height != npts:
        raise ReadError(path, f"PCD header: WIDTH×HEIGHT = {width * height} but POINTS = {npts}")
    fmts: list[str] = []
    for n, t, s in zip(names, header["TYPE"], sizes):
        code = _TYPES.get((t.upper(), s))
        if code is None:
            raise ReadError(path, f"PCD field {n!r} has unsupported TYPE {t} with SIZE {s}")
        fmts.append(code)
    uniq = unique_names(names)
    lower = [n.lower() for n in uniq]
    for a in "xyz":
        if a not in lower:
            raise ReadError(path, f"PCD has no field named {a} (fields: {' '.join(names)})")
        if counts[lower.index(a)] != 1:
            raise ReadError(path, f"PCD field {a} has COUNT {counts[lower.index(a)]}, expected 1")
    body = memoryview(data)[pos:]
    start = pos
    xyz = [lower.index(a) for a in "xyz"]
    extra = [] if xyz_only else [i for i in range(nf) if i not in xyz and not uniq[i].startswith("_")]

    if data_kind == "ascii":
        return _ascii(path, bytes(body), uniq, counts, npts, xyz, extra)
    if data_kind == "binary":
        dt = np.dtype([(n, "<" + f, (c,)) if c > 1 else (n, "<" + f) for n, f, c in zip(uniq, fmts, counts)])
        need = npts * dt.itemsize
        if len(body) < need:
            raise ReadError(
                path,
                f"truncated PCD binary data: {len(body)} B for {npts} points of {dt.itemsize} B (need {need} B)",
            )
        if all(f == "f4" for f in fmts) and all(c == 1 for c in counts):
            # the common x y z [intensity ...] float32 layout: one gather copy
            table = np.frombuffer(body, dtype="<f4", count=npts * nf).reshape(npts, nf)
            order = xyz + extra
            pts = table.copy() if order == list(range(nf)) else table[:, order]
            return Cloud(np.ascontiguousarray(pts, dtype=np.float32), tuple(["x", "y", "z"] + [uniq[i] for i in extra]))
        rec = np.frombuffer(body, dtype=dt, count=npts)
        return cloud_from_records(path, rec, xyz_only)
    if data_kind == "binary_compressed":
        return _compressed(path, data, start, uniq, fmts, counts, npts, xyz, extra)
    raise ReadError(path, f"unknown PCD DATA kind {data_kind!r} (ascii, binary or binary_compressed)")


def _compressed(
    path: PathLike,
    data: bytes,
    start: int,
    names: list[str],
    fmts: list[str],
    counts: list[int],
    npts: int,
    xyz: list[int],
    extra: list[int],
) -> Cloud:
    have = len(data) - start
    if have < 8:
        raise ReadError(path, "truncated PCD binary_compressed data: no size header")
    csize, usize = (int(v) for v in np.frombuffer(data, dtype="<u4", count=2, offset=start))
    if have < 8 + csize:
        raise ReadError(path, f"truncated PCD binary_compressed data: {have - 8} B of {csize} compressed B")
    itemsize = sum(np.dtype(f).itemsize * c for f, c in zip(fmts, counts))
    if usize != npts * itemsize:
        raise ReadError(
            path, f"PCD binary_compressed: uncompressed size {usize} B does not match {npts} points × {itemsize} B"
        )
    try:
        raw = decompress_array(data, usize, start + 8, start + 8 + csize)
    except ValueError as e:
        raise ReadError(path, f"corrupt PCD binary_compressed data: {e}") from None
    # Structure of arrays: all values of field 0, then of field 1, ...
    if all(f == "f4" for f in fmts) and all(c == 1 for c in counts):
        soa = raw.view("<f4").reshape(len(fmts), npts)
        order = xyz + extra
        pts = np.empty((npts, len(order)), dtype=np.float32)
        for j, i in enumerate(order):  # one strided column copy each: faster than a fancy-indexed transpose
            pts[:, j] = soa[i]
        return Cloud(pts, tuple(["x", "y", "z"] + [names[i] for i in extra]))
    arrays: list[npt.NDArray[Any]] = []
    off = 0
    for f, c in zip(fmts, counts):
        dt1 = np.dtype("<" + f)
        arrays.append(raw[off : off + npts * c * dt1.itemsize].view(dt1).reshape(npts, c))
        off += npts * c * dt1.itemsize
    cols = [arrays[i][:, 0] for i in xyz]
    fnames = ["x", "y", "z"]
    for i in extra:
        for j in range(counts[i]):
            cols.append(arrays[i][:, j])
            fnames.append(names[i] if counts[i] == 1 else f"{names[i]}_{j}")
    return stack_columns(cols, fnames)


def _ascii(
    path: PathLike, body: bytes, names: list[str], counts: list[int], npts: int, xyz: list[int], extra: list[int]
) -> Cloud:
    ncol = sum(counts)
    try:
        vals = np.array(body.split(), dtype=np.float64)
    except ValueError:
        raise ReadError(path, "PCD ascii data contains a value that is not a number") from None
    if vals.size != npts * ncol:
        raise ReadError(path, f"PCD ascii data has {vals.size} values, expected {npts} points × {ncol} = {npts * ncol}")
    table = vals.reshape(npts, ncol)
    starts = np.cumsum([0] + counts[:-1])
    cols: list[npt.NDArray[Any]] = [table[:, starts[i]] for i in xyz]
    fnames = ["x", "y", "z"]
    for i in extra:
        for k in range(counts[i]):
            cols.append(table[:, starts[i] + k])
            fnames.append(names[i] if counts[i] == 1 else f"{names[i]}_{k}")
    return stack_columns(cols, fnames)


def write_pcd(
    path: PathLike,
    points: npt.ArrayLike,
    fields: AbcSequence[str] | None = None,
    data: Literal["ascii", "binary", "binary_compressed"] = "binary",
) -> None:
    """Write an (N, C) array as PCD v0.7 with float32 fields (default names x y z, then f3, f4, ...)."""
    pts, names = columns_to_write(points, fields)
    n, c = pts.shape
    head = (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
        f"FIELDS {' '.join(names)}\nSIZE {' '.join(['4'] * c)}\nTYPE {' '.join(['F'] * c)}\n"
        f"COUNT {' '.join(['1'] * c)}\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\n"
        f"DATA {data}\n"
    ).encode("ascii")
    if data == "ascii":
        rows = "\n".join(" ".join(repr(float(v)) for v in row) for row in pts.astype(np.float64))
        body = (rows + "\n").encode("ascii") if n else b""
    elif data == "binary":
        body = np.ascontiguousarray(pts, dtype="<f4").tobytes()
    elif data == "binary_compressed":
        raw = np.ascontiguousarray(pts.T, dtype="<f4").tobytes()
        comp = lzf_compress(raw)
        body = np.array([len(comp), len(raw)], dtype="<u4").tobytes() + comp
    else:
        raise unknown_kind("PCD data kind", data, ("ascii", "binary", "binary_compressed"))
    atomic_write_bytes(Path(path), head + body)
