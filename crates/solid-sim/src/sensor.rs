//! Sensor models as data: beam patterns, field-of-view limits, range limits, noise and dropout.

use crate::error::{check, try_vec, SimError};
use crate::pose::Pose;
use crate::rng::{mix_seed, Rng};
use crate::world::World;

/// How a sensor distributes its rays over one frame.
#[derive(Clone, Debug, PartialEq)]
pub enum Pattern {
    /// A spinning (or raster) multi-beam sensor: every column fires all beams.
    Spinning {
        /// Beam elevations in degrees (positive up).
        elevations_deg: Vec<f64>,
        /// Columns per full revolution; column `c` looks at azimuth `360·c/columns` degrees
        /// (counter-clockwise from +x) before the horizontal field-of-view window is applied.
        columns: usize,
    },
    /// A Livox-like non-repetitive rosette from two counter-rotating prisms: each emitter `e`
    /// at time `t` looks at `(u, v) = ½(cos θ₁ + cos θ₂, sin θ₁ + sin θ₂)` scaled to the half
    /// widths, with `θᵢ = 2π fᵢ t + 2π·frac(e·0.618…)` (emitters rotated by the golden angle). Frame `k` covers
    /// `[k·frame_period, (k+1)·frame_period)`, so consecutive frames see different rays.
    Rosette {
        /// Points per frame (over all emitters).
        points: usize,
        /// Half of the horizontal field of view, degrees.
        half_width_deg: f64,
        /// Half of the vertical field of view, degrees.
        half_height_deg: f64,
        /// Number of emitters (each a copy of the pattern rotated by 360°/emitters).
        emitters: usize,
        /// Rotation frequency of the first prism, Hz.
        f1_hz: f64,
        /// Rotation frequency of the second prism, Hz (negative = counter-rotating).
        f2_hz: f64,
        /// Duration of one frame, seconds.
        frame_period_s: f64,
    },
}

/// A LiDAR sensor: a ray pattern plus limits and noise.
#[derive(Clone, Debug, PartialEq)]
pub struct Sensor {
    /// Name of the model (for display).
    pub name: String,
    /// The ray pattern.
    pub pattern: Pattern,
    /// Width of the horizontal field-of-view window in degrees, (0, 360]; rays whose azimuth
    /// lies outside the window are not fired.
    pub h_fov_deg: f64,
    /// Centre of the horizontal window in degrees (0 = straight ahead, +90 = left).
    pub h_centre_deg: f64,
    /// Returns closer than this are discarded, metres.
    pub min_range: f64,
    /// Rays are cast up to this range; farther surfaces give no return, metres.
    pub max_range: f64,
    /// Standard deviation of the Gaussian range noise, metres (0 = exact).
    pub range_noise_sd: f64,
    /// Probability that a return is dropped.
    pub dropout: f64,
    /// Seed of the noise and dropout streams (combined with the frame index).
    pub noise_seed: u64,
}

/// Names accepted by [`Sensor::preset`].
pub const SENSOR_PRESETS: [&str; 5] = ["hdl64", "vlp16", "os1-64", "avia", "aeva"];

/// HDL-64E beam elevations: upper block of 32 lasers from +2.0° to −8.33° (≈1/3° apart), lower
/// block of 32 from −8.83° to −24.33° (0.5° apart), per the HDL-64E S2 data sheet (26.9° vertical
/// field of view, nominally +2° to −24.8°).
pub fn hdl64_elevations() -> Vec<f64> {
    let upper = (0..32).map(|i| 2.0 - i as f64 * (10.33 / 31.0));
    let lower = (0..32).map(|i| -8.83 - i as f64 * 0.5);
    upper.chain(lower).collect()
}

fn uniform_elevations(n: usize, lo: f64, hi: f64) -> Vec<f64> {
    (0..n)
        .map(|i| hi - i as f64 * (hi - lo) / (n - 1) as f64)
        .collect()
}

fn spinning(
    name: &str,
    elevations_deg: Vec<f64>,
    columns: usize,
    max_range: f64,
    sd: f64,
) -> Sensor {
    Sensor {
        name: name.to_string(),
        pattern: Pattern::Spinning {
            elevations_deg,
            columns,
        },
        h_fov_deg: 360.0,
        h_centre_deg: 0.0,
        min_range: 1.0,
        max_range,
        range_noise_sd: sd,
        dropout: 0.0,
        noise_seed: 0,
    }
}

