"""Re-runs the hardening audit of issue 10 (items 2, 6 and 8), and the cases of issues 30 and 39,
against the installed ``solid``.

    python tools/hardening_audit.py [--json OUT] [--quick] [--only AREA] [--match TEXT]

Issue 39's area: writers over FIFOs and device nodes of its own making (as root; never the
system's), maps truncated or written in place under a running detector, ``verify_threads``
bounds, hostile g2o loop files, ``voxel_size`` 0, racing no-replace saves, forged maps, point
writers' errors and modes, a closed stdout pipe; its C API cases load ``libsolid.so`` with ctypes
(``$SOLID_C_LIB``, else ``target/{release,debug}``; skipped when there is none).

Every case runs in a child process (allocation limits through ``RLIMIT_AS``/``RLIMIT_FSIZE``, a
timeout for blocking reads) and is classed as handled cleanly (the package's error, ``TypeError``,
``MemoryError`` or ``OSError`` as documented, or the right result) or wrong (an abort, a hang, an
``OverflowError``, a plain ``ValueError``, a silently accepted bad value, lost data). Prints the
table ``area | cases tried | handled cleanly | wrong`` and the wrong cases. Point ``PYTHONPATH``
at another build to audit it. Linux only (``/proc``, tmpfs mounts need root: skipped otherwise).
Needs about 6 GiB of sparse space in the temporary folder and a few minutes.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

PRELUDE = textwrap.dedent(
    """
    import os, sys, resource, struct, zlib, threading
    import numpy as np
    import solid
    from solid import sim
    def limit_as(gib):
        b = int(gib * (1 << 30))
        resource.setrlimit(resource.RLIMIT_AS, (b, b))
    cfg = solid.SolidConfig.preset("hdl64")
    def desc(seed, cfg=cfg):
        rng = np.random.default_rng(seed)
        return solid.Descriptor(rng.random(cfg.n_range).astype(np.float32), rng.random(cfg.n_azimuth).astype(np.float32), cfg)
    def small_db(n, seed=0):
        db = solid.Database(cfg)
        for i in range(n):
            db.add(desc(seed * 100000 + i), session=seed, timestamp=float(i))
        return db
    def recrc(b):
        b = bytearray(b)
        b[-4:] = struct.pack("<I", zlib.crc32(bytes(b[:-4])))
        return bytes(b)
    """
)


@dataclass
class Outcome:
    kind: str  # "ok", "exc", "signal", "timeout"
    detail: str


def run(code: str, timeout: float = 120.0) -> Outcome:
    """Runs PRELUDE + code in a child; the code prints its own verdict line ``RESULT ...``."""
    wrapped = PRELUDE + "\ntry:\n" + textwrap.indent(textwrap.dedent(code), "    ") + textwrap.dedent(
        """
        except BaseException as e:
            print("RESULT exc", type(e).__module__ + "." + type(e).__qualname__, "|", str(e)[:160].replace("\\n", " "), flush=True)
        else:
            print("RESULT ok", flush=True)
        """
    )
    try:
        p = subprocess.run([sys.executable, "-c", wrapped], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return Outcome("timeout", f"no answer after {timeout:g} s")
    if p.returncode < 0:
        return Outcome("signal", f"{signal.Signals(-p.returncode).name}: {p.stderr.strip()[-160:]}")
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("RESULT ")]
    if not lines:
        return Outcome("exc", f"exit {p.returncode}: {p.stderr.strip()[-200:]}")
    head, _, rest = lines[-1][7:].partition(" ")
    return Outcome(head, rest)


def refused_save(path: Path, places: int, accepted: str) -> str:
    """Code for `run`: saving `places` places over the 5-place map at `path` must raise OSError
    (else AssertionError(`accepted`)), and leave the old map whole and no temporary file."""
    return textwrap.dedent(
        f"""
        path = {str(path)!r}
        try:
            small_db({places}).save(path)
        except OSError as e:
            print("refused:", e)
        else:
            raise AssertionError({accepted!r})
        assert len(solid.Database.load(path)) == 5
        assert os.listdir(os.path.dirname(path)) == ["map.soliddb"], os.listdir(os.path.dirname(path))
        """
    )


CLEAN_EXC = ("MemoryError", "OSError", "FileNotFoundError", "IsADirectoryError", "PermissionError", "TypeError")


def package_error(o: Outcome) -> bool:
    """A package error (solid.*Error, all subclasses of ValueError) or TypeError."""
    if o.kind != "exc":
        return False
    name = o.detail.split(" |")[0]
    return name.startswith("solid.") or name.endswith(("builtins.TypeError", "solid.errors.ConfigFileError"))


def clean_exc(o: Outcome, *names: str) -> bool:
    if o.kind != "exc":
        return False
    name = o.detail.split(" |")[0].rsplit(".", 1)[-1]
    return name in names or o.detail.startswith("solid.")


Results = dict[str, list[tuple[str, bool, str]]]


def record(results: Results, area: str, case: str, ok: bool, o: Outcome | str) -> None:
    detail = o if isinstance(o, str) else f"{o.kind}: {o.detail}"
    results.setdefault(area, []).append((case, ok, detail))
    print(f"  [{'ok' if ok else 'WRONG'}] {area}: {case}: {detail[:150]}", flush=True)


def run_cases(results: Results, area: str, cases: dict[str, str], ok: Callable[[Outcome], bool], timeout: float = 120.0) -> None:
    """Runs each case's code (`run`) and records whether `ok` holds for its outcome."""
    for case, code in cases.items():
        o = run(code, timeout=timeout)
        record(results, area, case, ok(o), o)


# ---------------------------------------------------------------------------------------------
# Item 2: allocation failure never aborts.


