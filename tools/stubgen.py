"""Writes ``python/solid/_solid.pyi`` from its hand-written parts in ``stubs/*.pyi`` (one per binding
module, in name order) and the core's parameter tables, and the parameter tables of
``docs/spec.md``.

``make stubs`` runs it; ``make test`` runs it with ``--check``, which fails when either is stale.
The tables (``solid._solid._param_table``) give each field's name, type, default, valid range and
doc line; this script turns them into each class's constructor, ``preset``, ``replace``,
``to_dict`` and properties, between the markers::

    # generated from the core's parameter table by tools/stubgen.py (make stubs): do not edit
    ...
    # end of generated

Everything outside the markers (class docstrings, other methods, the rest of the module) is
written by hand, in ``stubs/``, where the markers stand with nothing between them. In Markdown the markers are ``<!-- generated: CLASS ... -->`` and
``<!-- end of generated -->`` around a table of the class's parameters.

An argument or an error that means the same in several methods is described once: in a docstring
of ``stubs/``, the line ``<Args of CLASS.METHOD>`` stands for the entries of that method's
``Args:`` section naming arguments this method takes and has not described above the line, and
``<Raises of CLASS.METHOD>`` for all of its ``Raises:`` section.
"""

from __future__ import annotations

import argparse
import ast
import math
import re
import sys
from pathlib import Path
from collections.abc import Callable
from typing import Any

from solid.config import default_text, param_table, per_preset_fields

ROOT = Path(__file__).resolve().parent.parent
STUB = ROOT / "python" / "solid" / "_solid.pyi"
PARTS = ROOT / "stubs"
NOTE = "# Written by `make stubs` (tools/stubgen.py) from stubs/*.pyi and the core's parameter tables: edit those."
DOCS = [ROOT / "docs" / "spec.md"]
DOC_BEGIN = re.compile(r"^<!-- generated: (\w+) from the core's parameter table by tools/stubgen.py \(make stubs\) -->$")
DOC_END = "<!-- end of generated -->"
BEGIN = "    # generated from the core's parameter table by tools/stubgen.py (make stubs): do not edit"
END = "    # end of generated"

# The classes with a table: whether they have `preset(name, ...)`, and their parameter sets of
# their own (given as an object or a dict of overrides).
CLASSES: dict[str, dict[str, Any]] = {
    "SolidConfig": {"preset": "a sensor preset (docs/spec.md §4)", "nested": {}},
    "DetectorConfig": {
        "preset": "the detector defaults of a sensor preset (its measured loop threshold)",
        "nested": {
            "registration": ("RegistrationConfig", "The registration parameters (an object, or a dict of overrides of the current ones)."),
            "gate": ("AcceptanceGate", "The acceptance gate (an object, or a dict of overrides of the current one)."),
        },
    },
    "RegistrationConfig": {"preset": None, "nested": {}},
    "AcceptanceGate": {"preset": None, "nested": {}},
}


def _literal(v: Any) -> str:
    """A default as a stub literal (`...` where Python has none, such as infinity)."""
    if isinstance(v, float) and not math.isfinite(v):
        return "..."
    return repr(v)


def _described(f: dict[str, Any]) -> str:
    """The field's doc line with its valid values and default."""
    default = "required" if f["required"] else f"default {f['default']!r}"
    alias = f"; formerly {', '.join(f['aliases'])}" if f["aliases"] else ""
    return f"{f['doc'].rstrip('.')} ({f['expected']}; {default}{alias})."


def _args_doc(fields: list[dict[str, Any]], nested: dict[str, tuple[str, str]], indent: str) -> list[str]:
    out = [f"{indent}Args:"]
    for f in fields:
        out.append(f"{indent}    {f['name']}: {_described(f)}")
    for name, (_, doc) in nested.items():
        out.append(f"{indent}    {name}: {doc}")
    return out


def _signature(fields: list[dict[str, Any]], nested: dict[str, tuple[str, str]], *, defaults: bool) -> list[str]:
    """Keyword parameters: with the table's defaults, or `None` (not given) for overrides."""
    out = []
    for f in fields:
        if defaults and f["required"]:
            out.append(f"        {f['name']}: {f['type']},")
        elif defaults:
            out.append(f"        {f['name']}: {f['type']} = {_literal(f['default'])},")
        else:
            out.append(f"        {f['name']}: {f['type']} | None = None,")
    for name, (cls, _) in nested.items():
        out.append(f"        {name}: {cls} | dict[str, Any] | None = None,")
    return out


