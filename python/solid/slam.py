"""From loops to a consistent map: the pose graph of a run, its robust optimisation, and anchors.

A :class:`PoseGraph` holds one vertex per frame (id = the frame's index in its recording, as in
``loops.csv``; initial value = its given pose ``T_world_sensor``), an odometry edge between
consecutive frames (information from :class:`OdometryNoise`) and a loop edge per verified loop
(``T_query_candidate``, information from the registration: :attr:`solid.Loop.information`).
:meth:`PoseGraph.write_g2o` writes it whole; :func:`optimize_graph` optimises it with GTSAM
(``pip install solid-lidar[slam]``) under a robust scheme; :func:`estimate_anchor` places a
session in a saved map's world from its verified cross-session loops. docs/slam.md shows the
whole path and the frame conventions.

Every information matrix here is in g2o's order, translation first, for the error ``ξ`` of an
edge ``i → j`` measuring ``Z``: ``Exp(ξ) = Z⁻¹ · T_world_i⁻¹ · T_world_j`` (on the right of the
measurement, as g2o's ``EDGE_SE3:QUAT`` and GTSAM's ``BetweenFactor<Pose3>``), rotation in radians.
"""

from __future__ import annotations

import math
from collections.abc import Sequence as AbcSequence
from collections.abc import Set as AbcSet
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from .arrays import F64, I64
from .transforms import quaternion

__all__ = [
    "CHI2_6_MEDIAN",
    "GNC_INLIER_CHI2",
    "ODOMETRY_SCALE_MAX",
    "ROBUST_SCHEMES",
    "Anchor",
    "OdometryNoise",
    "PoseGraph",
    "SlamResult",
    "absolute_trajectory_error",
    "add_loop_edges",
    "adjoint",
    "anchor_of_run",
    "estimate_anchor",
    "fit_odometry_scale",
    "graph_from_run",
    "loop_chi2",
    "loop_residuals",
    "odometry_graph",
    "optimize_graph",
    "optimize_in_map",
    "optimize_run",
    "optimize_with_loops_of",
    "relative_pose_error",
    "require_gtsam",
    "write_kitti",
    "write_tum",
]


#: The robust schemes :func:`optimize_graph` offers; the first is the default (chosen by
#: measurement on the simulator with false loops injected: docs/slam.md#robust-back-end).
ROBUST_SCHEMES = ("gnc-tls", "cauchy", "dcs", "huber", "gnc-gm", "none")

#: How far from 1 the norm of a quaternion :meth:`PoseGraph.read_g2o` reads may be (the files
#: hold unit quaternions, printed to a few digits).
QUATERNION_TOLERANCE = 1e-3

_INSTALL = "the pose-graph back-end needs GTSAM: pip install 'solid-lidar[slam]' (or pip install gtsam)"


def require_gtsam() -> Any:
    """The ``gtsam`` module, or an ImportError that says how to install it."""
    try:
        import gtsam
    except ImportError as e:
        raise ImportError(_INSTALL) from e
    return gtsam


def as4(P: npt.ArrayLike) -> F64:
    """Poses (..., 3, 4) or (..., 4, 4) as (..., 4, 4)."""
    a = np.asarray(P, dtype=np.float64)
    if a.shape[-2:] == (4, 4):
        return a.copy()
    if a.shape[-2:] != (3, 4):
        raise ValueError(f"poses must have shape (..., 3, 4) or (..., 4, 4), got {a.shape}")
    out = np.zeros(a.shape[:-2] + (4, 4))
    out[..., :3, :] = a
    out[..., 3, 3] = 1.0
    return out


def inv(T: F64) -> F64:
    """Inverse of rigid transforms (..., 4, 4)."""
    R = T[..., :3, :3]
    out = np.zeros_like(T)
    Rt = np.swapaxes(R, -1, -2)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def _skew(v: F64) -> F64:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def adjoint(T: npt.ArrayLike) -> F64:
    """The adjoint of a rigid transform in g2o's order (translation first): ``T·Exp(ξ)·T⁻¹ =
    Exp(adjoint(T)·ξ)`` for ``ξ = (v, ω)``."""
    M = as4(T)
    R, t = M[:3, :3], M[:3, 3]
    A = np.zeros((6, 6))
    A[:3, :3] = R
    A[3:, 3:] = R
    A[:3, 3:] = _skew(t) @ R
    return A


@dataclass(frozen=True)
class OdometryNoise:
    """The odometry edges' noise: standard deviations per axis that grow with the step.

    ``σ_t = translation_floor_m + translation_fraction × step`` (metres, each axis) and
    ``σ_r = rotation_floor_deg + rotation_deg_per_m × step`` (degrees, each axis), ``step`` the
    distance between the two frames' given poses. The defaults are those of a LiDAR(-inertial)
    odometry drifting about 1 % of the distance travelled (docs/slam.md#odometry-noise).
    """

    translation_fraction: float = 0.02
    translation_floor_m: float = 0.01
    rotation_deg_per_m: float = 0.04
    rotation_floor_deg: float = 0.02

    def __post_init__(self) -> None:
        for k, v in vars(self).items():
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"OdometryNoise.{k} must be a finite value >= 0, got {v}")
        if self.translation_floor_m <= 0 or self.rotation_floor_deg <= 0:
            raise ValueError("OdometryNoise floors must be > 0 (an edge needs a finite information)")

    def scaled(self, factor: float) -> OdometryNoise:
        """The same noise with every standard deviation multiplied by ``factor`` (> 0)."""
        if not (math.isfinite(factor) and factor > 0):
            raise ValueError(f"an odometry noise factor must be a finite value > 0, got {factor}")
        return OdometryNoise(*(factor * v for v in (self.translation_fraction, self.translation_floor_m, self.rotation_deg_per_m, self.rotation_floor_deg)))

    def information(self, step_m: float) -> F64:
        """The 6×6 information (translation first) of an odometry edge over ``step_m`` metres."""
        st = self.translation_floor_m + self.translation_fraction * step_m
        sr = math.radians(self.rotation_floor_deg + self.rotation_deg_per_m * step_m)
        return np.diag([1 / st**2] * 3 + [1 / sr**2] * 3)


