"""The place-recognition engine from Python: Database, LoopDetector, wire form (issue 3)."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from conftest import data_dir, in_forked_child
from scans import read_kitti

import solid
from solid import io as sio



def kitti(name: str) -> npt.NDArray[np.float32]:
    return read_kitti(data_dir() / "kitti00" / "velodyne" / f"{name}.bin")


def synthetic(cfg: solid.SolidConfig, seed: int) -> solid.Descriptor:
    """A descriptor of a random scene (points on a few walls and the ground)."""
    rng = np.random.default_rng(seed)
    n = 3000
    az = rng.uniform(0, 2 * np.pi, n)
    rho = rng.choice(rng.uniform(5, 60, 8), n) + rng.normal(0, 0.3, n)
    z = rng.uniform(-1.7, 3.0, n)
    pts = np.stack([rho * np.cos(az), rho * np.sin(az), z], axis=1)
    return solid.describe(pts, cfg)


@pytest.fixture
def cfg() -> solid.SolidConfig:
    return solid.SolidConfig.preset("hdl64")


@pytest.fixture
def db(cfg: solid.SolidConfig) -> solid.Database:
    db = solid.Database(cfg)
    for i in range(40):
        pose: npt.NDArray[np.float64] | None = None
        if i % 2 == 0:
            pose = np.hstack([np.eye(3), np.array([[i], [0.0], [0.0]])])
        assert db.add(synthetic(cfg, i), session=i % 3, timestamp=float(i) if i % 5 else None, pose=pose) == i
    return db


def test_search_is_exact_and_methods_agree(cfg: solid.SolidConfig, db: solid.Database) -> None:
    assert len(db) == 40
    q = synthetic(cfg, 7)
    hits = db.search(q, k=5)
    assert [type(h) for h in hits] == [solid.Match] * 5
    assert hits[0].id == 7 and hits[0].distance < 1e-6
    assert [h.distance for h in hits] == sorted(h.distance for h in hits)
    for method in ("brute", "kdtree", "sketch", "auto"):
        assert db.search(q, k=5, method=method) == hits
    # A distance bound keeps the neighbours within it.
    assert db.search(q, k=5, max_distance=hits[2].distance) == hits[:3]
    # The distances are the docs/spec.md §3 cosine distances.
    for h in hits:
        assert h.distance == pytest.approx(solid.distance(q, synthetic(cfg, h.id)), abs=1e-5)
    # An R-SOLiD array works as a query too.
    assert db.search(np.asarray(q.r), k=5) == hits
    recent = db.search(q, k=100, exclude_recent=35)
    assert sorted(h.id for h in recent) == list(range(5))
    with pytest.raises(ValueError, match="method"):
        db.search(q, method="fast")


def test_batch_add_and_search_agree_with_one_at_a_time(cfg: solid.SolidConfig, db: solid.Database) -> None:
    descs = [synthetic(cfg, i) for i in range(40)]
    r = np.stack([d.r for d in descs])
    a = np.stack([d.a for d in descs])
    poses = np.array([np.hstack([np.eye(3), np.array([[i], [0.0], [0.0]])]) for i in range(40)])
    times = np.arange(40, dtype=np.float64)
    batch = solid.Database(cfg)
    assert batch.add_batch(r, a, session=2, timestamps=times, poses=poses) == 0
    assert batch.add_batch(r.astype(np.float64), a, index=False) == 40
    assert len(batch) == 80
    np.testing.assert_array_equal(batch.r[:40], r)
    np.testing.assert_array_equal(batch.sessions, [2] * 40 + [0] * 40)
    np.testing.assert_array_equal(batch.poses[:40], poses)
    assert np.isnan(batch.poses[40:]).all() and np.isnan(batch.timestamps[40:]).all()
    # Before and after the kd-tree catches up, every method finds what one search finds.
    for _ in range(2):
        ids, dists = batch.search_batch(r[:7], k=3, exclude_recent=10)
        assert ids.shape == (7, 3) and ids.dtype == np.int64 and dists.dtype == np.float32
        for i in range(7):
            hits = batch.search(r[i], k=3, exclude_recent=10)
            assert list(ids[i]) == [h.id for h in hits]
            np.testing.assert_array_equal(dists[i], [h.distance for h in hits])
        batch.build_index()
    for method in ("brute", "kdtree", "sketch", "auto"):
        ids_m, _ = batch.search_batch(descs[:5], k=4, method=method, max_distance=0.05)
        for i in range(5):
            hits = batch.search(descs[i], k=4, method="brute", max_distance=0.05)
            assert [h.id for h in hits] == [j for j in ids_m[i] if j >= 0]
            # Entry 40 + i is a copy of entry i: a tie, broken by the lower id.
            assert [h.id for h in hits[:2]] == [i, 40 + i] and hits[0].distance == hits[1].distance
    # Empty slots: -1 and inf.
    ids, dists = solid.Database(cfg).search_batch(r[:2], k=2)
    assert (ids == -1).all() and np.isinf(dists).all()
    with pytest.raises(ValueError, match=r"shape \(N, 40\)"):
        batch.add_batch(r[:, :5], a)
    with pytest.raises(ValueError, match="rows"):
        batch.add_batch(r, a[:3])
    with pytest.raises(ValueError, match="max_distance"):
        batch.search_batch(r[:1], max_distance=float("nan"))
    assert len(batch) == 80
    assert 0 < batch.memory_bytes() < 400 * 80


def random_places(n: int, seed: int) -> tuple[solid.SolidConfig, npt.NDArray[np.float32], npt.NDArray[np.float32]]:
    """The avia preset and `n` random R-SOLiD and A-SOLiD rows (uniform in [0, 1))."""
    cfg = solid.SolidConfig.preset("avia")
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.0, 1.0, (n, cfg.n_range)).astype(np.float32)
    a = rng.uniform(0.0, 1.0, (n, cfg.n_azimuth)).astype(np.float32)
    return cfg, r, a


def test_a_bulk_add_leaves_the_index_to_the_searches_that_pay_for_it() -> None:
    import threading

    n = 3000
    cfg, r, a = random_places(n, 8)
    db = solid.Database(cfg)
    db.add_batch(r, a)
    assert db.index_pending() == n
    want = [db.search(r[i], k=2, method="brute") for i in range(5)]
    assert [w[0].id for w in want] == list(range(5))
    # A build costs about 40 brute-force passes over the new entries: 39 searches scan them
    # instead (brute force itself counts nothing), and the 40th builds the index first.
    for i in range(39):
        assert db.search(r[i % 5], k=2, method="brute") == want[i % 5]
        assert db.search(r[i % 5], k=2) == want[i % 5]
        assert db.index_pending() == n
    assert db.search(r[0], k=2) == want[0]
    assert db.index_pending() == 0
    # A batch of 40 queries builds it before searching.
    batch = solid.Database(cfg)
    batch.add_batch(r, a)
    ids, _ = batch.search_batch(r[:40], k=1)
    assert batch.index_pending() == 0 and ids[:, 0].tolist() == list(range(40))
    # index=False: only build_index (or the next add); index=True: at once.
    stored = solid.Database(cfg)
    stored.add_batch(r, a, index=False)
    stored.search_batch(r[:100], k=1)
    assert stored.index_pending() == n
    stored.build_index()
    assert stored.index_pending() == 0
    now = solid.Database(cfg)
    now.add_batch(r, a, index=True)
    assert now.index_pending() == 0
    # The last add_batch decides for every entry still waiting.
    mixed = solid.Database(cfg)
    mixed.add_batch(r[:1000], a[:1000])
    mixed.add_batch(r[1000:], a[1000:], index=False)
    mixed.search_batch(r[:100], k=1)
    assert mixed.index_pending() == n
    mixed.add_batch(r[:1], a[:1])
    mixed.search_batch(r[:100], k=1)
    assert mixed.index_pending() == 0
    # A detector over a database builds its pending index first (it searches on every scan), in
    # the database it shares rather than in a copy.
    waiting = solid.Database(cfg)
    waiting.add_batch(r, a)
    assert waiting.index_pending() == n
    detector = solid.LoopDetector.from_database(waiting)
    assert detector.map.index_pending() == 0 and waiting.index_pending() == 0
    # Threads searching while one of them builds the index all find what brute force finds.
    shared = solid.Database(cfg)
    shared.add_batch(r, a)
    errors: list[str] = []

    def searcher(t: int) -> None:
        for j in range(30):
            i = (t + j) % 5
            got = shared.search(r[i], k=2)
            if got != want[i]:
                errors.append(f"thread {t}, query {i}: {got} != {want[i]}")

    threads = [threading.Thread(target=searcher, args=(t,)) for t in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    assert shared.index_pending() == 0


def resident_bytes() -> int:
    """The process's resident memory (Linux)."""
    pages = int(Path("/proc/self/statm").read_text().split()[1])
    return pages * 4096


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="reads /proc/self/statm (Linux)")
def test_a_detector_shares_its_map_instead_of_copying_it() -> None:
    n = 100_000
    cfg, r, a = random_places(n, 3)
    db = solid.Database(cfg)
    db.add_batch(r, a, index=True)
    before = resident_bytes()
    det = solid.LoopDetector.from_database(db, verify=False, exclude_recent=0, top_k=3)
    # A copy of the places would take as much memory again as the database holds.
    grew = resident_bytes() - before
    assert grew < db.memory_bytes() // 8, (grew, db.memory_bytes())
    assert len(det) == len(det.map) == len(det.database) == n
    # The map's places are candidates; the detector's scans are its own, the database stays as it was.
    place = solid.Descriptor(r[7], a[7], cfg)
    assert det.add(place) is not None and det.detect(place).candidates[0].id in (7, n)
    assert len(det) == n + 2 and len(db) == len(det.map) == n
    everything = det.database
    assert len(everything) == n + 2 and everything.sessions[n:].tolist() == [det.session] * 2
    assert np.array_equal(everything.r[n], r[7])
    # An add to the database afterwards makes it its own copy: the detector does not see it.
    db.add(solid.Descriptor(r[9], a[9], cfg))
    assert len(db) == n + 1 and len(det.map) == n and len(det) == n + 2
    found = det.query(solid.Descriptor(r[9], a[9], cfg))
    assert found is not None and found.candidate == 9


