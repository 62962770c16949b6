"""Measure the loop detector's threshold per sensor preset (the defaults in config.rs).

Usage: python tools/thresholds.py [--shared ../shared]

For every preset it runs the shipped pipeline (solid.pipeline.LoopClosurePipeline with the
preset's descriptor and detector, exclusion 50 frames) on the sequences that exist for that
sensor, scores it (docs/spec.md §5, radius 5 m) and prints each sequence's F1-max threshold. The chosen
threshold is the one that maximises the mean F1 over the preset's sequences, with real recordings
weighing as much as all simulated ones together (candidate thresholds: every observed top-1
score); the table shows the F1 and precision it gives on each.

Sequences: the simulator's looping drive (world seeds 0 and 1, 1.6 laps, frames 2 m apart) with
the sensor's full field of view and clipped to 90° ahead, for the five simulated sensors; for
`avia`, also the real Livox Avia walk hku1-avia (odometry poses). hdl32 has no sequence (no
simulated HDL-32E, only a single NCLT scan): it gets the median of the spinning sensors'
thresholds (hdl64, vlp16, os1-64).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

import solid
from solid import io as sio
from solid import sim
from solid.config import PipelineConfig
from solid.pipeline import LoopClosurePipeline


def evaluations(preset: str, shared: Path | None) -> list[tuple[str, object]]:
    out = []
    cfg = PipelineConfig.preset(preset, detector={"threshold": 1.0})
    if preset in sim.SENSORS:
        for seed in (0, 1):
            world = sim.World(seed=seed)
            traj = sim.Trajectory.loop(world, laps=1.6, spacing=2.0)
            for fov in (None, 90.0):
                seq = sim.simulate(world, sim.Sensor(preset, h_fov=fov), traj)
                res = LoopClosurePipeline(seq, cfg).run()
                out.append((f"sim seed {seed} {'full' if fov is None else '90°'}", res.evaluate(radius=5.0)))
    if preset == "avia" and shared is not None and (shared / "data" / "hku1-avia").is_dir():
        real = sio.Dataset(shared / "data" / "hku1-avia", poses="odom_poses.txt")
        res = LoopClosurePipeline(real, cfg).run()
        out.append(("hku1-avia (real)", res.evaluate(radius=5.0)))
    return out


def f1_at(ev: object, thr: float) -> tuple[float, float]:
    acc, tp, prec, rec = ev.scores.at_threshold(thr)  # type: ignore[attr-defined]
    f1 = 0.0 if acc == 0 or rec == 0 else 2 * prec * rec / (prec + rec)
    return f1, (prec if acc else float("nan"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shared", type=Path, default=Path(os.environ.get("SOLID_SHARED", "../shared")))
    ap.add_argument("--presets", nargs="*", default=None, help="only these presets")
    args = ap.parse_args()
    chosen: dict[str, float] = {}
    for preset in args.presets or solid.presets():
        evs = evaluations(preset, args.shared)
        if not evs:
            continue
        cands = np.unique(np.concatenate([e.score[np.isfinite(e.score)] for _, e in evs]))  # type: ignore[attr-defined]
        real = [e for n, e in evs if "real" in n]
        simulated = [e for n, e in evs if "real" not in n]

        def mean_f1_at(t: float) -> float:
            groups = [g for g in (simulated, real) if g]
            return float(np.mean([np.mean([f1_at(e, t)[0] for e in g]) for g in groups]))

        mean_f1 = [mean_f1_at(t) for t in cands]
        best = float(cands[int(np.argmax(mean_f1))])
        chosen[preset] = best
        print(f"{preset}: chosen threshold {best:.4f} (mean F1 {max(mean_f1):.3f})")
        for name, e in evs:
            f1m, thr = e.f1_max()  # type: ignore[attr-defined]
            f1, prec = f1_at(e, best)
            print(f"  {name:22} F1max {f1m:.3f} at {thr:.4f}; at the chosen threshold F1 {f1:.3f}, precision {prec:.3f}")
    spinning = [chosen[p] for p in ("hdl64", "vlp16", "os1-64") if p in chosen]
    if spinning:
        print(f"hdl32: no sequence; median of hdl64, vlp16, os1-64: {float(np.median(spinning)):.4f}")


if __name__ == "__main__":
    main()
