//! The index policy of bulk adds: the searches build the index when it is due, and only when the
//! last bulk add left it to them.
#![cfg(feature = "std")]

mod common;
use common::Xorshift;
use solid_lidar::db::{Database, IndexPolicy, Method, SearchOptions};
use solid_lidar::Config;

/// `n` rows of R-SOLiDs and A-SOLiDs.
fn arrays(cfg: &Config, n: usize, seed: u64) -> (Vec<f32>, Vec<f32>) {
    let mut g = Xorshift(seed | 1);
    let r = (0..n * cfg.n_range).map(|_| (g.next() * 100.0) as f32);
    let r = r.collect();
    let a = (0..n * cfg.n_azimuth).map(|_| (g.next() * 10.0) as f32);
    (r, a.collect())
}

/// A database of 1,000 indexed entries and 2,000 added with `policy`.
fn grown(policy: IndexPolicy) -> (Database, Vec<f32>) {
    let cfg = Config::preset("hdl64").unwrap();
    let (nr, na) = (cfg.n_range, cfg.n_azimuth);
    let (r, a) = arrays(&cfg, 3000, 7);
    let mut db = Database::new(cfg).unwrap();
    db.add_batch_with(
        &r[..1000 * nr],
        &a[..1000 * na],
        0,
        None,
        None,
        IndexPolicy::Now,
    )
    .unwrap();
    assert_eq!(db.index_pending(), 0);
    db.add_batch_with(&r[1000 * nr..], &a[1000 * na..], 0, None, None, policy)
        .unwrap();
    (db, r[5 * nr..6 * nr].to_vec())
}

fn auto() -> SearchOptions {
    SearchOptions {
        method: Method::Auto,
        ..SearchOptions::default()
    }
}

fn brute() -> SearchOptions {
    SearchOptions {
        method: Method::Brute,
        ..SearchOptions::default()
    }
}

#[test]
fn a_bulk_add_with_now_indexes_every_entry() {
    let (db, _) = grown(IndexPolicy::Now);
    assert_eq!(db.index_pending(), 0);
    assert!(!db.index_by_searches());
}

/// The searches build the index exactly when `index_due` says so, and stay exact before.
#[test]
fn the_searches_build_the_index_when_it_is_due() {
    let (mut db, q) = grown(IndexPolicy::BySearches);
    assert!(db.index_by_searches());
    let pending = db.index_pending();
    assert!(pending > 0);
    let mut searches = 0;
    while db.index_pending() > 0 {
        let due = db.index_due(&auto(), 1);
        assert_eq!(db.search_builds_index(&auto(), 1), due);
        db.build_index_for_search(&auto(), 1);
        assert_eq!(db.index_pending() == 0, due, "after {searches} searches");
        let found = db.search_with(&q, &auto()).unwrap();
        assert_eq!(found, db.search_with(&q, &brute()).unwrap());
        searches += 1;
        assert!(searches < 10_000, "the index never became due");
    }
    assert!(searches > 1, "built before the searches paid for it");
    // Nothing pending: nothing to build.
    assert!(!db.search_builds_index(&auto(), usize::MAX));
}

/// Searches that scan nothing beyond the index (brute force) never build it.
#[test]
fn brute_force_searches_do_not_build_the_index() {
    let (mut db, q) = grown(IndexPolicy::BySearches);
    let pending = db.index_pending();
    for _ in 0..200 {
        db.build_index_for_search(&brute(), 1);
        db.search_with(&q, &brute()).unwrap();
    }
    assert_eq!(db.index_pending(), pending);
}

/// Left on request, the index waits for `build_index` however much the searches scan; the last
/// bulk add decides.
#[test]
fn the_last_bulk_add_decides_who_builds_the_index() {
    let (mut db, q) = grown(IndexPolicy::OnRequest);
    assert!(!db.index_by_searches());
    let pending = db.index_pending();
    db.build_index_for_search(&auto(), usize::MAX);
    assert_eq!(db.index_pending(), pending);
    let mut searches = 0;
    while !db.index_due(&auto(), 1) {
        db.build_index_for_search(&auto(), 1);
        db.search_with(&q, &auto()).unwrap();
        searches += 1;
        assert!(searches < 10_000, "the index never became due");
    }
    assert!(!db.search_builds_index(&auto(), 1));
    db.build_index_for_search(&auto(), 1);
    assert_eq!(db.index_pending(), pending);

    // Another bulk add that leaves it to the searches takes every waiting entry with it.
    let cfg = *db.config();
    let (r, a) = arrays(&cfg, 10, 11);
    db.add_batch_with(&r, &a, 0, None, None, IndexPolicy::BySearches)
        .unwrap();
    assert!(db.search_builds_index(&auto(), usize::MAX));
    db.build_index_for_search(&auto(), usize::MAX);
    assert_eq!(db.index_pending(), 0);

    // A refused add changes nothing, the policy included.
    let (mut db, _) = grown(IndexPolicy::BySearches);
    let len = db.len();
    assert!(db
        .add_batch_with(&r[1..], &a, 0, None, None, IndexPolicy::OnRequest)
        .is_err());
    assert_eq!(db.len(), len);
    assert!(db.index_by_searches());
}

#[test]
fn a_loaded_map_is_indexed_by_its_kd_tree_alone_unless_asked() {
    let (db, _) = grown(IndexPolicy::Now);
    let cfg = *db.config();
    let mut loaded = Database::from_bytes(&db.to_bytes().unwrap()).unwrap();
    assert!(db.has_sketch() && !loaded.has_sketch());
    assert_eq!(loaded.index_pending(), db.len());
    let before = loaded.memory_bytes();
    loaded.build_index().unwrap();
    assert_eq!(loaded.index_pending(), 0);
    let tree = loaded.memory_bytes() - before;
    // Stored places and others: the same neighbours with every method, sketch or none.
    let (others, _) = arrays(&cfg, 4, 99);
    let (stored, _) = arrays(&cfg, 3000, 7);
    let queries: Vec<&[f32]> = others
        .chunks_exact(cfg.n_range)
        .chain(stored.chunks_exact(cfg.n_range).step_by(700))
        .collect();
    let same = |loaded: &Database| {
        for q in &queries {
            for method in [Method::Brute, Method::KdTree, Method::Sketch, Method::Auto] {
                let opts = SearchOptions {
                    k: 5,
                    method,
                    ..SearchOptions::default()
                };
                let want = db.search_with(q, &opts).unwrap();
                assert_eq!(loaded.search_with(q, &opts).unwrap(), want, "{method:?}");
            }
        }
    };
    same(&loaded);
    // Asked for, the sketch is built by the next build, and dropped when turned off again.
    loaded.set_sketch(true);
    assert_eq!(loaded.index_pending(), db.len());
    loaded.build_index().unwrap();
    assert_eq!(loaded.index_pending(), 0);
    assert!(loaded.memory_bytes() - before >= tree + db.len() * cfg.n_range);
    same(&loaded);
    loaded.set_sketch(false);
    assert_eq!(loaded.memory_bytes(), before + tree);
    same(&loaded);
}
