//! The compact point clouds places keep for verification (feature `alloc`).
//!
//! Each place may carry its downsampled cloud in the quantised wire form of
//! [`crate::reg::wire`] (a few bytes a point: docs/performance.md#cloud-wire-form), each with its
//! own checksum. The clouds are laid end to end in one sequence of bytes, split into segments: in
//! memory (added, or read from bytes), or, with `std`, still in the file a database was loaded
//! from, read by offset when a place's cloud is asked for (clouds on demand: a loaded map holds
//! none of them). Only the entries up to the last one with a cloud have an offset: a database
//! without clouds pays nothing per entry, nor do entries added after the last cloud.

use alloc::borrow::Cow;
use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;

use super::DbError;

/// Clouds of the entries, by id (see the module documentation).
#[derive(Debug, Clone, Default)]
pub struct Clouds {
    /// `offsets[i]..offsets[i + 1]` is entry `i`'s cloud in the sequence (empty: none), for the
    /// entries `i < offsets.len() - 1`; the others have none. Empty while no entry has a cloud.
    offsets: Vec<u64>,
    /// The sequence, by increasing start; each cloud lies within one segment.
    segments: Vec<Segment>,
}

/// A stretch of the sequence of clouds.
#[derive(Debug, Clone)]
struct Segment {
    /// Where it starts in the sequence.
    start: u64,
    /// Its bytes.
    store: Store,
    /// How many places precede its first in the database it was read from (the ids of the file
    /// are this database's minus `shift`, for messages).
    shift: u32,
}

#[derive(Debug, Clone)]
enum Store {
    Memory(Vec<u8>),
    #[cfg(feature = "std")]
    File(alloc::sync::Arc<FileClouds>, u64),
}

/// The cloud section of an open database file.
#[cfg(feature = "std")]
#[derive(Debug)]
pub(super) struct FileClouds {
    file: std::fs::File,
    /// The file's name, for messages.
    name: String,
    /// Where the section starts in the file.
    at: u64,
    /// The file's length, modification time, header and section table when it was loaded: every
    /// read checks them, so that a file truncated or written in place is an error naming it,
    /// never other bytes (see [`FileClouds::check_unchanged`]).
    len: u64,
    modified: Option<std::time::SystemTime>,
    head: Vec<u8>,
}

/// The bytes of a format 3/4 file's header and section table (`S` sections: 96 + 32·S + 4).
#[cfg(feature = "std")]
fn read_head(file: &std::fs::File) -> std::io::Result<Vec<u8>> {
    let mut count = [0u8; 4];
    read_file_at(file, &mut count, 88)?;
    let sections = u32::from_le_bytes(count).min(64) as usize;
    let mut head = vec![0u8; 96 + 32 * sections + 4];
    read_file_at(file, &mut head, 0)?;
    Ok(head)
}

#[cfg(feature = "std")]
impl FileClouds {
    /// The clouds section at `at` of the open `file` (named `name`), as the file is now.
    pub(super) fn new(file: std::fs::File, name: String, at: u64) -> std::io::Result<FileClouds> {
        let m = file.metadata()?;
        let head = read_head(&file)?;
        Ok(FileClouds {
            file,
            name,
            at,
            len: m.len(),
            modified: m.modified().ok(),
            head,
        })
    }

    fn changed(&self, how: String) -> DbError {
        DbError::Changed {
            file: self.name.clone(),
            how,
        }
    }

    /// Whether the file's length or modification time differ from when it was loaded.
    fn touched(&self) -> Result<Option<u64>, DbError> {
        let m = self.file.metadata().map_err(|source| DbError::Io {
            file: self.name.clone(),
            source,
        })?;
        let same = m.len() == self.len && m.modified().ok() == self.modified;
        Ok((!same).then_some(m.len()))
    }

