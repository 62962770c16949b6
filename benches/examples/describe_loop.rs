//! Describes one KITTI frame many times: a fixed workload for `valgrind --tool=callgrind`
//! (instruction counts are repeatable on a loaded machine, unlike wall-clock time).
//!
//! `cargo run --release -p solid-lidar-benches --example describe_loop -- [ITERATIONS] [VOXEL]`

use solid_lidar::{describe, describe_scratch_len, Config, Points};
use solid_lidar_benches::kitti;

fn main() {
    let mut args = std::env::args().skip(1);
    let iters: usize = args.next().map_or(50, |a| a.parse().expect("ITERATIONS"));
    let voxel: f64 = args.next().map_or(0.5, |a| a.parse().expect("VOXEL"));
    let raw = kitti("kitti00/velodyne/000000.bin");
    let cfg = Config {
        voxel_size: voxel,
        ..Config::preset("hdl64").unwrap()
    };
    let mut scratch = vec![0u64; describe_scratch_len(raw.len() / 4, &cfg)];
    let (mut r, mut a) = (vec![0f32; 40], vec![0f32; 60]);
    let mut kept = 0;
    for _ in 0..iters {
        kept += describe(
            Points::new(&raw, 4).unwrap(),
            &cfg,
            &mut scratch,
            &mut r,
            &mut a,
        )
        .unwrap()
        .n_kept;
    }
    println!("{kept} {}", r.iter().sum::<f32>());
}
