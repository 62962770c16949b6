"""How a verified detector should pick a step's loop among the candidates that pass the gate, and
how far a loop may reach (issue 26): runs the verified detector over hku1-avia with a wide gate,
records every verified candidate, then replays the choices offline.

    python tools/loop_choice.py [--max-translation 10]

For each largest loop (3 ... 10 m), each choice of a step's loop (highest fitness, nearest) and
each score (1 - fitness, loop length) it prints F1 max at radius 3 m and 5 m on the pose-aware
truth (docs/spec.md §5), the loops accepted and the pose-false ones. docs/performance.md
#loop-length-score quotes its output.
"""

from __future__ import annotations

import argparse
import collections
from typing import Any

import numpy as np

import solid
from solid import io as sio

SEQ = "../shared/data/hku1-avia"


def candidates(max_translation: float) -> list[dict[str, Any]]:
    """Every verified candidate of the shipped detector over hku1, with its truth."""
    P, _ = sio.load_poses(SEQ + "/odom_poses.txt")
    ds = sio.Dataset(SEQ)
    det = solid.LoopDetector(
        solid.SolidConfig.preset("avia"), detector=solid.DetectorConfig.preset("avia", gate={"max_translation": max_translation})
    )
    dets = det.detect_many([ds[i] for i in range(len(ds))], poses=[P[i] for i in range(len(ds))])
    out = []
    for q, d in enumerate(dets):
        for c in d.candidates:
            if not c.verified or c.pose is None:
                continue
            tq, tc = np.eye(4), np.eye(4)
            tq[:3], tc[:3] = P[q], P[c.id]
            true = np.linalg.inv(tq) @ tc
            r = c.pose[:3, :3].T @ true[:3, :3]
            out.append(
                {
                    "q": q,
                    "accepted": c.accepted,
                    "fitness": c.fitness,
                    "t": float(np.linalg.norm(c.pose[:3, 3])),
                    "true_dist": float(np.linalg.norm(P[q][:, 3] - P[c.id][:, 3])),
                    "e_t": float(np.linalg.norm(c.pose[:3, 3] - true[:3, 3])),
                    "e_r": float(np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))),
                }
            )
    return out


def replay(cands: list[dict[str, Any]], max_t: float, pick: str, score: str, gt: dict[float, int]) -> dict[float, tuple[float, int, int]]:
    steps: dict[int, list[dict[str, Any]]] = collections.defaultdict(list)
    for c in cands:
        steps[c["q"]].append(c)
    loops = []
    for cs in steps.values():
        ok = [c for c in cs if c["accepted"] and c["t"] <= max_t]
        if ok:
            b = max(ok, key=lambda c: c["fitness"]) if pick == "fitness" else min(ok, key=lambda c: c["t"])
            loops.append((1 - b["fitness"] if score == "1-fitness" else b["t"], b))
    loops.sort(key=lambda x: x[0])
    out = {}
    for r, n_gt in gt.items():
        tp, best = 0, 0.0
        for i, (_, b) in enumerate(loops):
            tp += b["true_dist"] <= r and b["e_t"] <= 1 and b["e_r"] <= 5
            p, rc = tp / (i + 1), tp / n_gt
            best = max(best, 2 * p * rc / (p + rc) if p + rc else 0.0)
        pose_false = sum(1 for _, b in loops if b["true_dist"] <= r and not (b["e_t"] <= 1 and b["e_r"] <= 5))
        out[r] = (best, len(loops), pose_false)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--max-translation", type=float, default=10.0)
    args = ap.parse_args()
    cands = candidates(args.max_translation)
    # GT-positive queries (docs/spec.md §5) at the detector's exclusion of 50 frames.
    P, _ = sio.load_poses(SEQ + "/odom_poses.txt")
    t = P[:, :, 3]
    gt = {r: sum(1 for q in range(51, len(t)) if np.linalg.norm(t[: q - 50] - t[q], axis=1).min() <= r) for r in (3.0, 5.0)}
    print("largest loop | step's loop | score | F1 max 3 m | F1 max 5 m | loops | pose-false")
    for max_t in (3.0, 4.0, 5.0, 6.0, 8.0, 10.0):
        if max_t > args.max_translation:
            continue
        for pick, score in (("fitness", "1-fitness"), ("nearest", "length")):
            r = replay(cands, max_t, pick, score, gt)
            print(f"{max_t:g} m | {pick} | {score} | {r[3.0][0]:.3f} | {r[5.0][0]:.3f} | {r[5.0][1]} | {r[3.0][2] + r[5.0][2]}")


if __name__ == "__main__":
    main()
