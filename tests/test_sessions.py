"""Loops into a map from another session (issue 41): the session is placed in the map by loops
that agree with each other, not by one odometry; a session that never enters the map gets no loop
into it and no anchor (docs/spec.md §8, placement). The simulator gives the exact truth: the second
session's poses are in its own frame, the map's in the first's."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import run

import solid
from solid import sim
from solid.config import PipelineConfig

SPACING = 5.0


def h(p: Any) -> np.ndarray:
    out = np.eye(4)
    out[:3, :] = np.asarray(p).reshape(3, 4)
    return out


@pytest.fixture(scope="module")
def city() -> tuple[sim.World, sim.Trajectory, Any, PipelineConfig, sim.Sensor]:
    """The default city's lap around a block, built into a map with its poses."""
    world = sim.World(seed=1)
    lap, _ = sim.session_routes(world, spacing=SPACING)
    cfg = PipelineConfig.preset("vlp16", radius=5.0)
    sensor = sim.Sensor("vlp16")
    mapper = solid.LoopDetector(cfg.descriptor, detector=cfg.detector)
    mapper.detect_many(sim.simulate(world, sensor, lap).scans, poses=sim.Session.of(lap).trajectory.poses)
    return world, lap, mapper.database, cfg, sensor


def test_a_session_in_its_own_frame_is_placed_in_the_map_by_consistent_loops(city: Any) -> None:
    world, lap, db, cfg, sensor = city
    _, second = sim.session_routes(world, spacing=SPACING)
    second = second[:26]  # from the west along the lap's southern street, then up its eastern one
    mine = sim.Session.of(second)
    det = solid.LoopDetector.from_database(db, detector=cfg.detector)
    assert det.map_anchor is None
    dets = det.detect_many(sim.simulate(world, sensor, second).scans, poses=mine.trajectory.poses)
    start = det.session_start
    loops = [d.loop for d in dets if d.loop is not None and d.loop.candidate < start]
    assert len(loops) >= 5
    for lp in loops:
        truth = np.linalg.inv(h(second.poses[lp.query - start])) @ h(lap.poses[lp.candidate])
        assert np.linalg.norm(np.asarray(lp.pose)[:3, 3] - truth[:3, 3]) < 1.0
    # The loops before the placement are dropped, with the rejection saying why.
    held = [c for d in dets for c in d.candidates if c.rejection == "the session is not placed in the map yet"]
    assert held
    a = det.map_anchor
    assert a is not None and a.loops >= cfg.detector.placement_loops and a.metres >= cfg.detector.placement_m
    assert start <= a.first_query <= a.last_query < start + len(second)
    truth = h(mine.anchor(sim.Session.of(lap)))
    assert np.allclose(a.transform, truth, atol=0.3)
    assert a.covariance is not None and a.covariance.shape == (6, 6)
    # Off: the same loops need only the support of the previous steps, and no anchor is made.
    off = solid.LoopDetector.from_database(db, detector=cfg.detector.replace(placement_loops=0))
    off.detect_many(sim.simulate(world, sensor, second[:12]).scans, poses=mine.trajectory[:12].poses)
    assert off.map_anchor is None


def test_a_session_that_never_enters_the_map_gets_no_loop_into_it(city: Any) -> None:
    world, _, db, cfg, sensor = city
    p = world.block_pitch
    # Streets north-east of the centre; the map's lap went round a block south-west of it.
    away = sim.Trajectory.from_waypoints(world, [(0.0, p), (1.5 * p, p)], spacing=SPACING)
    det = solid.LoopDetector.from_database(db, detector=cfg.detector)
    dets = det.detect_many(sim.simulate(world, sensor, away).scans, poses=sim.Session.of(away).trajectory.poses)
    assert not [d for d in dets if d.loop is not None and d.loop.candidate < det.session_start]
    assert det.map_anchor is None


def test_detect_with_a_map_reports_where_the_session_is_placed(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """`solid detect --map` prints the placement and writes it to summary.json (T_map_world within
    0.3 m of the simulator's anchor.txt)."""
    world = sim.World(seed=1)
    lap, second = sim.session_routes(world, spacing=SPACING)
    s0, s1 = sim.write_sessions(tmp_path / "sim", world, sim.Sensor("vlp16"), [lap, second[:26]], own_frames=True)
    db = str(tmp_path / "map.soliddb")
    assert run(capsys, "map", "build", str(s0), "--poses", str(s0 / "poses.txt"), "-o", db, "--preset", "vlp16", "-q")[0] == 0
    out_dir = tmp_path / "out"
    code, out, _ = run(capsys, "detect", str(s1), "--poses", str(s1 / "poses.txt"), "--map", db, "--preset", "vlp16", "-q", "-o", str(out_dir))
    assert code == 0 and "placed in the map from frame" in out
    a = json.loads((out_dir / "summary.json").read_text())["map_anchor"]
    truth = np.loadtxt(s1 / "anchor.txt").reshape(3, 4)
    assert np.allclose(np.asarray(a["transform"])[:3], truth, atol=0.3)
    assert a["loops"] >= 4 and a["metres"] >= 30.0 and 0 <= a["first_frame"] <= a["last_frame"] < 26
