"""The LiDAR simulator (solid.sim): determinism, geometry, sequence files, and two experiments with
exact ground truth: heading under a limited field of view (the paper's Fig. 6) and revisit
detection per sensor model (docs/spec.md §5).

Run with ``pytest -s tests/test_sim.py`` to see the per-FOV heading table and the Recall@1 per
sensor. Everything here is seeded, so the measured figures are reproducible bit for bit on one
build; the bounds leave room for float32-versus-float64 differences between implementations.
"""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest

import solid
from solid import sim
from solid.config import PipelineConfig
from solid.io import Dataset as ReadSequence
from solid.pipeline import LoopClosurePipeline

F64 = npt.NDArray[np.float64]


@pytest.fixture(scope="module")
def world() -> sim.World:
    return sim.World(seed=0)


# ---------------------------------------------------------------------------------------------
# determinism and basic geometry


def test_same_seed_gives_bit_identical_scans(world: sim.World) -> None:
    traj = sim.Trajectory.loop(world, spacing=40.0)
    other_world = sim.World(seed=0)
    for name in sim.SENSORS:
        sensor = sim.Sensor(name, dropout=0.05, seed=3)
        a = sim.simulate(world, sensor, traj)
        b = sim.simulate(other_world, sim.Sensor(name, dropout=0.05, seed=3), traj)
        assert len(a) == len(b) == len(traj)
        for x, y in zip(a, b):
            assert x.dtype == np.float32 and x.shape[1] == 4 and x.shape[0] > 1000
            assert x.tobytes() == y.tobytes()
        # One scan on its own equals the same frame inside a sequence.
        assert sim.scan(world, sensor, traj.poses[2], frame=2).tobytes() == a.scans[2].tobytes()


def test_worlds_and_sensors_pickle_by_their_parameters(world: sim.World) -> None:
    sensor = sim.Sensor("avia", h_fov=50.0, noise=0.05, dropout=0.1, seed=9, points=6000)
    w2, s2 = pickle.loads(pickle.dumps((world, sensor)))
    assert s2 == sensor and w2.seed == world.seed and len(w2) == len(world)
    pose = sim.Trajectory.loop(world).poses[5]
    assert sim.scan(w2, s2, pose, 4).tobytes() == sim.scan(world, sensor, pose, 4).tobytes()


def test_different_seeds_give_different_scans(world: sim.World) -> None:
    pose = sim.Trajectory.loop(world).poses[10]
    base = sim.scan(world, sim.Sensor("vlp16"), pose)
    other_world = sim.scan(sim.World(seed=1), sim.Sensor("vlp16"), sim.Trajectory.loop(sim.World(seed=1)).poses[10])
    other_noise = sim.scan(world, sim.Sensor("vlp16", seed=1), pose)
    # With nothing near the range limits every ray returns in both, so rays pair up by index.
    far = sim.scan(world, sim.Sensor("vlp16", max_range=1000.0), pose)
    far_noisy = sim.scan(world, sim.Sensor("vlp16", max_range=1000.0, seed=1), pose)
    other_frame = sim.scan(world, sim.Sensor("vlp16"), pose, frame=1)
    for other in (other_world, other_noise, other_frame):
        assert base.tobytes() != other.tobytes()
    # Noise changes ranges by centimetres, not the scene: the difference of two draws with
    # σ = 3 cm has σ·√2 ≈ 4.2 cm.
    assert far.shape == far_noisy.shape
    diff = np.linalg.norm(far_noisy[:, :3] - far[:, :3], axis=1)
    assert 0.035 < float(np.sqrt(np.mean(diff**2))) < 0.05
    # The rosette never repeats: consecutive frames fire different rays.
    avia = sim.Sensor("avia", noise=0.0)
    assert sim.scan(world, avia, pose, 0).tobytes() != sim.scan(world, avia, pose, 1).tobytes()


