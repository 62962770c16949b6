@final
class MapAnchor:
    """Where a detector's session lies in its prior map (`LoopDetector.map_anchor`): the placement
    that mutually consistent loops into the map support (docs/spec.md §8)."""
    @property
    def transform(self) -> npt.NDArray[np.float64]:
        """T_map_world, (4, 4) float64: maps the session's pose frame ("odom") into the map's frame
        (fitted to the latest supporting loops)."""
    @property
    def loops(self) -> int:
        """Distinct queries that support it: those of the set of registrations into the map that placed it (one the gate turned down counts when it agrees) and of the loops accepted on it since."""
    @property
    def metres(self) -> float:
        """Metres of the session's path they span."""
    @property
    def first_query(self) -> int:
        """Id of the first supporting query."""
    @property
    def last_query(self) -> int:
        """Id of the latest supporting query."""
    @property
    def from_query(self) -> int:
        """Id of the first query of the stretch of the session's odometry (between breaks) that
        the anchor places: `transform` maps that stretch's poses only."""
    @property
    def to_query(self) -> int | None:
        """Id of the last query of that stretch when a break of the odometry ended it; None: the
        stretch goes on (`transform` is the map -> odom of now)."""
    @property
    def covariance(self) -> npt.NDArray[np.float64] | None:
        """The spread of the supporting loops' placements about `transform`, (6, 6) float64
        ((rotation in radians, translation in metres) order), or None with fewer than two."""
    def __eq__(self, other: object, /) -> bool: ...

@final
class Loop:
    """A detected loop closure: the best candidate of a detector step, when its score passes the threshold."""
    @property
    def query(self) -> int:
        """Id of the query scan (for `LoopDetector.query`, the id it would get)."""
    @property
    def candidate(self) -> int:
        """Id of the matched database entry."""
    @property
    def distance(self) -> float:
        """Cosine distance of the R-SOLiDs."""
    @property
    def heading(self) -> float:
        """Heading of the query relative to the candidate (refined), degrees in (-180, 180]."""
    @property
    def score(self) -> float:
        """The score the loop was accepted with: the R-SOLiD distance, or with verification
        |t| / (1 + |t|), |t| the length of its pose's translation (metres)."""
    @property
    def verified(self) -> bool:
        """Whether the loop was verified by registration (then it has a pose)."""
    @property
    def pose(self) -> npt.NDArray[np.float64] | None:
        """`T_query_candidate`, (4, 4) float64, of a verified loop: `p_query ≈ pose @ p_candidate`
        (docs/spec.md §3); its yaw is `heading`. None when the loop was not verified."""
    @property
    def fitness(self) -> float | None:
        """Overlap of the verifying registration (None when not verified)."""
    @property
    def rmse(self) -> float | None:
        """Inlier RMSE of the verifying registration, metres (None when not verified)."""
    @property
    def information(self) -> npt.NDArray[np.float64] | None:
        """The (6, 6) information matrix of `pose` for a pose graph (translation first, g2o's
        order; the error on the right of the measurement, as g2o's EDGE_SE3:QUAT and GTSAM's
        BetweenFactor): the registration's Hessian carried over and calibrated (docs/slam.md).
        None when the loop was not verified."""
    def __eq__(self, other: object, /) -> bool: ...


@final
class Candidate:
    """One candidate of a detector step, in the detector's ranking order."""
    @property
    def id(self) -> int:
        """Id of the database entry."""
    @property
    def distance(self) -> float:
        """Cosine distance of the R-SOLiDs, in [0, 1]."""
    @property
    def heading(self) -> float:
        """Heading of the query relative to this candidate (refined), degrees in (-180, 180]."""
    @property
    def score(self) -> float:
        """What ranks the candidates and what a precision-recall curve sweeps: the R-SOLiD
        distance, or with verification |t| / (1 + |t|) for a candidate that passed the gate (|t|
        the length of its pose's translation) and 1.5 + distance / 2 otherwise."""
    @property
    def verified(self) -> bool:
        """Whether this candidate was registered."""
    @property
    def accepted(self) -> bool:
        """Whether its registration passed the gate."""
    @property
    def rejection(self) -> str | None:
        """Why the gate, or the detector's checks after it (odometry, look-alike, uniqueness, support, placement), rejected its registration (None when accepted or not registered); a candidate whose stored cloud is corrupt or unreadable is not registered and says so, naming the place ("place 12: its stored cloud is corrupt or unreadable")."""
    @property
    def pose(self) -> npt.NDArray[np.float64] | None:
        """`T_query_candidate` (4, 4) of its registration (None when not registered)."""
    @property
    def fitness(self) -> float | None:
        """Overlap of its registration (None when not registered)."""
    @property
    def structure_fitness(self) -> float | None:
        """Overlap of its registration's points off horizontal surfaces (None when not registered)."""
    @property
    def rmse(self) -> float | None:
        """Inlier RMSE of its registration, metres (None when not registered)."""
    @property
    def degeneracy_translation(self) -> float | None:
        """Smallest eigenvalue of the translation block of its registration's information matrix."""
    @property
    def agreement(self) -> tuple[int, int] | None:
        """(initial yaws that reached the best pose, yaws tried), or None when not registered."""
    def __eq__(self, other: object, /) -> bool: ...


