"""Issue 27: from loops to a consistent map — the pose graph, its robust optimisation, anchors.

The simulator gives exact truth; its drifting odometry (:meth:`solid.sim.Trajectory.odometry`: a
yaw bias and noise per step, a scale error) is what the pipeline is given, and on hku1 the same
drift is injected into the recording's odometry, which is the truth there.
"""

from __future__ import annotations

import dataclasses
import json
import math
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest

import solid
from solid import sim, slam
from solid.cli import main
from solid.commands import map_info
from solid.config import PipelineConfig
from solid.datasets.poses import load_poses
from solid.pipeline import LoopClosurePipeline
from solid.slam import as4, inv

from conftest import data_dir, read_csv

gtsam = pytest.importorskip("gtsam", reason="the [slam] extra (gtsam) is not installed")

F64 = npt.NDArray[np.float64]


# ---- the simulator: 1.2 laps through look-alike blocks, ~1 % drift ---------------------------------

SEEDS = range(5)


def sim_run(seed: int) -> tuple[Any, F64, F64]:
    """Frames 6 m apart: a lap is 54 frames, so with the preset's 50 excluded frames only the
    revisit's queries reach verification (at 4 m, 31 more first-lap queries did, 3× the time)."""
    world = sim.World(seed=seed, repetition=0.9)
    traj = sim.Trajectory.loop(world, laps=1.2, spacing=6.0)
    # 0.1° of yaw per 4 m, 1 % of scale, 0.05° of yaw noise per frame.
    odom = traj.odometry(yaw_bias_deg_per_m=0.025, scale_error=0.01, rotation_noise_deg=0.05, seed=seed)
    seq = dataclasses.replace(sim.simulate(world, sim.Sensor("vlp16"), traj), trajectory=odom)
    res = LoopClosurePipeline(seq, PipelineConfig.preset("vlp16")).run()
    return res, as4(traj.poses), as4(odom.poses)


def no_revisit_run() -> tuple[Any, F64, F64]:
    """sim.session_routes' second route goes east, north and east again, never back; in a world
    of look-alike blocks its end looks like its start. The detector's checks against the poses
    (issue 26) refuse those loops; switched off here, it returns them as a detector without poses
    would, for the back-end to refuse."""
    world = sim.World(seed=0, repetition=0.9)
    _, route = sim.session_routes(world, spacing=6.0)
    odom = route.odometry(yaw_bias_deg_per_m=0.025, scale_error=0.01, rotation_noise_deg=0.05, seed=0)
    seq = dataclasses.replace(sim.simulate(world, sim.Sensor("vlp16"), route), trajectory=odom)
    cfg = PipelineConfig.preset("vlp16", detector={"odometry_check": False, "unique": False, "min_support": 0})
    return LoopClosurePipeline(seq, cfg).run(), as4(route.poses), as4(odom.poses)


@pytest.fixture(scope="module")
def pipeline_runs() -> list[tuple[Any, F64, F64]]:
    """The five seeds' runs, then the no-revisit route's. Two at a time: the runs are
    independent, and one alone does not keep two cores busy."""
    with ThreadPoolExecutor(2) as pool:
        return list(pool.map(lambda job: job(), [*(partial(sim_run, seed) for seed in SEEDS), no_revisit_run]))


@pytest.fixture(scope="module")
def sim_runs(pipeline_runs: list[tuple[Any, F64, F64]]) -> list[tuple[Any, F64, F64]]:
    return pipeline_runs[: len(SEEDS)]


