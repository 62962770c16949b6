//! The parameter classes `SolidConfig`, `DetectorConfig`, `RegistrationConfig` and
//! `AcceptanceGate`, driven by the core's parameter tables (`solid_lidar::params`): keyword
//! arguments, properties, `replace`, `to_dict` and `repr` are read off the tables, so a
//! parameter is written once, in the core.

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::pyclass::boolean_struct::True;
use pyo3::types::{PyBool, PyCFunction, PyDict, PyList, PyTuple};
use pyo3::PyClass;
use solid_lidar::db::DetectorConfig;
use solid_lidar::params::{removed_message, Field, Kind, Params, Value};
use solid_lidar::reg::{Gate, RegConfig};
use solid_lidar::{Config, Preset, PRESETS};

use crate::args;
use crate::errors::ToPyErr;
use crate::reg::PyRegistration;
use crate::{core_err, ConfigError};

/// A table value as a Python object.
fn to_py<'py>(py: Python<'py>, v: Value<'_>) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        Value::Bool(b) => PyBool::new(py, b).to_owned().into_any(),
        Value::Int(i) => i.into_pyobject(py)?.into_any(),
        Value::Float(x) => x.into_pyobject(py)?.into_any(),
        Value::Name(n) => n.into_pyobject(py)?.into_any(),
    })
}

/// A table value as Python's `repr` writes it.
fn repr(v: Value<'_>) -> String {
    match v {
        Value::Bool(b) => String::from(if b { "True" } else { "False" }),
        Value::Int(i) => i.to_string(),
        Value::Float(x) => format!("{x:?}"),
        Value::Name(n) => format!("'{n}'"),
    }
}

/// Writes the Python value `v` into field `f` of `set`: a value of the wrong type is a
/// `TypeError`, one out of the field's range a `ConfigError` naming it.
fn set_field<T>(set: &mut T, f: &Field<T>, v: &Bound<'_, PyAny>) -> PyResult<()> {
    let name = f.name;
    match f.kind {
        Kind::Bool => {
            let b = v
                .cast::<PyBool>()
                .map_err(|_| PyTypeError::new_err(format!("{name} must be a bool")))?;
            f.set(set, Value::Bool(b.is_true()))
        }
        Kind::Int { .. } => f.set(set, Value::Int(args::int_arg(v, name, 0, u64::MAX.into())?)),
        Kind::Float { .. } => f.set(set, Value::Float(args::float_param(v, name)?)),
        Kind::Choice(names) => {
            let s: String = v
                .extract()
                .map_err(|_| PyTypeError::new_err(format!("{name} must be a string")))?;
            if !names.contains(&s.as_str()) {
                return Err(ConfigError::new_err(format!(
                    "invalid {name} = {s:?}: expected {}",
                    f.expected
                )));
            }
            f.set(set, Value::Name(&s))
        }
    }
    .map_err(core_err)
}

