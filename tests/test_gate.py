"""A gate that holds (issue 26): on the simulator's look-alike corridors and in a small room
where the sensor turns in place, every loop the shipped pipeline accepts carries a pose a pose
graph can trust, and most true revisits are still found.

The pipeline takes one set of poses, used both by the detector (its odometry check and the
support of the previous steps) and by the scoring: the runs with true poses score with them;
the run with a drifting odometry scores its loops against the truth here.
"""

from __future__ import annotations

from dataclasses import dataclass
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


def corridor_walk(seed: int, world: str = "short", *, spacing: float | None = None, laps: float = 1.3) -> tuple[sim.World, sim.Trajectory]:
    """``laps`` laps through look-alike corridors, a frame every ``spacing`` m: by default every
    3 m on the "short" world (two copies of one module per corridor), every 4 m on the default
    world (four copies)."""
    if world == "short":
        w = sim.World.corridors(seed=seed, modules=2)
        return w, sim.Trajectory.corridor_walk(w, laps=laps, spacing=spacing or 3.0)
    w = sim.World.corridors(seed=seed)
    return w, sim.Trajectory.corridor_walk(w, laps=laps, spacing=spacing or 4.0)


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


def as4(p: F64) -> F64:
    out = np.tile(np.eye(4), (len(p), 1, 1))
    out[:, :3, :] = np.asarray(p).reshape(len(p), 3, 4)
    return out


@dataclass
class DriftRun:
    """The pipeline's loops on a drifting odometry, scored against the truth."""

    #: Accepted loops.
    loops: int
    #: The loops off the true relative pose by more than the tolerance: (query frame, candidate
    #: frame, metres, degrees off).
    wrong: list[tuple[int, int, float, float]]
    #: The queries whose loop is right and joins places within 5 m.
    found: set[int]
    #: The true revisits: queries with a place within 5 m that the detector could see (50 frames back).
    revisits: set[int]

    def recall(self) -> float:
        return len(self.found & self.revisits) / max(1, len(self.revisits))

    def describe(self) -> str:
        return ", ".join(f"({q}, {c}, {m:.1f}, {deg:.1f})" for q, c, m, deg in self.wrong)


def drift_run(world: sim.World, traj: sim.Trajectory, sensor: sim.Sensor, preset: str, seed: int, detector: dict[str, Any] | None = None) -> DriftRun:
    """The shipped pipeline (``preset`` at radius 5 m, ``detector``'s overrides) given a drifting
    odometry along ``traj`` (0.01°/m of yaw, 1 % scale, noise; seeded) instead of its poses; its
    loops scored against ``traj``."""
    seq = sim.simulate(world, sensor, traj)
    odo = traj.odometry(yaw_bias_deg_per_m=0.01, scale_error=0.01, translation_noise=0.01, rotation_noise_deg=0.02, seed=seed)
    cfg = PipelineConfig.preset(preset, radius=5.0, detector=detector or {})
    res = LoopClosurePipeline(sim.Sequence(seq.scans, odo, sensor), cfg).run()
    T = as4(traj.poses)
    loops = res.loops()
    wrong = []
    found = set()
    for lp in loops:
        q, c = res.frame_of(lp.query), res.frame_of(lp.candidate)
        assert q is not None and c is not None
        rel = np.linalg.inv(T[q]) @ T[c]
        d = np.linalg.inv(rel) @ np.asarray(lp.pose)
        m = float(np.linalg.norm(d[:3, 3]))
        deg = float(np.degrees(np.arccos(np.clip((np.trace(d[:3, :3]) - 1) / 2, -1, 1))))
        if m > TOL_M or deg > TOL_DEG:
            wrong.append((q, c, m, deg))
        elif np.linalg.norm(rel[:3, 3]) <= 5.0:
            found.add(q)
    P = traj.positions
    revisits = {q for q in range(50, len(P)) if (np.linalg.norm(P[: q - 50] - P[q], axis=1) <= 5.0).any()}
    return DriftRun(len(loops), wrong, found, revisits)


