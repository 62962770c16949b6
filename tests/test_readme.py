"""The README's Python examples run as written (mypy checks them too: see the Makefile)."""

from __future__ import annotations

import contextlib
import io
import runpy
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tools"))

from readme_examples import extract, to_module  # noqa: E402


def test_readme_starts_with_the_two_commands() -> None:
    lines = (REPO / "README.md").read_text().splitlines()
    head = "\n".join(lines[:8])
    assert "make demo" in head and "make test" in head


def test_readme_python_examples_run(tmp_path: Path) -> None:
    blocks = extract((REPO / "README.md").read_text())
    assert blocks, "README has no python examples"
    mod = tmp_path / "readme_examples.py"
    mod.write_text(to_module(blocks) + "\n" + "\n".join(f"example_{i}()" for i in range(len(blocks))) + "\n")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        runpy.run_path(str(mod), run_name="__main__")
    printed = out.getvalue().splitlines()
    # The quick start prints the distance of a turned scan, then its heading (≈ 30°).
    heading = float(printed[2])
    assert abs(heading - 30.0) < 2.0, printed
    assert float(printed[1]) < 0.05, printed
