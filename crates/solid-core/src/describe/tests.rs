//! Tests of the descriptor's steps and of its compiled copies.

use super::*;

fn cfg() -> Config {
    Config::preset("hdl64").unwrap()
}

fn run(xyz: &[f64], cfg: &Config) -> (Vec<f32>, Vec<f32>, Stats) {
    let pts = Points::new(xyz, 3).unwrap();
    let mut scratch = vec![0; describe_scratch_len(pts.len(), cfg)];
    let mut r = vec![0.0; cfg.n_range];
    let mut a = vec![0.0; cfg.n_azimuth];
    let s = describe(pts, cfg, &mut scratch, &mut r, &mut a).unwrap();
    (r, a, s)
}

#[test]
fn empty_scan_is_all_zero() {
    let (r, a, s) = run(&[], &cfg());
    assert!(r.iter().chain(&a).all(|&v| v == 0.0));
    assert_eq!(s, Stats::default());
}

#[test]
fn single_point_lands_in_its_bins() {
    // x = 10, y = 10: r = 14.14 m -> bin 7 of 40 over 80 m; azimuth 45° -> bin 7 of 60;
    // flat EC (one point in one bin, but min = 0 over 64 bins) -> IEV of its bin is 1.
    let (r, a, s) = run(&[10.0, 10.0, -1.0], &cfg());
    assert_eq!(s.n_kept, 1);
    let nz: Vec<usize> = (0..40).filter(|&i| r[i] != 0.0).collect();
    assert_eq!(nz, [7]);
    assert_eq!(r[7], 1.0);
    let nz: Vec<usize> = (0..60).filter(|&j| a[j] != 0.0).collect();
    assert_eq!(nz, [7]);
}

#[test]
fn range_filter_is_strict_and_drops_non_finite() {
    let c = Config {
        voxel_size: 0.0,
        ..cfg()
    };
    let pts = [
        3.0,
        0.0,
        0.0, // on min_range: dropped
        80.0,
        0.0,
        0.0, // on max_range: dropped
        f64::NAN,
        1.0,
        1.0,
        f64::INFINITY,
        0.0,
        0.0,
        1e200,
        0.0,
        0.0,
        5.0,
        0.0,
        0.0, // kept
    ];
    let (_, _, s) = run(&pts, &c);
    assert_eq!((s.n_points, s.n_in_range, s.n_kept), (6, 1, 1));
}

#[test]
fn voxel_centroids_merge_points() {
    // Two points in voxel (20,0,0) and one in (21,0,0) with v = 0.5.
    let pts = [10.1, 0.1, 0.1, 10.2, 0.2, 0.2, 10.6, 0.1, 0.1];
    let (_, _, s) = run(&pts, &cfg());
    assert_eq!((s.n_in_range, s.n_kept), (3, 2));
    // Negative coordinates floor away from zero: -0.1 and 0.1 are different voxels.
    let pts = [10.1, -0.1, 0.1, 10.1, 0.1, 0.1];
    let (_, _, s) = run(&pts, &cfg());
    assert_eq!(s.n_kept, 2);
}

/// Centroids of `xyz` (stride 3) grouped naively, in order of first occupation, and the
/// number of points in range.
fn naive_voxels(xyz: &[f64], c: &Config) -> (Vec<[f64; 3]>, usize) {
    let mut order: Vec<[i64; 3]> = Vec::new();
    let mut sums: std::collections::HashMap<[i64; 3], [f64; 4]> = Default::default();
    let mut n_in = 0;
    for p in xyz.chunks_exact(3) {
        let d = libm::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        if !(d > c.min_range && d < c.max_range) {
            continue;
        }
        n_in += 1;
        let k = [0, 1, 2].map(|i| libm::floor(p[i] / c.voxel_size) as i64);
        let g = sums.entry(k).or_insert_with(|| {
            order.push(k);
            [0.0; 4]
        });
        *g = [g[0] + p[0], g[1] + p[1], g[2] + p[2], g[3] + 1.0];
    }
    let cents = order
        .iter()
        .map(|k| {
            let g = sums[k];
            [g[0] / g[3], g[1] / g[3], g[2] / g[3]]
        })
        .collect();
    (cents, n_in)
}

