//! Heading on a real full-360° KITTI scan rotated about z (voxel effects included).

mod common;

use solid_lidar::{Config, Describer, Points};

#[test]
fn rotated_kitti_scan_gives_the_rotation_as_heading() {
    let Some(shared) = common::shared() else {
        return;
    };
    let raw = common::read_kitti(&shared.join("data/kitti00/velodyne/000000.bin"));
    let xyz: Vec<f64> = raw
        .chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]].map(f64::from))
        .collect();
    let mut desc = Describer::new(Config::preset("hdl64").unwrap()).unwrap();
    let cand = desc.describe(Points::new(&xyz, 3).unwrap()).unwrap();
    for deg in [-150.0f64, -42.0, 13.0, 30.0, 90.0, 177.0] {
        let (s, c) = (libm::sin(deg.to_radians()), libm::cos(deg.to_radians()));
        let rot: Vec<f64> = xyz
            .chunks_exact(3)
            .flat_map(|p| [c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]])
            .collect();
        let q = desc.describe(Points::new(&rot, 3).unwrap()).unwrap();
        let d = q.distance(&cand).unwrap();
        assert!(d < 0.01, "{deg}°: distance {d}");
        let h = q.heading(&cand, true).unwrap().degrees;
        let err = (h - deg + 540.0).rem_euclid(360.0) - 180.0;
        assert!(err.abs() <= 2.0, "{deg}°: heading {h}");
    }
}
