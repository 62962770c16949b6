"""Extract the ```python blocks of a Markdown file into one module, for mypy and for tests.

Usage: python tools/readme_examples.py README.md build/readme_examples.py
Each block becomes a function ``example_N()`` so names do not leak between blocks.
"""

from __future__ import annotations

import re
import sys
import textwrap
from pathlib import Path


def extract(markdown: str) -> list[str]:
    """The bodies of the ```python fenced blocks, in order."""
    return [m.group(1) for m in re.finditer(r"```python\n(.*?)```", markdown, flags=re.S)]


def to_module(blocks: list[str]) -> str:
    out = ['"""Generated from README.md by tools/readme_examples.py; do not edit."""', ""]
    for i, block in enumerate(blocks):
        out.append(f"def example_{i}() -> None:")
        out.append(textwrap.indent(block.rstrip() or "pass", "    "))
        out.append("")
    return "\n".join(out) + "\n"


def main(argv: list[str]) -> int:
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    blocks = extract(Path(argv[1]).read_text(encoding="utf-8"))
    if not blocks:
        print(f"{argv[1]}: no ```python blocks", file=sys.stderr)
        return 1
    Path(argv[2]).write_text(to_module(blocks), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
