//! Maps at scale (issue 31): file bytes per place, load time (wall and CPU), resident memory after
//! the load and what a verifying detector over the map adds to it, `map info`
//! (`Database::summary`) and the verified step, for maps of real places in the current file format
//! (4) and the previous one (3, up to 100k).
//!
//! The places are the 314 HKU Livox Avia keyframes (`avia` preset), described with their compact
//! clouds by a verifying detector, copied with 2 % multiplicative noise on every descriptor bin,
//! a pose and a time per place, 314 places a session: the construction of `tools/map_scale.py`,
//! whose files (`base.soliddb`, `map{n}.v4.soliddb`) this reuses when it finds them. Maps are built
//! once under `SOLID_BENCH_MAP_DIR` (default `target/solid-bench-data/maps`; a 1M map is ~5.6 GB
//! with its clouds) a chunk of 100k places at a time, so their clouds are never all in memory.
//!
//! Every figure of the summary is taken in a fresh process (this benchmark run again as a child):
//! memory is the process's resident set (`VmRSS`): after the load, then what a detector over the
//! map adds in total after its first 20 steps: the map's search index, which a loaded map leaves
//! to its first search or detector (the detector builds it when made: also given alone), and the
//! detector's working memory; the verified step is the median wall time of a full step
//! (describe, prepare the cloud, search, verify the best candidates, add) for 20 hku1 scans,
//! which meet their own copies in the map. `SOLID_BENCH_MAP_CHILD=measure:FILE` prints one
//! process's figures, `search:FILE` the searches of the map with and without the sketch.
//!
//! `SOLID_BENCH_MAP_SIZES` (default `1000,10000,100000`; add `1000000` for the 1M map),
//! `SOLID_BENCH_JSON=path` writes the summary as JSON (`make readme-speed`: the README's row).
//! Criterion times the load and `map info` of the 10k map in both formats.

use criterion::Criterion;
use solid_lidar::db::{Database, DetectorConfig, LoopDetector};
use solid_lidar::{Config, Descriptor, Points, Stats};
use solid_lidar_benches::{read_xyz, shared_dir, Rng};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Places of the base session (hku1-avia's keyframes).
const BASE: usize = 314;
/// Places built in memory at a time.
const CHUNK: usize = 100_000;
/// The previous format (3) is measured up to this size.
const PREVIOUS_UP_TO: usize = 100_000;

fn map_dir() -> PathBuf {
    std::env::var_os("SOLID_BENCH_MAP_DIR").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/solid-bench-data/maps"),
        PathBuf::from,
    )
}

fn scan(i: usize) -> Vec<f32> {
    read_xyz(&shared_dir().join(format!("data/hku1-avia/Scans/{i:06}.pcd")))
}

fn detector_config() -> DetectorConfig {
    DetectorConfig::for_preset("avia").expect("the avia preset")
}

/// The 314 keyframes described with their compact clouds (cached in `dir`).
fn base(dir: &Path) -> Database {
    let path = dir.join("base.soliddb");
    if let Ok(db) = Database::load(&path) {
        return db;
    }
    let cfg = Config::preset("avia").expect("the avia preset");
    let mut dc = detector_config();
    dc.exclude_frames = BASE;
    let mut det = LoopDetector::new(cfg, dc).expect("a detector");
    for i in 0..BASE {
        let xyz = scan(i);
        let s = det.prepare_scan(Points::new(&xyz, 3).expect("points"));
        det.detect_scan(s.expect("a scan"), f64::NAN, None)
            .expect("a step");
    }
    let db = det.into_database().expect("the places");
    db.save(&path).expect("saved");
    db
}

