"""Scan Context baseline (G. Kim and A. Kim, IROS 2018), written from the paper, in numpy.

The descriptor is an ``n_ring × n_sector`` (20 × 60) polar grid over the horizontal plane out
to ``max_range``: ring i covers planar range ``[i, i+1)·max_range/n_ring``, sector j covers azimuth
``[j, j+1)·360°/n_sector`` (counter-clockwise from +x). A cell's value is the maximum height of
its points, measured as ``z + height_offset`` and clamped at 0, so heights are non-negative; an
empty cell is 0. The default offset is 2.0 m (a sensor mounted about 2 m above the ground, as on
the paper's vehicles); points lower than ``−height_offset`` therefore count as height 0.

The distance between a query and a candidate is, minimised over the n_sector column shifts n,
the mean over column pairs that are both non-empty of ``1 − cos(query column j, candidate column
(j − n) mod n_sector)``; 1.0 when no pair is non-empty. The best shift gives the heading
``ψ = n·360°/n_sector`` (wrapped into (−180°, 180°]) in the convention of SPEC §3: the query ≈ the
candidate rotated by ψ counter-clockwise. The ring-key pre-search of the paper is not used: every
query is compared exactly with every database frame. The shifts are evaluated for all frames at
once with FFT circular cross-correlation over the sector axis (summed over rings), which equals
the direct sum up to floating-point rounding (:func:`distance` is the direct reference).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .evaluation import Evaluation, _topk_from_dist, evaluate_topk, query_indices
from .io import _wrap180

__all__ = [
    "ScanContextConfig",
    "describe",
    "describe_many",
    "distance",
    "evaluate_scancontext",
    "topk",
]

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]


@dataclass(frozen=True)
class ScanContextConfig:
    """Scan Context parameters (paper defaults 20 × 60 over 80 m; height offset: see module doc)."""

    n_ring: int = 20
    n_sector: int = 60
    max_range: float = 80.0
    height_offset: float = 2.0

    def __post_init__(self) -> None:
        if self.n_ring < 1 or self.n_sector < 1:
            raise ValueError(f"n_ring and n_sector must be >= 1, got {self.n_ring}, {self.n_sector}")
        if not (math.isfinite(self.max_range) and self.max_range > 0):
            raise ValueError(f"max_range must be finite and > 0, got {self.max_range}")
        if not math.isfinite(self.height_offset):
            raise ValueError(f"height_offset must be finite, got {self.height_offset}")


def describe(points: npt.ArrayLike, cfg: ScanContextConfig = ScanContextConfig()) -> F64:
    """The (n_ring, n_sector) Scan Context of one scan (x, y, z in the first three columns)."""
    p = np.asarray(points)
    if p.ndim != 2 or p.shape[1] < 3:
        raise ValueError(f"points must have shape (N, >=3), got {p.shape}")
    x = p[:, 0].astype(np.float64)
    y = p[:, 1].astype(np.float64)
    z = p[:, 2].astype(np.float64)
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(z)
    r = np.hypot(x, y)
    ok &= r < cfg.max_range
    x, y, z, r = x[ok], y[ok], z[ok], r[ok]
    theta = np.degrees(np.arctan2(y, x)) % 360.0
    ring = np.minimum((r * cfg.n_ring / cfg.max_range).astype(np.int64), cfg.n_ring - 1)
    sector = np.minimum((theta * cfg.n_sector / 360.0).astype(np.int64), cfg.n_sector - 1)
    h = np.maximum(z + cfg.height_offset, 0.0)
    out = np.zeros(cfg.n_ring * cfg.n_sector, dtype=np.float64)
    np.maximum.at(out, ring * cfg.n_sector + sector, h)
    return out.reshape(cfg.n_ring, cfg.n_sector)


def describe_many(
    scans: Iterable[npt.ArrayLike],
    cfg: ScanContextConfig = ScanContextConfig(),
    progress: Callable[[int], None] | None = None,
) -> F64:
    """Stack the Scan Contexts of many scans into (N, n_ring, n_sector)."""
    out = []
    for s in scans:
        out.append(describe(s, cfg))
        if progress is not None:
            progress(1)
    if not out:
        return np.zeros((0, cfg.n_ring, cfg.n_sector))
    return np.stack(out)


def distance(query: npt.ArrayLike, candidate: npt.ArrayLike) -> tuple[float, int]:
    """Direct (reference) Scan Context distance and best shift between two descriptors.

    Returns ``(d, n)``: d = min over shifts n of the mean over both-non-empty column pairs of
    ``1 − cos(q[:, j], c[:, (j − n) mod S])`` (1.0 when there is no such pair); n = the first
    minimising shift.
    """
    q = np.asarray(query, dtype=np.float64)
    c = np.asarray(candidate, dtype=np.float64)
    if q.shape != c.shape or q.ndim != 2:
        raise ValueError(f"descriptor shapes differ or are not 2-D: {q.shape}, {c.shape}")
    s_count = q.shape[1]
    best, best_n = math.inf, 0
    qn = np.linalg.norm(q, axis=0)
    for n in range(s_count):
        cs = np.roll(c, n, axis=1)  # cs[:, j] = c[:, (j - n) mod S]
        cn = np.linalg.norm(cs, axis=0)
        both = (qn > 0) & (cn > 0)
        if not both.any():
            d = 1.0
        else:
            cos = (q[:, both] * cs[:, both]).sum(axis=0) / (qn[both] * cn[both])
            d = float(np.mean(1.0 - cos))
        if d < best:
            best, best_n = d, n
    return best, best_n


def _unit_columns(sc: F64) -> tuple[F64, F64]:
    norms = np.linalg.norm(sc, axis=-2, keepdims=True)
    unit = np.divide(sc, norms, out=np.zeros_like(sc), where=norms > 0)
    return unit, (norms[..., 0, :] > 0).astype(np.float64)


def topk(
    descriptors: npt.ArrayLike,
    exclude: int = 50,
    k: int = 5,
    *,
    progress: Callable[[int], None] | None = None,
    max_elements: int = 6_000_000,
) -> tuple[I64, I64, F64, I64]:
    """Exact top-k by Scan Context distance of every query against its database (SPEC §5).

    Returns ``(queries, ids (Q, k), distances (Q, k), best shift of the top-1 (Q,))``; ties by
    lower id; missing entries are id −1 / distance inf.
    """
    D = np.asarray(descriptors, dtype=np.float64)
    if D.ndim != 3:
        raise ValueError(f"descriptors must be (N, rings, sectors), got {D.shape}")
    n, _, s_count = D.shape
    unit, mask = _unit_columns(D)
    fu = np.fft.rfft(unit, axis=2)  # (N, R, K)
    fm = np.fft.rfft(mask, axis=1)  # (N, K)
    fu_t = np.ascontiguousarray(np.transpose(fu, (2, 1, 0)).conj())  # (K, R, N)
    queries = query_indices(n, exclude)
    ids = np.empty((queries.size, k), dtype=np.int64)
    dists = np.empty((queries.size, k), dtype=np.float64)
    shifts = np.zeros(queries.size, dtype=np.int64)
    chunk = max(1, max_elements // max(1, s_count * max(1, n)))
    for lo in range(0, queries.size, chunk):
        qs = queries[lo : lo + chunk]
        ndb = int(qs[-1]) - exclude
        fq = np.transpose(fu[qs], (2, 0, 1))  # (K, Q, R)
        g = np.matmul(fq, fu_t[:, :, :ndb])  # (K, Q, ndb)  Σ_r FQ·conj(FC)
        cos_sum = np.fft.irfft(g, n=s_count, axis=0)  # (S, Q, ndb): shift n
        gm = fm[qs].T[:, :, None] * fm[:ndb].conj().T[:, None, :]
        count = np.rint(np.fft.irfft(gm, n=s_count, axis=0))
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.where(count > 0, 1.0 - cos_sum / np.where(count > 0, count, 1.0), 1.0)
        best_shift = np.argmin(d, axis=0)  # (Q, ndb), first minimum
        dmin = np.take_along_axis(d, best_shift[None], axis=0)[0]
        np.clip(dmin, 0.0, 2.0, out=dmin)
        dmin[np.arange(ndb)[None, :] >= (qs - exclude)[:, None]] = np.inf
        i, dd = _topk_from_dist(dmin, k)
        ids[lo : lo + qs.size] = i
        dists[lo : lo + qs.size] = dd
        top1 = np.where(i[:, 0] >= 0, i[:, 0], 0)
        shifts[lo : lo + qs.size] = best_shift[np.arange(qs.size), top1]
        if progress is not None:
            progress(int(qs.size))
    return queries, ids, dists, shifts


def evaluate_scancontext(
    descriptors: npt.ArrayLike,
    poses: npt.ArrayLike,
    *,
    exclude: int = 50,
    radius: float = 5.0,
    k: int = 5,
    name: str = "Scan Context",
    progress: Callable[[int], None] | None = None,
) -> Evaluation:
    """SPEC §5 evaluation of Scan Context descriptors (N, rings, sectors) against poses."""
    D = np.asarray(descriptors, dtype=np.float64)
    queries, ids, dists, shifts = topk(D, exclude, k, progress=progress)
    heading = _wrap180(shifts.astype(np.float64) * 360.0 / D.shape[2])
    return evaluate_topk(name, queries, ids, dists, heading, poses, exclude=exclude, radius=radius)
