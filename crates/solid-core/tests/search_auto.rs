//! The automatic plan: which paths it takes, when it skips a failing step and tries it again,
//! and that it stays exact throughout (docs/spec.md §3).

mod common;
use common::search::{brute, check_index, normed, places, Built, Rng};

use solid_lidar::search::{
    auto_tree_row_cost, Cost, Exclude, Neighbor, Observed, Request, Rows, AUTO_MISSES,
    AUTO_PRIME_BASE, AUTO_PRIME_PER_K, AUTO_RETRY_EVERY, AUTO_RETRY_MAX, LEAF_SIZE,
};

/// Whether [`Observed`] tries a skipped sketch again on query `i` when it failed on the first
/// [`AUTO_MISSES`] queries and fails on every retry: its documented schedule, written out here on
/// its own (16, 32, 64, 128, then every 128th).
fn retried(i: u32) -> bool {
    if i < AUTO_RETRY_MAX {
        i >= AUTO_RETRY_EVERY && i.is_power_of_two()
    } else {
        i.is_multiple_of(AUTO_RETRY_MAX)
    }
}

/// Whether [`Observed`] tries a skipped deep walk again on query `i` while the sketch keeps
/// failing: three quarters of the way between the sketch's retries (12, 24, 48, 96, then 128
/// later each time).
fn deep_retried(i: u32) -> bool {
    let last = AUTO_RETRY_MAX / 4 * 3;
    if i < last {
        i >= AUTO_RETRY_EVERY / 4 * 3 && i.is_multiple_of(3) && (i / 3).is_power_of_two()
    } else {
        i % AUTO_RETRY_MAX == last
    }
}

#[test]
fn auto_tries_a_failing_step_again_less_and_less_often() {
    // Near-duplicates (one place under 0.1 % noise): the normal walk runs out and the sketch
    // gives up on every query, and the deep walk runs out too. Over 1,100 queries the sketch
    // runs on the first AUTO_MISSES and on its retries, the deep walk on a few queries until its
    // cost is known and then on its retries: the schedules `retried` and `deep_retried` spell out.
    let (n, dim) = (2_000, 24);
    let rows = places(n, dim, 1, 1e-3, &mut Rng(21));
    let q = places(1, dim, 1, 0.0, &mut Rng(21));
    let rows = Rows::normalized(&rows, dim).unwrap();
    let costs = observed_costs(rows, &q, 1, 1_100);
    let (mut sketched, mut deep) = (vec![], vec![]);
    for (i, c) in (0..).zip(&costs) {
        if c.sketch_rows > 0 {
            sketched.push(i);
        } else if c.tree_rows > 0 && i >= 2 * AUTO_MISSES {
            deep.push(i);
        }
    }
    assert_eq!(
        sketched,
        [0, 1, 2, 3, 16, 32, 64, 128, 256, 384, 512, 640, 768, 896, 1024]
    );
    assert_eq!(deep, [12, 24, 48, 96, 224, 352, 480, 608, 736, 864, 992]);
    let upto = |f: fn(u32) -> bool| (0..1_100).filter(|&i| f(i)).collect::<Vec<u32>>();
    assert_eq!(upto(retried), sketched[AUTO_MISSES as usize..]);
    assert_eq!(upto(deep_retried), deep);
}

