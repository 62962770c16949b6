//! Descriptor configuration ([spec §1](crate::spec#1-parameters)) and sensor presets ([spec §4](crate::spec#4-sensor-presets)).

use crate::params::{field, Field, Kind, Params, FINITE};
use crate::Error;

/// Bound on `max_range / voxel_size` (voxel keys pack 21 bits per axis, which leaves a margin for rounding).
pub const MAX_VOXELS_PER_AXIS: f64 = (1u64 << 19) as f64;

/// The parameters of the SOLiD descriptor ([spec §1](crate::spec#1-parameters)).
///
/// Fields are public; [`Config::validate`] checks them and every function that takes a `Config`
/// validates it first, so an invalid value is an error naming the parameter, never a clamp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Config {
    /// Number of range bins over `[0, max_range)` (1..=1024).
    pub n_range: usize,
    /// Number of azimuth bins over `[0°, 360°)` (1..=3600).
    pub n_azimuth: usize,
    /// Number of elevation bins over `[fov_down, fov_up)` (1..=1024).
    pub n_elevation: usize,
    /// Upper edge of the vertical field of view, degrees, in `[-90, 90]`.
    pub fov_up: f64,
    /// Lower edge of the vertical field of view, degrees, in `[-90, 90]`, below `fov_up`.
    pub fov_down: f64,
    /// Points with 3-D norm `<= min_range` (metres) are dropped; `0 <= min_range < max_range`.
    pub min_range: f64,
    /// Points with 3-D norm `>= max_range` (metres) are dropped.
    pub max_range: f64,
    /// Voxel edge in metres; `0` disables downsampling. Otherwise at least
    /// `max_range / 2^19` (voxel keys hold 2^19 voxels per axis on each side of the sensor).
    pub voxel_size: f64,
}

/// A named sensor preset ([spec §4](crate::spec#4-sensor-presets)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Preset {
    /// The preset's name, as accepted by [`Config::preset`].
    pub name: &'static str,
    /// The sensor it describes.
    pub sensor: &'static str,
    /// Its configuration ([spec §1](crate::spec#1-parameters) defaults for everything the sensor does not fix).
    pub config: Config,
    /// The loop detector's default threshold for this sensor (largest accepted R-SOLiD cosine
    /// distance), chosen from the F1-max thresholds measured on the shared data and the
    /// simulator: see [`LOOP_THRESHOLD_MEASUREMENT`].
    pub loop_threshold: f64,
    /// The sensor's horizontal field of view (degrees, 360 for a spinning sensor). Not a
    /// descriptor parameter (SOLiD bins all of 360°).
    pub h_fov: f64,
}

/// How the presets' loop thresholds were measured (`make thresholds`; figures in
/// docs/performance.md#loop-thresholds).
pub const LOOP_THRESHOLD_MEASUREMENT: &str = "tools/thresholds.py: F1-max thresholds of the shipped pipeline on the simulator (all presets) and hku1-avia (avia); hdl32 = median of hdl64, vlp16, os1-64";

const fn sensor(fov_up: f64, fov_down: f64, n_elevation: usize, max_range: f64) -> Config {
    Config {
        max_range,
        ..Config::with_defaults(fov_up, fov_down, n_elevation)
    }
}

/// The sensor presets of [spec §4](crate::spec#4-sensor-presets).
pub const PRESETS: [Preset; 6] = [
    Preset {
        name: "hdl64",
        sensor: "Velodyne HDL-64E (KITTI)",
        config: sensor(2.0, -24.8, 64, 80.0),
        loop_threshold: 0.0111,
        h_fov: 360.0,
    },
    Preset {
        name: "hdl32",
        sensor: "Velodyne HDL-32E (NCLT)",
        config: sensor(10.67, -30.67, 32, 80.0),
        loop_threshold: 0.0211,
        h_fov: 360.0,
    },
    Preset {
        name: "vlp16",
        sensor: "Velodyne VLP-16",
        config: sensor(15.0, -15.0, 16, 80.0),
        loop_threshold: 0.0217,
        h_fov: 360.0,
    },
    Preset {
        name: "os1-64",
        sensor: "Ouster OS1-64",
        config: sensor(22.5, -22.5, 64, 80.0),
        loop_threshold: 0.0211,
        h_fov: 360.0,
    },
    Preset {
        name: "avia",
        sensor: "Livox Avia",
        config: sensor(38.6, -38.6, 64, 120.0),
        loop_threshold: 0.0340,
        h_fov: 70.4,
    },
    Preset {
        name: "aeva",
        sensor: "Aeva Aeries II",
        config: sensor(9.6, -9.6, 64, 120.0),
        loop_threshold: 0.0248,
        h_fov: 120.0,
    },
];

