"""The descriptor through the Python API: golden outputs, edge cases, bad input, heading."""

from __future__ import annotations

import json
import os
import pickle
import threading
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest

import solid
from conftest import in_forked_child
from scans import read_kitti, read_xyz

HDL64 = solid.SolidConfig.preset("hdl64")


def golden_cases(shared: Path) -> list[dict[str, Any]]:
    cases: list[dict[str, Any]] = json.loads((shared / "golden" / "descriptors.json").read_text())["cases"]
    return cases


def rel_l1(ours: npt.NDArray[np.float32], golden: list[float]) -> float:
    g = np.asarray(golden, dtype=np.float64)
    return float(np.abs(ours.astype(np.float64) - g).sum() / max(np.abs(g).sum(), 1e-300))


def rotate_z(xyz: npt.NDArray[np.float64], deg: float) -> npt.NDArray[np.float64]:
    t = np.radians(deg)
    rot = np.array([[np.cos(t), -np.sin(t), 0.0], [np.sin(t), np.cos(t), 0.0], [0.0, 0.0, 1.0]])
    return np.ascontiguousarray(xyz @ rot.T)


# --- golden outputs (docs/spec.md §7) ------------------------------------------------------------------


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_every_golden_case_matches(shared: Path, dtype: type) -> None:
    cases = golden_cases(shared)
    assert len(cases) == 50
    for case in cases:
        cfg = solid.SolidConfig.preset(case["preset"], voxel_size=case["config"]["voxel_size"])
        assert cfg.to_dict() == case["config"], case["file"]
        xyz: npt.NDArray[Any] = read_xyz(shared / case["file"]).astype(dtype)
        d = solid.describe(xyz, cfg)
        where = f"{case['file']} voxel {cfg.voxel_size} {np.dtype(dtype).name}"
        assert d.n_points == case["n_points"], where
        assert d.n_in_range == case["n_in_range"], where
        assert abs(d.n_kept - case["n_kept"]) <= 1e-3 * case["n_kept"], where
        assert rel_l1(d.r, case["r_solid"]) <= 1e-3, where
        assert rel_l1(d.a, case["a_solid"]) <= 1e-3, where
        assert d.r.dtype == np.float32 and d.a.dtype == np.float32
        assert d.r.shape == (40,) and d.a.shape == (60,)


def test_extra_columns_are_ignored_and_read_in_place(data: Path) -> None:
    raw = read_kitti(data / "kitti00" / "velodyne" / "000000.bin")  # (N, 4) float32
    assert raw.flags.c_contiguous
    d4 = solid.describe(raw, HDL64)
    d3 = solid.describe(np.ascontiguousarray(raw[:, :3]), HDL64)
    wide = np.concatenate([raw, np.full((len(raw), 3), np.nan, np.float32)], axis=1)
    d7 = solid.describe(wide, HDL64)
    for d in (d3, d7):
        np.testing.assert_array_equal(d.r, d4.r)
        np.testing.assert_array_equal(d.a, d4.a)


# --- edge cases ------------------------------------------------------------------------------------


def test_empty_scan_is_all_zeros_and_distance_one() -> None:
    d = solid.describe(np.zeros((0, 3), np.float32), HDL64)
    assert (d.n_points, d.n_in_range, d.n_kept) == (0, 0, 0)
    assert not d.r.any() and not d.a.any()
    other = solid.describe(np.array([[10.0, 1.0, -1.0]]), HDL64)
    assert solid.distance(d, other) == 1.0
    assert solid.distance(d, d) == 1.0
    assert solid.heading(d, d) == 0.0


def test_all_nan_scan_is_empty() -> None:
    pts = np.full((1000, 4), np.nan, np.float32)
    d = solid.describe(pts, HDL64)
    assert (d.n_points, d.n_in_range, d.n_kept) == (1000, 0, 0)
    assert not d.r.any() and not d.a.any()


def test_points_outside_the_vertical_fov_go_to_the_edge_bins() -> None:
    rng = np.random.default_rng(1)
    n = 5000
    az = rng.uniform(0, 2 * np.pi, n)
    rho = rng.uniform(5, 70, n)
    for elev_deg in (60.0, -70.0):  # above +2° and below -24.8°
        el = np.radians(elev_deg)
        pts = np.stack([rho * np.cos(el) * np.cos(az), rho * np.cos(el) * np.sin(az), rho * np.sin(el)], axis=1)
        d = solid.describe(pts, HDL64.replace(voxel_size=0.0))
        # One elevation bin holds everything: EC is min-max normalised over 64 bins, so that
        # bin's weight is 1 and R-SOLiD / A-SOLiD are plain histograms of all points.
        assert d.n_kept == n
        assert d.r.sum() == pytest.approx(n) and d.a.sum() == pytest.approx(n)
        assert np.isfinite(d.r).all() and np.isfinite(d.a).all()