def test_optimize_reaches_the_true_loops_optimum_despite_false_loops(sim_runs: list[tuple[Any, F64, F64]]) -> None:
    """Done means: trajectory error ≤ 1.1× the optimum with only the true loops, ≤ 0.3× odometry;
    with false loops injected on top of the detector's own."""
    for seed, (res, truth, odo) in zip(SEEDS, sim_runs):
        out = slam.optimize_run(res)
        graph = out.graph
        loops = graph.loops()
        assert loops, f"seed {seed}: no loop"
        true_only = slam.PoseGraph(ids=graph.ids, poses=graph.poses)
        for e, kind in enumerate(graph.kinds):
            i, j = int(graph.edge_from[e]), int(graph.edge_to[e])
            err = np.linalg.norm((inv(truth[i]) @ truth[j])[:3, 3] - graph.measurements[e][:3, 3])
            if kind == "odometry" or err < 1.0:
                true_only.add_edge(i, j, graph.measurements[e], graph.information[e], kind)
        best, _ = slam.optimize_graph(true_only, "none")
        # Five false loops between places far apart, weighed like a real loop.
        rng = np.random.default_rng(seed)
        n = len(graph)
        while len(graph.loops()) < len(loops) + 5:
            q, c = int(rng.integers(n // 2, n)), int(rng.integers(0, 10))
            if np.linalg.norm(truth[q][:3, 3] - truth[c][:3, 3]) > 20:
                graph.add_edge(q, c, np.eye(4), graph.information[loops[0]], "loop")
        opt, w = slam.optimize_graph(graph)
        ate = {k: slam.absolute_trajectory_error(P, truth) for k, P in (("odo", odo), ("best", best), ("opt", opt))}
        assert ate["opt"] <= 1.1 * ate["best"], (seed, ate)
        assert ate["opt"] <= 0.3 * ate["odo"], (seed, ate)
        assert not (w[len(loops) :] > 0.5).any(), f"seed {seed}: a false loop was trusted"


def _true_loops_optimum(graph: slam.PoseGraph, truth: F64, build: Any) -> float:
    """The best ATE the graph's true loops (within 1 m of the truth) reach in plain least squares,
    over odometry noises from the default to 16× it: the optimum of the same loops with the noise
    that suits this odometry best."""
    best = math.inf
    for k in (1.0, 2.0, 4.0, 8.0, 16.0):
        g = build(slam.OdometryNoise().scaled(k))
        true_only = slam.PoseGraph(ids=g.ids, poses=g.poses)
        for e, kind in enumerate(g.kinds):
            i, j = int(g.edge_from[e]), int(g.edge_to[e])
            if kind == "odometry" or np.linalg.norm((inv(truth[i]) @ truth[j])[:3, 3] - g.measurements[e][:3, 3]) < 1.0:
                true_only.add_edge(i, j, g.measurements[e], g.information[e], kind)
        best = min(best, slam.absolute_trajectory_error(slam.optimize_graph(true_only, "none")[0], truth))
    return best


@pytest.mark.parametrize("drift", [1, 2, 3, 5])
def test_optimize_fits_the_odometry_noise_to_a_drift_of_several_percent(sim_runs: list[tuple[Any, F64, F64]], drift: int) -> None:
    """Issue 41: the odometry drifting 1–5 % (yaw 0.025°/m and 1 % of scale per percent; the
    detector's loops of the five seeds, its pipeline run on the 1 % odometry): the back-end
    keeps every true loop and ends within 1.2× the ATE of the same true loops under the noise
    that suits the odometry best. With the noise as given alone, GNC-TLS kept none of them at
    5 % and returned the odometry."""
    fitted = 0
    for seed, (res, truth, _) in zip(SEEDS, sim_runs):
        traj = sim.Trajectory(truth[:, :3, :], np.asarray(res.timestamps, dtype=np.float64))
        P = as4(traj.odometry(yaw_bias_deg_per_m=0.025 * drift, scale_error=0.01 * drift, rotation_noise_deg=0.05, seed=seed).poses)
        out = slam.optimize_run(dataclasses.replace(res, poses=P))
        loops = out.graph.loops()
        assert loops, f"seed {seed}: no loop"
        ate = slam.absolute_trajectory_error(out.optimized, truth)
        best = _true_loops_optimum(out.graph, truth, lambda n: slam.graph_from_run(res, n, poses=P))
        assert out.trusted_loops() == len(loops), (seed, drift, out.noise_scale, out.loop_weights)
        assert ate <= 1.2 * best, (seed, drift, out.noise_scale, ate, best)
        # Up to 3 % the noise as given keeps every loop: no fit.
        assert drift == 5 or out.noise_scale == 1.0, (seed, drift, out.noise_scale)
        fitted += out.noise_scale > 1.0
    # At 5 % the noise as given keeps none of most seeds' loops, and the fit takes over (seed 0's
    # 12 loops, with its revisit's first since the next steps' support, hold with the noise as
    # given: 4 of 5 seeds fitted).
    assert (fitted >= 3) == (drift == 5), (drift, fitted)


def test_the_noise_fit_keeps_the_default_when_the_loops_agree_with_the_odometry() -> None:
    """A straight drive measured exactly and loops that agree with it to a millimetre need no
    looser odometry; loops 50 m off a 156 m drive are beyond any drift the fit allows, so they
    cannot loosen it either (the fit returns 1: most loops false)."""
    X = np.stack([np.eye(4)] * 40)
    X[:, 0, 3] = np.arange(40) * 4.0
    graph = slam.odometry_graph(np.arange(40), X)
    info = np.diag([1e4] * 3 + [1e6] * 3)
    for q, c in ((30, 5), (35, 5), (38, 12)):
        Z = inv(X[q]) @ X[c]
        Z[1, 3] += 1e-3
        graph.add_edge(q, c, Z, info, "loop")
    assert slam.fit_odometry_scale(graph) == 1.0
    assert np.all(slam.loop_chi2(graph) < slam.CHI2_6_MEDIAN)
    far = slam.odometry_graph(np.arange(40), X)
    for q, c in ((30, 5), (35, 5), (38, 12)):
        far.add_edge(q, c, np.eye(4), info, "loop")  # each says the two places are one
    assert slam.fit_odometry_scale(far) == 1.0
    # The same loops with an odometry 5 % short: the fit loosens it, within the ceiling.
    short = X.copy()
    short[:, 0, 3] *= 0.95
    drifted = slam.odometry_graph(np.arange(40), short)
    for q, c in ((30, 5), (35, 5), (38, 12)):
        drifted.add_edge(q, c, inv(X[q]) @ X[c], info, "loop")
    k = slam.fit_odometry_scale(drifted)
    assert 1.0 < k < slam.ODOMETRY_SCALE_MAX
    assert np.median(slam.loop_chi2(drifted, k)) == pytest.approx(slam.CHI2_6_MEDIAN, rel=1e-3)


def test_without_a_robust_scheme_false_loops_ruin_the_map(sim_runs: list[tuple[Any, F64, F64]]) -> None:
    """Why the back-end is robust: the same graph in plain least squares."""
    res, truth, odo = sim_runs[0]
    graph = slam.graph_from_run(res)
    info = graph.information[graph.loops()[0]]
    graph.add_edge(len(graph) - 1, 0, np.eye(4), info, "loop")  # the last frame is not the first
    opt, _ = slam.optimize_graph(graph, "none")
    assert slam.absolute_trajectory_error(opt, truth) > slam.absolute_trajectory_error(odo, truth)



def test_the_tls_guard_restores_the_true_loops_gnc_tls_alone_drops(monkeypatch: pytest.MonkeyPatch) -> None:
    """``optimize_graph``'s GNC-TLS guard (docs/slam.md#robust-back-end) on a graph made here: a
    square lap of 4 m steps (40 poses) and 10 more along its first side, the odometry turning
    0.25° a frame too far (1.6 m ATE); 10 true loops (the last 10 poses onto the first 10) and 6
    false ones (each saying two places 40-70 m apart are one), all weighed alike. GNC-TLS alone
    settles in the minimum of every loop out, the odometry's; the Cauchy optimum's loops within
    the inlier threshold are the lower TLS cost, so the guard returns the optimum of the 10 true
    loops and no false one."""
    def turn(deg: float) -> F64:
        T = np.eye(4)
        c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
        T[:2, :2] = [[c, -s], [s, c]]
        return T

    step = np.eye(4)
    step[0, 3] = 4.0
    truth = [np.eye(4)]
    for k in range(49):
        truth.append(truth[-1] @ step @ turn(90.0 if (k + 1) % 10 == 0 else 0.0))
    T = np.stack(truth)
    X = [np.eye(4)]
    for k in range(49):
        X.append(X[-1] @ inv(T[k]) @ T[k + 1] @ turn(0.25))
    odometry = np.stack(X)
    info = np.diag([1e4] * 3 + [1e6] * 3)

    def with_true_loops() -> slam.PoseGraph:
        g = slam.PoseGraph(ids=np.arange(50), poses=odometry)
        for k in range(49):
            g.add_edge(k, k + 1, inv(odometry[k]) @ odometry[k + 1], slam.OdometryNoise().information(4.0), "odometry")
        for q in range(40, 50):
            g.add_edge(q, q - 40, inv(T[q]) @ T[q - 40], info, "loop")
        return g

    graph, true_only = with_true_loops(), with_true_loops()
    for f in range(6):
        graph.add_edge(40 + f, 12 + 3 * f, np.eye(4), info, "loop")
    best, _ = slam.optimize_graph(true_only, "none")

    def gnc_alone(*args: Any) -> tuple[Any, F64]:
        """The guard that keeps GNC-TLS's own optimum and weights (its last two arguments)."""
        return args[-2], args[-1]

    monkeypatch.setattr(slam, "_tls_guard", gnc_alone)
    alone, w = slam.optimize_graph(graph)
    monkeypatch.undo()
    assert not (w > 0.5).any()
    np.testing.assert_allclose(alone, odometry, atol=1e-6)
    P, w = slam.optimize_graph(graph)
    assert (w[:10] > 0.5).all() and not (w[10:] > 0.5).any()
    np.testing.assert_allclose(P, best, atol=1e-6)
    ate = slam.absolute_trajectory_error
    assert ate(P, T) < 0.1 < 1.0 < ate(odometry, T)


def test_loops_the_robust_optimum_rejects_do_not_move_the_map() -> None:
    """GNC-TLS rejects with weights of about 1e-5, not 0; over a long, loose odometry chain that
    was enough for three contradictory loops to move a straight 156 m drive by 7 m. What is
    returned is the optimum of the loops kept: here none, so the odometry itself."""
    X = np.stack([np.eye(4)] * 40)
    X[:, 0, 3] = np.arange(40) * 4.0
    graph = slam.PoseGraph(ids=np.arange(40), poses=X)
    for k in range(39):
        graph.add_edge(k, k + 1, inv(X[k]) @ X[k + 1], slam.OdometryNoise().information(4.0), "odometry")
    for q, c in ((30, 5), (35, 5), (38, 12)):  # each says the two places are one
        graph.add_edge(q, c, np.eye(4), np.diag([1e4] * 3 + [1e6] * 3), "loop")
    P, w = slam.optimize_graph(graph)
    assert (w < 0.5).all()
    assert np.abs(P[:, :3, 3] - X[:, :3, 3]).max() < 1e-6


def test_a_route_that_never_comes_back_stays_on_its_odometry(pipeline_runs: list[tuple[Any, F64, F64]]) -> None:
    """Done means: a stretch with no true revisit stays within 0.2 m of its odometry. The
    detector returns loops at the no-revisit route's end, all false, that agree with each other;
    with the former odometry noise (0.2°/m) GNC-TLS kept 8 of them and folded the route 193 m
    onto its start."""
    res, truth, _ = pipeline_runs[len(SEEDS)]
    out = slam.optimize_run(res)
    loops = out.graph.loops()
    assert loops  # the case is only a test with loops to refuse
    assert all(np.linalg.norm(truth[out.graph.edge_from[e], :3, 3] - truth[out.graph.edge_to[e], :3, 3]) > 100 for e in loops)
    assert np.abs(out.optimized[:, :3, 3] - out.odometry[:, :3, 3]).max() <= 0.2

def test_the_detector_itself_refuses_the_no_revisit_routes_look_alikes() -> None:
    """The same route through the shipped detector (its checks against the drifting odometry on):
    no loop joins places more than 100 m apart."""
    world = sim.World(seed=0, repetition=0.9)
    _, route = sim.session_routes(world, spacing=6.0)
    odom = route.odometry(yaw_bias_deg_per_m=0.025, scale_error=0.01, rotation_noise_deg=0.05, seed=0)
    seq = dataclasses.replace(sim.simulate(world, sim.Sensor("vlp16"), route), trajectory=odom)
    res = LoopClosurePipeline(seq, PipelineConfig.preset("vlp16")).run()
    truth = as4(route.poses)
    far = [lp for lp in res.loops() if np.linalg.norm(truth[lp.query, :3, 3] - truth[lp.candidate, :3, 3]) > 100]
    assert not far


# ---- hku1 with injected drift --------------------------------------------------------------------


@pytest.fixture(scope="module")
def hku1_optimized(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = data_dir() / "hku1-avia"
    if not root.is_dir():
        pytest.skip("shared data not present")
    tmp = tmp_path_factory.mktemp("hku1")
    G, _ = load_poses(root / "odom_poses.txt")
    # The injected drift: 0.02° of yaw per frame, 1 % of scale.
    odom = sim.Trajectory(G, np.arange(len(G), dtype=np.float64)).odometry(yaw_bias_deg_per_frame=0.02, scale_error=0.01)
    np.savetxt(tmp / "drift.txt", odom.poses.reshape(-1, 12))
    code = main(
        ["optimize", str(root), "--poses", str(tmp / "drift.txt"), "--truth", str(root / "odom_poses.txt"),
         "--preset", "avia", "-o", str(tmp / "out"), "-q"]
    )  # fmt: skip
    assert code == 0
    return tmp / "out"


def test_hku1_drift_is_corrected(hku1_optimized: Path) -> None:
    m = json.loads((hku1_optimized / "metrics.json").read_text())
    assert m["optimized"]["ate_m"] <= 0.15, m
    assert m["optimized"]["ate_m"] < m["odometry"]["ate_m"] / 3, m
    G, _ = load_poses(data_dir() / "hku1-avia" / "odom_poses.txt")
    P, _ = load_poses(hku1_optimized / "trajectory.kitti")
    Q, t = load_poses(hku1_optimized / "trajectory.tum")
    assert len(P) == len(G) == len(Q) and t is not None
    assert np.allclose(P, Q, atol=1e-4)  # the quaternion re-orthonormalises a 6-digit rotation
    assert slam.absolute_trajectory_error(P, G) == pytest.approx(m["optimized"]["ate_m"], rel=1e-6)


def test_g2o_loads_in_gtsam_as_a_full_graph_with_the_same_optimum(hku1_optimized: Path) -> None:
    graph, initial = gtsam.readG2o(str(hku1_optimized / "graph.g2o"), True)
    P, _ = load_poses(hku1_optimized / "trajectory.kitti")
    m = json.loads((hku1_optimized / "metrics.json").read_text())
    assert initial.size() == len(P)  # a value for every frame
    assert graph.size() == (len(P) - 1) + m["loop_edges"]
    # GTSAM's own GNC (truncated least squares) on the file as read, odometry and the prior known
    # to be inliers, at the documented threshold, reaches solid optimize's optimum and keeps the
    # same number of loops.
    graph.add(gtsam.PriorFactorPose3(0, initial.atPose3(0), gtsam.noiseModel.Isotropic.Sigma(6, 1e-6)))
    known = [k for k in range(graph.size()) if len(graph.at(k).keys()) == 1 or abs(graph.at(k).keys()[0] - graph.at(k).keys()[1]) == 1]
    assert len(known) == len(P)  # the prior and the odometry edges
    params = gtsam.GncLMParams(gtsam.LevenbergMarquardtParams())
    params.setLossType(gtsam.GncLossType.TLS)
    params.setKnownInliers(known)
    opt = gtsam.GncLMOptimizer(graph, initial, params)
    opt.setInlierCostThresholds(slam.GNC_INLIER_CHI2 / 2)  # GTSAM's factor error is χ²/2
    result = opt.optimize()
    kept = sum(1 for k, w in enumerate(np.asarray(opt.getWeights())) if k not in known and w > 0.5)
    assert kept == m["loop_edges_kept"] and kept >= m["loop_edges"] - 2
    ours = np.stack([np.asarray(result.atPose3(k).matrix())[:3] for k in range(len(P))])
    assert np.abs(ours[:, :, 3] - P[:, :, 3]).max() < 0.005


def test_a_runs_graph_is_optimised_again_from_its_g2o_file(hku1_optimized: Path) -> None:
    """A run's loops are reused without the detector: graph.g2o read back gives the same graph
    (odometry and loop edges told apart) and the same optimum."""
    graph = slam.PoseGraph.read_g2o(hku1_optimized / "graph.g2o")
    m = json.loads((hku1_optimized / "metrics.json").read_text())
    P, _ = load_poses(hku1_optimized / "trajectory.kitti")
    assert len(graph) == len(P) and len(graph.loops()) == m["loop_edges"]
    assert graph.kinds.count("odometry") == len(P) - 1
    opt, w = slam.optimize_graph(graph)
    assert int(np.sum(w > 0.5)) == m["loop_edges_kept"]
    assert np.abs(opt[:, :3, 3] - P[:, :, 3]).max() < 1e-3


def test_optimize_reuses_a_runs_loops_without_the_detector(hku1_optimized: Path, tmp_path: Path) -> None:
    """`solid optimize --loops RUN` reads the run's graph.g2o, joins its loops to the odometry of
    --poses and reaches the optimum of the run that detected them; loops measured with other
    poses are refused."""
    root = data_dir() / "hku1-avia"
    drift = hku1_optimized.parent / "drift.txt"
    args = ["optimize", str(root), "--poses", str(drift), "--truth", str(root / "odom_poses.txt"), "--preset", "avia", "--no-plots", "-q"]
    assert main([*args, "--loops", str(hku1_optimized), "-o", str(tmp_path / "again")]) == 0
    m0 = json.loads((hku1_optimized / "metrics.json").read_text())
    m1 = json.loads((tmp_path / "again" / "metrics.json").read_text())
    assert m1["loops_from"] == str(hku1_optimized.absolute()) and m1["timing"]["detect_s"] == 0
    assert (m1["loop_edges"], m1["loop_edges_kept"]) == (m0["loop_edges"], m0["loop_edges_kept"])
    assert m1["optimized"]["ate_m"] == pytest.approx(m0["optimized"]["ate_m"], abs=1e-6)
    P0, _ = load_poses(hku1_optimized / "trajectory.kitti")
    P1, _ = load_poses(tmp_path / "again" / "trajectory.kitti")
    assert np.abs(P0 - P1).max() < 1e-6
    # loops.csv names the same loops (frames and poses; the detector's scores are the run's). The
    # poses went through graph.g2o's 9 decimals, so the CSV's 6-decimal rounding may differ by its
    # last digit.
    again, run = read_csv(tmp_path / "again" / "loops.csv"), read_csv(hku1_optimized / "loops.csv")
    frames = ("query_frame", "candidate_frame")
    assert [tuple(r[k] for k in frames) for r in again] == [tuple(r[k] for k in frames) for r in run]
    pose = ("x", "y", "z", "qw")
    assert np.abs(np.array([[float(r[k]) for k in pose] for r in again]) - np.array([[float(r[k]) for k in pose] for r in run])).max() <= 1.5e-6
    # The same loops against other poses (the truth): another frame, refused before anything is written.
    other = [*args[:3], str(root / "odom_poses.txt"), *args[4:]]
    assert main([*other, "--loops", str(hku1_optimized / "graph.g2o"), "-o", str(tmp_path / "other")]) == 1
    assert main([*args, "--loops", str(tmp_path), "-o", str(tmp_path / "none")]) == 1  # a folder without a graph
    assert not (tmp_path / "other").exists() and not (tmp_path / "none").exists()


def test_detect_g2o_is_optimised_as_optimize_would(sim_runs: list[tuple[Any, F64, F64]], tmp_path: Path) -> None:
    """The file `solid detect --g2o` writes (:func:`solid.commands.write_g2o`), given back to
    `solid optimize --loops`, gives the optimum of `solid optimize` running the detector
    (:func:`solid.slam.optimize_run` on the same run); a file without vertices (a run without
    poses) is read as loop edges alone."""
    from solid import commands

    res, _, odo = sim_runs[0]
    commands.write_g2o(tmp_path / "det.g2o", res)
    world = sim.World(seed=0, repetition=0.9)
    traj = sim.Trajectory.loop(world, laps=1.2, spacing=6.0)
    odom = traj.odometry(yaw_bias_deg_per_m=0.025, scale_error=0.01, rotation_noise_deg=0.05, seed=0)
    seq = dataclasses.replace(sim.simulate(world, sim.Sensor("vlp16"), traj), trajectory=odom)
    assert np.allclose(as4(seq.poses), odo)
    cfg = PipelineConfig.preset("vlp16")
    run = commands.optimize(seq, cfg, commands.Inputs(tmp_path / "sim"), output=tmp_path / "out", plots=False, loops_from=tmp_path / "det.g2o")
    expected = slam.optimize_run(res)
    assert len(run.slam.graph.loops()) == len(expected.graph.loops()) > 0
    assert run.slam.trusted_loops() == expected.trusted_loops()
    assert np.abs(run.slam.optimized - expected.optimized).max() < 1e-6
    # Without poses the detector's file holds its loop edges alone, between frame numbers.
    loops_only = [s for s in (tmp_path / "det.g2o").read_text().splitlines() if s.startswith("EDGE") and abs(int(s.split()[1]) - int(s.split()[2])) > 1]
    (tmp_path / "loops.g2o").write_text("".join(s + "\n" for s in loops_only))
    graph = slam.PoseGraph.read_g2o(tmp_path / "loops.g2o")
    assert graph.kinds == ["loop"] * len(loops_only) and not np.isfinite(graph.poses).any()
    again = commands.optimize(seq, cfg, commands.Inputs(tmp_path / "sim"), output=tmp_path / "out2", plots=False, loops_from=tmp_path / "loops.g2o")
    assert np.abs(again.slam.optimized - expected.optimized).max() < 1e-6


def test_calib_puts_the_graph_and_the_trajectory_in_the_frame_of_the_poses(sim_runs: list[tuple[Any, F64, F64]], tmp_path: Path) -> None:
    """Poses of a body frame with `--calib` (T_body_lidar): `detect --g2o`'s graph
    (:func:`solid.commands.write_g2o`) and `optimize`'s trajectory and graph are in the body's
    frame, the optimum the LiDAR run's carried there; a graph written without the calibration is
    refused with it."""
    from solid import commands

    res, _, odo = sim_runs[0]
    E = np.eye(4)
    c, s = np.cos(np.radians(10.0)), np.sin(np.radians(10.0))
    E[:3, :3] = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) @ np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    E[:3, 3] = [0.3, -0.1, 0.5]
    body = E @ odo @ inv(E)  # what the dataset turns back into `odo` with the calibration
    world = sim.World(seed=0, repetition=0.9)
    sim.write_sequence(tmp_path / "seq", world, sim.Sensor("vlp16"), sim.Trajectory.loop(world, laps=1.2, spacing=6.0))
    np.savetxt(tmp_path / "body.txt", body[:, :3].reshape(-1, 12))
    np.savetxt(tmp_path / "extrinsic.txt", E[:3].reshape(1, 12))
    commands.write_g2o(tmp_path / "det.g2o", res, calib=E)
    written = slam.PoseGraph.read_g2o(tmp_path / "det.g2o")
    assert np.abs(written.poses - body).max() < 1e-6
    args = ["optimize", str(tmp_path / "seq"), "--poses", str(tmp_path / "body.txt"), "--loops", str(tmp_path / "det.g2o"), "--preset", "vlp16", "--no-plots", "-q"]
    assert main([*args, "--calib", str(tmp_path / "extrinsic.txt"), "-o", str(tmp_path / "out")]) == 0
    P, _ = load_poses(tmp_path / "out" / "trajectory.kitti")
    expected = E @ slam.optimize_run(res).optimized @ inv(E)
    assert np.abs(as4(P) - expected).max() < 1e-5
    assert np.abs(slam.PoseGraph.read_g2o(tmp_path / "out" / "graph.g2o").poses - body).max() < 1e-6
    # A graph written without the calibration (in the LiDAR's frame) does not fit these poses.
    commands.write_g2o(tmp_path / "lidar.g2o", res)
    args[args.index("--loops") + 1] = str(tmp_path / "lidar.g2o")
    assert main([*args, "--calib", str(tmp_path / "extrinsic.txt"), "-o", str(tmp_path / "mixed")]) == 1


# ---- two sessions: a map in another world ------------------------------------------------------


def test_eval_against_a_map_in_another_world_is_refused_or_anchored(tmp_path: Path) -> None:
    """eval --map never assumes one world: without a loop into the map it asks for an anchor;
    map merge asks to be told."""
    world = sim.World(seed=1)
    lap, second = sim.session_routes(world, spacing=4.0)
    s0, s1 = sim.write_sessions(tmp_path / "sim", world, sim.Sensor("vlp16"), [lap[:10], second[:6]])
    assert main(["map", "build", str(s0), "--preset", "vlp16", "--poses", "poses.txt", "-o", str(tmp_path / "m.soliddb"), "-q"]) == 0
    args = ["eval", str(s1), "--poses", "poses.txt", "--map", str(tmp_path / "m.soliddb"), "--no-plots", "-q"]
    assert main([*args, "-o", str(tmp_path / "a")]) == 1  # the route's first 6 frames never meet the lap's first 10
    np.savetxt(tmp_path / "anchor.txt", np.eye(4)[:3].reshape(1, 12))
    assert main([*args, "--anchor", str(tmp_path / "anchor.txt"), "-o", str(tmp_path / "b")]) == 0
    m = json.loads((tmp_path / "b" / "metrics.json").read_text())
    assert m["anchor"]["source"] == "given"
    assert main([*args, "--same-world", "-o", str(tmp_path / "c")]) == 0
    # Nor does map merge: two maps with poses are joined only when told their worlds are one.
    assert main(["map", "build", str(s1), "--preset", "vlp16", "--poses", "poses.txt", "-o", str(tmp_path / "m1.soliddb"), "-q"]) == 0
    merge = ["map", "merge", str(tmp_path / "m.soliddb"), str(tmp_path / "m1.soliddb"), "-q"]
    assert main([*merge, "-o", str(tmp_path / "both.soliddb")]) == 1
    assert not (tmp_path / "both.soliddb").exists()
    assert main([*merge, "--anchor", "same", "-o", str(tmp_path / "both.soliddb")]) == 0
    assert sorted(set(solid.Database.load(tmp_path / "both.soliddb").sessions.tolist())) == [0, 1]
    assert map_info(tmp_path / "both.soliddb")["anchors"] == [{"session": 1, "source": "same", "T_map_session": np.eye(4)[:3].tolist()}]


def test_a_session_whose_loops_into_the_map_contradict_each_other_stays_unanchored() -> None:
    """The joint optimisation's anchor is only as good as the loops it keeps: two loops that put
    the map 50 m apart leave nothing to trust; two that agree give the anchor exactly."""
    X = np.stack([np.eye(4)] * 10)
    X[:, 0, 3] = np.arange(10) * 2.0
    graph = slam.PoseGraph(ids=np.arange(10), poses=X)
    for k in range(9):
        graph.add_edge(k, k + 1, inv(X[k]) @ X[k + 1], slam.OdometryNoise().information(2.0), "odometry")
    loops = ([0, 9], [0, 1], np.stack([np.eye(4)] * 2), np.stack([np.eye(6) * 1e4] * 2))
    start = slam.Anchor(np.eye(4), 1, 2)
    apart = X[[0, 9]].copy()
    apart[1, 0, 3] += 50.0
    anchor, _, _ = slam.optimize_in_map(graph, apart, *loops, start)
    assert anchor is None
    north = X[[0, 9]].copy()
    north[:, 1, 3] += 5.0
    anchor, in_map, _ = slam.optimize_in_map(graph, north, *loops, start)
    assert anchor is not None and anchor.inliers == 2
    assert np.allclose(anchor.T_map_session[:3, 3], [0.0, 5.0, 0.0], atol=1e-6)
    assert np.allclose(in_map, anchor.T_map_session @ X, atol=1e-6)

def test_information_is_the_cores() -> None:
    """Loop.information is the registration's, carried over: symmetric positive definite."""
    world = sim.World(seed=3)
    x = world.roads[1]
    a, b = (sim.scan(world, sim.Sensor("vlp16"), p) for p in sim.Trajectory.spin(world, x, x, [0.0, 10.0]).poses)
    r = solid.register(b, a, yaws=[0.0, 10.0])
    info = r.information
    assert info.shape == (6, 6) and np.allclose(info, info.T, rtol=1e-9, atol=1e-6)
    assert np.linalg.eigvalsh(info).min() > 0
    # In the solver's coordinates (rotation first, about the query's origin), the covariance is
    # the Hessian's, scaled so its translation block's mean eigenvalue is 1 / LOOP_SIGMA_M² =
    # 1 / (9 mm)², plus LOOP_SIGMA_ROT_DEG² = (0.05°)² on each rotation axis.
    H = r.hessian
    want = np.linalg.inv(H * 3 / (np.trace(H[3:, 3:]) * 0.009**2))
    want[:3, :3] += np.radians(0.05) ** 2 * np.eye(3)
    R, t = r.pose[:3, :3], r.pose[:3, 3]
    ad = np.block([[R, np.zeros((3, 3))], [np.cross(np.eye(3), t) @ R, R]])  # δ = Ad(T)·ξ, as the core
    k = [3, 4, 5, 0, 1, 2]
    got = ad @ np.linalg.inv(info[np.ix_(k, k)]) @ ad.T
    d = np.sqrt(np.diag(want))
    assert np.allclose(got / np.outer(d, d), want / np.outer(d, d), atol=1e-6)


def test_true_loops_information_is_honest_on_the_simulator(sim_runs: list[tuple[Any, F64, F64]]) -> None:
    """The true errors of the simulator's true loops, weighed by their information, follow
    χ²(6) (mean 6; docs/slam.md#calibration): without the rotational floor the 100 m scans'
    Hessian made them 15× that (quartiles 5.4 / 28 / 136), with it 1.4 / 4.1 / 12.8, mean 7.4."""
    chi2 = []
    for res, truth, _ in sim_runs:
        g = slam.graph_from_run(res)
        for e in g.loops():
            i, j = int(g.edge_from[e]), int(g.edge_to[e])
            if np.linalg.norm((inv(truth[i]) @ truth[j])[:3, 3] - g.measurements[e][:3, 3]) > 1.0:
                continue  # a false loop: the robust back-end's business, not the calibration's
            noise = gtsam.noiseModel.Gaussian.Information(slam._gtsam_info(g.information[e]))
            f = gtsam.BetweenFactorPose3(0, 1, gtsam.Pose3(g.measurements[e]), noise)
            v = gtsam.Values()
            v.insert(0, gtsam.Pose3(truth[i]))
            v.insert(1, gtsam.Pose3(truth[j]))
            chi2.append(2 * f.error(v))
    assert len(chi2) >= 30
    assert 3 <= np.mean(chi2) <= 12, np.percentile(chi2, [25, 50, 75, 95])
    assert np.percentile(chi2, 75) < slam.GNC_INLIER_CHI2, np.percentile(chi2, [25, 50, 75, 95])


def test_a_drifting_session_is_anchored_in_a_map_by_a_joint_optimisation(tmp_path: Path) -> None:
    """Done means: two simulated sessions of one world, each in its own frame; the second's
    odometry drifts (0.025°/m, 1 %) and it drives on past the map into streets the map never
    saw. optimize --map puts its first frame within 0.2 m and 1° of the truth (0.01 m, 0.14°;
    fitted on the session's own optimised poses, as before, it was 0.45 m, 0.98°)."""
    world = sim.World(seed=1)
    lap, route = sim.session_routes(world, spacing=6.0)
    # The route from where it meets the lap, and 60 m on past where it leaves it.
    gap = np.linalg.norm(route.positions[:, None, :2] - lap.positions[None, :, :2], axis=2).min(axis=1)
    seen = np.flatnonzero(gap < 5.0)
    second = route[int(seen[0]) : int(seen[-1]) + 11]
    odom = second.odometry(yaw_bias_deg_per_m=0.025, scale_error=0.01, rotation_noise_deg=0.05, seed=1)
    s0, s1 = sim.write_sessions(tmp_path / "sim", world, sim.Sensor("vlp16"), [lap, second], own_frames=True, odometry=[lap, odom])
    db = tmp_path / "m.soliddb"
    assert main(["map", "build", str(s0), "--preset", "vlp16", "--poses", "poses.txt", "-o", str(db), "-q"]) == 0
    out = tmp_path / "out"
    # Two candidates verified per query, not five: half the time, the same loops into the map.
    args = ["optimize", str(s1), "--poses", "odometry.txt", "--truth", str(s1 / "poses.txt"), "--map", str(db), "--preset", "vlp16",
            "--verify-candidates", "2", "--no-plots", "-o", str(out), "-q"]  # fmt: skip
    assert main(args) == 0
    (est,), _ = load_poses(out / "anchor.txt")
    (true,), _ = load_poses(s1 / sim.ANCHOR_FILE)
    d = inv(as4(true)) @ as4(est)
    assert np.linalg.norm(est[:, 3] - true[:, 3]) <= 0.2
    assert np.degrees(np.arccos(np.clip((np.trace(d[:3, :3]) - 1) / 2, -1, 1))) <= 1.0
    m = json.loads((out / "metrics.json").read_text())
    assert m["anchor"]["inlier_loops"] >= m["anchor"]["cross_session_loops"] - 2
    # The map holds the session's shape too: better than its odometry against the truth.
    assert m["optimized"]["ate_m"] < m["odometry"]["ate_m"]


def test_a_map_merged_with_its_anchor_shares_the_first_maps_world(tmp_path: Path) -> None:
    """Two simulated sessions, each in its own frame: the second is anchored in the first's map
    by `solid optimize --map`, and `solid map merge --anchor anchor.txt` carries its map's poses
    into the first's world, within 0.2 m and 1° of the truth at every place, and records the
    anchor it applied."""
    world = sim.World(seed=2)
    lap, route = sim.session_routes(world, spacing=6.0)
    gap = np.linalg.norm(route.positions[:, None, :2] - lap.positions[None, :, :2], axis=2).min(axis=1)
    seen = np.flatnonzero(gap < 5.0)
    second = route[int(seen[0]) : int(seen[-1]) + 11]
    s0, s1 = sim.write_sessions(tmp_path / "sim", world, sim.Sensor("vlp16"), [lap, second], own_frames=True)
    build = ["map", "build", "--preset", "vlp16", "--poses", "poses.txt", "-q"]
    assert main([*build[:2], str(s0), *build[2:], "-o", str(tmp_path / "m0.soliddb")]) == 0
    assert main([*build[:2], str(s1), *build[2:], "-o", str(tmp_path / "m1.soliddb")]) == 0
    args = ["optimize", str(s1), "--poses", "poses.txt", "--map", str(tmp_path / "m0.soliddb"), "--preset", "vlp16",
            "--verify-candidates", "2", "--no-plots", "-o", str(tmp_path / "opt"), "-q"]  # fmt: skip
    assert main(args) == 0
    merge = ["map", "merge", str(tmp_path / "m0.soliddb"), str(tmp_path / "m1.soliddb"), "-q"]
    assert main([*merge, "--anchor", str(tmp_path / "opt" / "anchor.txt"), "-o", str(tmp_path / "both.soliddb")]) == 0
    both = solid.Database.load(tmp_path / "both.soliddb")
    m0 = solid.Database.load(tmp_path / "m0.soliddb")
    sessions = both.sessions
    assert sorted(set(sessions.tolist())) == [0, 1]
    assert np.array_equal(both.poses[sessions == 0], m0.poses)  # the first map's world is the merged map's
    (true,), _ = load_poses(s1 / sim.ANCHOR_FILE)
    G, _ = load_poses(s1 / "poses.txt")
    truth = as4(true) @ as4(G)
    got = as4(both.poses[sessions == 1])
    d = inv(truth) @ got
    assert np.linalg.norm(got[:, :3, 3] - truth[:, :3, 3], axis=1).max() <= 0.2
    assert np.degrees(np.arccos(np.clip((np.trace(d[:, :3, :3], axis1=1, axis2=2) - 1) / 2, -1, 1))).max() <= 1.0
    # Everything else of the second map as it was: places, clouds, times.
    m1 = solid.Database.load(tmp_path / "m1.soliddb")
    assert np.array_equal(both.r[sessions == 1], m1.r) and np.array_equal(both.a[sessions == 1], m1.a)
    assert both.clouds_stored == m0.clouds_stored + m1.clouds_stored
    (est,), _ = load_poses(tmp_path / "opt" / "anchor.txt")
    rec = map_info(tmp_path / "both.soliddb")["anchors"]
    assert [a["session"] for a in rec] == [1] and np.allclose(rec[0]["T_map_session"], est)
    assert rec[0]["source"] == str((tmp_path / "opt" / "anchor.txt").absolute())
    # An anchor file that is not one 3×4 row is refused, and nothing is written.
    (tmp_path / "two.txt").write_text((tmp_path / "opt" / "anchor.txt").read_text() * 2)
    assert main([*merge, "--anchor", str(tmp_path / "two.txt"), "-o", str(tmp_path / "bad.soliddb")]) == 1
    assert not (tmp_path / "bad.soliddb").exists()


def test_rotation_vector_keeps_the_angle_at_half_a_turn() -> None:
    """At 180° the skew part of R vanishes: the axis comes from (R + I)/2, the angle stays π."""
    from solid.slam import _rotation_vector

    def rot(axis: list[float], a: float) -> npt.NDArray[np.float64]:
        n = np.asarray(axis, float) / np.linalg.norm(axis)
        k = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
        return np.asarray(np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k, dtype=np.float64)

    cases: list[tuple[list[float], float]] = [([0, 0, 1], np.pi), ([1, 2, 3], np.pi), ([0, -1, 0], np.pi), ([1, 0, 0], 0.3), ([0, 1, 1], np.pi - 1e-9)]
    got = _rotation_vector(np.stack([rot(ax, a) for ax, a in cases]))
    for (ax, a), v in zip(cases, got):
        assert np.linalg.norm(v) == pytest.approx(a, abs=1e-9)
        n = np.asarray(ax, float) / np.linalg.norm(ax)
        assert abs(float(v @ n)) == pytest.approx(a, abs=1e-7)  # along the axis (either sign at π)