@dataclass
class PoseGraph:
    """A pose graph: vertices (``ids``, initial ``poses`` ``T_world_sensor`` (N, 4, 4)) and edges
    ``i → j`` (indices into the vertices) measuring ``T_i⁻¹·T_j`` with an information matrix."""

    ids: I64
    poses: F64
    edge_from: I64 = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    edge_to: I64 = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    measurements: F64 = field(default_factory=lambda: np.zeros((0, 4, 4)))
    information: F64 = field(default_factory=lambda: np.zeros((0, 6, 6)))
    #: "odometry" or "loop", per edge.
    kinds: list[str] = field(default_factory=list)
    #: The vertices (indices) the optimisation holds at their poses: the first by default, a
    #: saved map's places when a session is optimised into the map (:func:`optimize_in_map`).
    fixed: list[int] = field(default_factory=lambda: [0])

    def __len__(self) -> int:
        return len(self.ids)

    def add_edge(self, i: int, j: int, measurement: npt.ArrayLike, information: npt.ArrayLike, kind: str) -> None:
        """Append the edge ``i → j`` (vertex indices)."""
        info = np.asarray(information, dtype=np.float64)
        if info.shape != (6, 6) or not np.isfinite(info).all():
            raise ValueError(f"an edge's information must be a finite 6×6 matrix, got shape {info.shape}")
        self.edge_from = np.r_[self.edge_from, i].astype(np.int64)
        self.edge_to = np.r_[self.edge_to, j].astype(np.int64)
        self.measurements = np.concatenate([self.measurements, as4(measurement)[None]])
        self.information = np.concatenate([self.information, (info + info.T)[None] / 2])
        self.kinds.append(kind)

    def loops(self) -> list[int]:
        """Indices of the loop edges."""
        return [k for k, s in enumerate(self.kinds) if s == "loop"]

    def in_frame(self, T_new_old: npt.ArrayLike) -> PoseGraph:
        """The same graph with every pose re-expressed by ``X ↦ T·X·T⁻¹`` (vertices and edges;
        informations carried by the adjoint): e.g. from the LiDAR frame back into the frame of
        poses given with a calibration."""
        T = as4(T_new_old)
        Ti = inv(T)
        A = np.linalg.inv(adjoint(T))
        return PoseGraph(
            ids=self.ids.copy(),
            poses=T @ self.poses @ Ti,
            edge_from=self.edge_from.copy(),
            edge_to=self.edge_to.copy(),
            measurements=T @ self.measurements @ Ti,
            information=np.einsum("ji,ejk,kl->eil", A, self.information, A),
            kinds=list(self.kinds),
            fixed=list(self.fixed),
        )

    def g2o_lines(self, poses: F64 | None = None) -> list[str]:
        """The graph in g2o's text form: ``VERTEX_SE3:QUAT id x y z qx qy qz qw`` per vertex
        (``poses`` or the initial values), then ``EDGE_SE3:QUAT from to x y z qx qy qz qw`` and the
        upper triangle of the information, translation first. Vertices without a pose (a run
        without poses) are left out."""
        P = self.poses if poses is None else poses
        lines = [f"VERTEX_SE3:QUAT {int(v)} {_pose_text(p)}" for v, p in zip(self.ids, P) if np.isfinite(p).all()]
        for i, j, Z, info in zip(self.edge_from, self.edge_to, self.measurements, self.information):
            upper = " ".join(f"{info[a, b]:.9g}" for a in range(6) for b in range(a, 6))
            lines.append(f"EDGE_SE3:QUAT {int(self.ids[i])} {int(self.ids[j])} {_pose_text(Z)} {upper}")
        return lines

    def write_g2o(self, path: Path | str, poses: F64 | None = None) -> int:
        """Write :meth:`g2o_lines` to ``path``; returns the number of edges."""
        Path(path).write_text("".join(s + "\n" for s in self.g2o_lines(poses)), encoding="utf-8")
        return len(self.kinds)

    @classmethod
    def read_g2o(cls, path: Path | str) -> PoseGraph:
        """The graph of a g2o file :meth:`write_g2o` wrote (``solid detect --g2o``, ``solid
        optimize``'s ``graph.g2o``), to optimise again without running the detector: vertices in
        the file's order, each edge ``i → j`` with its measurement and information; an edge
        between two vertices next to each other in that order is odometry, any other a loop (a
        loop never joins consecutive frames: the detector excludes recent ones). A file without
        vertices (``solid detect --g2o`` without poses) holds loops alone: its vertices are the
        frames they join, without a pose (NaN).

        What a graph cannot use is refused with :class:`solid.io.ReadError` naming the file, the
        line and the reason, never dropped or weighted silently: a value that is not finite, a
        quaternion whose norm is not 1 (within :data:`QUATERNION_TOLERANCE`), an information
        matrix that is zero or not positive semidefinite, an edge from a vertex to itself."""
        from .datasets.poses import quat_to_matrix
        from .errors import ReadError

        def pose(v: list[float]) -> F64:
            if not all(math.isfinite(x) for x in v):
                raise ValueError("a value is not finite")
            q = np.asarray(v[3:7])
            norm = math.hypot(*q)
            if abs(norm - 1.0) > QUATERNION_TOLERANCE:
                raise ValueError(f"the quaternion (qx qy qz qw) has norm {norm:.6g}, not 1 (a rotation's)")
            T = np.eye(4)
            T[:3, :3] = quat_to_matrix((q / norm)[None])[0]
            T[:3, 3] = v[:3]
            return T

        def information(upper: list[float]) -> F64:
            info = np.zeros((6, 6))
            k = iter(upper)
            for a in range(6):
                for b in range(a, 6):
                    info[a, b] = info[b, a] = next(k)
            if not np.isfinite(info).all():
                raise ValueError("the information matrix holds a value that is not finite")
            eig = np.linalg.eigvalsh(info)
            if eig[-1] <= 0.0:
                raise ValueError("the information matrix is zero (the edge would carry no weight)")
            if eig[0] < -1e-9 * eig[-1]:
                raise ValueError(f"the information matrix is not positive semidefinite (eigenvalue {eig[0]:.6g})")
            return info

        ids: list[int] = []
        poses: list[F64] = []
        edges: list[tuple[int, int, F64, F64]] = []
        for n, line in enumerate(Path(path).read_text(encoding="utf-8").splitlines(), 1):
            f = line.split()
            try:
                if f and f[0] == "VERTEX_SE3:QUAT" and len(f) == 9:
                    ids.append(int(f[1]))
                    poses.append(pose([float(x) for x in f[2:]]))
                elif f and f[0] == "EDGE_SE3:QUAT" and len(f) == 31:
                    i, j = int(f[1]), int(f[2])
                    if i == j:
                        raise ValueError(f"an edge from vertex {i} to itself")
                    edges.append((i, j, pose([float(x) for x in f[3:10]]), information([float(x) for x in f[10:]])))
                elif f and not f[0].startswith("#"):
                    raise ValueError(f"not a VERTEX_SE3:QUAT (9 fields) or EDGE_SE3:QUAT (31 fields) line: {f[0]}, {len(f)} fields")
            except ValueError as e:
                raise ReadError(path, f"line {n}: {e}") from None
        loops_only = not ids
        if loops_only:
            # `solid detect --g2o` without poses: loop edges alone, between frames without a value.
            ids = sorted({v for i, j, _, _ in edges for v in (i, j)})
            poses = [np.full((4, 4), np.nan)] * len(ids)
        index = {v: k for k, v in enumerate(ids)}
        g = cls(ids=np.asarray(ids, dtype=np.int64), poses=np.stack(poses) if poses else np.zeros((0, 4, 4)))
        for i, j, Z, info in edges:
            if i not in index or j not in index:
                raise ReadError(path, f"the edge {i} → {j} joins a vertex the file does not hold")
            a, b = index[i], index[j]
            g.add_edge(a, b, Z, info, "odometry" if abs(a - b) == 1 and not loops_only else "loop")
        return g

    def with_loops_of(self, other: PoseGraph, *, tolerance_m: float = 1e-3, tolerance_deg: float = 0.01) -> PoseGraph:
        """This graph (vertices, odometry) with the loop edges of ``other`` (e.g. a run's graph
        read back by :meth:`read_g2o`), matched by vertex id. Refused (ValueError) when a loop
        joins a frame this graph does not hold, or when a vertex both hold has other poses in
        ``other`` (beyond the tolerances): its loops were then measured in another frame
        (another calibration) or for other frames."""
        index = {int(v): k for k, v in enumerate(self.ids)}
        for v, P in zip(other.ids, other.poses):
            k = index.get(int(v))
            if k is None or not np.isfinite(P).all():
                continue
            d = inv(self.poses[k]) @ P
            # From the antisymmetric part: a pose file's rotations are orthonormal only to its digits.
            w = np.array([d[2, 1] - d[1, 2], d[0, 2] - d[2, 0], d[1, 0] - d[0, 1]]) / 2
            angle = math.degrees(math.atan2(float(np.linalg.norm(w)), (float(np.trace(d[:3, :3])) - 1) / 2))
            if np.linalg.norm(d[:3, 3]) > tolerance_m or angle > tolerance_deg:
                raise ValueError(
                    f"frame {int(v)} has other poses in the two graphs ({np.linalg.norm(d[:3, 3]):.3g} m, {angle:.3g}° apart): "
                    "the loops were measured with other poses or another calibration"
                )
        out = PoseGraph(
            ids=self.ids.copy(),
            poses=self.poses.copy(),
            edge_from=self.edge_from.copy(),
            edge_to=self.edge_to.copy(),
            measurements=self.measurements.copy(),
            information=self.information.copy(),
            kinds=list(self.kinds),
            fixed=list(self.fixed),
        )
        for e in other.loops():
            i, j = int(other.ids[other.edge_from[e]]), int(other.ids[other.edge_to[e]])
            for v in (i, j):
                if v not in index:
                    raise ValueError(f"the loop {i} → {j} joins frame {v}, which this graph does not hold (select the frames of the run that found it)")
            out.add_edge(index[i], index[j], other.measurements[e], other.information[e], "loop")
        return out


