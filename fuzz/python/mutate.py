"""A fixed, seeded mutation run over every reader area; prints area | cases tried | handled
cleanly | wrong, and the first few wrong cases of each area.

    python fuzz/python/mutate.py [--cases N] [--seed S] [--areas pcd,ply,...]

The same cases (same seed) against two versions of the package give a before/after table. Each
case has a 10 s limit (a longer one counts as wrong: a hang) and the address space is capped at
4 GiB (an allocation beyond it counts as wrong: a MemoryError leak).
"""

from __future__ import annotations

import argparse
import random
import re
import resource
import signal
import sys
from collections import Counter

import targets

INTERESTING = [b"-1", b"0", b"1", b"4294967295", b"4294967296", b"2147483647", b"99999999999", b"-99999", b"nan", b"1e308"]
NUMBER = re.compile(rb"-?\d+")


def mutate(rng: random.Random, seed: bytes) -> bytes:
    data = bytearray(seed)
    for _ in range(rng.randint(1, 4)):
        op = rng.randrange(7)
        if not data:
            data += bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
            continue
        k = rng.randrange(len(data))
        if op == 0:
            data[k] ^= 1 << rng.randrange(8)
        elif op == 1:
            data[k] = rng.randrange(256)
        elif op == 2:
            del data[k : k + rng.randint(1, 64)]
        elif op == 3:
            data[k:k] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
        elif op == 4:
            data = data[: rng.randrange(len(data) + 1)]
        elif op == 5:
            nums = list(NUMBER.finditer(bytes(data[:4096])))
            if nums:
                m = rng.choice(nums)
                data[m.start() : m.end()] = rng.choice(INTERESTING)
        else:
            w = rng.choice((1, 2, 4, 8))
            data[k : k + w] = rng.choice((b"\xff", b"\x00", b"\x7f", b"\x80")) * w
    return bytes(data)


class Hang(Exception):
    pass


def _alarm(signum: int, frame: object) -> None:
    raise Hang()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=300, help="cases per area (default 300)")
    ap.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    ap.add_argument("--areas", default=",".join(targets.AREAS), help="comma-separated areas (default all)")
    args = ap.parse_args()
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))
    signal.signal(signal.SIGALRM, _alarm)
    print("| area | cases tried | handled cleanly | wrong |")
    print("|---|---:|---:|---:|")
    examples: dict[str, list[str]] = {}
    for name in args.areas.split(","):
        area = targets.AREAS[name]
        rng = random.Random(f"{args.seed}-{name}")
        seeds = area.seeds()
        counts: Counter[str] = Counter()
        for _ in range(args.cases):
            case = mutate(rng, rng.choice(seeds))
            signal.alarm(10)
            try:
                area.target(case)
                counts["clean"] += 1
            except Hang:
                counts["wrong"] += 1
                examples.setdefault(name, []).append("hang (> 10 s)")
            except targets.Wrong as e:
                counts["wrong"] += 1
                examples.setdefault(name, []).append(str(e))
            finally:
                signal.alarm(0)
        print(f"| {name} | {args.cases} | {counts['clean']} | {counts['wrong']} |")
    for name, ex in examples.items():
        kinds = Counter(e.split(":")[0] for e in ex)
        print(f"{name}: " + ", ".join(f"{k} ×{v}" for k, v in kinds.most_common(6)) + f"; e.g. {ex[0][:160]}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
