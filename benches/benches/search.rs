//! Search benchmarks (issue 3): build and top-1 query of brute force, the kd-tree and the online
//! index at 1k, 10k, 100k and 1M entries, on seeded random vectors shaped like R-SOLiDs and on
//! real HKU descriptors (perturbed copies to reach the sizes); the online index's insert cost;
//! and one full loop-detector step on KITTI (describe a full frame, search 4,541 entries, heading).
//!
//! After criterion, a summary table prints the mean query time of each method at each size
//! and the kd-tree / brute-force ratio measured in the same run, so the crossover is visible.
//! `SOLID_BENCH_QUICK=1` skips the 1M size.

use criterion::{BenchmarkId, Criterion, Throughput};
use solid_lidar::db::{Database, DetectorConfig, LoopDetector, Method};
use solid_lidar::search::{
    brute_force, normalize_rows, online_insert, Exclude, KdTree, Neighbor, OnlineIndex,
};
use solid_lidar::{Config, Describer, Descriptor, Points};
use solid_lidar_benches::{kitti, shared_dir};
use std::hint::black_box;
use std::time::Instant;

const DIM: usize = 40;

/// splitmix64: a small seeded generator, so every run benchmarks the same data.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.unit().max(1e-300), self.unit());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// A vector shaped like an R-SOLiD: counts that rise then fall with range (a random profile),
/// log-normal noise per bin, and empty far bins.
fn shaped(rng: &mut Rng) -> [f32; DIM] {
    let tau = 2.0 + 10.0 * rng.unit();
    let alpha = 2.0 * rng.unit();
    let scale = 50.0 + 500.0 * rng.unit();
    let cutoff = 10 + (rng.next_u64() % 31) as usize;
    let mut v = [0f32; DIM];
    for (i, x) in v.iter_mut().enumerate() {
        if i >= cutoff {
            break;
        }
        let t = i as f64 + 1.0;
        *x = (scale * t.powf(alpha) * (-t / tau).exp() * (0.4 * rng.normal()).exp()).round() as f32;
    }
    v
}

fn perturbed(base: &[f32], rng: &mut Rng, sigma: f64) -> Vec<f32> {
    base.iter()
        .map(|&x| (f64::from(x) * (sigma * rng.normal()).exp()) as f32)
        .collect()
}

fn read_pcd_xyz(path: &std::path::Path) -> Vec<f32> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let marker = b"DATA binary\n";
    let at = bytes
        .windows(marker.len())
        .position(|w| w == marker)
        .expect("binary PCD");
    let header = std::str::from_utf8(&bytes[..at]).unwrap();
    let value = |key: &str| -> Vec<String> {
        header
            .lines()
            .find(|l| l.starts_with(key))
            .unwrap()
            .split_whitespace()
            .skip(1)
            .map(String::from)
            .collect()
    };
    let fields = value("FIELDS").len();
    let n: usize = value("POINTS")[0].parse().unwrap();
    let rec = 4 * fields;
    bytes[at + marker.len()..at + marker.len() + n * rec]
        .chunks_exact(rec)
        .flat_map(|r| {
            (0..3).map(move |i| f32::from_le_bytes(r[4 * i..4 * i + 4].try_into().unwrap()))
        })
        .collect()
}

/// The R-SOLiDs of the 314 HKU Livox Avia keyframes (preset `avia`).
fn hku_r() -> Vec<Vec<f32>> {
    let dir = shared_dir().join("data/hku1-avia/Scans");
    let mut d = Describer::new(Config::preset("avia").unwrap()).unwrap();
    (0..314)
        .map(|i| {
            let xyz = read_pcd_xyz(&dir.join(format!("{i:06}.pcd")));
            d.describe(Points::new(&xyz, 3).unwrap()).unwrap().r
        })
        .collect()
}

/// A data set: normalised rows plus queries (normalised), `n` entries.
struct Set {
    name: &'static str,
    rows: Vec<f32>,
    queries: Vec<Vec<f32>>,
}

fn normalise(v: &[f32]) -> Vec<f32> {
    let mut o = vec![0f32; v.len()];
    normalize_rows(v, v.len(), &mut o).unwrap();
    o
}

