//! Format versions 3 and 4 of the database file: the columns as the database holds them, each
//! section found through a table in the header and checked on its own, the clouds read on
//! demand. Version 4 stores a pose as a unit quaternion (kinds 11 and 12) instead of a matrix.
//!
//! ```text
//! offset  size        field                     (all numbers little-endian)
//! 0       8           magic "SOLiDdb\0"
//! 8       4   u32     format version (4; 3 is read and written on request)
//! 12      4   u32     flags (0)
//! 16      4×u32       n_range, n_azimuth, n_elevation, 0
//! 32      5×f64       fov_up, fov_down, min_range, max_range, voxel_size
//! 72      8   u64     config fingerprint
//! 80      8   u64     entry count n
//! 88      4   u32     section count S (1..=16)
//! 92      4   u32     0
//! 96      S×32        section table: u32 kind, u32 0, u64 offset, u64 length L, u64 items
//! 96+32S  4   u32     CRC-32 of the bytes before it
//! ...                 the sections, back to back in table order, kinds increasing, each its L
//!                     bytes then the CRC-32 of those; the file ends with the last
//! ```
//! Sections (items: what the table counts; the starred ones only when there is something in them):
//! ```text
//! kind  name           items        bytes
//! 1     sessions       runs r       r×32: u32 session, u32 places, u32 with a pose, u32 0,
//!                                   f64 first and f64 last timestamp (NaN: none) of a run of
//!                                   consecutive places of one session
//! 2     r              0            n×n_range f32: the R-SOLiDs as added
//! 3     r_scale        0            n f32: 1/‖R‖, as `search::inverse_norm` gives it
//! 4     a_codes        0            n×n_azimuth u8: the A-SOLiDs at 8 bits (`Database::a`)
//! 5     a_step         0            n f32: their steps
//! 6*    times          0            n f64 (NaN: none)
//! 7*    poses          p            p×100: u32 id (increasing), 12×f64 row-major [R|t]: every
//!                                   pose in version 3; in version 4 only when some rotation is
//!                                   not rebuilt within 1e-12 from its quaternion (not a rotation)
//! 8*    cloud_offsets  m            version 3: (m+1)×u64, place i < m has bytes offset[i]..
//!                                   offset[i+1] of the clouds section (empty: no cloud);
//!                                   version 4: m×u32, the length of each, the offsets their
//!                                   running sums from 0
//!                                   the clouds section (empty: no cloud)
//! 9*    clouds         places with one  the clouds back to back, each in the wire form of
//!                                   `reg::encode_cloud` with its own CRC
//! 10*   metadata       0            UTF-8 text (`Database::metadata`), at most 1 MiB
//! 11*   pose_ids       p            p×u32: the places with a pose, increasing (version 4, with
//!                                   12, when some place has none)
//! 12*   pose_q         p            p×56: f64 w, x, y, z, the rotation's quaternion divided by
//!                                   its largest component (1), then f64 tx, ty, tz (version 4,
//!                                   instead of 7)
//! ```
//! A pose read from `pose_q` is the rotation the quaternion gives, each entry within 1e-12 of the
//! saved one (about 2e-14 for a rotation; `save` stores the matrix otherwise), and the translation
//! as saved; saved again, it gives the same bytes ([`poses`]).
//! A load reads the header and the table, checks them against the file's size, then reads each
//! section once into the column it becomes (no buffer of the whole file), checking its CRC, but
//! not the clouds: those are read by offset when a place's cloud is asked for, their own CRC
//! checked then ([`super::clouds`]). A summary ([`Summary`]) needs the header, the table and the
//! small `sessions` and `metadata` sections only.

use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;

use super::clouds::Clouds;
use super::database::{Columns, PoseStore};
use super::format::{is_bin_value, try_vec};
use super::{Database, DbError};
use crate::checksum::{crc32, Crc32};
use crate::Config;
use core::mem::MaybeUninit;
use runs::{runs, runs_of, sessions_of, Run};

pub(super) const VERSION: u32 = 4;
/// The previous version: poses as an id and a matrix only.
pub(super) const V3: u32 = 3;
const FIXED: usize = 96;
const ROW: usize = 32;
const MAX_SECTIONS: usize = 16;
/// Bytes per record of the `sessions` section.
const RUN: usize = 32;
/// Longest metadata text, in bytes.
pub const MAX_METADATA: usize = 1 << 20;
/// Bytes read or written at a time while streaming a section.
const CHUNK: usize = 1 << 20;