    /// [`DbError::Changed`] when the file is no longer the one loaded: shorter than it was, or
    /// written with another header or section table. A file that only grew (appended to) keeps
    /// the clouds where they were, each checked by its checksum when read ([`Clouds::get`]); one
    /// renamed over or unlinked is no change (the open file is still the one loaded).
    fn check_unchanged(&self) -> Result<(), DbError> {
        let Some(len) = self.touched()? else {
            return Ok(());
        };
        if len < self.len {
            return Err(self.changed(format!("{} bytes when loaded, {len} now", self.len)));
        }
        match read_head(&self.file) {
            Ok(head) if head == self.head => Ok(()),
            _ => Err(self.changed(String::from(
                "written since it was loaded: its header is no longer the one loaded",
            ))),
        }
    }
}

impl Segment {
    fn len(&self) -> u64 {
        match &self.store {
            Store::Memory(v) => v.len() as u64,
            #[cfg(feature = "std")]
            Store::File(_, len) => *len,
        }
    }
}

impl Clouds {
    /// Whether any entry has a cloud.
    pub fn any(&self) -> bool {
        self.data_len() > 0
    }

    /// The stored cloud of entry `id` (in the wire form), if any, its checksum checked
    /// ([`crate::reg::check_cloud`]).
    ///
    /// # Errors
    /// [`DbError::Format`] naming the place when its cloud is corrupt; [`DbError::Io`] when it
    /// cannot be read from the database's file.
    pub fn get(&self, id: usize) -> Result<Option<Cow<'_, [u8]>>, DbError> {
        if id + 1 >= self.offsets.len() {
            return Ok(None);
        }
        let (a, b) = (self.offsets[id], self.offsets[id + 1]);
        if b <= a {
            return Ok(None);
        }
        let at = self.segments.partition_point(|s| s.start <= a) - 1;
        let seg = &self.segments[at];
        let (from, to) = ((a - seg.start) as usize, (b - seg.start) as usize);
        let bytes: Cow<'_, [u8]> = match &seg.store {
            Store::Memory(v) => Cow::Borrowed(&v[from..to]),
            #[cfg(feature = "std")]
            Store::File(f, _) => {
                let mut buf = super::format::try_vec::<u8>(to - from)?;
                buf.resize(to - from, 0);
                let read = read_file_at(&f.file, &mut buf, f.at + from as u64);
                f.check_unchanged()?;
                read.map_err(|source| DbError::Io {
                    file: f.name.clone(),
                    source,
                })?;
                Cow::Owned(buf)
            }
        };
        if let Err(e) = crate::reg::check_cloud(&bytes) {
            // A cloud written over since the file was loaded is a change, not a corrupt cloud.
            #[cfg(feature = "std")]
            if let Store::File(f, _) = &seg.store {
                if f.touched()?.is_some() {
                    return Err(f.changed(format!(
                        "written since it was loaded: the stored cloud of place {id} is no longer the one loaded"
                    )));
                }
            }
            return Err(DbError::Format {
                file: None,
                reason: self.corrupt(id, seg, e),
            });
        }
        Ok(Some(bytes))
    }

    /// Why the cloud of place `id` in `seg` is refused, naming it as the file it came from does.
    fn corrupt(&self, id: usize, seg: &Segment, e: crate::error::RegError) -> String {
        #[cfg(feature = "std")]
        if let Store::File(f, _) = &seg.store {
            let own = id - seg.shift as usize;
            let place = if own == id {
                format!("the stored cloud of place {id} in {}", f.name)
            } else {
                format!(
                    "place {id}'s stored cloud (the cloud of place {own} in {})",
                    f.name
                )
            };
            return format!("{place} is corrupt: {e}");
        }
        let _ = seg;
        format!("the stored cloud of place {id} is corrupt: {e}")
    }

    /// Number of entries that have a cloud.
    pub fn count(&self) -> usize {
        self.offsets.windows(2).filter(|w| w[1] > w[0]).count()
    }

    /// Bytes held in memory (offsets and the clouds not left in a file).
    pub fn heap_bytes(&self) -> usize {
        self.offsets.capacity() * 8
            + self
                .segments
                .iter()
                .map(|s| match &s.store {
                    Store::Memory(v) => v.capacity(),
                    #[cfg(feature = "std")]
                    Store::File(..) => 0,
                })
                .sum::<usize>()
    }

    /// Total bytes of the clouds themselves.
    pub fn data_len(&self) -> usize {
        self.segments
            .last()
            .map_or(0, |s| (s.start + s.len()) as usize)
    }

    /// The memory segment at the end of the sequence, started when the last is not one.
    fn tail(&mut self) -> &mut Vec<u8> {
        if !matches!(
            self.segments.last(),
            Some(Segment {
                store: Store::Memory(_),
                ..
            })
        ) {
            let start = self.data_len() as u64;
            self.segments.push(Segment {
                start,
                store: Store::Memory(Vec::new()),
                shift: 0,
            });
        }
        match self.segments.last_mut() {
            Some(Segment {
                store: Store::Memory(v),
                ..
            }) => v,
            _ => unreachable!("a memory segment was just pushed"),
        }
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
        self.segments
            .try_reserve(1)
            .map_err(|_| DbError::OutOfMemory)?;
        let tail = self.tail();
        tail.try_reserve(bytes.len())
            .map_err(|_| DbError::OutOfMemory)?;
        tail.extend_from_slice(bytes);
        self.pad(id);
        self.offsets.push(self.data_len() as u64);
        Ok(())
    }

    /// Gives entries `..id` an offset (none of them gains a cloud); capacity reserved. Called
    /// after the bytes of entry `id`'s cloud (if any) were added: the padding ends where the
    /// sequence ended before them.
    fn pad(&mut self, id: usize) {
        let end = *self.offsets.last().unwrap_or(&0);
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
        }
        let end = self.offsets.last().copied().unwrap_or(0);
        while self.segments.last().is_some_and(|s| s.start >= end) {
            self.segments.pop();
        }
        if let Some(s) = self.segments.last_mut() {
            match &mut s.store {
                Store::Memory(v) => v.truncate((end - s.start) as usize),
                #[cfg(feature = "std")]
                Store::File(_, len) => *len = (*len).min(end - s.start),
            }
        }
        if !self.any() {
            self.offsets.clear();
            self.segments.clear();
        }
    }

    /// Appends the clouds of `other` after `self_len` entries (clouds still in a file stay there).
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
        self.segments
            .try_reserve(other.segments.len())
            .map_err(|_| DbError::OutOfMemory)?;
        let mut copies = Vec::new();
        copies
            .try_reserve(other.segments.len())
            .map_err(|_| DbError::OutOfMemory)?;
        for s in &other.segments {
            let store = match &s.store {
                Store::Memory(v) => {
                    let mut c = Vec::new();
                    c.try_reserve_exact(v.len())
                        .map_err(|_| DbError::OutOfMemory)?;
                    c.extend_from_slice(v);
                    Store::Memory(c)
                }
                #[cfg(feature = "std")]
                Store::File(f, len) => Store::File(f.clone(), *len),
            };
            copies.push((s.start, store, s.shift));
        }
        let base = self.data_len() as u64;
        self.pad(self_len);
        for (start, store, shift) in copies {
            self.segments.push(Segment {
                start: start + base,
                store,
                shift: shift + self_len as u32,
            });
        }
        self.offsets
            .extend(other.offsets[1..].iter().map(|&o| o + base));
        Ok(())
    }

    /// The per-entry lengths (`n` entries), for the version-2 file format.
    pub(super) fn lengths(&self, n: usize) -> impl Iterator<Item = u32> + '_ {
        (0..n).map(move |i| match self.offsets.get(i..i + 2) {
            Some(w) => (w[1] - w[0]) as u32,
            None => 0,
        })
    }

    /// The offsets of the entries `0..offsets().len() - 1` in the sequence (empty: no cloud).
    pub(super) fn offsets(&self) -> &[u64] {
        &self.offsets
    }

    /// Calls `put` with every stored cloud, in id order, each checked as [`Clouds::get`] does:
    /// a corrupt one stops the copy with its error, so that nothing copies it into a new file
    /// under a fresh checksum.
    ///
    /// # Errors
    /// As [`Clouds::get`], or the first error of `put`.
    pub(super) fn each(
        &self,
        mut put: impl FnMut(&[u8]) -> Result<(), DbError>,
    ) -> Result<(), DbError> {
        for id in 0..self.offsets.len().saturating_sub(1) {
            if let Some(c) = self.get(id)? {
                put(&c)?;
            }
        }
        Ok(())
    }

    /// Rebuilds from per-entry lengths and the concatenated bytes (the version-2 file format).
    ///
    /// # Errors
    /// [`DbError::Format`] when the lengths do not add up to the bytes;
    /// [`DbError::OutOfMemory`] when the memory cannot be reserved.
    pub(super) fn from_parts(lengths: &[u32], data: &[u8]) -> Result<Clouds, DbError> {
        let total: u64 = lengths.iter().map(|&l| u64::from(l)).sum();
        if total != data.len() as u64 {
            return Err(DbError::Format {
                file: None,
                reason: format!(
                    "the cloud lengths add up to {total} bytes but the section holds {}",
                    data.len()
                ),
            });
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
        Ok(Clouds::with_offsets(offsets, Store::Memory(bytes)))
    }

    /// Clouds at checked `offsets` (starting at 0, not decreasing, ending at the bytes' length)
    /// of the bytes in memory.
    pub(super) fn in_memory(offsets: Vec<u64>, data: Vec<u8>) -> Clouds {
        Clouds::with_offsets(offsets, Store::Memory(data))
    }

    /// Clouds at checked `offsets` of the cloud section of a file, read when asked for.
    #[cfg(feature = "std")]
    pub(super) fn in_file(offsets: Vec<u64>, file: FileClouds) -> Clouds {
        let len = offsets.last().copied().unwrap_or(0);
        Clouds::with_offsets(offsets, Store::File(alloc::sync::Arc::new(file), len))
    }

    fn with_offsets(offsets: Vec<u64>, store: Store) -> Clouds {
        let mut c = Clouds {
            offsets,
            segments: alloc::vec![Segment {
                start: 0,
                store,
                shift: 0,
            }],
        };
        if !c.any() {
            c = Clouds::default();
        }
        c
    }
}

