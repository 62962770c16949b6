"""docs/spec.md and the library say the same thing wherever a machine can check it.

The parameter table (§1: defaults and every validity rule), the fingerprint (§1), the presets
(§4), the loop detector's rule (§8) and the binary layouts (§9, §10, §13) are read from the page and
compared with what the library accepts and writes. A rule the page states in words this test does
not know fails the test, so the page cannot say something that goes unchecked.
"""

from __future__ import annotations

import math
import re
import struct
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import solid

SPEC = Path(__file__).resolve().parent.parent / "docs" / "spec.md"


def section(n: int) -> str:
    """The text of `## n. ...` up to the next `## `."""
    text = SPEC.read_text(encoding="utf-8")
    m = re.search(rf"^## {n}\. .*?(?=^## |\Z)", text, flags=re.M | re.S)
    assert m, f"docs/spec.md has no section {n}"
    return m.group(0)


def table(text: str) -> list[list[str]]:
    """The body rows of the first Markdown table in `text`, cells stripped (`\\|` is a literal bar)."""
    rows = [ln for ln in text.splitlines() if ln.startswith("|")]
    assert len(rows) > 2, "no table"
    cells = [[c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", r)[1:-1]] for r in rows]
    return cells[2:]  # header and separator


def number(cell: str) -> float:
    return float(cell.replace("−", "-"))


# --- §1 parameters ------------------------------------------------------------------------------

BASE: dict[str, Any] = {"fov_up": 2.0, "fov_down": -24.8, "n_elevation": 64}


def accepts(**params: Any) -> bool:
    """Whether SolidConfig accepts `params` over BASE."""
    try:
        solid.SolidConfig(**{**BASE, **params})
    except solid.ConfigError:
        return False
    return True


def refuses(name: str, **params: Any) -> bool:
    """Whether SolidConfig refuses `params` over BASE with an error that names `name`."""
    try:
        solid.SolidConfig(**{**BASE, **params})
    except solid.ConfigError as e:
        assert name in str(e), f"{params}: the error does not name {name}: {e}"
        return True
    return False


def params_table() -> dict[str, tuple[str, str]]:
    out = {}
    for name, default, _meaning, valid in table(section(1)):
        out[re.match(r"`(\w+)`", name).group(1)] = (default, valid)  # type: ignore[union-attr]
    return out


def test_the_parameter_table_names_every_field_of_the_config() -> None:
    assert set(params_table()) == set(solid.SolidConfig.preset("hdl64").to_dict())


def test_the_parameter_defaults_are_the_constructor_defaults() -> None:
    cfg = solid.SolidConfig(**BASE)
    for name, (default, _valid) in params_table().items():
        if default.startswith("none"):
            with pytest.raises(TypeError):  # required
                solid.SolidConfig(**{k: v for k, v in BASE.items() if k != name})
        else:
            assert getattr(cfg, name) == number(default), name


def _rule_checks(name: str, clause: str) -> Callable[[], None] | None:
    """A check of one clause of the `valid` column, or None when the clause is not understood."""
    if m := re.fullmatch(r"an integer in (\d+)\.\.=(\d+)", clause):
        lo, hi = int(m.group(1)), int(m.group(2))

        def check() -> None:
            assert accepts(**{name: lo}) and accepts(**{name: hi})
            assert refuses(name, **{name: lo - 1}) and refuses(name, **{name: hi + 1})

        return check
    if clause == "finite":

        def check() -> None:
            for bad in (math.nan, math.inf, -math.inf):
                assert refuses(name, **{name: bad}), (name, bad)

        return check
    if m := re.fullmatch(r"in \[(-?\d+), (-?\d+)\]", clause):
        fov_lo, fov_hi = float(m.group(1)), float(m.group(2))

        def check() -> None:
            # fov_down < fov_up leaves one bound of each to test on its own.
            assert accepts(fov_down=fov_lo, fov_up=fov_hi)
            if name == "fov_up":
                assert refuses(name, fov_up=fov_hi + 1e-9, fov_down=fov_lo)
            else:
                assert refuses(name, fov_down=fov_lo - 1e-9, fov_up=fov_hi)

        return check
    if clause == "below `fov_up`":

        def check() -> None:
            assert refuses(name, fov_down=10.0, fov_up=10.0) and refuses(name, fov_down=11.0, fov_up=10.0)
            assert accepts(fov_down=9.999, fov_up=10.0)

        return check
    if clause == "≥ 0":

        def check() -> None:
            assert accepts(**{name: 0.0}) and refuses(name, **{name: -1e-9})

        return check
    if clause == "above `min_range`":

        def check() -> None:
            assert refuses(name, min_range=5.0, max_range=5.0) and accepts(min_range=5.0, max_range=5.001)

        return check
    if clause == "when > 0, `max_range / voxel_size` < 2^19":

        def check() -> None:
            edge = 100.0 / 2**19
            assert refuses(name, max_range=100.0, voxel_size=edge)
            assert accepts(max_range=100.0, voxel_size=edge * 1.000001)

        return check
    return None


def test_every_validity_rule_is_what_solid_config_accepts() -> None:
    for name, (_default, valid) in params_table().items():
        for clause in re.split(r"; |, (?!`max_range)(?!\d)", valid):
            check = _rule_checks(name, clause)
            assert check is not None, f"§1 {name}: rule {clause!r} is not checked by this test: teach it"
            check()


def test_the_fingerprint_is_fnv1a_as_specified() -> None:
    text = section(1)
    basis = int(re.search(r"offset basis\s+`(0x[0-9a-f]+)`", text).group(1), 16)  # type: ignore[union-attr]
    prime = int(re.search(r"prime\s+`(0x[0-9a-f]+)`", text).group(1), 16)  # type: ignore[union-attr]

    def fnv1a(cfg: solid.SolidConfig) -> int:
        data = struct.pack("<3Q", cfg.n_range, cfg.n_azimuth, cfg.n_elevation)
        data += struct.pack("<5d", cfg.fov_up, cfg.fov_down, cfg.min_range, cfg.max_range, cfg.voxel_size)
        h = basis
        for b in data:
            h = ((h ^ b) * prime) % 2**64
        return h

    configs = list(solid.presets().values())
    configs += [configs[0].replace(voxel_size=0.0), configs[0].replace(n_azimuth=3600, min_range=0.0)]
    for cfg in configs:
        assert cfg.fingerprint == fnv1a(cfg), cfg


# --- §4 presets ---------------------------------------------------------------------------------


def test_the_presets_table_is_solid_presets() -> None:
    head = [c.strip() for c in section(4).split("\n|")[1].split("|")[:-1]]
    rows = [dict(zip(head, r)) for r in table(section(4))]
    presets, sensors = solid.presets(), solid.preset_sensors()
    assert [r["name"].strip("`") for r in rows] == list(presets)
    for r in rows:
        name = r["name"].strip("`")
        cfg = presets[name]
        for field in ("fov_up", "fov_down", "n_elevation", "max_range", "min_range"):
            assert getattr(cfg, field) == number(r[field]), (name, field)
        assert solid.DetectorConfig.preset(name).threshold == number(r["loop threshold"]), name
        assert solid.LoopDetector(cfg).threshold == number(r["loop threshold"]), name
        assert sensors[name] == r["sensor"]
    common = re.search(r"Every preset uses (.*?)\. ", section(4), flags=re.S).group(1)  # type: ignore[union-attr]
    for field, value in re.findall(r"`(\w+)` = ([\d.]+)", common):
        assert all(getattr(c, field) == float(value) for c in presets.values()), field


# --- §8 loop detector ---------------------------------------------------------------------------


def _detector(**params: Any) -> solid.DetectorConfig:
    """DetectorConfig with parameters chosen at run time (mypy cannot type them)."""
    return solid.DetectorConfig(**params)


def test_the_detector_parameter_table_is_detector_config() -> None:
    rows = {r[0].strip("`"): (r[1], r[3]) for r in table(section(8))}
    assert set(rows) == set(solid.DetectorConfig().to_dict())
    default = solid.DetectorConfig()
    largest = max(solid.DetectorConfig.preset(p).threshold for p in solid.presets())
    assert "Without a preset the default threshold is the largest of the presets'" in section(8)
    assert default.threshold == largest
    for name, (value, valid) in rows.items():
        if name == "threshold":
            assert value.startswith("the preset's loop threshold")
        elif isinstance(getattr(default, name), bool):
            assert value == ("on" if getattr(default, name) else "off"), name
        elif name in ("registration", "gate"):
            assert value == "§11" and valid == "§11", name
            continue
        else:
            assert getattr(default, name) == number(value.split()[0]), name
        for clause in [c for c in re.split(r", (?!\d)", valid) if c]:
            if m := re.fullmatch(r"an integer in (\d+)\.\.=(\d+)", clause):
                lo, hi = int(m.group(1)), int(m.group(2))
                _detector(**{name: lo})
                _detector(**{name: hi})
                for bad in (lo - 1, hi + 1):
                    with pytest.raises(solid.ConfigError, match=name):
                        _detector(**{name: bad})
            elif m := re.fullmatch(r"an integer ≥ (\d+)", clause):
                lo = int(m.group(1))
                _detector(**{name: lo})
                with pytest.raises(solid.SolidError, match=name):
                    _detector(**{name: lo - 1})
            elif clause == "finite":
                for nonfinite in (math.nan, math.inf):
                    with pytest.raises(solid.ConfigError, match=name):
                        _detector(**{name: nonfinite})
            elif clause == "≥ 0":
                _detector(**{name: 0.0})
                with pytest.raises(solid.ConfigError, match=name):
                    _detector(**{name: -1e-9})
            elif m := re.fullmatch(r"in \((\d+), (\d+)\]", clause):
                flo, fhi = float(m.group(1)), float(m.group(2))
                _detector(**{name: fhi})
                for outside in (flo, fhi + 1e-9):
                    with pytest.raises(solid.ConfigError, match=name):
                        _detector(**{name: outside})
            elif m := re.fullmatch(r"in \[(\d+), (\d+)\]", clause):
                flo, fhi = float(m.group(1)), float(m.group(2))
                _detector(**{name: flo})
                _detector(**{name: fhi})
                for outside in (flo - 1e-9, fhi + 1e-9):
                    with pytest.raises(solid.ConfigError, match=name):
                        _detector(**{name: outside})
            else:
                raise AssertionError(f"§8 {name}: rule {clause!r} is not checked by this test: teach it")


def test_the_loop_detector_follows_its_rule() -> None:
    text = section(8)
    assert "`distance(d, c) + aligned(d, c)`" in text and "≤ `threshold`" in text
    cfg = solid.SolidConfig.preset("vlp16")
    rng = np.random.default_rng(8)
    exclude, top_k, threshold = 4, 5, 0.35
    det = solid.LoopDetector(cfg, exclude_recent=exclude, threshold=threshold, top_k=top_k, rerank=True, verify=False)
    rs: list[np.ndarray[Any, Any]] = []
    as_: list[np.ndarray[Any, Any]] = []
    found = 0
    for q in range(60):
        # Sparse non-negative vectors, some of them near an earlier one (so that loops exist).
        if q > 10 and rng.random() < 0.5:
            src = int(rng.integers(0, q - exclude))
            r = rs[src] * rng.uniform(0.8, 1.2, cfg.n_range)
            a = np.roll(as_[src], int(rng.integers(0, cfg.n_azimuth))) * rng.uniform(0.8, 1.2, cfg.n_azimuth)
        else:
            r = rng.uniform(0, 1, cfg.n_range) * (rng.random(cfg.n_range) < 0.5)
            a = rng.uniform(0, 1, cfg.n_azimuth) * (rng.random(cfg.n_azimuth) < 0.5)
        d = solid.Descriptor(r.astype(np.float32), a.astype(np.float32), cfg)
        got = det.add(d)
        expected = _spec_loop(d, rs, as_, q, exclude, top_k, threshold)
        if expected is None:
            assert got is None, (q, got)
        else:
            assert got is not None, (q, expected)
            found += 1
            assert (got.query, got.candidate) == (q, expected[0])
            assert got.distance == pytest.approx(expected[1], abs=1e-6)
            assert got.heading == pytest.approx(solid.heading(d, _desc(cfg, rs[expected[0]], as_[expected[0]])))
        rs.append(d.r.astype(np.float64))
        # c's A-SOLiD is the one the database holds (8 bits per value, Database.a).
        as_.append(det.database.a[q].astype(np.float64))
    assert found >= 10, "the test made too few loops to mean anything"


def _desc(cfg: solid.SolidConfig, r: np.ndarray[Any, Any], a: np.ndarray[Any, Any]) -> solid.Descriptor:
    return solid.Descriptor(r.astype(np.float32), a.astype(np.float32), cfg)


def _spec_loop(
    d: solid.Descriptor,
    rs: list[np.ndarray[Any, Any]],
    as_: list[np.ndarray[Any, Any]],
    q: int,
    exclude: int,
    top_k: int,
    threshold: float,
) -> tuple[int, float] | None:
    """§8 in numpy: (candidate, distance) or None."""
    n_db = q - exclude
    if n_db <= 0:
        return None
    r, a = d.r.astype(np.float64), d.a.astype(np.float64)

    def cos_dist(u: np.ndarray[Any, Any], v: np.ndarray[Any, Any]) -> float:
        nu, nv = np.linalg.norm(u), np.linalg.norm(v)
        return 1.0 if nu == 0 or nv == 0 else float(1.0 - u @ v / (nu * nv))

    dists = [cos_dist(r, rs[i]) for i in range(n_db)]
    order = sorted(range(n_db), key=lambda i: (dists[i], i))[:top_k]

    def aligned(c: int) -> float:
        ac = as_[c]
        if not a.any() or not ac.any():
            return 1.0
        best = max(float(a @ np.roll(ac, s)) for s in range(len(a)))
        return float(np.clip(1.0 - best / (np.linalg.norm(a) * np.linalg.norm(ac)), 0.0, 1.0))

    best = min(order, key=lambda c: dists[c] + aligned(c)) if len(order) > 1 else order[0]
    return (best, dists[best]) if dists[best] <= threshold else None


# --- §9, §10 binary layouts ---------------------------------------------------------------------


def layout(n: int) -> list[tuple[str, str]]:
    """(offset, size) of each row of section n's table."""
    return [(row[0], row[1]) for row in table(section(n))]


def _five_places(session: Callable[[int], int]) -> tuple[solid.SolidConfig, solid.Database]:
    """Five random places, the odd ones with a pose, place 3 without a timestamp."""
    cfg = solid.SolidConfig.preset("avia", max_range=40.0)
    db = solid.Database(cfg)
    rng = np.random.default_rng(9)
    for i in range(5):
        d = _desc(cfg, rng.uniform(0, 3, cfg.n_range), rng.uniform(0, 3, cfg.n_azimuth))
        pose = np.hstack([np.eye(3), np.array([[i], [2.0], [0.5]])]) if i % 2 else None
        db.add(d, session=session(i), timestamp=None if i == 3 else 10.0 + i, pose=pose)
    return cfg, db


#: The rows (offset, size) that both file versions' header tables (§9, §13) begin with: magic,
#: version, flags, the grid, the ranges, the fingerprint, the place count.
SHARED_HEADER = [("0", "8"), ("8", "4"), ("12", "4"), ("16", "16"), ("32", "40"), ("72", "8"), ("80", "8")]


def test_the_database_file_is_laid_out_as_specified() -> None:
    assert layout(9) == SHARED_HEADER + [
        ("88", "8"),
        ("96", "n × 112"),
        ("96 + 112n", "n × Nr × 4"),
        ("…", "n × Na × 4"),
        ("…", "C"),
        ("end − 4", "4"),
    ], "the §9 table changed: update the reader below to the new layout"
    magic = re.search(r"magic `(\w+)\\0`", section(9)).group(1).encode() + b"\0"  # type: ignore[union-attr]
    cfg, db = _five_places(lambda i: i % 2)
    b = db.to_bytes(version=2)
    n, nr, na = len(db), cfg.n_range, cfg.n_azimuth

    assert b[0:8] == magic
    assert struct.unpack_from("<3I", b, 8)[:2] == (2, 0)
    assert struct.unpack_from("<4I", b, 16) == (nr, na, cfg.n_elevation, 0)
    assert struct.unpack_from("<5d", b, 32) == (cfg.fov_up, cfg.fov_down, cfg.min_range, cfg.max_range, cfg.voxel_size)
    assert struct.unpack_from("<3Q", b, 72) == (cfg.fingerprint, n, 0)  # no clouds
    for i in range(n):
        session, flags, t, *stored = struct.unpack_from("<2Id12d", b, 96 + 112 * i)
        assert session == db.sessions[i]
        assert flags == (i % 2)
        assert (math.isnan(t) and math.isnan(db.timestamps[i])) or t == db.timestamps[i]
        expected_pose = db.poses[i].ravel() if flags else np.zeros(12)
        assert stored == list(expected_pose)
    at = 96 + 112 * n
    r = np.frombuffer(b, "<f4", n * nr, at).reshape(n, nr)
    a = np.frombuffer(b, "<f4", n * na, at + 4 * n * nr).reshape(n, na)
    np.testing.assert_array_equal(r, db.r)
    np.testing.assert_array_equal(a, db.a)
    assert len(b) == at + 4 * n * (nr + na) + 4
    assert struct.unpack_from("<I", b, len(b) - 4)[0] == zlib.crc32(b[:-4])


def test_the_database_file_version_4_is_laid_out_as_specified() -> None:
    header, sections = section(13).split("| kind |", 1)
    assert [(row[0], row[1]) for row in table(header)] == SHARED_HEADER + [
        ("88", "4"),
        ("92", "4"),
        ("96", "S × 32"),
        ("96 + 32S", "4"),
        ("100 + 32S", "…"),
    ], "the §13 table changed: update the reader below to the new layout"
    kinds = {int(row[0]): row[1] for row in table("| kind |" + sections)}
    assert kinds == {
        1: "sessions", 2: "r", 3: "r_scale", 4: "a_codes", 5: "a_step", 6: "times", 7: "poses", 8: "cloud_offsets",
        9: "clouds", 10: "metadata", 11: "pose_ids", 12: "pose_q",
    }  # fmt: skip
    cfg, db = _five_places(lambda i: i // 3)
    db.metadata = "{}"
    b = db.to_bytes()
    n, nr, na = len(db), cfg.n_range, cfg.n_azimuth
    assert struct.unpack_from("<3I", b, 8)[:2] == (4, 0)
    assert struct.unpack_from("<4I", b, 16) == (nr, na, cfg.n_elevation, 0)
    assert struct.unpack_from("<2Q", b, 72) == (cfg.fingerprint, n)
    s, zero = struct.unpack_from("<2I", b, 88)
    assert zero == 0 and struct.unpack_from("<I", b, 96 + 32 * s)[0] == zlib.crc32(b[: 96 + 32 * s])
    at, got = 100 + 32 * s, {}
    for k in range(s):
        kind, zero, offset, length, items = struct.unpack_from("<2I3Q", b, 96 + 32 * k)
        assert zero == 0 and offset == at
        body = b[offset : offset + length]
        assert struct.unpack_from("<I", b, offset + length)[0] == zlib.crc32(body)
        got[kinds[kind]] = (body, items)
        at = offset + length + 4
    assert at == len(b) and list(got) == ["sessions", "r", "r_scale", "a_codes", "a_step", "times", "metadata", "pose_ids", "pose_q"]
    runs = [struct.unpack_from("<4I2d", got["sessions"][0], 32 * k) for k in range(got["sessions"][1])]
    assert [r[:4] for r in runs] == [(0, 3, 1, 0), (1, 2, 1, 0)] and runs[1][4:] == (14.0, 14.0)
    np.testing.assert_array_equal(np.frombuffer(got["r"][0], "<f4").reshape(n, nr), db.r)
    norms = np.frombuffer(got["r_scale"][0], "<f4")
    np.testing.assert_allclose(norms, 1 / np.linalg.norm(db.r.astype(np.float64), axis=1), rtol=1e-6)
    codes = np.frombuffer(got["a_codes"][0], "u1").reshape(n, na)
    steps = np.frombuffer(got["a_step"][0], "<f4")
    np.testing.assert_array_equal(codes * steps[:, None], db.a)
    np.testing.assert_array_equal(np.frombuffer(got["times"][0], "<f8"), db.timestamps)
    assert got["pose_ids"][1] == 2 and struct.unpack_from("<2I", got["pose_ids"][0]) == (1, 3)
    assert got["pose_q"][1] == 2 and struct.unpack_from("<7d", got["pose_q"][0], 56) == (1, 0, 0, 0, 3, 2, 0.5)
    # Version 3 stores each pose as its id and its matrix.
    v3 = db.to_bytes(version=3)
    assert struct.unpack_from("<3I", v3, 8)[:2] == (3, 0)
    s3 = struct.unpack_from("<I", v3, 88)[0]
    rows = [struct.unpack_from("<2I3Q", v3, 96 + 32 * k) for k in range(s3)]
    _, _, offset, length, items = next(row for row in rows if row[0] == 7)
    assert items == 2 and length == 200 and struct.unpack_from("<I12d", v3, offset + 100) == (3, *db.poses[3].ravel())
    assert got["metadata"][0] == b"{}"


def test_the_place_wire_form_is_laid_out_as_specified() -> None:
    assert layout(10) == [
        ("0", "2"),
        ("2", "1"),
        ("3", "1"),
        ("4", "2"),
        ("6", "2"),
        ("8", "8"),
        ("16", "payload"),
        ("end − 4", "4"),
    ], "the §10 table changed: update the reader below to the new layout"
    text = section(10)
    cfg = solid.SolidConfig.preset("hdl64")
    rng = np.random.default_rng(10)
    d = _desc(cfg, rng.uniform(0, 50, cfg.n_range) * (rng.random(cfg.n_range) < 0.7), rng.uniform(0, 9, cfg.n_azimuth))
    sizes = {"float32": 0, "quantised": 0}
    for quantized in (False, True):
        b = solid.encode_place(d, quantized=quantized)
        assert b[:2] == b"SP" and b[2] == 1 and b[3] == (2 if quantized else 1)
        assert struct.unpack_from("<2HQ", b, 4) == (cfg.n_range, cfg.n_azimuth, cfg.fingerprint)
        assert struct.unpack_from("<I", b, len(b) - 4)[0] == zlib.crc32(b[:-4])
        if quantized:
            at = 16
            for v in (d.r, d.a):
                m = struct.unpack_from("<f", b, at)[0]
                assert m == v.max()
                q = np.frombuffer(b, np.uint8, len(v), at + 4)
                np.testing.assert_array_equal(q, np.round(255 * np.sqrt(v.astype(np.float64) / m)))
                at += 4 + len(v)
            back = solid.decode_place(b, cfg)
            decoded = np.frombuffer(b, np.uint8, cfg.n_range, 20).astype(np.float64) / 255
            np.testing.assert_allclose(back.r, decoded**2 * d.r.max(), rtol=1e-6)
            sizes["quantised"] = len(b)
        else:
            np.testing.assert_array_equal(np.frombuffer(b, "<f4", cfg.n_range, 16), d.r)
            np.testing.assert_array_equal(np.frombuffer(b, "<f4", cfg.n_azimuth, 16 + 4 * cfg.n_range), d.a)
            sizes["float32"] = len(b)
    stated = re.search(r"(\d+) bytes as float32 and (\d+) bytes quantised", text)
    assert stated and (int(stated.group(1)), int(stated.group(2))) == (sizes["float32"], sizes["quantised"])
