//! Describe benchmarks on the full KITTI frame 000000 (124,668 points, hdl64, voxel 0.5) and its
//! 60° clip: each stage alone and the whole pipeline.
//!
//! After criterion, a summary times `describe` and a plain Rust implementation of SPEC §2 (the
//! obvious code: a `HashMap` voxel grid, `f64::atan2`) in the same run, checks that both give the
//! same descriptor and prints the median milliseconds and their ratio: on frame 000000 over and
//! over (in cache, as criterion times it), on its 60° clip, and on the five shared KITTI frames
//! in turn (out of cache, as in a batch).

use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, Criterion, Throughput};
use solid_lidar::{
    cosine_distance, describe, describe_scratch_len, heading_refined, Config, Coord, Points,
    Scratch,
};
use solid_lidar_benches::kitti;
use std::collections::HashMap;
use std::hint::black_box;
use std::time::Instant;

fn bench_describe(c: &mut Criterion) {
    let cfg = Config::preset("hdl64").unwrap();
    let flat = Config {
        voxel_size: 0.0,
        ..cfg
    };
    for (name, rel) in [
        ("kitti_full", "kitti00/velodyne/000000.bin"),
        ("kitti_60deg", "solid-samples/kitti_00_60/000000.bin"),
    ] {
        let raw = kitti(rel);
        let n = raw.len() / 4;
        let mut g = c.benchmark_group(name);
        g.throughput(Throughput::Elements(n as u64));
        let mut scratch =
            vec![0u64; describe_scratch_len(n, &flat).max(describe_scratch_len(n, &cfg))];
        let (mut r, mut a) = (vec![0f32; 40], vec![0f32; 60]);
        g.bench_function("range_filter", |b| {
            b.iter(|| {
                solid_lidar::stages::count_in_range(black_box(Points::new(&raw, 4).unwrap()), &cfg)
            })
        });
        let mut cent = vec![0f64; 3 * n];
        g.bench_function("voxel_downsample", |b| {
            b.iter(|| {
                solid_lidar::stages::voxel_downsample(
                    Points::new(black_box(&raw), 4).unwrap(),
                    &cfg,
                    &mut scratch,
                    &mut cent,
                )
                .unwrap()
            })
        });
        let (_, m) = solid_lidar::stages::voxel_downsample(
            Points::new(&raw, 4).unwrap(),
            &cfg,
            &mut scratch,
            &mut cent,
        )
        .unwrap();
        let cent = &cent[..3 * m];
        let mut out = (&mut scratch[..], &mut r[..], &mut a[..]);
        bench_on(&mut g, "bin_and_accumulate", cent, 3, &flat, &mut out);
        bench_on(&mut g, "describe_voxel0.5", &raw, 4, &cfg, &mut out);
        bench_on(&mut g, "describe_no_voxel", &raw, 4, &flat, &mut out);
        g.finish();
    }
    let raw0 = kitti("kitti00/velodyne/000000.bin");
    let raw1 = kitti("kitti00/velodyne/000094.bin");
    let n = raw0.len().max(raw1.len()) / 4;
    let mut scratch = vec![0u64; describe_scratch_len(n, &cfg)];
    let mut described = |raw: &[f32]| {
        let (mut r, mut a) = (vec![0f32; 40], vec![0f32; 60]);
        describe(
            Points::new(raw, 4).unwrap(),
            &cfg,
            &mut scratch,
            &mut r,
            &mut a,
        )
        .unwrap();
        (r, a)
    };
    let ((r0, a0), (r1, a1)) = (described(&raw0), described(&raw1));
    c.bench_function("compare/distance", |b| {
        b.iter(|| cosine_distance(black_box(&r0), black_box(&r1)).unwrap())
    });
    c.bench_function("compare/heading_refined", |b| {
        b.iter(|| heading_refined(black_box(&a0), black_box(&a1)).unwrap())
    });
}

/// Times `describe` of `data` (points of `stride` values) under `cfg` as `name`, into `out`
/// (scratch, R, A).
fn bench_on<T: Coord>(
    g: &mut BenchmarkGroup<'_, WallTime>,
    name: &str,
    data: &[T],
    stride: usize,
    cfg: &Config,
    out: &mut (&mut [Scratch], &mut [f32], &mut [f32]),
) {
    let (scratch, r, a) = out;
    g.bench_function(name, |b| {
        b.iter(|| {
            describe(
                Points::new(black_box(data), stride).unwrap(),
                cfg,
                scratch,
                r,
                a,
            )
            .unwrap()
        })
    });
}

