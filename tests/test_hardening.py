"""Hostile inputs of issue 10: no allocation aborts the interpreter (item 2), files are written
and read defensively (item 6), and every argument error is the package's error (item 8).

The cases that aborted the interpreter run in a child process under ``RLIMIT_AS`` and must end
with a clean exception and exit code 0, never a signal. Linux only where noted (``/proc``,
``RLIMIT_AS`` semantics)."""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import textwrap
import threading
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import solid
import solid.evaluation
from solid import scancontext, sim
from solid.config import PipelineConfig

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="needs Linux (/proc, RLIMIT_AS)")

CHILD = """
import resource, sys
import numpy as np
import solid
from solid import sim
def limit_as(gib, above_now=False):
    b = int(gib * (1 << 30))
    if above_now:  # that much more than the address space in use now
        b += int(open("/proc/self/status").read().split("VmSize:")[1].split()[0]) * 1024
    resource.setrlimit(resource.RLIMIT_AS, (b, b))
cfg = solid.SolidConfig.preset("hdl64")
try:
{body}
except BaseException as e:
    print("raised", type(e).__name__, str(e)[:300])
else:
    print("returned")
"""


def in_child(body: str, timeout: float = 240.0) -> list[str]:
    """Runs ``body`` in a fresh interpreter; returns what it printed, its verdict last ("raised
    <class> <message>" or "returned"). Fails the test on a signal (an abort) or a hang."""
    code = CHILD.format(body=textwrap.indent(textwrap.dedent(body), "    "))
    try:
        p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the child did not finish within {timeout} s (blocked?)")
    assert p.returncode == 0, f"the child ended with {p.returncode} (a negative code is a signal): {p.stderr[-800:]}"
    return p.stdout.strip().splitlines()


def descriptor(cfg: solid.SolidConfig, seed: int) -> solid.Descriptor:
    rng = np.random.default_rng(seed)
    return solid.Descriptor(rng.random(cfg.n_range, dtype=np.float32), rng.random(cfg.n_azimuth, dtype=np.float32), cfg)


@pytest.fixture
def cfg() -> solid.SolidConfig:
    return solid.SolidConfig.preset("hdl64")


def database(cfg: solid.SolidConfig, n: int, seed: int = 0) -> solid.Database:
    db = solid.Database(cfg)
    for i in range(n):
        db.add(descriptor(cfg, seed * 10_000 + i), session=seed, timestamp=float(i))
    return db


def with_crc(b: bytes | bytearray) -> bytes:
    """The bytes with their trailing CRC-32 recomputed (the file and place formats end with one)."""
    b = bytearray(b)
    b[-4:] = struct.pack("<I", zlib.crc32(bytes(b[:-4])))
    return bytes(b)


# --- item 2: allocation failure never aborts ---------------------------------------------------


@linux
def test_describe_of_a_400m_point_memory_map_is_a_memory_error(tmp_path: Path) -> None:
    path = tmp_path / "points.f32"
    with open(path, "wb") as f:
        f.truncate(400_000_000 * 3 * 4)  # sparse: 4.8 GB of zeros that take no disk space
    *_, out = in_child(
        f"""
        limit_as(8)
        pts = np.memmap({str(path)!r}, dtype=np.float32, mode="r", shape=(400_000_000, 3))
        solid.describe(pts, cfg)
        """
    )
    assert out.startswith("raised MemoryError") and "describe scratch" in out, out


@linux
def test_describe_of_40m_points_under_4_gib_is_a_memory_error() -> None:
    *_, out = in_child(
        """
        limit_as(4)
        pts = np.zeros((40_000_000, 4), np.float32)
        try:
            solid.describe(pts, cfg)
        except MemoryError:
            pass
        # The failed call changed nothing: a normal scan is described as before.
        assert solid.describe(np.ones((100, 3), np.float32) * 5, cfg).n_kept == 1
        solid.describe_batch([pts, pts], cfg, threads=2)
        """
    )
    assert out.startswith(("raised MemoryError", "returned")), out


@linux
def test_preparing_a_40m_point_cloud_under_4_gib_is_a_memory_error() -> None:
    *_, out = in_child(
        """
        limit_as(4)
        solid.PreparedCloud(np.zeros((40_000_000, 3), np.float32))
        """
    )
    assert out.startswith("raised MemoryError"), out


