"""Coverage-guided fuzzing of one reader area with atheris (libFuzzer for Python).

    python fuzz/python/fuzz.py AREA [libFuzzer options...]     # e.g. pcd -max_total_time=60

AREA is one of targets.AREAS (pcd, ply, npy, npz, bin, poses, rosbag1, mcap). The corpus starts
from seeds made at run time from the shared data (written to build/fuzz/corpus/AREA, never into
the repository); a case that breaks the readers' contract (targets.Wrong) stops the run with the
input saved by libFuzzer as crash-*. `make fuzz` runs every area for FUZZ_SECONDS each.
"""

from __future__ import annotations

import sys
from pathlib import Path

import atheris

with atheris.instrument_imports(include=["solid"]):
    import targets


def main() -> None:
    if len(sys.argv) < 2 or sys.argv[1] not in targets.AREAS:
        sys.exit(f"usage: fuzz.py AREA [libFuzzer options]; AREA in {', '.join(targets.AREAS)}")
    area = targets.AREAS[sys.argv[1]]
    corpus = targets.REPO / "build" / "fuzz" / "corpus" / area.name
    corpus.mkdir(parents=True, exist_ok=True)
    for i, seed in enumerate(area.seeds()):
        (corpus / f"seed-{i}").write_bytes(seed)
    artifacts = targets.REPO / "build" / "fuzz" / "artifacts" / area.name
    artifacts.mkdir(parents=True, exist_ok=True)

    def one_input(data: bytes) -> None:
        area.target(data)

    args = [sys.argv[0], *sys.argv[2:], f"-artifact_prefix={artifacts}/", str(corpus)]
    atheris.Setup(args, one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
