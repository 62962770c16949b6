"""The gate on the simulator's failure-mode worlds, through the shipped pipeline with true poses:
accepted loops, place-false and pose-false counts, loops more than 1 m / 5° off, recall, and the
registered candidates' disagreement with the poses (what the odometry check judges).

    PYTHONPATH=python python tools/gate_measure.py                      # the defaults
    PYTHONPATH=python python tools/gate_measure.py '{"odometry_check": false, "unique": false, "min_support": 0}'
    PYTHONPATH=python python tools/gate_measure.py '{}' presets          # corridors per preset
    PYTHONPATH=python python tools/gate_measure.py '{}' presets 1,2      # ... seeds 1 and 2 only
    PYTHONPATH=python python tools/gate_measure.py '{}' drift            # a drifting odometry
    PYTHONPATH=python python tools/gate_measure.py '{}' tests            # tests/test_gate.py's runs

The optional first argument is a JSON object of detector overrides (the names of DetectorConfig);
the second, ``presets``, runs the default look-alike world (``World.corridors()``'s modules) for
every preset at its own view and a 90° one, seeds 1–3 (or the comma-separated seeds of a third
argument), instead of the room and the three corridor runs; ``drift`` gives the detector
tests/test_gate.py's drifting odometry (0.01°/m of yaw, 1 % scale) instead of the true poses, on
the two-module world (frames 3 m apart, as that test) and the default one (4 m), and scores the
loops against the truth (``test_gate.drift_run``; the loops off it are listed: query frame, place
frame, metres and degrees off); ``tests`` runs tests/test_gate.py's scenarios (its corridor views,
the turning room, its drifting odometry on both worlds) with the overrides and prints what the
tests assert on.
docs/performance.md#loops-a-pose-graph-can-trust gives the figures.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from solid import sim
from solid.config import PipelineConfig
from solid.pipeline import LoopClosurePipeline

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import test_gate as T  # noqa: E402  (the tests' worlds, odometry and scoring)


def disagreement(res: Any, P: np.ndarray) -> tuple[list[float], list[float]]:
    """Metres by which each candidate that passed the gate's registration checks (whatever the
    checks against the poses said) lies off the true relative pose: (true places within 5 m, others)."""
    T = np.tile(np.eye(4), (len(P), 1, 1))
    T[:, :3, :] = P.reshape(len(P), 3, 4)
    true: list[float] = []
    false: list[float] = []
    for d in res.queries():
        for c in d.candidates:
            if not c.verified or not (c.accepted or c.rejection in ("disagrees with the odometry", "another candidate disagrees", "not supported by the previous steps", "a look-alike the odometry cannot rule out")):
                continue
            q, k = res.frame_of(d.query), res.frame_of(c.id)
            rel = np.linalg.inv(T[q]) @ T[k]
            off = float(np.linalg.norm(np.asarray(c.pose)[:3, 3] - rel[:3, 3]))
            (true if np.linalg.norm(rel[:3, 3]) <= 5.0 else false).append(off)
    return true, false


def quantiles(x: list[float]) -> str:
    if not x:
        return "none"
    q = np.quantile(np.asarray(x), [0.0, 0.5, 0.95, 1.0])
    return f"{len(x)}: min {q[0]:.2f} / median {q[1]:.2f} / p95 {q[2]:.2f} / max {q[3]:.2f} m"


def measure(name: str, world: sim.World, traj: sim.Trajectory, sensor: sim.Sensor, preset: str, detector: dict[str, Any]) -> None:
    seq = sim.simulate(world, sensor, traj)
    res = LoopClosurePipeline(seq, PipelineConfig.preset(preset, radius=5.0, detector=detector)).run()
    ev = res.evaluate()
    m = ev.metrics()
    em = np.nan_to_num(np.asarray(ev.scores.pose_error_m))
    ed = np.nan_to_num(np.asarray(ev.scores.pose_error_deg))
    off = int(np.sum(ev.accepted & ((em > 1.0) | (ed > 5.0))))
    true, false = disagreement(res, np.asarray(traj.poses))
    recall = "none (no true revisit)" if m["recall"] is None else f"{m['recall']:.3f}"
    print(
        f"{name}: {len(seq)} frames, {m['accepted']} accepted, {m['place_false_accepts']} place-false, "
        f"{m['pose_false_accepts']} pose-false, {off} off by > 1 m or 5°, recall {recall}; "
        f"registered candidates off the true pose, true places {quantiles(true)}; others {quantiles(false)}",
        flush=True,
    )


def measure_drift(name: str, world: sim.World, traj: sim.Trajectory, sensor: sim.Sensor, preset: str, detector: dict[str, Any], seed: int) -> None:
    """The detector on tests/test_gate.py's drifting odometry (``drift_run``); its loops scored
    against the truth (within 1 m and 5° of the true relative pose), recall over the queries with
    a true place within 5 m at least 50 frames back."""
    run = T.drift_run(world, traj, sensor, preset, seed, detector)
    print(
        f"{name}: {len(traj.poses)} frames, {run.loops} accepted, {len(run.wrong)} off the truth by > 1 m or 5°, "
        f"recall {len(run.found & run.revisits)}/{len(run.revisits)} = {run.recall():.3f}",
        flush=True,
    )
    if run.wrong:
        print(f"  off (query, place, m, °): {run.describe()}", flush=True)


def measure_tests(detector: dict[str, Any]) -> None:
    """tests/test_gate.py's runs with `detector`'s overrides merged into each: accepted loops,
    pose-false, recall (and for its drifting odometry the loops off the truth and the revisits found)."""
    def line(name: str, ev: Any) -> str:
        m = ev.metrics()
        return f"{name}: {int(np.sum(ev.accepted))} accepted, {m['pose_false_accepts']} pose-false, recall {m['recall']:.3f}"

    for preset, fov, seed, kind in T.VIEWS:
        world, walk = T.corridor_walk(seed, kind)
        seq = sim.simulate(world, sim.Sensor(preset, h_fov=fov), walk)
        ev = LoopClosurePipeline(seq, PipelineConfig.preset(preset, radius=5.0, detector=detector)).run().evaluate()
        print(line(f"corridors seed {seed} ({kind}), {preset} {fov or 'own'}°", ev), flush=True)
    for preset in ("avia", "os1-64"):
        room = sim.World.room(seed=1)
        walk = sim.Trajectory.turn_in_place(room, sweep=330.0, step=3.0, wobble=0.3, seed=1)
        cfg = PipelineConfig.preset(preset, radius=5.0, detector={"exclude_meters": 0.0, **detector})
        print(line(f"turning in place, {preset}", LoopClosurePipeline(sim.simulate(room, sim.Sensor(preset), walk), cfg).run().evaluate()), flush=True)
    world, walk = T.corridor_walk(3)
    measure_drift("drifting odometry, 2-module corridors seed 3, os1-64 with a 90° view", world, walk, sim.Sensor("os1-64", h_fov=90.0), "os1-64", detector, 3)
    for preset, fov, spacing, _ in T.FOUR_MODULE_DRIFT:
        world, walk = T.corridor_walk(1, "default", spacing=spacing, laps=1.2)
        name = f"drifting odometry, 4-module corridors seed 1 (frames {spacing:g} m apart, 1.2 laps), {preset} with a {fov:g}° view"
        measure_drift(name, world, walk, sim.Sensor(preset, h_fov=fov), preset, detector, 1)


def main() -> None:
    detector: dict[str, Any] = json.loads(sys.argv[1]) if len(sys.argv) > 1 else {}
    if sys.argv[2:3] == ["tests"]:
        measure_tests(detector)
        return
    if sys.argv[2:3] == ["drift"]:
        for modules, kind in ((2, "short"), (4, "default")):
            for preset, fov, seed in (("os1-64", 90.0, 3), ("vlp16", None, 2), ("hdl64", 90.0, 2), ("avia", None, 1), ("aeva", 90.0, 2), ("os1-64", None, 3)):
                world, walk = T.corridor_walk(seed, kind)
                view = "its own view" if fov is None else f"a {fov:g}° view"
                sensor = sim.Sensor(preset, h_fov=fov)
                measure_drift(f"drift, {modules}-module corridors seed {seed}, {preset} with {view}", world, walk, sensor, preset, detector, seed)
        return
    if sys.argv[2:3] == ["presets"]:
        seeds = [int(x) for x in sys.argv[3].split(",")] if len(sys.argv) > 3 else [1, 2, 3]
        for seed in seeds:
            world = sim.World.corridors(seed=seed)
            walk = sim.Trajectory.corridor_walk(world, laps=1.3)
            for preset in ("hdl64", "vlp16", "os1-64", "avia", "aeva"):
                for fov in (None, 90.0):
                    if fov is not None and preset == "avia":
                        continue  # the Avia's own view is 70°
                    view = "its own view" if fov is None else f"a {fov:g}° view"
                    measure(f"corridors seed {seed}, {preset} with {view}", world, walk, sim.Sensor(preset, h_fov=fov), preset, detector)
        return
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