/// SPEC §2 written the obvious way, as a baseline: a `HashMap` from voxel index to sums, then
/// `f64::atan2` and `floor` per centroid. Returns (R-SOLiD, A-SOLiD, points binned).
fn plain_describe(xyz4: &[f32], c: &Config) -> (Vec<f64>, Vec<f64>, usize) {
    let mut voxels: HashMap<[i64; 3], [f64; 4]> = HashMap::new();
    for p in xyz4.chunks_exact(4) {
        let [x, y, z] = [p[0], p[1], p[2]].map(f64::from);
        let d = (x * x + y * y + z * z).sqrt();
        if !(d > c.min_range && d < c.max_range) {
            continue;
        }
        let key = [x, y, z].map(|v| (v / c.voxel_size).floor() as i64);
        let s = voxels.entry(key).or_insert([0.0; 4]);
        *s = [s[0] + x, s[1] + y, s[2] + z, s[3] + 1.0];
    }
    let (nr, na, ne) = (c.n_range, c.n_azimuth, c.n_elevation);
    let mut rec = vec![0u32; nr * ne];
    let mut aec = vec![0u32; na * ne];
    for s in voxels.values() {
        let [x, y, z] = [s[0] / s[3], s[1] / s[3], s[2] / s[3]];
        let r = x.hypot(y);
        let theta = y.atan2(x).to_degrees().rem_euclid(360.0);
        let phi = z.atan2(r).to_degrees();
        let i = ((r * nr as f64 / c.max_range).floor() as usize).min(nr - 1);
        let j = ((theta * na as f64 / 360.0).floor() as usize).min(na - 1);
        let k = ((phi - c.fov_down) * ne as f64 / (c.fov_up - c.fov_down))
            .floor()
            .clamp(0.0, (ne - 1) as f64) as usize;
        rec[i * ne + k] += 1;
        aec[j * ne + k] += 1;
    }
    let ec: Vec<f64> = (0..ne)
        .map(|k| (0..nr).map(|i| f64::from(rec[i * ne + k])).sum())
        .collect();
    let (lo, hi) = ec
        .iter()
        .fold((f64::MAX, f64::MIN), |(l, h), &e| (l.min(e), h.max(e)));
    let iev: Vec<f64> = ec
        .iter()
        .map(|&e| if hi > lo { (e - lo) / (hi - lo) } else { 1.0 })
        .collect();
    let dot = |row: &[u32]| -> f64 { row.iter().zip(&iev).map(|(&n, w)| f64::from(n) * w).sum() };
    let r_solid = rec.chunks_exact(ne).map(dot).collect();
    let a_solid = aec.chunks_exact(ne).map(dot).collect();
    (r_solid, a_solid, voxels.len())
}

/// Median seconds of `f` over `reps` calls (after one warm-up call).
fn median(reps: usize, mut f: impl FnMut()) -> f64 {
    f();
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[reps / 2]
}

fn summary() {
    let cfg = Config::preset("hdl64").unwrap();
    println!("\nsummary (same run, single thread, hdl64, voxel 0.5): median ms");
    println!(
        "{:<28} {:>9} {:>14} {:>9}",
        "scan", "solid", "plain Rust", "speed-up"
    );
    for (name, rel) in [
        ("KITTI 000000 (124,668 pts)", "kitti00/velodyne/000000.bin"),
        ("its 60° clip", "solid-samples/kitti_00_60/000000.bin"),
    ] {
        let raw = kitti(rel);
        let pts = || Points::new(black_box(&raw), 4).unwrap();
        let mut scratch = vec![0u64; describe_scratch_len(raw.len() / 4, &cfg)];
        let (mut r, mut a) = (vec![0f32; cfg.n_range], vec![0f32; cfg.n_azimuth]);
        let stats = describe(pts(), &cfg, &mut scratch, &mut r, &mut a).unwrap();
        // The same descriptor (SPEC §7 tolerance): the two time equal work.
        let (r_plain, a_plain, kept) = plain_describe(&raw, &cfg);
        assert_eq!(stats.n_kept, kept, "{name}");
        for (ours, plain) in [(&r, &r_plain), (&a, &a_plain)] {
            let err: f64 = ours
                .iter()
                .zip(plain.iter())
                .map(|(&o, p)| (f64::from(o) - p).abs())
                .sum();
            assert!(err <= 1e-3 * plain.iter().sum::<f64>(), "{name}: {err}");
        }
        let t_solid = median(400, || {
            describe(pts(), &cfg, &mut scratch, &mut r, &mut a).unwrap();
        });
        let t_plain = median(40, || {
            black_box(plain_describe(black_box(&raw), &cfg));
        });
        println!(
            "{name:<28} {:>9.3} {:>14.3} {:>8.1}x",
            t_solid * 1e3,
            t_plain * 1e3,
            t_plain / t_solid
        );
    }
    // The same frame over and over stays in cache; a batch of scans does not.
    let frames: Vec<Vec<f32>> = [0, 94, 95, 198, 199]
        .iter()
        .map(|f| kitti(&format!("kitti00/velodyne/{f:06}.bin")))
        .collect();
    let n = frames.iter().map(|f| f.len() / 4).max().unwrap();
    let mut scratch = vec![0u64; describe_scratch_len(n, &cfg)];
    let (mut r, mut a) = (vec![0f32; cfg.n_range], vec![0f32; cfg.n_azimuth]);
    let mut k = 0;
    let t_solid = median(400, || {
        k = (k + 1) % frames.len();
        let pts = Points::new(black_box(&frames[k]), 4).unwrap();
        describe(pts, &cfg, &mut scratch, &mut r, &mut a).unwrap();
    });
    let t_plain = median(40, || {
        k = (k + 1) % frames.len();
        black_box(plain_describe(black_box(&frames[k]), &cfg));
    });
    println!(
        "{:<28} {:>9.3} {:>14.3} {:>8.1}x",
        "5 KITTI frames in turn",
        t_solid * 1e3,
        t_plain * 1e3,
        t_plain / t_solid
    );
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    bench_describe(&mut c);
    c.final_summary();
    summary();
}