def test_numpy_export(cfg: solid.SolidConfig, db: solid.Database) -> None:
    assert db.r.shape == (40, cfg.n_range) and db.r.dtype == np.float32
    assert db.a.shape == (40, 60) and db.a.dtype == np.float32
    # A-SOLiDs are kept at 8 bits: within half a step (max / 255 / 2) of the values added.
    a = synthetic(cfg, 3).a
    np.testing.assert_allclose(db.a[3], a, rtol=0, atol=np.abs(a).max() / 510 * 1.001)
    np.testing.assert_array_equal(db.r[3], synthetic(cfg, 3).r)
    np.testing.assert_array_equal(db.ids, np.arange(40))
    np.testing.assert_array_equal(db.sessions, np.arange(40) % 3)
    assert math.isnan(db.timestamps[0]) and db.timestamps[1] == 1.0
    assert db.poses.shape == (40, 3, 4)
    assert db.poses[4, 0, 3] == 4.0 and np.isnan(db.poses[1]).all()


def test_save_load_round_trip(tmp_path: Path, db: solid.Database) -> None:
    path = tmp_path / "map.soliddb"
    db.save(path)
    assert [p.name for p in tmp_path.iterdir()] == ["map.soliddb"]
    back = solid.Database.load(path)
    assert len(back) == len(db)
    np.testing.assert_array_equal(back.r, db.r)
    np.testing.assert_array_equal(back.a, db.a)
    np.testing.assert_array_equal(back.sessions, db.sessions)
    np.testing.assert_array_equal(back.timestamps, db.timestamps)
    np.testing.assert_array_equal(back.poses, db.poses)
    assert solid.Database.from_bytes(db.to_bytes()).search(db.r[5], k=3) == db.search(db.r[5], k=3)


