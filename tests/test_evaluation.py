"""docs/spec.md §5 scoring (the core's, through solid.evaluation) on hand-made cases and on the pipeline."""

from __future__ import annotations

import math
from collections.abc import Sequence as AbcSequence

import numpy as np
import numpy.typing as npt
import pytest
from conftest import data_dir

import solid
from solid import evaluation as ev
from solid import io as sio
from solid.config import PipelineConfig
from solid.pipeline import LoopClosurePipeline, PipelineResult



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
#   q3: [0]     d 0.10 → correct          q4: [1, 0]  d 0.10 → incorrect (tie with q3)
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


def hand_case(threshold: float | None = None) -> ev.Evaluation:
    queries = np.arange(3, 8, dtype=np.int64)
    ids = np.array([[0, -1], [1, 0], [0, 1], [2, 0], [2, 1]], dtype=np.int64)
    dist = np.array([0.10, 0.10, 0.30, 0.30, 0.05])
    heading = np.array([-25.0, 0.0, 0.0, 0.0, -175.0])
    return ev.evaluate_candidates("hand", queries, queries - 2, ids, dist, dist, heading, poses_from(XS, YAWS), radius=1.0, threshold=threshold)


def test_hand_case_metrics() -> None:
    e = hand_case(threshold=0.1)
    m = e.metrics()
    assert m["queries"] == 5 and m["gt_queries"] == 3
    assert list(e.gt_positive) == [True, False, True, False, True]
    assert list(e.correct) == [True, False, False, False, True]
    assert m["recall_at_1"] == pytest.approx(2 / 3)
    assert e.recall_at(2) == pytest.approx(1.0)
    thr, p, r = e.pr()
    assert thr.tolist() == [0.05, 0.10, 0.30]
    assert p.tolist() == pytest.approx([1.0, 2 / 3, 2 / 5])
    assert r.tolist() == pytest.approx([1 / 3, 2 / 3, 2 / 3])
    assert m["f1_max"] == pytest.approx(2 / 3) and m["f1_threshold"] == pytest.approx(0.10)
    assert m["auc"] == pytest.approx(11 / 12)
    assert m["rotation_error_deg_mean"] == pytest.approx(10.0)
    # at the operating threshold 0.1: q3, q4, q7 accepted, q4 wrong
    assert (m["accepted"], m["true_accepts"], m["false_accepts"]) == (3, 2, 1)
    assert m["precision"] == pytest.approx(2 / 3) and m["recall"] == pytest.approx(2 / 3)
    rows = e.rows()
    assert [r["accepted"] for r in rows] == [True, True, False, False, True]
    assert tuple(rows[0]) == ev.QUERY_COLUMNS
    assert float(rows[0]["true_heading_deg"]) == pytest.approx(-30.0)


def test_places_of_unknown_pose_are_left_out_of_the_scores() -> None:
    # The hand case's frames as a detector's steps, q5 given frame 0 alone. Frame 1's pose unknown
    # (a frame no anchor places: solid eval --anchor anchors.kitti): q4 and q7, whose candidates
    # include it, are left out; q5 stays, and frame 1 (0.2 m from it) is no true place of it.
    from types import SimpleNamespace as NS

    ranked = {3: [0], 4: [1, 0], 5: [0], 6: [2, 0], 7: [2, 1]}
    dist = {3: 0.10, 4: 0.10, 5: 0.30, 6: 0.30, 7: 0.05}
    steps = [
        NS(query=q, eligible=q - 2, candidates=[NS(id=c, distance=dist[q], score=dist[q], heading=0.0, accepted=False) for c in ids])
        for q, ids in ranked.items()
    ]
    db = NS(poses=poses_from(XS, YAWS), timestamps=np.zeros(len(XS)), sessions=np.zeros(len(XS), np.uint32))
    every = ev.evaluate_detections("x", steps, db, radius=1.0, threshold=0.1)
    assert every.query.tolist() == [3, 4, 5, 6, 7] and every.left_out.size == 0
    assert list(every.gt_positive) == [True, False, True, False, True]
    known = ev.evaluate_detections("x", steps, db, radius=1.0, threshold=0.1, unknown=[1])
    assert known.query.tolist() == [3, 5, 6] and known.left_out.tolist() == [4, 7]
    assert list(known.gt_positive) == [True, False, False] and list(known.correct) == [True, False, False]
    assert known.ids.tolist() == [[0, -1], [0, -1], [2, 0]]
    assert known.metrics()["gt_queries"] == 1 and known.metrics()["accepted"] == 1
    for bad in ([-1], [len(XS)]):  # an id no entry has (negative ids would wrap)
        with pytest.raises(ValueError, match="unknown: entry ids"):
            ev.evaluate_detections("x", steps, db, radius=1.0, threshold=0.1, unknown=bad)