def _pose_text(P: F64) -> str:
    qx, qy, qz, qw = quaternion(P[:3, :3])
    return f"{P[0, 3]:.9f} {P[1, 3]:.9f} {P[2, 3]:.9f} {qx:.12f} {qy:.12f} {qz:.12f} {qw:.12f}"


def odometry_graph(ids: npt.ArrayLike, poses: npt.ArrayLike, noise: OdometryNoise | None = None) -> PoseGraph:
    """A vertex per frame (``ids``, its pose ``T_world_sensor``) and an odometry edge between
    consecutive frames (``noise``); no edge when a pose is missing (NaN)."""
    noise = noise or OdometryNoise()
    P = as4(poses)
    g = PoseGraph(ids=np.asarray(ids, dtype=np.int64).copy(), poses=P)
    for k in range(len(P) - 1 if np.isfinite(P).all() else 0):
        Z = inv(P[k]) @ P[k + 1]
        g.add_edge(k, k + 1, Z, noise.information(float(np.linalg.norm(Z[:3, 3]))), "odometry")
    return g


def graph_from_run(
    result: Any,
    noise: OdometryNoise | None = None,
    poses: npt.ArrayLike | None = None,
) -> PoseGraph:
    """The pose graph of a :class:`solid.pipeline.PipelineResult`: a vertex per frame of the
    run (its pose: ``poses`` or the run's), odometry edges between consecutive frames, and a
    loop edge per verified loop between two frames of the run (loops into a prior map are left
    to :func:`estimate_anchor`)."""
    if poses is None and result.poses is None:
        # Without poses: no vertex values and no odometry, the loop edges alone.
        P = np.full((len(result.frames), 4, 4), np.nan)
    else:
        P = as4(result.poses if poses is None else poses)
    if P.shape[0] != len(result.frames):
        raise ValueError(f"{P.shape[0]} poses for {len(result.frames)} frames")
    g = odometry_graph(result.frame_ids, P, noise)
    add_loop_edges(g, result.loops(), int(result.map_size))
    return g


def add_loop_edges(graph: PoseGraph, loops: Any, base: int = 0) -> int:
    """Add a loop edge per verified loop between two places of the session (ids from ``base``,
    the number of prior-map places; loops into the map are left out); returns how many."""
    n = 0
    for lp in loops:
        if lp.pose is None or lp.information is None or int(lp.candidate) < base:
            continue
        graph.add_edge(int(lp.query) - base, int(lp.candidate) - base, lp.pose, lp.information, "loop")
        n += 1
    return n


# ---- how far the odometry drifts: measured on the loops ----------------------------------------

#: χ²(6)'s median: what half of the loops' χ² against the odometry stay under when the odometry
#: noise is honest (:func:`fit_odometry_scale`).
CHI2_6_MEDIAN = 5.348
#: The largest factor :func:`fit_odometry_scale` puts on the odometry noise (docs/slam.md#drift).
ODOMETRY_SCALE_MAX = 16.0


