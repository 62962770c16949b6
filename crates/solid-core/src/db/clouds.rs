//! The compact point clouds places keep for verification (feature `alloc`).
//!
//! Each place may carry its downsampled cloud in the quantised wire form of
//! [`crate::reg::wire`] (a few bytes a point: docs/performance.md#cloud-wire-form),
//! stored back to back in one buffer. Only the entries up to the last one with a cloud have an
//! offset: a database without clouds pays nothing per entry, nor do entries added after the last
//! cloud (bulk adds of descriptors alone).

use alloc::vec::Vec;

use super::DbError;

/// Clouds of the entries, by id (see the module documentation).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Clouds {
    /// `offsets[i]..offsets[i + 1]` is entry `i`'s cloud in `data` (empty: none), for the entries
    /// `i < offsets.len() - 1`; the others have none. Empty while no entry has a cloud.
    offsets: Vec<u64>,
    data: Vec<u8>,
}

impl Clouds {
    /// Whether any entry has a cloud.
    pub fn any(&self) -> bool {
        !self.data.is_empty()
    }

    /// The stored cloud of entry `id` (in the wire form), if any.
    pub fn get(&self, id: usize) -> Option<&[u8]> {
        if id + 1 >= self.offsets.len() {
            return None;
        }
        let (a, b) = (self.offsets[id] as usize, self.offsets[id + 1] as usize);
        (b > a).then(|| &self.data[a..b])
    }

    /// Number of entries that have a cloud.
    pub fn count(&self) -> usize {
        self.offsets.windows(2).filter(|w| w[1] > w[0]).count()
    }

    /// Bytes held (offsets and data).
    pub fn heap_bytes(&self) -> usize {
        self.offsets.capacity() * 8 + self.data.capacity()
    }

    /// Total bytes of the clouds themselves.
    pub fn data_len(&self) -> usize {
        self.data.len()
    }

    /// Stores `cloud` for entry `id`, which must not be below an entry that has one already
    /// (`None` or an empty cloud: nothing to store).
    ///
    /// # Errors
    /// [`DbError::OutOfMemory`] when the memory cannot be reserved (nothing changes).
    pub fn push(&mut self, id: usize, cloud: Option<&[u8]>) -> Result<(), DbError> {
        let bytes = match cloud {
            Some(b) if !b.is_empty() => b,
            _ => return Ok(()),
        };
        debug_assert!(
            id + 1 >= self.offsets.len(),
            "clouds are pushed in id order"
        );
        let grow = (id + 2).saturating_sub(self.offsets.len());
        self.offsets
            .try_reserve(grow)
            .map_err(|_| DbError::OutOfMemory)?;
        self.data
            .try_reserve(bytes.len())
            .map_err(|_| DbError::OutOfMemory)?;
        self.pad(id);
        self.data.extend_from_slice(bytes);
        self.offsets.push(self.data.len() as u64);
        Ok(())
    }

    /// Gives entries `..id` an offset (none of them gains a cloud); capacity reserved.
    fn pad(&mut self, id: usize) {
        let end = self.data.len() as u64;
        if self.offsets.is_empty() {
            self.offsets.push(0);
        }
        while self.offsets.len() < id + 1 {
            self.offsets.push(end);
        }
    }

    /// Forgets the clouds of entries `n..` (after an add that failed).
    pub fn truncate(&mut self, n: usize) {
        if self.offsets.len() > n + 1 {
            self.offsets.truncate(n + 1);
            self.data.truncate(self.offsets[n] as usize);
        }
        if self.data.is_empty() {
            self.offsets.clear();
        }
    }

    /// Appends the clouds of `other` after `self_len` entries.
    ///
    /// # Errors
    /// [`DbError::OutOfMemory`] when the memory cannot be reserved (nothing changes).
    pub fn append(&mut self, self_len: usize, other: &Clouds) -> Result<(), DbError> {
        if !other.any() {
            return Ok(());
        }
        let grow = (self_len + other.offsets.len()).saturating_sub(self.offsets.len());
        self.offsets
            .try_reserve(grow)
            .map_err(|_| DbError::OutOfMemory)?;
        self.data
            .try_reserve(other.data.len())
            .map_err(|_| DbError::OutOfMemory)?;
        self.pad(self_len);
        let base = self.data.len() as u64;
        self.data.extend_from_slice(&other.data);
        self.offsets
            .extend(other.offsets[1..].iter().map(|&o| o + base));
        Ok(())
    }