const SESSIONS: u32 = 1;
const R: u32 = 2;
const R_SCALE: u32 = 3;
const A_CODES: u32 = 4;
const A_STEP: u32 = 5;
const TIMES: u32 = 6;
const POSES: u32 = 7;
const CLOUD_OFFSETS: u32 = 8;
const CLOUDS: u32 = 9;
const METADATA: u32 = 10;
const POSE_IDS: u32 = 11;
const POSE_Q: u32 = 12;

fn name(kind: u32) -> &'static str {
    match kind {
        SESSIONS => "sessions",
        R => "r",
        R_SCALE => "r_scale",
        A_CODES => "a_codes",
        A_STEP => "a_step",
        TIMES => "times",
        POSES => "poses",
        CLOUD_OFFSETS => "cloud_offsets",
        CLOUDS => "clouds",
        POSE_IDS => "pose_ids",
        POSE_Q => "pose_q",
        _ => "metadata",
    }
}

fn bad(reason: String) -> DbError {
    DbError::Format { file: None, reason }
}

/// One row of the section table.
#[derive(Debug, Clone, Copy)]
struct Section {
    kind: u32,
    offset: u64,
    len: u64,
    items: u64,
}

/// What the header and the table of a file say.
struct Layout {
    /// Read by the summary (`std` only).
    #[cfg_attr(not(feature = "std"), allow(dead_code))]
    version: u32,
    config: Config,
    fingerprint: u64,
    count: usize,
    sections: Vec<Section>,
}

impl Layout {
    fn get(&self, kind: u32) -> Option<Section> {
        self.sections.iter().find(|s| s.kind == kind).copied()
    }
}

/// Where a file's bytes come from: memory, or (with `std`) a file read by offset; read from
/// several threads at once.
pub(super) trait Source: Sync {
    /// Length in bytes.
    fn size(&self) -> u64;
    /// Fills `buf` from offset `at` (within [`Source::size`], checked by the caller).
    fn read_at(&self, at: u64, buf: &mut [u8]) -> Result<(), DbError>;
    /// [`Source::read_at`] into memory not yet written; returns it, written.
    fn read_uninit<'a>(
        &self,
        at: u64,
        buf: &'a mut [MaybeUninit<u8>],
    ) -> Result<&'a mut [u8], DbError> {
        let buf = super::room::zeroed(buf);
        self.read_at(at, buf)?;
        Ok(buf)
    }
}

impl Source for [u8] {
    fn size(&self) -> u64 {
        self.len() as u64
    }
    fn read_at(&self, at: u64, buf: &mut [u8]) -> Result<(), DbError> {
        let at = at as usize;
        buf.copy_from_slice(&self[at..at + buf.len()]);
        Ok(())
    }
    fn read_uninit<'a>(
        &self,
        at: u64,
        buf: &'a mut [MaybeUninit<u8>],
    ) -> Result<&'a mut [u8], DbError> {
        let at = at as usize;
        Ok(super::room::copied(buf, &self[at..at + buf.len()]))
    }
}

/// An open database file.
#[cfg(feature = "std")]
pub(super) struct FileSource<'a> {
    pub(super) file: &'a std::fs::File,
    pub(super) size: u64,
    pub(super) name: &'a str,
}

#[cfg(feature = "std")]
impl Source for FileSource<'_> {
    fn size(&self) -> u64 {
        self.size
    }
    fn read_at(&self, at: u64, buf: &mut [u8]) -> Result<(), DbError> {
        super::clouds::read_file_at(self.file, buf, at).map_err(|source| self.failed(source))
    }
    fn read_uninit<'a>(
        &self,
        at: u64,
        buf: &'a mut [MaybeUninit<u8>],
    ) -> Result<&'a mut [u8], DbError> {
        super::clouds::read_file_uninit(self.file, buf, at).map_err(|source| self.failed(source))
    }
}

#[cfg(feature = "std")]
impl FileSource<'_> {
    fn failed(&self, source: std::io::Error) -> DbError {
        DbError::Io {
            file: String::from(self.name),
            source,
        }
    }
}

