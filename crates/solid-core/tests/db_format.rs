//! The database's file format and the wire form of one place.
#![cfg(feature = "std")]

mod common;
use common::db::{cfg, desc, flip_cloud_byte, format_reason, same, sample_db};
use proptest::prelude::*;
use solid_lidar::db::{decode_place, encode_place, Database, DbError, Method};
use solid_lidar::search::Neighbor;

#[test]
fn bytes_round_trip_and_search_agree() {
    let db = sample_db(300);
    let back = Database::from_bytes(&db.to_bytes().unwrap()).unwrap();
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
    let bytes = sample_db(4).to_bytes().unwrap();
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
    let bytes = sample_db(3).to_bytes().unwrap();
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
    let mut bytes = sample_db(2).to_bytes().unwrap();
    bytes[8..12].copy_from_slice(&5u32.to_le_bytes());
    let reason = format_reason(Database::from_bytes(&bytes).unwrap_err());
    assert!(reason.contains("version 5 is newer"), "{reason}");
    // A header that announces an absurd number of entries.
    let mut bytes = sample_db(2).to_bytes().unwrap();
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
    let v2 = db.to_bytes_version(2).unwrap();
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
    let back = Database::from_bytes(&with.to_bytes().unwrap()).unwrap();
    for i in 0..6u32 {
        assert_eq!(back.cloud(i).unwrap(), with.cloud(i).unwrap());
        assert_eq!(back.cloud(i).unwrap().is_some(), i % 2 == 1);
    }
    assert_eq!(back.cloud_bytes(), stored);
    let mut merged = sample_db(3);
    merged.merge(&back).unwrap();
    assert_eq!(merged.cloud(0).unwrap(), None);
    assert_eq!(merged.cloud(3 + 5).unwrap(), with.cloud(5).unwrap());
    // A cloud section that cannot hold its lengths is refused.
    let mut bytes = with.to_bytes_version(2).unwrap();
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
        let bytes = db.to_bytes().unwrap();
        let back = Database::from_bytes(&bytes).unwrap();
        same(&db, &back);
        // Saved again, the same bytes (the poses do not drift).
        prop_assert_eq!(back.to_bytes().unwrap(), bytes);
        let k = entries.len().min(5);
        let want: Vec<Neighbor> = db.search(&q, k, 0, Method::Brute).unwrap();
        prop_assert_eq!(back.search(&q, k, 0, Method::KdTree).unwrap(), want);
    }
}

/// Where section `kind` of a file in format version 3 or 4 lies: (offset, length).
fn section(bytes: &[u8], kind: u32) -> (usize, usize) {
    let s = u32::from_le_bytes(bytes[88..92].try_into().unwrap()) as usize;
    (0..s)
        .map(|i| &bytes[96 + 32 * i..128 + 32 * i])
        .find(|row| u32::from_le_bytes(row[..4].try_into().unwrap()) == kind)
        .map(|row| {
            let at = |k: usize| u64::from_le_bytes(row[k..k + 8].try_into().unwrap()) as usize;
            (at(8), at(16))
        })
        .expect("no such section")
}

/// Signs section `kind` again after an edit (its trailing CRC-32).
fn resign(bytes: &mut [u8], kind: u32) {
    let (at, len) = section(bytes, kind);
    let crc = solid_lidar::db::crc32(&bytes[at..at + len]);
    bytes[at + len..at + len + 4].copy_from_slice(&crc.to_le_bytes());
}

/// A database whose places 1, 3 and 4 have real clouds.
fn db_with_clouds() -> Database {
    let c = cfg();
    let mut db = Database::new(c).unwrap();
    for i in 0..6u32 {
        let points: Vec<[f64; 3]> = (0..20 + i * 7)
            .map(|k| [f64::from(k), 1.0, f64::from(i)])
            .collect();
        let cloud = solid_lidar::reg::encode_cloud(&points, 0.1, 8).unwrap();
        let with = [1, 3, 4].contains(&i);
        db.add_with_cloud(
            &desc(&c, i),
            i / 3,
            f64::from(i),
            None,
            with.then_some(&cloud[..]),
        )
        .unwrap();
    }
    db
}