/// Seeded random shaped vectors; queries are half revisits (perturbed entries) and half novel.
fn random_set(n: usize) -> Set {
    let mut rng = Rng(0x5eed ^ n as u64);
    let mut raw = Vec::with_capacity(n * DIM);
    for _ in 0..n {
        raw.extend_from_slice(&shaped(&mut rng));
    }
    let mut rows = vec![0f32; raw.len()];
    normalize_rows(&raw, DIM, &mut rows).unwrap();
    let queries = (0..64)
        .map(|i| {
            if i % 2 == 0 {
                let j = (rng.next_u64() % n as u64) as usize;
                normalise(&perturbed(&raw[j * DIM..(j + 1) * DIM], &mut rng, 0.1))
            } else {
                normalise(&shaped(&mut rng))
            }
        })
        .collect();
    Set {
        name: "random",
        rows,
        queries,
    }
}

/// Real HKU descriptors: the database holds the first 157 keyframes (the walk's first half),
/// each repeated with 10 % multiplicative noise until `n` entries. Queries alternate revisits
/// (other noisy copies of those keyframes) and novel places (keyframes 157..270, which the
/// walk has not seen before).
fn real_set(n: usize, real: &[Vec<f32>]) -> Set {
    let (seen, novel) = (&real[..157], &real[157..270]);
    let mut rng = Rng(0xa11a ^ n as u64);
    let mut raw = Vec::with_capacity(n * DIM);
    for i in 0..n {
        let sigma = if i < seen.len() { 0.0 } else { 0.1 };
        raw.extend(perturbed(&seen[i % seen.len()], &mut rng, sigma));
    }
    let mut rows = vec![0f32; raw.len()];
    normalize_rows(&raw, DIM, &mut rows).unwrap();
    let queries = (0..64)
        .map(|i| {
            if i % 2 == 0 {
                let j = (rng.next_u64() % seen.len() as u64) as usize;
                normalise(&perturbed(&seen[j], &mut rng, 0.1))
            } else {
                normalise(&novel[(i * 7) % novel.len()])
            }
        })
        .collect();
    Set {
        name: "hku_real",
        rows,
        queries,
    }
}

struct Index {
    perm: Vec<u32>,
    splits: Vec<u16>,
    online_perm: Vec<u32>,
    online_splits: Vec<u16>,
}

fn index(set: &Set) -> Index {
    let n = set.rows.len() / DIM;
    let (mut perm, mut splits) = (vec![0u32; n], vec![0u16; n]);
    KdTree::build(&set.rows, DIM, &mut perm, &mut splits).unwrap();
    let (mut op, mut os) = (vec![0u32; n], vec![0u16; n]);
    solid_lidar::search::online_rebuild(&set.rows, DIM, &mut op, &mut os).unwrap();
    Index {
        perm,
        splits,
        online_perm: op,
        online_splits: os,
    }
}

fn q_brute(set: &Set, q: &[f32], out: &mut [Neighbor]) -> u32 {
    brute_force(&set.rows, DIM, q, 1, &Exclude::NONE, out).unwrap();
    out[0].id
}

fn q_tree(set: &Set, ix: &Index, q: &[f32], out: &mut [Neighbor]) -> u32 {
    let t = KdTree::from_built(&set.rows, DIM, &ix.perm, &ix.splits).unwrap();
    t.search(q, 1, &Exclude::NONE, out).unwrap();
    out[0].id
}

fn q_online(set: &Set, ix: &Index, q: &[f32], out: &mut [Neighbor]) -> u32 {
    OnlineIndex::new(&set.rows, DIM, &ix.online_perm, &ix.online_splits)
        .unwrap()
        .search(q, 1, &Exclude::NONE, out)
        .unwrap();
    out[0].id
}

fn sizes() -> Vec<usize> {
    if std::env::var_os("SOLID_BENCH_QUICK").is_some() {
        vec![1_000, 10_000, 100_000]
    } else {
        vec![1_000, 10_000, 100_000, 1_000_000]
    }
}

