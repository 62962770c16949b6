//! Search benchmarks (issue 11) on realistic R-SOLiD databases of 10k, 100k and 1M entries.
//!
//! Data, all described with the `avia` preset from real scans:
//! - `hku`: the 314 HKU Livox Avia keyframes under a random yaw, a shift of up to 2 m, dropout of
//!   up to half the points and (half the time) a horizontal FOV clip to 40–70°. Queries `near`:
//!   other such copies (a revisit); `novel`: scans of other cities (HeLiPR Avia, KITTI, NCLT, a
//!   Naver Labs indoor scan; the 360° ones cut to the Avia's 70°) under the same perturbations.
//! - `dup`: copies of one HKU scan, each keeping a random 50–100 % of its points (a database of
//!   near-duplicates). Queries `same`: other such copies; `other`: perturbed other HKU scans.
//!
//! The descriptors are cached under `target/solid-bench-data/` (the 1M sets take about a
//! minute to describe on two cores the first time).
//!
//! After criterion (top-1 at 100k, index building, a full loop-detector step on KITTI) a
//! summary prints, for every database, size, query mix and k, the mean query time of each plan
//! of `search::Index` with the plans interleaved query by query (same queries, same run; the
//! median of 3 or 9 repetitions of each), the ratio `auto / brute`, the slowest `auto` query,
//! and `auto` with the loop detector's distance bound (0.03). `auto` learns over the mix what a
//! `Database` learns (`search::Observed`). Every plan's results are checked equal to brute
//! force's on the way.
//!
//! `SOLID_BENCH_QUICK=1` skips the 1M size; `SOLID_BENCH_SUMMARY=1` runs only the summary.

use criterion::{BenchmarkId, Criterion, Throughput};
use solid_lidar::db::{Database, DetectorConfig, LoopDetector, Method};
use solid_lidar::search::{
    normalize_rows, online_insert, online_rebuild, sketch_encode, sketch_len, Index, KdTree,
    Neighbor, Observed, Plan, Request, Rows,
};
use solid_lidar::{Config, Describer, Descriptor, Points};
use solid_lidar_benches::{kitti, read_xyz, shared_dir, Rng};
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Instant;

const DIM: usize = 40;

/// Bumped whenever the data generation changes, so that stale caches are not reused.
const DATA_VERSION: u32 = 1;

/// Queries per mix.
const QUERIES: usize = 48;

/// The loop detector's default distance threshold (`solid detect`).
const DETECTOR_BOUND: f32 = 0.03;

/// A scan as a Livox Avia at another moment would see it: only points within `fov` (half-angle,
/// radians) of +x when given; a random yaw, a shift of up to `shift` m, a random dropout of up to
/// `drop`; half the time a horizontal FOV clip to 40–70°.
fn perturb(xyz: &[f32], rng: &mut Rng, shift: f64, drop: f64, fov: Option<f64>) -> Vec<f32> {
    let yaw = rng.unit() * std::f64::consts::TAU;
    let (s, c) = yaw.sin_cos();
    let radius = shift * rng.unit().sqrt();
    let angle = rng.unit() * std::f64::consts::TAU;
    let (tx, ty) = (radius * angle.cos(), radius * angle.sin());
    let keep = 1.0 - drop * rng.unit();
    let clip = (rng.unit() < 0.5).then(|| (40.0 + 30.0 * rng.unit()).to_radians() / 2.0);
    let centre = (rng.unit() - 0.5) * 30f64.to_radians();
    let mut out = Vec::with_capacity(xyz.len());
    for p in xyz.chunks_exact(3) {
        if rng.unit() > keep {
            continue;
        }
        let (x, y, z) = (f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
        let azimuth = y.atan2(x);
        if fov.is_some_and(|h| azimuth.abs() > h)
            || clip.is_some_and(|h| (azimuth - centre).abs() > h)
        {
            continue;
        }
        let (x, y) = (x + tx, y + ty);
        out.extend_from_slice(&[(c * x - s * y) as f32, (s * x + c * y) as f32, z as f32]);
    }
    out
}

/// The scans the data sets are made from.
struct Scans {
    hku: Vec<Vec<f32>>,
    /// Scans of other cities and their half field of view to keep (`None`: already an Avia).
    novel: Vec<(Vec<f32>, Option<f64>)>,
}

fn scans() -> Scans {
    let data = shared_dir().join("data");
    let hku = (0..314)
        .map(|i| read_xyz(&data.join(format!("hku1-avia/Scans/{i:06}.pcd"))))
        .collect();
    let avia = Some(35f64.to_radians());
    let mut novel = Vec::new();
    for f in ["000000", "000001", "000010"] {
        novel.push((
            read_xyz(&data.join(format!("solid-samples/helipr_avia/{f}.bin"))),
            None,
        ));
    }
    for f in ["000000", "000094", "000095", "000198", "000199"] {
        novel.push((
            read_xyz(&data.join(format!("kitti00/velodyne/{f}.bin"))),
            avia,
        ));
    }
    for f in ["000313", "000314", "000315"] {
        novel.push((
            read_xyz(&data.join(format!("solid-samples/kitti_00_pcd/{f}.pcd"))),
            avia,
        ));
    }
    novel.push((read_xyz(&data.join("misc/naverlabs_vel16.pcd")), avia));
    novel.push((
        read_xyz(&data.join("misc/nclt_2012-01-15_1326652795280148_hdl32e.bin")),
        avia,
    ));
    Scans { hku, novel }
}

fn cache_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target"),
    }
    .join("solid-bench-data")
}

