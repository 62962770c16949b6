"""``solid view``: the rerun recording of a run, read back with rerun's own reader and checked
against the run's files (issue 40). Runs on a part of hku1 (frames 0-49 and 250-313: the walk's
start and its return, where its loops are)."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import data_dir, run

from solid.datasets import open_dataset
from solid.datasets.poses import load_poses, quat_to_matrix

rr = pytest.importorskip("rerun", reason="rerun-sdk is not installed (pip install 'solid-lidar[viewer]')")
FRAMES = "0:50,250:314"
FRAME_IDS = [*range(0, 50), *range(250, 314)]


def read_rrd(path: Path) -> dict[str, list[Any]]:
    """Every entity of a recording and its record batches, through rerun's reader (rerun.chunk,
    as of rerun-sdk 0.41: the reader API moved between releases, hence the pin)."""
    from rerun.chunk import RrdReader

    out: dict[str, list[Any]] = {}
    for chunk in RrdReader(path).stream():
        out.setdefault(chunk.entity_path, []).append(chunk.to_record_batch())
    return out


def column(batches: list[Any], name: str) -> list[Any]:
    """The values of one column over an entity's batches (a duration timeline in seconds)."""
    import pyarrow as pa

    out: list[Any] = []
    for rb in batches:
        if name in rb.schema.names:
            col = rb.column(name)
            if pa.types.is_duration(col.type):
                out += [ns / 1e9 for ns in col.cast(pa.int64()).to_pylist()]
            else:
                out += col.to_pylist()
    return out


def points(batches: list[Any]) -> Any:
    """The points of an entity's Points3D (every row's), as an (N, 3) array."""
    return np.array([p for row in column(batches, "Points3D:positions") for p in row]).reshape(-1, 3)


def rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def hku() -> Path:
    return data_dir() / "hku1-avia"


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory, hku: Path) -> dict[str, Path]:
    """An eval run, an optimize run and an optimize run against a map of the walk's first half (the
    second half: the detector places a session in a map only on consistent loops over 15 m of its
    path, and the walk's return alone is 10 m)."""
    tmp = tmp_path_factory.mktemp("view")
    cap = _NoCapture()
    common = ["--poses", "odom_poses.txt", "--preset", "avia", "--no-plots", "-q"]
    for argv in (
        ["eval", str(hku), "--frames", FRAMES, "--radius", "3", "-o", str(tmp / "ev"), *common],
        ["optimize", str(hku), "--frames", FRAMES, "-o", str(tmp / "opt"), *common],
        ["map", "build", str(hku), "--preset", "avia", "--poses", "odom_poses.txt", "--frames", "0:157", "-o", str(tmp / "start.soliddb"), "-q"],
        ["optimize", str(hku), "--frames", "157:314", "--map", str(tmp / "start.soliddb"), "-o", str(tmp / "optmap"), *common],
    ):
        code, _, err = run(cap, *argv)  # type: ignore[arg-type]
        assert code == 0, (argv, err)
    return {"eval": tmp / "ev", "optimize": tmp / "opt", "map": tmp / "optmap"}


class _NoCapture:
    """A stand-in for capsys in a module fixture: the commands' output is not needed."""

    def readouterr(self) -> Any:
        return type("R", (), {"out": "", "err": ""})()


