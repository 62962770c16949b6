class DatabaseError(SolidError):
    """A database, place or loop-detector error: config mismatch, corrupt, truncated, foreign or
    newer-version file (the message names the file and the reason)."""


@final
class Match:
    """One search result."""
    @property
    def id(self) -> int:
        """The entry's id in its database (insertion order, from 0)."""
    @property
    def distance(self) -> float:
        """Cosine distance of the R-SOLiDs, in [0, 1]."""
    def __eq__(self, other: object, /) -> bool: ...


@final
class Database:
    """Places with exact search at every size (a kd-tree, a byte sketch and brute force: `method`
    "auto" chooses, every method returns the same neighbours), batch add and search, merge, save
    and load. A-SOLiDs are kept at 8 bits per value (see `a`); about 300 bytes per entry, plus
    the compact clouds of places stored for verification.

    `save` writes a temporary file of its own next to the target and renames it over the
    target: concurrent saves to one path all succeed and leave one of them, whole; a save killed
    midway leaves the old file. `load` reads regular files only (a FIFO or a device is refused
    before it is opened) and checks the header against the file's size before reading the body.

    Safe to share between threads: searches run in parallel, an add or a merge waits for them
    and runs alone, and so does the search that builds an index left to the searches (see
    `add_batch`; that one search takes as long as `build_index`: pass `index=True` where no
    search may wait). A process forked while another thread adds, merges or builds the index finds
    its copy locked (as with any lock held across `fork`): fork while no thread does, or use
    `multiprocessing`'s `forkserver` or `spawn` start method.

    `LoopDetector.from_database` shares the places with the database instead of copying them:
    whichever changes them first (an add, a merge, `build_index`, a metadata change on the
    database) makes its own copy then.
    """
    def __new__(cls, cfg: SolidConfig) -> Database:
        """`Database(cfg)`: an empty database.

                Args:
                    cfg: The configuration of every descriptor the database will hold.
        """
    def add(
        self,
        descriptor: Descriptor,
        session: int = 0,
        timestamp: float | None = None,
        pose: npt.ArrayLike | None = None,
        cloud: bytes | bytearray | memoryview | None = None,
    ) -> int:
        """Adds one place, with the GIL released.

                Args:
                    descriptor: A descriptor made with the database's configuration.
                    session: The robot or run it comes from (0 to 2^32 - 2: the session after the last must be numbered).
                    timestamp: Seconds, or None for none (stored as NaN).
                    pose: `T_world_sensor` as a 3×4 array or 12 floats (row-major [R|t]), or None.
                    cloud: The place's compact cloud for verification (`solid.encode_cloud` or
                        `PreparedCloud.encode`, as `cloud` returns it), or None.

                Returns:
                    The new entry's id.

                Raises:
                    DatabaseError: The descriptor was made with another configuration, or the
                        cloud is not a valid compact cloud (its checksum).
                    ConfigError: A session outside 0..2**32-1, an infinite timestamp, or a pose
                        that is not finite or whose 3×3 part is not a rotation.
                    SolidError: A pose that is not 12 values or a 3×4 array.
                    TypeError: A session that is not an integer (a bool included).
        """
    def add_batch(
        self,
        r: npt.NDArray[np.float32] | npt.NDArray[np.float64],
        a: npt.NDArray[np.float32] | npt.NDArray[np.float64],
        session: int = 0,
        timestamps: npt.NDArray[np.float64] | None = None,
        poses: npt.NDArray[np.float64] | None = None,
        index: bool | None = None,
    ) -> int:
        """Adds N places at once from arrays, with the GIL released; everything is checked before
        anything is added.

        Args:
            r: R-SOLiDs, shape (N, n_range), float32 (read in place) or float64, C-contiguous.
            a: A-SOLiDs, shape (N, n_azimuth), float32 or float64, C-contiguous.
            session: The robot or run they come from (0 to 2^32 - 2: the session after the last must be numbered).
            timestamps: Seconds, shape (N,), float64 (NaN: none), or None for none.
            poses: `T_world_sensor` of each, float64 of shape (N, 3, 4), (N, 4, 4) or (N, 12)
                (row-major [R|t]), or None.
            index: When to bring the search sketch and the kd-tree up to date. Until then the
                entries are only stored (checked, normalised, A-SOLiDs quantised: the fastest way
                to load many) and searches stay exact, computing the distance of every entry
                beyond the index. None (the default): the first search that finds the index due
                builds it, alone, before searching: once the searches have scanned the entries
                beyond it about as many times over as building it costs (40 times the rows the
                build indexes; for a first bulk add into an empty database, 40 searches or a
                `search_batch` of 40 queries), so a few searches never pay for an index and many
                pay for it once. True: now. False: at `build_index`, the next `add`, an indexed
                `add_batch` or a `merge`. The last `add_batch` decides for every entry still
                waiting.

        Returns:
            The id of the first new entry (the others follow).

        Raises:
            SolidError: An array of the wrong shape or layout.
            ConfigError: A negative or non-finite descriptor value, an infinite timestamp, a
                session outside 0..2**32-1, or a pose that is not a rotation.
            TypeError: An argument that is not a float array.
        """
    def build_index(self, sketch: bool | None = None) -> None:
        """Extends the search sketch and the kd-tree over every entry (after `add_batch`, before
        the searches build them); nothing to do when they are up to date. A loaded map's index is
        the kd-tree alone: its searches are mostly for the places it holds, which the kd-tree
        answers, and the sketch (52 bytes a place with the presets) would only speed up searches
        for other places (docs/performance.md#maps-at-scale).

        Args:
            sketch: True builds the sketch too (a loaded map's searches for places it does not
                hold, about 2.5× faster at a million places, for 52 MiB more); False frees it;
                None keeps the database's choice (on for a new database, off for a loaded one).
                The search results are the same either way.
        """
    def index_pending(self) -> int:
        """The entries the search sketch and the kd-tree do not cover yet: those left by
        `add_batch`, and up to 15 before them (the sketch covers whole blocks of 16), scanned by
        brute force until the index is built.

        Returns:
            A count of entries (0 when the index is up to date).
        """
    def memory_bytes(self) -> int:
        """The memory the database holds.

        Returns:
            Bytes: every buffer's capacity (about 300 a place without a pose, 104 more with one;
                about 240 for places added with `add_batch` until the index is built).
        """
    def search(
        self,
        descriptor: Descriptor | npt.ArrayLike,
        k: int = 1,
        exclude_recent: int = 0,
        method: str = "auto",
        not_newer_than: float | None = None,
        max_distance: float | None = None,
    ) -> list[Match]:
        """The `k` nearest entries by cosine distance, exactly (docs/spec.md §3), GIL released.

                Args:
                    descriptor: A descriptor made with the database's configuration, or an R-SOLiD as a
                        1-D sequence of `n_range` floats.
                    k: How many neighbours.
                    exclude_recent: Leave out the most recently added entries (the last `exclude_recent`
                        ids), as a loop detector does.
                    method: "auto" (the kd-tree under a work budget, then the byte sketch, then brute
                        force, each from where the previous one stops paying; on a database whose
                        sketch keeps failing, rows too alike for its bytes, a deeper kd-tree walk
                        replaces it), "brute", "kdtree" or "sketch": the same neighbours either way.
                    not_newer_than: Leave out entries whose timestamp is greater (entries without one are
                        kept).
                    max_distance: Return only matches at most this far (a loop threshold), or None; every
                        method skips more with it.

                Returns:
                    Up to `k` matches, nearest first, ties by lower id.

                Raises:
                    DatabaseError: The descriptor was made with another configuration.
                    SolidError: An R-SOLiD of the wrong length.
                    ConfigError: An R-SOLiD with negative or non-finite values, an unknown
                        `method`, a negative `k` or `exclude_recent`, a NaN `not_newer_than` (None
                        means no limit), or a NaN `max_distance`.
                    TypeError: `descriptor` is neither a Descriptor nor a sequence of floats.
        """
    def search_batch(
        self,
        queries: npt.NDArray[np.float32] | npt.NDArray[np.float64] | Sequence[Descriptor],
        k: int = 1,
        exclude_recent: int = 0,
        method: str = "auto",
        not_newer_than: float | None = None,
        max_distance: float | None = None,
    ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float32]]:
        """`search` for many queries in one call: the GIL released once, the queries shared among
        every core.

        Args:
            queries: R-SOLiDs, shape (M, n_range), float32 or float64, or Descriptors made with the
                database's configuration.
            k: How many neighbours per query.
            exclude_recent: As in `search`.
            method: As in `search`.
            not_newer_than: As in `search`.
            max_distance: As in `search`.

        Returns:
            Ids, shape (M, k), int64 (-1 in empty slots), and distances, shape (M, k), float32 (inf
            in empty slots); row i holds what `search(queries[i], ...)` returns, nearest first.

        Raises:
            DatabaseError: A Descriptor made with another configuration.
            SolidError: An array of the wrong shape.
            ConfigError: A query with negative or non-finite values, an unknown `method`, a
                negative `k` or `exclude_recent`, a NaN `not_newer_than` or `max_distance`.
            TypeError: `queries` is neither an array nor a sequence of Descriptors.
        """
    def distances(self, descriptor: Descriptor | npt.ArrayLike) -> npt.NDArray[np.float32]:
        """The cosine distance from the query to every entry, in id order (for plots and analysis;
        `search` finds the nearest).

        Args:
            descriptor: A descriptor made with the database's configuration, or an R-SOLiD as a 1-D
                sequence of `n_range` floats.

        Returns:
            float32 array of shape (N,).

        Raises:
            DatabaseError: The descriptor was made with another configuration.
            SolidError: An R-SOLiD of the wrong length.
            TypeError: `descriptor` is neither a Descriptor nor a sequence of floats.
        """
    def merge(self, other: Database, new_sessions: bool = False, anchor: npt.ArrayLike | None = None) -> None:
        """Appends every entry of `other` (another robot's or run's map), keeping their order,
        timestamps and poses; their ids follow this database's. Nothing changes on error.

        Args:
            other: A database with the same configuration (it may be this one); it is not changed.
            new_sessions: Renumber the sessions of `other` to follow this database's, so that maps of
                separate runs stay apart.
            anchor: ``T_map_other`` (3×4 or 4×4): every pose of `other` is carried into this map's
                world (``X ↦ T·X``) as it is merged (``solid map merge --anchor``). Or one per place
                of `other`, an array of shape (len(other), 3, 4) or (len(other), 4, 4): each place's
                pose carried by its own (a session whose odometry broke: one anchor per stretch,
                ``anchors.kitti``); a place whose transform is all NaN is merged without a pose.
                float32 is read as float64.

        Raises:
            DatabaseError: `other` has another configuration.
            ConfigError: `anchor` is not a finite rigid transform; of an array of them, one is not
                (the message names its place) or there is not one per place of `other` (it names
                both counts).
            SolidError: `anchor` is of none of the shapes above.
            TypeError: an array of transforms is neither float64 nor float32.
            ValueError: a 4×4 of the array does not end with the row [0, 0, 0, 1], or the array's
                transforms are not 3×4 or 4×4.
        """
    def save(self, path: str | PathLike[str], version: int = 4, *, replace: bool = True) -> None:
        """Writes the database to `path` (docs/spec.md §9), atomically: a temporary file in the
                same folder, then a rename. Written as it is encoded: no copy of the whole file in
                memory. Only a regular file is ever replaced: a FIFO, a device, a socket or a
                directory at `path` (also through a symbolic link) is refused.

                Args:
                    path: The file to write (a regular file there is replaced, unless `replace` is
                        False).
                    version: The file format: 4 (the current one: a pose's rotation as a unit
                        quaternion, read back within 1e-12), 3 for readers before format 4 (poses
                        as matrices), or 2 for older readers (which keeps no `metadata`).
                    replace: False: refuse when anything exists at `path`, also when it appears
                        during the save (the file is linked into place, which never replaces
                        anything): of concurrent saves to one path exactly one succeeds.

                Raises:
                    ConfigError: Another version.
                    DatabaseError: A stored cloud read from the file this map was loaded from is
                        corrupt, or that file changed since it was loaded (it is never written
                        again under a fresh checksum); nothing is written.
                    FileExistsError: `path` is not a regular file, or exists and `replace` is False;
                        nothing is written.
                    OSError: The file cannot be written (the subclass matches the cause, with `filename`).
        """
    @staticmethod
    def summary(path: str | PathLike[str]) -> dict[str, Any]:
        """What a database file holds, read from its header, section table and small sections
        alone in formats 3 and 4 (neither descriptors nor clouds: fast at any size); older files are read
        whole.

        Args:
            path: The file to read.

        Returns:
            A dict: ``version``, ``config`` (SolidConfig), ``fingerprint``, ``places``,
            ``places_with_cloud``, ``cloud_bytes``, ``sessions`` (per session, by number: a dict of
            ``session``, ``places``, ``with_pose``, ``first_time`` and ``last_time``, NaN when it has
            no timestamp) and ``metadata``.

        Raises:
            DatabaseError: As `load`.
            OSError: As `load`.
        """
    @property
    def metadata(self) -> str:
        """Free-form text saved with the database (format 3 on): `solid map build` records there how
        its scans were clipped, as JSON. "" when none; set it to replace it (at most 1 MiB)."""
    @metadata.setter
    def metadata(self, text: str) -> None:
        """Replaces the text saved with the database.

        Args:
            text: The new text, at most 1 MiB of UTF-8.

        Raises:
            ConfigError: The text is longer than 1 MiB.
        """
    @staticmethod
    def load(path: str | PathLike[str]) -> Database:
        """Reads a database written by `save`, checking everything (docs/spec.md §9).

                A file in format 3 or 4 is read in one pass, section by section, and its stored clouds
                stay in the file: the database keeps it open and reads a place's cloud when
                verification (or `cloud`) asks for it, checking that cloud's checksum then. Its
                search index (the kd-tree alone, see `build_index`) is left to the first search
                or detector.

                Args:
                    path: The file to read.

                Returns:
                    The database.

                Raises:
                    DatabaseError: Not a solid database, a newer format version, truncated, corrupted
                        (checksum), or invalid content; the message names the file and the reason.
                    OSError: The file cannot be read (FileNotFoundError, PermissionError, ...).
        """
    def to_bytes(self, version: int = 4) -> bytes:
        """The database in its file format (docs/spec.md §9).

                Args:
                    version: The file format: 4 (the current one), 3 or 2 for older readers.

                Returns:
                    The bytes `save` would write.

                Raises:
                    ConfigError: Another version.
                    DatabaseError: A stored cloud read from the map's file is corrupt.
        """
    @staticmethod
    def from_bytes(data: bytes | bytearray | memoryview) -> Database:
        """A database from bytes made by `to_bytes`, checked as `load` checks a file.

                Args:
                    data: The bytes: bytes, bytearray or memoryview.

                Returns:
                    The database.

                Raises:
                    DatabaseError: The bytes are not a valid database (the message says why).
                    MemoryError: The entries do not fit in memory.
                    TypeError: `data` is not bytes, bytearray or memoryview.
        """
    def __len__(self) -> int: ...
    @property
    def config(self) -> SolidConfig:
        """The configuration every entry was described with."""
    @property
    def r(self) -> npt.NDArray[np.float32]:
        """Every R-SOLiD, shape (N, n_range), float32 (a copy)."""
    @property
    def a(self) -> npt.NDArray[np.float32]:
        """Every A-SOLiD as kept, shape (N, n_azimuth), float32 (a copy): 8 bits per value with one
        step per entry, so each value is within half a step (0.2 % of the entry's largest value) of
        the one added."""
    @property
    def ids(self) -> npt.NDArray[np.int64]:
        """Entry ids 0..N, int64."""
    @property
    def cloud_bytes(self) -> int:
        """Bytes of the compact clouds stored for verification (0: none)."""
    @property
    def clouds_stored(self) -> int:
        """Number of places that have a stored cloud."""
    def cloud(self, id: int) -> bytes | None:
        """The compact cloud stored with a place for verification.

        Args:
            id: The place's id.

        Returns:
            Its wire form (decode it with `solid.decode_cloud`), or None when it has none. A map
            loaded from a file in format 3 or 4 reads it from the file now.

        Raises:
            DatabaseError: The stored cloud is corrupt (its checksum), named by place and file,
                or the file was truncated or written since the map was loaded (named).
            OSError: The file cannot be read.
            ConfigError: No place has this id (negative, beyond 64 bits, or `len(db)` and up).
            TypeError: An id that is not an integer (or a bool).
        """
    @property
    def sessions(self) -> npt.NDArray[np.uint32]:
        """Each entry's session, uint32."""
    @property
    def timestamps(self) -> npt.NDArray[np.float64]:
        """Each entry's timestamp, float64 (NaN where none was given)."""
    @property
    def poses(self) -> npt.NDArray[np.float64]:
        """Each entry's pose, shape (N, 3, 4), float64 (all NaN where none was given)."""


def encode_place(descriptor: Descriptor, quantized: bool = False) -> bytes:
    """Encodes one place for exchange between robots (docs/spec.md §10).

        Args:
            descriptor: The place.
            quantized: One byte per bin (square-root companded) instead of float32.

        Returns:
            420 bytes as float32 or 128 bytes quantised, for the default 40 + 60 bins.

        Raises:
            ConfigError: A vector with a negative or non-finite value (no descriptor holds one),
                named as r_solid or a_solid.
    """


def decode_place(data: bytes | bytearray | memoryview, cfg: SolidConfig) -> Descriptor:
    """Decodes a place made by `encode_place`. Point counts are not transmitted (they read 0).

        Args:
            data: The encoded place: bytes, bytearray or memoryview.
            cfg: The configuration the receiver uses; the place must have been made with it.

        Returns:
            The descriptor (approximate vectors when the place was quantised).

        Raises:
            DatabaseError: Not a place, an unknown version, a wrong length, a checksum mismatch, a
                negative or non-finite value, or a place made with another configuration (checked
                by fingerprint).
            TypeError: `data` is not bytes, bytearray or memoryview.
    """