def _rotation_vector(R: F64) -> F64:
    """The rotation vectors (radians) of rotation matrices (..., 3, 3)."""
    w = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], axis=-1) / 2
    s = np.linalg.norm(w, axis=-1)
    c = (np.trace(R, axis1=-2, axis2=-1) - 1) / 2
    angle = np.arctan2(s, c)
    with np.errstate(invalid="ignore", divide="ignore"):
        f = np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 1.0)
    out = np.asarray(w * f[..., None], dtype=np.float64)
    # Near 180° the skew part vanishes and carries no axis: R ≈ 2·n·nᵀ − I there, so the axis is
    # the column of (R + I)/2 with the largest diagonal, normalised (its sign is free at π).
    near_pi = (s < 1e-6) & (c < 0)
    if np.any(near_pi):
        sym = (R[near_pi] + np.eye(3)) / 2
        col = np.argmax(np.diagonal(sym, axis1=-2, axis2=-1), axis=-1)
        axis = np.take_along_axis(sym, col[:, None, None], axis=-1)[..., 0]
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        out[near_pi] = axis * angle[near_pi][:, None]
    return out


def loop_residuals(graph: PoseGraph) -> tuple[F64, F64, F64]:
    """Each loop edge against the odometry alone: its error ``ξ`` at the graph's initial values
    (``Exp(ξ) = Z⁻¹·T_i⁻¹·T_j``, translation first, the rotation as a rotation vector), the
    covariance the odometry edges between its two frames give that relative pose (each edge's
    covariance carried to the loop's frame by the adjoint and summed: the chain's first-order
    covariance), and the loop's own covariance. Returns ``(ξ (L, 6), Σ_odometry (L, 6, 6),
    Σ_loop (L, 6, 6))`` in the order of :meth:`PoseGraph.loops`; a loop whose frames the
    odometry does not join (no chain of odometry edges, or no poses) gets NaN."""
    loops = graph.loops()
    L = len(loops)
    xi = np.full((L, 6), np.nan)
    s_odo = np.full((L, 6, 6), np.nan)
    s_loop = np.full((L, 6, 6), np.nan)
    n = len(graph)
    # The odometry edge k → k+1 of each vertex k (its covariance), where the graph has one.
    step_cov = np.full((max(n - 1, 0), 6, 6), np.nan)
    for e, kind in enumerate(graph.kinds):
        i, j = int(graph.edge_from[e]), int(graph.edge_to[e])
        if kind == "odometry" and j == i + 1:
            step_cov[i] = np.linalg.inv(graph.information[e])
    P = graph.poses
    for k, e in enumerate(loops):
        a, b = int(graph.edge_from[e]), int(graph.edge_to[e])
        lo, hi = min(a, b), max(a, b)
        C = step_cov[lo:hi]
        if hi == lo or not np.isfinite(C).all() or not np.isfinite(P[[a, b]]).all():
            continue
        # T_lo_hi = Z_lo ··· Z_hi−1: a perturbation on Z_m reaches the end through Ad(P_hi⁻¹·P_m+1).
        A = np.stack([adjoint(M) for M in inv(P[hi])[None] @ P[lo + 1 : hi + 1]])
        S = np.einsum("kab,kbc,kdc->ad", A, C, A)
        T = inv(P[a]) @ P[b]
        if a == hi:  # T_ab = T_lo_hi⁻¹: the perturbation comes out on the left
            Ad = adjoint(inv(T))
            S = Ad @ S @ Ad.T
        d = inv(graph.measurements[e]) @ T
        xi[k, :3] = d[:3, 3]
        xi[k, 3:] = _rotation_vector(d[:3, :3])
        s_odo[k] = S
        s_loop[k] = np.linalg.inv(graph.information[e])
    return xi, s_odo, s_loop


def loop_chi2(graph: PoseGraph, scale: float = 1.0) -> F64:
    """Each loop's χ² against the odometry alone, with the odometry's standard deviations
    multiplied by ``scale`` (:func:`loop_residuals`; NaN where the odometry does not join its
    frames)."""
    return _chi2(*loop_residuals(graph), scale)


def _chi2(xi: F64, s_odo: F64, s_loop: F64, scale: float) -> F64:
    """``ξᵀ·(scale²·Σ_odometry + Σ_loop)⁻¹·ξ`` of each loop of :func:`loop_residuals` (NaN where ξ is)."""
    out = np.full(len(xi), np.nan)
    for k in range(len(xi)):
        if np.isfinite(xi[k]).all():
            out[k] = float(xi[k] @ np.linalg.solve(scale**2 * s_odo[k] + s_loop[k], xi[k]))
    return out


def fit_odometry_scale(graph: PoseGraph, *, ceiling: float = ODOMETRY_SCALE_MAX) -> float:
    """The factor on the odometry noise that the loops say it needs: the smallest ``s ≥ 1`` at
    which the median of the loops' χ² against the odometry alone (:func:`loop_chi2`) is χ²(6)'s
    median; 1 without a loop the odometry joins, and 1 when even ``ceiling`` is not enough (the
    loops then disagree with the odometry beyond any drift it plausibly has: most are false). The median: true loops
    agree with the odometry within its real drift, false ones are far off whatever the noise,
    and as long as most loops are true they set it. An odometry that drifts more than the
    noise model assumes (a wheel odometry, a LIO on a hard stretch) otherwise makes every true
    loop look like an outlier to a robust back-end."""
    xi, s_odo, s_loop = loop_residuals(graph)
    ok = np.isfinite(xi).all(axis=1)
    if not ok.any():
        return 1.0
    xi, s_odo, s_loop = xi[ok], s_odo[ok], s_loop[ok]

    def median_chi2(s: float) -> float:
        return float(np.median(_chi2(xi, s_odo, s_loop, s)))

    if median_chi2(1.0) <= CHI2_6_MEDIAN:
        return 1.0
    if median_chi2(ceiling) > CHI2_6_MEDIAN:
        # Beyond any drift the ceiling allows: most loops are false (they agree with each other,
        # or the odometry would not be this far off), and a looser odometry would let them fold
        # the map. The noise stays as given.
        return 1.0
    lo, hi = 1.0, float(ceiling)
    for _ in range(30):  # the median falls as s grows: bisection, to 1e-9 of the ceiling
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if median_chi2(mid) > CHI2_6_MEDIAN else (lo, mid)
    return hi


# ---- optimisation ---------------------------------------------------------------------------------


def _gtsam_info(info_g2o: F64) -> F64:
    """g2o's order (translation first) → GTSAM's Pose3 order (rotation first)."""
    k = [3, 4, 5, 0, 1, 2]
    return np.asarray(info_g2o[np.ix_(k, k)], dtype=np.float64)


#: Kernel widths, in units of the whitened error (√χ²). A true loop, honestly weighed, has
#: √χ² around √6; a false one tens to thousands.
_KERNEL_WIDTH = {"cauchy": 3.0, "dcs": 3.0, "huber": 3.0}
#: GNC's inlier threshold: the χ² (6 degrees of freedom) exceeded by 1 in 1000 true edges.
GNC_INLIER_CHI2 = 22.46


