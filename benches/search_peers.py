"""Times solid's search against faiss-cpu (IndexFlatIP) and numpy, in one process.

    make bench-search-py        # installs benches/requirements-bench.txt (faiss-cpu) first
    python benches/search_peers.py --json benches/results/search.json   # also writes the figures

The JSON file is what tools/readme_speed.py turns into the README's search table.

On realistic R-SOLiD databases of 10k, 100k and 1M entries (SOLID_BENCH_QUICK=1 stops at 100k):
`hku` holds the 314 HKU Livox Avia keyframes under a random yaw, a shift of up to 2 m, dropout
of up to half the points and (half the time) a horizontal FOV clip to 40-70 degrees; its queries
are other such copies (`near`) and scans of other cities cut to the Avia's FOV (`novel`). `dup`
holds copies of one scan keeping 50-100 % of its points (near-duplicates); its queries are other
such copies (`same`) and the `near` queries (`other`). Descriptors are cached under
target/solid-bench-data/ (the 1M sets take a few minutes the first time).

Prints, with every figure measured in the same run and the ratio peer / solid:
- single search: mean µs per query over 144 queries, each method run once on each query, the
  methods interleaved query by query, on a fresh database each time (what `auto` learns starts
  from nothing), three times; the median of the three means of each method, and the range of
  `auto` ÷ brute force over the three (one run on this shared 2-core machine moved that ratio by
  up to 0.15 from one run to the next); solid `auto` and `brute`, faiss `IndexFlatIP.search` of one
  query (on 1 thread or on every core, whichever was faster on the first 16 queries of that
  database: one query at 10k entries takes faiss 0.05 ms on 1 thread, 0.25-0.34 ms on 2), numpy
  `argmax(X @ q)`;
- batch search: 1,000 queries (half of each mix) in one call: `Database.search_batch` and faiss
  (best of 7 / 5 / 2 runs at 10k / 100k / 1M), numpy in blocks of 16 queries, and a loop over
  `Database.search`;
- bulk add of the N entries from arrays: `Database.add_batch` (the default, which leaves the
  index to the searches, and `index=True`, which builds it),
  faiss `normalize_L2` + `add`, numpy row normalisation;
- bytes per entry: `Database.memory_bytes()` / N, faiss and numpy 160.
Top-1 ids are checked equal to faiss's (ties aside: equal distances) on every query.
"""

from __future__ import annotations

import os

# Idle thread pools of the peers wait without spinning, before numpy (OpenBLAS) and faiss (OpenMP)
# start them: by default their threads spin for a while after every call, taking the cores from
# whatever is timed next (the methods are interleaved query by query; perf of a loop of solid
# searches in a process that had used numpy showed OpenBLAS's blas_thread_server in 13-18 % of the
# samples on this 2-core machine). Each library still uses every core.
os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import argparse
import itertools
import json
import statistics
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import numpy.typing as npt

import solid
from python_baseline import cpu_jiffies, cpu_model, other_busy_cores, shared_data  # benches/, the script's own folder
from solid import io as sio

try:
    import faiss  # type: ignore[import-not-found,import-untyped,unused-ignore]
except ImportError:
    sys.exit("faiss-cpu is needed: pip install -r benches/requirements-bench.txt (or make bench-search-py)")

F32 = npt.NDArray[np.float32]
#: faiss's threads by default (every core): batches always run on them.
FAISS_THREADS = faiss.omp_get_max_threads()
CFG = solid.SolidConfig.preset("avia")
#: Queries of each mix for single search: 6 times the 24 orders of the 4 methods.
QUERIES = 144
DATA_VERSION = 1


def cache_dir() -> Path:
    env = os.environ.get("CARGO_TARGET_DIR")
    root = Path(env) if env else Path(__file__).resolve().parents[1] / "target"
    return root / "solid-bench-data"


