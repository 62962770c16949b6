//! The database file format: checksummed, little-endian, written atomically.
//!
//! Version 4 is written (docs/spec.md §13: the columns as the database holds them, sections found
//! through a table, clouds read on demand); versions 3, 2 and 1 are still read, and versions 3
//! and 2 are written on request ([`Database::to_bytes_version`]).
//!
//! # Version 2, version 1
//! All numbers little-endian. Version 1 is version 2 without the field at offset 88 and without
//! the cloud section (its entries start at offset 88).
//! ```text
//! offset  size        field
//! 0       8           magic  "SOLiDdb\0"
//! 8       4   u32     format version (2)
//! 12      4   u32     flags (0)
//! 16      4×u32       n_range, n_azimuth, n_elevation, 0
//! 32      5×f64       fov_up, fov_down, min_range, max_range, voxel_size
//! 72      8   u64     config fingerprint (Config::fingerprint)
//! 80      8   u64     entry count n
//! 88      8   u64     cloud section length C in bytes (0: no entry has a cloud)
//! 96      n×112       per entry: u32 session, u32 flags (bit 0: has pose), f64 timestamp
//!                     (NaN = none), 12×f64 pose (row-major 3×4 [R|t], zeros when absent)
//! ...     n×Nr×f32    R-SOLiD vectors, entry after entry
//! ...     n×Na×f32    A-SOLiD vectors
//! ...     C           when C > 0: n×u32 cloud lengths (0: none), then the clouds back to back,
//!                     each in the wire form of `reg::encode_cloud` (its own CRC)
//! end-4   4   u32     CRC-32 (IEEE) of every byte before it
//! ```
//! The header alone gives the file's length (checked before anything else is read).

use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;

use super::clouds::Clouds;
use super::lean;
use super::{Database, DbError};
use crate::Config;

pub use super::lean::{SessionSummary, Summary, MAX_METADATA};
pub use crate::checksum::crc32;

impl Database {
    /// Serialises the database in the current format, version 4 (allocates
    /// [`Database::encoded_len`] bytes; [`Database::encode_into`] writes into a buffer of the
    /// caller's).
    ///
    /// # Errors
    /// As [`Database::to_bytes_version`].
    pub fn to_bytes(&self) -> Result<Vec<u8>, DbError> {
        self.to_bytes_version(lean::VERSION)
    }

    /// Serialises the database in format `version`: 4 (the current one), 3 (poses as
    /// matrices, what solid before format 4 reads) or 2 (what solid before format 3 reads; it
    /// holds no [`Database::metadata`]).
    ///
    /// # Errors
    /// [`DbError::Core`] with [`crate::Error::InvalidParameter`] for another version;
    /// [`DbError::Format`] naming the place when a stored cloud is corrupt (it is never copied
    /// under a fresh checksum); [`DbError::Io`] when a cloud cannot be read from the file the
    /// database was loaded from; [`DbError::OutOfMemory`].
    pub fn to_bytes_version(&self, version: u32) -> Result<Vec<u8>, DbError> {
        let len = match version {
            2 => self.encoded_len_v2(),
            lean::V3 | lean::VERSION => lean::encoded_len(self, version),
            _ => return Err(bad_version(version)),
        };
        let mut out = try_vec::<u8>(len)?;
        if version == 2 {
            out.resize(len, 0);
            self.encode_v2_into(&mut out)?;
        } else {
            lean::encode(self, version, &mut |b| {
                out.extend_from_slice(b);
                Ok(())
            })?;
        }
        debug_assert_eq!(out.len(), len);
        Ok(out)
    }

    /// Length of the database in the current file format, in bytes.
    pub fn encoded_len(&self) -> usize {
        lean::encoded_len(self, lean::VERSION)
    }