def test_scoring_refuses_bad_input() -> None:
    P = poses_from(XS, YAWS)
    q = np.array([3])
    with pytest.raises(ValueError, match="eligible"):
        ev.evaluate_candidates("x", q, np.array([0]), np.array([[0]]), [0.1], [0.1], [0.0], P, radius=1.0)
    with pytest.raises(ValueError, match="ids"):  # a candidate the query could not be matched with
        ev.evaluate_candidates("x", q, np.array([1]), np.array([[2]]), [0.1], [0.1], [0.0], P, radius=1.0)
    with pytest.raises(ValueError, match="radius"):
        ev.evaluate_candidates("x", q, np.array([1]), np.array([[0]]), [0.1], [0.1], [0.0], P, radius=0.0)
    Pn = P.copy()
    Pn[0, 0, 3] = np.nan
    with pytest.raises(ValueError, match="no pose"):
        ev.evaluate_candidates("x", q, np.array([1]), np.array([[0]]), [0.1], [0.1], [0.0], Pn, radius=1.0)


def hku_pipeline(**detector: float) -> PipelineResult:
    """The pipeline on hku1 (verification off and the frames-only exclusion of docs/spec.md §5
    unless asked: these tests are about the search and the protocol)."""
    seq = sio.Dataset(data_dir() / "hku1-avia", poses="odom_poses.txt")
    return LoopClosurePipeline(seq, PipelineConfig.preset("avia", detector={"verify": False, "exclude_meters": 0.0, **detector})).run()


def test_ground_truth_counts_match_the_data_readme() -> None:
    res = hku_pipeline()
    assert len(res.queries()) == 263
    assert res.evaluate(radius=3.0).metrics()["gt_queries"] == 66
    assert res.evaluate(radius=5.0).metrics()["gt_queries"] == 155


def test_eval_scores_exactly_what_the_detector_decided() -> None:
    """No second search or heading: the scored top-1 is the detector's best candidate, step by step."""
    res = hku_pipeline(threshold=1.0)
    e = res.evaluate(radius=5.0)
    det = solid.LoopDetector(solid.SolidConfig.preset("avia"), threshold=1.0, verify=False)
    seq = sio.Dataset(data_dir() / "hku1-avia")
    loops = [lp for p in seq if (lp := det.add(p)) is not None]
    assert [lp.query for lp in loops] == e.query.tolist()
    assert [lp.candidate for lp in loops] == e.ids[:, 0].tolist()
    assert np.array_equal([lp.heading for lp in loops], e.heading_deg)
    assert np.array_equal([lp.distance for lp in loops], e.distance)
    m = e.metrics()
    assert m["recall_at_1"] == pytest.approx(0.490, abs=1e-3)  # the R-SOLiD top-1 at 5 m (no re-rank by default)


def test_exclusion_by_metres_changes_what_is_eligible() -> None:
    frames = hku_pipeline()
    metres = hku_pipeline(exclude_frames=0, exclude_meters=10.0)
    # ~0.2 m per keyframe: 10 m is about 50 frames, not exactly
    a = np.array([d.eligible for d in frames.detections])
    b = np.array([d.eligible for d in metres.detections])
    assert not np.array_equal(a, b)
    P = np.asarray(metres.database.poses)[:, :, 3]
    path = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
    for q, d in enumerate(metres.detections):
        assert d.eligible == int(np.sum(path[:q] <= path[q] - 10.0))
