"""The figures of an evaluation, for real data as for the simulator.

- ``pr.png`` / ``roc.png``: every method's curve, its F1-max point (a dot) and the run's operating
  threshold (a cross);
- ``trajectory.png``: the places seen from above with the accepted loops drawn between query and
  candidate, correct ones green, beyond the radius orange, with a wrong pose red;
- ``distances.png``: the query × database R-SOLiD distance matrix (entries a query could not be
  matched with left blank), with the ground-truth revisits outlined;
- ``heading.png``: estimated against true heading of the correct top-1 matches.

Matplotlib's object API with the Agg canvas only: no pyplot global state, safe in notebooks.
"""

from __future__ import annotations

import io as _io
from collections.abc import Sequence as AbcSequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["figure", "plot_distance_matrix", "plot_heading", "plot_pr_roc", "plot_trajectory", "save"]

TRUE = "#1a9641"  # green: a true loop
FALSE = "#d7191c"  # red: a false loop
BEYOND = "#fdae61"  # orange: a loop longer than the radius (not scored as the same place)
PATH = "0.35"


def figure(w: float = 5.4, h: float = 4.6) -> Any:
    """An empty ``w`` × ``h`` inch figure on the Agg canvas (no pyplot state)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h), dpi=120)
    FigureCanvasAgg(fig)
    return fig


def save(fig: Any, path: Path) -> Path:
    """Writes the figure as PNG."""
    fig.tight_layout()
    buf = _io.BytesIO()
    fig.savefig(buf, format="png")
    path.write_bytes(buf.getvalue())
    return path


def _fmt(v: Any) -> str:
    return "n/a" if v is None else f"{v:.3f}"


def plot_pr_roc(out: Path, evals: AbcSequence[Any], subtitle: str) -> dict[str, Path]:
    """``pr.png`` and ``roc.png`` of every evaluation on shared axes."""
    written: dict[str, Path] = {}
    for kind in ("pr", "roc"):
        fig = figure()
        ax = fig.add_subplot()
        for ev in evals:
            m = ev.metrics()
            f1, f1_thr = ev.f1_max()
            if kind == "pr":
                thr, p, r = ev.pr()
                line = ax.plot(np.r_[0.0, r], np.r_[1.0 if p.size == 0 else p[0], p], lw=1.8,
                               label=f"{ev.name} (F1 max {_fmt(f1)}, R@1 {_fmt(m['recall_at_1'])})")[0]
                pts = [(f1_thr, "o", "F1 max")]
                if ev.threshold is not None:
                    pts.append((ev.threshold, "X", f"threshold {ev.threshold:g}"))
                for t, marker, what in pts:
                    if t is None or thr.size == 0:
                        continue
                    i = int(np.searchsorted(thr, t, side="right")) - 1
                    if i >= 0:
                        ax.plot(r[i], p[i], marker, color=line.get_color(), ms=8, mec="k", label=f"{ev.name}: {what}")
            else:
                thr, fpr, tpr = ev.roc()
                line = ax.plot(fpr, tpr, lw=1.8, label=f"{ev.name} (AUC {_fmt(m['auc'])})")[0]
                pts = [(f1_thr, "o", "F1 max")]
                if ev.threshold is not None:
                    pts.append((ev.threshold, "X", f"threshold {ev.threshold:g}"))
                for t, marker, what in pts:
                    if t is None:
                        continue
                    i = int(np.searchsorted(thr, t, side="right")) - 1
                    if i >= 0:
                        ax.plot(fpr[i], tpr[i], marker, color=line.get_color(), ms=8, mec="k", label=f"{ev.name}: {what}")
        if kind == "pr":
            ax.set_xlabel("recall")
            ax.set_ylabel("precision")
            ax.set_title(f"Precision–recall\n{subtitle}", fontsize=9)
        else:
            ax.plot([0, 1], [0, 1], color="0.7", lw=0.8, ls="--")
            ax.set_xlabel("false-positive rate (incorrect top-1 accepted)")
            ax.set_ylabel("true-positive rate (correct top-1 accepted)")
            ax.set_title(f"ROC of top-1 matches\n{subtitle}", fontsize=9)
        ax.set_xlim(0, 1.0)
        ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
        ax.legend(loc="lower left" if kind == "pr" else "lower right", fontsize=7)
        written[kind] = save(fig, out / f"{kind}.png")
    return written


def _draw_loops(ax: Any, xy: npt.NDArray[np.float64], loops: AbcSequence[tuple[int, int, bool]], names: tuple[str, str], lw: float, alpha: float) -> None:
    """Loops (i, j, good) between positions `xy`, seen from above: good green, bad red, each kind
    counted in the legend under its name; metres on both axes."""
    good = 0
    for i, j, ok in loops:
        good += ok
        ax.plot([xy[i, 0], xy[j, 0]], [xy[i, 1], xy[j, 1]], color=TRUE if ok else FALSE, lw=lw, alpha=alpha, zorder=3)
    ax.plot([], [], color=TRUE, label=f"{names[0]} ({good})")
    ax.plot([], [], color=FALSE, label=f"{names[1]} ({len(loops) - good})")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def plot_trajectory(path: Path, ev: Any, poses: npt.NDArray[np.float64], sessions: npt.NDArray[Any], subtitle: str) -> Path:
    """Places from above (one line per session) and the accepted loops: correct green, beyond the
    radius orange, with a pose off red."""
    fig = figure(6.0, 5.6)
    ax = fig.add_subplot()
    xy = poses[:, :2, 3]
    for k, s in enumerate(np.unique(sessions)):
        m = (sessions == s) & np.isfinite(xy).all(axis=1)
        ax.plot(xy[m, 0], xy[m, 1], color=PATH if k == 0 else "#2c7bb6", lw=1.0, label=f"session {int(s)}")
    acc = np.nonzero(ev.accepted)[0]
    loops = [(int(ev.query[i]), int(ev.ids[i, 0]), bool(ev.correct[i])) for i in acc if ev.correct[i] or not ev.place_correct[i]]
    # Loops longer than the radius are not wrong loops: drawn apart, their count in the legend.
    beyond = [(int(ev.query[i]), int(ev.ids[i, 0])) for i in acc if not ev.place_correct[i]]
    for i, j in beyond:
        ax.plot([xy[i, 0], xy[j, 0]], [xy[i, 1], xy[j, 1]], color=BEYOND, lw=1.0, alpha=0.8, zorder=3)
    ax.plot([], [], color=BEYOND, label=f"beyond the {ev.radius:g} m radius ({len(beyond)})")
    loops = [(i, j, ok) for i, j, ok in loops if ok] + [(int(ev.query[i]), int(ev.ids[i, 0]), False) for i in acc if ev.place_correct[i] and not ev.correct[i]]
    _draw_loops(ax, xy, loops, ("correct loop", "pose off"), lw=1.0, alpha=0.8)
    thr = "" if ev.threshold is None else f" at threshold {ev.threshold:g}"
    ax.set_title(f"Accepted loops{thr}\n{subtitle}", fontsize=9)
    ax.legend(loc="best", fontsize=7)
    ax.grid(alpha=0.3)
    return save(fig, path)


def plot_distance_matrix(path: Path, ev: Any, database: Any, subtitle: str, max_rows: int = 600) -> Path:
    """Query × database R-SOLiD distances (from the core, ``Database.distances``); entries a
    query could not be matched with are blank; ground-truth revisits (within the radius) outlined."""
    q = ev.query
    if q.size > max_rows:
        q = q[np.linspace(0, q.size - 1, max_rows).astype(np.int64)]
    n = len(database)
    R = np.asarray(database.r)
    P = np.asarray(database.poses, dtype=np.float64)[:, :, 3]
    elig = dict(zip(ev.query.tolist(), ev.eligible.tolist()))
    M = np.full((q.size, n), np.nan, dtype=np.float32)
    near = np.zeros((q.size, n), dtype=bool)
    for row, qi in enumerate(q.tolist()):
        e = elig[qi]
        M[row, :e] = np.asarray(database.distances(R[qi]))[:e]
        near[row, :e] = np.linalg.norm(P[:e] - P[qi], axis=1) <= ev.radius
    fig = figure(6.0, 5.0)
    ax = fig.add_subplot()
    im = ax.imshow(M, aspect="auto", cmap="viridis_r", interpolation="nearest", vmin=0.0, vmax=float(np.nanmax(M)) if np.isfinite(M).any() else 1.0)
    if near.any():
        ax.contour(near.astype(float), levels=[0.5], colors=[FALSE], linewidths=0.6)
    fig.colorbar(im, ax=ax, label="R-SOLiD cosine distance")
    ax.set_xlabel("database place id")
    ax.set_ylabel("query (row)" if q.size == ev.query.size else f"query ({q.size} of {ev.query.size})")
    ax.set_title(f"Query × database distances (red outline: within {ev.radius:g} m)\n{subtitle}", fontsize=9)
    return save(fig, path)


def plot_heading(path: Path, ev: Any, subtitle: str) -> Path:
    """Estimated against true heading of the correct top-1 matches."""
    c = ev.correct
    est = ev.heading_deg[c]
    true = np.asarray(ev.scores.true_heading_deg)[c]
    err = np.asarray(ev.scores.rotation_errors())
    fig = figure(5.0, 4.8)
    ax = fig.add_subplot()
    ax.plot([-180, 180], [-180, 180], color="0.6", lw=0.8, ls="--", label="estimate = truth")
    ax.scatter(true, est, s=9, color="#2c7bb6", label=f"correct top-1 ({int(c.sum())})")
    lim = max(10.0, float(np.nanmax(np.abs(np.r_[est, true]))) * 1.1) if c.any() else 180.0
    lim = min(lim, 180.0)
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_aspect("equal")
    ax.set_xlabel("true heading ψ [deg] (poses)")
    ax.set_ylabel("estimated heading [deg]")
    mean = f"{err.mean():.2f}°" if err.size else "n/a"
    ax.set_title(f"Heading of correct matches (mean error {mean})\n{subtitle}", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=7)
    return save(fig, path)


def plot_before_after(
    path: Path,
    before: npt.NDArray[np.float64],
    after: npt.NDArray[np.float64],
    edges: AbcSequence[tuple[int, int, bool]],
    subtitle: str,
    truth: npt.NDArray[np.float64] | None = None,
) -> Path:
    """Two panels from above: the odometry and the optimised trajectory (with the truth when
    given), each with its loop edges (kept by the optimum in green, rejected in red)."""
    fig = figure(10.0, 5.0)
    for k, (P, name) in enumerate(((before, "odometry"), (after, "optimised"))):
        ax = fig.add_subplot(1, 2, k + 1)
        xy = P[:, :2, 3]
        if truth is not None:
            ax.plot(truth[:, 0, 3], truth[:, 1, 3], color="#999999", lw=2.0, alpha=0.6, label="truth")
        ax.plot(xy[:, 0], xy[:, 1], color=PATH, lw=1.0, label=name)
        _draw_loops(ax, xy, edges, ("loop kept", "loop rejected"), lw=0.8, alpha=0.7)
        ax.set_title(f"{name}\n{subtitle}", fontsize=9)
        ax.legend(loc="best", fontsize=7)
        ax.grid(alpha=0.3)
    return save(fig, path)
