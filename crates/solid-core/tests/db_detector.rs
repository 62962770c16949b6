//! The loop detector over descriptors (verification off: these tests feed no points).
#![cfg(feature = "std")]

mod common;
use common::db::{cfg, desc, unverified};
use solid_lidar::db::{Database, DbError, DetectorConfig, LoopDetector};
use solid_lidar::{Descriptor, Error};

#[test]
fn loop_detector_finds_revisits_after_the_exclusion_window() {
    let c = cfg();
    let det_cfg = DetectorConfig {
        exclude_frames: 5,
        threshold: 0.05,
        ..unverified()
    };
    let mut det = LoopDetector::new(c, det_cfg).unwrap();
    // Ten distinct places, then place 2 again (rotated A-SOLiD by 3 bins = 18°).
    for i in 0..10 {
        assert_eq!(det.add(&desc(&c, i), f64::from(i)).unwrap(), None);
    }
    let mut again = desc(&c, 2);
    again.a.rotate_right(3);
    let found = det.query(&again).unwrap().expect("a loop");
    assert_eq!((found.query, found.candidate), (10, 2));
    assert!(found.distance < 1e-6);
    // The database keeps A-SOLiDs at 8 bits (Database::a): the refined heading of an exact
    // 3-bin rotation comes out within a few thousandths of a degree of 18.
    assert!(
        (found.heading_deg - 18.0).abs() < 0.01,
        "{}",
        found.heading_deg
    );
    assert_eq!(det.add(&again, 10.0).unwrap(), Some(found));
    // A revisit of the most recent scan is inside the exclusion window: no loop.
    assert_eq!(det.add(&desc(&c, 9), 11.0).unwrap(), None);
    assert_eq!(det.len(), 12);
    for bad in [
        DetectorConfig {
            threshold: f64::NAN,
            ..det_cfg
        },
        DetectorConfig {
            threshold: 1.5,
            ..det_cfg
        },
        DetectorConfig {
            top_k: 0,
            ..det_cfg
        },
        DetectorConfig {
            exclude_meters: -1.0,
            ..det_cfg
        },
        DetectorConfig {
            exclude_seconds: f64::INFINITY,
            ..det_cfg
        },
    ] {
        assert!(matches!(
            LoopDetector::new(c, bad),
            Err(DbError::Core(Error::InvalidParameter { .. }))
        ));
    }
}