/// The names a set takes, for messages.
fn valid_names<T: Params>(extra: &[&str]) -> String {
    T::FIELDS
        .iter()
        .map(|f| f.name)
        .chain(extra.iter().copied())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Applies keyword overrides to `set` by field name; `None` means "not given". `nested` takes
/// the keys that are not fields (`extra`, applied first), and the set is not validated here.
fn apply<T: Params>(
    set: &mut T,
    kw: Option<&Bound<'_, PyDict>>,
    extra: &[&str],
    mut nested: impl FnMut(&mut T, &str, &Bound<'_, PyAny>) -> PyResult<()>,
) -> PyResult<()> {
    let Some(kw) = kw else { return Ok(()) };
    let mut fields = Vec::with_capacity(kw.len());
    for (k, v) in kw.iter() {
        if v.is_none() {
            continue;
        }
        let key: String = k.extract()?;
        if extra.contains(&key.as_str()) {
            nested(set, &key, &v)?;
        } else if let Some(f) = T::field(&key) {
            fields.push((f, v));
        } else if let Some(why) = removed_message::<T>(&key) {
            return Err(PyTypeError::new_err(why));
        } else {
            return Err(PyTypeError::new_err(format!(
                "unknown {} parameter {key:?}; valid: {}",
                T::NAME,
                valid_names::<T>(extra)
            )));
        }
    }
    fields
        .into_iter()
        .try_for_each(|(f, v)| set_field(set, f, &v))
}

/// `set` with keyword overrides of its fields (a set with no nested sets), checked by `validate`.
fn overridden<T: Params, E: ToPyErr>(
    mut set: T,
    kw: Option<&Bound<'_, PyDict>>,
    validate: fn(&T) -> Result<(), E>,
) -> PyResult<T> {
    apply(&mut set, kw, &[], |_, _, _| Ok(()))?;
    validate(&set).map_err(core_err)?;
    Ok(set)
}

/// A set with keyword overrides, validated (`config_with`, `gate_with`, ...).
type WithOverrides<T> = fn(T, Option<&Bound<'_, PyDict>>) -> PyResult<T>;

/// The set an object of class `C` holds, or `with(base, dict)` for a dict of overrides; for
/// anything else a `TypeError` saying `expected`.
fn set_from<C: ParamClass>(
    obj: &Bound<'_, PyAny>,
    base: C::Set,
    with: WithOverrides<C::Set>,
    expected: &str,
) -> PyResult<C::Set>
where
    C::Set: Copy,
{
    if let Ok(c) = obj.cast::<C>() {
        return Ok(*c.get().params());
    }
    let d = obj
        .cast::<PyDict>()
        .map_err(|_| PyTypeError::new_err(expected.to_owned()))?;
    with(base, Some(d))
}

/// The fields of `set` as a dict.
fn fields_dict<'py, T: Params>(py: Python<'py>, set: &T) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for f in T::FIELDS {
        d.set_item(f.name, to_py(py, (f.get)(set))?)?;
    }
    Ok(d)
}

/// `Name(field=value, ...)` over the table.
fn fields_repr<T: Params>(set: &T) -> String {
    let parts: Vec<String> = T::FIELDS
        .iter()
        .map(|f| format!("{}={}", f.name, repr((f.get)(set))))
        .collect();
    format!("{}({})", T::NAME, parts.join(", "))
}

/// A Python class over a parameter set.
trait ParamClass: PyClass<Frozen = True> + Sync {
    /// The set it holds.
    type Set: Params;
    /// The set.
    fn params(&self) -> &Self::Set;
}

/// Adds a read-only property per table field to the class `C`, with the field's doc line.
fn add_properties<C: ParamClass>(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    let property = py.import("builtins")?.getattr("property")?;
    let cls = py.get_type::<C>();
    for f in C::Set::FIELDS {
        let get = f.get;
        let getter = PyCFunction::new_closure(
            py,
            None,
            None,
            move |a: &Bound<'_, PyTuple>, _: Option<&Bound<'_, PyDict>>| -> PyResult<Py<PyAny>> {
                let slf = a.get_item(0)?;
                let c = slf.cast::<C>()?;
                Ok(to_py(a.py(), get(c.get().params()))?.unbind())
            },
        )?;
        cls.setattr(
            f.name,
            property.call1((getter, py.None(), py.None(), f.doc))?,
        )?;
    }
    Ok(())
}

/// The table of a parameter set, as `_param_table` gives it to Python.
fn table<'py, T: Params>(py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
    let defaults = T::defaults();
    let out = PyList::empty(py);
    for f in T::FIELDS {
        let d = PyDict::new(py);
        d.set_item("name", f.name)?;
        d.set_item("aliases", f.aliases.to_vec())?;
        let ty = match f.kind {
            Kind::Bool => "bool",
            Kind::Int { min, max } => {
                d.set_item("min", min)?;
                d.set_item("max", max)?;
                "int"
            }
            Kind::Float { lo, lo_open, hi } => {
                d.set_item("min", lo)?;
                d.set_item("min_open", lo_open)?;
                d.set_item("max", hi)?;
                "float"
            }
            Kind::Choice(names) => {
                d.set_item("choices", names.to_vec())?;
                "str"
            }
        };
        d.set_item("type", ty)?;
        d.set_item("expected", f.expected)?;
        d.set_item("required", f.required)?;
        d.set_item("rule", f.rule)?;
        let default = if f.required {
            None
        } else {
            Some(to_py(py, (f.get)(&defaults))?)
        };
        d.set_item("default", default)?;
        d.set_item("doc", f.doc)?;
        out.append(d)?;
    }
    Ok(out)
}