    /// Writes the database in the current file format into `out`; returns the bytes written
    /// ([`Database::encoded_len`]).
    ///
    /// # Errors
    /// [`DbError::Core`] with [`crate::Error::BufferTooSmall`] when `out` is shorter than
    /// [`Database::encoded_len`]; otherwise as [`Database::to_bytes_version`].
    pub fn encode_into(&self, out: &mut [u8]) -> Result<usize, DbError> {
        let len = self.encoded_len();
        if out.len() < len {
            return Err(crate::Error::BufferTooSmall {
                buffer: "out",
                needed: len,
                got: out.len(),
            }
            .into());
        }
        let mut at = 0;
        lean::encode(self, lean::VERSION, &mut |b| {
            out[at..at + b.len()].copy_from_slice(b);
            at += b.len();
            Ok(())
        })?;
        Ok(at)
    }

    /// Length of the database in format version 2, in bytes.
    fn encoded_len_v2(&self) -> usize {
        let c = &self.config;
        HEADER_LEN
            + self.len() * (ENTRY_LEN + (c.n_range + c.n_azimuth) * 4)
            + self.cloud_section_len()
            + 4
    }

    /// Length of the cloud section (0 when no entry has a cloud).
    fn cloud_section_len(&self) -> usize {
        if self.clouds.any() {
            4 * self.len() + self.clouds.data_len()
        } else {
            0
        }
    }

    /// Writes the database in format version 2 into `out`, of [`Database::encoded_len_v2`] bytes.
    fn encode_v2_into(&self, out: &mut [u8]) -> Result<usize, DbError> {
        let mut w = Writer { b: out, at: 0 };
        let n = self.len();
        header_start(self, 2, &mut |b| w.put(b));
        let cloud_section = self.cloud_section_len();
        w.put(&(cloud_section as u64).to_le_bytes());
        for i in 0..n {
            w.put(&self.sessions()[i].to_le_bytes());
            let (flags, pose) = match self.pose(i as u32) {
                Some(p) => (1u32, p),
                None => (0u32, [0.0; 12]),
            };
            w.put(&flags.to_le_bytes());
            w.put(&self.timestamps()[i].to_le_bytes());
            for v in pose {
                w.put(&v.to_le_bytes());
            }
        }
        for v in self.r_all() {
            w.put(&v.to_le_bytes());
        }
        // The A-SOLiDs as stored (Database::a), entry after entry.
        for i in 0..n {
            for v in self.a_values(i as u32) {
                w.put(&v.to_le_bytes());
            }
        }
        if cloud_section > 0 {
            for l in self.clouds.lengths(n) {
                w.put(&l.to_le_bytes());
            }
            self.clouds.each(|b| {
                w.put(b);
                Ok(())
            })?;
        }
        let crc = crc32(&w.b[..w.at]);
        w.put(&crc.to_le_bytes());
        Ok(w.at)
    }