impl Sensor {
    /// A preset sensor model:
    /// - `hdl64`: Velodyne HDL-64E, 64 beams ([`hdl64_elevations`]), 2083 columns (≈0.17° at
    ///   10 Hz), 120 m, σ = 2 cm;
    /// - `vlp16`: Velodyne VLP-16, 16 beams from −15° to +15° every 2°, 1800 columns (0.2°),
    ///   100 m, σ = 3 cm;
    /// - `os1-64`: Ouster OS1-64, 64 beams uniform over ±22.5°, 1024 columns, 120 m, σ = 3 cm;
    /// - `avia`: Livox-Avia-like rosette over 70.4° × 77.2°, 24 000 points per 0.1 s frame,
    ///   6 emitters, 190 m, σ = 2 cm;
    /// - `aeva`: Aeva-Aeries-II-like raster, 64 lines uniform over ±9.6°, 120° horizontal at
    ///   0.12° (1000 columns in the window), 250 m, σ = 2 cm.
    ///
    /// All start with a 1 m minimum range, no dropout and noise seed 0.
    ///
    /// # Errors
    /// [`SimError::UnknownName`] for any other name.
    pub fn preset(name: &str) -> Result<Sensor, SimError> {
        Ok(match name {
            "hdl64" => spinning(name, hdl64_elevations(), 2083, 120.0, 0.02),
            "vlp16" => spinning(name, uniform_elevations(16, -15.0, 15.0), 1800, 100.0, 0.03),
            "os1-64" => spinning(name, uniform_elevations(64, -22.5, 22.5), 1024, 120.0, 0.03),
            "aeva" => Sensor {
                h_fov_deg: 120.0,
                ..spinning(name, uniform_elevations(64, -9.6, 9.6), 3000, 250.0, 0.02)
            },
            "avia" => Sensor {
                name: name.to_string(),
                pattern: Pattern::Rosette {
                    points: 24_000,
                    half_width_deg: 35.2,
                    half_height_deg: 38.6,
                    emitters: 6,
                    f1_hz: 117.3,
                    f2_hz: -83.9,
                    frame_period_s: 0.1,
                },
                h_fov_deg: 360.0,
                h_centre_deg: 0.0,
                min_range: 1.0,
                max_range: 190.0,
                range_noise_sd: 0.02,
                dropout: 0.0,
                noise_seed: 0,
            },
            _ => {
                return Err(SimError::UnknownName {
                    what: "sensor preset",
                    name: name.to_string(),
                })
            }
        })
    }

    /// Checks every parameter.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the first invalid parameter.
    pub fn validate(&self) -> Result<(), SimError> {
        check(
            "h_fov_deg",
            self.h_fov_deg,
            self.h_fov_deg > 0.0 && self.h_fov_deg <= 360.0,
            "(0, 360]",
        )?;
        check(
            "h_centre_deg",
            self.h_centre_deg,
            self.h_centre_deg.abs() <= 360.0,
            "[-360, 360]",
        )?;
        check("min_range", self.min_range, self.min_range >= 0.0, ">= 0")?;
        check(
            "max_range",
            self.max_range,
            self.max_range > self.min_range && self.max_range <= 10_000.0,
            "(min_range, 10000]",
        )?;
        check(
            "range_noise_sd",
            self.range_noise_sd,
            self.range_noise_sd >= 0.0 && self.range_noise_sd <= 10.0,
            "[0, 10]",
        )?;
        check(
            "dropout",
            self.dropout,
            (0.0..=1.0).contains(&self.dropout),
            "[0, 1]",
        )?;
        match &self.pattern {
            Pattern::Spinning {
                elevations_deg,
                columns,
            } => {
                check(
                    "columns",
                    *columns as f64,
                    (1..=100_000).contains(columns),
                    "1..=100000",
                )?;
                check(
                    "elevations",
                    elevations_deg.len() as f64,
                    (1..=1024).contains(&elevations_deg.len()),
                    "1..=1024 beams",
                )?;
                for &e in elevations_deg {
                    check("elevation", e, e.abs() <= 90.0, "[-90, 90] degrees")?;
                }
            }
            Pattern::Rosette {
                points,
                half_width_deg,
                half_height_deg,
                emitters,
                f1_hz,
                f2_hz,
                frame_period_s,
            } => {
                check(
                    "points",
                    *points as f64,
                    (1..=10_000_000).contains(points),
                    "1..=10000000",
                )?;
                check(
                    "half_width_deg",
                    *half_width_deg,
                    *half_width_deg > 0.0 && *half_width_deg <= 90.0,
                    "(0, 90]",
                )?;
                check(
                    "half_height_deg",
                    *half_height_deg,
                    *half_height_deg > 0.0 && *half_height_deg <= 90.0,
                    "(0, 90]",
                )?;
                check(
                    "emitters",
                    *emitters as f64,
                    (1..=128).contains(emitters),
                    "1..=128",
                )?;
                check("f1_hz", *f1_hz, f1_hz.abs() <= 1e5, "|f| <= 1e5")?;
                check("f2_hz", *f2_hz, f2_hz.abs() <= 1e5, "|f| <= 1e5")?;
                check(
                    "frame_period_s",
                    *frame_period_s,
                    *frame_period_s > 0.0 && *frame_period_s <= 10.0,
                    "(0, 10]",
                )?;
            }
        }
        Ok(())
    }

