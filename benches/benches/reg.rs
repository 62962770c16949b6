//! Registration on simulated HDL-64E scans (the loop verification that dominates a verifying
//! detector's time): preparing a cloud (voxel levels, kd-trees, covariances), one registration,
//! three yaw hypotheses as the detector runs them, and the kd-tree's nearest-point queries alone
//! (every fine point of one place against the other's tree).

use criterion::{criterion_group, criterion_main, Criterion};
use solid_lidar::reg::{
    register, register_hypotheses, Hypothesis, PreparedCloud, RegConfig, IDENTITY,
};
use solid_lidar::Points;
use solid_lidar_sim::{Sensor, Trajectory, World, WorldConfig};
use std::hint::black_box;

/// Two places 2 m apart on the default world's loop, as prepared clouds, and the raw points of
/// the first.
fn places(cfg: &RegConfig) -> (Vec<f32>, PreparedCloud, PreparedCloud) {
    let world = World::new(WorldConfig::default()).unwrap();
    let traj = Trajectory::closed_loop(&world, 1, 1, 1.0, &Default::default()).unwrap();
    let sensor = Sensor::preset("hdl64").unwrap();
    let scan = |k: usize| -> Vec<f32> {
        let pts = sensor.scan(&world, &traj.poses[k], k as u64).unwrap();
        pts.iter().flat_map(|p| [p[0], p[1], p[2]]).collect()
    };
    let (a, b) = (scan(40), scan(42));
    let prep = |xyz: &[f32]| PreparedCloud::new(Points::new(xyz, 3).unwrap(), cfg).unwrap();
    let (qa, qb) = (prep(&a), prep(&b));
    (a, qa, qb)
}

fn bench(c: &mut Criterion) {
    let cfg = RegConfig::default();
    let (raw, query, candidate) = places(&cfg);
    let mut g = c.benchmark_group("reg");
    g.sample_size(20);
    g.bench_function("prepare", |b| {
        b.iter(|| PreparedCloud::new(Points::new(black_box(&raw), 3).unwrap(), &cfg).unwrap())
    });
    g.bench_function("register", |b| {
        b.iter(|| register(&query, &candidate, black_box(&IDENTITY), &cfg).unwrap())
    });
    let yaws = [0.0, 25.0, -25.0];
    let mut out = [Hypothesis::default(); 3];
    g.bench_function("register_hypotheses_3", |b| {
        b.iter(|| {
            register_hypotheses(
                &query,
                &candidate,
                black_box(&yaws),
                &IDENTITY,
                &cfg,
                &mut out,
            )
            .unwrap()
            .best
        })
    });
    let tree = candidate.fine.tree();
    let max_d2 = cfg.max_correspondence * cfg.max_correspondence;
    g.bench_function("nearest_fine", |b| {
        b.iter(|| {
            let mut found = 0usize;
            for p in &query.fine.points {
                found += usize::from(tree.nearest(black_box(*p), max_d2).is_some());
            }
            found
        })
    });
    g.finish();
    println!(
        "fine points: query {}, candidate {}; coarse: {}, {}",
        query.fine.len(),
        candidate.fine.len(),
        query.coarse.as_ref().map_or(0, |l| l.len()),
        candidate.coarse.as_ref().map_or(0, |l| l.len())
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