def test_scans_respect_the_sensor_model(world: sim.World) -> None:
    pose = sim.Trajectory.loop(world).poses[30]
    for name in sim.SENSORS:
        sensor = sim.Sensor(name, noise=0.0)
        pts = sim.scan(world, sensor, pose)
        r = np.linalg.norm(pts[:, :3].astype(np.float64), axis=1)
        assert r.min() > 1.0 and r.max() < sensor.effective_max_range
        assert pts[:, 3].min() >= 0.0 and pts[:, 3].max() <= 1.0
        elev = np.degrees(np.arcsin(pts[:, 2] / r))
        lo, hi = sensor.vertical_fov
        assert elev.min() >= lo - 1e-3 and elev.max() <= hi + 1e-3, name
        az = np.degrees(np.arctan2(pts[:, 1], pts[:, 0]))
        half = sensor.effective_h_fov / 2.0
        if half < 180.0:
            assert np.abs(az).max() <= half + 1e-3, name
        # Most rays of a street scene return (the ground or an object).
        assert pts.shape[0] > 0.5 * sensor.n_rays(), name
    narrow = sim.scan(world, sim.Sensor("hdl64", h_fov=60.0, h_centre=90.0), pose)
    az = np.degrees(np.arctan2(narrow[:, 1], narrow[:, 0]))
    assert np.abs(az - 90.0).max() <= 30.0 + 1e-3
    dropped = sim.scan(world, sim.Sensor("hdl64", dropout=0.5, seed=1), pose)
    full = sim.scan(world, sim.Sensor("hdl64"), pose)
    assert 0.45 < dropped.shape[0] / full.shape[0] < 0.55


def test_invalid_parameters_are_rejected(world: sim.World) -> None:
    with pytest.raises(ValueError, match="sensor preset"):
        sim.Sensor("hdl65")
    with pytest.raises(ValueError, match="h_fov"):
        sim.Sensor("hdl64", h_fov=0.0)
    with pytest.raises(ValueError, match="dropout"):
        sim.Sensor("hdl64", dropout=1.5)
    with pytest.raises(ValueError, match="points"):
        sim.Sensor("hdl64", points=1000)
    with pytest.raises(ValueError, match="blocks"):
        sim.World(blocks=0)
    with pytest.raises(ValueError, match="trajectory kind"):
        sim.Trajectory.named(world, "spiral")
    with pytest.raises(ValueError, match="shape"):
        sim.scan(world, sim.Sensor(), np.eye(3))


def test_trajectories_revisit_as_described(world: sim.World) -> None:
    loop = sim.Trajectory.loop(world, laps=1.0)
    assert np.linalg.norm(loop.positions[0] - loop.positions[-1]) < 1.0
    assert abs(sim.true_heading(loop.poses[-1], loop.poses[0])) < 1e-6
    steps = np.linalg.norm(np.diff(loop.positions[:, :2], axis=0), axis=1)
    assert steps.max() <= 1.0 + 1e-9 and steps.min() > 0.99  # chords of the corner arcs are shorter
    rev = sim.Trajectory.reverse(world)
    assert abs(abs(sim.true_heading(rev.poses[-11], rev.poses[10])) - 180.0) < 1e-6
    for traj, angle in ((sim.Trajectory.crossing(world), 90.0), (sim.Trajectory.figure_eight(world), 90.0)):
        p = traj.positions
        d = np.linalg.norm(p[:, None, :2] - p[None, :, :2], axis=2)
        d[np.abs(np.arange(len(p))[:, None] - np.arange(len(p))[None, :]) < 60] = np.inf
        i, j = np.unravel_index(int(np.argmin(d)), d.shape)
        assert d[i, j] < 2.0
        assert abs(abs(sim.true_heading(traj.poses[i], traj.poses[j])) - angle) < 1.0


