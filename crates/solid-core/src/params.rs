//! Parameter tables: one [`Field`] per parameter of each parameter set ([`crate::Config`],
//! [`crate::db::DetectorConfig`], [`crate::reg::RegConfig`], [`crate::reg::Gate`]), written next to
//! the set's defaults.
//!
//! A field gives the name users see (in Rust, Python, the command line and C), its type, its
//! valid range (checked by the set's `validate`), one line of documentation and how to read and
//! write it. The bindings, the command-line flags, the Python stub and the C API are driven by
//! these tables, so adding a parameter means adding its field and using it, nothing else.
//!
//! ```
//! use solid_lidar::params::{Params, Value};
//! use solid_lidar::Config;
//!
//! let mut cfg = Config::preset("avia").unwrap();
//! Config::field("max_range").unwrap().set(&mut cfg, Value::Float(40.0)).unwrap();
//! assert_eq!(cfg.get("max_range"), Some(Value::Float(40.0)));
//! assert!(Config::field("n_range").unwrap().set(&mut cfg, Value::Int(0)).is_err());
//! ```

use crate::Error;

/// A parameter's value, as the tables read and write it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value<'a> {
    /// A switch.
    Bool(bool),
    /// A count or a size.
    Int(u64),
    /// A real number.
    Float(f64),
    /// One of the names of a [`Kind::Choice`].
    Name(&'a str),
}

impl Value<'_> {
    /// The value as a number, for error messages (NaN for a name).
    pub fn as_f64(&self) -> f64 {
        match *self {
            Value::Bool(b) => f64::from(u8::from(b)),
            Value::Int(i) => i as f64,
            Value::Float(v) => v,
            Value::Name(_) => f64::NAN,
        }
    }
}

/// What values a parameter takes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    /// `true` or `false`.
    Bool,
    /// An integer in `min..=max`.
    Int {
        /// Smallest valid value.
        min: u64,
        /// Largest valid value.
        max: u64,
    },
    /// A number in the interval from `lo` to `hi` (never NaN); `f64::MAX` as a bound keeps the
    /// value finite, an infinite bound lets infinity through.
    Float {
        /// Lower bound.
        lo: f64,
        /// Whether `lo` itself is excluded.
        lo_open: bool,
        /// Upper bound (always included).
        hi: f64,
    },
    /// One of these names.
    Choice(&'static [&'static str]),
}

impl Kind {
    /// Any integer from `min` on.
    pub const fn at_least(min: u64) -> Kind {
        Kind::Int { min, max: u64::MAX }
    }

    /// A number in `[lo, hi]`.
    pub const fn closed(lo: f64, hi: f64) -> Kind {
        Kind::Float {
            lo,
            lo_open: false,
            hi,
        }
    }

    /// A number in `(lo, hi]`.
    pub const fn open_closed(lo: f64, hi: f64) -> Kind {
        Kind::Float {
            lo,
            lo_open: true,
            hi,
        }
    }

    /// Whether `v` is of this kind and in its range.
    pub fn admits(&self, v: Value<'_>) -> bool {
        match (*self, v) {
            (Kind::Bool, Value::Bool(_)) => true,
            (Kind::Int { min, max }, Value::Int(i)) => (min..=max).contains(&i),
            (Kind::Float { lo, lo_open, hi }, Value::Float(_) | Value::Int(_)) => {
                let x = v.as_f64();
                (if lo_open { x > lo } else { x >= lo }) && x <= hi
            }
            (Kind::Choice(names), Value::Name(n)) => names.contains(&n),
            _ => false,
        }
    }
}

/// One parameter of the set `T`.
pub struct Field<T: 'static> {
    /// The name users see (Python keyword, `--flag` with `-` for `_`, C and JSON key).
    pub name: &'static str,
    /// Older names still accepted (Python keywords), newest first.
    pub aliases: &'static [&'static str],
    /// Type and valid range.
    pub kind: Kind,
    /// The valid range in words, as an invalid value's error says it.
    pub expected: &'static str,
    /// Whether the set has no default for it (the sensor's field of view, say).
    pub required: bool,
    /// A rule between this field and others, in words (the set's `validate` checks it), or "".
    pub rule: &'static str,
    /// One line of documentation.
    pub doc: &'static str,
    /// Reads the parameter.
    pub get: fn(&T) -> Value<'static>,
    /// Writes a value that [`Kind::admits`].
    pub put: fn(&mut T, Value<'_>),
}

impl<T> Field<T> {
    /// Whether `name` is this field's name or one of its aliases.
    pub fn is_named(&self, name: &str) -> bool {
        self.name == name || self.aliases.contains(&name)
    }

    /// Writes `v` into `set` when it is of the field's kind and in its range.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field, with [`Field::expected`]; `set` is unchanged.
    pub fn set(&self, set: &mut T, v: Value<'_>) -> Result<(), Error> {
        let v = match (self.kind, v) {
            (Kind::Float { .. }, Value::Int(i)) => Value::Float(i as f64),
            _ => v,
        };
        if !self.kind.admits(v) {
            return Err(Error::invalid(self.name, v.as_f64(), self.expected));
        }
        (self.put)(set, v);
        Ok(())
    }

    /// Checks the value `set` holds against the field's range.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field.
    pub fn check(&self, set: &T) -> Result<(), Error> {
        let v = (self.get)(set);
        if self.kind.admits(v) {
            Ok(())
        } else {
            Err(Error::invalid(self.name, v.as_f64(), self.expected))
        }
    }
}

