//! The poses a [`Database`](super::Database) holds: as given (an id and the 3×4 matrix, 104
//! bytes), or, read from a file that stores them as quaternions (format 4), in that form (an id
//! and the quaternion with the translation, 60 bytes), the matrix rebuilt on each read being the
//! one the load rebuilt before: the same values either way.

use alloc::vec::Vec;

use crate::db::lean::pose_matrix;

/// The poses of a database, by id.
#[derive(Debug, Clone, Default)]
pub(crate) struct PoseStore {
    /// Poses as given (row-major `[R|t]`), by increasing id.
    full: Vec<(u32, [f64; 12])>,
    /// The ids of the poses read as quaternions, increasing, and their records (the file's
    /// quaternion and translation).
    lean_ids: Vec<u32>,
    lean: Vec<[f64; 7]>,
}

impl PoseStore {
    /// Poses as given, by increasing id.
    pub(crate) fn from_full(full: Vec<(u32, [f64; 12])>) -> Self {
        PoseStore {
            full,
            ..PoseStore::default()
        }
    }

    /// Poses read as quaternions and translations, of the places `ids` (increasing).
    pub(crate) fn from_lean(ids: Vec<u32>, lean: Vec<[f64; 7]>) -> Self {
        debug_assert_eq!(ids.len(), lean.len());
        PoseStore {
            lean_ids: ids,
            lean,
            ..PoseStore::default()
        }
    }

    /// Number of poses.
    pub(crate) fn len(&self) -> usize {
        self.full.len() + self.lean.len()
    }

    /// The pose of place `id`, if it has one.
    pub(crate) fn get(&self, id: u32) -> Option<[f64; 12]> {
        if let Ok(at) = self.lean_ids.binary_search(&id) {
            return Some(pose_matrix(&self.lean[at]));
        }
        self.full
            .binary_search_by_key(&id, |(i, _)| *i)
            .ok()
            .map(|at| self.full[at].1)
    }

    /// Every pose with its id (not in id order when some are held each way).
    pub(crate) fn each(&self) -> impl Iterator<Item = (u32, [f64; 12])> + '_ {
        let lean = self.lean_ids.iter().zip(&self.lean);
        (self.full.iter().copied()).chain(lean.map(|(&id, v)| (id, pose_matrix(v))))
    }

    /// The ids of the places with a pose, increasing.
    pub(crate) fn ids(&self) -> impl Iterator<Item = u32> + '_ {
        let mut full = self.full.iter().map(|(id, _)| *id).peekable();
        let mut lean = self.lean_ids.iter().copied().peekable();
        core::iter::from_fn(move || match (full.peek(), lean.peek()) {
            (Some(f), Some(l)) if f < l => full.next(),
            (Some(_), None) => full.next(),
            _ => lean.next(),
        })
    }

    pub(crate) fn try_reserve(&mut self, additional: usize) -> Result<(), ()> {
        self.full.try_reserve(additional).map_err(|_| ())
    }

    /// Adds the pose of place `id`, beyond every id held (room reserved).
    pub(crate) fn push(&mut self, id: u32, pose: [f64; 12]) {
        self.full.push((id, pose));
    }

    /// Reserves room for `other`'s poses ([`PoseStore::append`]).
    pub(crate) fn reserve_for(&mut self, other: &PoseStore) -> Result<(), ()> {
        let oom = |_| ();
        self.full.try_reserve(other.full.len()).map_err(oom)?;
        self.lean_ids.try_reserve(other.lean.len()).map_err(oom)?;
        self.lean.try_reserve(other.lean.len()).map_err(oom)
    }

    /// Appends `other`'s poses (room reserved), their ids shifted by `base` (beyond every id
    /// held), each in the form `other` holds it.
    pub(crate) fn append(&mut self, other: &PoseStore, base: u32) {
        self.full
            .extend(other.full.iter().map(|(id, p)| (id + base, *p)));
        self.lean_ids
            .extend(other.lean_ids.iter().map(|id| id + base));
        self.lean.extend_from_slice(&other.lean);
    }

    /// Bytes of heap memory held (every buffer's capacity).
    pub(crate) fn heap_bytes(&self) -> usize {
        self.full.capacity() * core::mem::size_of::<(u32, [f64; 12])>()
            + self.lean_ids.capacity() * 4
            + self.lean.capacity() * core::mem::size_of::<[f64; 7]>()
    }
}
