"""Registration schedules, and the conditioning of the registration's information, measured
(issue 26: a registration that keeps a good start; the Hessian as a gate term).

    .venv/bin/python tools/reg_schedule.py                  # both parts (a few minutes)
    .venv/bin/python tools/reg_schedule.py schedules        # the schedules only
    .venv/bin/python tools/reg_schedule.py information      # the information's distributions

(SOLID_SHARED=/path/to/shared when the shared folder is not beside the repository.)

schedules: on hku1-avia's true revisits (each query of keyframes 260.. with its nearest keyframe
among 0..60 within 5 m) and on simulated true pairs (every preset, 0-2 m and up to 20° apart),
each schedule registers every pair (a) from the poses' relative pose and (b) as the verifying
detector does, from the identity with its yaw hypotheses (0°, the A-SOLiD minima, ±25°). It
counts the registrations that end within 0.5 m / 2° of the true relative pose, and those within
1 m / 5° that the default gate accepts.

information: the gate's information terms (``AcceptanceGate.min_marginal_translation_information``)
on the registrations of hku1's true loops (each query's top-5 SOLiD candidates, registered as the
detector does, that end within 1 m / 5° of the truth between keyframes within 5 m) and on the
simulator's wrong registrations that pass every other threshold of the gate: the look-alike
corridors (places 30 m and more apart, registered with their top-5 look-alikes) and the
turn-in-place room (pairs of views of one standing Avia).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

import solid
from solid import sim
from solid.io import read_points

from reg_measure import pose_error

F64 = npt.NDArray[np.float64]
#: `SOLID_SHARED`/data, else <repo>/../shared/data (as the tests find it).
DATA = Path(os.environ.get("SOLID_SHARED") or Path(__file__).resolve().parent.parent.parent / "shared") / "data"
#: The verifying detector's fan of extra yaws (DetectorConfig.fan_deg) and its yaws per pair.
FAN, HYPOTHESES = 25.0, 4


def yaws_for(dq: solid.Descriptor, dc: solid.Descriptor) -> list[float]:
    """The detector's initial yaws: 0°, the A-SOLiD minima, then ±fan, at most HYPOTHESES, none
    within 6° (one azimuth bin of the avia preset) of another."""
    out: list[float] = []
    for y in [*solid.hypothesis_yaws(dq, dc, n=HYPOTHESES), FAN, -FAN]:
        if len(out) < HYPOTHESES and all(abs((y - o + 180.0) % 360.0 - 180.0) >= 6.0 for o in out):
            out.append(y)
    return out


def to4(p: F64) -> F64:
    out = np.eye(4)
    out[:3] = p[:3]
    return out


def quantiles(name: str, v: list[float]) -> str:
    a = np.asarray(v, dtype=np.float64)
    if a.size == 0:
        return f"  {name:<34} (none)"
    q = np.percentile(a, [0, 5, 25, 50, 75, 95])
    return f"  {name:<34} n={a.size:<5d} min {q[0]:7.3f}  p5 {q[1]:7.3f}  p25 {q[2]:7.3f}  p50 {q[3]:7.3f}  p75 {q[4]:7.3f}  p95 {q[5]:7.3f}"


# --- schedules -------------------------------------------------------------------------------

#: name -> RegistrationConfig overrides.
SCHEDULES: dict[str, dict[str, Any]] = {
    "coarse+fine": {"schedule": "coarse-fine"},
    "fine only": {"coarse_voxel_size": 0.0},
    "coarse keeps a fitting start": {"schedule": "keep-start"},
    "fine from both, lower cost": {"schedule": "both"},
}


def schedule_configs() -> dict[str, solid.RegistrationConfig]:
    return {name: solid.RegistrationConfig(**over) for name, over in SCHEDULES.items()}


def hku1_pairs(wide: bool = False) -> tuple[list[np.ndarray], list[solid.Descriptor], list[tuple[int, int, F64]]]:
    """Each revisiting query with its nearest early keyframe within 5 m; `wide`: every third
    query with every third early keyframe 2-8 m away (starts that overlap less)."""
    root = DATA / "hku1-avia"
    T = np.array([to4(p) for p in np.loadtxt(root / "odom_poses.txt").reshape(-1, 3, 4)])
    scans = [np.ascontiguousarray(read_points(root / "Scans" / f"{i:06d}.pcd")[:, :3]) for i in range(len(T))]
    desc = solid.describe_batch(scans, solid.SolidConfig.preset("avia"))
    pos = T[:, :3, 3]
    pairs: list[tuple[int, int, F64]] = []
    for q in range(260, len(T), 3 if wide else 1):
        d = np.linalg.norm(pos[:61] - pos[q], axis=1)
        near = [c for c in range(0, 61, 3) if 2.0 < d[c] <= 8.0] if wide else [int(np.argmin(d))] if d.min() <= 5.0 else []
        pairs.extend((q, c, np.linalg.inv(T[q]) @ T[c]) for c in near)
    return scans, desc, pairs


def sim_pairs(name: str, count: int = 24, spread: float = 1.0) -> tuple[list[np.ndarray], list[solid.Descriptor], list[tuple[int, int, F64]]]:
    world = sim.World(seed=11)
    traj = sim.Trajectory.loop(world, laps=1.0, spacing=20.0)
    rng = np.random.default_rng(5)
    sensor = sim.Sensor(name)
    dcfg = solid.SolidConfig.preset(name)
    scans: list[np.ndarray] = []
    pairs: list[tuple[int, int, F64]] = []
    for k in range(min(count, len(traj.poses))):
        Tc = to4(traj.poses[k])
        yaw = np.radians(rng.uniform(-20.0, 20.0) * spread)
        dT = np.eye(4)
        dT[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
        dT[:2, 3] = rng.uniform(-1.0, 1.0, size=2) * np.array([2.0, 1.0]) * spread
        Tq = Tc @ dT
        scans.append(sim.scan(world, sensor, Tq, frame=2 * k + 1)[:, :3].astype(np.float64))
        scans.append(sim.scan(world, sensor, Tc, frame=2 * k)[:, :3].astype(np.float64))
        pairs.append((2 * k, 2 * k + 1, np.linalg.inv(Tq) @ Tc))
    return scans, solid.describe_batch(scans, dcfg), pairs


def run_schedules(label: str, scans: list[np.ndarray], desc: list[solid.Descriptor], pairs: list[tuple[int, int, F64]]) -> None:
    gate = solid.AcceptanceGate()
    print(f" {label}: {len(pairs)} true pairs")
    for name, cfg in schedule_configs().items():
        prepared = [solid.PreparedCloud(s, cfg) for s in scans]
        line = []
        for start in ("relative pose", "detector"):
            kept = good = acc = 0
            fit: list[float] = []
            t0 = time.perf_counter()
            for q, c, gt in pairs:
                if start == "relative pose":
                    r = solid.register(prepared[q], prepared[c], gt, config=cfg)
                else:
                    r = solid.register(prepared[q], prepared[c], yaws=yaws_for(desc[q], desc[c]), config=cfg)
                em, ed = pose_error(r.pose, gt)
                kept += em <= 0.5 and ed <= 2.0
                ok = em <= 1.0 and ed <= 5.0
                good += ok
                acc += ok and gate.check(r) is None
                if not (em <= 0.5 and ed <= 2.0):
                    fit.append(r.fitness)
            ms = 1e3 * (time.perf_counter() - t0) / max(len(pairs), 1)
            off = f" (fitness of those off: {min(fit):.2f}-{max(fit):.2f})" if fit else ""
            line.append(f"from the {start}: within 0.5 m / 2° {kept}, within 1 m / 5° {good}, accepted {acc}{off}, {ms:.1f} ms/pair")
        print(f"   {name:<30} " + "; ".join(line), flush=True)


def schedules() -> None:
    print("schedules (true pairs; counts of registrations ending near the true relative pose):")
    run_schedules("hku1-avia revisits (keyframes 260.. with their nearest of 0..60 within 5 m)", *hku1_pairs())
    run_schedules("hku1-avia wider revisits (every 3rd of 260.. with every 3rd of 0..60 2-8 m away)", *hku1_pairs(wide=True))
    for name in sim.SENSORS:
        run_schedules(f"simulator {name} (world seed 11, 0-2 m, up to 20° apart)", *sim_pairs(name))
    for name in ("avia", "os1-64"):
        run_schedules(f"simulator {name}, wider (0-5 m, up to 50° apart)", *sim_pairs(name, spread=2.5))


# --- information -----------------------------------------------------------------------------


INFORMATION_TERMS = ("block min / n (today's term)", "marginal min / n", "block conditioning", "marginal conditioning")


def information_terms(r: solid.Registration) -> dict[str, float]:
    """The translation block's smallest eigenvalue per correspondence (degeneracy_translation),
    the same after marginalising the rotation (degeneracy_marginal_translation, the Schur
    complement of the rotation block), and the conditioning (smallest / largest eigenvalue) of
    each, from the Hessian."""
    h = np.asarray(r.hessian)
    htt = h[3:, 3:]
    block = np.linalg.eigvalsh(htt)
    try:
        schur = np.linalg.eigvalsh(htt - h[3:, :3] @ np.linalg.solve(h[:3, :3], h[:3, 3:]))
    except np.linalg.LinAlgError:
        schur = np.zeros(3)
    return {
        "block min / n (today's term)": float(r.degeneracy_translation),
        "marginal min / n": float(r.degeneracy_marginal_translation),
        "block conditioning": float(block[0] / block[-1]) if block[-1] > 0 else 0.0,
        "marginal conditioning": float(schur[0] / schur[-1]) if schur[-1] > 0 else 0.0,
    }


def passes_others(r: solid.Registration, gate: solid.AcceptanceGate) -> bool:
    """Whether `r` passes every registration threshold of `gate` but the information terms."""
    return bool(r.fitness >= gate.min_fitness and r.structure_fitness >= gate.min_structure_fitness and r.rmse <= gate.max_rmse)


def hku1_true_loops(cfg: solid.RegistrationConfig) -> list[dict[str, float]]:
    root = DATA / "hku1-avia"
    T = np.array([to4(p) for p in np.loadtxt(root / "odom_poses.txt").reshape(-1, 3, 4)])
    scans = [np.ascontiguousarray(read_points(root / "Scans" / f"{i:06d}.pcd")[:, :3]) for i in range(len(T))]
    desc = solid.describe_batch(scans, solid.SolidConfig.preset("avia"))
    prepared = [solid.PreparedCloud(s, cfg) for s in scans]
    R = np.stack([d.r for d in desc]).astype(np.float64)
    R /= np.maximum(np.linalg.norm(R, axis=1, keepdims=True), 1e-12)
    rows = []
    for q in range(51, len(T)):
        for c in np.argsort(1.0 - R[: q - 50] @ R[q], kind="stable")[:5]:
            c = int(c)
            gt = np.linalg.inv(T[q]) @ T[c]
            if np.linalg.norm(gt[:3, 3]) > 5.0:
                continue
            r = solid.register(prepared[q], prepared[c], yaws=yaws_for(desc[q], desc[c]), config=cfg)
            em, ed = pose_error(r.pose, gt)
            if em <= 1.0 and ed <= 5.0 and passes_others(r, solid.AcceptanceGate()):
                rows.append(information_terms(r))
    return rows


def sim_wrong(cfg: solid.RegistrationConfig, world: sim.World, traj: sim.Trajectory, sensor: sim.Sensor, preset: str, far: float, stride: int) -> list[dict[str, float]]:
    """Registrations off by more than 1 m / 5° that pass the gate's other thresholds: every
    `stride`-th frame with its top-5 SOLiD candidates among the frames at least `far` m away
    (the room: every other frame of the stride)."""
    seq = sim.simulate(world, sensor, traj)
    T = np.array([to4(p) for p in seq.poses])
    idx = list(range(0, len(seq), stride))
    scans = [np.ascontiguousarray(seq[i][:, :3].astype(np.float64)) for i in idx]
    desc = solid.describe_batch(scans, solid.SolidConfig.preset(preset))
    prepared = [solid.PreparedCloud(s, cfg) for s in scans]
    R = np.stack([d.r for d in desc]).astype(np.float64)
    R /= np.maximum(np.linalg.norm(R, axis=1, keepdims=True), 1e-12)
    pos = T[idx, :3, 3]
    gate = solid.AcceptanceGate()
    rows = []
    for a in range(len(idx)):
        cands = [b for b in range(len(idx)) if b != a and np.linalg.norm(pos[b] - pos[a]) >= far]
        if far > 0:
            cands = sorted(cands, key=lambda b: -float(R[a] @ R[b]))[:5]
        for b in cands:
            r = solid.register(prepared[a], prepared[b], yaws=yaws_for(desc[a], desc[b]), config=cfg)
            em, ed = pose_error(r.pose, np.linalg.inv(T[idx[a]]) @ T[idx[b]])
            if (em > 1.0 or ed > 5.0) and passes_others(r, gate):
                rows.append(information_terms(r))
    return rows


def information() -> None:
    cfg = solid.RegistrationConfig()
    gate = solid.AcceptanceGate()
    print("information terms (registrations as the detector makes them, default RegistrationConfig):")
    groups: dict[str, list[dict[str, float]]] = {}
    groups["hku1 true loops (within 1 m / 5°, places within 5 m), passing the rest"] = hku1_true_loops(cfg)
    room = sim.World.room(seed=1)
    turn = sim.Trajectory.turn_in_place(room, sweep=330.0, step=2.0, wobble=0.3, seed=1)
    groups["room, avia turning in place: wrong, passing the rest"] = sim_wrong(cfg, room, turn, sim.Sensor("avia"), "avia", 0.0, 6)
    corridors = sim.World.corridors(seed=3, modules=3)
    walk = sim.Trajectory.corridor_walk(corridors, laps=1.3)
    for preset, fov in (("avia", None), ("os1-64", 90.0)):
        view = "own view" if fov is None else f"{fov:g}°"
        groups[f"corridors, {preset} {view}: wrong, passing the rest"] = sim_wrong(cfg, corridors, walk, sim.Sensor(preset, h_fov=fov), preset, 30.0, 4)
    for label, rows in groups.items():
        print(f" {label}: {len(rows)} registrations")
        for k in INFORMATION_TERMS:
            print(quantiles(k, [r[k] for r in rows]))
    today = INFORMATION_TERMS[0]
    print(f" each term's threshold: registrations passing it and today's {today} >= {gate.min_translation_information:g} (per group)")
    print("  " + " | ".join(f"{label.split(':')[0]} ({sum(r[today] >= gate.min_translation_information for r in rows)})" for label, rows in groups.items()))
    for k in INFORMATION_TERMS[1:]:
        true = [r[k] for r in next(iter(groups.values()))]
        ths = sorted({round(float(np.percentile(true, p)), 3) for p in (0, 1, 2, 5, 10)} | set(THRESHOLDS.get(k, ())))
        for th in ths:
            counts = [sum(r[k] >= th and r[today] >= gate.min_translation_information for r in rows) for rows in groups.values()]
            print(f"  {k} >= {th:.3f}: " + " | ".join(str(c) for c in counts))


#: Round thresholds printed besides the true loops' low percentiles.
THRESHOLDS = {"marginal min / n": (0.8, 1.0, 1.2, 1.5), "block conditioning": (0.01, 0.02), "marginal conditioning": (0.02, 0.03)}


def main(argv: list[str]) -> int:
    parts = set(argv) or {"schedules", "information"}
    if not DATA.is_dir():
        print(f"shared data not found at {DATA}", file=sys.stderr)
        return 1
    if "schedules" in parts:
        schedules()
    if "information" in parts:
        information()
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