/// Reads and checks the header and the section table (see the module documentation).
fn layout(src: &(impl Source + ?Sized)) -> Result<Layout, DbError> {
    let size = src.size();
    let truncated = |need: u64| {
        bad(format!(
            "truncated: {size} bytes, shorter than the {need}-byte header"
        ))
    };
    if size < (FIXED + 4) as u64 {
        return Err(truncated((FIXED + 4) as u64));
    }
    let mut head = [0u8; FIXED];
    src.read_at(0, &mut head)?;
    let (config, fingerprint, count) = super::format::fixed_header(&head).map_err(bad)?;
    let version = u32::from_le_bytes([head[8], head[9], head[10], head[11]]);
    let last_kind = if version > V3 { POSE_Q } else { METADATA };
    let le32 = |at: usize| u32::from_le_bytes([head[at], head[at + 1], head[at + 2], head[at + 3]]);
    let (s, reserved) = (le32(88) as usize, le32(92));
    if reserved != 0 {
        return Err(bad(format!(
            "corrupted header: reserved field is {reserved:#x}, not 0"
        )));
    }
    if !(1..=MAX_SECTIONS).contains(&s) {
        return Err(bad(format!(
            "corrupted header: {s} sections (expected 1 to {MAX_SECTIONS})"
        )));
    }
    // The columns every place needs, to refuse an absurd count before reading further.
    let (nr, na) = (config.n_range as u64, config.n_azimuth as u64);
    let least = count
        .checked_mul(nr * 4 + na + 8)
        .filter(|&b| b <= usize::MAX as u64)
        .ok_or_else(|| {
            bad(format!(
                "corrupted header: entry count {count} is impossible"
            ))
        })?;
    if least > size {
        return Err(bad(format!(
            "truncated: the header announces {count} entries (at least {least} bytes) but there are only {size} bytes"
        )));
    }
    let table_end = FIXED + ROW * s;
    if size < (table_end + 4) as u64 {
        return Err(truncated((table_end + 4) as u64));
    }
    let mut whole = alloc::vec![0u8; table_end + 4];
    whole[..FIXED].copy_from_slice(&head);
    src.read_at(FIXED as u64, &mut whole[FIXED..])?;
    let stored = u32::from_le_bytes([
        whole[table_end],
        whole[table_end + 1],
        whole[table_end + 2],
        whole[table_end + 3],
    ]);
    let actual = crc32(&whole[..table_end]);
    if stored != actual {
        return Err(bad(format!(
            "header checksum mismatch (stored {stored:#010x}, computed {actual:#010x}): the file is corrupted"
        )));
    }
    super::format::check_config(&config, fingerprint, count).map_err(bad)?;
    let n = count;
    let mut sections: Vec<Section> = Vec::with_capacity(s);
    let mut at = (table_end + 4) as u64;
    for row in whole[FIXED..table_end].chunks_exact(ROW) {
        let u64_at = |k: usize| u64::from_le_bytes(row[k..k + 8].try_into().unwrap_or([0; 8]));
        let kind = u32::from_le_bytes([row[0], row[1], row[2], row[3]]);
        let zero = u32::from_le_bytes([row[4], row[5], row[6], row[7]]);
        let sec = Section {
            kind,
            offset: u64_at(8),
            len: u64_at(16),
            items: u64_at(24),
        };
        if !(SESSIONS..=last_kind).contains(&kind) || zero != 0 {
            return Err(bad(format!(
                "unknown section kind {kind} (flags {zero:#x})"
            )));
        }
        if sections.last().is_some_and(|p| p.kind >= kind) {
            return Err(bad(format!(
                "corrupted section table: section {} out of order",
                name(kind)
            )));
        }
        if sec.offset != at {
            return Err(bad(format!(
                "corrupted section table: section {} at byte {} instead of {at}",
                name(kind),
                sec.offset
            )));
        }
        let want = match kind {
            SESSIONS => (sec.items <= n).then(|| sec.items * RUN as u64),
            R => Some(n * nr * 4),
            R_SCALE | A_STEP => Some(n * 4),
            A_CODES => Some(n * na),
            TIMES => Some(n * 8),
            POSES => (sec.items <= n).then(|| sec.items * poses::POSE as u64),
            POSE_IDS => (sec.items <= n).then(|| sec.items * poses::ID as u64),
            POSE_Q => (sec.items <= n).then(|| sec.items * poses::POSE_Q as u64),
            CLOUD_OFFSETS if version > V3 => (sec.items <= n).then(|| sec.items * 4),
            CLOUD_OFFSETS => (sec.items <= n).then(|| (sec.items + 1) * 8),
            CLOUDS => (sec.items <= n).then_some(sec.len),
            _ => (sec.len <= MAX_METADATA as u64).then_some(sec.len),
        };
        if want != Some(sec.len)
            || ([R, R_SCALE, A_CODES, A_STEP, TIMES, METADATA].contains(&kind) && sec.items != 0)
        {
            return Err(bad(format!(
                "corrupted section table: section {} of {} bytes and {} items does not fit {n} entries",
                name(kind),
                sec.len,
                sec.items
            )));
        }
        at = sec
            .offset
            .checked_add(sec.len)
            .and_then(|v| v.checked_add(4))
            .ok_or_else(|| bad(String::from("corrupted section table: impossible length")))?;
        sections.push(sec);
    }
    match at.cmp(&size) {
        core::cmp::Ordering::Greater => {
            return Err(bad(format!(
                "truncated: the header announces {n} entries ({at} bytes) but there are only {size} bytes"
            )))
        }
        core::cmp::Ordering::Less => {
            return Err(bad(format!(
                "{} unexpected bytes after the end of the data ({at} bytes expected)",
                size - at
            )))
        }
        core::cmp::Ordering::Equal => {}
    }
    let l = Layout {
        version,
        config,
        fingerprint,
        count: n as usize,
        sections,
    };
    for kind in [SESSIONS, R, R_SCALE, A_CODES, A_STEP] {
        if l.get(kind).is_none() {
            return Err(bad(format!("the {} section is missing", name(kind))));
        }
    }
    poses::check_pose_sections(l.get(POSES), l.get(POSE_IDS), l.get(POSE_Q), n)?;
    if l.get(CLOUD_OFFSETS).is_some() != l.get(CLOUDS).is_some() {
        return Err(bad(String::from(
            "the cloud_offsets and clouds sections come together, or not at all",
        )));
    }
    Ok(l)
}

