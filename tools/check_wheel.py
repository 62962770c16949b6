"""Check that a built wheel is what `make dist` promises: abi3 and manylinux2014 (glibc 2.17).

Usage: python tools/check_wheel.py dist/solid_lidar-*.whl [ARCH]
ARCH (uname -m style: x86_64, aarch64) defaults to this machine's.

Two checks, both must pass: the file name's tags (what pip matches against the machine), and
`auditwheel show` (what the extension module really needs: the newest versioned glibc symbol it
links to), so a wheel whose name claims more than its content fails.
"""

from __future__ import annotations

import platform
import re
import subprocess
import sys
from pathlib import Path

from packaging.utils import parse_wheel_filename

GLIBC = (2, 17)  # manylinux2014


def main(argv: list[str]) -> int:
    if len(argv) not in (2, 3):
        print(__doc__, file=sys.stderr)
        return 2
    wheel = Path(argv[1])
    arch = argv[2] if len(argv) == 3 else platform.machine()
    name, _version, _build, tags = parse_wheel_filename(wheel.name)
    problems = []
    if name != "solid-lidar":
        problems.append(f"distribution name {name!r}, expected 'solid-lidar'")
    if {t.abi for t in tags} != {"abi3"} or {t.interpreter for t in tags} != {"cp39"}:
        problems.append(f"tags {sorted(map(str, tags))}: expected cp39-abi3 (one wheel for CPython >= 3.9)")
    platforms = {t.platform for t in tags}
    wanted = f"manylinux_{GLIBC[0]}_{GLIBC[1]}_{arch}"
    if wanted not in platforms:
        problems.append(f"platform tags {sorted(platforms)}: expected {wanted} (manylinux2014)")

    # auditwheel prints 'is consistent with the following platform tag: "manylinux_2_17_x86_64"',
    # wrapped over lines: the tightest tag the binary's symbol versions allow.
    shown = subprocess.run(
        [sys.executable, "-m", "auditwheel", "show", str(wheel)], capture_output=True, text=True, check=False
    )
    text = " ".join(shown.stdout.split())
    m = re.search(r'consistent with the following platform tag: "manylinux_(\d+)_(\d+)_(\w+)"', text)
    if shown.returncode != 0 or m is None:
        problems.append(f"auditwheel show failed or said something unexpected:\n{shown.stdout}{shown.stderr}")
    elif (int(m.group(1)), int(m.group(2))) > GLIBC or m.group(3) != arch:
        problems.append(f"auditwheel: the extension needs glibc {m.group(1)}.{m.group(2)} on {m.group(3)}: {text}")
    if problems:
        print(f"{wheel.name}:", *problems, sep="\n  ", file=sys.stderr)
        return 1
    print(f"{wheel.name}: abi3, {wanted}, auditwheel agrees (glibc <= {GLIBC[0]}.{GLIBC[1]})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