@linux
def test_loading_a_1m_entry_file_under_1_gib_is_a_memory_error(tmp_path: Path, cfg: solid.SolidConfig) -> None:
    path = tmp_path / "big.soliddb"
    n, chunk = 1_000_000, 50_000
    head = bytearray(solid.Database(cfg).to_bytes(version=2)[:96])  # a format-2 file, written by hand
    head[80:88] = struct.pack("<Q", n)
    crc = zlib.crc32(bytes(head))
    with open(path, "wb") as f:
        f.write(head)
        parts = [struct.pack("<IId", 0, 0, 0.0) + bytes(96), np.ones(cfg.n_range, np.float32).tobytes(), np.ones(cfg.n_azimuth, np.float32).tobytes()]
        for part in parts:
            for _ in range(n // chunk):
                b = part * chunk
                crc = zlib.crc32(b, crc)
                f.write(b)
        f.write(struct.pack("<I", crc))
    *_, out = in_child(
        f"""
        limit_as(1)
        db = solid.Database.load({str(path)!r})
        assert len(db) == {n}
        """
    )
    assert out.startswith(("raised MemoryError", "returned")), out


def test_a_route_of_absurd_length_is_refused_up_front() -> None:
    *_, out = in_child(
        """
        w = sim.World(seed=1)
        sim.Trajectory.from_waypoints(w, [(0, 0), (1e9, 0)], spacing=0.01)
        """
    )
    assert out.startswith("raised ConfigError") and "frames" in out, out


@linux
def test_a_route_that_does_not_fit_in_memory_is_a_memory_error() -> None:
    *_, out = in_child(
        """
        w = sim.World(seed=1)
        limit_as(0.15, above_now=True)  # room for the 900k poses (86 MB), not for a copy of them
        t = sim.Trajectory.from_waypoints(w, [(0, 0), (9_000, 0)], spacing=0.01)
        """
    )
    assert out.startswith("raised MemoryError") and "trajectory poses" in out, out


# --- item 6: files -----------------------------------------------------------------------------


def test_concurrent_saves_to_one_path_all_succeed_and_leave_one_whole(tmp_path: Path, cfg: solid.SolidConfig) -> None:
    dbs = [database(cfg, 300, 1), database(cfg, 200, 2), database(cfg, 100, 3)]
    want = {db.to_bytes() for db in dbs}
    path = tmp_path / "map.soliddb"
    for _ in range(20):
        errors: list[BaseException] = []

        def save(db: solid.Database) -> None:
            try:
                db.save(path)
            except BaseException as e:  # noqa: BLE001 - every failure is a test failure
                errors.append(e)

        threads = [threading.Thread(target=save, args=(db,)) for db in dbs]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert errors == []
        assert solid.Database.load(path).to_bytes() in want
    assert os.listdir(tmp_path) == ["map.soliddb"]


@pytest.mark.skipif(not hasattr(os, "symlink"), reason="needs symbolic links")
def test_save_never_writes_through_a_temporary_name_that_exists(tmp_path: Path) -> None:
    """What a killed save leaves behind (or a planted link) is never reused: no collision."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    *_, out = in_child(
        f"""
        import os
        d = {str(tmp_path)!r}
        pid = os.getpid()
        # Every temporary name this fresh process could pick first, past and present schemes.
        names = [f".map.soliddb.{{pid}}.tmp"] + [f".map.soliddb.{{pid}}-{{n}}.tmp" for n in range(64)]
        for name in names:
            os.symlink(os.path.join(d, "victim.txt"), os.path.join(d, name))
        db = solid.Database(cfg)
        db.save(os.path.join(d, "map.soliddb"))
        assert len(solid.Database.load(os.path.join(d, "map.soliddb"))) == 0
        assert all(os.path.islink(os.path.join(d, n)) for n in names)
        """
    )
    assert out == "returned", out
    assert victim.read_text() == "precious"
    assert not (tmp_path / "map.soliddb").is_symlink()


def test_a_save_killed_midway_leaves_the_old_or_the_new_file(tmp_path: Path, cfg: solid.SolidConfig) -> None:
    path = tmp_path / "map.soliddb"
    database(cfg, 10).save(path)
    writer = textwrap.dedent(
        f"""
        import numpy as np, solid
        cfg = solid.SolidConfig.preset("hdl64")
        db = solid.Database(cfg)
        rng = np.random.default_rng(0)
        for i in range(3000):
            db.add(solid.Descriptor(rng.random(cfg.n_range, dtype=np.float32), rng.random(cfg.n_azimuth, dtype=np.float32), cfg))
        print("ready", flush=True)
        while True:
            db.save({str(path)!r})
        """
    )
    for delay in (0.0, 0.05, 0.1, 0.2):
        with subprocess.Popen([sys.executable, "-c", writer], stdout=subprocess.PIPE, text=True) as p:
            assert p.stdout is not None
            assert p.stdout.readline() == "ready\n"
            threading.Event().wait(delay)
            p.kill()
        assert len(solid.Database.load(path)) in (10, 3000)
    database(cfg, 5).save(path)
    assert len(solid.Database.load(path)) == 5


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_load_refuses_a_fifo_without_blocking(tmp_path: Path) -> None:
    fifo = tmp_path / "map.soliddb"
    os.mkfifo(fifo)
    *_, out = in_child(f"solid.Database.load({str(fifo)!r})", timeout=60)
    assert out.startswith("raised DatabaseError") and "not a regular file (a FIFO)" in out, out


@linux
def test_load_refuses_a_link_to_dev_zero_and_a_directory(tmp_path: Path) -> None:
    link = tmp_path / "zero.soliddb"
    link.symlink_to("/dev/zero")
    *_, out = in_child(f"limit_as(2)\nsolid.Database.load({str(link)!r})")
    assert out.startswith("raised DatabaseError") and "character device" in out, out
    with pytest.raises(IsADirectoryError):
        solid.Database.load(tmp_path)


@linux
@pytest.mark.parametrize("head", ["foreign", "one entry"])
def test_load_checks_the_header_against_the_size_before_reading(tmp_path: Path, cfg: solid.SolidConfig, head: str) -> None:
    """A 6 GiB file is refused after reading its header (< 1 MiB read, /proc/self/io)."""
    path = tmp_path / "huge.bin"
    with open(path, "wb") as f:
        if head == "one entry":
            f.write(database(cfg, 1).to_bytes())
        f.truncate(6 << 30)  # sparse
    out = in_child(
        f"""
        limit_as(2)
        rchar = lambda: int(open("/proc/self/io").read().split("rchar: ")[1].split()[0])
        before = rchar()
        try:
            solid.Database.load({str(path)!r})
        finally:
            print("read", rchar() - before)
        """
    )
    *lines, verdict = out
    assert verdict.startswith("raised DatabaseError"), verdict
    assert ("not a SOLiD database" if head == "foreign" else "unexpected bytes after the end") in verdict, verdict
    read = int(lines[-1].split()[1])
    assert read < 1 << 20, f"read {read} bytes of a file it had to refuse"


def test_the_reserved_header_word_is_checked(cfg: solid.SolidConfig) -> None:
    b = bytearray(database(cfg, 3).to_bytes())
    b[28:32] = struct.pack("<I", 7)
    with pytest.raises(solid.DatabaseError, match="reserved"):
        solid.Database.from_bytes(with_crc(b))


@pytest.mark.parametrize("where", ["r", "a"])
def test_from_bytes_refuses_negative_vectors(cfg: solid.SolidConfig, where: str) -> None:
    n = 3
    b = bytearray(database(cfg, n).to_bytes(version=2))  # format-2 offsets
    at = 96 + n * 112 if where == "r" else len(b) - 8
    b[at : at + 4] = struct.pack("<f", -1.0)
    with pytest.raises(solid.DatabaseError, match="negative"):
        solid.Database.from_bytes(with_crc(b))
    with pytest.raises(solid.SolidError):  # what Descriptor(...) refuses too
        solid.Descriptor(-np.ones(cfg.n_range), np.ones(cfg.n_azimuth), cfg)


def test_from_bytes_refuses_infinite_timestamps(cfg: solid.SolidConfig) -> None:
    b = bytearray(database(cfg, 2).to_bytes(version=2))  # format-2 offsets
    b[104:112] = struct.pack("<d", float("inf"))
    with pytest.raises(solid.DatabaseError, match="infinite timestamp"):
        solid.Database.from_bytes(with_crc(b))


@pytest.mark.parametrize("quantized", [False, True])
def test_decode_place_refuses_negative_vectors(cfg: solid.SolidConfig, quantized: bool) -> None:
    b = bytearray(solid.encode_place(descriptor(cfg, 1), quantized=quantized))
    b[16:20] = struct.pack("<f", -2.0)  # the first value, or the quantised R-SOLiD's scale
    with pytest.raises(solid.DatabaseError, match="negative"):
        solid.decode_place(with_crc(b), cfg)


@pytest.mark.parametrize("kind", [bytes, bytearray, memoryview])
def test_byte_arguments_take_bytes_bytearray_and_memoryview(cfg: solid.SolidConfig, kind: Callable[[bytes], Any]) -> None:
    d = descriptor(cfg, 4)
    assert solid.decode_place(kind(solid.encode_place(d)), cfg).distance(d) < 1e-6
    db = database(cfg, 3)
    assert solid.Database.from_bytes(kind(db.to_bytes())).to_bytes() == db.to_bytes()
    with pytest.raises(TypeError, match="bytes, bytearray or memoryview"):
        solid.decode_place("SP", cfg)  # type: ignore[arg-type]
    pts = np.random.default_rng(1).random((300, 3)) * 20
    wire = solid.encode_cloud(pts)
    np.testing.assert_array_equal(solid.decode_cloud(kind(wire)), solid.decode_cloud(wire))
    cloud = solid.PreparedCloud(pts)
    assert len(solid.PreparedCloud.decode(kind(cloud.encode()))) == len(cloud)


# --- item 8: API edges -------------------------------------------------------------------------


def _calls(cfg: solid.SolidConfig) -> dict[str, Callable[[Any], object]]:
    """Each public entry point that takes an integer, called with the value under test."""
    db = database(cfg, 3)
    d = descriptor(cfg, 9)
    world = sim.World(seed=1)
    pose = np.eye(3, 4)
    ev = solid.evaluation.evaluate_candidates("x", [1], [1], [[0]], [0.1], [0.1], [0.0], np.tile(pose, (2, 1, 1)), radius=5.0)
    cloud = solid.PreparedCloud(np.random.default_rng(0).random((500, 3)) * 20)
    return {
        "Database.search k": lambda v: db.search(d, k=v),
        "Database.search exclude_recent": lambda v: db.search(d, exclude_recent=v),
        "Database.add session": lambda v: solid.Database(cfg).add(d, session=v),
        "describe_batch threads": lambda v: solid.describe_batch([np.zeros((10, 3), np.float32)], cfg, threads=v),
        "LoopDetector exclude_recent": lambda v: solid.LoopDetector(cfg, exclude_recent=v),
        "LoopDetector top_k": lambda v: solid.LoopDetector(cfg, top_k=v),
        "LoopDetector.from_database top_k": lambda v: solid.LoopDetector.from_database(db, top_k=v),
        "LoopDetector.candidates k": lambda v: solid.LoopDetector(cfg).candidates(d, k=v),
        "DetectorConfig top_k": lambda v: solid.DetectorConfig(top_k=v),
        "DetectorConfig exclude_frames": lambda v: solid.DetectorConfig(exclude_frames=v),
        "SolidConfig.preset n_range": lambda v: solid.SolidConfig.preset("hdl64", n_range=v),
        "SolidConfig n_elevation": lambda v: solid.SolidConfig(fov_up=2.0, fov_down=-24.8, n_elevation=v),
        "Descriptor n_points": lambda v: solid.Descriptor(d.r, d.a, cfg, n_points=v),
        "sim.World seed": lambda v: sim.World(seed=v),
        "sim.World blocks": lambda v: sim.World(blocks=v),
        "sim.Sensor seed": lambda v: sim.Sensor("hdl64", seed=v),
        "sim.Sensor points": lambda v: sim.Sensor("avia", points=v),
        "sim.scan frame": lambda v: sim.scan(world, sim.Sensor("vlp16", h_fov=10.0), pose, frame=v),
        "Sensor.n_rays frame": lambda v: sim.Sensor("vlp16").n_rays(v),
        "Scores.recall_at n": lambda v: ev.recall_at(v),
        "RegistrationConfig neighbors": lambda v: solid.RegistrationConfig(neighbors=v),
        "PreparedCloud.encode bits": lambda v: cloud.encode(bits=v),
        "encode_cloud bits": lambda v: solid.encode_cloud(cloud.points, bits=v),
        "hypothesis_yaws n": lambda v: solid.hypothesis_yaws(d, d, n=v),
        "AcceptanceGate min_agreement": lambda v: solid.AcceptanceGate(min_agreement=v),
    }


def test_bad_integers_give_the_package_error_never_overflow(cfg: solid.SolidConfig) -> None:
    wrong = []
    for name, call in _calls(cfg).items():
        for value, expected in ((-1, solid.ConfigError), (2**64, solid.ConfigError), (True, TypeError), (1.5, TypeError)):
            try:
                call(value)
            except expected:
                continue
            except BaseException as e:  # noqa: BLE001 - collected and reported below
                wrong.append(f"{name}={value!r}: {type(e).__name__}: {e}")
            else:
                wrong.append(f"{name}={value!r}: accepted")
    assert wrong == []


def test_nan_time_limit_is_a_config_error(cfg: solid.SolidConfig) -> None:
    db = database(cfg, 3)
    with pytest.raises(solid.ConfigError, match="not_newer_than"):
        db.search(descriptor(cfg, 1), not_newer_than=float("nan"))
    assert [m.id for m in db.search(descriptor(cfg, 1), k=3, not_newer_than=float("inf"))] != []
    assert db.search(descriptor(cfg, 1), not_newer_than=-1.0) == []
    with pytest.raises(solid.ConfigError, match="timestamp"):
        db.add(descriptor(cfg, 1), timestamp=float("inf"))


def test_the_documented_error_classes(cfg: solid.SolidConfig) -> None:
    cases: list[tuple[Callable[[], object], type[BaseException]]] = [
        (lambda: sim.World(blocks=0), solid.ConfigError),
        (lambda: sim.Sensor("nope"), solid.ConfigError),
        (lambda: sim.Trajectory.from_waypoints(sim.World(seed=1), [(0, 0, 0), (10, 0, 0)]), solid.SolidError),
        (lambda: sim.Trajectory(np.zeros((2, 4, 4)), np.zeros(2)), solid.SolidError),
        (lambda: sim.scan(sim.World(seed=1), sim.Sensor("vlp16"), np.eye(2)), solid.SolidError),
        (lambda: database(cfg, 3).search(descriptor(cfg, 1), method="x"), solid.ConfigError),
        (lambda: database(cfg, 3).search([-1.0] * cfg.n_range), solid.ConfigError),
        (lambda: solid.LoopDetector.from_database(database(cfg, 2), top_k=0), solid.ConfigError),
        (lambda: solid.Database(cfg).add(descriptor(cfg, 1), pose=[1.0] * 5), solid.SolidError),
        (lambda: solid.SolidConfig.preset("hdl64", voxel_size=True), TypeError),
        (lambda: solid.SolidConfig(fov_up=True, fov_down=-24.8, n_elevation=64), TypeError),
        (lambda: solid.LoopDetector(cfg, threshold=True), TypeError),
        (lambda: PipelineConfig.preset("hdl64", radius=True), solid.ConfigError),
        (lambda: PipelineConfig.preset("hdl64", input={"fov": True}), solid.ConfigError),
        (lambda: PipelineConfig.preset("hdl64", descriptor={"n_range": 2**70}), solid.ConfigError),
        (
            lambda: solid.evaluation.evaluate_candidates("x", [5], [1], [[0]], [0.1], [0.1], [0.0], np.tile(np.eye(3, 4), (2, 1, 1)), radius=5.0),
            solid.SolidError,
        ),
        (lambda: solid.decode_cloud(b"not a cloud"), solid.DatabaseError),
        (lambda: solid.RegistrationConfig(voxel_size=True), TypeError),
        (lambda: solid.AcceptanceGate(min_fitness=True), TypeError),
        (lambda: scancontext.ScanContextConfig(n_ring=0), solid.ConfigError),
        (lambda: scancontext.ScanContextConfig(n_sector=True), TypeError),
        (lambda: scancontext.describe(np.zeros((5, 2))), solid.SolidError),
        (lambda: scancontext.candidates(np.zeros((3, 20, 60)), k=0), solid.ConfigError),
    ]
    for call, expected in cases:
        with pytest.raises(expected):
            call()
    assert all(issubclass(e, ValueError) for e in (solid.ConfigError, solid.DatabaseError, solid.SolidError))
