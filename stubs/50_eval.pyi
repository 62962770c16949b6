DEFAULT_RADIUS: float


DEFAULT_POSE_TOLERANCE_M: float


DEFAULT_POSE_TOLERANCE_DEG: float


VERIFIED_THRESHOLD: float


@final
class Scores:
    """Per-query outcomes and the summary metrics of one scored run (docs/spec.md §5), made by
    `score_candidates`; `solid.evaluation` builds reports on it.
    """
    @property
    def radius(self) -> float:
        """Radius in metres within which a place counts as the same."""
    @property
    def gt_positive(self) -> npt.NDArray[np.bool_]:
        """Whether some eligible place lies within the radius, per query (bool array)."""
    @property
    def pose_tolerance_m(self) -> float:
        """Largest translation error (metres) of a correct loop's pose."""
    @property
    def pose_tolerance_deg(self) -> float:
        """Largest rotation error (degrees) of a correct loop's pose."""
    @property
    def correct(self) -> npt.NDArray[np.bool_]:
        """Whether the best candidate lies within the radius and its estimated pose, if any,
        within the pose tolerance, per query (bool array)."""
    @property
    def place_correct(self) -> npt.NDArray[np.bool_]:
        """Whether the best candidate lies within the radius, whatever its pose (bool array)."""
    @property
    def first_hit(self) -> npt.NDArray[np.uint32]:
        """1-based rank of the first candidate within the radius (0: none), per query."""
    @property
    def candidate_distance_m(self) -> npt.NDArray[np.float64]:
        """Metres from each query to its best candidate (NaN: none)."""
    @property
    def true_heading_deg(self) -> npt.NDArray[np.float64]:
        """True heading between each query and its best candidate, degrees (NaN: none)."""
    @property
    def pose_error_m(self) -> npt.NDArray[np.float64]:
        """Translation error of each query's estimated pose against the true
        `inv(T_world_query) @ T_world_candidate`, metres (NaN: no pose)."""
    @property
    def pose_error_deg(self) -> npt.NDArray[np.float64]:
        """Rotation error of each query's estimated pose, degrees (NaN: no pose)."""
    @property
    def n_gt(self) -> int:
        """Number of GT-positive queries."""
    def recall_at(self, n: int) -> float:
        """Recall@n: GT-positive queries with a correct candidate among their first n, over GT-positive queries.

        Args:
            n: How many candidates count (>= 1).

        Returns:
            The recall, NaN without GT-positive queries.
        """
    def pr_curve(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The precision-recall curve: a query's top-1 is accepted when its score <= τ, for τ over
        every observed top-1 score.

        Returns:
            (thresholds, precision, recall), float64 arrays of equal length.
        """
    def roc_curve(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The ROC curve of correct vs incorrect top-1s.

        Returns:
            (thresholds, false-positive rate, true-positive rate), float64 arrays.
        """
    def f1_max(self) -> tuple[float, float]:
        """The largest F1 = 2PR/(P+R) on the precision-recall curve.

        Returns:
            (F1 max, its threshold); (NaN, NaN) for an empty curve.
        """
    def auc(self) -> float:
        """The probability that a correct top-1 scores lower than an incorrect one (ties count one half).

        Returns:
            The AUC, NaN when either class is empty.
        """
    def at_threshold(self, threshold: float) -> tuple[int, int, float, float]:
        """What accepting the top-1s with score <= `threshold` gives.

        Args:
            threshold: The largest accepted score.

        Returns:
            (accepted, correct accepted, precision, recall).
        """
    def false_at_threshold(self, threshold: float) -> tuple[int, int]:
        """The wrong top-1s among those accepted with score <= `threshold`.

        Args:
            threshold: The largest accepted score.

        Returns:
            (place-false: the candidate lies beyond the radius, pose-false: the place is right
            but the estimated pose is outside the tolerance).
        """
    def rotation_errors(self) -> npt.NDArray[np.float64]:
        """|ψ_est − ψ_true| wrapped into [0°, 180°], over the correct top-1s.

        Returns:
            float64 array, degrees.
        """
    def __len__(self) -> int: ...


def score_candidates(
    query: npt.NDArray[np.int64],
    eligible: npt.NDArray[np.int64],
    ids: npt.NDArray[np.int64],
    score: npt.NDArray[np.float64],
    heading_deg: npt.NDArray[np.float64],
    poses: npt.NDArray[np.float64],
    radius: float,
    pose: npt.NDArray[np.float64] | None = None,
    pose_tolerance_m: float = ...,
    pose_tolerance_deg: float = ...,
) -> Scores:
    """Scores what a detector (or a baseline) decided against poses (docs/spec.md §5), with the
    GIL released; `solid.evaluation` wraps it in a friendlier form.

    Args:
        query: Query ids, shape (M,).
        eligible: Per query, the number of entries it could be matched with (ids 0..eligible).
        ids: Per query, its ranked candidate ids, shape (M, k); -1 pads missing candidates.
        score: Per query, its best candidate's score (what a threshold is compared with).
        heading_deg: Per query, the heading estimated for its best candidate, degrees.
        poses: Every frame's pose, shape (N, 3, 4), float64.
        radius: Metres within which a place counts as the same.
        pose: Per query, the metric `T_query_candidate` estimated for its best candidate, shape
            (M, 4, 4), NaN where none; None when no query has one.
        pose_tolerance_m: A top-1 whose pose is off by more than this many metres is not correct
            (default `DEFAULT_POSE_TOLERANCE_M`).
        pose_tolerance_deg: ... nor one off by more than this many degrees (default
            `DEFAULT_POSE_TOLERANCE_DEG`).

    Returns:
        The per-query outcomes and summary metrics.

    Raises:
        SolidError: A negative id (other than the -1 padding of `ids`), `poses` not of shape
            (N, 3, 4), or arrays of inconsistent lengths.
        ConfigError: A radius that is not finite and positive, an id outside the poses, a
            candidate that is not eligible, an `eligible` of 0 (skip queries with no database) or
            beyond the poses, a non-finite position.
    """