@final
class Detection:
    """Everything one detector step decided (docs/spec.md §8)."""
    @property
    def query(self) -> int:
        """Id of the query (the entry the step added)."""
    @property
    def eligible(self) -> int:
        """The candidates were drawn from the entries 0..eligible (the others were too recent); 0: nothing to search yet."""
    @property
    def candidates(self) -> list[Candidate]:
        """Up to `top_k` candidates, best first; with verification and a pose, also the places chosen by pose (`pose_candidates`, up to twice that after a long path without a loop)."""
    @property
    def loop(self) -> Loop | None:
        """The loop, when the best candidate's score is at most the threshold; else None."""
    @property
    def released(self) -> list[Loop]:
        """Loops of earlier queries reported late, in query order: loops into the map held until this step placed the session in the map (or revised the placement) and found them consistent with it (docs/spec.md §8, placement), loops the neighbours' vouching waited for (docs/loops.md#when-the-odometry-drifts), the loops the previous steps did not support that a later step's loop agrees with (docs/spec.md §8, support), and the loops of candidates a step's budget deferred to this one (`verify_step_points`, docs/spec.md §8, budget)."""
    @property
    def deferred(self) -> list[int]:
        """Ids of the candidates this step's budget deferred (`verify_step_points`, docs/spec.md §8, budget): unverified among `candidates`; the next steps register them, and a loop of theirs comes in `released` of the step that does. Empty when the step found its loop."""
    @property
    def placement(self) -> str | None:
        """What this step did to the session's placement in its map (`LoopDetector.map_anchor`): "placed" (the first placement), "revised" (a larger consistent set that disagreed replaced it), or None."""
    @property
    def pose(self) -> npt.NDArray[np.float64] | None:
        """T_world_sensor (4, 4) the step's checks used for the query: the caller's, or without one
        the detector's own odometry (the scan registered with the previous keyframe, chained;
        docs/loops.md#without-poses); None when the step had neither (verification off)."""
    @property
    def pose_source(self) -> str | None:
        """Where `pose` came from: "given" (the caller's), "chained" (the own odometry), "started"
        (the own odometry starts a frame here, the identity: the first scan without a pose, or the
        first after a link that failed the registration's quality checks; no odometry relates it
        to the places before); None without a pose."""


