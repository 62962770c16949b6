"""The ``solid`` command line, end to end on the shared data and the simulator."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import data_dir, read_csv, run

import solid
from solid import io as sio
from solid import sim, transforms
from solid.cli import build_parser
from solid.records import LOOP_COLUMNS


def test_help_and_usage_errors(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "--help")
    assert code == 0 and "examples:" in out and "solid eval" in out and "docs/spec.md" in out
    for sub in ("describe", "detect", "eval", "presets", "bench", "demo"):
        code, out, _ = run(capsys, sub, "--help")
        assert code == 0 and "usage: solid " + sub in out, sub
    for sub in ("build", "merge", "info"):
        code, out, _ = run(capsys, "map", sub, "--help")
        assert code == 0 and "usage: solid map " + sub in out, sub
    code, _, err = run(capsys)
    assert code == 2 and "required" in err
    code, _, err = run(capsys, "eval", "somewhere", "--preset", "avia")
    assert code == 2 and "--poses" in err
    code, _, err = run(capsys, "describe", "x.bin", "--no-such-flag")
    assert code == 2 and "unrecognized arguments" in err
    code, _, err = run(capsys, "describe", "x.bin", "--max-range", "far")
    assert code == 2 and "invalid float value" in err


def test_usage_errors_are_one_line_and_help_is_short(capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 40: the reason and where to look, not argparse's usage block; --help lists the
    options most runs need, --help-all every one."""
    code, _, err = run(capsys, "eval", "somewhere", "--preset", "avia")
    assert code == 2 and err.count("\n") == 1 and "--poses" in err and err.rstrip().endswith("(see solid eval --help)"), err
    code, short, _ = run(capsys, "eval", "--help")
    assert code == 0
    code, full, _ = run(capsys, "eval", "--help-all")
    assert code == 0

    def shown(text: str) -> set[str]:
        return {w.rstrip(",") for w in text.split() if w.startswith("--")}

    for flag in ("--poses", "--preset", "--radius", "--map", "--threshold", "--exclude-frames", "--help-all"):
        assert flag in shown(short), flag
    for flag in ("--gate-min-fitness", "--occlude-center", "--verify-fan-deg", "--subsample-m", "--sc-max-range"):
        assert flag not in shown(short) and flag in shown(full), flag
    assert len(short.splitlines()) < len(full.splitlines()) / 2, (len(short.splitlines()), len(full.splitlines()))
    # Hidden from --help, still parsed.
    assert build_parser().parse_args(["eval", "s", "--poses", "p", "--gate-min-fitness", "0.5"]).gate_min_fitness == 0.5


@pytest.mark.parametrize(
    "argv",
    [
        ("detect", "s", "--preset", "avia", "--exclude", "-1"),
        ("detect", "s", "--preset", "avia", "--top-k", "-1"),
        ("detect", "s", "--preset", "avia", "--top-k", "0"),
        ("detect", "s", "--preset", "avia", "--threads", "-1"),
        ("detect", "s", "--preset", "avia", "--threshold", "1.5"),
        ("detect", "s", "--preset", "avia", "--threshold", "nan"),
        ("detect", "s", "--preset", "avia", "--exclude-m", "-3"),
        ("detect", "s", "--preset", "avia", "--exclude", "99999999999999999999"),
        ("eval", "s", "--poses", "p", "--preset", "avia", "--radius", "0"),
        ("eval", "s", "--poses", "p", "--preset", "avia", "--fov", "400"),
        ("demo", "--seed", "-1"),
        ("demo", "--laps", "inf"),
        ("describe", "x.bin", "--preset", "avia", "--n-range", "-3"),
    ],
)
def test_out_of_range_options_are_usage_errors(capsys: pytest.CaptureFixture[str], argv: tuple[str, ...]) -> None:
    """Issue 10, item 7: these ended in OverflowError tracebacks; now exit 2 with one line."""
    code, _, err = run(capsys, *argv)
    assert code == 2, err
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith("solid ")


