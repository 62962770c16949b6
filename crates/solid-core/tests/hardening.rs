//! Issue 10, items 6 and 8 in the core: files written and read defensively, and every value a
//! descriptor cannot hold refused at the entry points.
#![cfg(feature = "std")]

use std::path::{Path, PathBuf};

use solid_lidar::db::{
    crc32, decode_place, encode_place, Database, DbError, Method, SearchOptions,
};
use solid_lidar::{Config, Error};

fn cfg() -> Config {
    Config::preset("hdl64").unwrap()
}

/// A database of `n` entries whose vectors depend on `seed`.
fn db(n: u32, seed: u32) -> Database {
    let c = cfg();
    let mut db = Database::new(c).unwrap();
    for i in 0..n {
        let v = |dim: usize| -> Vec<f32> {
            (0..dim)
                .map(|j| ((i * 31 + seed * 7 + j as u32) % 17) as f32)
                .collect()
        };
        db.add_vectors(&v(c.n_range), &v(c.n_azimuth), seed, f64::from(i), None)
            .unwrap();
    }
    db
}

fn with_crc(mut b: Vec<u8>) -> Vec<u8> {
    let n = b.len();
    let crc = crc32(&b[..n - 4]);
    b[n - 4..].copy_from_slice(&crc.to_le_bytes());
    b
}

fn reason(r: Result<Database, DbError>) -> String {
    match r {
        Err(DbError::Format { reason, .. }) => reason,
        other => panic!("expected a format error, got {other:?}"),
    }
}

/// A fresh folder under the system's temporary folder.
fn scratch_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("solid-hardening-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn encode_into_writes_what_to_bytes_returns_and_checks_the_buffer() {
    let d = db(7, 1);
    let bytes = d.to_bytes().unwrap();
    assert_eq!(bytes.len(), d.encoded_len());
    let mut out = vec![0u8; d.encoded_len() + 3];
    assert_eq!(d.encode_into(&mut out).unwrap(), bytes.len());
    assert_eq!(&out[..bytes.len()], &bytes[..]);
    assert!(matches!(
        d.encode_into(&mut out[..bytes.len() - 1]),
        Err(DbError::Core(Error::BufferTooSmall { .. }))
    ));
}

#[test]
fn the_reserved_header_word_is_checked() {
    let mut b = db(2, 0).to_bytes().unwrap();
    b[28..32].copy_from_slice(&1u32.to_le_bytes());
    assert!(reason(Database::from_bytes(&with_crc(b))).contains("reserved"));
}

#[test]
fn from_bytes_refuses_what_no_database_holds() {
    let n = 3;
    // Offsets of format version 2 (version 3 has a test of its own in db_format.rs).
    let good = db(n, 0).to_bytes_version(2).unwrap();
    let r0 = 96 + n as usize * 112;
    let last_a = good.len() - 8;
    for (at, v) in [(r0, -1.0f32), (last_a, -0.25), (r0, f32::NAN)] {
        let mut b = good.clone();
        b[at..at + 4].copy_from_slice(&v.to_le_bytes());
        let why = reason(Database::from_bytes(&with_crc(b)));
        assert!(why.contains("negative or non-finite"), "{why}");
    }
    let mut b = good.clone();
    b[104..112].copy_from_slice(&f64::INFINITY.to_le_bytes());
    assert!(reason(Database::from_bytes(&with_crc(b))).contains("infinite timestamp"));
}

#[test]
fn places_with_negative_values_are_neither_encoded_nor_decoded() {
    let c = cfg();
    let (r, a) = (vec![1.0f32; c.n_range], vec![2.0f32; c.n_azimuth]);
    let mut neg = r.clone();
    neg[3] = -1.0;
    for quantized in [false, true] {
        assert!(matches!(
            encode_place(&neg, &a, c.fingerprint(), quantized),
            Err(Error::InvalidParameter {
                name: "r_solid",
                ..
            })
        ));
        let mut b = encode_place(&r, &a, c.fingerprint(), quantized).unwrap();
        b[16..20].copy_from_slice(&(-3.0f32).to_le_bytes());
        match decode_place(&with_crc(b)) {
            Err(DbError::Format { reason, .. }) => assert!(reason.contains("negative"), "{reason}"),
            other => panic!("accepted: {other:?}"),
        }
    }
}

