"""Verified loop closures (issue 9): the detector registers its best candidates and accepts only
what passes the gate; a loop carries its metric pose T_query_candidate (docs/spec.md §3, §11)."""

from __future__ import annotations

import math
from typing import Any
from pathlib import Path

import numpy as np
import pytest
from conftest import data_dir

import solid
from solid import sim
from solid.commands import build_map
from solid.config import PipelineConfig
from solid.evaluation import Evaluation
from solid.pipeline import LoopClosurePipeline, PipelineResult


@pytest.fixture(scope="module")
def hku3() -> tuple[PipelineResult, Evaluation]:
    """The shipped pipeline on the real Livox walk at radius 3 m (exclusion 50 keyframes only,
    the protocol of docs/spec.md §5: the default 30 m window is off), its loops bounded at 3 m too
    (the gate's own default is 5 m, issue 26)."""
    ds = solid.datasets.open_dataset(data_dir() / "hku1-avia", poses="odom_poses.txt")
    cfg = PipelineConfig.preset("avia", radius=3.0, detector={"exclude_meters": 0.0, "gate": {"max_translation": 3.0}})
    res = LoopClosurePipeline(ds, cfg).run()
    return res, res.evaluate()


def test_verified_loops_on_hku1_meet_the_targets(hku3: tuple[PipelineResult, Evaluation]) -> None:
    """Measured on this build: Recall@1 0.758, F1 max 0.821, 46 loops accepted, none false, median
    pose error 2.8 cm / 0.17°, worst 0.20 m (unverified SOLiD: 0.621 / 0.388)."""
    _, ev = hku3
    m = ev.metrics()
    assert m["gt_queries"] == 66
    assert m["recall_at_1"] >= 0.70 and m["f1_max"] >= 0.60, m
    assert m["accepted"] >= 30 and m["precision"] >= 0.95, m
    assert m["pose_error_m_median"] <= 0.05 and m["pose_error_deg_median"] <= 0.3, m
    # No accepted loop is more than 1 m off, counting the ones the radius calls false too.
    assert m["pose_error_m_max_all_accepted"] < 1.0, m


def test_a_loop_pose_is_consistent_with_its_heading_and_the_stored_places(hku3: tuple[PipelineResult, Evaluation]) -> None:
    res, _ = hku3
    loops = res.loops()
    assert loops and all(lp.verified and lp.pose is not None for lp in loops)
    for lp in loops:
        T = lp.pose
        assert T is not None and T.shape == (4, 4)
        np.testing.assert_allclose(T[3], [0, 0, 0, 1])
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9)
        yaw = math.degrees(math.atan2(T[1, 0], T[0, 0]))
        assert abs((yaw - lp.heading + 180.0) % 360.0 - 180.0) < 1e-9  # docs/spec.md §3
        assert 0.35 <= (lp.fitness or 0.0) <= 1.0 and 0.0 < (lp.rmse or 1.0) <= 0.30
        assert np.linalg.norm(T[:3, 3]) <= 3.0  # the gate's max_translation
    db = res.database
    assert db.clouds_stored == len(db) == 314
    per_place = db.cloud_bytes / db.clouds_stored
    assert 1_000 < per_place < 20_000, per_place  # a few kB per Avia keyframe (measured ~5 kB)
    # The stored compact cloud decodes back to the place's downsampled points.
    pts = solid.decode_cloud(db.cloud(300))
    assert pts.shape[1] == 3 and 500 < pts.shape[0] < 5000


def test_verification_needs_points_and_says_so() -> None:
    cfg = solid.SolidConfig.preset("vlp16")
    det = solid.LoopDetector(cfg)
    assert det.config.verify
    d = solid.describe(np.random.default_rng(0).uniform(-20, 20, (500, 3)), cfg)
    with pytest.raises(solid.ConfigError, match="verify"):
        det.add(d)
    with pytest.raises(solid.ConfigError, match="verify"):
        det.query(d)
    assert len(det) == 0
    # With verification off, descriptors are fine.
    assert solid.LoopDetector(cfg, verify=False).add(d) is None


def test_maps_keep_their_clouds_and_a_second_session_is_verified_against_them(tmp_path: Path) -> None:
    world = sim.World(seed=1)
    lap, second = sim.session_routes(world)
    sensor = sim.Sensor("vlp16")
    s0, s1 = sim.simulate(world, sensor, lap), sim.simulate(world, sensor, second)
    cfg = PipelineConfig.preset("vlp16")
    # The map as `solid map build` makes it: every place and its cloud, no detection within the lap.
    first, _ = build_map(s0, cfg, tmp_path / "map.soliddb")
    back = solid.Database.load(tmp_path / "map.soliddb")
    assert back.clouds_stored == len(back) == len(lap)
    assert [back.cloud(i) for i in (0, 7)] == [first.cloud(i) for i in (0, 7)]
    res = LoopClosurePipeline(s1, cfg, map=back).run()
    ev = res.evaluate(radius=5.0)
    m = ev.metrics()
    # The simulated city repeats its blocks exactly: 5 of 88 accepted loops (measured) join a
    # place with its identical copy 113-124 m away, which no descriptor or registration can tell
    # apart (a perfect registration, fitness 0.42-0.44). Every other accepted loop is true.
    assert m["precision"] >= 0.9 and m["recall"] > 0.8, m
    # Loops into the map, with exact-truth pose errors of a few centimetres and a heading error
    # (the registration's yaw) far below the 6° bins of A-SOLiD.
    loops = [lp for lp in res.loops() if lp.candidate < len(lap)]
    assert len(loops) > 40
    assert m["pose_error_m_median"] < 0.05 and m["pose_error_deg_median"] < 0.3, m
    assert m["rotation_error_deg_mean"] < 0.3, m