def perturb(xyz: F32, rng: np.random.Generator, fov: float | None) -> F32:
    """Random yaw, shift of up to 2 m, dropout of up to half the points, half the time a FOV clip."""
    yaw = rng.uniform(0, 2 * np.pi)
    radius, angle = 2.0 * np.sqrt(rng.uniform()), rng.uniform(0, 2 * np.pi)
    keep = rng.uniform() >= rng.uniform(0, 0.5, len(xyz))
    az = np.arctan2(xyz[:, 1], xyz[:, 0])
    if fov is not None:
        keep &= np.abs(az) <= fov
    if rng.uniform() < 0.5:
        half = np.radians(40 + 30 * rng.uniform()) / 2
        centre = (rng.uniform() - 0.5) * np.radians(30)
        keep &= np.abs(az - centre) <= half
    p = xyz[keep, :3].astype(np.float64)
    p[:, 0] += radius * np.cos(angle)
    p[:, 1] += radius * np.sin(angle)
    c, s = np.cos(yaw), np.sin(yaw)
    out = np.empty_like(p)
    out[:, 0] = c * p[:, 0] - s * p[:, 1]
    out[:, 1] = s * p[:, 0] + c * p[:, 1]
    out[:, 2] = p[:, 2]
    return out.astype(np.float32)


def subsample(xyz: F32, rng: np.random.Generator) -> F32:
    keep = rng.uniform(size=len(xyz)) < rng.uniform(0.5, 1.0)
    return np.ascontiguousarray(xyz[keep, :3])


class Scans:
    def __init__(self, data: Path) -> None:
        self.hku = [sio.read_points(data / f"hku1-avia/Scans/{i:06d}.pcd")[:, :3] for i in range(314)]
        avia = np.radians(35.0)
        self.novel: list[tuple[F32, float | None]] = []
        for f in ("000000", "000001", "000010"):
            self.novel.append((sio.read_points(data / f"solid-samples/helipr_avia/{f}.bin", "helipr-avia")[:, :3], None))
        for f in ("000000", "000094", "000095", "000198", "000199"):
            self.novel.append((sio.read_points(data / f"kitti00/velodyne/{f}.bin", "kitti")[:, :3], avia))
        for f in ("000313", "000314", "000315"):
            self.novel.append((sio.read_points(data / f"solid-samples/kitti_00_pcd/{f}.pcd")[:, :3], avia))
        self.novel.append((sio.read_points(data / "misc/naverlabs_vel16.pcd")[:, :3], avia))
        nclt = "misc/nclt_2012-01-15_1326652795280148_hdl32e.bin"
        self.novel.append((sio.read_points(data / nclt, "nclt")[:, :3], avia))

    def hku_copy(self, rng: np.random.Generator) -> F32:
        return perturb(self.hku[rng.integers(len(self.hku))], rng, None)

    def novel_copy(self, rng: np.random.Generator) -> F32:
        xyz, fov = self.novel[rng.integers(len(self.novel))]
        return perturb(xyz, rng, fov)

    def dup_copy(self, rng: np.random.Generator) -> F32:
        return subsample(self.hku[0], rng)


def described(name: str, n: int, seed: int, make: Callable[[np.random.Generator], F32]) -> tuple[F32, F32]:
    """R-SOLiDs (n, 40) and A-SOLiDs (n, 60) of n scans made by `make`; cached (smaller sets
    are prefixes of larger ones, as each scan has its own seed)."""
    path = cache_dir() / f"py-{name}-{n}-{seed}-v{DATA_VERSION}.npz"
    if path.exists():
        z = np.load(path)
        return z["r"], z["a"]
    print(f"describing {n} scans for {name} (cached in {path})", file=sys.stderr, flush=True)
    r = np.empty((n, CFG.n_range), np.float32)
    a = np.empty((n, CFG.n_azimuth), np.float32)
    step = 20_000
    for start in range(0, n, step):
        scans = [make(np.random.default_rng([seed, i])) for i in range(start, min(n, start + step))]
        for j, d in enumerate(solid.describe_batch(scans, CFG)):
            r[start + j], a[start + j] = d.r, d.a
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, r=r, a=a)
    return r, a


def normalised(x: F32) -> F32:
    y = np.array(x, dtype=np.float32)
    faiss.normalize_L2(y)
    return y


def timed(fn: Callable[[], object]) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def best_of(reps: int, fn: Callable[[], object]) -> float:
    return min(timed(fn) for _ in range(reps))


def best_interleaved(reps: int, fns: dict[str, Callable[[], object]]) -> dict[str, float]:
    """The best of `reps` runs of each function, the functions taking turns in every round, so
    that each meets the same state of the machine (the allocator's free memory above all: a bulk
    add into memory the allocator kept from an earlier one skips the page faults of fresh memory,
    faiss's add of 100,000 entries took 3.5 to 7.7 ms over two runs of this script); each round
    takes the next order of the functions, so that none always follows the same one."""
    best = dict.fromkeys(fns, float("inf"))
    orders = list(itertools.permutations(fns))
    for round_ in range(reps):
        for name in orders[round_ % len(orders)]:
            best[name] = min(best[name], timed(fns[name]))
    return best