/// Reads section `sec` through `each` (a whole number of `unit`-byte records at a time), then
/// checks its CRC.
fn read_section(
    src: &(impl Source + ?Sized),
    sec: Section,
    unit: usize,
    mut each: impl FnMut(&[u8]) -> Result<(), DbError>,
) -> Result<(), DbError> {
    let step = (CHUNK / unit).max(1) * unit;
    let mut buf = try_vec::<u8>(step.min(sec.len as usize))?;
    let mut crc = Crc32::default();
    let mut done = 0u64;
    while done < sec.len {
        let take = step.min((sec.len - done) as usize);
        buf.resize(take, 0);
        src.read_at(sec.offset + done, &mut buf)?;
        crc.update(&buf);
        each(&buf)?;
        done += take as u64;
    }
    check_crc(src, sec, crc)
}

/// A value a column holds, stored little-endian.
trait Le: bytemuck::Pod {
    /// The value of the little-endian bytes `self` was read as (or the little-endian bytes of
    /// `self`: swapping is its own inverse).
    fn swap_le(self) -> Self;
}

macro_rules! le {
    ($($t:ty => $bits:ty),*) => {$(
        impl Le for $t {
            fn swap_le(self) -> Self {
                <$t>::from_bits(<$bits>::from_le(self.to_bits()))
            }
        }
    )*};
}
le!(f32 => u32, f64 => u64);

impl Le for u8 {
    fn swap_le(self) -> Self {
        self
    }
}

impl Le for u32 {
    fn swap_le(self) -> Self {
        u32::from_le(self)
    }
}

impl Le for u64 {
    fn swap_le(self) -> Self {
        u64::from_le(self)
    }
}