fn pose_at(x: f64) -> [f64; 12] {
    [1.0, 0.0, 0.0, x, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
}

#[test]
fn detector_excludes_by_frames_metres_and_seconds_within_its_own_session() {
    let c = cfg();
    let base = DetectorConfig {
        exclude_frames: 0,
        exclude_meters: 0.0,
        threshold: 1.0,
        top_k: 3,
        ..unverified()
    };
    // The metres window is on by default: within 30 m of path, a 2 m walk sees nothing.
    let mut det = LoopDetector::new(c, unverified()).unwrap();
    let d = det
        .detect(&desc(&c, 0), f64::NAN, Some(pose_at(0.0)))
        .unwrap();
    assert_eq!(d.eligible, 0);
    for i in 1..60 {
        let d = det
            .detect(&desc(&c, i), f64::NAN, Some(pose_at(0.2 * f64::from(i))))
            .unwrap();
        // Past 50 frames, the frames window alone would let the first places through.
        assert_eq!(d.eligible, 0, "step {i}");
    }
    // Ten scans 0.2 m and 1 s apart.
    let run = |dc: DetectorConfig| -> Vec<u32> {
        let mut det = LoopDetector::new(c, dc).unwrap();
        (0..10)
            .map(|i| {
                det.detect(
                    &desc(&c, i),
                    f64::from(i),
                    Some(pose_at(0.2 * f64::from(i))),
                )
                .unwrap()
                .eligible
            })
            .collect()
    };
    assert_eq!(run(base), (0..10).collect::<Vec<u32>>());
    let frames = DetectorConfig {
        exclude_frames: 3,
        ..base
    };
    assert_eq!(run(frames), [0, 0, 0, 0, 1, 2, 3, 4, 5, 6]);
    // 1 m back along the path: query i sees j with 0.2 (i - j) >= 1, i.e. j <= i - 5.
    let metres = DetectorConfig {
        exclude_meters: 1.0 - 1e-9,
        ..base
    };
    assert_eq!(run(metres), [0, 0, 0, 0, 0, 1, 2, 3, 4, 5]);
    let seconds = DetectorConfig {
        exclude_seconds: 2.0,
        ..base
    };
    assert_eq!(run(seconds), [0, 0, 1, 2, 3, 4, 5, 6, 7, 8]);
    // All three: the strictest wins.
    let all = DetectorConfig {
        exclude_frames: 3,
        exclude_meters: 1.0 - 1e-9,
        exclude_seconds: 2.0,
        ..base
    };
    assert_eq!(run(all), [0, 0, 0, 0, 0, 1, 2, 3, 4, 5]);

    // Exclusion by metres applies to the scans that carry a pose, by seconds to those with a
    // time: a scan without one is excluded by frames only, and the path goes on from the last
    // pose (the places without one sit where the path stood).
    let mut det = LoopDetector::new(c, metres).unwrap();
    let steps: Vec<u32> = [Some(0.0), Some(0.2), None, Some(0.6), Some(1.2), None]
        .iter()
        .enumerate()
        .map(|(i, x)| {
            det.detect(&desc(&c, i as u32), f64::NAN, x.map(pose_at))
                .unwrap()
                .eligible
        })
        .collect();
    // Query 3 at 0.6 m sees nothing; query 4 at 1.2 m sees the places at 0 and 0.2 m and the
    // pose-less one, which sits at 0.2 m; query 5 has no pose: it sees every earlier place.
    assert_eq!(steps, [0, 0, 2, 0, 3, 5]);
    // Time must not go back; on error nothing is added.
    let mut det = LoopDetector::new(c, seconds).unwrap();
    det.detect(&desc(&c, 0), 5.0, None).unwrap();
    assert!(det.detect(&desc(&c, 1), 4.0, None).is_err());
    assert!(det.detect(&desc(&c, 1), f64::INFINITY, None).is_err());
    assert_eq!(det.len(), 1);
    // A scan without a time is not excluded by seconds.
    assert_eq!(
        det.detect(&desc(&c, 1), f64::NAN, None).unwrap().eligible,
        1
    );
    det.detect(&desc(&c, 1), 5.5, None).unwrap();
    assert_eq!(det.len(), 3);
    // A pose that is not a rotation is refused.
    let mut skew = pose_at(0.0);
    skew[1] = 0.5;
    assert!(det.detect(&desc(&c, 1), 6.0, Some(skew)).is_err());
    // detect_many checks everything first: a bad timestamp in the middle adds nothing.
    let ds: Vec<Descriptor> = (0..4).map(|i| desc(&c, i)).collect();
    assert!(det.detect_many(&ds, &[6.0, 7.0, 3.0, 8.0], &[]).is_err());
    assert_eq!(det.len(), 3);
    let steps = det.detect_many(&ds, &[6.0, 7.0, 8.0, 9.0], &[]).unwrap();
    assert_eq!(
        steps.iter().map(|s| s.query).collect::<Vec<_>>(),
        [3, 4, 5, 6]
    );
}

#[test]
fn a_prior_map_is_never_excluded_and_candidates_are_ranked() {
    let c = cfg();
    let mut map = Database::new(c).unwrap();
    for i in 0..5 {
        map.add(&desc(&c, i), 3, f64::from(i), Some(pose_at(f64::from(i))))
            .unwrap();
    }
    let dc = DetectorConfig {
        exclude_frames: 50,
        threshold: 0.01,
        top_k: 4,
        ..unverified()
    };
    let mut det = LoopDetector::with_database(map, dc).unwrap();
    assert_eq!((det.session(), det.session_start()), (4, 5));
    // The first scan of the new session sees the whole map although 50 frames are excluded.
    let step = det.detect(&desc(&c, 2), 100.0, None).unwrap();
    assert_eq!((step.query, step.eligible), (5, 5));
    assert_eq!(step.candidates.len(), 4);
    assert_eq!(step.candidates[0].id, 2);
    assert!(step
        .candidates
        .windows(2)
        .all(|w| w[0].distance <= w[1].distance || det.config().rerank));
    assert_eq!(step.accepted.map(|l| l.candidate), Some(2));
    assert_eq!(det.entry(5).0, 4);
    // Its own scans are excluded: the next one sees the map only.
    let step = det.detect(&desc(&c, 2), 101.0, None).unwrap();
    assert_eq!(step.eligible, 5);
    // candidates() is the same search without adding.
    let cands = det.candidates(&desc(&c, 3), 2, 102.0, None).unwrap();
    assert_eq!(cands.len(), 2);
    assert_eq!(cands[0].id, 3);
    assert_eq!(det.len(), 7);
}

#[test]
fn a_config_from_a_preset_gives_the_detector_that_presets_threshold() {
    for p in &solid_lidar::PRESETS {
        let d = DetectorConfig::for_base_preset(Some(p));
        assert_eq!(d.threshold, p.loop_threshold, "{}", p.name);
        assert_eq!(d, DetectorConfig::for_preset(p.name).unwrap());
        // Nothing else depends on the preset.
        let general = DetectorConfig {
            threshold: p.loop_threshold,
            ..DetectorConfig::default()
        };
        assert_eq!(d, general, "{}", p.name);
    }
    // A config made from no preset: the general default (the largest preset threshold).
    let none = DetectorConfig::for_base_preset(None);
    assert_eq!(none, DetectorConfig::default());
    let largest = solid_lidar::PRESETS.iter().map(|p| p.loop_threshold);
    assert_eq!(none.threshold, largest.fold(0.0, f64::max));
    assert_eq!(
        DetectorConfig::for_preset("hdl-64"),
        Err(Error::UnknownPreset)
    );
}
