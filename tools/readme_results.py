"""Regenerate the README's results on the real Livox Avia walk from `solid eval` outputs.

Usage:
    python tools/readme_results.py            # run the evaluations, rewrite README.md and the PR plot
    python tools/readme_results.py --check    # exit 1 if README.md differs from a fresh run

It runs what `solid eval ../shared/data/hku1-avia --poses odom_poses.txt --preset avia --radius R
--baseline scancontext` runs (the shipped pipeline and the faithful Scan Context on the same
queries) at R = 3 m and 5 m, writes the table and the sentence on where each method wins between
the markers `<!-- results:hku1:start -->` and `<!-- results:hku1:end -->`, and copies the 3 m
precision-recall plot to docs/pr_hku1_avia.png. Nothing in that block is typed by hand.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
START, END = "<!-- results:hku1:start -->", "<!-- results:hku1:end -->"
COMMAND = "solid eval ../shared/data/hku1-avia --poses odom_poses.txt --preset avia --radius {r} --baseline scancontext"


def shared() -> Path:
    env = os.environ.get("SOLID_SHARED")
    return Path(env) if env else REPO.parent / "shared"


def run(radius: float, out: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """(SOLiD metrics, Scan Context metrics) of one `solid eval` run at `radius`."""
    from solid.cli import main

    seq = shared() / "data" / "hku1-avia"
    argv = ["eval", str(seq), "--poses", "odom_poses.txt", "--preset", "avia", "--radius", f"{radius:g}", "--baseline", "scancontext", "-o", str(out), "-q"]
    import contextlib
    import io

    with contextlib.redirect_stdout(io.StringIO()):
        code = main(argv)
    if code != 0:
        raise SystemExit(f"solid eval failed ({code})")
    import json

    m = json.loads((out / "metrics.json").read_text())
    return m, m["baselines"]["scancontext"]


def fmt(v: Any, digits: int = 3) -> str:
    return "n/a" if v is None else f"{v:.{digits}f}"


def block(results: dict[float, tuple[dict[str, Any], dict[str, Any]]]) -> str:
    rows = [
        "| radius | method | GT queries | Recall@1 | Recall@5 | F1 max | AUC | heading error (mean) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r, (s, c) in results.items():
        for name, m in (("SOLiD", s), ("Scan Context", c)):
            rows.append(
                f"| {r:g} m | {name} | {m['gt_queries']} | {fmt(m['recall_at_1'])} | {fmt(m['recall_at_5'])} | "
                f"{fmt(m['f1_max'])} | {fmt(m['auc'])} | {fmt(m['rotation_error_deg_mean'], 1)}° |"
            )
    lines = ["\n".join(rows), ""]
    s3, c3 = results[3.0]
    s5, c5 = results[5.0]

    def who(key: str, s: dict[str, Any], c: dict[str, Any]) -> str:
        return "SOLiD" if s[key] > c[key] else "Scan Context" if c[key] > s[key] else "neither"

    def both(key: str, s: dict[str, Any], c: dict[str, Any], digits: int = 3) -> str:
        return f"SOLiD {fmt(s[key], digits)}, Scan Context {fmt(c[key], digits)}"

    lines.append(
        f"Within 3 m, {who('recall_at_1', s3, c3)} has the higher Recall@1 ({both('recall_at_1', s3, c3)}) and "
        f"{who('f1_max', s3, c3)} the higher F1 max ({both('f1_max', s3, c3)}); within 5 m, "
        f"{who('recall_at_1', s5, c5)} has the higher Recall@1 ({both('recall_at_1', s5, c5)}) and "
        f"{who('f1_max', s5, c5)} the higher F1 max ({both('f1_max', s5, c5)}). The heading of a correct match is "
        f"closer to the truth with {'Scan Context' if c3['rotation_error_deg_mean'] < s3['rotation_error_deg_mean'] else 'SOLiD'} "
        f"(mean error at 3 m: {both('rotation_error_deg_mean', s3, c3, 1)} degrees): with a 70° field of view "
        f"the A-SOLiD shift barely resolves the small turns of this walk."
    )
    lines.append("")
    lines.append("Both methods answer the same queries (263, exclusion 50 keyframes ≈ 10 m here) and are scored by")
    lines.append("the same code ([spec §5](docs/spec.md#5-evaluating-loop-closure-against-poses), in the Rust core). Regenerate this block with `python tools/readme_results.py`;")
    lines.append("each row is what " + "`" + COMMAND.format(r="R") + "` prints.")
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="only compare with README.md (exit 1 when it differs)")
    args = ap.parse_args()
    readme = REPO / "README.md"
    text = readme.read_text(encoding="utf-8")
    if START not in text or END not in text:
        raise SystemExit(f"README.md has no {START} … {END} block")
    with tempfile.TemporaryDirectory() as tmp:
        results = {r: run(r, Path(tmp) / f"r{r:g}") for r in (3.0, 5.0)}
        new = block(results)
        head, rest = text.split(START, 1)
        _, tail = rest.split(END, 1)
        updated = f"{head}{START}\n{new}\n{END}{tail}"
        if args.check:
            if updated != text:
                print("README.md results differ from a fresh run; run python tools/readme_results.py", file=sys.stderr)
                return 1
            return 0
        readme.write_text(updated, encoding="utf-8")
        shutil.copyfile(Path(tmp) / "r3" / "pr.png", REPO / "docs" / "pr_hku1_avia.png")
    print("README.md and docs/pr_hku1_avia.png updated")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
