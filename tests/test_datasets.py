"""solid.datasets: the registry, content sniffing, datasets with poses and timestamps, bags with
Livox CustomMsg, and the readers' error contract. The traps of issues 8 and 10 each have a test."""

from __future__ import annotations

import os
import shutil
import struct
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from conftest import data_dir, run

import solid
from solid import datasets as sd
from solid import io as sio
from solid import transforms
from solid.datasets.poses import matrix_to_quat, quat_to_matrix

KITTI_00_TR = (
    "4.276802385584e-04 -9.999672484946e-01 -8.084491683471e-03 -1.198459927713e-02 "
    "-7.210626507497e-03 8.081198471645e-03 -9.999413164504e-01 -5.403984729748e-02 "
    "9.999738645903e-01 4.859485810390e-04 -7.206933692422e-03 -2.921968648686e-01"
)


def test_registry_and_api_shape() -> None:
    names = sd.available()
    for n in ("kitti", "nclt", "helipr-aeva", "helipr-avia", "helipr-ouster", "helipr-velodyne", "pcd", "ply", "npy", "npz", "rosbag:pointcloud2", "rosbag:livox"):
        assert n in names and names[n]
    assert set(sd.FORMATS) == set(names) | {"rosbag"}
    assert issubclass(sd.ReadError, solid.SolidError) and issubclass(sd.ReadError, ValueError)
    assert sio.ReadError is sd.ReadError and sio.Dataset is sd.Dataset
    with pytest.raises(ValueError, match="unknown format 'lasx'"):
        sd.open_dataset(data_dir() / "kitti00", format="lasx")


# --------------------------------------------------------------------------------------------
# content decides the reader (issue 8's traps)


def test_renamed_nclt_scan_is_read_as_nclt(tmp_path: Path) -> None:
    src = data_dir() / "misc/nclt_2012-01-15_1326652795280148_hdl32e.bin"
    p = tmp_path / "scan_hdl32.bin"
    shutil.copy(src, p)
    assert os.path.getsize(p) % 16 == 0  # also a whole number of KITTI records: the trap
    assert sd.detect_format(p) == "nclt"
    c = sd.read_cloud(p)
    assert c.fields == ("x", "y", "z", "intensity", "laser_id")
    raw = np.frombuffer(src.read_bytes(), dtype="<u2").reshape(-1, 4)
    assert np.allclose(c.points[:, :3], raw[:, :3] * 0.005 - 100.0, atol=1e-5)
    assert float(np.abs(c.points[:, :3]).max()) < 100.0
    ds = sd.open_dataset(p)
    assert ds.reader == "nclt" and len(ds) == 1 and ds.path == p


def test_kitti_scan_in_a_livox_folder_is_read_as_kitti(tmp_path: Path) -> None:
    pts = np.fromfile(data_dir() / "kitti00/velodyne/000000.bin", dtype="<f4").reshape(-1, 4)[: 19 * 3000]
    folder = tmp_path / "livox_scans"
    folder.mkdir()
    for i in range(3):
        (folder / f"{i:06d}.bin").write_bytes(pts[i * 1000 :].tobytes())
    p = folder / "000000.bin"
    assert os.path.getsize(p) % 19 == 0  # also a whole number of Avia records: the trap
    assert sd.detect_format(p) == "kitti"
    assert np.array_equal(sd.read_points(p), pts)
    ds = sd.open_dataset(folder)
    assert ds.reader == "kitti" and len(ds) == 3 and ds.frame_ids.tolist() == [0, 1, 2]
    assert np.array_equal(ds[1], pts[1000:, :3])


def test_every_shared_bin_is_sniffed_right() -> None:
    d = data_dir()
    want = {"kitti00/velodyne": "kitti", "solid-samples/kitti_00_60": "kitti", "solid-samples/helipr_aeva": "helipr-aeva", "solid-samples/helipr_avia": "helipr-avia"}
    for folder, name in want.items():
        for p in sorted((d / folder).glob("*.bin")):
            assert sd.detect_format(p) == name, p
    assert sd.detect_format(d / "misc/nclt_2012-01-15_1326652795280148_hdl32e.bin") == "nclt"


