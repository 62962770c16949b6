"""Measures the figures behind the work budgets of registration and the detector (docs/performance.md#work-budgets).

    PYTHONPATH=python python tools/budget_measure.py
"""

from __future__ import annotations

import time, numpy as np, solid
from solid.datasets import open_dataset
cfg = solid.RegistrationConfig()
for name, path in (("kitti00", "/work/shared/data/kitti00"), ("hku1-avia", "/work/shared/data/hku1-avia")):
    ds = open_dataset(path)
    n = [len(solid.PreparedCloud(ds[i], cfg)) for i in range(0, min(len(ds), 400), 20)]
    a, b = ds[0], ds[min(len(ds)-1, 5)]
    qa, qb = solid.PreparedCloud(a, cfg), solid.PreparedCloud(b, cfg)
    t0 = time.perf_counter(); solid.register(qa, qb, yaws=[float(y) for y in range(0, 360, 5)]); t72 = time.perf_counter() - t0
    print(f"{name}: fine points per scan median {int(np.median(n))}, max {max(n)}; 72 yaws: {t72:.2f} s ({t72/72*1e3:.1f} ms per yaw)")
rng = np.random.default_rng(0)
big = (rng.random((5_000_000, 3)) * 400 - 200).astype(np.float32)
c2 = solid.RegistrationConfig(max_range=400.0)
t0 = time.perf_counter(); p = solid.PreparedCloud(big, c2); tp = time.perf_counter() - t0
t0 = time.perf_counter(); solid.register(p, p, config=c2); tr = time.perf_counter() - t0
print(f"5M random points in a 400 m cube: prepared to {len(p)} fine points in {tp:.1f} s; registered with itself in {tr:.1f} s")
