//! The LZF oracle shared by the stable property test (tests/lzf.rs) and the cargo-fuzz target
//! (fuzz/fuzz_targets/lzf.rs): a byte-at-a-time decoder written from the format's description,
//! and the check that `decompress_into` agrees with it on any input and output size.

use solid_lidar::lzf::{decompress_into, max_decompressed_len, LzfError};

/// The format, one byte at a time, growing a Vec.
pub fn reference(input: &[u8], cap: usize) -> Result<Vec<u8>, LzfError> {
    let mut out = Vec::new();
    let mut ip = 0;
    while ip < input.len() {
        let at = ip;
        let ctrl = input[ip] as usize;
        ip += 1;
        if ctrl < 32 {
            let lit = input
                .get(ip..ip + ctrl + 1)
                .ok_or(LzfError::Truncated { offset: at })?;
            if out.len() + lit.len() > cap {
                return Err(LzfError::OutputTooSmall {
                    needed: out.len() + lit.len(),
                    capacity: cap,
                });
            }
            out.extend_from_slice(lit);
            ip += ctrl + 1;
            continue;
        }
        let mut len = ctrl >> 5;
        if len == 7 {
            len += *input.get(ip).ok_or(LzfError::Truncated { offset: at })? as usize;
            ip += 1;
        }
        let low = *input.get(ip).ok_or(LzfError::Truncated { offset: at })? as usize;
        ip += 1;
        let distance = ((ctrl & 0x1f) << 8) + low + 1;
        if distance > out.len() {
            return Err(LzfError::BadReference {
                offset: at,
                distance,
                written: out.len(),
            });
        }
        if out.len() + len + 2 > cap {
            return Err(LzfError::OutputTooSmall {
                needed: out.len() + len + 2,
                capacity: cap,
            });
        }
        for _ in 0..len + 2 {
            out.push(out[out.len() - distance]);
        }
    }
    Ok(out)
}

/// Decodes `input` into an output of `cap` bytes with `decompress_into` and with [`reference`]:
/// same count and bytes, or the same error; never more than `max_decompressed_len`.
pub fn check(input: &[u8], cap: usize) {
    let mut out = vec![0u8; cap];
    let got = decompress_into(input, &mut out);
    match (got, reference(input, cap)) {
        (Ok(n), Ok(want)) => {
            assert_eq!(n, want.len());
            assert_eq!(&out[..n], &want[..]);
            assert!(n <= max_decompressed_len(input.len()));
        }
        (Err(a), Err(b)) => assert_eq!(a, b),
        (a, b) => panic!("decoder {a:?} but reference {b:?}"),
    }
}
