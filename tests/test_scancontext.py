"""The Scan Context baseline: descriptor and distance on hand-made cases, candidate search, and
agreement with the authors' C++ implementation on hku1-avia."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pytest
from conftest import data_dir

from solid import io as sio
from solid import scancontext as sc, transforms

F64 = npt.NDArray[np.float64]

# 2 rings × 4 sectors, 8 m: rings (0, 4], (4, 8] m; sectors (0°, 90°], (90°, 180°], ... (0° → sector 0).
# search_ratio 0.5 → shift window ±1 (round(0.5·0.5·4) = 1) around the sector-key alignment.
SMALL = sc.ScanContextConfig(n_ring=2, n_sector=4, max_range=8.0, search_ratio=0.5)


def polar(r: float, theta_deg: float, z: float) -> list[float]:
    t = math.radians(theta_deg)
    return [r * math.cos(t), r * math.sin(t), z]


# --------------------------------------------------------------------------------------------
# descriptor


def test_describe_cells_heights_and_bin_edges() -> None:
    cfg = sc.ScanContextConfig(n_ring=2, n_sector=4, max_range=10.0)  # rings (0, 5], (5, 10] m
    pts = np.array(
        [
            [1.0, 0.2, -0.5],  # ring 0, sector 0: height 1.5
            [2.0, 0.5, 0.5],  # same cell, height 2.5
            [0.0, 0.0, 1.0],  # r = 0, θ = 0: ring 0, sector 0; height 3.0, the cell keeps the max
            [-1.0, 7.0, -3.0],  # ring 1, sector 1 (98°): only points below −2 m → −1.0, not clamped
            [-2.0, 7.0, -2.5],  # same cell: max(−1.0, −0.5) = −0.5
            [-3.0, -4.0, 1.0],  # r = 5 m exactly: ring 0 (rings are closed outside); sector 2 (233°)
            [6.0, -8.0, 0.0],  # r = max_range exactly: kept, ring 1, sector 3 (307°)
            [6.0, -8.001, 5.0],  # beyond max_range: dropped
            [1.0, float("nan"), 9.0],  # non-finite: dropped
        ]
    )
    d = sc.describe(np.c_[pts, np.zeros(len(pts))], cfg)  # extra columns are ignored
    want = np.array([[3.0, 0.0, 3.0, 0.0], [0.0, -0.5, 0.0, 2.0]])
    assert d.shape == (2, 4)
    np.testing.assert_allclose(d, want, atol=1e-12)
    # an empty scan is all zeros; the default grid is the paper's 20 × 60
    assert not sc.describe(np.zeros((0, 3)), cfg).any()
    assert sc.describe(np.array([[1.0, 1.0, 1.0]])).shape == (20, 60)
    with pytest.raises(ValueError, match="shape"):
        sc.describe(np.zeros((5, 2)))


def test_keys() -> None:
    d = np.array([[3.0, 0.0, 3.0, 0.0], [0.0, -0.5, 0.0, 2.0]])
    np.testing.assert_allclose(sc.ring_key(d, SMALL), [1.5, 0.375])  # ring means, empty cells count as 0
    np.testing.assert_allclose(sc.sector_key(d), [1.5, -0.25, 1.5, 1.0])
    paper = sc.ScanContextConfig(n_ring=2, n_sector=4, max_range=8.0, variant="paper")
    np.testing.assert_allclose(sc.ring_key(d, paper), [0.5, 0.5])  # occupancy ‖ring‖₀ / Ns
    assert sc.ring_key(np.stack([d, d]), SMALL).shape == (2, 2)


def test_config_is_checked() -> None:
    for bad in (
        {"n_ring": 0},
        {"max_range": math.inf},
        {"lidar_height": math.nan},
        {"n_candidates": 0},
        {"search_ratio": 1.5},
        {"variant": "fast"},
    ):
        with pytest.raises(ValueError):
            sc.ScanContextConfig(**bad)
    assert sc.ScanContextConfig().shift_radius == 3  # ±3 of 60 sectors, as the C++ (SEARCH_RATIO 0.1)
    assert SMALL.shift_radius == 1


# --------------------------------------------------------------------------------------------
# distance and heading


def test_distance_means_over_columns_non_empty_in_both() -> None:
    q = np.array([[1.0, 1.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
    c = np.array([[1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]])
    # Sector keys: q (0.5, 1, 0, 0), c (1, 0, 0, 0); the alignment is shift 1 (c moved to column 1).
    # Window {0, 1, 2}: shift 0 pairs column 0 only, cos 1/√2 → d = 1 − 0.7071;
    # shift 1 pairs column 1 only, (1,1)·(1,1) → d = 0; shift 2 pairs nothing (not comparable).
    d, n = sc.distance(q, c, SMALL)
    assert d == pytest.approx(0.0, abs=1e-12) and n == 1
    # with the paper's 1/Ns over all columns, empty columns count as cosine 0: d = 1 − 1/4
    paper = sc.ScanContextConfig(n_ring=2, n_sector=4, max_range=8.0, variant="paper")
    d, n = sc.distance(q, c, paper)
    assert d == pytest.approx(0.75) and n == 1


def test_negative_heights_and_incomparable_pairs() -> None:
    q = np.array([[-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
    c = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
    # an all-negative column is non-empty: cos = −1 → d = 2 (a clamped descriptor would see 0 and 1)
    d, n = sc.distance(q, c, SMALL)
    assert d == pytest.approx(2.0) and n == 0
    # no column non-empty in both at any searched shift: not comparable → +inf, shift 0
    assert sc.distance(q, np.zeros((2, 4)), SMALL) == (math.inf, 0)
    assert sc.distance(np.zeros((2, 4)), np.zeros((2, 4)), SMALL) == (math.inf, 0)
    # the paper's variant has a distance for them: 1 − 0/Ns
    paper = sc.ScanContextConfig(n_ring=2, n_sector=4, max_range=8.0, variant="paper")
    assert sc.distance(q, np.zeros((2, 4)), paper) == (1.0, 0)


def test_shift_window_is_around_the_sector_key_alignment() -> None:
    # 2 rings × 6 sectors. Candidate columns 0 = (1, 0), 1 = (0, 1); the query has them at columns 2
    # and 3 (a perfect fit at shift 2) plus a tall column 5 = (5, 5) that pulls the sector-key
    # alignment to shift 4 (‖Vq − Vc₄‖² = 21 < ‖Vq − Vc₂‖² = 25). At shift 4 the only pair non-empty
    # in both is query column 5 with candidate column 1: cos = 1/√2.
    q = np.zeros((2, 6))
    q[:, 2], q[:, 3], q[:, 5] = [1, 0], [0, 1], [5, 5]
    c = np.zeros((2, 6))
    c[:, 0], c[:, 1] = [1, 0], [0, 1]

    def cfg(**kw: float | str) -> sc.ScanContextConfig:
        return sc.ScanContextConfig(n_ring=2, n_sector=6, max_range=8.0, **kw)  # type: ignore[arg-type]

    near = 1 - 1 / math.sqrt(2)
    d, n = sc.distance(q, c, cfg(search_ratio=0.0))  # the alignment only
    assert n == 4 and d == pytest.approx(near)
    d, n = sc.distance(q, c, cfg(search_ratio=1 / 3))  # ±1: shifts 3 (d = 1), 4, 5 (d = 1 − 1/√2)
    assert n == 4 and d == pytest.approx(near)
    d, n = sc.distance(q, c, cfg(search_ratio=1.0))  # ±3 covers every shift
    assert n == 2 and d == pytest.approx(0.0, abs=1e-12)
    d, n = sc.distance(q, c, cfg(variant="paper"))  # every shift, 1/Ns: 1 − 2/6
    assert n == 2 and d == pytest.approx(2 / 3)


def test_heading_sign_convention() -> None:
    # A random cloud and the same cloud rotated counter-clockwise by 3 sectors (18°): the rotated
    # one, as the query, has heading +18° relative to the original (docs/spec.md §3: p_query ≈ Rz(ψ)·p_cand).
    rng = np.random.default_rng(3)
    n = 4000
    r = rng.uniform(1, 70, n)
    t = rng.uniform(0, 360, n)
    t = np.floor(t / 6) * 6 + 3  # sector centres: rotating by 18° moves every point exactly 3 sectors
    z = rng.normal(0, 1.5, n)
    cand = np.c_[r * np.cos(np.radians(t)), r * np.sin(np.radians(t)), z]
    query = transforms.rotate_z(cand, 18.0)
    dq, dc = sc.describe(query), sc.describe(cand)
    d, s = sc.distance(dq, dc)
    assert d == pytest.approx(0.0, abs=1e-12) and s == 3
    assert sc.heading_deg(s, 60) == pytest.approx(18.0)
    d, s = sc.distance(dc, dq)
    assert d == pytest.approx(0.0, abs=1e-12) and sc.heading_deg(s, 60) == pytest.approx(-18.0)
    # through the search: frame 1 (the rotated cloud) finds frame 0 with heading +18°
    c = sc.candidates(np.stack([dc, dq]), exclude=0)
    assert c.queries.tolist() == [1] and c.ids[0, 0] == 0 and c.headings_deg[0, 0] == pytest.approx(18.0)
    assert sc.heading_deg(30, 60) == 180.0 and sc.heading_deg(31, 60) == pytest.approx(-174.0)


# --------------------------------------------------------------------------------------------
# candidate search


def random_descriptors(n: int, seed: int = 5) -> F64:
    rng = np.random.default_rng(seed)
    D = rng.normal(1.0, 1.0, (n, 20, 60))
    D[rng.random(D.shape) < 0.7] = 0.0
    D[:, :, rng.random(60) < 0.2] = 0.0  # empty columns
    D[4] = 0.0  # an empty scan: not comparable with anything
    return D


def test_candidates_rerank_ring_key_neighbours_by_direct_distance() -> None:
    D = random_descriptors(40)
    cfg = sc.ScanContextConfig()
    c = sc.candidates(D, exclude=5, k=3, cfg=cfg)
    assert c.queries.tolist() == list(range(6, 40))
    keys = sc.ring_key(D, cfg)
    for i, q in enumerate(c.queries):
        db = np.arange(q - 5)
        kd = ((keys[db] - keys[q]) ** 2).sum(axis=1)
        near = db[np.lexsort((db, kd))][:10]  # the 10 nearest ring keys, ties by lower id
        direct = sorted((sc.distance(D[q], D[j], cfg)[0], j) for j in near)
        assert c.ids[i, 0] in near
        m = min(3, len(direct))
        assert c.distances[i, :m].tolist() == pytest.approx([x[0] for x in direct[:m]], abs=1e-9)
        assert np.all(c.ids[i, m:] == -1)
        s = sc.distance(D[q], D[c.ids[i, 0]], cfg)[1]
        assert c.headings_deg[i, 0] == pytest.approx(float(sc.heading_deg(s, 60)))
    # the empty scan 4 is never a finite candidate, and as a query it has none
    assert not np.any((c.ids == 4) & np.isfinite(c.distances))
    # n_candidates=None ranks every eligible entry: never worse at top-1
    full = sc.candidates(D, exclude=5, k=3, cfg=sc.ScanContextConfig(n_candidates=None))
    assert np.all(full.distances[:, 0] <= c.distances[:, 0] + 1e-12)


def test_candidates_pads_small_databases() -> None:
    D = random_descriptors(9)
    c = sc.candidates(D, exclude=5, k=3)
    assert c.queries.tolist() == [6, 7, 8]
    assert c.ids[0, 1:].tolist() == [-1, -1] and np.isinf(c.distances[0, 1:]).all()
    assert np.isnan(c.headings_deg[0, 1:]).all()
    assert sorted(c.ids[2, :3].tolist()) == [0, 1, 2]
    with pytest.raises(ValueError):
        sc.candidates(D, exclude=-1)
    with pytest.raises(ValueError):
        sc.candidates(D[:, :, :30])


def test_exclusion_forms_agree() -> None:
    D = random_descriptors(30)
    n = len(D)
    base = sc.candidates(D, exclude=7, k=4)
    mask = np.arange(n)[None, :] < np.arange(n)[:, None] - 7
    by_mask = sc.candidates(D, exclude=mask, k=4)
    by_fn = sc.candidates(D, exclude=lambda q: np.arange(n) < q - 7, k=4)
    by_ids = sc.candidates(D, exclude=lambda q: np.arange(max(0, q - 7)), k=4)
    for other in (by_mask, by_fn, by_ids):
        assert other.queries.tolist() == base.queries.tolist()
        assert np.array_equal(other.ids, base.ids)
        assert np.array_equal(other.distances, base.distances)
    # a mask can also look forward (e.g. another session): query 0 against frames 20..29 only
    fwd = sc.candidates(D, exclude=lambda q: np.arange(n) >= 20, k=2, queries=[0])
    assert fwd.queries.tolist() == [0] and set(fwd.ids[0].tolist()) <= set(range(20, 30))
    with pytest.raises(ValueError, match="mask"):
        sc.candidates(D, exclude=np.ones((3, 3), dtype=bool))


# --------------------------------------------------------------------------------------------
# against the authors' C++ on hku1-avia

# docs/spec.md §5 metrics of the authors' C++ Scan Context (gisbi-kim/scancontext, cpp/module/Scancontext,
# unmodified; 10 candidates from its nanoflann ring-key tree over every frame < q − 50, re-ranked by its
# distanceBtnScanContext) on hku1-avia, exclude 50, radius 3 m. Produced by a harness kept outside the
# repository (/work/peers/scancontext; its source and build commands are in the helper note
# /work/notes/sc.md):
#   ./harness all hku1.list > ref_all.csv && python score.py /work/shared/data/hku1-avia
# (35 of 66 GT-positive queries correct; F1max 0.32461; AUC 0.74574; this module's top-5 candidates,
# distances (to 7e-9) and headings equal the C++'s for all 263 queries).
REF_RECALL_AT_1 = 0.530
REF_F1_MAX = 0.325
REF_AUC = 0.746


def test_hku1_matches_the_reference_implementation() -> None:
    seq = sio.Dataset(data_dir() / "hku1-avia", poses="odom_poses.txt")
    assert seq.poses is not None and len(seq) == 314
    D = sc.describe_many(seq[i] for i in range(len(seq)))
    m = sc.evaluate_scancontext(D, seq.poses, exclude=50, radius=3.0).metrics()
    assert m["gt_queries"] == 66 and m["queries"] == 263
    assert abs(m["recall_at_1"] - REF_RECALL_AT_1) <= 0.03, m
    assert abs(m["f1_max"] - REF_F1_MAX) <= 0.03, m
    assert abs(m["auc"] - REF_AUC) <= 0.03, m
    # the faithful baseline's headings are meaningful (the former one had 92% of them beyond 60°)
    c = sc.candidates(D, 50, 1, queries=sc.query_indices(len(seq), 50))
    assert np.mean(np.abs(c.headings_deg[:, 0]) > 60) < 0.05
    assert m["rotation_error_deg_mean"] is not None and m["rotation_error_deg_mean"] < 10