def allocation(results: Results, tmp: Path) -> None:
    area = "allocation (item 2)"
    big = tmp / "points-4e8.f32"
    with open(big, "wb") as f:
        f.truncate(400_000_000 * 3 * 4)
    cases = {
        "describe, 4e8-point memory-mapped array (RLIMIT_AS 8 GiB)": f"""
            limit_as(8)
            pts = np.memmap({str(big)!r}, dtype=np.float32, mode="r", shape=(400_000_000, 3))
            solid.describe(pts, cfg)
        """,
        "describe, 40M points (RLIMIT_AS 4 GiB)": """
            limit_as(4)
            solid.describe(np.zeros((40_000_000, 4), np.float32), cfg)
        """,
        "describe_batch, 2 x 40M points, 2 threads (RLIMIT_AS 4 GiB)": """
            limit_as(4)
            a = np.zeros((40_000_000, 3), np.float32)
            solid.describe_batch([a, a], cfg, threads=2)
        """,
        "sim.Trajectory.from_waypoints 1e9 m at 0.01 m": """
            w = sim.World(seed=1)
            sim.Trajectory.from_waypoints(w, [(0, 0), (1e9, 0)], spacing=0.01)
        """,
        "sim.Trajectory.from_waypoints 9e3 m at 0.01 m (RLIMIT_AS 1 GiB)": """
            w = sim.World(seed=1)
            limit_as(1)
            sim.Trajectory.from_waypoints(w, [(0, 0), (9e3, 0)], spacing=0.01)
        """,
        "Database.from_bytes, header announcing 2^40 entries": """
            b = bytearray(small_db(2).to_bytes())
            b[80:88] = struct.pack("<Q", 1 << 40)
            solid.Database.from_bytes(recrc(b))
        """,
    }
    # A 1M-entry database file written directly (header + entries + vectors + CRC).
    path = tmp / "db-1m.soliddb"
    write_big_db(path, 1_000_000)
    cases["Database.load of a 1M-entry file (RLIMIT_AS 1 GiB)"] = f"""
        limit_as(1)
        db = solid.Database.load({str(path)!r})
        print("loaded", len(db))
    """
    run_cases(results, area, cases, lambda o: o.kind == "ok" or clean_exc(o, "MemoryError"), timeout=300)
    big.unlink()
    path.unlink()


def write_big_db(path: Path, n: int) -> None:
    """A valid database of n entries for the hdl64 preset, written in chunks (CRC on the way)."""
    import struct
    import zlib

    import numpy as np
    import solid

    cfg = solid.SolidConfig.preset("hdl64")
    head = bytearray(solid.Database(cfg).to_bytes()[:96])
    head[80:88] = struct.pack("<Q", n)
    crc = zlib.crc32(bytes(head))
    with open(path, "wb") as f:
        f.write(head)
        entry = struct.pack("<IId", 0, 0, 0.0) + bytes(96)
        chunk = 10_000
        for start in range(0, n, chunk):
            b = entry * min(chunk, n - start)
            crc = zlib.crc32(b, crc)
            f.write(b)
        for dim in (cfg.n_range, cfg.n_azimuth):
            row = np.ones(dim, np.float32).tobytes()
            for start in range(0, n, chunk):
                b = row * min(chunk, n - start)
                crc = zlib.crc32(b, crc)
                f.write(b)
        f.write(struct.pack("<I", crc))


# ---------------------------------------------------------------------------------------------
# Item 6: files.