/// The column that section `sec` holds, read straight into its memory (huge pages for a large
/// one, see `room`; not zeroed first), a MiB at a time, each piece folded into its CRC while it
/// is in the cache; a large column on the pool's threads (the kernel's zeroing of the fresh
/// pages and the copy are most of a load), their CRCs combined in order.
#[allow(unsafe_code)]
fn column<T: Le>(src: &(impl Source + ?Sized), sec: Section) -> Result<Vec<T>, DbError> {
    let n = sec.len as usize / core::mem::size_of::<T>();
    let mut out: Vec<T> = Vec::new();
    super::room::reserve(&mut out, n).map_err(|_| DbError::OutOfMemory)?;
    let slots = super::room::spare(&mut out, n);
    let len = core::mem::size_of_val(slots);
    // SAFETY: the same memory seen as bytes (`MaybeUninit<u8>` has no alignment or validity
    // requirement), for as long as `slots` is borrowed.
    let bytes: &mut [MaybeUninit<u8>] =
        unsafe { core::slice::from_raw_parts_mut(slots.as_mut_ptr().cast(), len) };
    let read = |(k, piece): (usize, &mut [MaybeUninit<u8>])| {
        let mut crc = Crc32::default();
        crc.update(src.read_uninit(sec.offset + (k * CHUNK) as u64, piece)?);
        Ok::<Crc32, DbError>(crc)
    };
    let crc = pieces(bytes, read)?;
    // SAFETY: every byte of the `n` slots was read above (a failed read returned early), and
    // any bytes are a valid `T` (`Pod`).
    unsafe { super::room::commit(&mut out, n) };
    check_crc(src, sec, crc)?;
    if cfg!(target_endian = "big") {
        for v in &mut out {
            *v = v.swap_le();
        }
    }
    Ok(out)
}

/// The CRC of `bytes` filled a MiB at a time by `read`, which returns each piece's CRC: on the
/// pool's threads when there are many pieces.
fn pieces(
    bytes: &mut [MaybeUninit<u8>],
    read: impl Fn((usize, &mut [MaybeUninit<u8>])) -> Result<Crc32, DbError> + Sync,
) -> Result<Crc32, DbError> {
    let mut crc = Crc32::default();
    #[cfg(feature = "parallel")]
    if let Some(threads) = (bytes.len() >= 16 * CHUNK)
        .then(crate::pool::work)
        .flatten()
    {
        use rayon::prelude::*;
        let crcs: Vec<Crc32> = threads.install(|| {
            bytes
                .par_chunks_mut(CHUNK)
                .enumerate()
                .map(&read)
                .collect::<Result<_, _>>()
        })?;
        for c in &crcs {
            crc.combine(c);
        }
        return Ok(crc);
    }
    for piece in bytes.chunks_mut(CHUNK).enumerate() {
        crc.combine(&read(piece)?);
    }
    Ok(crc)
}

/// Compares the CRC of section `sec`'s bytes with the one stored after them.
fn check_crc(src: &(impl Source + ?Sized), sec: Section, crc: Crc32) -> Result<(), DbError> {
    let mut stored = [0u8; 4];
    src.read_at(sec.offset + sec.len, &mut stored)?;
    let (stored, actual) = (u32::from_le_bytes(stored), crc.finish());
    if stored != actual {
        return Err(bad(format!(
            "checksum mismatch in the {} section (stored {stored:#010x}, computed {actual:#010x}): the file is corrupted",
            name(sec.kind)
        )));
    }
    Ok(())
}

fn metadata_of(src: &(impl Source + ?Sized), l: &Layout) -> Result<String, DbError> {
    let Some(sec) = l.get(METADATA) else {
        return Ok(String::new());
    };
    let mut bytes = try_vec::<u8>(sec.len as usize)?;
    read_section(src, sec, 1, |b| {
        bytes.extend_from_slice(b);
        Ok(())
    })?;
    String::from_utf8(bytes).map_err(|_| bad(String::from("the metadata is not UTF-8 text")))
}