def test_detector_config_round_trips_with_registration_and_gate() -> None:
    d = solid.DetectorConfig.preset("avia", verify_candidates=3, gate={"max_translation": 3.0, "min_fitness": 0.4})
    assert d.verify_candidates == 3 and d.gate.max_translation == 3.0 and d.gate.min_fitness == 0.4
    assert solid.DetectorConfig(**d.to_dict()) == d
    r = d.replace(registration={"voxel_size": 0.4})
    assert r.registration.voxel_size == 0.4 and r.gate == d.gate
    with pytest.raises(solid.ConfigError, match="verify_candidates"):
        solid.DetectorConfig(verify_candidates=0)
    with pytest.raises(TypeError, match="gate"):
        solid.DetectorConfig(gate=3)  # type: ignore[arg-type]
    # The evaluation radius says how loops are scored, never which ones the detector accepts
    # (issue 26): the gate's largest loop is the detector's own parameter.
    assert PipelineConfig.preset("avia", radius=3.0).detector.gate.max_translation == solid.DetectorConfig().gate.max_translation == 5.0
    assert PipelineConfig.preset("avia", radius=3.0, detector={"gate": {"max_translation": 8.0}}).detector.gate.max_translation == 8.0



def _revisits(detector: dict[str, Any]) -> list[solid.Detection]:
    """The look-alike city's loop with its poses, frames 0-11 and 48-64 (53-64 revisit 0-11), VLP-16,
    the preset's detector with `detector` over it."""
    world = sim.World(seed=1, repetition=0.9)
    traj = sim.Trajectory.loop(world, laps=1.2, spacing=6.0)
    seq = sim.simulate(world, sim.Sensor("vlp16"), traj)
    dc = solid.DetectorConfig.preset("vlp16").replace(**detector)
    det = solid.LoopDetector(solid.SolidConfig.preset("vlp16"), exclude_recent=3, detector=dc)
    return [det.detect(seq.scans[f], timestamp=float(f), pose=np.asarray(traj.poses[f])) for f in [*range(0, 12), *range(48, 65)]]


def test_a_step_over_its_budget_says_which_candidates_wait() -> None:
    """`verify_step_points` (docs/spec.md §8, budget): a step registers its candidates while their
    cost fits (its first always) and defers the rest, naming them in `Detection.deferred`
    (unverified among its candidates; the next steps register them and release a loop of theirs,
    crates/solid-core's defer tests); a step that found its loop keeps none waiting. The look-alike
    city's revisits (frames 53-64 of 0-11, with poses): a budget of one point defers, an unlimited
    one never does, and both find the same loops."""
    runs = {budget: _revisits({"verify_step_points": budget}) for budget in (1, 2**40)}
    for s in runs[1]:
        assert set(s.deferred) <= {c.id for c in s.candidates if not c.verified}, (s.query, s.deferred)
        assert not (s.loop is not None and s.deferred)
    assert sum(len(s.deferred) for s in runs[1]) >= 2
    assert all(not s.deferred for s in runs[2**40])
    loops = {b: [(s.query, s.loop.candidate) for s in r if s.loop is not None] for b, r in runs.items()}
    assert len(loops[1]) >= 10 and {q for q, _ in loops[1]} == {q for q, _ in loops[2**40]}


def test_verify_threads_register_the_same_loops_as_one() -> None:
    """`verify_threads` (default 1, docs/performance.md#threads): a step's registrations on the
    verify pool (2 threads, 0: one per core) give every candidate the same verification, bit for
    bit, as on the calling thread: the registrations are independent of each other."""
    def outcome(d: solid.Detection) -> list[tuple[int, bool, float | None, bytes | None]]:
        return [(c.id, c.accepted, c.fitness, None if c.pose is None else np.asarray(c.pose).tobytes()) for c in d.candidates]

    assert solid.DetectorConfig().verify_threads == 1
    one = _revisits({})
    assert sum(d.loop is not None for d in one) >= 10
    for k in (2, 0):
        assert [outcome(d) for d in _revisits({"verify_threads": k})] == [outcome(d) for d in one], k
