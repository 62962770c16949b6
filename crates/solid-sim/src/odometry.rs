//! What a robot believes about its own path: odometry that drifts away from the true trajectory,
//! and sessions whose poses are expressed in their own starting frame.

use crate::error::{check, check_in, try_vec, SimError};
use crate::pose::Pose;
use crate::rng::{mix_seed, Rng};
use crate::trajectory::Trajectory;

/// How [`Trajectory::odometry`] corrupts each relative motion.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DriftOptions {
    /// Yaw added per metre travelled, degrees (a gyro bias seen through a moving platform).
    pub yaw_bias_deg_per_m: f64,
    /// Yaw added per frame, degrees (a gyro bias over time).
    pub yaw_bias_deg_per_frame: f64,
    /// Relative error of every step's length (0.01: each step measured 1 % too long).
    pub scale_error: f64,
    /// Standard deviation of the Gaussian noise added to each step's translation, per axis,
    /// metres.
    pub translation_noise: f64,
    /// Standard deviation of the Gaussian noise added to each step's yaw, degrees.
    pub rotation_noise_deg: f64,
    /// Seed of the noise.
    pub seed: u64,
    /// The frames whose step (from the frame before) the odometry gets badly wrong, `[first,
    /// end)`: a stretch where it breaks down (a LIO on a featureless or fast stretch). Empty
    /// (the default `[0, 0]`): none.
    pub breakdown: [usize; 2],
    /// Metres added to each step inside [`Self::breakdown`], in a seeded random horizontal
    /// direction of the sensor's frame (tens of metres: keyframe jumps where the platform
    /// moved a few).
    pub breakdown_jump_m: f64,
    /// Vertical metres the odometry drifts over the whole [`Self::breakdown`] stretch (spread
    /// evenly over its steps, along the sensor's z axis).
    pub breakdown_climb_m: f64,
}

impl DriftOptions {
    fn validate(&self) -> Result<(), SimError> {
        check(
            "yaw_bias_deg_per_m",
            self.yaw_bias_deg_per_m,
            self.yaw_bias_deg_per_m.abs() <= 90.0,
            "|bias| <= 90 deg/m",
        )?;
        check(
            "yaw_bias_deg_per_frame",
            self.yaw_bias_deg_per_frame,
            self.yaw_bias_deg_per_frame.abs() <= 90.0,
            "|bias| <= 90 deg/frame",
        )?;
        check(
            "scale_error",
            self.scale_error,
            self.scale_error.abs() < 1.0,
            "(-1, 1)",
        )?;
        check_in(
            "translation_noise",
            self.translation_noise,
            0.0,
            10.0,
            "[0, 10] m",
        )?;
        check_in(
            "rotation_noise_deg",
            self.rotation_noise_deg,
            0.0,
            90.0,
            "[0, 90] deg",
        )?;
        let [first, end] = self.breakdown;
        check(
            "breakdown",
            first as f64,
            first <= end,
            "[first, end) with first <= end",
        )?;
        check_in(
            "breakdown_jump_m",
            self.breakdown_jump_m,
            0.0,
            1000.0,
            "[0, 1000] m",
        )?;
        check(
            "breakdown_climb_m",
            self.breakdown_climb_m,
            self.breakdown_climb_m.abs() <= 1000.0,
            "|climb| <= 1000 m",
        )
    }
}