#[test]
fn auto_comes_back_to_the_kd_tree_when_the_queries_change() {
    // 10,000 near-duplicates of one place and 30,000 rows around 3,000 other places. Queries of
    // the near-duplicated place first: the sketch gives up and the deep walk runs out, so brute
    // force soon runs alone, its retries spaced out to AUTO_RETRY_MAX. Then queries of the other
    // places, whose walks finish: the first retry of the deep walk, under half a pass, starts
    // the average of the deep walk's cost again from its cost, and the kd-tree is back (a
    // review's probe of this counted 1,652 queries of brute force alone before that, with
    // retries every 256th query and the average falling an eighth at a time; without the new
    // start, 394 of these 400 here). The results never change.
    let dim = 24;
    let mut data = places(10_000, dim, 1, 1e-3, &mut Rng(31));
    let dup = places(1, dim, 1, 0.0, &mut Rng(31));
    let others = places(30_000, dim, 3_000, 0.05, &mut Rng(32));
    data.extend_from_slice(&others);
    let rows = Rows::normalized(&data, dim).unwrap();
    let built = Built::of(rows);
    let index = built.index(rows);
    let observed = Observed::new();
    let search = |q: &[f32]| {
        let req = Request {
            observed: Some(&observed),
            ..Request::nearest(1)
        };
        let mut out = [Neighbor::default()];
        let found = index.search(q, &req, &mut out).unwrap();
        assert_eq!(&out[..], &brute(rows, q, 1, &Exclude::NONE)[..]);
        found.cost
    };
    for _ in 0..300 {
        search(&dup);
    }
    let walked: Vec<bool> = (0..400)
        .map(|i| search(&others[(i * 997 % 30_000) * dim..][..dim]).tree_rows > 0)
        .collect();
    let alone = walked.iter().filter(|w| !**w).count();
    assert!(
        alone <= AUTO_RETRY_MAX as usize,
        "{alone} queries of brute force alone"
    );
    assert!(
        walked[walked.len() - 100..].iter().all(|w| *w),
        "{walked:?}"
    );
}

/// The costs of `queries` searches of `q` with [`Plan::Auto`] sharing one [`Observed`], each
/// checked equal to brute force.
fn observed_costs(rows: Rows<'_>, q: &[f32], k: usize, queries: u32) -> Vec<Cost> {
    let built = Built::of(rows);
    let index = built.index(rows);
    let observed = Observed::new();
    let want = brute(rows, q, k, &Exclude::NONE);
    (0..queries)
        .map(|i| {
            let req = Request {
                observed: Some(&observed),
                ..Request::nearest(k)
            };
            let mut out = vec![Neighbor::default(); k];
            let found = index.search(q, &req, &mut out).unwrap();
            assert_eq!(out, want, "query {i}");
            found.cost
        })
        .collect()
}

#[test]
fn auto_takes_each_path_and_stays_exact() {
    let (n, dim) = (6000, 24);
    let mut rng = Rng(12);
    // Revisits: the query is a noisy copy of a stored place; the tree finishes within budget.
    let rows = places(n, dim, 300, 0.05, &mut Rng(11));
    let q = places(1, dim, 1, 0.0, &mut Rng(11));
    for k in [1, 5] {
        let cost = check_index(Rows::normalized(&rows, dim).unwrap(), &q, k, &Exclude::NONE);
        assert!(cost.tree_rows > 0 && cost.sketch_rows == 0, "{cost:?}");
    }
    // A novel place among unstructured rows: the tree gives up and the sketch rules out almost
    // every row from its bytes.
    let rows = places(n, dim, n, 0.0, &mut rng);
    let q = places(1, dim, 1, 0.0, &mut rng);
    for k in [1, 5] {
        let ex = Exclude::recent(n, 100);
        let cost = check_index(Rows::normalized(&rows, dim).unwrap(), &q, k, &ex);
        assert!(cost.tree_rows > 0, "{cost:?}");
        assert_eq!(cost.sketch_rows, n - 100, "{cost:?}");
        assert!(cost.exact_rows < n / 20, "{cost:?}");
    }
    // Near-duplicates: one place under 0.1 % noise, a query beside it; the bytes cannot tell the
    // rows apart, so brute force takes over after the first check.
    let rows = places(n, dim, 1, 1e-3, &mut Rng(13));
    let q = places(1, dim, 1, 0.0, &mut Rng(13));
    let rows = Rows::normalized(&rows, dim).unwrap();
    let cost = check_index(rows, &q, 3, &Exclude::NONE);
    assert!(
        cost.sketch_rows < n / 2 && cost.exact_rows >= n / 2,
        "{cost:?}"
    );
    // Observed over many queries: the sketch that keeps giving up is skipped and the kd-tree
    // walks deeper instead; a deep walk that keeps running out of budget (each then costs its
    // budget, two passes of brute force at first and one on a retry, and the pass that
    // follows) is skipped too, within a
    // few queries (brute force alone). Each is tried again less and less often while it keeps
    // failing (retried, deep_retried); the results do not change.
    for (i, c) in (0..).zip(observed_costs(rows, &q, 3, 100)) {
        let sketch = i < AUTO_MISSES || retried(i);
        assert_eq!(c.sketch_rows > 0, sketch, "query {i}: {c:?}");
        let deep = !sketch && c.tree_rows > 0;
        if i == AUTO_MISSES || deep_retried(i) {
            assert!(deep, "query {i}: {c:?}");
        }
        if i >= 2 * AUTO_MISSES && !deep_retried(i) && !sketch {
            assert!(!deep, "query {i}: {c:?}");
        }
        if deep {
            // Deeper than the normal budget allows, out of budget, then brute force.
            assert!(
                c.tree_rows > n / 16 && c.exact_rows == n,
                "query {i}: {c:?}"
            );
        }
    }
    // Near-duplicates the kd-tree can still tell apart with a deeper walk: once the sketch is
    // skipped, the deep walk finishes, cheaper than brute force, which is not needed.
    // (One place moved along two directions: rows that differ in two dimensions only.)
    let mut rng = Rng(14);
    let moved = Moved::new(dim, 2, &mut rng);
    let rows = moved.rows(n, &mut rng);
    let q = moved.at(&[0.3, 0.6]);
    let rows = Rows::normalized(&rows, dim).unwrap();
    let mut deep_finished = 0;
    for (i, c) in (0..).zip(observed_costs(rows, &q, 1, AUTO_RETRY_EVERY)) {
        if i < AUTO_MISSES {
            // The normal walk ran out of budget and the sketch gave up.
            assert!(
                c.sketch_rows > 0 && c.exact_rows > n / 2,
                "query {i}: {c:?}"
            );
        } else if c.sketch_rows == 0 && c.exact_rows == 0 && c.tree_rows > n / 16 {
            // Deeper than the normal budget allows, and finished.
            deep_finished += 1;
        }
    }
    assert_eq!(deep_finished, AUTO_RETRY_EVERY - AUTO_MISSES);
}