/// A parameter set with a table of its fields.
pub trait Params: Sized + Copy + 'static {
    /// The set's name as users see it (the Python class).
    const NAME: &'static str;
    /// The fields, in the order users see them.
    const FIELDS: &'static [Field<Self>];
    /// Parameters the set no longer has, each with the version that removed it, why, and what
    /// replaces it. Setting one (C `*_config_set`, Python keyword arguments) is refused naming
    /// this ([`removed_message`]); a `config.json` of an earlier run that names one loads
    /// without it, with a warning (Python `solid.config.REMOVED_DETECTOR_KEYS`, read from here).
    const REMOVED: &'static [Removed] = &[];

    /// The defaults (for a [`Field::required`] field, a placeholder that fails the checks).
    fn defaults() -> Self;

    /// The field called `name` (or once called so).
    fn field(name: &str) -> Option<&'static Field<Self>> {
        Self::FIELDS.iter().find(|f| f.is_named(name))
    }

    /// The value of the field called `name`.
    fn get(&self, name: &str) -> Option<Value<'static>> {
        Self::field(name).map(|f| (f.get)(self))
    }

    /// Checks every field against its range, in table order.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the first field out of its range.
    fn check_fields(&self) -> Result<(), Error> {
        Self::FIELDS.iter().try_for_each(|f| f.check(self))
    }
}

/// A parameter a set no longer has ([`Params::REMOVED`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Removed {
    /// Its name.
    pub name: &'static str,
    /// The version of solid that removed it (not the version built: a message of a later
    /// version still names the one it went in).
    pub since: &'static str,
    /// Why, and what replaces it.
    pub why: &'static str,
}

/// Why parameter `name` of `P` is no more ([`Params::REMOVED`]), naming the version of solid
/// that removed it: None for a name never removed.
#[cfg(feature = "alloc")]
pub fn removed_message<P: Params>(name: &str) -> Option<alloc::string::String> {
    P::REMOVED.iter().find(|r| r.name == name).map(|r| {
        alloc::format!(
            "{} parameter {:?} was removed in solid {}: {}",
            P::NAME,
            r.name,
            r.since,
            r.why
        )
    })
}

/// A value of a Rust field type as a table [`Value`], and back (for values the field's
/// [`Kind`] admits).
pub trait ParamType: Copy {
    /// The value as a table value.
    fn to_value(self) -> Value<'static>;
    /// The field value of a table value of the right kind.
    fn from_value(v: Value<'_>) -> Self;
}

impl ParamType for bool {
    fn to_value(self) -> Value<'static> {
        Value::Bool(self)
    }
    fn from_value(v: Value<'_>) -> Self {
        matches!(v, Value::Bool(true))
    }
}

impl ParamType for f64 {
    fn to_value(self) -> Value<'static> {
        // `+ 0.0` turns -0.0 into +0.0, as the fingerprints do.
        Value::Float(self + 0.0)
    }
    fn from_value(v: Value<'_>) -> Self {
        v.as_f64()
    }
}

macro_rules! int_param {
    ($($t:ty),*) => {$(
        impl ParamType for $t {
            fn to_value(self) -> Value<'static> {
                Value::Int(self as u64)
            }
            fn from_value(v: Value<'_>) -> Self {
                // The kind's range keeps the value representable.
                match v {
                    Value::Int(i) => <$t>::try_from(i).unwrap_or(<$t>::MAX),
                    _ => 0,
                }
            }
        }
    )*};
}
int_param!(u8, u32, usize);

/// A [`Field`] of a parameter set, read and written at a field path of the struct:
/// `field!(T, "name", path.to.field, kind, "expected", "doc")`, optionally followed by
/// `aliases = [..]`, `required = true` and `rule = "..."`, in that order.
#[macro_export]
#[doc(hidden)]
macro_rules! param_field {
    ($t:ty, $name:literal, $($path:ident).+, $kind:expr, $expected:literal, $doc:literal $(, aliases = [$($alias:literal),*])? $(, required = $req:literal)? $(, rule = $rule:literal)?) => {
        $crate::params::Field::<$t> {
            name: $name,
            aliases: &[$($($alias),*)?],
            kind: $kind,
            expected: $expected,
            required: false $(|| $req)?,
            rule: concat!("" $(, $rule)?),
            doc: $doc,
            get: |c: &$t| $crate::params::ParamType::to_value(c.$($path).+),
            put: |c: &mut $t, v| c.$($path).+ = $crate::params::ParamType::from_value(v),
        }
    };
}
pub use param_field as field;

/// `f64::MAX`: the upper bound of a finite number.
pub const FINITE: f64 = f64::MAX;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_admit_their_ranges() {
        let k = Kind::open_closed(0.0, f64::INFINITY);
        assert!(!k.admits(Value::Float(0.0)));
        assert!(k.admits(Value::Float(f64::INFINITY)));
        assert!(!k.admits(Value::Float(f64::NAN)));
        assert!(!Kind::closed(0.0, FINITE).admits(Value::Float(f64::INFINITY)));
        assert!(Kind::closed(f64::NEG_INFINITY, f64::INFINITY).admits(Value::Float(-1e300)));
        assert!(!Kind::Int { min: 1, max: 16 }.admits(Value::Int(17)));
        assert!(!Kind::Int { min: 1, max: 16 }.admits(Value::Float(3.0)));
        assert!(!Kind::Bool.admits(Value::Int(1)));
        assert!(Kind::Choice(&["a", "b"]).admits(Value::Name("b")));
        assert!(!Kind::Choice(&["a", "b"]).admits(Value::Name("c")));
    }
}