/// The L2-normalised R-SOLiDs of `n` scans made by `make(rng)` (each from its own seed), on every
/// core; cached on disk.
fn described<F: Fn(&mut Rng) -> Vec<f32> + Sync>(
    name: &str,
    n: usize,
    seed: u64,
    make: F,
) -> Vec<f32> {
    let path = cache_dir().join(format!("{name}-{n}-{seed}-v{DATA_VERSION}.f32"));
    if let Ok(bytes) = std::fs::read(&path) {
        if bytes.len() == n * DIM * 4 {
            return bytes
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                .collect();
        }
    }
    eprintln!(
        "describing {n} scans for {name} (cached in {})",
        path.display()
    );
    let cfg = Config::preset("avia").unwrap();
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    let mut raw = vec![0f32; n * DIM];
    let chunk = n.div_ceil(threads).max(1);
    std::thread::scope(|s| {
        for (t, part) in raw.chunks_mut(chunk * DIM).enumerate() {
            let make = &make;
            s.spawn(move || {
                let mut describer = Describer::new(cfg).unwrap();
                for (j, row) in part.chunks_exact_mut(DIM).enumerate() {
                    let i = (t * chunk + j) as u64;
                    let mut rng = Rng(seed ^ i.wrapping_mul(0x2545_F491_4F6C_DD1D));
                    let xyz = make(&mut rng);
                    let d = describer.describe(Points::new(&xyz, 3).unwrap()).unwrap();
                    row.copy_from_slice(&d.r);
                }
            });
        }
    });
    let mut rows = vec![0f32; raw.len()];
    normalize_rows(&raw, DIM, &mut rows).unwrap();
    std::fs::create_dir_all(cache_dir()).unwrap();
    let bytes: Vec<u8> = rows.iter().flat_map(|x| x.to_le_bytes()).collect();
    std::fs::write(&path, bytes).unwrap();
    rows
}

fn hku_copy(s: &Scans, rng: &mut Rng) -> Vec<f32> {
    let i = rng.below(s.hku.len());
    perturb(&s.hku[i], rng, 2.0, 0.5, None)
}

fn novel_copy(s: &Scans, rng: &mut Rng) -> Vec<f32> {
    let (xyz, fov) = &s.novel[rng.below(s.novel.len())];
    perturb(xyz, rng, 2.0, 0.5, *fov)
}

fn dup_copy(s: &Scans, rng: &mut Rng) -> Vec<f32> {
    let keep = 0.5 + 0.5 * rng.unit();
    s.hku[0]
        .chunks_exact(3)
        .filter(|_| rng.unit() < keep)
        .flatten()
        .copied()
        .collect()
}

/// A database with every buffer of `search::Index`.
struct Db {
    name: &'static str,
    rows: Vec<f32>,
    perm: Vec<u32>,
    splits: Vec<u16>,
    codes: Vec<u8>,
    params: Vec<f32>,
    mixes: Vec<(&'static str, Vec<f32>)>,
}

impl Db {
    fn new(name: &'static str, rows: Vec<f32>, mixes: Vec<(&'static str, Vec<f32>)>) -> Db {
        let n = rows.len() / DIM;
        let (mut perm, mut splits) = (vec![0u32; n], vec![0u16; n]);
        let r = Rows::normalized(&rows, DIM).unwrap();
        online_rebuild(r, &mut perm, &mut splits).unwrap();
        let (nc, np) = sketch_len(n, DIM);
        let (mut codes, mut params) = (vec![0u8; nc], vec![0f32; np]);
        sketch_encode(r, 0, &mut codes, &mut params).unwrap();
        Db {
            name,
            rows,
            perm,
            splits,
            codes,
            params,
            mixes,
        }
    }

    fn len(&self) -> usize {
        self.rows.len() / DIM
    }

