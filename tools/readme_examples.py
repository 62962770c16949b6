"""The fenced examples of the Markdown docs, extracted for mypy and run as written.

Usage: python tools/readme_examples.py README.md build/readme_examples.py
       python tools/readme_examples.py --run README.md
       python tools/readme_examples.py --run-docs [--shell-only] FILE.md...
Each ```python block becomes a function ``example_N()`` so names do not leak between blocks.
``--run`` runs every Python block against the installed ``solid`` (and refuses a ``solid``
imported from a source tree), which is how ``make test`` checks a freshly installed wheel or sdist.

``--run-docs`` runs every ```bash/```sh block (and, without ``--shell-only``, every ```python
block) of each file verbatim, in document order, with ``bash -e`` in a fresh workspace where the
docs' placeholder names are the shared data (:data:`PLACEHOLDERS`; ``SOLID_SHARED`` or
``../shared``): ``hku1-avia`` and ``my_run`` are part of the hku1 walk (its start and its return,
where its loops are: every command stays a few seconds), ``run1``/``run2`` two sessions of it,
``odom.txt`` its poses, ``scan.pcd`` one of its scans, and so on. A block that cannot run here is
preceded by ``<!-- docs-check: skip REASON -->``, a line of a block by ``<!-- docs-check:
skip-line "START" REASON -->`` (every line starting with START); the reason is required and printed.
"""

from __future__ import annotations

import os
import re
import sys
import textwrap
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


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


# ---- the shell blocks ------------------------------------------------------------------------------

#: Frames of hku1-avia the docs' recordings hold: the walk's start and its return to it.
_HKU_FRAMES = [*range(0, 50), *range(250, 314)]
# Two sessions of the walk, the second starting where the first ends: the detector places a session in
# a map only on consistent loops over 15 m of its path (placement_m), longer than the return alone.
_SESSIONS = {"run1": range(0, 157), "run2": range(157, 314)}

#: What each placeholder name of the docs is in the workspace (made by :func:`prepare`).
PLACEHOLDERS = {
    "hku1-avia/": "frames 0-49 and 250-313 of the shared hku1-avia (Scans/, odom_poses.txt, times.txt)",
    "my_run/": "the same recording",
    "odom.txt, gt.txt, odom_poses.txt": "its poses (hku1-avia/odom_poses.txt)",
    "run1/, run2/ (poses.txt)": "frames 0-156 and 157-313 of hku1-avia, each with its poses",
    "scan.pcd": "hku1-avia/Scans/000000.pcd",
    "000000.bin": "kitti00/velodyne/000000.bin",
    "old.soliddb": "a map of run1's first 20 scans saved in format 2",
    "tests/, tools/": "the repository's (commands that the docs run from a checkout)",
}

_FENCE = re.compile(r"^(?P<marks>(?:<!-- docs-check:[^\n]*-->\n)*)```(?P<lang>[\w,]*)[^\n]*\n(?P<body>.*?)^```", re.M | re.S)
_MARK = re.compile(r'<!-- docs-check: (skip-line "(?P<start>[^"]+)"|skip) (?P<reason>[^-][^\n]*?) -->')


@dataclass
class Block:
    """A fenced block of a Markdown file: its language, text, line and skip markers."""

    lang: str
    body: str
    line: int
    skip: str | None = None
    skip_lines: dict[str, str] = field(default_factory=dict)


def blocks_of(markdown: str) -> list[Block]:
    """The ```bash, ```sh and ```python blocks, in order, with their markers."""
    out = []
    for m in _FENCE.finditer(markdown):
        lang = m.group("lang").split(",")[0]
        if lang not in ("bash", "sh", "python"):
            continue
        b = Block(lang, m.group("body"), markdown.count("\n", 0, m.start("body")) + 1)
        for mk in _MARK.finditer(m.group("marks")):
            reason = mk.group("reason").strip()
            if mk.group("start"):
                b.skip_lines[mk.group("start")] = reason
            else:
                b.skip = reason
        if m.group("marks") and not (b.skip or b.skip_lines):
            raise SystemExit(f"line {b.line}: a docs-check marker needs a reason: {m.group('marks').strip()}")
        out.append(b)
    return out


def shared_data() -> Path:
    """The shared data folder (``SOLID_SHARED``/data, else ../shared/data beside the repository)."""
    env = os.environ.get("SOLID_SHARED")
    return (Path(env) if env else Path(__file__).resolve().parent.parent.parent / "shared") / "data"


