"""Seeds of the core's cargo-fuzz targets, made at run time from the shared data (never stored in
the repository).

    python fuzz/python/seed_core.py CORPUS_ROOT

Writes CORPUS_ROOT/<target>/seed-* for db_from_bytes (databases of described shared scans, with
sessions, times and poses), place_decode (their places, float32 and quantised), describe (shared
scans thinned to a few hundred points, in each input layout of the target), score (queries and
candidates over shared ground-truth poses), reg_decode_cloud (the wire form of shared scans) and
register (pairs of thinned shared scans of one place, in each input layout). Without the shared
data it writes small synthetic seeds and says so.
"""

from __future__ import annotations

import os
import struct
import sys
from pathlib import Path

import numpy as np

import solid

REPO = Path(__file__).resolve().parents[2]


def shared_data() -> Path | None:
    """`SOLID_SHARED`/data, else <repo>/../shared/data; None when absent."""
    env = os.environ.get("SOLID_SHARED")
    d = (Path(env) if env else REPO.parent / "shared") / "data"
    return d if d.is_dir() else None


def scans(data: Path | None) -> list[np.ndarray]:
    """A few real scans (x, y, z float32), or synthetic rings without the shared data. The
    second and third are the same place (KITTI 94 and 95)."""
    out = []
    if data is not None:
        for rel in ["kitti00/velodyne/000000.bin", "kitti00/velodyne/000094.bin", "kitti00/velodyne/000095.bin", "solid-samples/kitti_00_60/000000.bin"]:
            p = data / rel
            if p.is_file():
                out.append(np.ascontiguousarray(np.fromfile(p, dtype="<f4").reshape(-1, 4)[:, :3]))
    if not out:
        rng = np.random.default_rng(0)
        az = rng.uniform(0, 2 * np.pi, 5000)
        rho = rng.uniform(3, 60, 5000)
        ring = np.stack([rho * np.cos(az), rho * np.sin(az), rng.uniform(-2, 3, 5000)], 1).astype(np.float32)
        out += [ring, ring, ring + np.float32(0.2)]
    return out


def poses(data: Path | None) -> np.ndarray:
    """Ground-truth poses (N, 12): the HKU walk (it revisits its start), else a circle."""
    if data is not None and (data / "hku1-avia/odom_poses.txt").is_file():
        return np.loadtxt(data / "hku1-avia/odom_poses.txt").reshape(-1, 12)
    t = np.linspace(0, 2 * np.pi, 80)
    p = np.tile(np.eye(3, 4).ravel(), (80, 1))
    p[:, 3], p[:, 7] = 20 * np.cos(t), 20 * np.sin(t)
    return p


def describe_input(points: np.ndarray, preset: int, flags: int, cfg: solid.SolidConfig | None = None) -> bytes:
    """The describe target's layout: preset, flags, [26 bytes of config], points."""
    head = bytes([preset, flags])
    if flags & 4:
        assert cfg is not None
        head += struct.pack("<HHH5f", cfg.n_range, cfg.n_azimuth, cfg.n_elevation, cfg.fov_up, cfg.fov_down, cfg.min_range, cfg.max_range, cfg.voxel_size)
    cols = 4 if flags & 2 else 3
    p = np.zeros((len(points), cols), np.float64)
    p[:, :3] = points
    return head + p.astype("<f8" if flags & 1 else "<f4").tobytes()