def test_with_a_drifting_odometry_loops_are_right_by_the_truth() -> None:
    """The detector sees a drifting odometry (0.01°/m of yaw, 1 % scale, noise); every loop it
    accepts is within the tolerance of the true relative pose, and it finds most revisits. The
    shipped defaults verify two places chosen by pose: without their checks (information floor,
    restarts, the odometry check) 16 of their 33 loops here slid 4-15 m."""
    assert PipelineConfig.preset("os1-64").detector.pose_candidates > 0
    world, traj = corridor_walk(3)
    run = drift_run(world, traj, sim.Sensor("os1-64", h_fov=90.0), "os1-64", 3)
    assert run.loops and not run.wrong, run.describe()
    assert run.recall() >= 0.5, (len(run.found), len(run.revisits))


#: The four-module world with the drifting odometry, shrunk (1.2 laps), seed 1: 90° views, the
#: metres between frames and the share of the revisits each must find. HDL-64 at 90° finds few
#: of this world's revisits (2 of 31): its case asserts no wrong loop.
FOUR_MODULE_DRIFT = [("vlp16", 90.0, 6.0, 0.7), ("os1-64", 90.0, 6.0, 0.7), ("hdl64", 90.0, 5.0, 0.0)]


@pytest.mark.parametrize(("name", "fov", "spacing", "recall"), FOUR_MODULE_DRIFT, ids=[f"{n}-{f:g}-{s:g}m" for n, f, s, _ in FOUR_MODULE_DRIFT])
def test_on_four_modules_a_drifting_odometry_gets_no_run_of_look_alike_loops(name: str, fov: float, spacing: float, recall: float) -> None:
    """On the default world (four copies of each module, a 744 m lap) the drifting odometry is
    12-13 m off when the first lap ends, and its last stretch is a run of look-alike loops into
    the start's places 78.8 m along, agreeing with one another. When the neighbours vouched for one another along a straight (before
    d42fdde) they were accepted: 9 of 9 loops wrong (VLP-16, frames 6 m apart), 6 of 6 (OS1-64). They now vouch only
    over a 45° turn: no loop is wrong, and the revisit after the corner is found (20 and 22 of the
    25 revisits; 11 and 12 while the look-alike check took a quarter of the rotation's allowance
    in any direction instead of the odometry check's directed form).

    HDL-64, frames 5 m apart: 20 m before the lap ends, where the query has no place within 5 m
    yet, its loop into place 1, a look-alike 33.8 m away, was 22 m off the poses after 710 m of
    path, within the odometry check's allowance in any direction (1 m + 1 % of the path + 7.2° of
    rotation · path / 2 = 52.6 m), and the anchor it set carried 8 more: 9 of 9 loops wrong. The
    check now takes the rotation's allowance as the displacement that rotation predicts
    (direction and length from the path's centroid): the true place lies about 1 m from it, the
    look-alike a period."""
    world, traj = corridor_walk(1, "default", spacing=spacing, laps=1.2)
    run = drift_run(world, traj, sim.Sensor(name, h_fov=fov), name, 1)
    assert not run.wrong, f"{len(run.wrong)} of {run.loops} loops off the truth (query, place, m, °): {run.describe()}"
    assert run.recall() >= recall, f"found {sorted(run.found & run.revisits)} of {len(run.revisits)} revisits"


def test_after_a_lap_without_a_loop_the_places_the_odometry_cannot_tell_apart_are_verified() -> None:
    """The default world (four copies of each module, a 744 m lap), VLP-16 with its own view, the
    drifting odometry 10.8-15.7 m and 7° off when the lap ends. The descriptor's candidates are
    the corridors' copies, and the two places nearest to where the odometry puts the query are
    its neighbours a step or two off (registered 7-13 m off the truth); the true place is the
    fourth or fifth nearest. Before r19-drift no revisit got a loop (0 of 57): the places chosen
    by pose now widen by one per typical step the odometry may be off by (1 m + 1 % of the path:
    8.4 m, two 4 m steps), and are checked with the displacement the rotation drift predicts, as
    the descriptor's are: the true place's first loop anchors the rest of the revisit."""
    world, traj = corridor_walk(2, "default")
    run = drift_run(world, traj, sim.Sensor("vlp16"), "vlp16", 2)
    assert not run.wrong, f"{len(run.wrong)} of {run.loops} loops off the truth (query, place, m, °): {run.describe()}"
    assert run.recall() >= 0.9, f"found {sorted(run.found & run.revisits)} of {len(run.revisits)} revisits"