def generate(cls: str) -> list[str]:
    """The generated members of class `cls`."""
    spec = CLASSES[cls]
    fields: list[dict[str, Any]] = param_table(cls)
    nested: dict[str, tuple[str, str]] = spec["nested"]
    raises = [
        "        Raises:",
        "            ConfigError: A value out of its range (named in the message).",
        "            TypeError: An unknown parameter, or a value of the wrong type.",
    ]
    lines = [BEGIN, "    def __new__(", "        cls,", "        *,"]
    lines += _signature(fields, nested, defaults=True)
    lines += [f"    ) -> {cls}:", f'        """`{cls}(...)`: parameters by keyword (None: the default).', ""]
    lines += _args_doc(fields, nested, "        ") + [""] + raises + ['        """']
    if spec["preset"]:
        lines += ["    @staticmethod", "    def preset(", "        name: str,", "        *,"]
        lines += _signature(fields, nested, defaults=False)
        lines += [f"    ) -> {cls}:", f'        """{spec["preset"][0].upper()}{spec["preset"][1:]}, with overrides (None: the preset\'s).', ""]
        lines += ['        Args:', '            name: A preset name (`solid.presets()`): "hdl64", "hdl32", "vlp16", "os1-64", "avia", "aeva".']
        lines += _args_doc(fields, nested, "        ")[1:] + ["", "        Returns:", "            The validated parameters.", ""]
        lines += ["        Raises:", "            ConfigError: An unknown preset name (the message lists them) or an invalid value.", "            TypeError: An unknown parameter, or a value of the wrong type.", '        """']
    lines += ["    def replace(", "        self,", "        *,"]
    lines += _signature(fields, nested, defaults=False)
    lines += [f"    ) -> {cls}:", '        """A copy with some parameters changed (None: unchanged); this one is immutable.', ""]
    lines += _args_doc(fields, nested, "        ") + ["", "        Returns:", "            The validated new parameters.", ""] + raises + ['        """']
    keys = ", ".join(f["name"] for f in fields) + "".join(f", {n}" for n in nested)
    lines += [
        "    def to_dict(self) -> dict[str, Any]:",
        f'        """The parameters by name ({keys}): what `{cls}(**d)` takes back.',
        "",
        "        Returns:",
        "            A new dict.",
        '        """',
    ]
    for f in fields:
        lines += ["    @property", f"    def {f['name']}(self) -> {f['type']}:", f'        """{_described(f)}"""']
    lines.append(END)
    return lines


def render(text: str) -> str:
    """`text` (the stub) with every generated region written anew."""
    lines = text.split("\n")
    out: list[str] = []
    cls = None
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("class "):
            cls = line[len("class ") :].split("(")[0].split(":")[0]
        if line == BEGIN:
            if cls not in CLASSES:
                raise SystemExit(f"stubgen: a generated region in class {cls!r}, which has no parameter table")
            end = lines.index(END, i)
            out += generate(cls)
            i = end + 1
            continue
        out.append(line)
        i += 1
    missing = [c for c in CLASSES if f"class {c}:" not in text or _region_count(text, c) != 1]
    if missing:
        raise SystemExit(f"stubgen: no generated region (or more than one) in class {', '.join(missing)}")
    return "\n".join(out)


def _doc_default(f: dict[str, Any], per_preset: set[str]) -> str:
    """`default_text` (as the flags' help says it), with where the sensor's and the presets' are."""
    if f["required"]:
        return "none (the sensor's)"
    if f["name"] == "threshold" and f["name"] in per_preset:
        return "the preset's loop threshold (§4)"
    text = default_text(f, per_preset)
    return f"{text} (§4)" if f["name"] in per_preset else text


def _num(x: float) -> str:
    return str(int(x)) if x == int(x) else repr(x)


def _valid(f: dict[str, Any]) -> str:
    """The field's valid values, from its kind and its rule (the grammar of docs/spec.md)."""
    big = sys.float_info.max
    if f["type"] == "int":
        lo, hi = f["min"], f["max"]
        text = f"an integer ≥ {lo}" if hi >= 2**32 - 1 else f"an integer in {lo}..={hi}"
    elif f["type"] == "float":
        lo, hi, lo_open = f["min"], f["max"], f["min_open"]
        low = f"{'>' if lo_open else '≥'} {_num(lo)}"
        if lo == -big and hi == big:
            text = "finite"
        elif hi == big:
            text = f"finite, {low}"
        elif math.isinf(hi):
            text = f"{low} (∞: no limit)" if lo > -math.inf else "any number but NaN"
        else:
            text = f"in {'(' if lo_open else '['}{_num(lo)}, {_num(hi)}]"
    elif f["type"] == "str":
        text = " or ".join(f'"{c}"' for c in f["choices"])
    else:
        text = ""
    return ", ".join(t for t in (text, f["rule"]) if t)


def doc_table(cls: str) -> list[str]:
    """The Markdown table of class `cls`'s parameters: name, default, meaning, valid values."""
    per_preset = per_preset_fields() if cls == "DetectorConfig" else set()
    rows = ["| name | default | meaning | valid |", "|---|---|---|---|"]
    for f in param_table(cls):
        rows.append(f"| `{f['name']}` | {_doc_default(f, per_preset)} | {f['doc'].rstrip('.')} | {_valid(f)} |")
    for name, (set_cls, doc) in CLASSES[cls]["nested"].items():
        rows.append(f"| `{name}` | §11 | {doc.rstrip('.')} ({set_cls}) | §11 |")
    return rows