#[test]
fn voxels_keep_their_order_through_runs_flicker_and_blocks() {
    // A scan line that grazes voxel boundaries (A B A B ...), long runs in one voxel that
    // span several blocks, points out of range and not finite between points of one voxel,
    // and voxels revisited far apart: the order of first occupation, the counts and the
    // centroids must be those of a naive grouping.
    let c = cfg();
    let mut xyz = Vec::new();
    for i in 0..3000 {
        let t = i as f64;
        // Flicker across x = 10 and y = 0 (negative coordinates floor away from zero).
        xyz.extend([10.0 + 0.01 * libm::sin(t), 0.01 * libm::cos(1.7 * t), -1.0]);
        if i % 97 == 0 {
            xyz.extend([f64::NAN, 0.0, 0.0]);
            xyz.extend([0.5, 0.5, 0.5]); // inside min_range
        }
    }
    for i in 0..1500 {
        xyz.extend([20.1 + 1e-4 * i as f64, 5.2, 0.3]); // one voxel over three blocks
    }
    for i in 0..3000 {
        let t = i as f64 * 0.05;
        xyz.extend([
            30.0 * libm::cos(t),
            30.0 * libm::sin(t),
            0.1 * libm::sin(7.0 * t),
        ]);
    }
    xyz.extend([10.001, 0.001, -0.999, 20.2, 5.3, 0.4]); // back to early voxels
    let (naive, n_naive) = naive_voxels(&xyz, &c);
    let pts = Points::new(&xyz, 3).unwrap();
    let mut scratch = vec![0; describe_scratch_len(pts.len(), &c)];
    let mut out = vec![0.0; xyz.len()];
    let (n_in, m) = stages::voxel_downsample(pts, &c, &mut scratch, &mut out).unwrap();
    assert_eq!((n_in, m), (n_naive, naive.len()));
    for (ours, theirs) in out.chunks_exact(3).zip(&naive) {
        for i in 0..3 {
            assert!((ours[i] - theirs[i]).abs() < 0.5 / (1u64 << 24) as f64 + 1e-12);
        }
    }
}

#[test]
fn voxel_table_grows_and_matches_a_naive_grouping() {
    // 60k pseudo-random points, many sharing voxels, enough distinct voxels to force several
    // table doublings; centroids must equal a BTreeMap grouping.
    use std::collections::BTreeMap;
    let mut state = 0x1234_5678_9abc_def0u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut xyz = Vec::new();
    for _ in 0..60_000 {
        xyz.extend([
            next() * 120.0 - 60.0,
            next() * 120.0 - 60.0,
            next() * 8.0 - 4.0,
        ]);
    }
    let c = cfg();
    let pts = Points::new(&xyz, 3).unwrap();
    let mut scratch = vec![0; describe_scratch_len(pts.len(), &c)];
    let mut out = vec![0.0; xyz.len()];
    let (n_in, m) = stages::voxel_downsample(pts, &c, &mut scratch, &mut out).unwrap();
    let mut groups: BTreeMap<[i64; 3], (f64, f64, f64, f64)> = BTreeMap::new();
    let mut n_naive = 0;
    for p in xyz.chunks_exact(3) {
        let d = libm::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        if !(d > 3.0 && d < 80.0) {
            continue;
        }
        n_naive += 1;
        let k = [0, 1, 2].map(|i| libm::floor(p[i] / 0.5) as i64);
        let g = groups.entry(k).or_insert((0.0, 0.0, 0.0, 0.0));
        *g = (g.0 + p[0], g.1 + p[1], g.2 + p[2], g.3 + 1.0);
    }
    assert_eq!(n_in, n_naive);
    assert_eq!(m, groups.len());
    let initial_slots = (xyz.len() / 3 / 4).next_power_of_two();
    assert!(
        m > initial_slots,
        "test must force two table doublings ({m} voxels)"
    );
    let mut ours: Vec<[f64; 3]> = out[..3 * m]
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let mut naive: Vec<[f64; 3]> = groups
        .values()
        .map(|g| [g.0 / g.3, g.1 / g.3, g.2 / g.3])
        .collect();
    ours.sort_by(|a, b| a.partial_cmp(b).unwrap());
    naive.sort_by(|a, b| a.partial_cmp(b).unwrap());
    for (a, b) in ours.iter().zip(&naive) {
        for i in 0..3 {
            // Offsets are summed in units of v / 2^23: the mean is off by v / 2^24 at most.
            assert!(
                (a[i] - b[i]).abs() < 0.5 / (1u64 << 24) as f64 + 1e-12,
                "{a:?} vs {b:?}"
            );
        }
    }
}

/// The output of one compiled copy of [`describe`] (stats and the bits of R-SOLiD and
/// A-SOLiD), and of [`stages::voxel_downsample`]'s voxelisation (points in range, then every
/// voxel record).
fn run_copy<T: Coord>(isa: Isa, pts: Points<'_, T>, c: &Config) -> (Stats, Vec<u32>, Vec<u64>) {
    let mut scratch = vec![0; describe_scratch_len(pts.len(), c)];
    let (mut r, mut a) = (vec![0f32; c.n_range], vec![0f32; c.n_azimuth]);
    let stats = describe_on(isa, pts, c, &mut scratch, &mut r, &mut a).unwrap();
    let bits = r.iter().chain(&a).map(|x| x.to_bits()).collect();
    let mut voxels = Vec::new();
    if c.voxel_size > 0.0 {
        let (table, recs) = voxel_scratch(&mut scratch, pts.len());
        let (n_in, m) = voxelize_on(isa, pts, c, table, recs);
        voxels.push(n_in as u64);
        voxels.extend(recs[..m].iter().flatten());
    }
    (stats, bits, voxels)
}

