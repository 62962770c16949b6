_SIM_SENSORS: list[str]


_SIM_TRAJECTORIES: list[str]


@final
class _SimWorld:
    @property
    def seed(self) -> int: ...
    @property
    def blocks(self) -> int: ...
    @property
    def block_pitch(self) -> float: ...
    @property
    def roads(self) -> list[float]: ...
    @property
    def bounds(self) -> tuple[float, float, float, float]: ...
    @property
    def layout(self) -> str: ...
    def __len__(self) -> int: ...
    def ground_height(self, x: float, y: float) -> float: ...
    def footprints(self) -> tuple[list[str], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...


@final
class _SimSensor:
    @property
    def name(self) -> str: ...
    @property
    def h_fov(self) -> float: ...
    @property
    def h_centre(self) -> float: ...
    @property
    def min_range(self) -> float: ...
    @property
    def max_range(self) -> float: ...
    @property
    def noise(self) -> float: ...
    @property
    def dropout(self) -> float: ...
    @property
    def seed(self) -> int: ...
    @property
    def vertical_fov(self) -> tuple[float, float]: ...
    @property
    def channels(self) -> int: ...
    def n_rays(self, frame: int = 0) -> int: ...


def _sim_world(
    seed: int = 0,
    blocks: int = 4,
    block_pitch: float = 80.0,
    road_half_width: float = 7.0,
    slope: tuple[float, float] = ...,  # (0.01, -0.006)
    repetition: float = 0.3,
    cell_size: float = 4.0,
) -> _SimWorld: ...


def _sim_corridor_world(
    seed: int = 0,
    blocks: int = 1,
    modules: int = 4,
    module_length: float = 45.0,
    width: float = 6.0,
    height: float = 3.0,
    jitter: float = 0.15,
    dropout: float = 0.1,
    cell_size: float = 4.0,
) -> _SimWorld: ...


def _sim_room_world(
    seed: int = 0,
    size: tuple[float, float] = ...,  # (6.0, 4.5)
    height: float = 2.6,
    furniture: int = 8,
    cell_size: float = 1.0,
) -> _SimWorld: ...


def _sim_sensor(
    name: str,
    h_fov: float | None = None,
    h_centre: float = 0.0,
    min_range: float | None = None,
    max_range: float | None = None,
    noise: float | None = None,
    dropout: float = 0.0,
    seed: int = 0,
    points: int | None = None,
) -> _SimSensor: ...


def _sim_scan(world: _SimWorld, sensor: _SimSensor, pose: npt.NDArray[np.float64], frame: int = 0) -> npt.NDArray[np.float32]: ...


def _sim_scans(
    world: _SimWorld, sensor: _SimSensor, poses: npt.NDArray[np.float64], first_frame: int = 0
) -> list[npt.NDArray[np.float32]]: ...


def _sim_trajectory(
    world: _SimWorld,
    kind: str,
    spacing: float = 1.0,
    laps: float = 1.0,
    lane_offset: float = 1.75,
    corner_radius: float = 8.0,
    speed: float = 10.0,
    mount_height: float = 1.73,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...


def _sim_route(
    world: _SimWorld,
    waypoints: list[tuple[float, float]],
    spacing: float = 1.0,
    lane_offset: float = 1.75,
    corner_radius: float = 8.0,
    speed: float = 10.0,
    mount_height: float = 1.73,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...


def _sim_spin(
    world: _SimWorld, x: float, y: float, headings: list[float], mount_height: float = 1.73
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...


def _sim_turn(
    world: _SimWorld,
    x: float,
    y: float,
    start: float = 0.0,
    sweep: float = 330.0,
    step: float = 2.0,
    wobble: float = 0.0,
    seed: int = 0,
    mount_height: float = 1.2,
    period: float = 0.1,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...


def _sim_odometry(
    poses: npt.NDArray[np.float64],
    times: list[float],
    yaw_bias_deg_per_m: float = 0.0,
    yaw_bias_deg_per_frame: float = 0.0,
    scale_error: float = 0.0,
    translation_noise: float = 0.0,
    rotation_noise_deg: float = 0.0,
    seed: int = 0,
    breakdown: tuple[int, int] | None = None,
    breakdown_jump_m: float = 0.0,
    breakdown_climb_m: float = 0.0,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...


def _sim_in_frame(poses: npt.NDArray[np.float64], frame: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]: ...


def _sim_write_poses(path: str | os.PathLike[str], poses: npt.NDArray[np.float64]) -> None: ...


def _sim_write_sequence(
    directory: str | os.PathLike[str],
    world: _SimWorld,
    sensor: _SimSensor,
    poses: npt.NDArray[np.float64],
    times: list[float],
) -> int: ...


def _sim_write_scans(
    directory: str | os.PathLike[str],
    scans: list[npt.NDArray[np.float32]],
    poses: npt.NDArray[np.float64],
    times: list[float],
) -> int: ...