/// The parameter table of `SolidConfig`, `DetectorConfig`, `RegistrationConfig` or
/// `AcceptanceGate`: one dict per field (name, aliases, type, range, expected, required, rule,
/// default, doc), in order. The command line and the stub generator read it.
#[pyfunction]
fn _param_table<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyList>> {
    match name {
        n if n == Config::NAME => table::<Config>(py),
        n if n == DetectorConfig::NAME => table::<DetectorConfig>(py),
        n if n == RegConfig::NAME => table::<RegConfig>(py),
        n if n == Gate::NAME => table::<Gate>(py),
        other => Err(ConfigError::new_err(format!(
            "no parameter table {other:?}; valid: {}, {}, {}, {}",
            Config::NAME,
            DetectorConfig::NAME,
            RegConfig::NAME,
            Gate::NAME
        ))),
    }
}

/// The parameters `DetectorConfig` no longer has, each with why and what replaces it (the core's
/// `Params::REMOVED`): `solid.config.REMOVED_DETECTOR_KEYS`.
#[pyfunction]
fn _removed_detector_keys<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    for r in DetectorConfig::REMOVED {
        out.set_item(r.name, r.why)?;
    }
    Ok(out)
}

/// The names of the presets, for messages.
fn preset_names() -> String {
    PRESETS
        .iter()
        .map(|p| p.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The preset called `name`, or a `ConfigError` listing them.
fn find_preset(name: &str) -> PyResult<&'static Preset> {
    Preset::find(name).map_err(|_| {
        ConfigError::new_err(format!(
            "unknown preset {name:?}; available: {}",
            preset_names()
        ))
    })
}

// ---- SolidConfig -------------------------------------------------------------------------------

/// The descriptor configuration exposed as `solid.SolidConfig` (immutable).
#[pyclass(name = "SolidConfig", module = "solid", frozen, eq)]
#[derive(Clone)]
pub struct PyConfig {
    /// The validated core config.
    pub inner: Config,
    /// The preset it was made from (`SolidConfig.preset`), kept through `replace` and pickling:
    /// it chooses the loop detector's defaults (`DetectorConfig::for_base_preset`). Not part of
    /// equality or hashing.
    pub base_preset: Option<&'static Preset>,
}

impl PartialEq for PyConfig {
    fn eq(&self, other: &Self) -> bool {
        self.inner == other.inner
    }
}

impl ParamClass for PyConfig {
    type Set = Config;
    fn params(&self) -> &Config {
        &self.inner
    }
}

/// `cfg` with keyword overrides, validated.
fn config_with(cfg: Config, kw: Option<&Bound<'_, PyDict>>) -> PyResult<Config> {
    overridden(cfg, kw, Config::validate)
}

impl PyConfig {
    /// Wraps a config that was validated already (a database's, say).
    pub fn new_unchecked(inner: Config) -> Self {
        PyConfig {
            inner,
            base_preset: None,
        }
    }

    /// The detector defaults for this config (the core chooses them from its base preset).
    pub fn detector_defaults(&self) -> DetectorConfig {
        DetectorConfig::for_base_preset(self.base_preset)
    }

    /// `SolidConfig(...)` as Python's `repr` writes it.
    pub(crate) fn repr(&self) -> String {
        fields_repr(&self.inner)
    }
}

#[pymethods]
impl PyConfig {
    /// A configuration from explicit values; the sensor's `fov_up`, `fov_down` and
    /// `n_elevation` are required, the others take the docs/spec.md §1 defaults of the core.
    #[new]
    #[pyo3(signature = (**params))]
    fn new(params: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        for f in Config::FIELDS.iter().filter(|f| f.required) {
            let given = match params {
                Some(p) => p.get_item(f.name)?.is_some_and(|v| !v.is_none()),
                None => false,
            };
            if !given {
                return Err(PyTypeError::new_err(format!(
                    "SolidConfig() missing required keyword argument '{}'",
                    f.name
                )));
            }
        }
        Ok(PyConfig::new_unchecked(config_with(
            Config::defaults(),
            params,
        )?))
    }

    /// A sensor preset (docs/spec.md §4), with optional keyword overrides.
    #[staticmethod]
    #[pyo3(signature = (name, **overrides))]
    fn preset(name: &str, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let p = find_preset(name)?;
        Ok(PyConfig {
            inner: config_with(p.config, overrides)?,
            base_preset: Some(p),
        })
    }

    /// A copy with some parameters changed (it keeps its base preset).
    #[pyo3(signature = (**overrides))]
    fn replace(&self, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(PyConfig {
            inner: config_with(self.inner, overrides)?,
            base_preset: self.base_preset,
        })
    }

    /// The preset this config was made from (`SolidConfig.preset(name, ...)`), or None. It
    /// chooses the loop detector's default threshold; it is not part of equality.
    #[getter]
    fn base_preset(&self) -> Option<&'static str> {
        self.base_preset.map(|p| p.name)
    }

    /// The parameters as a dict (what `SolidConfig(**d)` takes back).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        fields_dict(py, &self.inner)
    }

    /// A 64-bit fingerprint of every parameter; equal configs have equal fingerprints.
    #[getter]
    fn fingerprint(&self) -> u64 {
        self.inner.fingerprint()
    }

    fn __hash__(&self) -> u64 {
        self.inner.fingerprint()
    }

    fn __repr__(&self) -> String {
        self.repr()
    }

    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyDict>,))> {
        let py = slf.py();
        let ctor = py.import("solid._solid")?.getattr("_config_from_dict")?;
        let d = slf.get().to_dict(py)?;
        if let Some(p) = slf.get().base_preset {
            d.set_item("base_preset", p.name)?;
        }
        Ok((ctor, (d,)))
    }
}