def top_k_numpy(x: F32, q: F32, k: int) -> npt.NDArray[np.int64]:
    s = x @ q
    if k == 1:
        return np.array([np.argmax(s)])
    part = np.argpartition(-s, k)[:k]
    return part[np.argsort(-s[part], kind="stable")]


def faiss_single_threads(index: faiss.IndexFlatIP, qn: F32) -> int:
    """faiss's faster thread count for one query on this index, 1 or every core, from the first 16
    queries run both ways in turn (best of 3 each). One query is a short job: on few entries the
    threads cost more than they save (10k entries: 0.05 ms on 1 thread, 0.25-0.34 ms on 2, with
    the passive wait policy above), on 1M they pay."""
    total = {1: 0.0, FAISS_THREADS: 0.0}
    for i in range(min(16, len(qn))):
        for threads in total:
            faiss.omp_set_num_threads(threads)
            total[threads] += best_of(3, lambda: index.search(qn[i : i + 1], 1))
    faiss.omp_set_num_threads(FAISS_THREADS)
    return min(total, key=lambda t: total[t])


def single(db: solid.Database, index: faiss.IndexFlatIP, x: F32, queries: F32, k: int, faiss_threads: int) -> dict[str, float]:
    """Mean seconds per query of each method over the queries, each method run once on each query
    (a repeat of one query would hide what `auto` learns across queries: it counts every call,
    and its periodic retries fall on the repeats), interleaved query by query, each query taking
    the next of every order of the methods: each method then follows each other one equally
    often. (With the order only rotated, a method always ran right after the same one, `auto`
    after numpy and brute force after `auto`: on near-duplicates at 10,000 entries, k = 1, `auto`
    took 1.15× brute force's time that way and 1.02–1.04× this way, in one process.) faiss runs
    on `faiss_threads` threads."""
    qn = normalised(queries)
    methods: dict[str, Callable[[int], object]] = {
        "auto": lambda i: db.search(queries[i], k=k),
        "brute": lambda i: db.search(queries[i], k=k, method="brute"),
        "faiss": lambda i: index.search(qn[i : i + 1], k),
        "numpy": lambda i: top_k_numpy(x, qn[i], k),
    }
    orders = list(itertools.permutations(methods))
    total = dict.fromkeys(methods, 0.0)
    faiss.omp_set_num_threads(faiss_threads)
    try:
        for i in range(len(queries)):
            for name in orders[i % len(orders)]:
                total[name] += timed(lambda: methods[name](i))
    finally:
        faiss.omp_set_num_threads(FAISS_THREADS)
    if k == 1:
        for i in range(len(queries)):
            hit = db.search(queries[i], k=1)[0]
            d_faiss, i_faiss = index.search(qn[i : i + 1], 1)
            assert hit.id == i_faiss[0, 0] or abs(hit.distance - (1 - d_faiss[0, 0])) < 1e-5, (hit, i_faiss)
    return {name: t / len(queries) for name, t in total.items()}


#: Runs of each single-search case, each on a fresh database, the median taken.
SINGLE_RUNS = 3

#: Runs of each batch search, best taken, by number of entries (with 2 at 10k, one run took
#: solid's batch 17.7 ms where the run before took 11.0 and a probe 12.6-12.9, alternating the
#: wheels before and after a change: a busy moment on this shared machine).
BATCH_REPS = {10_000: 7, 100_000: 5, 1_000_000: 2}

#: Rounds of the bulk adds, best taken, by number of entries: whole cycles of the 24 orders of
#: the 4 adds at 10k and 100k entries, so that each add follows each other one equally often. At
#: 10k entries an add takes about 0.2 ms and depends on what ran before it: in one process, solid's
#: stored add took 0.15 ms after itself, 0.21 after the indexed add and 0.30 after a numpy pass
#: over 32 MB; with 31 rounds, one run of this script gave 0.30 ms for HKU copies where the rounds
#: before had given 0.16.
ADD_REPS = {10_000: 72, 100_000: 24, 1_000_000: 5}


def fresh(r: F32, a: F32) -> solid.Database:
    """A new database of the rows, indexed at once: nothing observed by `auto` yet."""
    db = solid.Database(CFG)
    db.add_batch(r, a, index=True)
    return db