/// A map of `n` noisy copies of `base`'s places, each with its place's cloud, at `path`.
fn build(base: &Database, n: usize, path: &Path) {
    let cfg = *base.config();
    let mut rng = Rng(n as u64);
    let mut whole = Database::new(cfg).expect("a database");
    let mut parts = Vec::new();
    let noisy = |v: &[f32], rng: &mut Rng| -> Vec<f32> {
        v.iter()
            .map(|&x| (f64::from(x) * (1.0 + 0.02 * rng.normal())).max(0.0) as f32)
            .collect()
    };
    for start in (0..n).step_by(CHUNK) {
        let mut db = Database::new(cfg).expect("a database");
        for j in start..n.min(start + CHUNK) {
            let i = (j % BASE) as u32;
            let d = Descriptor {
                r: noisy(base.r(i), &mut rng),
                a: noisy(&base.a(i), &mut rng),
                stats: Stats::default(),
                fingerprint: cfg.fingerprint(),
            };
            let mut pose = [0.0; 12];
            (pose[0], pose[5], pose[10]) = (1.0, 1.0, 1.0);
            (pose[3], pose[7]) = (j as f64, (j / BASE) as f64);
            let cloud = base.cloud(i).expect("a readable cloud");
            let session = (j / BASE) as u32;
            db.add_with_cloud(&d, session, 0.1 * j as f64, Some(pose), cloud.as_deref())
                .expect("a place");
        }
        let part = path.with_extension(format!("part{start}"));
        db.save(&part).expect("saved");
        drop(db);
        whole
            .merge(&Database::load(&part).expect("loaded"))
            .expect("merged");
        parts.push(part);
    }
    whole.save(path).expect("saved");
    for p in parts {
        std::fs::remove_file(p).ok();
    }
}

fn rss_mib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

/// CPU time this process has used so far, every thread's, user and system (seconds; the kernel
/// counts it in ticks of 10 ms).
fn cpu_s() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // The fields after the command's closing parenthesis: utime and stime are the 12th and 13th.
    let fields: Vec<&str> = stat
        .rsplit_once(')')
        .map_or("", |(_, rest)| rest)
        .split_whitespace()
        .collect();
    let ticks = |i: usize| fields.get(i).and_then(|v| v.parse::<f64>().ok());
    match (ticks(11), ticks(12)) {
        (Some(u), Some(s)) => (u + s) / 100.0,
        _ => f64::NAN,
    }
}

/// In this (fresh) process: load, detector (which builds the map's index), verified steps; as
/// one JSON line.
fn child_measure(path: &str) {
    let queries: Vec<Vec<f32>> = (0..BASE).step_by(16).take(20).map(scan).collect();
    let before = rss_mib();
    let (t0, cpu0) = (Instant::now(), cpu_s());
    let db = Database::load(path).expect("loaded");
    let (load_s, load_cpu_s) = (t0.elapsed().as_secs_f64(), cpu_s() - cpu0);
    let after_load = rss_mib();
    let t0 = Instant::now();
    let mut det = LoopDetector::with_database(db, detector_config()).expect("a detector");
    let detector_s = t0.elapsed().as_secs_f64();
    let after_det = rss_mib();
    let mut steps: Vec<f64> = queries
        .iter()
        .map(|q| {
            let t0 = Instant::now();
            let s = det.prepare_scan(Points::new(q, 3).expect("points"));
            det.detect_scan(s.expect("a scan"), f64::NAN, None)
                .expect("a step");
            t0.elapsed().as_secs_f64()
        })
        .collect();
    steps.sort_by(f64::total_cmp);
    let step_ms = 1e3 * (steps[steps.len() / 2 - 1] + steps[steps.len() / 2]) / 2.0;
    let after_steps = rss_mib();
    println!(
        "{{\"load_s\": {load_s}, \"load_cpu_s\": {load_cpu_s}, \"rss_load_mib\": {}, \"detector_s\": {detector_s}, \"rss_index_mib\": {}, \"rss_steps_mib\": {}, \"rss_detector_mib\": {}, \"step_ms\": {step_ms}}}",
        after_load - before,
        after_det - after_load,
        after_steps - after_det,
        after_steps - after_load
    );
}

