//! Property tests of the descriptor's invariants (docs/spec.md §2).

use proptest::prelude::*;
use solid_lidar::{Config, Describer, Descriptor, Points};

fn cfg(voxel: f64) -> Config {
    Config {
        voxel_size: voxel,
        ..Config::preset("hdl64").unwrap()
    }
}

fn describe(xyz: &[f64], cfg: Config) -> Descriptor {
    Describer::new(cfg)
        .unwrap()
        .describe(Points::new(xyz, 3).unwrap())
        .unwrap()
}

/// Points spread over the sensor's whole range and field of view.
fn cloud() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec((3.5f64..79.0, 0.0f64..360.0, -24.0f64..1.5), 1..400).prop_map(|pts| {
        pts.into_iter()
            .flat_map(|(rho, az, el)| {
                let (az, el) = (az.to_radians(), el.to_radians());
                let r = rho * libm::cos(el);
                [r * libm::cos(az), r * libm::sin(az), rho * libm::sin(el)]
            })
            .collect()
    })
}

fn rotate(xyz: &[f64], deg: f64) -> Vec<f64> {
    let (s, c) = (libm::sin(deg.to_radians()), libm::cos(deg.to_radians()));
    xyz.chunks_exact(3)
        .flat_map(|p| [c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]])
        .collect()
}

fn l1(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| f64::from((x - y).abs()))
        .sum()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Rotating the scan by m·360/Na about z leaves R-SOLiD unchanged and shifts A-SOLiD by m bins.
    /// Without voxels the only effect is rounding, which can move a point lying within ~1e-13°
    /// of a bin edge: at most one point's weight (IEV <= 1) per vector.
    #[test]
    fn rotation_by_whole_bins_shifts_a_and_keeps_r(xyz in cloud(), m in 0usize..60) {
        let base = describe(&xyz, cfg(0.0));
        let rot = describe(&rotate(&xyz, m as f64 * 6.0), cfg(0.0));
        prop_assert!(l1(&base.r, &rot.r) <= 2.0, "r changed by {}", l1(&base.r, &rot.r));
        let shifted: Vec<f32> = (0..60).map(|j| base.a[(j + 60 - m) % 60]).collect();
        prop_assert!(l1(&shifted, &rot.a) <= 2.0, "a not shifted: {}", l1(&shifted, &rot.a));
        prop_assert_eq!(base.stats.n_kept, rot.stats.n_kept);
    }

    /// Non-finite points are dropped before anything else: inserting them changes nothing.
    #[test]
    fn non_finite_points_never_change_the_output(
        xyz in cloud(),
        junk in prop::collection::vec((0usize..400, 0usize..3, 0usize..3), 1..50),
        voxel in prop::sample::select(vec![0.0, 0.5, 1.0]),
    ) {
        let base = describe(&xyz, cfg(voxel));
        let mut dirty = xyz.clone();
        for (at, col, kind) in junk {
            let bad = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][kind];
            let mut p = [5.0, 5.0, 0.0];
            p[col] = bad;
            let at = 3 * (at % (dirty.len() / 3 + 1));
            dirty.splice(at..at, p);
        }
        let d = describe(&dirty, cfg(voxel));
        prop_assert_eq!(&base.r, &d.r);
        prop_assert_eq!(&base.a, &d.a);
        prop_assert_eq!(base.stats.n_in_range, d.stats.n_in_range);
    }

    /// Whatever the points and the (valid) config, the output is finite and non-negative.
    #[test]
    fn output_is_always_finite(
        raw in prop::collection::vec(prop_oneof![
            -200.0f64..200.0,
            Just(f64::NAN), Just(f64::INFINITY), Just(-1e30), Just(1e30), Just(0.0),
            any::<f64>(),
        ], 0..600),
        n_range in 1usize..100, n_azimuth in 1usize..400, n_elevation in 1usize..100,
        fov in (-90.0f64..89.0, 0.01f64..100.0),
        ranges in (0.0f64..10.0, 0.1f64..300.0),
        voxel in prop::sample::select(vec![0.0, 0.05, 0.5, 3.0]),
    ) {
        let fov_down = fov.0;
        let fov_up = (fov.0 + fov.1).min(90.0);
        let cfg = Config {
            n_range, n_azimuth, n_elevation, fov_up, fov_down,
            min_range: ranges.0, max_range: ranges.0 + ranges.1, voxel_size: voxel,
        };
        prop_assume!(cfg.validate().is_ok());
        let n = raw.len() / 3 * 3;
        let d = describe(&raw[..n], cfg);
        prop_assert!(d.r.iter().chain(&d.a).all(|v| v.is_finite() && *v >= 0.0));
        prop_assert!(d.stats.n_kept <= d.stats.n_in_range && d.stats.n_in_range <= d.stats.n_points);
        // Both vectors weigh the same points: their sums agree.
        let (sr, sa): (f64, f64) = (d.r.iter().map(|&v| f64::from(v)).sum(), d.a.iter().map(|&v| f64::from(v)).sum());
        prop_assert!((sr - sa).abs() <= 1e-4 * sr.max(1.0));
    }
}
