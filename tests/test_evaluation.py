"""SPEC §5 metrics on hand-made cases, the numpy heading, and the Scan Context baseline."""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence as AbcSequence
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from conftest import data_dir

import solid
from solid import evaluation as ev
from solid import io as sio
from solid import scancontext as sc



def rz(deg: float) -> npt.NDArray[np.float64]:
    t = math.radians(deg)
    return np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1]])


def poses_from(xs: AbcSequence[float], yaws: AbcSequence[float]) -> npt.NDArray[np.float64]:
    P = np.zeros((len(xs), 3, 4))
    for i, (x, y) in enumerate(zip(xs, yaws)):
        P[i, :, :3] = rz(y)
        P[i, 0, 3] = x
    return P


# --------------------------------------------------------------------------------------------
# the hand-made case (answers worked out in the comments)
#
# frames (x position, yaw):  0:(0, 0)  1:(10, 0)  2:(20, 0)  3:(0.5, 30)  4:(30, 0)
#                            5:(10.2, 0)  6:(100, 0)  7:(20.1, -85) ; frame 2 has yaw 85
# exclude = 2 → queries 3..7; radius 1 m.
#   q3: db {0}       → frame 0 at 0.5 m: GT-positive
#   q4: db {0,1}     → nearest 10 m away: negative
#   q5: db {0,1,2}   → frame 1 at 0.2 m: positive
#   q6: db {0..3}    → negative
#   q7: db {0..4}    → frame 2 at 0.1 m: positive          gt_queries = 3
# ranked candidates given to the scorer:
#   q3: [0, 1]  d 0.10 → correct          q4: [1, 0]  d 0.10 → incorrect (tie with q3)
#   q5: [0, 1]  d 0.30 → incorrect, but frame 1 is 2nd → correct within top 2
#   q6: [2, 0]  d 0.30 → incorrect        q7: [2, 1]  d 0.05 → correct
# Recall@1 = 2/3; Recall@2 = 3/3.
# PR over τ ∈ {0.05, 0.10, 0.30}: (P, R) = (1, 1/3), (2/3, 2/3), (2/5, 2/3); F1 = 1/2, 2/3, 1/2 → max 2/3.
# AUC: correct {0.05, 0.10} vs incorrect {0.10, 0.30, 0.30}: 0.05 beats all 3; 0.10 ties one (½) and
#   beats two → (3 + 2.5) / 6 = 11/12.
# Headings: q3 vs 0: ψ_true = yaw(Rz(30)ᵀ Rz(0)) = −30; estimate −25 → error 5.
#           q7 vs 2: ψ_true = yaw(Rz(−85)ᵀ Rz(85)) = 170; estimate −175 → |−345| wraps to 15.
#   mean rotation error over the 2 correct matches = 10.
XS = [0, 10, 20, 0.5, 30, 10.2, 100, 20.1]
YAWS = [0, 0, 85, 30, 0, 0, 0, -85]


def hand_case() -> ev.Evaluation:
    queries = np.arange(3, 8, dtype=np.int64)
    ids = np.array([[0, 1], [1, 0], [0, 1], [2, 0], [2, 1]], dtype=np.int64)
    dist = np.array([[0.10, 0.5], [0.10, 0.4], [0.30, 0.35], [0.30, 0.9], [0.05, 0.5]])
    heading = np.array([-25.0, 0.0, 0.0, 0.0, -175.0])
    return ev.evaluate_topk("hand", queries, ids, dist, heading, poses_from(XS, YAWS), exclude=2, radius=1.0)


def test_hand_case_metrics() -> None:
    e = hand_case()
    assert e.gt_positive.tolist() == [True, False, True, False, True]
    assert e.correct.tolist() == [True, False, False, False, True]
    assert e.recall_at(1) == pytest.approx(2 / 3)
    assert e.recall_at(2) == pytest.approx(1.0)
    thr, p, r = e.pr()
    assert thr.tolist() == [0.05, 0.10, 0.30]
    assert p == pytest.approx([1.0, 2 / 3, 0.4])
    assert r == pytest.approx([1 / 3, 2 / 3, 2 / 3])
    m = e.metrics()
    assert m["queries"] == 5 and m["gt_queries"] == 3 and m["correct_top1"] == 2
    assert m["f1_max"] == pytest.approx(2 / 3)
    assert m["f1_threshold"] == pytest.approx(0.10)
    assert m["auc"] == pytest.approx(11 / 12)
    assert e.heading_true[[0, 4]] == pytest.approx([-30.0, 170.0])
    assert m["rotation_error_deg_mean"] == pytest.approx(10.0)
    assert m["rotation_error_deg_max"] == pytest.approx(15.0)
    assert m["recall_at_5"] is None  # only 2 candidates kept: not computable, not invented
    _, fpr, tpr = e.roc()
    assert fpr.tolist() == pytest.approx([0, 0, 1 / 3, 1])
    assert tpr.tolist() == pytest.approx([0, 0.5, 1, 1])


