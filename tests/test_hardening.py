"""Hostile inputs of issue 10: no allocation aborts the interpreter (item 2), files are written
and read defensively (item 6), and every argument error is the package's error (item 8).

The cases that aborted the interpreter run in a child process under ``RLIMIT_AS`` and must end
with a clean exception and exit code 0, never a signal. Linux only where noted (``/proc``,
``RLIMIT_AS`` semantics)."""

from __future__ import annotations

import json
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
import solid.io
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


# ---------------------------------------------------------------------------------------------
# Issue 39: writers that never replace what they did not write, maps that notice they changed,
# bounded threads, a g2o reader that refuses what it cannot use, forged maps, writer errors.


def _special(path: Path, kind: str) -> int:
    """Makes a FIFO or (as root) a character device of our own (a null device, 1:3) at ``path``."""
    import stat

    if kind == "fifo":
        os.mkfifo(path)
    else:
        if os.geteuid() != 0:
            pytest.skip("making a device node needs root")
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    return os.stat(path).st_mode


SPECIAL_KINDS = [pytest.param("fifo", marks=linux), pytest.param("chardev", marks=linux)]


@pytest.mark.parametrize("kind", SPECIAL_KINDS)
def test_writers_never_replace_a_fifo_or_a_device(tmp_path: Path, kind: str) -> None:
    """Why: `Database.save`, `write_pcd`, `write_ply` (and the C API's saves) renamed their
    temporary file over whatever the path was: run as root, `-o /dev/null` turned the system's
    null device into a regular file. A path that is not a regular file is refused, and kept."""
    from solid.io import write_pcd, write_ply

    out = tmp_path / "out"
    mode = _special(out, kind)
    pts = np.zeros((5, 3), np.float32)
    writers: dict[str, Callable[[], Any]] = {
        "Database.save": lambda: solid.Database(solid.SolidConfig.preset("hdl64")).save(out),
        "Database.save(replace=False)": lambda: solid.Database(solid.SolidConfig.preset("hdl64")).save(out, replace=False),
        "write_pcd": lambda: write_pcd(out, pts),
        "write_ply": lambda: write_ply(out, pts),
        "PipelineConfig.dump": lambda: PipelineConfig.preset("hdl64").dump(out),
    }
    for name, write in writers.items():
        with pytest.raises(FileExistsError, match="not a regular file|exists"):
            write()
        assert os.stat(out).st_mode == mode, f"{name} replaced the {kind}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no temporary file left