#[test]
fn auto_shortens_a_walk_that_keeps_running_out() {
    // Queries from places the rows do not hold: the normal walk runs out of its budget without
    // finishing while the sketch rules rows out. After AUTO_MISSES such walks the walk shrinks to
    // the leaves nearest the query (AUTO_PRIME_BASE + AUTO_PRIME_PER_K·k distances), the normal
    // walk being tried again every AUTO_RETRY_EVERY queries (it costs little); a query near a
    // stored place at such a retry finishes the walk and brings the normal walk back. The
    // results never change.
    let (n, dim, k) = (20_000, 40, 3);
    let mut rng = Rng(90);
    let data = places(n, dim, 2_000, 0.05, &mut rng);
    let rows = Rows::normalized(&data, dim).unwrap();
    let built = Built::of(rows);
    let index = built.index(rows);
    let observed = Observed::new();
    let short = AUTO_PRIME_BASE + AUTO_PRIME_PER_K * k;
    let search = |q: &[f32]| {
        let req = Request {
            observed: Some(&observed),
            ..Request::nearest(k)
        };
        let mut out = vec![Neighbor::default(); k];
        let found = index.search(q, &req, &mut out).unwrap();
        assert_eq!(&out[..], &brute(rows, q, k, &Exclude::NONE)[..]);
        found.cost
    };
    // Novel queries: the normal walk (at the first AUTO_MISSES and at every retry) stops on its
    // budget, the sketch scans every row; in between, the short walk.
    let novel = 2 * AUTO_RETRY_EVERY + 5;
    for i in 0..novel {
        let c = search(&places(1, dim, 1, 0.0, &mut Rng(1_000 + u64::from(i))));
        let normal = i < AUTO_MISSES || i.is_multiple_of(AUTO_RETRY_EVERY);
        assert_eq!(c.sketch_rows, n, "query {i}: {c:?}");
        assert_eq!(c.tree_rows > 2 * short, normal, "query {i}: {c:?}");
    }
    // Stored places: the short walk and the sketch until the next retry, whose walk finishes;
    // the normal walk from then on (finished, or stopped on its budget).
    let back = novel.next_multiple_of(AUTO_RETRY_EVERY);
    for i in novel..back + AUTO_RETRY_EVERY {
        let c = search(&data[(i as usize * 997 % n) * dim..][..dim]);
        let finished = c.sketch_rows == 0 && c.exact_rows == 0;
        if i < back {
            assert!(
                (short..2 * short).contains(&c.tree_rows) && c.sketch_rows == n,
                "query {i}: {c:?}"
            );
        } else {
            assert!(finished || c.tree_rows > 2 * short, "query {i}: {c:?}");
            assert!(finished || i > back, "query {i}: {c:?}");
        }
    }
}