def test_a_loaded_maps_sketch_is_built_on_request_with_the_same_results(cfg: solid.SolidConfig, db: solid.Database) -> None:
    back = solid.Database.from_bytes(db.to_bytes())
    novel = synthetic(cfg, 1000)
    back.build_index()
    lean = back.memory_bytes()
    want = back.search(novel, k=5)
    back.build_index(sketch=True)
    assert back.memory_bytes() >= lean + len(back) * (cfg.n_range + 12)
    assert back.search(novel, k=5) == want == db.search(novel, k=5)
    back.build_index(sketch=False)
    assert back.memory_bytes() < lean + len(back) * cfg.n_range
    assert back.search(novel, k=5) == want


def test_a_turned_pose_comes_back_within_1e_12_and_saved_again_the_same_bytes(cfg: solid.SolidConfig) -> None:
    """Format 4 stores a rotation as a quaternion (docs/spec.md §13): a loaded pose is within
    1e-12 of the saved one, its translation exact, and saving the loaded map again gives the same
    bytes; format 3 keeps the matrices bit for bit."""
    db = solid.Database(cfg)
    d = synthetic(cfg, 0)
    for i in range(30):
        a, b = 0.9 * i, 0.4 * i - 1.0
        rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
        db.add(d, pose=np.hstack([rz @ ry, np.array([[i * 10.0], [-3.5], [0.25]])]))
    b4 = db.to_bytes()
    back = solid.Database.from_bytes(b4)
    assert np.abs(back.poses - db.poses).max() <= 1e-12
    np.testing.assert_array_equal(back.poses[:, :, 3], db.poses[:, :, 3])
    assert back.to_bytes() == b4 and len(b4) < len(db.to_bytes(version=3))
    np.testing.assert_array_equal(solid.Database.from_bytes(db.to_bytes(version=3)).poses, db.poses)


