//! Searching the [`Database`]: the options, one query, a batch of queries and every distance.

use alloc::vec;
use alloc::vec::Vec;

use super::{check_bins, Database};
use crate::db::{DbError, Method};
use crate::search::{self, Exclude, Index, Neighbor, Observed, Plan, Request, Rows};
use crate::{Descriptor, Error};

/// Options of [`Database::search_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchOptions {
    /// Number of neighbours.
    pub k: usize,
    /// Skip the most recent entries (the last `exclude_recent` ids).
    pub exclude_recent: usize,
    /// Skip entries whose timestamp is greater than this (entries without a time are kept).
    pub not_newer_than: Option<f64>,
    /// Return only neighbours at most this far (`f32::INFINITY`: no bound). A caller that
    /// accepts only matches within a threshold passes it: every method then skips more.
    pub max_distance: f32,
    /// Search method.
    pub method: Method,
}

impl Default for SearchOptions {
    fn default() -> Self {
        SearchOptions {
            k: 1,
            exclude_recent: 0,
            not_newer_than: None,
            max_distance: f32::INFINITY,
            method: Method::Auto,
        }
    }
}

/// The results of [`Database::search_batch`]: `k` slots per query, nearest first.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchResults {
    /// Slots per query.
    pub k: usize,
    /// Ids, `queries × k`, row-major; [`BatchResults::NONE`] in the slots of a query with
    /// fewer than `k` neighbours.
    pub ids: Vec<u32>,
    /// Distances, `queries × k`; infinity in empty slots.
    pub distances: Vec<f32>,
}

impl BatchResults {
    /// The id of an empty slot.
    pub const NONE: u32 = u32::MAX;

    /// The neighbours of query `i`.
    ///
    /// # Panics
    /// When `i` is not a query of the batch.
    pub fn neighbors(&self, i: usize) -> impl Iterator<Item = Neighbor> + '_ {
        let range = i * self.k..(i + 1) * self.k;
        self.ids[range.clone()]
            .iter()
            .zip(&self.distances[range])
            .take_while(|(&id, _)| id != Self::NONE)
            .map(|(&id, &distance)| Neighbor { id, distance })
    }
}

