"""Extract the ```python blocks of a Markdown file into one module, for mypy and for tests.

Usage: python tools/readme_examples.py README.md build/readme_examples.py
       python tools/readme_examples.py --run README.md
Each block becomes a function ``example_N()`` so names do not leak between blocks. ``--run`` runs
every block against the installed ``solid`` (and refuses a ``solid`` imported from a source tree),
which is how ``make test`` checks a freshly installed wheel or sdist.
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


def run(markdown_path: str) -> int:
    """Runs every block in order; returns the number run."""
    import solid  # here, not at the top: extracting must not need the package

    where = Path(solid.__file__).resolve()
    if not where.is_relative_to(Path(sys.prefix).resolve()):
        raise SystemExit(f"solid was imported from {where}, not from the environment {sys.prefix}")
    blocks = extract(Path(markdown_path).read_text(encoding="utf-8"))
    namespace: dict[str, object] = {"__name__": "readme_examples_run"}
    exec(compile(to_module(blocks), markdown_path, "exec"), namespace)
    for i in range(len(blocks)):
        print(f"--- {markdown_path} example {i + 1} of {len(blocks)}", flush=True)
        example = namespace[f"example_{i}"]
        assert callable(example)
        example()
    print(f"{len(blocks)} examples of {markdown_path} ran against solid {solid.__version__} from {where.parent}")
    return len(blocks)


def main(argv: list[str]) -> int:
    if len(argv) == 3 and argv[1] == "--run":
        return 0 if run(argv[2]) else 1
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
