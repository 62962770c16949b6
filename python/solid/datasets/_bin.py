"""Raw ``.bin`` layouts (packed fixed-size records) and the sniffer that picks one from content.

A ``.bin`` file says nothing about itself, and several layouts can divide a file's size (every
KITTI file is also a whole number of 8 B NCLT records). The sniffer decodes an evenly spaced
sample of records with every layout whose record size divides the file size and keeps the layout
whose values are plausible (finite coordinates within 100 km and not denormal garbage, small
ring/line numbers, an NCLT laser id below 32): bytes decoded with the wrong layout fail these
checks for nearly every record. Folder and file names are never consulted.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ..arrays import PathLike
from ..errors import ReadError
from ._common import Cloud, cloud_from_records, records

#: A layout is taken when at least this fraction of the sampled records decode plausibly.
PLAUSIBLE: float = 0.9
#: Records decoded per candidate layout when sniffing.
SAMPLE: int = 4096

Mask = npt.NDArray[np.bool_]


@dataclass(frozen=True)
class BinLayout:
    """One packed-record ``.bin`` layout."""

    name: str
    dtype: np.dtype[Any]
    what: str
    plausible: Callable[[npt.NDArray[Any]], Mask]
    decode: Callable[[PathLike, bytes, bool], Cloud] | None = None

    @property
    def record(self) -> int:
        return self.dtype.itemsize

    def read(self, path: PathLike, data: bytes, xyz_only: bool) -> Cloud:
        """Decode the whole file (its size must be a whole number of records)."""
        if self.decode is not None:
            return self.decode(path, data, xyz_only)
        return cloud_from_records(path, records(path, data, self.dtype, self.what), xyz_only)


def plausible_coords(*cols: npt.NDArray[Any]) -> Mask:
    """Coordinates a sensor could report: finite, |v| < 100 km, and 0 or |v| > 1e-6."""
    ok = np.ones(cols[0].shape[0], dtype=bool)
    with np.errstate(invalid="ignore", over="ignore"):
        for c in cols:
            a = np.abs(c.astype(np.float64))
            ok &= np.isfinite(a) & (a < 1e5) & ((a == 0) | (a > 1e-6))
    return ok


def finite_below(c: npt.NDArray[Any], bound: float) -> Mask:
    with np.errstate(invalid="ignore", over="ignore"):
        a = np.abs(c.astype(np.float64))
        return np.isfinite(a) & (a < bound)


def sample_records(data: bytes, dtype: np.dtype[Any]) -> npt.NDArray[Any]:
    rec = np.frombuffer(data, dtype=dtype)
    if rec.shape[0] > SAMPLE:
        rec = rec[np.linspace(0, rec.shape[0] - 1, SAMPLE).astype(np.int64)]
    return rec


def score(layout: BinLayout, data: bytes) -> float:
    """Fraction of sampled records that decode plausibly (1.0 for an empty file)."""
    rec = sample_records(data, layout.dtype)
    if rec.shape[0] == 0:
        return 1.0
    return float(np.mean(layout.plausible(rec)))


def sniff(path: PathLike, data: bytes, layouts: Sequence[BinLayout]) -> BinLayout:
    """The layout of a ``.bin`` file's bytes; a :class:`ReadError` naming its size when none fits.

    Among the layouts whose record size divides the size, the one with the most plausible
    records wins; ties (an all-zero file) go to the first in ``layouts`` order.
    """
    size = len(data)
    fits = [lay for lay in layouts if size % lay.record == 0]
    if not fits:
        sizes = ", ".join(f"{lay.name} {lay.record} B" for lay in layouts)
        raise ReadError(path, f"size {size} B is not a whole number of records of any .bin layout ({sizes})")
    scored = [(score(lay, data), -k, lay) for k, lay in enumerate(fits)]
    best, _, layout = max(scored, key=lambda s: (s[0], s[1]))
    if best < PLAUSIBLE:
        tried = ", ".join(f"{lay.name} ({lay.record} B): {100 * s:.0f}% plausible records" for s, _, lay in scored)
        raise ReadError(
            path,
            f"size {size} B fits {tried}, and no layout decodes to plausible points; "
            "not a point-cloud .bin, or pass format=",
        )
    return layout
