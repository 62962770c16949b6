//! The SPEC §5 scorer (`solid_lidar::eval::score`) on arbitrary queries, candidates and poses:
//! an error for inconsistent input, never a panic, and every summary of what it accepts computes.
//!
//! Input: u8 entries n (0..=63), u8 queries q (0..=31), u8 k (0..=7), f64 radius, n x 12 f64
//! poses, then per query u32 query id, u32 eligible, f64 score, f64 heading, k x u32 candidate
//! ids, then u8 flag: when odd, q x 16 f64 estimated loop poses (all little-endian; missing bytes
//! read as zeros).
#![no_main]

use libfuzzer_sys::fuzz_target;
use solid_lidar::eval::{score, Queries};

mod common;
use common::take;

fuzz_target!(|data: &[u8]| {
    let mut d = data;
    let [n, q, k] = take::<3>(&mut d);
    let (n, nq, k) = (usize::from(n % 64), usize::from(q % 32), usize::from(k % 8));
    let f64s = |d: &mut &[u8]| f64::from_le_bytes(take(d));
    let u32s = |d: &mut &[u8]| u32::from_le_bytes(take(d));
    let radius = f64s(&mut d);
    let poses: Vec<[f64; 12]> = (0..n)
        .map(|_| core::array::from_fn(|_| f64s(&mut d)))
        .collect();
    let (mut query, mut eligible, mut sc, mut heading, mut ids) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for _ in 0..nq {
        query.push(u32s(&mut d) % 80);
        eligible.push(u32s(&mut d) % 80);
        sc.push(f64s(&mut d));
        heading.push(f64s(&mut d));
        for _ in 0..k {
            let id = u32s(&mut d);
            ids.push(if id % 5 == 4 { u32::MAX } else { id % 80 });
        }
    }
    let est: Vec<[f64; 16]> = if take::<1>(&mut d)[0] % 2 == 1 {
        (0..nq)
            .map(|_| core::array::from_fn(|_| f64s(&mut d)))
            .collect()
    } else {
        Vec::new()
    };
    let queries = Queries {
        pose: &est,
        query: &query,
        eligible: &eligible,
        k,
        ids: &ids,
        score: &sc,
        heading_deg: &heading,
    };
    let Ok(ev) = score(&queries, &poses, radius) else {
        return;
    };
    assert_eq!(ev.len(), nq);
    assert!(ev.n_gt() <= nq);
    for r in 1..=k + 1 {
        if let Some(v) = ev.recall_at(r) {
            assert!((0.0..=1.0).contains(&v), "recall {v}");
        }
    }
    let (t, p, rc) = ev.pr_curve();
    assert!(t.len() == p.len() && p.len() == rc.len());
    let (t, f, tp) = ev.roc_curve();
    assert!(t.len() == f.len() && f.len() == tp.len());
    let _ = (ev.f1_max(), ev.auc(), ev.rotation_errors());
    for th in [f64::NAN, f64::NEG_INFINITY, 0.0, 0.5, f64::INFINITY] {
        let (acc, good, _, _) = ev.at_threshold(th);
        assert!(good <= acc && acc <= nq);
    }
});