#[pyfunction]
fn _config_from_dict(d: &Bound<'_, PyDict>) -> PyResult<PyConfig> {
    for f in Config::FIELDS.iter().filter(|f| f.required) {
        if !d.contains(f.name)? {
            return Err(ConfigError::new_err(format!(
                "config is missing {}",
                f.name
            )));
        }
    }
    let d = d.copy()?;
    let preset = match d.get_item("base_preset")? {
        Some(v) => {
            d.del_item("base_preset")?;
            let name: String = v.extract()?;
            Preset::find(&name).ok()
        }
        None => None,
    };
    Ok(PyConfig {
        inner: config_with(Config::defaults(), Some(&d))?,
        base_preset: preset,
    })
}

// ---- DetectorConfig ----------------------------------------------------------------------------

/// The loop detector's parameters (the defaults come from the core).
#[pyclass(name = "DetectorConfig", module = "solid", frozen, eq)]
#[derive(Clone, PartialEq)]
pub struct PyDetectorConfig {
    /// The validated core parameters.
    pub inner: DetectorConfig,
}

impl ParamClass for PyDetectorConfig {
    type Set = DetectorConfig;
    fn params(&self) -> &DetectorConfig {
        &self.inner
    }
}

/// The detector's parameter sets of their own, given as objects or dicts of overrides.
const DETECTOR_SETS: [&str; 2] = ["registration", "gate"];