/// In this (fresh) process: the median time of a search (k = 10, as a detector's) of the map as
/// loaded (its index the kd-tree alone), then with the sketch, for 20 of the places the map
/// holds (hku1's keyframes, of which it holds noisy copies) and 20 it does not (the sums of two
/// keyframes' R-SOLiDs), with `auto` and with brute force; as one JSON line.
fn child_search(path: &str) {
    use solid_lidar::db::{Method, SearchOptions};
    let base = Database::load(Path::new(path).with_file_name("base.soliddb")).expect("loaded");
    let held: Vec<Vec<f32>> = (0..BASE)
        .step_by(16)
        .map(|i| base.r(i as u32).to_vec())
        .collect();
    let other: Vec<Vec<f32>> = (0..BASE)
        .step_by(16)
        .map(|i| {
            let far = base.r(((i + BASE / 2) % BASE) as u32);
            base.r(i as u32)
                .iter()
                .zip(far)
                .map(|(x, y)| x + y)
                .collect()
        })
        .collect();
    let mut db = Database::load(path).expect("loaded");
    let median_ms = |db: &Database, queries: &[Vec<f32>], method| {
        let opts = SearchOptions {
            k: 10,
            method,
            ..SearchOptions::default()
        };
        let mut ms: Vec<f64> = queries
            .iter()
            .map(|q| {
                let t0 = Instant::now();
                db.search_with(q, &opts).expect("a search");
                1e3 * t0.elapsed().as_secs_f64()
            })
            .collect();
        ms.sort_by(f64::total_cmp);
        ms[ms.len() / 2]
    };
    let (mut fields, loaded) = (Vec::new(), db.memory_bytes());
    for sketch in [false, true] {
        db.set_sketch(sketch);
        let t0 = Instant::now();
        db.build_index().expect("the index");
        let name = if sketch { "sketch" } else { "tree" };
        fields.push(format!(
            "\"{name}_build_s\": {}",
            t0.elapsed().as_secs_f64()
        ));
        let index = (db.memory_bytes() - loaded) as f64 / 1048576.0;
        fields.push(format!("\"{name}_index_mib\": {index}"));
        for (what, queries) in [("held", &held), ("other", &other)] {
            let ms = median_ms(&db, queries, Method::Auto);
            fields.push(format!("\"{name}_{what}_ms\": {ms}"));
        }
    }
    for (what, queries) in [("held", &held), ("other", &other)] {
        let ms = median_ms(&db, queries, Method::Brute);
        fields.push(format!("\"brute_{what}_ms\": {ms}"));
    }
    println!("{{{}}}", fields.join(", "));
}

fn child_info(path: &str) {
    let t0 = Instant::now();
    Database::summary(path).expect("a summary");
    println!("{{\"info_s\": {}}}", t0.elapsed().as_secs_f64());
}

/// This benchmark run again with `what` and `path`: the JSON line it printed.
fn in_child(what: &str, path: &Path) -> String {
    let exe = std::env::current_exe().expect("this benchmark");
    let out = Command::new(exe)
        .env(
            "SOLID_BENCH_MAP_CHILD",
            format!("{what}:{}", path.display()),
        )
        .output()
        .expect("a child");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    text.lines().last().unwrap_or_default().to_owned()
}

fn field(json: &str, key: &str) -> f64 {
    let at = json.find(&format!("\"{key}\": ")).expect("a field") + key.len() + 4;
    let end = json[at..].find([',', '}']).expect("a value") + at;
    json[at..end].trim().parse().expect("a number")
}

/// One measured file.
struct Row {
    places: usize,
    version: u32,
    file_bytes: u64,
    cloud_bytes: u64,
    measured: String,
    info_s: f64,
}