/// Reads a whole database in format version 3 or 4 from `src`; `file`, when given, is the open file
/// the clouds stay in (read on demand), else they are read into memory.
pub(super) fn decode(
    src: &(impl Source + ?Sized),
    #[cfg(feature = "std")] file: Option<(&std::fs::File, &str)>,
) -> Result<Database, DbError> {
    let l = layout(src)?;
    let n = l.count;
    let sec = |k| {
        l.get(k)
            .ok_or_else(|| bad(format!("the {} section is missing", name(k))))
    };
    let runs = runs_of(src, sec(SESSIONS)?)?;
    let r = column::<f32>(src, sec(R)?)?;
    let r_scale = column::<f32>(src, sec(R_SCALE)?)?;
    let a_codes = column::<u8>(src, sec(A_CODES)?)?;
    let a_scale = column::<f32>(src, sec(A_STEP)?)?;
    // At most the step of an A-SOLiD whose largest value is f32::MAX (what an add can give):
    // beyond it, the codes times the step overflow to infinity.
    if let Some(i) = a_scale
        .iter()
        .position(|s| !(is_bin_value(*s) && *s <= f32::MAX / 255.0))
    {
        return Err(bad(format!(
            "entry {i}: negative or non-finite value in its A-SOLiD (its step is {})",
            a_scale[i]
        )));
    }
    let timestamps = match l.get(TIMES) {
        Some(s) => column::<f64>(src, s)?,
        None => {
            let mut t = try_vec::<f64>(n)?;
            t.resize(n, f64::NAN);
            t
        }
    };
    if let Some(i) = timestamps.iter().position(|t| t.is_infinite()) {
        return Err(bad(format!("entry {i}: infinite timestamp")));
    }
    let poses = match (l.get(POSES), l.get(POSE_Q)) {
        (Some(s), _) => PoseStore::from_full(poses::with_ids(src, s, n)?),
        (None, Some(s)) => poses::quaternions(src, s, l.get(POSE_IDS), n)?,
        (None, None) => PoseStore::default(),
    };
    let sessions = sessions_of(&runs, n, &timestamps, poses.ids())?;
    let clouds = match (l.get(CLOUD_OFFSETS), l.get(CLOUDS)) {
        (Some(o), Some(c)) => {
            let offsets = if l.version > V3 {
                offsets_of(&column::<u32>(src, o)?)?
            } else {
                column::<u64>(src, o)?
            };
            let ok = offsets.first() == Some(&0)
                && offsets.windows(2).all(|w| w[0] <= w[1])
                && offsets.last() == Some(&c.len);
            let with = offsets.windows(2).filter(|w| w[1] > w[0]).count() as u64;
            if !ok || with != c.items {
                return Err(bad(String::from(
                    "corrupted cloud_offsets section: the offsets do not cover the clouds section",
                )));
            }
            #[cfg(feature = "std")]
            if let Some((f, name)) = file {
                let file = f.try_clone().map_err(|source| DbError::Io {
                    file: String::from(name),
                    source,
                })?;
                let clouds = super::clouds::FileClouds::new(file, String::from(name), c.offset)
                    .map_err(|source| DbError::Io {
                        file: String::from(name),
                        source,
                    })?;
                return finish(
                    l,
                    runs_free(sessions, timestamps, poses),
                    r,
                    r_scale,
                    a_codes,
                    a_scale,
                    Clouds::in_file(offsets, clouds),
                    src,
                );
            }
            let mut data = try_vec::<u8>(c.len as usize)?;
            read_section(src, c, 1, |b| {
                data.extend_from_slice(b);
                Ok(())
            })?;
            Clouds::in_memory(offsets, data)
        }
        _ => Clouds::default(),
    };
    finish(
        l,
        runs_free(sessions, timestamps, poses),
        r,
        r_scale,
        a_codes,
        a_scale,
        clouds,
        src,
    )
}

/// The offsets of the clouds from their lengths (version 4): their running sums from 0.
fn offsets_of(lengths: &[u32]) -> Result<Vec<u64>, DbError> {
    let mut offsets = try_vec::<u64>(lengths.len() + 1)?;
    let mut at = 0u64;
    offsets.push(at);
    for &len in lengths {
        at += u64::from(len);
        offsets.push(at);
    }
    Ok(offsets)
}

/// The per-place columns besides the descriptors.
struct Meta {
    sessions: Vec<u32>,
    timestamps: Vec<f64>,
    poses: PoseStore,
}

fn runs_free(sessions: Vec<u32>, timestamps: Vec<f64>, poses: PoseStore) -> Meta {
    Meta {
        sessions,
        timestamps,
        poses,
    }
}