def test_bad_files_raise_clear_errors(tmp_path: Path, db: solid.Database) -> None:
    path = tmp_path / "map.soliddb"
    db.save(path)
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x40
    path.write_bytes(bytes(data))
    with pytest.raises(solid.DatabaseError, match="map.soliddb.*checksum"):
        solid.Database.load(path)
    assert issubclass(solid.DatabaseError, solid.SolidError)
    assert issubclass(solid.DatabaseError, ValueError)
    path.write_bytes(db.to_bytes()[:1000])
    with pytest.raises(ValueError, match="truncated"):
        solid.Database.load(path)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(200))
    with pytest.raises(ValueError, match="not a SOLiD database"):
        solid.Database.load(path)
    with pytest.raises(FileNotFoundError) as e:
        solid.Database.load(tmp_path / "missing.soliddb")
    assert e.value.filename is not None and e.value.filename.endswith("missing.soliddb")


def test_merge(cfg: solid.SolidConfig, db: solid.Database) -> None:
    other = solid.Database(cfg)
    other.add(synthetic(cfg, 100), session=9)
    db.merge(other)
    assert len(db) == 41 and db.sessions[40] == 9
    assert db.search(synthetic(cfg, 100))[0].id == 40
    db.merge(db)
    assert len(db) == 82
    foreign = solid.Database(solid.SolidConfig.preset("vlp16"))
    with pytest.raises(solid.DatabaseError, match="config"):
        db.merge(foreign)
    with pytest.raises(solid.DatabaseError, match="config"):
        db.add(synthetic(solid.SolidConfig.preset("vlp16"), 1))


def test_merge_with_an_anchor_moves_the_others_poses_into_this_world(cfg: solid.SolidConfig) -> None:
    here, there = solid.Database(cfg), solid.Database(cfg)
    here.add(synthetic(cfg, 1), pose=np.eye(4))
    there.add(synthetic(cfg, 2), pose=np.eye(4)[:3])
    T = np.eye(4)
    T[:3, 3] = [5.0, -1.0, 0.0]
    skew = T.copy()
    skew[0, 1] = 0.5
    with pytest.raises(solid.SolidError, match="anchor"):
        here.merge(there, anchor=skew)
    with pytest.raises(solid.SolidError, match="anchor"):
        here.merge(there, anchor=[1.0, 2.0])
    assert len(here) == 1
    here.merge(there, new_sessions=True, anchor=T.astype(np.float32))
    np.testing.assert_allclose(here.poses[1], T[:3])
    np.testing.assert_allclose(there.poses[0], np.eye(4)[:3])