def test_sizes_that_contradict_the_format_name_both(tmp_path: Path) -> None:
    avia = data_dir() / "solid-samples/helipr_avia/000001.bin"  # 233,320 B
    with pytest.raises(sd.ReadError, match=r"000001\.bin: size 233320 B is not a multiple of 16 B, the KITTI record"):
        sd.read_points(avia, format="kitti")
    with pytest.raises(sd.ReadError, match=r"size 233320 B is not a multiple of the 26 B HeLiPR Ouster"):
        sd.read_points(avia, format="helipr-ouster")
    odd = tmp_path / "odd.bin"
    odd.write_bytes(bytes(23))
    with pytest.raises(sd.ReadError, match=r"odd\.bin: size 23 B is not a whole number of records of any \.bin layout"):
        sd.read_points(odd)
    noise = tmp_path / "noise.bin"
    noise.write_bytes(np.random.default_rng(1).integers(0, 256, 16 * 19 * 40, dtype=np.uint8).tobytes())
    with pytest.raises(sd.ReadError, match=r"noise\.bin: size 12160 B fits kitti \(16 B\): \d+% plausible.*no layout decodes"):
        sd.read_points(noise)
    # a forced format still reads what it is told to
    assert sd.read_points(noise, format="kitti").shape == (760, 4)


def test_name_times_and_folder_of_nclt_scans(tmp_path: Path) -> None:
    src = data_dir() / "misc/nclt_2012-01-15_1326652795280148_hdl32e.bin"
    folder = tmp_path / "velodyne_sync"
    folder.mkdir()
    for utime in (1326652795280148, 1326652795380150):
        shutil.copy(src, folder / f"{utime}.bin")
    ds = sd.open_dataset(folder)
    assert ds.reader == "nclt"
    assert ds.timestamps is not None and np.allclose(ds.timestamps, [1326652795.280148, 1326652795.380150], rtol=0, atol=1e-6)
    assert ds.name(1) == "1326652795380150.bin"


# --------------------------------------------------------------------------------------------
# poses, timestamps and calibration


def _kitti_sequence(tmp_path: Path, frames: range) -> tuple[Path, npt.NDArray[np.float64]]:
    """dataset/sequences/00 with velodyne/<frames>.bin (tiny scans), times.txt, calib.txt, and poses/00.txt."""
    d = data_dir() / "kitti00"
    seq = tmp_path / "dataset" / "sequences" / "00"
    (seq / "velodyne").mkdir(parents=True)
    pts = np.fromfile(d / "velodyne/000000.bin", dtype="<f4").reshape(-1, 4)
    for f in frames:
        (seq / "velodyne" / f"{f:06d}.bin").write_bytes(pts[f : f + 50].tobytes())
    lines = (d / "poses_00.txt").read_text().splitlines()[:300]
    (tmp_path / "dataset" / "poses").mkdir()
    (tmp_path / "dataset" / "poses" / "00.txt").write_text("\n".join(lines) + "\n")
    (seq / "times.txt").write_text("".join(f"{0.1 * k:.6e}\n" for k in range(300)))
    (seq / "calib.txt").write_text("P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: " + KITTI_00_TR + "\n")
    cam = np.array([[float(v) for v in ln.split()] for ln in lines]).reshape(-1, 3, 4)
    return seq, cam


def test_kitti_sequence_subset_uses_frame_numbers(tmp_path: Path) -> None:
    seq, cam = _kitti_sequence(tmp_path, range(100, 200))
    ds = sd.open_dataset(seq)
    assert ds.reader == "kitti" and len(ds) == 100
    assert ds.frame_ids.tolist() == list(range(100, 200))
    assert ds.pose_source == tmp_path / "dataset" / "poses" / "00.txt"
    assert ds.calib_source == seq / "calib.txt" and ds.timestamp_source == seq / "times.txt"
    assert ds.timestamps is not None and np.allclose(ds.timestamps, 0.1 * np.arange(100, 200))
    # the Velodyne poses, in the Velodyne frame of the poses' origin: relative poses as sensor_poses gives
    Tr = sio.load_extrinsic(seq / "calib.txt")
    lidar = sio.sensor_poses(cam[100:200], Tr)
    assert ds.poses is not None and ds.poses.shape == (100, 3, 4)
    rel_ds = np.linalg.inv(np.vstack([ds.poses[0], [0, 0, 0, 1]])) @ np.vstack([ds.poses[50], [0, 0, 0, 1]])
    rel_io = np.linalg.inv(np.vstack([lidar[0], [0, 0, 0, 1]])) @ np.vstack([lidar[50], [0, 0, 0, 1]])
    assert np.allclose(rel_ds, rel_io, atol=1e-9)
    # explicit poses take the calibration only when it is given
    gt = tmp_path / "dataset" / "poses" / "00.txt"
    explicit = sd.open_dataset(seq, poses=gt, calib="calib.txt")
    assert explicit.poses is not None and np.array_equal(explicit.poses, ds.poses)
    raw = sd.open_dataset(seq, poses=gt)
    assert raw.calib_source is None and raw.poses is not None and np.array_equal(raw.poses, cam[100:200])
    # z is up: KITTI drives in the x-y plane of the Velodyne frame
    assert abs(ds.poses[-1, 2, 3] - ds.poses[0, 2, 3]) < 2.0 < np.linalg.norm(ds.poses[-1, :2, 3] - ds.poses[0, :2, 3])


