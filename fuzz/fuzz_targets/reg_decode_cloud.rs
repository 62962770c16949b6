//! `reg::decode_cloud` (the wire form of a prepared cloud's points) on arbitrary bytes: never a
//! panic (ASan). What it accepts is finite points that prepare into a cloud, and that encode
//! again with the header's grid and bits.
#![no_main]

use libfuzzer_sys::fuzz_target;
use solid_lidar::reg::{decode_cloud, encode_cloud, PreparedCloud, RegConfig};

fuzz_target!(|data: &[u8]| {
    let Ok(pts) = decode_cloud(data) else {
        return;
    };
    assert!(pts.iter().flatten().all(|v| v.is_finite()));
    let grid = f64::from(f32::from_le_bytes([data[4], data[5], data[6], data[7]]));
    let again = encode_cloud(&pts, grid, data[3]).expect("decoded points encode again");
    assert_eq!(
        decode_cloud(&again).expect("encoded points decode").len(),
        pts.len()
    );
    PreparedCloud::from_downsampled(&pts, &RegConfig::default()).expect("decoded points prepare");
});