fn sets(real: &[Vec<f32>]) -> Vec<Set> {
    let mut v = Vec::new();
    for n in sizes() {
        v.push(random_set(n));
        v.push(real_set(n, real));
    }
    v
}

fn bench_queries(c: &mut Criterion, sets: &[Set]) {
    let mut g = c.benchmark_group("search_top1");
    g.sample_size(20);
    for set in sets {
        let n = set.rows.len() / DIM;
        let ix = index(set);
        let mut out = [Neighbor::default(); 1];
        let mut i = 0usize;
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(
            BenchmarkId::new(format!("{}/brute", set.name), n),
            &n,
            |b, _| {
                b.iter(|| {
                    i = (i + 1) % set.queries.len();
                    black_box(q_brute(set, &set.queries[i], &mut out))
                })
            },
        );
        g.bench_with_input(
            BenchmarkId::new(format!("{}/kdtree", set.name), n),
            &n,
            |b, _| {
                b.iter(|| {
                    i = (i + 1) % set.queries.len();
                    black_box(q_tree(set, &ix, &set.queries[i], &mut out))
                })
            },
        );
        g.bench_with_input(
            BenchmarkId::new(format!("{}/online", set.name), n),
            &n,
            |b, _| {
                b.iter(|| {
                    i = (i + 1) % set.queries.len();
                    black_box(q_online(set, &ix, &set.queries[i], &mut out))
                })
            },
        );
    }
    g.finish();
}

fn bench_build(c: &mut Criterion, sets: &[Set]) {
    let mut g = c.benchmark_group("search_build");
    g.sample_size(10);
    for set in sets.iter().filter(|s| s.name == "random") {
        let n = set.rows.len() / DIM;
        let (mut perm, mut splits) = (vec![0u32; n], vec![0u16; n]);
        let mut normed = vec![0f32; set.rows.len()];
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::new("brute_normalize_rows", n), &n, |b, _| {
            b.iter(|| normalize_rows(black_box(&set.rows), DIM, &mut normed).unwrap())
        });
        g.bench_with_input(BenchmarkId::new("kdtree_build", n), &n, |b, _| {
            b.iter(|| {
                KdTree::build(black_box(&set.rows), DIM, &mut perm, &mut splits).unwrap();
            })
        });
        if n <= 100_000 {
            // Online: insert all n entries one by one (the time per entry is this / n).
            g.bench_with_input(BenchmarkId::new("online_insert_all", n), &n, |b, _| {
                b.iter(|| {
                    for k in 1..=n {
                        online_insert(&set.rows[..k * DIM], DIM, &mut perm, &mut splits).unwrap();
                    }
                })
            });
        }
    }
    g.finish();
}

/// A 4,541-entry loop-detector database (the length of KITTI 00): the 5 real KITTI frames and
/// shaped random descriptors, and the full KITTI frame 000000 as the scan of every step.
fn bench_loop_step(c: &mut Criterion) {
    let cfg = Config::preset("hdl64").unwrap();
    let mut describer = Describer::new(cfg).unwrap();
    let frames: Vec<Descriptor> = ["000000", "000094", "000095", "000198", "000199"]
        .iter()
        .map(|f| {
            let raw = kitti(&format!("kitti00/velodyne/{f}.bin"));
            describer.describe(Points::new(&raw, 4).unwrap()).unwrap()
        })
        .collect();
    let mut rng = Rng(4541);
    let mut db = Database::new(cfg).unwrap();
    for i in 0..4541 {
        let f = &frames[i % frames.len()];
        let r = if i < frames.len() {
            f.r.clone()
        } else {
            shaped(&mut rng).to_vec()
        };
        let a = perturbed(&f.a, &mut rng, 0.2);
        db.add_vectors(&r, &a, 0, i as f64, None).unwrap();
    }
    let scan = kitti("kitti00/velodyne/000094.bin");
    let mut g = c.benchmark_group("loop_step");
    g.sample_size(30);
    for rerank in [false, true] {
        let det = LoopDetector::with_database(
            db.clone(),
            DetectorConfig {
                threshold: 0.1,
                rerank,
                ..DetectorConfig::default()
            },
        )
        .unwrap();
        g.bench_function(
            format!(
                "kitti_describe+search4541+heading{}",
                if rerank { "+rerank10" } else { "" }
            ),
            |b| {
                b.iter(|| {
                    let d = describer
                        .describe(Points::new(black_box(&scan), 4).unwrap())
                        .unwrap();
                    black_box(det.query(&d).unwrap())
                })
            },
        );
    }
    let d = describer.describe(Points::new(&scan, 4).unwrap()).unwrap();
    g.bench_function("describe_only", |b| {
        b.iter(|| {
            describer
                .describe(Points::new(black_box(&scan), 4).unwrap())
                .unwrap()
        })
    });
    for m in [Method::Brute, Method::KdTree] {
        g.bench_function(format!("search4541_top10_{m:?}"), |b| {
            b.iter(|| db.search(black_box(&d.r), 10, 0, m).unwrap())
        });
    }
    g.finish();
}

