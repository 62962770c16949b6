"""A deterministic LiDAR simulator: procedural worlds, sensor models, trajectories, sequences.

The heavy lifting (world generation, exact ray casting through a uniform grid) is the Rust crate
``solid-lidar-sim``; this module is its typed Python face. Everything is seeded: the same seeds give
bit-identical scans on every platform.

>>> from solid import sim
>>> world = sim.World(seed=7)
>>> sensor = sim.Sensor("hdl64", h_fov=60.0)             # HDL-64E clipped to 60° ahead
>>> traj = sim.Trajectory.loop(world, laps=1.5)           # 1.5 laps around a block, 1 m apart
>>> seq = sim.simulate(world, sensor, traj)               # scans (N, 4) float32 + poses (M, 3, 4)
>>> seq.write("sim_seq")                                  # KITTI layout: velodyne/*.bin, poses.txt

The failure modes of loop closure, with exact truth (:meth:`World.corridors`,
:meth:`World.room`, :meth:`Trajectory.odometry`, :class:`Session`):

>>> corridors = sim.World.corridors(seed=1)               # one module repeated every 45 m
>>> walk = sim.Trajectory.corridor_walk(corridors, laps=1.3)  # true loops and look-alikes
>>> odom = walk.odometry(yaw_bias_deg_per_m=0.01, scale_error=0.01, seed=1)  # drifts
>>> sim.write_sequence("walk", corridors, sim.Sensor("avia"), walk, odometry=odom)  # + odometry.txt
>>> room = sim.World.room(seed=2)
>>> turn = sim.Trajectory.turn_in_place(room, sweep=330.0, step=2.0, wobble=0.3)

Frames: the sensor frame is x forward, y left, z up; poses are ``T_world_sensor`` as (3, 4)
row-major float64 matrices, the KITTI convention in the LiDAR frame. Heading convention of docs/spec.md §3:
:func:`true_heading` gives ψ with ``p_query ≈ Rz(ψ) · p_candidate``.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence as AbcSequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict, overload

import numpy as np
import numpy.typing as npt

from . import _solid
from .arrays import F32, F64, PathLike
from .transforms import wrap_degrees, yaw_degrees

if TYPE_CHECKING:
    from typing_extensions import Unpack

    from .pipeline import Progress

__all__ = [
    "ANCHOR_FILE",
    "DriveOptions",
    "ODOMETRY_FILE",
    "SENSORS",
    "TRAJECTORIES",
    "Sensor",
    "Sequence",
    "Session",
    "Trajectory",
    "World",
    "away_route",
    "corridor_sessions",
    "demo_summary",
    "run_demo",
    "scan",
    "session_routes",
    "simulate",
    "true_heading",
    "write_sequence",
    "write_sessions",
]


#: Sensor model names (read from the simulator crate); each matches the descriptor preset of the
#: same name (``solid.presets()``).
SENSORS: tuple[str, ...] = tuple(_solid._SIM_SENSORS)
#: Built-in trajectory kinds (read from the simulator crate; see :class:`Trajectory`).
TRAJECTORIES: tuple[str, ...] = tuple(_solid._SIM_TRAJECTORIES)


class World:
    """A seeded procedural city: a sloped ground plane, a grid of roads, blocks of buildings, parks
    (trees behind fences), parking lots (rows of cars, light poles, a low wall), walled compounds,
    and street furniture (poles, street trees, parked cars, walls and fences).

    With probability ``repetition`` a block or a street side copies one of three shared templates,
    so some places look alike. The default world is 480 m × 480 m (4 × 4 blocks inside the road
    grid plus an outer ring). Immutable.
    """

    __slots__ = ("_ext", "_args", "_layout")

    def __init__(
        self,
        seed: int = 0,
        *,
        blocks: int = 4,
        block_pitch: float = 80.0,
        road_half_width: float = 7.0,
        slope: tuple[float, float] = (0.01, -0.006),
        repetition: float = 0.3,
        cell_size: float = 4.0,
    ) -> None:
        self._args: dict[str, Any] = dict(
            seed=seed,
            blocks=blocks,
            block_pitch=block_pitch,
            road_half_width=road_half_width,
            slope=(float(slope[0]), float(slope[1])),
            repetition=repetition,
            cell_size=cell_size,
        )
        self._layout = "city"
        self._ext = _solid._sim_world(**self._args)

    @classmethod
    def corridors(
        cls,
        seed: int = 0,
        *,
        blocks: int = 1,
        modules: int = 4,
        module_length: float = 45.0,
        width: float = 6.0,
        height: float = 3.0,
        jitter: float = 0.15,
        dropout: float = 0.1,
        cell_size: float = 4.0,
    ) -> World:
        """A look-alike world: corridors (``width`` m wall to wall, ceiling at ``height`` m, flat
        floor at z = 0) along the roads of a ``blocks`` × ``blocks`` grid (one block: a square ring
        of four corridors, :attr:`roads` gives their centrelines). Every corridor between two
        intersections is ``modules`` copies of one ``module_length`` m module — pillar pairs
        under ceiling beams, doors, cabinets and benches along the walls — each copy moving every
        feature by up to ``jitter`` m and leaving it out with probability ``dropout``. Places one
        module apart look nearly the same to a descriptor although they are tens of metres apart;
        :meth:`Trajectory.corridor_walk` laps the ring, so a drive has true revisits too.

        >>> w = World.corridors(seed=3, modules=3)
        >>> w.layout, w.block_pitch                      # pitch = modules · module_length + width
        ('corridors', 141.0)
        """
        args: dict[str, Any] = dict(
            seed=seed, blocks=blocks, modules=modules, module_length=module_length, width=width,
            height=height, jitter=jitter, dropout=dropout, cell_size=cell_size,
        )
        return cls._made("corridors", args)

    @classmethod
    def room(
        cls,
        seed: int = 0,
        *,
        size: tuple[float, float] = (6.0, 4.5),
        height: float = 2.6,
        furniture: int = 8,
        cell_size: float = 1.0,
    ) -> World:
        """A small closed room centred on the origin (inner extent ``size`` m along x and y,
        ceiling at ``height`` m, flat floor at z = 0): a pillar standing out of one wall, up to
        ``furniture`` cabinets, shelves and boxes along the walls, and a table in one corner;
        nothing within 1.2 m of the centre. For a sensor turning in place
        (:meth:`Trajectory.turn_in_place`), where a narrow view sees nothing twice once it has
        turned by more than its field of view. It has no roads.

        >>> World.room(seed=1).layout
        'room'
        """
        args: dict[str, Any] = dict(
            seed=seed, size=(float(size[0]), float(size[1])), height=height, furniture=furniture, cell_size=cell_size
        )
        return cls._made("room", args)

    @classmethod
    def _made(cls, layout: str, args: dict[str, Any]) -> World:
        make: dict[str, Callable[..., _solid._SimWorld]] = {
            "city": _solid._sim_world, "corridors": _solid._sim_corridor_world, "room": _solid._sim_room_world
        }
        world = cls.__new__(cls)
        world._args = args
        world._layout = layout
        world._ext = make[layout](**args)
        return world

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        # Pickled by its parameters; unpickling regenerates the identical world.
        return (_world_from_args, (self._args, self._layout))

    @property
    def layout(self) -> str:
        """Which generator made the world: ``"city"`` (the constructor), ``"corridors"`` or
        ``"room"``."""
        return self._ext.layout

    @property
    def seed(self) -> int:
        """The world's seed."""
        return self._ext.seed

    @property
    def blocks(self) -> int:
        """Blocks per side inside the road grid."""
        return self._ext.blocks

    @property
    def block_pitch(self) -> float:
        """Distance between parallel roads, metres."""
        return self._ext.block_pitch

    @property
    def roads(self) -> list[float]:
        """Road centrelines: roads run along x at each of these y, and along y at each of these x."""
        return self._ext.roads

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) covered by objects."""
        return self._ext.bounds

    def __len__(self) -> int:
        return len(self._ext)

    def ground_height(self, x: float, y: float) -> float:
        """Height of the ground at (x, y)."""
        return self._ext.ground_height(x, y)

    def footprints(self) -> tuple[list[str], F64, F64]:
        """(kinds, footprints (P, 4) as [xmin, ymin, xmax, ymax], tops (P,)) of every primitive."""
        return self._ext.footprints()

    def __repr__(self) -> str:
        kind = "" if self._layout == "city" else f"{self._layout}, "
        return f"World({kind}seed={self.seed}, blocks={self.blocks}, block_pitch={self.block_pitch:g}, primitives={len(self)})"


def _world_from_args(args: dict[str, Any], layout: str = "city") -> World:
    return World._made(layout, args)


@dataclass(frozen=True)
class Sensor:
    """A sensor model: one of :data:`SENSORS` plus options.

    - ``hdl64``: Velodyne HDL-64E, 64 beams at the data sheet's elevations (upper block +2.0° to
      −8.33° at ≈1/3°, lower block −8.83° to −24.33° at 0.5°), 2083 columns (≈0.17°), 120 m;
    - ``vlp16``: 16 beams from −15° to +15° every 2°, 0.2° columns, 100 m;
    - ``os1-64``: 64 beams uniform over ±22.5°, 1024 columns, 120 m;
    - ``avia``: a Livox-Avia-like non-repetitive rosette over 70.4° × 77.2°, ``points`` per 0.1 s
      frame (24 000 by default), 190 m;
    - ``aeva``: an Aeva-like raster, 64 lines over ±9.6°, 120° horizontal at 0.12°, 250 m.

    ``h_fov`` (degrees, (0, 360]; default: the model's own) keeps only the rays whose azimuth lies
    within ``h_fov / 2`` of ``h_centre`` (0 = ahead, +90 = left): the window turns with the
    vehicle. ``noise`` is the standard deviation of Gaussian range noise in metres (default: the
    data sheet's accuracy, 2–3 cm), ``dropout`` the probability of losing a return, ``seed`` the
    seed of both (combined with the frame index). ``min_range``/``max_range`` default to the model's.
    """

    name: str = "hdl64"
    h_fov: float | None = None
    h_centre: float = 0.0
    min_range: float | None = None
    max_range: float | None = None
    noise: float | None = None
    dropout: float = 0.0
    seed: int = 0
    points: int | None = None
    _ext: _solid._SimSensor = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        ext = _solid._sim_sensor(
            self.name,
            h_fov=self.h_fov,
            h_centre=self.h_centre,
            min_range=self.min_range,
            max_range=self.max_range,
            noise=self.noise,
            dropout=self.dropout,
            seed=self.seed,
            points=self.points,
        )
        object.__setattr__(self, "_ext", ext)

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        return (Sensor, (self.name, self.h_fov, self.h_centre, self.min_range, self.max_range, self.noise, self.dropout, self.seed, self.points))

    @property
    def effective_h_fov(self) -> float:
        """The horizontal window actually used, degrees."""
        return float(self._ext.h_fov)

    @property
    def effective_max_range(self) -> float:
        """The maximum range actually used, metres."""
        return float(self._ext.max_range)

    @property
    def effective_noise(self) -> float:
        """The range-noise standard deviation actually used, metres."""
        return float(self._ext.noise)

    @property
    def vertical_fov(self) -> tuple[float, float]:
        """(lowest, highest) beam elevation in degrees."""
        return self._ext.vertical_fov

    @property
    def channels(self) -> int:
        """Beams (spinning and raster models) or emitters (rosette)."""
        return self._ext.channels

    def n_rays(self, frame: int = 0) -> int:
        """Rays fired in frame ``frame`` (after the horizontal window)."""
        return self._ext.n_rays(frame)


class DriveOptions(TypedDict, total=False):
    """How a :class:`Trajectory` builder drives; a key left out takes the simulator's default."""

    #: Metres between frames, measured on the map (default 1.0).
    spacing: float
    #: Metres right of the road's centreline (default 1.75: the right-hand lane).
    lane_offset: float
    #: Radius of the arcs that round the corners, metres (default 8.0).
    corner_radius: float
    #: Metres per second, which sets the time stamps (default 10.0).
    speed: float
    #: Height of the sensor above the sloped ground, metres (default 1.73).
    mount_height: float


@dataclass(frozen=True)
class Trajectory:
    """Sensor poses ``T_world_sensor`` (M, 3, 4) float64 and time stamps (M,) in seconds.

    The builders drive on the world's roads in the right-hand lane (``lane_offset`` metres right
    of the centreline), round corners with ``corner_radius`` arcs, keep the sensor
    ``mount_height`` above the sloped ground (its z axis along the ground normal), and place
    frames ``spacing`` metres apart (measured on the map) at ``speed`` m/s.
    """

    poses: F64
    times: F64

    def __post_init__(self) -> None:
        p = np.ascontiguousarray(self.poses, dtype=np.float64)
        t = np.ascontiguousarray(self.times, dtype=np.float64)
        if p.ndim != 3 or p.shape[1:] != (3, 4):
            raise _solid.SolidError(f"poses must have shape (M, 3, 4), got {p.shape}")
        if t.shape != (p.shape[0],):
            raise _solid.SolidError(f"times must have shape ({p.shape[0]},), got {t.shape}")
        object.__setattr__(self, "poses", p)
        object.__setattr__(self, "times", t)

    def __len__(self) -> int:
        return int(self.poses.shape[0])

    @property
    def positions(self) -> F64:
        """Sensor positions (M, 3)."""
        return np.ascontiguousarray(self.poses[:, :, 3])

    @property
    def headings(self) -> F64:
        """Yaw of each pose in degrees, (−180, 180]."""
        return yaw_degrees(self.poses[:, :, :3])

    def __getitem__(self, index: slice) -> Trajectory:
        return Trajectory(self.poses[index], self.times[index])

    @classmethod
    def named(cls, world: World, kind: str, *, laps: float = 1.0, **options: Unpack[DriveOptions]) -> Trajectory:
        """One of :data:`TRAJECTORIES` (``laps`` applies to ``loop`` only)."""
        return cls(*_solid._sim_trajectory(world._ext, kind, laps=laps, **options))

    @classmethod
    def loop(cls, world: World, laps: float = 1.0, **options: Unpack[DriveOptions]) -> Trajectory:
        """Counter-clockwise laps around the block south-west of the world's centre, starting
        mid-way along its southern street; 1.0 returns to the start, 1.5 repeats half the loop."""
        return cls.named(world, "loop", laps=laps, **options)

    @classmethod
    def figure_eight(cls, world: World, **options: Unpack[DriveOptions]) -> Trajectory:
        """Around the north-east block, straight through the central intersection (90° to the
        first pass), around the south-west block, and on along the first street again."""
        return cls.named(world, "figure-eight", **options)

    @classmethod
    def reverse(cls, world: World, **options: Unpack[DriveOptions]) -> Trajectory:
        """Two blocks east along the central street, a U-turn, and back in the opposite lane."""
        return cls.named(world, "reverse", **options)

    @classmethod
    def crossing(cls, world: World, **options: Unpack[DriveOptions]) -> Trajectory:
        """Through the central intersection heading east, around the south-east block, and
        through it again heading north (a revisit at a 90° different heading)."""
        return cls.named(world, "crossing", **options)

    @classmethod
    def from_waypoints(
        cls, world: World, waypoints: AbcSequence[tuple[float, float]] | npt.ArrayLike, **options: Unpack[DriveOptions]
    ) -> Trajectory:
        """Drive along a centreline polyline (K, 2) in metres; 180° reversals become U-turns."""
        wp = np.asarray(waypoints, dtype=np.float64)
        if wp.ndim != 2 or wp.shape[1] != 2:
            raise _solid.SolidError(f"waypoints must have shape (K, 2), got {wp.shape}")
        return cls(*_solid._sim_route(world._ext, [(float(x), float(y)) for x, y in wp], **options))

    @classmethod
    def spin(cls, world: World, x: float, y: float, headings: AbcSequence[float], mount_height: float = 1.73) -> Trajectory:
        """Poses at one place (x, y) on the ground, one per heading (degrees); times = indices."""
        poses, times = _solid._sim_spin(world._ext, float(x), float(y), [float(h) for h in headings], mount_height)
        return cls(poses, times)

    @classmethod
    def corridor_walk(
        cls,
        world: World,
        laps: float = 1.3,
        *,
        spacing: float = 2.0,
        speed: float = 1.5,
        mount_height: float = 1.2,
    ) -> Trajectory:
        """Walk counter-clockwise laps along the middle of the corridor ring of
        :meth:`World.corridors` (around the central block, from the middle of its southern
        corridor; corners rounded with 3 m arcs), a frame every ``spacing`` m at ``speed`` m/s,
        the sensor ``mount_height`` m above the floor. ``laps`` > 1 revisits the start's
        stretch in the same direction (true loops); every lap passes each module's copies, which
        look alike but lie ``module_length`` m and more apart.

        >>> w = World.corridors(seed=1, modules=3)
        >>> t = Trajectory.corridor_walk(w, laps=1.2)
        >>> round(float(np.linalg.norm(t.positions[1] - t.positions[0])), 6)
        2.0
        """
        return cls.loop(
            world, laps=laps, spacing=spacing, lane_offset=0.0, corner_radius=3.0, speed=speed, mount_height=mount_height
        )

    @classmethod
    def turn_in_place(
        cls,
        world: World,
        x: float = 0.0,
        y: float = 0.0,
        *,
        start: float = 0.0,
        sweep: float = 330.0,
        step: float = 2.0,
        wobble: float = 0.0,
        seed: int = 0,
        mount_height: float = 1.2,
        period: float = 0.1,
    ) -> Trajectory:
        """A sensor standing at (x, y) turning through ``sweep`` degrees (negative: clockwise) in
        ``step`` degree steps from heading ``start``; its position wanders smoothly within
        ``wobble`` metres of (x, y) (a seeded path, as a hand-held sensor's), ``mount_height``
        m above the ground, frames ``period`` s apart. ``floor(|sweep| / step) + 1`` frames.

        >>> t = Trajectory.turn_in_place(World.room(), sweep=330.0, step=2.0, wobble=0.3, seed=1)
        >>> len(t), bool(np.linalg.norm(t.positions[:, :2], axis=1).max() <= 0.3)
        (166, True)
        """
        poses, times = _solid._sim_turn(
            world._ext, float(x), float(y), start=start, sweep=sweep, step=step, wobble=wobble, seed=seed,
            mount_height=mount_height, period=period,
        )
        return cls(poses, times)

    def odometry(
        self,
        *,
        yaw_bias_deg_per_m: float = 0.0,
        yaw_bias_deg_per_frame: float = 0.0,
        scale_error: float = 0.0,
        translation_noise: float = 0.0,
        rotation_noise_deg: float = 0.0,
        seed: int = 0,
        breakdown: tuple[int, int] = (0, 0),
        breakdown_jump_m: float = 0.0,
        breakdown_climb_m: float = 0.0,
    ) -> Trajectory:
        """The odometry a drifting estimator would report along this true trajectory: same
        first pose, frame and time stamps. Every relative motion ``Δ = T_{k−1}⁻¹ T_k`` is
        corrupted — its translation scaled by ``1 + scale_error`` plus Gaussian noise of
        ``translation_noise`` m per axis, its rotation followed by a yaw about the sensor's z of
        ``yaw_bias_deg_per_m · |t_Δ| + yaw_bias_deg_per_frame`` plus Gaussian noise of
        ``rotation_noise_deg`` — and integrated, so the error grows with the path as a real
        odometry's does (on a straight line of length L, a yaw bias b puts the end b·L degrees
        and about b·L²/2 (radians) metres sideways off). The noise is seeded: the same seed gives
        the same odometry.

        ``breakdown`` = ``(first, end)`` makes the odometry break down for the steps into frames
        ``first … end − 1``: each of them also jumps ``breakdown_jump_m`` metres in a seeded
        horizontal direction and climbs its share of ``breakdown_climb_m`` (a LIO losing track:
        keyframe steps of tens of metres where the platform moved a few, tens of metres of
        vertical drift). The steps after it are right again; the error it made stays.

        >>> w = World(seed=1)
        >>> truth = Trajectory.loop(w, spacing=2.0)
        >>> odom = truth.odometry(yaw_bias_deg_per_m=0.01, scale_error=0.01, seed=3)
        >>> bool(np.allclose(odom.poses[0], truth.poses[0]))
        True
        """
        poses, times = _solid._sim_odometry(
            self.poses, [float(t) for t in self.times], yaw_bias_deg_per_m=yaw_bias_deg_per_m,
            yaw_bias_deg_per_frame=yaw_bias_deg_per_frame, scale_error=scale_error,
            translation_noise=translation_noise, rotation_noise_deg=rotation_noise_deg, seed=seed,
            breakdown=(int(breakdown[0]), int(breakdown[1])), breakdown_jump_m=breakdown_jump_m,
            breakdown_climb_m=breakdown_climb_m,
        )
        return Trajectory(poses, times)

    def drifting(
        self, percent: float, *, seed: int = 0, breakdown: tuple[int, int] = (0, 0), breakdown_jump_m: float = 0.0,
        breakdown_climb_m: float = 0.0,
    ) -> Trajectory:
        """The odometry of the documented drift class "``percent`` %" (docs/slam.md#drift): a yaw
        bias of 0.025°/m and a scale error of 1 % per percent, plus 0.05° of yaw and 1 cm of
        translation noise per step — the issue-41 cases use 1, 2, 3 and 5 %. A LiDAR(-inertial)
        odometry on an easy route drifts about 1 %, wheel odometry or a LIO on a hard stretch
        several times more. ``breakdown*``: as :meth:`odometry`'s.

        >>> truth = Trajectory.loop(World(seed=1), spacing=4.0)
        >>> bool(np.allclose(truth.drifting(0).poses, truth.odometry(rotation_noise_deg=0.05, translation_noise=0.01).poses))
        True
        """
        return self.odometry(
            yaw_bias_deg_per_m=0.025 * percent, scale_error=0.01 * percent, rotation_noise_deg=0.05,
            translation_noise=0.01, seed=seed, breakdown=breakdown, breakdown_jump_m=breakdown_jump_m,
            breakdown_climb_m=breakdown_climb_m,
        )

    def in_frame(self, frame: npt.ArrayLike) -> Trajectory:
        """The same poses expressed in ``frame`` ((3, 4) or (4, 4) ``T_world_frame``): each pose P
        becomes ``frame⁻¹ · P``."""
        return Trajectory(_solid._sim_in_frame(self.poses, _pose_array(frame)), self.times)


@dataclass(frozen=True)
class Sequence:
    """Simulated scans ((N, 4) float32: x, y, z, intensity in the sensor frame) with their poses."""

    scans: list[F32]
    trajectory: Trajectory
    sensor: Sensor

    def __len__(self) -> int:
        return len(self.scans)

    def __iter__(self) -> Iterator[F32]:
        return iter(self.scans)

    def __getitem__(self, i: int) -> F32:
        return self.scans[i]

    @property
    def poses(self) -> F64:
        """(M, 3, 4) ``T_world_sensor``."""
        return self.trajectory.poses

    @property
    def timestamps(self) -> F64:
        """(M,) seconds (the pipeline's name for :attr:`times`)."""
        return self.trajectory.times

    @property
    def times(self) -> F64:
        """(M,) seconds."""
        return self.trajectory.times

    def write(self, directory: PathLike, *, odometry: Trajectory | None = None) -> Path:
        """Write as a KITTI-layout folder (see :func:`write_sequence`); returns the folder."""
        write_sequence(directory, self, odometry=odometry)
        return Path(directory)


def _pose_array(pose: npt.ArrayLike) -> F64:
    p = np.ascontiguousarray(pose, dtype=np.float64)
    if p.shape == (4, 4):
        p = np.ascontiguousarray(p[:3])
    if p.shape != (3, 4):
        raise _solid.SolidError(f"pose must have shape (3, 4) or (4, 4), got {p.shape}")
    return p


def scan(world: World, sensor: Sensor, pose: npt.ArrayLike, frame: int = 0) -> F32:
    """One frame seen from ``pose`` (``T_world_sensor``, (3, 4) or (4, 4)): (N, 4) float32 points
    x, y, z, intensity in the sensor frame. ``frame`` selects the noise stream (and the rosette's
    time window). Rays with no return within range, or dropped, give no point."""
    return _solid._sim_scan(world._ext, sensor._ext, _pose_array(pose), frame)


def simulate(world: World, sensor: Sensor, trajectory: Trajectory, first_frame: int = 0) -> Sequence:
    """Scan every pose of ``trajectory`` (frame indices ``first_frame + i``), with the GIL released."""
    scans = _solid._sim_scans(world._ext, sensor._ext, trajectory.poses, first_frame)
    return Sequence(scans=scans, trajectory=trajectory, sensor=sensor)


#: File name of the drifting odometry that :func:`write_sequence` writes beside ``poses.txt``.
ODOMETRY_FILE = "odometry.txt"
#: File name of a session's true anchor that :func:`write_sessions` writes beside ``poses.txt``.
ANCHOR_FILE = "anchor.txt"


@overload
def write_sequence(directory: PathLike, source: Sequence, *, odometry: Trajectory | None = None) -> int: ...
@overload
def write_sequence(
    directory: PathLike, source: World, sensor: Sensor, trajectory: Trajectory, *, odometry: Trajectory | None = None
) -> int: ...
def write_sequence(
    directory: PathLike,
    source: Sequence | World,
    sensor: Sensor | None = None,
    trajectory: Trajectory | None = None,
    *,
    odometry: Trajectory | None = None,
) -> int:
    """Write a KITTI-layout folder: ``velodyne/000000.bin`` … (float32 N×4, little-endian),
    ``poses.txt`` (12 numbers per line: row-major 3×4 ``T_world_sensor``, the exact truth) and
    ``times.txt``; with ``odometry`` (e.g. :meth:`Trajectory.odometry`, one pose per frame) also
    ``odometry.txt`` in the same form, the poses a drifting estimator would report.
    Each file is written under a temporary name and renamed. Either pass a simulated
    :class:`Sequence`, or a world, sensor and trajectory to simulate and write one frame at a time
    (constant memory). Returns the number of frames."""
    d = os.fspath(directory)
    if isinstance(source, Sequence):
        if sensor is not None or trajectory is not None:
            raise TypeError("pass either a Sequence or (world, sensor, trajectory)")
        truth = source.trajectory
    elif sensor is None or trajectory is None:
        raise TypeError("write_sequence(directory, world, sensor, trajectory) needs all three")
    else:
        truth = trajectory
    if odometry is not None and len(odometry) != len(truth):
        raise _solid.SolidError(f"odometry has {len(odometry)} poses for {len(truth)} frames")
    if isinstance(source, Sequence):
        scans = [np.ascontiguousarray(s, dtype=np.float32) for s in source.scans]
        n = _solid._sim_write_scans(d, scans, source.poses, [float(t) for t in source.times])
    else:
        assert sensor is not None
        n = _solid._sim_write_sequence(d, source._ext, sensor._ext, truth.poses, [float(t) for t in truth.times])
    if odometry is not None:
        _solid._sim_write_poses(os.path.join(d, ODOMETRY_FILE), odometry.poses)
    return n


def session_routes(world: World, spacing: float = 2.0) -> tuple[Trajectory, Trajectory]:
    """Two sessions' routes through one world, in one frame: a lap around the block south-west
    of the centre (counter-clockwise), and a route that comes from the west along the block's
    southern street, turns north up its eastern street (both the way the lap drove them), and
    goes on north and east into streets the lap never saw. For multi-session tests and docs:
    the second session revisits about half of its route in the first session's direction."""
    pitch = world.block_pitch
    lap = Trajectory.loop(world, laps=1.0, spacing=spacing)
    second = Trajectory.from_waypoints(
        world, [(-2 * pitch, -pitch), (0.0, -pitch), (0.0, pitch), (pitch, pitch)], spacing=spacing
    )
    return lap, second


def away_route(world: World, spacing: float = 2.0) -> Trajectory:
    """A session that never visits the map of :func:`session_routes`' lap: streets north-east of
    the centre (from one block north of it, east for two blocks and north for one), which that
    lap, round the block south-west of the centre, never saw. In a look-alike world its places
    resemble the map's; every loop it gets into the lap's map is false and no anchor is right."""
    p = world.block_pitch
    return Trajectory.from_waypoints(world, [(0.0, p), (2 * p, p), (2 * p, 2 * p)], spacing=spacing)


def corridor_sessions(world: World, *, laps: float = 1.0, spacing: float = 2.0) -> tuple[Trajectory, Trajectory]:
    """Two sessions' walks around the corridor ring of :meth:`World.corridors`, in the world's
    frame: the first as :meth:`Trajectory.corridor_walk` (from the middle of the southern
    corridor, heading east), the second from the middle of the eastern corridor heading north —
    a different place and a heading 90° apart — both counter-clockwise for ``laps`` laps, so
    each revisits all of the other. Make them :class:`Session` s to give each its own frame."""
    first = Trajectory.corridor_walk(world, laps=laps, spacing=spacing)
    x0, x1 = world.roads[0], world.roads[1]
    ym = (x0 + x1) / 2.0
    ring = [(x1, x1), (x0, x1), (x0, x0), (x1, x0)]
    turns = int(np.ceil(laps))
    route = [(x1, ym)] + ring * turns + [(x1, ym)]
    second = Trajectory.from_waypoints(world, route, spacing=spacing, lane_offset=0.0, corner_radius=3.0, speed=1.5, mount_height=1.2)
    per_lap = (len(second) - 1) / turns
    return first, second[: int(round(laps * per_lap)) + 1]


@dataclass(frozen=True)
class Session:
    """One recording session with its own world frame, as a robot that starts its odometry at
    the identity sees it: :attr:`trajectory` holds the poses in the session's frame (the first
    is the identity) and :attr:`frame` is ``T_world_session`` (3, 4), the exact transform from the
    session's coordinates to the simulator's world.

    >>> w = World.corridors(seed=2, modules=2)
    >>> a, b = (Session.of(t) for t in corridor_sessions(w))
    >>> anchor = b.anchor(a)            # maps session b's coordinates into session a's
    >>> bool(np.allclose(b.trajectory.poses[0], np.eye(4)[:3]))
    True
    """

    trajectory: Trajectory
    frame: F64

    @classmethod
    def of(cls, trajectory: Trajectory, frame: npt.ArrayLike | None = None) -> Session:
        """The session that recorded ``trajectory`` (poses in the world's frame) in ``frame``
        (``T_world_session``; default: its first pose, so the session starts at the identity)."""
        f = _pose_array(trajectory.poses[0] if frame is None else frame)
        return cls(trajectory.in_frame(f), f)

    def anchor(self, other: Session) -> F64:
        """``T_other_self`` (3, 4): maps this session's coordinates into ``other`` 's — the
        anchor of this session in a map recorded by ``other`` (issue 27's ``anchor.txt``)."""
        anchor: F64 = _solid._sim_in_frame(self.frame, other.frame)[0]
        return anchor

    def in_world(self) -> Trajectory:
        """The poses back in the simulator's world frame."""
        return Trajectory(_solid._sim_in_frame(self.trajectory.poses, _inverse(self.frame)), self.trajectory.times)


def _inverse(pose: F64) -> F64:
    r = pose[:, :3]
    return np.ascontiguousarray(np.hstack([r.T, -(r.T @ pose[:, 3:])]))


def write_sessions(
    directory: PathLike,
    world: World,
    sensor: Sensor,
    trajectories: AbcSequence[Trajectory],
    *,
    own_frames: bool = False,
    odometry: AbcSequence[Trajectory] | None = None,
) -> list[Path]:
    """Simulate and write one KITTI-layout folder per trajectory (``session_0/``, ``session_1/``,
    …, see :func:`write_sequence`), so that a map built from one session can be evaluated
    against another (``solid map build`` / ``solid eval --map``). Returns the folders.

    By default all poses are in the world's frame. With ``own_frames``, each session's
    ``poses.txt`` is in its own frame (its first pose is the identity, as two independent
    odometries would give) and ``anchor.txt`` holds the exact transform from that session's
    frame into the first session's (one KITTI 3×4 row; the identity for ``session_0``).
    ``odometry`` (one trajectory per session, in the world's frame, e.g. from
    :meth:`Trajectory.odometry`) is written as each folder's ``odometry.txt``, in the same frame
    as its ``poses.txt``."""
    if odometry is not None and len(odometry) != len(trajectories):
        raise _solid.SolidError(f"{len(odometry)} odometries for {len(trajectories)} sessions")
    sessions = [Session.of(t) if own_frames else Session.of(t, np.eye(4)[:3]) for t in trajectories]
    out = []
    for i, (traj, sess) in enumerate(zip(trajectories, sessions)):
        d = Path(directory) / f"session_{i}"
        odom = None if odometry is None else odometry[i].in_frame(sess.frame)
        n = write_sequence(d, world, sensor, traj, odometry=odom)
        if own_frames:
            _solid._sim_write_poses(d / ANCHOR_FILE, sess.anchor(sessions[0])[None])
            # The scans are the same; only the frame of the poses changes.
            _solid._sim_write_poses(d / "poses.txt", sess.trajectory.poses)
        assert n == len(traj)
        out.append(d)
    return out


def true_heading(pose_query: npt.ArrayLike, pose_candidate: npt.ArrayLike) -> float:
    """docs/spec.md §3 ground-truth heading in degrees, (−180, 180]: ψ = yaw(R_queryᵀ · R_candidate), so
    that ``p_query ≈ Rz(ψ) · p_candidate``."""
    rq = _pose_array(pose_query)[:, :3]
    rc = _pose_array(pose_candidate)[:, :3]
    return float(yaw_degrees(rq.T @ rc))


def run_demo(
    out_dir: PathLike | None = None,
    *,
    seed: int = 3,
    sensor: str = "hdl64",
    h_fov: float = 60.0,
    laps: float = 1.5,
    spacing: float = 1.0,
    exclude: int = 50,
    radius: float = 5.0,
    threshold: float | None = None,
    plots: bool = True,
    progress: Progress = None,
) -> dict[str, Any]:
    """Simulate a drive with a loop under a narrow field of view and run the loop-closure pipeline
    on it (:class:`solid.pipeline.LoopClosurePipeline`, the preset's detector, ``threshold`` when
    given), scored against the simulator's exact poses by the same evaluation as ``solid eval``.
    Writes ``metrics.json``, ``queries.csv``, ``loops.csv``, ``config.json`` and (with ``plots``)
    the evaluation plots and ``map.png`` into a fresh folder (``out_dir``, or one under
    ``solid_results/``). ``progress`` (:data:`solid.pipeline.Progress`) reports each scan, by
    default with a bar in interactive use. Returns the metrics dictionary plus ``"simulation"``
    (the settings) and ``"folder"``; :func:`demo_summary` formats it."""
    from .commands import Inputs, evaluate
    from .config import PipelineConfig

    world = World(seed=seed)
    sens = Sensor(sensor, h_fov=h_fov)
    traj = Trajectory.loop(world, laps=laps, spacing=spacing)
    seq = simulate(world, sens, traj)
    det: dict[str, Any] = {"exclude_frames": exclude}
    if threshold is not None:
        det["threshold"] = threshold
    cfg = PipelineConfig.preset(sensor, detector=det, radius=radius)
    settings = {"seed": seed, "sensor": sensor, "h_fov": h_fov, "laps": laps, "spacing": spacing}

    def heading_of_true_loops(ev: Any) -> dict[str, Any]:
        m = ev.accepted & ev.correct
        err = np.abs(wrap_degrees(ev.heading_deg[m] - np.asarray(ev.scores.true_heading_deg)[m]))
        return {
            "true_loop_heading_error_deg_mean": float(err.mean()) if err.size else None,
            "true_loop_heading_error_deg_max": float(err.max()) if err.size else None,
        }

    def map_png(folder: Path, result: Any, evals: list[Any]) -> None:
        if plots:
            ev = evals[0]
            _plot_map(folder / "map.png", world, traj, ev.query, ev.ids[:, 0], ev.correct, ev.gt_positive)

    run = evaluate(
        seq,
        cfg,
        Inputs(sequence=Path(f"simulated_{sensor}_{h_fov:g}deg_seed{seed}"), reader="sim"),
        output=None if out_dir is None else Path(out_dir),
        plots=plots,
        extra={"simulation": settings},
        write_more=map_png,
        progress=progress,
    )
    out = dict(run.metrics)
    out.update(heading_of_true_loops(run.evaluations[0]))
    out["folder"] = str(run.folder)
    return out


def demo_summary(metrics: dict[str, Any]) -> str:
    """Human-readable lines for the result of :func:`run_demo` (what ``solid demo`` prints)."""

    def f(key: str, fmt: str = ".3f") -> str:
        v = metrics.get(key)
        return "n/a" if v is None else format(v, fmt)

    sim_cfg = metrics.get("simulation", {})
    det = metrics.get("config", {}).get("detector", {})
    lines = [
        f"simulated drive: {sim_cfg.get('laps', '?')} laps around a block, {metrics.get('frames')} frames "
        f"{sim_cfg.get('spacing', '?')} m apart, sensor {sim_cfg.get('sensor', '?')} clipped to "
        f"{sim_cfg.get('h_fov', '?')}° field of view (world seed {sim_cfg.get('seed', '?')})",
        f"online loop detector (threshold {det.get('threshold')}): {metrics.get('accepted')} loops, "
        f"{metrics.get('true_accepts')} true (precision {f('precision')}); heading error of true loops mean "
        f"{f('true_loop_heading_error_deg_mean', '.2f')}°, max {f('true_loop_heading_error_deg_max', '.2f')}°",
        f"loop detection (exclude {det.get('exclude_frames')} frames, radius {metrics.get('radius_m')} m, "
        f"{metrics.get('gt_queries')} revisiting queries of {metrics.get('queries')}):",
        f"  Recall@1 {f('recall_at_1')}   Recall@5 {f('recall_at_5')}   F1 max {f('f1_max')} "
        f"(at score <= {f('f1_threshold')})   AUC {f('auc')}",
        f"  heading error vs the simulator's truth over {metrics.get('correct_top1')} correct matches: "
        f"mean {f('rotation_error_deg_mean', '.2f')}°, median {f('rotation_error_deg_median', '.2f')}°, "
        f"max {f('rotation_error_deg_max', '.2f')}°",
    ]
    if metrics.get("folder"):
        lines.append(f"wrote {metrics['folder']}")
    return "\n".join(lines) + "\n"


def _plot_map(
    path: Path,
    world: World,
    traj: Trajectory,
    queries: npt.NDArray[np.int64],
    top1: npt.NDArray[np.int64],
    correct: npt.NDArray[np.bool_],
    gt: npt.NDArray[np.bool_],
) -> Path:
    from matplotlib.patches import Rectangle

    from .plots import figure, save

    # Muted colours for the world, none of them the legend's green (correct) or red (wrong).
    colours = {"building": "0.65", "car": "#9ecae1", "crown": "#c7b99a", "trunk": "#8c6d46",
               "pole": "0.2", "wall": "#bcbddc", "fence": "#fdd0a2"}
    kinds, fp, _ = world.footprints()
    xy = traj.positions
    pad = 60.0
    lo, hi = xy[:, :2].min(axis=0) - pad, xy[:, :2].max(axis=0) + pad
    fig = figure(6.5, 6.5)
    ax = fig.add_subplot()
    for k, f in zip(kinds, fp):
        if f[2] < lo[0] or f[0] > hi[0] or f[3] < lo[1] or f[1] > hi[1]:
            continue
        ax.add_patch(Rectangle((f[0], f[1]), f[2] - f[0], f[3] - f[1], color=colours.get(k, "0.5"), alpha=0.5, lw=0))
    ax.plot(xy[:, 0], xy[:, 1], color="k", lw=1.0, label="trajectory")
    ok_q = queries[correct]
    ax.scatter(xy[ok_q, 0], xy[ok_q, 1], s=6, color="#1a9641", zorder=3, label="query with a correct top-1")
    for q, c, ok, g in zip(queries, top1, correct, gt):
        if g and not ok and c >= 0:
            ax.plot([xy[q, 0], xy[c, 0]], [xy[q, 1], xy[c, 1]], color="#d7191c", lw=0.8, alpha=0.7, zorder=3)
    ax.plot([], [], color="#d7191c", label="wrong top-1 of a GT-positive query")
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"simulated world (seed {world.seed}) and loop matches", fontsize=9)
    ax.legend(loc="upper right", fontsize=7)
    return save(fig, path)
