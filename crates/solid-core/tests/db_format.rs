//! The database's file format and the wire form of one place.
#![cfg(feature = "std")]

mod common;
use common::db::{cfg, desc, format_reason, same, sample_db};
use proptest::prelude::*;
use solid_lidar::db::{decode_place, encode_place, Database, DbError, Method};
use solid_lidar::search::Neighbor;

#[test]
fn bytes_round_trip_and_search_agree() {
    let db = sample_db(300);
    let back = Database::from_bytes(&db.to_bytes()).unwrap();
    same(&db, &back);
    let c = cfg();
    for q in 0..20 {
        let d = desc(&c, 1000 + q);
        for m in [Method::Brute, Method::KdTree, Method::Auto] {
            assert_eq!(
                db.search(&d.r, 5, 10, m).unwrap(),
                back.search(&d.r, 5, 10, Method::Brute).unwrap()
            );
        }
    }
    // An entry is its own nearest neighbour.
    let hit = db.search(&desc(&c, 42).r, 1, 0, Method::KdTree).unwrap();
    assert_eq!(hit[0].id, 42);
    assert!(hit[0].distance < 1e-6);
}

#[test]
fn file_round_trip_is_atomic_and_names_the_file_on_errors() {
    let dir = std::env::temp_dir().join(format!("solid-engine-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("map.soliddb");
    let db = sample_db(57);
    db.save(&path).unwrap();
    same(&db, &Database::load(&path).unwrap());
    // No temporary file is left behind.
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, [std::ffi::OsString::from("map.soliddb")]);
    // Overwriting works.
    sample_db(3).save(&path).unwrap();
    assert_eq!(Database::load(&path).unwrap().len(), 3);

    // Corrupt file: the message names the file and the reason.
    let mut bytes = std::fs::read(&path).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x10;
    std::fs::write(&path, &bytes).unwrap();
    let msg = Database::load(&path).unwrap_err().to_string();
    assert!(
        msg.contains("map.soliddb") && msg.contains("checksum"),
        "{msg}"
    );

    // Missing file: an I/O error of kind NotFound that names the file.
    match Database::load(dir.join("nope.soliddb")) {
        Err(DbError::Io { file, source }) => {
            assert!(file.ends_with("nope.soliddb"));
            assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
        }
        other => panic!("expected an I/O error, got {other:?}"),
    }
    // Saving into a missing directory fails cleanly.
    assert!(matches!(
        db.save(dir.join("missing/dir/x.db")),
        Err(DbError::Io { .. })
    ));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn every_truncation_is_rejected_as_truncated() {
    let bytes = sample_db(4).to_bytes();
    for len in 0..bytes.len() {
        let reason = format_reason(Database::from_bytes(&bytes[..len]).unwrap_err());
        assert!(
            reason.contains("truncated") || (len < 8 && reason.contains("not a SOLiD database")),
            "length {len}: {reason}"
        );
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(format_reason(Database::from_bytes(&longer).unwrap_err()).contains("unexpected bytes"));
}

#[test]
fn every_single_byte_corruption_is_rejected() {
    let bytes = sample_db(3).to_bytes();
    for i in 0..bytes.len() {
        for flip in [0x01u8, 0x80, 0xff] {
            let mut b = bytes.clone();
            b[i] ^= flip;
            let r = Database::from_bytes(&b);
            assert!(r.is_err(), "byte {i} ^ {flip:#x} was accepted");
        }
    }
}

#[test]
fn foreign_and_newer_files_are_rejected_with_the_reason() {
    let reason =
        format_reason(Database::from_bytes(b"PK\x03\x04 a zip file, not a database").unwrap_err());
    assert!(reason.contains("not a SOLiD database"), "{reason}");
    assert!(format_reason(Database::from_bytes(&[]).unwrap_err()).contains("not a SOLiD database"));
    let mut bytes = sample_db(2).to_bytes();
    bytes[8..12].copy_from_slice(&3u32.to_le_bytes());
    let reason = format_reason(Database::from_bytes(&bytes).unwrap_err());
    assert!(reason.contains("version 3 is newer"), "{reason}");
    // A header that announces an absurd number of entries.
    let mut bytes = sample_db(2).to_bytes();
    bytes[80..88].copy_from_slice(&u64::MAX.to_le_bytes());
    let reason = format_reason(Database::from_bytes(&bytes).unwrap_err());
    assert!(
        reason.contains("impossible") || reason.contains("truncated"),
        "{reason}"
    );
}

/// The same database in format version 1 (no cloud-section field, no clouds).
fn as_version_1(db: &Database) -> Vec<u8> {
    assert!(!db.has_clouds());
    let v2 = db.to_bytes();
    let mut v1 = Vec::new();
    v1.extend_from_slice(&v2[..8]);
    v1.extend_from_slice(&1u32.to_le_bytes());
    v1.extend_from_slice(&v2[12..88]);
    v1.extend_from_slice(&v2[96..v2.len() - 4]);
    let crc = solid_lidar::db::crc32(&v1);
    v1.extend_from_slice(&crc.to_le_bytes());
    v1
}

#[test]
fn version_1_files_still_load_and_clouds_round_trip() {
    let db = sample_db(7);
    let old = Database::from_bytes(&as_version_1(&db)).unwrap();
    same(&db, &old);
    assert!(!old.has_clouds());
    // Clouds: some entries with one, some without; they survive bytes and merges.
    let c = cfg();
    let mut with = Database::new(c).unwrap();
    let mut stored = 0;
    for i in 0..6u32 {
        // Real clouds of different sizes: a load decodes every stored cloud.
        let points: Vec<[f64; 3]> = (0..i * 7).map(|k| [f64::from(k), 1.0, 0.5]).collect();
        let cloud = solid_lidar::reg::encode_cloud(&points, 0.1, 8).unwrap();
        let cloud = (i % 2 == 1).then_some(&cloud[..]);
        stored += cloud.map_or(0, <[u8]>::len);
        with.add_with_cloud(&desc(&c, i), 0, f64::from(i), None, cloud)
            .unwrap();
    }
    let back = Database::from_bytes(&with.to_bytes()).unwrap();
    for i in 0..6u32 {
        assert_eq!(back.cloud(i), with.cloud(i));
        assert_eq!(back.cloud(i).is_some(), i % 2 == 1);
    }
    assert_eq!(back.cloud_bytes(), stored);
    let mut merged = sample_db(3);
    merged.merge(&back).unwrap();
    assert_eq!(merged.cloud(0), None);
    assert_eq!(merged.cloud(3 + 5), with.cloud(5));
    // A cloud section that cannot hold its lengths is refused.
    let mut bytes = with.to_bytes();
    bytes[88..96].copy_from_slice(&3u64.to_le_bytes());
    assert!(Database::from_bytes(&bytes).is_err());
}

#[test]
fn wire_form_round_trips() {
    let c = cfg();
    let d = desc(&c, 7);
    let f = encode_place(&d.r, &d.a, d.fingerprint, false).unwrap();
    assert_eq!(f.len(), 16 + 400 + 4);
    let p = decode_place(&f).unwrap();
    assert_eq!(
        (p.r, p.a, p.fingerprint, p.quantized),
        (d.r.clone(), d.a.clone(), d.fingerprint, false)
    );
    let q = encode_place(&d.r, &d.a, d.fingerprint, true).unwrap();
    assert!(q.len() <= 200, "{}", q.len());
    let p = decode_place(&q).unwrap();
    assert!(p.quantized);
    let err = solid_lidar::cosine_distance(&p.r, &d.r).unwrap();
    assert!(err < 1e-3, "quantisation moved the descriptor by {err}");
    for bytes in [&f, &q] {
        for i in 0..bytes.len() {
            let mut b = bytes.to_vec();
            b[i] ^= 0x04;
            assert!(decode_place(&b).is_err(), "corruption at byte {i} accepted");
        }
        assert!(decode_place(&bytes[..bytes.len() - 1]).is_err());
    }
    assert!(encode_place(&[-1.0], &[1.0], 0, true).is_err());
    assert!(encode_place(&[f32::NAN], &[1.0], 0, false).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn random_databases_round_trip(
        entries in prop::collection::vec(
            (any::<u32>(), prop_oneof![Just(f64::NAN), -1e9f64..1e9], prop::option::of((-3.2f64..3.2, prop::array::uniform3(-1e3f64..1e3))),
             prop::collection::vec(0.0f32..1e4, 40), prop::collection::vec(0.0f32..1e4, 60)),
            0..30),
        q in prop::collection::vec(0.0f32..1e4, 40),
    ) {
        let mut db = Database::new(cfg()).unwrap();
        for (s, t, p, r, a) in &entries {
            // A pose: a rotation about z by `yaw` and a translation.
            let pose = p.map(|(yaw, t): (f64, [f64; 3])| {
                let (sn, cs) = yaw.sin_cos();
                [cs, -sn, 0.0, t[0], sn, cs, 0.0, t[1], 0.0, 0.0, 1.0, t[2]]
            });
            db.add_vectors(r, a, *s, *t, pose).unwrap();
        }
        let back = Database::from_bytes(&db.to_bytes()).unwrap();
        same(&db, &back);
        let k = entries.len().min(5);
        let want: Vec<Neighbor> = db.search(&q, k, 0, Method::Brute).unwrap();
        prop_assert_eq!(back.search(&q, k, 0, Method::KdTree).unwrap(), want);
    }
}