def test_merge_with_one_anchor_per_place_moves_each_by_its_own(cfg: solid.SolidConfig) -> None:
    """An anchor array of shape (len(other), 3|4, 4): each place by its own transform (a session
    whose odometry broke: one per stretch), a row of NaN leaving its place without a pose; a
    count that is not one per place, or one transform that is not rigid, refused, nothing changed."""
    here, there = solid.Database(cfg), solid.Database(cfg)
    here.add(synthetic(cfg, 1), pose=np.eye(4))
    for k in range(3):
        P = np.eye(4)
        P[0, 3] = float(k)
        there.add(synthetic(cfg, 2 + k), pose=P)
    each = np.tile(np.eye(4), (3, 1, 1))
    each[0, 1, 3], each[1, 1, 3] = 10.0, 20.0
    each[2] = np.nan
    with pytest.raises(solid.SolidError, match="anchors"):
        here.merge(there, anchor=each[:2])
    skew = each.copy()
    skew[1, 0, 1] = 0.5
    with pytest.raises(solid.SolidError, match="anchor"):
        here.merge(there, anchor=skew)
    not_rigid = each.copy()
    not_rigid[0, 3, 3] = 2.0  # a 4x4 whose last row is not [0, 0, 0, 1]
    with pytest.raises(ValueError, match=r"anchor\[0\]"):
        here.merge(there, anchor=not_rigid)
    part_nan = each.copy()
    part_nan[1, 0, 3] = np.nan
    with pytest.raises(solid.ConfigError, match="anchor of place 1: invalid anchor = NaN"):
        here.merge(there, anchor=part_nan)
    with pytest.raises(solid.ConfigError, match="2 given, but the database merged has 3 places"):
        here.merge(there, anchor=each[:2])
    with pytest.raises(TypeError, match="got dtype int64"):
        here.merge(there, anchor=np.zeros((3, 3, 4), dtype=np.int64))
    with pytest.raises(ValueError, match=r"got shape \(3, 3, 3\)"):
        here.merge(there, anchor=each[:, :3, :3])
    with pytest.raises(solid.SolidError, match=r"one per place, an array of shape"):
        here.merge(there, anchor=np.zeros((3, 12)))
    assert len(here) == 1
    # float32 is read as float64, not refused (NaN rows still mean "no pose").
    here.merge(there, new_sessions=True, anchor=each[:, :3].astype(np.float32))
    P = here.poses
    np.testing.assert_allclose(P[1][:, 3], [0.0, 10.0, 0.0])
    np.testing.assert_allclose(P[2][:, 3], [1.0, 20.0, 0.0])
    assert np.isnan(P[3]).all()
    assert list(here.sessions) == [0, 1, 1, 1]


def test_loop_detector_on_kitti_revisit() -> None:
    cfg = solid.SolidConfig.preset("hdl64")
    # KITTI 94/95 and 198/199 are the same places; other pairs are at distance >= 0.08.
    det = solid.LoopDetector(cfg, exclude_recent=0, threshold=0.03, top_k=10, verify=False)
    assert det.add(kitti("000000")) is None
    assert det.add(kitti("000094"), timestamp=9.4) is None
    assert det.add(kitti("000198")) is None
    assert len(det) == 3
    found = det.query(kitti("000095"))
    assert isinstance(found, solid.Loop)
    assert (found.query, found.candidate) == (3, 1)
    assert 0.0 <= found.distance <= 0.03
    assert -180.0 < found.heading <= 180.0
    assert len(det) == 3
    assert det.add(solid.describe(kitti("000095"), cfg)) == found
    loop = det.add(kitti("000199"))
    assert loop is not None and (loop.query, loop.candidate) == (4, 2)
    assert len(det) == 5 and len(det.database) == 5


