"""Which frames of a recording a run reads, and reading them: ``--frames`` and ``subsample_m``.

:func:`parse_frames` reads a selection such as ``"0:60,284:314,300"``; :func:`select_frames`
applies it and then the distance subsampling to a recording; :func:`iter_selected` reads the
selected scans once each, in order (a bag is streamed, never sought).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence as AbcSequence
from typing import Any

from ..arrays import F32, F64
from ..errors import ConfigError
from ..transforms import subsample_by_distance

__all__ = ["iter_selected", "parse_frames", "select_frames"]


def parse_frames(spec: str, n: int) -> list[int]:
    """Frame selection ``"0:60,284:314,300"`` (Python slices and indices, in that order, no repeats)."""
    out: list[int] = []
    seen: set[int] = set()
    for part in spec.split(","):
        part = part.strip()
        if not part:
            continue
        try:
            if ":" in part:
                bits = [int(b) if b.strip() else None for b in part.split(":")]
                if len(bits) > 3:
                    raise ValueError
                idx = list(range(n))[slice(*bits)]
            else:
                i = int(part)
                if not -n <= i < n:
                    raise ConfigError(f"frames: frame {i} is out of range for {n} scans")
                idx = [i % n]
        except ValueError:
            raise ConfigError(f"frames: cannot parse {part!r} (use e.g. 0:60,284:314)") from None
        for i in idx:
            if i not in seen:
                seen.add(i)
                out.append(i)
    if not out:
        raise ConfigError(f"frames {spec!r} selects no scans")
    return out


def select_frames(n: int, poses: F64 | None, frames: str | None, subsample_m: float | None) -> list[int]:
    """The dataset indices the pipeline reads, in order (``input.frames``, then ``subsample_m``)."""
    idx = parse_frames(frames, n) if frames else list(range(n))
    if subsample_m is not None:
        if poses is None:
            raise ConfigError("input.subsample_m needs poses")
        keep = subsample_by_distance(poses[idx], subsample_m)
        idx = [idx[int(k)] for k in keep]
    return idx


def iter_selected(ds: Any, idx: AbcSequence[int]) -> Iterator[F32]:
    """Scans idx[0], idx[1], ... read once each: streamed in order when the selection is every
    scan (bags read sequentially), by index otherwise."""
    if list(idx) == list(range(len(ds))):
        yield from iter(ds)
        return
    if getattr(ds, "is_bag", False):
        want = {i: k for k, i in enumerate(idx)}
        buf: dict[int, F32] = {}
        nxt = 0
        for i, pts in enumerate(ds):
            if i in want:
                buf[want[i]] = pts
                while nxt in buf:
                    yield buf.pop(nxt)
                    nxt += 1
            if nxt == len(idx):
                return
        return
    for i in idx:
        yield ds[i]
