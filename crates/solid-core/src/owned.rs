//! Owning conveniences over the allocation-free API (feature `alloc`).

use alloc::vec;
use alloc::vec::Vec;

use crate::{
    cosine_distance, describe, describe_scratch_len, heading, heading_refined, Config, Coord,
    Error, Heading, Points, Scratch, Stats,
};

/// One scan's SOLiD descriptor with the counts and the fingerprint of the config that made it.
#[derive(Debug, Clone, PartialEq)]
pub struct Descriptor {
    /// R-SOLiD, `n_range` values.
    pub r: Vec<f32>,
    /// A-SOLiD, `n_azimuth` values.
    pub a: Vec<f32>,
    /// Point counts.
    pub stats: Stats,
    /// [`Config::fingerprint`] of the config used.
    pub fingerprint: u64,
}

impl Descriptor {
    /// Cosine distance of the R-SOLiDs ([spec §3](crate::spec#3-comparing-descriptors)).
    ///
    /// # Errors
    /// [`Error::LengthMismatch`] when the descriptors have different lengths.
    pub fn distance(&self, other: &Descriptor) -> Result<f64, Error> {
        cosine_distance(&self.r, &other.r)
    }

    /// Heading of `self` (query) relative to `candidate` ([spec §3](crate::spec#3-comparing-descriptors)), refined or integer.
    ///
    /// # Errors
    /// [`Error::LengthMismatch`] when the descriptors have different lengths.
    pub fn heading(&self, candidate: &Descriptor, refine: bool) -> Result<Heading, Error> {
        if refine {
            heading_refined(&self.a, &candidate.a)
        } else {
            heading(&self.a, &candidate.a)
        }
    }
}

/// Describes scan after scan with one config, reusing its scratch buffer.
#[derive(Debug, Clone)]
pub struct Describer {
    cfg: Config,
    scratch: Vec<Scratch>,
}

impl Describer {
    /// A describer for `cfg`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] when `cfg` is invalid.
    pub fn new(cfg: Config) -> Result<Self, Error> {
        cfg.validate()?;
        Ok(Describer {
            cfg,
            scratch: Vec::new(),
        })
    }

    /// The config.
    pub fn config(&self) -> &Config {
        &self.cfg
    }

    /// Bytes held by the scratch buffer (it grows to the largest scan described so far).
    pub fn scratch_bytes(&self) -> usize {
        self.scratch.len() * core::mem::size_of::<Scratch>()
    }

    /// Describes one scan, growing the scratch buffer when needed.
    ///
    /// # Errors
    /// [`Error::OutOfMemory`] when the scratch buffer for this many points cannot be allocated
    /// (the describer is left as it was); otherwise [`describe`]'s errors.
    pub fn describe<T: Coord>(&mut self, points: Points<'_, T>) -> Result<Descriptor, Error> {
        let need = describe_scratch_len(points.len(), &self.cfg);
        if self.scratch.len() < need {
            reserve(&mut self.scratch, need, "describe scratch")?;
            self.scratch.resize(need, 0);
        }
        let mut d = Descriptor {
            r: vec![0.0; self.cfg.n_range],
            a: vec![0.0; self.cfg.n_azimuth],
            stats: Stats::default(),
            fingerprint: self.cfg.fingerprint(),
        };
        d.stats = describe(points, &self.cfg, &mut self.scratch, &mut d.r, &mut d.a)?;
        Ok(d)
    }
}

/// Makes room in `v` for `n` elements in all, or [`Error::OutOfMemory`] naming `what` (nothing is
/// changed): the one way the `alloc` conveniences grow a buffer whose size the input decides.
pub(crate) fn reserve<T>(v: &mut Vec<T>, n: usize, what: &'static str) -> Result<(), Error> {
    v.try_reserve_exact(n.saturating_sub(v.len()))
        .map_err(|_| Error::OutOfMemory {
            what,
            bytes: n.saturating_mul(core::mem::size_of::<T>()),
        })
}

/// `n` copies of `value` in a vector allocated with [`reserve`].
pub(crate) fn try_filled<T: Clone>(
    n: usize,
    value: T,
    what: &'static str,
) -> Result<Vec<T>, Error> {
    let mut v = Vec::new();
    reserve(&mut v, n, what)?;
    v.resize(n, value);
    Ok(v)
}
