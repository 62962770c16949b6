"""Poses, timestamps and extrinsics: files, path resolution, and how their rows meet the scans.

Pose files (:func:`load_poses`): KITTI rows (12 numbers, row-major 3×4), 4×4 rows (16 numbers)
or TUM rows (``t x y z qx qy qz qw``). Which pose a scan gets (:func:`match_rows`):

* TUM poses and scan times known (a timestamps file, a bag's stamps, NCLT/HeLiPR file names):
  by time. Each scan's pose is interpolated between the two poses around its time (linear in
  position, spherical-linear in rotation), so a pose stream at any rate (say 10× the scan rate)
  works; a scan time outside the poses' time range is an error that gives both ranges.
* Otherwise by row: one row per scan; or, when the file has more rows than there are scans and
  the scans are named by frame number (KITTI ``000100.bin``), the rows of those frame numbers.
  Timestamp files follow the same rule.

A relative ``poses=``/``timestamps=``/``calib=`` path is looked up in the current directory and
in the sequence folder (:func:`resolve`): when it exists in both and the two files differ, that
is an error naming both, never a silent choice.
"""

from __future__ import annotations

import filecmp
import os
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..arrays import F64, I64, PathLike
from ..errors import ReadError
from ._common import file_size


def _rows(path: PathLike, what: str) -> list[list[str]]:
    file_size(path, f"{what} file")  # a FIFO or device would block: refused in one line
    try:
        with open(path, encoding="utf-8") as f:
            return [ln.replace(",", " ").split() for ln in f if ln.strip() and not ln.lstrip().startswith("#")]
    except UnicodeDecodeError:
        raise ReadError(path, f"{what} file is not text") from None