def files(results: Results, tmp: Path, quick: bool) -> None:
    area = "files (item 6)"
    trials = 10 if quick else 40
    # Two concurrent saves to one path: both succeed, the file is one of them, whole.
    o = run(
        f"""
        a, b = small_db(300, 1), small_db(200, 2)
        want = {{a.to_bytes(), b.to_bytes()}}
        path = {str(tmp / "race.soliddb")!r}
        lost = 0
        for t in range({trials}):
            errs = []
            def save(db):
                try:
                    db.save(path)
                except Exception as e:
                    errs.append(e)
            ts = [threading.Thread(target=save, args=(d,)) for d in (a, b)]
            [x.start() for x in ts]
            [x.join() for x in ts]
            try:
                whole = solid.Database.load(path).to_bytes() in want
            except Exception:
                whole = False
            lost += bool(errs) or not whole
        left = [p for p in os.listdir(os.path.dirname(path)) if p.endswith(".tmp")]
        print("RESULT ok", lost, "of", {trials}, "trials lost data;", len(left), "temp files left")
        sys.stdout.flush(); os._exit(0)
        """
    )
    lost = int(o.detail.split()[0]) if o.kind == "ok" else -1
    record(results, area, f"two concurrent saves to one path x{trials}", lost == 0, o)

    # kill -9 during save: the old or the new file, whole; what the kill leaves never collides.
    kdir = tmp / "kill"
    kdir.mkdir()
    path = kdir / "map.soliddb"
    run(f"small_db(10).save({str(path)!r})")
    writer = PRELUDE + textwrap.dedent(
        f"""
        a, b = small_db(2000, 1), small_db(1000, 2)
        print("ready", flush=True)
        while True:
            a.save({str(path)!r}); b.save({str(path)!r})
        """
    )
    bad = 0
    for t in range(trials):
        p = subprocess.Popen([sys.executable, "-c", writer], stdout=subprocess.PIPE, text=True)
        assert p.stdout is not None
        p.stdout.readline()
        time.sleep(random.uniform(0.0, 0.3))
        p.kill()
        p.wait()
        o = run(f"n = len(solid.Database.load({str(path)!r})); assert n in (10, 2000, 1000), n")
        bad += o.kind != "ok"
    left = sorted(p.name for p in kdir.iterdir() if p.name.endswith(".tmp"))
    o = run(f"small_db(5).save({str(path)!r}); assert len(solid.Database.load({str(path)!r})) == 5")
    record(
        results,
        area,
        f"kill -9 during save x{trials}, then save again",
        bad == 0 and o.kind == "ok",
        f"{bad} torn files; {len(left)} temp files left by the kills; the next save: {o.kind} {o.detail}",
    )

    fifo = tmp / "fifo.soliddb"
    os.mkfifo(fifo)
    o = run(f"solid.Database.load({str(fifo)!r})", timeout=10)
    record(results, area, "load of a FIFO", clean_exc(o, "OSError"), o)
    zero = tmp / "zero.soliddb"
    zero.symlink_to("/dev/zero")
    o = run(f"limit_as(2); solid.Database.load({str(zero)!r})", timeout=60)
    record(results, area, "load of a link to /dev/zero (RLIMIT_AS 2 GiB)", package_error(o), o)
    o = run(f"solid.Database.load({str(tmp)!r})")
    record(results, area, "load of a directory", clean_exc(o, "IsADirectoryError"), o)

    sparse = tmp / "foreign-6g.bin"
    with open(sparse, "wb") as f:
        f.truncate(6 << 30)
    check_read = f"""
        limit_as(2)
        io0 = int(open("/proc/self/io").read().split("rchar: ")[1].split()[0])
        try:
            solid.Database.load(PATH)
        finally:
            io1 = int(open("/proc/self/io").read().split("rchar: ")[1].split()[0])
            print("read", io1 - io0, "bytes", file=sys.stderr)
            assert io1 - io0 < 1 << 20, f"read {{io1 - io0}} bytes of a file it had to refuse"
    """
    o = run(check_read.replace("PATH", repr(str(sparse))), timeout=120)
    record(results, area, "load of a 6 GiB foreign (sparse) file, < 1 MiB read", package_error(o) and "not a SOLiD" in o.detail, o)
    valid_head = tmp / "header-6g.soliddb"
    run(f"open({str(valid_head)!r}, 'wb').write(small_db(1).to_bytes())")
    with open(valid_head, "r+b") as f:
        f.truncate(6 << 30)
    o = run(check_read.replace("PATH", repr(str(valid_head))), timeout=120)
    record(results, area, "load of a 6 GiB file with a 1-entry header, < 1 MiB read", package_error(o), o)
    sparse.unlink()
    valid_head.unlink()

    # Byte offsets of format version 2 (docs/spec.md §9); version 3 checks each section by its own CRC.
    corrupt = {
        "reserved header word set (CRC recomputed)": "b = bytearray(small_db(3).to_bytes(version=2)); b[28:32] = struct.pack('<I', 7); solid.Database.from_bytes(recrc(b))",
        "negative R-SOLiD value (CRC recomputed)": "db = small_db(3); b = bytearray(db.to_bytes(version=2)); o = 96 + 3 * 112; b[o:o+4] = struct.pack('<f', -1.0); solid.Database.from_bytes(recrc(b))",
        "negative A-SOLiD value (CRC recomputed)": "db = small_db(3); b = bytearray(db.to_bytes(version=2)); o = len(b) - 8; b[o:o+4] = struct.pack('<f', -0.5); solid.Database.from_bytes(recrc(b))",
        "infinite timestamp (CRC recomputed)": "b = bytearray(small_db(3).to_bytes(version=2)); b[104:112] = struct.pack('<d', float('inf')); solid.Database.from_bytes(recrc(b))",
        "decode_place, negative value (CRC recomputed)": "b = bytearray(solid.encode_place(desc(1))); b[16:20] = struct.pack('<f', -2.0); solid.decode_place(recrc(b), cfg)",
        "decode_place, negative quantised scale (CRC recomputed)": "b = bytearray(solid.encode_place(desc(1), quantized=True)); b[16:20] = struct.pack('<f', -2.0); solid.decode_place(recrc(b), cfg)",
    }
    run_cases(results, area, corrupt, package_error)
    accepts = {
        "decode_place(bytearray)": "d = desc(1); assert solid.decode_place(bytearray(solid.encode_place(d)), cfg).distance(d) < 1e-6",
        "decode_place(memoryview)": "d = desc(1); assert solid.decode_place(memoryview(solid.encode_place(d)), cfg).distance(d) < 1e-6",
        "Database.from_bytes(bytearray)": "db = small_db(3); assert len(solid.Database.from_bytes(bytearray(db.to_bytes()))) == 3",
        "Database.from_bytes(memoryview)": "db = small_db(3); assert len(solid.Database.from_bytes(memoryview(db.to_bytes()))) == 3",
    }
    run_cases(results, area, accepts, lambda o: o.kind == "ok")

    # Disks that refuse the write: the old file stays whole, no temporary file is left.
    limit = tmp / "fsize"
    limit.mkdir()
    path = limit / "map.soliddb"
    o = run(
        f"small_db(5).save({str(path)!r})\nresource.setrlimit(resource.RLIMIT_FSIZE, (100_000, 100_000))\n"
        + refused_save(path, 1000, "a 240 kB save under a 100 kB file size limit succeeded")
    )
    record(results, area, "save under ulimit -f (file size limit)", o.kind == "ok", o)
    if os.geteuid() == 0:
        for label, opts, remount in (("full disk (1 MiB tmpfs)", "size=1m", None), ("read-only file system", "size=64m", "remount,ro")):
            mnt = tmp / f"mnt-{opts}"
            mnt.mkdir()
            if subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", str(mnt)]).returncode != 0:
                continue
            try:
                run(f"small_db(5).save({str(mnt / 'map.soliddb')!r})")
                if remount:
                    subprocess.run(["mount", "-o", remount, str(mnt)], check=True)
                o = run(refused_save(mnt / "map.soliddb", 12000, "the save succeeded"))
                record(results, area, f"save on a {label}", o.kind == "ok", o)
            finally:
                subprocess.run(["umount", str(mnt)])


