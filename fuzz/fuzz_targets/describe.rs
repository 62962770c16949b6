//! `describe` on arbitrary points and configs: never a panic (ASan, including the AVX2 copy), a
//! config error for an invalid config, and otherwise a descriptor that is the same bits from the
//! AVX2 and the portable copy and from float32 and float64 coordinates.
//!
//! Input: byte 0 picks a preset; byte 1 is flags (bit 0: float64 points, bit 1: stride 4 instead
//! of 3, bit 2: 26 bytes of config overrides follow: u16 n_range, n_azimuth, n_elevation, then f32
//! fov_up, fov_down, min_range, max_range, voxel_size); the rest is the points, little-endian.
#![no_main]

use libfuzzer_sys::fuzz_target;
use solid_lidar::{describe, describe_scratch_len, stages, Config, Error, Points, PRESETS};

mod common;
use common::take;

fuzz_target!(|data: &[u8]| {
    let mut d = data;
    let [preset, flags] = take::<2>(&mut d);
    let mut cfg = PRESETS[preset as usize % PRESETS.len()].config;
    if flags & 4 != 0 {
        let u16s = |d: &mut &[u8]| usize::from(u16::from_le_bytes(take(d)));
        let f32s = |d: &mut &[u8]| f64::from(f32::from_le_bytes(take(d)));
        cfg = Config {
            n_range: u16s(&mut d),
            n_azimuth: u16s(&mut d),
            n_elevation: u16s(&mut d),
            fov_up: f32s(&mut d),
            fov_down: f32s(&mut d),
            min_range: f32s(&mut d),
            max_range: f32s(&mut d),
            voxel_size: f32s(&mut d),
        };
    }
    let stride = if flags & 2 != 0 { 4 } else { 3 };
    let pts64: Vec<f64> = if flags & 1 != 0 {
        d.chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect()
    } else {
        d.chunks_exact(4)
            .map(|c| f64::from(f32::from_le_bytes(c.try_into().unwrap())))
            .collect()
    };
    let n = pts64.len() / stride;
    let pts64 = &pts64[..n * stride];
    let valid = cfg.validate().is_ok();
    // Sizes for an invalid config are whatever it says, capped: it must be refused anyway.
    let (nr, na) = (cfg.n_range.min(1 << 12), cfg.n_azimuth.min(1 << 12));
    let mut scratch = vec![0u64; describe_scratch_len(n, &cfg).min(1 << 20)];
    let mut out = [
        (vec![0f32; nr], vec![0f32; na]),
        (vec![0f32; nr], vec![0f32; na]),
    ];
    let [(r0, a0), (r1, a1)] = &mut out;
    let p64 = Points::new(pts64, stride).unwrap();
    let fast = describe(p64, &cfg, &mut scratch, r0, a0);
    let portable = stages::describe_portable(p64, &cfg, &mut scratch, r1, a1);
    match (&fast, valid) {
        (Err(Error::InvalidParameter { .. }), false) => {
            // Debug form: the errors carry the rejected value, which may be NaN.
            assert_eq!(format!("{fast:?}"), format!("{portable:?}"));
            return;
        }
        (Err(Error::BufferTooSmall { .. }), true) => return, // a config too large for the caps
        (Ok(_), true) => {}
        other => panic!("unexpected {other:?} for {cfg:?}"),
    }
    assert_eq!(fast, portable);
    assert_eq!(r0, r1, "AVX2 and portable R-SOLiD differ");
    assert_eq!(a0, a1, "AVX2 and portable A-SOLiD differ");
    let s = fast.unwrap();
    assert!(s.n_kept <= s.n_in_range && s.n_in_range <= s.n_points && s.n_points == n);
    assert!(r0
        .iter()
        .chain(a0.iter())
        .all(|v| v.is_finite() && *v >= 0.0));
    if flags & 1 == 0 {
        // The same points as float32: the same bits.
        let pts32: Vec<f32> = pts64.iter().map(|&v| v as f32).collect();
        let (mut r2, mut a2) = (vec![0f32; nr], vec![0f32; na]);
        let s32 = describe(
            Points::new(&pts32, stride).unwrap(),
            &cfg,
            &mut scratch,
            &mut r2,
            &mut a2,
        );
        assert_eq!(s32, Ok(s));
        assert_eq!(
            (&r2, &a2),
            (&*r0, &*a0),
            "float32 and float64 points differ"
        );
    }
});
