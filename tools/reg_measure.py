"""Measure registration and its acceptance gate on real data and the simulator.

Prints the distributions behind the thresholds of ``solid.AcceptanceGate`` (and of the Rust
``solid_lidar::reg::Gate``), the gate's precision and recall, pose errors, and the size of the
compact cloud encoding. Run from the repository root after ``make wheel`` (or ``maturin
develop --release``)::

    .venv/bin/python tools/reg_measure.py            # everything (about a minute or two)
    .venv/bin/python tools/reg_measure.py hku1 wire  # some parts: hku1, sim, wire

hku1: every query of hku1-avia (SPEC §5, exclude 50 keyframes ≈ 10 m) against its top-5 SOLiD
candidates (preset ``avia``). A candidate is *correct* when the registration's pose is within
1 m and 5° of the ground truth (odom_poses.txt), and *near* when the two keyframes are within
3 m / 5 m. Every candidate is registered from the yaws of :func:`yaws_for` (0°, the A-SOLiD
minima, ±25°).

sim: for every simulated sensor, pairs of scans 0–2 m and up to ±20° apart (true pairs) and
pairs from places at least 60 m apart (wrong pairs).

wire: bytes per place of ``PreparedCloud.encode`` on hku1 and KITTI, and how far registering the
decoded clouds moves the pose.

Measured with the defaults (RegistrationConfig(), AcceptanceGate()):

- hku1: 1305 candidates, 462 registered within 1 m / 5° of the truth; the gate accepts 373 of
  them and none of the 843 others (median pose error 4.4 cm / 0.21°, worst 0.75 m). A detector
  keeping each query's best accepted candidate, with ``max_translation`` = radius: at 3 m
  precision 1.000, recall 0.697 (46 loops); at 5 m precision 1.000, recall 0.503. Without the
  translation cap, correct loops between keyframes farther apart than the radius count as false
  by SPEC §5 (precision 0.307 at 3 m).
- simulator: every sensor, 17 true pairs each: 17/17/17/14/16 (hdl64, vlp16, os1-64, avia,
  aeva) registered correctly and all of those accepted, heading error mean 0.001–0.002° (A-SOLiD
  alone: 0.24–8.4°); 0 of 85 wrong pairs accepted.
- wire (voxel 0.5 m, 8 bits): 5.3 kB per hku1 place (4.1 B/point), 34 kB per KITTI scan; the
  decoded cloud moves the pose by a median 1.3 mm.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

import solid
from solid import sim
from solid.io import read_points

F64 = npt.NDArray[np.float64]
DATA = Path(__file__).resolve().parent.parent.parent / "shared" / "data"
#: Extra initial yaws (degrees) tried besides 0° and the A-SOLiD minima: a narrow field of view
#: (Livox Avia) has a single A-SOLiD minimum, so these give the hypotheses something to agree on.
FAN = (-25.0, 25.0)


def yaws_for(dq: solid.Descriptor, dc: solid.Descriptor) -> list[float]:
    """0°, up to two A-SOLiD minima, then the fan, skipping yaws within 6° of one already in."""
    out: list[float] = []
    for y in [*solid.hypothesis_yaws(dq, dc, n=3), *FAN]:
        if all(abs((y - o + 180.0) % 360.0 - 180.0) >= 6.0 for o in out):
            out.append(y)
    return out


def pose_error(a: F64, b: F64) -> tuple[float, float]:
    """Translation (m) and angle (deg) of inv(a) @ b."""
    d = np.linalg.inv(a) @ b
    c = float(np.clip((np.trace(d[:3, :3]) - 1.0) / 2.0, -1.0, 1.0))
    return float(np.linalg.norm(d[:3, 3])), float(np.degrees(np.arccos(c)))


def quantiles(name: str, v: npt.ArrayLike) -> str:
    a = np.asarray(v, dtype=np.float64)
    if a.size == 0:
        return f"  {name:<22} (none)"
    q = np.percentile(a, [5, 25, 50, 75, 95])
    return f"  {name:<22} n={a.size:<5d} p5 {q[0]:8.3f}  p25 {q[1]:8.3f}  p50 {q[2]:8.3f}  p75 {q[3]:8.3f}  p95 {q[4]:8.3f}"


FEATURES = ("fitness", "structure_fitness", "overlap_query", "overlap_candidate", "rmse", "degeneracy_translation", "degeneracy_rotation", "agreement", "converged")


def features(r: solid.Registration, gate: solid.AcceptanceGate) -> dict[str, float]:
    f = {k: float(getattr(r, k)) for k in FEATURES if k not in ("agreement",)}
    f["agreement"] = float(gate.agreement(r))
    return f


def print_distributions(rows: list[dict[str, Any]], label: str, title: str) -> None:
    for cls, keep in ((f"{title}: correct", True), (f"{title}: wrong", False)):
        sel = [r for r in rows if r[label] == keep]
        print(f" {cls} ({len(sel)})")
        for k in FEATURES:
            print(quantiles(k, [r[k] for r in sel]))


def gate_report(rows: list[dict[str, Any]], label: str) -> tuple[int, int]:
    """(accepted correct, accepted wrong) over `rows`."""
    acc = [r for r in rows if r["accepted"]]
    good = sum(1 for r in acc if r[label])
    return good, len(acc) - good


def hku1(cfg: solid.RegistrationConfig, gate: solid.AcceptanceGate) -> None:
    root = DATA / "hku1-avia"
    poses34 = np.loadtxt(root / "odom_poses.txt").reshape(-1, 3, 4)
    n = len(poses34)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :] = poses34
    pos = T[:, :3, 3]
    scans = [np.ascontiguousarray(read_points(root / "Scans" / f"{i:06d}.pcd")[:, :3]) for i in range(n)]
    dcfg = solid.SolidConfig.preset("avia")
    desc = solid.describe_batch(scans, dcfg)
    t0 = time.perf_counter()
    prepared = [solid.PreparedCloud(s, cfg) for s in scans]
    prep_ms = 1e3 * (time.perf_counter() - t0) / n
    R = np.stack([d.r for d in desc]).astype(np.float64)
    R /= np.maximum(np.linalg.norm(R, axis=1, keepdims=True), 1e-12)
    rows: list[dict[str, Any]] = []
    times: list[float] = []
    for q in range(51, n):
        dist = 1.0 - R[: q - 50] @ R[q]
        for c in np.argsort(dist, kind="stable")[:5]:
            c = int(c)
            gt = np.linalg.inv(T[q]) @ T[c]
            t = time.perf_counter()
            r = solid.register(prepared[q], prepared[c], yaws=yaws_for(desc[q], desc[c]), config=cfg)
            times.append(time.perf_counter() - t)
            em, ed = pose_error(r.pose, gt)
            row: dict[str, Any] = {"q": q, "c": c, "rank": len([x for x in rows if x["q"] == q]), "sdist": float(dist[c])}
            row.update(features(r, gate))
            row["gt_m"] = float(np.linalg.norm(pos[q] - pos[c]))
            row["err_m"], row["err_deg"] = em, ed
            row["t_m"] = float(np.linalg.norm(r.pose[:3, 3]))
            row["correct"] = em <= 1.0 and ed <= 5.0
            row["accepted"] = gate.check(r) is None
            row["reason"] = gate.check(r)
            rows.append(row)
    if DUMP:
        import json

        Path(DUMP).write_text(json.dumps(rows))
    print(f"hku1-avia: {n} keyframes, {len(rows)} (query, top-5 candidate) pairs; prepare {prep_ms:.2f} ms/cloud, register (all hypotheses) median {1e3 * np.median(times):.2f} ms, p90 {1e3 * np.percentile(times, 90):.2f} ms per candidate")
    print_distributions(rows, "correct", "pose within 1 m / 5 deg of ground truth")
    good, bad = gate_report(rows, "correct")
    print(f" gate {gate}")
    print(f"  per candidate: accepted {good + bad}, of which pose wrong (> 1 m or > 5 deg): {bad}; correct candidates {sum(r['correct'] for r in rows)}, accepted {good}")
    reasons: dict[str, int] = {}
    for row in rows:
        if row["correct"] and not row["accepted"]:
            reasons[row["reason"]] = reasons.get(row["reason"], 0) + 1
    print(f"  correct candidates rejected by: {reasons}")
    worst = sorted((r for r in rows if r["accepted"]), key=lambda r: -r["err_m"])[:3]
    print("  worst accepted pose errors: " + ", ".join(f"{r['q']}-{r['c']}: {r['err_m']:.2f} m {r['err_deg']:.2f} deg" for r in worst))
    acc_ok = [r for r in rows if r["accepted"] and r["correct"]]
    if acc_ok:
        print(f"  pose error over accepted correct candidates: median {np.median([r['err_m'] for r in acc_ok]):.3f} m {np.median([r['err_deg'] for r in acc_ok]):.3f} deg, max {max(r['err_m'] for r in acc_ok):.3f} m")
    agr2 = [r for r in rows if r["accepted"] and r["agreement"] >= 2]
    print(f"  requiring agreement >= 2 as well would keep {sum(r['correct'] for r in agr2)} correct and {sum(not r['correct'] for r in agr2)} wrong")
    # A verifying detector: per query, the accepted candidate with the highest fitness; with
    # the gate's max_translation left infinite, and set to the radius.
    for radius, capped in ((3.0, False), (5.0, False), (3.0, True), (5.0, True)):
        positives = 0
        tp = fp = 0
        for q in range(51, n):
            gt_pos = bool(np.min(np.linalg.norm(pos[: q - 50] - pos[q], axis=1)) <= radius)
            positives += gt_pos
            acc = [r for r in rows if r["q"] == q and r["accepted"] and (not capped or r["t_m"] <= radius)]
            if not acc:
                continue
            best = max(acc, key=lambda r: r["fitness"])
            if best["gt_m"] <= radius:
                tp += 1
            else:
                fp += 1
        p = tp / (tp + fp) if tp + fp else 1.0
        cap = f", max_translation {radius:.0f} m" if capped else ""
        print(f"  detector (best accepted of top-5{cap}) at {radius:.0f} m: {positives} GT-positive queries, {tp + fp} loops, precision {p:.3f}, recall {tp / positives:.3f}, false accepts (candidate farther than {radius:.0f} m) {fp}")


def sim_pairs(cfg: solid.RegistrationConfig, gate: solid.AcceptanceGate) -> None:
    world = sim.World(seed=11)
    traj = sim.Trajectory.loop(world, laps=1.0, spacing=20.0)
    rng = np.random.default_rng(5)
    print(f"simulator: world seed 11, {len(traj)} places on a loop, per sensor true pairs (0-2 m, up to +-20 deg apart) and wrong pairs (>= 60 m apart)")
    for name in [s for s in sim.SENSORS if not SENSORS or s in SENSORS]:
        sensor = sim.Sensor(name)
        dcfg = solid.SolidConfig.preset(name)
        rows: list[dict[str, Any]] = []
        base = traj.poses
        for k in range(len(base)):
            Tc = np.eye(4)
            Tc[:3] = base[k]
            yaw = float(rng.uniform(-20.0, 20.0))
            d = rng.uniform(-1.0, 1.0, size=2) * np.array([2.0, 1.0])
            dT = np.eye(4)
            cy, sy = np.cos(np.radians(yaw)), np.sin(np.radians(yaw))
            dT[:2, :2] = [[cy, -sy], [sy, cy]]
            dT[:2, 3] = d
            Tq = Tc @ dT
            qs = sim.scan(world, sensor, Tq, frame=2 * k + 1)[:, :3].copy()
            cs = sim.scan(world, sensor, Tc, frame=2 * k)[:, :3].copy()
            dq, dc = solid.describe(qs, dcfg), solid.describe(cs, dcfg)
            r = solid.register(qs, cs, yaws=yaws_for(dq, dc), config=cfg)
            gt = np.linalg.inv(Tq) @ Tc
            em, ed = pose_error(r.pose, gt)
            true_yaw = float(np.degrees(np.arctan2(gt[1, 0], gt[0, 0])))
            herr = abs((r.yaw - true_yaw + 180.0) % 360.0 - 180.0)
            row: dict[str, Any] = {"kind": "true", "herr": herr, "asolid_herr": abs((solid.heading(dq, dc) - true_yaw + 180.0) % 360.0 - 180.0)}
            row.update(features(r, gate))
            row["correct"] = em <= 1.0 and ed <= 5.0
            row["err_m"], row["err_deg"] = em, ed
            row["accepted"] = gate.check(r) is None
            rows.append(row)
            # A wrong pair: the place half a loop away.
            j = (k + len(base) // 2) % len(base)
            Tw = np.eye(4)
            Tw[:3] = base[j]
            ws = sim.scan(world, sensor, Tw, frame=2 * j)[:, :3].copy()
            dw = solid.describe(ws, dcfg)
            r = solid.register(qs, ws, yaws=yaws_for(dq, dw), config=cfg)
            em, ed = pose_error(r.pose, np.linalg.inv(Tq) @ Tw)
            row = {"kind": "wrong"}
            row.update(features(r, gate))
            row["correct"] = em <= 1.0 and ed <= 5.0
            row["accepted"] = gate.check(r) is None
            rows.append(row)
        true = [r for r in rows if r["kind"] == "true"]
        wrong = [r for r in rows if r["kind"] == "wrong"]
        if DUMP:
            import json

            Path(f"{DUMP}.{name}").write_text(json.dumps(rows))
        ok = [r for r in true if r["correct"]]
        print(f" {name}: true pairs {len(true)}, registered correctly {len(ok)}, accepted {sum(r['accepted'] for r in true)} (of which wrong pose {sum(r['accepted'] and not r['correct'] for r in true)}); wrong pairs accepted {sum(r['accepted'] for r in wrong)} of {len(wrong)}")
        if ok:
            print(f"   heading error where registered correctly: mean {np.mean([r['herr'] for r in ok]):.3f} deg, max {max(r['herr'] for r in ok):.3f}; A-SOLiD heading error mean {np.mean([r['asolid_herr'] for r in ok]):.2f} deg; pose error median {np.median([r['err_m'] for r in ok]):.3f} m")
        print(quantiles("fitness (true)", [r["fitness"] for r in true]))
        print(quantiles("fitness (wrong)", [r["fitness"] for r in wrong]))
        print(quantiles("structure fit. (true)", [r["structure_fitness"] for r in true]))
        print(quantiles("structure fit. (wrong)", [r["structure_fitness"] for r in wrong]))
        print(quantiles("rmse (true)", [r["rmse"] for r in true]))
        print(quantiles("rmse (wrong)", [r["rmse"] for r in wrong]))
        print(quantiles("degen. transl. (true)", [r["degeneracy_translation"] for r in true]))
        print(quantiles("degen. transl. (wrong)", [r["degeneracy_translation"] for r in wrong]))


def wire(cfg: solid.RegistrationConfig, gate: solid.AcceptanceGate) -> None:
    root = DATA / "hku1-avia"
    velo = DATA / "kitti00" / "velodyne"
    sets = {
        "hku1-avia": [(root / "Scans" / f"{i:06d}.pcd", root / "Scans" / f"{i + 1:06d}.pcd") for i in range(0, 313, 10)],
        "kitti00": [(velo / "000094.bin", velo / "000095.bin"), (velo / "000198.bin", velo / "000199.bin")],
    }
    for name, pairs in sets.items():
        for bits in (4, 6, 8):
            sizes, n_pts, moved = [], [], []
            for pa, pb in pairs:
                a, b = (solid.PreparedCloud(np.ascontiguousarray(read_points(p)[:, :3]), cfg) for p in (pa, pb))
                data = a.encode(bits=bits)
                sizes.append(len(data))
                n_pts.append(len(a))
                r0 = solid.register(a, b, config=cfg)
                if gate.accepts(r0):
                    r1 = solid.register(solid.PreparedCloud.decode(data, cfg), b, config=cfg)
                    moved.append(pose_error(r0.pose, r1.pose))
            mv = np.array(moved)
            print(f" {name} (voxel {cfg.voxel_size} m, {bits} bits): {np.mean(n_pts):.0f} points/place, {np.mean(sizes):.0f} bytes/place ({np.mean(sizes) / np.mean(n_pts):.2f} B/point); over {len(mv)} consecutive pairs the gate accepts, registering the decoded query moves the pose by median {np.median(mv[:, 0]) * 1000:.2f} mm / {np.median(mv[:, 1]):.4f} deg, max {mv[:, 0].max() * 1000:.2f} mm / {mv[:, 1].max():.4f} deg")


DUMP: str | None = None
SENSORS: list[str] = []


def main(argv: list[str]) -> int:
    global DUMP
    dumps = [a for a in argv if a.startswith("--dump=")]
    DUMP = dumps[0].split("=", 1)[1] if dumps else None
    SENSORS.extend(a.split("=", 1)[1] for a in argv if a.startswith("--sensor="))
    parts = {a for a in argv if not a.startswith("--")} or {"hku1", "sim", "wire"}
    if not DATA.is_dir():
        print(f"shared data not found at {DATA}", file=sys.stderr)
        return 1
    cfg = solid.RegistrationConfig()
    gate = solid.AcceptanceGate()
    print(cfg)
    if "hku1" in parts:
        hku1(cfg, gate)
    if "sim" in parts:
        sim_pairs(cfg, gate)
    if "wire" in parts:
        print("wire form of one place's cloud (PreparedCloud.encode):")
        wire(cfg, gate)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
