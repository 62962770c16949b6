"""One pipeline configuration: descriptor, loop detector, evaluation and input options.

The descriptor fields, the presets, the detector's fields and defaults (the per-preset loop
thresholds among them) and the evaluation radius are read from the Rust core at run time: this
module keeps no second copy of any of them. A :class:`PipelineConfig` is dumped to JSON, loaded
back, and recorded whole in every output folder (``config.json`` and ``metrics.json``)::

    cfg = PipelineConfig.preset("avia", descriptor={"max_range": 40.0}, detector={"exclude_meters": 20.0})
    cfg.dump("avia40.json")
    assert PipelineConfig.load("avia40.json") == cfg

JSON layout::

    {"preset": "avia",
     "descriptor": {"n_range": 40, ...},          # solid.SolidConfig fields
     "detector": {"exclude_frames": 50, ..., "verify": true, ...,
                  "registration": {...}, "gate": {...}},   # solid.DetectorConfig fields
     "evaluation": {"radius": 5.0, "pose_tolerance_m": 1.0, "pose_tolerance_deg": 5.0},
     "input": {"fov": null, "fov_center": null, "occlude": null, "occlude_center": 0.0,
               "frames": null, "subsample_m": null}}

Any section or key may be left out (it takes its default); unknown keys are errors that name
them, except the detector keys of checks since removed (:data:`REMOVED_DETECTOR_KEYS`), which are
dropped with a warning so that the ``config.json`` of an earlier run still loads. ``-0.0`` is written as ``0.0`` so that equal configurations dump, compare and hash equally.
The evaluation section only says how loops are scored (docs/spec.md §5: a loop is correct when its
candidate lies within ``radius`` and its pose within the pose tolerance of the truth); it never
changes what the detector accepts, so ``solid eval`` and ``solid detect`` with the same detector
settings accept the same loops.
"""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from collections.abc import Set as AbcSet
from typing import Any

from . import _solid
from .arrays import PathLike
from .errors import ConfigFileError
from .outputs import atomic_write_bytes

__all__ = ["REMOVED_DETECTOR_KEYS", "ConfigFileError", "InputOptions", "PipelineConfig", "default_text", "descriptor_fields", "detector_fields", "param_table", "per_preset_fields"]


#: Detector parameters of checks removed since they were written to ``config.json`` files, with
#: why and what replaces them (docs/performance.md#the-trust-matrix-issue-41; the core's table,
#: which refuses setting one: ``DetectorConfig(...)``, C ``solid_detector_config_set``).
#: A configuration file that names one loads without it, with a warning.
REMOVED_DETECTOR_KEYS: dict[str, str] = _solid._removed_detector_keys()


def descriptor_fields() -> dict[str, type]:
    """The descriptor parameters and their types, read from the core (``SolidConfig.to_dict``)."""
    any_preset = next(iter(_solid.presets().values()))
    return {k: type(v) for k, v in any_preset.to_dict().items()}


def detector_fields() -> dict[str, type]:
    """The loop-detector parameters and their types, read from the core."""
    return {k: type(v) for k, v in _solid.DetectorConfig().to_dict().items()}


def param_table(name: str) -> list[dict[str, Any]]:
    """The core's table of a parameter set ("SolidConfig", "DetectorConfig", "RegistrationConfig",
    "AcceptanceGate"): one dict per field with its name, aliases, type, range (``min``, ``max``,
    ``min_open`` or ``choices``), ``expected`` (the range in words), ``rule``, ``required``,
    ``default`` and ``doc``. The command-line flags and the stub are made from it."""
    return _solid._param_table(name)


def default_text(field: dict[str, Any], per_preset: AbcSet[str] = frozenset()) -> str:
    """A table field's default as the flags' help and the docs' tables write it: "the preset's"
    for a field each preset sets, on/off for a switch, "∞ (no limit)", a name in double quotes,
    else the number in its shortest exact form (3, 0.5)."""
    if field["name"] in per_preset:
        return "the preset's"
    v = field["default"]
    if isinstance(v, bool):
        return "on" if v else "off"
    if isinstance(v, float):
        if math.isinf(v):
            return "∞ (no limit)"
        return f"{v:g}" if float(f"{v:g}") == v else repr(v)
    return json.dumps(v) if isinstance(v, str) else str(v)


def per_preset_fields() -> set[str]:
    """The detector parameters whose default depends on the sensor preset (the loop threshold)."""
    base = _solid.DetectorConfig().to_dict()
    return {k for p in _solid.presets() for k, v in _solid.DetectorConfig.preset(p).to_dict().items() if v != base[k]}


