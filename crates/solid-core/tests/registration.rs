//! Registration on real scans: known transforms recovered, true hku1 revisits against the ground
//! truth, the gate on wrong candidates and on a corridor, yaw hypotheses, the wire form, and no
//! panic on degenerate input.
#![cfg(feature = "std")]

mod common;

use common::{data_dir, read_scan};
use solid_lidar::reg::{
    decode_cloud, encode_cloud, hypothesis_yaws, pose_distance, register, register_hypotheses,
    register_hypotheses_for, Gate, Hypothesis, Pose, PreparedCloud, RegConfig, RegError,
    Registration, Rejection, IDENTITY,
};
use solid_lidar::{Config, Describer, Error, Points};

fn pose(yaw_deg: f64, roll_deg: f64, t: [f64; 3]) -> Pose {
    let (sy, cy) = yaw_deg.to_radians().sin_cos();
    let (sr, cr) = roll_deg.to_radians().sin_cos();
    // Rz(yaw) · Rx(roll)
    [
        [cy, -sy * cr, sy * sr, t[0]],
        [sy, cy * cr, -cy * sr, t[1]],
        [0.0, sr, cr, t[2]],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

fn apply(p: &Pose, xyz: &[f64]) -> Vec<f64> {
    xyz.chunks_exact(3)
        .flat_map(|v| {
            (0..3).map(move |i| p[i][0] * v[0] + p[i][1] * v[1] + p[i][2] * v[2] + p[i][3])
        })
        .collect()
}

fn prepare(xyz: &[f64], cfg: &RegConfig) -> PreparedCloud {
    PreparedCloud::new(Points::new(xyz, 3).unwrap(), cfg).unwrap()
}

fn mul(a: &Pose, b: &Pose) -> Pose {
    let mut c = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            c[i][j] = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

fn inverse(a: &Pose) -> Pose {
    let mut c = IDENTITY;
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[j][i];
        }
        c[i][3] = -(0..3).map(|k| a[k][i] * a[k][3]).sum::<f64>();
    }
    c
}

#[test]
fn recovers_known_transforms_of_real_scans() {
    let Some(data) = data_dir() else { return };
    let cfg = RegConfig::default();
    let gate = Gate::default();
    for path in [
        data.join("kitti00/velodyne/000000.bin"),
        data.join("hku1-avia/Scans/000100.pcd"),
    ] {
        let xyz = read_scan(&path);
        let candidate = prepare(&xyz, &cfg);
        for t in [
            pose(4.0, 0.0, [0.6, -0.3, 0.05]),
            pose(-9.0, 1.0, [1.2, 0.8, -0.1]),
            pose(15.0, -0.5, [-0.5, 1.0, 0.2]),
        ] {
            let query = prepare(&apply(&t, &xyz), &cfg);
            let r = register(&query, &candidate, &IDENTITY, &cfg).unwrap();
            // The two copies are voxelised on differently placed grids: centroids move by up to
            // a few centimetres, so the pose is not exact.
            let (m, deg) = pose_distance(&r.pose, &t).unwrap();
            assert!(m < 0.03 && deg < 0.1, "{}: {m} m {deg} deg", path.display());
            assert!(r.converged && r.fitness > 0.9, "{r:?}");
            assert_eq!(gate.check(&r, &[], 0), Ok(()), "{r:?}");
            // The yaw of the pose is the heading of SPEC §3.
            let yaw = t[1][0].atan2(t[0][0]).to_degrees();
            assert!((r.yaw_degrees() - yaw).abs() < 0.1);
        }
    }
}

struct Hku1 {
    clouds: Vec<PreparedCloud>,
    a_solid: Vec<Vec<f32>>,
    poses: Vec<Pose>,
}

fn hku1(cfg: &RegConfig) -> Option<Hku1> {
    let dir = data_dir()?.join("hku1-avia");
    let poses: Vec<Pose> = std::fs::read_to_string(dir.join("odom_poses.txt"))
        .unwrap()
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            [
                [v[0], v[1], v[2], v[3]],
                [v[4], v[5], v[6], v[7]],
                [v[8], v[9], v[10], v[11]],
                [0.0, 0.0, 0.0, 1.0],
            ]
        })
        .collect();
    let mut describer = Describer::new(Config::preset("avia").unwrap()).unwrap();
    let (mut clouds, mut a_solid) = (vec![], vec![]);
    for i in 0..poses.len() {
        let xyz = read_scan(&dir.join(format!("Scans/{i:06}.pcd")));
        a_solid.push(describer.describe(Points::new(&xyz, 3).unwrap()).unwrap().a);
        clouds.push(prepare(&xyz, cfg));
    }
    Some(Hku1 {
        clouds,
        a_solid,
        poses,
    })
}