    fn norm_rows(&self) -> Rows<'_> {
        Rows::normalized(&self.rows, DIM).unwrap()
    }

    fn index(&self) -> Index<'_> {
        Index::new(
            self.norm_rows(),
            &self.perm,
            &self.splits,
            &self.codes,
            &self.params,
        )
        .unwrap()
    }
}

fn sizes() -> Vec<usize> {
    if std::env::var_os("SOLID_BENCH_QUICK").is_some() {
        vec![10_000, 100_000]
    } else {
        vec![10_000, 100_000, 1_000_000]
    }
}

fn databases(s: &Scans) -> Vec<Db> {
    let near = described("near", QUERIES, 2, |r| hku_copy(s, r));
    let novel = described("novel", QUERIES, 3, |r| novel_copy(s, r));
    let same = described("dup-same", QUERIES, 5, |r| dup_copy(s, r));
    let mut dbs = Vec::new();
    for n in sizes() {
        // Seeds per row do not depend on n: the smaller sets are prefixes of the larger.
        let hku = described("hku", n, 1, |r| hku_copy(s, r));
        dbs.push(Db::new(
            "hku",
            hku,
            vec![("near", near.clone()), ("novel", novel.clone())],
        ));
        let dup = described("dup", n, 4, |r| dup_copy(s, r));
        dbs.push(Db::new(
            "dup",
            dup,
            vec![("same", same.clone()), ("other", near.clone())],
        ));
    }
    dbs
}

fn bench_queries(c: &mut Criterion, dbs: &[Db]) {
    let mut g = c.benchmark_group("search_top1");
    g.sample_size(20);
    g.measurement_time(std::time::Duration::from_secs(2));
    for db in dbs.iter().filter(|d| d.len() == 100_000) {
        let index = db.index();
        for (mix, queries) in &db.mixes {
            let mut out = [Neighbor::default(); 1];
            let mut i = 0usize;
            for plan in [Plan::Brute, Plan::KdTree, Plan::Sketch, Plan::Auto] {
                let id = BenchmarkId::new(format!("{}/{mix}/{plan:?}", db.name), db.len());
                g.bench_function(id, |b| {
                    b.iter(|| {
                        i = (i + 1) % QUERIES;
                        let q = &queries[i * DIM..(i + 1) * DIM];
                        let req = Request {
                            plan,
                            ..Request::nearest(1)
                        };
                        black_box(index.search(q, &req, &mut out).unwrap())
                    })
                });
            }
        }
    }
    g.finish();
}

fn bench_build(c: &mut Criterion, dbs: &[Db]) {
    let mut g = c.benchmark_group("search_build");
    g.sample_size(10);
    for db in dbs.iter().filter(|d| d.name == "hku" && d.len() <= 100_000) {
        let n = db.len();
        let (mut perm, mut splits) = (vec![0u32; n], vec![0u16; n]);
        let (nc, np) = sketch_len(n, DIM);
        let (mut codes, mut params) = (vec![0u8; nc], vec![0f32; np]);
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::new("kdtree_build", n), &n, |b, _| {
            b.iter(|| {
                KdTree::build(black_box(db.norm_rows()), &mut perm, &mut splits).unwrap();
            });
        });
        g.bench_with_input(BenchmarkId::new("sketch_encode", n), &n, |b, _| {
            b.iter(|| {
                sketch_encode(black_box(db.norm_rows()), 0, &mut codes, &mut params).unwrap()
            });
        });
        // Online: insert all n entries one by one (the time per entry is this / n).
        g.bench_with_input(BenchmarkId::new("online_insert_all", n), &n, |b, _| {
            b.iter(|| {
                for k in 1..=n {
                    online_insert(db.norm_rows().prefix(k), &mut perm, &mut splits).unwrap();
                }
            })
        });
    }
    g.finish();
}

/// A 4,541-entry loop-detector database (the length of KITTI 00): the 5 real KITTI frames and
/// perturbed copies of them, and the full KITTI frame 000094 as the scan of every step.
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
    let mut noisy = |v: &[f32]| -> Vec<f32> {
        v.iter()
            .map(|&x| (f64::from(x) * (1.0 + 0.4 * (rng.unit() - 0.5))) as f32)
            .collect()
    };
    let mut db = Database::new(cfg).unwrap();
    for i in 0..4541 {
        let f = &frames[i % frames.len()];
        let r = if i < frames.len() {
            f.r.clone()
        } else {
            noisy(&f.r)
        };
        let a = noisy(&f.a);
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
    for m in [Method::Brute, Method::KdTree] {
        g.bench_function(format!("search4541_top10_{m:?}"), |b| {
            b.iter(|| db.search(black_box(&d.r), 10, 0, m).unwrap())
        });
    }
    g.finish();
}

