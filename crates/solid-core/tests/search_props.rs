//! Exactness of the searches: kd-tree and online index against brute force (docs/spec.md §3), on random
//! vectors, adversarial ones (duplicates, all-zero, many equal coordinates, a single entry) and
//! real descriptors of the HKU Livox Avia sequence.

mod common;
use common::search::{
    brute, check_index, normed, online, places, scales, sketch, sketch_of, tree, Built, Rng,
};
use common::{data_dir, read_xyz_f32, Xorshift};
use proptest::prelude::*;
use solid_lidar::search::{
    brute_force, inverse_norm, normalize, normalized_distance, online_extend,
    online_extend_scratch_len, online_extend_with, online_insert, online_rebuild, sketch_encode,
    sketch_len, Exclude, Index, KdTree, Neighbor, OnlineIndex, Plan, Request, Rows, Sketch,
    SKETCH_BLOCK,
};
use solid_lidar::{cosine_distance, Config, Describer, Points};

/// R-SOLiD of every HKU scan (every `step`-th), described with the core.
fn hku_r(step: usize) -> Option<(Vec<f32>, usize)> {
    let dir = data_dir()?.join("hku1-avia/Scans");
    let cfg = Config::preset("avia").unwrap();
    let mut describer = Describer::new(cfg).unwrap();
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "pcd"))
        .collect();
    names.sort();
    assert!(names.len() >= 300, "expected the 314 HKU scans");
    let mut r = Vec::new();
    for p in names.iter().step_by(step) {
        let xyz = read_xyz_f32(p);
        let d = describer.describe(Points::new(&xyz, 3).unwrap()).unwrap();
        r.extend_from_slice(&d.r);
    }
    Some((r, cfg.n_range))
}

/// Checks that every method agrees with brute force, and that brute force is right: sorted by
/// (distance, id), the k smallest of all candidates; for the rows stored normalised and for the
/// raw rows with their scales.
fn check_all(raw: &[f32], dim: usize, query_raw: &[f32], k: usize, ex: &Exclude<'_>) {
    let (normalised, scale) = (normed(raw, dim), scales(raw, dim));
    let mut q = vec![0.0; dim];
    normalize(query_raw, &mut q).unwrap();
    for rows in [
        Rows::normalized(&normalised, dim).unwrap(),
        Rows::scaled(raw, dim, &scale).unwrap(),
    ] {
        let b = brute(rows, &q, k, ex);
        assert_eq!(b, tree(rows, &q, k, ex), "kd-tree differs from brute force");
        assert_eq!(b, online(rows, &q, k, ex), "online index differs");
        assert_eq!(
            b,
            sketch(rows, &q, k, ex),
            "sketch differs from brute force"
        );
        check_index(rows, &q, k, ex);
        // Reference: sort all allowed candidates.
        let mut dists = vec![0.0f32; rows.len()];
        rows.distances(&q, &mut dists).unwrap();
        let mut all: Vec<Neighbor> = (0..rows.len())
            .filter(|&i| {
                i < ex.before_id
                    && ex
                        .not_newer_than
                        .is_none_or(|(t, m)| t[i].is_nan() || t[i] <= m)
            })
            .map(|i| Neighbor {
                id: i as u32,
                distance: dists[i],
            })
            .collect();
        all.sort_by(|x, y| x.distance.total_cmp(&y.distance).then(x.id.cmp(&y.id)));
        all.truncate(k);
        assert_eq!(b, all, "brute force is not the sorted k best");
        // Distances agree with the f64 cosine distance of docs/spec.md §3.
        for nb in &b {
            let i = nb.id as usize;
            let want = cosine_distance(query_raw, &raw[i * dim..(i + 1) * dim]).unwrap();
            assert!(
                (f64::from(nb.distance) - want).abs() < 1e-5,
                "distance {} vs {want}",
                nb.distance
            );
        }
    }
    // Normalised rows give the distances `normalized_distance` gives.
    let rows = Rows::normalized(&normalised, dim).unwrap();
    for nb in brute(rows, &q, k, ex) {
        let i = nb.id as usize;
        let c = &normalised[i * dim..(i + 1) * dim];
        assert_eq!(nb.distance, normalized_distance(&q, c).unwrap());
    }
}