def test_auc_ties_and_degenerate() -> None:
    assert ev.auc_score([0.2, 0.2], [True, False]) == 0.5
    assert ev.auc_score([0.1, 0.2, 0.2, 0.3], [True, True, False, False]) == pytest.approx((2 + 1.5) / 4)
    assert ev.auc_score([0.9, 0.1], [True, False]) == 0.0
    assert math.isnan(ev.auc_score([0.1, 0.2], [True, True]))


def test_cosine_topk_hand_vectors() -> None:
    R = np.array([[1, 0], [0, 1], [1, 1], [2, 0], [0, 0], [1, 2]], dtype=np.float32)
    q, ids, d = ev.cosine_topk(R, exclude=1, k=3)
    assert q.tolist() == [2, 3, 4, 5]
    # q2 sees frame 0 only
    assert ids[0].tolist() == [0, -1, -1] and d[0, 0] == pytest.approx(1 - 1 / math.sqrt(2))
    assert np.isinf(d[0, 1:]).all()
    assert ids[1].tolist() == [0, 1, -1] and d[1, :2] == pytest.approx([0.0, 1.0])
    # an all-zero query is at distance 1 from everything; ties go to the lower id
    assert ids[2].tolist() == [0, 1, 2] and d[2] == pytest.approx([1, 1, 1])
    # [1,2]: 1−3/√10 to frame 2, 1−2/√5 to frame 1, then 0 and 3 tie at 1−1/√5 → lower id first
    assert ids[3].tolist() == [2, 1, 0]
    assert d[3] == pytest.approx([1 - 3 / math.sqrt(10), 1 - 2 / math.sqrt(5), 1 - 1 / math.sqrt(5)])


def test_cosine_topk_matches_brute_force_and_chunking() -> None:
    rng = np.random.default_rng(5)
    R = rng.integers(0, 4, (300, 8)).astype(np.float32)  # small integers: many exact ties
    q, ids, d = ev.cosine_topk(R, exclude=20, k=4, max_elements=100)
    q2, ids2, d2 = ev.cosine_topk(R, exclude=20, k=4)
    assert np.array_equal(ids, ids2) and np.array_equal(d, d2)
    for i in (0, 50, 150, q.size - 1):
        qq = int(q[i])
        brute = [(1 - float(np.dot(R[qq], R[j])) / (np.linalg.norm(R[qq]) * np.linalg.norm(R[j])) if R[qq].any() and R[j].any() else 1.0, j) for j in range(qq - 20)]
        brute.sort(key=lambda t: (round(t[0], 12), t[1]))
        assert [j for _, j in brute[:4]] == [j for j in ids[i].tolist() if j >= 0]


def test_heading_numpy_hand() -> None:
    ac = np.array([1, 0, 0, 0, 0, 0], dtype=np.float32)
    assert ev.heading_numpy(np.roll(ac, 2), ac, refine=False)[0] == 120.0
    assert ev.heading_numpy(np.roll(ac, 5), ac, refine=False)[0] == -60.0
    assert ev.heading_numpy(np.roll(ac, 3), ac, refine=False)[0] == 180.0
    # costs 1.52, 0.32, 0.72 around s* = 2 → δ = 0.8 / 3.2 = 0.25 → 2.25 × 60° = 135°
    aq = np.array([0, 0, 0.6, 0.4, 0, 0])
    assert ev.heading_numpy(aq, ac, refine=True)[0] == pytest.approx(135.0)
    assert ev.heading_numpy(aq, ac, refine=False)[0] == 120.0
    # all-equal costs: first argmin (shift 0), flat parabola → no refinement
    assert ev.heading_numpy(np.zeros(6), np.zeros(6))[0] == 0.0


