"""Readers and datasets of solid.io and the transforms of solid.transforms, on the shared real scans and on files written here."""

from __future__ import annotations

import math
import os
import struct
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from conftest import data_dir

from solid import io as sio
from solid import transforms



def header_end(raw: bytes) -> int:
    i = raw.index(b"DATA ")
    return raw.index(b"\n", i) + 1


# --------------------------------------------------------------------------------------------
# real files


def test_kitti_bin_matches_raw_floats() -> None:
    p = data_dir() / "kitti00/velodyne/000000.bin"
    c = sio.read_cloud(p)
    raw = np.fromfile(p, dtype="<f4").reshape(-1, 4)
    assert sio.detect_format(p) == "kitti"
    assert c.fields == ("x", "y", "z", "reflectance")
    assert c.points.dtype == np.float32 and c.points.flags.c_contiguous
    assert c.points.shape == (os.path.getsize(p) // 16, 4)
    assert np.array_equal(c.points, raw)
    xyz = sio.read_points(p, xyz_only=True)
    assert xyz.shape == (raw.shape[0], 3) and xyz.flags.c_contiguous
    assert np.array_equal(xyz, raw[:, :3])


def read_real(rel: str, fmt: str) -> tuple[bytes, Any]:
    """The bytes of a real sample (a path under the data folder) and the cloud read from it, once
    its format is detected as `fmt`."""
    p = data_dir() / rel
    assert sio.detect_format(p) == fmt
    return p.read_bytes(), sio.read_cloud(p)


@pytest.mark.parametrize(
    "rel, n",
    [
        ("solid-samples/kitti_00_pcd/000313.pcd", 121853),
        ("misc/naverlabs_vel16.pcd", 29184),
        ("hku1-avia/Scans/000000.pcd", 3430),
    ],
)
def test_pcd_binary_real(rel: str, n: int) -> None:
    raw, c = read_real(rel, "pcd")
    assert c.points.shape[0] == n
    assert c.fields[:3] == ("x", "y", "z")
    ncol = len(c.fields)
    expected = np.frombuffer(raw[header_end(raw) :], dtype="<f4", count=n * ncol).reshape(n, ncol)
    assert np.array_equal(c.points, expected)


def test_helipr_aeva_records() -> None:
    raw, c = read_real("solid-samples/helipr_aeva/000000.bin", "helipr-aeva")
    assert c.points.shape == (len(raw) // 29, 8)
    assert c.fields == ("x", "y", "z", "reflectivity", "velocity", "time_offset_ns", "line_index", "intensity")
    for i in (0, 1234, c.points.shape[0] - 1):
        x, y, z, refl, vel, toff, line, inten = struct.unpack_from("<5fiBf", raw, 29 * i)
        expect = np.array([x, y, z, refl, vel, toff, line, inten], dtype=np.float32)
        assert np.array_equal(c.points[i], expect)
    # Aeva Aeries II: all points inside its narrow vertical field of view (±9.6° nominal, plus margin)
    xyz = c.points[:, :3].astype(np.float64)
    el = np.degrees(np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1])))
    assert np.percentile(np.abs(el), 99) < 15.0