/// The yaws a verifying detector tries: 0°, the A-SOLiD minima, ±25°.
fn yaws(a_q: &[f32], a_c: &[f32]) -> Vec<f64> {
    let mut y = [0.0; 3];
    let k = hypothesis_yaws(a_q, a_c, &mut y).unwrap();
    let mut out = y[..k].to_vec();
    for extra in [-25.0, 25.0] {
        if out.iter().all(|&o: &f64| (o - extra).abs() >= 6.0) {
            out.push(extra);
        }
    }
    out
}

#[test]
fn hku1_revisits_match_the_ground_truth_and_the_gate_lets_no_wrong_pose_through() {
    let cfg = RegConfig::default();
    let Some(seq) = hku1(&cfg) else { return };
    let gate = Gate::default();
    let pos = |i: usize| [seq.poses[i][0][3], seq.poses[i][1][3], seq.poses[i][2][3]];
    let dist = |a: [f64; 3], b: [f64; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    let (mut errors, mut pairs, mut accepted_wrong) = (vec![], 0, vec![]);
    let mut gave_up = 0usize;
    let mut hyps = vec![Hypothesis::default(); 8];
    // Every query's nearest earlier keyframe within 3 m (exclude 50), and a keyframe 30 or more
    // metres away as a wrong candidate.
    for q in 51..seq.poses.len() {
        let (d, c) = (0..q - 50)
            .map(|c| (dist(pos(q), pos(c)), c))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap();
        let far = (0..q - 50).find(|&c| dist(pos(q), pos(c)) > 30.0);
        for (c, truth) in [(Some(c).filter(|_| d <= 3.0), true), (far, false)] {
            let Some(c) = c else { continue };
            let y = yaws(&seq.a_solid[q], &seq.a_solid[c]);
            // As the detector registers: a candidate clearly no match gives up before the
            // fine level.
            let (qc, cc) = (&seq.clouds[q], &seq.clouds[c]);
            let h =
                register_hypotheses_for(qc, cc, &y, &IDENTITY, &cfg, &mut hyps, gate.min_fitness)
                    .unwrap();
            let r = h.registration;
            if r.iterations == hyps[h.best].iterations {
                // It gave up (the fine level adds at least one iteration): only where the full
                // registration is rejected too, and never on a true revisit the gate accepts.
                gave_up += 1;
                let mut all = hyps.clone();
                let full = register_hypotheses(qc, cc, &y, &IDENTITY, &cfg, &mut all).unwrap();
                assert!(r.fitness < gate.min_fitness, "{r:?}");
                assert!(gate
                    .check(&full.registration, &all[..full.count], full.best)
                    .is_err());
            }
            let gt = mul(&inverse(&seq.poses[q]), &seq.poses[c]);
            let (m, deg) = pose_distance(&r.pose, &gt).unwrap();
            if gate.check(&r, &hyps[..h.count], h.best).is_ok() {
                if m > 1.0 || deg > 5.0 {
                    accepted_wrong.push((q, c, m, deg));
                } else {
                    errors.push((m, deg));
                }
            }
            pairs += usize::from(truth);
        }
    }
    assert_eq!(accepted_wrong, vec![], "accepted loops with a wrong pose");
    assert_eq!(pairs, 66);
    // Measured: 12 of the true pairs the gate rejects gave up, none of the wrong (their ground
    // and walls overlap enough on the narrow Avia); the other gave-up case is in
    // hypotheses_give_up_before_the_fine_level_only_on_a_candidate_the_gate_rejects.
    println!("gave up before the fine level: {gave_up} of the pairs");
    // Most true revisits pass the gate (measured: 36 of 66 with the default gate), and their
    // poses are close to the odometry's ground truth.
    assert!(errors.len() >= 30, "only {} accepted", errors.len());
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let m = median(errors.iter().map(|e| e.0).collect());
    let deg = median(errors.iter().map(|e| e.1).collect());
    println!(
        "hku1: {} of 66 true revisits accepted, median pose error {m:.3} m {deg:.3} deg",
        errors.len()
    );
    assert!(m <= 0.05 && deg <= 0.3, "median error {m} m {deg} deg");
}

/// `xyz` registered (from the identity) to itself moved by `t`.
fn register_moved(xyz: &[f64], t: &Pose, cfg: &RegConfig) -> Registration {
    register(
        &prepare(&apply(t, xyz), cfg),
        &prepare(xyz, cfg),
        &IDENTITY,
        cfg,
    )
    .unwrap()
}

/// Two walls and a floor along x (a corridor), or three orthogonal planes (a corner).
fn planes(corridor: bool) -> Vec<f64> {
    let mut xyz = vec![];
    for i in 0..120 {
        for j in 0..16 {
            let (u, v) = (i as f64 * 0.25 - 15.0, j as f64 * 0.25);
            xyz.extend([u, v - 2.0, -1.5]); // floor, y in [-2, 2)
            xyz.extend([u, -2.0, v - 1.5]); // right wall
            if corridor {
                xyz.extend([u, 2.0, v - 1.5]); // left wall
            } else if i < 16 {
                xyz.extend([6.0, u + 13.0, v - 1.5]); // an end wall ahead
            }
        }
    }
    xyz
}

#[test]
fn the_gate_rejects_a_corridor_and_accepts_a_corner() {
    let cfg = RegConfig::default();
    let gate = Gate::default();
    for corridor in [true, false] {
        let xyz = planes(corridor);
        let t = pose(2.0, 0.0, [0.4, 0.1, 0.0]);
        let r = register_moved(&xyz, &t, &cfg);
        let check = gate.check(&r, &[], 0);
        if corridor {
            // Sliding along the corridor costs nothing: the translation block has a tiny
            // eigenvalue whatever the overlap says.
            assert!(r.degeneracy.translation < 1.0, "{r:?}");
            assert_eq!(check, Err(Rejection::DegenerateTranslation), "{r:?}");
        } else {
            assert!(r.degeneracy.translation > 5.0, "{r:?}");
            assert_eq!(check, Ok(()), "{r:?}");
            let (m, deg) = pose_distance(&r.pose, &t).unwrap();
            assert!(m < 0.02 && deg < 0.1, "{m} {deg}");
        }
    }
}

/// A round room of radius 6 m (wall, floor and ceiling) seen from 3 m off its axis: every
/// direction of the translation is seen, yet a turn about the room's axis changes nothing.
fn round_room() -> Vec<f64> {
    let (r, centre) = (6.0, [-3.0, 0.0]);
    let mut xyz = vec![];
    for i in 0..150 {
        let a = i as f64 * core::f64::consts::TAU / 150.0;
        let (x, y) = (centre[0] + r * a.cos(), centre[1] + r * a.sin());
        for k in 0..12 {
            xyz.extend([x, y, k as f64 * 0.25 - 1.5]);
        }
    }
    for i in -24..=24 {
        for j in -24..=24 {
            let (u, v) = (i as f64 * 0.25, j as f64 * 0.25);
            if u * u + v * v < (r - 0.3) * (r - 0.3) {
                xyz.extend([centre[0] + u, centre[1] + v, -1.5]);
                xyz.extend([centre[0] + u, centre[1] + v, 1.5]);
            }
        }
    }
    xyz
}

#[test]
fn the_marginal_translation_information_sees_a_turn_the_translation_block_does_not() {
    let cfg = RegConfig::default();
    // Between the room's marginal (in-plane information only, about 1-2 per correspondence:
    // GICP's plane covariances weigh an offset along a surface ~1000 times less than across)
    // and the corner's.
    let gate = Gate {
        min_marginal_translation_information: 3.0,
        ..Gate::default()
    };
    let mut marginals = [0.0; 2];
    for (k, room) in [true, false].into_iter().enumerate() {
        let xyz = if room { round_room() } else { planes(false) };
        let t = pose(2.0, 0.0, [0.3, 0.1, 0.0]);
        let r = register_moved(&xyz, &t, &cfg);
        let d = r.degeneracy;
        // Marginalising the rotation can only lose information.
        assert!(d.marginal_translation <= d.translation + 1e-9, "{r:?}");
        marginals[k] = d.marginal_translation;
        if room {
            // The block sees walls all round and passes the block's own term; a turn about
            // the axis (a turn about the sensor plus a sideways step) is free: the marginal
            // keeps under a tenth of the block, and the registration slides along that turn.
            assert!(
                d.translation > Gate::default().min_translation_information,
                "{r:?}"
            );
            assert!(d.marginal_translation < d.translation / 10.0, "{r:?}");
            assert_eq!(
                gate.check(&r, &[], 0),
                Err(Rejection::WeakMarginalTranslation),
                "{r:?}"
            );
        } else {
            assert_eq!(gate.check(&r, &[], 0), Ok(()), "{r:?}");
        }
    }
    assert!(marginals[1] > 5.0 * marginals[0], "{marginals:?}");
}

#[test]
fn hypotheses_give_up_before_the_fine_level_only_on_a_candidate_the_gate_rejects() {
    let cfg = RegConfig::default();
    let gate = Gate::default();
    let yaws = [0.0, 25.0, -25.0];
    let corner = planes(false);
    let (room, moved) = (
        round_room(),
        apply(&pose(2.0, 0.0, [0.4, 0.1, 0.0]), &corner),
    );
    let (query, same, other) = (
        prepare(&moved, &cfg),
        prepare(&corner, &cfg),
        prepare(&room, &cfg),
    );
    // The registration with and without giving up, each with its hypotheses.
    let both = |candidate: &PreparedCloud| {
        let (mut all, mut hyps) = ([Hypothesis::default(); 3], [Hypothesis::default(); 3]);
        let full = register_hypotheses(&query, candidate, &yaws, &IDENTITY, &cfg, &mut all);
        let m = gate.min_fitness;
        let gated =
            register_hypotheses_for(&query, candidate, &yaws, &IDENTITY, &cfg, &mut hyps, m);
        (full.unwrap(), all, gated.unwrap(), hyps)
    };
    // The true match: the same registration as without giving up, accepted.
    let (full, all, gated, hyps) = both(&same);
    assert_eq!(gated, full);
    assert_eq!(hyps, all);
    assert_eq!(gate.check(&gated.registration, &hyps, gated.best), Ok(()));
    // Another place: it gives up after the coarse level, and the gate rejects it for its overlap,
    // as it rejects the full registration.
    let (full, all, gated, mut hyps) = both(&other);
    assert_eq!(hyps, all, "the hypotheses are the same");
    assert_eq!(gated.best, full.best);
    assert_eq!(gated.registration.iterations, hyps[gated.best].iterations);
    assert!(full.registration.iterations > gated.registration.iterations);
    assert!(!gated.registration.converged && gated.registration.hessian == [[0.0; 6]; 6]);
    assert_eq!(
        gate.check(&gated.registration, &hyps, gated.best),
        Err(Rejection::LowOverlap)
    );
    assert!(gate.check(&full.registration, &all, full.best).is_err());
    // min_fitness 0 never gives up; outside [0, 1] it is an error naming it.
    let never = register_hypotheses_for(&query, &other, &yaws, &IDENTITY, &cfg, &mut hyps, 0.0);
    assert_eq!(never.unwrap(), full);
    let bad = register_hypotheses_for(&query, &other, &yaws, &IDENTITY, &cfg, &mut hyps, 1.5);
    assert!(format!("{}", bad.unwrap_err()).contains("min_fitness"));
}

#[test]
fn hypotheses_recover_a_large_yaw_that_a_single_start_misses() {
    let Some(data) = data_dir() else { return };
    let cfg = RegConfig::default();
    let xyz = read_scan(&data.join("kitti00/velodyne/000000.bin"));
    let t = pose(120.0, 0.0, [1.0, -0.5, 0.0]);
    let moved = apply(&t, &xyz);
    let (query, candidate) = (prepare(&moved, &cfg), prepare(&xyz, &cfg));
    let single = register(&query, &candidate, &IDENTITY, &cfg).unwrap();
    assert!(pose_distance(&single.pose, &t).unwrap().1 > 10.0);
    let mut describer = Describer::new(Config::preset("hdl64").unwrap()).unwrap();
    let aq = describer
        .describe(Points::new(&moved, 3).unwrap())
        .unwrap()
        .a;
    let ac = describer.describe(Points::new(&xyz, 3).unwrap()).unwrap().a;
    let mut y = [0.0; 4];
    let k = hypothesis_yaws(&aq, &ac, &mut y).unwrap();
    assert!(k >= 2 && y[0] == 0.0, "{y:?}");
    let mut hyps = [Hypothesis::default(); 4];
    let h = register_hypotheses(&query, &candidate, &y[..k], &IDENTITY, &cfg, &mut hyps).unwrap();
    let (m, deg) = pose_distance(&h.registration.pose, &t).unwrap();
    assert!(m < 0.02 && deg < 0.1, "{m} {deg} {:?}", &hyps[..k]);
    assert!(hyps[h.best].cost <= hyps.iter().take(k).map(|h| h.cost).fold(1.0, f64::min));
    assert!(Gate::default()
        .check(&h.registration, &hyps[..k], h.best)
        .is_ok());
}

#[test]
fn the_wire_form_is_small_and_barely_moves_the_pose() {
    let Some(data) = data_dir() else { return };
    let cfg = RegConfig::default();
    for (a, b) in [
        ("hku1-avia/Scans/000280.pcd", "hku1-avia/Scans/000281.pcd"),
        ("kitti00/velodyne/000094.bin", "kitti00/velodyne/000095.bin"),
    ] {
        let (xa, xb) = (read_scan(&data.join(a)), read_scan(&data.join(b)));
        let (pa, pb) = (prepare(&xa, &cfg), prepare(&xb, &cfg));
        let bytes = encode_cloud(&pa.fine.points, cfg.voxel_size, 8).unwrap();
        let per_point = bytes.len() as f64 / pa.fine.len() as f64;
        assert!(per_point < 5.0, "{a}: {per_point} bytes per point");
        let decoded = decode_cloud(&bytes).unwrap();
        assert_eq!(decoded.len(), pa.fine.len());
        let back = PreparedCloud::from_downsampled(&decoded, &cfg).unwrap();
        let r0 = register(&pa, &pb, &IDENTITY, &cfg).unwrap();
        let r1 = register(&back, &pb, &IDENTITY, &cfg).unwrap();
        let (m, deg) = pose_distance(&r0.pose, &r1.pose).unwrap();
        assert!(
            m < 0.01 && deg < 0.05,
            "{a}: quantisation moved the pose {m} m {deg} deg"
        );
    }
}

#[test]
fn degenerate_input_never_panics() {
    let cfg = RegConfig::default();
    let n = f64::NAN;
    let clouds: Vec<Vec<f64>> = vec![
        vec![],
        vec![5.0, 0.0, 0.0],
        vec![n, n, n, 5.0, n, 1.0, f64::INFINITY, 0.0, 0.0],
        [5.0, 1.0, 0.5].repeat(1000),
        vec![1e300, 0.0, 0.0, -1e300, 1e300, 0.0, 3e10, 1.0, 2.0],
        (0..60)
            .flat_map(|i| [i as f64 * 0.3 + 2.0, 0.0, 0.0])
            .collect(),
        planes(true),
    ];
    let prepared: Vec<PreparedCloud> = clouds.iter().map(|c| prepare(c, &cfg)).collect();
    let mut hyps = [Hypothesis::default(); 3];
    for a in &prepared {
        for b in &prepared {
            let r = register(a, b, &IDENTITY, &cfg).unwrap();
            assert!(r.pose.iter().flatten().all(|v| v.is_finite()));
            let h =
                register_hypotheses(a, b, &[0.0, 90.0, -90.0], &IDENTITY, &cfg, &mut hyps).unwrap();
            assert!(h.best < 3);
            if a.fine.len() < 6 || b.fine.len() < 6 {
                assert!(!r.converged, "{r:?}");
                assert!(Gate::default().check(&r, &[], 0).is_err());
            }
        }
    }
    // Wrong arguments are errors that name what is wrong.
    let (a, b) = (&prepared[6], &prepared[6]);
    let bad_init = [[f64::NAN; 4]; 4];
    assert!(matches!(
        register(a, b, &bad_init, &cfg),
        Err(RegError::Core(Error::InvalidParameter { name: "init", .. }))
    ));
    let mut not_rigid = IDENTITY;
    not_rigid[0][0] = 2.0;
    assert!(register(a, b, &not_rigid, &cfg).is_err());
    assert!(matches!(
        register_hypotheses(a, b, &[], &IDENTITY, &cfg, &mut hyps),
        Err(RegError::Core(Error::Empty { .. }))
    ));
    assert!(matches!(
        register_hypotheses(a, b, &[0.0; 4], &IDENTITY, &cfg, &mut hyps),
        Err(RegError::Core(Error::BufferTooSmall { .. }))
    ));
    assert!(register_hypotheses(a, b, &[f64::NAN], &IDENTITY, &cfg, &mut hyps).is_err());
    let other = RegConfig {
        voxel_size: 0.3,
        ..cfg
    };
    assert_eq!(
        register(a, b, &IDENTITY, &other),
        Err(RegError::NotPreparedWith)
    );
}

#[test]
fn invalid_configs_name_the_parameter() {
    let base = RegConfig::default();
    let cases: [(RegConfig, &str); 10] = [
        (
            RegConfig {
                voxel_size: -1.0,
                ..base
            },
            "voxel_size",
        ),
        (
            RegConfig {
                coarse_voxel_size: 0.3,
                ..base
            },
            "coarse_voxel_size",
        ),
        (
            RegConfig {
                min_range: f64::NAN,
                ..base
            },
            "min_range",
        ),
        (
            RegConfig {
                max_range: 0.5,
                ..base
            },
            "max_range",
        ),
        (
            RegConfig {
                neighbors: 2,
                ..base
            },
            "neighbors",
        ),
        (
            RegConfig {
                max_correspondence: 0.0,
                ..base
            },
            "max_correspondence",
        ),
        (
            RegConfig {
                max_iterations: 0,
                ..base
            },
            "max_iterations",
        ),
        (
            RegConfig {
                translation_eps: f64::INFINITY,
                ..base
            },
            "translation_eps",
        ),
        (
            RegConfig {
                kernel_scale: 20.0,
                ..base
            },
            "kernel_scale",
        ),
        (
            RegConfig {
                inlier_distance: -0.1,
                ..base
            },
            "inlier_distance",
        ),
    ];
    for (cfg, name) in cases {
        match cfg.validate() {
            Err(RegError::Core(Error::InvalidParameter { name: got, .. })) => {
                assert_eq!(got, name)
            }
            other => panic!("{name}: {other:?}"),
        }
        assert!(PreparedCloud::new(Points::new(&[1.0f64, 2.0, 3.0], 3).unwrap(), &cfg).is_err());
    }
    base.validate().unwrap();
    RegConfig {
        coarse_voxel_size: 0.0,
        voxel_size: 0.0,
        ..base
    }
    .validate()
    .unwrap();
}