def render_doc(text: str) -> str:
    """Markdown `text` with every generated table written anew."""
    lines = text.split("\n")
    out: list[str] = []
    i = 0
    while i < len(lines):
        m = DOC_BEGIN.match(lines[i])
        if m is None:
            out.append(lines[i])
            i += 1
            continue
        if m.group(1) not in CLASSES:
            raise SystemExit(f"stubgen: no parameter table {m.group(1)!r}")
        end = lines.index(DOC_END, i)
        out += [lines[i], *doc_table(m.group(1)), DOC_END]
        i = end + 1
    return "\n".join(out)


def assemble() -> str:
    """The stub: the parts of `stubs/` joined, the note after the module docstring, the regions filled."""
    parts = [p.read_text(encoding="utf-8").strip("\n") for p in sorted(PARTS.glob("*.pyi"))]
    text = expand_shared("\n\n\n".join(parts) + "\n")
    end = text.index('"""', 3) + 3  # the module docstring of the first part
    check_exports(text)
    return render(text[:end] + "\n" + NOTE + text[end:])


def check_exports(text: str) -> None:
    """Fails when the stub's `__all__` lists a private name (`_name`; dunders such as
    `__version__` are public): the module leaves those out of its `__all__` (crates/solid-py's
    `drop_private_names`), and stubtest compares the two."""
    for node in ast.parse(text).body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            names = ast.literal_eval(node.value)
            private = [n for n in names if n.startswith("_") and not (n.startswith("__") and n.endswith("__"))]
            if private:
                raise SystemExit(f"stubgen: __all__ lists private names: {', '.join(private)}")


SHARED = re.compile(r"^(\s*)<(Args|Raises) of (\w+)\.(\w+)>$")
ENTRY = re.compile(r"^(\s*)(\*{0,2}\w+): ")


def _entries(lines: list[str], doc: range, section: str) -> list[tuple[str, list[str]]]:
    """(name, lines) of each entry of a docstring's `section` (`doc`: the docstring's line indices)."""
    head = next((i for i in doc if lines[i].strip() == f"{section}:"), None)
    if head is None:
        return []
    depth = len(lines[head]) - len(lines[head].lstrip()) + 4
    out: list[tuple[str, list[str]]] = []
    for i in range(head + 1, doc.stop):
        line = lines[i]
        indent = len(line) - len(line.lstrip())
        if not line.strip() or indent < depth:
            break
        if SHARED.match(line):
            continue
        m = ENTRY.match(line)
        if indent == depth and m:
            out.append((m.group(2), [line]))
        elif out:
            out[-1][1].append(line)
    return out


def expand_shared(text: str) -> str:
    """`text` with each `<Args of C.M>` / `<Raises of C.M>` line replaced by those entries of C.M."""
    lines = text.split("\n")
    methods: dict[str, ast.FunctionDef] = {}
    for node in ast.parse(text).body:
        if isinstance(node, ast.ClassDef):
            for item in node.body:
                if isinstance(item, ast.FunctionDef):
                    methods[f"{node.name}.{item.name}"] = item

    def doc_range(fn: ast.FunctionDef) -> range:
        first = fn.body[0]
        return range(first.lineno - 1, first.end_lineno or first.lineno)

    out: list[str] = []
    for i, line in enumerate(lines):
        m = SHARED.match(line)
        if m is None:
            out.append(line)
            continue
        indent, section, source = m.group(1), m.group(2), f"{m.group(3)}.{m.group(4)}"
        if source not in methods:
            raise SystemExit(f"stubgen: line {i + 1}: no method {source}")
        src = doc_range(methods[source])
        if any(SHARED.match(lines[k]) for k in src):
            raise SystemExit(f"stubgen: line {i + 1}: {source} refers to another method itself: name the first one")
        entries = _entries(lines, src, section)
        if section == "Args":
            here = next(fn for fn in methods.values() if i in doc_range(fn))
            a = here.args
            takes = {x.arg for x in a.posonlyargs + a.args + a.kwonlyargs}
            done = {name for name, _ in _entries(lines, range(doc_range(here).start, i), section)}
            entries = [(name, e) for name, e in entries if name in takes and name not in done]
        if not entries:
            raise SystemExit(f"stubgen: line {i + 1}: nothing to take from {section} of {source}")
        depth = len(entries[0][1][0]) - len(entries[0][1][0].lstrip())
        out += [indent + e[depth:] for _, block in entries for e in block]
    return "\n".join(out)


def _region_count(text: str, cls: str) -> int:
    body = text.split(f"class {cls}:", 1)[1].split("\nclass ", 1)[0]
    return body.count(BEGIN)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--check", action="store_true", help="fail when the stub is not what this would write")
    args = p.parse_args(argv)
    stale = []
    outputs: list[tuple[Path, Callable[[str], str]]] = [(STUB, lambda _old: assemble()), *((d, render_doc) for d in DOCS)]
    for path, write in outputs:
        old = path.read_text(encoding="utf-8") if path.exists() else ""
        new = write(old)
        if new == old:
            continue
        if args.check:
            stale.append(str(path.relative_to(ROOT)))
        else:
            path.write_text(new, encoding="utf-8")
            print(f"wrote {path.relative_to(ROOT)}")
    if stale:
        print(f"stale: {', '.join(stale)}: run `make stubs`", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
