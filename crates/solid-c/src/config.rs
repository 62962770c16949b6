//! Configuration handles: the descriptor's ([`SolidConfig`]), the loop detector's
//! ([`SolidDetectorConfig`]) and registration's ([`SolidRegConfig`]), each made from defaults and
//! changed one parameter at a time by name (the names of the core's parameter tables).

use std::ffi::c_char;

use solid_lidar::db::DetectorConfig;
use solid_lidar::reg::RegConfig;
use solid_lidar::Config;

use crate::{guard, nonnull, out, release, string, Failure, SolidStatus};

/// A parameter value as the tables hold it.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Value {
    Bool(bool),
    Int(u64),
    Float(f64),
}

/// A parameter struct whose fields are read and written by name.
trait Named: Sized + Copy {
    fn get(&self, name: &str) -> Option<Value>;
    fn set(&mut self, name: &str, v: Value) -> Result<(), Failure>;
    fn check(&self) -> Result<(), Failure>;
}

fn unknown(name: &str) -> Failure {
    Failure::arg(format!("unknown parameter {name:?}"))
}

macro_rules! named {
    ($ty:ty, $check:expr, { $($name:literal => $field:ident $(. $sub:ident)* : $kind:ident),* $(,)? }) => {
        impl Named for $ty {
            fn get(&self, name: &str) -> Option<Value> {
                match name {
                    $($name => Some(named!(@get $kind, self.$field $(. $sub)*)),)*
                    _ => None,
                }
            }
            fn set(&mut self, name: &str, v: Value) -> Result<(), Failure> {
                match (name, v) {
                    $(($name, named!(@pat $kind, x)) => self.$field $(. $sub)* = named!(@set $kind, x),)*
                    _ => return Err(unknown(name)),
                }
                Ok(())
            }
            fn check(&self) -> Result<(), Failure> {
                let f: fn(&$ty) -> Result<(), Failure> = $check;
                f(self)
            }
        }
    };
    (@get bool, $e:expr) => { Value::Bool($e) };
    (@get usize, $e:expr) => { Value::Int($e as u64) };
    (@get u8, $e:expr) => { Value::Int(u64::from($e)) };
    (@get f64, $e:expr) => { Value::Float($e) };
    (@pat bool, $x:ident) => { Value::Bool($x) };
    (@pat usize, $x:ident) => { Value::Int($x) };
    (@pat u8, $x:ident) => { Value::Int($x) };
    (@pat f64, $x:ident) => { Value::Float($x) };
    (@set bool, $x:ident) => { $x };
    (@set usize, $x:ident) => { usize::try_from($x).unwrap_or(usize::MAX) };
    (@set u8, $x:ident) => { u8::try_from($x).unwrap_or(u8::MAX) };
    (@set f64, $x:ident) => { $x };
}

named!(Config, |c| Ok(c.validate()?), {
    "n_range" => n_range: usize,
    "n_azimuth" => n_azimuth: usize,
    "n_elevation" => n_elevation: usize,
    "fov_up" => fov_up: f64,
    "fov_down" => fov_down: f64,
    "min_range" => min_range: f64,
    "max_range" => max_range: f64,
    "voxel_size" => voxel_size: f64,
});

named!(DetectorConfig, |c| Ok(c.validate()?), {
    "exclude_frames" => exclude_frames: usize,
    "exclude_meters" => exclude_meters: f64,
    "exclude_seconds" => exclude_seconds: f64,
    "threshold" => threshold: f64,
    "top_k" => top_k: usize,
    "rerank" => rerank: bool,
    "verify" => verify.enabled: bool,
    "verify_candidates" => verify.candidates: usize,
    "verify_hypotheses" => verify.hypotheses: usize,
    "verify_fan_deg" => verify.fan_deg: f64,
    "cloud_bits" => verify.cloud_bits: u8,
    "cache_bytes" => verify.cache_bytes: usize,
    "verify_threads" => verify.threads: usize,
    "max_loop_distance" => verify.gate.max_translation: f64,
});

named!(RegConfig, |c| Ok(c.validate()?), {
    "voxel_size" => voxel_size: f64,
    "coarse_voxel_size" => coarse_voxel_size: f64,
    "min_range" => min_range: f64,
    "max_range" => max_range: f64,
    "neighbors" => neighbors: usize,
    "max_correspondence" => max_correspondence: f64,
    "coarse_max_correspondence" => coarse_max_correspondence: f64,
    "max_iterations" => max_iterations: usize,
    "rotation_eps_deg" => rotation_eps_deg: f64,
    "translation_eps" => translation_eps: f64,
    "kernel_scale" => kernel_scale: f64,
    "inlier_distance" => inlier_distance: f64,
});

