//! Brute force, kd-tree build and query, the online index, the sketch and every plan of the index
//! allocate nothing: a counting global allocator sees zero allocations across them.

mod common;

use solid_lidar::search::{
    brute_force, normalize_rows, online_insert, online_rebuild, sketch_encode, sketch_len, Exclude,
    Index, KdTree, Neighbor, OnlineIndex, Plan, Request,
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

    let before = common::allocations();
    normalize_rows(&raw, dim, &mut rows).unwrap();
    let q = &rows[17 * dim..18 * dim];
    let ex = Exclude {
        before_id: n - 50,
        not_newer_than: Some((&times, 4000.0)),
    };
    let got = brute_force(&rows, dim, q, 10, &ex, &mut out).unwrap();
    let tree = KdTree::build(&rows, dim, &mut perm, &mut splits).unwrap();
    tree.search(q, 10, &ex, &mut out2).unwrap();
    for k in 1..=n {
        online_insert(&rows[..k * dim], dim, &mut operm, &mut osplits).unwrap();
    }
    online_rebuild(&rows, dim, &mut operm, &mut osplits).unwrap();
    let index = OnlineIndex::new(&rows, dim, &operm, &osplits).unwrap();
    let mut out3 = [Neighbor::default(); 10];
    index.search(q, 10, &ex, &mut out3).unwrap();
    for k in 1..=n {
        sketch_encode(&rows[..k * dim], dim, k - 1, &mut codes, &mut params).unwrap();
    }
    let index = Index::new(&rows, dim, &operm, &osplits, &codes, &params).unwrap();
    for (plan, o) in [Plan::Brute, Plan::KdTree, Plan::Sketch, Plan::Auto]
        .into_iter()
        .zip(&mut outs)
    {
        let req = Request {
            k: 10,
            exclude: ex,
            max_distance: 0.5,
            plan,
        };
        index.search(q, &req, o).unwrap();
    }
    let after = common::allocations();

    assert_eq!(after - before, 0, "the searches allocated");
    assert_eq!(got, 10);
    assert_eq!(out[0].id, 17);
    assert_eq!(out, out2);
    assert_eq!(&out[..], &out3[..]);
    for o in &outs {
        assert_eq!(&out[..], &o[..]);
    }
}
