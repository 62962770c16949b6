//! Describes one KITTI frame many times: a fixed workload for `valgrind --tool=callgrind`
//! (instruction counts are repeatable on a loaded machine, unlike wall-clock time), and the
//! minimum and median time of a call.
//!
//! `cargo run --release -p solid-lidar-benches --example describe_loop -- [ITERATIONS] [VOXEL] [COPIES]`
//!
//! With COPIES > 1 the calls go through that many copies of the frame in turn, so that each call
//! reads a scan that is not in the CPU's caches, as in a batch (100 copies take 200 MB).

use solid_lidar::{describe, describe_scratch_len, Config, Points};
use solid_lidar_benches::kitti;
use std::time::Instant;

fn main() {
    let mut args = std::env::args().skip(1);
    let iters: usize = args.next().map_or(50, |a| a.parse().expect("ITERATIONS"));
    let voxel: f64 = args.next().map_or(0.5, |a| a.parse().expect("VOXEL"));
    let copies: usize = args.next().map_or(1, |a| a.parse().expect("COPIES"));
    let raw = kitti("kitti00/velodyne/000000.bin");
    let frames = vec![raw; copies.max(1)];
    let cfg = Config {
        voxel_size: voxel,
        ..Config::preset("hdl64").unwrap()
    };
    let mut scratch = vec![0u64; describe_scratch_len(frames[0].len() / 4, &cfg)];
    let (mut r, mut a) = (vec![0f32; 40], vec![0f32; 60]);
    let mut kept = 0;
    let mut ms = Vec::with_capacity(iters);
    for frame in frames.iter().cycle().take(iters) {
        let t = Instant::now();
        kept += describe(
            Points::new(frame, 4).unwrap(),
            &cfg,
            &mut scratch,
            &mut r,
            &mut a,
        )
        .unwrap()
        .n_kept;
        ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    ms.sort_by(f64::total_cmp);
    println!("{kept} {}", r.iter().sum::<f32>());
    if let (Some(min), Some(median)) = (ms.first(), ms.get(iters / 2)) {
        println!("describe: min {min:.3} ms, median {median:.3} ms over {iters} calls");
    }
}