# ---------------------------------------------------------------------------------------------
# Item 8: API edges. Every case passes one bad value; handled cleanly = TypeError or a package
# error (solid.SolidError and its subclasses, all ValueErrors); wrong = accepted, OverflowError,
# plain ValueError, a panic.

API_CASES: list[tuple[str, str]] = []


def _api() -> None:
    ints = {
        "-1": "-1",
        "2**64": "2**64",
        "True": "True",
    }
    targets = {
        "Database.search k={}": "small_db(3).search(desc(9), k={})",
        "Database.search exclude_recent={}": "small_db(3).search(desc(9), exclude_recent={})",
        "Database.add session={}": "solid.Database(cfg).add(desc(1), session={})",
        "describe_batch threads={}": "solid.describe_batch([np.zeros((10, 3), np.float32)], cfg, threads={})",
        "LoopDetector exclude_recent={}": "solid.LoopDetector(cfg, exclude_recent={})",
        "LoopDetector top_k={}": "solid.LoopDetector(cfg, top_k={})",
        "LoopDetector.from_database top_k={}": "solid.LoopDetector.from_database(small_db(2), top_k={})",
        "LoopDetector.candidates k={}": "solid.LoopDetector(cfg).candidates(desc(1), k={})",
        "DetectorConfig top_k={}": "solid.DetectorConfig(top_k={})",
        "DetectorConfig exclude_frames={}": "solid.DetectorConfig(exclude_frames={})",
        "SolidConfig.preset n_range={}": "solid.SolidConfig.preset('hdl64', n_range={})",
        "SolidConfig n_elevation={}": "solid.SolidConfig(fov_up=2.0, fov_down=-24.8, n_elevation={})",
        "Descriptor n_points={}": "d = desc(1); solid.Descriptor(d.r, d.a, cfg, n_points={})",
        "sim.World seed={}": "sim.World(seed={})",
        "sim.World blocks={}": "sim.World(blocks={})",
        "sim.Sensor seed={}": "sim.Sensor('hdl64', seed={})",
        "sim.Sensor points={}": "sim.Sensor('avia', points={})",
        "sim.scan frame={}": "w = sim.World(seed=1); s = sim.Sensor('vlp16'); sim.scan(w, s, sim.Trajectory.loop(w).poses[0], frame={})",
        "Sensor.n_rays frame={}": "sim.Sensor('vlp16').n_rays({})",
        "Scores.recall_at n={}": "ev = solid.evaluation.evaluate_candidates('x', [1], [1], [[0]], [0.1], [0.1], [0.0], np.tile(np.eye(3, 4), (2, 1, 1)), radius=5.0); ev.scores.recall_at({})",
    }
    for name, code in targets.items():
        for label, v in ints.items():
            API_CASES.append((name.format(label), code.format(v)))
    others = {
        "Database.search not_newer_than=nan": "small_db(3).search(desc(9), not_newer_than=float('nan'))",
        "Database.search method='x'": "small_db(3).search(desc(9), method='x')",
        "Database.search with a negative R-SOLiD list": "small_db(3).search([-1.0] * cfg.n_range)",
        "Database.add timestamp=inf": "solid.Database(cfg).add(desc(1), timestamp=float('inf'))",
        "sim.World blocks=0": "sim.World(blocks=0)",
        "sim.World block_pitch=nan": "sim.World(block_pitch=float('nan'))",
        "sim.Sensor unknown name": "sim.Sensor('nope')",
        "sim.Trajectory.from_waypoints spacing=0": "sim.Trajectory.from_waypoints(sim.World(seed=1), [(0, 0), (10, 0)], spacing=0.0)",
        "sim.Trajectory.from_waypoints (K, 3) waypoints": "sim.Trajectory.from_waypoints(sim.World(seed=1), [(0, 0, 0), (10, 0, 0)])",
        "sim.Trajectory poses of shape (2, 4, 4)": "sim.Trajectory(np.zeros((2, 4, 4)), np.zeros(2))",
        "sim.scan pose of shape (2, 2)": "w = sim.World(seed=1); sim.scan(w, sim.Sensor('vlp16'), np.eye(2))",
        "sim.Trajectory.spin heading=nan": "sim.Trajectory.spin(sim.World(seed=1), 0.0, 0.0, [float('nan')])",
        "LoopDetector.from_database top_k=0": "solid.LoopDetector.from_database(small_db(2), top_k=0)",
        "LoopDetector threshold=True": "solid.LoopDetector(cfg, threshold=True)",
        "DetectorConfig threshold=nan": "solid.DetectorConfig(threshold=float('nan'))",
        "SolidConfig.preset voxel_size=True": "solid.SolidConfig.preset('hdl64', voxel_size=True)",
        "SolidConfig fov_up=True": "solid.SolidConfig(fov_up=True, fov_down=-24.8, n_elevation=64)",
        "Database.add pose of 5 values": "solid.Database(cfg).add(desc(1), pose=[1.0] * 5)",
        "Descriptor with a negative value": "d = desc(1); r = d.r.copy(); r[0] = -1; solid.Descriptor(r, d.a, cfg)",
        "decode_place of 2 bytes": "solid.decode_place(b'SP', cfg)",
        "decode_place of a str": "solid.decode_place('SP', cfg)",
        "evaluate_candidates poses of shape (2, 4, 4)": "solid.evaluation.evaluate_candidates('x', [1], [1], [[0]], [0.1], [0.1], [0.0], np.zeros((2, 4, 4)), radius=5.0)",
        "PipelineConfig radius=True": "solid.config.PipelineConfig.preset('hdl64', radius=True)",
        "PipelineConfig input fov=True": "solid.config.PipelineConfig.preset('hdl64', input={'fov': True})",
        "PipelineConfig detector top_k=-1": "solid.config.PipelineConfig.preset('hdl64', detector={'top_k': -1})",
        "PipelineConfig descriptor n_range=2**70": "solid.config.PipelineConfig.preset('hdl64', descriptor={'n_range': 2**70})",
    }
    API_CASES.extend(others.items())