    /// Returns a copy with the horizontal window set to `width_deg` centred on `centre_deg`.
    pub fn with_h_fov(&self, width_deg: f64, centre_deg: f64) -> Sensor {
        Sensor {
            h_fov_deg: width_deg,
            h_centre_deg: centre_deg,
            ..self.clone()
        }
    }

    /// Unit ray directions (sensor frame) of frame `frame`, after the horizontal window.
    pub fn ray_directions(&self, frame: u64) -> Vec<[f64; 3]> {
        let half = self.h_fov_deg / 2.0;
        let in_window = |az_deg: f64| {
            self.h_fov_deg >= 360.0 || wrap180(az_deg - self.h_centre_deg).abs() <= half
        };
        let mut dirs = Vec::new();
        match &self.pattern {
            Pattern::Spinning {
                elevations_deg,
                columns,
            } => {
                let elev: Vec<(f64, f64)> = elevations_deg
                    .iter()
                    .map(|e| libm::sincos(e.to_radians()))
                    .collect();
                for c in 0..*columns {
                    let az = 360.0 * c as f64 / *columns as f64;
                    if !in_window(az) {
                        continue;
                    }
                    let (sa, ca) = libm::sincos(az.to_radians());
                    for &(se, ce) in &elev {
                        dirs.push([ce * ca, ce * sa, se]);
                    }
                }
            }
            Pattern::Rosette {
                points,
                half_width_deg,
                half_height_deg,
                emitters,
                f1_hz,
                f2_hz,
                frame_period_s,
            } => {
                let per_emitter = points.div_ceil(*emitters);
                let dt = frame_period_s / per_emitter as f64;
                let t0 = frame as f64 * frame_period_s;
                let tau = core::f64::consts::TAU;
                for i in 0..*points {
                    let e = i % emitters;
                    let t = t0 + (i / emitters) as f64 * dt;
                    // Emitter copies are rotated by multiples of the golden angle, so their petals
                    // interleave instead of falling onto each other's.
                    let phase = tau * frac(e as f64 * GOLDEN);
                    // Phases reduced modulo one turn before scaling keep precision for late frames.
                    let th1 = tau * frac(f1_hz * t) + phase;
                    let th2 = tau * frac(f2_hz * t) + phase;
                    let (s1, c1) = libm::sincos(th1);
                    let (s2, c2) = libm::sincos(th2);
                    let u = 0.5 * (c1 + c2) * half_width_deg;
                    let v = 0.5 * (s1 + s2) * half_height_deg;
                    if self.h_fov_deg < 360.0 && u.abs() > half {
                        continue;
                    }
                    let (sa, ca) = libm::sincos((self.h_centre_deg + u).to_radians());
                    let (se, ce) = libm::sincos(v.to_radians());
                    dirs.push([ce * ca, ce * sa, se]);
                }
            }
        }
        dirs
    }

    /// Simulates frame `frame` seen from `pose` (`T_world_sensor`) and returns the points in the
    /// sensor frame as `[x, y, z, intensity]`, intensity = reflectivity · |cos incidence| in [0, 1].
    /// Rays with no surface within `max_range`, returns closer than `min_range`, and dropped
    /// returns give no point. The noise stream depends only on (`noise_seed`, `frame`).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] when [`Sensor::validate`] fails; [`SimError::OutOfMemory`]
    /// when the points do not fit in memory.
    pub fn scan(&self, world: &World, pose: &Pose, frame: u64) -> Result<Vec<[f32; 4]>, SimError> {
        self.validate()?;
        let dirs = self.ray_directions(frame);
        let mut rng = Rng::new(mix_seed(&[self.noise_seed, frame]));
        let origin = pose.translation();
        let mut out = try_vec(dirs.len(), "scan points")?;
        for ds in dirs {
            let dropped = self.dropout > 0.0 && rng.chance(self.dropout);
            let noise = if self.range_noise_sd > 0.0 {
                rng.gaussian() * self.range_noise_sd
            } else {
                0.0
            };
            let d = pose.rotate(ds);
            let Some(hit) = world.cast(origin, d, self.max_range) else {
                continue;
            };
            let range = hit.t + noise;
            if dropped
                || hit.t <= self.min_range
                || range <= self.min_range
                || range >= self.max_range
            {
                continue;
            }
            let cos = -(d[0] * hit.normal[0] + d[1] * hit.normal[1] + d[2] * hit.normal[2]);
            let intensity = (f64::from(hit.reflectivity) * cos.abs()).clamp(0.0, 1.0);
            out.push([
                (ds[0] * range) as f32,
                (ds[1] * range) as f32,
                (ds[2] * range) as f32,
                intensity as f32,
            ]);
        }
        Ok(out)
    }
}