def test_eval_run_recording_holds_the_poses_loops_and_clouds(runs: dict[str, Path], hku: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = runs["eval"]
    code, out, err = run(capsys, "view", str(folder), "-o", str(folder / "v.rrd"))
    assert code == 0, err
    assert f"{len(FRAME_IDS)} frames" in out and "v.rrd" in out
    ents = read_rrd(folder / "v.rrd")

    # The odometry: one pose per frame, on the frame timeline, equal to the pose file's rows.
    P, _ = load_poses(hku / "odom_poses.txt")
    pose = ents["/world/odometry/pose"]
    assert column(pose, "frame") == FRAME_IDS
    got = np.array([t[0] for t in column(pose, "Transform3D:translation")])
    np.testing.assert_allclose(got, P[FRAME_IDS, :, 3], atol=1e-5)
    path = np.array(column(ents["/world/odometry/path"], "LineStrips3D:strips")[0][0])
    np.testing.assert_allclose(path, P[FRAME_IDS, :, 3], atol=1e-5)
    times = column(pose, "time")
    assert times[0] == 0.0 and all(b > a for a, b in zip(times, times[1:]))

    # The loops: each accepted query of queries.csv, under eval's verdict, between the right frames.
    want = {}
    for r in rows(folder / "queries.csv"):
        if r["accepted"] == "True":
            kind = "correct" if r["correct"] == "True" else ("beyond_radius" if r["place_correct"] != "True" else "pose_false")
            want[f"/world/loops/{kind}/{r['query_frame']}-{r['candidate_frame']}"] = (int(r["query_frame"]), int(r["candidate_frame"]))
    got_loops = {e for e in ents if e.startswith("/world/loops/")}
    assert want and got_loops == set(want), (sorted(got_loops ^ set(want)))[:5]
    assert any("/correct/" in e for e in want)
    for e, (q, c) in want.items():
        seg = np.array(column(ents[e], "LineStrips3D:strips")[0][0])
        np.testing.assert_allclose(seg, P[[q, c], :, 3], atol=1e-5)
        assert column(ents[e], "frame") == [q]

    # The chosen loop's clouds (by default the first correct verified loop): the two scans as
    # read, and the candidate moved by the loop's pose in loops.csv.
    chosen = sorted({e.split("/")[2] for e in ents if e.startswith("/loop/")})
    assert len(chosen) == 1, chosen
    q, c = (int(s) for s in chosen[0].split("-"))
    row = next(r for r in rows(folder / "loops.csv") if (int(r["query_frame"]), int(r["candidate_frame"])) == (q, c))
    assert f"/world/loops/correct/{q}-{c}" in want and row["verified"] == "True"
    ds = open_dataset(hku)
    base = f"/loop/{q}-{c}"
    for stage in ("before", "after"):
        assert len(points(ents[f"{base}/{stage}/query"])) == len(ds[q])
        assert len(points(ents[f"{base}/{stage}/candidate"])) == len(ds[c])
    before = points(ents[f"{base}/before/candidate"])
    after = points(ents[f"{base}/after/candidate"])
    np.testing.assert_allclose(before, ds[c][:, :3], atol=1e-5)
    R = quat_to_matrix(np.array([[float(row[k]) for k in ("qx", "qy", "qz", "qw")]]))[0]
    T = np.array([float(row[k]) for k in ("x", "y", "z")])
    assert np.linalg.norm(T) > 0.1  # the pose moves the candidate: "after" is not "before"
    np.testing.assert_allclose(after, before @ R.T + T, atol=1e-3)


def test_optimize_run_recording_holds_both_trajectories_and_kept_loops(runs: dict[str, Path], hku: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from solid import view

    folder = runs["optimize"]
    written = view.view(folder, folder / "v.rrd", clouds=False)
    assert written == folder / "v.rrd"
    ents = read_rrd(written)
    assert not any(e.startswith("/loop/") for e in ents)  # clouds=False
    opt, _ = load_poses(folder / "trajectory.kitti")
    got = np.array([t[0] for t in column(ents["/world/optimized/pose"], "Transform3D:translation")])
    np.testing.assert_allclose(got, opt[:, :, 3], atol=1e-5)
    P, _ = load_poses(hku / "odom_poses.txt")
    got = np.array([t[0] for t in column(ents["/world/odometry/pose"], "Transform3D:translation")])
    np.testing.assert_allclose(got, P[FRAME_IDS, :, 3], atol=1e-5)
    edges = rows(folder / "loop_edges.csv")
    m = json.loads((folder / "metrics.json").read_text())
    assert len(edges) == m["loop_edges"] > 0 and sum(e["kept"] == "True" for e in edges) == m["loop_edges_kept"]
    at = {f: k for k, f in enumerate(FRAME_IDS)}
    for e in edges:
        name = f"/world/loops/{'kept' if e['kept'] == 'True' else 'dropped'}/{e['query_frame']}-{e['candidate_frame']}"
        seg = np.array(column(ents[name], "LineStrips3D:strips")[0][0])  # drawn on the optimum
        np.testing.assert_allclose(seg, opt[[at[int(e["query_frame"])], at[int(e["candidate_frame"])]], :, 3], atol=1e-5)
    assert sum(e.startswith("/world/loops/") for e in ents) == len(edges)


def test_map_run_recording_places_the_session_in_the_map(runs: dict[str, Path], hku: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import solid

    folder = runs["map"]
    code, out, err = run(capsys, "view", str(folder))
    assert code == 0, err
    ents = read_rrd(folder / "view.rrd")
    m = json.loads((folder / "metrics.json").read_text())
    db = solid.Database.load(m["inputs"]["map"])
    places = points(ents["/world/places"])
    assert len(places) == len(db) == 157
    np.testing.assert_allclose(places, np.asarray(db.poses)[:, :3, 3], atol=1e-5)
    # The optimum in the map's world is trajectory_map.kitti; the odometry is carried by anchor.txt.
    Pm, _ = load_poses(folder / "trajectory_map.kitti")
    got = np.array([t[0] for t in column(ents["/world/optimized/pose"], "Transform3D:translation")])
    np.testing.assert_allclose(got, Pm[:, :, 3], atol=1e-4)
    A, _ = load_poses(folder / "anchor.txt")
    P, _ = load_poses(hku / "odom_poses.txt")
    odo = P[157:314, :, 3] @ A[0, :, :3].T + A[0, :, 3]
    got = np.array([t[0] for t in column(ents["/world/odometry/pose"], "Transform3D:translation")])
    np.testing.assert_allclose(got, odo, atol=1e-4)
    # The loops into the map end at the map's places.
    into_map = [r for r in rows(folder / "loops.csv") if int(r["candidate"]) < len(db)]
    assert into_map and m["anchor"]["cross_session_loops"] == len(into_map)
    at = {f: k for k, f in enumerate(range(157, 314))}
    for r in into_map:
        seg = np.array(column(ents[f"/world/loops/map/{r['query_frame']}-map{r['candidate']}"], "LineStrips3D:strips")[0][0])
        np.testing.assert_allclose(seg, [Pm[at[int(r["query_frame"])], :, 3], places[int(r["candidate"])]], atol=1e-4)
    assert "map" in out and "trajectories: odometry, optimized" in out


def test_view_refuses_what_is_not_a_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "view", str(tmp_path))
    assert code == 1 and "not a run folder" in err and err.count("\n") == 1


def test_optimize_reuses_a_runs_loops_without_a_preset(runs: dict[str, Path], hku: Path, capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """Issue 40, item 1: `optimize --loops RUN` reads no scan, so it needs no --preset: the run's
    config.json gives the frames, and the optimum is the run's."""
    first = runs["optimize"]
    code, out, err = run(capsys, "optimize", str(hku), "--poses", "odom_poses.txt", "--loops", str(first), "-o", str(tmp_path / "again"), "--no-plots", "-q")
    assert code == 0, err
    assert json.loads((tmp_path / "again" / "config.json").read_text())["input"]["frames"] == FRAMES
    a, _ = load_poses(first / "trajectory.kitti")
    b, _ = load_poses(tmp_path / "again" / "trajectory.kitti")
    np.testing.assert_allclose(a, b, atol=1e-6)