def test_write_sequence_round_trips_through_the_readers(world: sim.World, tmp_path: Path) -> None:
    traj = sim.Trajectory.figure_eight(world, spacing=25.0)
    sensor = sim.Sensor("os1-64", seed=2)
    seq = sim.simulate(world, sensor, traj)
    n = sim.write_sequence(tmp_path / "a", seq)
    m = sim.write_sequence(tmp_path / "b", world, sensor, traj)
    assert n == m == len(traj)
    for folder in ("a", "b"):
        files = sorted((tmp_path / folder / "velodyne").iterdir())
        assert [f.name for f in files] == [f"{i:06d}.bin" for i in range(n)]
        back = ReadSequence(tmp_path / folder, poses="poses.txt", timestamps="times.txt", xyz_only=False)
        assert len(back) == n and back.poses is not None and back.timestamps is not None
        np.testing.assert_allclose(back.poses, traj.poses, rtol=1e-11, atol=1e-9)
        np.testing.assert_allclose(back.timestamps, traj.times, rtol=1e-6)
        for i in range(n):
            assert back[i].tobytes() == seq.scans[i].tobytes()


# ---------------------------------------------------------------------------------------------
# heading under a limited field of view (paper Fig. 6)

#: Yaw offsets of the query against the reference, degrees: multiples of the 6° azimuth bin and
#: values between bins, both signs, up to a U-turn.
OFFSETS = (3.0, -8.0, 17.0, -30.0, 30.0, -43.0, 51.0, 77.0, -90.0, 90.0, 135.0, -150.0, 180.0)
FOVS = (360.0, 180.0, 120.0, 60.0)


def _heading_errors(world: sim.World, fov: float, places: F64) -> dict[float, list[float]]:
    """For each place, scan at the road's heading and at heading + offset (the sensor, and so its
    field-of-view window, turns with the vehicle) and estimate the query's heading against the
    reference with A-SOLiD. The true heading is ψ = yaw(R_qᵀ R_c) = −offset."""
    sensor = sim.Sensor("hdl64", h_fov=fov)
    cfg = solid.SolidConfig.preset("hdl64")
    errors: dict[float, list[float]] = {o: [] for o in OFFSETS}
    for x, y, h in places:
        traj = sim.Trajectory.spin(world, x, y, [h] + [h + o for o in OFFSETS])
        descs = solid.describe_batch(sim.simulate(world, sensor, traj).scans, cfg)
        ref = descs[0]
        for o, d in zip(OFFSETS, descs[1:]):
            est = solid.heading(d, ref, refine=True)
            true = sim.true_heading(traj.poses[1 + OFFSETS.index(o)], traj.poses[0])
            assert abs(true + o - 360.0 * round((true + o) / 360.0)) < 0.01  # tilt by the slope
            errors[o].append(abs((est - true + 180.0) % 360.0 - 180.0))
    return errors


def test_heading_error_per_field_of_view(world: sim.World) -> None:
    loop = sim.Trajectory.loop(world)
    idx = np.arange(20, len(loop), 50)  # places along the loop's streets and corners
    places = np.column_stack([loop.positions[idx, 0], loop.positions[idx, 1], loop.headings[idx]])
    print(f"\nrefined heading error (degrees), HDL-64E, {len(places)} places x {len(OFFSETS)} offsets")
    print(f"{'FOV':>5} | {'all: mean':>9} {'median':>6} {'max':>6} | {'|off|<=8: mean':>14} {'max':>5} | {'<3 deg':>6} | {'|off|>=FOV: mean':>16}")
    success = []
    for fov in FOVS:
        errors = _heading_errors(world, fov, places)
        every = np.concatenate([errors[o] for o in OFFSETS])
        small = np.concatenate([errors[o] for o in OFFSETS if abs(o) <= 8.0])
        far_offsets = [o for o in OFFSETS if abs(o) >= fov]
        far = np.concatenate([errors[o] for o in far_offsets]) if far_offsets else np.array([])
        rate = float((every < 3.0).mean())
        success.append(rate)
        far_txt = f"{far.mean():16.1f}" if far.size else f"{'-':>16}"
        print(
            f"{fov:5.0f} | {every.mean():9.2f} {np.median(every):6.2f} {every.max():6.2f} | "
            f"{small.mean():14.2f} {small.max():5.2f} | {rate:6.0%} | {far_txt}"
        )
        if fov == 360.0:
            # Full view: every offset is recovered to a fraction of the 6° bin (measured: mean
            # 0.25°, max 1.1°), far better than the ±3° of the bare bin.
            assert every.mean() < 0.6 and every.max() < 2.0
        else:
            # The window turns with the vehicle. A small turn (≤ 8°, most of the view shared)
            # is still recovered within about half a bin on average (measured means: 0.8° at
            # 180°, 1.7° at 120°, 2.8° at 60°; maxima 2.9°, 7.2°, 8.7°; seeds 1–3 give means up
            # to 4.2° at 60°) ...
            assert small.mean() < 5.0 and small.max() < 15.0, fov
            # ... and once the two windows no longer overlap, A-SOLiD carries no heading
            # information: the estimate stays near 0 and the error is about the offset itself
            # (measured means ≥ 100°), the effect the paper's Fig. 6 shows on recall.
            assert far.mean() > 45.0, fov
    # The narrower the view, the fewer headings are recovered (measured: 100 %, 53 %, 35 %, 15 %).
    assert success[0] == 1.0
    assert all(a >= b for a, b in zip(success, success[1:])), success
    assert success[-1] < 0.5