def main() -> int:
    root = Path(sys.argv[1])
    data = shared_data()
    if data is None:
        print("seed_core: no shared data found; writing synthetic seeds", file=sys.stderr)
    for t in ("db_from_bytes", "place_decode", "describe", "score", "reg_decode_cloud", "register"):
        (root / t).mkdir(parents=True, exist_ok=True)

    def put(target: str, name: str, b: bytes) -> None:
        (root / target / f"seed-{name}").write_bytes(b)

    clouds = scans(data)
    presets = list(solid.presets())
    cfg = solid.SolidConfig.preset("hdl64")
    descs = [solid.describe(c, cfg) for c in clouds]
    # Databases: empty, one entry, every scan with sessions, times and (every other) poses.
    db = solid.Database(cfg)
    put("db_from_bytes", "empty", db.to_bytes())
    for i, d in enumerate(descs * 2):
        pose: np.ndarray | None = np.hstack([np.eye(3), np.array([[i], [0.0], [0.0]])]) if i % 2 == 0 else None
        db.add(d, session=i % 2, timestamp=0.1 * i if i % 3 else None, pose=pose)
        if i in (0, len(descs) * 2 - 1):
            put("db_from_bytes", f"n{i + 1}", db.to_bytes())
    # The poses of format 3 (ids and matrices), and of format 4 when every place has one.
    put("db_from_bytes", "v3", db.to_bytes(version=3))
    turned = solid.Database(cfg)
    for i, d in enumerate(descs):
        c, s = np.cos(0.3 * i), np.sin(0.3 * i)
        turned.add(d, pose=np.array([[c, -s, 0, i], [s, c, 0, 0], [0, 0, 1, 0.5]]))
    put("db_from_bytes", "posed", turned.to_bytes())
    small = solid.Database(solid.SolidConfig.preset("hdl64", n_range=4, n_azimuth=6))
    small.add(solid.Descriptor(np.arange(4.0), np.arange(6.0), small.config), timestamp=1.0)
    put("db_from_bytes", "tiny", small.to_bytes())
    # Places.
    for i, d in enumerate(descs):
        put("place_decode", f"f32-{i}", solid.encode_place(d))
        put("place_decode", f"u8-{i}", solid.encode_place(d, quantized=True))
    # Scans thinned to ~300 points, in each layout, over every preset.
    for i, c in enumerate(clouds):
        thin = c[:: max(1, len(c) // 300)]
        for flags in (0, 1, 2, 3):
            put("describe", f"scan{i}-flags{flags}", describe_input(thin, i % len(presets), flags))
        put("describe", f"scan{i}-config", describe_input(thin, 0, 4, solid.SolidConfig.preset("vlp16", voxel_size=0.0)))
    put("describe", "empty", describe_input(np.zeros((0, 3)), 2, 0))
    # Scoring: 60 poses of a walk that revisits its start; queries near the end, candidates near
    # the start and random ones.
    P = poses(data)
    P = P[np.linspace(0, len(P) - 1, 60).astype(int)]
    rng = np.random.default_rng(1)
    for k in (1, 3):
        body = struct.pack("<BBBd", len(P), 20, k, 5.0) + P.astype("<f8").tobytes()
        for qi in range(40, 60):
            body += struct.pack("<IIdd", qi, qi - 10, rng.uniform(0, 1), rng.uniform(-180, 180))
            body += struct.pack(f"<{k}I", *rng.integers(0, qi - 10, k))
        put("score", f"walk-k{k}", body)
    # Registration: the wire form of thinned scans, and pairs of one place.
    for i, c in enumerate(clouds):
        thin = np.ascontiguousarray(c[:: max(1, len(c) // 2000)], dtype=np.float64)
        put("reg_decode_cloud", f"scan{i}", solid.encode_cloud(thin))
        put("reg_decode_cloud", f"scan{i}-4bits", solid.encode_cloud(thin, grid=1.0, bits=4))
        put("reg_decode_cloud", f"prepared{i}", solid.PreparedCloud(thin).encode())
    q, c = (x[:: max(1, len(x) // 300)] for x in clouds[1:3])
    yaws = struct.pack("<4f", 0.0, 25.0, -25.0, 90.0)
    init = np.eye(3, 4).astype("<f8").tobytes()
    for flags in (0, 1, 2, 4, 8, 16, 8 | 16):
        head = struct.pack("<BBBfH", flags, 10, 20, 0.5, len(q))
        body = (init if flags & 16 else b"") + (yaws if flags & 8 else b"")
        put("register", f"kitti94-95-flags{flags}", head + body + q.astype("<f4").tobytes() + c.astype("<f4").tobytes())
    return 0


if __name__ == "__main__":
    sys.exit(main())