def _factors(gtsam: Any, graph: PoseGraph, robust: str) -> tuple[Any, list[int]]:
    fg = gtsam.NonlinearFactorGraph()
    prior = gtsam.noiseModel.Diagonal.Sigmas(np.full(6, 1e-6))
    for v in graph.fixed:
        fg.add(gtsam.PriorFactorPose3(int(graph.ids[v]), gtsam.Pose3(graph.poses[v]), prior))
    known = list(range(len(graph.fixed)))
    for e, (i, j, Z, info, kind) in enumerate(
        zip(graph.edge_from, graph.edge_to, graph.measurements, graph.information, graph.kinds)
    ):
        model: Any = gtsam.noiseModel.Gaussian.Information(_gtsam_info(info))
        if kind == "loop" and robust in _KERNEL_WIDTH:
            m = gtsam.noiseModel.mEstimator
            kernel = {"cauchy": m.Cauchy, "dcs": m.DCS, "huber": m.Huber}[robust].Create(_KERNEL_WIDTH[robust])
            model = gtsam.noiseModel.Robust.Create(kernel, model)
        fg.add(gtsam.BetweenFactorPose3(int(graph.ids[i]), int(graph.ids[j]), gtsam.Pose3(Z), model))
        if kind != "loop":
            known.append(len(graph.fixed) + e)
    return fg, known


def optimize_graph(graph: PoseGraph, robust: str = ROBUST_SCHEMES[0], *, max_iterations: int = 100) -> tuple[F64, F64]:
    """Optimise ``graph`` with GTSAM (Levenberg–Marquardt) from its initial values, the
    vertices :attr:`PoseGraph.fixed` held at their poses. ``robust`` (one of
    :data:`ROBUST_SCHEMES`) treats the loop edges:
    ``gnc-tls``/``gnc-gm`` graduated non-convexity with a truncated-least-squares / Geman–McClure
    cost (odometry known to be inliers), ``cauchy``/``dcs``/``huber`` an M-estimator kernel,
    ``none`` plain least squares. Returns the optimised poses (N, 4, 4) and each loop edge's
    weight in [0, 1] (how much the optimum trusts it; 1 without a robust scheme). GNC-TLS's
    own minimum is checked against that of the loops a Cauchy optimum keeps (:func:`_tls_guard`,
    docs/slam.md#robust-back-end)."""
    if robust not in ROBUST_SCHEMES:
        raise ValueError(f"robust must be one of {', '.join(ROBUST_SCHEMES)}, got {robust!r}")
    gtsam = require_gtsam()
    if len(graph) == 0:
        return np.zeros((0, 4, 4)), np.zeros(0)
    fg, known = _factors(gtsam, graph, robust)
    init = gtsam.Values()
    for v, P in zip(graph.ids, graph.poses):
        init.insert(int(v), gtsam.Pose3(P))
    lm = gtsam.LevenbergMarquardtParams()
    lm.setMaxIterations(max_iterations)
    loops = graph.loops()
    weights = np.ones(len(loops))
    if robust.startswith("gnc") and loops:
        params = gtsam.GncLMParams(lm)
        params.setLossType(gtsam.GncLossType.TLS if robust == "gnc-tls" else gtsam.GncLossType.GM)
        params.setKnownInliers(known)
        opt = gtsam.GncLMOptimizer(fg, init, params)
        opt.setInlierCostThresholds(GNC_INLIER_CHI2 / 2)  # GTSAM's factor error is χ²/2
        values = opt.optimize()
        w = np.asarray(opt.getWeights())
        weights = np.array([w[len(graph.fixed) + e] for e in loops])
        if robust == "gnc-tls":
            # TLS stops with weights within a tolerance of 0 or 1, but a loop's information so
            # outweighs a long odometry chain's that a "0" of 1e-5 still bends the map: the
            # optimum returned is that of the loops kept.
            values = _kept_optimum(gtsam, fg, init, lm, w > 0.5)
            # GNC is a heuristic for the TLS cost and can settle in a worse minimum (every loop
            # out, the odometry's: one true loop moved to the adjacent keyframe flipped it,
            # docs/slam.md#robust-back-end). The loops a Cauchy kernel's optimum finds within
            # the inlier threshold are a second candidate; the lower TLS cost wins.
            values, weights = _tls_guard(gtsam, graph, fg, init, lm, known, w > 0.5, values, weights)
    else:
        values = gtsam.LevenbergMarquardtOptimizer(fg, init, lm).optimize()
        if robust in _KERNEL_WIDTH:
            for n, e in enumerate(loops):
                f = fg.at(len(graph.fixed) + e)
                whitened = math.sqrt(2 * f.error(values))
                weights[n] = float(f.noiseModel().robust().weight(whitened))
    out = np.stack([np.asarray(values.atPose3(int(v)).matrix()) for v in graph.ids])
    return out, weights


def _tls_guard(gtsam: Any, graph: PoseGraph, fg: Any, init: Any, lm: Any, known: list[int], kept: Any, values: Any, weights: F64) -> tuple[Any, F64]:
    """GNC-TLS's optimum ``values`` (of the factors ``kept``; loop weights ``weights``) or, when
    its TLS cost is lower, that of the factors a Cauchy kernel's optimum leaves within the inlier
    threshold, with those loops' weights (0 or 1)."""
    cauchy, _ = _factors(gtsam, graph, "cauchy")
    known_set = set(known)
    at_cauchy = gtsam.LevenbergMarquardtOptimizer(cauchy, init, lm).optimize()
    inlier = np.array([k in known_set or 2 * fg.at(k).error(at_cauchy) <= GNC_INLIER_CHI2 for k in range(fg.size())])
    if not np.array_equal(inlier, kept):
        other = _kept_optimum(gtsam, fg, init, lm, inlier)
        if _tls_cost(fg, other, known_set) < _tls_cost(fg, values, known_set):
            return other, np.array([float(inlier[len(graph.fixed) + e]) for e in graph.loops()])
    return values, weights


def _kept_optimum(gtsam: Any, fg: Any, init: Any, lm: Any, kept: Any) -> Any:
    """The least-squares optimum of the factors of ``fg`` that ``kept`` (a mask) keeps."""
    sub = gtsam.NonlinearFactorGraph()
    for k in range(fg.size()):
        if kept[k]:
            sub.add(fg.at(k))
    return gtsam.LevenbergMarquardtOptimizer(sub, init, lm).optimize()