fn summary(files: &[(usize, u32, PathBuf)]) -> Vec<Row> {
    println!("| places | format | file bytes / place | beside clouds | load (CPU) | RSS after load | + a detector | of which its index | verified step | map info |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut rows = Vec::new();
    for (places, version, path) in files {
        let s = Database::summary(path).expect("a summary");
        let file_bytes = std::fs::metadata(path).expect("a file").len();
        let measured = in_child("measure", path);
        let info_s = field(&in_child("info", path), "info_s");
        let r = Row {
            places: *places,
            version: *version,
            file_bytes,
            cloud_bytes: s.cloud_bytes,
            measured,
            info_s,
        };
        println!(
            "| {} | {} | {:.0} | {:.0} | {:.2} s ({:.2} s) | {:.0} MiB | {:.1} MiB | {:.1} MiB in {:.2} s | {:.0} ms | {:.1} ms |",
            r.places,
            r.version,
            r.file_bytes as f64 / r.places as f64,
            (r.file_bytes - r.cloud_bytes) as f64 / r.places as f64,
            field(&r.measured, "load_s"),
            field(&r.measured, "load_cpu_s"),
            field(&r.measured, "rss_load_mib"),
            field(&r.measured, "rss_detector_mib"),
            field(&r.measured, "rss_index_mib"),
            field(&r.measured, "detector_s"),
            field(&r.measured, "step_ms"),
            r.info_s * 1e3
        );
        rows.push(r);
    }
    rows
}

fn write_json(path: &str, rows: &[Row]) {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .unwrap_or_default()
        .lines()
        .find_map(|l| {
            l.strip_prefix("model name")
                .map(|v| v.trim_start_matches([' ', '\t', ':']).to_owned())
        })
        .unwrap_or_default();
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let body: Vec<String> = rows
        .iter()
        .map(|r| {
            format!(
                "    {{\"places\": {}, \"version\": {}, \"file_bytes\": {}, \"cloud_bytes\": {}, \"info_s\": {}, \"measured\": {}}}",
                r.places, r.version, r.file_bytes, r.cloud_bytes, r.info_s, r.measured
            )
        })
        .collect();
    let doc = format!(
        "{{\n  \"command\": \"cargo bench -p solid-lidar-benches --bench maps\",\n  \"solid\": \"{}\",\n  \"cpu\": \"{cpu}\",\n  \"cores\": {cores},\n  \"maps\": [\n{}\n  ]\n}}\n",
        env!("CARGO_PKG_VERSION"),
        body.join(",\n")
    );
    std::fs::write(path, doc).expect("the JSON written");
}

fn main() {
    if let Some(job) = std::env::var_os("SOLID_BENCH_MAP_CHILD") {
        let job = job.to_string_lossy().into_owned();
        match job.split_once(':') {
            Some(("measure", path)) => child_measure(path),
            Some(("info", path)) => child_info(path),
            Some(("search", path)) => child_search(path),
            _ => panic!("unknown child job {job}"),
        }
        return;
    }
    let sizes: Vec<usize> = std::env::var("SOLID_BENCH_MAP_SIZES")
        .unwrap_or_else(|_| String::from("1000,10000,100000"))
        .split(',')
        .map(|s| s.trim().parse().expect("a size"))
        .collect();
    let dir = map_dir();
    std::fs::create_dir_all(&dir).expect("the map folder");
    let base = base(&dir);
    let mut files = Vec::new();
    for &n in &sizes {
        let v4 = dir.join(format!("map{n}.v4.soliddb"));
        if !v4.exists() {
            build(&base, n, &v4);
        }
        files.push((n, 4, v4.clone()));
        if n <= PREVIOUS_UP_TO {
            let v3 = dir.join(format!("map{n}.v3.soliddb"));
            if !v3.exists() {
                let db = Database::load(&v4).expect("loaded");
                db.save_version(&v3, 3).expect("saved");
            }
            files.push((n, 3, v3));
        }
    }
    let mut c = Criterion::default().configure_from_args().sample_size(10);
    for (n, version, path) in files.iter().filter(|f| f.0 == 10_000) {
        c.bench_function(&format!("load a {n}-place map, format {version}"), |b| {
            b.iter(|| Database::load(path).expect("loaded"));
        });
        c.bench_function(
            &format!("map info of a {n}-place map, format {version}"),
            |b| {
                b.iter(|| Database::summary(path).expect("a summary"));
            },
        );
    }
    c.final_summary();
    let rows = summary(&files);
    if let Ok(path) = std::env::var("SOLID_BENCH_JSON") {
        write_json(&path, &rows);
    }
}