/// (√5 − 1) / 2.
const GOLDEN: f64 = 0.618_033_988_749_894_8;

fn frac(x: f64) -> f64 {
    x - libm::floor(x)
}

/// Wraps an angle in degrees into (−180, 180].
pub fn wrap180(a: f64) -> f64 {
    let r = a - 360.0 * libm::floor(a / 360.0); // [0, 360)
    if r > 180.0 {
        r - 360.0
    } else {
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hdl64_beams_follow_the_data_sheet() {
        let e = hdl64_elevations();
        assert_eq!(e.len(), 64);
        assert_eq!(e[0], 2.0);
        assert!((e[31] + 8.33).abs() < 1e-12);
        assert!((e[32] + 8.83).abs() < 1e-12);
        assert!((e[63] + 24.33).abs() < 1e-12);
        assert!(e.windows(2).all(|w| w[1] < w[0]));
    }

    #[test]
    fn presets_validate_and_have_expected_ray_counts() {
        for name in SENSOR_PRESETS {
            let s = Sensor::preset(name).unwrap();
            s.validate().unwrap();
            let n = s.ray_directions(0).len();
            let expected = match name {
                "hdl64" => 64 * 2083,
                "vlp16" => 16 * 1800,
                "os1-64" => 64 * 1024,
                "avia" => 24_000,
                _ => 64 * 1001, // 120° window at 0.12° includes both edges
            };
            assert_eq!(n, expected, "{name}");
        }
        assert!(Sensor::preset("nope").is_err());
    }

    #[test]
    fn fov_window_limits_azimuths() {
        let s = Sensor::preset("vlp16").unwrap().with_h_fov(60.0, 90.0);
        for d in s.ray_directions(0) {
            let az = libm::atan2(d[1], d[0]).to_degrees();
            assert!((az - 90.0).abs() <= 30.0 + 1e-9, "{az}");
        }
        let avia = Sensor::preset("avia").unwrap();
        let (mut max_az, mut max_el) = (0.0f64, 0.0f64);
        for d in avia.ray_directions(3) {
            let az = libm::atan2(d[1], d[0]).to_degrees();
            let el = libm::asin(d[2]).to_degrees();
            max_az = max_az.max(az.abs());
            max_el = max_el.max(el.abs());
        }
        assert!(max_az <= 35.2 + 1e-9 && max_az > 34.0, "{max_az}");
        assert!(max_el <= 38.6 + 1e-9 && max_el > 37.0, "{max_el}");
        assert_ne!(
            avia.ray_directions(0),
            avia.ray_directions(1),
            "rosette must not repeat"
        );
    }

    #[test]
    fn scan_is_deterministic_and_noise_depends_on_seed() {
        let world = World::city(0, 2);
        let pose = Pose::from_xyz_yaw(5.0, -1.75, world.ground_height(5.0, -1.75) + 1.73, 0.0);
        let mut s = Sensor::preset("vlp16").unwrap();
        s.dropout = 0.1;
        let a = s.scan(&world, &pose, 7).unwrap();
        let b = s.scan(&world, &pose, 7).unwrap();
        assert_eq!(a, b);
        assert!(a.len() > 15_000, "{}", a.len());
        let c = s.scan(&world, &pose, 8).unwrap();
        assert_ne!(a, c);
        s.noise_seed = 1;
        assert_ne!(a, s.scan(&world, &pose, 7).unwrap());
    }

    #[test]
    fn noiseless_ranges_are_exact_and_intensity_bounded() {
        let world = World::city(0, 2);
        let pose = Pose::from_xyz_yaw(0.0, 1.75, world.ground_height(0.0, 1.75) + 1.73, 30.0);
        let mut s = Sensor::preset("vlp16").unwrap();
        s.range_noise_sd = 0.0;
        let pts = s.scan(&world, &pose, 0).unwrap();
        for p in pts.iter().step_by(97) {
            let v = [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])];
            let r = libm::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            let d = pose.rotate([v[0] / r, v[1] / r, v[2] / r]);
            let hit = world
                .cast_brute_force(pose.translation(), d, s.max_range)
                .unwrap();
            assert!((hit.t - r).abs() < 1e-4, "{} vs {r}", hit.t);
            assert!((0.0..=1.0).contains(&p[3]));
        }
    }
}
