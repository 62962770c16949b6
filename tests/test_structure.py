"""The shape of python/solid: no import cycles, no private names taken from another module, none
exported by the compiled module.

Read from the source (the AST of every python/solid/**/*.py, imports inside functions included),
so a cycle hidden behind a lazy import counts as one.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "python" / "solid"


def _modules() -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package."""
    out = {}
    for f in sorted(PACKAGE.rglob("*.py")):
        parts = ["solid", *f.relative_to(PACKAGE).with_suffix("").parts]
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = f
    return out


def _is_package(name: str, mods: dict[str, Path]) -> bool:
    return mods[name].name == "__init__.py"


def _known(name: str, mods: dict[str, Path]) -> bool:
    """A module of the package, or the compiled extension (which has no .py)."""
    return name in mods or name == "solid._solid"


def _imports(name: str, mods: dict[str, Path]) -> list[tuple[str, str | None, int]]:
    """(imported module, imported name or None, line) of every import of a solid module."""
    tree = ast.parse(mods[name].read_text(encoding="utf-8"))
    package = name if _is_package(name, mods) else name.rpartition(".")[0]
    out: list[tuple[str, str | None, int]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, None, node.lineno) for a in node.names if a.name.split(".")[0] == "solid"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                src = ".".join(base + ([node.module] if node.module else []))
            else:
                src = node.module or ""
            if src.split(".")[0] != "solid":
                continue
            for a in node.names:
                sub = f"{src}.{a.name}"
                # `from . import x` imports the module x; `from .m import x` the name x of m.
                if _known(sub, mods):
                    out.append((sub, None, node.lineno))
                else:
                    out.append((src, a.name, node.lineno))
    return out


def _private(part: str) -> bool:
    return part.startswith("_") and not (part.startswith("__") and part.endswith("__"))


def test_no_private_names_or_modules_imported_across_modules() -> None:
    mods = _modules()
    bad = []
    for name in mods:
        for src, what, line in _imports(name, mods):
            where = f"{mods[name].relative_to(PACKAGE.parent)}:{line}"
            if what is not None and _private(what):
                bad.append(f"{where}: imports the private name {what} of {src}")
            # A private module (solid.datasets._common) belongs to its package (solid.datasets).
            parts = src.split(".")
            for i, p in enumerate(parts):
                owner = ".".join(parts[:i])
                if _private(p) and not (name == owner or name.startswith(owner + ".")):
                    bad.append(f"{where}: imports {src}, private to {owner}")
    assert not bad, "\n".join(bad)


def test_no_import_cycles() -> None:
    mods = _modules()
    graph = {name: sorted({src for src, _, _ in _imports(name, mods) if src in mods and src != name}) for name in mods}
    cycles = []
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(n: str) -> None:
        state[n] = 1
        path.append(n)
        for m in graph[n]:
            if state.get(m) == 1:
                cycles.append(" -> ".join(path[path.index(m) :] + [m]))
            elif m not in state:
                visit(m)
        path.pop()
        state[n] = 2

    for n in graph:
        if n not in state:
            visit(n)
    assert not cycles, "import cycles in python/solid:\n" + "\n".join(cycles)


def test_every_module_says_what_it_holds() -> None:
    mods = _modules()
    missing = [str(f.relative_to(PACKAGE.parent)) for f in mods.values() if ast.get_docstring(ast.parse(f.read_text(encoding="utf-8"))) is None]
    assert not missing, f"modules without a docstring: {missing}"


def test_the_compiled_module_exports_no_private_name() -> None:
    # Its `__all__` (and the stub's, which stubtest compares) leaves out `_register_verifying`,
    # `_sim_world`...: they stay importable by name, outside the API.
    from solid import _solid

    assert not [n for n in _solid.__all__ if _private(n)]
    assert "register" in _solid.__all__ and "__version__" in _solid.__all__
    assert callable(_solid._register_verifying)
