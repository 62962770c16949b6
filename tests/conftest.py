"""Shared fixtures: where ../shared is, and skipping (never under CI) when it is absent."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


def shared_dir() -> Path:
    """`SOLID_SHARED`, else `<repo>/../shared`."""
    env = os.environ.get("SOLID_SHARED")
    return Path(env) if env else REPO.parent / "shared"


def require_shared() -> Path:
    """The shared folder; skips the test when it is absent, fails under CI=true."""
    d = shared_dir()
    if (d / "data").is_dir():
        return d
    if os.environ.get("CI") == "true":
        pytest.fail(f"shared data folder {d} is missing under CI")
    pytest.skip(f"shared data folder {d} not found (set SOLID_SHARED)")


def data_dir() -> Path:
    """`<shared>/data`; skips the test when absent, fails under CI=true."""
    return require_shared() / "data"


@pytest.fixture(scope="session")
def shared() -> Path:
    return require_shared()


@pytest.fixture(scope="session")
def data(shared: Path) -> Path:
    return shared / "data"
