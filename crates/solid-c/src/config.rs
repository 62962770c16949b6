//! Configuration handles: the descriptor's ([`SolidConfig`]), the loop detector's
//! ([`SolidDetectorConfig`]) and registration's ([`SolidRegConfig`]), each made from defaults and
//! changed one parameter at a time by name (the names of the core's parameter tables).

use std::ffi::c_char;

use solid_lidar::db::DetectorConfig;
use solid_lidar::params::{removed_message, Field, Kind, Params, Value};
use solid_lidar::reg::{Gate, RegConfig};
use solid_lidar::Config;

use crate::{guard, new_handle, nonnull, out, put, release, string, Failure, SolidStatus};

/// A parameter set whose fields C reads and writes by name: the core's tables
/// ([`solid_lidar::params`]), and for the detector, its registration and gate tables under
/// `registration.` and `gate.`.
trait Named: Params {
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

/// `Named` for parameter sets with a `validate` method, the field `$name` found by `$slot`.
macro_rules! named {
    ($($set:ty => |$me:ident, $name:ident| $slot:expr;)*) => {$(
        impl Named for $set {
            fn slot<'a>(&'a mut self, $name: &str) -> Option<Box<dyn AnySlot + 'a>> {
                let $me = self;
                $slot
            }
            fn check(&self) -> Result<(), Failure> {
                Ok(self.validate()?)
            }
        }
    )*};
}

named! {
    Config => |set, name| slot(set, name);
    RegConfig => |set, name| slot(set, name);
    DetectorConfig => |set, name| {
        if let Some(n) = name.strip_prefix("registration.") {
            return slot(&mut set.verify.registration, n);
        }
        if let Some(n) = name.strip_prefix("gate.") {
            return slot::<Gate>(&mut set.verify.gate, n);
        }
        slot(set, name)
    };
}

/// The error of a name that is not a parameter of `P`; of one since removed
/// ([`Params::REMOVED`]), saying so, in which version, why and what replaces it.
fn unknown<P: Params>(name: &str) -> Failure {
    match removed_message::<P>(name) {
        Some(why) => Failure::arg(why),
        None => Failure::arg(format!("unknown parameter {name:?}")),
    }
}

/// Sets parameter `name` of `p` to `value` and checks the whole set: on error `p` is unchanged.
fn set_value<P: Named>(p: &mut P, name: &str, value: Value<'_>) -> Result<(), Failure> {
    let mut changed = *p;
    changed
        .slot(name)
        .ok_or_else(|| unknown::<P>(name))?
        .put(value)?;
    changed.check()?;
    *p = changed;
    Ok(())
}

/// Sets parameter `name` of `p` from a C double, converted to the parameter's kind.
fn set_by_name<P: Named>(p: &mut P, name: &str, value: f64) -> Result<(), Failure> {
    let kind = (*p).slot(name).ok_or_else(|| unknown::<P>(name))?.kind();
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
    let v = copy.slot(name).ok_or_else(|| unknown::<P>(name))?.get();
    match v {
        Value::Name(n) => Err(Failure::arg(format!(
            "{name} is a name ({n:?}), not a number"
        ))),
        v => Ok(v.as_f64()),
    }
}

/// A configuration handle: the parameter set it holds.
trait Handle {
    type Set: Named;
    fn params(&self) -> &Self::Set;
    fn params_mut(&mut self) -> &mut Self::Set;
}

macro_rules! handles {
    ($($handle:ty => $set:ty;)*) => {$(
        impl Handle for $handle {
            type Set = $set;
            fn params(&self) -> &$set {
                &self.cfg
            }
            fn params_mut(&mut self) -> &mut $set {
                &mut self.cfg
            }
        }
    )*};
}

handles! {
    SolidConfig => Config;
    SolidDetectorConfig => DetectorConfig;
    SolidRegConfig => RegConfig;
}

/// The body of the `*_set` and `*_set_name` entry points `what`: parameter `name` of `handle`
/// set by `set` to `value()` (taken before the name, as the messages expect).
unsafe fn set_entry<H: Handle, V>(
    what: &str,
    handle: *mut H,
    name: *const c_char,
    value: impl FnOnce() -> Result<V, Failure>,
    set: fn(&mut H::Set, &str, V) -> Result<(), Failure>,
) -> SolidStatus {
    guard(what, || {
        let c = out(handle, "config")?;
        let v = value()?;
        set(c.params_mut(), string(name, "name")?, v)
    })
}