    /// Reads a database written by [`Database::to_bytes`] (any format version), checking
    /// everything: the magic, the version, the reserved header fields, the length, the checksums
    /// (of the file in versions 1 and 2, of the header and of each section in versions 3 and 4),
    /// the config and every value. The stored clouds are checked when they are read
    /// ([`Database::try_cloud`]), in versions 3 and 4 by their own checksums only: a corrupt one
    /// is an error for its place, not for the file. (Versions 1 and 2 decode every cloud here.)
    ///
    /// # Errors
    /// [`DbError::Format`] (with `file: None`) naming what is wrong: not a SOLiD database,
    /// a newer format version, truncated, trailing bytes, checksum mismatch, invalid config,
    /// negative or non-finite vector values, infinite timestamps, non-finite poses, a stored
    /// cloud that [`crate::reg::decode_cloud`] refuses (its own checksum);
    /// [`DbError::OutOfMemory`] when the entries do not fit in
    /// memory.
    pub fn from_bytes(bytes: &[u8]) -> Result<Database, DbError> {
        let bad = |reason: String| DbError::Format { file: None, reason };
        if version_of(bytes).map_err(bad)? >= lean::V3 {
            return lean::decode(
                bytes,
                #[cfg(feature = "std")]
                None,
            );
        }
        let header = Header::parse(bytes).map_err(bad)?;
        header.check_len(bytes.len()).map_err(bad)?;
        let expected = bytes.len();
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
        let (config, fingerprint, count) = (header.config, header.fingerprint, header.count);
        check_config(&config, fingerprint, count).map_err(bad)?;
        let n = count as usize;
        let (nr, na) = (config.n_range, config.n_azimuth);
        let mut rd = Reader {
            b: bytes,
            at: header.header_len,
        };
        let mut db = Database::new(config)?;
        let mut sessions = try_vec::<u32>(n)?;
        let mut timestamps = try_vec::<f64>(n)?;
        let mut poses = Vec::new();
        for i in 0..n {
            let session = rd.u32();
            if super::check_session(session).is_err() {
                return Err(bad(format!(
                    "entry {i}: session 2^32 - 1 (never a session)"
                )));
            }
            sessions.push(session);
            let eflags = rd.u32();
            let t = rd.f64();
            if t.is_infinite() {
                return Err(bad(format!("entry {i}: infinite timestamp")));
            }
            timestamps.push(t);
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
                    lean::check_rotation(i as u32, &pose)?;
                    poses.try_reserve(1).map_err(|_| DbError::OutOfMemory)?;
                    poses.push((i as u32, pose));
                }
                _ => return Err(bad(format!("entry {i}: unknown flags {eflags:#x}"))),
            }
        }
        let mut r = try_vec::<f32>(n * nr)?;
        let mut a = try_vec::<f32>(n * na)?;
        r.extend((0..n * nr).map(|_| rd.f32()));
        a.extend((0..n * na).map(|_| rd.f32()));
        // Descriptors are finite and non-negative (SPEC §3): anything else was not written by
        // `to_bytes`, whatever its checksum says.
        if let Some(p) = r.iter().chain(&a).position(|v| !is_bin_value(*v)) {
            let (which, entry) = if p < n * nr {
                ("R-SOLiD", p / nr)
            } else {
                ("A-SOLiD", (p - n * nr) / na)
            };
            return Err(bad(format!(
                "entry {entry}: negative or non-finite value in its {which}"
            )));
        }
        let cloud_section = header.cloud_section;
        let mut clouds = Clouds::default();
        if cloud_section > 0 {
            let lengths_len = 4 * n as u64;
            if cloud_section < lengths_len {
                return Err(bad(format!(
                    "corrupted header: a cloud section of {cloud_section} bytes cannot hold {n} lengths"
                )));
            }
            let mut lengths = try_vec::<u32>(n)?;
            lengths.extend((0..n).map(|_| rd.u32()));
            let data = &bytes[rd.at..rd.at + (cloud_section - lengths_len) as usize];
            clouds = Clouds::from_parts(&lengths, data)?;
            // Each cloud is decoded once here: a corrupt one is refused with the file, never
            // merged and re-signed, nor found out only when a step verifies against it.
            for id in 0..n {
                let decoded = clouds.get(id).map_err(|e| format!("{e}")).and_then(|c| {
                    c.map_or(Ok(()), |c| {
                        crate::reg::decode_cloud(c)
                            .map(|_| ())
                            .map_err(|e| format!("{e}"))
                    })
                });
                if let Err(e) = decoded {
                    return Err(bad(format!(
                        "the stored cloud of place {id} is invalid: {e}"
                    )));
                }
            }
        }
        db.load_entries(&r, &a, sessions, timestamps, poses, clouds)?;
        Ok(db)
    }

    /// Writes the database to `path` atomically: into a temporary file of its own in the same
    /// directory, flushed to disk, then renamed over `path`.
    ///
    /// Every call writes its own temporary file (`.<name>.<pid>-<n>.tmp`, created exclusively),
    /// so concurrent saves to one path never mix: each succeeds and the file ends up whole, as
    /// one of them wrote it. A temporary file left by a killed process is never reused.
    ///
    /// # Errors
    /// [`DbError::Io`] naming the file when writing or renaming fails (the temporary file is
    /// removed); [`DbError::OutOfMemory`] when the encoded file does not fit in memory.
    #[cfg(feature = "std")]
    pub fn save<P: AsRef<std::path::Path>>(&self, path: P) -> Result<(), DbError> {
        self.save_version(path, lean::VERSION)
    }

    /// [`Database::save`] in format `version` (see [`Database::to_bytes_version`]). Version 3 is
    /// written as it is encoded, with no buffer of the whole file.
    ///
    /// # Errors
    /// As [`Database::save`] and [`Database::to_bytes_version`] (nothing is written then).
    #[cfg(feature = "std")]
    pub fn save_version<P: AsRef<std::path::Path>>(
        &self,
        path: P,
        version: u32,
    ) -> Result<(), DbError> {
        self.write_file(path.as_ref(), version, true)
    }

    /// [`Database::save_version`] to a path that must not exist: the file appears whole there, or
    /// the call fails with [`DbError::Io`] of kind `AlreadyExists` and nothing changes, also when
    /// another process or thread creates the path meanwhile (the temporary file is linked to
    /// `path`, which never replaces anything, then removed). Of several calls racing for one
    /// path exactly one succeeds. On a file system without hard links the existence check and
    /// the rename are two steps (a writer racing in between may be replaced).
    ///
    /// # Errors
    /// As [`Database::save_version`], and the above.
    #[cfg(feature = "std")]
    pub fn save_new<P: AsRef<std::path::Path>>(
        &self,
        path: P,
        version: u32,
    ) -> Result<(), DbError> {
        self.write_file(path.as_ref(), version, false)
    }

    /// Writes the file of [`Database::save_version`] (`replace`) or [`Database::save_new`].
    #[cfg(feature = "std")]
    fn write_file(
        &self,
        path: &std::path::Path,
        version: u32,
        replace: bool,
    ) -> Result<(), DbError> {
        use std::io::Write;
        let io = |source| DbError::Io {
            file: path.display().to_string(),
            source,
        };
        let name = path
            .file_name()
            .ok_or_else(|| io(std::io::Error::other("the path names no file")))?;
        let bytes = match version {
            2 => Some(self.to_bytes_version(2)?),
            lean::V3 | lean::VERSION => None,
            _ => return Err(bad_version(version)),
        };
        writable(path, replace).map_err(io)?;
        let (f, tmp) = create_temp(path, name).map_err(io)?;
        let mut out = std::io::BufWriter::with_capacity(1 << 20, f);
        let written = match &bytes {
            Some(b) => out.write_all(b).map_err(io),
            None => lean::encode(self, version, &mut |b| out.write_all(b).map_err(io)),
        };
        let write = || -> std::io::Result<()> {
            let f = out
                .into_inner()
                .map_err(std::io::IntoInnerError::into_error)?;
            f.sync_all()?;
            drop(f);
            put_in_place(&tmp, path, replace)
        };
        if let Err(e) = written.and_then(|()| write().map_err(io)) {
            let _ = std::fs::remove_file(&tmp);
            return Err(e);
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

    /// Reads a database saved by [`Database::save`] (any format version).
    ///
    /// Only regular files are read (a FIFO, a device or a directory is refused before it is
    /// opened), and the header is checked against the file's size before the body is read: a
    /// foreign, truncated or padded file is refused after reading at most its header (and, in
    /// versions 3 and 4, its section table). In those each section is read once, straight into the
    /// column it becomes, and the clouds stay in the file: the database keeps it open and reads a
    /// place's cloud when it is asked for ([`Database::try_cloud`]). Its search index is left to
    /// the searches, as after a bulk add ([`super::IndexPolicy::BySearches`]; a
    /// [`super::LoopDetector`] builds it at its start): a map opened to be summed up, merged or
    /// saved never builds it, and the searches before it are exact.
    ///
    /// # Errors
    /// [`DbError::Io`] naming the file when it cannot be read (for example, it does not exist,
    /// or it is a directory); [`DbError::Format`] naming the file and the reason when it is not a
    /// regular file or its content is not a valid database (see [`Database::from_bytes`]);
    /// [`DbError::OutOfMemory`] when it does not fit in memory.
    #[cfg(feature = "std")]
    pub fn load<P: AsRef<std::path::Path>>(path: P) -> Result<Database, DbError> {
        open_named(
            path.as_ref(),
            |src| lean::decode(src, Some((src.file, src.name))),
            |f, size, _, file| {
                let bytes = read_checked(f, size).map_err(|e| e.named(file))?;
                Database::from_bytes(&bytes)
            },
        )
    }

    /// What the database file at `path` holds (places, sessions, clouds, metadata), read from its
    /// header, section table and small sections alone in format versions 3 and 4 (neither
    /// descriptors nor clouds), from the whole file in versions 1 and 2.
    ///
    /// # Errors
    /// As [`Database::load`].
    #[cfg(feature = "std")]
    pub fn summary<P: AsRef<std::path::Path>>(path: P) -> Result<Summary, DbError> {
        let path = path.as_ref();
        open_named(
            path,
            |src| lean::summary(src),
            |f, _, version, _| {
                drop(f);
                Ok(lean::summary_of(&Database::load(path)?, version))
            },
        )
    }
}

/// Opens the database file at `path` and hands it to `lean` (version 3 on: read by offset) or
/// to `older` (versions 1 and 2: the open file, its size, its version and its name); the errors
/// name the file.
#[cfg(feature = "std")]
fn open_named<R>(
    path: &std::path::Path,
    lean: impl FnOnce(&lean::FileSource<'_>) -> Result<R, DbError>,
    older: impl FnOnce(std::fs::File, u64, u32, &str) -> Result<R, DbError>,
) -> Result<R, DbError> {
    let file = path.display().to_string();
    let (f, size, version) = open_checked(path).map_err(|e| e.named(&file))?;
    let out = if version >= lean::V3 {
        lean(&lean::FileSource {
            file: &f,
            size,
            name: &file,
        })
    } else {
        older(f, size, version, &file)
    };
    out.map_err(|e| named(e, &file))
}

/// What the fixed-size header announces.
struct Header {
    config: Config,
    fingerprint: u64,
    count: u64,
    /// Length of the cloud section (0 in version 1).
    cloud_section: u64,
    /// Where the entries start: the header's length in this version.
    header_len: usize,
    /// The length of the whole file it implies, in bytes.
    len: u64,
}

impl Header {
    /// Reads the header at the start of `bytes` and checks what can be checked without the body:
    /// the magic, the version, the flags and the reserved field. Needs the version's header and
    /// checksum (fewer is "truncated", or "not a SOLiD database" when even the magic is missing).
    fn parse(bytes: &[u8]) -> Result<Header, String> {
        let version = version_of(bytes)?;
        debug_assert!(
            version < lean::V3,
            "versions 3 and 4 have a header of their own"
        );
        let truncated = |need: usize| {
            format!(
                "truncated: {} bytes, shorter than the {need}-byte header",
                bytes.len()
            )
        };
        let header_len = if version >= 2 {
            HEADER_LEN
        } else {
            HEADER_LEN_V1
        };
        if bytes.len() < header_len + 4 {
            return Err(truncated(header_len + 4));
        }
        let (config, fingerprint, count) = fixed_header(&bytes[..88])?;
        let (n_range, n_azimuth) = (config.n_range, config.n_azimuth);
        let mut rd = Reader { b: bytes, at: 88 };
        let cloud_section = if version >= 2 { rd.u64() } else { 0 };
        let per_entry = (n_range as u64 + n_azimuth as u64) * 4 + ENTRY_LEN as u64;
        let len = count
            .checked_mul(per_entry)
            .and_then(|v| v.checked_add(cloud_section))
            .and_then(|v| v.checked_add((header_len + 4) as u64))
            .filter(|&e| e <= usize::MAX as u64)
            .ok_or_else(|| format!("corrupted header: entry count {count} is impossible"))?;
        Ok(Header {
            config,
            fingerprint,
            count,
            cloud_section,
            header_len,
            len,
        })
    }

    /// Checks that `actual` bytes is the length the header announces (before the checksum, so
    /// that a truncated file says "truncated").
    fn check_len(&self, actual: usize) -> Result<(), String> {
        let (count, expected) = (self.count, self.len);
        match (actual as u64).cmp(&expected) {
            core::cmp::Ordering::Less => Err(format!(
                "truncated: the header announces {count} entries ({expected} bytes) but there are only {actual} bytes"
            )),
            core::cmp::Ordering::Greater => Err(format!(
                "{} unexpected bytes after the end of the data ({expected} bytes expected)",
                actual as u64 - expected
            )),
            core::cmp::Ordering::Equal => Ok(()),
        }
    }
}

/// The format version of a file starting with `bytes`, after its magic: refused when it is
/// newer than this library reads, or 0. Needs 12 bytes (fewer is "truncated", or "not a SOLiD
/// database" when even the magic is missing).
pub(super) fn version_of(bytes: &[u8]) -> Result<u32, String> {
    if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
        return Err(String::from(
            "not a SOLiD database (wrong magic number at the start of the file)",
        ));
    }
    if bytes.len() < 12 {
        return Err(format!(
            "truncated: {} bytes, shorter than the {}-byte header",
            bytes.len(),
            HEADER_LEN_V1 + 4
        ));
    }
    let version = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
    if version > lean::VERSION {
        return Err(format!(
            "format version {version} is newer than this library reads (up to {}); upgrade solid",
            lean::VERSION
        ));
    }
    if version == 0 {
        return Err(String::from("invalid format version 0"));
    }
    Ok(version)
}

/// The fields every version's header starts with (bytes 12..88: flags, dimensions, reserved
/// word, config, fingerprint, entry count), the flags and the reserved word checked.
pub(super) fn fixed_header(b: &[u8]) -> Result<(Config, u64, u64), String> {
    let mut rd = Reader { b, at: 12 };
    let flags = rd.u32();
    if flags != 0 {
        return Err(format!("unknown header flags {flags:#x}"));
    }
    let (n_range, n_azimuth, n_elevation, reserved) = (rd.u32(), rd.u32(), rd.u32(), rd.u32());
    if reserved != 0 {
        return Err(format!(
            "corrupted header: reserved field is {reserved:#x}, not 0"
        ));
    }
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
    Ok((config, rd.u64(), rd.u64()))
}

/// Checks what the header says of the config (valid, and the one its fingerprint names) and the
/// entry count (below `u32::MAX`).
pub(super) fn check_config(config: &Config, fingerprint: u64, count: u64) -> Result<(), String> {
    if let Err(e) = config.validate() {
        return Err(format!("invalid config in header: {e}"));
    }
    if config.fingerprint() != fingerprint {
        return Err(format!(
            "config fingerprint {fingerprint:#018x} does not match the stored config ({:#018x})",
            config.fingerprint()
        ));
    }
    if count >= u32::MAX as u64 {
        return Err(format!("too many entries ({count})"));
    }
    Ok(())
}

/// The error for a format version that cannot be written.
fn bad_version(version: u32) -> DbError {
    crate::Error::InvalidParameter {
        name: "version",
        value: f64::from(version),
        expected: "a format version this library writes: 2, 3 or 4",
    }
    .into()
}

/// A value a descriptor bin can hold: finite and non-negative (SPEC §3).
pub(super) fn is_bin_value(v: f32) -> bool {
    v.is_finite() && v >= 0.0
}

/// An empty vector with room for `n` elements, or [`DbError::OutOfMemory`].
pub(super) fn try_vec<T>(n: usize) -> Result<Vec<T>, DbError> {
    let mut v = Vec::new();
    crate::owned::reserve(&mut v, n, "database").map_err(|_| DbError::OutOfMemory)?;
    Ok(v)
}

/// Why [`read_checked`] failed.
#[cfg(feature = "std")]
enum ReadError {
    Io(std::io::Error),
    Db(DbError),
}

#[cfg(feature = "std")]
impl ReadError {
    /// The error of reading `file`.
    fn named(self, file: &str) -> DbError {
        match self {
            ReadError::Io(source) => DbError::Io {
                file: String::from(file),
                source,
            },
            ReadError::Db(e) => named(e, file),
        }
    }
}

/// A format error `e` of reading `file`, naming it.
#[cfg(feature = "std")]
fn named(e: DbError, file: &str) -> DbError {
    match e {
        DbError::Format { reason, .. } => DbError::Format {
            file: Some(String::from(file)),
            reason,
        },
        other => other,
    }
}

#[cfg(feature = "std")]
impl From<std::io::Error> for ReadError {
    fn from(e: std::io::Error) -> Self {
        ReadError::Io(e)
    }
}

/// The database file at `path`, open, with its size and format version: refuses what is not a
/// regular file before opening it, and reads the first 12 bytes only.
#[cfg(feature = "std")]
fn open_checked(path: &std::path::Path) -> Result<(std::fs::File, u64, u32), ReadError> {
    let not_regular = |meta: &std::fs::Metadata| -> Option<ReadError> {
        let kind = meta.file_type();
        if kind.is_file() {
            return None;
        }
        if kind.is_dir() {
            return Some(ReadError::Io(std::io::ErrorKind::IsADirectory.into()));
        }
        Some(ReadError::Db(DbError::Format {
            file: None,
            reason: format!(
                "not a regular file ({}): refusing to read it",
                file_kind(&kind)
            ),
        }))
    };
    // Opening a FIFO blocks until a writer appears: look before opening, then check again what
    // was opened (the path may have changed in between).
    if let Some(e) = not_regular(&std::fs::metadata(path)?) {
        return Err(e);
    }
    let mut f = std::fs::File::open(path)?;
    let meta = f.metadata()?;
    if let Some(e) = not_regular(&meta) {
        return Err(e);
    }
    let mut head = [0u8; 12];
    let got = read_up_to(&mut f, &mut head)?;
    let db = |reason| ReadError::Db(DbError::Format { file: None, reason });
    let version = version_of(&head[..got]).map_err(db)?;
    Ok((f, meta.len(), version))
}

/// The bytes of an open database file in format version 1 or 2 of `size` bytes, read after its
/// first 12 ([`open_checked`]): reads the header, checks the size it implies against the file's,
/// and only then reads the body into one buffer allocated once.
#[cfg(feature = "std")]
fn read_checked(mut f: std::fs::File, size: u64) -> Result<Vec<u8>, ReadError> {
    use std::io::{Read, Seek};
    f.seek(std::io::SeekFrom::Start(0))?;
    let db = |reason| ReadError::Db(DbError::Format { file: None, reason });
    let mut head = [0u8; HEADER_LEN + 4];
    let got = read_up_to(&mut f, &mut head)?;
    let header = Header::parse(&head[..got]).map_err(db)?;
    let len = usize::try_from(size).unwrap_or(usize::MAX);
    header.check_len(len).map_err(db)?;
    let mut bytes = try_vec::<u8>(len).map_err(ReadError::Db)?;
    bytes.extend_from_slice(&head[..got]);
    // One byte more than announced, to notice a file that grew since it was measured.
    f.take(size - got as u64 + 1).read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// Reads until `buf` is full or the file ends; returns the bytes read.
#[cfg(feature = "std")]
fn read_up_to(f: &mut std::fs::File, buf: &mut [u8]) -> std::io::Result<usize> {
    use std::io::Read;
    let mut got = 0;
    while got < buf.len() {
        match f.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// A name for a file type that is not a regular file.
#[cfg(feature = "std")]
fn file_kind(kind: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            return "a FIFO";
        }
        if kind.is_char_device() {
            return "a character device";
        }
        if kind.is_block_device() {
            return "a block device";
        }
        if kind.is_socket() {
            return "a socket";
        }
    }
    if kind.is_symlink() {
        return "a symbolic link";
    }
    "not a file"
}

/// Whether a file may be written to `path`: refused (`AlreadyExists`) when something that is not
/// a regular file is there (a FIFO, a device, a socket, a directory, also through a symbolic
/// link: a save never replaces what it did not write), or anything at all without `replace`.
#[cfg(feature = "std")]
fn writable(path: &std::path::Path, replace: bool) -> std::io::Result<()> {
    let refuse = |what: &str| {
        Err(std::io::Error::new(
            std::io::ErrorKind::AlreadyExists,
            format!("{what}: refusing to replace it"),
        ))
    };
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => refuse("exists and is a directory, not a regular file"),
        Ok(m) if !m.is_file() => refuse(&format!(
            "exists and is {}, not a regular file",
            file_kind(&m.file_type())
        )),
        _ if !replace && std::fs::symlink_metadata(path).is_ok() => refuse("exists"),
        _ => Ok(()),
    }
}

/// Moves the whole temporary file `tmp` to `path`: renamed over it (`replace`, after checking
/// again what is there), or linked to it, which fails when `path` exists, then removed.
#[cfg(feature = "std")]
fn put_in_place(
    tmp: &std::path::Path,
    path: &std::path::Path,
    replace: bool,
) -> std::io::Result<()> {
    writable(path, replace)?;
    if replace {
        return std::fs::rename(tmp, path);
    }
    match std::fs::hard_link(tmp, path) {
        Ok(()) => std::fs::remove_file(tmp),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Err(std::io::Error::new(
            e.kind(),
            "exists: refusing to replace it",
        )),
        // A file system without hard links: checked above, then renamed.
        Err(_) => std::fs::rename(tmp, path),
    }
}

/// Creates a temporary file of its own next to `path`: `.<name>.<pid>-<n>.tmp`, with `n` counting
/// the calls of this process and the file created exclusively (a name already taken, by another
/// call or left by a killed process, is skipped).
#[cfg(feature = "std")]
fn create_temp(
    path: &std::path::Path,
    name: &std::ffi::OsStr,
) -> std::io::Result<(std::fs::File, std::path::PathBuf)> {
    use std::sync::atomic::{AtomicU64, Ordering};
    static CALLS: AtomicU64 = AtomicU64::new(0);
    let mut tries = 0;
    loop {
        let n = CALLS.fetch_add(1, Ordering::Relaxed);
        tries += 1;
        let mut tmp_name = std::ffi::OsString::from(".");
        tmp_name.push(name);
        tmp_name.push(format!(".{}-{n}.tmp", std::process::id()));
        let tmp = path.with_file_name(tmp_name);
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
        {
            Ok(f) => return Ok((f, tmp)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && tries < 1000 => continue,
            Err(e) => return Err(e),
        }
    }
}

pub(super) const MAGIC: [u8; 8] = *b"SOLiDdb\0";

/// The start of the header of versions 2 and 3, through `put`: the magic, the version, the
/// flags (0), the config, its fingerprint and the number of places.
pub(super) fn header_start(db: &Database, version: u32, put: &mut dyn FnMut(&[u8])) {
    let c = &db.config;
    put(&MAGIC);
    put(&version.to_le_bytes());
    put(&0u32.to_le_bytes());
    for v in [c.n_range, c.n_azimuth, c.n_elevation, 0] {
        put(&(v as u32).to_le_bytes());
    }
    for v in [c.fov_up, c.fov_down, c.min_range, c.max_range, c.voxel_size] {
        put(&v.to_le_bytes());
    }
    put(&db.fingerprint.to_le_bytes());
    put(&(db.len() as u64).to_le_bytes());
}
const HEADER_LEN_V1: usize = 88;
const HEADER_LEN: usize = 96;
const ENTRY_LEN: usize = 4 + 4 + 8 + 96;

/// A little-endian reader over bytes whose length was checked beforehand.
pub(super) struct Reader<'a> {
    pub(super) b: &'a [u8],
    pub(super) at: usize,
}

/// A writer into a buffer whose length was checked beforehand.
struct Writer<'a> {
    b: &'a mut [u8],
    at: usize,
}

impl Writer<'_> {
    fn put(&mut self, v: &[u8]) {
        self.b[self.at..self.at + v.len()].copy_from_slice(v);
        self.at += v.len();
    }
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