def test_helipr_avia_records() -> None:
    raw, c = read_real("solid-samples/helipr_avia/000010.bin", "helipr-avia")
    assert c.points.shape == (len(raw) // 19, 7)
    for i in (0, 777, c.points.shape[0] - 1):
        x, y, z, refl, tag, line, off = struct.unpack_from("<3f3BI", raw, 19 * i)
        assert np.array_equal(c.points[i], np.array([x, y, z, refl, tag, line, off], dtype=np.float32))
    assert set(np.unique(c.points[:, 5])) <= {0, 1, 2, 3, 4, 5}  # Avia has 6 lines


def test_nclt_scaled_uint16() -> None:
    raw, c = read_real("misc/nclt_2012-01-15_1326652795280148_hdl32e.bin", "nclt")
    assert c.points.shape == (23546, 5)
    for i in (0, 100, 23545):
        xr, yr, zr, inten, laser = struct.unpack_from("<3H2B", raw, 8 * i)
        want = [xr * 0.005 - 100, yr * 0.005 - 100, zr * 0.005 - 100, inten, laser]
        assert np.allclose(c.points[i], want, atol=1e-5, rtol=0)
    assert c.points[:, 4].max() == 31  # HDL-32E laser ids 0..31


def test_forced_format_and_unknown() -> None:
    p = data_dir() / "solid-samples/helipr_avia/000001.bin"
    # this Avia file (233,320 B) is not a whole number of 16 B records: KITTI refuses it, naming the file
    with pytest.raises(sio.ReadError, match=r"000001\.bin.*multiple of 16"):
        sio.read_points(p, format="kitti")
    assert sio.read_points(p, format="helipr-avia").shape[1] == 7
    with pytest.raises(ValueError, match="unknown format"):
        sio.read_points(p, format="lasx")
    # 233,320 B is not a whole number of 26 B Ouster records either.
    with pytest.raises(sio.ReadError, match=r"000001\.bin"):
        sio.read_points(p, format="helipr-ouster")


def test_helipr_ouster_and_velodyne_records(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    n = 257
    xyzi = rng.normal(0, 20, size=(n, 4)).astype("<f4")
    ouster = np.zeros(n, dtype=[("p", "<f4", 4), ("t", "<u4"), ("refl", "<u2"), ("ring", "<u2"), ("amb", "<u2")])
    ouster["p"], ouster["t"], ouster["ring"] = xyzi, np.arange(n), np.arange(n) % 128
    velo = np.zeros(n, dtype=[("p", "<f4", 4), ("ring", "<u2"), ("time", "<f4")])
    velo["p"], velo["ring"], velo["time"] = xyzi, np.arange(n) % 16, np.linspace(0, 0.1, n)
    assert ouster.itemsize == 26 and velo.itemsize == 22
    for kind, rec in (("Ouster", ouster), ("Velodyne", velo)):
        path = tmp_path / "LiDAR" / kind / "1692248305025943817.bin"
        path.parent.mkdir(parents=True)
        path.write_bytes(rec.tobytes())
        assert sio.detect_format(path) == f"helipr-{kind.lower()}"
        pts = sio.read_points(path)
        np.testing.assert_array_equal(pts[:, :4], xyzi)
        np.testing.assert_array_equal(pts[:, 4 if kind == "Velodyne" else 6], rec["ring"])
        path.write_bytes(rec.tobytes()[:-5])
        with pytest.raises(sio.ReadError, match="1692248305025943817.bin"):
            sio.read_points(path)
    # The content decides, not the folder: a KITTI scan stored under LiDAR/Ouster/ is read as KITTI.
    k = tmp_path / "LiDAR" / "Ouster" / "000000.bin"
    k.write_bytes(xyzi[: 13 * 16].tobytes())  # 208 records of 16 B = 3328 B = 128 Ouster records
    assert sio.detect_format(k) == "kitti"


def test_clip_fov_reproduces_authors_clipped_samples() -> None:
    d = data_dir()
    full = sio.read_points(d / "kitti00/velodyne/000000.bin")
    for width in (60, 120, 180):
        sample = sio.read_points(d / f"solid-samples/kitti_00_{width}/000000.bin")
        ours = transforms.clip_fov(full, width)
        assert ours.shape == sample.shape
        a = np.sort(ours.view("V16").ravel())
        b = np.sort(np.ascontiguousarray(sample).view("V16").ravel())
        assert np.array_equal(a, b)


def test_sequence_hku() -> None:
    d = data_dir() / "hku1-avia"
    seq = sio.Dataset(d, poses="odom_poses.txt", timestamps="times.txt")
    assert len(seq) == 314
    assert seq.files[0].name == "000000.pcd" and seq.files[-1].name == "000313.pcd"
    assert seq.poses is not None and seq.poses.shape == (314, 3, 4)
    assert seq.timestamps is not None and np.all(np.diff(seq.timestamps) > 0)
    # first pose is the identity (keyframe → world of the first keyframe)
    assert np.allclose(seq.poses[0][:, :3], np.eye(3), atol=1e-2)
    first = seq[0]
    assert first.shape == (3430, 3) and first.dtype == np.float32
    assert np.array_equal(seq[-1], seq[313])
    assert [p.shape[0] for p in seq[:2]] == [3430, seq[1].shape[0]]
    n = 0
    for pts in seq:
        assert pts.shape[1] == 3 and 3000 < pts.shape[0] < 6000
        n += 1
    assert n == 314
    with pytest.raises(IndexError):
        seq[314]
    pos = seq.positions()
    travelled = float(np.linalg.norm(np.diff(pos, axis=0), axis=1).sum())
    assert 55 < travelled < 80  # the README's 64 m walk


def test_sequence_kitti_layout(tmp_path: Path) -> None:
    d = data_dir() / "kitti00"
    seq = sio.Dataset(d)
    assert [f.name for f in seq.files] == ["000000.bin", "000094.bin", "000095.bin", "000198.bin", "000199.bin"]
    poses, t = sio.load_poses(d / "poses_00.txt")
    assert poses.shape == (4541, 3, 4) and t is None


# --------------------------------------------------------------------------------------------
# round trips through files written here


def cloud(n: int = 500, c: int = 4, seed: int = 0) -> npt.NDArray[np.float32]:
    rng = np.random.default_rng(seed)
    pts = rng.normal(0, 20, (n, c)).astype(np.float32)
    pts[::7, 2] = 0.0  # repeated values, so LZF finds back-references
    pts[::11, 3 % c] = 1.0
    return pts


@pytest.mark.parametrize("kind", ["ascii", "binary", "binary_compressed"])
def test_pcd_round_trip(tmp_path: Path, kind: Any) -> None:
    pts = cloud()
    p = tmp_path / f"c_{kind}.pcd"
    sio.write_pcd(p, pts, ["x", "y", "z", "intensity"], data=kind)
    c = sio.read_cloud(p)
    assert c.fields == ("x", "y", "z", "intensity")
    assert np.array_equal(c.points, pts)
    empty = tmp_path / f"e_{kind}.pcd"
    sio.write_pcd(empty, np.zeros((0, 3), np.float32), data=kind)
    assert sio.read_points(empty).shape == (0, 3)


def test_pcd_fields_types_counts_and_order(tmp_path: Path) -> None:
    n = 50
    rng = np.random.default_rng(3)
    dt = np.dtype(
        [
            ("intensity", "<f4"),
            ("normal", "<f4", (3,)),
            ("_", "u1", (2,)),
            ("z", "<f8"),
            ("ring", "<u2"),
            ("x", "<f4"),
            ("y", "<f4"),
            ("t", "<i4"),
        ]
    )
    rec = np.zeros(n, dtype=dt)
    for name in ("intensity", "z", "x", "y"):
        rec[name] = rng.normal(0, 10, n)
    rec["normal"] = rng.normal(0, 1, (n, 3))
    rec["ring"] = rng.integers(0, 64, n)
    rec["t"] = rng.integers(-1000, 1000, n)
    head = (
        "VERSION 0.7\nFIELDS intensity normal _ z ring x y t\nSIZE 4 4 1 8 2 4 4 4\n"
        "TYPE F F U F U F F I\nCOUNT 1 3 2 1 1 1 1 1\n"
        f"WIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA binary\n"
    )
    p = tmp_path / "typed.pcd"
    p.write_bytes(head.encode() + rec.tobytes())
    c = sio.read_cloud(p)
    assert c.fields == ("x", "y", "z", "intensity", "normal_0", "normal_1", "normal_2", "ring", "t")
    assert np.array_equal(c.points[:, 0], rec["x"])
    assert np.array_equal(c.points[:, 2], rec["z"].astype(np.float32))
    assert np.array_equal(c.points[:, 5], rec["normal"][:, 1])
    assert np.array_equal(c.points[:, 7], rec["ring"].astype(np.float32))
    assert np.array_equal(c.points[:, 8], rec["t"].astype(np.float32))
    # the same cloud as ascii
    rows = []
    for r in rec:
        vals = [r["intensity"], *r["normal"], *r["_"], r["z"], r["ring"], r["x"], r["y"], r["t"]]
        rows.append(" ".join(repr(float(v)) if isinstance(v, (float, np.floating)) else str(int(v)) for v in vals))
    pa = tmp_path / "typed_ascii.pcd"
    pa.write_text(head.replace("DATA binary", "DATA ascii") + "\n".join(rows) + "\n")
    ca = sio.read_cloud(pa)
    assert ca.fields == c.fields
    assert np.array_equal(ca.points, c.points)
    # and as binary_compressed: structure of arrays, each field's values contiguous, LZF
    soa = b"".join(np.ascontiguousarray(rec[name]).tobytes() for name in dt.names or ())
    comp = sio.lzf_compress(soa)
    pc = tmp_path / "typed_c.pcd"
    pc.write_bytes(
        head.replace("DATA binary", "DATA binary_compressed").encode()
        + struct.pack("<II", len(comp), len(soa))
        + comp
    )
    assert np.array_equal(sio.read_points(pc), c.points)


def test_pcd_float_fields_in_any_order(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    table = rng.normal(0, 5, (40, 5)).astype("<f4")  # columns: intensity _ z x y
    head = (
        "VERSION 0.7\nFIELDS intensity _ z x y\nSIZE 4 4 4 4 4\nTYPE F F F F F\nCOUNT 1 1 1 1 1\n"
        "WIDTH 40\nHEIGHT 1\nPOINTS 40\nDATA binary\n"
    )
    p = tmp_path / "order.pcd"
    p.write_bytes(head.encode() + table.tobytes())
    c = sio.read_cloud(p)
    assert c.fields == ("x", "y", "z", "intensity")
    assert np.array_equal(c.points, table[:, [3, 4, 2, 0]]) and c.points.flags.c_contiguous
    assert np.array_equal(sio.read_points(p, xyz_only=True), table[:, [3, 4, 2]])


def test_lzf_hand_made_streams() -> None:
    # literal run "abc" (control 2), then a back-reference: length 5 (control 3<<5), offset 3 (byte 2)
    assert sio.lzf_decompress(bytes([2]) + b"abc" + bytes([0x60, 2]), 8) == b"abcabcab"
    # overlapping run: "z" then a long back-reference of 7+10+2 = 19 bytes at distance 1
    assert sio.lzf_decompress(bytes([0, ord("z"), 0xE0, 10, 0]), 20) == b"z" * 20
    with pytest.raises(ValueError, match="before the start"):
        sio.lzf_decompress(bytes([0, ord("z"), 0x20, 5]), 4)
    with pytest.raises(ValueError, match="truncated"):
        sio.lzf_decompress(bytes([5]) + b"ab", 6)
    with pytest.raises(ValueError, match="expected 9 B"):
        sio.lzf_decompress(bytes([2]) + b"abc" + bytes([0x60, 2]), 9)


def test_lzf_round_trip_random() -> None:
    rng = np.random.default_rng(7)
    for trial in range(60):
        n = int(rng.integers(0, 5000))
        kind = trial % 3
        if kind == 0:
            data = rng.integers(0, 3, n).astype(np.uint8).tobytes()
        elif kind == 1:
            data = rng.integers(0, 256, n).astype(np.uint8).tobytes()
        else:
            data = (b"solid-lzf" * (n // 9 + 1))[:n]
        comp = sio.lzf_compress(data)
        assert sio.lzf_decompress(comp, len(data)) == data


@pytest.mark.parametrize("kind", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_ply_round_trip(tmp_path: Path, kind: Any) -> None:
    pts = cloud(300, 5)
    p = tmp_path / "c.ply"
    sio.write_ply(p, pts, ["x", "y", "z", "intensity", "ring"], data=kind)
    assert sio.detect_format(p) == "ply"
    c = sio.read_cloud(p)
    assert c.fields == ("x", "y", "z", "intensity", "ring")
    assert np.array_equal(c.points, pts)


def test_ply_with_faces_and_double(tmp_path: Path) -> None:
    verts = np.array([(1.5, -2.0, 3.25, 7), (0.0, 1.0, -1.0, 9)], dtype=[("x", ">f8"), ("y", ">f8"), ("z", ">f8"), ("red", "u1")])
    head = (
        "ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty double x\nproperty double y\n"
        "property double z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
    )
    p = tmp_path / "mesh.ply"
    p.write_bytes(head.encode() + verts.tobytes() + bytes([3]) + struct.pack(">3i", 0, 1, 1))
    c = sio.read_cloud(p)
    assert c.fields == ("x", "y", "z", "red")
    assert np.array_equal(c.points, np.array([[1.5, -2.0, 3.25, 7], [0.0, 1.0, -1.0, 9]], dtype=np.float32))


def test_numpy_files(tmp_path: Path) -> None:
    pts = cloud(100, 4).astype(np.float64)
    np.save(tmp_path / "a.npy", pts)
    got = sio.read_points(tmp_path / "a.npy")
    assert got.dtype == np.float32 and np.array_equal(got, pts.astype(np.float32))
    np.savez(tmp_path / "b.npz", points=pts, other=np.zeros(3))
    assert np.array_equal(sio.read_points(tmp_path / "b.npz"), pts.astype(np.float32))
    np.savez(tmp_path / "c.npz", cloud=pts[:, :3])
    assert sio.read_points(tmp_path / "c.npz").shape == (100, 3)
    np.savez(tmp_path / "d.npz", a=pts, b=pts)
    with pytest.raises(sio.ReadError, match="d.npz.*one named 'points'"):
        sio.read_points(tmp_path / "d.npz")
    rec = np.zeros(4, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("t", "f8")])
    rec["y"] = [1, 2, 3, 4]
    np.save(tmp_path / "s.npy", rec)
    c = sio.read_cloud(tmp_path / "s.npy")
    assert c.fields == ("x", "y", "z", "t") and np.array_equal(c.points[:, 1], [1, 2, 3, 4])
    np.save(tmp_path / "bad.npy", np.zeros((5, 2)))
    with pytest.raises(sio.ReadError, match=r"bad\.npy.*\(N, >=3\)"):
        sio.read_points(tmp_path / "bad.npy")


# --------------------------------------------------------------------------------------------
# corrupt and truncated files


def test_truncated_and_corrupt_files(tmp_path: Path) -> None:
    pts = cloud(200, 4)
    k = tmp_path / "t.bin"
    k.write_bytes(pts.tobytes()[:-3])
    with pytest.raises(sio.ReadError, match=r"t\.bin: size 3197 B is not a whole number of records of any .bin layout \(kitti 16 B"):
        sio.read_points(k)
    with pytest.raises(sio.ReadError, match=r"t\.bin: size 3197 B is not a multiple of 16 B, the KITTI record"):
        sio.read_points(k, format="kitti")

    good = tmp_path / "g.pcd"
    sio.write_pcd(good, pts)
    raw = good.read_bytes()
    bad = tmp_path / "trunc.pcd"
    bad.write_bytes(raw[:-10])
    with pytest.raises(sio.ReadError, match=r"trunc\.pcd: truncated PCD binary data"):
        sio.read_points(bad)
    nohead = tmp_path / "nohead.pcd"
    nohead.write_bytes(raw[:40])
    with pytest.raises(sio.ReadError, match=r"nohead\.pcd: PCD header ends before its DATA"):
        sio.read_points(nohead)
    nofields = tmp_path / "nofields.pcd"
    nofields.write_bytes(raw.replace(b"FIELDS x y z f3\n", b""))
    with pytest.raises(sio.ReadError, match="no FIELDS line"):
        sio.read_points(nofields)
    noz = tmp_path / "noz.pcd"
    noz.write_bytes(raw.replace(b"FIELDS x y z f3", b"FIELDS x y w f3"))
    with pytest.raises(sio.ReadError, match="no field named z"):
        sio.read_points(noz)

    comp = tmp_path / "c.pcd"
    sio.write_pcd(comp, pts, data="binary_compressed")
    craw = comp.read_bytes()
    cut = tmp_path / "ccut.pcd"
    cut.write_bytes(craw[:-5])
    with pytest.raises(sio.ReadError, match=r"ccut\.pcd: truncated PCD binary_compressed"):
        sio.read_points(cut)
    # corrupt the compressed payload's first control byte: a literal run becomes a back-reference
    h = header_end(craw)
    broken = bytearray(craw)
    broken[h + 8] = 0x40
    cor = tmp_path / "corrupt.pcd"
    cor.write_bytes(bytes(broken))
    with pytest.raises(sio.ReadError, match=r"corrupt\.pcd: corrupt PCD binary_compressed data"):
        sio.read_points(cor)
    asc = tmp_path / "a.pcd"
    sio.write_pcd(asc, pts[:5], data="ascii")
    text = asc.read_text().splitlines()
    (tmp_path / "a_short.pcd").write_text("\n".join(text[:-1]) + "\n")
    with pytest.raises(sio.ReadError, match="expected 5 points"):
        sio.read_points(tmp_path / "a_short.pcd")
    (tmp_path / "a_nan.pcd").write_text("\n".join(text[:-1] + ["1 2 three 4"]) + "\n")
    with pytest.raises(sio.ReadError, match="not a number"):
        sio.read_points(tmp_path / "a_nan.pcd")

    ply = tmp_path / "p.ply"
    sio.write_ply(ply, pts)
    (tmp_path / "pt.ply").write_bytes(ply.read_bytes()[:-1])
    with pytest.raises(sio.ReadError, match=r"pt\.ply: truncated PLY binary data"):
        sio.read_points(tmp_path / "pt.ply")
    (tmp_path / "notply.ply").write_bytes(b"PLY?\n")
    with pytest.raises(sio.ReadError, match="no 'ply' magic"):
        sio.read_points(tmp_path / "notply.ply")

    aeva = tmp_path / "aeva" / "0.bin"
    aeva.parent.mkdir()
    aeva.write_bytes(bytes(29 * 3 + 5))
    with pytest.raises(sio.ReadError, match=r"0\.bin: size 92 B is not a multiple of the 29 B"):
        sio.read_points(aeva, format="helipr-aeva")
    npy = tmp_path / "junk.npy"
    npy.write_bytes(b"\x93NUMPY garbage")
    with pytest.raises(sio.ReadError, match=r"junk\.npy: not a valid .npy header"):
        sio.read_points(npy)
    with pytest.raises(FileNotFoundError):
        sio.read_points(tmp_path / "missing.bin")


# --------------------------------------------------------------------------------------------
# sequences, poses, timestamps


def test_natural_order_and_scan_folder(tmp_path: Path) -> None:
    v = tmp_path / "seq" / "velodyne"
    v.mkdir(parents=True)
    for i in (10, 2, 1, 100):
        (v / f"{i}.bin").write_bytes(np.full((3, 4), i, dtype=np.float32).tobytes())
    (tmp_path / "seq" / "notes.txt").write_text("not a scan")
    seq = sio.Dataset(tmp_path / "seq")
    assert [f.name for f in seq.files] == ["1.bin", "2.bin", "10.bin", "100.bin"]
    assert [float(s[0, 0]) for s in seq] == [1.0, 2.0, 10.0, 100.0]
    (v / "3.pcd").write_bytes(b"")
    with pytest.raises(sio.ReadError, match="mixed scan types"):
        sio.Dataset(tmp_path / "seq")
    assert sorted(["a10b", "a2b", "a1b"], key=sio.natural_key) == ["a1b", "a2b", "a10b"]


def test_poses_kitti_tum_and_errors(tmp_path: Path) -> None:
    kitti = tmp_path / "k.txt"
    kitti.write_text("1 0 0 1 0 1 0 2 0 0 1 3\n0 -1 0 4 1 0 0 5 0 0 1 6\n")
    P, t = sio.load_poses(kitti)
    assert t is None and P.shape == (2, 3, 4)
    assert np.array_equal(P[1, :, 3], [4, 5, 6])
    assert np.allclose(transforms.yaw_degrees(P[:, :, :3]), [0.0, 90.0])
    tum = tmp_path / "t.txt"
    s = math.sin(math.radians(30) / 2)
    c = math.cos(math.radians(30) / 2)
    tum.write_text(f"# t x y z qx qy qz qw\n10.5 1 2 3 0 0 0 1\n11.5 4 5 6 0 0 {s} {c}\n")
    P, t = sio.load_poses(tum)
    assert t is not None and np.array_equal(t, [10.5, 11.5])
    assert np.allclose(P[0, :, :3], np.eye(3))
    assert np.allclose(P[1, :, 3], [4, 5, 6])
    assert math.isclose(float(transforms.yaw_degrees(P[1, :, :3])), 30.0, abs_tol=1e-9)
    bad = tmp_path / "bad.txt"
    bad.write_text("1 2 3 4 5\n")
    with pytest.raises(sio.ReadError, match=r"bad\.txt: pose rows have 5 numbers"):
        sio.load_poses(bad)
    ragged = tmp_path / "ragged.txt"
    ragged.write_text("1 0 0 1 0 1 0 2 0 0 1 3\n1 0 0\n")
    with pytest.raises(sio.ReadError, match="row 2 has 3 numbers"):
        sio.load_poses(ragged)


KITTI_00_TR = (
    "4.276802385584e-04 -9.999672484946e-01 -8.084491683471e-03 -1.198459927713e-02 "
    "-7.210626507497e-03 8.081198471645e-03 -9.999413164504e-01 -5.403984729748e-02 "
    "9.999738645903e-01 4.859485810390e-04 -7.206933692422e-03 -2.921968648686e-01"
)


def test_kitti_calib_turns_camera_poses_into_lidar_yaw(tmp_path: Path) -> None:
    calib = tmp_path / "calib.txt"
    calib.write_text("P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: " + KITTI_00_TR + "\n")
    T = sio.load_extrinsic(calib)
    assert T.shape == (4, 4) and T[3].tolist() == [0, 0, 0, 1]
    assert T[0, 1] == pytest.approx(-0.9999672484946)
    # the camera (x right, y down, z forward) turns left by 25° seen from above = −25° about its y
    a = math.radians(-25.0)
    ry = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    cam = np.zeros((2, 3, 4))
    cam[0, :, :3] = np.eye(3)
    cam[1, :, :3] = ry
    cam[1, :, 3] = [0, 0, 2.0]  # 2 m forward
    rel_cam = cam[0, :, :3].T @ cam[1, :, :3]
    assert abs(float(transforms.yaw_degrees(rel_cam))) < 1e-9  # "yaw" of the camera frame is not the heading
    lidar = sio.sensor_poses(cam, T)
    rel = lidar[0, :, :3].T @ lidar[1, :, :3]
    assert float(transforms.yaw_degrees(rel)) == pytest.approx(25.0, abs=0.5)
    # the lidar sits 0.27 m behind the camera: moving 2 m forward moves it 2 m too
    assert np.linalg.norm(lidar[1, :, 3] - lidar[0, :, 3]) == pytest.approx(2.0, abs=0.1)
    plain = tmp_path / "tr.txt"
    plain.write_text(KITTI_00_TR + "\n")
    assert np.array_equal(sio.load_extrinsic(plain), T)
    bad = tmp_path / "bad_calib.txt"
    bad.write_text("P0: 1 2 3\n")
    with pytest.raises(sio.ReadError, match="no 'Tr:' line"):
        sio.load_extrinsic(bad)
    skew = tmp_path / "skew.txt"
    skew.write_text("2 0 0 0 0 1 0 0 0 0 1 0\n")
    with pytest.raises(sio.ReadError, match="not a rotation"):
        sio.load_extrinsic(skew)


# --------------------------------------------------------------------------------------------
# transforms


def ring_points() -> npt.NDArray[np.float32]:
    az = np.radians(np.arange(0, 360, 1.0) + 0.5)
    return np.stack([10 * np.cos(az), 10 * np.sin(az), np.arange(360) * 0.01, np.arange(360)], axis=1).astype(np.float32)


def test_clip_and_occlude_sectors() -> None:
    p = ring_points()  # one point per degree at azimuth k + 0.5
    front = transforms.clip_fov(p, 60)
    assert front.shape[0] == 60
    az = np.degrees(np.arctan2(front[:, 1], front[:, 0]))
    assert np.all(np.abs(az) < 30)
    left = transforms.clip_fov(p, 90, center_deg=90)
    azl = np.degrees(np.arctan2(left[:, 1], left[:, 0]))
    assert left.shape[0] == 90 and np.all((azl > 45) & (azl < 135))
    back = transforms.clip_fov(p, 20, center_deg=180)  # wraps through ±180°
    assert back.shape[0] == 20
    occ = transforms.occlude_sector(p, 90, center_deg=-45)
    assert occ.shape[0] == 270
    azo = np.degrees(np.arctan2(occ[:, 1], occ[:, 0]))
    assert not np.any((azo > -90) & (azo < 0))
    assert transforms.clip_fov(p, 360).shape[0] == 360 and transforms.occlude_sector(p, 0).shape[0] == 360
    with pytest.raises(ValueError):
        transforms.clip_fov(p, 0)


def test_rotate_z_counter_clockwise() -> None:
    p = np.array([[1.0, 0.0, 2.0, 5.0], [0.0, 2.0, -1.0, 6.0]], dtype=np.float32)
    r = transforms.rotate_z(p, 90)
    assert np.allclose(r, [[0, 1, 2, 5], [-2, 0, -1, 6]], atol=1e-6)
    assert r.dtype == np.float32
    assert np.allclose(transforms.rotate_z(transforms.rotate_z(p, 33), -33), p, atol=1e-6)


def test_subsample_by_distance() -> None:
    # positions 0, 0.4, 0.8, ..., 4.0 m along x: one frame per metre keeps 0, 1.2, 2.0, 3.2, 4.0
    n = 11
    P = np.tile(np.eye(3, 4), (n, 1, 1))
    P[:, 0, 3] = np.arange(n) * 0.4
    keep = transforms.subsample_by_distance(P, 1.0)
    assert keep.tolist() == [0, 3, 5, 8, 10]
    # standing still keeps only the first frame
    still = np.tile(np.eye(3, 4), (5, 1, 1))
    assert transforms.subsample_by_distance(still, 0.5).tolist() == [0]
    with pytest.raises(ValueError):
        transforms.subsample_by_distance(P, 0.0)


# --------------------------------------------------------------------------------------------
# ROS bags (optional extra)


def _write_bags(tmp_path: Path, clouds: list[npt.NDArray[np.float32]]) -> list[Path]:
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    from solid.datasets.rosbag import cloud_to_pointcloud2

    def message(ts: Any, pts: npt.NDArray[np.float32], sec: int) -> Any:
        # x y z float32, a padding byte gap, then intensity as float64: point_step 24
        rec = np.zeros(pts.shape[0], dtype={"names": ["x", "y", "z", "intensity"], "formats": ["<f4", "<f4", "<f4", "<f8"], "offsets": [0, 4, 8, 16], "itemsize": 24})
        rec["x"], rec["y"], rec["z"], rec["intensity"] = pts[:, 0], pts[:, 1], pts[:, 2], pts[:, 3]
        return cloud_to_pointcloud2(ts, rec, sec, "lidar")

    msgtype = "sensor_msgs/msg/PointCloud2"
    out: list[Path] = []
    ts2 = get_typestore(Stores.ROS2_HUMBLE)
    for plugin, name in ((StoragePlugin.SQLITE3, "ros2_sqlite"), (StoragePlugin.MCAP, "ros2_mcap")):
        with Writer2(tmp_path / name, version=9, storage_plugin=plugin) as w:
            conn = w.add_connection("/points", msgtype, typestore=ts2)
            other = w.add_connection("/chatter", "std_msgs/msg/String", typestore=ts2)
            for i, p in enumerate(clouds):
                w.write(conn, (i + 1) * 10**9, ts2.serialize_cdr(message(ts2, p, i + 1), msgtype))
                w.write(other, (i + 1) * 10**9 + 1, ts2.serialize_cdr(ts2.types["std_msgs/msg/String"](data="hi"), "std_msgs/msg/String"))
        out.append(tmp_path / name)
    ts1 = get_typestore(Stores.ROS1_NOETIC)
    with Writer1(tmp_path / "ros1.bag") as w1:
        conn = w1.add_connection("/points", msgtype, typestore=ts1)
        for i, p in enumerate(clouds):
            w1.write(conn, (i + 1) * 10**9, ts1.serialize_ros1(message(ts1, p, i + 1), msgtype))
    out.append(tmp_path / "ros1.bag")
    out.append(next((tmp_path / "ros2_mcap").glob("*.mcap")))
    return out


def test_rosbag_pointcloud2(tmp_path: Path) -> None:
    pytest.importorskip("rosbags", reason="rosbags is an optional extra: pip install solid-lidar[ros]")
    clouds = [cloud(20 + 5 * i, 4, seed=i) for i in range(3)]
    for path in _write_bags(tmp_path, clouds):
        seq = sio.Dataset(path, xyz_only=False)
        assert len(seq) == 3, path
        assert seq.timestamps is not None and np.array_equal(seq.timestamps, [1.0, 2.0, 3.0])
        got = list(seq)
        for g, want in zip(got, clouds):
            assert g.shape == (want.shape[0], 4)
            assert np.array_equal(g[:, :3], want[:, :3])
            assert np.array_equal(g[:, 3], want[:, 3])
        assert np.array_equal(seq[1][:, :3], clouds[1][:, :3])
        with pytest.raises(sio.ReadError, match="no topic '/nope'"):
            sio.Dataset(path, topic="/nope")


def test_rosbag_missing_extra_message(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    import builtins

    real_import = builtins.__import__

    def fake_import(name: str, *args: Any, **kwargs: Any) -> Any:
        if name == "rosbags" or name.startswith("rosbags."):
            raise ImportError("No module named 'rosbags'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake_import)
    bag = tmp_path / "x.bag"
    bag.write_bytes(b"#ROSBAG V2.0\n")
    with pytest.raises(ImportError, match=r"pip install solid-lidar\[ros\]"):
        sio.Dataset(bag)


def test_names_that_moved_out_of_solid_io_still_work_with_a_warning() -> None:
    from solid import datasets

    with pytest.warns(DeprecationWarning, match="solid.io.Sequence is solid.datasets.Dataset"):
        assert sio.Sequence is datasets.Dataset
    for name in ("clip_fov", "occlude_sector", "rotate_z", "subsample_by_distance", "yaw_degrees"):
        with pytest.warns(DeprecationWarning, match=f"solid.transforms.{name}"):
            assert getattr(sio, name) is getattr(transforms, name)
    with pytest.raises(AttributeError):
        sio.no_such_name  # noqa: B018