/// Non-negative vectors shaped like R-SOLiDs: a few large bins, many small or zero ones, values
/// drawn from a small set so that coordinates repeat often.
fn descriptor_like(dim: usize) -> impl Strategy<Value = Vec<f32>> {
    prop::collection::vec(
        prop_oneof![
            3 => Just(0.0f32),
            2 => (0u8..4).prop_map(f32::from),
            2 => 0.0f32..100.0,
        ],
        dim,
    )
}

fn dataset() -> impl Strategy<Value = (usize, Vec<f32>, Vec<f32>, usize)> {
    (1usize..12, 1usize..300, 1usize..8).prop_flat_map(|(dim, n, k)| {
        (
            Just(dim),
            prop::collection::vec(descriptor_like(dim), n)
                .prop_map(|rows| rows.into_iter().flatten().collect::<Vec<f32>>()),
            descriptor_like(dim),
            Just(k),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn kdtree_and_online_equal_brute_force((dim, raw, q, k) in dataset()) {
        check_all(&raw, dim, &q, k, &Exclude::NONE);
    }

    #[test]
    fn duplicated_rows_tie_by_lower_id((dim, raw, q, k) in dataset(), copies in 2usize..6) {
        let n = raw.len() / dim;
        let mut rows = Vec::new();
        for _ in 0..copies {
            rows.extend_from_slice(&raw[..n.min(20) * dim]);
        }
        check_all(&rows, dim, &q, k * copies, &Exclude::NONE);
    }

    #[test]
    fn exclusions_are_respected((dim, raw, q, k) in dataset(), recent in 0usize..50, bound in 0.0f64..300.0) {
        let n = raw.len() / dim;
        let times: Vec<f64> = (0..n).map(|i| if i % 7 == 3 { f64::NAN } else { i as f64 }).collect();
        let ex = Exclude { before_id: n.saturating_sub(recent), not_newer_than: Some((&times, bound)) };
        check_all(&raw, dim, &q, k, &ex);
        check_all(&raw, dim, &q, k, &Exclude::recent(n, recent));
    }

    /// The length of every preset's R-SOLiD, which the AVX2 scan compiles a copy of its own for:
    /// the same bits as the scalar distance (`check_all` compares brute force with
    /// `Rows::distances`).
    #[test]
    fn preset_length_rows((raw, q, k) in (1usize..300, 1usize..8).prop_flat_map(|(n, k)| (
        prop::collection::vec(descriptor_like(40), n).prop_map(|r| r.into_iter().flatten().collect::<Vec<f32>>()),
        descriptor_like(40),
        Just(k),
    ))) {
        check_all(&raw, 40, &q, k, &Exclude::NONE);
        let n = raw.len() / 40;
        check_all(&raw, 40, &q, k, &Exclude::recent(n, n / 3));
    }

    #[test]
    fn gaussian_vectors_with_signs(seed_rows in prop::collection::vec(prop::collection::vec(-1.0f32..1.0, 16), 1..200), q in prop::collection::vec(-1.0f32..1.0, 16), k in 1usize..10) {
        let raw: Vec<f32> = seed_rows.into_iter().flatten().collect();
        check_all(&raw, 16, &q, k, &Exclude::NONE);
    }
}

#[test]
fn all_zero_rows_and_query() {
    let dim = 5;
    let mut raw = vec![0.0f32; 40 * dim];
    for i in (0..40).step_by(3) {
        raw[i * dim + i % dim] = 1.0 + i as f32;
    }
    check_all(&raw, dim, &[0.0; 5], 10, &Exclude::NONE);
    check_all(&raw, dim, &[0.0, 1.0, 0.0, 0.0, 2.0], 40, &Exclude::NONE);
    // Every row zero: all distances are 1 and the order is by id.
    let zeros = vec![0.0f32; 100 * dim];
    let rows = normed(&zeros, dim);
    let rows = Rows::normalized(&rows, dim).unwrap();
    let got = tree(rows, &[0.6, 0.8, 0.0, 0.0, 0.0], 3, &Exclude::NONE);
    assert_eq!(
        got.iter().map(|n| (n.id, n.distance)).collect::<Vec<_>>(),
        [(0, 1.0), (1, 1.0), (2, 1.0)]
    );
}

/// The build that gathers split values into scratch keys (nodes of 64 entries and more)
/// gives an index as exact as brute force, on rows with few distinct values (many ties in the
/// selections), grown in steps and from scratch, with scratch too short for some blocks.
#[test]
fn keyed_build_equals_brute_force() {
    let mut x = 0x9e37_79b9u32;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        x
    };
    for (n, dim, levels) in [(3000usize, 40usize, 4u32), (2500, 16, 1000), (1024, 8, 2)] {
        let raw: Vec<f32> = (0..n * dim).map(|_| (next() % levels) as f32).collect();
        let scale = scales(&raw, dim);
        let rows = Rows::scaled(&raw, dim, &scale).unwrap();
        for (from, keys_len) in [(0, usize::MAX), (n / 3, usize::MAX), (0, 1024)] {
            let (mut perm, mut splits) = (vec![0u32; n], vec![0u16; n]);
            online_rebuild(rows.prefix(from), &mut perm, &mut splits).unwrap();
            let need = online_extend_scratch_len(n, from);
            assert!(
                need >= 1024,
                "n {n} from {from}: no block to build with keys"
            );
            let mut keys = vec![7u64; need.min(keys_len)];
            online_extend_with(rows, from, &mut perm, &mut splits, &mut keys).unwrap();
            let mut sorted = perm.clone();
            sorted.sort_unstable();
            assert!(sorted.iter().enumerate().all(|(i, &p)| p as usize == i));
            let index = OnlineIndex::new(rows, &perm, &splits).unwrap();
            for _ in 0..20 {
                let q_raw: Vec<f32> = (0..dim).map(|_| (next() % levels) as f32 + 0.5).collect();
                let mut q = vec![0.0; dim];
                normalize(&q_raw, &mut q).unwrap();
                for k in [1, 7] {
                    let mut out = vec![Neighbor::default(); k];
                    let got = index.search(&q, k, &Exclude::NONE, &mut out).unwrap();
                    out.truncate(got);
                    assert_eq!(out, brute(rows, &q, k, &Exclude::NONE), "n {n} dim {dim}");
                }
            }
        }
    }
    assert_eq!(
        online_extend_scratch_len(5000, 4999),
        0,
        "one new row: nothing large to build"
    );
}

#[test]
fn single_entry_and_empty() {
    check_all(&[3.0, 4.0], 2, &[4.0, 3.0], 1, &Exclude::NONE);
    check_all(&[3.0, 4.0], 2, &[4.0, 3.0], 5, &Exclude::NONE);
    let empty = Rows::normalized(&[], 2).unwrap();
    assert!(brute(empty, &[1.0, 0.0], 3, &Exclude::NONE).is_empty());
    assert!(tree(empty, &[1.0, 0.0], 3, &Exclude::NONE).is_empty());
    let one = Rows::normalized(&[1.0, 0.0], 2).unwrap();
    assert!(brute(one, &[1.0, 0.0], 0, &Exclude::NONE).is_empty());
}

#[test]
fn many_identical_rows_keep_the_tree_balanced_and_exact() {
    // 5,000 copies of 3 distinct vectors: every coordinate repeats thousands of times.
    let base = [
        [1.0f32, 0.0, 2.0, 0.0],
        [1.0, 0.0, 2.0, 0.5],
        [0.0, 0.0, 0.0, 0.0],
    ];
    let raw: Vec<f32> = (0..5000).flat_map(|i| base[i % 3]).collect();
    check_all(&raw, 4, &[1.0, 0.0, 2.0, 0.4], 7, &Exclude::NONE);
    check_all(
        &raw,
        4,
        &[1.0, 0.0, 2.0, 0.0],
        3000,
        &Exclude::recent(5000, 10),
    );
}

#[test]
fn errors_instead_of_panics() {
    let data = [1.0f32, 0.0, 0.0, 1.0];
    assert!(Rows::normalized(&data, 3).is_err());
    assert!(Rows::normalized(&data, 0).is_err());
    assert!(Rows::scaled(&data, 2, &[1.0]).is_err());
    let rows = Rows::normalized(&data, 2).unwrap();
    let mut out = [Neighbor::default(); 1];
    assert!(brute_force(rows, &[1.0], 1, &Exclude::NONE, &mut out).is_err());
    assert!(brute_force(rows, &[1.0, 0.0], 2, &Exclude::NONE, &mut out).is_err());
    let times = [0.0f64];
    let ex = Exclude {
        before_id: usize::MAX,
        not_newer_than: Some((&times, 1.0)),
    };
    assert!(brute_force(rows, &[1.0, 0.0], 1, &ex, &mut out).is_err());
    let (mut perm, mut splits) = ([0u32; 1], [0u16; 2]);
    assert!(KdTree::build(rows, &mut perm, &mut splits).is_err());
    assert!(KdTree::from_built(rows, &[0, 5], &[0, 0]).is_err());
    let mut o = [0.0f32; 2];
    assert!(normalize(&[f32::NAN, 1.0], &mut o).is_err());
    assert!(normalize(&[1.0], &mut o).is_err());
    assert!(inverse_norm(&[1.0, f32::INFINITY]).is_err());
    let empty = Rows::normalized(&[], 2).unwrap();
    assert!(online_insert(empty, &mut [], &mut []).is_err());
    assert!(online_extend(rows, 3, &mut [0; 2], &mut [0; 2]).is_err());
    let (mut codes, mut params) = ([0u8; 31], [0f32; 48]);
    assert!(sketch_encode(rows, 0, &mut codes, &mut params).is_err());
    assert!(sketch_encode(rows, 3, &mut [0; 32], &mut params).is_err());
    assert!(Sketch::new(rows, &codes, &params).is_err());
    let req = Request {
        max_distance: f32::NAN,
        ..Request::nearest(1)
    };
    let (mut p2, mut s2) = ([0u32; 2], [0u16; 2]);
    online_rebuild(rows, &mut p2, &mut s2).unwrap();
    let (codes, params) = sketch_of(rows);
    let index = Index::new(rows, &p2, &s2, &codes, &params).unwrap();
    assert!(index.search(&[1.0, 0.0], &req, &mut out).is_err());
    assert!(Index::new(rows, &p2, &s2[..1], &codes, &params).is_err());
}

#[test]
fn real_descriptors_kdtree_equals_brute_force() {
    let Some((raw, dim)) = hku_r(1) else { return };
    let n = raw.len() / dim;
    let rows = normed(&raw, dim);
    // Every scan as the query, docs/spec.md §5 exclusion of the 50 most recent, k = 1 and 10.
    let all = Rows::normalized(&rows, dim).unwrap();
    for qi in 0..n {
        let q = &rows[qi * dim..(qi + 1) * dim];
        let db = all.prefix(qi);
        for k in [1, 10] {
            let ex = Exclude::recent(qi, 50);
            let b = brute(db, q, k, &ex);
            assert_eq!(b, tree(db, q, k, &ex), "query {qi}");
            assert_eq!(b, online(db, q, k, &ex), "query {qi}");
            assert_eq!(b, sketch(db, q, k, &ex), "query {qi}");
        }
    }
    // Duplicated database (every scan twice): ties must go to the lower id.
    let mut dup = rows.clone();
    dup.extend_from_slice(&rows);
    let dup = Rows::normalized(&dup, dim).unwrap();
    for qi in (0..n).step_by(5) {
        let q = &rows[qi * dim..(qi + 1) * dim];
        let b = brute(dup, q, 4, &Exclude::NONE);
        assert_eq!(b[0].id as usize, qi);
        assert_eq!(b, tree(dup, q, 4, &Exclude::NONE));
        assert_eq!(b, online(dup, q, 4, &Exclude::NONE));
        check_index(dup, q, 4, &Exclude::NONE);
    }
}

/// The HKU R-SOLiDs, described once for all the property cases.
fn hku_cached() -> Option<&'static (Vec<f32>, usize)> {
    static CACHE: std::sync::OnceLock<Option<(Vec<f32>, usize)>> = std::sync::OnceLock::new();
    CACHE.get_or_init(|| hku_r(1)).as_ref()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Random subsets of the real descriptors (some duplicated, some zeroed), random queries
    /// among them (or perturbed), random k and exclusions.
    #[test]
    fn real_descriptor_subsets(
        picks in prop::collection::vec((0usize..314, 0u8..10), 1..400),
        query in 0usize..314,
        noise in prop::collection::vec(0.8f32..1.25, 40),
        k in 1usize..12,
        recent in 0usize..60,
    ) {
        let Some((all, dim)) = hku_cached() else { return Ok(()) };
        let dim = *dim;
        let mut raw = Vec::new();
        for &(i, kind) in &picks {
            let row = &all[i * dim..(i + 1) * dim];
            match kind {
                0 => raw.extend(std::iter::repeat_n(0.0f32, dim)),
                1 => raw.extend(row.iter().zip(&noise).map(|(a, b)| a * b)),
                _ => raw.extend_from_slice(row),
            }
        }
        let q: Vec<f32> = all[query * dim..(query + 1) * dim].to_vec();
        let n = raw.len() / dim;
        check_all(&raw, dim, &q, k, &Exclude::recent(n, recent));
    }
}

/// Checks that brute force and every plan of `index` (over `rows`) find, for each `k` and
/// exclusion of recent ids, the neighbours that sorting every allowed row by distance, then id,
/// gives.
fn assert_every_plan_exact(
    index: &Index<'_>,
    rows: Rows<'_>,
    q: &[f32],
    ks: &[usize],
    exclusions: &[Exclude<'_>],
) {
    let mut dists = vec![0.0f32; rows.len()];
    rows.distances(q, &mut dists).unwrap();
    let mut all: Vec<Neighbor> = dists
        .iter()
        .enumerate()
        .map(|(i, &distance)| Neighbor {
            id: i as u32,
            distance,
        })
        .collect();
    all.sort_by(|x, y| x.distance.total_cmp(&y.distance).then(x.id.cmp(&y.id)));
    for &k in ks {
        for ex in exclusions {
            let want: Vec<Neighbor> = all
                .iter()
                .filter(|nb| {
                    let id = nb.id as usize;
                    // A timestamp past the bound leaves the entry out; NaN (no time) keeps it.
                    id < ex.before_id
                        && ex
                            .not_newer_than
                            .is_none_or(|(t, bound)| t[id].is_nan() || t[id] <= bound)
                })
                .take(k)
                .copied()
                .collect();
            assert_eq!(brute(rows, q, k, ex), want, "brute k {k}");
            for plan in [Plan::Sketch, Plan::Auto, Plan::KdTree, Plan::Brute] {
                let req = Request {
                    k,
                    exclude: *ex,
                    max_distance: f32::INFINITY,
                    plan,
                    observed: None,
                };
                let mut out = vec![Neighbor::default(); k];
                let found = index.search(q, &req, &mut out).unwrap();
                assert_eq!(&out[..found.len], &want[..], "{plan:?} k {k} {ex:?}");
            }
        }
    }
}

#[test]
fn long_scans_cut_in_parts_stay_exact() {
    // Enough rows for brute force and the sketch to search parts on two threads (with the
    // `parallel` feature), and a k above the limit of that (a single pass).
    let (n, dim) = (70_000, 8);
    let mut rng = Rng(70);
    let rows = places(n, dim, 5_000, 0.01, &mut rng);
    let rows = Rows::normalized(&rows, dim).unwrap();
    let built = Built::of(rows);
    let index = built.index(rows);
    for qi in 0..3 {
        let q = places(1, dim, 1, 0.0, &mut Rng(100 + qi));
        assert_every_plan_exact(&index, rows, &q, &[1, 10, 100], &[Exclude::recent(n, 3)]);
    }
}

#[test]
fn rows_past_the_tree_cut_in_parts_stay_exact() {
    // A kd-tree and a sketch over the first rows only, as in a database after a stored-only add:
    // a finished walk fills the heap, then the rows past the tree are searched in parts on two
    // threads (`parallel`), each part after the first into a heap of its own, bounded by the
    // walk's k-th distance. Every 7th row past the tree repeats a row of the tree, so that equal
    // distances (lower id first) meet across the tree, the cut and the parts.
    let (head, n, dim) = (4_096, 4_096 + 70_000, 8);
    let mut rng = Rng(71);
    let mut data = places(n, dim, 3_000, 0.01, &mut rng);
    for i in (head..n).step_by(7) {
        let from = (i * 13) % head;
        data.copy_within(from * dim..(from + 1) * dim, i * dim);
    }
    let rows = Rows::normalized(&data, dim).unwrap();
    let (mut perm, mut splits) = (vec![0u32; head], vec![0u16; head]);
    online_rebuild(rows.prefix(head), &mut perm, &mut splits).unwrap();
    let (codes, params) = sketch_of(rows.prefix(head));
    let index = Index::new(rows, &perm, &splits, &codes, &params).unwrap();
    // Timestamps that leave out every third row, in the tree and past it (NaN: no time, kept).
    let times: Vec<f64> = (0..n)
        .map(|i| match i % 3 {
            0 => 1e9,
            1 => f64::NAN,
            _ => i as f64,
        })
        .collect();
    for qi in 0..4 {
        // Queries on repeated rows (ties at every distance of their copies) and one elsewhere.
        let q: Vec<f32> = if qi < 3 {
            data[qi * 1_000 * dim..][..dim].to_vec()
        } else {
            places(1, dim, 1, 0.0, &mut Rng(200))
        };
        let exclusions = [
            Exclude::recent(n, 3),
            Exclude::recent(n, 1_000),
            Exclude::recent(n, n - head / 2),
            Exclude {
                before_id: n - 500,
                not_newer_than: Some((&times, 1e8)),
            },
        ];
        assert_every_plan_exact(&index, rows, &q, &[1, 5, 40], &exclusions);
    }
}

/// The stored error bounds the exact error (TwoSum in `f64`), through the public encoder, on rows
/// meant to break it: values a few ulps apart, spread over 140 binades, rounding ties, 1e30 with
/// scale 1e-30, normalised values among the subnormals, constant rows; lengths 1 to 65,535.
#[test]
fn the_sketch_error_bounds_the_exact_one_on_adversarial_rows() {
    let mut g = Xorshift(0x1234_5678_9abc_def1);
    let mut worst = f64::INFINITY;
    for dim in [
        1usize, 2, 3, 5, 7, 8, 9, 15, 16, 17, 40, 255, 1024, 4099, 65535,
    ] {
        for kind in 0..9 {
            let n = if dim > 5000 {
                SKETCH_BLOCK
            } else {
                3 * SKETCH_BLOCK
            };
            let mut raw = Vec::with_capacity(n * dim);
            let mut scale = Vec::with_capacity(n);
            for _ in 0..n {
                let base = (g.next() * 10.0 + 0.1) as f32;
                for d in 0..dim {
                    let x = g.next();
                    let v = match kind {
                        0 => x as f32,
                        1 => base + (x * 8.0).floor() as f32 * f32::EPSILON * base,
                        2 => {
                            // many magnitudes
                            (x * 2.0f64.powi(-((d % 140) as i32))) as f32
                        }
                        3 => {
                            if d % 2 == 0 {
                                1.0
                            } else {
                                1.0 + f32::EPSILON
                            }
                        }
                        4 => (x * 255.0).floor() as f32 + 0.5,
                        5 => 1e30 * x as f32,
                        6 => (x * 1e-3) as f32,
                        7 => {
                            if d == 0 {
                                1.0
                            } else {
                                (x * 1e-20) as f32
                            }
                        }
                        _ => base,
                    };
                    raw.push(v);
                }
                scale.push(match kind {
                    2 => 1.0,
                    5 => 1e-30,
                    6 => 1e-38, // values into subnormals
                    7 => 3.0e-39,
                    8 => 1.0 / 3.0,
                    _ => (g.next() * 4.0) as f32 + 1e-3,
                });
            }
            let rows = Rows::scaled(&raw, dim, &scale).unwrap();
            let (nc, np) = sketch_len(n, dim);
            let (mut codes, mut params) = (vec![0u8; nc], vec![0f32; np]);
            sketch_encode(rows, 0, &mut codes, &mut params).unwrap();
            let pd = dim.next_multiple_of(4);
            let width = pd * SKETCH_BLOCK;
            for i in 0..n {
                let (b, lane) = (i / SKETCH_BLOCK, i % SKETCH_BLOCK);
                let p = |j: usize| params[b * 3 * SKETCH_BLOCK + j * SKETCH_BLOCK + lane];
                let (lo, step, err) = (p(0) as f64, p(1) as f64, p(2) as f64);
                let s = scale[i] as f64;
                let mut e2 = 0.0f64;
                for d in 0..dim {
                    let k = codes[b * width + ((d / 4) * SKETCH_BLOCK + lane) * 4 + d % 4] as f64;
                    let cval = raw[i * dim + d] as f64 * s; // exact
                    let sk = step * k; // exact
                                       // two-sum lo + sk
                    let a1 = lo + sk;
                    let bb = a1 - lo;
                    let a2 = (lo - (a1 - bb)) + (sk - bb);
                    // cval - a1 two-sum
                    let d1 = cval - a1;
                    let bb = d1 - cval;
                    let d2 = (cval - (d1 - bb)) + (-a1 - bb);
                    let e = d1 + (d2 - a2);
                    e2 += e * e;
                }
                let exact = e2.sqrt();
                assert!(
                    err >= exact * (1.0 - 1e-13),
                    "dim {dim} kind {kind} row {i}: err {err:e} < exact {exact:e}"
                );
                if exact > 0.0 {
                    worst = worst.min(err / exact - 1.0);
                }
            }
        }
    }
    assert!(worst.is_finite(), "no row with an error");
}