def test_kitti_subset_with_the_full_poses_file() -> None:
    d = data_dir() / "kitti00"
    ds = sd.open_dataset(d, poses="poses_00.txt", timestamps="times_00.txt")
    full, _ = sio.load_poses(d / "poses_00.txt")
    assert ds.frame_ids.tolist() == [0, 94, 95, 198, 199]
    assert ds.poses is not None and np.array_equal(ds.poses, full[[0, 94, 95, 198, 199]])
    assert ds.timestamps is not None and ds.timestamps[1] == pytest.approx(9.746, abs=0.01)


def test_poses_that_do_not_fit_are_errors(tmp_path: Path) -> None:
    seq, _ = _kitti_sequence(tmp_path, range(3))
    short = tmp_path / "short.txt"
    short.write_text("1 0 0 0 0 1 0 0 0 0 1 0\n" * 2)
    with pytest.raises(sd.ReadError, match=r"short\.txt: 2 poses for 3 scans"):
        sd.open_dataset(seq, poses=short)
    (seq / "velodyne" / "000400.bin").write_bytes(bytes(16))
    with pytest.raises(sd.ReadError, match=r"times\.txt: 300 timestamps for 4 scans, and scan frame number 400 has no row"):
        sd.open_dataset(seq)


def _tum_rows(t: npt.NDArray[np.float64], P: npt.NDArray[np.float64]) -> str:
    q = matrix_to_quat(P[:, :, :3])
    rows = np.column_stack([t, P[:, :, 3], q])
    return "".join(" ".join(repr(float(v)) for v in r) + "\n" for r in rows)


def test_tum_poses_at_ten_times_the_scan_rate(tmp_path: Path) -> None:
    d = data_dir() / "hku1-avia"
    P, _ = sio.load_poses(d / "odom_poses.txt")
    t = sio.load_timestamps(d / "times.txt")
    # 10 poses per scan interval: the keyframe poses, and in between positions on the segment
    # and the earlier keyframe's rotation (what a 10x odometry stream looks like to the reader)
    ts, Ps = [], []
    for k in range(len(t) - 1):
        for j in range(10):
            s = j / 10
            ts.append(t[k] + s * (t[k + 1] - t[k]))
            p = P[k].copy()
            p[:, 3] = (1 - s) * P[k, :, 3] + s * P[k + 1, :, 3]
            Ps.append(p)
    ts.append(t[-1])
    Ps.append(P[-1])
    tum = tmp_path / "tum.txt"
    tum.write_text(_tum_rows(np.array(ts), np.array(Ps)))
    ds = sd.open_dataset(d, poses=tum, timestamps="times.txt")
    assert len(ds) == 314 and ds.poses is not None
    assert np.allclose(ds.poses[:, :, 3], P[:, :, 3], atol=1e-6)
    assert np.allclose(ds.poses[:, :, :3], P[:, :, :3], atol=1e-6)
    # the times.txt beside Scans/ are the scans' timestamps when none are given (issue 26) ...
    auto = sd.open_dataset(d, poses=tum)
    assert auto.timestamp_source == (d / "times.txt").absolute() and auto.poses is not None
    assert np.allclose(auto.poses, ds.poses)
    # ... and a TUM file for scans without timestamps cannot be matched
    with pytest.raises(sd.ReadError, match=r"3131 TUM poses for 314 scans.*pass timestamps="):
        sd.open_dataset(d / "Scans", poses=tum)


