"""Every exception solid raises, in one place.

The extension's :class:`SolidError` (a ``ValueError``), :class:`ConfigError` and
:class:`DatabaseError` are re-exported here; the Python layers' own errors subclass them (or, for
an output that exists, ``FileExistsError``) and are defined here once. Each is also importable from
the module that raises it (``solid.datasets.ReadError``, ``solid.config.ConfigFileError``,
``solid.outputs.OutputExistsError``) and the extension's three from ``solid``.
"""

from __future__ import annotations

import os
from typing import Any

from ._solid import ConfigError, DatabaseError, SolidError
from .arrays import PathLike

__all__ = ["ConfigError", "ConfigFileError", "DatabaseError", "OutputExistsError", "ReadError", "SolidError"]


class ReadError(SolidError):
    """A point-cloud, bag, pose, timestamp or calibration file is malformed, truncated or unsupported.

    A :class:`solid.SolidError`, hence a :class:`ValueError`. The message always starts with the
    file's path, then says what is wrong; :attr:`path` and :attr:`what` hold the two parts.
    """

    def __init__(self, path: PathLike, what: str) -> None:
        self.path = os.fspath(path)
        self.what = what
        super().__init__(f"{self.path}: {what}")

    def __reduce__(self) -> tuple[Any, tuple[str, str]]:
        return (type(self), (self.path, self.what))


class ConfigFileError(ConfigError):
    """A configuration file that cannot be read or holds something invalid (names the file)."""


class OutputExistsError(FileExistsError):
    """The requested output folder already holds something."""
