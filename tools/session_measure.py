"""Loops into a map from another session (issue 41), on the simulator's look-alike corridors: a map
built from one walk around the ring, a second walk (starting elsewhere, 90° apart) detected against
it with its poses in its own frame (or without poses, or with a drifting odometry), and a session in
another world that never enters the map. Every loop into the map is scored against the truth (more
than 1 m or 5° off the true relative pose: wrong); recall counts the second session's queries that
got a right loop into the map over those with a map place within 5 m.

    PYTHONPATH=python python tools/session_measure.py                   # seeds 1-3, three views
    PYTHONPATH=python python tools/session_measure.py '{"placement_loops": 3}' 1 hdl64
    PYTHONPATH=python python tools/session_measure.py '{}' 1,2 avia,os1-64:90 nopose,drift5

Arguments: detector overrides (JSON), seeds, views (preset[:fov]), cases (poses, nopose, drift1,
drift2, drift3, drift5, never; default: poses, nopose, never), and the world: city (the default city with
its repeated blocks: a lap around a block and a route that drives half of it, then streets the lap
never saw) or the blocks of a corridor grid (1 or 2; its ring rotated by 90° about the block's
centre is a copy of itself, so a second walk's placement is ambiguous there).
"""

from __future__ import annotations

import json
import sys
import time
from typing import Any

import numpy as np

import solid
from solid import sim
from solid.config import PipelineConfig


def h(p: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :] = np.asarray(p).reshape(3, 4)
    return out


def run(world: sim.World, view: str, detector: dict[str, Any], case: str, seed: int, spacing: float) -> str:
    preset, _, fov = view.partition(":")
    sensor = sim.Sensor(preset, h_fov=float(fov) if fov else None)
    cfg = PipelineConfig.preset(preset, radius=5.0, detector=detector)
    if world.layout == "city":
        first, second = sim.session_routes(world, spacing=spacing)
    else:
        first, second = sim.corridor_sessions(world, laps=1.0, spacing=spacing)
    a = sim.Session.of(first)
    mapper = solid.LoopDetector(cfg.descriptor, detector=cfg.detector)
    mapper.detect_many(sim.simulate(world, sensor, first).scans, poses=a.trajectory.poses)
    if case == "never" and world.layout == "city":
        # Streets north-east of the centre, which the map's lap (south-west) never saw.
        p = world.block_pitch
        second = sim.Trajectory.from_waypoints(world, [(0.0, p), (2 * p, p), (2 * p, 2 * p)], spacing=spacing)
        scans = sim.simulate(world, sensor, second).scans
    elif case == "never":
        # Another building: corridors of another module and pitch.
        other = sim.World.corridors(seed=seed + 10, modules=3, blocks=world.blocks)
        second = sim.Trajectory.corridor_walk(other, laps=1.0, spacing=spacing)
        scans = sim.simulate(other, sensor, second).scans
    else:
        scans = sim.simulate(world, sensor, second).scans
    b = sim.Session.of(second)
    poses: Any = b.trajectory.poses
    if case.startswith("drift"):
        pct = float(case[5:]) / 100.0
        odo = second.odometry(yaw_bias_deg_per_m=pct, scale_error=pct, translation_noise=0.01, rotation_noise_deg=0.02, seed=seed)
        poses = sim.Session.of(odo, b.frame).trajectory.poses
    elif case == "nopose":
        poses = None
    det = solid.LoopDetector.from_database(mapper.database, detector=cfg.detector)
    t0 = time.process_time()
    dets = det.detect_many(scans, poses=poses)
    cpu = time.process_time() - t0
    start = det.session_start
    A = [h(p) for p in first.poses]
    B = [h(p) for p in second.poses]
    wrong = right = 0
    found: set[int] = set()
    for d in dets:
        lp = d.loop
        if lp is None or lp.candidate >= start:
            continue
        q = d.query - start
        truth = np.linalg.inv(B[q]) @ A[lp.candidate]
        if case == "never":
            wrong += 1
            continue
        e = np.linalg.inv(truth) @ np.asarray(lp.pose)
        deg = np.degrees(np.arccos(np.clip((np.trace(e[:3, :3]) - 1) / 2, -1, 1)))
        if np.linalg.norm(e[:3, 3]) > 1.0 or deg > 5.0:
            wrong += 1
        else:
            right += 1
            found.add(q)
    XA = np.array([m[:3, 3] for m in A])
    revisits = set() if case == "never" else {q for q in range(len(B)) if (np.linalg.norm(XA - B[q][:3, 3], axis=1) <= 5.0).any()}
    anchor = getattr(det, "map_anchor", None)
    placed = "no anchor"
    if anchor is not None:
        truth_anchor = h(b.anchor(a)) if case != "never" else None
        err = ""
        if truth_anchor is not None:
            e = np.linalg.inv(truth_anchor) @ anchor.transform
            err = f", {np.linalg.norm(e[:3, 3]):.2f} m off at the session origin"
        placed = f"anchor at query {anchor.first_query - start} from {anchor.loops} loops over {anchor.metres:.0f} m{err}"
    rec = len(found & revisits) / max(1, len(revisits))
    return (
        f"{case}: {right + wrong} loops into the map, {wrong} wrong, recall {len(found & revisits)}/{len(revisits)} = {rec:.3f}, "
        f"{placed} ({cpu:.0f} s CPU)"
    )


def main() -> None:
    detector: dict[str, Any] = json.loads(sys.argv[1]) if len(sys.argv) > 1 else {}
    seeds = [int(s) for s in sys.argv[2].split(",")] if len(sys.argv) > 2 else [1, 2, 3]
    views = sys.argv[3].split(",") if len(sys.argv) > 3 else ["hdl64", "avia", "os1-64:90"]
    cases = sys.argv[4].split(",") if len(sys.argv) > 4 else ["poses", "nopose", "never"]
    kind = sys.argv[5] if len(sys.argv) > 5 else "city"
    for seed in seeds:
        world = sim.World(seed=seed) if kind == "city" else sim.World.corridors(seed=seed, modules=2, blocks=int(kind))
        for view in views:
            for case in cases:
                print(f"seed {seed}, {view}, {run(world, view, detector, case, seed, 3.0)}", flush=True)


if __name__ == "__main__":
    main()