# ---------------------------------------------------------------------------------------------
# revisit detection per sensor model (docs/spec.md §5)

#: Recall@1 floors per sensor on the seed-0 loop below. Measured with the extension: hdl64 0.98,
#: vlp16 0.99, os1-64 0.99, avia 0.98, aeva 0.99 (seeds 1–3: 0.98–0.99 for every sensor). The
#: second lap drives the same lane in the same direction, so every sensor, even the 70° Avia whose
#: rosette never repeats, sees each place again from within a metre; R-SOLiD then finds nearly
#: every revisit. The floor 0.9 allows ~8 of the 99 GT-positive queries to flip (float32 versus
#: float64 binning at bin edges, a changed tie) and is still 30× the chance level (0.027) that the
#: test prints. Harder revisits (reverse direction, narrow FOV) are tested separately below.
RECALL_FLOOR = {"hdl64": 0.9, "vlp16": 0.9, "os1-64": 0.9, "aeva": 0.9, "avia": 0.9}
SPACING = 2.0  # metres between frames, as the paper's Park protocol
EXCLUDE = 25  # frames (50 m)
RADIUS = 5.0  # metres


@pytest.fixture(scope="module")
def revisit_loop(world: sim.World) -> sim.Trajectory:
    # 1.6 laps of a 320 m block: the second lap revisits 60 % of the first.
    return sim.Trajectory.loop(world, laps=1.6, spacing=SPACING)


def recall_at_1(seq: sim.Sequence, preset: str) -> tuple[float, int, float]:
    """docs/spec.md §5 Recall@1 of the descriptor through the shipped pipeline (the preset's
    detector, excluding EXCLUDE frames, without verification: what the sensor model lets R-SOLiD
    find; the verified loops per sensor are test_gate's) scored by solid.evaluation; also the
    number of GT-positive queries and the chance level (the expected Recall@1 of a random eligible
    frame)."""
    cfg = PipelineConfig.preset(preset, detector={"exclude_frames": EXCLUDE, "verify": False})
    ev = LoopClosurePipeline(seq, cfg).run().evaluate(radius=RADIUS)
    m = ev.metrics()
    xyz = seq.poses[:, :, 3]
    chance = [
        float((np.linalg.norm(xyz[:e] - xyz[q], axis=1) <= RADIUS).mean())
        for q, e, g in zip(ev.query, ev.eligible, ev.gt_positive)
        if g
    ]
    return float(m["recall_at_1"]), int(m["gt_queries"]), float(np.mean(chance)) if chance else 0.0


@pytest.mark.parametrize("name", sim.SENSORS)
def test_revisit_recall_per_sensor(world: sim.World, revisit_loop: sim.Trajectory, name: str) -> None:
    seq = sim.simulate(world, sim.Sensor(name), revisit_loop)
    recall, positives, chance = recall_at_1(seq, name)
    print(f"\n{name:7} Recall@1 {recall:.3f} over {positives} GT-positive queries (chance {chance:.3f}, floor {RECALL_FLOOR[name]})")
    assert positives >= 90
    assert RECALL_FLOOR[name] > 10 * chance
    assert recall >= RECALL_FLOOR[name]


