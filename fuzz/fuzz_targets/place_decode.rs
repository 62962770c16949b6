//! `decode_place` on arbitrary bytes: never a panic (ASan). What it accepts holds finite,
//! non-negative vectors, encodes again, and (float32 places) decodes to the same values.
#![no_main]

use libfuzzer_sys::fuzz_target;
use solid_lidar::db::{decode_place, encode_place};

fuzz_target!(|data: &[u8]| {
    let Ok(p) = decode_place(data) else {
        return;
    };
    assert!(p.r.iter().chain(&p.a).all(|v| v.is_finite() && *v >= 0.0));
    let again = encode_place(&p.r, &p.a, p.fingerprint, p.quantized)
        .expect("a decoded place encodes again");
    if !p.quantized {
        assert_eq!(again, data, "float32 places are exact");
    }
    let q = decode_place(&again).expect("an encoded place decodes");
    assert_eq!(
        (q.r.len(), q.a.len(), q.fingerprint),
        (p.r.len(), p.a.len(), p.fingerprint)
    );
});
