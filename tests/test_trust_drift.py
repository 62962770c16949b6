"""Loops within one session that do not lean on the odometry (issue 41): an odometry drifting
beyond the detector's bounds, or breaking down for a stretch, keeps the loops its short stretches
vouch for; without poses, a loop whose place has a look-alike elsewhere is not accepted.

The world is docs/slam.md#drift's (a loop through look-alike blocks, 1.2 laps, frames 6 m apart,
VLP-16); every loop is scored against the simulator's truth (1 m, 5°)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest

from solid import sim, slam
from solid.config import PipelineConfig
from solid.pipeline import LoopClosurePipeline

F64 = npt.NDArray[np.float64]


@pytest.fixture(scope="module")
def loop_world() -> tuple[sim.Sequence, sim.Trajectory]:
    world = sim.World(seed=0, repetition=0.9)
    traj = sim.Trajectory.loop(world, laps=1.2, spacing=6.0)
    return sim.simulate(world, sim.Sensor("vlp16"), traj), traj


def scored(seq: sim.Sequence, odometry: sim.Trajectory | None, truth: F64) -> tuple[int, set[int]]:
    """The pipeline given `odometry` (None: no poses): (pose-false loops, queries with a right loop)."""
    given = dataclasses.replace(seq, trajectory=odometry) if odometry is not None else _without_poses(seq)
    res = LoopClosurePipeline(given, PipelineConfig.preset("vlp16")).run()
    wrong, right = 0, set[int]()
    for lp in res.loops():
        q, c = res.frame_of(lp.query), res.frame_of(lp.candidate)
        assert q is not None and c is not None  # every place is a frame of this run
        d = np.linalg.inv(np.linalg.inv(truth[q]) @ truth[c]) @ np.asarray(lp.pose)
        deg = np.degrees(np.arccos(np.clip((np.trace(d[:3, :3]) - 1) / 2, -1, 1)))
        if np.linalg.norm(d[:3, 3]) > 1.0 or deg > 5.0:
            wrong += 1
        else:
            right.add(q)
    return wrong, right


class _without_poses:
    def __init__(self, seq: sim.Sequence) -> None:
        self.seq, self.poses, self.timestamps = seq, None, seq.times

    def __len__(self) -> int:
        return len(self.seq.scans)

    def __getitem__(self, i: int) -> Any:
        return self.seq.scans[i]


def test_an_odometry_drifting_beyond_the_bounds_or_breaking_down_keeps_its_loops(loop_world: tuple[sim.Sequence, sim.Trajectory]) -> None:
    """1 % is within the detector's bounds; at 5 % (40° of yaw after a lap: beyond the 30° ceiling)
    the odometry check alone turned every revisit down (0 loops before issue 41's item 1); a
    breakdown on the first lap (three keyframes jumping 4 m each, or 12 m of climb over ten) puts
    every revisit beyond the bounds too (0 loops before), yet the stretches on both sides of each
    loop still hold. (A breakdown beyond five times the drift bounds, tens of metres after a lap of
    300 m, costs the loops across it: a look-alike stretch is as likely, VOUCHED_DRIFT.)"""
    seq, traj = loop_world
    truth = slam.as4(traj.poses)
    wrong, base = scored(seq, traj.drifting(1, seed=0), truth)
    assert wrong == 0 and len(base) >= 8, (wrong, sorted(base))
    for name, odo in (
        ("5 %", traj.drifting(5, seed=0)),
        ("1 %, jumps", traj.drifting(1, seed=0, breakdown=(20, 23), breakdown_jump_m=4.0)),
        ("1 %, climb", traj.drifting(1, seed=0, breakdown=(20, 31), breakdown_climb_m=12.0)),
    ):
        wrong, right = scored(seq, odo, truth)
        assert wrong == 0, name
        # At most the first loop of the revisit is lost (it has no neighbour yet).
        assert len(right) >= len(base) - 1, (name, sorted(right), sorted(base))