def test_reverse_revisit_needs_the_full_view(world: sim.World) -> None:
    """Driving back the other way: with 360° the street is recognised; clipped to 60° ahead the
    two visits see opposite sides of every place and SOLiD cannot match them (the limitation the
    paper's conclusion names)."""
    traj = sim.Trajectory.reverse(world, spacing=SPACING)
    recalls = {}
    for fov in (360.0, 60.0):
        seq = sim.simulate(world, sim.Sensor("hdl64", h_fov=fov), traj)
        recalls[fov], positives, chance = recall_at_1(seq, "hdl64")
        print(f"\nreverse revisit, hdl64 {fov:.0f}°: Recall@1 {recalls[fov]:.3f} over {positives} queries (chance {chance:.3f})")
        assert positives >= 50
    # Measured: 360° 0.75 (R-SOLiD ignores the heading, but the lanes are 3.5 m apart, so each
    # place is seen from a shifted position), 60° 0.045, i.e. chance (0.041).
    assert recalls[360.0] >= 0.6
    assert recalls[60.0] <= 0.2


# ---------------------------------------------------------------------------------------------
# the failure modes of loop closure (issue 26) and drifting odometry (issue 27), with exact truth


def _r_distances(seq: sim.Sequence, preset: str) -> F64:
    """All pairwise R-SOLiD cosine distances of a sequence (the matrix solid.distance gives)."""
    descs = solid.describe_batch(seq.scans, solid.SolidConfig.preset(preset))
    r = np.stack([d.r for d in descs]).astype(np.float64)
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    dist: F64 = 1.0 - r @ r.T
    assert abs(dist[3, 40] - solid.distance(descs[3], descs[40])) < 1e-5
    return dist


@pytest.mark.parametrize(("seed", "name", "fov"), [(1, "vlp16", None), (2, "avia", None), (3, "os1-64", 90.0)])
def test_corridor_look_alikes_beat_true_revisits(seed: int, name: str, fov: float | None) -> None:
    """The point of the corridor world: for many revisiting queries a place 40–50 m away (a module
    further on) describes closer than the true place within 3 m, so the nearest descriptor is a
    false loop and only verification can tell (measured: 40 % of queries with vlp16, 19 % with
    the Avia, 14 % with a 90° os1-64)."""
    world = sim.World.corridors(seed=seed, modules=3)
    assert world.layout == "corridors"
    walk = sim.Trajectory.corridor_walk(world, laps=1.25)
    seq = sim.simulate(world, sim.Sensor(name, h_fov=fov), walk)
    dist = _r_distances(seq, name)
    xy = walk.positions[:, :2]
    apart = np.linalg.norm(xy[:, None] - xy[None], axis=2)
    true_best, alike_best = [], []
    for q in range(len(walk)):
        earlier = np.arange(len(walk)) < q - 25  # more than 50 m of walking back
        true = earlier & (apart[q] <= 3.0)
        alike = earlier & (apart[q] >= 40.0) & (apart[q] <= 50.0)
        if true.any() and alike.any():
            true_best.append(dist[q][true].min())
            alike_best.append(dist[q][alike].min())
    wins = float(np.mean(np.less(alike_best, true_best)))
    print(
        f"\n{name} {fov or 'full'}°, seed {seed}: {len(true_best)} revisiting queries; a look-alike 40-50 m away "
        f"beats the true place for {wins:.0%} (median best distance: true {np.median(true_best):.3f}, "
        f"look-alike {np.median(alike_best):.3f})"
    )
    assert len(true_best) >= 60
    assert wins >= 0.1
    # Yet the walk has true loops: every revisiting query's true place is closer than unrelated
    # places of the same world (more than 60 m away) usually are.
    far = np.median(dist[np.triu_indices(len(walk), k=1)][apart[np.triu_indices(len(walk), k=1)] > 60.0])
    assert np.median(true_best) < far


