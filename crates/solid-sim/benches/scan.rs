//! Scan simulation time per sensor model, with a brute-force baseline (every primitive tested)
//! measured in the same run on a subsample of the rays.
use criterion::{criterion_group, criterion_main, Criterion};
use solid_lidar_sim::{Sensor, Trajectory, World, WorldConfig, SENSOR_PRESETS};
use std::hint::black_box;
use std::time::Instant;

fn bench(c: &mut Criterion) {
    let world = World::new(WorldConfig::default()).unwrap();
    let traj = Trajectory::closed_loop(&world, 1, 1, 1.0, &Default::default()).unwrap();
    let pose = traj.poses[40];
    let mut group = c.benchmark_group("scan");
    group.sample_size(20);
    for name in SENSOR_PRESETS {
        let sensor = Sensor::preset(name).unwrap();
        group.bench_function(name, |b| {
            b.iter(|| black_box(sensor.scan(&world, &pose, 0).unwrap().len()))
        });
    }
    group.finish();

    // Grid versus brute force on the HDL-64E rays (every 50th ray for the brute force).
    let sensor = Sensor::preset("hdl64").unwrap();
    let dirs = sensor.ray_directions(0);
    let o = pose.translation();
    let t0 = Instant::now();
    let mut n = 0usize;
    for d in &dirs {
        n += usize::from(world.cast(o, pose.rotate(*d), 120.0).is_some());
    }
    let grid_s = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let mut m = 0usize;
    for d in dirs.iter().step_by(50) {
        m += usize::from(world.cast_brute_force(o, pose.rotate(*d), 120.0).is_some());
    }
    let brute_s = t0.elapsed().as_secs_f64() * 50.0;
    println!(
        "hdl64 {} rays ({} hits, {} primitives): grid {:.1} ms, brute force (extrapolated) {:.0} ms, speed-up {:.0}x ({} hits on the subsample)",
        dirs.len(),
        n,
        world.primitives().len(),
        grid_s * 1e3,
        brute_s * 1e3,
        brute_s / grid_s,
        m
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
