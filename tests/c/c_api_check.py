"""The C and C++ examples, built against the installed C package, against the Python product.

Run by `make c-test` (not collected by the plain pytest run: the examples must be built first),
which sets SOLID_C_BUILD to the folder holding the builds: cmake/ (find_package), pkgconfig/,
static/ (libsolid.a) and asan/ (AddressSanitizer). Checks that `describe` prints the Python
descriptor bit for bit, that `loops` prints `solid detect`'s loops.csv (verified and
--no-verify, alone and into a map: the loops a placement released, the anchor) and its
odometry.csv (the detector's own odometry, `SolidStep`), and that both run clean under
AddressSanitizer and valgrind.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest

import solid
from solid import io as sio

# (scan, preset) pairs covering KITTI .bin (clipped and full), binary PCD of three sensors.
SCANS = [
    *[(f"solid-samples/kitti_00_{fov}/{f}.bin", "hdl64") for fov in (60, 120, 180) for f in ("000000", "000001", "000060")],
    *[(f"kitti00/velodyne/{f}.bin", "hdl64") for f in ("000000", "000094", "000198")],
    *[(f"solid-samples/kitti_00_pcd/{f}.pcd", "hdl64") for f in ("000313", "000314", "000315")],
    *[(f"hku1-avia/Scans/{f:06d}.pcd", "avia") for f in (0, 1, 100, 200, 313)],
    ("misc/naverlabs_vel16.pcd", "vlp16"),
]


def build_dir() -> Path:
    env = os.environ.get("SOLID_C_BUILD")
    if not env:
        pytest.fail("SOLID_C_BUILD is not set: run these checks through `make c-test`")
    return Path(env)


def run(cmd: list[str], env: dict[str, str] | None = None, timeout: float = 600) -> str:
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout)
    assert p.returncode == 0, f"{' '.join(cmd)} exited {p.returncode}:\n{p.stderr[-4000:]}"
    return p.stdout


def parse_describe(out: str) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
    r, a = out.split("\n\n")
    return np.array(r.split(), dtype=np.float32), np.array(a.split(), dtype=np.float32)


@pytest.mark.parametrize(("scan", "preset"), SCANS)
def test_describe_equals_python_bit_for_bit(data: Path, scan: str, preset: str) -> None:
    path = data / scan
    r, a = parse_describe(run([str(build_dir() / "cmake" / "describe"), str(path), preset]))
    want = solid.describe(sio.read_points(path), solid.SolidConfig.preset(preset))
    assert r.tobytes() == np.asarray(want.r, dtype=np.float32).tobytes()
    assert a.tobytes() == np.asarray(want.a, dtype=np.float32).tobytes()


@pytest.mark.parametrize("variant", ["pkgconfig", "static", "asan"])
def test_other_builds_print_the_same(data: Path, variant: str) -> None:
    for scan, preset in (SCANS[0], SCANS[-1]):
        args = [str(data / scan), preset]
        assert run([str(build_dir() / variant / "describe"), *args]) == run([str(build_dir() / "cmake" / "describe"), *args])


def test_describe_names_what_is_wrong(data: Path, tmp_path: Path) -> None:
    exe = str(build_dir() / "cmake" / "describe")
    p = subprocess.run([exe, str(data / SCANS[0][0]), "nope"], capture_output=True, text=True)
    assert p.returncode == 1 and "unknown preset" in p.stderr
    bad = tmp_path / "bad.bin"
    bad.write_bytes(b"\0" * 17)
    p = subprocess.run([exe, str(bad), "hdl64"], capture_output=True, text=True)
    assert p.returncode == 1 and "16-byte" in p.stderr


def solid_detect(scans: Path, preset: str, out: Path, verify: bool, *more: str) -> str:
    cmd = [sys.executable, "-m", "solid", "detect", str(scans), "--preset", preset, "-o", str(out), "-q", *more]
    run(cmd + ([] if verify else ["--no-verify"]))
    return (out / "loops.csv").read_text()


def stretch(data: Path, tmp_path: Path, frames: list[int] | range | None = None) -> Path:
    """Keyframes of the hku1 walk as links (default: its start and its end, the revisit)."""
    folder = tmp_path / "stretch"
    folder.mkdir()
    for i in frames if frames is not None else [*range(0, 30), *range(262, 314)]:
        (folder / f"{i:06d}.pcd").symlink_to(data / "hku1-avia" / "Scans" / f"{i:06d}.pcd")
    return folder


@pytest.mark.parametrize("verify", [True, False], ids=["verified", "no-verify"])
def test_loops_equal_solid_detect_on_the_walk(data: Path, tmp_path: Path, verify: bool) -> None:
    scans = data / "hku1-avia" / "Scans"
    want = solid_detect(scans, "avia", tmp_path / "py", verify)
    odometry = tmp_path / "odometry.csv"
    flags = ["--odometry", str(odometry)] if verify else ["--no-verify"]
    got = run([str(build_dir() / "cmake" / "loops"), str(scans), "avia", *flags])
    # Without poses the verified walk has 49 loops (the detector's own odometry,
    # docs/loops.md#without-poses), without verification more.
    assert want.count("\n") > 40, "the walk has loops"
    assert got == want
    if verify:
        # The poses the steps used (SolidStep: the detector's own odometry), as solid detect
        # writes them.
        assert odometry.read_text() == (tmp_path / "py" / "odometry.csv").read_text()
        assert odometry.read_text().count(",chained,") > 250


def test_loops_into_a_map_are_released_when_the_session_is_placed(data: Path, tmp_path: Path) -> None:
    """The first half of the walk as a map (with its poses), the second half as a new session
    against it, without poses: its loops into the map wait for the placement (frame 265), which
    releases them (solid_detector_last_step, solid_detector_released), and the anchor
    (solid_detector_map_anchor) is the one solid detect reports."""
    walk = data / "hku1-avia"
    m = tmp_path / "first.soliddb"
    run([sys.executable, "-m", "solid", "map", "build", str(walk / "Scans"), "--frames", "0:157",
         "--poses", str(walk / "odom_poses.txt"), "--preset", "avia", "-o", str(m), "-q"])
    second = stretch(data, tmp_path, range(157, 314))
    want = solid_detect(second, "avia", tmp_path / "py", True, "--map", str(m))
    p = subprocess.run([str(build_dir() / "cmake" / "loops"), str(second), "avia", "--map", str(m)],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    assert p.stdout == want
    placed = [ln for ln in p.stderr.splitlines() if ln.startswith("placed in the map")]
    assert len(placed) == 1, p.stderr
    released = int(placed[0].split("released ")[1].split()[0])
    # Loops of queries before the placement, in loops.csv but accepted at no step of their own.
    assert released >= 10
    a = json.loads((tmp_path / "py" / "summary.json").read_text())["map_anchor"]
    t = np.array(a["transform"])
    assert f"anchor: {a['loops']} loops over {a['metres']:.3f} m" in p.stderr
    assert "translation " + " ".join(f"{v:.6f}" for v in t[:3, 3]) in p.stderr


def test_examples_clean_under_address_sanitizer(data: Path, tmp_path: Path) -> None:
    env = dict(os.environ, ASAN_OPTIONS="detect_leaks=1:halt_on_error=1:abort_on_error=0")
    # The whole walk: verified without poses, the detector's own odometry links every keyframe to
    # the one before, so a stretch with a gap (stretch()) relates its two ends by no odometry
    # and has no loop (docs/loops.md#without-poses).
    folder = data / "hku1-avia" / "Scans"
    got = run([str(build_dir() / "asan" / "loops"), str(folder), "avia"], env=env)
    assert got == solid_detect(folder, "avia", tmp_path / "py", True)
    assert got.count("\n") > 5
    run([str(build_dir() / "asan" / "describe"), str(data / SCANS[-2][0]), "avia"], env=env)


def test_examples_clean_under_valgrind(data: Path, tmp_path: Path) -> None:
    if shutil.which("valgrind") is None:
        pytest.fail("valgrind is missing (make c-deps installs it)")
    vg = ["valgrind", "--quiet", "--error-exitcode=99", "--leak-check=full", "--errors-for-leak-kinds=definite,indirect"]
    folder = stretch(data, tmp_path)
    got = run([*vg, str(build_dir() / "cmake" / "loops"), str(folder), "avia", "--no-verify"])
    assert got == solid_detect(folder, "avia", tmp_path / "py", False)
    run([*vg, str(build_dir() / "cmake" / "describe"), str(data / SCANS[0][0]), "hdl64"])
