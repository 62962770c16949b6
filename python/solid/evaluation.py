"""Loop-closure evaluation on a sequence with poses: the protocol of SPEC §5.

Given one descriptor per frame and the frames' poses, :func:`evaluate_solid` (R-SOLiD / A-SOLiD)
and :func:`solid.scancontext.evaluate_scancontext` return an :class:`Evaluation` holding, per query,
its top-k candidates, distances, ground truth and heading error, plus the summary metrics
(Recall@1, Recall@5, F1 max, AUC, rotation error) and the PR and ROC curves.
:func:`write_report` writes ``metrics.json``, the per-query CSVs and the PNG plots.

Definitions (SPEC §5): query q is compared with frames ``< q − exclude``; queries with an empty
database are skipped. A query is GT-positive when some database frame lies within ``radius``
metres (``<=``); its top-1 is correct when that candidate does. Recall@N = GT-positive queries with a
correct candidate among their top N / GT-positive queries. The PR curve accepts a query's top-1 when
its distance ≤ τ, for τ over every observed top-1 distance; precision = TP / accepted, recall = TP /
GT-positive queries. AUC = P(correct top-1 distance < incorrect top-1 distance), ties one half.
Rotation error = |ψ_est − ψ_true| wrapped into [0°, 180°] over the correct top-1 matches, with
ψ_true = yaw(R_queryᵀ · R_candidate).
"""

from __future__ import annotations

import csv
import io as _io
import json
import math
import os
from collections.abc import Callable, Sequence as AbcSequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from .io import _atomic_write_bytes, _wrap180, yaw_degrees

__all__ = [
    "CSV_COLUMNS",
    "Evaluation",
    "auc_score",
    "cosine_topk",
    "evaluate_solid",
    "evaluate_topk",
    "f1_max",
    "gt_positive",
    "heading_numpy",
    "metrics_document",
    "plot_curves",
    "pr_curve",
    "query_indices",
    "roc_curve",
    "write_report",
]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]
B = npt.NDArray[np.bool_]

#: Columns of the per-query CSV, in order.
CSV_COLUMNS = (
    "query",
    "gt_positive",
    "nearest_db_m",
    "candidate",
    "distance",
    "candidate_m",
    "correct",
    "correct_at_k",
    "heading_est_deg",
    "heading_true_deg",
    "heading_error_deg",
)


# --------------------------------------------------------------------------------------------
# headings


