"""The documentation's sources are complete: every public callable of the stub is documented.

The API reference of the documentation site is generated from python/solid/_solid.pyi (mkdocs,
built with --strict by `make docs`, which also rejects a documented argument that is not in the
signature). This test checks the other direction: every public function, method and property has
a docstring, every argument is described under "Args:", and whatever returns a value says what
under "Returns:".
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
STUB = REPO / "python" / "solid" / "_solid.pyi"


def public_defs() -> Iterator[tuple[str, ast.FunctionDef]]:
    """(qualified name, node) of every public function, method, property and constructor."""
    tree = ast.parse(STUB.read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
            yield node.name, node
        elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
            for item in node.body:
                if isinstance(item, ast.FunctionDef) and (item.name == "__new__" or not item.name.startswith("_")):
                    yield f"{node.name}.{item.name}", item


def section(doc: str, name: str) -> str:
    """The body of a Google-style section (indented lines after `name:`), or ""."""
    m = re.search(rf"^([ \t]*){name}:\n((?:\1[ \t]+.*\n?|[ \t]*\n)*)", doc, flags=re.M)
    return m.group(2) if m else ""


def test_every_public_callable_of_the_stub_is_documented() -> None:
    problems = []
    defs = list(public_defs())
    assert len(defs) > 40, "the stub parser found too little"
    for name, node in defs:
        doc = ast.get_docstring(node)
        if not doc:
            problems.append(f"{name}: no docstring")
            continue
        if any(isinstance(d, ast.Name) and d.id == "property" for d in node.decorator_list):
            continue  # a property's docstring is its description
        args = [a.arg for a in node.args.posonlyargs + node.args.args + node.args.kwonlyargs]
        args = [a for a in args if a not in ("self", "cls")]
        if node.args.vararg:
            args.append("*" + node.args.vararg.arg)
        if node.args.kwarg:
            args.append("**" + node.args.kwarg.arg)
        documented = section(doc + "\n", "Args")
        for arg in args:
            if not re.search(rf"^\s*{re.escape(arg)}:", documented, flags=re.M):
                problems.append(f"{name}: argument {arg} is not described under Args:")
        returns_none = isinstance(node.returns, ast.Constant) and node.returns.value is None
        if node.name != "__new__" and not returns_none and not section(doc + "\n", "Returns"):
            problems.append(f"{name}: no Returns: section")
    assert not problems, "\n".join(problems)


def test_the_check_sees_a_missing_argument() -> None:
    doc = "Does it.\n\nArgs:\n    a: The first.\n"
    assert re.search(r"^\s*a:", section(doc, "Args"), flags=re.M)
    assert not re.search(r"^\s*b:", section(doc, "Args"), flags=re.M)