#[test]
fn version_2_files_still_load_and_every_version_round_trips() {
    for db in [sample_db(9), db_with_clouds()] {
        for version in [2, 3, 4] {
            let back = Database::from_bytes(&db.to_bytes_version(version).unwrap()).unwrap();
            same(&db, &back);
            if version < 4 {
                assert_eq!(back.poses(), db.poses(), "matrices are kept bit for bit");
            }
            for id in 0..db.len() as u32 {
                assert_eq!(
                    back.cloud(id).unwrap(),
                    db.cloud(id).unwrap(),
                    "version {version}, place {id}"
                );
            }
        }
    }
    assert!(sample_db(1).to_bytes_version(1).is_err());
    assert!(sample_db(1).to_bytes_version(5).is_err());
}

#[test]
fn version_4_keeps_an_entry_with_its_pose_in_300_bytes_beside_its_cloud() {
    let c = cfg();
    let mut db = Database::new(c).unwrap();
    for i in 0..1000u32 {
        db.add(&desc(&c, i), i / 100, f64::from(i), Some(turned(i)))
            .unwrap();
    }
    let (v4, v3, v2) = (
        db.encoded_len(),
        db.to_bytes_version(3).unwrap().len(),
        db.to_bytes_version(2).unwrap().len(),
    );
    let per_entry = |len: usize| (len - 1024) / 1000;
    assert!(per_entry(v4) <= 300, "{} bytes per entry", per_entry(v4));
    assert_eq!(
        per_entry(v3) - per_entry(v4),
        44,
        "the pose: 100 bytes, now 56"
    );
    assert!(v4 < v2 * 3 / 5, "version 4: {v4} bytes, version 2: {v2}");
    // The metadata travels with the file (versions 3 and 4).
    db.set_metadata("{\"fov_deg\": 90}").unwrap();
    let back = Database::from_bytes(&db.to_bytes().unwrap()).unwrap();
    assert_eq!(back.metadata(), "{\"fov_deg\": 90}");
    assert!(db.set_metadata(&"x".repeat((1 << 20) + 1)).is_err());
}

#[test]
fn version_4_refuses_what_no_database_holds_in_each_section() {
    let db = sample_db(5);
    let good = db.to_bytes().unwrap();
    let (r, _) = section(&good, 2);
    let cases: [(u32, usize, Vec<u8>, &str); 4] = [
        (
            2,
            r + 4,
            (-1.0f32).to_le_bytes().to_vec(),
            "negative or non-finite",
        ),
        (
            3,
            section(&good, 3).0,
            0.5f32.to_le_bytes().to_vec(),
            "norm does not match",
        ),
        (
            6,
            section(&good, 6).0 + 8,
            f64::INFINITY.to_le_bytes().to_vec(),
            "infinite timestamp",
        ),
        (
            1,
            section(&good, 1).0 + 4,
            9u32.to_le_bytes().to_vec(),
            "sessions",
        ),
    ];
    for (kind, at, value, why) in cases {
        let mut b = good.clone();
        b[at..at + value.len()].copy_from_slice(&value);
        assert!(format_reason(Database::from_bytes(&b).unwrap_err()).contains("checksum"));
        resign(&mut b, kind);
        let reason = format_reason(Database::from_bytes(&b).unwrap_err());
        assert!(reason.contains(why), "section {kind}: {reason}");
    }
    // A table that does not fit the entries is refused before any section is read.
    let mut b = good.clone();
    b[80..88].copy_from_slice(&4u64.to_le_bytes());
    assert!(Database::from_bytes(&b).is_err());
}

