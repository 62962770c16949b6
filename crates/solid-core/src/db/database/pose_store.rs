//! The poses a [`Database`](super::Database) holds: as given (an id and the 3×4 matrix, 104
//! bytes), or, read from a file that stores them as quaternions (format 4), in that form (an id
//! and the quaternion with the translation, 60 bytes), the matrix rebuilt on each read being the
//! one the load rebuilt before: the same values either way.

use alloc::vec::Vec;

use crate::db::lean::pose_matrix;

/// What carries the pose of a place (its id in the store appended) into another world
/// ([`PoseStore::append`]); None: the place keeps no pose.
pub(crate) type Move<'a> = &'a dyn Fn(u32, &[f64; 12]) -> Option<[f64; 12]>;

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

    /// Reserves room for `other`'s poses ([`PoseStore::append`]; `moved`: every one as a
    /// matrix).
    pub(crate) fn reserve_for(&mut self, other: &PoseStore, moved: bool) -> Result<(), ()> {
        let oom = |_| ();
        if moved {
            return self.full.try_reserve(other.len()).map_err(oom);
        }
        self.full.try_reserve(other.full.len()).map_err(oom)?;
        self.lean_ids.try_reserve(other.lean.len()).map_err(oom)?;
        self.lean.try_reserve(other.lean.len()).map_err(oom)
    }

    /// Appends `other`'s poses (room reserved), their ids shifted by `base` (beyond every id
    /// held): each in the form `other` holds it, or, with `moved`, as the matrix `moved` gives for
    /// it (a map carried into another's world; none where it gives none).
    pub(crate) fn append(&mut self, other: &PoseStore, base: u32, moved: Option<Move<'_>>) {
        if let Some(f) = moved {
            for id in other.ids() {
                if let Some(p) = other.get(id).and_then(|p| f(id, &p)) {
                    self.full.push((id + base, p));
                }
            }
            return;
        }
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

#[cfg(test)]
mod tests {
    use super::{pose_matrix, PoseStore};
    use alloc::vec;
    use alloc::vec::Vec;

    #[test]
    fn appended_poses_keep_their_form_or_are_moved_as_matrices() {
        // Places 1 and 3 read as quaternions (a quarter turn about z), 2 given as a matrix.
        let q = [1.0, 0.0, 0.0, 1.0, 5.0, 6.0, 7.0];
        let mut other = PoseStore::from_lean(vec![1, 3], vec![q, q]);
        let mut m = pose_matrix(&q);
        m[3] = -1.0;
        other.try_reserve(1).unwrap();
        other.push(2, m);
        assert_eq!(other.ids().collect::<Vec<_>>(), [1, 2, 3]);
        let mut kept = PoseStore::from_full(vec![(0, m)]);
        kept.reserve_for(&other, false).unwrap();
        kept.append(&other, 10, None);
        assert_eq!(kept.ids().collect::<Vec<_>>(), [0, 11, 12, 13]);
        assert_eq!(kept.lean.len(), 2);
        assert_eq!(kept.get(11), Some(pose_matrix(&q)));
        assert_eq!(kept.get(12), Some(m));
        let shift = |p: &[f64; 12]| {
            let mut p = *p;
            p[3] += 100.0;
            p
        };
        let mut moved = PoseStore::default();
        moved.reserve_for(&other, true).unwrap();
        moved.append(&other, 0, Some(&|_, p| Some(shift(p))));
        assert!(moved.lean.is_empty() && moved.len() == 3);
        assert_eq!(moved.ids().collect::<Vec<_>>(), [1, 2, 3]);
        for id in 1..4 {
            assert_eq!(moved.get(id), other.get(id).map(|p| shift(&p)));
        }
        assert_eq!(moved.get(0), None);
        // A place the move gives no pose keeps none.
        let mut some = PoseStore::default();
        some.reserve_for(&other, true).unwrap();
        some.append(&other, 10, Some(&|id, p| (id != 2).then(|| shift(p))));
        assert_eq!(some.ids().collect::<Vec<_>>(), [11, 13]);
        assert_eq!(some.get(12), None);
    }
}