def test_single_point() -> None:
    d = solid.describe(np.array([[10.0, 10.0, -1.0]], np.float64), HDL64)
    assert d.n_kept == 1
    assert np.flatnonzero(d.r).tolist() == [7]  # r = 14.1 m of 80 m in 40 bins
    assert np.flatnonzero(d.a).tolist() == [7]  # 45° in 6° bins
    assert d.r[7] == 1.0


def test_huge_coordinates_are_dropped_not_overflowing() -> None:
    base = np.array([[10.0, 2.0, -1.0], [-20.0, 5.0, 0.5]], np.float32)
    huge = np.array([[1e30, 0, 0], [-1e30, 1e30, 1e30], [3e38, -3e38, 0]], np.float32)
    for dt in (np.float32, np.float64):
        b: npt.NDArray[Any] = base.astype(dt)
        hb: npt.NDArray[Any] = np.concatenate([huge, base]).astype(dt)
        d0 = solid.describe(b, HDL64)
        d1 = solid.describe(hb, HDL64)
        np.testing.assert_array_equal(d0.r, d1.r)
        np.testing.assert_array_equal(d0.a, d1.a)
        assert d1.n_points == 5 and d1.n_in_range == 2


def test_ten_million_points() -> None:
    rng = np.random.default_rng(7)
    n = 10_000_000
    pts = rng.uniform(-60.0, 60.0, size=(n, 3)).astype(np.float32)
    pts[:, 2] *= 0.1
    d = solid.describe(pts, HDL64)
    assert d.n_points == n
    inside = np.linalg.norm(pts[:1_000_000].astype(np.float64), axis=1)
    frac = ((inside > 3.0) & (inside < 80.0)).mean()
    assert d.n_in_range == pytest.approx(frac * n, rel=0.01)
    assert 0 < d.n_kept < d.n_in_range
    assert np.isfinite(d.r).all() and d.r.sum() > 0


# --- bad input -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("points", "exc", "words"),
    [
        (np.zeros(12, np.float32), solid.SolidError, "shape (12,)"),
        (np.zeros((4, 2), np.float32), solid.SolidError, "shape (4, 2)"),
        (np.zeros((2, 3, 3), np.float32), solid.SolidError, "shape (2, 3, 3)"),
        (np.zeros((4, 3), np.int64), TypeError, "astype(np.float32)"),
        (np.zeros((4, 3), np.float16), TypeError, "dtype float16"),
        (np.zeros((4, 3), ">f8"), TypeError, "native float32 or float64"),
        (np.asfortranarray(np.zeros((4, 3), np.float32)), solid.SolidError, "np.ascontiguousarray"),
        (np.zeros((8, 3), np.float32)[::2], solid.SolidError, "not C-contiguous"),
        ([[1.0, 2.0, 3.0]], TypeError, "np.asarray"),
    ],
)
def test_bad_points_are_rejected_with_the_fix(points: Any, exc: type[Exception], words: str) -> None:
    with pytest.raises(exc, match=None) as info:
        solid.describe(points, HDL64)
    assert words in str(info.value)


def test_solid_errors_are_value_errors() -> None:
    assert issubclass(solid.SolidError, ValueError)
    assert issubclass(solid.ConfigError, solid.SolidError)


def test_fortran_input_is_never_read_wrongly() -> None:
    # A (4, 3) Fortran array has the same bytes as its transpose in C order: reading it in place
    # would be silently wrong, so it must be refused, and the fix must give the right answer.
    pts = np.array([[10.0, 0, 0], [0, 12, 0], [-20, -3, -2], [5, 5, 1]], np.float64)
    f = np.asfortranarray(pts)
    with pytest.raises(solid.SolidError):
        solid.describe(f, HDL64)
    np.testing.assert_array_equal(solid.describe(np.ascontiguousarray(f), HDL64).r, solid.describe(pts, HDL64).r)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"n_range": 0}, "n_range"),
        ({"n_range": 1025}, "n_range"),
        ({"n_azimuth": 3601}, "n_azimuth"),
        ({"n_elevation": 0}, "n_elevation"),
        ({"n_elevation": -3}, "n_elevation"),
        ({"fov_up": 95.0}, "fov_up"),
        ({"fov_down": float("nan")}, "fov_down"),
        ({"fov_down": 5.0}, "fov_down"),
        ({"min_range": -1.0}, "min_range"),
        ({"max_range": 2.0}, "max_range"),
        ({"max_range": float("inf")}, "max_range"),
        ({"voxel_size": -0.1}, "voxel_size"),
    ],
)
def test_invalid_config_names_the_parameter(kwargs: dict[str, Any], name: str) -> None:
    with pytest.raises(solid.ConfigError, match=name):
        solid.SolidConfig.preset("hdl64", **kwargs)
    with pytest.raises(solid.ConfigError, match=name):
        HDL64.replace(**kwargs)