/// Applies detector overrides given by name (`registration` and `gate` first, as objects or
/// dicts of overrides of the current ones); `None` values are skipped. Validates the result.
pub(crate) fn detector_overrides(
    mut c: DetectorConfig,
    kw: Option<&Bound<'_, PyDict>>,
) -> PyResult<DetectorConfig> {
    apply(&mut c, kw, &DETECTOR_SETS, |c, key, v| {
        if key == "registration" {
            c.verify.registration = reg_config_from(v, c.verify.registration)?;
        } else {
            c.verify.gate = gate_from(v, c.verify.gate)?;
        }
        Ok(())
    })?;
    c.validate().map_err(core_err)?;
    Ok(c)
}

#[pymethods]
impl PyDetectorConfig {
    /// Parameters by keyword; those not given take the core's defaults (the threshold: the
    /// largest preset threshold; prefer `DetectorConfig.preset(name)`).
    #[new]
    #[pyo3(signature = (**params))]
    fn new(params: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(PyDetectorConfig {
            inner: detector_overrides(DetectorConfig::default(), params)?,
        })
    }

    /// The defaults for a sensor preset (its measured loop threshold), with overrides.
    #[staticmethod]
    #[pyo3(signature = (name, **params))]
    fn preset(name: &str, params: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let base = DetectorConfig::for_base_preset(Some(find_preset(name)?));
        Ok(PyDetectorConfig {
            inner: detector_overrides(base, params)?,
        })
    }

    /// A copy with some parameters changed.
    #[pyo3(signature = (**params))]
    fn replace(&self, params: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(PyDetectorConfig {
            inner: detector_overrides(self.inner, params)?,
        })
    }

    /// The parameters as a dict (what `DetectorConfig(**d)` takes back).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = fields_dict(py, &self.inner)?;
        let v = &self.inner.verify;
        d.set_item("registration", fields_dict(py, &v.registration)?)?;
        d.set_item("gate", fields_dict(py, &v.gate)?)?;
        Ok(d)
    }

    /// The registration parameters.
    #[getter]
    fn registration(&self) -> PyRegConfig {
        PyRegConfig {
            inner: self.inner.verify.registration,
        }
    }

    /// The acceptance gate (its max_translation is the largest loop, metres).
    #[getter]
    fn gate(&self) -> PyGate {
        PyGate {
            inner: self.inner.verify.gate,
        }
    }

    fn __repr__(&self) -> String {
        fields_repr(&self.inner)
    }

    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyDict>,))> {
        let py = slf.py();
        let ctor = py
            .import("solid._solid")?
            .getattr("_detector_config_from_dict")?;
        Ok((ctor, (slf.get().to_dict(py)?,)))
    }
}

#[pyfunction]
fn _detector_config_from_dict(params: &Bound<'_, PyDict>) -> PyResult<PyDetectorConfig> {
    PyDetectorConfig::new(Some(params))
}

// ---- RegistrationConfig ------------------------------------------------------------------------

/// The registration parameters, exposed as `solid.RegistrationConfig` (immutable).
#[pyclass(name = "RegistrationConfig", module = "solid", frozen, eq)]
#[derive(Clone, PartialEq)]
pub struct PyRegConfig {
    pub(crate) inner: RegConfig,
}

impl ParamClass for PyRegConfig {
    type Set = RegConfig;
    fn params(&self) -> &RegConfig {
        &self.inner
    }
}

/// `c` with keyword overrides, validated.
fn reg_config_with(c: RegConfig, kw: Option<&Bound<'_, PyDict>>) -> PyResult<RegConfig> {
    overridden(c, kw, RegConfig::validate)
}

/// A registration config from a `RegistrationConfig` or a dict of overrides of `base`.
pub(crate) fn reg_config_from(obj: &Bound<'_, PyAny>, base: RegConfig) -> PyResult<RegConfig> {
    let expected = "registration must be a solid.RegistrationConfig or a dict of its parameters";
    set_from::<PyRegConfig>(obj, base, reg_config_with, expected)
}