def _tls_cost(fg: Any, values: Any, known: AbcSet[int]) -> float:
    """The truncated-least-squares cost GNC-TLS minimises: the ``known`` inliers' χ² and each
    other factor's χ² capped at :data:`GNC_INLIER_CHI2`."""
    chi = [2 * fg.at(k).error(values) for k in range(fg.size())]
    return float(sum(c if k in known else min(c, GNC_INLIER_CHI2) for k, c in enumerate(chi)))


# ---- errors ---------------------------------------------------------------------------------------


def _umeyama(src: F64, dst: F64) -> F64:
    """The rigid transform (4, 4) best mapping points ``src`` onto ``dst`` (least squares)."""
    mu_s, mu_d = src.mean(0), dst.mean(0)
    U, _, Vt = np.linalg.svd((dst - mu_d).T @ (src - mu_s))
    S = np.eye(3)
    S[2, 2] = np.sign(np.linalg.det(U @ Vt)) or 1.0
    T = np.eye(4)
    T[:3, :3] = U @ S @ Vt
    T[:3, 3] = mu_d - T[:3, :3] @ mu_s
    return T


def absolute_trajectory_error(estimate: npt.ArrayLike, truth: npt.ArrayLike, align: bool = True) -> float:
    """ATE: the RMS distance (metres) between the positions of ``estimate`` and ``truth`` (both
    (N, 3|4, 4)), after the rigid alignment that minimises it (``align``; as ``evo_ape -a``)."""
    E, G = as4(estimate)[:, :3, 3], as4(truth)[:, :3, 3]
    if align and len(E) >= 3:
        T = _umeyama(E, G)
        E = E @ T[:3, :3].T + T[:3, 3]
    return float(np.sqrt(np.mean(np.sum((E - G) ** 2, axis=1))))


def relative_pose_error(estimate: npt.ArrayLike, truth: npt.ArrayLike, delta: int = 1) -> tuple[float, float]:
    """RPE over ``delta`` frames: the RMS translation (metres) and rotation (degrees) of
    ``(G_i⁻¹G_{i+δ})⁻¹ · (E_i⁻¹E_{i+δ})``."""
    E, G = as4(estimate), as4(truth)
    if len(E) <= delta:
        return float("nan"), float("nan")
    dE = inv(E[:-delta]) @ E[delta:]
    dG = inv(G[:-delta]) @ G[delta:]
    err = inv(dG) @ dE
    t = np.linalg.norm(err[:, :3, 3], axis=1)
    c = np.clip((np.trace(err[:, :3, :3], axis1=1, axis2=2) - 1) / 2, -1.0, 1.0)
    r = np.degrees(np.arccos(c))
    return float(np.sqrt(np.mean(t**2))), float(np.sqrt(np.mean(r**2)))


# ---- anchors --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Anchor:
    """Where a session sits in a map: ``T_map_session`` maps the session's world coordinates into
    the map's world; ``inliers`` of ``loops`` cross-session loops agreed on it."""

    T_map_session: F64
    inliers: int
    loops: int


def estimate_anchor(
    session_poses: npt.ArrayLike,
    map_poses: npt.ArrayLike,
    query_index: AbcSequence[int],
    candidate_index: AbcSequence[int],
    loop_poses: npt.ArrayLike,
    *,
    tolerance_m: float = 1.0,
    tolerance_deg: float = 3.0,
) -> Anchor | None:
    """The session's world → the map's world, from verified cross-session loops, robustly.

    Loop ``k`` joins the session's frame ``query_index[k]`` (pose in ``session_poses``) to the
    map's place ``candidate_index[k]`` (pose in ``map_poses``) by ``T_query_candidate``
    ``loop_poses[k]``; each proposes ``T_map_candidate · T_qc⁻¹ · T_session_query⁻¹``. The
    largest set of proposals that agree within the tolerances with one of them wins (a false
    loop proposes a world far off); the anchor is the rigid transform that best maps, over that
    set, where the session puts each candidate onto where the map has it (orientations averaged
    when the candidates are too few or collinear to fix a rotation). None without a loop."""
    S, M, L = as4(session_poses), as4(map_poses), as4(loop_poses)
    q = np.asarray(query_index, dtype=np.int64)
    c = np.asarray(candidate_index, dtype=np.int64)
    if len(q) == 0:
        return None
    cand_in_session = S[q] @ L  # where the session puts each candidate
    proposals = M[c] @ inv(cand_in_session)
    best: npt.NDArray[np.bool_] = np.zeros(len(q), dtype=bool)
    for P in proposals:
        d = inv(P)[None] @ proposals
        dt = np.linalg.norm(d[:, :3, 3], axis=1)
        da = np.degrees(np.arccos(np.clip((np.trace(d[:, :3, :3], axis1=1, axis2=2) - 1) / 2, -1, 1)))
        agree = (dt <= tolerance_m) & (da <= tolerance_deg)
        if agree.sum() > best.sum():
            best = agree
    src, dst = cand_in_session[best, :3, 3], M[c[best], :3, 3]
    spread = np.linalg.svd(src - src.mean(0), compute_uv=False) if len(src) >= 3 else np.zeros(3)
    if spread[1] > 1.0:  # candidates spread in two directions fix the rotation
        T = _umeyama(src, dst)
    else:
        R = _mean_rotation(proposals[best, :3, :3])
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = np.mean(dst - src @ R.T, axis=0)
    return Anchor(T, int(best.sum()), len(q))


def map_loops(result: Any) -> tuple[F64, list[Any]]:
    """A run against a map: the map's stored poses (4×4) and the run's verified loops into map
    places that have a pose."""
    base = int(result.map_size)
    stored = as4(np.asarray(result.database.poses, dtype=np.float64)[:base])
    ok = [
        lp
        for lp in result.loops()
        if lp.pose is not None and lp.information is not None and int(lp.candidate) < base and np.isfinite(stored[int(lp.candidate)]).all()
    ]
    return stored, ok


def anchor_of_run(result: Any, session_poses: npt.ArrayLike | None = None) -> Anchor | None:
    """The session's placement in the map of a run against one — the one anchor ``solid
    localize``, ``optimize --map``, ``eval --map`` and the ROS 2 node start from: the detector's
    own (``result.map_anchor``: mutually consistent loops into the map, docs/spec.md §8), whose
    ``inliers`` are its supporting loops. A run without it (placement off, ``placement_loops``
    0) falls back to the consensus of its verified loops into the map (:func:`estimate_anchor`
    over ``session_poses``, by default the run's). None when neither places the session."""
    stored, ok = map_loops(result)
    anchor = getattr(result, "map_anchor", None)
    if anchor is not None:
        return Anchor(as4(anchor.transform), int(anchor.loops), len(ok))
    poses = result.poses if session_poses is None else session_poses
    if poses is None:
        return None
    base = int(result.map_size)
    Z = np.stack([lp.pose for lp in ok]) if ok else np.zeros((0, 4, 4))
    return estimate_anchor(poses, stored, [int(lp.query) - base for lp in ok], [int(lp.candidate) for lp in ok], Z)


