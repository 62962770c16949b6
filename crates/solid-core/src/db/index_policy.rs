//! When the index (the kd-tree and the search sketch) over entries added in bulk is built: with
//! the add, on request, or by the searches once they have scanned about what building costs.

use super::{Database, DbError, SearchOptions};

/// When [`Database::add_batch_with`] builds the index over the entries it adds. Searches are
/// exact under every policy: the entries beyond the index are scanned by brute force.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IndexPolicy {
    /// With the add.
    Now,
    /// On request: [`Database::build_index`], the next single add, an indexed bulk add or a
    /// merge.
    OnRequest,
    /// By the first search that finds it due ([`Database::index_due`]): a searcher calls
    /// [`Database::build_index_for_search`] before searching. Also on request, as
    /// [`IndexPolicy::OnRequest`].
    BySearches,
}

impl Database {
    /// [`Database::add_batch`], with the index built as `policy` says; the last call decides for
    /// every entry still waiting (a single add or [`Database::add_batch`] leaves the policy as it
    /// is).
    ///
    /// # Errors
    /// As [`Database::add_batch`]; on error nothing is added and the policy is unchanged.
    pub fn add_batch_with(
        &mut self,
        r: &[f32],
        a: &[f32],
        session: u32,
        timestamps: Option<&[f64]>,
        poses: Option<&[[f64; 12]]>,
        policy: IndexPolicy,
    ) -> Result<u32, DbError> {
        let index = policy == IndexPolicy::Now;
        let first = self.add_batch(r, a, session, timestamps, poses, index)?;
        self.index_by_searches = policy == IndexPolicy::BySearches;
        Ok(first)
    }

    /// Whether the searches build the index when it is due: the last
    /// [`Database::add_batch_with`] said [`IndexPolicy::BySearches`], and no build for the
    /// searches has run out of memory since.
    pub fn index_by_searches(&self) -> bool {
        self.index_by_searches
    }

    /// Whether [`Database::build_index_for_search`] builds the index before `queries` searches
    /// with `opts`: the searches build it ([`Database::index_by_searches`]) and it is due
    /// ([`Database::index_due`]). Through `&self`, so that a caller sharing the database (a read
    /// lock) asks before taking it alone.
    pub fn search_builds_index(&self, opts: &SearchOptions, queries: usize) -> bool {
        self.index_by_searches && self.index_due(opts, queries)
    }

    /// Builds the index before `queries` searches with `opts` when
    /// [`Database::search_builds_index`] says so. Without memory for it the searches stay exact
    /// by brute force and stop trying (as [`IndexPolicy::OnRequest`]); a search never fails for
    /// want of an index.
    pub fn build_index_for_search(&mut self, opts: &SearchOptions, queries: usize) {
        if self.search_builds_index(opts, queries) && self.build_index().is_err() {
            self.index_by_searches = false;
        }
    }
}