@final
class LoopDetector:
    """Online loop closure (docs/spec.md §8): each scan is searched against the places it may be
    matched with — a prior map, and its own session minus the exclusion window — then added.

    Safe to share between threads: a step (search, then add) runs alone; `query` and the
    getters run in parallel. A process forked while another thread runs a step finds its copy
    locked, as `Database`'s.
    """
    def __new__(
        cls,
        cfg: SolidConfig,
        exclude_recent: int | None = None,
        threshold: float | None = None,
        top_k: int | None = None,
        rerank: bool | None = None,
        *,
        exclude_meters: float | None = None,
        exclude_seconds: float | None = None,
        verify: bool | None = None,
        detector: DetectorConfig | None = None,
    ) -> LoopDetector:
        """`LoopDetector(cfg, ...)`: a detector with an empty database.

        Args:
            cfg: The configuration scans are described with; its base preset chooses the default
                threshold.
            exclude_recent: Frames of the own session never matched (the robot is still there);
                None: 50. The same as `DetectorConfig.exclude_frames`.
            threshold: Largest score (R-SOLiD cosine distance) accepted as a loop; None: the loop
                threshold of the configuration's base preset (docs/spec.md §4), else the largest preset
                threshold.
            top_k: Candidates each step returns (1..=1000); None: 10.
            rerank: Re-rank the candidates by R-SOLiD distance plus rotation-aligned A-SOLiD distance;
                None: off.
            exclude_meters: Also skip places of the own session fewer than this many metres back along
                the path (every scan then needs a pose); None or 0: off.
            exclude_seconds: Also skip places of the own session fewer than this many seconds back
                (every scan then needs a non-decreasing timestamp); None or 0: off.
            verify: Verify the best candidates by registration (None: on, the default); with it on,
                scans must be given as points.
            detector: Parameters to start from instead of the defaults; the other arguments override
                them.

        Raises:
            ConfigError: A detector parameter out of its range (named in the message).
            TypeError: A parameter of the wrong type.
        """
    @staticmethod
    def from_database(
        database: Database,
        exclude_recent: int | None = None,
        threshold: float | None = None,
        top_k: int | None = None,
        rerank: bool | None = None,
        *,
        exclude_meters: float | None = None,
        exclude_seconds: float | None = None,
        verify: bool | None = None,
        detector: DetectorConfig | None = None,
    ) -> LoopDetector:
        """A detector over an existing database (a prior map, other sessions), sharing its places
        instead of copying them: they are candidates from the first scan on and are never excluded
        as recent; the detector's own scans get the session after the largest one in the database
        and are kept by the detector, apart from `database`, which stays as it was (an add to it
        afterwards does not reach the detector and makes it its own copy first).

        Args:
            database: The map; its configuration becomes the detector's.
            <Args of LoopDetector.__new__>

        Returns:
            The detector.

        Raises:
            ConfigError: A detector parameter out of its range.
            DatabaseError: The database already uses the largest session number.
            TypeError: A parameter of the wrong type.
        """
    def add(
        self,
        points_or_descriptor: Descriptor | npt.ArrayLike,
        timestamp: float | None = None,
        pose: npt.ArrayLike | None = None,
    ) -> Loop | None:
        """Searches one scan against the eligible places, then adds it (GIL released).

        Args:
            points_or_descriptor: The scan's points (as `solid.describe` accepts) or its descriptor,
                made with the detector's configuration.
            timestamp: Seconds, or None.
            pose: `T_world_sensor` as a 3×4 array or 12 floats (row-major [R|t]), or None; stored with
                the place.

        Returns:
            The loop, or None when the best candidate's score is above the threshold (or there is no
            candidate yet).

        Raises:
            DatabaseError: A descriptor made with another configuration.
            ConfigError: An infinite timestamp, a non-finite pose or one that is not a rotation, a pose
                or timestamp missing when the exclusion needs it, a timestamp older than the previous
                one when excluding by seconds. Nothing is added then.
            SolidError: Points of the wrong shape or layout (as `solid.describe`).
            TypeError: Points of the wrong type or dtype.
            SolidError: A pose that is not 12 values or a 3×4 array.
        """
    def detect(
        self,
        points_or_descriptor: Descriptor | npt.ArrayLike,
        timestamp: float | None = None,
        pose: npt.ArrayLike | None = None,
    ) -> Detection:
        """As `add`, returning everything the step decided. With verification on (the default) the
        scan must be given as points: its cloud is prepared, stored with the place and registered
        with the best candidates'; a Descriptor then raises ConfigError.

        Args:
            <Args of LoopDetector.add>

        Returns:
            The step's query id, eligible entries, ranked candidates and loop.

        Raises:
            <Raises of LoopDetector.add>
        """
    def detect_many(
        self,
        scans: Sequence[Descriptor] | Sequence[npt.ArrayLike],
        timestamps: Sequence[float | None] | npt.ArrayLike | None = None,
        poses: Sequence[npt.ArrayLike | None] | npt.ArrayLike | None = None,
        threads: int | None = None,
        progress: Callable[[int], object] | None = None,
    ) -> list[Detection]:
        """`detect` for many scans in order, in one call (the GIL is released but for a moment
        between steps): point arrays are described (and, when the detector verifies, their clouds
        prepared) in parallel, then the steps run in order. Every input is checked before the first
        is added: on error nothing is added. Ctrl-C raises KeyboardInterrupt within a step (or a
        few scans of the preparation): the steps done before it are kept, each whole.

        Args:
            scans: Point arrays (as `solid.describe` accepts), or Descriptors made with the
                detector's configuration (verification off).
            threads: Workers describing and preparing the scans (None or 0: one per core).
            progress: Called with 1 after each step (for a progress bar); what it raises stops
                the batch there, as an interrupt does.
            timestamps: One per scan (None entries: none), or None for none at all.
            poses: One per scan (3×4 or 12 floats; None entries: none), an (N, 3, 4) array,
                or None for none at all.

        Returns:
            One Detection per descriptor, in order.

        Raises:
            <Raises of LoopDetector.add>
            SolidError: `timestamps` or `poses` of another length than `scans`.
        """
    def candidates(
        self,
        points_or_descriptor: Descriptor | npt.ArrayLike,
        k: int | None = None,
        timestamp: float | None = None,
        pose: npt.ArrayLike | None = None,
    ) -> list[Candidate]:
        """The candidates the scan would get if it were added now (with this timestamp and pose),
        without adding it.

        Args:
            <Args of LoopDetector.add>
            k: At most this many; None: the detector's `top_k`.

        Returns:
            The candidates, best first.

        Raises:
            <Raises of LoopDetector.add>
        """
    def query(self, points_or_descriptor: Descriptor | npt.ArrayLike) -> Loop | None:
        """Searches one scan against every place without adding it and without excluding any
        (localisation in a prior map); with verification on, its best candidates are registered
        (then the scan must be given as points).

        Args:
            points_or_descriptor: The scan's points or its descriptor.

        Returns:
            The best match as a Loop (its `query` is the id the scan would get), or None when its
            score is above the threshold.

        Raises:
            DatabaseError: A descriptor made with another configuration.
            ConfigError: A Descriptor given to a verifying detector (it needs the points).
            SolidError: Points of the wrong shape or layout.
            TypeError: Points of the wrong type or dtype.
        """
    def __len__(self) -> int: ...
    @property
    def database(self) -> Database:
        """Every place (the prior map and every scan added so far) as a Database of its own: the
        prior map itself, shared, while the detector has added no scan; after that a copy of the
        descriptors made by this call (a loaded map's clouds stay in its file). Later steps do not
        reach it."""
    @property
    def map(self) -> Database:
        """The prior map the detector was made over (`from_database`'s database as it was then;
        empty for a new detector), shared with the detector rather than copied."""
    @property
    def config(self) -> DetectorConfig:
        """The detector's parameters."""
    @property
    def session(self) -> int:
        """The session of the scans this detector adds."""
    @property
    def map_anchor(self) -> MapAnchor | None:
        """Where the session lies in the prior map, once loops into the map have placed it
        (docs/spec.md §8, placement: `placement_loops` mutually consistent loops over `placement_m`
        metres of its path); None before, and for a detector without a map or without poses."""
    @property
    def map_anchors(self) -> list[MapAnchor]:
        """The session's anchors in the map, one per stretch of its odometry between breaks that
        loops into the map placed, in order (`MapAnchor.from_query`); the last is `map_anchor`.
        Empty before the session is placed."""
    @property
    def session_start(self) -> int:
        """Id of the first scan of the own session (the number of prior-map places)."""
    @property
    def exclude_recent(self) -> int:
        """Frames of the own session excluded as too recent."""
    @property
    def threshold(self) -> float:
        """Largest score accepted as a loop."""
    @property
    def top_k(self) -> int:
        """Candidates re-ranked by A-SOLiD alignment."""
    @property
    def rerank(self) -> bool:
        """Whether re-ranking is on."""

def _drift_swing(
    r_expected: npt.NDArray[np.float64],
    r_pose: npt.NDArray[np.float64],
    positions: npt.NDArray[np.float64],
    r_query: npt.NDArray[np.float64],
) -> tuple[float, float, float]:
    """`ω × arm`: the displacement of the query (in its frame) that a rotation drift at a constant
    rate along the path `positions` ((N, 3) in the world, the place's first, the query's last)
    predicts, `ω` the rotation vector of `r_expected · r_poseᵀ` and the arm the place's position
    less the path's centroid, turned into the query's frame by `r_query`: the odometry check's
    allowance for a rotation drift (docs/spec.md §8; `solid.commands.measured_drift` uses it).

    Raises:
        SolidError: A rotation that is not (3, 3), (3, 4) or (4, 4); positions not (N, 3); a NaN
            or infinity.
    """