@pytest.mark.parametrize("kind", SPECIAL_KINDS)
def test_describe_writes_through_a_stream(tmp_path: Path, kind: str) -> None:
    """`solid describe -o` is an output that may be a stream (`-o /dev/stdout`): a FIFO or a
    character device is written through, never replaced."""
    scan = tmp_path / "s.bin"
    np.random.default_rng(0).random((2000, 4)).astype(np.float32).tofile(scan)
    out = tmp_path / "out"
    mode = _special(out, kind)
    got: list[bytes] = []

    def read() -> None:
        with open(out, "rb") as f:
            got.append(f.read())

    reader = threading.Thread(target=read, daemon=True)
    if kind == "fifo":
        reader.start()
    p = subprocess.run([sys.executable, "-m", "solid", "describe", str(scan), "--preset", "hdl64", "-o", str(out)], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    if kind == "fifo":
        reader.join(10)
        assert got and json.loads(got[0])["n_points"] == 2000
    assert os.stat(out).st_mode == mode


def _changing_map(tmp_path: Path) -> tuple[Path, list[np.ndarray]]:
    """A map of 14 simulated scans (with clouds) saved to a file, and the scans."""
    w = sim.World(seed=3)
    s = sim.simulate(w, sim.Sensor("vlp16"), sim.Trajectory.loop(w, laps=1.1, spacing=6.0))
    scans = [np.ascontiguousarray(x[:, :3]) for x in s.scans]
    det = solid.LoopDetector(solid.SolidConfig.preset("vlp16"))
    det.detect_many(scans[:14])
    path = tmp_path / "map.soliddb"
    det.database.save(path)
    return path, scans


def _truncate(path: Path) -> None:
    os.truncate(path, path.stat().st_size // 2)


def _overwrite(path: Path) -> None:
    size = path.stat().st_size
    with open(path, "r+b") as f:  # in place: same inode, same size, other bytes
        f.seek(size // 2)
        f.write(bytes(size // 2 - 8))


@pytest.mark.parametrize("change", [_truncate, _overwrite], ids=["truncated", "overwritten"])
def test_a_map_changed_while_open_is_an_error_naming_it(tmp_path: Path, change: Callable[[Path], None]) -> None:
    """Why: a map truncated or overwritten in place under a running detector lost its loops
    silently (38 verified loops became 0–11), and `Database.cloud` then raised `OSError: [Errno 0]
    failed to fill whole buffer`. The step now fails with an error naming the map and saying it
    changed; no candidate whose cloud could not be read is verified."""
    path, scans = _changing_map(tmp_path)
    det = solid.LoopDetector.from_database(solid.Database.load(path), exclude_recent=0)
    db = solid.Database.load(path)
    change(path)
    with pytest.raises(solid.DatabaseError, match="changed while it was open") as e:
        for s in scans[:14]:
            det.detect(s)
    assert str(path) in str(e.value)
    with pytest.raises(solid.DatabaseError, match="changed while it was open"):
        for i in range(len(db)):
            db.cloud(i)
    with pytest.raises(solid.DatabaseError, match="changed while it was open"):
        db.save(tmp_path / "copy.soliddb")
    assert not (tmp_path / "copy.soliddb").exists()


def test_verify_threads_is_bounded(capsys: pytest.CaptureFixture[str]) -> None:
    """Why: `verify_threads = 1e6` was accepted and the first verifying step kept starting
    threads. The parameter table bounds it (0..=256), so every front-end refuses it alike."""
    from conftest import run

    assert solid.DetectorConfig(verify_threads=256).verify_threads == 256
    with pytest.raises(solid.ConfigError, match="verify_threads"):
        solid.DetectorConfig(verify_threads=10**6)
    with pytest.raises(solid.ConfigError, match="verify_threads"):
        solid.LoopDetector(solid.SolidConfig.preset("hdl64"), detector=solid.DetectorConfig().replace(verify_threads=257))
    code, _, err = run(capsys, "config", "dump", "--verify-threads", "1000000")
    assert code != 0 and "--verify-threads: '1000000' is not an integer in 0..=256" in err, err


def _g2o(tmp_path: Path, edge: str) -> Path:
    f = tmp_path / "loops.g2o"
    verts = "".join(f"VERTEX_SE3:QUAT {i} {i} 0 0 0 0 0 1\n" for i in range(3))
    f.write_text(verts + edge + "\n")
    return f


EYE = " ".join("1" if a == b else "0" for a in range(6) for b in range(a, 6))
BAD_EDGES = {
    "NaN translation": (f"EDGE_SE3:QUAT 0 2 nan 0 0 0 0 0 1 {EYE}", "not finite"),
    "zero quaternion": (f"EDGE_SE3:QUAT 0 2 1 0 0 0 0 0 0 {EYE}", "norm 0"),
    "quaternion of norm 1e200": (f"EDGE_SE3:QUAT 0 2 1 0 0 0 0 0 1e200 {EYE}", "norm 1e"),
    "information not PSD": (f"EDGE_SE3:QUAT 0 2 1 0 0 0 0 0 1 {EYE.replace('1', '-1', 1)}", "not positive semidefinite"),
    "all-zero information": (f"EDGE_SE3:QUAT 0 2 1 0 0 0 0 0 1 {' '.join(['0'] * 21)}", "is zero"),
    "self-edge": (f"EDGE_SE3:QUAT 1 1 1 0 0 0 0 0 1 {EYE}", "to itself"),
}


@pytest.mark.parametrize("case", list(BAD_EDGES))
def test_g2o_edges_a_graph_cannot_use_are_refused_with_their_line(tmp_path: Path, case: str) -> None:
    """Why: `solid optimize --loops FILE` accepted a NaN translation (the edge dropped silently),
    a zero quaternion or one of norm 1e200 (numpy's warnings leaked), information that is not
    positive semidefinite (the trajectory moved 0.18–0.21 m) or all zero, a self-edge."""
    import warnings

    from solid.slam import PoseGraph

    edge, why = BAD_EDGES[case]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(solid.io.ReadError, match=f"line 4: .*{why}"):
            PoseGraph.read_g2o(_g2o(tmp_path, edge))
    # The same edge, usable, is read.
    good = f"EDGE_SE3:QUAT 0 2 1 0 0 0 0 0 1 {EYE}"
    assert len(PoseGraph.read_g2o(_g2o(tmp_path, good)).kinds) == 1


def test_registration_voxel_size_zero_works_in_the_detector() -> None:
    """Why: `registration.voxel_size = 0` ("keeps every point") worked in `solid.register` but made
    every detector step fail with "invalid grid = 0". The stored clouds then use a fixed grid."""
    w = sim.World(seed=3)
    s = sim.simulate(w, sim.Sensor("vlp16"), sim.Trajectory.loop(w, laps=0.2, spacing=3.0))
    det = solid.LoopDetector(solid.SolidConfig.preset("vlp16"), detector=solid.DetectorConfig(registration={"voxel_size": 0.0}))
    for x in s.scans[:4]:
        det.detect(np.ascontiguousarray(x[:, :3]))
    db = det.database
    assert db.clouds_stored == 4
    # Every point kept: a stored cloud holds about as many points as the scan in range.
    stored = db.cloud(0)
    assert stored is not None
    cloud = solid.decode_cloud(stored)
    assert len(cloud) > 0.5 * len(s.scans[0])


def test_saves_without_replace_never_both_win(tmp_path: Path) -> None:
    """Why: two concurrent `solid map build … -o SAME` both printed "wrote" and one map silently
    replaced the other (the existence check raced the rename). `save(replace=False)` links the
    file into place, which fails when the path exists: exactly one of racing saves wins."""
    cfg = solid.SolidConfig.preset("hdl64")
    rng = np.random.default_rng(0)

    def db(n: int) -> solid.Database:
        d = solid.Database(cfg)
        for _ in range(n):
            d.add(solid.Descriptor(rng.random(cfg.n_range).astype(np.float32), rng.random(cfg.n_azimuth).astype(np.float32), cfg))
        return d

    a, b = db(300), db(200)
    for t in range(20):
        path = tmp_path / f"m{t}.soliddb"
        wins: list[int] = []
        refused: list[BaseException] = []

        def save(d: solid.Database) -> None:
            try:
                d.save(path, replace=False)
                wins.append(len(d))
            except FileExistsError as e:
                refused.append(e)

        ts = [threading.Thread(target=save, args=(d,)) for d in (a, b)]
        for x in ts:
            x.start()
        for x in ts:
            x.join(60)
        assert len(wins) == 1 and len(refused) == 1, (wins, refused)
        assert len(solid.Database.load(path)) == wins[0]
        assert "exists" in str(refused[0]) and str(path) in str(refused[0])
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_session_2_32_minus_1_is_refused() -> None:
    """Why: session 2^32 - 1 was accepted, and every later `detect` on that map failed with a
    misleading "database full"."""
    cfg = solid.SolidConfig.preset("hdl64")
    d = solid.Descriptor(np.ones(cfg.n_range, np.float32), np.ones(cfg.n_azimuth, np.float32), cfg)
    db = solid.Database(cfg)
    with pytest.raises(solid.ConfigError, match="session"):
        db.add(d, session=2**32 - 1)
    db.add(d, session=2**32 - 2)
    assert len(db) == 1


def _forge(b: bytes, kind: int, mutate: Callable[[bytearray], None]) -> bytes:
    """A format 3/4 map with section ``kind`` changed by ``mutate``, its checksum right again."""
    out = bytearray(b)
    for k in range(struct.unpack_from("<I", out, 88)[0]):
        kd, _, off, ln, _ = struct.unpack_from("<IIQQQ", out, 96 + 32 * k)
        if kd == kind:
            sec = bytearray(out[off : off + ln])
            mutate(sec)
            out[off : off + ln] = sec
            struct.pack_into("<I", out, off + ln, zlib.crc32(bytes(sec)))
            return bytes(out)
    raise KeyError(kind)


def _posed_db() -> solid.Database:
    cfg = solid.SolidConfig.preset("hdl64")
    db = solid.Database(cfg)
    for i in range(4):
        p = np.eye(3, 4)
        p[0, 3] = i
        db.add(solid.Descriptor(np.ones(cfg.n_range, np.float32), np.full(cfg.n_azimuth, i + 1.0, np.float32), cfg), timestamp=float(i), pose=p.ravel())
    return db


FORGED = {
    "session 2^32-1": (4, 1, lambda s: struct.pack_into("<I", s, 0, 0xFFFFFFFF), "session 2\\^32 - 1"),
    "not a rotation": (3, 7, lambda s: struct.pack_into("<d", s, 4, 2.0), "rotation"),
    "A-SOLiD step overflowing": (4, 5, lambda s: struct.pack_into("<f", s, 0, 1e38), "A-SOLiD"),
}


@pytest.mark.parametrize("case", list(FORGED))
def test_forged_maps_are_refused_at_load_as_add_refuses_them(tmp_path: Path, case: str) -> None:
    """Why: maps whose poses are not rotations, whose A-SOLiD step overflows to inf, or with
    session 2^32 - 1 loaded, although `add` refuses such values."""
    version, kind, mutate, why = FORGED[case]
    good = _posed_db().to_bytes(version=version)
    assert len(solid.Database.from_bytes(good)) == 4
    bad = _forge(good, kind, mutate)
    with pytest.raises(solid.DatabaseError, match=why):
        solid.Database.from_bytes(bad)
    (tmp_path / "bad.soliddb").write_bytes(bad)
    with pytest.raises(solid.DatabaseError, match=why):
        solid.Database.load(tmp_path / "bad.soliddb")


@pytest.mark.parametrize("writer", ["write_pcd", "write_ply"])
def test_point_writers_raise_solid_errors_and_honour_the_umask(tmp_path: Path, writer: str) -> None:
    """Why: `write_pcd`/`write_ply` raised plain `ValueError` for points of the wrong shape (the
    README promises `SolidError` subclasses) and wrote mode 0600 whatever the umask."""
    import stat

    write = getattr(solid.io, writer)
    with pytest.raises(solid.SolidError, match="shape"):
        write(tmp_path / "x", np.zeros((5, 2), np.float32))
    with pytest.raises(solid.SolidError):
        write(tmp_path / "x", [["a", "b", "c"]])
    with pytest.raises(solid.ConfigError, match="field names"):
        write(tmp_path / "x", np.zeros((5, 3), np.float32), fields=["x", "y"])
    with pytest.raises(solid.ConfigError, match="unknown"):
        write(tmp_path / "x", np.zeros((5, 3), np.float32), data="nope")
    old = os.umask(0o022)
    try:
        write(tmp_path / "a", np.zeros((5, 3), np.float32))
        os.umask(0o027)
        write(tmp_path / "b", np.zeros((5, 3), np.float32))
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "a").stat().st_mode) == 0o644
    assert stat.S_IMODE((tmp_path / "b").stat().st_mode) == 0o640


def test_a_closed_pipe_ends_a_command_quietly(tmp_path: Path) -> None:
    """Why: `solid map info | head` printed "solid map: error: [Errno 32] Broken pipe"."""
    path = tmp_path / "m.soliddb"
    _posed_db().save(path)
    p = subprocess.Popen([sys.executable, "-m", "solid", "map", "info", str(path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert p.stdout is not None and p.stderr is not None
    p.stdout.close()  # the reader leaves before the command writes
    with p.stderr:
        err = p.stderr.read().decode()
    p.wait(60)
    assert err == "" and p.returncode == 141, (p.returncode, err)


def test_two_concurrent_map_builds_to_one_path_never_both_win(tmp_path: Path) -> None:
    """Why: two concurrent `solid map build … -o SAME` both printed "wrote"; one map silently
    replaced the other. Now one writes the map, the other fails saying the path exists."""
    w = sim.World(seed=2)
    sim.write_sequence(tmp_path / "run", w, sim.Sensor("vlp16"), sim.Trajectory.loop(w, laps=0.3, spacing=4.0)[:12])
    out = tmp_path / "map.soliddb"
    cmd = [sys.executable, "-m", "solid", "map", "build", str(tmp_path / "run"), "--preset", "vlp16", "-o", str(out), "-q"]
    ps = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    res = [(*p.communicate(timeout=120), p.returncode) for p in ps]
    assert sorted(r[2] for r in res) == [0, 1], res
    assert "exists" in "".join(r[1] for r in res)
    assert len(solid.Database.load(out)) == 12


def test_a_map_appended_to_while_open_still_verifies_as_loaded(tmp_path: Path) -> None:
    """Appending leaves the header, the section table and every cloud where they were: the map
    is still the one loaded (each cloud is checked by its checksum when read), so a run goes on
    and finds what it finds on the unchanged map; only a shorter file or another header is a
    change."""
    path, scans = _changing_map(tmp_path)
    runs = []
    for append in (False, True):
        det = solid.LoopDetector.from_database(solid.Database.load(path), exclude_recent=0)
        if append:
            with open(path, "ab") as f:
                f.write(bytes(4096))
        runs.append([(s.loop.candidate if s.loop else None) for s in (det.detect(x) for x in scans[:14])])
    assert runs[0] == runs[1] and any(c is not None for c in runs[0])
