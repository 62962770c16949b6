//! `describe`, `cosine_distance` and `heading` allocate nothing: a counting global allocator
//! sees zero allocations across calls on a real scan.

mod common;

use solid_lidar::{
    cosine_distance, describe, describe_scratch_len, heading, heading_refined, Config, Points,
};

#[global_allocator]
static GLOBAL: common::Counting = common::Counting;

#[test]
fn describe_distance_heading_allocate_nothing() {
    let Some(shared) = common::shared() else {
        return;
    };
    let raw = common::read_kitti(&shared.join("data/kitti00/velodyne/000000.bin"));
    let raw2 = common::read_kitti(&shared.join("data/kitti00/velodyne/000094.bin"));
    let n = raw.len().max(raw2.len()) / 4;
    for voxel in [0.5, 0.0] {
        let cfg = Config {
            voxel_size: voxel,
            ..Config::preset("hdl64").unwrap()
        };
        let mut scratch = vec![0u64; describe_scratch_len(n, &cfg)];
        let (mut r1, mut a1) = (vec![0f32; 40], vec![0f32; 60]);
        let (mut r2, mut a2) = (vec![0f32; 40], vec![0f32; 60]);
        let before = common::allocations();
        let mut total = 0.0;
        for _ in 0..3 {
            describe(
                Points::new(&raw, 4).unwrap(),
                &cfg,
                &mut scratch,
                &mut r1,
                &mut a1,
            )
            .unwrap();
            describe(
                Points::new(&raw2, 4).unwrap(),
                &cfg,
                &mut scratch,
                &mut r2,
                &mut a2,
            )
            .unwrap();
            total += cosine_distance(&r1, &r2).unwrap();
            total +=
                heading(&a1, &a2).unwrap().degrees + heading_refined(&a1, &a2).unwrap().degrees;
        }
        let after = common::allocations();
        assert_eq!(
            after - before,
            0,
            "allocations during describe/distance/heading (voxel {voxel})"
        );
        assert!(total.is_finite());
    }
}
