//! Registration over prepared clouds allocates nothing: a counting global allocator sees zero
//! allocations across `register`, `register_hypotheses`, `hypothesis_yaws` and the gate.
#![cfg(feature = "std")]

mod common;

use solid_lidar::reg::{
    hypothesis_yaws, register, register_hypotheses, Gate, Hypothesis, PreparedCloud, RegConfig,
    IDENTITY,
};
use solid_lidar::Points;

#[global_allocator]
static GLOBAL: common::Counting = common::Counting;

#[test]
fn registration_allocates_nothing() {
    let Some(data) = common::data_dir() else {
        return;
    };
    let cfg = RegConfig::default();
    let a = common::read_scan(&data.join("hku1-avia/Scans/000280.pcd"));
    let b = common::read_scan(&data.join("hku1-avia/Scans/000020.pcd"));
    let pa = PreparedCloud::new(Points::new(&a, 3).unwrap(), &cfg).unwrap();
    let pb = PreparedCloud::new(Points::new(&b, 3).unwrap(), &cfg).unwrap();
    let (qa, ca) = (
        [1.0f32, 4.0, 2.0, 0.0, 0.0, 3.0],
        [0.0f32, 1.0, 4.0, 2.0, 0.0, 3.0],
    );
    let mut yaws = [0.0; 4];
    let mut hyps = [Hypothesis::default(); 4];
    let gate = Gate::default();
    let before = common::allocations();
    let k = hypothesis_yaws(&qa, &ca, &mut yaws).unwrap();
    let r = register(&pa, &pb, &IDENTITY, &cfg).unwrap();
    let h = register_hypotheses(&pa, &pb, &yaws[..k], &IDENTITY, &cfg, &mut hyps).unwrap();
    let _ = gate.check(&h.registration, &hyps[..k], h.best);
    assert_eq!(common::allocations(), before);
    assert!(r.iterations > 0 && k >= 1);
}
