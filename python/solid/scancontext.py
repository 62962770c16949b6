"""Scan Context baseline (G. Kim and A. Kim, IROS 2018), in numpy: descriptor and candidate search.

Written from the paper, with the choices of the authors' C++ implementation (gisbi-kim/scancontext,
``cpp/module/Scancontext``) where the paper leaves them open or the C++ differs, so that its results
match that reference (``tests/test_scancontext.py`` checks this on hku1-avia). This module generates
candidates; scoring them (docs/spec.md §5) is the caller's job.

Descriptor (paper §III-A/B): an ``n_ring × n_sector`` (20 × 60) polar grid of the horizontal plane.
With ``r = √(x² + y²)`` and θ = azimuth counter-clockwise from +x in [0°, 360°), a point with
``r ≤ max_range`` (80 m) falls into ring ``clip(⌈r·Nr/max_range⌉, 1, Nr) − 1`` and sector
``clip(⌈θ·Ns/360°⌉, 1, Ns) − 1``: bins are closed at their outer edge, and r = 0 or θ = 0 go to
bin 0 (as in the C++). A cell holds the largest ``z + lidar_height`` of its points (lidar_height
2 m: the C++'s ``LIDAR_HEIGHT``), not clamped: a cell whose points all lie below ``−lidar_height``
holds that negative maximum. An empty cell holds 0. Points with a non-finite coordinate are dropped
(the C++ would index out of its grid with them).

Keys (paper §III-D and the C++): the ring key is rotation invariant and drives a nearest-neighbour
pre-search; the C++ uses each ring's mean over its sectors (empty cells count as 0), the paper its
occupancy ratio ``‖ring‖₀ / Ns``. The sector key (the C++'s "variant key", not in the paper) is each
sector's mean over its rings; it gives a coarse alignment before the fine shift search.

Distance between a query Q and a candidate C at column shift n (paper eq. 5 and 6), with
``C_n[:, j] = C[:, (j − n) mod Ns]`` and column cosine ``cos_j = Q[:, j]·C_n[:, j] / (‖Q[:, j]‖‖C_n[:, j]‖)``:
- ``variant="reference"`` (the C++, the default): the mean of ``1 − cos_j`` over the columns where
  both columns are non-empty (non-zero norm), searched only over the shifts within
  ``round(search_ratio·Ns/2)`` (±3 of 60) of the sector-key alignment
  ``argmin_n ‖Vq − Vc_n‖`` (first minimum); among those shifts the first minimum in increasing
  shift order wins. A shift where no column pair is non-empty in both is not comparable; a candidate
  with no comparable shift gets distance ``+inf`` (the C++ never picks it) and shift 0.
- ``variant="paper"``: ``1 − (1/Ns)·Σⱼ cos_j`` over all Ns columns (an empty column has cosine 0),
  minimised over all Ns shifts (first minimum); the ring key is the occupancy ratio.

Heading: the best shift n means ``Q[:, j] ≈ C[:, j − n]``, so the query is the candidate rotated
counter-clockwise by ``ψ = n·360°/Ns``, wrapped into (−180°, 180°]: the convention of docs/spec.md §3
(``p_query ≈ Rz(ψ)·p_candidate``). (The C++ reports ``n·360°/Ns`` in [0°, 360°).)

Search (the C++'s ``detectLoopClosureID``): the ``n_candidates`` (10) database entries nearest to the
query by Euclidean distance between ring keys (exact; ties by lower id; the C++ asks a nanoflann
kd-tree, which is exact too), re-ranked by the distance above. ``n_candidates=None`` compares the
query with every eligible entry. Which entries are eligible is the caller's choice
(:data:`Exclusion`): by default every frame ``< q − 50``, the docs/spec.md §5 protocol. The C++'s online loop
differs in two ways that this module does not copy: its database holds the frames ``≤ q − 50``, and
it rebuilds its kd-tree only every 50 queries, so most queries search a stale subset.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Literal, Union

import numpy as np
import numpy.typing as npt

from . import _solid
from .arrays import B, F64, I64
from .evaluation import Evaluation, evaluate_candidates
from .transforms import wrap_degrees

__all__ = [
    "Candidates",
    "Exclusion",
    "ScanContextConfig",
    "candidates",
    "describe",
    "describe_many",
    "distance",
    "eligible_count",
    "evaluate_scancontext",
    "heading_deg",
    "ring_key",
    "sector_key",
]


#: Which database entries a query may match. An ``int`` e: the frames ``< q − e`` (docs/spec.md §5). An
#: (N, N) boolean array: row q marks the eligible entries of query q. A callable ``f(q)``: a boolean
#: mask of length N or an array of eligible ids (e.g. exclusion by metres travelled or by seconds).
Exclusion = Union[int, npt.ArrayLike, Callable[[int], npt.ArrayLike]]


@dataclass(frozen=True)
class ScanContextConfig:
    """Scan Context parameters; the defaults are the paper's and the reference C++'s.

    ``search_ratio`` is the width of the shift search window as a fraction of the sectors (the
    C++'s ``SEARCH_RATIO``: 0.1 → ±3 shifts of 60 around the sector-key alignment); it applies to
    ``variant="reference"`` only (``"paper"`` searches every shift). ``n_candidates`` is how many
    ring-key neighbours are re-ranked (``None``: every eligible entry).
    """

    n_ring: int = 20
    n_sector: int = 60
    max_range: float = 80.0
    lidar_height: float = 2.0
    n_candidates: int | None = 10
    search_ratio: float = 0.1
    variant: Literal["reference", "paper"] = "reference"

    def __post_init__(self) -> None:
        for name in ("n_ring", "n_sector", "n_candidates"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, np.integer)) or (v is None and name == "n_candidates")):
                raise TypeError(f"{name} must be an integer, got {type(v).__name__}")
        if self.n_ring < 1 or self.n_sector < 1:
            raise _solid.ConfigError(f"n_ring and n_sector must be >= 1, got {self.n_ring}, {self.n_sector}")
        if not (math.isfinite(self.max_range) and self.max_range > 0):
            raise _solid.ConfigError(f"max_range must be finite and > 0, got {self.max_range}")
        if not math.isfinite(self.lidar_height):
            raise _solid.ConfigError(f"lidar_height must be finite, got {self.lidar_height}")
        if self.n_candidates is not None and self.n_candidates < 1:
            raise _solid.ConfigError(f"n_candidates must be >= 1 or None, got {self.n_candidates}")
        if not (math.isfinite(self.search_ratio) and 0 <= self.search_ratio <= 1):
            raise _solid.ConfigError(f"search_ratio must be in [0, 1], got {self.search_ratio}")
        if self.variant not in ("reference", "paper"):
            raise _solid.ConfigError(f"variant must be 'reference' or 'paper', got {self.variant!r}")

    @property
    def shift_radius(self) -> int:
        """Half-width of the shift window: ``round(search_ratio·n_sector/2)`` (halves away from 0)."""
        if self.variant == "paper":
            return self.n_sector
        return int(math.floor(0.5 * self.search_ratio * self.n_sector + 0.5))


def describe(points: npt.ArrayLike, cfg: ScanContextConfig = ScanContextConfig()) -> F64:
    """The (n_ring, n_sector) Scan Context of one scan (x, y, z in the first three columns)."""
    p = np.asarray(points)
    if p.ndim != 2 or p.shape[1] < 3:
        raise _solid.SolidError(f"points must have shape (N, >=3), got {p.shape}")
    x = p[:, 0].astype(np.float64)
    y = p[:, 1].astype(np.float64)
    z = p[:, 2].astype(np.float64)
    r = np.hypot(x, y)
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(z) & (r <= cfg.max_range)
    x, y, z, r = x[ok], y[ok], z[ok], r[ok]
    theta = np.degrees(np.arctan2(y, x)) % 360.0
    ring = np.clip(np.ceil(r * cfg.n_ring / cfg.max_range), 1, cfg.n_ring).astype(np.int64) - 1
    sector = np.clip(np.ceil(theta * cfg.n_sector / 360.0), 1, cfg.n_sector).astype(np.int64) - 1
    out = np.full(cfg.n_ring * cfg.n_sector, -np.inf)
    np.maximum.at(out, ring * cfg.n_sector + sector, z + cfg.lidar_height)
    out[out == -np.inf] = 0.0
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


def _as_descriptors(descriptors: npt.ArrayLike, cfg: ScanContextConfig) -> F64:
    D = np.asarray(descriptors, dtype=np.float64)
    if D.ndim == 2:
        D = D[None]
    if D.ndim != 3 or D.shape[1:] != (cfg.n_ring, cfg.n_sector):
        raise _solid.SolidError(f"descriptors must be (N, {cfg.n_ring}, {cfg.n_sector}), got {D.shape}")
    return D


def ring_key(descriptors: npt.ArrayLike, cfg: ScanContextConfig = ScanContextConfig()) -> F64:
    """Rotation-invariant ring keys, (n_ring,) or (N, n_ring): ring mean (reference) or occupancy (paper)."""
    D = np.asarray(descriptors, dtype=np.float64)
    if cfg.variant == "paper":
        return np.asarray(np.count_nonzero(D, axis=-1) / D.shape[-1], dtype=np.float64)
    return np.asarray(D.mean(axis=-1), dtype=np.float64)


def sector_key(descriptors: npt.ArrayLike) -> F64:
    """Sector keys, (n_sector,) or (N, n_sector): each sector's mean over its rings."""
    return np.asarray(np.asarray(descriptors, dtype=np.float64).mean(axis=-2), dtype=np.float64)


def heading_deg(shift: npt.ArrayLike, n_sector: int) -> F64:
    """Heading of docs/spec.md §3 (degrees in (−180, 180]) for a best column shift."""
    return wrap_degrees(np.asarray(shift, dtype=np.float64) * 360.0 / n_sector)


@dataclass(frozen=True)
class _Prepared:
    """What the distance needs of each frame, computed once: unit columns, non-empty columns, sector keys."""

    unit: F64  # (N, R, S), empty columns stay 0
    nonempty: B  # (N, S)
    skey: F64  # (N, S)

    @staticmethod
    def of(D: F64) -> _Prepared:
        norms = np.linalg.norm(D, axis=1, keepdims=True)
        unit = np.divide(D, norms, out=np.zeros_like(D), where=norms > 0)
        return _Prepared(unit, norms[:, 0, :] > 0, sector_key(D))


def _pair_distances(
    prep: _Prepared, qi: I64, ci: I64, cfg: ScanContextConfig, chunk: int = 256
) -> tuple[F64, I64]:
    """Distance and best shift of each pair of frames (qi[p], ci[p]) (see the module doc)."""
    P = qi.size
    S = cfg.n_sector
    dist = np.empty(P)
    shift = np.zeros(P, dtype=np.int64)
    j = np.arange(S)
    roll = (j[None, :] - j[:, None]) % S  # roll[n, j] = (j − n) mod S
    h = cfg.shift_radius
    offsets = None if 2 * h + 1 >= S else np.arange(-h, h + 1)
    for lo in range(0, P, chunk):
        q, c = qi[lo : lo + chunk], ci[lo : lo + chunk]
        m = q.size
        rows = np.arange(m)[:, None, None]
        if offsets is None:
            shifts = np.broadcast_to(j, (m, S))
        else:
            vdiff = prep.skey[q][:, None, :] - prep.skey[c][:, roll]  # (m, n, j)
            align = np.argmin(np.sqrt(np.einsum("mnj,mnj->mn", vdiff, vdiff)), axis=1)
            shifts = np.sort((align[:, None] + offsets[None, :]) % S, axis=1)
        # cos[p, j, l]: query column j against candidate column l
        cos = np.matmul(np.swapaxes(prep.unit[q], 1, 2), prep.unit[c])
        cols = roll[shifts]  # (m, W, S): the candidate column (j − n) mod S facing query column j
        cos_sum = cos[rows, j[None, None, :], cols].sum(axis=2)
        if cfg.variant == "paper":
            d = 1.0 - cos_sum / S
        else:
            count = (prep.nonempty[q][:, None, :] & prep.nonempty[c][rows, cols]).sum(axis=2)
            d = np.where(count > 0, 1.0 - cos_sum / np.maximum(count, 1), np.inf)
        best = np.argmin(d, axis=1)
        dmin = d[np.arange(m), best]
        dist[lo : lo + m] = dmin
        shift[lo : lo + m] = np.where(np.isfinite(dmin), shifts[np.arange(m), best], 0)
    return dist, shift


def distance(
    query: npt.ArrayLike, candidate: npt.ArrayLike, cfg: ScanContextConfig = ScanContextConfig()
) -> tuple[float, int]:
    """Scan Context distance and best column shift between two (n_ring, n_sector) descriptors.

    Returns ``(d, n)`` with ``query[:, j] ≈ candidate[:, (j − n) mod n_sector]`` at the best shift n;
    ``heading_deg(n, n_sector)`` is the query's heading relative to the candidate (docs/spec.md §3).
    """
    q = _as_descriptors(query, cfg)
    c = _as_descriptors(candidate, cfg)
    if q.shape[0] != 1 or c.shape[0] != 1:
        raise _solid.SolidError("distance compares two single descriptors")
    d, n = _pair_distances(_Prepared.of(np.concatenate([q, c])), np.array([0]), np.array([1]), cfg)
    return float(d[0]), int(n[0])


@dataclass(frozen=True)
class Candidates:
    """Per query, its top-k candidates by Scan Context distance (best first).

    Missing entries (fewer than k candidates) are id −1, distance +inf, heading NaN. A candidate that
    is not comparable with the query (no column pair non-empty in both) has distance +inf and heading 0.
    """

    queries: I64  # (Q,)
    ids: I64  # (Q, k)
    distances: F64  # (Q, k)
    headings_deg: F64  # (Q, k), docs/spec.md §3 convention


def eligible_count(query: npt.ArrayLike, exclude: int) -> I64:
    """How many frames each query frame may be matched with under docs/spec.md §5 frame exclusion:
    those ``< q − exclude``. The rule of the core's loop detector for one session, which does not
    expose it; the baseline must ask the same questions."""
    return np.maximum(np.asarray(query, dtype=np.int64) - exclude, 0)


def _eligibility(exclude: Exclusion, n: int) -> Callable[[int], B]:
    if isinstance(exclude, (int, np.integer)) and not isinstance(exclude, bool):
        e = int(exclude)
        if e < 0:
            raise _solid.ConfigError(f"exclude must be >= 0, got {e}")
        ids = np.arange(n)
        return lambda q: np.asarray(ids < eligible_count(q, e), dtype=bool)
    if callable(exclude):
        f = exclude

        def from_callable(q: int) -> B:
            v = np.asarray(f(q))
            if v.dtype == np.bool_:
                if v.shape != (n,):
                    raise _solid.SolidError(f"exclusion mask for query {q} has shape {v.shape}, expected ({n},)")
                return v
            mask = np.zeros(n, dtype=bool)
            idx = v.astype(np.int64).ravel()
            if idx.size and (idx.min() < 0 or idx.max() >= n):
                raise _solid.SolidError(f"eligible ids for query {q} out of range [0, {n})")
            mask[idx] = True
            return mask

        return from_callable
    M = np.asarray(exclude)
    if M.dtype != np.bool_ or M.shape != (n, n):
        raise _solid.SolidError(f"an exclusion array must be a boolean ({n}, {n}) mask, got {M.dtype} {M.shape}")
    return lambda q: np.asarray(M[q], dtype=bool)


def candidates(
    descriptors: npt.ArrayLike,
    exclude: Exclusion = 50,
    k: int = 1,
    cfg: ScanContextConfig = ScanContextConfig(),
    *,
    queries: npt.ArrayLike | None = None,
    progress: Callable[[int], None] | None = None,
    chunk: int = 64,
) -> Candidates:
    """Top-k Scan Context candidates of each query among its eligible database entries.

    ``descriptors`` is (N, n_ring, n_sector), one per frame; the database of query q is the frames
    that ``exclude`` marks eligible (:data:`Exclusion`; default: frames ``< q − 50``). ``queries``
    defaults to every frame with a non-empty database. The ``cfg.n_candidates`` nearest entries by
    ring key are ranked by Scan Context distance (ties: nearer ring key, then lower id).
    """
    D = _as_descriptors(descriptors, cfg)
    n = D.shape[0]
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
        raise TypeError(f"k must be an integer, got {type(k).__name__}")
    if k < 1:
        raise _solid.ConfigError(f"k must be >= 1, got {k}")
    eligible = _eligibility(exclude, n)
    masks: dict[int, B] = {}
    if queries is None:
        qlist = []
        for q in range(n):
            m = eligible(q)
            if m.any():
                qlist.append(q)
                masks[q] = m
        qs_all = np.asarray(qlist, dtype=np.int64)
    else:
        qs_all = np.asarray(queries, dtype=np.int64).ravel()
        if qs_all.size and (qs_all.min() < 0 or qs_all.max() >= n):
            raise _solid.SolidError(f"query ids out of range [0, {n})")
    keys = ring_key(D, cfg)
    prep = _Prepared.of(D)
    nc = n if cfg.n_candidates is None else min(cfg.n_candidates, n)
    ids = np.full((qs_all.size, k), -1, dtype=np.int64)
    dists = np.full((qs_all.size, k), np.inf)
    heads = np.full((qs_all.size, k), np.nan)
    for lo in range(0, qs_all.size, chunk):
        qs = qs_all[lo : lo + chunk]
        mask = np.stack([masks.pop(int(q)) if int(q) in masks else eligible(int(q)) for q in qs])
        kd = ((keys[qs][:, None, :] - keys[None, :, :]) ** 2).sum(axis=2)
        kd[~mask] = np.inf
        order = np.lexsort((np.broadcast_to(np.arange(n), kd.shape), kd), axis=1)[:, :nc]  # (Qc, nc)
        valid = np.isfinite(np.take_along_axis(kd, order, axis=1))
        r, col = np.nonzero(valid)
        d = np.full(order.shape, np.inf)
        s = np.zeros(order.shape, dtype=np.int64)
        if r.size:
            pd, ps = _pair_distances(prep, qs[r], order[r, col], cfg)
            d[r, col] = pd
            s[r, col] = ps
        # stable: equal distances keep the ring-key order; missing entries (+inf, invalid) go last
        rank = np.lexsort((~valid, d), axis=1)[:, :k]
        kk = rank.shape[1]
        got = np.take_along_axis(valid, rank, axis=1)
        ids[lo : lo + qs.size, :kk] = np.where(got, np.take_along_axis(order, rank, axis=1), -1)
        dists[lo : lo + qs.size, :kk] = np.where(got, np.take_along_axis(d, rank, axis=1), np.inf)
        heads[lo : lo + qs.size, :kk] = np.where(
            got, heading_deg(np.take_along_axis(s, rank, axis=1), cfg.n_sector), np.nan
        )
        if progress is not None:
            progress(int(qs.size))
    return Candidates(qs_all, ids, dists, heads)


def evaluate_scancontext(
    descriptors: npt.ArrayLike,
    poses: npt.ArrayLike,
    *,
    radius: float,
    exclude: int = 50,
    queries: npt.ArrayLike | None = None,
    eligible: npt.ArrayLike | None = None,
    k: int = 5,
    cfg: ScanContextConfig = ScanContextConfig(),
    name: str = "Scan Context",
    progress: Callable[[int], None] | None = None,
) -> Evaluation:
    """docs/spec.md §5 evaluation of Scan Context candidates against poses, by the same scorer as SOLiD.

    The queries and what each may be matched with are either given (``queries`` and ``eligible``:
    query q sees frames ``< eligible``, e.g. a SOLiD run's own, so both methods face the same
    questions), or the docs/spec.md §5 default: frames ``< q − exclude``. The one place where this module
    hands its candidates to a scorer.
    """
    D = _as_descriptors(descriptors, cfg)
    n = D.shape[0]
    if queries is None:
        qs = query_indices(n, exclude)
        el = qs - exclude
    else:
        qs = np.asarray(queries, dtype=np.int64)
        el = np.asarray(eligible, dtype=np.int64)
        if el.shape != qs.shape:
            raise _solid.SolidError(f"eligible must have the shape of queries {qs.shape}, got {el.shape}")
    bound = dict(zip(qs.tolist(), el.tolist()))
    ids_all = np.arange(n)

    def mask(q: int) -> B:
        return np.asarray(ids_all < bound.get(q, 0), dtype=bool)

    c = candidates(D, mask, k, cfg, queries=qs, progress=progress)
    best = c.distances[:, 0]
    ev = evaluate_candidates(name, c.queries, el, c.ids, best, best, c.headings_deg[:, 0], poses, radius=radius)
    ev.extra["config"] = {
        "n_ring": cfg.n_ring,
        "n_sector": cfg.n_sector,
        "max_range": cfg.max_range,
        "lidar_height": cfg.lidar_height,
        "n_candidates": cfg.n_candidates,
        "search_ratio": cfg.search_ratio,
        "variant": cfg.variant,
    }
    return ev


def query_indices(n_frames: int, exclude: int) -> I64:
    """Frames that are queries under docs/spec.md §5 frame exclusion: those with a non-empty database."""
    if exclude < 0:
        raise _solid.ConfigError(f"exclude must be >= 0, got {exclude}")
    q = np.arange(n_frames, dtype=np.int64)
    return q[eligible_count(q, exclude) > 0]