/// Sets parameter `name` of `p` from a C double, converted to the parameter's kind, and checks
/// the whole struct: on error `p` is unchanged.
fn set_by_name<P: Named>(p: &mut P, name: &str, value: f64) -> Result<(), Failure> {
    let bad = |expected: &str| {
        Failure::new(
            SolidStatus::InvalidParameter,
            format!("invalid {name} = {value}: expected {expected}"),
        )
    };
    let v = match p.get(name).ok_or_else(|| unknown(name))? {
        Value::Bool(_) if value == 0.0 || value == 1.0 => Value::Bool(value == 1.0),
        Value::Bool(_) => return Err(bad("0 (false) or 1 (true)")),
        // Integers up to 2^53 are exact in a double.
        Value::Int(_)
            if (0.0..=9_007_199_254_740_992.0).contains(&value) && value.fract() == 0.0 =>
        {
            Value::Int(value as u64)
        }
        Value::Int(_) => return Err(bad("a non-negative integer")),
        Value::Float(_) => Value::Float(value),
    };
    let mut changed = *p;
    changed.set(name, v)?;
    changed.check()?;
    *p = changed;
    Ok(())
}

/// Parameter `name` of `p` as a double (booleans as 0 or 1).
fn get_by_name<P: Named>(p: &P, name: &str) -> Result<f64, Failure> {
    Ok(match p.get(name).ok_or_else(|| unknown(name))? {
        Value::Bool(b) => f64::from(u8::from(b)),
        Value::Int(i) => i as f64,
        Value::Float(f) => f,
    })
}

/// The descriptor's parameters (docs/spec.md §1: `n_range`, `n_azimuth`, `n_elevation`, `fov_up`,
/// `fov_down`, `min_range`, `max_range`, `voxel_size`).
///
/// Threads: a config that no thread changes may be read from several threads at once.
pub struct SolidConfig {
    pub(crate) cfg: Config,
}

/// The loop detector's parameters (the names of `solid config dump`'s `detector` section, such
/// as `exclude_frames`, `threshold`, `verify`, `verify_candidates`, `max_loop_distance`).
///
/// Threads: as [`SolidConfig`].
pub struct SolidDetectorConfig {
    pub(crate) cfg: DetectorConfig,
}

/// Registration's parameters (`voxel_size`, `max_correspondence`, `max_iterations`, ...).
///
/// Threads: as [`SolidConfig`].
pub struct SolidRegConfig {
    pub(crate) cfg: RegConfig,
}

/// Makes the descriptor configuration of a sensor preset (`"hdl64"`, `"hdl32"`, `"vlp16"`,
/// `"os1-64"`, `"avia"`, `"aeva"`; docs/spec.md §4) in `*out`; release it with
/// [`solid_config_free`].
#[no_mangle]
pub unsafe extern "C" fn solid_config_new(
    preset: *const c_char,
    out_config: *mut *mut SolidConfig,
) -> SolidStatus {
    guard("solid_config_new", || {
        let o = out(out_config, "out_config")?;
        let cfg = Config::preset(string(preset, "preset")?)?;
        crate::give(o, SolidConfig { cfg });
        Ok(())
    })
}

/// Releases a configuration (NULL: nothing).
#[no_mangle]
pub unsafe extern "C" fn solid_config_free(config: *mut SolidConfig) {
    release(config);
}

/// Sets descriptor parameter `name` to `value` (integers as whole doubles). The whole
/// configuration is checked: an invalid value is refused with a message naming it, and the
/// configuration stays as it was.
#[no_mangle]
pub unsafe extern "C" fn solid_config_set(
    config: *mut SolidConfig,
    name: *const c_char,
    value: f64,
) -> SolidStatus {
    guard("solid_config_set", || {
        let c = out(config, "config")?;
        set_by_name(&mut c.cfg, string(name, "name")?, value)
    })
}