/// The plans of the summary, in column order; the last is `Auto` with the detector's bound.
const COLUMNS: [(Plan, bool); 5] = [
    (Plan::Brute, false),
    (Plan::KdTree, false),
    (Plan::Sketch, false),
    (Plan::Auto, false),
    (Plan::Auto, true),
];

/// Per column: the mean and the largest seconds per query over the mix; checks every plan's
/// results against brute force's (cut at the bound).
fn time_mix(index: &Index<'_>, queries: &[f32], k: usize) -> [(f64, f64); COLUMNS.len()] {
    let n = index.len();
    let reps = if n >= 100_000 { 3 } else { 9 };
    let mut sum = [0.0f64; COLUMNS.len()];
    let mut max = [0.0f64; COLUMNS.len()];
    let mut outs = vec![vec![Neighbor::default(); k]; COLUMNS.len()];
    let mut lens = [0usize; COLUMNS.len()];
    // What auto learns over the mix, as a Database keeps it (one per column: the bounded one
    // sees other outcomes).
    let observed: [Observed; COLUMNS.len()] = core::array::from_fn(|_| Observed::timed());
    for (qi, q) in queries.chunks_exact(DIM).enumerate() {
        // Rotate the order of the plans from query to query, so that none always runs first.
        for step in 0..COLUMNS.len() {
            let col = (qi + step) % COLUMNS.len();
            let (plan, bounded) = COLUMNS[col];
            let req = Request {
                k,
                max_distance: if bounded {
                    DETECTOR_BOUND
                } else {
                    f32::INFINITY
                },
                plan,
                observed: Some(&observed[col]),
                ..Request::nearest(k)
            };
            let mut times = [0.0f64; 9];
            for t in times.iter_mut().take(reps) {
                let start = Instant::now();
                lens[col] = black_box(index.search(q, &req, &mut outs[col]).unwrap()).len;
                *t = start.elapsed().as_secs_f64();
            }
            times[..reps].sort_by(f64::total_cmp);
            let t = times[reps / 2];
            sum[col] += t;
            max[col] = max[col].max(t);
        }
        let brute = &outs[0][..lens[0]];
        for col in 1..COLUMNS.len() {
            let want: Vec<Neighbor> = if COLUMNS[col].1 {
                brute
                    .iter()
                    .copied()
                    .filter(|nb| nb.distance <= DETECTOR_BOUND)
                    .collect()
            } else {
                brute.to_vec()
            };
            assert_eq!(
                &outs[col][..lens[col]],
                &want[..],
                "{:?} differs",
                COLUMNS[col]
            );
        }
    }
    let m = (queries.len() / DIM) as f64;
    core::array::from_fn(|c| (sum[c] / m, max[c]))
}

fn summary(dbs: &[Db]) {
    println!(
        "\nsummary (same run, plans interleaved query by query; mean µs per query over {QUERIES} \
         queries; auto/bf < 1: auto is faster than brute force; auto max: slowest auto query; \
         auto≤{DETECTOR_BOUND}: auto returning only neighbours within the detector's bound)"
    );
    println!(
        "{:<10} {:>9} {:>3} {:>10} {:>10} {:>10} {:>10} {:>8} {:>10} {:>10}",
        "db/mix", "n", "k", "brute", "kdtree", "sketch", "auto", "auto/bf", "auto max", "auto≤0.03"
    );
    for db in dbs {
        let index = db.index();
        for (mix, queries) in &db.mixes {
            for k in [1, 10] {
                let t = time_mix(&index, queries, k);
                let us = |c: usize| t[c].0 * 1e6;
                println!(
                    "{:<10} {:>9} {:>3} {:>10.1} {:>10.1} {:>10.1} {:>10.1} {:>8.2} {:>10.1} {:>10.1}",
                    format!("{}/{mix}", db.name),
                    db.len(),
                    k,
                    us(0),
                    us(1),
                    us(2),
                    us(3),
                    t[3].0 / t[0].0,
                    t[3].1 * 1e6,
                    us(4),
                );
            }
        }
    }
    let n = 1_000_000;
    let (nc, np) = sketch_len(n, DIM);
    println!(
        "\nindex bytes per entry beside the f32 rows ({} B): kd-tree {} B, sketch {} B",
        DIM * 4,
        4 + 2,
        (nc + 4 * np) / n
    );
}

fn main() {
    let scans = scans();
    let dbs = databases(&scans);
    if std::env::var_os("SOLID_BENCH_SUMMARY").is_none() {
        let mut c = Criterion::default().configure_from_args();
        bench_queries(&mut c, &dbs);
        bench_build(&mut c, &dbs);
        bench_loop_step(&mut c);
        c.final_summary();
    }
    summary(&dbs);
}
