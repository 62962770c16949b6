//! The database: adding, merging and searching entries, one at a time and in batches.
#![cfg(feature = "std")]

mod common;
use common::db::{cfg, desc, same, sample_arrays, sample_db, unverified};
use common::Xorshift;
use solid_lidar::db::{Database, DbError, LoopDetector, MergeAnchor, Method, SearchOptions};
use solid_lidar::Config;

#[test]
fn merge_appends_and_refuses_other_configs() {
    let mut a = sample_db(20);
    let b = sample_db(13);
    a.merge(&b).unwrap();
    assert_eq!(a.len(), 33);
    assert_eq!(a.r(25), b.r(5));
    assert_eq!(a.sessions()[25], b.sessions()[5]);
    let c = cfg();
    // Entry 5 of b now exists twice (ids 5 and 25): the lower id wins the tie.
    let hits = a.search(&desc(&c, 5).r, 2, 0, Method::KdTree).unwrap();
    assert_eq!(hits.iter().map(|h| h.id).collect::<Vec<_>>(), [5, 25]);
    assert_eq!(hits, a.search(&desc(&c, 5).r, 2, 0, Method::Brute).unwrap());

    let other = Database::new(Config {
        max_range: 40.0,
        ..c
    })
    .unwrap();
    let err = a.merge(&other).unwrap_err();
    assert!(matches!(err, DbError::ConfigMismatch { .. }));
    assert!(err.to_string().contains("config"));
    let foreign = desc(&Config { n_range: 20, ..c }, 1);
    assert!(matches!(
        a.add(&foreign, 0, 0.0, None),
        Err(DbError::ConfigMismatch { .. })
    ));
}