/// Mean seconds per call of `f` over `reps` calls.
fn mean<F: FnMut(usize)>(reps: usize, mut f: F) -> f64 {
    let s = Instant::now();
    for i in 0..reps {
        f(i);
    }
    s.elapsed().as_secs_f64() / reps as f64
}

/// Mean query times (brute, kd-tree, online) over the queries `pick` selects.
fn times(set: &Set, ix: &Index, pick: &[usize]) -> (f64, f64, f64) {
    let n = set.rows.len() / DIM;
    let reps = if n >= 1_000_000 {
        pick.len()
    } else {
        4 * pick.len()
    };
    let mut out = [Neighbor::default(); 1];
    let q = |i: usize| &set.queries[pick[i % pick.len()]];
    let b = mean(reps, |i| {
        black_box(q_brute(set, q(i), &mut out));
    });
    let t = mean(reps, |i| {
        black_box(q_tree(set, ix, q(i), &mut out));
    });
    let o = mean(reps, |i| {
        black_box(q_online(set, ix, q(i), &mut out));
    });
    (b, t, o)
}

fn summary(sets: &[Set]) {
    println!(
        "\nsummary: mean top-1 query time (same run); kd/bf < 1: the kd-tree wins, > 1: it loses"
    );
    println!(
        "{:<16} {:>9} {:>11} {:>11} {:>11} {:>8} {:>8}",
        "data/queries", "n", "brute µs", "kdtree µs", "online µs", "kd/bf", "on/bf"
    );
    for set in sets {
        let n = set.rows.len() / DIM;
        let ix = index(set);
        let all: Vec<usize> = (0..set.queries.len()).collect();
        let kinds = [
            (
                "revisit",
                all.iter()
                    .copied()
                    .filter(|i| i % 2 == 0)
                    .collect::<Vec<_>>(),
            ),
            (
                "novel",
                all.iter().copied().filter(|i| i % 2 == 1).collect(),
            ),
        ];
        for (kind, pick) in kinds {
            let label = format!("{}/{kind}", set.name);
            let (b, t, o) = times(set, &ix, &pick);
            println!(
                "{:<16} {:>9} {:>11.1} {:>11.1} {:>11.1} {:>8.2} {:>8.2}",
                label,
                n,
                b * 1e6,
                t * 1e6,
                o * 1e6,
                t / b,
                o / b
            );
        }
    }
    // Small sizes, to place the Auto crossover.
    println!("\ncrossover (random shaped data, all queries): n, brute µs, online µs");
    for n in [256usize, 512, 1024, 2048, 4096, 8192, 16384] {
        let set = random_set(n);
        let ix = index(&set);
        let all: Vec<usize> = (0..64).collect();
        let (b, _, o) = times(&set, &ix, &all);
        println!(
            "{n:>6} {:>9.2} {:>9.2}  ratio {:.2}",
            b * 1e6,
            o * 1e6,
            o / b
        );
    }
}

fn main() {
    let real = hku_r();
    let sets = sets(&real);
    let mut c = Criterion::default().configure_from_args();
    bench_queries(&mut c, &sets);
    bench_build(&mut c, &sets);
    bench_loop_step(&mut c);
    c.final_summary();
    summary(&sets);
}
