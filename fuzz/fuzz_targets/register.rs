//! Registration input: two arbitrary clouds, an arbitrary initial pose, yaw hypotheses and
//! config variations. Never a panic (ASan); an invalid config, pose or yaw is an error; a
//! registration that succeeds returns a finite rigid pose and fractions in [0, 1].
//!
//! Input: byte 0 flags (bit 0: point-to-plane, bit 1: no kernel, bit 2: no coarse level, bit 3:
//! register from yaw hypotheses, bit 4: arbitrary initial pose, else identity), byte 1
//! neighbours, byte 2 iterations, f32 voxel size, u16 query points; with bit 4 twelve f64 of
//! `[R | t]`, with bit 3 four f32 yaws in degrees; then the query's points and the candidate's
//! (x, y, z as f32; missing bytes read as zeros).
#![no_main]

use libfuzzer_sys::fuzz_target;
use solid_lidar::reg::{
    register, register_hypotheses, Factor, Hypothesis, Kernel, PreparedCloud, RegConfig, RegError,
    IDENTITY,
};
use solid_lidar::{Error, Points};

mod common;
use common::take;

fuzz_target!(|data: &[u8]| {
    let mut d = data;
    let [flags, neighbors, iterations] = take::<3>(&mut d);
    let voxel = f64::from(f32::from_le_bytes(take(&mut d)));
    let nq = usize::from(u16::from_le_bytes(take(&mut d)));
    let mut cfg = RegConfig::default();
    if flags & 1 != 0 {
        cfg.factor = Factor::PointToPlane;
    }
    if flags & 2 != 0 {
        cfg.kernel = Kernel::None;
    }
    if flags & 4 != 0 {
        cfg.coarse_voxel_size = 0.0;
    }
    cfg.neighbors = usize::from(neighbors % 70);
    cfg.max_iterations = usize::from(iterations % 40);
    cfg.voxel_size = voxel;
    let mut init = IDENTITY;
    if flags & 16 != 0 {
        for row in init.iter_mut().take(3) {
            for v in row.iter_mut() {
                *v = f64::from_le_bytes(take(&mut d));
            }
        }
    }
    let yaws: Vec<f64> = if flags & 8 != 0 {
        (0..4)
            .map(|_| f64::from(f32::from_le_bytes(take(&mut d))))
            .collect()
    } else {
        Vec::new()
    };
    let xyz: Vec<f32> = d
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    let n = xyz.len() / 3;
    let (q, c) = xyz[..3 * n].split_at(3 * nq.min(n));
    let valid = cfg.validate().is_ok();
    let prepare = |p: &[f32]| PreparedCloud::new(Points::new(p, 3).unwrap(), &cfg);
    let (qp, cp) = match (prepare(q), prepare(c)) {
        (Ok(a), Ok(b)) => (a, b),
        (Err(RegError::Core(Error::InvalidParameter { .. })), _) if !valid => return,
        other => panic!(
            "preparing with a {} config: {other:?}",
            if valid { "valid" } else { "invalid" }
        ),
    };
    assert!(valid, "an invalid config prepared a cloud");
    let reg = if yaws.is_empty() {
        register(&qp, &cp, &init, &cfg)
    } else {
        let mut out = [Hypothesis::default(); 4];
        register_hypotheses(&qp, &cp, &yaws, &init, &cfg, &mut out).map(|h| h.registration)
    };
    match reg {
        Ok(r) => {
            assert!(r.pose.iter().flatten().all(|v| v.is_finite()), "{r:?}");
            for f in [r.fitness, r.overlap_query, r.overlap_candidate] {
                assert!((0.0..=1.0).contains(&f), "{r:?}");
            }
        }
        Err(RegError::Core(Error::InvalidParameter { .. })) => {} // a bad init pose or yaw
        Err(e) => panic!("unexpected {e:?}"),
    }
});
