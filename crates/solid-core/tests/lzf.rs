//! LZF decoding agrees with a byte-at-a-time oracle on arbitrary and on valid streams, for any
//! output size (the same check the cargo-fuzz target runs, here on stable with proptest).

use proptest::prelude::*;

#[path = "common/lzf_oracle.rs"]
mod oracle;

/// A valid stream: literal runs and copies mixed at random (copies only once there is output).
fn stream() -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(
        (
            any::<bool>(),
            0u8..32,
            any::<u8>(),
            1usize..300,
            any::<u8>(),
        ),
        1..80,
    )
    .prop_map(|toks| {
        let mut out = Vec::new();
        let mut written = 0usize;
        for (lit, n, byte, len, back) in toks {
            if lit || written == 0 {
                out.push(n);
                out.extend(std::iter::repeat_n(byte, usize::from(n) + 1));
                written += usize::from(n) + 1;
            } else {
                let len = len.clamp(3, 264);
                let distance = (usize::from(back) % written.min(8192)) + 1;
                let (hi, lo) = ((distance - 1) >> 8, (distance - 1) & 0xff);
                if len - 2 < 7 {
                    out.push((((len - 2) << 5) | hi) as u8);
                } else {
                    out.push(((7 << 5) | hi) as u8);
                    out.push((len - 9) as u8);
                }
                out.push(lo as u8);
                written += len;
            }
        }
        out
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_bytes(input in prop::collection::vec(any::<u8>(), 0..600), cap in 0usize..4000) {
        oracle::check(&input, cap);
    }

    #[test]
    fn valid_streams(input in stream(), slack in 0usize..40, short in any::<bool>()) {
        let full = oracle::reference(&input, usize::MAX).unwrap().len();
        oracle::check(&input, full + slack);
        oracle::check(&input, if short { full.saturating_sub(slack + 1) } else { full });
    }
}
