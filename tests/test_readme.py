"""The README's Python examples run as written (mypy checks them too: see the Makefile)."""

from __future__ import annotations

import contextlib
import io
import sys
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tools"))

from readme_examples import extract, to_module  # noqa: E402


def load_examples() -> tuple[ModuleType, int]:
    blocks = extract((REPO / "README.md").read_text())
    assert blocks, "README has no python examples"
    module = ModuleType("readme_examples_generated")
    exec(compile(to_module(blocks), "README.md", "exec"), module.__dict__)
    return module, len(blocks)


def run(module: ModuleType, i: int) -> list[str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        getattr(module, f"example_{i}")()
    return out.getvalue().splitlines()


def test_readme_starts_with_the_two_commands() -> None:
    head = "\n".join((REPO / "README.md").read_text().splitlines()[:8])
    assert "make demo" in head and "make test" in head


def test_quick_start_prints_what_it_says() -> None:
    module, _ = load_examples()
    printed = run(module, 0)
    # The quick start prints the shapes and counts, the distance of the turned scan, its heading.
    assert printed[0].startswith("(40,) (60,) 20000")
    assert float(printed[1]) < 0.05, printed
    assert abs(float(printed[2]) - 30.0) < 2.0, printed


def test_every_readme_example_runs() -> None:
    module, n = load_examples()
    for i in range(n):
        run(module, i)
    loop_lines = run(module, 1)
    assert any("revisits" in line for line in loop_lines), loop_lines