/// A name argument of a `*_set_name` entry point, as a parameter value.
unsafe fn name_value<'a>(value: *const c_char) -> Result<Value<'a>, Failure> {
    Ok(Value::Name(string(value, "value")?))
}

/// The body of the `*_get` entry point `what`: parameter `name` of `handle` into `*value`.
unsafe fn get_entry<H: Handle>(
    what: &str,
    handle: *const H,
    name: *const c_char,
    value: *mut f64,
) -> SolidStatus {
    guard(what, || {
        let c = nonnull(handle, "config")?;
        let v = get_by_name(c.params(), string(name, "name")?)?;
        put(value, "value", v)
    })
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
    new_handle("solid_config_new", out_config, "out_config", || {
        let cfg = Config::preset(string(preset, "preset")?)?;
        Ok(SolidConfig { cfg })
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
    set_entry("solid_config_set", config, name, || Ok(value), set_by_name)
}

/// Reads descriptor parameter `name` into `*value`.
#[no_mangle]
pub unsafe extern "C" fn solid_config_get(
    config: *const SolidConfig,
    name: *const c_char,
    value: *mut f64,
) -> SolidStatus {
    get_entry("solid_config_get", config, name, value)
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
    new_handle(
        "solid_detector_config_new",
        out_config,
        "out_config",
        || {
            let cfg = DetectorConfig::for_preset(string(preset, "preset")?)?;
            Ok(SolidDetectorConfig { cfg })
        },
    )
}

/// Releases a detector configuration (NULL: nothing).
#[no_mangle]
pub unsafe extern "C" fn solid_detector_config_free(config: *mut SolidDetectorConfig) {
    release(config);
}

/// Sets detector parameter `name` to `value` (booleans as 0 or 1, integers as whole doubles);
/// checked as [`solid_config_set`]. A parameter since removed (`view_fov_deg`,
/// `view_min_overlap_deg`, `pose_candidate_shift_m`) is refused as an unknown one
/// (`SOLID_STATUS_INVALID_ARGUMENT`), the message saying in which version it was removed, why,
/// and what replaces it (nothing, for these: drop the call).
#[no_mangle]
pub unsafe extern "C" fn solid_detector_config_set(
    config: *mut SolidDetectorConfig,
    name: *const c_char,
    value: f64,
) -> SolidStatus {
    set_entry(
        "solid_detector_config_set",
        config,
        name,
        || Ok(value),
        set_by_name,
    )
}

/// Reads detector parameter `name` into `*value` (booleans as 0 or 1).
#[no_mangle]
pub unsafe extern "C" fn solid_detector_config_get(
    config: *const SolidDetectorConfig,
    name: *const c_char,
    value: *mut f64,
) -> SolidStatus {
    get_entry("solid_detector_config_get", config, name, value)
}

/// Sets detector parameter `name`, whose values are names, to `value` (such as
/// `registration.factor`: `"gicp"` or `"point-to-plane"`); checked as [`solid_config_set`].
#[no_mangle]
pub unsafe extern "C" fn solid_detector_config_set_name(
    config: *mut SolidDetectorConfig,
    name: *const c_char,
    value: *const c_char,
) -> SolidStatus {
    set_entry(
        "solid_detector_config_set_name",
        config,
        name,
        || name_value(value),
        set_value,
    )
}

/// Makes registration's defaults in `*out`; release it with [`solid_reg_config_free`].
#[no_mangle]
pub unsafe extern "C" fn solid_reg_config_new(out_config: *mut *mut SolidRegConfig) -> SolidStatus {
    new_handle("solid_reg_config_new", out_config, "out_config", || {
        Ok(SolidRegConfig {
            cfg: RegConfig::default(),
        })
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
    set_entry(
        "solid_reg_config_set",
        config,
        name,
        || Ok(value),
        set_by_name,
    )
}

/// Sets registration parameter `name`, whose values are names, to `value` (`factor`: `"gicp"`
/// or `"point-to-plane"`; `kernel`); checked as [`solid_config_set`].
#[no_mangle]
pub unsafe extern "C" fn solid_reg_config_set_name(
    config: *mut SolidRegConfig,
    name: *const c_char,
    value: *const c_char,
) -> SolidStatus {
    set_entry(
        "solid_reg_config_set_name",
        config,
        name,
        || name_value(value),
        set_value,
    )
}

/// Reads registration parameter `name` into `*value`.
#[no_mangle]
pub unsafe extern "C" fn solid_reg_config_get(
    config: *const SolidRegConfig,
    name: *const c_char,
    value: *mut f64,
) -> SolidStatus {
    get_entry("solid_reg_config_get", config, name, value)
}
