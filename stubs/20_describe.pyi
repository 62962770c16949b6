@final
class Descriptor:
    """One scan's SOLiD descriptor: R-SOLiD (``r``) and A-SOLiD (``a``) with point counts."""

    def __new__(
        cls,
        r: npt.ArrayLike,
        a: npt.ArrayLike,
        config: SolidConfig,
        n_points: int = 0,
        n_in_range: int = 0,
        n_kept: int = 0,
    ) -> Descriptor:
        """`Descriptor(...)`: a descriptor from stored vectors.

                Args:
                    r: R-SOLiD, `config.n_range` finite non-negative values.
                    a: A-SOLiD, `config.n_azimuth` finite non-negative values.
                    config: The configuration the vectors were computed with.
                    n_points: Points in the scan (informative).
                    n_in_range: Points left after the range filter (informative).
                    n_kept: Points binned, after voxel downsampling (informative).

                Raises:
                    SolidError: A vector of the wrong length, or with a negative or non-finite value.
                    TypeError: A vector that is not a 1-D sequence of numbers.
        """
    @property
    def r(self) -> npt.NDArray[np.float32]:
        """R-SOLiD, shape (n_range,), float32 (a new array on each access)."""
    @property
    def a(self) -> npt.NDArray[np.float32]:
        """A-SOLiD, shape (n_azimuth,), float32 (a new array on each access)."""
    @property
    def n_points(self) -> int:
        """Points passed in, before any filtering."""
    @property
    def n_in_range(self) -> int:
        """Points that were finite and within (min_range, max_range) (docs/spec.md §2 steps 1–2)."""
    @property
    def n_kept(self) -> int:
        """Points binned: voxel centroids after downsampling, else `n_in_range`."""
    @property
    def config(self) -> SolidConfig:
        """The configuration the descriptor was computed with."""
    def distance(self, other: Descriptor) -> float:
        """Cosine distance of the R-SOLiDs (docs/spec.md §3); the same as `solid.distance(self, other)`.

                Args:
                    other: A descriptor made with the same configuration.

                Returns:
                    The distance in [0, 1]: small for the same place; 1 when either scan was empty.

                Raises:
                    SolidError: The descriptors come from different configurations.
        """
    def heading(self, candidate: Descriptor, refine: bool = True) -> float:
        """Heading of this scan relative to `candidate` (docs/spec.md §3); the same as
                `solid.heading(self, candidate, refine)`.

                Args:
                    candidate: A descriptor of the same place made with the same configuration.
                    refine: Refine the best shift to a fraction of a bin (parabolic fit); if False the
                        result is a multiple of 360°/n_azimuth.

                Returns:
                    ψ in degrees, in (-180, 180]: this scan ≈ the candidate rotated by ψ counter-clockwise
                    about +z.

                Raises:
                    SolidError: The descriptors come from different configurations.
        """
    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]: ...


def describe(points: npt.NDArray[np.float32] | npt.NDArray[np.float64], config: SolidConfig) -> Descriptor:
    """Computes the SOLiD descriptor of one scan (docs/spec.md §2), with the GIL released.

        The array is read in place, never copied or converted: columns 0, 1, 2 are x, y, z in metres
        in the sensor frame (x forward, y left, z up); further columns (intensity, time, ...) are
        ignored. Non-finite points and points outside (min_range, max_range) are dropped; an empty
        scan is valid and gives all-zero vectors.

        Args:
            points: A C-contiguous float32 or float64 numpy array of shape (N, >=3).
            config: The descriptor configuration.

        Returns:
            The descriptor, with its point counts.

        Raises:
            TypeError: `points` is not a numpy array, or its dtype is not float32 or float64.
            SolidError: The shape is not (N, >=3), or the array is Fortran-ordered, a strided view
                or misaligned (the message says how to convert it).
    """


def describe_batch(
    scans: Iterable[npt.NDArray[np.float32] | npt.NDArray[np.float64]],
    config: SolidConfig,
    threads: int | None = None,
) -> list[Descriptor]:
    """Describes many scans in parallel, with the GIL released; the same results as `describe`
        on each.

        Args:
            scans: Point arrays, each as `describe` accepts (float32 and float64 may be mixed).
            config: The descriptor configuration.
            threads: Worker threads, at most one per core; None or 0 one per core, 1 the
                calling thread. The workers persist from one call to the next, each keeping its
                scratch buffers.

        Returns:
            One descriptor per scan, in order.

        Raises:
            TypeError: `scans` is not iterable, or an element is not a float32/float64 numpy array.
            SolidError: An element has the wrong shape or layout (named as `scans[i]`), or
                `threads` is negative.
    """


def distance(a: Descriptor, b: Descriptor) -> float:
    """Cosine distance between two descriptors' R-SOLiDs (docs/spec.md §3).

        Args:
            a: One descriptor.
            b: Another, made with the same configuration.

        Returns:
            The distance in [0, 1]: small for the same place; 1 when either scan was empty.

        Raises:
            SolidError: The descriptors come from different configurations.
    """


def heading(query: Descriptor, candidate: Descriptor, refine: bool = True) -> float:
    """Heading of `query` relative to `candidate` from their A-SOLiDs (docs/spec.md §3).

        Args:
            query: The scan taken now.
            candidate: An earlier scan of the same place, made with the same configuration.
            refine: Refine the best circular shift to a fraction of a bin (parabolic fit); if False
                the result is a multiple of 360°/n_azimuth.

        Returns:
            ψ in degrees, in (-180, 180]: the query scan ≈ the candidate rotated by ψ
            counter-clockwise about +z (`p_query ≈ Rz(ψ) · p_candidate`; with poses,
            ψ = yaw(R_queryᵀ · R_candidate)).

        Raises:
            SolidError: The descriptors come from different configurations.
    """


def presets() -> dict[str, SolidConfig]:
    """Every sensor preset (docs/spec.md §4).

        Returns:
            A new dict from preset name to its configuration, in the order of the spec's table.
    """


def preset_sensors() -> dict[str, str]:
    """The sensor each preset describes.

        Returns:
            A new dict from preset name to the sensor's name ("Velodyne HDL-64E (KITTI)", ...).
    """
