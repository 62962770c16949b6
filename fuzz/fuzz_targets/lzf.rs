//! LZF decoding of arbitrary bytes into an output of arbitrary size (the first two bytes): never
//! a panic or an out-of-bounds access (ASan), never more than the output holds, and the same
//! result as the byte-at-a-time oracle shared with the stable property test.
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "../../crates/solid-core/tests/common/lzf_oracle.rs"]
mod oracle;

fuzz_target!(|data: &[u8]| {
    let (head, input) = data.split_at(data.len().min(2));
    let cap = head.iter().fold(0usize, |a, &b| (a << 8) | b as usize);
    oracle::check(input, cap);
});