def _voxels(points: F64, voxel: float = 0.15) -> npt.NDArray[np.int64]:
    """The voxels the points (in one frame) occupy, each once, as sorted keys (21 bits an axis:
    exact within ±150 km)."""
    v = np.floor(points / voxel).astype(np.int64) + (1 << 20)
    keys: npt.NDArray[np.int64] = np.unique((v[:, 0] << 42) | (v[:, 1] << 21) | v[:, 2])
    return keys


def _overlap(va: npt.NDArray[np.int64], vb: npt.NDArray[np.int64]) -> float:
    """Fraction of b's occupied voxels that a also occupies (both `_voxels`)."""
    return float(np.isin(vb, va, assume_unique=True).sum()) / max(len(vb), 1)


def _world_points(scan: npt.NDArray[np.float32], pose: F64) -> F64:
    p = scan[:, :3].astype(np.float64)
    return p @ pose[:, :3].T + pose[:, 3]


def test_turn_in_place_views_more_than_the_fov_apart_share_nothing() -> None:
    room = sim.World.room(seed=4)
    assert room.layout == "room" and room.roads == []
    turn = sim.Trajectory.turn_in_place(room, sweep=330.0, step=2.0, wobble=0.35, seed=4)
    assert len(turn) == 166
    # Never more than the wobble from the turning point, and the headings step by 2°.
    assert np.linalg.norm(turn.positions[:, :2], axis=1).max() <= 0.35
    steps = np.diff(np.unwrap(np.radians(turn.headings)))
    np.testing.assert_allclose(np.degrees(steps), 2.0, atol=1e-9)
    avia = sim.simulate(room, sim.Sensor("avia"), turn[::5])
    full = sim.simulate(room, sim.Sensor("vlp16"), turn[::5])
    pts = [_voxels(_world_points(s, p)) for s, p in zip(avia.scans, avia.poses)]
    assert all(len(s) > 5000 for s in avia.scans)
    near, far = [], []
    for a in range(len(pts)):
        for b in range(a + 1, len(pts)):
            gap = abs(float(avia.trajectory.headings[a] - avia.trajectory.headings[b] + 180.0) % 360.0 - 180.0)
            if gap <= 10.0:
                near.append(_overlap(pts[a], pts[b]))
            elif gap > 90.0:
                far.append(_overlap(pts[a], pts[b]))
    print(f"\nroom, avia: voxel overlap {np.mean(near):.2f} within 10°, at most {max(far):.3f} beyond 90°")
    # The Avia's ~70° views share most of what they see 10° apart and nothing beyond 90°, while a
    # 360° sensor sees the same room from every heading.
    assert np.mean(near) > 0.3 and max(far) < 0.02
    full_pts = [_voxels(_world_points(s, p)) for s, p in zip(full.scans, full.poses)]
    assert _overlap(full_pts[0], full_pts[len(full_pts) // 2]) > 0.3


def test_odometry_drifts_as_configured_and_noise_is_seeded() -> None:
    world = sim.World(seed=1, slope=(0.0, 0.0))
    line = sim.Trajectory.from_waypoints(world, [(0.0, 0.0), (300.0, 0.0)], spacing=1.0)
    length = 300.0
    # Scale: the end is scale · L too far along the line.
    odom = line.odometry(scale_error=0.01)
    np.testing.assert_allclose(odom.positions[-1] - line.positions[-1], [3.0, 0.0, 0.0], atol=1e-9)
    # Yaw bias b (deg/m): the end is b·L degrees off and about b·L²/2 (in radians) sideways.
    b = 0.005
    odom = line.odometry(yaw_bias_deg_per_m=b)
    assert abs(sim.true_heading(line.poses[-1], odom.poses[-1]) - b * length) < 1e-9
    side = odom.positions[-1, 1] - line.positions[-1, 1]
    assert abs(side / (np.radians(b) * length**2 / 2.0) - 1.0) < 0.02
    per_frame = line.odometry(yaw_bias_deg_per_frame=b)  # 1 m per frame: the same drift
    np.testing.assert_allclose(per_frame.poses, odom.poses, atol=1e-9)
    # Noise: reproducible by seed, different across seeds, and growing with the path.
    noisy: dict[str, Any] = dict(translation_noise=0.02, rotation_noise_deg=0.05)
    a = line.odometry(seed=7, **noisy)
    assert a.poses.tobytes() == line.odometry(seed=7, **noisy).poses.tobytes()
    assert a.poses.tobytes() != line.odometry(seed=8, **noisy).poses.tobytes()
    errors = np.array([
        np.linalg.norm(line.odometry(seed=s, **noisy).positions - line.positions, axis=1) for s in range(20)
    ])
    rms = np.sqrt((errors**2).mean(axis=0))
    assert rms[0] == 0.0 and rms[30] < rms[150] < rms[300]
    np.testing.assert_array_equal(a.times, line.times)
    with pytest.raises(ValueError, match="scale_error"):
        line.odometry(scale_error=1.5)


def test_odometry_can_break_down_for_a_stretch_and_drift_by_a_documented_percent() -> None:
    """Issue 41's cases: a few keyframe steps of tens of metres and tens of metres of climb, then
    right steps again (the error stays); the drift class "p %" grows linearly with p."""
    world = sim.World(seed=1, slope=(0.0, 0.0))
    line = sim.Trajectory.from_waypoints(world, [(0.0, 0.0), (120.0, 0.0)], spacing=4.0)
    odom = line.odometry(breakdown=(10, 13), breakdown_jump_m=25.0, breakdown_climb_m=60.0, seed=3)
    steps = np.linalg.norm(np.diff(odom.positions[:, :2], axis=0), axis=1)
    climb = np.diff(odom.positions[:, 2] - line.positions[:, 2])
    inside = np.zeros(len(steps), dtype=bool)
    inside[9:12] = True  # the steps into frames 10, 11, 12
    assert np.all((steps[inside] > 20.0) & (steps[inside] < 30.0))
    np.testing.assert_allclose(steps[~inside], 4.0, atol=1e-6)
    np.testing.assert_allclose(climb[inside], 20.0, atol=1e-6)
    np.testing.assert_allclose(climb[~inside], 0.0, atol=1e-6)
    np.testing.assert_allclose(odom.positions[9], line.positions[9], atol=1e-9)
    with pytest.raises(ValueError, match="breakdown"):
        line.odometry(breakdown=(5, 2))
    # The drift class: the end's error grows with the percent (1 % of scale per percent and yaw).
    loop = sim.Trajectory.loop(world, spacing=4.0)
    end = [np.linalg.norm(loop.drifting(p, seed=1).positions[-1] - loop.positions[-1]) for p in (1, 2, 5)]
    assert 0.5 < end[0] < end[1] < end[2]
    assert end[2] / end[0] > 3.0


def test_the_away_route_never_comes_near_the_maps_lap() -> None:
    world = sim.World(seed=1, repetition=0.9)
    lap, _ = sim.session_routes(world, spacing=4.0)
    away = sim.away_route(world, spacing=4.0)
    d = np.linalg.norm(away.positions[:, None, :2] - lap.positions[None, :, :2], axis=2)
    assert d.min() > 30.0


def test_odometry_is_written_beside_the_truth(tmp_path: Path) -> None:
    world = sim.World.corridors(seed=5, modules=2)
    walk = sim.Trajectory.corridor_walk(world, laps=0.1, spacing=4.0)
    odom = walk.odometry(yaw_bias_deg_per_m=0.02, scale_error=0.01, seed=1)
    n = sim.write_sequence(tmp_path / "s", world, sim.Sensor("vlp16"), walk, odometry=odom)
    truth = np.loadtxt(tmp_path / "s" / "poses.txt").reshape(-1, 3, 4)
    drift = np.loadtxt(tmp_path / "s" / sim.ODOMETRY_FILE).reshape(-1, 3, 4)
    assert n == len(walk) == len(drift)
    np.testing.assert_allclose(truth, walk.poses, atol=1e-9)
    np.testing.assert_allclose(drift, odom.poses, atol=1e-9)
    assert np.linalg.norm(drift[-1, :, 3] - truth[-1, :, 3]) > 0.05
    with pytest.raises(ValueError, match="odometry"):
        sim.write_sequence(tmp_path / "t", world, sim.Sensor("vlp16"), walk, odometry=odom[:3])


def _h(p: F64) -> F64:
    return np.vstack([p, [0.0, 0.0, 0.0, 1.0]])


def test_two_sessions_relate_by_the_stated_anchor(tmp_path: Path) -> None:
    world = sim.World.corridors(seed=6, modules=2)
    first, second = sim.corridor_sessions(world, laps=1.0)
    # Different starting places and headings.
    assert np.linalg.norm(first.positions[0] - second.positions[0]) > 50.0
    assert abs(abs(sim.true_heading(first.poses[0], second.poses[0])) - 90.0) < 1e-6
    a, b = sim.Session.of(first), sim.Session.of(second)
    np.testing.assert_allclose(a.trajectory.poses[0], np.eye(4)[:3], atol=1e-12)
    np.testing.assert_allclose(b.trajectory.poses[0], np.eye(4)[:3], atol=1e-12)
    np.testing.assert_allclose(b.in_world().poses, second.poses, atol=1e-9)
    anchor = b.anchor(a)
    # The anchor takes session b's poses to where session a's frame has them ...
    for k in (0, 17, len(second) - 1):
        np.testing.assert_allclose(_h(anchor) @ _h(b.trajectory.poses[k]), np.linalg.inv(_h(a.frame)) @ _h(second.poses[k]), atol=1e-9)
    # ... so a scan of b placed by the anchor lands on the same walls as a's scan of that place.
    sensor = sim.Sensor("vlp16", noise=0.0)
    kb = 10
    ka = int(np.argmin(np.linalg.norm(first.positions - second.positions[kb], axis=1)))
    in_a = _world_points(sim.scan(world, sensor, second.poses[kb]), (_h(anchor) @ _h(b.trajectory.poses[kb]))[:3])
    seen_a = _world_points(sim.scan(world, sensor, first.poses[ka]), a.trajectory.poses[ka])
    assert _overlap(_voxels(seen_a), _voxels(in_a)) > 0.3
    # Written in their own frames, with the anchor beside each.
    folders = sim.write_sessions(tmp_path, world, sensor, [first[:5], second[:5]], own_frames=True,
                                 odometry=[first[:5].odometry(scale_error=0.02), second[:5].odometry(scale_error=0.02)])
    for folder, sess in zip(folders, (a, b)):
        poses = np.loadtxt(folder / "poses.txt").reshape(-1, 3, 4)
        np.testing.assert_allclose(poses, sess.trajectory.poses[:5], atol=1e-9)
        odom = np.loadtxt(folder / sim.ODOMETRY_FILE).reshape(-1, 3, 4)
        np.testing.assert_allclose(odom[0], np.eye(4)[:3], atol=1e-9)
    np.testing.assert_allclose(np.loadtxt(folders[0] / sim.ANCHOR_FILE), np.eye(4)[:3].ravel(), atol=1e-12)
    np.testing.assert_allclose(np.loadtxt(folders[1] / sim.ANCHOR_FILE), anchor.ravel(), atol=1e-9)


def test_indoor_worlds_pickle_and_reject_bad_parameters() -> None:
    world = sim.World.corridors(seed=2, modules=2, jitter=0.3)
    back = pickle.loads(pickle.dumps(world))
    assert back.layout == "corridors" and len(back) == len(world)
    room = pickle.loads(pickle.dumps(sim.World.room(seed=3, furniture=4)))
    assert room.layout == "room" and len(room) == len(sim.World.room(seed=3, furniture=4))
    with pytest.raises(ValueError, match="width"):
        sim.World.corridors(width=1.0)
    with pytest.raises(ValueError, match="size"):
        sim.World.room(size=(2.0, 5.0))
    with pytest.raises(ValueError, match="wobble"):
        sim.Trajectory.turn_in_place(room, wobble=9.0)
    with pytest.raises(ValueError, match="furniture"):
        sim.World.room(furniture=-1)