def test_threads_zero_is_one_per_core_as_in_the_api() -> None:
    """Issue 29: --threads reads as every API's thread count (0, the default: one per core)."""
    parser = build_parser()
    for command in (["detect", "s", "--preset", "avia"], ["bench", "s", "--preset", "avia"]):
        assert parser.parse_args(command).threads == 0
        assert parser.parse_args([*command, "--threads", "0"]).threads == 0
        assert parser.parse_args([*command, "--threads", "3"]).threads == 3


def test_presets_and_config_dump(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, out, _ = run(capsys, "presets")
    assert code == 0
    names = {line.split()[0] for line in out.splitlines()[1:]}
    assert names == set(solid.presets())
    code, out, _ = run(capsys, "presets", "--json")
    doc = json.loads(out)
    assert doc["avia"]["fov_up"] == pytest.approx(38.6) and doc["avia"]["max_range"] == 120
    assert doc["avia"]["loop_threshold"] == solid.DetectorConfig.preset("avia").threshold
    code, out, _ = run(capsys, "config", "dump", "--preset", "avia", "--max-range", "40", "--n-range", "20", "--exclude-m", "12")
    assert code == 0
    cfg = json.loads(out)
    assert cfg["preset"] == "avia" and cfg["descriptor"]["max_range"] == 40 and cfg["descriptor"]["n_range"] == 20
    assert cfg["descriptor"]["n_elevation"] == 64 and cfg["detector"]["exclude_meters"] == 12
    assert cfg["detector"]["threshold"] == solid.DetectorConfig.preset("avia").threshold
    # dump → --config → dump gives the same document, also without a preset name
    (tmp_path / "c.json").write_text(out)
    code, out2, _ = run(capsys, "config", "dump", "--config", str(tmp_path / "c.json"))
    assert code == 0 and json.loads(out2) == cfg
    bare = dict(cfg, preset=None)
    (tmp_path / "bare.json").write_text(json.dumps(bare))
    code, out3, _ = run(capsys, "config", "dump", "--config", str(tmp_path / "bare.json"))
    assert code == 0 and json.loads(out3) == bare


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
    code, out, _ = run(capsys, "config", "dump", "--preset", "hdl64", "--max-range", "50")
    cfg_file = tmp_path / "c.json"
    cfg_file.write_text(out)
    code, out1, _ = run(capsys, "describe", str(scan), "--config", str(cfg_file))
    code2, out2, _ = run(capsys, "describe", str(scan), "--preset", "hdl64", "--max-range", "50")
    a, b = json.loads(out1), json.loads(out2)
    assert code == code2 == 0 and a["r"] == b["r"] and a["config"]["max_range"] == 50
    assert a["r"] != doc["r"]
    code, out, _ = run(capsys, "describe", str(scan), "--preset", "hdl64", "-o", str(tmp_path / "d.json"))
    assert code == 0 and out == "" and json.loads((tmp_path / "d.json").read_text())["r"] == doc["r"]


def test_user_errors_are_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, _, err = run(capsys, "describe", str(tmp_path / "missing.bin"), "--preset", "hdl64")
    assert code == 1 and "missing.bin" in err and "Traceback" not in err and err.count("\n") == 1
    bad = tmp_path / "bad.bin"
    bad.write_bytes(b"\0" * 17)
    code, _, err = run(capsys, "describe", str(bad), "--preset", "hdl64")
    assert code == 1 and "bad.bin" in err and err.count("\n") == 1
    code, _, err = run(capsys, "describe", str(bad), "--preset", "hdl65")
    assert code == 1 and "unknown preset 'hdl65'" in err
    good = tmp_path / "good.bin"
    good.write_bytes(np.zeros((4, 4), dtype=np.float32).tobytes())
    code, _, err = run(capsys, "describe", str(good), "--preset", "hdl64", "--max-range", "-5")
    assert code == 1 and "max_range" in err and err.count("\n") == 1
    code, _, err = run(capsys, "describe", str(good))
    assert code == 1 and "--preset" in err
    (tmp_path / "junk.json").write_text("{not json")
    code, _, err = run(capsys, "describe", str(good), "--config", str(tmp_path / "junk.json"))
    assert code == 1 and "junk.json" in err
    (tmp_path / "unk.json").write_text('{"preset": "hdl64", "descriptor": {"rings": 3}}')
    code, _, err = run(capsys, "describe", str(good), "--config", str(tmp_path / "unk.json"))
    assert code == 1 and "unknown descriptor keys rings" in err
    # Issue 10, item 7: a deeply nested configuration is one line, not a RecursionError.
    (tmp_path / "deep.json").write_text("[" * 100_000)
    code, _, err = run(capsys, "describe", str(good), "--config", str(tmp_path / "deep.json"))
    assert code == 1 and "deep.json" in err and "Traceback" not in err and err.count("\n") == 1


def test_subprocess_exit_codes(tmp_path: Path) -> None:
    env = dict(os.environ)
    r = subprocess.run([sys.executable, "-m", "solid.cli", "presets"], capture_output=True, text=True, env=env)
    assert r.returncode == 0 and "avia" in r.stdout
    r = subprocess.run([sys.executable, "-m", "solid.cli", "eval"], capture_output=True, text=True, env=env)
    assert r.returncode == 2 and "see solid eval --help" in r.stderr and r.stderr.count("\n") == 1, r.stderr
    r = subprocess.run(
        [sys.executable, "-m", "solid.cli", "describe", str(tmp_path / "nope.pcd"), "--preset", "vlp16"],
        capture_output=True,
        text=True,
        env=env,
    )
    assert r.returncode == 1 and "nope.pcd" in r.stderr and "Traceback" not in r.stderr


HKU = ["--poses", "odom_poses.txt", "--preset", "avia", "--no-verify"]  # verification: its own tests


def test_eval_end_to_end_hku(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    seq_dir = data_dir() / "hku1-avia"
    out_dir = tmp_path / "ev"
    code, out, err = run(
        capsys, "eval", str(seq_dir), *HKU, "--frames", "0:60,284:314", "--exclude", "20", "--exclude-m", "0", "--radius", "5",
        "--baseline", "scancontext", "--output", str(out_dir), "--quiet",
    )  # fmt: skip
    assert code == 0, err
    assert "SOLiD" in out and "Scan Context" in out and "best F1" in out and "--threshold" in out
    m = json.loads((out_dir / "metrics.json").read_text())
    # 90 frames, exclusion 20 → queries are selection positions 21..89
    assert m["frames"] == 90 and m["queries"] == 69
    # the configuration is recorded whole, the inputs with absolute paths
    assert m["config"] == json.loads((out_dir / "config.json").read_text())
    assert m["config"]["detector"]["exclude_frames"] == 20 and m["config"]["input"]["frames"] == "0:60,284:314"
    assert m["inputs"]["sequence"] == str(seq_dir.absolute()) and Path(m["inputs"]["poses"]).is_absolute()
    assert Path(m["inputs"]["poses"]) == (seq_dir / "odom_poses.txt").absolute()
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
    rows = read_csv(out_dir / "queries.csv")
    assert len(rows) == 69 and int(rows[0]["query"]) == 21
    assert sum(r["correct"] == "True" for r in rows) == m["correct_top1"]
    assert sum(r["accepted"] == "True" for r in rows) == m["accepted"]
    for png in ("pr", "roc", "trajectory", "distances", "heading"):
        assert (out_dir / f"{png}.png").read_bytes()[:4] == b"\x89PNG", png
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_eval_accepted_rows_are_exactly_detects_loops(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """One configuration (verification on): the rows of eval's queries.csv with accepted true are
    detect's loops.csv, poses included (eval hands its poses to the detector, so detect gets them
    too: the odometry starts registrations and checks loops); without poses, detect's g2o file
    holds its loops and the library's detector made the same decisions. Candidates chosen by pose
    are off (test_trust compares detect and eval with every default)."""
    seq = str(data_dir() / "hku1-avia")
    common = ["--preset", "avia", "--frames", "0:40,260:314", "--exclude-m", "0", "--pose-candidates", "0", "-q"]
    code, _, err = run(capsys, "detect", seq, *common, "--max-loop-distance", "3", "--poses", "odom_poses.txt", "-o", str(tmp_path / "d"))
    assert code == 0, err
    code, _, err = run(capsys, "eval", seq, *common, "--max-loop-distance", "3", "--radius", "3", "--poses", "odom_poses.txt", "--no-plots", "-o", str(tmp_path / "e"))
    assert code == 0, err
    loops = read_csv(tmp_path / "d" / "loops.csv")
    accepted = [{k: r[k] for k in LOOP_COLUMNS} for r in read_csv(tmp_path / "e" / "queries.csv") if r["accepted"] == "True"]
    assert loops and accepted == loops
    assert all(r["verified"] == "True" and r["qw"] != "" for r in loops)
    assert read_csv(tmp_path / "e" / "loops.csv") == loops
    m = json.loads((tmp_path / "e" / "metrics.json").read_text())
    assert m["accepted"] == len(loops) and m["pose_error_m_median"] < 0.1
    # Without poses, the g2o file has one EDGE_SE3:QUAT per verified loop, between frame
    # numbers (issue 27), with the same pose. (One stretch of the walk: without poses the
    # detector's own odometry relates no place across a gap in the frames.)
    alone = [*common[:2], "--frames", "100:190", *common[4:]]
    code, _, err = run(capsys, "detect", seq, *alone, "--max-loop-distance", "3", "-o", str(tmp_path / "n"), "--g2o", str(tmp_path / "loops.g2o"))
    assert code == 0, err
    loops = read_csv(tmp_path / "n" / "loops.csv")
    assert loops
    edges = (tmp_path / "loops.g2o").read_text().splitlines()
    assert len(edges) == len(loops)
    for e, r in zip(edges, loops):
        f = e.split()
        assert f[0] == "EDGE_SE3:QUAT" and (f[1], f[2]) == (r["query_frame"], r["candidate_frame"]) and len(f) == 3 + 7 + 21
        assert [float(x) for x in f[3:10]] == pytest.approx([float(r[k]) for k in ("x", "y", "z", "qx", "qy", "qz", "qw")], abs=1e-6)
    # and the library's detector, run by hand on the same frames, made the same decisions
    cfg = solid.config.PipelineConfig.preset("avia", radius=3.0, detector={"gate": {"max_translation": 3.0}, "pose_candidates": 0, "exclude_meters": 0.0})
    det = solid.LoopDetector(cfg.descriptor, detector=cfg.detector)
    ds = sio.Dataset(seq)
    frames = list(range(100, 190))
    mine = [lp for i in frames if (lp := det.add(ds[i])) is not None]
    assert [(lp.query, lp.candidate, f"{lp.distance:.6f}", f"{lp.pose[0, 3]:.6f}") for lp in mine if lp.pose is not None] == [
        (int(r["query"]), int(r["candidate"]), r["distance"], r["x"]) for r in loops
    ]


def test_eval_transforms_change_the_input(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    seq_dir = data_dir() / "hku1-avia"
    base = ["eval", str(seq_dir), *HKU, "--frames", "0:30,290:314", "--exclude", "10", "--exclude-m", "0", "--no-plots", "-q"]
    code, _, err = run(capsys, *base, "--output", str(tmp_path / "a"))
    assert code == 0, err
    code, _, err = run(capsys, *base, "--output", str(tmp_path / "b"), "--fov", "30", "--fov-center", "0", "--occlude", "10", "--occlude-center", "5")
    assert code == 0, err
    a = json.loads((tmp_path / "a/metrics.json").read_text())
    b = json.loads((tmp_path / "b/metrics.json").read_text())
    assert b["config"]["input"]["fov"] == 30 and b["config"]["input"]["occlude_center"] == 5
    assert a["queries"] == b["queries"]

    def distances(d: str) -> list[str]:
        return [r["distance"] for r in read_csv(tmp_path / d / "queries.csv")]

    assert distances("a") != distances("b")
    assert not (tmp_path / "a/pr.png").exists()
    code, _, err = run(capsys, *base[:-2], "--subsample-m", "1.0", "--exclude", "3", "--output", str(tmp_path / "c"), "-q")
    assert code == 0, err
    c = json.loads((tmp_path / "c/metrics.json").read_text())
    assert c["config"]["input"]["subsample_m"] == 1.0 and c["frames"] < 54
    code, _, err = run(capsys, *base, "--exclude", "60", "--output", str(tmp_path / "d"))
    assert code == 1 and "no query" in err and not (tmp_path / "d").exists()
    # an identity extrinsic changes nothing; any extrinsic leaves the descriptors (distances) alone
    (tmp_path / "id.txt").write_text("1 0 0 0 0 1 0 0 0 0 1 0\n")
    code, _, err = run(capsys, *base, "--calib", str(tmp_path / "id.txt"), "--output", str(tmp_path / "e"))
    assert code == 0, err
    e = json.loads((tmp_path / "e/metrics.json").read_text())
    keys = ("recall_at_1", "auc", "rotation_error_deg_mean")
    assert {k: e[k] for k in keys} == {k: a[k] for k in keys}
    (tmp_path / "rz.txt").write_text("0 -1 0 0.1 1 0 0 0 0 0 1 0\n")
    code, _, err = run(capsys, *base, "--calib", str(tmp_path / "rz.txt"), "--output", str(tmp_path / "f"))
    assert code == 0, err
    assert distances("f") == distances("a")


def test_output_folders_are_fresh_and_whole(capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    seq = str(data_dir() / "hku1-avia")
    args = ["detect", seq, "--preset", "avia", "--frames", "0:80", "-q"]
    # an existing non-empty folder is refused, and left as it was
    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "stale.csv").write_text("x\n")
    code, _, err = run(capsys, *args, "-o", str(tmp_path / "old"))
    assert code == 1 and "not empty" in err
    assert [p.name for p in (tmp_path / "old").iterdir()] == ["stale.csv"]
    # without -o: a fresh timestamped folder and a `latest` link, twice in a row
    monkeypatch.chdir(tmp_path)
    for _ in range(2):
        code, out, err = run(capsys, *args)
        assert code == 0, err
    runs = sorted(p for p in (tmp_path / "solid_results").iterdir() if not p.is_symlink())
    assert len(runs) == 2 and runs[0] != runs[1]
    latest = tmp_path / "solid_results" / "latest"
    assert latest.is_symlink() and latest.resolve() in {r.resolve() for r in runs}
    assert (latest / "loops.csv").exists() and (latest / "config.json").exists()


def test_interrupted_eval_leaves_no_folder(tmp_path: Path) -> None:
    """Issue 10, item 7: SIGINT during eval left folders mixing two runs; now nothing is left."""
    seq = str(data_dir() / "hku1-avia")
    out = tmp_path / "out"
    p = subprocess.Popen(
        [sys.executable, "-m", "solid.cli", "eval", seq, *HKU, "-o", str(out), "-q", "--baseline", "scancontext"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(2.0)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    # Finished before the signal, or got it while exiting (the interpreter no longer catches
    # SIGINT then, so it dies of it): the folder must then be complete.
    if p.returncode == 0 or (p.returncode == -signal.SIGINT and out.exists()):
        assert (out / "metrics.json").exists()
    else:
        assert p.returncode == 130, err
        assert not out.exists() and list(tmp_path.iterdir()) == []


def test_bench_prints_rates(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "bench", str(data_dir() / "hku1-avia"), "--preset", "avia", "--scans", "20", "--db-size", "500", "-q")
    assert code == 0, err
    for word in ("read", "describe", "batch", "search"):
        line = next(ln for ln in out.splitlines() if ln.startswith(word))
        assert float(line.split()[1]) > 0


def test_detect_writes_loops(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, out, err = run(
        capsys, "detect", str(data_dir() / "hku1-avia"), "--preset", "avia", "--exclude", "50",
        "--threshold", "0.2", "--no-verify", "--output", str(tmp_path / "d"), "-q",
    )  # fmt: skip
    assert code == 0, err
    rows = read_csv(tmp_path / "d" / "loops.csv")
    assert rows and tuple(rows[0].keys()) == LOOP_COLUMNS
    times = sio.load_timestamps(data_dir() / "hku1-avia" / "times.txt")
    for r in rows:
        q, c = int(r["query"]), int(r["candidate"])
        assert q - c > 50 and 0 <= float(r["distance"]) <= 0.2 and -180 < float(r["heading_deg"]) <= 180
        assert r["query_time"] == "" or float(r["query_time"]) == pytest.approx(times[q])
    assert f"{len(rows)} loops" in out


def test_map_build_and_eval_across_two_simulated_sessions(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """Issue 8: a map from one session, queries from another, ground truth from both in one frame."""
    world = sim.World(seed=1)
    lap, second = sim.session_routes(world)
    s0, s1 = sim.write_sessions(tmp_path / "sim", world, sim.Sensor("vlp16"), [lap, second])
    code, out, err = run(capsys, "map", "build", str(s0), "--preset", "vlp16", "--poses", "poses.txt", "--timestamps", "times.txt", "-o", str(tmp_path / "run1.soliddb"), "-q")
    assert code == 0, err
    assert f"{len(lap)} places ({len(lap)} with poses)" in out
    code, out, err = run(capsys, "map", "info", str(tmp_path / "run1.soliddb"), "--json")
    info = json.loads(out)
    assert info["places"] == len(lap) and info["sessions"][0]["with_pose"] == len(lap)
    # The descriptor's recall across the sessions (the simulator's sessions share one world; the
    # anchor estimated from verified loops is test_slam's and test_view's).
    code, out, err = run(capsys, "eval", str(s1), "--poses", "poses.txt", "--map", str(tmp_path / "run1.soliddb"), "--same-world", "--no-verify", "-o", str(tmp_path / "ev"), "--no-plots", "-q")
    assert code == 0, err
    m = json.loads((tmp_path / "ev" / "metrics.json").read_text())
    assert m["map_places"] == len(lap) and m["queries"] == len(second)
    assert m["gt_queries"] > 50
    assert m["recall_at_1"] >= 0.9, m
    rows = read_csv(tmp_path / "ev" / "queries.csv")
    assert {r["candidate_session"] for r in rows if r["correct"] == "True"} == {"0"}
    # detect against the map without poses, and merging maps keeps the sessions apart (the whole
    # session: the detector's own odometry places it in the map by consistent loops first)
    code, out, err = run(capsys, "detect", str(s1), "--map", str(tmp_path / "run1.soliddb"), "-o", str(tmp_path / "det"), "-q")
    assert code == 0, err
    assert f"{len(second)} scans" in out and f"map of {len(lap)} places" in out, out
    found = read_csv(tmp_path / "det" / "loops.csv")
    assert found and all(r["candidate_session"] == "0" and r["verified"] == "True" for r in found), found
    code, out, err = run(capsys, "map", "build", str(s1), "--preset", "vlp16", "--poses", "poses.txt", "-o", str(tmp_path / "run2.soliddb"), "-q")
    assert code == 0, err
    code, out, err = run(capsys, "map", "merge", str(tmp_path / "run1.soliddb"), str(tmp_path / "run2.soliddb"), "--anchor", "same", "-o", str(tmp_path / "both.soliddb"), "-q")
    assert code == 0, err
    both = solid.Database.load(tmp_path / "both.soliddb")
    assert len(both) == len(lap) + len(second) and sorted(set(both.sessions.tolist())) == [0, 1]
    # a map of another configuration is refused with both named
    code, out, err = run(capsys, "eval", str(s1), "--poses", "poses.txt", "--preset", "hdl64", "--map", str(tmp_path / "run1.soliddb"), "-q")
    assert code == 1 and "run1.soliddb" in err
    code, out, err = run(capsys, "map", "build", str(s1), "--preset", "vlp16", "-o", str(tmp_path / "run1.soliddb"), "-q")
    assert code == 1 and "exists" in err


def test_a_map_records_how_its_scans_were_clipped_and_upgrades_from_format_2(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """Issue 30 ("maps forget how they were made") and issue 31 (`map info` from the header,
    `map upgrade`): the clip of `map build` is stored in the map, printed by `map info`, and a
    query run that clips otherwise is warned."""
    world = sim.World(seed=3)
    sim.write_sequence(tmp_path / "seq", world, sim.Sensor("vlp16"), sim.Trajectory.loop(world, laps=0.1, spacing=3.0))
    m = tmp_path / "m.soliddb"
    code, out, err = run(capsys, "map", "build", str(tmp_path / "seq"), "--preset", "vlp16", "--fov", "90", "-o", str(m), "-q")
    assert code == 0, err
    code, out, err = run(capsys, "map", "info", str(m), "--json")
    info = json.loads(out)
    assert info["format_version"] == 4
    assert info["clip"] == {"fov_deg": 90.0, "fov_center_deg": 0.0, "occlude_deg": None, "occlude_center_deg": None}
    code, out, err = run(capsys, "map", "info", str(m))
    assert "scans clipped: --fov 90° centred on 0°" in out, out
    # The same clip: no warning; another: one warning naming both.
    code, out, err = run(capsys, "detect", str(tmp_path / "seq"), "--map", str(m), "--fov", "90", "-o", str(tmp_path / "a"), "-q")
    assert code == 0 and "was built with scans clipped" not in err, err
    code, out, err = run(capsys, "detect", str(tmp_path / "seq"), "--map", str(m), "-o", str(tmp_path / "b"), "-q")
    assert code == 0 and "was built with scans clipped as --fov 90° centred on 0°" in err and "none (full scans)" in err, err
    # A map in format 2 holds no record; `map upgrade` rewrites it in format 4, same places.
    db = solid.Database.load(m)
    old = tmp_path / "old.soliddb"
    db.save(old, version=2)
    code, out, err = run(capsys, "map", "info", str(old), "--json")
    assert json.loads(out)["format_version"] == 2 and json.loads(out)["clip"] is None
    code, out, err = run(capsys, "map", "upgrade", str(old), "-o", str(tmp_path / "new.soliddb"))
    assert code == 0 and "format 2 → 4" in out, err
    new = solid.Database.load(tmp_path / "new.soliddb")
    assert len(new) == len(db) and np.array_equal(new.r, db.r) and new.cloud(1) == db.cloud(1)
    assert (tmp_path / "new.soliddb").stat().st_size < old.stat().st_size
    code, out, err = run(capsys, "map", "upgrade", str(old))
    assert code == 0 and json.loads(run(capsys, "map", "info", str(old), "--json")[1])["format_version"] == 4


def test_optimize_without_the_slam_extra_says_how_to_install_it(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Issue 27: without GTSAM, `solid optimize` stops before reading anything and names the extra."""
    monkeypatch.setitem(sys.modules, "gtsam", None)  # `import gtsam` raises ImportError
    code, _, err = run(capsys, "optimize", str(tmp_path), "--poses", "odom.txt", "-o", str(tmp_path / "out"), "-q")
    assert code == 1 and "pip install 'solid-lidar[slam]'" in err
    assert not (tmp_path / "out").exists()


def test_a_run_counts_its_rejections_and_says_when_the_odometry_turned_down_most() -> None:
    """Issue 41: when the odometry check turns down many registered candidates against few loops
    (an odometry drifting beyond its bounds), detect and eval say so and what to try; a run whose
    odometry agrees with its loops gets no such line."""
    from types import SimpleNamespace

    from solid.commands import ODOMETRY_REJECTION, advice, measured_drift, rejection_counts
    from solid.config import PipelineConfig

    def step(*reasons: str | None) -> SimpleNamespace:
        return SimpleNamespace(candidates=[SimpleNamespace(rejection=r) for r in reasons])

    result = SimpleNamespace(
        detections=[step(ODOMETRY_REJECTION, "low overlap", None), step("place 7: its stored cloud is corrupt or unreadable"), step(ODOMETRY_REJECTION)]
    )
    counts = rejection_counts(result)  # type: ignore[arg-type]
    assert counts == {ODOMETRY_REJECTION: 2, "its stored cloud is corrupt or unreadable": 1, "low overlap": 1}
    d = PipelineConfig.preset("avia").detector
    (line,) = advice({"loops": 0, "rejections": {ODOMETRY_REJECTION: 232}}, d)
    assert "232 registered candidates against 0 loops" in line and "--odometry-drift" in line
    assert advice({"loops": 49, "rejections": {ODOMETRY_REJECTION: 60}}, d) == []  # most loops were accepted
    assert advice({"loops": 0, "rejections": {ODOMETRY_REJECTION: 9}}, d) == []  # too few to say
    off = PipelineConfig.preset("avia", detector={"odometry_check": False}).detector
    assert advice({"loops": 0, "rejections": {ODOMETRY_REJECTION: 232}}, off) == []
    # The drift the accepted loops measure: one loop back to the start of a straight 100 m path,
    # 2° and 2 m along the path off the poses' prediction, and sideways by what the 2° predict
    # at the path's half (the swing the check allows, ω × arm: 1.75 m): 1 m beyond the check's
    # constant 1 m over 100 m, and 0°/m beyond its constant 3°. Sideways the other way is not the
    # rotation's: 4.02 m off, 3.02 beyond.
    P = np.tile(np.eye(4)[:3], (101, 1, 1))
    P[:, 0, 3] = np.arange(101.0)
    c, s = np.cos(np.radians(2.0)), np.sin(np.radians(2.0))
    swing = np.radians(2.0) * 50.0
    for t, drift in (([-98.0, -swing], 0.01), ([-98.0, swing], (np.hypot(2.0, 2.0 * swing) - 1.0) / 100)):
        pose = np.array([[c, -s, 0, t[0]], [s, c, 0, t[1]], [0, 0, 1, 0], [0, 0, 0, 1]])
        run = SimpleNamespace(poses=P, map_size=0, config=PipelineConfig.preset("avia"), loops=lambda pose=pose: [SimpleNamespace(query=100, candidate=0, pose=pose)])
        m = measured_drift(run)  # type: ignore[arg-type]
        assert m is not None and m["loops"] == 1 and m["rotation_deg_per_m"] == 0.0
        assert m["drift"] == pytest.approx(drift, abs=1e-4)
        assert m["rotation_max_deg"] == pytest.approx(2.0)
    assert measured_drift(SimpleNamespace(poses=None)) is None  # type: ignore[arg-type]
    # The allowance is the detector's own (one function, in the core); bad shapes are named.
    with pytest.raises(solid.SolidError, match=r"positions must have shape \(N, 3\)"):
        solid._solid._drift_swing(np.eye(3), np.eye(3), np.zeros((2, 2)), np.eye(3))
    with pytest.raises(solid.SolidError, match="r_query must be a"):
        solid._solid._drift_swing(np.eye(3), np.eye(3), np.zeros((2, 3)), np.eye(2))
    m = {"loops": 1, "drift": 0.05, "rotation_deg_per_m": 0.1, "rotation_max_deg": 37.0}
    (line,) = advice({"loops": 1, "rejections": {ODOMETRY_REJECTION: 40}, "odometry_drift_measured": m}, d)
    assert "measure it at 0.05 of the path" in line and ": --odometry-drift 0.05 --odometry-rotation-max-deg 37 (docs" in line
    # Many candidates waiting for a placement against few loops: the session never entered its
    # map, or its odometry broke.
    (line,) = advice({"loops": 2, "rejections": {"not placed yet: too few loops": 30}}, d)
    assert "30 registered candidates waited for a placement" in line and "#breakdowns" in line
    assert advice({"loops": 20, "rejections": {"not placed yet: too few loops": 30}}, d) == []


@pytest.mark.parametrize("value", ["0", "-2", "nan", "loose"])
def test_optimize_refuses_a_noise_scale_that_is_neither_auto_nor_positive(capsys: pytest.CaptureFixture[str], tmp_path: Path, value: str) -> None:
    code, _, err = run(capsys, "optimize", str(tmp_path), "--poses", "odom.txt", "--odom-noise-scale", value, "-o", str(tmp_path / "out"))
    assert code == 2 and "--odom-noise-scale" in err and "auto or a finite number > 0" in err
    assert not (tmp_path / "out").exists()
