"""Loops into a map from another session (issue 41): the session is placed in the map by loops
that agree with each other, not by one odometry; a session that never enters the map gets no loop
into it and no anchor (docs/spec.md §8, placement). The simulator gives the exact truth: the second
session's poses are in its own frame, the map's in the first's."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

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
    away = sim.Trajectory.from_waypoints(world, [(0.0, p), (2 * p, p)], spacing=SPACING)
    det = solid.LoopDetector.from_database(db, detector=cfg.detector)
    dets = det.detect_many(sim.simulate(world, sensor, away).scans, poses=sim.Session.of(away).trajectory.poses)
    assert not [d for d in dets if d.loop is not None and d.loop.candidate < det.session_start]
    assert det.map_anchor is None
