@final
class PreparedCloud:
    """A cloud prepared once for registration: voxel levels, kd-trees, local covariances.

    Prepare each place once and pass it to `register` as often as needed; the two clouds of a
    registration must be prepared with the same configuration.
    """

    def __new__(
        cls,
        points: npt.NDArray[np.float32] | npt.NDArray[np.float64],
        config: RegistrationConfig | None = None,
    ) -> PreparedCloud:
        """`PreparedCloud(points, config)`: prepares raw points, with the GIL released.

        Args:
            points: (N, >=3) float32 or float64 array, x, y, z first (sensor frame, metres).
            config: The registration configuration; None: `RegistrationConfig()`.

        Raises:
            TypeError: `points` is not a numpy array or has another dtype.
            SolidError: `points` has the wrong shape or is not C-contiguous.
        """
    @staticmethod
    def decode(data: bytes | bytearray | memoryview, config: RegistrationConfig | None = None) -> PreparedCloud:
        """Decodes a cloud made by `PreparedCloud.encode` and prepares it.

        Args:
            data: The encoded cloud.
            config: The configuration; it must have the sender's voxel sizes, range and neighbours
                for the two clouds to register. None: `RegistrationConfig()`.

        Returns:
            The prepared cloud, as the sender would have prepared the same fine points.

        Raises:
            DatabaseError: Not a cloud, a checksum mismatch, or a bad length.
            TypeError: `data` is not bytes, bytearray or memoryview.
        """
    def encode(self, bits: int = 8) -> bytes:
        """The compact wire form of the fine points, for a robot asked to verify a loop.

        Args:
            bits: Bits per axis for the position within a grid cell (the config's voxel size;
                0.5 m when it is 0), 1..=16.

        Returns:
            The encoded cloud (about 4 bytes a point with 8 bits), CRC-checked.

        Raises:
            ConfigError: `bits` outside 1..=16.
        """
    @property
    def points(self) -> npt.NDArray[np.float64]:
        """The fine points, (N, 3) float64."""
    @property
    def coarse_points(self) -> npt.NDArray[np.float64]:
        """The coarse points, (M, 3) float64 (empty without a coarse level)."""
    @property
    def config(self) -> RegistrationConfig:
        """The configuration it was prepared with."""
    def __len__(self) -> int: ...


@final
class Hypothesis:
    """One initial yaw of a multi-hypothesis registration and where its coarse level ended."""

    @property
    def yaw(self) -> float:
        """The initial yaw, degrees."""
    @property
    def pose(self) -> npt.NDArray[np.float64]:
        """The pose after the coarse level, (4, 4) float64."""
    @property
    def cost(self) -> float:
        """The fine level's robust cost at that pose, normalised to [0, 1] (lower is better)."""
    @property
    def converged(self) -> bool:
        """Whether the coarse level converged."""
    @property
    def iterations(self) -> int:
        """Iterations of the coarse level."""


@final
class Registration:
    """T_query_candidate with p_query ≈ pose @ p_candidate (docs/spec.md §3) and its quality."""

    @property
    def pose(self) -> npt.NDArray[np.float64]:
        """T_query_candidate, (4, 4) float64: p_query ≈ pose @ p_candidate."""
    @property
    def fitness(self) -> float:
        """min(overlap_query, overlap_candidate): symmetric in the two clouds."""
    @property
    def overlap_query(self) -> float:
        """Fraction of the query's fine points within `inlier_distance` of a candidate point."""
    @property
    def overlap_candidate(self) -> float:
        """Fraction of the candidate's fine points within `inlier_distance` of a query point."""
    @property
    def structure_fitness(self) -> float:
        """The fitness over points off horizontal surfaces (the ground of any two places overlaps)."""
    @property
    def rmse(self) -> float:
        """Root mean square distance of the candidate's inliers, metres."""
    @property
    def inliers(self) -> int:
        """Number of candidate inliers."""
    @property
    def iterations(self) -> int:
        """Gauss-Newton iterations, summed over the levels."""
    @property
    def converged(self) -> bool:
        """Whether the fine level met the convergence test."""
    @property
    def degeneracy_rotation(self) -> float:
        """Smallest eigenvalue of the rotation block of the information matrix, per correspondence."""
    @property
    def degeneracy_translation(self) -> float:
        """Smallest eigenvalue of the translation block, per correspondence (low: a corridor)."""
    @property
    def degeneracy_marginal_translation(self) -> float:
        """Smallest eigenvalue of the translation's information with the rotation marginalised
        (Schur complement), per correspondence (low: the translation trades against a rotation)."""
    @property
    def hessian(self) -> npt.NDArray[np.float64]:
        """The Gauss–Newton Hessian JᵀWJ at the fine level at the final pose, (6, 6): rotation
        first, a perturbation on the left in the query's frame, unscaled."""
    @property
    def information(self) -> npt.NDArray[np.float64]:
        """The (6, 6) information matrix of `pose` for a pose graph, translation first (as
        `Loop.information`); zeros when there is no Hessian."""
    @property
    def yaw(self) -> float:
        """Yaw of the pose, degrees in (-180, 180]: the heading of docs/spec.md §3."""
    @property
    def hypotheses(self) -> list[Hypothesis]:
        """Every hypothesis, in the order of `yaws` (empty when no yaws were given)."""
    @property
    def best_hypothesis(self) -> int | None:
        """Index of the best hypothesis (None when no yaws were given)."""