def batches(m: int, size: int) -> Iterator[slice]:
    for start in range(0, m, size):
        yield slice(start, min(m, start + size))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", type=Path, help="also write every figure to this JSON file")
    args = ap.parse_args()
    quick = os.environ.get("SOLID_BENCH_QUICK") is not None
    busy0, wall0, cpu0 = cpu_jiffies(), time.perf_counter(), time.process_time()
    sizes = [10_000, 100_000] if quick else [10_000, 100_000, 1_000_000]
    scans = Scans(shared_data())
    near, _ = described("near", 500, 2, scans.hku_copy)
    novel, _ = described("novel", 500, 3, scans.novel_copy)
    same, _ = described("dup-same", 500, 5, scans.dup_copy)
    print(
        f"solid {solid.__version__}, faiss {faiss.__version__} ({FAISS_THREADS} threads), "
        f"numpy {np.__version__}; {os.cpu_count()} cores; avia preset (40 range bins)"
    )
    rows_single: list[str] = []
    rows_batch: list[str] = []
    rows_add: list[str] = []
    rows_mem: list[str] = []
    doc: dict[str, object] = {
        "command": "python benches/search_peers.py --json benches/results/search.json",
        "solid": solid.__version__,
        "faiss": faiss.__version__,
        "faiss_threads": FAISS_THREADS,
        "numpy": np.__version__,
        "cores": os.cpu_count(),
        "cpu": cpu_model(),
        "queries": QUERIES,
        "single_runs": SINGLE_RUNS,
    }
    js_single: list[dict[str, object]] = []
    js_batch: list[dict[str, object]] = []
    js_add: list[dict[str, object]] = []
    js_mem: list[dict[str, object]] = []
    for n in sizes:
        for db_name, make, mixes in (
            ("hku", scans.hku_copy, {"near": near, "novel": novel}),
            ("dup", scans.dup_copy, {"same": same, "other": near}),
        ):
            r, a = described(db_name, n, 1 if db_name == "hku" else 4, make)
            # Bulk add: solid's default (stored, the index left to the searches that pay for it)
            # and index=True (the sketch and the kd-tree built at once), faiss, numpy, taking
            # turns (best of ADD_REPS rounds).
            reps = ADD_REPS[n]
            adds = best_interleaved(
                reps,
                {
                    "default": lambda: solid.Database(CFG).add_batch(r, a),
                    "indexed": lambda: solid.Database(CFG).add_batch(r, a, index=True),
                    "faiss": lambda: faiss.IndexFlatIP(CFG.n_range).add(normalised(r)),
                    "numpy": lambda: r / np.maximum(np.linalg.norm(r, axis=1, keepdims=True), 1e-30),
                },
            )
            t_add, t_add_indexed, t_faiss_add, t_np_add = (adds[m] for m in ("default", "indexed", "faiss", "numpy"))
            db = fresh(r, a)
            x = normalised(r)
            index = faiss.IndexFlatIP(CFG.n_range)
            index.add(x)
            rows_add.append(
                f"{db_name:4s} {n:>9d} {t_add * 1e3:9.1f} {t_add_indexed * 1e3:9.1f} {t_faiss_add * 1e3:9.1f} "
                f"{t_np_add * 1e3:9.1f} {t_faiss_add / t_add:8.2f} {t_faiss_add / t_add_indexed:8.2f}"
            )
            js_add.append(
                {"db": db_name, "n": n, "add_s": t_add, "add_indexed_s": t_add_indexed, "faiss_s": t_faiss_add, "numpy_s": t_np_add}
            )
            if db_name == "hku":
                js_mem.append({"n": n, "solid": db.memory_bytes() / n, "faiss": index.ntotal * 4 * CFG.n_range / n})
                rows_mem.append(f"{n:>9d} {db.memory_bytes() / n:8.1f} {index.ntotal * 4 * CFG.n_range / n:8.1f} {x.nbytes / n:8.1f}")
            for mix, queries in mixes.items():
                threads = faiss_single_threads(index, normalised(queries[:QUERIES]))
                for k in (1, 10):
                    runs = [single(fresh(r, a), index, x, queries[:QUERIES], k, threads) for _ in range(SINGLE_RUNS)]
                    t = {m: statistics.median(run[m] for run in runs) for m in runs[0]}
                    spread = [run["auto"] / run["brute"] for run in runs]
                    js_single.append(
                        {
                            "db": db_name,
                            "mix": mix,
                            "n": n,
                            "k": k,
                            "faiss_threads": threads,
                            **{f"{m}_s": v for m, v in t.items()},
                            "auto_brute_runs": spread,
                        }
                    )
                    rows_single.append(
                        f"{db_name + '/' + mix:10s} {n:>9d} {k:3d} {t['auto'] * 1e6:9.1f} {t['brute'] * 1e6:9.1f} "
                        f"{t['faiss'] * 1e6:9.1f} {threads:2d} {t['numpy'] * 1e6:9.1f} {t['faiss'] / t['auto']:8.2f} "
                        f"{t['numpy'] / t['brute']:8.2f} {t['brute'] / t['auto']:8.2f} {min(spread):5.2f}-{max(spread):4.2f}"
                    )
            # Batch: 1,000 queries, half of each mix.
            q = np.concatenate([m[:500] for m in mixes.values()])
            qn = normalised(q)
            t_batch = best_of(BATCH_REPS[n], lambda: db.search_batch(q, k=1))
            t_faiss = best_of(BATCH_REPS[n], lambda: index.search(qn, 1))
            t_np = best_of(1, lambda: [np.argmax(x @ qn[s].T, axis=0) for s in batches(len(qn), 16)])
            t_loop = best_of(1, lambda: [db.search(v, k=1) for v in q])
            ids, dists = db.search_batch(q, k=1)
            d_f, i_f = index.search(qn, 1)
            agree = np.mean((ids[:, 0] == i_f[:, 0]) | (np.abs(dists[:, 0] - (1 - d_f[:, 0])) < 1e-5))
            assert agree == 1.0, agree
            js_batch.append({"db": db_name, "n": n, "queries": len(q), "batch_s": t_batch, "faiss_s": t_faiss, "numpy_s": t_np, "loop_s": t_loop})
            rows_batch.append(
                f"{db_name:4s} {n:>9d} {t_batch * 1e3:9.1f} {t_faiss * 1e3:9.1f} {t_np * 1e3:9.1f} "
                f"{t_loop * 1e3:9.1f} {t_faiss / t_batch:8.2f} {t_np / t_batch:8.2f} {t_loop / t_batch:8.2f}"
            )
            print(f"  done {db_name} {n}", file=sys.stderr, flush=True)

    print(
        f"\nsingle search: mean µs per query over {QUERIES} queries, methods interleaved, median of {SINGLE_RUNS} runs on fresh "
        "databases; faiss on th threads; ratios peer / solid; auto/brute over the runs"
    )
    print(
        f"{'db/mix':10s} {'n':>9s} {'k':>3s} {'auto':>9s} {'brute':>9s} {'faiss':>9s} {'th':>2s} {'numpy':>9s} {'faiss/au':>8s} "
        f"{'np/brute':>8s} {'bf/auto':>8s} {'au/bf runs':>10s}"
    )
    print("\n".join(rows_single))
    print("\nbatch search: 1,000 queries (500 of each mix), k = 1, ms; ratios peer / solid search_batch")
    print(f"{'db':4s} {'n':>9s} {'batch':>9s} {'faiss':>9s} {'numpy':>9s} {'loop':>9s} {'faiss/b':>8s} {'numpy/b':>8s} {'loop/b':>8s}")
    print("\n".join(rows_batch))
    reps_text = " / ".join(str(ADD_REPS[n]) for n in sizes)
    sizes_text = " / ".join(f"{n // 1000:,}k" for n in sizes)
    print(f"\nbulk add of n entries from arrays, ms (best of {reps_text} runs at {sizes_text}); ratios faiss / solid (default, index=True)")
    print(f"{'db':4s} {'n':>9s} {'add':>9s} {'indexed':>9s} {'faiss':>9s} {'numpy':>9s} {'faiss/a':>8s} {'faiss/ix':>8s}")
    print("\n".join(rows_add))
    print("\nbytes per entry (hku): solid Database.memory_bytes() / n, faiss IndexFlatIP, numpy float32 rows")
    print(f"{'n':>9s} {'solid':>8s} {'faiss':>8s} {'numpy':>8s}")
    print("\n".join(rows_mem))
    others = other_busy_cores(busy0, wall0, cpu0)
    if others is not None:
        print(f"\nother processes kept {others:.2f} of {os.cpu_count()} cores busy during the run")
    if args.json is not None:
        doc.update(other_processes_busy_cores=others, single=js_single, batch=js_batch, add=js_add, memory=js_mem)
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(doc, indent=1) + "\n")
        print(f"\nwrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
