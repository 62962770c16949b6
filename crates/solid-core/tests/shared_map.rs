//! A detector over a shared map: the map is not copied nor changed, its places and the
//! detector's are searched as one database, and a corrupt cloud met in a step says so.
#![cfg(feature = "std")]

mod common;
use std::sync::Arc;

use common::db::{cfg, desc, flip_cloud_byte, unverified};
use solid_lidar::db::{Database, DetectorConfig, LoopDetector, Method, Scan, SearchOptions};
use solid_lidar::reg::{self, PreparedCloud, Rejection};

fn map(n: u32) -> Database {
    let c = cfg();
    let mut db = Database::new(c).unwrap();
    for i in 0..n {
        db.add(&desc(&c, i), 2, f64::from(i), None).unwrap();
    }
    db
}

#[test]
fn a_detector_shares_the_map_and_searches_it_with_its_own_places_as_one_database() {
    let c = cfg();
    let shared = Arc::new(map(300));
    let dc = DetectorConfig {
        exclude_frames: 4,
        top_k: 25,
        ..unverified()
    };
    let mut det = LoopDetector::with_map(Arc::clone(&shared), dc).unwrap();
    // The detector holds the map itself, not a copy.
    assert!(Arc::ptr_eq(det.map(), &shared));
    assert_eq!((det.session(), det.session_start()), (3, 300));
    for i in 0..40 {
        // Revisits of the map and of the session's own places, with distinct ones.
        let seed = [i * 7, 300 + i, 1000 + i][i as usize % 3];
        let step = det.detect(&desc(&c, seed), f64::from(i), None).unwrap();
        assert_eq!(step.query, 300 + i);
        // The same search over one database holding every place gives the same candidates.
        let all = det.to_database().unwrap();
        let hits = all
            .search_with(
                &desc(&c, seed).r,
                &SearchOptions {
                    k: 25,
                    exclude_recent: all.len() - step.eligible as usize,
                    method: Method::Brute,
                    ..SearchOptions::default()
                },
            )
            .unwrap();
        let mut ids: Vec<u32> = step.candidates.iter().map(|c| c.id).collect();
        let mut want: Vec<u32> = hits.iter().map(|h| h.id).collect();
        ids.sort_unstable();
        want.sort_unstable();
        assert_eq!(ids, want, "step {i}");
    }
    // The map is as it was: the detector's places are its own.
    assert_eq!(
        (shared.len(), det.len(), det.places().len()),
        (300, 340, 40)
    );
    assert_eq!(det.entry(310), (3, 10.0));
    assert_eq!(det.entry(10), (2, 10.0));
    assert!(!Arc::ptr_eq(&det.shared_database().unwrap(), &shared));
    // Without a step, the database of every place is the map itself.
    let fresh = LoopDetector::with_map(Arc::clone(&shared), dc).unwrap();
    assert!(Arc::ptr_eq(&fresh.shared_database().unwrap(), &shared));
    // Handing the detector back gives every place, in order.
    let all = det.into_database().unwrap();
    assert_eq!(all.len(), 340);
    assert_eq!(all.r(311), desc(&c, 1011).r.as_slice());
    assert_eq!(all.sessions()[299..301], [2, 3]);
}

/// Points on three walls and a floor: enough structure to prepare and register.
fn room(shift: f64) -> Vec<[f64; 3]> {
    let mut p = Vec::new();
    for a in 0..30 {
        for b in 0..12 {
            let (u, v) = (f64::from(a) * 0.4 - 6.0, f64::from(b) * 0.4);
            p.push([u + shift, 8.0, v]);
            p.push([-7.0 + shift, u, v]);
            p.push([9.0 + shift, u * 0.5, v]);
            p.push([u + shift, v * 2.0 - 6.0, -1.5]);
        }
    }
    p
}

#[test]
fn a_corrupt_cloud_met_in_a_step_is_the_candidates_stated_rejection() {
    let c = cfg();
    let mut dc = DetectorConfig::for_preset("hdl64").unwrap();
    dc.exclude_frames = 0;
    let rc = dc.verify.registration;
    let mut db = Database::new(c).unwrap();
    for i in 0..5u32 {
        let cloud = reg::encode_cloud(&room(f64::from(i) * 0.3), rc.voxel_size, 10).unwrap();
        db.add_with_cloud(&desc(&c, i), 0, f64::from(i), None, Some(&cloud))
            .unwrap();
    }
    let dir = std::env::temp_dir().join(format!("solid-shared-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("corrupt.soliddb");
    db.save(&path).unwrap();
    // One byte of place 3's cloud flipped in the file: the map loads, the cloud is bad.
    flip_cloud_byte(&db, 3, &path, &path);
    let map = Database::load(&path).unwrap();
    let mut det = LoopDetector::with_database(map, dc).unwrap();
    let q = PreparedCloud::from_downsampled(&room(0.9), &rc).unwrap();
    let step = det
        .detect_scan(
            Scan {
                descriptor: desc(&c, 3),
                cloud: Some(q),
            },
            10.0,
            None,
        )
        .unwrap();
    let place3 = step.candidates.iter().find(|c| c.id == 3).expect("place 3");
    let v = place3.verification.expect("place 3 is not left unverified");
    assert_eq!(v.rejection, Some(Rejection::CorruptCloud));
    assert!(!v.accepted);
    assert!(step.accepted.is_none_or(|l| l.candidate != 3));
    // The other candidates were registered from their clouds.
    assert!(step.candidates.iter().filter(|c| c.id != 3).any(|c| c
        .verification
        .is_some_and(|v| v.rejection != Some(Rejection::CorruptCloud))));
    // The detector names the place and the file when asked for its cloud.
    let why = det.try_cloud(3).unwrap_err().to_string();
    assert!(
        why.contains("place 3") && why.contains("corrupt.soliddb"),
        "{why}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
