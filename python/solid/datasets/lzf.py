"""LZF, the compression of PCD ``binary_compressed`` data (liblzf's format, as PCL writes it).

Decoding is the core crate's :func:`solid_lidar::lzf::decompress_into`: bounded by the declared
size (the output is allocated once, here, and a stream that would expand past it stops there) and
run with the GIL released. :func:`lzf_compress` is a plain-Python encoder for writing test files
and small clouds.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .. import _solid


def max_decompressed_len(n: int) -> int:
    """The most bytes any LZF stream of ``n`` bytes can decode to (88 n)."""
    return int(_solid._lzf_max_decompressed_len(n))


def decompress_array(data: bytes, expected_size: int, start: int = 0, stop: int | None = None) -> npt.NDArray[np.uint8]:
    """:func:`lzf_decompress` of ``data[start:stop]`` into a new uint8 array (no copies to ``bytes``)."""
    if expected_size < 0:
        raise ValueError(f"expected size {expected_size} B is negative")
    length = (len(data) if stop is None else stop) - start
    bound = max_decompressed_len(length)
    if expected_size > bound:
        raise ValueError(
            f"LZF data of {length} B cannot decompress to {expected_size} B (at most {bound} B): "
            "the declared size is false"
        )
    out = np.empty(expected_size, dtype=np.uint8)
    n = _solid._lzf_decompress_into(data, out, start, stop)
    if n != expected_size:
        raise ValueError(f"LZF data decompresses to {n} B, expected {expected_size} B")
    return out


def lzf_decompress(data: bytes | bytearray | memoryview, expected_size: int) -> bytes:
    """Decompress an LZF stream that must decode to exactly ``expected_size`` bytes.

    Raises:
        ValueError: the stream is corrupt (a back-reference before the start of the output, a
            token running past the end of the input), expands beyond ``expected_size`` or decodes
            to fewer bytes; or ``expected_size`` is more than any stream of this length can give.
    """
    return decompress_array(bytes(data), expected_size).tobytes()


def lzf_compress(data: bytes | bytearray | memoryview) -> bytes:
    """Compress with LZF (liblzf's format; greedy, 3-byte hash, 8 KiB window).

    A plain-Python encoder meant for writing test files and small clouds; PCL, liblzf and
    :func:`lzf_decompress` read its output. Always returns a valid stream (incompressible input
    grows by one byte per 32).
    """
    src = bytes(data)
    n = len(src)
    out = bytearray()
    table: dict[bytes, int] = {}
    lit_start = 0
    i = 0

    def flush_literals(end: int) -> None:
        s = lit_start
        while s < end:
            ln = min(32, end - s)
            out.append(ln - 1)
            out.extend(src[s : s + ln])
            s += ln

    while i + 2 < n:
        key = src[i : i + 3]
        cand = table.get(key)
        table[key] = i
        if cand is not None and 0 < i - cand <= 8192:
            # extend the match (overlap allowed: cand < i)
            ln = 3
            maxlen = min(264, n - i)
            while ln < maxlen and src[cand + ln] == src[i + ln]:
                ln += 1
            flush_literals(i)
            off = i - cand - 1
            enc = ln - 2
            if enc < 7:
                out.append((enc << 5) | (off >> 8))
            else:
                out.append((7 << 5) | (off >> 8))
                out.append(enc - 7)
            out.append(off & 0xFF)
            for k in range(i + 1, min(i + ln, n - 2)):
                table[src[k : k + 3]] = k
            i += ln
            lit_start = i
        else:
            i += 1
    flush_literals(n)
    return bytes(out)