def heading_numpy(a_query: npt.ArrayLike, a_candidate: npt.ArrayLike, refine: bool = True) -> F64:
    """SPEC §3 heading, vectorised: degrees in (−180, 180], one per row of (M, Na) inputs.

    ``cost[s] = Σⱼ (Aq[j] − Ac[(j − s) mod Na])²``; s* = the first argmin; with ``refine`` the
    parabolic sub-bin refinement of SPEC §3 (δ clamped to [−0.5, 0.5], 0 when the parabola is not
    convex). Accepts 1-D inputs too (returns shape (1,)). Computed in float64.
    """
    q = np.atleast_2d(np.asarray(a_query, dtype=np.float64))
    c = np.atleast_2d(np.asarray(a_candidate, dtype=np.float64))
    if q.shape != c.shape:
        raise ValueError(f"A-SOLiD shapes differ: {q.shape} vs {c.shape}")
    m, na = q.shape
    if na == 0:
        raise ValueError("empty A-SOLiD")
    j = np.arange(na)
    idx = (j[None, :] - j[:, None]) % na  # idx[s, j] = (j - s) mod Na
    out = np.empty(m, dtype=np.float64)
    chunk = max(1, 4_000_000 // (na * na))
    for lo in range(0, m, chunk):
        qs = q[lo : lo + chunk]
        cs = c[lo : lo + chunk]
        diff = qs[:, None, :] - cs[:, idx]  # (M, s, j)
        cost = np.einsum("msj,msj->ms", diff, diff)
        s = np.argmin(cost, axis=1)
        pos = s.astype(np.float64)
        if refine and na >= 3:
            rows = np.arange(cost.shape[0])
            cm = cost[rows, (s - 1) % na]
            c0 = cost[rows, s]
            cp = cost[rows, (s + 1) % na]
            den = 2.0 * (cm - 2.0 * c0 + cp)
            with np.errstate(divide="ignore", invalid="ignore"):
                delta = np.where(den > 0, (cm - cp) / np.where(den > 0, den, 1.0), 0.0)
            pos = pos + np.clip(delta, -0.5, 0.5)
        out[lo : lo + chunk] = _wrap180(pos * 360.0 / na)
    return out


def _headings_extension(a_query: F32, a_candidate: F32, refine: bool) -> F64 | None:
    """SPEC §3 heading through ``solid.heading`` when the extension is importable, else None.

    ``solid.heading`` takes Descriptors; they are rebuilt around the A-SOLiDs with a minimal
    config of the right azimuth count (heading reads only ``a``).
    """
    try:
        import solid
    except ImportError:
        return None
    if not all(hasattr(solid, n) for n in ("heading", "Descriptor", "SolidConfig")):
        return None
    na = a_query.shape[1]
    cfg = solid.SolidConfig(fov_up=1.0, fov_down=-1.0, n_elevation=1, n_range=1, n_azimuth=na)
    one = np.ones(1, dtype=np.float32)
    out = np.empty(a_query.shape[0], dtype=np.float64)
    for i in range(a_query.shape[0]):
        q = solid.Descriptor(one, np.ascontiguousarray(a_query[i], dtype=np.float32), cfg)
        c = solid.Descriptor(one, np.ascontiguousarray(a_candidate[i], dtype=np.float32), cfg)
        out[i] = float(solid.heading(q, c, refine=refine))
    return out


# --------------------------------------------------------------------------------------------
# search and ground truth


def _topk_from_dist(dist: F64, k: int) -> tuple[I64, F64]:
    """Per-row k smallest (ties by lower column index); masked entries are +inf → id −1."""
    kk = min(k, dist.shape[1])
    order = np.argsort(dist, axis=1, kind="stable")[:, :kk]
    d = np.take_along_axis(dist, order, axis=1)
    ids = np.where(np.isfinite(d), order, -1).astype(np.int64)
    if kk < k:
        pad = k - kk
        ids = np.concatenate([ids, np.full((ids.shape[0], pad), -1, dtype=np.int64)], axis=1)
        d = np.concatenate([d, np.full((d.shape[0], pad), np.inf)], axis=1)
    return ids, d


def query_indices(n_frames: int, exclude: int) -> I64:
    """Frames that are queries: those with a non-empty database (q − exclude ≥ 1)."""
    if exclude < 0:
        raise ValueError(f"exclude must be >= 0, got {exclude}")
    return np.arange(exclude + 1, n_frames, dtype=np.int64)


def cosine_topk(
    r: npt.ArrayLike,
    exclude: int = 50,
    k: int = 5,
    *,
    max_elements: int = 4_000_000,
    progress: Callable[[int], None] | None = None,
) -> tuple[I64, I64, F64]:
    """Exact top-k by cosine distance (SPEC §3) of every query against its database.

    Returns ``(queries, ids (Q, k), distances (Q, k))``; ties are broken by lower id, missing
    entries (database smaller than k) are id −1 / distance inf. All-zero vectors have distance 1
    to everything. Float64; every distance is summed in the same order whatever the chunking
    (no BLAS), so equal vectors give bit-equal distances and ties resolve the same way every time.
    Chunked over queries (``max_elements`` products at a time): 4,541 frames need ~100 MB at most.
    """
    R = np.asarray(r, dtype=np.float64)
    if R.ndim != 2:
        raise ValueError(f"R-SOLiDs must be (N, Nr), got {R.shape}")
    n, dim = R.shape
    norms = np.sqrt(np.square(R).sum(axis=1))
    U = np.divide(R, norms[:, None], out=np.zeros_like(R), where=norms[:, None] > 0)
    zero = norms == 0
    queries = query_indices(n, exclude)
    ids = np.empty((queries.size, k), dtype=np.int64)
    dists = np.empty((queries.size, k), dtype=np.float64)
    lo = 0
    while lo < queries.size:
        chunk = max(1, max_elements // max(1, dim * (n - exclude)))
        qs = queries[lo : lo + chunk]
        ndb = int(qs[-1]) - exclude  # the largest database in this chunk
        sim = (U[qs][:, None, :] * U[None, :ndb, :]).sum(axis=2)
        d = 1.0 - sim
        d[zero[qs], :] = 1.0
        d[:, zero[:ndb]] = 1.0
        np.clip(d, 0.0, 2.0, out=d)
        d[np.arange(ndb)[None, :] >= (qs - exclude)[:, None]] = np.inf
        i, dd = _topk_from_dist(d, k)
        ids[lo : lo + qs.size] = i
        dists[lo : lo + qs.size] = dd
        if progress is not None:
            progress(int(qs.size))
        lo += qs.size
    return queries, ids, dists


def gt_positive(positions: npt.ArrayLike, queries: I64, exclude: int, radius: float, chunk: int = 512) -> tuple[B, F64]:
    """Per query: whether some database frame lies within ``radius`` m, and the nearest distance."""
    P = np.asarray(positions, dtype=np.float64)
    pos = np.zeros(queries.size, dtype=bool)
    nearest = np.full(queries.size, np.inf)
    for lo in range(0, queries.size, chunk):
        qs = queries[lo : lo + chunk]
        ndb = int(qs[-1]) - exclude
        d = np.linalg.norm(P[qs][:, None, :] - P[None, :ndb, :], axis=2)
        d[np.arange(ndb)[None, :] >= (qs - exclude)[:, None]] = np.inf
        m = d.min(axis=1)
        nearest[lo : lo + qs.size] = m
        pos[lo : lo + qs.size] = m <= radius
    return pos, nearest


# --------------------------------------------------------------------------------------------
# curves and scores


def pr_curve(distance: npt.ArrayLike, correct: npt.ArrayLike, n_gt: int) -> tuple[F64, F64, F64]:
    """(thresholds, precision, recall): accept top-1 when distance ≤ τ, τ over observed distances."""
    d = np.asarray(distance, dtype=np.float64)
    c = np.asarray(correct, dtype=bool)
    if d.size == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    order = np.argsort(d, kind="stable")
    ds = d[order]
    tp = np.cumsum(c[order])
    fp = np.cumsum(~c[order])
    last = np.r_[ds[1:] != ds[:-1], True]  # last index of each distinct threshold
    thr = ds[last]
    tp = tp[last].astype(np.float64)
    fp = fp[last].astype(np.float64)
    precision = tp / (tp + fp)
    recall = tp / n_gt if n_gt > 0 else np.zeros_like(tp)
    return thr, precision, recall


def f1_max(precision: F64, recall: F64) -> tuple[float, int]:
    """Largest 2PR/(P+R) on the curve and its index (−1 for an empty curve)."""
    if precision.size == 0:
        return 0.0, -1
    s = precision + recall
    f1 = np.divide(2 * precision * recall, s, out=np.zeros_like(s), where=s > 0)
    i = int(np.argmax(f1))
    return float(f1[i]), i


def roc_curve(distance: npt.ArrayLike, correct: npt.ArrayLike) -> tuple[F64, F64, F64]:
    """(thresholds, false-positive rate, true-positive rate) of correct vs incorrect top-1s."""
    d = np.asarray(distance, dtype=np.float64)
    c = np.asarray(correct, dtype=bool)
    thr, _, _ = pr_curve(d, c, 1)
    npos, nneg = int(c.sum()), int((~c).sum())
    order = np.argsort(d, kind="stable")
    ds = d[order]
    last = np.r_[ds[1:] != ds[:-1], True] if ds.size else np.zeros(0, dtype=bool)
    tp = np.cumsum(c[order])[last].astype(np.float64)
    fp = np.cumsum(~c[order])[last].astype(np.float64)
    tpr = tp / npos if npos else np.zeros_like(tp)
    fpr = fp / nneg if nneg else np.zeros_like(fp)
    return np.r_[-np.inf, thr], np.r_[0.0, fpr], np.r_[0.0, tpr]


def auc_score(distance: npt.ArrayLike, correct: npt.ArrayLike) -> float:
    """P(a correct top-1's distance < an incorrect one's), ties one half; NaN if a class is empty.

    Mann–Whitney U with average ranks, exact for ties.
    """
    d = np.asarray(distance, dtype=np.float64)
    c = np.asarray(correct, dtype=bool)
    n_c, n_i = int(c.sum()), int((~c).sum())
    if n_c == 0 or n_i == 0:
        return math.nan
    _, inv, counts = np.unique(d, return_inverse=True, return_counts=True)
    first = np.cumsum(counts) - counts  # 0-based rank of each distinct value's first element
    avg_rank = first + (counts + 1) / 2.0  # 1-based average rank
    ranks = avg_rank[inv]
    r_incorrect = float(ranks[~c].sum())
    u = r_incorrect - n_i * (n_i + 1) / 2.0  # pairs (correct, incorrect) with correct < incorrect (+½ ties)
    return u / (n_c * n_i)


# --------------------------------------------------------------------------------------------
# the result


@dataclass
class Evaluation:
    """Per-query results and summary of one method on one sequence (see the module docstring)."""

    name: str
    exclude: int
    radius: float
    n_frames: int
    queries: I64
    gt_positive: B
    nearest_db_m: F64
    top_ids: I64
    top_dist: F64
    correct: B
    correct_at_k: B
    candidate_m: F64
    heading_est: F64
    heading_true: F64
    within: B
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def heading_error(self) -> F64:
        """|ψ_est − ψ_true| wrapped into [0, 180] for every query (meaningful where correct)."""
        return np.abs(_wrap180(self.heading_est - self.heading_true))

    def recall_at(self, n: int) -> float:
        """Recall@n over GT-positive queries (NaN when there are none)."""
        if n > self.top_ids.shape[1]:
            raise ValueError(f"only the top {self.top_ids.shape[1]} candidates were kept")
        gt = int(self.gt_positive.sum())
        if gt == 0:
            return math.nan
        hit = self.within[:, :n].any(axis=1)
        return float((hit & self.gt_positive).sum()) / gt

    def pr(self) -> tuple[F64, F64, F64]:
        """(thresholds, precision, recall) of SPEC §5."""
        return pr_curve(self.top_dist[:, 0], self.correct, int(self.gt_positive.sum()))

    def roc(self) -> tuple[F64, F64, F64]:
        """(thresholds, FPR, TPR) of correct vs incorrect top-1 matches."""
        return roc_curve(self.top_dist[:, 0], self.correct)

    def metrics(self) -> dict[str, Any]:
        """The summary dictionary written to ``metrics.json`` (NaN → None)."""
        thr, p, r = self.pr()
        f1, i = f1_max(p, r)
        err = self.heading_error[self.correct]
        k = self.top_ids.shape[1]
        m: dict[str, Any] = {
            "method": self.name,
            "frames": self.n_frames,
            "exclude": self.exclude,
            "radius": self.radius,
            "queries": int(self.queries.size),
            "gt_queries": int(self.gt_positive.sum()),
            "correct_top1": int(self.correct.sum()),
            "recall_at_1": self.recall_at(1),
            "recall_at_5": self.recall_at(5) if k >= 5 else math.nan,
            "f1_max": f1,
            "f1_threshold": float(thr[i]) if i >= 0 else math.nan,
            "precision_at_f1_max": float(p[i]) if i >= 0 else math.nan,
            "recall_at_f1_max": float(r[i]) if i >= 0 else math.nan,
            "auc": auc_score(self.top_dist[:, 0], self.correct),
            "rotation_error_deg_mean": float(err.mean()) if err.size else math.nan,
            "rotation_error_deg_median": float(np.median(err)) if err.size else math.nan,
            "rotation_error_deg_max": float(err.max()) if err.size else math.nan,
        }
        m.update(self.extra)
        return {key: (None if isinstance(v, float) and math.isnan(v) else v) for key, v in m.items()}

    def rows(self) -> list[dict[str, Any]]:
        """One dictionary per query, keys :data:`CSV_COLUMNS`."""
        err = self.heading_error
        out = []
        for i, q in enumerate(self.queries):
            out.append(
                {
                    "query": int(q),
                    "gt_positive": int(self.gt_positive[i]),
                    "nearest_db_m": round(float(self.nearest_db_m[i]), 4),
                    "candidate": int(self.top_ids[i, 0]),
                    "distance": float(self.top_dist[i, 0]),
                    "candidate_m": round(float(self.candidate_m[i]), 4),
                    "correct": int(self.correct[i]),
                    "correct_at_k": int(self.correct_at_k[i]),
                    "heading_est_deg": round(float(self.heading_est[i]), 4),
                    "heading_true_deg": round(float(self.heading_true[i]), 4),
                    "heading_error_deg": round(float(err[i]), 4),
                }
            )
        return out


def evaluate_topk(
    name: str,
    queries: I64,
    top_ids: I64,
    top_dist: F64,
    heading_est: npt.ArrayLike,
    poses: npt.ArrayLike,
    *,
    exclude: int,
    radius: float,
) -> Evaluation:
    """Score ranked candidates (any descriptor) against poses (N, 3, 4) by SPEC §5.

    ``heading_est[i]`` is the method's heading estimate (degrees) between query ``queries[i]``
    and its top-1 candidate ``top_ids[i, 0]`` (NaN if the method has none).
    """
    P = np.asarray(poses, dtype=np.float64)
    if P.ndim != 3 or P.shape[1:] not in ((3, 4), (4, 4)):
        raise ValueError(f"poses must have shape (N, 3, 4), got {P.shape}")
    if not radius > 0:
        raise ValueError(f"radius must be > 0, got {radius}")
    n = P.shape[0]
    t = P[:, :3, 3]
    gt, nearest = gt_positive(t, queries, exclude, radius)
    safe = np.where(top_ids >= 0, top_ids, 0)
    cand_m_all = np.linalg.norm(t[safe] - t[queries][:, None, :], axis=2)
    cand_m_all = np.where(top_ids >= 0, cand_m_all, np.inf)
    within = cand_m_all <= radius
    correct = within[:, 0].copy()
    Rq = P[queries, :3, :3]
    Rc = P[safe[:, 0], :3, :3]
    h_true = yaw_degrees(np.einsum("nji,njk->nik", Rq, Rc))
    ev = Evaluation(
        name=name,
        exclude=exclude,
        radius=float(radius),
        n_frames=n,
        queries=queries,
        gt_positive=gt,
        nearest_db_m=nearest,
        top_ids=top_ids,
        top_dist=top_dist,
        correct=correct,
        correct_at_k=np.asarray(within.any(axis=1), dtype=np.bool_),
        candidate_m=cand_m_all[:, 0],
        heading_est=np.asarray(heading_est, dtype=np.float64),
        heading_true=h_true,
        within=within,
    )
    return ev


def evaluate_solid(
    r: npt.ArrayLike,
    a: npt.ArrayLike,
    poses: npt.ArrayLike,
    *,
    exclude: int = 50,
    radius: float = 5.0,
    k: int = 5,
    refine: bool = True,
    use_extension: bool = True,
    name: str = "SOLiD",
    progress: Callable[[int], None] | None = None,
) -> Evaluation:
    """SPEC §5 evaluation of per-frame R-SOLiD (N, Nr) and A-SOLiD (N, Na) against poses (N, 3, 4).

    Headings come from ``solid.heading`` when the extension is importable and ``use_extension``,
    else from :func:`heading_numpy` (the same SPEC §3 rule).
    """
    R = np.asarray(r, dtype=np.float32)
    A = np.asarray(a, dtype=np.float32)
    P = np.asarray(poses, dtype=np.float64)
    if not (R.shape[0] == A.shape[0] == P.shape[0]):
        raise ValueError(f"{R.shape[0]} R-SOLiDs, {A.shape[0]} A-SOLiDs and {P.shape[0]} poses")
    queries, ids, dists = cosine_topk(R, exclude, k, progress=progress)
    top1 = np.where(ids[:, 0] >= 0, ids[:, 0], 0)
    h = _headings_extension(A[queries], A[top1], refine) if use_extension else None
    if h is None:
        h = heading_numpy(A[queries], A[top1], refine)
    return evaluate_topk(name, queries, ids, dists, h, P, exclude=exclude, radius=radius)


# --------------------------------------------------------------------------------------------
# reports


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return None if math.isnan(float(o)) else float(o)
    raise TypeError(f"not JSON serialisable: {type(o)}")


def metrics_document(main: Evaluation, baselines: AbcSequence[Evaluation] = (), extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """``metrics.json`` content: the main method's metrics at top level, baselines by name."""
    doc = dict(main.metrics())
    if extra:
        doc.update(extra)
    if baselines:
        doc["baselines"] = {b.name.lower().replace(" ", ""): b.metrics() for b in baselines}
    return doc


def write_report(
    out_dir: os.PathLike[str] | str,
    main: Evaluation,
    baselines: AbcSequence[Evaluation] = (),
    *,
    extra: dict[str, Any] | None = None,
    plots: bool = True,
) -> dict[str, Path]:
    """Write metrics.json, queries.csv (+ queries_<baseline>.csv), pr.png and roc.png atomically."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: dict[str, Path] = {}
    doc = metrics_document(main, baselines, extra)
    p = out / "metrics.json"
    _atomic_write_bytes(p, (json.dumps(doc, indent=2, default=_json_default) + "\n").encode())
    written["metrics"] = p
    for ev, fname in [(main, "queries.csv")] + [
        (b, f"queries_{b.name.lower().replace(' ', '')}.csv") for b in baselines
    ]:
        buf = _io.StringIO()
        w = csv.DictWriter(buf, fieldnames=list(CSV_COLUMNS), lineterminator="\n")
        w.writeheader()
        w.writerows(ev.rows())
        p = out / fname
        _atomic_write_bytes(p, buf.getvalue().encode())
        written[fname] = p
    if plots:
        seq = (extra or {}).get("sequence")
        title = None
        if seq:
            title = f"{Path(str(seq)).name}: exclude {main.exclude} frames, radius {main.radius:g} m, {main.queries.size} queries"
        written.update(plot_curves(out, [main, *baselines], title))
    return written


def plot_curves(out_dir: Path, evals: AbcSequence[Evaluation], title: str | None = None) -> dict[str, Path]:
    """PR and ROC curves of every method on shared axes, as pr.png and roc.png.

    Uses matplotlib's object API with the Agg canvas, so it never touches pyplot's global state
    (safe inside notebooks and GUIs).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    written: dict[str, Path] = {}
    ev0 = evals[0]
    sub = title or f"exclude {ev0.exclude} frames, radius {ev0.radius:g} m, {ev0.queries.size} queries"
    for kind in ("pr", "roc"):
        fig = Figure(figsize=(5.2, 4.4), dpi=120)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        for ev in evals:
            m = ev.metrics()
            if kind == "pr":
                _, p, r = ev.pr()
                f1 = m["f1_max"]
                ax.plot(np.r_[0.0, r], np.r_[1.0 if p.size == 0 else p[0], p], lw=1.8, label=f"{ev.name} (F1 max {f1:.3f}, R@1 {_fmt(m['recall_at_1'])})")
            else:
                _, fpr, tpr = ev.roc()
                ax.plot(fpr, tpr, lw=1.8, label=f"{ev.name} (AUC {_fmt(m['auc'])})")
        if kind == "pr":
            ax.set_xlabel("recall")
            ax.set_ylabel("precision")
            ax.set_title(f"Precision–recall\n{sub}", fontsize=9)
        else:
            ax.plot([0, 1], [0, 1], color="0.7", lw=0.8, ls="--")
            ax.set_xlabel("false-positive rate (incorrect top-1 accepted)")
            ax.set_ylabel("true-positive rate (correct top-1 accepted)")
            ax.set_title(f"ROC of top-1 matches\n{sub}", fontsize=9)
        ax.set_xlim(0, 1.0)
        ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
        ax.legend(loc="lower left" if kind == "pr" else "lower right", fontsize=8)
        fig.tight_layout()
        buf = _io.BytesIO()
        fig.savefig(buf, format="png")
        png = Path(out_dir) / f"{kind}.png"
        _atomic_write_bytes(png, buf.getvalue())
        written[kind] = png
    return written


def _fmt(v: Any) -> str:
    return "n/a" if v is None else f"{v:.3f}"
