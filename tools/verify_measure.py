"""Measure the verifying loop detector: accuracy on the simulator and hku1, speed of a step.

Usage: python tools/verify_measure.py [--shared ../shared] [--only sim|hku|speed] [--sensors avia,vlp16]

- sim: for every simulated sensor, full view and 90° ahead, the simulator's looping drive (world 0,
  1.6 laps, frames 2 m apart, exclusion 25) through the shipped pipeline; prints the verified
  loops, their precision, and the heading error of the accepted true loops against the exact
  poses (the registration's yaw; A-SOLiD's alone for comparison) and their pose error.
- hku: hku1-avia at 3 m and 5 m (exclusion 50): Recall@1, F1 max, the operating point and the pose
  errors, with verification and without.
- speed: a full detector step (describe, prepare the cloud, search, verify 5 candidates) on hku1,
  single-threaded and with one thread per core, as wall time per scan (the CPU's load shows), and
  the descriptor-only step for comparison.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

import solid
from solid import sim
from solid.config import PipelineConfig
from solid.pipeline import LoopClosurePipeline


def sim_table(sensors: list[str] | None = None) -> None:
    world = sim.World(seed=0)
    traj = sim.Trajectory.loop(world, laps=1.6, spacing=2.0)
    print("sensor  view  accepted false  heading err (verified / A-SOLiD) mean  pose err median")
    for name in sensors or sim.SENSORS:
        for fov in (None, 90.0):
            seq = sim.simulate(world, sim.Sensor(name, h_fov=fov), traj)
            cfg = PipelineConfig.preset(name, detector={"exclude_frames": 25})
            ev = LoopClosurePipeline(seq, cfg).run().evaluate(radius=5.0)
            m = ev.metrics()
            ok = ev.accepted & ev.correct
            truth = np.asarray(ev.scores.true_heading_deg)
            err = np.abs((ev.heading_deg[ok] - truth[ok] + 180.0) % 360.0 - 180.0)
            # A-SOLiD's heading of the same pairs, for comparison.
            descs = solid.describe_batch(seq.scans, cfg.descriptor)
            a = [abs((solid.heading(descs[int(q)], descs[int(c)]) - t + 180.0) % 360.0 - 180.0) for q, c, t in zip(ev.query[ok], ev.ids[ok, 0], truth[ok])]
            view = "full" if fov is None else "90°"
            print(
                f"{name:7} {view:5} {m['accepted']:8d} {m['false_accepts']:5d}  "
                f"{err.mean() if err.size else float('nan'):8.3f}° / {np.mean(a) if a else float('nan'):6.2f}°"
                f"           {100 * (m.get('pose_error_m_median') or float('nan')):6.2f} cm"
            )


def hku_table(shared: Path) -> None:
    ds = solid.datasets.open_dataset(shared / "data" / "hku1-avia", poses="odom_poses.txt")
    for verify in (True, False):
        for radius in (3.0, 5.0):
            cfg = PipelineConfig.preset("avia", radius=radius, detector={"verify": verify})
            m = LoopClosurePipeline(ds, cfg).run().evaluate().metrics()
            keys = ("recall_at_1", "f1_max", "accepted", "false_accepts", "precision", "pose_error_m_median", "pose_error_deg_median", "pose_error_m_max_all_accepted")
            print(f"verify={verify} radius {radius:g}: " + ", ".join(f"{k} {m.get(k)}" for k in keys))


def speed(shared: Path) -> None:
    ds = solid.datasets.open_dataset(shared / "data" / "hku1-avia")
    scans = [ds[i] for i in range(len(ds))]
    for threads in (1, 0):
        cfg = PipelineConfig.preset("avia", detector={"verify_threads": threads})
        det = solid.LoopDetector(cfg.descriptor, detector=cfg.detector)
        t0, c0 = time.perf_counter(), time.process_time()
        for p in scans:
            det.detect(p)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        label = "1 thread" if threads == 1 else f"{os.cpu_count()} threads"
        print(f"detector step with verification, {label}: {1e3 * wall / len(scans):.1f} ms wall ({len(scans) / wall:.1f} Hz), {1e3 * cpu / len(scans):.1f} ms CPU per scan")
    det = solid.LoopDetector(PipelineConfig.preset("avia").descriptor, verify=False)
    t0 = time.perf_counter()
    for p in scans:
        det.detect(p)
    wall = time.perf_counter() - t0
    print(f"detector step without verification (describe, search, heading): {1e3 * wall / len(scans):.2f} ms wall ({len(scans) / wall:.0f} Hz)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shared", type=Path, default=Path(os.environ.get("SOLID_SHARED", "../shared")))
    ap.add_argument("--only", choices=["sim", "hku", "speed"])
    ap.add_argument("--sensors", type=lambda v: v.split(","), default=None, help="simulated sensors (default: every one; about 3 minutes each)")
    args = ap.parse_args()
    if args.only in (None, "sim"):
        sim_table(args.sensors)
    if args.only in (None, "hku"):
        hku_table(args.shared)
    if args.only in (None, "speed"):
        speed(args.shared)


if __name__ == "__main__":
    main()