_api()


def api(results: Results) -> None:
    area = "API edges (item 8)"
    code = "import solid.evaluation, solid.config\nout = []\n"
    for name, c in API_CASES:
        code += textwrap.dedent(
            f"""
            try:
                exec({c!r})
            except BaseException as e:
                out.append(({name!r}, "exc", type(e).__module__ + "." + type(e).__qualname__ + " | " + str(e)[:120]))
            else:
                out.append(({name!r}, "ok", "accepted"))
            """
        )
    code += "import json; print('RESULT ok', json.dumps(out)); sys.stdout.flush(); os._exit(0)\n"
    o = run(code, timeout=600)
    if o.kind != "ok":
        record(results, area, "all cases (the child died)", False, o)
        return
    for name, kind, detail in json.loads(o.detail):
        oc = Outcome(kind, detail)
        record(results, area, name, package_error(oc), oc)


# ---------------------------------------------------------------------------------------------
# Issue 30: interrupts, special files, budgets and contracts. Each case prints its own verdict:
# "RESULT ok" when handled as the issue asks, an exception or a timeout otherwise.

ISSUE30_CASES: list[tuple[str, str, float]] = [
    ("db.cloud(-1) is ConfigError", "db = small_db(2)\ntry:\n    db.cloud(-1)\nexcept solid.ConfigError:\n    pass", 60),
    ("db.cloud(2**64) is ConfigError", "db = small_db(2)\ntry:\n    db.cloud(2**64)\nexcept solid.ConfigError:\n    pass", 60),
    ("db.cloud(len(db)) is ConfigError", "db = small_db(2)\ntry:\n    db.cloud(2)\nexcept solid.ConfigError:\n    pass", 60),
    ("clip_fov(x, nan) is ConfigError", "from solid.transforms import clip_fov\ntry:\n    clip_fov(np.zeros((3, 3), np.float32), float('nan'))\nexcept solid.ConfigError:\n    pass", 60),
    ("clip_fov(x, 60, nan) is ConfigError", "from solid.transforms import clip_fov\ntry:\n    clip_fov(np.zeros((3, 3), np.float32), 60.0, float('nan'))\nexcept solid.ConfigError:\n    pass", 60),
    ("register with 10,000 yaws refused at once", "p = np.random.default_rng(0).random((5000, 3)).astype(np.float32) * 40\ntry:\n    solid.register(p, p, yaws=[float(y) for y in range(10000)])\nexcept solid.SolidError:\n    pass", 30),
    ("5M-point clouds registered in bounded time", "p = (np.random.default_rng(0).random((5_000_000, 3)) * 400 - 200).astype(np.float32)\nc = solid.RegistrationConfig(max_range=400.0)\nsolid.register(p, p, config=c)", 120),
    ("query(points) on a verifying detector", "w = sim.World(seed=1); s = sim.simulate(w, sim.Sensor('vlp16'), sim.Trajectory.loop(w, laps=0.1, spacing=2.0))\ndet = solid.LoopDetector(solid.SolidConfig.preset('vlp16'))\nfor x in s.scans[:5]:\n    det.detect(np.ascontiguousarray(x[:, :3]))\nassert det.query(np.ascontiguousarray(s.scans[2][:, :3])) is not None", 120),
    ("write_pcd from two threads", "from solid.io import write_pcd\nimport tempfile\nd = tempfile.mkdtemp(); errs = []\npts = np.zeros((1000, 3), np.float32)\ndef w():\n    for _ in range(100):\n        try: write_pcd(d + '/x.pcd', pts)\n        except Exception as e: errs.append(e)\nts = [threading.Thread(target=w) for _ in range(2)]\n[t.start() for t in ts]; [t.join() for t in ts]\nassert not errs, errs[:1]", 120),
    ("write_ply from two threads", "from solid.io import write_ply\nimport tempfile\nd = tempfile.mkdtemp(); errs = []\npts = np.zeros((1000, 3), np.float32)\ndef w():\n    for _ in range(100):\n        try: write_ply(d + '/x.ply', pts)\n        except Exception as e: errs.append(e)\nts = [threading.Thread(target=w) for _ in range(2)]\n[t.start() for t in ts]; [t.join() for t in ts]\nassert not errs, errs[:1]", 120),
    ("load_poses(FIFO) refused", "import tempfile\nf = tempfile.mkdtemp() + '/p'; os.mkfifo(f)\nfrom solid.io import load_poses\ntry:\n    load_poses(f)\nexcept solid.io.ReadError:\n    pass", 20),
    ("load_timestamps(FIFO) refused", "import tempfile\nf = tempfile.mkdtemp() + '/t'; os.mkfifo(f)\nfrom solid.io import load_timestamps\ntry:\n    load_timestamps(f)\nexcept solid.io.ReadError:\n    pass", 20),
    ("load_extrinsic(FIFO) refused", "import tempfile\nf = tempfile.mkdtemp() + '/c'; os.mkfifo(f)\nfrom solid.io import load_extrinsic\ntry:\n    load_extrinsic(f)\nexcept solid.io.ReadError:\n    pass", 20),
    ("load_poses(/dev/zero) refused", "limit_as(2)\nfrom solid.io import load_poses\ntry:\n    load_poses('/dev/zero')\nexcept solid.io.ReadError:\n    pass", 20),
    ("corrupt inner cloud refused by load", "w = sim.World(seed=1); s = sim.simulate(w, sim.Sensor('vlp16'), sim.Trajectory.loop(w, laps=0.1, spacing=2.0))\ndet = solid.LoopDetector(solid.SolidConfig.preset('vlp16'))\ndet.detect_many([np.ascontiguousarray(x[:, :3]) for x in s.scans[:4]])\ndb = det.database; c = db.cloud(2); b = bytearray(db.to_bytes()); k = bytes(b).find(c)\nb[k + len(c) // 2] ^= 0xFF\ntry:\n    solid.Database.from_bytes(recrc(bytes(b)))\nexcept solid.DatabaseError:\n    pass\nelse:\n    raise AssertionError('accepted')", 120),
]