/// One place moved along `m` random directions: rows that differ in `m` dimensions only.
struct Moved {
    dim: usize,
    base: Vec<f32>,
    dirs: Vec<Vec<f32>>,
}

impl Moved {
    fn new(dim: usize, m: usize, rng: &mut Rng) -> Moved {
        let base = (0..dim).map(|_| 0.5 + rng.unit()).collect();
        let dirs = (0..m)
            .map(|_| (0..dim).map(|_| rng.unit() - 0.5).collect())
            .collect();
        Moved { dim, base, dirs }
    }

    /// The place moved by `c[j]` along direction `j`, normalised.
    fn at(&self, c: &[f32]) -> Vec<f32> {
        normed(&self.raw(c), self.dim)
    }

    fn raw(&self, c: &[f32]) -> Vec<f32> {
        (0..self.dim)
            .map(|d| {
                let shift: f32 = self.dirs.iter().zip(c).map(|(dir, c)| c * dir[d]).sum();
                self.base[d] + 0.3 * shift
            })
            .collect()
    }

    /// `n` rows moved at random, normalised.
    fn rows(&self, n: usize, rng: &mut Rng) -> Vec<f32> {
        let raw: Vec<f32> = (0..n)
            .flat_map(|_| {
                let c: Vec<f32> = self.dirs.iter().map(|_| rng.unit()).collect();
                self.raw(&c)
            })
            .collect();
        normed(&raw, self.dim)
    }
}

#[test]
fn auto_skips_a_deep_walk_dearer_than_brute_force_and_retries_it_within_a_pass() {
    // Near-duplicates moved along six directions: the sketch gives up, and the kd-tree finishes
    // its walk, but only after computing more distances than a brute-force pass costs
    // (auto_tree_row_cost each, 8,000 rows: one thread). The first deep walk (a budget of two
    // passes) finishes, and sets the moving average: brute force runs alone from the next query.
    // The walk is tried again on its own retries (deep_retried) with a budget of one pass (a
    // dearer walk is no use): each stops there and brute force follows. The results do not
    // change.
    let (n, dim) = (8000, 24);
    let mut rng = Rng(14);
    let moved = Moved::new(dim, 6, &mut rng);
    let rows = moved.rows(n, &mut rng);
    let q = moved.at(&[0.8, 0.1, 0.4, 0.7, 0.0, 0.3]);
    let rows = Rows::normalized(&rows, dim).unwrap();
    let pass = n / auto_tree_row_cost(n, 1);
    let (mut retries, mut skipped) = (0, false);
    for (i, c) in (0..).zip(observed_costs(rows, &q, 1, 3 * AUTO_RETRY_EVERY)) {
        let sketch = i < AUTO_MISSES || retried(i);
        assert_eq!(c.sketch_rows > 0, sketch, "query {i}: {c:?}");
        if sketch {
            continue;
        }
        if i == AUTO_MISSES {
            // Finished, and dearer than a pass of brute force.
            assert!(
                c.exact_rows == 0 && (pass + 1..2 * pass).contains(&c.tree_rows),
                "query {i}: {c:?}"
            );
        } else if deep_retried(i) {
            // Stopped after a pass's worth of distances (and at most a leaf more), then brute
            // force.
            assert!(
                c.exact_rows == n && (pass..pass + LEAF_SIZE).contains(&c.tree_rows),
                "query {i}: {c:?}"
            );
            retries += 1;
        } else {
            assert!(c.tree_rows == 0 && c.exact_rows == n, "query {i}: {c:?}");
            skipped = true;
        }
    }
    assert!(skipped && retries >= 2, "{retries} retries");
}
