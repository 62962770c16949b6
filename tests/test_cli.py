"""The ``solid`` command line, end to end on the shared data."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import data_dir

import solid
from solid import evaluation as ev
from solid import io as sio
from solid.cli import main



def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    try:
        code = main(list(argv))
    except SystemExit as e:
        code = int(e.code) if isinstance(e.code, int) else 1
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_help_and_usage_errors(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "--help")
    assert code == 0 and "examples:" in out and "solid eval" in out
    for sub in ("describe", "detect", "eval", "presets", "bench"):
        code, out, _ = run(capsys, sub, "--help")
        assert code == 0 and "usage: solid " + sub in out, sub
    code, _, err = run(capsys)
    assert code == 2 and "required" in err
    code, _, err = run(capsys, "eval", "somewhere", "--preset", "avia")
    assert code == 2 and "--poses" in err
    code, _, err = run(capsys, "describe", "x.bin", "--no-such-flag")
    assert code == 2 and "unrecognized arguments" in err
    code, _, err = run(capsys, "describe", "x.bin", "--max-range", "far")
    assert code == 2 and "invalid float value" in err


def test_presets_and_config_dump(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, out, _ = run(capsys, "presets")
    assert code == 0
    names = {line.split()[0] for line in out.splitlines()[1:]}
    assert {"hdl64", "hdl32", "vlp16", "os1-64", "avia", "aeva"} <= names
    code, out, _ = run(capsys, "presets", "--json")
    doc = json.loads(out)
    assert doc["avia"]["fov_up"] == pytest.approx(38.6) and doc["avia"]["max_range"] == 120
    code, out, _ = run(capsys, "config", "dump", "--preset", "avia", "--max-range", "40", "--n-range", "20")
    assert code == 0
    cfg = json.loads(out)
    assert cfg["preset"] == "avia" and cfg["max_range"] == 40 and cfg["n_range"] == 20
    assert cfg["n_elevation"] == 64 and cfg["fov_down"] == pytest.approx(-38.6)
    # a config without a preset name is complete too
    bare = {k: v for k, v in cfg.items() if k != "preset"}
    (tmp_path / "bare.json").write_text(json.dumps(bare))
    code, out, _ = run(capsys, "config", "dump", "--config", str(tmp_path / "bare.json"))
    assert code == 0 and {k: v for k, v in json.loads(out).items() if k != "preset"} == bare


def test_describe_matches_api_and_config_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    scan = data_dir() / "kitti00/velodyne/000000.bin"
    code, out, _ = run(capsys, "describe", str(scan), "--preset", "hdl64")
    assert code == 0
    doc = json.loads(out)
    d = solid.describe(sio.read_points(scan), solid.SolidConfig.preset("hdl64"))
    assert doc["preset"] == "hdl64" and doc["format"] == "kitti"
    assert doc["n_points"] == 124668 == d.n_points and doc["n_kept"] == d.n_kept
    assert np.array_equal(np.array(doc["r"], dtype=np.float32), d.r)
    assert np.array_equal(np.array(doc["a"], dtype=np.float32), d.a)
    # config dump → edit → --config gives the same as the flags
    code, out, _ = run(capsys, "config", "dump", "--preset", "hdl64", "--max-range", "50")
    cfg_file = tmp_path / "c.json"
    cfg_file.write_text(out)
    code, out1, _ = run(capsys, "describe", str(scan), "--config", str(cfg_file))
    code2, out2, _ = run(capsys, "describe", str(scan), "--preset", "hdl64", "--max-range", "50")
    a, b = json.loads(out1), json.loads(out2)
    assert code == code2 == 0 and a["r"] == b["r"] and a["config"]["max_range"] == 50
    assert a["r"] != doc["r"]
    # -o writes the file atomically and prints nothing
    code, out, _ = run(capsys, "describe", str(scan), "--preset", "hdl64", "-o", str(tmp_path / "d.json"))
    assert code == 0 and out == "" and json.loads((tmp_path / "d.json").read_text())["r"] == doc["r"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.json", "d.json"]


def test_user_errors_are_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, _, err = run(capsys, "describe", str(tmp_path / "missing.bin"), "--preset", "hdl64")
    assert code == 1 and "missing.bin" in err and "Traceback" not in err and err.count("\n") == 1
    bad = tmp_path / "bad.bin"
    bad.write_bytes(b"\0" * 17)
    code, _, err = run(capsys, "describe", str(bad), "--preset", "hdl64")
    assert code == 1 and "bad.bin" in err and "multiple of 16" in err and err.count("\n") == 1
    code, _, err = run(capsys, "describe", str(bad), "--preset", "hdl65")
    assert code == 1 and "unknown preset 'hdl65'" in err
    pts = np.zeros((4, 4), dtype=np.float32)
    good = tmp_path / "good.bin"
    good.write_bytes(pts.tobytes())
    code, _, err = run(capsys, "describe", str(good), "--preset", "hdl64", "--max-range", "-5")
    assert code == 1 and "max_range" in err and err.count("\n") == 1
    code, _, err = run(capsys, "describe", str(good))
    assert code == 1 and "--preset" in err
    (tmp_path / "junk.json").write_text("{not json")
    code, _, err = run(capsys, "describe", str(good), "--config", str(tmp_path / "junk.json"))
    assert code == 1 and "junk.json" in err
    (tmp_path / "unk.json").write_text('{"preset": "hdl64", "rings": 3}')
    code, _, err = run(capsys, "describe", str(good), "--config", str(tmp_path / "unk.json"))
    assert code == 1 and "unknown keys rings" in err


def test_subprocess_exit_codes(tmp_path: Path) -> None:
    env = dict(os.environ)
    r = subprocess.run([sys.executable, "-m", "solid.cli", "presets"], capture_output=True, text=True, env=env)
    assert r.returncode == 0 and "avia" in r.stdout
    r = subprocess.run([sys.executable, "-m", "solid.cli", "eval"], capture_output=True, text=True, env=env)
    assert r.returncode == 2 and "usage:" in r.stderr
    r = subprocess.run(
        [sys.executable, "-m", "solid.cli", "describe", str(tmp_path / "nope.pcd"), "--preset", "vlp16"],
        capture_output=True,
        text=True,
        env=env,
    )
    assert r.returncode == 1 and "nope.pcd" in r.stderr and "Traceback" not in r.stderr


def test_eval_end_to_end_hku(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    seq_dir = data_dir() / "hku1-avia"
    out_dir = tmp_path / "ev"
    code, out, err = run(
        capsys, "eval", str(seq_dir), "--poses", "odom_poses.txt", "--preset", "avia",
        "--frames", "0:60,284:314", "--exclude", "20", "--radius", "5",
        "--baseline", "scancontext", "--output", str(out_dir), "--quiet",
    )  # fmt: skip
    assert code == 0, err
    assert "SOLiD" in out and "Scan Context" in out
    m = json.loads((out_dir / "metrics.json").read_text())
    # 90 frames, exclusion 20 → queries are selection positions 21..89
    assert m["frames_evaluated"] == 90 and m["queries"] == 69
    # ground truth recomputed here by brute force from the pose file
    P, _ = sio.load_poses(seq_dir / "odom_poses.txt")
    sel = list(range(60)) + list(range(284, 314))
    t = P[sel, :, 3]
    gt = sum(1 for q in range(21, 90) if np.linalg.norm(t[: q - 20] - t[q], axis=1).min() <= 5.0)
    assert m["gt_queries"] == gt
    for key in ("recall_at_1", "recall_at_5", "f1_max", "auc", "rotation_error_deg_mean"):
        assert isinstance(m[key], float) and 0 <= m[key] <= (180 if key.startswith("rot") else 1)
    assert m["recall_at_1"] > 0.5  # the last 30 keyframes revisit the first ones
    assert set(m["baselines"]) == {"scancontext"}
    # the command line agrees with the library on the same frames
    cfg = solid.SolidConfig.preset("avia")
    seq = sio.Sequence(seq_dir, poses="odom_poses.txt")
    assert seq.poses is not None
    descs = [solid.describe(seq[i], cfg) for i in sel]
    e = ev.evaluate_solid(np.stack([d.r for d in descs]), np.stack([d.a for d in descs]), seq.poses[sel], exclude=20, radius=5.0)
    assert e.metrics()["recall_at_1"] == m["recall_at_1"] and e.metrics()["auc"] == m["auc"]
    with open(out_dir / "queries.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 69 and int(rows[0]["query"]) == 21
    assert (out_dir / "pr.png").read_bytes()[:4] == b"\x89PNG" and (out_dir / "roc.png").stat().st_size > 1000
    assert not [p for p in out_dir.iterdir() if p.name.startswith(".")]


def test_eval_transforms_change_the_input(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    seq_dir = data_dir() / "hku1-avia"
    base = ["eval", str(seq_dir), "--poses", "odom_poses.txt", "--preset", "avia", "--frames", "0:30,290:314", "--exclude", "10", "--no-plots", "-q"]
    code, _, err = run(capsys, *base, "--output", str(tmp_path / "a"))
    assert code == 0, err
    code, _, err = run(capsys, *base, "--output", str(tmp_path / "b"), "--fov", "30", "--occlude", "10", "--occlude-center", "5")
    assert code == 0, err
    a = json.loads((tmp_path / "a/metrics.json").read_text())
    b = json.loads((tmp_path / "b/metrics.json").read_text())
    assert b["fov_clip_deg"] == [30, 0] and b["occluded_sector_deg"] == [10, 5]
    assert a["queries"] == b["queries"]

    def distances(d: str) -> list[str]:
        with open(tmp_path / d / "queries.csv", newline="") as f:
            return [r["distance"] for r in csv.DictReader(f)]

    assert distances("a") != distances("b")
    assert not (tmp_path / "a/pr.png").exists()
    code, _, err = run(capsys, *base[:-2], "--subsample-m", "1.0", "--exclude", "3", "--output", str(tmp_path / "c"), "-q")
    assert code == 0, err
    c = json.loads((tmp_path / "c/metrics.json").read_text())
    assert c["subsample_m"] == 1.0 and c["frames_evaluated"] < 54
    code, _, err = run(capsys, *base, "--exclude", "60", "--output", str(tmp_path / "d"))
    assert code == 1 and "no query" in err
    # an identity extrinsic changes nothing; any extrinsic leaves the descriptors (distances) alone
    (tmp_path / "id.txt").write_text("1 0 0 0 0 1 0 0 0 0 1 0\n")
    code, _, err = run(capsys, *base, "--calib", str(tmp_path / "id.txt"), "--output", str(tmp_path / "e"))
    assert code == 0, err
    e = json.loads((tmp_path / "e/metrics.json").read_text())
    assert {k: e[k] for k in ("recall_at_1", "auc", "rotation_error_deg_mean")} == {k: a[k] for k in ("recall_at_1", "auc", "rotation_error_deg_mean")}
    (tmp_path / "rz.txt").write_text("0 -1 0 0.1 1 0 0 0 0 0 1 0\n")
    code, _, err = run(capsys, *base, "--calib", str(tmp_path / "rz.txt"), "--output", str(tmp_path / "f"))
    assert code == 0, err
    assert distances("f") == distances("a")


def test_bench_prints_rates(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "bench", str(data_dir() / "hku1-avia"), "--preset", "avia", "--frames", "20", "--db-size", "500", "-q")
    assert code == 0, err
    for word in ("read", "describe", "batch", "search"):
        line = next(ln for ln in out.splitlines() if ln.startswith(word))
        assert float(line.split()[1]) > 0


@pytest.mark.skipif(not hasattr(solid, "LoopDetector"), reason="solid.LoopDetector (issue 3) is not in this build yet")
def test_detect_writes_loops(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, out, err = run(
        capsys, "detect", str(data_dir() / "hku1-avia"), "--preset", "avia", "--exclude", "50",
        "--threshold", "0.2", "--output", str(tmp_path), "-q",
    )  # fmt: skip
    assert code == 0, err
    with open(tmp_path / "loops.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0].keys()) == ["query", "candidate", "distance", "heading_deg"] if rows else True
    assert rows, "the HKU walk returns to its start: some loop must be found at threshold 0.2"
    for r in rows:
        q, c = int(r["query"]), int(r["candidate"])
        assert q - c > 50 and 0 <= float(r["distance"]) <= 0.2 and -180 < float(r["heading_deg"]) <= 180
    assert f"{len(rows)} loops" in out
