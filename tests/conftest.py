"""Shared fixtures: where ../shared is, and skipping (never under CI) when it is absent."""

from __future__ import annotations

import csv
import multiprocessing
import os
import signal
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parent.parent

# A shell that starts the suite as a background job (`make test &`, nohup under a script) ignores
# SIGINT, and so would the commands the tests start: the tests of Ctrl-C need it delivered. A
# handler (unlike SIG_IGN) is reset to the default in the commands started from here.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


#: Modules whose tests time something against the clock or another process (the ROS 2 node
#: against a player over the middleware; Ctrl-C within a bound): marked `serial`, which `make
#: test` runs alone after the others have run in parallel (pytest-xdist).
SERIAL_MODULES = {"test_ros2", "test_interrupts"}


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if item.path.stem in SERIAL_MODULES:
            item.add_marker(pytest.mark.serial)


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


def in_forked_child(target: Callable[..., None], *args: Any, what: str, timeout: float = 60.0) -> Any:
    """Runs `target(*args, conn)` in a child made by fork and returns what it sent through
    `conn`; fails the test when the child hangs (the parent's worker threads do not exist there:
    code that waits for them never returns) or dies. Skips where fork does not exist."""
    if "fork" not in multiprocessing.get_all_start_methods():
        pytest.skip("needs fork")
    ctx = multiprocessing.get_context("fork")
    ours, theirs = ctx.Pipe()
    child = ctx.Process(target=target, args=(*args, theirs))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # fork of a multi-threaded process
        child.start()
    child.join(timeout)
    if child.is_alive():
        child.kill()
        pytest.fail(f"{what} hung in a forked child")
    assert child.exitcode == 0
    return ours.recv()


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    """``solid ARGV`` in this process: its exit code (1 for an exit without a number), stdout, stderr."""
    from solid.cli import main

    try:
        code = main(list(argv))
    except SystemExit as e:
        code = int(e.code) if isinstance(e.code, int) else 1
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))