@pytest.mark.xfail(strict=True, reason="open: the registration's minimum for this pair lies 1.0 m along the corridor (docs/performance.md#the-swept-loop-that-is-1-m-off)")
def test_a_revisit_along_a_corridor_registers_at_its_true_pose_from_every_nearby_start() -> None:
    """The four-module sweep's one wrong loop (``drift_run`` on ``corridor_walk(1, "default")``,
    HDL-64 with a 90° view): query frame 214 into place 29, 1.15 m behind it along the corridor,
    1.004 m off the truth. It is not a slide that follows its start: the preset's registration
    ends 1.0 m along the corridor from the true pose itself and from every start within 3 m
    of it along the corridor, so the shifted-restart check (``pose_candidate_shift_m``, since
    removed), which place 29, a candidate chosen by pose, did get, found both restarts back at
    that pose. The
    same pair registers within 0.05 m with point-to-plane, with 6 or 20 neighbours per
    covariance instead of 10, or without the floor's and ceiling's points.

    Fails (strictly expected) until the registration ends within the gate's
    ``agree_translation`` (0.5 m) of the truth from these starts."""
    import solid

    world, walk = corridor_walk(1, "default")
    sensor = sim.Sensor("hdl64", h_fov=90.0)
    rc = PipelineConfig.preset("hdl64", radius=5.0).detector.registration

    def cloud(frame: int) -> Any:
        pts = np.asarray(sim.simulate(world, sensor, walk[frame : frame + 1], first_frame=frame).scans[0], dtype=np.float64)
        return solid.PreparedCloud(np.ascontiguousarray(pts[:, :3]), rc)

    q, c = cloud(214), cloud(29)
    truth = as4(walk.poses)
    rel = np.linalg.inv(truth[214]) @ truth[29]
    off = []
    for shift in (-3.0, 0.0, 3.0):
        start = rel.copy()
        start[:3, 3] += shift * rel[:3, 0]  # along the corridor (the sensor's x axis)
        pose = np.asarray(solid.register(q, c, start, config=rc).pose)
        off.append(round(float(np.linalg.norm(pose[:3, 3] - rel[:3, 3])), 3))
    assert max(off) <= 0.5, f"metres off the truth from starts -3, 0, +3 m along the corridor: {off}"


def test_a_route_driven_three_times_finds_the_revisits_of_its_third_pass() -> None:
    """The city loop (``sim.World(seed=1)``, a scan every 2 m, 160 a lap) driven 3.2 times by a
    VLP-16 on a drifting odometry: the third pass finds its revisits as the second does, and no
    loop is wrong. Its candidates on the first two passes lie where the odometry put them, over
    10 m apart after the drift; through the odometry alone the anchor's path back to the first
    pass is a whole lap, whose bounds admit the street's neighbouring places as look-alikes, and
    the two passes' candidates of one step disagree. The accepted loops that joined the passes
    give the short path (docs/spec.md §8, "Passes"): without it the third pass found 22 of its
    192 revisits (docs/performance.md#a-route-driven-three-times-the-third-pass-lost-its-loops-r22-passes)."""
    world = sim.World(seed=1)
    traj = sim.Trajectory.loop(world, laps=3.2, spacing=2.0)
    run = drift_run(world, traj, sim.Sensor("vlp16"), "vlp16", 0)
    assert not run.wrong, run.describe()
    lap = len(traj.positions) / 3.2
    second = {q for q in run.revisits if lap <= q < 2 * lap}
    third = {q for q in run.revisits if q >= 2 * lap}
    assert len(run.found & second) >= 0.8 * len(second), (len(run.found & second), len(second))
    assert len(run.found & third) >= 0.8 * len(third), (len(run.found & third), len(third))
