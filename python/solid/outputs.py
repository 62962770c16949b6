"""Output folders that appear whole or not at all, and the files written into them.

Every command that writes results gets a fresh folder. Without ``-o``, it is
``solid_results/<date>_<time>_<command>_<name>/`` with a ``solid_results/latest`` link to it (as
kiss-icp does); with ``-o DIR``, ``DIR`` must not exist or be empty (an existing result is never
mixed with a new one). The files are written into a hidden sibling folder that is renamed to the
final name only when everything is written: an interrupted or failed run (Ctrl-C, a full disk, an
error) leaves no folder that looks complete, and removes its partial one. A single file is written
the same way (:func:`atomic_write_bytes`): to a temporary name, renamed over the target when whole.
Only a regular file is ever replaced so: a FIFO or a device at an output path is refused (or, for
an output meant as a stream, ``solid describe -o``, written through), never renamed over.
"""

from __future__ import annotations

import csv
import io as _io
import json
import math
import os
import secrets
import shutil
import stat
import time
from collections.abc import Iterable, Iterator, Sequence as AbcSequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .errors import OutputExistsError

__all__ = ["Output", "OutputExistsError", "atomic_write_bytes", "output_folder", "write_csv", "write_json"]

DEFAULT_ROOT = Path("solid_results")


def _json_default(o: Any) -> Any:
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        v = float(o)
        return None if math.isnan(v) else v
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o)}")


def _clean(o: Any) -> Any:
    """NaN and infinities → None (JSON has neither)."""
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    return o


def write_json(path: Path, doc: Any) -> Path:
    """``doc`` as indented JSON (NaN → null)."""
    path.write_text(json.dumps(_clean(doc), indent=2, default=_json_default) + "\n", encoding="utf-8")
    return path


def _kind(mode: int) -> str:
    """A name for a file type that is not a regular file."""
    for test, name in (
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return name
    return "not a regular file"


def _special(path: Path) -> int | None:
    """The mode of what is at ``path`` (through symbolic links) when it is not a regular file."""
    try:
        mode = os.stat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        return None
    return None if stat.S_ISREG(mode) else mode


def _refuse(path: Path, mode: int) -> OutputExistsError:
    return OutputExistsError(f"{path} exists and is {_kind(mode)}, not a regular file: refusing to replace it")


def atomic_write_bytes(path: Path, data: bytes, *, stream: bool = False) -> None:
    """Write ``data`` to a temporary file beside ``path``, then rename it over ``path``. Every call
    creates its own temporary file (exclusively), so that calls from several threads or
    processes writing one path never share one: the last rename wins, whole. The file gets the
    mode any new file gets (``0o666`` less the umask).

    Only a regular file is ever replaced: a FIFO, a device, a socket or a directory at ``path``
    (also through a symbolic link) raises :class:`OutputExistsError`, except that with ``stream``
    (an output that may be a stream, as ``solid describe -o /dev/stdout``) a FIFO or a character
    device is written through: opened and written like a shell redirection, never replaced."""
    path = Path(path)
    mode = _special(path)
    if mode is not None:
        if stream and (stat.S_ISFIFO(mode) or stat.S_ISCHR(mode)):
            with open(path, "wb") as f:
                f.write(data)
            return
        raise _refuse(path, mode)
    while True:
        tmp = path.parent / f".{path.name}.{os.getpid()}-{secrets.token_hex(6)}.tmp"
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o666)
        except FileExistsError:
            continue
        break
    try:
        with open(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        mode = _special(path)  # again: something may have appeared meanwhile
        if mode is not None:
            raise _refuse(path, mode)
        os.replace(tmp, path)
    except BaseException:
        try:
            tmp.unlink()
        except FileNotFoundError:
            pass
        raise


def write_csv(path: Path, columns: AbcSequence[str], rows: Iterable[dict[str, Any]]) -> Path:
    """Rows (dicts keyed by ``columns``) as CSV with a header line."""
    buf = _io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), lineterminator="\n", extrasaction="ignore")
    w.writeheader()
    w.writerows(rows)
    path.write_text(buf.getvalue(), encoding="utf-8")
    return path


def _slug(name: str) -> str:
    keep = "".join(c if c.isalnum() or c in "-_." else "_" for c in name)
    return keep.strip("._") or "run"


def _fresh_default(root: Path, command: str, name: str) -> Path:
    stamp = time.strftime("%Y-%m-%d_%H-%M-%S")
    base = root / f"{stamp}_{command}_{_slug(name)}"
    out, n = base, 2
    while out.exists() or out.is_symlink():
        out = base.with_name(f"{base.name}-{n}")
        n += 1
    return out


def _check_empty(out: Path) -> None:
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise OutputExistsError(f"{out} exists and is not a folder: choose another output folder")
    if out.is_dir() and any(out.iterdir()):
        raise OutputExistsError(
            f"{out} is not empty: results are never mixed with an earlier run's; choose another folder or remove it"
        )


def _remove_empty(folders: list[Path]) -> None:
    """Remove the folders this run created (innermost first) while they are empty."""
    for d in folders:
        try:
            d.rmdir()
        except OSError:
            return


@dataclass(frozen=True)
class Output:
    """Where to write (``work``, hidden until done) and where it will appear (``final``)."""

    work: Path
    final: Path


@contextmanager
def output_folder(output: Path | None, command: str, name: str, root: Path = DEFAULT_ROOT) -> Iterator[Output]:
    """Yields an :class:`Output`: write into ``.work``; on success it is renamed to ``.final``.

    ``final`` is ``output`` (which must not exist or be empty) or a fresh timestamped folder under
    ``root`` (then ``root/latest`` is pointed at it). On any exception, including
    ``KeyboardInterrupt``, the work folder is removed and nothing is left behind.
    """
    final = Path(output) if output is not None else _fresh_default(root, command, name)
    _check_empty(final)
    made = [p for p in [final.parent, *final.parent.parents] if not p.exists()]
    final.parent.mkdir(parents=True, exist_ok=True)
    try:
        work = final.parent / f".{final.name}.partial-{os.getpid()}-{time.monotonic_ns()}"
        work.mkdir()
    except BaseException:
        _remove_empty(made)
        raise
    try:
        yield Output(work, final)
        _check_empty(final)  # nothing appeared there meanwhile
        if final.is_dir():
            final.rmdir()  # empty: replaced atomically by the rename below
        os.replace(work, final)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        _remove_empty(made)  # a failed run leaves no empty solid_results/ either
        raise
    if output is None:
        link = root / "latest"
        tmp = root / f".latest-{os.getpid()}"
        try:
            if tmp.is_symlink() or tmp.exists():
                tmp.unlink()
            tmp.symlink_to(final.name)
            os.replace(tmp, link)
        except OSError:
            pass  # a file system without symbolic links: the folder itself is what matters