def test_config_construction_and_presets() -> None:
    cfg = solid.SolidConfig(fov_up=2.0, fov_down=-24.8, n_elevation=64)
    assert cfg == HDL64  # defaults of docs/spec.md §1 otherwise
    assert solid.SolidConfig.preset("avia", max_range=40.0).max_range == 40.0
    with pytest.raises(TypeError):
        solid.SolidConfig(fov_up=2.0, fov_down=-24.8)  # type: ignore[call-arg]
    with pytest.raises(TypeError, match="max_rnge"):
        solid.SolidConfig.preset("avia", max_rnge=40.0)  # type: ignore[call-arg]
    with pytest.raises(solid.ConfigError, match="hdl64, hdl32, vlp16, os1-64, avia, aeva"):
        solid.SolidConfig.preset("velodyne")
    presets = solid.presets()
    assert sorted(presets) == sorted(["hdl64", "hdl32", "vlp16", "os1-64", "avia", "aeva"])
    for name, p in presets.items():
        assert p == solid.SolidConfig.preset(name)
    assert presets["aeva"].to_dict() == {
        "n_range": 40, "n_azimuth": 60, "n_elevation": 64, "fov_up": 9.6, "fov_down": -9.6,
        "min_range": 3.0, "max_range": 120.0, "voxel_size": 0.5,
    }  # fmt: skip
    assert solid.SolidConfig(**presets["vlp16"].to_dict()) == presets["vlp16"]
    assert len({hash(p) for p in presets.values()}) == 6


def test_pickle_round_trip() -> None:
    d = solid.describe(np.array([[10.0, 1.0, -1.0], [20.0, -4.0, 0.0]]), HDL64)
    d2 = pickle.loads(pickle.dumps(d))
    np.testing.assert_array_equal(d.r, d2.r)
    np.testing.assert_array_equal(d.a, d2.a)
    assert (d2.n_points, d2.n_kept, d2.config) == (d.n_points, d.n_kept, d.config)
    assert pickle.loads(pickle.dumps(HDL64)) == HDL64


def test_descriptor_from_stored_vectors_is_checked() -> None:
    cfg = HDL64
    d = solid.Descriptor(np.ones(40), np.ones(60), cfg)
    assert d.r.dtype == np.float32 and solid.distance(d, d) == 0.0
    with pytest.raises(solid.SolidError, match="length 39"):
        solid.Descriptor(np.ones(39), np.ones(60), cfg)
    with pytest.raises(solid.SolidError, match="non-negative"):
        solid.Descriptor(np.full(40, np.nan), np.ones(60), cfg)


def test_comparing_descriptors_of_different_configs_is_an_error() -> None:
    pts = np.array([[10.0, 1.0, -1.0]])
    a = solid.describe(pts, HDL64)
    b = solid.describe(pts, HDL64.replace(voxel_size=0.25))
    with pytest.raises(solid.SolidError, match="different configs"):
        solid.distance(a, b)
    with pytest.raises(solid.SolidError, match="different configs"):
        solid.heading(a, b)


# --- batch and threads --------------------------------------------------------------------------


def test_describe_batch_equals_describe(data: Path) -> None:
    scans: list[npt.NDArray[Any]] = [read_kitti(p) for p in sorted((data / "kitti00" / "velodyne").glob("*.bin"))]
    scans.append(read_xyz(data / "misc" / "naverlabs_vel16.pcd"))  # float64 mixed in
    one = [solid.describe(s, HDL64) for s in scans]
    for threads in (None, 1, 3):
        many = solid.describe_batch(scans, HDL64, threads=threads)
        assert len(many) == len(one)
        for a, b in zip(one, many):
            np.testing.assert_array_equal(a.r, b.r)
            np.testing.assert_array_equal(a.a, b.a)
    assert solid.describe_batch([], HDL64) == []
    assert len(solid.describe_batch(iter(scans[:2]), HDL64)) == 2


def _describe_workers() -> set[int]:
    """Thread ids of this process's describe_batch workers (Linux: named in /proc)."""
    tids: set[int] = set()
    for tid in os.listdir("/proc/self/task"):
        try:
            name = Path(f"/proc/self/task/{tid}/comm").read_text().strip()
        except OSError:  # ended meanwhile
            continue
        if name.startswith("solid-describe"):
            tids.add(int(tid))
    return tids


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="reads thread names from Linux's /proc")
def test_describe_batch_workers_persist_across_calls(data: Path) -> None:
    scans = [read_kitti(p) for p in sorted((data / "kitti00" / "velodyne").glob("*.bin"))]
    solid.describe_batch(scans, HDL64, threads=2)
    solid.describe_batch(scans, HDL64)  # every core: another pool where there are more than 2
    workers = _describe_workers()
    assert workers, "no describe worker outlives a batch"
    for threads in (2, None, 2, 1, None):
        solid.describe_batch(scans, HDL64, threads=threads)
        assert _describe_workers() == workers, "a batch started or ended workers"