def issue30(results: Results) -> None:
    area = "issue 30 contracts"
    for name, code, timeout in ISSUE30_CASES:
        o = run(code, timeout=timeout)
        record(results, area, name, o.kind == "ok", o)


# ---------------------------------------------------------------------------------------------
# Issue 39: writers and special files, maps changed while open, bounded threads, hostile g2o
# loops, voxel_size 0, concurrent no-replace writers, forged maps, writer errors and modes, a
# closed pipe. Each case prints "RESULT ok" when handled as the issue asks.

FORGE = """
import struct, zlib
def forge(b, kind, mutate):
    # A format 3/4 map with section `kind`'s bytes changed by mutate(bytearray), its CRC right.
    b = bytearray(b)
    count = struct.unpack_from('<I', b, 88)[0]
    for k in range(count):
        kd, _, off, ln, _ = struct.unpack_from('<IIQQQ', b, 96 + 32 * k)
        if kd == kind:
            sec = bytearray(b[off:off + ln]); mutate(sec)
            b[off:off + ln] = sec
            struct.pack_into('<I', b, off + ln, zlib.crc32(bytes(sec)))
            return bytes(b)
    raise KeyError(kind)
def posed_db(n=4, session=0):
    db = solid.Database(cfg)
    for i in range(n):
        p = np.eye(3, 4); p[0, 3] = i
        db.add(desc(i), session=session, timestamp=float(i), pose=p.ravel())
    return db
def sim_map(path, n=14):
    w = sim.World(seed=3); s = sim.simulate(w, sim.Sensor('vlp16'), sim.Trajectory.loop(w, laps=1.1, spacing=6.0))
    scans = [np.ascontiguousarray(x[:, :3]) for x in s.scans]
    det = solid.LoopDetector(solid.SolidConfig.preset('vlp16'))
    det.detect_many(scans[:n])
    det.database.save(path)
    return scans
def special(path, kind):
    import stat
    if kind == 'fifo':
        os.mkfifo(path)
    else:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))  # a null device of our own
    return os.stat(path).st_mode
def same_node(path, mode):
    st = os.stat(path)
    assert st.st_mode == mode, f"{path} is no longer the special file it was (mode {st.st_mode:o})"
"""

G2O_EDGE = "EDGE_SE3:QUAT 0 2 {t} {q} {info}"


def _g2o_cases() -> dict[str, str]:
    eye = " ".join("1" if a == b else "0" for a in range(6) for b in range(a, 6))
    good_q = "0 0 0 1"
    bad = {
        "NaN translation": G2O_EDGE.format(t="nan 0 0", q=good_q, info=eye),
        "zero quaternion": G2O_EDGE.format(t="1 0 0", q="0 0 0 0", info=eye),
        "quaternion of norm 1e200": G2O_EDGE.format(t="1 0 0", q="0 0 0 1e200", info=eye),
        "information not positive semidefinite": G2O_EDGE.format(t="1 0 0", q=good_q, info=eye.replace("1", "-1", 1)),
        "all-zero information": G2O_EDGE.format(t="1 0 0", q=good_q, info=" ".join(["0"] * 21)),
        "edge from a vertex to itself": G2O_EDGE.format(t="1 0 0", q=good_q, info=eye).replace(" 0 2 ", " 1 1 ", 1),
    }
    verts = "".join(f"VERTEX_SE3:QUAT {i} {i} 0 0 0 0 0 1\n" for i in range(3))
    cases = {}
    for name, edge in bad.items():
        cases[f"g2o loops file with {name} refused naming line 4"] = f"""
            import tempfile, warnings
            from solid.slam import PoseGraph
            warnings.simplefilter('error')
            f = tempfile.mkdtemp() + '/loops.g2o'
            open(f, 'w').write({verts!r} + {edge + chr(10)!r})
            try:
                PoseGraph.read_g2o(f)
            except solid.SolidError as e:
                assert 'line 4' in str(e), e
            else:
                raise AssertionError('accepted')
        """
    return cases


