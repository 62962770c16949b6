"""Seeds of the cargo-fuzz LZF target, made at run time from the shared data.

    python fuzz/python/seed_lzf.py CORPUS_DIR

Each seed is the target's input: two bytes of output size (big-endian), then an LZF stream (the
first 1-4 KiB of shared scans, compressed by solid's writer).
"""

from __future__ import annotations

import sys
from pathlib import Path

import targets

from solid import io as sio


def main() -> int:
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    d = targets.shared_data()
    sources = ["kitti00/velodyne/000000.bin", "hku1-avia/Scans/000000.pcd", "misc/nclt_2012-01-15_1326652795280148_hdl32e.bin"]
    for i, rel in enumerate(sources):
        for n in (1024, 4096):
            raw = (d / rel).read_bytes()[:n]
            (out / f"seed-{i}-{n}").write_bytes(len(raw).to_bytes(2, "big") + sio.lzf_compress(raw))
    return 0


if __name__ == "__main__":
    sys.exit(main())
