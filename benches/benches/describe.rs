//! Describe benchmarks on the full KITTI frame 000000 (124,668 points, hdl64, voxel 0.5) and its
//! 60° clip: each stage alone and the whole pipeline.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use solid_lidar::{
    cosine_distance, describe, describe_scratch_len, heading_refined, Config, Points,
};
use solid_lidar_benches::kitti;
use std::hint::black_box;

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
        g.bench_function("bin_and_accumulate", |b| {
            b.iter(|| {
                describe(
                    Points::new(black_box(cent), 3).unwrap(),
                    &flat,
                    &mut scratch,
                    &mut r,
                    &mut a,
                )
                .unwrap()
            })
        });
        g.bench_function("describe_voxel0.5", |b| {
            b.iter(|| {
                describe(
                    Points::new(black_box(&raw), 4).unwrap(),
                    &cfg,
                    &mut scratch,
                    &mut r,
                    &mut a,
                )
                .unwrap()
            })
        });
        g.bench_function("describe_no_voxel", |b| {
            b.iter(|| {
                describe(
                    Points::new(black_box(&raw), 4).unwrap(),
                    &flat,
                    &mut scratch,
                    &mut r,
                    &mut a,
                )
                .unwrap()
            })
        });
        g.finish();
    }
    let raw0 = kitti("kitti00/velodyne/000000.bin");
    let raw1 = kitti("kitti00/velodyne/000094.bin");
    let n = raw0.len().max(raw1.len()) / 4;
    let mut scratch = vec![0u64; describe_scratch_len(n, &cfg)];
    let (mut r0, mut a0, mut r1, mut a1) = (
        vec![0f32; 40],
        vec![0f32; 60],
        vec![0f32; 40],
        vec![0f32; 60],
    );
    describe(
        Points::new(&raw0, 4).unwrap(),
        &cfg,
        &mut scratch,
        &mut r0,
        &mut a0,
    )
    .unwrap();
    describe(
        Points::new(&raw1, 4).unwrap(),
        &cfg,
        &mut scratch,
        &mut r1,
        &mut a1,
    )
    .unwrap();
    c.bench_function("compare/distance", |b| {
        b.iter(|| cosine_distance(black_box(&r0), black_box(&r1)).unwrap())
    });
    c.bench_function("compare/heading_refined", |b| {
        b.iter(|| heading_refined(black_box(&a0), black_box(&a1)).unwrap())
    });
}

criterion_group!(benches, bench_describe);
criterion_main!(benches);