def test_heading_numpy_matches_extension_on_real_scans() -> None:
    d = data_dir()
    cfg = solid.SolidConfig.preset("avia")
    seq = sio.Sequence(d / "hku1-avia")
    idx = [0, 5, 40, 120, 200, 280, 300, 313]
    descs = [solid.describe(seq[i], cfg) for i in idx]
    pairs = [(q, c) for q in descs for c in descs]
    # narrow-FOV Avia pairs give headings near 0 only; add a full-360° scan turned by many angles
    kitti = sio.read_points(d / "kitti00/velodyne/000094.bin", xyz_only=True)
    h64 = solid.SolidConfig.preset("hdl64")
    turned = [solid.describe(sio.rotate_z(kitti, ang), h64) for ang in (0, 31, -77, 123, 178, -150)]
    pairs += [(q, c) for q in turned for c in turned]
    for group in (pairs[:64], pairs[64:]):
        aq = np.stack([q.a for q, _ in group])
        ac = np.stack([c.a for _, c in group])
        ours = ev.heading_numpy(aq, ac, refine=False)
        theirs = np.array([solid.heading(q, c, refine=False) for q, c in group])
        assert np.array_equal(ours, theirs)  # integer shifts: identical
        ours = ev.heading_numpy(aq, ac, refine=True)
        theirs = np.array([solid.heading(q, c, refine=True) for q, c in group])
        assert np.allclose(ours, theirs, atol=1e-3)  # the extension refines in float32
    assert len(set(np.round(ours).tolist())) > 15  # many distinct headings, not a degenerate sample
    # the hand-made refinement case, through the extension
    one = np.ones(1, dtype=np.float32)
    c6 = solid.SolidConfig(fov_up=1.0, fov_down=-1.0, n_elevation=1, n_range=1, n_azimuth=6)
    q = solid.Descriptor(one, np.array([0, 0, 0.6, 0.4, 0, 0], dtype=np.float32), c6)
    c = solid.Descriptor(one, np.array([1, 0, 0, 0, 0, 0], dtype=np.float32), c6)
    assert solid.heading(q, c, refine=True) == pytest.approx(135.0, abs=1e-4)


def test_rotated_scan_heading_solid_and_scancontext() -> None:
    pts = sio.read_points(data_dir() / "kitti00/velodyne/000000.bin", xyz_only=True)
    rot = sio.rotate_z(pts, 30.0)
    cfg = solid.SolidConfig.preset("hdl64")
    a0 = solid.describe(pts, cfg).a
    a1 = solid.describe(rot, cfg).a
    assert abs(ev.heading_numpy(a1, a0, refine=False)[0] - 30.0) <= 6.0
    assert abs(ev.heading_numpy(a0, a1, refine=False)[0] + 30.0) <= 6.0
    c0 = sc.describe(pts)
    c1 = sc.describe(rot)
    dist, shift = sc.distance(c1, c0)
    assert shift == 5 and dist < 0.05  # 5 sectors of 6° = 30° counter-clockwise


# --------------------------------------------------------------------------------------------
# Scan Context


def test_scancontext_hand_case() -> None:
    # 2 rings × 4 sectors. Query columns 0 = (1, 0), 1 = (0, 1); candidate columns 1 = (1, 0), 2 = (0, 1):
    # the query is the candidate rotated by one sector counter-clockwise.
    q = np.zeros((2, 4))
    q[:, 0] = [1, 0]
    q[:, 1] = [0, 1]
    c = np.roll(q, 1, axis=1)
    d, n = sc.distance(q, c)
    assert d == pytest.approx(0.0) and n == 3  # q[:, j] = c[:, (j − 3) mod 4]: candidate shifted back
    d, n = sc.distance(c, q)
    assert d == pytest.approx(0.0) and n == 1  # c is q rotated +1 sector → heading +90°
    # an empty candidate leaves no column pair that is non-empty in both: distance 1, shift 0
    assert sc.distance(q, np.zeros((2, 4))) == (1.0, 0)