impl Trajectory {
    /// The odometry a drifting estimator would report along this (true) trajectory, in the same
    /// world frame and starting at the same first pose. Each relative motion `Δ = T_{k−1}⁻¹·T_k`
    /// is corrupted — its translation scaled by `1 + scale_error` plus noise, its rotation
    /// followed by a yaw about the sensor's z axis of `yaw_bias_deg_per_m · |t_Δ| +
    /// yaw_bias_deg_per_frame` plus noise — and integrated, so the error grows with the path as
    /// a real odometry's does. Inside the `breakdown` stretch each step also jumps
    /// `breakdown_jump_m` sideways (a seeded horizontal direction) and climbs its share of
    /// `breakdown_climb_m`; outside it the steps are right again, so the error the stretch made
    /// stays in every later pose, as a real breakdown's does. The time stamps are the truth's.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for an option outside its range;
    /// [`SimError::OutOfMemory`] when the poses do not fit in memory.
    pub fn odometry(&self, opts: &DriftOptions) -> Result<Trajectory, SimError> {
        opts.validate()?;
        let mut poses = try_vec(self.poses.len(), "odometry poses")?;
        let mut rng = Rng::new(mix_seed(&[opts.seed, 50]));
        let mut jumps = Rng::new(mix_seed(&[opts.seed, 51]));
        let [first, end] = opts.breakdown;
        let climb = if end > first {
            opts.breakdown_climb_m / (end - first) as f64
        } else {
            0.0
        };
        let mut prev: Option<(&Pose, Pose)> = None;
        for (i, truth) in self.poses.iter().enumerate() {
            let here = match prev {
                None => *truth,
                Some((last_truth, last_odom)) => {
                    let delta = last_truth.inverse().compose(truth);
                    let t = delta.translation();
                    let step = libm::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
                    let k = 1.0 + opts.scale_error;
                    let noise = [rng.gaussian(), rng.gaussian(), rng.gaussian()];
                    let yaw = opts.yaw_bias_deg_per_m * step
                        + opts.yaw_bias_deg_per_frame
                        + opts.rotation_noise_deg * rng.gaussian();
                    let mut m = delta.compose(&Pose::from_xyz_yaw(0.0, 0.0, 0.0, yaw)).m;
                    for (axis, n) in noise.iter().enumerate() {
                        m[4 * axis + 3] = k * t[axis] + opts.translation_noise * n;
                    }
                    if (first..end).contains(&i) {
                        let a = jumps.uniform() * core::f64::consts::TAU;
                        m[3] += opts.breakdown_jump_m * libm::cos(a);
                        m[7] += opts.breakdown_jump_m * libm::sin(a);
                        m[11] += climb;
                    }
                    last_odom.compose(&Pose { m })
                }
            };
            poses.push(here);
            prev = Some((truth, here));
        }
        Ok(Trajectory {
            poses,
            times: self.times.clone(),
        })
    }

