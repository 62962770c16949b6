//! Brute force, kd-tree build and query, the online index, the sketch and every plan of the index
//! allocate nothing: a counting global allocator sees zero allocations across them.

mod common;

use solid_lidar::search::{
    brute_force, inverse_norm, normalize_rows, online_insert, online_rebuild, sketch_encode,
    sketch_len, Exclude, Index, KdTree, Neighbor, OnlineIndex, Plan, Request, Rows,
};

#[global_allocator]
static GLOBAL: common::Counting = common::Counting;

#[test]
fn searches_allocate_nothing() {
    let (n, dim) = (5000usize, 40usize);
    let raw: Vec<f32> = (0..n * dim)
        .map(|i| ((i * 2_654_435_761) % 1000) as f32 * if i % 3 == 0 { 0.0 } else { 1.0 })
        .collect();
    let mut rows = vec![0f32; raw.len()];
    let (mut perm, mut splits) = (vec![0u32; n], vec![0u16; n]);
    let (mut operm, mut osplits) = (vec![0u32; n], vec![0u16; n]);
    let mut out = vec![Neighbor::default(); 10];
    let mut out2 = vec![Neighbor::default(); 10];
    let times: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let (nc, np) = sketch_len(n, dim);
    let (mut codes, mut params) = (vec![0u8; nc], vec![0f32; np]);
    let mut outs = [[Neighbor::default(); 10]; 4];
    let mut scaled_outs = [[Neighbor::default(); 10]; 4];
    let mut scale = vec![0f32; n];

    let before = common::allocations();
    normalize_rows(&raw, dim, &mut rows).unwrap();
    let q = &rows[17 * dim..18 * dim];
    let normed = Rows::normalized(&rows, dim).unwrap();
    let ex = Exclude {
        before_id: n - 50,
        not_newer_than: Some((&times, 4000.0)),
    };
    let got = brute_force(normed, q, 10, &ex, &mut out).unwrap();
    let tree = KdTree::build(normed, &mut perm, &mut splits).unwrap();
    tree.search(q, 10, &ex, &mut out2).unwrap();
    for k in 1..=n {
        online_insert(normed.prefix(k), &mut operm, &mut osplits).unwrap();
    }
    online_rebuild(normed, &mut operm, &mut osplits).unwrap();
    let index = OnlineIndex::new(normed, &operm, &osplits).unwrap();
    let mut out3 = [Neighbor::default(); 10];
    index.search(q, 10, &ex, &mut out3).unwrap();
    for k in 1..=n {
        sketch_encode(normed.prefix(k), k - 1, &mut codes, &mut params).unwrap();
    }
    let every_plan = |index: &Index<'_>, outs: &mut [[Neighbor; 10]; 4]| {
        let plans = [Plan::Brute, Plan::KdTree, Plan::Sketch, Plan::Auto];
        for (plan, o) in plans.into_iter().zip(outs) {
            let req = Request {
                k: 10,
                exclude: ex,
                max_distance: 0.5,
                plan,
                observed: None,
            };
            index.search(q, &req, o).unwrap();
        }
    };
    let index = Index::new(normed, &operm, &osplits, &codes, &params).unwrap();
    every_plan(&index, &mut outs);
    // The raw rows with their scales: the same neighbours.
    for (s, row) in scale.iter_mut().zip(raw.chunks_exact(dim)) {
        *s = inverse_norm(row).unwrap();
    }
    let scaled = Rows::scaled(&raw, dim, &scale).unwrap();
    online_rebuild(scaled, &mut operm, &mut osplits).unwrap();
    sketch_encode(scaled, 0, &mut codes, &mut params).unwrap();
    let index = Index::new(scaled, &operm, &osplits, &codes, &params).unwrap();
    every_plan(&index, &mut scaled_outs);
    let after = common::allocations();

    assert_eq!(after - before, 0, "the searches allocated");
    assert_eq!(got, 10);
    assert_eq!(out[0].id, 17);
    assert_eq!(out, out2);
    assert_eq!(&out[..], &out3[..]);
    for o in &outs {
        assert_eq!(&out[..], &o[..]);
    }
    for o in &scaled_outs {
        assert_eq!(o[0].id, 17);
        assert_eq!(o, &scaled_outs[0]);
    }
}