/// The default number of range bins ([`Config::with_defaults`]), which every preset keeps.
pub(crate) const DEFAULT_N_RANGE: usize = 40;
/// The default number of azimuth bins ([`Config::with_defaults`]), which every preset keeps.
pub(crate) const DEFAULT_N_AZIMUTH: usize = 60;

impl Preset {
    /// The preset called `name` (`hdl64`, `hdl32`, `vlp16`, `os1-64`, `avia`, `aeva`).
    ///
    /// # Errors
    /// [`Error::UnknownPreset`] for any other name.
    pub fn find(name: &str) -> Result<&'static Preset, Error> {
        PRESETS
            .iter()
            .find(|p| p.name == name)
            .ok_or(Error::UnknownPreset)
    }
}

impl Config {
    /// A config for a sensor's vertical field of view and channel count, with the [spec §1](crate::spec#1-parameters)
    /// defaults for everything else: 40 range bins, 60 azimuth bins, ranges (3, 80) m, voxel
    /// 0.5 m. The one place these defaults are written.
    pub const fn with_defaults(fov_up: f64, fov_down: f64, n_elevation: usize) -> Config {
        Config {
            n_range: DEFAULT_N_RANGE,
            n_azimuth: DEFAULT_N_AZIMUTH,
            n_elevation,
            fov_up,
            fov_down,
            min_range: 3.0,
            max_range: 80.0,
            voxel_size: 0.5,
        }
    }

    /// The configuration of a named preset (`hdl64`, `hdl32`, `vlp16`, `os1-64`, `avia`, `aeva`).
    ///
    /// # Errors
    /// [`Error::UnknownPreset`] for any other name.
    pub fn preset(name: &str) -> Result<Config, Error> {
        Preset::find(name).map(|p| p.config)
    }

    /// Checks every parameter against [spec §1](crate::spec#1-parameters): each against its
    /// range in [`Config::FIELDS`], then the rules between them.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the first invalid parameter.
    pub fn validate(&self) -> Result<(), Error> {
        self.check_fields()?;
        if self.fov_down >= self.fov_up {
            return Err(Error::invalid(
                "fov_down",
                self.fov_down,
                "a value below fov_up",
            ));
        }
        if self.max_range <= self.min_range {
            return Err(Error::invalid(
                "max_range",
                self.max_range,
                "a finite value above min_range",
            ));
        }
        if self.voxel_size > 0.0 && self.max_range / self.voxel_size >= MAX_VOXELS_PER_AXIS {
            return Err(Error::invalid(
                "voxel_size",
                self.voxel_size,
                "0, or at least max_range / 2^19 (at most 2^19 voxels per axis within max_range)",
            ));
        }
        Ok(())
    }

