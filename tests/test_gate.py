"""A gate that holds (issue 26): on the simulator's look-alike corridors and in a small room
where the sensor turns in place, every loop the shipped pipeline accepts carries a pose a pose
graph can trust, and most true revisits are still found.

The pipeline takes one set of poses, used both by the detector (its odometry check and the
support of the previous steps) and by the scoring: the runs with true poses score with them;
the run with a drifting odometry scores its loops against the truth here.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
import pytest

from solid import sim
from solid.config import PipelineConfig
from solid.pipeline import LoopClosurePipeline

F64 = npt.NDArray[np.float64]

#: The issue's pose tolerance: a loop more than this far from the true relative pose is wrong.
TOL_M, TOL_DEG = 1.0, 5.0

#: Every preset the simulator models, at 360° where the sensor has it, and as a 90° view
#: (the Avia's own window is 70°); the seeds vary the corridors' modules. The last field is the
#: world: two modules per corridor (a 384 m lap) or the default world (four, a 744 m lap, where
#: the odometry's drift bounds are widest when the revisit comes).
VIEWS = [
    ("hdl64", None, 1, "short"),
    ("vlp16", None, 2, "default"),
    ("os1-64", None, 3, "default"),
    ("hdl64", 90.0, 2, "short"),
    ("vlp16", 90.0, 3, "default"),
    ("os1-64", 90.0, 1, "default"),
    ("avia", None, 1, "short"),
    ("aeva", 90.0, 2, "short"),
]


def corridor_walk(seed: int, world: str = "short") -> tuple[sim.World, sim.Trajectory]:
    """1.3 laps through look-alike corridors, a frame every 3 m ("short": two copies of one module
    per corridor) or every 4 m (the default world, four copies)."""
    if world == "short":
        w = sim.World.corridors(seed=seed, modules=2)
        return w, sim.Trajectory.corridor_walk(w, laps=1.3, spacing=3.0)
    w = sim.World.corridors(seed=seed)
    return w, sim.Trajectory.corridor_walk(w, laps=1.3, spacing=4.0)


def wrong_poses(ev: Any) -> int:
    """Accepted loops whose pose is off the true relative pose by more than the tolerance,
    wherever their candidate lies."""
    em = np.nan_to_num(np.asarray(ev.scores.pose_error_m))
    ed = np.nan_to_num(np.asarray(ev.scores.pose_error_deg))
    return int(np.sum(ev.accepted & ((em > TOL_M) | (ed > TOL_DEG))))


@pytest.fixture(scope="module", params=VIEWS, ids=[f"{n}-{'own' if f is None else f'{f:g}'}-seed{s}-{w}" for n, f, s, w in VIEWS])
def corridors(request: pytest.FixtureRequest) -> tuple[str, Any]:
    """One view's run through the corridors with true poses: (sensor, evaluation)."""
    name, fov, seed, kind = request.param
    world, traj = corridor_walk(seed, kind)
    seq = sim.simulate(world, sim.Sensor(name, h_fov=fov), traj)
    # The shipped defaults: the default world's revisits come after a 744 m lap, where among its
    # look-alikes the descriptor's candidates rarely hold the true place; the two places chosen by
    # pose (by default) do.
    cfg = PipelineConfig.preset(name, radius=5.0)
    return name, LoopClosurePipeline(seq, cfg).run().evaluate()


def test_look_alike_corridors_give_no_loop_with_a_wrong_pose(corridors: tuple[str, Any]) -> None:
    _, ev = corridors
    m = ev.metrics()
    assert m["pose_false_accepts"] == 0, m
    assert wrong_poses(ev) == 0, m


def test_look_alike_corridors_find_most_revisits(corridors: tuple[str, Any]) -> None:
    """Most true revisits are found although every place has look-alikes (on the default world
    thanks to the places chosen by pose, verified beside the descriptor's by default)."""
    _, ev = corridors
    assert ev.metrics()["recall"] >= 0.5, ev.metrics()


@pytest.mark.parametrize("name", ["avia", "os1-64"])
def test_turning_in_place_accepts_no_loop_more_than_5_degrees_off(name: str) -> None:
    room = sim.World.room(seed=1)
    traj = sim.Trajectory.turn_in_place(room, sweep=330.0, step=3.0, wobble=0.3, seed=1)
    # The sensor never leaves the spot, so the default 30 m window would exclude every place and
    # hide the gate: frames only, as the issue measured it.
    cfg = PipelineConfig.preset(name, radius=5.0, detector={"exclude_meters": 0.0})
    ev = LoopClosurePipeline(sim.simulate(room, sim.Sensor(name), traj), cfg).run().evaluate()
    assert ev.metrics()["queries"] > 0
    ed = np.nan_to_num(np.asarray(ev.scores.pose_error_deg))
    assert not (ev.accepted & (ed > TOL_DEG)).any(), ev.metrics()
    assert ev.metrics()["pose_false_accepts"] == 0