#[allow(clippy::too_many_arguments)]
fn finish(
    l: Layout,
    m: Meta,
    r: Vec<f32>,
    r_scale: Vec<f32>,
    a_codes: Vec<u8>,
    a_scale: Vec<f32>,
    clouds: Clouds,
    src: &(impl Source + ?Sized),
) -> Result<Database, DbError> {
    let metadata = metadata_of(src, &l)?;
    let mut db = Database::new(l.config)?;
    let cols = Columns {
        sessions: m.sessions,
        timestamps: m.timestamps,
        poses: m.poses,
        r,
        r_scale,
        a_codes,
        a_scale,
        clouds,
        metadata,
    };
    if let Err((i, what)) = db.load_columns(cols)? {
        return Err(bad(format!("entry {i}: {what}")));
    }
    let _ = l.fingerprint;
    Ok(db)
}

/// The sections of `db` in format `version`, 3 or 4 (offsets from the end of the header).
fn sections(db: &Database, runs: &[Run], version: u32) -> Vec<Section> {
    let (n, c) = (db.len() as u64, db.config());
    let (nr, na) = (c.n_range as u64, c.n_azimuth as u64);
    let poses = db.poses_stored() as u64;
    let offsets = db.clouds.offsets().len() as u64;
    let mut out = Vec::new();
    let mut add = |kind, len, items| {
        out.push(Section {
            kind,
            offset: 0,
            len,
            items,
        })
    };
    add(SESSIONS, runs.len() as u64 * RUN as u64, runs.len() as u64);
    add(R, n * nr * 4, 0);
    add(R_SCALE, n * 4, 0);
    add(A_CODES, n * na, 0);
    add(A_STEP, n * 4, 0);
    if db.timestamps().iter().any(|t| !t.is_nan()) {
        add(TIMES, n * 8, 0);
    }
    let lean_poses = poses > 0 && version > V3 && poses::all_lean(db);
    if poses > 0 && !lean_poses {
        add(POSES, poses * poses::POSE as u64, poses);
    }
    if db.clouds.any() {
        let len = if version > V3 {
            (offsets - 1) * 4
        } else {
            offsets * 8
        };
        add(CLOUD_OFFSETS, len, offsets - 1);
        add(
            CLOUDS,
            db.clouds.data_len() as u64,
            db.clouds.count() as u64,
        );
    }
    if !db.metadata().is_empty() {
        add(METADATA, db.metadata().len() as u64, 0);
    }
    if lean_poses && poses < n {
        add(POSE_IDS, poses * poses::ID as u64, poses);
    }
    if lean_poses {
        add(POSE_Q, poses * poses::POSE_Q as u64, poses);
    }
    let mut at = (FIXED + ROW * out.len() + 4) as u64;
    for s in &mut out {
        s.offset = at;
        at += s.len + 4;
    }
    out
}

/// Length of `db` in format `version`, 3 or 4.
pub(super) fn encoded_len(db: &Database, version: u32) -> usize {
    let secs = sections(db, &runs(db), version);
    secs.last()
        .map_or(FIXED + 4, |s| (s.offset + s.len + 4) as usize)
}