def _is_number(v: Any) -> bool:
    """A real number (int or float), not a bool."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _norm(v: Any) -> Any:
    """-0.0 → 0.0, in nested dicts too (everything else is left alone)."""
    if isinstance(v, float) and v == 0.0:
        return 0.0
    if isinstance(v, dict):
        return {k: _norm(x) for k, x in v.items()}
    return v


@dataclass(frozen=True)
class InputOptions:
    """What the pipeline does to the input before describing it (all off by default).

    ``fov``/``fov_center``: keep only the horizontal sector ``fov`` degrees wide around
    ``fov_center`` (None: :data:`solid.pipeline.DEFAULT_FOV_CENTER`, 0° = +x, for every run, with a
    warning when the first scan has no point there). ``occlude``/``occlude_center``: remove a sector. ``frames``: a selection such as
    ``"0:60,284:314"`` (Python slices). ``subsample_m``: keep one frame per this many metres
    travelled (needs poses).
    """

    fov: float | None = None
    fov_center: float | None = None
    occlude: float | None = None
    occlude_center: float = 0.0
    frames: str | None = None
    subsample_m: float | None = None

    def __post_init__(self) -> None:
        for name in ("fov", "occlude"):
            v = getattr(self, name)
            if v is not None and not (_is_number(v) and math.isfinite(v) and 0 < v <= 360):
                raise _solid.ConfigError(f"invalid input.{name} = {v!r}: expected degrees in (0, 360]")
        for name in ("fov_center", "occlude_center"):
            v = getattr(self, name)
            if v is not None and not (_is_number(v) and math.isfinite(v)):
                raise _solid.ConfigError(f"invalid input.{name} = {v!r}: expected finite degrees")
        if self.subsample_m is not None and not (
            _is_number(self.subsample_m) and math.isfinite(self.subsample_m) and self.subsample_m > 0
        ):
            raise _solid.ConfigError(f"invalid input.subsample_m = {self.subsample_m!r}: expected metres > 0")
        if self.frames is not None and not isinstance(self.frames, str):
            raise _solid.ConfigError(f"invalid input.frames = {self.frames!r}: expected a string such as '0:60,284:314'")

    def to_dict(self) -> dict[str, Any]:
        return {f.name: _norm(getattr(self, f.name)) for f in fields(self)}


#: The keys of the evaluation section (each a finite number > 0) and what they hold.
_EVALUATION_KEYS = {"radius": "metres > 0", "pose_tolerance_m": "metres > 0", "pose_tolerance_deg": "degrees > 0"}


@dataclass(frozen=True)
class PipelineConfig:
    """Descriptor + detector + evaluation + input options of one pipeline run."""

    descriptor: _solid.SolidConfig
    detector: _solid.DetectorConfig
    radius: float = field(default=float(_solid.DEFAULT_RADIUS))
    input: InputOptions = field(default_factory=InputOptions)
    preset_name: str | None = None
    pose_tolerance_m: float = field(default=float(_solid.DEFAULT_POSE_TOLERANCE_M))
    pose_tolerance_deg: float = field(default=float(_solid.DEFAULT_POSE_TOLERANCE_DEG))

    def __post_init__(self) -> None:
        for name in _EVALUATION_KEYS:
            v = getattr(self, name)
            if not (_is_number(v) and math.isfinite(v) and v > 0):
                raise _solid.ConfigError(f"invalid evaluation.{name} = {v!r}: expected {_EVALUATION_KEYS[name]}")
            object.__setattr__(self, name, float(v) + 0.0)

    def evaluation(self) -> dict[str, float]:
        """The evaluation section: radius and pose tolerance of a correct loop (docs/spec.md §5)."""
        return {k: _norm(getattr(self, k)) for k in _EVALUATION_KEYS}

    @classmethod
    def preset(
        cls,
        name: str,
        *,
        descriptor: dict[str, Any] | None = None,
        detector: dict[str, Any] | None = None,
        radius: float | None = None,
        input: dict[str, Any] | None = None,
    ) -> PipelineConfig:
        """A sensor preset's descriptor and detector defaults, with overrides per section."""
        return cls.from_dict(
            {
                "preset": name,
                "descriptor": descriptor or {},
                "detector": detector or {},
                "evaluation": {} if radius is None else {"radius": radius},
                "input": input or {},
            }
        )

    @classmethod
    def from_dict(cls, doc: Any, where: str = "config") -> PipelineConfig:
        """Build from the JSON layout of the module docstring (missing keys take defaults)."""
        if not isinstance(doc, dict):
            raise _solid.ConfigError(f"{where}: expected a JSON object, got {type(doc).__name__}")
        unknown = set(doc) - {"preset", "descriptor", "detector", "evaluation", "input"}
        if unknown:
            raise _solid.ConfigError(
                f"{where}: unknown sections {', '.join(sorted(unknown))} (allowed: preset, descriptor, detector, evaluation, input)"
            )
        preset = doc.get("preset")
        if preset is not None and preset not in _solid.presets():
            raise _solid.ConfigError(f"{where}: unknown preset {preset!r}; one of {', '.join(_solid.presets())}")
        sections: dict[str, dict[str, Any]] = {}
        for sec in ("descriptor", "detector", "evaluation", "input"):
            v = doc.get(sec, {})
            if not isinstance(v, dict):
                raise _solid.ConfigError(f"{where}: section {sec!r} must be an object")
            sections[sec] = v
        removed = sorted(set(sections["detector"]) & set(REMOVED_DETECTOR_KEYS))
        if removed:
            warnings.warn(
                f"{where}: detector keys {', '.join(removed)} ignored: "
                + "; ".join(sorted({REMOVED_DETECTOR_KEYS[k] for k in removed})),
                UserWarning,
                stacklevel=2,
            )
            sections["detector"] = {k: v for k, v in sections["detector"].items() if k not in REMOVED_DETECTOR_KEYS}
        allowed = {
            "descriptor": set(descriptor_fields()),
            "detector": set(detector_fields()),
            "evaluation": set(_EVALUATION_KEYS),
            "input": {f.name for f in fields(InputOptions)},
        }
        for sec, keys in allowed.items():
            bad = set(sections[sec]) - keys
            if bad:
                raise _solid.ConfigError(f"{where}: unknown {sec} keys {', '.join(sorted(bad))} (allowed: {', '.join(sorted(keys))})")
        try:
            if preset is not None:
                desc = _solid.SolidConfig.preset(preset, **sections["descriptor"])
                det = _solid.DetectorConfig.preset(preset, **sections["detector"])
            else:
                missing = [k for k in ("fov_up", "fov_down", "n_elevation") if k not in sections["descriptor"]]
                if missing:
                    raise _solid.ConfigError(f"{where}: give a preset or the descriptor fields {', '.join(missing)}")
                desc = _solid.SolidConfig(**sections["descriptor"])
                det = _solid.DetectorConfig(**sections["detector"])
            inp = InputOptions(**sections["input"])
        except TypeError as e:
            raise _solid.ConfigError(f"{where}: {e}") from None
        try:  # __post_init__ checks the evaluation keys; the message gains the file's name
            return cls(descriptor=desc, detector=det, input=inp, preset_name=preset, **sections["evaluation"])
        except _solid.ConfigError as e:
            raise _solid.ConfigError(f"{where}: {e}") from None

    def to_dict(self) -> dict[str, Any]:
        """The JSON layout of the module docstring, every field written out."""
        return {
            "preset": self.preset_name,
            "descriptor": {k: _norm(v) for k, v in self.descriptor.to_dict().items()},
            "detector": {k: _norm(v) for k, v in self.detector.to_dict().items()},
            "evaluation": self.evaluation(),
            "input": self.input.to_dict(),
        }

    def dumps(self) -> str:
        """The configuration as indented JSON (what :meth:`loads` reads back)."""
        return json.dumps(self.to_dict(), indent=2) + "\n"

    @classmethod
    def loads(cls, text: str, where: str = "config") -> PipelineConfig:
        """Parse JSON text (errors name ``where``)."""
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as e:
            raise ConfigFileError(f"{where}: not JSON ({e})") from None
        except RecursionError:
            raise ConfigFileError(f"{where}: JSON nested too deeply") from None
        try:
            return cls.from_dict(doc, where)
        except ConfigFileError:
            raise
        except _solid.ConfigError as e:
            raise ConfigFileError(str(e)) from None

    def dump(self, path: PathLike) -> None:
        """Write :meth:`dumps` to ``path`` atomically."""
        atomic_write_bytes(Path(path), self.dumps().encode())

    @classmethod
    def load(cls, path: PathLike) -> PipelineConfig:
        """Read a file written by :meth:`dump` (or by ``solid config dump``)."""
        p = Path(path)
        if p.exists() and not p.is_file():
            raise ConfigFileError(f"{p}: not a regular file")
        try:
            size = p.stat().st_size
        except FileNotFoundError:
            raise FileNotFoundError(f"{p}: no such file") from None
        if size > 1 << 20:
            raise ConfigFileError(f"{p}: {size} bytes is far too large for a configuration file")
        try:
            text = p.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise ConfigFileError(f"{p}: not a text file") from None
        return cls.loads(text, str(p))

    def replace(self, **changes: Any) -> PipelineConfig:
        """A copy with whole fields replaced (``descriptor=``, ``detector=``, ``radius=``, ...)."""
        return replace(self, **changes)

    def __hash__(self) -> int:
        return hash(json.dumps(self.to_dict(), sort_keys=True))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PipelineConfig):
            return NotImplemented
        return self.to_dict() == other.to_dict()