    /// The per-entry lengths, for the file format (`n` entries).
    pub(super) fn lengths(&self, n: usize) -> impl Iterator<Item = u32> + '_ {
        (0..n).map(move |i| self.get(i).map_or(0, |c| c.len() as u32))
    }

    /// The concatenated cloud bytes, in id order.
    pub(super) fn bytes(&self) -> &[u8] {
        &self.data
    }

    /// Rebuilds from per-entry lengths and the concatenated bytes (the file format).
    ///
    /// # Errors
    /// [`DbError::Format`] when the lengths do not add up to the bytes;
    /// [`DbError::OutOfMemory`] when the memory cannot be reserved.
    pub(super) fn from_parts(lengths: &[u32], data: &[u8]) -> Result<Clouds, DbError> {
        let total: u64 = lengths.iter().map(|&l| u64::from(l)).sum();
        if total != data.len() as u64 {
            return Err(DbError::Format {
                file: None,
                reason: alloc::format!(
                    "the cloud lengths add up to {total} bytes but the section holds {}",
                    data.len()
                ),
            });
        }
        if data.is_empty() {
            return Ok(Clouds::default());
        }
        let mut offsets = Vec::new();
        offsets
            .try_reserve_exact(lengths.len() + 1)
            .map_err(|_| DbError::OutOfMemory)?;
        offsets.push(0u64);
        let mut at = 0u64;
        for &l in lengths {
            at += u64::from(l);
            offsets.push(at);
        }
        let mut bytes = Vec::new();
        bytes
            .try_reserve_exact(data.len())
            .map_err(|_| DbError::OutOfMemory)?;
        bytes.extend_from_slice(data);
        Ok(Clouds {
            offsets,
            data: bytes,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sparse_clouds_and_append() {
        let mut c = Clouds::default();
        c.push(0, None).unwrap();
        c.push(1, None).unwrap();
        assert!(!c.any() && c.heap_bytes() == 0);
        c.push(2, Some(&[1, 2, 3])).unwrap();
        c.push(3, None).unwrap();
        c.push(4, Some(&[4])).unwrap();
        assert_eq!(
            (0..6).map(|i| c.get(i)).collect::<Vec<_>>(),
            [
                None,
                None,
                Some(&[1u8, 2, 3][..]),
                None,
                Some(&[4u8][..]),
                None
            ]
        );
        let mut d = Clouds::default();
        d.push(0, None).unwrap();
        d.append(1, &c).unwrap();
        assert_eq!(d.count(), 2);
        assert_eq!(d.get(3), Some(&[1u8, 2, 3][..]));
        assert_eq!(d.get(5), Some(&[4u8][..]));
        let lengths: Vec<u32> = d.lengths(6).collect();
        assert_eq!(lengths, [0, 0, 0, 3, 0, 1]);
        assert_eq!(
            Clouds::from_parts(&lengths, d.bytes()).unwrap().get(5),
            Some(&[4u8][..])
        );
        assert!(Clouds::from_parts(&lengths, &[1, 2]).is_err());
        // Entries without clouds after the last one cost nothing and stay in step.
        d.append(6, &Clouds::default()).unwrap();
        assert_eq!(d.get(7), None);
        d.push(8, Some(&[9])).unwrap();
        assert_eq!(d.get(8), Some(&[9u8][..]));
        assert_eq!(
            d.lengths(10).collect::<Vec<_>>(),
            [0, 0, 0, 3, 0, 1, 0, 0, 1, 0]
        );
        // A failed add is cut back; cutting back the only cloud leaves none.
        d.truncate(8);
        assert_eq!((d.get(8), d.count(), d.data_len()), (None, 2, 4));
        let mut e = Clouds::default();
        e.push(3, Some(&[1])).unwrap();
        e.truncate(3);
        assert!(!e.any() && e.get(3).is_none() && e.heap_bytes() > 0);
        e.push(3, Some(&[2])).unwrap();
        assert_eq!(e.get(3), Some(&[2u8][..]));
    }
}
