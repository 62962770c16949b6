//! The database file format: checksummed, little-endian, written atomically.
//!
//! # Version 1
//! All numbers little-endian.
//! ```text
//! offset  size        field
//! 0       8           magic  "SOLiDdb\0"
//! 8       4   u32     format version (1)
//! 12      4   u32     flags (0)
//! 16      4×u32       n_range, n_azimuth, n_elevation, 0
//! 32      5×f64       fov_up, fov_down, min_range, max_range, voxel_size
//! 72      8   u64     config fingerprint (Config::fingerprint)
//! 80      8   u64     entry count n
//! 88      n×112       per entry: u32 session, u32 flags (bit 0: has pose), f64 timestamp
//!                     (NaN = none), 12×f64 pose (row-major 3×4 [R|t], zeros when absent)
//! ...     n×Nr×f32    R-SOLiD vectors, entry after entry
//! ...     n×Na×f32    A-SOLiD vectors
//! end-4   4   u32     CRC-32 (IEEE) of every byte before it
//! ```

use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;

use super::{Database, DbError};
use crate::Config;

impl Database {
    /// Serialises the database in the file format above.
    pub fn to_bytes(&self) -> Vec<u8> {
        let n = self.len();
        let c = &self.config;
        let (nr, na) = (c.n_range, c.n_azimuth);
        let mut out = Vec::with_capacity(HEADER_LEN + n * ENTRY_LEN + n * (nr + na) * 4 + 4);
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
        for v in [c.n_range, c.n_azimuth, c.n_elevation, 0] {
            out.extend_from_slice(&(v as u32).to_le_bytes());
        }
        for v in [c.fov_up, c.fov_down, c.min_range, c.max_range, c.voxel_size] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.fingerprint.to_le_bytes());
        out.extend_from_slice(&(n as u64).to_le_bytes());
        for i in 0..n {
            out.extend_from_slice(&self.sessions[i].to_le_bytes());
            let (flags, pose) = match self.pose(i as u32) {
                Some(p) => (1u32, p),
                None => (0u32, [0.0; 12]),
            };
            out.extend_from_slice(&flags.to_le_bytes());
            out.extend_from_slice(&self.timestamps[i].to_le_bytes());
            for v in pose {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        for v in self.r_all().iter().chain(&self.a_all()) {
            out.extend_from_slice(&v.to_le_bytes());
        }
        let crc = crc32(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    /// Reads a database written by [`Database::to_bytes`], checking everything: the magic, the
    /// version, the length, the checksum, the config and every value.
    ///
    /// # Errors
    /// [`DbError::Format`] (with `file: None`) naming what is wrong: not a SOLiD database,
    /// a newer format version, truncated, trailing bytes, checksum mismatch, invalid config,
    /// non-finite values.
    pub fn from_bytes(bytes: &[u8]) -> Result<Database, DbError> {
        let bad = |reason: String| DbError::Format { file: None, reason };
        if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
            return Err(bad(String::from(
                "not a SOLiD database (wrong magic number at the start of the file)",
            )));
        }
        if bytes.len() < HEADER_LEN + 4 {
            return Err(bad(format!(
                "truncated: {} bytes, shorter than the {}-byte header",
                bytes.len(),
                HEADER_LEN + 4
            )));
        }
        let mut rd = Reader { b: bytes, at: 8 };
        let version = rd.u32();
        if version > FORMAT_VERSION {
            return Err(bad(format!(
                "format version {version} is newer than this library reads (up to {FORMAT_VERSION}); \
                 upgrade solid"
            )));
        }
        if version == 0 {
            return Err(bad(String::from("invalid format version 0")));
        }
        let flags = rd.u32();
        if flags != 0 {
            return Err(bad(format!("unknown header flags {flags:#x}")));
        }
        let (n_range, n_azimuth, n_elevation, _pad) = (rd.u32(), rd.u32(), rd.u32(), rd.u32());
        let config = Config {
            n_range: n_range as usize,
            n_azimuth: n_azimuth as usize,
            n_elevation: n_elevation as usize,
            fov_up: rd.f64(),
            fov_down: rd.f64(),
            min_range: rd.f64(),
            max_range: rd.f64(),
            voxel_size: rd.f64(),
        };
        let fingerprint = rd.u64();
        let count = rd.u64();
        // Length check before the checksum, so that a truncated file says "truncated".
        let per_entry = (n_range as u64 + n_azimuth as u64) * 4 + ENTRY_LEN as u64;
        let expected = count
            .checked_mul(per_entry)
            .and_then(|v| v.checked_add((HEADER_LEN + 4) as u64));
        let expected = match expected {
            Some(e) if e <= usize::MAX as u64 => e as usize,
            _ => {
                return Err(bad(format!(
                    "corrupted header: entry count {count} is impossible"
                )))
            }
        };
        if bytes.len() < expected {
            return Err(bad(format!(
                "truncated: the header announces {count} entries ({expected} bytes) but there are only {} bytes",
                bytes.len()
            )));
        }
        if bytes.len() > expected {
            return Err(bad(format!(
                "{} unexpected bytes after the end of the data ({expected} bytes expected)",
                bytes.len() - expected
            )));
        }
        let body = &bytes[..expected - 4];
        let stored = u32::from_le_bytes([
            bytes[expected - 4],
            bytes[expected - 3],
            bytes[expected - 2],
            bytes[expected - 1],
        ]);
        let actual = crc32(body);
        if stored != actual {
            return Err(bad(format!(
                "checksum mismatch (stored {stored:#010x}, computed {actual:#010x}): the file is corrupted"
            )));
        }
        if let Err(e) = config.validate() {
            return Err(bad(format!("invalid config in header: {e}")));
        }
        if config.fingerprint() != fingerprint {
            return Err(bad(format!(
                "config fingerprint {fingerprint:#018x} does not match the stored config ({:#018x})",
                config.fingerprint()
            )));
        }
        if count >= u32::MAX as u64 {
            return Err(bad(format!("too many entries ({count})")));
        }
        let n = count as usize;
        let mut db = Database::new(config)?;
        let (mut sessions, mut timestamps, mut poses) = (Vec::new(), Vec::new(), Vec::new());
        sessions.reserve_exact(n);
        timestamps.reserve_exact(n);
        for i in 0..n {
            sessions.push(rd.u32());
            let eflags = rd.u32();
            timestamps.push(rd.f64());
            let mut pose = [0.0; 12];
            for v in &mut pose {
                *v = rd.f64();
            }
            match eflags {
                0 => {}
                1 => {
                    if pose.iter().any(|v| !v.is_finite()) {
                        return Err(bad(format!("entry {i}: non-finite pose")));
                    }
                    poses.push((i as u32, pose));
                }
                _ => return Err(bad(format!("entry {i}: unknown flags {eflags:#x}"))),
            }
        }
        let (nr, na) = (config.n_range, config.n_azimuth);
        let r: Vec<f32> = (0..n * nr).map(|_| rd.f32()).collect();
        let a: Vec<f32> = (0..n * na).map(|_| rd.f32()).collect();
        if let Some(p) = r.iter().chain(&a).position(|v| !v.is_finite()) {
            let (which, entry) = if p < n * nr {
                ("R-SOLiD", p / nr)
            } else {
                ("A-SOLiD", (p - n * nr) / na)
            };
            return Err(bad(format!(
                "entry {entry}: non-finite value in its {which}"
            )));
        }
        db.load_entries(&r, &a, sessions, timestamps, poses)?;
        Ok(db)
    }

    /// Writes the database to `path` atomically: into a temporary file in the same directory,
    /// flushed to disk, then renamed over `path`.
    ///
    /// # Errors
    /// [`DbError::Io`] naming the file when writing or renaming fails (the temporary file is
    /// removed).
    #[cfg(feature = "std")]
    pub fn save<P: AsRef<std::path::Path>>(&self, path: P) -> Result<(), DbError> {
        use std::io::Write;
        let path = path.as_ref();
        let io = |source| DbError::Io {
            file: path.display().to_string(),
            source,
        };
        let name = path
            .file_name()
            .ok_or_else(|| io(std::io::Error::other("the path names no file")))?;
        let mut tmp_name = std::ffi::OsString::from(".");
        tmp_name.push(name);
        tmp_name.push(format!(".{}.tmp", std::process::id()));
        let tmp = path.with_file_name(tmp_name);
        let bytes = self.to_bytes();
        let write = || -> std::io::Result<()> {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(&bytes)?;
            f.sync_all()?;
            drop(f);
            std::fs::rename(&tmp, path)
        };
        if let Err(e) = write() {
            let _ = std::fs::remove_file(&tmp);
            return Err(io(e));
        }
        // Make the rename durable where the platform allows it (best effort).
        if let Some(dir) = path.parent() {
            let dir = if dir.as_os_str().is_empty() {
                std::path::Path::new(".")
            } else {
                dir
            };
            if let Ok(d) = std::fs::File::open(dir) {
                let _ = d.sync_all();
            }
        }
        Ok(())
    }

    /// Reads a database saved by [`Database::save`].
    ///
    /// # Errors
    /// [`DbError::Io`] naming the file when it cannot be read (for example, it does not exist);
    /// [`DbError::Format`] naming the file and the reason when its content is not a valid
    /// database (see [`Database::from_bytes`]).
    #[cfg(feature = "std")]
    pub fn load<P: AsRef<std::path::Path>>(path: P) -> Result<Database, DbError> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let bytes = match std::fs::read(path) {
            Ok(b) => b,
            Err(source) => return Err(DbError::Io { file, source }),
        };
        Database::from_bytes(&bytes).map_err(|e| match e {
            DbError::Format { reason, .. } => DbError::Format {
                file: Some(file),
                reason,
            },
            other => other,
        })
    }
}

const MAGIC: [u8; 8] = *b"SOLiDdb\0";
const FORMAT_VERSION: u32 = 1;
const HEADER_LEN: usize = 88;
const ENTRY_LEN: usize = 4 + 4 + 8 + 96;

/// A little-endian reader over bytes whose length was checked beforehand.
pub(super) struct Reader<'a> {
    pub(super) b: &'a [u8],
    pub(super) at: usize,
}

impl Reader<'_> {
    pub(super) fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut v = [0u8; N];
        v.copy_from_slice(&self.b[self.at..self.at + N]);
        self.at += N;
        v
    }
    pub(super) fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    pub(super) fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
    pub(super) fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take())
    }
    pub(super) fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
}

const CRC_TABLE: [u32; 256] = {
    let mut t = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
            k += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
};

/// CRC-32 (IEEE 802.3, the one of zlib and PNG) of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c = CRC_TABLE[((c ^ b as u32) & 0xff) as usize] ^ (c >> 8);
    }
    !c
}