    /// The same poses expressed in `frame`: each pose `P` becomes `frame⁻¹·P`. With `frame` the
    /// first pose this is the trajectory as a session that starts at the identity would record
    /// it; `frame` is then the true transform from that session's coordinates to the world's.
    pub fn in_frame(&self, frame: &Pose) -> Trajectory {
        let inv = frame.inverse();
        Trajectory {
            poses: self.poses.iter().map(|p| inv.compose(p)).collect(),
            times: self.times.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectory::RouteOptions;
    use crate::world::{World, WorldConfig};

    fn straight(len: f64, spacing: f64) -> Trajectory {
        let world = World::new(WorldConfig {
            slope: [0.0, 0.0],
            blocks: 1,
            ..WorldConfig::default()
        })
        .unwrap();
        let opts = RouteOptions {
            spacing,
            ..RouteOptions::default()
        };
        Trajectory::from_waypoints(&world, &[[0.0, 0.0], [len, 0.0]], &opts).unwrap()
    }

    fn xy(p: &Pose) -> [f64; 2] {
        [p.m[3], p.m[7]]
    }

    #[test]
    fn no_drift_is_the_truth() {
        let t = straight(50.0, 1.0);
        let o = t.odometry(&DriftOptions::default()).unwrap();
        for (a, b) in t.poses.iter().zip(&o.poses) {
            assert!(a.m.iter().zip(b.m).all(|(x, y)| (x - y).abs() < 1e-9));
        }
    }

    #[test]
    fn scale_error_stretches_the_path() {
        let t = straight(100.0, 1.0);
        let o = t
            .odometry(&DriftOptions {
                scale_error: 0.02,
                ..DriftOptions::default()
            })
            .unwrap();
        let (a, b) = (xy(&t.poses[100]), xy(&o.poses[100]));
        assert!((b[0] - a[0] - 2.0).abs() < 1e-9 && (b[1] - a[1]).abs() < 1e-9);
    }

    #[test]
    fn yaw_bias_turns_and_bends_as_integrated() {
        // n steps of length d with a heading error growing by b·d per step: the final heading
        // is off by b·n·d, the final position sideways by Σ d·sin((k−1)·b·d) ≈ b·(n·d)²/2.
        let (n, d, b) = (200usize, 1.0, 0.01f64);
        let t = straight(n as f64 * d, d);
        let o = t
            .odometry(&DriftOptions {
                yaw_bias_deg_per_m: b,
                ..DriftOptions::default()
            })
            .unwrap();
        let rel = t.poses[n].inverse().compose(&o.poses[n]);
        assert!((rel.yaw_deg() - b * n as f64 * d).abs() < 1e-9);
        let side: f64 = (1..=n)
            .map(|k| d * libm::sin(((k - 1) as f64 * b * d).to_radians()))
            .sum();
        let err = xy(&o.poses[n])[1] - xy(&t.poses[n])[1];
        assert!((err - side).abs() < 1e-9, "{err} {side}");
        let approx = b.to_radians() * (n as f64 * d).powi(2) / 2.0;
        assert!((err / approx - 1.0).abs() < 0.02);
    }

    #[test]
    fn noise_is_seeded() {
        let t = straight(30.0, 1.0);
        let opts = DriftOptions {
            translation_noise: 0.02,
            rotation_noise_deg: 0.1,
            seed: 4,
            ..DriftOptions::default()
        };
        let a = t.odometry(&opts).unwrap();
        assert_eq!(a, t.odometry(&opts).unwrap());
        let b = t
            .odometry(&DriftOptions {
                seed: 5,
                ..opts.clone()
            })
            .unwrap();
        assert_ne!(a, b);
        assert!(t
            .odometry(&DriftOptions {
                scale_error: 1.0,
                ..opts
            })
            .is_err());
    }

    #[test]
    fn a_breakdown_jumps_inside_its_stretch_and_keeps_the_error_after_it() {
        let t = straight(60.0, 2.0);
        let o = t
            .odometry(&DriftOptions {
                breakdown: [10, 13],
                breakdown_jump_m: 20.0,
                breakdown_climb_m: 30.0,
                seed: 2,
                ..DriftOptions::default()
            })
            .unwrap();
        let step = |p: &[Pose], i: usize| {
            let d = p[i - 1].inverse().compose(&p[i]);
            let t = d.translation();
            (libm::sqrt(t[0] * t[0] + t[1] * t[1]), t[2])
        };
        for i in 1..t.poses.len() {
            let (horizontal, up) = step(&o.poses, i);
            if (10..13).contains(&i) {
                // 2 m forward plus a 20 m jump: between 18 and 22 m; a third of the climb.
                assert!((18.0..=22.0).contains(&horizontal), "{i}: {horizontal}");
                assert!((up - 10.0).abs() < 1e-9);
            } else {
                assert!((horizontal - 2.0).abs() < 1e-9 && up.abs() < 1e-9, "{i}");
            }
        }
        let last = t.poses.len() - 1;
        assert!((o.poses[last].m[11] - t.poses[last].m[11] - 30.0).abs() < 1e-9);
        assert!(t
            .odometry(&DriftOptions {
                breakdown: [5, 3],
                ..DriftOptions::default()
            })
            .is_err());
    }

    #[test]
    fn in_frame_starts_at_identity_and_keeps_relative_motion() {
        let t = straight(20.0, 2.0);
        let s = t.in_frame(&t.poses[0]);
        assert!(s.poses[0]
            .m
            .iter()
            .zip(Pose::IDENTITY.m)
            .all(|(a, b)| (a - b).abs() < 1e-12));
        let back = t.poses[0].compose(&s.poses[7]);
        assert!(back
            .m
            .iter()
            .zip(t.poses[7].m)
            .all(|(a, b)| (a - b).abs() < 1e-9));
    }
}