def test_scancontext_describe_cells() -> None:
    pts = np.array(
        [
            [1.0, 0.1, -0.5, 0],  # ring 0, sector 0, height 1.5
            [1.0, 0.05, 0.5, 0],  # same cell, height 2.5 (max)
            [-10.0, 0.01, 1.0, 0],  # ring 2 (10 m of 80 m / 20 rings = 4 m each), sector 29 (≈180°)
            [0.0, -50.0, -3.0, 0],  # below −2 m: clamped to height 0
            [90.0, 0.0, 0.0, 0],  # beyond max range: dropped
        ],
        dtype=np.float32,
    )
    d = sc.describe(pts)
    assert d.shape == (20, 60)
    assert d[0, 0] == pytest.approx(2.5)
    assert d[2, 29] == pytest.approx(3.0)
    assert np.count_nonzero(d) == 2


def test_scancontext_fft_topk_matches_direct() -> None:
    rng = np.random.default_rng(11)
    D = rng.random((40, 5, 12))
    D[rng.random(D.shape) < 0.6] = 0
    D[:, :, rng.random(12) < 0.3] = 0  # empty columns
    D[7] = 0  # an empty descriptor
    q, ids, d, shifts = sc.topk(D, exclude=3, k=3, max_elements=500)
    for i, qq in enumerate(q):
        direct = sorted((sc.distance(D[qq], D[j])[0], j) for j in range(qq - 3))
        assert d[i, 0] == pytest.approx(direct[0][0], abs=1e-9)
        if len(direct) > 1 and direct[1][0] - direct[0][0] > 1e-9:
            assert ids[i, 0] == direct[0][1]
            assert shifts[i] == sc.distance(D[qq], D[ids[i, 0]])[1]


# --------------------------------------------------------------------------------------------
# on the real loop sequence


def test_ground_truth_counts_match_readme() -> None:
    seq = sio.Sequence(data_dir() / "hku1-avia", poses="odom_poses.txt")
    q = ev.query_indices(len(seq), 50)
    assert q.size == 263
    gt3, _ = ev.gt_positive(seq.positions(), q, 50, 3.0)
    gt5, _ = ev.gt_positive(seq.positions(), q, 50, 5.0)
    assert int(gt3.sum()) == 66 and int(gt5.sum()) == 155


def test_evaluate_solid_and_report(tmp_path: Path) -> None:
    seq = sio.Sequence(data_dir() / "hku1-avia", poses="odom_poses.txt")
    assert seq.poses is not None
    keep = list(range(0, 41)) + list(range(270, 314))
    cfg = solid.SolidConfig.preset("avia", max_range=40.0)
    descs = [solid.describe(seq[i], cfg) for i in keep]
    R = np.stack([x.r for x in descs])
    A = np.stack([x.a for x in descs])
    P = seq.poses[keep]
    e = ev.evaluate_solid(R, A, P, exclude=40, radius=5.0)
    e_np = ev.evaluate_solid(R, A, P, exclude=40, radius=5.0, use_extension=False)
    assert np.allclose(e.heading_est, e_np.heading_est, atol=1e-6)
    m = e.metrics()
    # frames 270..313 revisit 0..32 (README): most of them are GT-positive and SOLiD finds many
    assert m["gt_queries"] >= 30
    assert m["recall_at_1"] is not None and m["recall_at_1"] > 0.3
    assert m["recall_at_5"] >= m["recall_at_1"]
    assert m["rotation_error_deg_mean"] is not None and m["rotation_error_deg_mean"] < 20
    base = sc.evaluate_scancontext(sc.describe_many(seq[i] for i in keep), P, exclude=40, radius=5.0)
    out = ev.write_report(tmp_path / "out", e, [base], extra={"sequence": "hku1-avia"})
    doc = json.loads((tmp_path / "out" / "metrics.json").read_text())
    for key in ("queries", "gt_queries", "recall_at_1", "recall_at_5", "f1_max", "auc", "rotation_error_deg_mean"):
        assert key in doc and key in doc["baselines"]["scancontext"]
    assert doc["sequence"] == "hku1-avia"
    with open(out["queries.csv"], newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == m["queries"] and tuple(rows[0].keys()) == ev.CSV_COLUMNS
    assert sum(int(r["correct"]) for r in rows) == m["correct_top1"]
    for png in ("pr", "roc"):
        assert out[png].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list((tmp_path / "out").glob(".*tmp"))