def test_tum_interpolation_and_range(tmp_path: Path) -> None:
    seq = tmp_path / "seq"
    seq.mkdir()
    for k in range(5):
        sio.write_pcd(seq / f"{k}.pcd", np.full((4, 3), k, np.float32))
    (seq / "times.txt").write_text("1.0\n2.0\n3.0\n4.0\n5.05\n")
    tp = np.arange(0.95, 5.1, 0.1)
    yaw = np.radians(10.0 * tp)
    P = np.zeros((tp.size, 3, 4))
    P[:, :, :3] = quat_to_matrix(np.stack([0 * yaw, 0 * yaw, np.sin(yaw / 2), np.cos(yaw / 2)], axis=1))
    P[:, 0, 3] = tp
    (seq / "poses.txt").write_text(_tum_rows(tp, P))
    ds = sd.open_dataset(seq, poses="poses.txt", timestamps="times.txt")
    assert ds.poses is not None and ds.timestamps is not None
    assert np.allclose(ds.poses[:, 0, 3], ds.timestamps, atol=1e-9)
    assert np.allclose(transforms.yaw_degrees(ds.poses[:, :, :3]), 10.0 * ds.timestamps, atol=1e-6)
    (seq / "late.txt").write_text("1.0\n2.0\n3.0\n4.0\n5.2\n")
    with pytest.raises(sd.ReadError, match=r"poses\.txt: 1 of 5 scans lie outside the pose times \[0\.950000, 5\.050000\] s"):
        sd.open_dataset(seq, poses="poses.txt", timestamps="late.txt")


