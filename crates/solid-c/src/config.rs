//! Configuration handles: the descriptor's ([`SolidConfig`]), the loop detector's
//! ([`SolidDetectorConfig`]) and registration's ([`SolidRegConfig`]), each made from defaults and
//! changed one parameter at a time by name (the names of the core's parameter tables).

use std::ffi::c_char;

use solid_lidar::db::DetectorConfig;
use solid_lidar::params::{Field, Kind, Params, Value};
use solid_lidar::reg::{Gate, RegConfig};
use solid_lidar::Config;

use crate::{guard, nonnull, out, release, string, Failure, SolidStatus};

/// A parameter set whose fields C reads and writes by name: the core's tables
/// ([`solid_lidar::params`]), and for the detector, its registration and gate tables under
/// `registration.` and `gate.`.
trait Named: Sized + Copy {
    /// The field called `name` of the set, as a place to read and write.
    fn slot<'a>(&'a mut self, name: &str) -> Option<Box<dyn AnySlot + 'a>>;
    /// Checks the whole set (fields and the rules between them).
    fn check(&self) -> Result<(), Failure>;
}

/// One field of one set, bound to the set.
struct Slot<'a, P: 'static> {
    set: &'a mut P,
    field: &'static Field<P>,
}

/// A [`Slot`] of any set.
trait AnySlot {
    fn kind(&self) -> Kind;
    fn get(&self) -> Value<'static>;
    fn put(&mut self, v: Value<'_>) -> Result<(), solid_lidar::Error>;
}

impl<P> AnySlot for Slot<'_, P> {
    fn kind(&self) -> Kind {
        self.field.kind
    }
    fn get(&self) -> Value<'static> {
        (self.field.get)(self.set)
    }
    fn put(&mut self, v: Value<'_>) -> Result<(), solid_lidar::Error> {
        self.field.set(self.set, v)
    }
}

fn slot<'a, P: Params>(set: &'a mut P, name: &str) -> Option<Box<dyn AnySlot + 'a>> {
    let field = P::field(name)?;
    Some(Box::new(Slot { set, field }))
}

impl Named for Config {
    fn slot<'a>(&'a mut self, name: &str) -> Option<Box<dyn AnySlot + 'a>> {
        slot(self, name)
    }
    fn check(&self) -> Result<(), Failure> {
        Ok(self.validate()?)
    }
}

impl Named for RegConfig {
    fn slot<'a>(&'a mut self, name: &str) -> Option<Box<dyn AnySlot + 'a>> {
        slot(self, name)
    }
    fn check(&self) -> Result<(), Failure> {
        Ok(self.validate()?)
    }
}

impl Named for DetectorConfig {
    fn slot<'a>(&'a mut self, name: &str) -> Option<Box<dyn AnySlot + 'a>> {
        if let Some(n) = name.strip_prefix("registration.") {
            return slot(&mut self.verify.registration, n);
        }
        if let Some(n) = name.strip_prefix("gate.") {
            return slot::<Gate>(&mut self.verify.gate, n);
        }
        slot(self, name)
    }
    fn check(&self) -> Result<(), Failure> {
        Ok(self.validate()?)
    }
}

fn unknown(name: &str) -> Failure {
    Failure::arg(format!("unknown parameter {name:?}"))
}

/// Sets parameter `name` of `p` to `value` and checks the whole set: on error `p` is unchanged.
fn set_value<P: Named>(p: &mut P, name: &str, value: Value<'_>) -> Result<(), Failure> {
    let mut changed = *p;
    changed
        .slot(name)
        .ok_or_else(|| unknown(name))?
        .put(value)?;
    changed.check()?;
    *p = changed;
    Ok(())
}

/// Sets parameter `name` of `p` from a C double, converted to the parameter's kind.
fn set_by_name<P: Named>(p: &mut P, name: &str, value: f64) -> Result<(), Failure> {
    let kind = (*p).slot(name).ok_or_else(|| unknown(name))?.kind();
    let bad = |expected: &str| {
        Failure::new(
            SolidStatus::InvalidParameter,
            format!("invalid {name} = {value}: expected {expected}"),
        )
    };
    let v = match kind {
        Kind::Bool if value == 0.0 || value == 1.0 => Value::Bool(value == 1.0),
        Kind::Bool => return Err(bad("0 (false) or 1 (true)")),
        // Integers up to 2^53 are exact in a double.
        Kind::Int { .. }
            if (0.0..=9_007_199_254_740_992.0).contains(&value) && value.fract() == 0.0 =>
        {
            Value::Int(value as u64)
        }
        Kind::Int { .. } => return Err(bad("a non-negative integer")),
        Kind::Choice(names) => {
            return Err(bad(&format!(
                "one of the names {names:?}, set with the *_set_name function"
            )))
        }
        _ => Value::Float(value),
    };
    set_value(p, name, v)
}

/// Parameter `name` of `p` as a double (booleans as 0 or 1).
fn get_by_name<P: Named>(p: &P, name: &str) -> Result<f64, Failure> {
    let mut copy = *p;
    let v = copy.slot(name).ok_or_else(|| unknown(name))?.get();
    match v {
        Value::Name(n) => Err(Failure::arg(format!(
            "{name} is a name ({n:?}), not a number"
        ))),
        v => Ok(v.as_f64()),
    }
}

/// The descriptor's parameters (docs/spec.md §1: `n_range`, `n_azimuth`, `n_elevation`, `fov_up`,
/// `fov_down`, `min_range`, `max_range`, `voxel_size`).
///
/// Threads: a config that no thread changes may be read from several threads at once.
pub struct SolidConfig {
    pub(crate) cfg: Config,
}

/// The loop detector's parameters, by the names of its table in docs/spec.md (`exclude_frames`,
/// `threshold`, `verify`, `verify_candidates`, ...), and those of its registration and
/// acceptance gate prefixed with `registration.` and `gate.` (`registration.voxel_size`,
/// `gate.max_translation`: the largest loop in metres), as in `solid config dump`.
///
/// Threads: as [`SolidConfig`].
pub struct SolidDetectorConfig {
    pub(crate) cfg: DetectorConfig,
}

/// Registration's parameters, by the names of its table in docs/spec.md (`voxel_size`,
/// `max_correspondence`, `max_iterations`, ...).
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

/// Sets detector parameter `name`, whose values are names, to `value` (such as
/// `registration.factor`: `"gicp"` or `"point-to-plane"`); checked as [`solid_config_set`].
#[no_mangle]
pub unsafe extern "C" fn solid_detector_config_set_name(
    config: *mut SolidDetectorConfig,
    name: *const c_char,
    value: *const c_char,
) -> SolidStatus {
    guard("solid_detector_config_set_name", || {
        let c = out(config, "config")?;
        let v = Value::Name(string(value, "value")?);
        set_value(&mut c.cfg, string(name, "name")?, v)
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

/// Sets registration parameter `name`, whose values are names, to `value` (`factor`: `"gicp"`
/// or `"point-to-plane"`; `kernel`); checked as [`solid_config_set`].
#[no_mangle]
pub unsafe extern "C" fn solid_reg_config_set_name(
    config: *mut SolidRegConfig,
    name: *const c_char,
    value: *const c_char,
) -> SolidStatus {
    guard("solid_reg_config_set_name", || {
        let c = out(config, "config")?;
        let v = Value::Name(string(value, "value")?);
        set_value(&mut c.cfg, string(name, "name")?, v)
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