/// Writes `db` in format `version` (3 or 4) through `put`, in order, in pieces of at most about
/// a MiB.
pub(super) fn encode(
    db: &Database,
    version: u32,
    put: &mut dyn FnMut(&[u8]) -> Result<(), DbError>,
) -> Result<(), DbError> {
    let runs = runs(db);
    let secs = sections(db, &runs, version);
    let mut head = try_vec::<u8>(FIXED + ROW * secs.len() + 4)?;
    super::format::header_start(db, version, &mut |b| head.extend_from_slice(b));
    head.extend_from_slice(&(secs.len() as u32).to_le_bytes());
    head.extend_from_slice(&0u32.to_le_bytes());
    for s in &secs {
        head.extend_from_slice(&s.kind.to_le_bytes());
        head.extend_from_slice(&0u32.to_le_bytes());
        for v in [s.offset, s.len, s.items] {
            head.extend_from_slice(&v.to_le_bytes());
        }
    }
    let crc = crc32(&head);
    head.extend_from_slice(&crc.to_le_bytes());
    put(&head)?;
    drop(head);
    for s in &secs {
        let mut w = SectionWriter::new(put)?;
        match s.kind {
            SESSIONS => {
                for r in &runs {
                    let mut b = [0u8; RUN];
                    b[0..4].copy_from_slice(&r.session.to_le_bytes());
                    b[4..8].copy_from_slice(&r.places.to_le_bytes());
                    b[8..12].copy_from_slice(&r.with_pose.to_le_bytes());
                    b[16..24].copy_from_slice(&r.first.to_le_bytes());
                    b[24..32].copy_from_slice(&r.last.to_le_bytes());
                    w.put(&b)?;
                }
            }
            R => w.values(db.r_all())?,
            R_SCALE => w.values(db.r_scales())?,
            A_CODES => w.put(db.a_codes())?,
            A_STEP => w.values(db.a_steps())?,
            TIMES => w.values(db.timestamps())?,
            POSES => {
                for id in 0..db.len() as u32 {
                    if let Some(p) = db.pose(id) {
                        w.put(&id.to_le_bytes())?;
                        w.values(&p)?;
                    }
                }
            }
            POSE_IDS => {
                for id in (0..db.len() as u32).filter(|&id| db.pose(id).is_some()) {
                    w.put(&id.to_le_bytes())?;
                }
            }
            POSE_Q => {
                for p in (0..db.len() as u32).filter_map(|id| db.pose(id)) {
                    w.values(&poses::lean_record(&p))?;
                }
            }
            CLOUD_OFFSETS if version > V3 => {
                for (i, o) in db.clouds.offsets().windows(2).enumerate() {
                    let len = u32::try_from(o[1] - o[0]).map_err(|_| {
                        bad(format!(
                            "place {i}: its cloud of {} bytes is larger than format 4 stores (4 GiB)",
                            o[1] - o[0]
                        ))
                    })?;
                    w.values(&[len])?;
                }
            }
            CLOUD_OFFSETS => w.values(db.clouds.offsets())?,
            CLOUDS => db.clouds.each(|b| w.put(b))?,
            _ => w.put(db.metadata().as_bytes())?,
        }
        w.finish()?;
    }
    Ok(())
}

/// Writes one section's bytes in pieces, then its CRC.
struct SectionWriter<'a> {
    put: &'a mut dyn FnMut(&[u8]) -> Result<(), DbError>,
    buf: Vec<u8>,
    crc: Crc32,
}

impl<'a> SectionWriter<'a> {
    fn new(put: &'a mut dyn FnMut(&[u8]) -> Result<(), DbError>) -> Result<Self, DbError> {
        Ok(SectionWriter {
            put,
            buf: try_vec::<u8>(CHUNK)?,
            crc: Crc32::default(),
        })
    }
    fn flush(&mut self) -> Result<(), DbError> {
        if !self.buf.is_empty() {
            self.crc.update(&self.buf);
            (self.put)(&self.buf)?;
            self.buf.clear();
        }
        Ok(())
    }
    fn put(&mut self, b: &[u8]) -> Result<(), DbError> {
        if self.buf.len() + b.len() > CHUNK {
            self.flush()?;
        }
        if b.len() >= CHUNK {
            self.crc.update(b);
            return (self.put)(b);
        }
        self.buf.extend_from_slice(b);
        Ok(())
    }
    /// Writes `v` little-endian (as it is in memory on a little-endian machine).
    fn values<T: Le>(&mut self, v: &[T]) -> Result<(), DbError> {
        if cfg!(target_endian = "little") {
            for piece in v.chunks(CHUNK / core::mem::size_of::<T>().max(1)) {
                self.put(bytemuck::cast_slice(piece))?;
            }
            return Ok(());
        }
        for &x in v {
            // Swapping the bytes is its own inverse.
            self.put(bytemuck::bytes_of(&x.swap_le()))?;
        }
        Ok(())
    }
    fn finish(mut self) -> Result<(), DbError> {
        self.flush()?;
        let crc = self.crc.finish();
        (self.put)(&crc.to_le_bytes())
    }
}

mod poses;
pub(super) use poses::{check_rotation, matrix as pose_matrix};
mod runs;
mod summary;

#[cfg(feature = "std")]
pub(super) use summary::{summary, summary_of};
pub use summary::{SessionSummary, Summary};