#: The factor on the information of an odometry edge across a break when :func:`optimize_in_map`
#: starts each stretch at its own anchor (on the simulated breakdown of tests/test_sessions.py,
#: at full weight the optimum kept 21 of 26 loops into the map and left the frame before the
#: break 2.2 m off; at 1e-2 or 1e-4, 26 of 26 and 0.24 m).
BREAK_EDGE_WEIGHT = 1e-4


def stretch_anchors_of_run(result: Any) -> tuple[F64, list[int]] | None:
    """Each frame's ``T_map_session`` (N, 4, 4) when loops into the map placed the run
    (``result.map_anchors``: one anchor per placed stretch of the odometry between breaks,
    docs/loops.md#breakdowns): the anchor of the frame's own stretch, or for a frame of a
    stretch no anchor placed, that of the nearest placed stretch (:func:`nearest_placed`).
    Returns them and the frames (indices into the run's) placed by another stretch's anchor:
    with one anchor, those outside its stretch when the odometry broke. None when no anchor
    placed the run (an anchor estimated from the loops, :func:`anchor_of_run`, then places
    every frame)."""
    if not (getattr(result, "map_anchors", None) or []):
        return None
    from .localize import frame_anchors_of_run

    return nearest_placed(frame_anchors_of_run(result))


def nearest_placed(anchors: npt.ArrayLike) -> tuple[F64, list[int]]:
    """Per-frame anchors (N, 4, 4; a row not finite: a frame no anchor places) with each such
    frame's taken from the nearest placed frame (by frames, the earlier on a tie: so its
    stretch's anchor), and those frames (indices). When no frame is placed, nothing is there to
    take: every row stays as it was and every frame is listed (callers refuse that)."""
    out = np.array(anchors, dtype=np.float64)
    finite = np.isfinite(out).all(axis=(1, 2))
    placed = np.flatnonzero(finite)
    borrowed = [int(k) for k in np.flatnonzero(~finite)]
    if not placed.size:
        return out, borrowed
    for k in borrowed:
        out[k] = out[placed[int(np.argmin(np.abs(placed - k)))]]
    return out, borrowed


def optimize_in_map(
    graph: PoseGraph,
    map_poses: npt.ArrayLike,
    query_index: AbcSequence[int],
    candidate_index: AbcSequence[int],
    loop_poses: npt.ArrayLike,
    loop_information: npt.ArrayLike,
    initial: Anchor,
    robust: str = ROBUST_SCHEMES[0],
    start: npt.ArrayLike | None = None,
    stretch_anchors: npt.ArrayLike | None = None,
) -> tuple[Anchor | None, F64, F64]:
    """A session's graph optimised into a saved map, the map's places held where the map has
    them: the session's vertices (started at ``initial.T_map_session`` · ``start``, by default
    their poses; e.g. the session optimised alone; or, given ``stretch_anchors`` (N, 4, 4), each
    vertex at its own ``T_map_session`` · ``start``: the anchor of its stretch of the odometry
    between breaks, :func:`stretch_anchors_of_run`, the odometry edges across a break then
    weakened by :data:`BREAK_EDGE_WEIGHT`) and edges, and a loop edge per
    cross-session loop ``k`` from the session's vertex ``query_index[k]`` to the map's place
    ``candidate_index[k]`` (pose in ``map_poses``), all loops under ``robust``. The anchor is where the optimum puts the session's first frame:
    ``T_map_session = Y₀ · X₀⁻¹`` (``X₀`` its pose in the session's world, ``Y₀`` in the map's),
    so it is fixed by the loops and the odometry together rather than fitted on poses that
    drift away from the session's start. Returns the anchor (``inliers``: the cross-session
    loops the optimum kept; None when it kept none, since nothing then ties the session to the
    map), the session's poses in the map's world and the weights of the session's own loop
    edges."""
    M = as4(map_poses)
    c = np.asarray(candidate_index, dtype=np.int64)
    places = np.unique(c)
    n = len(graph)
    # The map's places become vertices after the session's, with ids past the session's.
    first_id = int(graph.ids.max()) + 1 if n else 0
    joint = PoseGraph(
        ids=np.r_[graph.ids, first_id + places].astype(np.int64),
        poses=np.concatenate([(initial.T_map_session if stretch_anchors is None else as4(stretch_anchors)) @ as4(graph.poses if start is None else start), M[places]]),
        edge_from=graph.edge_from.copy(),
        edge_to=graph.edge_to.copy(),
        measurements=graph.measurements.copy(),
        information=graph.information.copy(),
        kinds=list(graph.kinds),
        fixed=list(range(n, n + len(places))),
    )
    if stretch_anchors is not None:
        # An odometry edge across a break (its two frames in stretches with different anchors)
        # holds a step the odometry cannot have made: weakened, it no longer fights the loops.
        S = as4(stretch_anchors)
        for e, kind in enumerate(joint.kinds):
            i, j = int(joint.edge_from[e]), int(joint.edge_to[e])
            if kind == "odometry" and not np.array_equal(S[i], S[j]):
                joint.information[e] = joint.information[e] * BREAK_EDGE_WEIGHT
    vertex = {int(m): n + k for k, m in enumerate(places)}
    for q, m, Z, info in zip(query_index, c, as4(loop_poses), np.asarray(loop_information, dtype=np.float64)):
        joint.add_edge(int(q), vertex[int(m)], Z, info, "loop")
    Y, w = optimize_graph(joint, robust)
    own = len(graph.loops())
    kept = int(np.sum(w[own:] > 0.5))
    anchor = Anchor(Y[0] @ inv(graph.poses[0]), kept, len(c)) if kept else None
    return anchor, Y[:n], w[:own]


def _mean_rotation(Rs: F64) -> F64:
    U, _, Vt = np.linalg.svd(Rs.sum(0))
    S = np.eye(3)
    S[2, 2] = np.sign(np.linalg.det(U @ Vt)) or 1.0
    return np.asarray(U @ S @ Vt, dtype=np.float64)


# ---- a whole run ----------------------------------------------------------------------------------


