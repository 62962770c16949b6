"""The README's generated blocks: text between a start and an end marker, rewritten by a tool
(tools/readme_results.py, tools/readme_speed.py) and never typed by hand."""

from __future__ import annotations

import sys
from pathlib import Path

README = Path(__file__).resolve().parent.parent / "README.md"


def update(start: str, end: str, new: str, check: bool, tool: str) -> bool:
    """Puts `new` between `start` and `end` in README.md; with `check`, only compares (prints
    what to run when it differs). Returns whether README.md holds `new` (or now holds it)."""
    text = README.read_text(encoding="utf-8")
    if start not in text or end not in text:
        raise SystemExit(f"README.md has no {start} … {end} block")
    head, rest = text.split(start, 1)
    _, tail = rest.split(end, 1)
    updated = f"{head}{start}\n{new}\n{end}{tail}"
    if check:
        if updated != text:
            print(f"README.md's block {start} differs from what {tool} generates; run python {tool}", file=sys.stderr)
            return False
        return True
    README.write_text(updated, encoding="utf-8")
    return True