#[test]
fn the_entry_points_refuse_negative_vectors_infinite_times_and_nan_limits() {
    let c = cfg();
    let mut d = db(3, 0);
    let (r, a) = (vec![1.0f32; c.n_range], vec![1.0f32; c.n_azimuth]);
    let (mut neg_r, mut neg_a) = (r.clone(), a.clone());
    neg_r[0] = -0.5;
    neg_a[7] = -0.5;
    for (rr, aa) in [(&neg_r, &a), (&r, &neg_a)] {
        assert!(matches!(
            d.add_vectors(rr, aa, 0, 1.0, None),
            Err(DbError::Core(Error::InvalidParameter { .. }))
        ));
    }
    assert!(matches!(
        d.add_vectors(&r, &a, 0, f64::INFINITY, None),
        Err(DbError::Core(Error::InvalidParameter {
            name: "timestamp",
            ..
        }))
    ));
    assert_eq!(d.len(), 3, "a refused add changes nothing");
    assert!(d.search(&neg_r, 1, 0, Method::Auto).is_err());
    let opts = SearchOptions {
        not_newer_than: Some(f64::NAN),
        ..SearchOptions::default()
    };
    assert!(matches!(
        d.search_with(&r, &opts),
        Err(DbError::Core(Error::InvalidParameter {
            name: "not_newer_than",
            ..
        }))
    ));
}

#[test]
fn concurrent_saves_to_one_path_all_succeed_and_leave_one_whole() {
    let dir = scratch_dir("race");
    let path = dir.join("map.soliddb");
    let dbs: Vec<Database> = (0..4).map(|s| db(50 + 20 * s, s)).collect();
    let want: Vec<Vec<u8>> = dbs.iter().map(|d| d.to_bytes().unwrap()).collect();
    for _ in 0..20 {
        std::thread::scope(|s| {
            for d in &dbs {
                let path = &path;
                s.spawn(move || d.save(path).unwrap());
            }
        });
        let got = std::fs::read(&path).unwrap();
        assert!(
            want.contains(&got),
            "the file is none of the saved databases"
        );
    }
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["map.soliddb"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `Database::load(path)` on another thread, failing the test if it blocks.
fn load_within_seconds(path: &Path) -> Result<Database, DbError> {
    let (tx, rx) = std::sync::mpsc::channel();
    let p = path.to_path_buf();
    std::thread::spawn(move || {
        let _ = tx.send(Database::load(&p));
    });
    rx.recv_timeout(std::time::Duration::from_secs(20))
        .expect("load blocked")
}

#[cfg(unix)]
#[test]
fn load_refuses_what_is_not_a_regular_file() {
    let dir = scratch_dir("special");
    let fifo = dir.join("fifo.soliddb");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .map(|s| s.success());
    if matches!(made, Ok(true)) {
        let why = reason(load_within_seconds(&fifo));
        assert!(why.contains("not a regular file (a FIFO)"), "{why}");
    }
    let zero = dir.join("zero.soliddb");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    assert!(reason(load_within_seconds(&zero)).contains("a character device"));
    match Database::load(&dir) {
        Err(DbError::Io { source, .. }) => {
            assert_eq!(source.kind(), std::io::ErrorKind::IsADirectory)
        }
        other => panic!("expected an I/O error, got {other:?}"),
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn load_compares_the_header_with_the_file_size_before_reading_the_body() {
    let dir = scratch_dir("sparse");
    // 6 GiB of zeros (sparse): foreign, refused on its magic.
    let foreign = dir.join("foreign.bin");
    std::fs::File::create(&foreign)
        .unwrap()
        .set_len(6 << 30)
        .unwrap();
    assert!(reason(Database::load(&foreign)).contains("not a SOLiD database"));
    // A valid one-entry database padded to 6 GiB: refused on its size.
    let padded = dir.join("padded.soliddb");
    std::fs::write(&padded, db(1, 0).to_bytes().unwrap()).unwrap();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&padded)
        .unwrap()
        .set_len(6 << 30)
        .unwrap();
    let why = reason(Database::load(&padded));
    assert!(why.contains("unexpected bytes after the end"), "{why}");
    // Truncated: the header announces more than the file holds.
    let short = dir.join("short.soliddb");
    let bytes = db(5, 0).to_bytes().unwrap();
    std::fs::write(&short, &bytes[..bytes.len() - 100]).unwrap();
    assert!(reason(Database::load(&short)).starts_with("truncated"));
    // Shorter than the header, and empty.
    std::fs::write(&short, &bytes[..50]).unwrap();
    assert!(reason(Database::load(&short)).starts_with("truncated"));
    std::fs::write(&short, b"").unwrap();
    assert!(reason(Database::load(&short)).contains("not a SOLiD database"));
    std::fs::remove_dir_all(&dir).unwrap();
}