@dataclass
class SlamResult:
    """What :func:`optimize_run` produced; poses ``T_world_sensor`` (N, 4, 4) in the run's frame
    (the LiDAR's, calibration applied); ``anchor`` and ``map_poses`` with a map."""

    graph: PoseGraph
    odometry: F64
    optimized: F64
    loop_weights: F64
    robust: str
    anchor: Anchor | None = None
    map_poses: F64 | None = None
    #: The factor the odometry noise was multiplied by (:func:`fit_odometry_scale`, or as given).
    noise_scale: float = 1.0
    #: How many stretches of the odometry between breaks their own anchors started in the map
    #: (``result.map_anchors``; 1: one anchor started every frame).
    stretches: int = 1
    #: The frames (indices into the run's) of stretches no anchor placed (the odometry broke),
    #: started at the nearest placed stretch's anchor (with one anchor: that one's).
    borrowed: list[int] = field(default_factory=list)

    def trusted_loops(self) -> int:
        """Loop edges the optimum kept (weight above one half)."""
        return int(np.sum(self.loop_weights > 0.5))


def _optimized(build: Any, noise: OdometryNoise | None, noise_scale: float | None, robust: str) -> tuple[PoseGraph, F64, F64, float]:
    """``build(noise)``'s graph optimised (:func:`optimize_graph`), the odometry noise multiplied
    by ``noise_scale``; by default (None) as given, unless the robust optimum then keeps fewer
    than half of the loops: then multiplied by the factor the loops need
    (:func:`fit_odometry_scale`), when that keeps more of them. Returns the graph, the optimised
    poses, the loops' weights and the factor used."""
    noise = noise or OdometryNoise()
    scale = 1.0 if noise_scale is None else float(noise_scale)
    graph = build(noise.scaled(scale) if scale != 1.0 else noise)
    optimized, weights = optimize_graph(graph, robust)
    kept = int(np.sum(weights > 0.5))
    if noise_scale is None and 2 * kept < len(weights):
        fitted = fit_odometry_scale(graph)
        if fitted > 1.0:
            wider = build(noise.scaled(fitted))
            Y, w = optimize_graph(wider, robust)
            if int(np.sum(w > 0.5)) > kept:
                return wider, Y, w, fitted
    return graph, optimized, weights, scale


def optimize_run(
    result: Any,
    *,
    robust: str = ROBUST_SCHEMES[0],
    noise: OdometryNoise | None = None,
    noise_scale: float | None = None,
) -> SlamResult:
    """The pose graph of a pipeline run (:func:`graph_from_run`), optimised
    (:func:`optimize_graph`); with a map and loops into it, the session optimised into the
    map's world with the map's places held (:func:`optimize_in_map`, started from the
    consensus of :func:`estimate_anchor`), which gives the anchor, the poses in the map's world
    and, carried back by the anchor, the session's optimised poses. When that optimum trusts
    no loop into the map, the session stays unanchored (``anchor`` None). The odometry noise
    (``noise``, by default :class:`OdometryNoise`'s) is multiplied by ``noise_scale``; by default
    it is as given unless the optimum then keeps fewer than half of the loops, when it is
    multiplied by the factor the loops say the odometry needs (:func:`fit_odometry_scale`) if
    that keeps more of them."""
    if result.poses is None:
        raise ValueError("a pose graph needs the odometry's poses (give --poses)")
    graph, optimized, weights, scale = _optimized(lambda n: graph_from_run(result, n), noise, noise_scale, robust)
    out = SlamResult(graph, graph.poses.copy(), optimized, weights, robust, noise_scale=scale)
    if int(result.map_size) == 0:
        return out
    stored, ok = map_loops(result)
    base = int(result.map_size)
    q = [int(lp.query) - base for lp in ok]
    c = [int(lp.candidate) for lp in ok]
    Z = np.stack([lp.pose for lp in ok]) if ok else np.zeros((0, 4, 4))
    initial = anchor_of_run(result, optimized)
    if initial is None:
        return out
    info = np.stack([lp.information for lp in ok])
    per = stretch_anchors_of_run(result)
    stretches = 1 if per is None else len(result.map_anchors)
    # One anchor starts every frame as ``initial`` (its transform); several, each its stretch's.
    starts = per[0] if per is not None and stretches > 1 else None
    anchor, in_map, own_weights = optimize_in_map(graph, stored, q, c, Z, info, initial, robust, optimized, starts)
    if anchor is None:
        return out
    out.anchor, out.map_poses, out.loop_weights = anchor, in_map, own_weights
    if per is not None:
        out.stretches, out.borrowed = stretches, per[1]
    out.optimized = inv(anchor.T_map_session) @ in_map
    return out


def optimize_with_loops_of(
    path: Path | str,
    ids: npt.ArrayLike,
    poses: npt.ArrayLike,
    *,
    calib: npt.ArrayLike | None = None,
    robust: str = ROBUST_SCHEMES[0],
    noise: OdometryNoise | None = None,
    noise_scale: float | None = None,
) -> SlamResult:
    """The frames ``ids`` at their ``poses`` (the run's, calibration applied), their odometry
    edges, and the loop edges of a run's g2o file (``solid detect --g2o``, ``graph.g2o``; in the
    frame of that run's given poses, so carried back by ``calib`` when it had one), optimised:
    a run's loops reused without the detector (:meth:`PoseGraph.with_loops_of` refuses a file
    written for other poses); the odometry noise as :func:`optimize_run` makes it."""
    saved = PoseGraph.read_g2o(path)
    if calib is not None:
        saved = saved.in_frame(inv(as4(calib)))
    graph, optimized, weights, scale = _optimized(lambda n: odometry_graph(ids, poses, n).with_loops_of(saved), noise, noise_scale, robust)
    return SlamResult(graph, graph.poses.copy(), optimized, weights, robust, noise_scale=scale)


def write_kitti(path: Path | str, poses: npt.ArrayLike, header: str = "") -> None:
    """One row-major 3×4 ``[R | t]`` per line (KITTI's odometry format), after ``header`` (its
    ``#`` comment lines, which pose readers skip)."""
    P = as4(poses)[:, :3, :].reshape(-1, 12)
    Path(path).write_text(header + "".join(" ".join(f"{v:.9g}" for v in row) + "\n" for row in P), encoding="utf-8")


def write_tum(path: Path | str, times: npt.ArrayLike, poses: npt.ArrayLike) -> None:
    """``t x y z qx qy qz qw`` per line (TUM's format, as evo reads it)."""
    P = as4(poses)
    lines = []
    for t, M in zip(np.asarray(times, dtype=np.float64), P):
        qx, qy, qz, qw = quaternion(M[:3, :3])
        lines.append(f"{t:.9f} {M[0, 3]:.9f} {M[1, 3]:.9f} {M[2, 3]:.9f} {qx:.12f} {qy:.12f} {qz:.12f} {qw:.12f}\n")
    Path(path).write_text("".join(lines), encoding="utf-8")
