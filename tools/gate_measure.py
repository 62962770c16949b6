"""The gate on the simulator's failure-mode worlds, through the shipped pipeline with true poses:
accepted loops, place-false and pose-false counts, loops more than 1 m / 5° off, recall.

    PYTHONPATH=python python tools/gate_measure.py                      # the defaults
    PYTHONPATH=python python tools/gate_measure.py '{"odometry_check": false, "unique": false, "min_support": 0}'

The optional argument is a JSON object of detector overrides (the names of DetectorConfig);
docs/performance.md#loops-a-pose-graph-can-trust gives the figures.
"""

from __future__ import annotations

import json
import sys
from typing import Any

import numpy as np

from solid import sim
from solid.config import PipelineConfig
from solid.pipeline import LoopClosurePipeline


def measure(name: str, world: sim.World, traj: sim.Trajectory, sensor: sim.Sensor, preset: str, detector: dict[str, Any]) -> None:
    seq = sim.simulate(world, sensor, traj)
    ev = LoopClosurePipeline(seq, PipelineConfig.preset(preset, radius=5.0, detector=detector)).run().evaluate()
    m = ev.metrics()
    em = np.nan_to_num(np.asarray(ev.scores.pose_error_m))
    ed = np.nan_to_num(np.asarray(ev.scores.pose_error_deg))
    off = int(np.sum(ev.accepted & ((em > 1.0) | (ed > 5.0))))
    print(
        f"{name}: {len(seq)} frames, {m['accepted']} accepted, {m['place_false_accepts']} place-false, "
        f"{m['pose_false_accepts']} pose-false, {off} off by > 1 m or 5°, recall {m['recall']:.3f}",
        flush=True,
    )


def main() -> None:
    detector: dict[str, Any] = json.loads(sys.argv[1]) if len(sys.argv) > 1 else {}
    room = sim.World.room(seed=1)
    turn = sim.Trajectory.turn_in_place(room, sweep=330.0, step=2.0, wobble=0.3, seed=1)
    for preset in ("avia", "os1-64"):
        measure(f"room, {preset} turning in place", room, turn, sim.Sensor(preset), preset, detector)
    corridors = sim.World.corridors(seed=3, modules=3)
    walk = sim.Trajectory.corridor_walk(corridors, laps=1.3)
    for preset, fov in (("avia", None), ("os1-64", None), ("os1-64", 90.0)):
        sensor = sim.Sensor(preset, h_fov=fov)
        view = "its own view" if fov is None else f"a {fov:g}° view"
        measure(f"corridors, {preset} with {view}", corridors, walk, sensor, preset, detector)


if __name__ == "__main__":
    main()
