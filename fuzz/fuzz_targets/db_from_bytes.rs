//! `Database::from_bytes` on arbitrary bytes: never a panic or an out-of-bounds access (ASan).
//! What it accepts is a database that behaves: it encodes to its own length, reads back the same,
//! and its search methods (brute force, kd-tree, sketch, auto) agree.
#![no_main]

use libfuzzer_sys::fuzz_target;
use solid_lidar::db::{Database, Method};

fuzz_target!(|data: &[u8]| {
    let Ok(db) = Database::from_bytes(data) else {
        return;
    };
    // A stored cloud is checked when it is read: one that is corrupt is refused by the encoder.
    let Ok(bytes) = db.to_bytes() else {
        return;
    };
    assert_eq!(bytes.len(), db.encoded_len());
    let version = u32::from_le_bytes([data[8], data[9], data[10], data[11]]);
    if version == 2 {
        let again = db.to_bytes_version(2).expect("its clouds were read once");
        assert_eq!(
            again.len(),
            data.len(),
            "a database is exactly its announced length"
        );
    }
    let back = Database::from_bytes(&bytes).expect("what to_bytes writes reads back");
    assert_eq!(back.len(), db.len());
    assert_eq!(back.r_all(), db.r_all());
    assert_eq!(back.a_all(), db.a_all());
    assert_eq!(back.sessions(), db.sessions());
    assert!(db
        .r_all()
        .iter()
        .chain(db.a_all().iter())
        .all(|v| v.is_finite() && *v >= 0.0));
    for id in 0..db.len().min(4) as u32 {
        let q = db.r(id);
        let brute = db
            .search(q, 3, 0, Method::Brute)
            .expect("a stored vector is a valid query");
        for method in [Method::KdTree, Method::Sketch, Method::Auto] {
            let other = db
                .search(q, 3, 0, method)
                .expect("a stored vector is a valid query");
            assert_eq!(brute.len(), other.len());
            for (b, t) in brute.iter().zip(&other) {
                assert!((b.distance - t.distance).abs() <= 1e-6, "{method:?}: {b:?} vs {t:?}");
                assert!((0.0..=1.0 + 1e-6).contains(&b.distance), "{b:?}");
            }
        }
    }
});
