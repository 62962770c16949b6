"""mkdocs hooks (mkdocs.yml `hooks:`): pages include sections of other Markdown files.

A line `--8<-- "crates/solid-core/README.md:quick-start"` in a page is replaced by the text between
`<!-- --8<-- [start:quick-start] -->` and `<!-- --8<-- [end:quick-start] -->` in that file (a path
from the repository root), so the documentation shows the crate README's examples, which compile
as doctests, instead of copies that could drift. Rust fences keep only their language
(`rust,no_run` is rustdoc's; Markdown would not recognise the fence). A missing file or section
fails the build.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from mkdocs.exceptions import PluginError

INCLUDE = re.compile(r'^--8<-- "(?P<path>[^":]+):(?P<section>[\w-]+)"[ \t]*$', flags=re.M)


def include(root: Path, path: str, section: str) -> str:
    """The text of `section` in the file `path` under `root`, with rustdoc fence attributes dropped."""
    file = root / path
    if not file.is_file():
        raise PluginError(f"include: no file {path}")
    found = re.search(
        rf"^<!-- --8<-- \[start:{re.escape(section)}\] -->\n(.*?)^<!-- --8<-- \[end:{re.escape(section)}\] -->",
        file.read_text(encoding="utf-8"),
        flags=re.M | re.S,
    )
    if found is None:
        raise PluginError(f"include: no section {section!r} in {path}")
    return re.sub(r"^(\s*```rust),[\w,]+$", r"\1", found.group(1), flags=re.M)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    root = Path(config.config_file_path).parent
    return INCLUDE.sub(lambda m: include(root, m.group("path"), m.group("section")), markdown)