#[pymethods]
impl PyRegConfig {
    /// Defaults (measured; see the Rust documentation of `solid_lidar::reg`) with keyword
    /// overrides.
    #[new]
    #[pyo3(signature = (**overrides))]
    fn new(overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(PyRegConfig {
            inner: reg_config_with(RegConfig::default(), overrides)?,
        })
    }

    /// A copy with some parameters changed.
    #[pyo3(signature = (**overrides))]
    fn replace(&self, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(PyRegConfig {
            inner: reg_config_with(self.inner, overrides)?,
        })
    }

    /// The parameters as a dict (what `RegistrationConfig(**d)` takes back).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        fields_dict(py, &self.inner)
    }

    fn __repr__(&self) -> String {
        fields_repr(&self.inner)
    }
}

// ---- AcceptanceGate ----------------------------------------------------------------------------

/// The acceptance gate, exposed as `solid.AcceptanceGate` (immutable).
#[pyclass(name = "AcceptanceGate", module = "solid", frozen, eq)]
#[derive(Clone, PartialEq)]
pub struct PyGate {
    pub(crate) inner: Gate,
}

impl ParamClass for PyGate {
    type Set = Gate;
    fn params(&self) -> &Gate {
        &self.inner
    }
}

/// `g` with keyword overrides, validated.
fn gate_with(g: Gate, kw: Option<&Bound<'_, PyDict>>) -> PyResult<Gate> {
    overridden(g, kw, Gate::validate)
}

/// A gate from an `AcceptanceGate`, or a dict of overrides of `base`.
pub(crate) fn gate_from(obj: &Bound<'_, PyAny>, base: Gate) -> PyResult<Gate> {
    let expected = "gate must be a solid.AcceptanceGate or a dict of its thresholds";
    set_from::<PyGate>(obj, base, gate_with, expected)
}

#[pymethods]
impl PyGate {
    /// The measured default thresholds, with keyword overrides.
    #[new]
    #[pyo3(signature = (**overrides))]
    fn new(overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(PyGate {
            inner: gate_with(Gate::default(), overrides)?,
        })
    }

    /// A copy with some thresholds changed.
    #[pyo3(signature = (**overrides))]
    fn replace(&self, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(PyGate {
            inner: gate_with(self.inner, overrides)?,
        })
    }

    /// The thresholds as a dict (what `AcceptanceGate(**d)` takes back).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        fields_dict(py, &self.inner)
    }

    /// None when `registration` passes, else why it is rejected.
    fn check(&self, registration: &PyRegistration) -> Option<String> {
        self.inner
            .check(
                &registration.inner,
                &registration.hypotheses,
                registration.best.unwrap_or(0),
            )
            .err()
            .map(|r| r.to_string())
    }

    /// Whether `registration` passes every threshold.
    fn accepts(&self, registration: &PyRegistration) -> bool {
        self.check(registration).is_none()
    }

    /// How many hypotheses reached the best one's pose (0 without hypotheses).
    fn agreement(&self, registration: &PyRegistration) -> usize {
        registration
            .best
            .map_or(0, |b| self.inner.agreement(&registration.hypotheses, b))
    }

    fn __repr__(&self) -> String {
        fields_repr(&self.inner)
    }
}

/// Adds the parameter classes, their properties and the table reader to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyConfig>()?;
    m.add_class::<PyDetectorConfig>()?;
    m.add_class::<PyRegConfig>()?;
    m.add_class::<PyGate>()?;
    add_properties::<PyConfig>(m)?;
    add_properties::<PyDetectorConfig>(m)?;
    add_properties::<PyRegConfig>(m)?;
    add_properties::<PyGate>(m)?;
    add_functions! { m, _config_from_dict, _detector_config_from_dict, _param_table, _removed_detector_keys }
    Ok(())
}