def register(
    query: PreparedCloud | npt.NDArray[np.float32] | npt.NDArray[np.float64],
    candidate: PreparedCloud | npt.NDArray[np.float32] | npt.NDArray[np.float64],
    init: npt.ArrayLike | None = None,
    *,
    yaws: Iterable[float] | None = None,
    config: RegistrationConfig | None = None,
) -> Registration:
    """Registers `candidate` to `query` (GIL released): the pose with p_query ≈ pose @ p_candidate.

    Args:
        query: The query place: a PreparedCloud, or (N, >=3) float32/float64 points.
        candidate: The candidate place, likewise.
        init: Initial guess, (4, 4) rigid transform; None: the identity.
        yaws: Initial yaws (degrees) to try, each applied before `init` (see `hypothesis_yaws`);
            the coarse level runs from each and the fine level continues from the best. None:
            start from `init` only.
        config: The configuration; None: `RegistrationConfig()`. PreparedClouds must have been
            prepared with it.

    Returns:
        The registration. Clouds too small or too different give a result that is not converged
        (and that `AcceptanceGate` rejects), never an error.

    Raises:
        TypeError: Points that are not a numpy array or of another dtype; a malformed `init`.
        SolidError: Points of the wrong shape or not C-contiguous, `init` not (4, 4), empty
            `yaws`, or a PreparedCloud prepared with another configuration.
        ConfigError: `init` is not a finite rigid transform, or a yaw is not finite.
    """


def _register_verifying(
    query: PreparedCloud | npt.NDArray[np.float32] | npt.NDArray[np.float64],
    candidate: PreparedCloud | npt.NDArray[np.float32] | npt.NDArray[np.float64],
    init: npt.ArrayLike | None = None,
    *,
    yaws: Iterable[float] | None = None,
    config: RegistrationConfig | None = None,
    gate: AcceptanceGate | None = None,
) -> Registration:
    """`register` as a verifying detector runs it for a loop candidate, for the convergence-basin
    benchmark (`benches/reg_basin.py`); not part of the public API.

    The fine level (with `yaws`, every level) also stops once its cost has not reached a new low
    for 3 iterations while the candidate's overlap there is below `gate`'s `min_fitness` or `min_structure_fitness`; with
    `yaws`, a candidate whose best hypothesis is clearly below `min_fitness` gives up before the
    fine level (docs/spec.md §11). `gate` None: `AcceptanceGate()`. Arguments and errors as
    `register`'s.
    """

def hypothesis_yaws(query: Descriptor, candidate: Descriptor, n: int = 4) -> list[float]:
    """Initial yaws worth trying for a pair of places: 0° then the A-SOLiD minima.

    Args:
        query: The query's descriptor.
        candidate: The candidate's descriptor (same configuration).
        n: Most yaws to return.

    Returns:
        Degrees, 0 first, then the local minima of the A-SOLiD shift cost (docs/spec.md §3) lowest
        first, skipping any within one azimuth bin of one already chosen.

    Raises:
        SolidError: Descriptors from different configurations.
    """


def encode_cloud(
    points: npt.NDArray[np.float32] | npt.NDArray[np.float64], grid: float = 0.5, bits: int = 8
) -> bytes:
    """Encodes points compactly: Morton-sorted grid cells plus quantised offsets, CRC-checked.

    Args:
        points: (N, >=3) float32 or float64 array.
        grid: Grid edge, metres.
        bits: Bits per axis for the offset within a cell, 1..=16 (error at most grid / 2^(bits+1)).

    Returns:
        The encoded points (their order is not kept).

    Raises:
        ConfigError: A bad `grid` or `bits`, or a non-finite or far-away point.
    """


def decode_cloud(data: bytes | bytearray | memoryview) -> npt.NDArray[np.float64]:
    """Decodes points made by `encode_cloud`.

    Args:
        data: The encoded points.

    Returns:
        The points, (N, 3) float64.

    Raises:
        DatabaseError: Not a cloud, a checksum mismatch, or a bad length.
        TypeError: `data` is not bytes, bytearray or memoryview.
    """
