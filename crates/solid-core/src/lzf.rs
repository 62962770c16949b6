//! LZF decompression (the liblzf format, used by PCD's `binary_compressed` data), bounded and
//! allocation-free.
//!
//! [`decompress_into`] decodes into a caller-owned slice and never writes, or reads, past either
//! end: a stream that would expand beyond `output.len()` stops at the first token that would
//! overflow with [`LzfError::OutputTooSmall`], so a decompression bomb costs at most one pass over
//! `output.len()` bytes. [`max_decompressed_len`] bounds what any stream of a given length can
//! decode to, so that a caller can refuse an impossible declared size before allocating it.
//!
//! ```
//! use solid_lidar::lzf::{decompress_into, LzfError};
//!
//! // a literal run "abc", then a back-reference of 5 bytes at distance 3
//! let stream = [2, b'a', b'b', b'c', 0x60, 2];
//! let mut out = [0u8; 8];
//! assert_eq!(decompress_into(&stream, &mut out), Ok(8));
//! assert_eq!(&out, b"abcabcab");
//! let mut small = [0u8; 4];
//! assert!(matches!(decompress_into(&stream, &mut small), Err(LzfError::OutputTooSmall { .. })));
//! ```

pub use crate::error::LzfError;

/// The most bytes any LZF stream of `input_len` bytes can decode to (88 per input byte: a
/// 3-byte token copies at most 264 bytes), saturating at `usize::MAX`.
pub const fn max_decompressed_len(input_len: usize) -> usize {
    input_len.saturating_mul(88)
}

/// Decodes the LZF stream `input` into `output` and returns the number of bytes written.
///
/// The decoder is liblzf's: a control byte below 32 starts a literal run of `ctrl + 1` bytes;
/// otherwise its top 3 bits (plus a length byte when they are all set) give a copy of 3 to 264
/// bytes from up to 8 KiB back in the output, overlapping copies allowed. A caller that knows the
/// decoded size passes an output of exactly that size and checks the returned count. Bytes of
/// `output` past the returned count are unspecified (the decoder copies in fixed-size blocks).
///
/// # Errors
/// [`LzfError::OutputTooSmall`] as soon as a token would write past `output.len()`,
/// [`LzfError::Truncated`] when a token runs past the end of `input`, and
/// [`LzfError::BadReference`] when a copy starts before the start of the output.
///
/// # Panics
/// Never.
pub fn decompress_into(input: &[u8], output: &mut [u8]) -> Result<usize, LzfError> {
    let (n_in, cap) = (input.len(), output.len());
    let (mut ip, mut op) = (0usize, 0usize);
    while ip < n_in {
        let at = ip;
        let ctrl = usize::from(input[ip]);
        ip += 1;
        if ctrl < 32 {
            let len = ctrl + 1;
            if ip + 32 <= n_in && op + 32 <= cap {
                // Room on both sides: copy a fixed 32 bytes (two vector moves instead of a
                // variable-length memcpy); the bytes past `len` are overwritten by what follows.
                output[op..op + 32].copy_from_slice(&input[ip..ip + 32]);
                ip += len;
                op += len;
                continue;
            }
            let src = input
                .get(ip..ip + len)
                .ok_or(LzfError::Truncated { offset: at })?;
            let dst = output
                .get_mut(op..op + len)
                .ok_or(LzfError::OutputTooSmall {
                    needed: op + len,
                    capacity: cap,
                })?;
            dst.copy_from_slice(src);
            ip += len;
            op += len;
            continue;
        }
        let mut len = ctrl >> 5;
        if len == 7 {
            len += usize::from(*input.get(ip).ok_or(LzfError::Truncated { offset: at })?);
            ip += 1;
        }
        let low = usize::from(*input.get(ip).ok_or(LzfError::Truncated { offset: at })?);
        ip += 1;
        len += 2;
        let distance = ((ctrl & 0x1f) << 8) + low + 1;
        if distance > op {
            return Err(LzfError::BadReference {
                offset: at,
                distance,
                written: op,
            });
        }
        if len > cap - op {
            return Err(LzfError::OutputTooSmall {
                needed: op + len,
                capacity: cap,
            });
        }
        let from = op - distance;
        // Copy in fixed 8-byte (or 4-byte) chunks, in order: with `distance` at least the chunk
        // size each chunk reads bytes already written, which is exactly LZF's overlapping copy.
        // Bytes past `len` (at most one chunk) are overwritten by what follows.
        if distance >= 8 && cap - op >= len + 7 {
            let mut k = 0;
            while k < len {
                output.copy_within(from + k..from + k + 8, op + k);
                k += 8;
            }
        } else if distance >= 4 && cap - op >= len + 3 {
            let mut k = 0;
            while k < len {
                output.copy_within(from + k..from + k + 4, op + k);
                k += 4;
            }
        } else {
            // Near the end of the output, or a run of 1 to 3 repeated bytes: byte by byte.
            for k in 0..len {
                output[op + k] = output[from + k];
            }
        }
        op += len;
    }
    Ok(op)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn literal_and_references() {
        let mut out = [0u8; 20];
        assert_eq!(decompress_into(&[0, b'z', 0xE0, 10, 0], &mut out), Ok(20));
        assert_eq!(out, [b'z'; 20]);
        let mut out = [0u8; 8];
        assert_eq!(
            decompress_into(&[2, b'a', b'b', b'c', 0x60, 2], &mut out),
            Ok(8)
        );
        assert_eq!(&out, b"abcabcab");
        // a shorter stream into a larger output: the count says how much was written
        let mut big = [0u8; 16];
        assert_eq!(decompress_into(&[1, 7, 9], &mut big), Ok(2));
        assert_eq!(decompress_into(&[], &mut big), Ok(0));
    }

    #[test]
    fn malformed_streams_are_errors() {
        let mut out = [0u8; 64];
        assert_eq!(
            decompress_into(&[5, b'a', b'b'], &mut out),
            Err(LzfError::Truncated { offset: 0 })
        );
        assert_eq!(
            decompress_into(&[0, b'z', 0xE0], &mut out),
            Err(LzfError::Truncated { offset: 2 })
        );
        assert_eq!(
            decompress_into(&[0, b'z', 0xE0, 1], &mut out),
            Err(LzfError::Truncated { offset: 2 })
        );
        assert_eq!(
            decompress_into(&[0, b'z', 0x20, 5], &mut out),
            Err(LzfError::BadReference {
                offset: 2,
                distance: 6,
                written: 1
            })
        );
        assert_eq!(
            decompress_into(&[0x20, 0], &mut out),
            Err(LzfError::BadReference {
                offset: 0,
                distance: 1,
                written: 0
            })
        );
    }

    #[test]
    fn a_bomb_stops_at_the_output_bound() {
        // one literal then 10,000 maximal copies: 2.6 MB from 30 kB, into a 1 KiB output
        let mut stream = [0u8; 2 + 3 * 10_000];
        stream[0] = 0;
        stream[1] = 0xAB;
        for t in 0..10_000 {
            stream[2 + 3 * t..5 + 3 * t].copy_from_slice(&[0xE0, 255, 0]);
        }
        let mut out = [0u8; 1024];
        // 1 + 3 × 264 = 793 bytes fit; the fourth copy would need 1057
        assert_eq!(
            decompress_into(&stream, &mut out),
            Err(LzfError::OutputTooSmall {
                needed: 1057,
                capacity: 1024
            })
        );
        assert!(max_decompressed_len(stream.len()) > 264 * 10_000);
        assert_eq!(max_decompressed_len(usize::MAX), usize::MAX);
    }
}