#[test]
fn a_loaded_map_reads_its_clouds_on_demand_and_finds_a_corrupt_one_at_first_use() {
    let dir = std::env::temp_dir().join(format!("solid-lean-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (path, bad) = (dir.join("m.soliddb"), dir.join("bad.soliddb"));
    let db = db_with_clouds();
    db.save(&path).unwrap();
    let loaded = Database::load(&path).unwrap();
    same(&db, &loaded);
    // The clouds stay in the file until asked for.
    assert!(loaded.memory_bytes() + db.cloud_bytes() / 2 < db.memory_bytes());
    for id in 0..6 {
        assert_eq!(loaded.cloud(id).unwrap(), db.cloud(id).unwrap());
    }
    let s = Database::summary(&path).unwrap();
    assert_eq!(
        (s.version, s.places, s.places_with_cloud, s.cloud_bytes),
        (4, 6, 3, db.cloud_bytes() as u64)
    );
    assert_eq!(
        s.sessions
            .iter()
            .map(|x| (x.session, x.places))
            .collect::<Vec<_>>(),
        [(0, 3), (1, 3)]
    );
    assert_eq!(
        (s.sessions[1].first_time, s.sessions[1].last_time),
        (3.0, 5.0)
    );
    // One byte of place 3's cloud flipped: the file still loads (its header and sections are
    // whole), place 3's cloud is an error naming it, the others are read.
    flip_cloud_byte(&db, 3, &path, &bad);
    let broken = Database::load(&bad).unwrap();
    let why = broken.try_cloud(3).unwrap_err().to_string();
    assert!(
        why.contains("cloud of place 3") && why.contains("bad.soliddb") && why.contains("checksum"),
        "{why}"
    );
    assert!(broken.cloud(3).is_err());
    assert_eq!(broken.cloud(4).unwrap(), db.cloud(4).unwrap());
    // Nor can it be added to a database.
    let mut fresh = Database::new(cfg()).unwrap();
    let mut corrupt = db.cloud(3).unwrap().unwrap().into_owned();
    let mid = corrupt.len() / 2;
    corrupt[mid] ^= 0xFF;
    let why = fresh
        .add_with_cloud(&desc(&cfg(), 0), 0, f64::NAN, None, Some(&corrupt))
        .unwrap_err()
        .to_string();
    assert!(why.contains("checksum") && fresh.is_empty(), "{why}");
    // Nothing copies it under a fresh checksum: saving or merging and saving is refused, and
    // the error names the place as the corrupt file numbers it.
    let out = dir.join("out.soliddb");
    assert!(broken.save(&out).is_err() && !out.exists());
    let mut merged = Database::load(&path).unwrap();
    merged.merge(&broken).unwrap();
    let why = merged.save(&out).unwrap_err().to_string();
    assert!(
        why.contains("place 9") && why.contains("cloud of place 3 in"),
        "{why}"
    );
    assert!(!out.exists());
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        2,
        "no temporary file is left"
    );
    // A map saved again from its own file keeps its clouds (read from the old file).
    let again = dir.join("again.soliddb");
    loaded.save(&again).unwrap();
    assert_eq!(
        std::fs::read(&again).unwrap(),
        std::fs::read(&path).unwrap()
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A pose turned about every axis by angles that depend on `i`, with a translation.
fn turned(i: u32) -> [f64; 12] {
    let (a, b, c) = (
        0.7 * f64::from(i),
        1.3 * f64::from(i) + 0.2,
        -0.4 * f64::from(i),
    );
    let (sa, ca) = a.sin_cos();
    let (sb, cb) = b.sin_cos();
    let (sc, cc) = c.sin_cos();
    // Rz(a) · Ry(b) · Rx(c): every rotation, the half-turns among them (i = 0 gives Ry(0.2)).
    [
        ca * cb,
        ca * sb * sc - sa * cc,
        ca * sb * cc + sa * sc,
        f64::from(i) * 1e3,
        sa * cb,
        sa * sb * sc + ca * cc,
        sa * sb * cc - ca * sc,
        -2.5,
        -sb,
        cb * sc,
        cb * cc,
        1e-3 * f64::from(i),
    ]
}

#[test]
fn version_4_stores_a_rotation_as_a_quaternion_and_anything_else_as_saved() {
    let c = cfg();
    // Every place with a turned pose: quaternions and no ids (kinds 12, not 7 or 11).
    let mut db = Database::new(c).unwrap();
    for i in 0..200u32 {
        db.add(&desc(&c, i), 0, f64::NAN, Some(turned(i))).unwrap();
    }
    let mut half_turns = db.clone();
    for (k, diag) in [[1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]]
        .iter()
        .enumerate()
    {
        let mut p = [0.0; 12];
        (p[0], p[5], p[10], p[3]) = (diag[0], diag[1], diag[2], k as f64);
        half_turns
            .add(&desc(&c, 300), 1, f64::NAN, Some(p))
            .unwrap();
    }
    for db in [&db, &half_turns] {
        let bytes = db.to_bytes().unwrap();
        let kinds: Vec<u32> = (0..u32::from_le_bytes(bytes[88..92].try_into().unwrap()) as usize)
            .map(|k| u32::from_le_bytes(bytes[96 + 32 * k..100 + 32 * k].try_into().unwrap()))
            .collect();
        assert!(kinds.contains(&12) && !kinds.contains(&7) && !kinds.contains(&11));
        let back = Database::from_bytes(&bytes).unwrap();
        same(db, &back);
        // The translation as saved, bit for bit.
        for id in 0..db.len() as u32 {
            let (p, q) = (db.pose(id).unwrap(), back.pose(id).unwrap());
            assert_eq!([p[3], p[7], p[11]], [q[3], q[7], q[11]]);
        }
        // Saved again, the same bytes: the poses do not drift from save to save.
        assert_eq!(back.to_bytes().unwrap(), bytes);
    }
    // Places without a pose among them: the ids of those with one (kind 11).
    let partial = sample_db(9);
    let bytes = partial.to_bytes().unwrap();
    let (_, ids) = section(&bytes, 11);
    assert_eq!(ids, 4 * 5);
    let back = Database::from_bytes(&bytes).unwrap();
    same(&partial, &back);
    assert_eq!(
        back.pose(2),
        partial.pose(2),
        "the identity comes back exactly"
    );
    // A matrix that is not a rotation (a pose from a text file of 6 digits) is kept as saved.
    let mut rough = Database::new(c).unwrap();
    let mut p = turned(3);
    p[0] += 1e-7;
    rough.add(&desc(&c, 0), 0, f64::NAN, Some(p)).unwrap();
    let bytes = rough.to_bytes().unwrap();
    section(&bytes, 7);
    assert_eq!(Database::from_bytes(&bytes).unwrap().pose(0), Some(p));
}

#[test]
fn version_4_refuses_a_bad_quaternion_or_pose_ids() {
    let partial = sample_db(9);
    let good = partial.to_bytes().unwrap();
    let (q, _) = section(&good, 12);
    let (ids, _) = section(&good, 11);
    // A quaternion whose largest component is 1.5, a NaN translation, ids out of order, an id past the places.
    let cases: [(u32, usize, Vec<u8>, &str); 4] = [
        (
            12,
            q,
            1.5f64.to_le_bytes().to_vec(),
            "largest component of 1",
        ),
        (
            12,
            q + 40,
            f64::NAN.to_le_bytes().to_vec(),
            "non-finite pose",
        ),
        (11, ids + 4, 0u32.to_le_bytes().to_vec(), "out of order"),
        (
            11,
            ids + 16,
            9u32.to_le_bytes().to_vec(),
            "out of order or range",
        ),
    ];
    for (kind, at, value, why) in cases {
        let mut b = good.clone();
        b[at..at + value.len()].copy_from_slice(&value);
        assert!(Database::from_bytes(&b).is_err());
        resign(&mut b, kind);
        let reason = format_reason(Database::from_bytes(&b).unwrap_err());
        assert!(reason.contains(why), "section {kind}: {reason}");
    }
    // Ids of other places than the runs count poses for.
    let mut b = good.clone();
    b[ids..ids + 4].copy_from_slice(&1u32.to_le_bytes());
    resign(&mut b, 11);
    assert!(format_reason(Database::from_bytes(&b).unwrap_err()).contains("sessions"));
    // Kinds 11 and 12 are not version 3's: a version 3 header over them is refused.
    let mut b = good.clone();
    b[8..12].copy_from_slice(&3u32.to_le_bytes());
    let s = u32::from_le_bytes(b[88..92].try_into().unwrap()) as usize;
    let crc = solid_lidar::db::crc32(&b[..96 + 32 * s]);
    b[96 + 32 * s..100 + 32 * s].copy_from_slice(&crc.to_le_bytes());
    assert!(format_reason(Database::from_bytes(&b).unwrap_err()).contains("unknown section kind"));
}

#[test]
fn version_3_files_still_load_and_upgrade_to_version_4() {
    let c = cfg();
    let mut db = Database::new(c).unwrap();
    for i in 0..50u32 {
        db.add(
            &desc(&c, i),
            i / 20,
            f64::from(i),
            (i % 3 > 0).then(|| turned(i)),
        )
        .unwrap();
    }
    let v3 = db.to_bytes_version(3).unwrap();
    assert_eq!(u32::from_le_bytes(v3[8..12].try_into().unwrap()), 3);
    section(&v3, 7);
    let old = Database::from_bytes(&v3).unwrap();
    // Version 3 keeps the matrices as saved, bit for bit.
    assert_eq!(old.poses(), db.poses());
    let upgraded = Database::from_bytes(&old.to_bytes().unwrap()).unwrap();
    same(&db, &upgraded);
}

#[test]
fn a_loaded_map_keeps_its_quaternions_and_merges_give_every_pose_back() {
    let c = cfg();
    // Some places with a turned pose, some without (kinds 11 and 12).
    let mut saved = Database::new(c).unwrap();
    for i in 0..64u32 {
        let pose = (i % 3 != 0).then(|| turned(i));
        saved.add(&desc(&c, i), 0, f64::NAN, pose).unwrap();
    }
    let bytes = saved.to_bytes().unwrap();
    let v4 = Database::from_bytes(&bytes).unwrap();
    // Saved in version 3 and read again: the matrices the quaternions gave, held as matrices.
    let v3 = Database::from_bytes(&v4.to_bytes_version(3).unwrap()).unwrap();
    // The same poses, bit for bit, whichever form holds them; 40 bytes less a pose in memory.
    assert_eq!(v4.poses(), v3.poses());
    let posed = saved.poses_stored();
    assert!(v3.memory_bytes() >= v4.memory_bytes() + 40 * posed);
    // Merged either way with places whose poses are held as given.
    let fresh = sample_db(9);
    let mut a = v4.clone();
    a.merge(&fresh).unwrap();
    let mut b = fresh.clone();
    b.merge(&v4).unwrap();
    for (m, first) in [(&a, &v4), (&b, &fresh)] {
        let second = if std::ptr::eq(first, &v4) {
            &fresh
        } else {
            &v4
        };
        let want: Vec<_> = first.poses().into_iter().chain(second.poses()).collect();
        assert_eq!(m.poses(), want);
        assert_eq!(m.poses_stored(), want.iter().flatten().count());
        for (id, p) in want.iter().enumerate() {
            assert_eq!(m.pose(id as u32), *p);
        }
        // Saved and read again: the same poses, and the same bytes saved again.
        let back = Database::from_bytes(&m.to_bytes().unwrap()).unwrap();
        assert_eq!(back.poses(), want);
        assert_eq!(back.to_bytes().unwrap(), m.to_bytes().unwrap());
    }
}