def issue39_cases(c_lib: Path | None) -> dict[str, tuple[str, float]]:
    cases: dict[str, tuple[str, float]] = {}
    for kind in ("fifo", "chardev"):
        if kind == "chardev" and os.geteuid() != 0:
            continue
        label = "FIFO" if kind == "fifo" else "character device (own mknod 1,3)"
        writers = {
            "Database.save": "small_db(3).save(out)",
            "write_pcd": "from solid.io import write_pcd; write_pcd(out, np.zeros((5, 3), np.float32))",
            "write_ply": "from solid.io import write_ply; write_ply(out, np.zeros((5, 3), np.float32))",
            "PipelineConfig.dump": "solid.config.PipelineConfig.preset('hdl64').dump(out)",
        }
        for name, call in writers.items():
            cases[f"{name} over a {label} refused, the node kept"] = (
                FORGE
                + f"""
import tempfile, solid.config
out = tempfile.mkdtemp() + '/out'
mode = special(out, {kind!r})
try:
    {call}
except OSError as e:
    print('refused:', e)
else:
    raise AssertionError('written')
same_node(out, mode)
""",
                30,
            )
        cases[f"solid describe -o a {label}: written through, the node kept"] = (
            FORGE
            + f"""
import tempfile, subprocess
d = tempfile.mkdtemp(); out = d + '/out'; scan = d + '/s.bin'
np.random.default_rng(0).random((2000, 4)).astype(np.float32).tofile(scan)
mode = special(out, {kind!r})
got = []
if {kind!r} == 'fifo':
    def rd():
        with open(out, 'rb') as f:
            got.append(f.read())
    t = threading.Thread(target=rd); t.start()
p = subprocess.run([sys.executable, '-m', 'solid', 'describe', scan, '--preset', 'hdl64', '-o', out], capture_output=True, text=True, timeout=60)
assert p.returncode == 0, p.stderr
if {kind!r} == 'fifo':
    t.join(10); assert got and b'"n_points": 2000' in got[0], got
same_node(out, mode)
""",
            60,
        )
    if c_lib is not None:
        for fn in ("solid_database_save", "solid_detector_save"):
            cases[f"C {fn} over a FIFO refused, the FIFO kept"] = (
                FORGE
                + f"""
import ctypes, tempfile
lib = ctypes.CDLL({str(c_lib)!r})
lib.solid_last_error.restype = ctypes.c_char_p
out = tempfile.mkdtemp() + '/out'
mode = special(out, 'fifo')
c = ctypes.c_void_p(); assert lib.solid_config_new(b'hdl64', ctypes.byref(c)) == 0
h = ctypes.c_void_p()
if {fn!r} == 'solid_database_save':
    assert lib.solid_database_new(c, ctypes.byref(h)) == 0
else:
    dc = ctypes.c_void_p(); assert lib.solid_detector_config_new(b'hdl64', ctypes.byref(dc)) == 0
    assert lib.solid_detector_new(c, dc, ctypes.byref(h)) == 0, lib.solid_last_error()
st = getattr(lib, {fn!r})(h, out.encode())
assert st != 0, 'written'
print('refused:', lib.solid_last_error())
same_node(out, mode)
""",
                30,
            )
    changed = {
        "truncated": "os.truncate(path, os.path.getsize(path) // 2)",
        "overwritten in place": "f = open(path, 'r+b'); f.seek(os.path.getsize(path) // 2); f.write(os.urandom(os.path.getsize(path) // 2 - 8)); f.close()",
    }
    for how, change in changed.items():
        cases[f"map {how} under a running detector: the step fails naming the map"] = (
            FORGE
            + f"""
import tempfile
path = tempfile.mkdtemp() + '/map.soliddb'
scans = sim_map(path)
det = solid.LoopDetector.from_database(solid.Database.load(path), exclude_recent=0)
{change}
try:
    for s in scans[:14]:
        det.detect(s)
except solid.SolidError as e:
    assert path in str(e) and 'changed' in str(e), e
else:
    raise AssertionError('the run went on without an error')
""",
            120,
        )
        cases[f"map {how} while open: Database.cloud fails naming the map"] = (
            FORGE
            + f"""
import tempfile
path = tempfile.mkdtemp() + '/map.soliddb'
sim_map(path)
db = solid.Database.load(path)
{change}
try:
    [db.cloud(i) for i in range(len(db))]
except solid.SolidError as e:
    assert path in str(e) and 'changed' in str(e), e
else:
    raise AssertionError('read')
""",
            120,
        )
    cases["DetectorConfig(verify_threads=10**6) refused"] = (
        "try:\n    solid.DetectorConfig(verify_threads=10**6)\nexcept solid.ConfigError:\n    pass\nelse:\n    raise AssertionError('accepted')",
        30,
    )
    cases["solid config dump --verify-threads 1000000 refused"] = (
        "import subprocess\np = subprocess.run([sys.executable, '-m', 'solid', 'config', 'dump', '--verify-threads', '1000000'], capture_output=True, text=True, timeout=60)\nassert p.returncode != 0 and '0..=256' in p.stderr, (p.returncode, p.stderr)",
        60,
    )
    if c_lib is not None:
        cases["C solid_detector_config_set verify_threads 1e6 refused"] = (
            f"""
import ctypes
lib = ctypes.CDLL({str(c_lib)!r})
h = ctypes.c_void_p(); assert lib.solid_detector_config_new(b'hdl64', ctypes.byref(h)) == 0, 'config'
lib.solid_detector_config_set.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_double]
assert lib.solid_detector_config_set(h, b'verify_threads', 1e6) != 0, 'accepted'
""",
            30,
        )
    cases.update({k: (v, 30) for k, v in _g2o_cases().items()})
    cases["registration.voxel_size = 0: the detector runs (or the config is refused)"] = (
        """
w = sim.World(seed=3); s = sim.simulate(w, sim.Sensor('vlp16'), sim.Trajectory.loop(w, laps=1.1, spacing=6.0))
try:
    dc = solid.DetectorConfig(registration={'voxel_size': 0.0})
except solid.ConfigError:
    pass
else:
    det = solid.LoopDetector(solid.SolidConfig.preset('vlp16'), detector=dc)
    for x in s.scans[:6]:
        det.detect(np.ascontiguousarray(x[:, :3]))
""",
        120,
    )
    cases["two concurrent saves without replacing: exactly one wins x20"] = (
        """
import tempfile
a, b = small_db(300, 1), small_db(200, 2)
bad = 0
for t in range(20):
    path = tempfile.mkdtemp() + '/m.soliddb'
    wins, errs = [], []
    def save(db):
        try:
            db.save(path, replace=False); wins.append(len(db))
        except FileExistsError as e:
            errs.append(e)
    ts = [threading.Thread(target=save, args=(d,)) for d in (a, b)]
    [x.start() for x in ts]; [x.join() for x in ts]
    bad += not (len(wins) == 1 and len(errs) == 1 and len(solid.Database.load(path)) == wins[0])
assert bad == 0, f'{bad} of 20 trials wrong'
""",
        120,
    )
    cases["two concurrent `solid map build -o SAME`: exactly one wins x3"] = (
        """
import tempfile, subprocess
d = tempfile.mkdtemp()
w = sim.World(seed=2)
sim.write_sequence(d + '/run', w, sim.Sensor('vlp16'), sim.Trajectory.loop(w, laps=0.3, spacing=4.0)[:12])
bad = []
for t in range(3):
    out = f'{d}/map{t}.soliddb'
    cmd = [sys.executable, '-m', 'solid', 'map', 'build', d + '/run', '--preset', 'vlp16', '-o', out, '-q']
    ps = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    res = [p.communicate(timeout=120) + (p.returncode,) for p in ps]
    codes = sorted(r[2] for r in res)
    if codes != [0, 1] or 'exists' not in ''.join(r[1] for r in res):
        bad.append((codes, [r[1][-120:] for r in res]))
assert not bad, bad
""",
        400,
    )
    cases["Database.add session=2**32-1 refused"] = (
        "try:\n    solid.Database(cfg).add(desc(1), session=2**32 - 1)\nexcept solid.SolidError:\n    pass\nelse:\n    raise AssertionError('accepted')",
        30,
    )
    forged = {
        "session 2^32-1": "forge(posed_db().to_bytes(version=4), 1, lambda s: struct.pack_into('<I', s, 0, 0xFFFFFFFF))",
        "a pose that is not a rotation": "forge(posed_db().to_bytes(version=3), 7, lambda s: struct.pack_into('<d', s, 4, 2.0))",
        "an A-SOLiD step that overflows to inf": "forge(posed_db().to_bytes(version=4), 5, lambda s: struct.pack_into('<f', s, 0, 1e38))",
    }
    for name, code in forged.items():
        cases[f"forged map with {name} refused at load"] = (
            FORGE + f"b = {code}\ntry:\n    solid.Database.from_bytes(b)\nexcept solid.DatabaseError as e:\n    print(e)\nelse:\n    raise AssertionError('loaded')",
            30,
        )
    for w in ("write_pcd", "write_ply"):
        cases[f"{w} of points of shape (5, 2) is a SolidError"] = (
            f"import tempfile\nfrom solid.io import {w}\ntry:\n    {w}(tempfile.mkdtemp() + '/x', np.zeros((5, 2), np.float32))\nexcept solid.SolidError:\n    pass",
            30,
        )
        cases[f"{w} honours the umask (022: 0644)"] = (
            f"import tempfile, stat\nfrom solid.io import {w}\nos.umask(0o022)\nf = tempfile.mkdtemp() + '/x'\n{w}(f, np.zeros((5, 3), np.float32))\nm = stat.S_IMODE(os.stat(f).st_mode)\nassert m == 0o644, oct(m)",
            30,
        )
    cases["solid map info into a closed pipe: no Broken-pipe error"] = (
        """
import tempfile, subprocess
path = tempfile.mkdtemp() + '/m.soliddb'
small_db(3).save(path)
p = subprocess.Popen([sys.executable, '-m', 'solid', 'map', 'info', path], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
p.stdout.close()
err = p.stderr.read().decode(); p.wait(60)
assert 'Broken pipe' not in err and 'Traceback' not in err and 'error' not in err, err
""",
        60,
    )
    return cases


