//! The allocation-free paths allocate nothing: a counting global allocator sees zero
//! allocations across `describe`, `cosine_distance` and `heading` on a real scan, and across
//! registration over prepared clouds (`register`, `register_hypotheses`, `hypothesis_yaws`, the
//! gate).

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

#[cfg(feature = "std")]
#[test]
fn registration_allocates_nothing() {
    use solid_lidar::reg::{
        hypothesis_yaws, register, register_hypotheses, Gate, Hypothesis, PreparedCloud, RegConfig,
        IDENTITY,
    };
    let Some(data) = common::data_dir() else {
        return;
    };
    let cfg = RegConfig::default();
    let a = common::read_scan(&data.join("hku1-avia/Scans/000280.pcd"));
    let b = common::read_scan(&data.join("hku1-avia/Scans/000020.pcd"));
    let pa = PreparedCloud::new(Points::new(&a, 3).unwrap(), &cfg).unwrap();
    let pb = PreparedCloud::new(Points::new(&b, 3).unwrap(), &cfg).unwrap();
    let (qa, ca) = (
        [1.0f32, 4.0, 2.0, 0.0, 0.0, 3.0],
        [0.0f32, 1.0, 4.0, 2.0, 0.0, 3.0],
    );
    let mut yaws = [0.0; 4];
    let mut hyps = [Hypothesis::default(); 4];
    let gate = Gate::default();
    let before = common::allocations();
    let k = hypothesis_yaws(&qa, &ca, &mut yaws).unwrap();
    let r = register(&pa, &pb, &IDENTITY, &cfg).unwrap();
    let h = register_hypotheses(&pa, &pb, &yaws[..k], &IDENTITY, &cfg, &mut hyps).unwrap();
    let _ = gate.check(&h.registration, &hyps[..k], h.best);
    assert_eq!(common::allocations(), before);
    assert!(r.iterations > 0 && k >= 1);
}
