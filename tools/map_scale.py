"""Maps at scale: file size, load time and memory, a detector on the map, `map info` and the
verified step, for maps of 1k to 1M places in the current file format (4) and the previous one (3).
The same figures from Rust: `cargo bench -p solid-lidar-benches --bench maps` (benches/benches/maps.rs,
which reuses this tool's files given `SOLID_BENCH_MAP_DIR`).

    PYTHONPATH=python python tools/map_scale.py [--sizes 1000,10000,100000] [--previous-up-to 100000]
        [--shared /work/shared] [--dir /tmp/map_scale]

The places are the 314 real Livox Avia keyframes of hku1-avia, each with its real compact cloud,
copied with 2 % multiplicative noise on every descriptor bin (a session of 314 places per copy,
a pose and a time per place), so that every map holds real descriptors and real clouds. Each
figure is measured in a fresh process: the load's wall and CPU time (user and system, every
thread's), the process's resident memory after `Database.load` (above the process before it:
Python, numpy and the query scans), then what a verifying detector over the map
(`LoopDetector.from_database`, the preset's defaults; it shares the database) adds by the end of
its steps: the map's search index, which a load leaves to the first search or detector (also
given alone), and the detector's working memory. The verified
step is the median wall time of a full step (describe, prepare the cloud, search, verify the best
candidates) for 20 hku1 scans, which match their own copies in the map. `map info` is
`Database.summary` (what `solid map info` prints), timed in a fresh process.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import solid
from solid.datasets import open_dataset

QUERIES = list(range(0, 314, 16))[:20]


def rss_mib() -> float:
    """The resident memory of this process, MiB (Linux)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def base_places(shared: Path, cache: Path) -> solid.Database:
    """The 314 hku1-avia keyframes described, each with its compact cloud (cached)."""
    if cache.exists():
        return solid.Database.load(cache)
    ds = open_dataset(shared / "data" / "hku1-avia")
    det = solid.LoopDetector(solid.SolidConfig.preset("avia"), exclude_recent=len(ds))
    det.detect_many([ds[i] for i in range(len(ds))])
    db = det.database
    db.save(cache)
    return db


def build(base: solid.Database, n: int, path: Path, seed: int, chunk: int = 100_000) -> None:
    """A map of `n` places: noisy copies of `base`'s, each with its place's cloud. Built a chunk at
    a time (each saved, loaded back with its clouds left in its file, and merged), so that the
    clouds of a large map are never all in memory at once."""
    rng = np.random.default_rng(seed)
    cfg = base.config
    r, a = base.r, base.a
    clouds = [base.cloud(i) for i in range(len(base))]
    pose = np.hstack([np.eye(3), np.zeros((3, 1))])
    whole = solid.Database(cfg)
    parts = []
    for start in range(0, n, chunk):
        db = solid.Database(cfg)
        for j in range(start, min(n, start + chunk)):
            i = j % len(base)
            nr = np.maximum(r[i] * (1 + 0.02 * rng.standard_normal(r.shape[1])), 0).astype(np.float32)
            na = np.maximum(a[i] * (1 + 0.02 * rng.standard_normal(a.shape[1])), 0).astype(np.float32)
            pose[:, 3] = (j, j // len(base), 0.0)
            db.add(solid.Descriptor(nr, na, cfg), session=j // len(base), timestamp=0.1 * j, pose=pose, cloud=clouds[i])
        part = path.with_name(f"{path.name}.part{start}")
        db.save(part)
        del db
        whole.merge(solid.Database.load(part))
        parts.append(part)
    whole.save(path)
    for part in parts:
        part.unlink()


def measure(path: str, shared: str) -> dict[str, Any]:
    """In this (fresh) process: load, detector, verified step; `map info` in another."""
    ds = open_dataset(Path(shared) / "data" / "hku1-avia")
    queries = [np.ascontiguousarray(ds[i][:, :3]) for i in QUERIES]
    before = rss_mib()
    t0, cpu0 = time.perf_counter(), cpu_s()
    db = solid.Database.load(path)
    load_s, load_cpu_s = time.perf_counter() - t0, cpu_s() - cpu0
    after_load = rss_mib()
    t0 = time.perf_counter()
    det = solid.LoopDetector.from_database(db)
    det_s = time.perf_counter() - t0
    after_det = rss_mib()
    steps = []
    for q in queries:
        t0 = time.perf_counter()
        det.detect(q)
        steps.append(time.perf_counter() - t0)
    after_steps = rss_mib()
    return {
        "load_s": load_s,
        "load_cpu_s": load_cpu_s,
        "rss_load_mib": after_load - before,
        "detector_s": det_s,
        "rss_index_mib": after_det - after_load,
        "rss_steps_mib": after_steps - after_det,
        "rss_detector_mib": after_steps - after_load,
        "step_ms": 1e3 * float(np.median(steps)),
    }


def cpu_s() -> float:
    """CPU time of this process so far, every thread's, user and system."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def info_time(path: str) -> float:
    t0 = time.perf_counter()
    solid.Database.summary(path)
    return time.perf_counter() - t0


def in_child(what: str, *args: str) -> Any:
    out = subprocess.run([sys.executable, __file__, "--child", what, *args], check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="1000,10000,100000")
    p.add_argument("--previous-up-to", type=int, default=100_000, help="also measure format 3 for maps up to this size")
    p.add_argument("--shared", type=Path, default=Path(os.environ.get("SOLID_SHARED", "/work/shared")))
    p.add_argument("--dir", type=Path, default=Path("/tmp/map_scale"))
    p.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        what, *rest = args.child
        print(json.dumps(measure(*rest) if what == "measure" else info_time(*rest)))
        return
    args.dir.mkdir(parents=True, exist_ok=True)
    base = base_places(args.shared, args.dir / "base.soliddb")
    print(
        "| places | format | file bytes / place | beside clouds | load (CPU) | RSS after load | + a detector | of which its index "
        "| verified step | map info |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for n in (int(s) for s in args.sizes.split(",")):
        v4 = args.dir / f"map{n}.v4.soliddb"
        if not v4.exists():
            build(base, n, v4, seed=n)
        files = [(4, v4)]
        if n <= args.previous_up_to:
            v3 = args.dir / f"map{n}.v3.soliddb"
            if not v3.exists():
                solid.Database.load(v4).save(v3, version=3)
            files.append((3, v3))
        for version, f in files:
            size = f.stat().st_size
            s = solid.Database.summary(f)
            m = in_child("measure", str(f), str(args.shared))
            info = in_child("info", str(f))
            print(
                f"| {n:,} | {version} | {size / n:,.0f} | {(size - s['cloud_bytes']) / n:,.0f} | "
                f"{m['load_s']:.2f} s ({m['load_cpu_s']:.2f} s) | {m['rss_load_mib']:,.0f} MiB | {m['rss_detector_mib']:,.1f} MiB | "
                f"{m['rss_index_mib']:,.1f} MiB in {m['detector_s']:.2f} s | {m['step_ms']:.0f} ms | {info * 1e3:,.1f} ms |",
                flush=True,
            )


if __name__ == "__main__":
    main()