def test_loop_detector_on_hku_matches_exact_search() -> None:
    root = data_dir() / "hku1-avia"
    scans = sorted((root / "Scans").glob("*.pcd"))
    positions = np.loadtxt(root / "odom_poses.txt").reshape(-1, 3, 4)[:, :, 3]
    cfg = solid.SolidConfig.preset("avia")
    threshold = 0.05
    det = solid.LoopDetector(cfg, exclude_recent=50, threshold=threshold, rerank=False, verify=False)
    loops = [det.add(sio.read_points(p), timestamp=float(i)) for i, p in enumerate(scans)]
    assert len(det) == len(scans) == 314
    # Reference: the exact nearest neighbour among frames < q - 50 (docs/spec.md §5), computed in numpy.
    r = det.database.r.astype(np.float64)
    unit = r / np.linalg.norm(r, axis=1, keepdims=True)
    for q, lp in enumerate(loops):
        if q <= 50:
            assert lp is None
            continue
        dist = 1.0 - unit[: q - 50] @ unit[q]
        best = int(np.argmin(dist))
        if dist[best] > threshold + 1e-5:
            assert lp is None, q
        elif dist[best] < threshold - 1e-5:
            assert lp is not None and lp.query == q
            assert lp.distance == pytest.approx(dist[best], abs=1e-5)
            assert dist[lp.candidate] == pytest.approx(dist[best], abs=1e-5)
    # The strongest loops are the true revisit of the walk's start (odometry poses within 5 m).
    found = sorted((lp for lp in loops if lp is not None), key=lambda lp: lp.distance)
    true = [np.linalg.norm(positions[lp.query] - positions[lp.candidate]) <= 5.0 for lp in found[:5]]
    assert sum(true) >= 3, found[:5]


def test_wire_form(cfg: solid.SolidConfig) -> None:
    d = synthetic(cfg, 3)
    f = solid.encode_place(d)
    q = solid.encode_place(d, quantized=True)
    assert len(f) == 420 and len(q) <= 200
    back = solid.decode_place(f, cfg)
    np.testing.assert_array_equal(back.r, d.r)
    approx = solid.decode_place(q, cfg)
    assert solid.distance(approx, d) < 1e-3
    with pytest.raises(solid.DatabaseError, match="config"):
        solid.decode_place(f, solid.SolidConfig.preset("vlp16"))
    broken = bytearray(q)
    broken[20] ^= 1
    with pytest.raises(solid.DatabaseError, match="checksum"):
        solid.decode_place(bytes(broken), cfg)


def test_database_and_detector_are_safe_to_share_between_threads(cfg: solid.SolidConfig) -> None:
    """Issue 10, item 1: searches during adds, adds from several threads and merges during adds.

    On the old main these raised ``RuntimeError: Already mutably borrowed``, lost scans and raised
    pyo3's ``PanicException`` (not an ``Exception``), which the ``BaseException`` catch below records.
    """
    import threading

    descs = [synthetic(cfg, s) for s in range(40)]
    db = solid.Database(cfg)
    det = solid.LoopDetector(cfg, exclude_recent=0, threshold=1.0, verify=False)
    other = solid.Database(cfg)
    for d in descs[:10]:
        other.add(d)
    errors: list[BaseException] = []
    adds_per_thread = 60

    def adder(tid: int) -> None:
        try:
            for i in range(adds_per_thread):
                d = descs[(tid * 7 + i) % len(descs)]
                db.add(d, session=tid)
                det.add(d)
        except BaseException as e:  # noqa: BLE001 - PanicException derives from BaseException
            errors.append(e)

    def searcher() -> None:
        try:
            for i in range(200):
                db.search(descs[i % len(descs)], k=3)
                det.query(descs[i % len(descs)])
                len(det)
        except BaseException as e:  # noqa: BLE001
            errors.append(e)

    def merger() -> None:
        try:
            for _ in range(5):
                db.merge(other)
        except BaseException as e:  # noqa: BLE001
            errors.append(e)

    threads = [threading.Thread(target=adder, args=(t,)) for t in range(4)]
    threads += [threading.Thread(target=searcher) for _ in range(2)]
    threads.append(threading.Thread(target=merger))
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    assert len(db) == 4 * adds_per_thread + 5 * len(other)
    assert len(det) == 4 * adds_per_thread  # no scan lost
    # Session 0 also holds the merged entries (added without a session).
    assert list(np.bincount(db.sessions)) == [adds_per_thread + 5 * len(other)] + [adds_per_thread] * 3
    # A self-merge doubles the database and does not deadlock.
    n = len(db)
    db.merge(db)
    assert len(db) == 2 * n