def test_relative_pose_file_in_cwd_and_sequence(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    seq = tmp_path / "seq"
    seq.mkdir()
    for k in range(3):
        sio.write_pcd(seq / f"{k}.pcd", np.full((4, 3), k, np.float32))
    eye = "1 0 0 {} 0 1 0 0 0 0 1 0\n"
    (seq / "odom_poses.txt").write_text("".join(eye.format(k) for k in range(3)))
    cwd = tmp_path / "work"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    ds = sd.open_dataset(seq, poses="odom_poses.txt")  # only in the sequence folder
    assert ds.pose_source == seq / "odom_poses.txt" and ds.pose_source.is_absolute()
    (cwd / "odom_poses.txt").write_text("".join(eye.format(10 * k) for k in range(3)))
    with pytest.raises(sd.ReadError, match=r"two different poses files.*work/odom_poses\.txt \(current directory\).*seq/odom_poses\.txt \(sequence folder\)"):
        sd.open_dataset(seq, poses="odom_poses.txt")
    shutil.copy(seq / "odom_poses.txt", cwd / "odom_poses.txt")
    assert sd.open_dataset(seq, poses="odom_poses.txt").pose_source == seq / "odom_poses.txt"
    (seq / "odom_poses.txt").unlink()
    (cwd / "odom_poses.txt").write_text("".join(eye.format(10 * k) for k in range(3)))
    ds = sd.open_dataset(seq, poses="odom_poses.txt")  # only in the current directory
    assert ds.pose_source == cwd / "odom_poses.txt" and ds.poses is not None and ds.poses[2, 0, 3] == 20
    with pytest.raises(FileNotFoundError, match="nope.txt"):
        sd.open_dataset(seq, timestamps="nope.txt")


# --------------------------------------------------------------------------------------------
# Livox CustomMsg in bags


def _livox_message(ts: Any, msgtype: str, pts: npt.NDArray[np.float32], sec: int) -> Any:
    pkg = msgtype.split("/")[0]
    types = ts.types
    point = types[f"{pkg}/msg/CustomPoint"]
    hdr_t = types["std_msgs/msg/Header"]
    stamp = types["builtin_interfaces/msg/Time"](sec=sec, nanosec=0)
    hdr = hdr_t(seq=sec, stamp=stamp, frame_id="livox") if "seq" in hdr_t.__dataclass_fields__ else hdr_t(stamp=stamp, frame_id="livox")
    plist = [point(offset_time=100 * i, x=float(p[0]), y=float(p[1]), z=float(p[2]), reflectivity=i % 256, tag=16, line=i % 6) for i, p in enumerate(pts)]
    return types[msgtype](header=hdr, timebase=sec * 10**9, point_num=len(plist), lidar_id=0, rsvd=np.zeros(3, np.uint8), points=plist)


def test_livox_custom_msg_bags(tmp_path: Path) -> None:
    pytest.importorskip("rosbags", reason="rosbags is an optional extra: pip install solid-lidar[ros]")
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    from solid.datasets.rosbag import livox_types

    rng = np.random.default_rng(5)
    clouds = [rng.normal(0, 10, (30 + 7 * i, 3)).astype(np.float32) for i in range(3)]
    bags: list[tuple[Path, str]] = []
    for pkg in ("livox_ros_driver", "livox_ros_driver2"):
        msgtype = f"{pkg}/msg/CustomMsg"
        ts1 = get_typestore(Stores.ROS1_NOETIC)
        ts1.register(livox_types())
        bag1 = tmp_path / f"{pkg}.bag"
        with Writer1(bag1) as w1:
            c1 = w1.add_connection("/livox/lidar", msgtype, typestore=ts1)
            for i, p in enumerate(clouds):
                w1.write(c1, (i + 1) * 10**9, ts1.serialize_ros1(_livox_message(ts1, msgtype, p, i + 1), msgtype))
        bags.append((bag1, msgtype))
        ts2 = get_typestore(Stores.ROS2_HUMBLE)
        ts2.register(livox_types())
        for plugin in (StoragePlugin.SQLITE3, StoragePlugin.MCAP):
            bag2 = tmp_path / f"{pkg}_ros2_{plugin.name.lower()}"
            with Writer2(bag2, version=9, storage_plugin=plugin) as w2:
                c2 = w2.add_connection("/livox/lidar", msgtype, typestore=ts2)
                for i, p in enumerate(clouds):
                    w2.write(c2, (i + 1) * 10**9, ts2.serialize_cdr(_livox_message(ts2, msgtype, p, i + 1), msgtype))
            bags.append((bag2, msgtype))
    for bag, msgtype in bags:
        ds = sd.open_dataset(bag)
        assert ds.reader == "rosbag:livox" and ds.topic == "/livox/lidar" and len(ds) == 3, bag
        assert ds.timestamps is not None and np.array_equal(ds.timestamps, [1.0, 2.0, 3.0])
        assert ds.frame_ids.tolist() == [0, 1, 2] and ds.name(2) == f"/livox/lidar@{3 * 10**9}"
        for got, want in zip(ds, clouds):
            assert got.dtype == np.float32 and got.flags.c_contiguous and np.array_equal(got, want)
        full = sd.open_dataset(bag, xyz_only=False, format="rosbag:livox")[1]
        assert full.shape == (37, 7)
        assert np.array_equal(full[:, 5], np.arange(37) % 6) and np.array_equal(full[:, 6], 100 * np.arange(37))
        with pytest.raises(sd.ReadError, match="holds .*CustomMsg, not what rosbag:pointcloud2 reads|no .*PointCloud2 messages"):
            sd.open_dataset(bag, format="rosbag:pointcloud2")


# --------------------------------------------------------------------------------------------
# the error contract and silently wrong data (issue 10, items 4 and 5)


def test_ply_negative_vertex_count_is_refused(tmp_path: Path) -> None:
    head = (
        "ply\nformat binary_little_endian 1.0\nelement vertex -1\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
    )
    p = tmp_path / "neg.ply"
    p.write_bytes(head.encode() + bytes([3]) + struct.pack("<3i", 0, 1, 2) + bytes(160))
    with pytest.raises(sd.ReadError, match=r"neg\.ply: PLY element 'vertex' has a negative count -1"):
        sd.read_points(p)


def test_ply_comment_holding_end_header(tmp_path: Path) -> None:
    pts = np.arange(12, dtype=np.float32).reshape(4, 3)
    head = (
        "ply\nformat binary_little_endian 1.0\ncomment the header stops at end_header, not here\n"
        "element vertex 4\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    )
    p = tmp_path / "comment.ply"
    p.write_bytes(head.encode() + pts.tobytes())
    assert np.array_equal(sd.read_points(p), pts)


def test_pcd_duplicate_field_names_keep_their_columns(tmp_path: Path) -> None:
    rec = np.array([(1.0, 2.0, 3.0, 100.0, 200.0, 300.0)], dtype=[(n, "<f4") for n in ("x", "y", "z", "a", "b", "c")])
    head = "VERSION 0.7\nFIELDS x y z t_1 t t\nSIZE 4 4 4 4 4 4\nTYPE F F F F F F\nCOUNT 1 1 1 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary\n"
    p = tmp_path / "dup.pcd"
    p.write_bytes(head.encode() + rec.tobytes())
    c = sd.read_cloud(p)
    assert c.fields == ("x", "y", "z", "t_1", "t", "t_2")
    assert dict(zip(c.fields, c.points[0].tolist())) == {"x": 1, "y": 2, "z": 3, "t_1": 100, "t": 200, "t_2": 300}


def test_structured_npy_with_complex_x_is_refused(tmp_path: Path) -> None:
    rec = np.zeros(3, dtype=[("x", "c8"), ("y", "f4"), ("z", "f4")])
    rec["x"] = [1 + 2j, 3 + 4j, 5 + 6j]
    np.save(tmp_path / "cx.npy", rec)
    with pytest.raises(sd.ReadError, match=r"cx\.npy: field 'x' has dtype complex64, expected real numbers"):
        sd.read_points(tmp_path / "cx.npy")
    np.save(tmp_path / "c2.npy", np.zeros((3, 3), np.complex128))
    with pytest.raises(sd.ReadError, match=r"c2\.npy: field 'points' has dtype complex128"):
        sd.read_points(tmp_path / "c2.npy")


def test_npy_and_npz_damage_is_a_read_error(tmp_path: Path) -> None:
    good = tmp_path / "good.npy"
    np.save(good, np.arange(30, dtype=np.float32).reshape(10, 3))
    raw = good.read_bytes()
    cases = {
        "huge.npy": raw.replace(b"(10, 3)", b"(9999999999, 3)"),
        "trunc.npy": raw[:-7],
        "badhdr.npy": raw.replace(b"'descr'", b"'descr\x00"),
        "notdict.npy": raw.replace(b"{'descr'", b"['descr'"),
        "object.npy": raw.replace(b"'<f4'", b"'|O8'"),
    }
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
        with pytest.raises(sd.ReadError, match=name.replace(".", r"\.")):
            sd.read_points(tmp_path / name)
    with pytest.raises(sd.ReadError, match=r"declares shape \(9999999999, 3\)"):
        sd.read_points(tmp_path / "huge.npy")
    z = tmp_path / "z.npz"
    np.savez_compressed(z, points=np.arange(300, dtype=np.float32).reshape(100, 3))
    zraw = bytearray(z.read_bytes())
    for k in range(0, len(zraw), 7):
        bad = bytearray(zraw)
        bad[k] ^= 0xFF
        (tmp_path / "bad.npz").write_bytes(bytes(bad))
        try:
            got = sd.read_points(tmp_path / "bad.npz")
        except sd.ReadError as e:
            assert "bad.npz" in str(e)
        else:
            assert got.shape[1] == 3


def test_lzf_bombs_are_refused(tmp_path: Path) -> None:
    # a 100-byte stream that declares 3.6 GB: impossible for LZF, refused before allocating
    npts = 300_000_000
    head = f"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {npts}\nHEIGHT 1\nPOINTS {npts}\nDATA binary_compressed\n"
    stream = bytes([0, 0]) + bytes([0xE0, 255, 0]) * 33
    p = tmp_path / "declares.pcd"
    p.write_bytes(head.encode() + struct.pack("<II", len(stream), 12 * npts) + stream)
    with pytest.raises(sd.ReadError, match=r"declares\.pcd: corrupt PCD binary_compressed data: LZF data of 101 B cannot decompress to 3600000000 B"):
        sd.read_points(p)
    # a stream that expands far beyond what the header declares (2.6 MB into 1,200 B) stops at the bound
    stream = bytes([0, 0]) + bytes([0xE0, 255, 0]) * 10_000
    head = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 100\nHEIGHT 1\nPOINTS 100\nDATA binary_compressed\n"
    p = tmp_path / "expands.pcd"
    p.write_bytes(head.encode() + struct.pack("<II", len(stream), 1200) + stream)
    with pytest.raises(sd.ReadError, match=r"expands\.pcd: corrupt PCD binary_compressed data: LZF data expands beyond the declared 1200 B"):
        sd.read_points(p)


def test_special_files_are_refused(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe.pcd"
    os.mkfifo(fifo)
    with pytest.raises(sd.ReadError, match=r"pipe\.pcd: is not a regular file"):
        sd.read_points(fifo)
    with pytest.raises(sd.ReadError, match="is a folder"):
        sd.read_points(tmp_path, format="pcd")


def test_mutated_bags_raise_read_errors(tmp_path: Path) -> None:
    pytest.importorskip("rosbags", reason="rosbags is an optional extra: pip install solid-lidar[ros]")
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.typesys import Stores, get_typestore

    from solid.datasets.rosbag import livox_types

    ts = get_typestore(Stores.ROS1_NOETIC)
    ts.register(livox_types())
    msgtype = "livox_ros_driver/msg/CustomMsg"
    bag = tmp_path / "good.bag"
    with Writer1(bag) as w:
        c = w.add_connection("/livox/lidar", msgtype, typestore=ts)
        for i in range(3):
            w.write(c, (i + 1) * 10**9, ts.serialize_ros1(_livox_message(ts, msgtype, np.ones((5, 3), np.float32) * i, i + 1), msgtype))
    raw = bag.read_bytes()
    rng = np.random.default_rng(11)
    outcomes = {"ok": 0, "ReadError": 0}
    for trial in range(60):
        bad = bytearray(raw)
        if trial % 3 == 0:
            bad = bad[: int(rng.integers(13, len(raw)))]
        else:
            for k in rng.integers(0, len(raw), 1 + trial % 4):
                bad[int(k)] = int(rng.integers(0, 256))
        p = tmp_path / f"m{trial}.bag"
        p.write_bytes(bytes(bad))
        try:
            ds = sd.open_dataset(p)
            for _ in ds:
                pass
            outcomes["ok"] += 1
        except sd.ReadError as e:
            assert f"m{trial}.bag" in str(e)
            outcomes["ReadError"] += 1
    assert outcomes["ReadError"] > 0


def test_a_bag_is_not_one_scan(tmp_path: Path) -> None:
    bag = tmp_path / "x.bag"
    bag.write_bytes(b"#ROSBAG V2.0\n")
    with pytest.raises(sd.ReadError, match="a bag holds many scans"):
        sd.read_points(bag)


def test_helipr_names_are_nanosecond_times(tmp_path: Path) -> None:
    src = data_dir() / "solid-samples/helipr_avia/000010.bin"
    folder = tmp_path / "Avia"
    folder.mkdir()
    stamps = [1692248305025943817, 1692248305125943817]
    for s in stamps:
        shutil.copy(src, folder / f"{s}.bin")
    ds = sd.open_dataset(folder)
    assert ds.reader == "helipr-avia" and ds.frame_ids.tolist() == stamps
    assert ds.timestamps is not None and np.allclose(ds.timestamps, [s * 1e-9 for s in stamps], rtol=0, atol=1e-6)
    assert ds[0].shape == (os.path.getsize(src) // 19, 3)


def test_poses_from_a_bags_odometry_topic(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 40: `--poses /odom` takes the poses of a nav_msgs/Odometry topic of the bag, at the
    scans' times (interpolated between the odometry's messages), so a bag alone is enough."""
    pytest.importorskip("rosbags", reason="rosbags is an optional extra: pip install solid-lidar[ros]")
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    from solid.datasets.poses import matrix_to_quat
    from solid.datasets.rosbag import cloud_to_pointcloud2

    rng = np.random.default_rng(3)
    clouds = [rng.uniform(-30, 30, (400, 3)).astype(np.float32) for _ in range(4)]
    # Odometry at 4 Hz along x at 2 m/s, turning 10° a second; scans at 1 Hz, 0.1 s after a message.
    t_odo = np.arange(0, 5.01, 0.25)
    yaw = np.radians(10.0) * t_odo
    P = np.zeros((len(t_odo), 3, 4))
    P[:, 0, 0], P[:, 0, 1], P[:, 1, 0], P[:, 1, 1], P[:, 2, 2] = np.cos(yaw), -np.sin(yaw), np.sin(yaw), np.cos(yaw), 1.0
    P[:, 0, 3] = 2.0 * t_odo
    q = matrix_to_quat(P[:, :, :3])
    t_scan = np.array([1.1, 2.1, 3.1, 4.1])

    def odometry(ts: Any, k: int) -> Any:
        T = ts.types
        hdr_t = T["std_msgs/msg/Header"]
        sec = int(t_odo[k])
        stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((t_odo[k] - sec) * 1e9)))
        hdr = hdr_t(seq=k, stamp=stamp, frame_id="odom") if "seq" in hdr_t.__dataclass_fields__ else hdr_t(stamp=stamp, frame_id="odom")
        pose = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=P[k, 0, 3], y=P[k, 1, 3], z=P[k, 2, 3]),
            orientation=T["geometry_msgs/msg/Quaternion"](x=q[k, 0], y=q[k, 1], z=q[k, 2], w=q[k, 3]),
        )
        twist = T["geometry_msgs/msg/Twist"](linear=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0), angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0))
        return T["nav_msgs/msg/Odometry"](
            header=hdr,
            child_frame_id="base",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)),
        )

    def points(ts: Any, k: int) -> Any:
        rec = np.zeros(len(clouds[k]), dtype={"names": ["x", "y", "z"], "formats": ["<f4"] * 3})
        rec["x"], rec["y"], rec["z"] = clouds[k].T
        return cloud_to_pointcloud2(ts, rec, int(t_scan[k]), "lidar")

    pc2, odo = "sensor_msgs/msg/PointCloud2", "nav_msgs/msg/Odometry"
    ts1, ts2 = get_typestore(Stores.ROS1_NOETIC), get_typestore(Stores.ROS2_HUMBLE)
    with Writer1(tmp_path / "run.bag") as w1:
        cp, co = w1.add_connection("/points", pc2, typestore=ts1), w1.add_connection("/odom", odo, typestore=ts1)
        for k in range(len(t_odo)):
            w1.write(co, int(round(t_odo[k] * 1e9)), ts1.serialize_ros1(odometry(ts1, k), odo))
        for k in range(len(t_scan)):
            w1.write(cp, int(round(t_scan[k] * 1e9)), ts1.serialize_ros1(points(ts1, k), pc2))
    with Writer2(tmp_path / "run_ros2", version=9, storage_plugin=StoragePlugin.MCAP) as w2:
        cp, co = w2.add_connection("/points", pc2, typestore=ts2), w2.add_connection("/odom", odo, typestore=ts2)
        for k in range(len(t_odo)):
            w2.write(co, int(round(t_odo[k] * 1e9)), ts2.serialize_cdr(odometry(ts2, k), odo))
        for k in range(len(t_scan)):
            w2.write(cp, int(round(t_scan[k] * 1e9)), ts2.serialize_cdr(points(ts2, k), pc2))
    yaw_s = np.radians(10.0) * t_scan
    for bag in (tmp_path / "run.bag", tmp_path / "run_ros2"):
        ds = sd.open_dataset(bag, poses="/odom")
        assert ds.poses is not None and ds.poses.shape == (4, 3, 4) and str(ds.pose_source) == "/odom"
        assert ds.timestamps is not None
        np.testing.assert_allclose(ds.timestamps, t_scan, atol=1e-9)
        np.testing.assert_allclose(ds.poses[:, 0, 3], 2.0 * t_scan, atol=1e-9)  # between two messages
        np.testing.assert_allclose(np.arctan2(ds.poses[:, 1, 0], ds.poses[:, 0, 0]), yaw_s, atol=1e-9)
        with pytest.raises(sd.ReadError, match=r"'/points' holds sensor_msgs/msg/PointCloud2; its nav_msgs/msg/Odometry topics: /odom"):
            sd.open_dataset(bag, poses="/points")
        with pytest.raises(sd.ReadError, match=r"'/gps' is not in the bag"):
            sd.open_dataset(bag, poses="/gps")
    # The command line: the poses feed the detector's metres window, which it says it applied.
    code, out, err = run(capsys, "detect", str(tmp_path / "run.bag"), "--poses", "/odom", "--preset", "vlp16", "--no-verify", "-o", str(tmp_path / "det"), "-q")
    assert code == 0 and "/ 30 m" in out, (out, err)
    code, out, err = run(capsys, "detect", str(tmp_path / "run.bag"), "--preset", "vlp16", "--no-verify", "-o", str(tmp_path / "det2"), "-q")
    assert code == 0 and "/ 30 m" not in out and "threshold" in out, (out, err)