def prepare(work: Path, data: Path) -> None:
    """The workspace of the docs' commands: their placeholder names made of the shared data."""
    hku = data / "hku1-avia"

    def recording(where: Path, frames: Any, poses_name: str) -> None:
        (where / "Scans").mkdir(parents=True)
        for i in frames:
            (where / "Scans" / f"{i:06d}.pcd").symlink_to(hku / "Scans" / f"{i:06d}.pcd")
        (where / poses_name).symlink_to(hku / "odom_poses.txt")
        (where / "times.txt").symlink_to(hku / "times.txt")

    recording(work / "hku1-avia", _HKU_FRAMES, "odom_poses.txt")
    (work / "my_run").symlink_to("hku1-avia")
    for name in ("odom.txt", "gt.txt", "odom_poses.txt"):
        (work / name).symlink_to(hku / "odom_poses.txt")
    for name, frames in _SESSIONS.items():
        recording(work / name, frames, "poses.txt")
    (work / "scan.pcd").symlink_to(hku / "Scans" / "000000.pcd")
    (work / "000000.bin").symlink_to(data / "kitti00" / "velodyne" / "000000.bin")
    repo = Path(__file__).resolve().parent.parent
    for name in ("tests", "tools"):
        (work / name).symlink_to(repo / name)
    import solid
    from solid.datasets import open_dataset

    ds = open_dataset(work / "run1")
    db = solid.Database(solid.SolidConfig.preset("avia"))
    for i in range(20):
        db.add(solid.describe(ds[i], db.config))
    db.save(work / "old.soliddb", version=2)


def run_docs(paths: list[str], shell_only: bool, timeout_s: float = 600.0) -> int:
    """Runs the blocks of each file in a fresh workspace (:func:`prepare`); returns the number run."""
    import resource
    import shutil
    import subprocess
    import tempfile

    data = shared_data()
    if not (data / "hku1-avia").is_dir():
        if os.environ.get("CI") == "true":
            raise SystemExit(f"the shared data {data} is missing under CI")
        print(f"skipped: the shared data {data} is not here (set SOLID_SHARED)")
        return 0
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}", MPLBACKEND="Agg", PYTHONUNBUFFERED="1")
    ran = 0
    for md in paths:
        blocks = blocks_of(Path(md).read_text(encoding="utf-8"))
        # The workspace is a checkout's stand-in: `../shared` beside it is the shared folder, as the
        # docs that run from a checkout (docs/ros2.md) name it.
        root = Path(tempfile.mkdtemp(prefix="docs-check-"))
        work = root / "repo"
        work.mkdir()
        (root / "shared").symlink_to(data.parent)
        try:
            prepare(work, data)
            namespace: dict[str, object] = {"__name__": "docs_examples_run"}
            for b in blocks:
                where = f"{md}:{b.line}"
                if b.lang == "python" and shell_only:
                    continue
                if b.skip is not None:
                    print(f"--- {where} ({b.lang}) not run: {b.skip}", flush=True)
                    continue
                c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
                t0 = resource.getrusage(resource.RUSAGE_SELF)
                if b.lang == "python":
                    print(f"--- {where} (python)", flush=True)
                    cwd = os.getcwd()
                    os.chdir(work)
                    try:
                        exec(compile(b.body, where, "exec"), namespace)
                    finally:
                        os.chdir(cwd)
                else:
                    body = b.body
                    for start, reason in b.skip_lines.items():
                        hit = [ln for ln in body.splitlines() if ln.strip().startswith(start)]
                        if not hit:
                            raise SystemExit(f"{where}: the skip-line marker {start!r} matches no line")
                        print(f"--- {where}: not run: {start!r}: {reason}", flush=True)
                        body = "\n".join(("# " + ln) if ln.strip().startswith(start) else ln for ln in body.splitlines()) + "\n"
                    print(f"--- {where} (shell)", flush=True)
                    r = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", body], cwd=work, env=env, capture_output=True, text=True, timeout=timeout_s)
                    if r.returncode != 0:
                        tail = [ln for ln in re.split(r"[\r\n]+", r.stdout + r.stderr) if ln.strip()][-15:]
                        print(b.body, *tail, sep="\n", file=sys.stderr)
                        raise SystemExit(f"{where}: this block failed with exit code {r.returncode} (run in {work}; placeholders: tools/readme_examples.py)")
                c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
                t1 = resource.getrusage(resource.RUSAGE_SELF)
                cpu = (c1.ru_utime + c1.ru_stime - c0.ru_utime - c0.ru_stime) + (t1.ru_utime + t1.ru_stime - t0.ru_utime - t0.ru_stime)
                print(f"    ok, {cpu:.1f} s CPU", flush=True)
                ran += 1
        finally:
            shutil.rmtree(root, ignore_errors=True)
    print(f"{ran} blocks of {', '.join(paths)} ran as written")
    return ran


def main(argv: list[str]) -> int:
    if len(argv) == 3 and argv[1] == "--run":
        return 0 if run(argv[2]) else 1
    if len(argv) >= 3 and argv[1] == "--run-docs":
        files = [a for a in argv[2:] if a != "--shell-only"]
        run_docs(files, shell_only="--shell-only" in argv[2:])
        return 0
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