def issue39(results: Results, c_lib: Path | None, match: str | None = None) -> None:
    area = "issue 39 writers, changed maps, bounds"
    if c_lib is None:
        print("  (C API cases skipped: no libsolid.so; build it with cargo build -p solid-c or set SOLID_C_LIB)")
    for name, (code, timeout) in issue39_cases(c_lib).items():
        if match is not None and match not in name:
            continue
        o = run(code, timeout=timeout)
        record(results, area, name, o.kind == "ok", o)


def find_c_lib() -> Path | None:
    """libsolid.so: $SOLID_C_LIB, else this checkout's release or debug build."""
    env = os.environ.get("SOLID_C_LIB")
    if env:
        return Path(env)
    root = Path(__file__).resolve().parent.parent / "target"
    for p in (root / "release" / "libsolid.so", root / "debug" / "libsolid.so"):
        if p.exists():
            return p
    return None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", type=Path, help="write the per-case results here")
    ap.add_argument("--quick", action="store_true", help="10 trials instead of 40 for the races and kills")
    ap.add_argument("--only", choices=["allocation", "files", "api", "issue30", "issue39"], action="append")
    ap.add_argument("--match", help="run only the issue-39 cases whose name holds this text")
    a = ap.parse_args()
    results: Results = {}
    only = set(a.only or ["allocation", "files", "api", "issue30", "issue39"])
    with tempfile.TemporaryDirectory(prefix="solid-audit-") as d:
        tmp = Path(d)
        if "api" in only:
            api(results)
        if "issue30" in only:
            issue30(results)
        if "issue39" in only:
            issue39(results, find_c_lib(), a.match)
        if "files" in only:
            files(results, tmp, a.quick)
        if "allocation" in only:
            allocation(results, tmp)
    print("\n| area | cases tried | handled cleanly | wrong |\n|---|---|---|---|")
    for area, rows in results.items():
        good = sum(ok for _, ok, _ in rows)
        print(f"| {area} | {len(rows)} | {good} | {len(rows) - good} |")
    wrong = [(area, c, d) for area, rows in results.items() for c, ok, d in rows if not ok]
    if wrong:
        print("\nwrong:")
        for area, c, d in wrong:
            print(f"- {area}: {c}: {d[:200]}")
    if a.json:
        a.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