def _describe_batch_in_child(raw: npt.NDArray[Any], conn: Any) -> None:
    d = solid.describe_batch([raw, raw], HDL64, threads=2)
    conn.send([x.r.tolist() for x in d])


def test_describe_batch_works_in_a_forked_child(data: Path) -> None:
    # The parent's workers do not exist in a child made by fork: the child must start its own
    # instead of waiting for them forever.
    raw = read_kitti(data / "kitti00" / "velodyne" / "000094.bin")
    want = solid.describe(raw, HDL64).r.tolist()
    solid.describe_batch([raw, raw], HDL64, threads=2)  # the parent's workers exist
    assert in_forked_child(_describe_batch_in_child, raw, what="describe_batch") == [want, want]


def test_describe_batch_names_the_bad_scan() -> None:
    good = np.zeros((5, 3), np.float32)
    with pytest.raises(solid.SolidError, match=r"scans\[1\]"):
        solid.describe_batch([good, np.zeros((5, 2), np.float32)], HDL64)
    with pytest.raises(solid.SolidError, match="threads"):
        solid.describe_batch([good], HDL64, threads=-1)


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="reads thread names from Linux's /proc")
def test_zero_threads_mean_one_per_core_as_everywhere(data: Path) -> None:
    # Issue 29: one meaning of a thread count (as verify_threads and the CLI's --threads): 0 is
    # None's pool, one worker per core.
    scans = [read_kitti(p) for p in sorted((data / "kitti00" / "velodyne").glob("*.bin"))]
    want = [d.r.tolist() for d in solid.describe_batch(scans, HDL64)]
    workers = _describe_workers()
    assert [d.r.tolist() for d in solid.describe_batch(scans, HDL64, threads=0)] == want
    assert _describe_workers() == workers, "threads=0 started another pool than None's"


def test_python_threads_share_the_extension_safely(data: Path) -> None:
    raw = read_kitti(data / "kitti00" / "velodyne" / "000094.bin")
    want = solid.describe(raw, HDL64)
    flat = HDL64.replace(voxel_size=0.0)
    want_flat = solid.describe(raw, flat)
    errors: list[str] = []

    def work(cfg: solid.SolidConfig, expect: solid.Descriptor) -> None:
        for _ in range(5):
            got = solid.describe(raw, cfg)
            if not np.array_equal(got.r, expect.r):
                errors.append("mismatch")

    threads = [threading.Thread(target=work, args=(c, w)) for c, w in [(HDL64, want), (flat, want_flat)] * 2]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []


# --- heading on real 360° scans -----------------------------------------------------------------


def full_scans(data: Path) -> list[npt.NDArray[np.float64]]:
    paths = sorted((data / "kitti00" / "velodyne").glob("*.bin")) + sorted(
        (data / "solid-samples" / "kitti_00_pcd").glob("*.pcd")
    )
    assert len(paths) == 8
    return [read_xyz(p) for p in paths]


def test_refined_heading_on_rotated_full_scans(data: Path) -> None:
    angles = [-170.0, -123.4, -77.0, -30.0, -4.5, 2.0, 17.3, 45.0, 91.7, 150.0, 179.0]
    errors = []
    for xyz in full_scans(data):
        cand = solid.describe(xyz, HDL64)
        for deg in angles:
            q = solid.describe(rotate_z(xyz, deg), HDL64)
            est = solid.heading(q, cand, refine=True)
            assert -180.0 < est <= 180.0
            errors.append(abs((est - deg + 180.0) % 360.0 - 180.0))
            assert solid.distance(q, cand) < 0.02
    err = np.asarray(errors)
    print(f"refined heading error over {err.size} rotations: mean {err.mean():.3f}°, max {err.max():.3f}°")
    assert err.mean() <= 1.0
    assert err.max() <= 2.0


def test_integer_heading_is_a_multiple_of_the_bin(data: Path) -> None:
    xyz = full_scans(data)[0]
    cand = solid.describe(xyz, HDL64)
    q = solid.describe(rotate_z(xyz, 30.0), HDL64)
    assert solid.heading(q, cand, refine=False) == 30.0
    assert solid.heading(cand, q, refine=False) == -30.0
    assert q.heading(cand) == solid.heading(q, cand)