def _search_in_child(r: npt.NDArray[np.float32], a: npt.NDArray[np.float32], conn: Any) -> None:
    db = solid.Database(solid.SolidConfig.preset("avia"))
    db.add_batch(r, a, index=True)  # the kd-tree and the sketch built on several threads
    hits = [db.search(r[i], k=2, method=m) for i in (5, 70_000) for m in ("brute", "auto", "sketch")]
    ids, _ = db.search_batch(r[:8], k=1)
    conn.send(([[h.id for h in x] for x in hits], ids[:, 0].tolist()))


def test_database_works_in_a_forked_child() -> None:
    # Scans of 65,536 rows and more, index builds and batches run on worker threads, which do
    # not exist in a child made by fork: the child must start its own instead of waiting for
    # them forever (it did, with rayon's global pool).
    cfg, r, a = random_places(80_000, 3)
    r[70_001] = r[70_000]  # a tie: the lower id first
    parent = solid.Database(cfg)
    parent.add_batch(r, a, index=True)
    assert parent.search(r[5], k=1, method="brute")[0].id == 5  # the parent's workers exist
    hits, batch = in_forked_child(_search_in_child, r, a, what="a Database")
    assert all(h[0] == 5 for h in hits[:3]) and all(h == [70_000, 70_001] for h in hits[3:])
    assert batch == list(range(8))


_WITHOUT_THREADS = """
import resource, sys, threading
import numpy as np
import solid

cfg = solid.SolidConfig.preset("avia")
rng = np.random.default_rng(5)
r = rng.uniform(0.0, 1.0, (1000, cfg.n_range)).astype(np.float32)
a = rng.uniform(0.0, 1.0, (1000, cfg.n_azimuth)).astype(np.float32)
db = solid.Database(cfg)
db.add_batch(r, a, index=False)  # too few rows to start worker threads
# No new thread can start: its stack (2 MiB or more) does not fit in the address space left.
with open("/proc/self/statm") as f:
    size = int(f.read().split()[0]) * resource.getpagesize()
resource.setrlimit(resource.RLIMIT_AS, (size + (1 << 20), resource.RLIM_INFINITY))
try:
    threading.Thread(target=lambda: None).start()
    sys.exit("a thread started: the limit did not hold")
except RuntimeError:
    pass
ids, _ = db.search_batch(r[:100], k=1)
assert ids[:, 0].tolist() == list(range(100)), ids[:, 0]
db.build_index()
assert [db.search(r[i], k=1)[0].id for i in (3, 999)] == [3, 999]
print("ok")
"""


def test_a_process_that_cannot_start_threads_still_searches() -> None:
    # Without worker threads (none can start), batches and index builds run on the calling
    # thread; search_batch used to hand its queries to rayon's global pool then, which could
    # not start either, and panicked. A fresh interpreter: a forked child could reuse the stacks
    # of its parent's ended threads.
    if not Path("/proc/self/statm").exists():
        pytest.skip("needs Linux's /proc")
    run = subprocess.run([sys.executable, "-c", _WITHOUT_THREADS], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and run.stdout == "ok\n", run.stderr[-2000:]


def test_a_query_is_read_the_same_from_any_float_layout() -> None:
    # float32 and float64 arrays are read directly (contiguous) or as sequences (strided views,
    # lists): the same neighbours and distances either way.
    cfg, r, a = random_places(500, 6)
    db = solid.Database(cfg)
    db.add_batch(r, a)
    q = r[3] * np.float32(0.9) + r[4] * np.float32(0.1)
    want = [(m.id, m.distance) for m in db.search(q, k=3)]
    assert want[0][0] == 3
    strided = np.repeat(q, 2)[::2]
    assert not strided.flags.c_contiguous
    for variant in (q.astype(np.float64), strided, strided.astype(np.float64), q.tolist()):
        assert [(m.id, m.distance) for m in db.search(variant, k=3)] == want
    with pytest.raises(TypeError):
        db.search(r[:2], k=1)  # two queries: search_batch takes those