    /// A 64-bit fingerprint of every parameter (FNV-1a over their little-endian bytes).
    ///
    /// Two descriptors are comparable only when their configurations have the same fingerprint.
    pub fn fingerprint(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |bytes: [u8; 8]| {
            for b in bytes {
                h ^= u64::from(b);
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        };
        eat((self.n_range as u64).to_le_bytes());
        eat((self.n_azimuth as u64).to_le_bytes());
        eat((self.n_elevation as u64).to_le_bytes());
        for v in [
            self.fov_up,
            self.fov_down,
            self.min_range,
            self.max_range,
            self.voxel_size,
        ] {
            // `+ 0.0` turns -0.0 into +0.0: configs that compare equal fingerprint equally.
            eat((v + 0.0).to_bits().to_le_bytes());
        }
        h
    }
}

/// An angle of the vertical field of view.
const ANGLE: Kind = Kind::closed(-90.0, 90.0);

impl Params for Config {
    const NAME: &'static str = "SolidConfig";
    const FIELDS: &'static [Field<Config>] = &[
        field!(
            Config,
            "n_range",
            n_range,
            Kind::Int { min: 1, max: 1024 },
            "an integer in 1..=1024",
            "Range bins over [0, max_range): the length of R-SOLiD."
        ),
        field!(
            Config,
            "n_azimuth",
            n_azimuth,
            Kind::Int { min: 1, max: 3600 },
            "an integer in 1..=3600",
            "Azimuth bins over [0°, 360°): the length of A-SOLiD."
        ),
        field!(
            Config,
            "n_elevation",
            n_elevation,
            Kind::Int { min: 1, max: 1024 },
            "an integer in 1..=1024",
            "Elevation bins over [fov_down, fov_up) (the sensor's channels).",
            required = true
        ),
        field!(
            Config,
            "fov_up",
            fov_up,
            ANGLE,
            "a finite angle in [-90, 90] degrees",
            "Upper edge of the vertical field of view, degrees.",
            required = true
        ),
        field!(
            Config,
            "fov_down",
            fov_down,
            ANGLE,
            "a finite angle in [-90, 90] degrees",
            "Lower edge of the vertical field of view, degrees, below fov_up.",
            required = true,
            rule = "below `fov_up`"
        ),
        field!(
            Config,
            "min_range",
            min_range,
            Kind::closed(0.0, FINITE),
            "a finite value >= 0 metres",
            "Points at or within this distance (metres, 3-D) are dropped."
        ),
        field!(
            Config,
            "max_range",
            max_range,
            Kind::closed(-FINITE, FINITE),
            "a finite value above min_range",
            "Points at or beyond this distance (metres, 3-D) are dropped.",
            rule = "above `min_range`"
        ),
        field!(
            Config,
            "voxel_size",
            voxel_size,
            Kind::closed(0.0, FINITE),
            "a finite value >= 0 metres (0 disables downsampling)",
            "Voxel edge in metres for downsampling (0: none).",
            rule = "when > 0, `max_range / voxel_size` < 2^19"
        ),
    ];

    fn defaults() -> Config {
        Config::with_defaults(f64::NAN, f64::NAN, 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_valid_and_found_by_name() {
        for p in PRESETS {
            p.config.validate().unwrap();
            assert_eq!(Config::preset(p.name).unwrap(), p.config);
        }
        assert_eq!(Config::preset("hdl-64"), Err(Error::UnknownPreset));
    }

    #[test]
    fn invalid_values_name_the_parameter() {
        let base = PRESETS[0].config;
        let cases: [(Config, &str); 10] = [
            (Config { n_range: 0, ..base }, "n_range"),
            (
                Config {
                    n_azimuth: 3601,
                    ..base
                },
                "n_azimuth",
            ),
            (
                Config {
                    n_elevation: 1025,
                    ..base
                },
                "n_elevation",
            ),
            (
                Config {
                    fov_up: 91.0,
                    ..base
                },
                "fov_up",
            ),
            (
                Config {
                    fov_down: f64::NAN,
                    ..base
                },
                "fov_down",
            ),
            (
                Config {
                    fov_down: 2.0,
                    ..base
                },
                "fov_down",
            ),
            (
                Config {
                    min_range: -1.0,
                    ..base
                },
                "min_range",
            ),
            (
                Config {
                    max_range: 3.0,
                    ..base
                },
                "max_range",
            ),
            (
                Config {
                    voxel_size: f64::INFINITY,
                    ..base
                },
                "voxel_size",
            ),
            (
                Config {
                    voxel_size: 1e-5,
                    ..base
                },
                "voxel_size",
            ),
        ];
        for (cfg, name) in cases {
            match cfg.validate() {
                Err(Error::InvalidParameter { name: got, .. }) => assert_eq!(got, name),
                other => panic!("{name}: expected InvalidParameter, got {other:?}"),
            }
        }
    }

    #[test]
    fn fingerprint_separates_configs() {
        let a = PRESETS[0].config;
        let b = Config {
            voxel_size: 0.4,
            ..a
        };
        assert_eq!(a.fingerprint(), PRESETS[0].config.fingerprint());
        assert_ne!(a.fingerprint(), b.fingerprint());
    }
}