/// Reads `buf.len()` bytes of `file` at offset `at` (the file's position untouched, so that
/// threads share one handle).
#[cfg(feature = "std")]
pub(super) fn read_file_at(file: &std::fs::File, buf: &mut [u8], at: u64) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::os::unix::fs::FileExt::read_exact_at(file, buf, at)
    }
    #[cfg(windows)]
    {
        let mut done = 0;
        while done < buf.len() {
            match std::os::windows::fs::FileExt::seek_read(file, &mut buf[done..], at + done as u64)
            {
                Ok(0) => return Err(std::io::ErrorKind::UnexpectedEof.into()),
                Ok(n) => done += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }
}

/// [`read_file_at`] into memory not yet written: the bytes read, without zeroing the buffer
/// first (on Unix; elsewhere it is zeroed, then read).
#[cfg(feature = "std")]
pub(super) fn read_file_uninit<'a>(
    file: &std::fs::File,
    buf: &'a mut [core::mem::MaybeUninit<u8>],
    at: u64,
) -> std::io::Result<&'a mut [u8]> {
    #[cfg(unix)]
    #[allow(unsafe_code)]
    {
        use std::os::unix::io::AsRawFd;
        let mut done = 0;
        while done < buf.len() {
            let rest = &mut buf[done..];
            let offset = libc::off_t::try_from(at + done as u64)
                .map_err(|_| std::io::Error::from(std::io::ErrorKind::InvalidInput))?;
            // SAFETY: pread writes at most `rest.len()` bytes into `rest`, memory this function
            // holds exclusively; it reads none of it.
            let got = unsafe {
                libc::pread(
                    file.as_raw_fd(),
                    rest.as_mut_ptr().cast::<libc::c_void>(),
                    rest.len(),
                    offset,
                )
            };
            match got {
                0 => return Err(std::io::ErrorKind::UnexpectedEof.into()),
                n if n > 0 => done += n as usize,
                _ => {
                    let e = std::io::Error::last_os_error();
                    if e.kind() != std::io::ErrorKind::Interrupted {
                        return Err(e);
                    }
                }
            }
        }
        // SAFETY: every byte was written by pread above; `MaybeUninit<u8>` has the layout of u8.
        Ok(unsafe { &mut *(core::ptr::from_mut(buf) as *mut [u8]) })
    }
    #[cfg(not(unix))]
    {
        let buf = super::room::zeroed(buf);
        read_file_at(file, buf, at)?;
        Ok(buf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cloud(tag: u8, n: usize) -> Vec<u8> {
        let points: Vec<[f64; 3]> = (0..n).map(|k| [k as f64, f64::from(tag), 0.5]).collect();
        crate::reg::encode_cloud(&points, 0.1, 8).unwrap()
    }

    fn got(c: &Clouds, id: usize) -> Option<Vec<u8>> {
        c.get(id).unwrap().map(|b| b.into_owned())
    }

    #[test]
    fn sparse_clouds_and_append() {
        let (x, y, z) = (cloud(1, 3), cloud(2, 1), cloud(3, 5));
        let mut c = Clouds::default();
        c.push(0, None).unwrap();
        c.push(1, None).unwrap();
        assert!(!c.any() && c.heap_bytes() == 0);
        c.push(2, Some(&x)).unwrap();
        c.push(3, None).unwrap();
        c.push(4, Some(&y)).unwrap();
        assert_eq!(
            (0..6).map(|i| got(&c, i)).collect::<Vec<_>>(),
            [None, None, Some(x.clone()), None, Some(y.clone()), None]
        );
        let mut d = Clouds::default();
        d.push(0, None).unwrap();
        d.append(1, &c).unwrap();
        assert_eq!(d.count(), 2);
        assert_eq!(got(&d, 3), Some(x.clone()));
        assert_eq!(got(&d, 5), Some(y.clone()));
        let lengths: Vec<u32> = d.lengths(6).collect();
        let (lx, ly) = (x.len() as u32, y.len() as u32);
        assert_eq!(lengths, [0, 0, 0, lx, 0, ly]);
        let mut all = x.clone();
        all.extend_from_slice(&y);
        assert_eq!(
            got(&Clouds::from_parts(&lengths, &all).unwrap(), 5),
            Some(y.clone())
        );
        assert!(Clouds::from_parts(&lengths, &[1, 2]).is_err());
        // Entries without clouds after the last one cost nothing and stay in step.
        d.append(6, &Clouds::default()).unwrap();
        assert_eq!(got(&d, 7), None);
        d.push(8, Some(&z)).unwrap();
        assert_eq!(got(&d, 8), Some(z.clone()));
        assert_eq!(
            d.lengths(10).collect::<Vec<_>>(),
            [0, 0, 0, lx, 0, ly, 0, 0, z.len() as u32, 0]
        );
        // A failed add is cut back; cutting back the only cloud leaves none.
        d.truncate(8);
        assert_eq!(
            (got(&d, 8), d.count(), d.data_len()),
            (None, 2, (lx + ly) as usize)
        );
        let mut e = Clouds::default();
        e.push(3, Some(&x)).unwrap();
        e.truncate(3);
        assert!(!e.any() && got(&e, 3).is_none());
        e.push(3, Some(&y)).unwrap();
        assert_eq!(got(&e, 3), Some(y.clone()));
    }

    #[test]
    fn a_corrupt_cloud_is_an_error_naming_its_place() {
        let mut x = cloud(1, 4);
        let mut c = Clouds::default();
        c.push(0, Some(&x)).unwrap();
        let mid = x.len() / 2;
        x[mid] ^= 0x10;
        c.push(1, Some(&x)).unwrap();
        assert!(c.get(0).unwrap().is_some());
        let why = alloc::string::ToString::to_string(&c.get(1).unwrap_err());
        assert!(
            why.contains("cloud of place 1") && why.contains("checksum"),
            "{why}"
        );
        assert!(c.each(|_| Ok(())).is_err());
    }
}
