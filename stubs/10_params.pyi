@final
class SolidConfig:
    """SOLiD parameters (docs/spec.md §1), immutable and hashable.

    Nothing is clamped: an invalid value raises ConfigError naming the parameter. Usually made
    from a sensor preset, `SolidConfig.preset("hdl64")`, rather than field by field.
    """
    # generated from the core's parameter table by tools/stubgen.py (make stubs): do not edit
    # end of generated
    @property
    def base_preset(self) -> str | None:
        """The preset this configuration was made from (`SolidConfig.preset(name, ...)`), or None.
        It chooses the loop detector's default threshold; it is not part of equality or the fingerprint.
        """
    @property
    def fingerprint(self) -> int:
        """64-bit FNV-1a hash of every parameter (docs/spec.md §1): descriptors are comparable
                only when their configurations' fingerprints are equal.
        """
    def __eq__(self, value: object, /) -> bool: ...
    def __ne__(self, value: object, /) -> bool: ...
    def __hash__(self) -> int: ...
    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]: ...


def _config_from_dict(d: dict[str, Any]) -> SolidConfig: ...


@final
class DetectorConfig:
    """The loop detector's parameters (docs/spec.md §8), immutable.

    The defaults come from the Rust core, the one place they are written; prefer
    `DetectorConfig.preset(name)`, which takes the loop threshold measured for that sensor.
    """
    # generated from the core's parameter table by tools/stubgen.py (make stubs): do not edit
    # end of generated
    @property
    def registration(self) -> RegistrationConfig:
        """The registration parameters."""
    @property
    def gate(self) -> AcceptanceGate:
        """The acceptance gate; its `max_translation` is the largest loop, metres."""
    def __eq__(self, other: object, /) -> bool: ...
    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]: ...


def _detector_config_from_dict(params: dict[str, Any]) -> DetectorConfig: ...


def _removed_detector_keys() -> dict[str, str]:
    """The parameters DetectorConfig no longer has, each with why and what replaces it (the
    core's table; ``solid.config.REMOVED_DETECTOR_KEYS``). Setting one is refused naming this.
    """


def _param_table(name: str) -> list[dict[str, Any]]:
    """The core's parameter table of "SolidConfig", "DetectorConfig", "RegistrationConfig" or
    "AcceptanceGate": one dict per field (name, aliases, type, min/max or choices, expected,
    required, default, doc), in order. The command line and tools/stubgen.py read it.
    """


@final
class RegistrationConfig:
    """Registration parameters, immutable; invalid values raise ConfigError naming the parameter.

    The defaults were chosen by measurement on hku1-avia (see the Rust documentation of
    `solid_lidar::reg`): GICP with a Geman-McClure kernel, coarse 1 m voxels with 3 m
    correspondences, then 0.5 m / 1 m.
    """
    # generated from the core's parameter table by tools/stubgen.py (make stubs): do not edit
    # end of generated
    def __eq__(self, value: object, /) -> bool: ...
    def __ne__(self, value: object, /) -> bool: ...


@final
class AcceptanceGate:
    """Thresholds a registration must meet to be accepted as a loop (measured defaults).

    Tuned for precision on hku1-avia and the simulator: with the defaults, none of 843 wrong
    registrations of hku1's top-5 candidates passes, 373 of 462 correct ones do.
    """
    # generated from the core's parameter table by tools/stubgen.py (make stubs): do not edit
    # end of generated
    def __eq__(self, other: object, /) -> bool: ...
    def check(self, registration: Registration) -> str | None:
        """Why `registration` is rejected, if it is.
        Args:
            registration: A result of `register`.
        Returns:
            None when it passes every threshold, else the first failed check ("low overlap",
            "degenerate translation", ...).
        """
    def accepts(self, registration: Registration) -> bool:
        """Whether `registration` passes every threshold.
        Args:
            registration: A result of `register`.
        Returns:
            True when `check` finds nothing.
        """
    def agreement(self, registration: Registration) -> int:
        """How many hypotheses reached the best one's pose (within this gate's tolerances).
        Args:
            registration: A result of `register` with `yaws`.
        Returns:
            The count, the best included; 0 without hypotheses.
        """