impl Database {
    /// The rows the searches compare.
    fn rows(&self) -> Result<Rows<'_>, Error> {
        Rows::scaled(&self.r, self.config.n_range, &self.r_scale)
    }

    /// Every search over the entries.
    fn index(&self) -> Result<Index<'_>, Error> {
        Index::new(
            self.rows()?,
            &self.perm,
            &self.splits,
            &self.codes,
            &self.params,
        )
    }

    /// The `k` nearest entries to the R-SOLiD `query_r` ([spec §3](crate::spec#3-comparing-descriptors)), nearest first, ties by lower
    /// id, skipping the `exclude_recent` most recent entries.
    ///
    /// # Errors
    /// [`DbError::Core`] for a query of the wrong length or with negative or non-finite values.
    pub fn search(
        &self,
        query_r: &[f32],
        k: usize,
        exclude_recent: usize,
        method: Method,
    ) -> Result<Vec<Neighbor>, DbError> {
        self.search_with(
            query_r,
            &SearchOptions {
                k,
                exclude_recent,
                method,
                ..SearchOptions::default()
            },
        )
    }

    /// [`Database::search`] for a descriptor, checking that it was made with this database's
    /// config.
    ///
    /// # Errors
    /// [`DbError::ConfigMismatch`] for another config; otherwise as [`Database::search`].
    pub fn search_descriptor(
        &self,
        d: &Descriptor,
        k: usize,
        exclude_recent: usize,
        method: Method,
    ) -> Result<Vec<Neighbor>, DbError> {
        self.check_fingerprint(d.fingerprint)?;
        self.search(&d.r, k, exclude_recent, method)
    }

    /// The general search: see [`SearchOptions`].
    ///
    /// # Errors
    /// [`DbError::Core`] for a query of the wrong length or with negative or non-finite values,
    /// a NaN `not_newer_than` (it would compare false with every time: no limit is `None`), or
    /// (name `max_distance`) a NaN bound.
    pub fn search_with(
        &self,
        query_r: &[f32],
        opts: &SearchOptions,
    ) -> Result<Vec<Neighbor>, DbError> {
        let mut q = vec![0.0f32; self.config.n_range];
        self.normalize_query(query_r, &mut q)?;
        let req = self.request(opts)?;
        let mut out = vec![Neighbor::default(); req.k];
        let found = self.index()?.search(&q, &req, &mut out)?;
        self.unindexed.add(self.unindexed_rows(&req));
        out.truncate(found.len);
        Ok(out)
    }

    /// The `k` nearest entries to each of the R-SOLiDs in `queries_r` (`m × n_range`,
    /// row-major), with the same options for all: the results of [`Database::search_with`] for
    /// every query, in one call. With the `parallel` feature the queries are shared among the
    /// threads of a persistent pool (rayon's), one per core.
    ///
    /// # Errors
    /// As [`Database::search_with`], for the first invalid query; [`Error::LengthMismatch`] when
    /// `queries_r` is not a whole number of R-SOLiDs; [`DbError::OutOfMemory`].
    pub fn search_batch(
        &self,
        queries_r: &[f32],
        opts: &SearchOptions,
    ) -> Result<BatchResults, DbError> {
        let nr = self.config.n_range;
        let m = queries_r.len() / nr;
        if m * nr != queries_r.len() {
            return Err(Error::LengthMismatch {
                what: "queries vs a multiple of n_range",
                left: queries_r.len(),
                right: m * nr,
            }
            .into());
        }
        let req = self.request(opts)?;
        let k = req.k;
        let index = self.index()?;
        let oom = |_| DbError::OutOfMemory;
        let mut normed = Vec::new();
        normed.try_reserve_exact(queries_r.len()).map_err(oom)?;
        normed.resize(queries_r.len(), 0.0);
        for (q, out) in queries_r.chunks_exact(nr).zip(normed.chunks_exact_mut(nr)) {
            self.normalize_query(q, out)?;
        }
        let mut ids = Vec::new();
        let mut distances = Vec::new();
        ids.try_reserve_exact(m * k).map_err(oom)?;
        distances.try_reserve_exact(m * k).map_err(oom)?;
        ids.resize(m * k, BatchResults::NONE);
        distances.resize(m * k, f32::INFINITY);
        let one = |q: &[f32],
                   ids: &mut [u32],
                   dists: &mut [f32],
                   scratch: &mut [Neighbor],
                   observed: &Observed| {
            let req = Request {
                observed: Some(observed),
                ..req
            };
            let found = index.search(q, &req, scratch)?;
            for (j, nb) in scratch[..found.len].iter().enumerate() {
                ids[j] = nb.id;
                dists[j] = nb.distance;
            }
            Ok::<(), Error>(())
        };
        if k > 0 {
            batch::run(&normed, nr, k, &mut ids, &mut distances, one)?;
            self.unindexed
                .add(self.unindexed_rows(&req).saturating_mul(m));
        }
        Ok(BatchResults { k, ids, distances })
    }

    /// The search request of `opts` over this database.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a NaN `not_newer_than` (it would compare false with every
    /// time: no limit is `None`).
    pub(super) fn request(&self, opts: &SearchOptions) -> Result<Request<'_>, Error> {
        if let Some(t) = opts.not_newer_than.filter(|t| t.is_nan()) {
            return Err(Error::InvalidParameter {
                name: "not_newer_than",
                value: t,
                expected: "a time in seconds (or None for no limit), not NaN",
            });
        }
        let n = self.len();
        let exclude = Exclude {
            before_id: n.saturating_sub(opts.exclude_recent),
            not_newer_than: opts.not_newer_than.map(|t| (&self.timestamps[..], t)),
        };
        Ok(Request {
            k: opts.k.min(exclude.before_id),
            exclude,
            max_distance: opts.max_distance,
            plan: match opts.method {
                Method::Brute => Plan::Brute,
                Method::KdTree => Plan::KdTree,
                Method::Sketch => Plan::Sketch,
                Method::Auto => Plan::Auto,
            },
            observed: Some(&self.observed),
        })
    }

    /// `query_r` checked against the config and L2-normalised into `out`.
    fn normalize_query(&self, query_r: &[f32], out: &mut [f32]) -> Result<(), DbError> {
        let nr = self.config.n_range;
        super::super::same_len("query r_solid vs config n_range", query_r.len(), nr)?;
        check_bins("query r_solid", query_r)?;
        search::normalize(query_r, out)?;
        Ok(())
    }

    /// The cosine distance ([spec §3](crate::spec#3-comparing-descriptors)) from the R-SOLiD `query_r` to every entry, in id order
    /// (for plots and analysis; searches use [`Database::search`]): the distances the searches
    /// compute.
    ///
    /// # Errors
    /// [`DbError::Core`] for a query of the wrong length or with negative or non-finite values;
    /// [`DbError::OutOfMemory`] when the output cannot be allocated.
    pub fn distances(&self, query_r: &[f32]) -> Result<Vec<f32>, DbError> {
        let mut q = vec![0.0f32; self.config.n_range];
        self.normalize_query(query_r, &mut q)?;
        let mut out = Vec::new();
        out.try_reserve_exact(self.len())
            .map_err(|_| DbError::OutOfMemory)?;
        out.resize(self.len(), 0.0);
        self.rows()?.distances(&q, &mut out)?;
        Ok(out)
    }
}

/// The worker side of [`Database::search_batch`].
mod batch {
    use super::{Error, Neighbor, Observed};
    use alloc::vec;

    /// Queries handed to a worker at a time (small enough to balance, large enough to amortise).
    const CHUNK: usize = 16;

    /// Runs `one` for every query (`queries`: rows of `dim`), writing `k` slots per query. Each
    /// worker keeps its own [`Observed`] for the queries it takes (runs of consecutive queries):
    /// shared, the record of two workers on queries of different kinds would undo each other.
    pub(super) fn run<F>(
        queries: &[f32],
        dim: usize,
        k: usize,
        ids: &mut [u32],
        dists: &mut [f32],
        one: F,
    ) -> Result<(), Error>
    where
        F: Fn(&[f32], &mut [u32], &mut [f32], &mut [Neighbor], &Observed) -> Result<(), Error>
            + Sync,
    {
        let chunk = |observed: &mut Observed,
                     (q, (ids, dists)): (&[f32], (&mut [u32], &mut [f32]))| {
            let mut scratch = vec![Neighbor::default(); k];
            for ((q, ids), dists) in q
                .chunks_exact(dim)
                .zip(ids.chunks_exact_mut(k))
                .zip(dists.chunks_exact_mut(k))
            {
                one(q, ids, dists, &mut scratch, observed)?;
            }
            Ok(())
        };
        let parts = queries
            .chunks(CHUNK * dim)
            .zip(ids.chunks_mut(CHUNK * k).zip(dists.chunks_mut(CHUNK * k)));
        #[cfg(feature = "parallel")]
        if let Some(threads) = crate::pool::work() {
            use rayon::prelude::*;
            let parts: alloc::vec::Vec<_> = parts.collect();
            return threads.install(|| {
                parts
                    .into_par_iter()
                    .try_for_each_init(Observed::timed, chunk)
            });
        }
        let mut observed = Observed::timed();
        parts
            .into_iter()
            .try_for_each(|part| chunk(&mut observed, part))
    }
}