/// Reads descriptor parameter `name` into `*value`.
#[no_mangle]
pub unsafe extern "C" fn solid_config_get(
    config: *const SolidConfig,
    name: *const c_char,
    value: *mut f64,
) -> SolidStatus {
    guard("solid_config_get", || {
        let c = nonnull(config, "config")?;
        let v = get_by_name(&c.cfg, string(name, "name")?)?;
        *out(value, "value")? = v;
        Ok(())
    })
}

/// The lengths of the R-SOLiD (`n_range`) and A-SOLiD (`n_azimuth`) vectors of this
/// configuration: the sizes of the output buffers of `solid_describe`.
#[no_mangle]
pub unsafe extern "C" fn solid_config_lengths(
    config: *const SolidConfig,
    n_range: *mut usize,
    n_azimuth: *mut usize,
) -> SolidStatus {
    guard("solid_config_lengths", || {
        let c = nonnull(config, "config")?;
        let (r, a) = (out(n_range, "n_range")?, out(n_azimuth, "n_azimuth")?);
        (*r, *a) = (c.cfg.n_range, c.cfg.n_azimuth);
        Ok(())
    })
}

/// Makes the loop detector's defaults for a sensor preset (its measured loop threshold) in
/// `*out`; release it with [`solid_detector_config_free`].
#[no_mangle]
pub unsafe extern "C" fn solid_detector_config_new(
    preset: *const c_char,
    out_config: *mut *mut SolidDetectorConfig,
) -> SolidStatus {
    guard("solid_detector_config_new", || {
        let o = out(out_config, "out_config")?;
        let cfg = DetectorConfig::for_preset(string(preset, "preset")?)?;
        crate::give(o, SolidDetectorConfig { cfg });
        Ok(())
    })
}

/// Releases a detector configuration (NULL: nothing).
#[no_mangle]
pub unsafe extern "C" fn solid_detector_config_free(config: *mut SolidDetectorConfig) {
    release(config);
}

/// Sets detector parameter `name` to `value` (booleans as 0 or 1, integers as whole doubles);
/// checked as [`solid_config_set`].
#[no_mangle]
pub unsafe extern "C" fn solid_detector_config_set(
    config: *mut SolidDetectorConfig,
    name: *const c_char,
    value: f64,
) -> SolidStatus {
    guard("solid_detector_config_set", || {
        let c = out(config, "config")?;
        set_by_name(&mut c.cfg, string(name, "name")?, value)
    })
}

/// Reads detector parameter `name` into `*value` (booleans as 0 or 1).
#[no_mangle]
pub unsafe extern "C" fn solid_detector_config_get(
    config: *const SolidDetectorConfig,
    name: *const c_char,
    value: *mut f64,
) -> SolidStatus {
    guard("solid_detector_config_get", || {
        let c = nonnull(config, "config")?;
        let v = get_by_name(&c.cfg, string(name, "name")?)?;
        *out(value, "value")? = v;
        Ok(())
    })
}

/// Makes registration's defaults in `*out`; release it with [`solid_reg_config_free`].
#[no_mangle]
pub unsafe extern "C" fn solid_reg_config_new(out_config: *mut *mut SolidRegConfig) -> SolidStatus {
    guard("solid_reg_config_new", || {
        let o = out(out_config, "out_config")?;
        crate::give(
            o,
            SolidRegConfig {
                cfg: RegConfig::default(),
            },
        );
        Ok(())
    })
}

/// Releases a registration configuration (NULL: nothing).
#[no_mangle]
pub unsafe extern "C" fn solid_reg_config_free(config: *mut SolidRegConfig) {
    release(config);
}

/// Sets registration parameter `name` to `value`; checked as [`solid_config_set`].
#[no_mangle]
pub unsafe extern "C" fn solid_reg_config_set(
    config: *mut SolidRegConfig,
    name: *const c_char,
    value: f64,
) -> SolidStatus {
    guard("solid_reg_config_set", || {
        let c = out(config, "config")?;
        set_by_name(&mut c.cfg, string(name, "name")?, value)
    })
}

/// Reads registration parameter `name` into `*value`.
#[no_mangle]
pub unsafe extern "C" fn solid_reg_config_get(
    config: *const SolidRegConfig,
    name: *const c_char,
    value: *mut f64,
) -> SolidStatus {
    guard("solid_reg_config_get", || {
        let c = nonnull(config, "config")?;
        let v = get_by_name(&c.cfg, string(name, "name")?)?;
        *out(value, "value")? = v;
        Ok(())
    })
}