/// A synthetic spinning-LiDAR scan: rings of points in scan order (so runs, voxel-boundary
/// flicker and revisited voxels occur as on a real scan), then scattered points, with
/// points out of range and not finite mixed in. Three values a point, plus `extra` columns.
fn ring_scan() -> impl proptest::strategy::Strategy<Value = (Vec<f64>, usize)> {
    use proptest::prelude::*;
    let ring = (3.0f64..70.0, -3.0f64..3.0, 16usize..900, 0.0f64..0.2);
    let scattered = (-90.0f64..90.0, -90.0f64..90.0, -5.0f64..5.0);
    (
        prop::collection::vec(ring, 1..6),
        prop::collection::vec(scattered, 0..200),
        0usize..3,
        any::<u64>(),
    )
        .prop_map(|(rings, scattered, extra, seed)| {
            let mut state = seed | 1;
            let mut next = move || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 53) as f64
            };
            let mut xyz = Vec::new();
            let push = |p: [f64; 3], xyz: &mut Vec<f64>| {
                xyz.extend(p);
                xyz.extend((0..extra).map(|e| e as f64));
            };
            for (rho, z, n, noise) in rings {
                for i in 0..n {
                    let t = core::f64::consts::TAU * i as f64 / n as f64;
                    let rho = rho + noise * (next() - 0.5);
                    let p = match (next() * 40.0) as u32 {
                        0 => [f64::NAN, 1.0, 0.0],
                        1 => [0.1, 0.2, 0.3],
                        2 => [90.0, 0.0, 0.0],
                        _ => [rho * libm::cos(t), rho * libm::sin(t), z],
                    };
                    push(p, &mut xyz);
                }
            }
            for (x, y, z) in scattered {
                push([x, y, z], &mut xyz);
            }
            (xyz, 3 + extra)
        })
}

proptest::proptest! {
    #![proptest_config(proptest::test_runner::Config::with_cases(64))]

    /// Every compiled copy of `describe` this CPU runs gives the bits of the portable one, for
    /// `f64` and `f32` points, any stride, with and without voxels.
    #[test]
    fn every_copy_gives_the_portable_bits(
        (xyz, stride) in ring_scan(),
        voxel in proptest::sample::select(vec![0.0, 0.1, 0.25, 0.5, 1.3]),
    ) {
        let c = Config { voxel_size: voxel, ..cfg() };
        let f32s: Vec<f32> = xyz.iter().map(|&v| v as f32).collect();
        let wide = Points::new(&xyz, stride).unwrap();
        let narrow = Points::new(&f32s, stride).unwrap();
        let (want64, want32) = (
            run_copy(Isa::Portable, wide, &c),
            run_copy(Isa::Portable, narrow, &c),
        );
        for isa in Isa::available() {
            proptest::prop_assert_eq!(&run_copy(isa, wide, &c), &want64, "{:?} on f64", isa);
            proptest::prop_assert_eq!(&run_copy(isa, narrow, &c), &want32, "{:?} on f32", isa);
        }
    }
}

#[test]
fn out_of_fov_points_go_to_edge_bins() {
    let c = Config {
        voxel_size: 0.0,
        ..cfg()
    };
    // Straight up and straight down: elevation bins 63 and 0; both counted, nothing wraps.
    let (r, _, s) = run(&[0.0, 0.0, 10.0, 0.0, 0.0, -10.0, 20.0, 0.0, 0.0], &c);
    assert_eq!(s.n_kept, 3);
    assert!(r.iter().all(|v| v.is_finite()));
}

#[test]
fn buffers_too_small_are_errors() {
    let c = cfg();
    let xyz = [10.0f32, 0.0, 0.0];
    let pts = Points::new(&xyz, 3).unwrap();
    let need = describe_scratch_len(1, &c);
    let mut scratch = vec![0; need - 1];
    let mut r = vec![0.0; 40];
    let mut a = vec![0.0; 60];
    assert_eq!(
        describe(pts, &c, &mut scratch, &mut r, &mut a),
        Err(Error::BufferTooSmall {
            buffer: "scratch",
            needed: need,
            got: need - 1
        })
    );
    let mut scratch = vec![0; need];
    assert!(matches!(
        describe(pts, &c, &mut scratch, &mut r[..39], &mut a),
        Err(Error::BufferTooSmall {
            buffer: "r_out",
            ..
        })
    ));
    assert!(matches!(
        describe(pts, &c, &mut scratch, &mut r, &mut a[..1]),
        Err(Error::BufferTooSmall {
            buffer: "a_out",
            ..
        })
    ));
}

#[test]
fn bad_layout_is_an_error() {
    let xyz = [1.0f32; 8];
    assert!(Points::new(&xyz, 3).is_err());
    assert!(Points::new(&xyz, 2).is_err());
    assert_eq!(Points::new(&xyz, 4).unwrap().len(), 2);
}
