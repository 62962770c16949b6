"""Registration speed: solid against small-gicp on the same hku1-avia pairs, in the same run.

    make bench-reg        # or: .venv/bin/python benches/registration.py

Pairs: every query of hku1-avia (SPEC §5, exclude 50) with its nearest earlier keyframe within
3 m (the true revisits), plus its top-5 SOLiD candidates (what a verifying detector registers).
Both libraries run single-threaded with the same two levels (1 m voxels / 3 m correspondences,
then 0.5 m / 1 m), from the identity, on clouds preprocessed once per keyframe. Times are CPU
time (``time.process_time``: the machine may be shared) per candidate; wall-clock medians are
printed beside them. small-gicp is a benchmark-only dependency (requirements-dev.txt).

Measured (release wheel, shared 2-core machine under load, CPU ms median): true revisits solid
5.96, small-gicp 6.85, solid with four yaw hypotheses 9.20 (ratio of totals 1.58x); top-5
candidates 5.65 / 9.30 / 9.98 (1.64x); preprocessing a cloud 2.43 / 2.29.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

import solid
from solid.io import read_points

DATA = Path(__file__).resolve().parent.parent.parent / "shared" / "data" / "hku1-avia"


def timed(fn: Callable[[], Any]) -> tuple[Any, float, float]:
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.process_time() - c, time.perf_counter() - w


def main() -> int:
    try:
        import small_gicp
    except ImportError:
        print("small_gicp is not installed (pip install small_gicp): nothing to compare with", file=sys.stderr)
        return 1
    if not DATA.is_dir():
        print(f"hku1-avia not found at {DATA}", file=sys.stderr)
        return 1
    p34 = np.loadtxt(DATA / "odom_poses.txt").reshape(-1, 3, 4)
    n = len(p34)
    pos = p34[:, :, 3]
    scans = [np.ascontiguousarray(read_points(DATA / "Scans" / f"{i:06d}.pcd")[:, :3], dtype=np.float64) for i in range(n)]
    cfg = solid.RegistrationConfig()
    dcfg = solid.SolidConfig.preset("avia")
    desc = solid.describe_batch(scans, dcfg, threads=1)

    ours: list[solid.PreparedCloud] = []
    theirs: list[tuple[Any, Any, Any, Any]] = []
    prep = {"solid": [0.0, 0.0], "small_gicp": [0.0, 0.0]}
    for s in scans:
        p, cpu, wall = timed(lambda: solid.PreparedCloud(s, cfg))
        ours.append(p)
        prep["solid"][0] += cpu
        prep["solid"][1] += wall

        def sg_prep() -> tuple[Any, Any, Any, Any]:
            coarse, ctree = small_gicp.preprocess_points(s, downsampling_resolution=cfg.coarse_voxel_size, num_neighbors=cfg.neighbors, num_threads=1)
            fine, ftree = small_gicp.preprocess_points(s, downsampling_resolution=cfg.voxel_size, num_neighbors=cfg.neighbors, num_threads=1)
            return coarse, ctree, fine, ftree

        t, cpu, wall = timed(sg_prep)
        theirs.append(t)
        prep["small_gicp"][0] += cpu
        prep["small_gicp"][1] += wall

    R = np.stack([d.r for d in desc]).astype(np.float64)
    R /= np.maximum(np.linalg.norm(R, axis=1, keepdims=True), 1e-12)
    true_pairs: list[tuple[int, int]] = []
    cand_pairs: list[tuple[int, int]] = []
    for q in range(51, n):
        d = np.linalg.norm(pos[: q - 50] - pos[q], axis=1)
        if d.min() <= 3.0:
            true_pairs.append((q, int(np.argmin(d))))
        for c in np.argsort(1.0 - R[: q - 50] @ R[q], kind="stable")[:5]:
            cand_pairs.append((q, int(c)))

    def sg_align(q: int, c: int) -> Any:
        tq, tc = theirs[q], theirs[c]
        r = small_gicp.align(tq[0], tc[0], tq[1], init_T_target_source=np.eye(4), max_correspondence_distance=cfg.coarse_max_correspondence, num_threads=1)
        return small_gicp.align(tq[2], tc[2], tq[3], init_T_target_source=r.T_target_source, max_correspondence_distance=cfg.max_correspondence, num_threads=1)

    print(f"hku1-avia, {n} keyframes ({np.mean([len(p) for p in ours]):.0f} fine / {np.mean([len(p.coarse_points) for p in ours]):.0f} coarse points per cloud), single-threaded, CPU ms (wall ms in brackets)")
    for who, (cpu, wall) in prep.items():
        print(f"  preprocess one cloud (both levels)  {who:<11} {1e3 * cpu / n:7.2f} ({1e3 * wall / n:.2f})")
    for name, pairs in (("true revisits (<= 3 m)", true_pairs), ("top-5 SOLiD candidates", cand_pairs)):
        rows: dict[str, list[tuple[float, float]]] = {"solid": [], "small_gicp": [], "solid, yaw hypotheses": []}
        for q, c in pairs:
            _, cs, ws = timed(lambda: solid.register(ours[q], ours[c], config=cfg))
            rows["solid"].append((cs, ws))
            _, cs, ws = timed(lambda: sg_align(q, c))
            rows["small_gicp"].append((cs, ws))
            _, cs, ws = timed(lambda: solid.register(ours[q], ours[c], yaws=[*solid.hypothesis_yaws(desc[q], desc[c], n=3), -25.0, 25.0], config=cfg))
            rows["solid, yaw hypotheses"].append((cs, ws))
        print(f" {name}: {len(pairs)} pairs, register one candidate (prepared clouds)")
        med = {k: np.median(np.array(v), axis=0) for k, v in rows.items()}
        for k, (cpu, wall) in med.items():
            tot = np.sum(np.array(rows[k]), axis=0)
            print(f"  {k:<24} median {1e3 * cpu:6.2f} ({1e3 * wall:.2f})   mean {1e3 * tot[0] / len(pairs):6.2f} ({1e3 * tot[1] / len(pairs):.2f})")
        ratio = np.sum(np.array(rows["small_gicp"])[:, 0]) / np.sum(np.array(rows["solid"])[:, 0])
        print(f"  ratio small_gicp / solid (total CPU time, one registration each): {ratio:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
