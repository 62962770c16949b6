"""Times solid.describe against a vectorised numpy implementation of docs/spec.md §2, in one process.

    python benches/python_baseline.py            # or: make bench-py
    python benches/python_baseline.py --json results.json

Prints, for the full KITTI frame 000000 (124,668 points, hdl64, voxel 0.5) and its 60° clip, the
median milliseconds of each implementation and their ratio, checks that both give the same
descriptor, and prints the Python call overhead (describe of a one-point array). Then times
`describe_batch` on the shared KITTI frames with every core against one thread, in the same run.
With `--json PATH` it also writes every figure it prints to PATH (machine-readable, for the
README's speed table), with how many cores other processes kept busy during the run (the figures
mean little when that is not near 0).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import numpy.typing as npt

import solid
from solid import io as sio

F64 = npt.NDArray[np.float64]


def describe_numpy(points: npt.NDArray[np.floating], cfg: solid.SolidConfig) -> tuple[F64, F64, int]:
    """docs/spec.md §2 with numpy, vectorised throughout (no Python loop over points)."""
    xyz = np.asarray(points[:, :3], dtype=np.float64)
    xyz = xyz[np.isfinite(xyz).all(axis=1)]
    d = np.sqrt((xyz * xyz).sum(axis=1))
    xyz = xyz[(d > cfg.min_range) & (d < cfg.max_range)]
    if cfg.voxel_size > 0:
        k = np.floor(xyz / cfg.voxel_size).astype(np.int64) + (1 << 20)
        packed = k[:, 0] | (k[:, 1] << 21) | (k[:, 2] << 42)
        _, inverse, counts = np.unique(packed, return_inverse=True, return_counts=True)
        xyz = np.stack([np.bincount(inverse, weights=xyz[:, c]) for c in range(3)], axis=1) / counts[:, None]
    x, y, z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    r = np.hypot(x, y)
    theta = np.degrees(np.arctan2(y, x)) % 360.0
    phi = np.degrees(np.arctan2(z, r))
    nr, na, ne = cfg.n_range, cfg.n_azimuth, cfg.n_elevation
    i = np.minimum(np.floor(r * nr / cfg.max_range), nr - 1).astype(np.int64)
    j = np.minimum(np.floor(theta * na / 360.0), na - 1).astype(np.int64)
    kk = np.clip(np.floor((phi - cfg.fov_down) * ne / (cfg.fov_up - cfg.fov_down)), 0, ne - 1).astype(np.int64)
    rec = np.bincount(i * ne + kk, minlength=nr * ne).reshape(nr, ne).astype(np.float64)
    aec = np.bincount(j * ne + kk, minlength=na * ne).reshape(na, ne).astype(np.float64)
    ec = rec.sum(axis=0)
    span = ec.max() - ec.min() if len(ec) else 0.0
    iev = (ec - ec.min()) / span if span > 0 else np.ones(ne)
    return rec @ iev, aec @ iev, len(xyz)


def median_seconds(fn: Callable[[], object], repeats: int) -> float:
    fn()  # warm up (page faults, scratch buffers)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def cpu_model() -> str:
    """The CPU's model name (Linux), else what the platform module knows."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def cpu_jiffies() -> tuple[int, int] | None:
    """(busy, total) CPU time of the whole machine so far, from /proc/stat (Linux), else None."""
    try:
        fields = [int(v) for v in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    except (OSError, ValueError):
        return None
    idle = fields[3] + (fields[4] if len(fields) > 4 else 0)
    return sum(fields) - idle, sum(fields)


def other_busy_cores(start: tuple[int, int] | None, wall0: float, cpu0: float) -> float | None:
    """Cores that other processes kept busy on average since `start` (machine busy time minus ours)."""
    end = cpu_jiffies()
    if start is None or end is None or end[1] == start[1]:
        return None
    machine = (os.cpu_count() or 1) * (end[0] - start[0]) / (end[1] - start[1])
    ours = (time.process_time() - cpu0) / (time.perf_counter() - wall0)
    return max(0.0, machine - ours)


def shared_data() -> Path:
    env = os.environ.get("SOLID_SHARED")
    root = Path(env) if env else Path(__file__).resolve().parents[2] / "shared"
    if not (root / "data").is_dir():
        sys.exit(f"benchmark data not found under {root} (set SOLID_SHARED)")
    return root / "data"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--json", type=Path, metavar="PATH", help="also write the figures to PATH as JSON")
    args = parser.parse_args(argv)
    busy0, wall0, cpu0 = cpu_jiffies(), time.perf_counter(), time.process_time()
    data = shared_data()
    cfg = solid.SolidConfig.preset("hdl64")
    results: dict[str, object] = {
        "solid_version": solid.__version__,
        "preset": "hdl64",
        "voxel_size": cfg.voxel_size,
        "machine": {"cpu": cpu_model(), "cores": os.cpu_count()},
    }
    describe_rows: list[dict[str, object]] = []
    # id (stable, for tools reading --json) -> (printed name, points)
    scans = {
        "kitti00_000000": (
            "KITTI 000000, full 360° (124,668 pts)",
            sio.read_points(data / "kitti00/velodyne/000000.bin", "kitti"),
        ),
        "kitti00_000000_60deg": (
            "KITTI 000000, 60° clip",
            sio.read_points(data / "solid-samples/kitti_00_60/000000.bin", "kitti"),
        ),
    }
    print(f"solid {solid.__version__}, single thread, hdl64, voxel {cfg.voxel_size} m; median of repeated runs")
    print(f"{'scan':40s} {'numpy ms':>9s} {'solid ms':>9s} {'speed-up':>9s}")
    for scan_id, (name, pts) in scans.items():
        r_np, a_np, kept = describe_numpy(pts, cfg)
        d = solid.describe(pts, cfg)
        # Same descriptor (docs/spec.md §7 tolerance): the benchmark compares equal work.
        assert abs(d.n_kept - kept) <= 1e-3 * kept, (d.n_kept, kept)
        assert np.abs(d.r - r_np).sum() <= 1e-3 * np.abs(r_np).sum()
        assert np.abs(d.a - a_np).sum() <= 1e-3 * np.abs(a_np).sum()
        t_np = median_seconds(lambda: describe_numpy(pts, cfg), 15)
        t_solid = median_seconds(lambda: solid.describe(pts, cfg), 200)
        print(f"{name:40s} {t_np * 1e3:9.3f} {t_solid * 1e3:9.3f} {t_np / t_solid:8.1f}x")
        describe_rows.append(
            {
                "id": scan_id,
                "scan": name,
                "n_points": len(pts),
                "n_kept": d.n_kept,
                "threads": 1,
                "numpy_median_ms": t_np * 1e3,
                "solid_median_ms": t_solid * 1e3,
                "ratio": t_np / t_solid,
            }
        )
    results["describe"] = describe_rows
    batch = [sio.read_points(f, "kitti") for f in sorted((data / "kitti00/velodyne").glob("*.bin"))] * 8
    cores = os.cpu_count() or 1
    solid.describe_batch(batch, cfg)  # start the workers once: they persist across calls
    # Fastest of alternating runs: a run that another process interrupts says nothing of scaling.
    t_one, t_all = float("inf"), float("inf")
    for _ in range(9):
        t0 = time.perf_counter()
        solid.describe_batch(batch, cfg, threads=1)
        t1 = time.perf_counter()
        solid.describe_batch(batch, cfg)
        t_one, t_all = min(t_one, t1 - t0), min(t_all, time.perf_counter() - t1)
    print(
        f"describe_batch of {len(batch)} KITTI frames (fastest of 9): {t_one / len(batch) * 1e3:.3f} ms/frame "
        f"on 1 thread, {t_all / len(batch) * 1e3:.3f} ms/frame on {cores} cores: {t_one / t_all:.2f}x"
    )
    results["describe_batch"] = {
        "frames": len(batch),
        "n_points": sum(len(p) for p in batch),
        "repeats": 9,
        "statistic": "fastest",
        "threads_one": 1,
        "threads_all": cores,
        "ms_per_frame_one": t_one / len(batch) * 1e3,
        "ms_per_frame_all": t_all / len(batch) * 1e3,
        "speedup": t_one / t_all,
    }
    one = np.array([[10.0, 1.0, -1.0]], dtype=np.float32)
    t_call = median_seconds(lambda: solid.describe(one, cfg), 20000)
    t_noop = median_seconds(lambda: one.sum(), 20000)
    print(f"Python call overhead (describe of 1 point): {t_call * 1e6:.2f} µs ({t_call / t_noop:.1f}x a numpy .sum() of it)")
    results["call_overhead"] = {
        "n_points": 1,
        "solid_median_us": t_call * 1e6,
        "numpy_sum_median_us": t_noop * 1e6,
        "ratio_to_numpy_sum": t_call / t_noop,
    }
    others = other_busy_cores(busy0, wall0, cpu0)
    results["other_processes_busy_cores"] = others
    if others is not None:
        print(f"other processes kept {others:.2f} of {os.cpu_count()} cores busy during the run")
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
        print(f"figures written to {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
