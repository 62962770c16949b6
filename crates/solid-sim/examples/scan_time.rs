//! Prints the time to simulate one frame per sensor preset (median of repeated runs, one core).
//!
//! `cargo run --release -p solid-lidar-sim --example scan_time`
use solid_lidar_sim::{Sensor, Trajectory, World, WorldConfig, SENSOR_PRESETS};
use std::time::Instant;

fn main() {
    let t0 = Instant::now();
    let world = World::new(WorldConfig::default()).unwrap();
    println!(
        "world: {} primitives, generated in {:.1} ms",
        world.primitives().len(),
        t0.elapsed().as_secs_f64() * 1e3
    );
    let traj = Trajectory::closed_loop(&world, 1, 1, 1.0, &Default::default()).unwrap();
    for name in SENSOR_PRESETS {
        let sensor = Sensor::preset(name).unwrap();
        let rays = sensor.ray_directions(0).len();
        let mut times = Vec::new();
        let mut points = 0;
        for (i, pose) in traj.poses.iter().step_by(15).enumerate() {
            let t = Instant::now();
            points = sensor.scan(&world, pose, i as u64).unwrap().len();
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{name:7} {rays:7} rays, {points:7} points: median {:.1} ms, max {:.1} ms over {} poses",
            times[times.len() / 2],
            times[times.len() - 1],
            times.len()
        );
    }
}