/// A map merged with an anchor carries every pose of the other by `T` (`X ↦ T·X`) and keeps the
/// rest; a transform that is not rigid is refused with nothing changed, the other map untouched.
#[test]
fn merge_with_an_anchor_carries_the_poses_and_refuses_a_non_rigid_one() {
    let c = cfg();
    let pose = |x: f64| [1.0, 0.0, 0.0, x, 0.0, 1.0, 0.0, 2.0, 0.0, 0.0, 1.0, 0.5];
    let mut a = Database::new(c).unwrap();
    a.add(&desc(&c, 1), 3, 1.0, Some(pose(0.0))).unwrap();
    let mut b = Database::new(c).unwrap();
    b.add(&desc(&c, 2), 0, 2.0, Some(pose(1.0))).unwrap();
    b.add(&desc(&c, 3), 0, 3.0, None).unwrap();
    // A quarter turn about z, then 10 m along x.
    let t = [0.0, -1.0, 0.0, 10.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let mut skew = t;
    skew[0] = 0.5;
    assert!(a.merge_with(&b, true, Some(&skew)).is_err());
    assert_eq!(a.len(), 1);
    assert_eq!(a.merge_with(&b, true, Some(&t)).unwrap(), 4);
    let poses = a.poses();
    let moved = poses[1].unwrap();
    let want = [0.0, -1.0, 0.0, 8.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.5];
    assert!(
        moved.iter().zip(want).all(|(x, y)| (x - y).abs() < 1e-12),
        "{moved:?}"
    );
    assert_eq!(poses[2], None);
    assert_eq!(a.sessions(), [3, 4, 4]);
    assert_eq!(a.r(1), b.r(0));
    assert_eq!(b.poses()[0], Some(pose(1.0)));
}

/// A map merged with one anchor per place carries each place's pose by its own transform (a
/// session whose odometry broke: one per stretch), keeps no pose where none is given, and is
/// refused, nothing changed, when the list does not hold one per place or one is not rigid.
#[test]
fn merge_with_one_anchor_per_place_carries_each_by_its_own() {
    let c = cfg();
    let pose = |x: f64| [1.0, 0.0, 0.0, x, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let mut a = Database::new(c).unwrap();
    a.add(&desc(&c, 1), 0, 1.0, Some(pose(0.0))).unwrap();
    let mut b = Database::new(c).unwrap();
    for k in 0..3u32 {
        b.add(
            &desc(&c, 2 + k),
            0,
            2.0 + f64::from(k),
            Some(pose(f64::from(k))),
        )
        .unwrap();
    }
    let shift = |y: f64| [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, y, 0.0, 0.0, 1.0, 0.0];
    let mut skew = shift(0.0);
    skew[0] = 0.5;
    let mut part_nan = shift(1.0);
    part_nan[7] = f64::NAN;
    // Each refusal names what is wrong: both counts, or the place whose transform it is.
    for (bad, says) in [
        (
            vec![Some(shift(1.0)); 2],
            "per-place anchors: 2 given, but the database merged has 3 places",
        ),
        (
            vec![Some(shift(1.0)), Some(skew), None],
            "anchor of place 1: invalid anchor",
        ),
        (
            vec![None, None, Some(part_nan)],
            "anchor of place 2: invalid anchor = NaN: expected finite values",
        ),
    ] {
        let e = a
            .merge_anchored(&b, true, Some(MergeAnchor::PerPlace(&bad)))
            .unwrap_err();
        assert!(e.to_string().starts_with(says), "{e}");
        // A bad transform's error is the one wrapped (its source); a count has none.
        let source = std::error::Error::source(&e).map(|s| s.to_string());
        match &e {
            DbError::BadAnchor { error, .. } => assert_eq!(source, Some(error.to_string())),
            _ => assert_eq!(source, None),
        }
        assert_eq!(a.len(), 1);
    }
    let each = [Some(shift(10.0)), Some(shift(20.0)), None];
    assert_eq!(
        a.merge_anchored(&b, true, Some(MergeAnchor::PerPlace(&each)))
            .unwrap(),
        1
    );
    let poses = a.poses();
    assert_eq!(poses[1].map(|p| (p[3], p[7])), Some((0.0, 10.0)));
    assert_eq!(poses[2].map(|p| (p[3], p[7])), Some((1.0, 20.0)));
    assert_eq!(poses[3], None);
    assert_eq!(a.sessions(), [0, 1, 1, 1]);
    assert_eq!(b.poses()[2], Some(pose(2.0)));
}

#[test]
fn search_options_exclude_recent_and_newer_entries() {
    let db = sample_db(100);
    let c = cfg();
    let q = desc(&c, 99);
    let hits = db.search(&q.r, 100, 30, Method::KdTree).unwrap();
    assert_eq!(hits.len(), 70);
    assert!(hits.iter().all(|h| h.id < 70));
    let opts = SearchOptions {
        k: 100,
        exclude_recent: 0,
        not_newer_than: Some(5.0),
        method: Method::KdTree,
        ..SearchOptions::default()
    };
    let hits = db.search_with(&q.r, &opts).unwrap();
    // Ids with time <= 5.0 (i * 0.1) or without time (every third id).
    let ok = |i: u32| i.is_multiple_of(3) || f64::from(i) * 0.1 <= 5.0;
    assert_eq!(hits.len(), (0..100).filter(|&i| ok(i)).count());
    assert!(hits.iter().all(|h| ok(h.id)));
    assert_eq!(
        hits,
        db.search_with(
            &q.r,
            &SearchOptions {
                method: Method::Brute,
                ..opts
            }
        )
        .unwrap()
    );
    assert!(db.search(&q.r[..5], 1, 0, Method::Auto).is_err());
    assert!(Method::parse("kd").is_err());
}

#[test]
fn batch_add_equals_adding_one_by_one() {
    let n = 700;
    let (r, a, t, p) = sample_arrays(n);
    let c = cfg();
    let mut one = Database::new(c).unwrap();
    for i in 0..n as usize {
        let (nr, na) = (c.n_range, c.n_azimuth);
        one.add_vectors(&r[i * nr..][..nr], &a[i * na..][..na], 3, t[i], Some(p[i]))
            .unwrap();
    }
    // Two batches, the second without the kd-tree until build_index.
    let mut batch = Database::new(c).unwrap();
    let split = 300 * c.n_range;
    let split_a = 300 * c.n_azimuth;
    assert_eq!(
        batch
            .add_batch(
                &r[..split],
                &a[..split_a],
                3,
                Some(&t[..300]),
                Some(&p[..300]),
                true
            )
            .unwrap(),
        0
    );
    assert_eq!(
        batch
            .add_batch(
                &r[split..],
                &a[split_a..],
                3,
                Some(&t[300..]),
                Some(&p[300..]),
                false
            )
            .unwrap(),
        300
    );
    same(&one, &batch);
    let q = desc(&c, 12345);
    for method in [Method::Brute, Method::KdTree, Method::Sketch, Method::Auto] {
        for k in [1, 7, 700] {
            let want = one.search(&q.r, k, 20, Method::Brute).unwrap();
            assert_eq!(
                batch.search(&q.r, k, 20, method).unwrap(),
                want,
                "{method:?}"
            );
        }
    }
    batch.build_index().unwrap();
    same(&one, &batch);
    assert_eq!(one.to_bytes().unwrap(), batch.to_bytes().unwrap());
    // A batch with one bad value adds nothing.
    let mut bad = r[..2 * c.n_range].to_vec();
    bad[c.n_range + 3] = f32::NAN;
    assert!(batch
        .add_batch(&bad, &a[..2 * c.n_azimuth], 0, None, None, true)
        .is_err());
    assert!(batch
        .add_batch(&r[..c.n_range], &a[..1], 0, None, None, true)
        .is_err());
    assert!(batch
        .add_batch(
            &r[..c.n_range],
            &a[..c.n_azimuth],
            0,
            Some(&[1.0, 2.0]),
            None,
            true
        )
        .is_err());
    let mut skew = p[0];
    skew[1] = 0.5;
    assert!(batch
        .add_batch(
            &r[..c.n_range],
            &a[..c.n_azimuth],
            0,
            None,
            Some(&[skew]),
            true
        )
        .is_err());
    same(&one, &batch);
}

#[test]
fn batch_search_equals_one_search_per_query() {
    let db = sample_db(900);
    let c = cfg();
    let queries: Vec<f32> = (0..50).flat_map(|i| desc(&c, 2000 + i * 37).r).collect();
    for method in [Method::Brute, Method::KdTree, Method::Sketch, Method::Auto] {
        for (k, exclude_recent, not_newer_than, max_distance) in [
            (1, 0, None, f32::INFINITY),
            (10, 100, Some(40.0), f32::INFINITY),
            (5, 0, None, 0.2),
            (0, 0, None, f32::INFINITY),
        ] {
            let opts = SearchOptions {
                k,
                exclude_recent,
                not_newer_than,
                max_distance,
                method,
            };
            let got = db.search_batch(&queries, &opts).unwrap();
            assert_eq!(got.k, k);
            assert_eq!(got.ids.len(), 50 * k);
            for (i, q) in queries.chunks_exact(c.n_range).enumerate() {
                let want = db.search_with(q, &opts).unwrap();
                assert_eq!(
                    got.neighbors(i).collect::<Vec<_>>(),
                    want,
                    "{method:?} k {k}"
                );
            }
        }
    }
    assert!(db
        .search_batch(&queries[..c.n_range + 1], &SearchOptions::default())
        .is_err());
    let mut nan = queries.clone();
    nan[5] = f32::NAN;
    assert!(db.search_batch(&nan, &SearchOptions::default()).is_err());
}

#[test]
fn entries_take_at_most_300_bytes_and_a_solid_is_kept_to_half_a_step() {
    // The avia preset: 40 range bins, 60 azimuth bins.
    let c = Config::preset("avia").unwrap();
    let n = 10_000u32;
    let (mut r, mut a) = (Vec::new(), Vec::new());
    for i in 0..n {
        let d = desc(&c, i);
        r.extend_from_slice(&d.r);
        a.extend_from_slice(&d.a);
    }
    let mut db = Database::new(c).unwrap();
    db.add_batch(&r, &a, 0, None, None, true).unwrap();
    let per_entry = db.memory_bytes() as f64 / f64::from(n);
    assert!(per_entry <= 300.0, "{per_entry} bytes per entry");
    for i in [0u32, 17, 9999] {
        let want = &a[i as usize * c.n_azimuth..][..c.n_azimuth];
        let step = want.iter().fold(0.0f32, |m, v| m.max(v.abs())) / 255.0;
        for (got, want) in db.a(i).iter().zip(want) {
            assert!((got - want).abs() <= 0.5 * step * 1.0001, "{got} vs {want}");
        }
        assert_eq!(db.r(i), &r[i as usize * c.n_range..][..c.n_range]);
    }
    // Negative values (what no descriptor holds) are refused, in a batch too, and nothing is added.
    let signed: Vec<f32> = (0..c.n_azimuth).map(|j| j as f32 - 30.0).collect();
    assert!(db
        .add_vectors(&r[..c.n_range], &signed, 0, f64::NAN, None)
        .is_err());
    let mut two = a[..2 * c.n_azimuth].to_vec();
    two[c.n_azimuth + 3] = -1.0;
    assert!(db
        .add_batch(&r[..2 * c.n_range], &two, 0, None, None, true)
        .is_err());
    assert_eq!(db.len(), n as usize);
    // Saving writes the A-SOLiDs as stored: loading and saving again gives the same bytes.
    let bytes = db.to_bytes().unwrap();
    assert_eq!(
        Database::from_bytes(&bytes).unwrap().to_bytes().unwrap(),
        bytes
    );
}

#[test]
fn a_bad_value_deep_in_a_large_batch_leaves_the_database_as_it_was() {
    let c = cfg();
    let (nr, na) = (c.n_range, c.n_azimuth);
    let (r, a, _, _) = sample_arrays(5000);
    // Five entries first, so that the batch starts inside a block of the sketch.
    let mut db = Database::new(c).unwrap();
    db.add_batch(&r[..5 * nr], &a[..5 * na], 0, None, None, true)
        .unwrap();
    let before = db.to_bytes().unwrap();
    for (which, at) in [("r", 4000 * nr + 7), ("a", 3000 * na + 1)] {
        let (mut rb, mut ab) = (r.clone(), a.clone());
        match which {
            "r" => rb[at] = f32::INFINITY,
            _ => ab[at] = f32::NAN,
        }
        assert!(
            db.add_batch(&rb, &ab, 1, None, None, true).is_err(),
            "{which}"
        );
        assert_eq!(db.to_bytes().unwrap(), before, "{which}");
    }
    // The database still works as if the failed batches never happened.
    db.add_batch(&r[5 * nr..], &a[5 * na..], 0, None, None, false)
        .unwrap();
    let mut one = Database::new(c).unwrap();
    for i in 0..5000 {
        one.add_vectors(&r[i * nr..][..nr], &a[i * na..][..na], 0, f64::NAN, None)
            .unwrap();
    }
    same(&one, &db);
    let q = desc(&c, 777);
    for method in [Method::Brute, Method::Sketch, Method::Auto] {
        assert_eq!(
            db.search(&q.r, 5, 0, method).unwrap(),
            one.search(&q.r, 5, 0, Method::Brute).unwrap()
        );
    }
}

#[test]
fn batch_add_with_a_range_count_that_is_not_a_multiple_of_four() {
    // The sketch pads each row's codes to groups of four values.
    let c = Config {
        n_range: 21,
        ..cfg()
    };
    let (nr, na) = (c.n_range, c.n_azimuth);
    let n = 3000;
    let (r, a): (Vec<f32>, Vec<f32>) =
        (0..n as u32)
            .map(|i| desc(&c, i))
            .fold((Vec::new(), Vec::new()), |(mut r, mut a), d| {
                r.extend_from_slice(&d.r);
                a.extend_from_slice(&d.a);
                (r, a)
            });
    let mut batch = Database::new(c).unwrap();
    batch
        .add_batch(&r[..7 * nr], &a[..7 * na], 0, None, None, true)
        .unwrap();
    batch
        .add_batch(&r[7 * nr..], &a[7 * na..], 0, None, None, true)
        .unwrap();
    let mut one = Database::new(c).unwrap();
    for i in 0..n {
        one.add_vectors(&r[i * nr..][..nr], &a[i * na..][..na], 0, f64::NAN, None)
            .unwrap();
    }
    for s in [5u32, 6000, 6001] {
        let q = desc(&c, s);
        let want = one.search(&q.r, 9, 0, Method::Brute).unwrap();
        for method in [Method::Brute, Method::KdTree, Method::Sketch, Method::Auto] {
            assert_eq!(
                batch.search(&q.r, 9, 0, method).unwrap(),
                want,
                "{method:?}"
            );
            assert_eq!(one.search(&q.r, 9, 0, method).unwrap(), want, "{method:?}");
        }
    }
}

/// A stored R-SOLiD so small that `1 / ‖r‖` overflows `f32` (subnormal values: nothing a scan
/// gives, but nothing refuses it either) is treated as all-zero: at distance 1 from every query,
/// never NaN, the same for every method.
#[test]
fn a_vanishingly_small_descriptor_is_at_distance_one() {
    let c = cfg();
    let na = c.n_azimuth;
    let mut db = Database::new(c).unwrap();
    for i in 0..3000u32 {
        let d = desc(&c, i);
        let mut r = d.r.clone();
        if i % 1000 == 7 {
            // ‖r‖ ≈ 6e-40: its products with a query's values are subnormal, not zero.
            r.fill(1e-40);
        }
        db.add_vectors(&r, &d.a[..na], 0, f64::NAN, None).unwrap();
    }
    for s in [5u32, 1007, 9000] {
        let q = desc(&c, s);
        let all = db.search(&q.r, 3000, 0, Method::Brute).unwrap();
        assert!(all.iter().all(|n| n.distance.is_finite()));
        assert!(all
            .iter()
            .filter(|n| n.id % 1000 == 7)
            .all(|n| n.distance == 1.0));
        let want = db.search(&q.r, 9, 0, Method::Brute).unwrap();
        for method in [Method::KdTree, Method::Sketch, Method::Auto] {
            assert_eq!(db.search(&q.r, 9, 0, method).unwrap(), want, "{method:?}");
        }
    }
}

#[test]
fn every_way_of_growing_a_database_searches_as_brute_force() {
    // 20 entries leave the sketch's second block partly filled; whatever follows (a merge, a
    // bulk add that only stores, then the index built) must not take the block's empty lanes
    // for entries.
    let c = cfg();
    let (nr, na) = (c.n_range, c.n_azimuth);
    let check = |db: &Database, what: &str| {
        for s in [3u32, 21, 40, 1000] {
            let q = desc(&c, s);
            let want = db.search(&q.r, 7, 0, Method::Brute).unwrap();
            for method in [Method::Sketch, Method::KdTree, Method::Auto] {
                assert_eq!(
                    db.search(&q.r, 7, 0, method).unwrap(),
                    want,
                    "{what}, {method:?}"
                );
            }
        }
    };
    let mut merged = sample_db(20);
    merged.merge(&sample_db(13)).unwrap();
    check(&merged, "merged");

    let (r, a, _, _) = sample_arrays(90);
    let mut db = Database::new(c).unwrap();
    db.add_batch(&r[..20 * nr], &a[..20 * na], 0, None, None, true)
        .unwrap();
    db.add_batch(&r[20 * nr..], &a[20 * na..], 0, None, None, false)
        .unwrap();
    check(&db, "stored only");
    let stored = db.memory_bytes();
    db.build_index().unwrap();
    check(&db, "index built");
    // Storing only held no room for the index of the new entries: building it takes more.
    assert!(db.memory_bytes() > stored);
}

fn growth_cfg() -> Config {
    Config::preset("hdl64").unwrap()
}

/// Clustered rows: 8 centres, small noise.
fn clustered_arrays(n: usize, seed: u64) -> (Vec<f32>, Vec<f32>) {
    let c = growth_cfg();
    let mut g = Xorshift(seed | 1);
    let centres: Vec<Vec<f32>> = (0..8)
        .map(|_| (0..c.n_range).map(|_| (g.next() * 100.0) as f32).collect())
        .collect();
    let mut r = Vec::new();
    let mut a = Vec::new();
    for i in 0..n {
        let ce = &centres[i % 8];
        r.extend(ce.iter().map(|&v| v + (g.next() * 3.0) as f32));
        a.extend((0..c.n_azimuth).map(|_| (g.next() * 10.0) as f32));
    }
    (r, a)
}

/// Sketch, kd-tree and auto give brute force's neighbours for queries next to every 7th entry
/// and to those around the first block boundaries.
fn check_methods(db: &Database, what: &str) {
    let nr = db.config().n_range;
    let n = db.len();
    let mut ids: Vec<usize> = (0..n).step_by(7).collect();
    ids.extend([n.saturating_sub(1), n / 2, 16, 17, 20, 31, 32, 33]);
    for &i in ids.iter().filter(|&&i| i < n) {
        let q: Vec<f32> = db.r(i as u32)[..nr].iter().map(|v| v * 1.001).collect();
        for k in [1usize, 5, 40] {
            for ex in [0usize, 3] {
                let want = db.search(&q, k, ex, Method::Brute).unwrap();
                for m in [Method::Sketch, Method::KdTree, Method::Auto] {
                    assert_eq!(
                        db.search(&q, k, ex, m).unwrap(),
                        want,
                        "{what}: q{i} k{k} ex{ex} {m:?}"
                    );
                }
            }
        }
    }
}

/// (From a second read of the stored-only add.) Stored-only adds of partial blocks, single and
/// failed adds after them, an empty batch, a large indexed add from a partial block (the chunked
/// path on several threads), merges and a load of databases with a stored-only tail.
#[test]
fn growth_through_every_path_and_block_boundary_searches_as_brute_force() {
    let c = growth_cfg();
    let (nr, na) = (c.n_range, c.n_azimuth);
    let (r, a) = clustered_arrays(5000, 7);
    // Adds entries `x..y` in one batch, with or without the index.
    let add = |db: &mut Database, x: usize, y: usize, index: bool| {
        db.add_batch(&r[x * nr..y * nr], &a[x * na..y * na], 0, None, None, index)
            .unwrap()
    };
    let add_one = |db: &mut Database, x: usize| {
        db.add_vectors(&r[x * nr..][..nr], &a[x * na..][..na], 0, f64::NAN, None)
            .unwrap()
    };

    // indexed 20, stored 13, single add, stored 2100, single add
    let mut db = Database::new(c).unwrap();
    add(&mut db, 0, 20, true);
    add(&mut db, 20, 33, false);
    check_methods(&db, "20+13 stored");
    add_one(&mut db, 33);
    check_methods(&db, "20+13 stored + single");
    add(&mut db, 34, 2134, false);
    check_methods(&db, "+2100 stored");
    // a failing add (bad value) after a stored-only add
    let mut bad = r[2134 * nr..2136 * nr].to_vec();
    bad[nr + 1] = f32::NAN;
    assert!(db
        .add_batch(&bad, &a[2134 * na..2136 * na], 0, None, None, true)
        .is_err());
    assert!(db
        .add_batch(&bad, &a[2134 * na..2136 * na], 0, None, None, false)
        .is_err());
    check_methods(&db, "after failed adds");
    add_one(&mut db, 2134);
    check_methods(&db, "+single after 2100 stored");
    // empty stored-only batch
    db.add_batch(&[], &[], 0, None, None, false).unwrap();
    check_methods(&db, "empty stored");
    db.build_index().unwrap();
    check_methods(&db, "built");

    // indexed 20 then a big indexed add (large extend path from an unaligned sketch)
    let mut big = Database::new(c).unwrap();
    add(&mut big, 0, 20, true);
    add(&mut big, 20, 2500, true);
    check_methods(&big, "20 + 2480 indexed");
    // merge of a db with a stored-only tail into one with a partial block
    let mut tail = Database::new(c).unwrap();
    add(&mut tail, 2500, 2530, true);
    add(&mut tail, 2530, 4700, false);
    check_methods(&tail, "tail stored");
    let mut m = Database::new(c).unwrap();
    add(&mut m, 4700, 4721, true);
    m.merge(&tail).unwrap();
    check_methods(&m, "merged");
    let back = Database::from_bytes(&tail.to_bytes().unwrap()).unwrap();
    check_methods(&back, "from bytes");
    m.merge_as_new_sessions(&back).unwrap();
    check_methods(&m, "merged as new sessions");
}

/// After a stored-only bulk add, `index_due` waits until the searches have scanned the entries
/// beyond the index `INDEX_AFTER_PASSES` times the rows a build would index: searches by brute
/// force and `auto` over few entries use no index and count nothing, a batch counts each of its
/// queries, excluded entries are not scanned, and a build starts the count again.
#[test]
fn the_index_is_due_when_the_searches_have_scanned_what_building_costs() {
    use solid_lidar::db::INDEX_AFTER_PASSES;
    let c = growth_cfg();
    let (nr, na) = (c.n_range, c.n_azimuth);
    let (r, a) = clustered_arrays(3000, 11);
    let opts = |method, exclude_recent| SearchOptions {
        method,
        exclude_recent,
        ..SearchOptions::default()
    };
    let auto = opts(Method::Auto, 0);
    let q = &r[5 * nr..6 * nr];

    let mut db = Database::new(c).unwrap();
    db.add_batch(&r[..1000 * nr], &a[..1000 * na], 0, None, None, true)
        .unwrap();
    assert_eq!(db.index_pending(), 0);
    assert!(!db.index_due(&auto, usize::MAX), "nothing pending");
    db.add_batch(&r[1000 * nr..], &a[1000 * na..], 0, None, None, false)
        .unwrap();
    // The sketch was cut back to its whole blocks of 16: entries 992.. are beyond it.
    let pending = 3000 - 992;
    assert_eq!(db.index_pending(), pending);
    // From 1,000 entries to 3,000 the kd-tree rebuilds every block: the blocks over 3,000
    // (ids 0..2048, 2048..2560, ...) are none of those over 1,000 (0..512, 512..768, ...).
    let build = solid_lidar::search::online_extend_rows(3000, 1000);
    assert_eq!(build, 3000);
    let passes = (INDEX_AFTER_PASSES * build).div_ceil(pending);
    let brute = opts(Method::Brute, 0);
    for _ in 0..passes {
        db.search_with(q, &brute).unwrap();
    }
    assert!(
        !db.index_due(&brute, usize::MAX),
        "brute force uses no index"
    );
    assert!(!db.index_due(&auto, passes - 1), "brute force counted");
    assert!(db.index_due(&auto, passes), "a batch counts each query");
    for i in 0..passes - 1 {
        assert!(!db.index_due(&auto, 1), "due after {i} searches");
        let found = db.search_with(q, &auto).unwrap();
        assert_eq!(found, db.search_with(q, &brute).unwrap());
    }
    assert!(db.index_due(&auto, 1));
    // A search for no neighbour scans nothing.
    let none = SearchOptions {
        k: 0,
        ..SearchOptions::default()
    };
    db.search_with(q, &none).unwrap();
    assert!(!db.index_due(&none, usize::MAX));
    // Excluding the 1,990 newest entries leaves 18 beyond the index to scan: a cheap search.
    assert!(!db.index_due(&opts(Method::Auto, 1990), 1));
    // The kd-tree's and the sketch's plans scan the rows beyond them too.
    assert!(db.index_due(&opts(Method::KdTree, 0), 1));
    assert!(db.index_due(&opts(Method::Sketch, 0), 1));
    db.build_index().unwrap();
    assert_eq!(db.index_pending(), 0);
    assert!(!db.index_due(&auto, usize::MAX));

    // A batch's queries count, and a build starts the count again.
    db.add_batch(&r[..10 * nr], &a[..10 * na], 0, None, None, false)
        .unwrap();
    let queries: Vec<f32> = r[..4 * nr].to_vec();
    let before = db.index_due(&auto, 1);
    db.search_batch(&queries, &auto).unwrap();
    assert!(!before);
    // From 3,000 to 3,010 it rebuilds 2944..3008 and 3008..3010.
    let build = solid_lidar::search::online_extend_rows(3010, 3000);
    assert_eq!(build, 66);
    // The sketch was cut back to 2,992 entries: 18 beyond the index.
    assert_eq!(db.index_pending(), 18);
    let need = (INDEX_AFTER_PASSES * build).div_ceil(18);
    assert!(db.index_due(&auto, need - 4) && !db.index_due(&auto, need - 5));

    // `auto` over fewer than 256 entries computes every distance: never due.
    let mut small = Database::new(c).unwrap();
    small
        .add_batch(&r[..200 * nr], &a[..200 * na], 0, None, None, false)
        .unwrap();
    assert_eq!(small.index_pending(), 200);
    assert!(!small.index_due(&auto, usize::MAX));
    assert!(small.index_due(&opts(Method::KdTree, 0), usize::MAX));

    // A detector searches on every step: it builds a pending index first.
    let det = LoopDetector::with_database(small, unverified()).unwrap();
    assert_eq!(det.map().index_pending(), 0);
}
