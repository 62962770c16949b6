"""The verified detector step: CPU time per step of the shipped detector, beside an older build and
small_gicp, in the same run.

    make bench-step                                          # this build alone (and small_gicp)
    .venv/bin/python benches/detector_step.py --baseline DIR # beside an older build installed in DIR
    .venv/bin/python benches/detector_step.py --json benches/results/step.json
    .venv/bin/python benches/detector_step.py --threads --walks hku1-avia/no-poses --steps 120
    .venv/bin/python benches/detector_step.py --walks sim-os1-64 --detector '{"verify_step_points": 120000}'
    .venv/bin/python benches/detector_step.py --walks sim:os1-64:1:2.5,sim:hdl64:1:2.5:no-poses  # other drives

Walks: hku1-avia (314 keyframes, the shared data; skipped with a reason when absent) with its
odometry poses and without poses, and a simulated 360° OS1-64 drive (``sim.World(seed=0)``, 1.6
laps, a frame every 2 m: 257 scans of about 59k points) seen through a drifting odometry (0.01°/m of
yaw, 1 % scale). Each walk runs the shipped defaults of its preset with one verify thread:
``LoopDetector.detect(points, timestamp, pose)`` per scan (describe, prepare the cloud, search,
register, check), timed as the process's CPU time (``time.process_time``: the machine may be
shared). Printed: mean, median, p95 and max per step, the registered candidates per step, the
accepted loops.

``--baseline DIR``: DIR holds another build of the package (``pip install --target DIR
dist/solid_lidar-*.whl`` of an older commit); every walk runs in a child process of each build, one
after the other, and the ratio of the mean steps is printed with whether the two accepted the same
loops. small_gicp (a benchmark-only dependency, requirements-dev.txt) registers the pairs this
build registered, beside ``solid.register``, both single-threaded with the same two levels from the
identity on clouds prepared once per scan: the ratio of their total CPU time.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

HKU = Path(os.environ.get("SOLID_SHARED", Path(__file__).resolve().parent.parent.parent / "shared")) / "data" / "hku1-avia"
WALKS = ("hku1-avia", "hku1-avia/no-poses", "sim-os1-64")


def walk(name: str) -> tuple[str, list[Any], list[float], list[Any]]:
    """(preset, scans, timestamps, poses or None per scan) of a walk: one of WALKS, or a simulated
    drive ``sim:SENSOR:SEED:LAPS[:no-poses]`` (``sim:os1-64:0:1.6`` is ``sim-os1-64``)."""
    import solid
    from solid import sim

    if name.startswith("hku1") and name in WALKS:
        ds = solid.datasets.open_dataset(HKU, poses="odom_poses.txt")
        scans = [np.asarray(ds[i]) for i in range(len(ds))]
        T = [float(t) for t in np.asarray(ds.timestamps)]
        P = [p for p in np.asarray(ds.poses)] if name == "hku1-avia" else [None] * len(scans)
        return "avia", scans, T, P
    parts = ("sim:os1-64:0:1.6" if name == "sim-os1-64" else name).split(":")
    try:
        if parts[0] != "sim" or len(parts) not in (4, 5) or parts[4:] not in ([], ["no-poses"]):
            raise ValueError(name)
        sensor, seed, laps = parts[1], int(parts[2]), float(parts[3])
    except ValueError:
        raise SystemExit(f"unknown walk {name!r}: one of {', '.join(WALKS)}, or sim:SENSOR:SEED:LAPS[:no-poses]") from None
    world = sim.World(seed=seed)
    traj = sim.Trajectory.loop(world, laps=laps, spacing=2.0)
    seq = sim.simulate(world, sim.Sensor(sensor), traj)
    odo = traj.odometry(yaw_bias_deg_per_m=0.01, scale_error=0.01, translation_noise=0.01, rotation_noise_deg=0.02, seed=0)
    poses = [None] * len(seq.scans) if parts[4:] else list(np.asarray(odo.poses))
    return sensor, list(seq.scans), [float(t) for t in seq.times], poses


def child(name: str, overrides: dict[str, Any]) -> None:
    """Runs one walk with the importable build (its preset's detector with `overrides`); prints its
    steps as JSON."""
    import solid
    from solid.config import PipelineConfig

    preset, scans, T, P = walk(name)
    cfg = PipelineConfig.preset(preset, detector={"verify_threads": 1, **overrides})
    det = solid.LoopDetector(cfg.descriptor, detector=cfg.detector)
    cpu: list[float] = []
    registering: list[bool] = []  # whether the step registered a candidate of its own
    pairs: list[tuple[int, int]] = []
    loops: list[tuple[int, int]] = []
    for i, pts in enumerate(scans):
        c = time.process_time()
        d = det.detect(pts, T[i], P[i])
        cpu.append(time.process_time() - c)
        pairs.extend((d.query, x.id) for x in d.candidates if x.verified and x.pose is not None)
        registering.append(any(x.verified for x in d.candidates))
        if d.loop is not None:
            loops.append((d.query, d.loop.candidate))
        # Loops a later step released (held for a placement, or a candidate deferred by its
        # step's budget): each once, the query's.
        loops.extend((int(lp.query), int(lp.candidate)) for lp in getattr(d, "released", ()))
    print(json.dumps({"cpu": cpu, "registering": registering, "pairs": pairs, "loops": sorted(loops), "solid": solid.__file__}))


def threads(name: str, steps: int | None) -> None:
    """`verify_threads` 1, 2, 1, 2 over one walk in one process: CPU (every thread's) and wall
    time per step, with the load average before and after (the machine may be shared)."""
    import solid
    from solid.config import PipelineConfig

    preset, scans, T, P = walk(name)
    n = min(steps or len(scans), len(scans))
    for k in (1, 2, 1, 2):
        cfg = PipelineConfig.preset(preset, detector={"verify_threads": k})
        det = solid.LoopDetector(cfg.descriptor, detector=cfg.detector)
        load = os.getloadavg()[0]
        c, w = time.process_time(), time.perf_counter()
        loops = sum(det.detect(scans[i], T[i], P[i]).loop is not None for i in range(n))
        c, w = time.process_time() - c, time.perf_counter() - w
        print(
            f"  verify_threads {k}: CPU {1e3 * c / n:.1f} ms a step, wall {1e3 * w / n:.1f} ms, {loops} loops "
            f"(load average {load:.1f} -> {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)",
            flush=True,
        )


def run(name: str, path: str | None, overrides: dict[str, Any]) -> dict[str, Any]:
    env = dict(os.environ)
    if path is not None:
        env["PYTHONPATH"] = os.pathsep.join([path, env.get("PYTHONPATH", "")])
    out = subprocess.run([sys.executable, __file__, "--child", name, "--detector", json.dumps(overrides)], env=env, capture_output=True, text=True, check=False, timeout=7200)
    if out.returncode != 0:
        raise SystemExit(f"{name} ({path or 'this build'}) failed:\n{out.stderr[-3000:]}")
    doc: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return doc


def stats(doc: dict[str, Any]) -> dict[str, float]:
    """Per-step figures of a walk; also the steps that registered a candidate of their own (the
    others cost about the descriptor): their share, mean and p95. When a share s of the steps
    register at about one cost each, the p95 of all steps is that cost and the mean s times it,
    so the p95 ÷ mean of all steps is about 1 / s for s above 5 %: a figure of the walk (how
    much of it revisits) as much as of the detector."""
    ms = 1e3 * np.asarray(doc["cpu"])
    reg = np.asarray(doc.get("registering", []), dtype=bool)
    out = {
        "steps": len(ms),
        "mean_ms": float(ms.mean()),
        "median_ms": float(np.median(ms)),
        "p95_ms": float(np.percentile(ms, 95)),
        "max_ms": float(ms.max()),
        "registered_per_step": len(doc["pairs"]) / max(1, len(ms)),
        "loops": len(doc["loops"]),
    }
    if len(reg) == len(ms) and reg.any():
        out["registering_share"] = float(reg.mean())
        out["registering_mean_ms"] = float(ms[reg].mean())
        out["registering_p95_ms"] = float(np.percentile(ms[reg], 95))
    return out


def line(label: str, s: dict[str, float]) -> str:
    out = (
        f"  {label:<10} mean {s['mean_ms']:7.1f}  median {s['median_ms']:7.1f}  p95 {s['p95_ms']:7.1f}  max {s['max_ms']:7.1f} ms"
        f" (p95 {s['p95_ms'] / s['mean_ms']:.2f}x the mean)  ({s['registered_per_step']:.2f} registered per step, {s['loops']:.0f} loops)"
    )
    if "registering_share" in s:
        out += (
            f"\n  {'':<10} the {100 * s['registering_share']:.0f} % of steps that register: mean {s['registering_mean_ms']:.1f}, "
            f"p95 {s['registering_p95_ms']:.1f} ms ({s['registering_p95_ms'] / s['registering_mean_ms']:.2f}x their mean)"
        )
    return out


def peers(name: str, pairs: list[tuple[int, int]]) -> dict[str, float] | None:
    """solid.register and small_gicp on `pairs` (at most 300, evenly spread) of the walk."""
    try:
        import small_gicp
    except ImportError:
        print("  small_gicp is not installed (pip install -r requirements-dev.txt): no peer", file=sys.stderr)
        return None
    import solid

    if not pairs:
        return None
    pairs = [pairs[i] for i in np.linspace(0, len(pairs) - 1, min(300, len(pairs))).astype(int)]
    _, scans, _, _ = walk(name)
    cfg = solid.RegistrationConfig()
    used = sorted({i for p in pairs for i in p})
    ours = {i: solid.PreparedCloud(np.asarray(scans[i])[:, :3].astype(np.float64), cfg) for i in used}
    theirs = {}
    for i in used:
        s = np.ascontiguousarray(np.asarray(scans[i])[:, :3], dtype=np.float64)
        s = s[np.isfinite(s).all(axis=1)]
        theirs[i] = (
            small_gicp.preprocess_points(s, downsampling_resolution=cfg.coarse_voxel_size, num_neighbors=cfg.neighbors, num_threads=1),
            small_gicp.preprocess_points(s, downsampling_resolution=cfg.voxel_size, num_neighbors=cfg.neighbors, num_threads=1),
        )

    def sg(q: int, c: int) -> Any:
        (qc, qt), (qf, qft) = theirs[q]
        (cc, _), (cf, _) = theirs[c]
        r = small_gicp.align(qc, cc, qt, init_T_target_source=np.eye(4), max_correspondence_distance=cfg.coarse_max_correspondence, num_threads=1)
        return small_gicp.align(qf, cf, qft, init_T_target_source=r.T_target_source, max_correspondence_distance=cfg.max_correspondence, num_threads=1)

    t = {"solid": 0.0, "small_gicp": 0.0}
    for q, c in pairs:
        a = time.process_time()
        solid.register(ours[q], ours[c], config=cfg)
        b = time.process_time()
        sg(q, c)
        t["solid"] += b - a
        t["small_gicp"] += time.process_time() - b
    n = len(pairs)
    return {"pairs": n, "solid_ms": 1e3 * t["solid"] / n, "small_gicp_ms": 1e3 * t["small_gicp"] / n}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--baseline", metavar="DIR", help="a directory holding another build of the package (pip install --target DIR <wheel>)")
    ap.add_argument("--walks", default=",".join(WALKS), help="comma-separated walks (default: all)")
    ap.add_argument("--baseline-label", default="an older build", help="what the baseline is, for the JSON (e.g. main @ fcb11b6)")
    ap.add_argument("--threads", action="store_true", help="instead: verify_threads 1, 2, 1, 2 on each walk, CPU and wall time per step")
    ap.add_argument("--steps", type=int, help="with --threads: the first N steps of each walk")
    ap.add_argument("--detector", type=json.loads, default={}, help="detector parameters over the preset's, both builds (JSON, DetectorConfig names)")
    ap.add_argument("--json", type=Path, help="write the figures here (tools/readme_speed.py reads benches/results/step.json)")
    args = ap.parse_args()
    if args.child:
        child(args.child, args.detector)
        return 0
    results: dict[str, Any] = {}
    if args.threads:
        for name in args.walks.split(","):
            print(f"{name}: verify threads", flush=True)
            threads(name, args.steps)
        return 0
    for name in args.walks.split(","):
        if name.startswith("hku1") and not HKU.is_dir():
            if os.environ.get("CI") == "true":
                raise SystemExit(f"{HKU} is missing")
            print(f"{name}: skipped, {HKU} not found (SOLID_SHARED)")
            continue
        given = f" with {json.dumps(args.detector)}" if args.detector else ""
        print(f"{name}: CPU per verified step (LoopDetector.detect, shipped defaults{given}, 1 verify thread)", flush=True)
        now = run(name, None, args.detector)
        row: dict[str, Any] = {"this": stats(now)}
        if args.baseline:
            base = run(name, args.baseline, args.detector)
            row["baseline"] = stats(base)
            row["ratio"] = row["this"]["mean_ms"] / row["baseline"]["mean_ms"]
            row["same_loops"] = base["loops"] == now["loops"]
            print(line("baseline", row["baseline"]))
        print(line("this", row["this"]))
        if args.baseline:
            same = "the same loops" if row["same_loops"] else "DIFFERENT loops"
            print(f"  this / baseline, mean step: {row['ratio']:.2f}x; {same}")
        peer = peers(name, [tuple(p) for p in now["pairs"]])
        if peer:
            row["peers"] = peer
            print(
                f"  one registration of {peer['pairs']} registered pairs, from the identity: solid {peer['solid_ms']:.2f} ms, "
                f"small_gicp {peer['small_gicp_ms']:.2f} ms ({peer['small_gicp_ms'] / peer['solid_ms']:.2f}x solid's)",
                flush=True,
            )
        results[name] = row
    if args.json:
        import solid
        from python_baseline import cpu_model  # benches/, the script's own folder

        doc = {
            "command": "python benches/detector_step.py --baseline DIR --json benches/results/step.json",
            "solid": solid.__version__,
            "cpu": cpu_model(),
            "cores": os.cpu_count(),
            "baseline": args.baseline_label if args.baseline else None,
            "detector": args.detector,
            "walks": results,
        }
        args.json.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