def quat_to_matrix(q: npt.ArrayLike) -> F64:
    """Rotation matrices (N, 3, 3) of quaternions (N, 4) ``qx qy qz qw`` (normalised here)."""
    a = np.asarray(q, dtype=np.float64)
    x, y, z, w = (a / np.linalg.norm(a, axis=1)[:, None]).T
    R = np.empty((a.shape[0], 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z)
    R[:, 0, 1] = 2 * (x * y - z * w)
    R[:, 0, 2] = 2 * (x * z + y * w)
    R[:, 1, 0] = 2 * (x * y + z * w)
    R[:, 1, 1] = 1 - 2 * (x * x + z * z)
    R[:, 1, 2] = 2 * (y * z - x * w)
    R[:, 2, 0] = 2 * (x * z - y * w)
    R[:, 2, 1] = 2 * (y * z + x * w)
    R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def matrix_to_quat(R: npt.ArrayLike) -> F64:
    """Unit quaternions (N, 4) ``qx qy qz qw`` of rotation matrices (N, 3, 3) (Shepperd's method)."""
    m = np.asarray(R, dtype=np.float64)
    n = m.shape[0]
    tr = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    diag = np.stack([m[:, 0, 0], m[:, 1, 1], m[:, 2, 2], tr], axis=1)
    k = np.argmax(diag, axis=1)
    q = np.empty((n, 4))
    for case in range(4):
        s = k == case
        if not s.any():
            continue
        a = m[s]
        if case == 3:
            r = np.sqrt(1.0 + tr[s]) * 2
            q[s] = np.stack([(a[:, 2, 1] - a[:, 1, 2]) / r, (a[:, 0, 2] - a[:, 2, 0]) / r, (a[:, 1, 0] - a[:, 0, 1]) / r, r / 4], axis=1)
        else:
            i, j, l = case, (case + 1) % 3, (case + 2) % 3
            r = np.sqrt(1.0 + a[:, i, i] - a[:, j, j] - a[:, l, l]) * 2
            v = np.empty((a.shape[0], 4))
            v[:, i] = r / 4
            v[:, j] = (a[:, j, i] + a[:, i, j]) / r
            v[:, l] = (a[:, l, i] + a[:, i, l]) / r
            v[:, 3] = (a[:, l, j] - a[:, j, l]) / r
            q[s] = v
    out: F64 = q / np.linalg.norm(q, axis=1)[:, None]
    return out


def load_poses(path: PathLike) -> tuple[F64, F64 | None]:
    """Read poses as (N, 3, 4) float64 [R|t] (frame → world) and, for TUM files, timestamps.

    Auto-detected by column count: 12 = KITTI row-major 3×4; 8 = TUM ``t x y z qx qy qz qw``;
    16 = row-major 4×4. Blank lines and lines starting with ``#`` are ignored.
    """
    rows = _rows(path, "pose")
    if not rows:
        raise ReadError(path, "pose file is empty")
    ncol = len(rows[0])
    bad = next((i for i, r in enumerate(rows) if len(r) != ncol), None)
    if bad is not None:
        raise ReadError(path, f"pose row {bad + 1} has {len(rows[bad])} numbers, row 1 has {ncol}")
    try:
        a = np.array(rows, dtype=np.float64)
    except ValueError:
        raise ReadError(path, "pose file contains a value that is not a number") from None
    if not np.isfinite(a).all():
        raise ReadError(path, "pose file contains a non-finite value")
    if ncol == 12:
        return a.reshape(-1, 3, 4), None
    if ncol == 16:
        return a.reshape(-1, 4, 4)[:, :3, :], None
    if ncol == 8:
        if np.any(np.linalg.norm(a[:, 4:8], axis=1) < 1e-9):
            raise ReadError(path, "TUM pose with a zero quaternion")
        P = np.concatenate([quat_to_matrix(a[:, 4:8]), a[:, 1:4, None]], axis=2)
        return P, a[:, 0].copy()
    raise ReadError(path, f"pose rows have {ncol} numbers: expected 12 (KITTI 3×4), 8 (TUM) or 16 (4×4)")


def load_timestamps(path: PathLike) -> F64:
    """Read one timestamp per line (first column; seconds)."""
    try:
        t = np.array([r[0] for r in _rows(path, "timestamp")], dtype=np.float64)
    except ValueError:
        raise ReadError(path, "timestamp file contains a value that is not a number") from None
    if not np.isfinite(t).all():
        raise ReadError(path, "timestamp file contains a non-finite value")
    return t


def load_extrinsic(path: PathLike) -> F64:
    """Read a sensor → pose-frame transform as a 4×4 matrix.

    Accepts a KITTI ``calib.txt`` (the ``Tr:`` or ``Tr_velo_to_cam:`` line: Velodyne → left
    camera, the frame of KITTI's poses) or a file holding exactly 12 (row-major 3×4) or 16 numbers.
    """
    file_size(path, "calibration file")
    try:
        with open(path, encoding="utf-8") as f:
            lines = [ln.strip() for ln in f if ln.strip() and not ln.lstrip().startswith("#")]
    except UnicodeDecodeError:
        raise ReadError(path, "extrinsic file is not text") from None
    vals: list[str] | None = None
    for ln in lines:
        key, sep, rest = ln.partition(":")
        if sep and key.strip() in ("Tr", "Tr_velo_to_cam", "Tr_velo_cam"):
            vals = rest.split()
            break
    if vals is None:
        if any(":" in ln for ln in lines):
            raise ReadError(path, "no 'Tr:' line (Velodyne → camera) in this calibration file")
        vals = " ".join(lines).replace(",", " ").split()
    try:
        a = np.array(vals, dtype=np.float64)
    except ValueError:
        raise ReadError(path, "extrinsic contains a value that is not a number") from None
    if a.size not in (12, 16) or not np.isfinite(a).all():
        raise ReadError(path, f"extrinsic has {a.size} numbers, expected 12 (3×4) or 16 (4×4)")
    T = np.eye(4)
    T[: a.size // 4, :] = a.reshape(-1, 4)
    if not np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-3):
        raise ReadError(path, "the extrinsic's rotation part is not a rotation matrix")
    return T


def sensor_poses(poses: npt.ArrayLike, T_pose_sensor: npt.ArrayLike) -> F64:
    """Poses of the sensor, ``T_world_sensor = T_world_pose · T_pose_sensor``, as (N, 3, 4).

    For KITTI: ``sensor_poses(camera_poses, load_extrinsic("calib.txt"))`` gives the Velodyne
    poses, whose yaw is the heading docs/spec.md §3 compares against.
    """
    P = np.asarray(poses, dtype=np.float64)
    T = np.asarray(T_pose_sensor, dtype=np.float64)
    out = np.empty((P.shape[0], 3, 4))
    out[:, :, :3] = P[:, :3, :3] @ T[:3, :3]
    out[:, :, 3] = np.einsum("nij,j->ni", P[:, :3, :3], T[:3, 3]) + P[:, :3, 3]
    return out


def sensor_poses_in_sensor_world(poses: npt.ArrayLike, T_pose_sensor: npt.ArrayLike) -> F64:
    """``T⁻¹ · P · T``: sensor poses in the world frame re-expressed as a sensor frame.

    Relative poses, distances and headings are those of :func:`sensor_poses`; only the world
    frame changes, to the sensor's axes at the poses' origin (for KITTI: z up, so a trajectory
    plots in x, y rather than in the camera's x, z).
    """
    T = np.asarray(T_pose_sensor, dtype=np.float64)
    out = sensor_poses(poses, T)
    Rinv = T[:3, :3].T
    out[:, :, :3] = Rinv @ out[:, :, :3]
    out[:, :, 3] = out[:, :, 3] @ Rinv.T - Rinv @ T[:3, 3]
    return out


def resolve(p: PathLike, root: Path, what: str) -> Path:
    """The absolute path of a ``poses=``/``timestamps=``/``calib=`` argument.

    An absolute path is taken as is. A relative one is looked up in the current directory and in
    ``root`` (the sequence folder): if it exists in both and the files differ, :class:`ReadError`
    names both; otherwise the one that exists (they are the same data when both do).
    """
    pp = Path(p).expanduser()
    if pp.is_absolute():
        if not pp.exists():
            raise FileNotFoundError(f"{pp}: no such {what} file")
        return pp
    here = Path(os.path.abspath(pp))
    inside = Path(os.path.abspath(root / pp))
    if here.is_file() and inside.is_file():
        if not (os.path.samefile(here, inside) or filecmp.cmp(here, inside, shallow=False)):
            raise ReadError(
                pp,
                f"two different {what} files have this name: {here} (current directory) and {inside} "
                "(sequence folder); pass the one you mean by its absolute path",
            )
        return inside
    for cand in (here, inside):
        if cand.exists():
            return cand
    raise FileNotFoundError(f"{pp}: no such {what} file (looked in {Path.cwd()} and in {root})")


def match_rows(
    path: Path, n_rows: int, n_scans: int, frame_numbers: I64 | None, what: str, wanted: list[int] | None = None
) -> npt.NDArray[np.intp] | slice:
    """The rows of a per-frame file (poses or timestamps) that belong to the scans.

    One row per scan; or, with more rows than scans and scans named by frame number, the rows of
    those frames. With ``wanted`` (the scans a run reads, ``--frames``), only those need a row:
    the others get row -1 (none; see :func:`take_rows`).
    """
    if n_rows == n_scans:
        return slice(None)
    if wanted is not None and n_scans > 0:
        rows = frame_numbers.astype(np.intp) if frame_numbers is not None and n_rows > n_scans else np.arange(n_scans, dtype=np.intp)
        has = (rows >= 0) & (rows < n_rows)
        if has[np.asarray(wanted, dtype=np.intp)].all():
            return np.where(has, rows, -1)
    if frame_numbers is not None and n_rows > n_scans and n_scans > 0:
        hi = int(frame_numbers.max())
        if int(frame_numbers.min()) >= 0 and hi < n_rows:
            return frame_numbers.astype(np.intp)
        raise ReadError(path, f"{n_rows} {what} for {n_scans} scans, and scan frame number {hi} has no row")
    hint = "" if frame_numbers is not None else " (scan names are not frame numbers, so rows cannot be picked by frame)"
    raise ReadError(path, f"{n_rows} {what} for {n_scans} scans{hint}")


def take_rows(a: F64, rows: npt.NDArray[np.intp] | slice) -> F64:
    """``a[rows]`` where row -1 (a scan without a row, see :func:`match_rows`) is NaN."""
    if isinstance(rows, slice):
        return np.ascontiguousarray(a[rows])
    out = np.ascontiguousarray(a[np.maximum(rows, 0)])
    out[rows < 0] = np.nan
    return out


def interpolate_poses(path: Path, pose_times: F64, poses: F64, scan_times: F64) -> F64:
    """The pose at each scan time, interpolated between the poses around it (see the module docs).

    ``pose_times`` must increase; a scan time outside ``[pose_times[0], pose_times[-1]]`` is a
    :class:`ReadError` that gives both ranges.
    """
    tp = np.asarray(pose_times, dtype=np.float64)
    ts = np.asarray(scan_times, dtype=np.float64)
    if tp.size > 1 and not np.all(np.diff(tp) > 0):
        k = int(np.flatnonzero(np.diff(tp) <= 0)[0])
        raise ReadError(path, f"pose times must increase: row {k + 2} ({tp[k + 1]!r}) is not after row {k + 1} ({tp[k]!r})")
    eps = 1e-6
    outside = (ts < tp[0] - eps) | (ts > tp[-1] + eps)
    if outside.any():
        k = int(np.flatnonzero(outside)[0])
        raise ReadError(
            path,
            f"{int(outside.sum())} of {ts.size} scans lie outside the pose times "
            f"[{tp[0]:.6f}, {tp[-1]:.6f}] s (scans span [{ts.min():.6f}, {ts.max():.6f}] s; "
            f"first: scan {k} at {ts[k]:.6f} s); are the scan timestamps and the poses on the same clock?",
        )
    if tp.size == 1:
        return np.repeat(poses[:1], ts.size, axis=0)
    i = np.clip(np.searchsorted(tp, ts, side="right") - 1, 0, tp.size - 2)
    s = np.clip((ts - tp[i]) / (tp[i + 1] - tp[i]), 0.0, 1.0)
    q0 = matrix_to_quat(poses[i, :, :3])
    q1 = matrix_to_quat(poses[i + 1, :, :3])
    dot = np.sum(q0 * q1, axis=1)
    q1 = np.where(dot[:, None] < 0, -q1, q1)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin = np.sin(theta)
    small = sin < 1e-9
    w0 = np.where(small, 1 - s, np.sin((1 - s) * theta) / np.where(small, 1.0, sin))
    w1 = np.where(small, s, np.sin(s * theta) / np.where(small, 1.0, sin))
    q = w0[:, None] * q0 + w1[:, None] * q1
    out = np.empty((ts.size, 3, 4))
    out[:, :, :3] = quat_to_matrix(q)
    out[:, :, 3] = (1 - s)[:, None] * poses[i, :, 3] + s[:, None] * poses[i + 1, :, 3]
    return out