def test_the_view_check_rejects_loops_whose_yaw_turns_the_avia_away() -> None:
    """With the checks that need poses off, the view check alone rejects the room's loops whose
    registered yaw leaves the Avia's two 70.4° views sharing less than the minimum; the loops it
    keeps share at least that much, and none is rejected with it off."""
    room = sim.World.room(seed=1)
    traj = sim.Trajectory.turn_in_place(room, sweep=330.0, step=2.0, wobble=0.3, seed=1)
    seq = sim.simulate(room, sim.Sensor("avia"), traj)
    alone = {"exclude_meters": 0.0, "odometry_check": False, "unique": False, "min_support": 0}

    def run(minimum: float) -> tuple[list[float], list[float]]:
        cfg = PipelineConfig.preset("avia", radius=5.0, detector={**alone, "view_min_overlap_deg": minimum})
        kept: list[float] = []
        rejected: list[float] = []
        for d in LoopClosurePipeline(seq, cfg).run().queries():
            for c in d.candidates:
                if c.pose is None:
                    continue
                yaw = float(np.degrees(np.arctan2(c.pose[1, 0], c.pose[0, 0])))
                if c.accepted:
                    kept.append(yaw)
                elif c.rejection == "the views do not overlap":
                    rejected.append(yaw)
        return kept, rejected

    kept, rejected = run(0.0)
    assert kept and not rejected
    kept, rejected = run(60.0)
    # 70.4° wide: sharing at least 60° is turning by at most 10.4°.
    assert rejected and all(abs(h) > 10.4 for h in rejected), rejected
    assert kept and all(abs(h) <= 10.4 + 1e-6 for h in kept), kept


class Odometry:
    """A simulated sequence whose poses are a drifting odometry (what the pipeline gives the detector)."""

    def __init__(self, seq: sim.Sequence, odometry: sim.Trajectory) -> None:
        self.scans = seq.scans
        self.poses = odometry.poses
        self.timestamps = seq.times

    def __len__(self) -> int:
        return len(self.scans)

    def __iter__(self) -> Any:
        return iter(self.scans)

    def __getitem__(self, i: int) -> Any:
        return self.scans[i]


def as4(p: F64) -> F64:
    out = np.tile(np.eye(4), (len(p), 1, 1))
    out[:, :3, :] = np.asarray(p).reshape(len(p), 3, 4)
    return out


def test_with_a_drifting_odometry_loops_are_right_by_the_truth() -> None:
    """The detector sees a drifting odometry (0.01°/m of yaw, 1 % scale, noise); every loop it
    accepts is within the tolerance of the true relative pose, and it finds most revisits. The
    shipped defaults verify two places chosen by pose: without their checks (information floor,
    restarts, the odometry without the rotation's allowance) 16 of their 33 loops here slid 4-15 m."""
    world, traj = corridor_walk(3)
    seq = sim.simulate(world, sim.Sensor("os1-64", h_fov=90.0), traj)
    odo = traj.odometry(yaw_bias_deg_per_m=0.01, scale_error=0.01, translation_noise=0.01, rotation_noise_deg=0.02, seed=3)
    cfg = PipelineConfig.preset("os1-64", radius=5.0)
    assert cfg.detector.pose_candidates > 0
    res = LoopClosurePipeline(Odometry(seq, odo), cfg).run()
    T = as4(traj.poses)
    loops = res.loops()
    assert loops
    found = set()
    for lp in loops:
        q, c = res.frame_of(lp.query), res.frame_of(lp.candidate)
        assert q is not None and c is not None
        d = np.linalg.inv(np.linalg.inv(T[q]) @ T[c]) @ np.asarray(lp.pose)
        deg = np.degrees(np.arccos(np.clip((np.trace(d[:3, :3]) - 1) / 2, -1, 1)))
        assert np.linalg.norm(d[:3, 3]) <= TOL_M and deg <= TOL_DEG, (q, c, d)
        found.add(q)
    # True revisits: queries with a place within 5 m that the detector could see (50 frames back).
    P = traj.positions
    revisits = [q for q in range(50, len(P)) if (np.linalg.norm(P[: q - 50] - P[q], axis=1) <= 5.0).any()]
    assert len(found & set(revisits)) >= 0.5 * len(revisits), (len(found), len(revisits))
