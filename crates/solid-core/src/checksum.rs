//! The checksum of every byte format of the crate (the database file, a place on the wire, a
//! compact cloud): CRC-32, so that each format checks its bytes the same way.
//!
//! It is the CRC-32 of IEEE 802.3 (zlib's and PNG's: reflected polynomial `0xEDB88320`, all
//! ones in and out), computed by `crc32fast`, which folds with carry-less multiplication where
//! the CPU has it: a map's sections are checked at several GB/s as they are read.

/// CRC-32 (IEEE 802.3, the one of zlib and PNG) of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    crc32fast::hash(bytes)
}

/// [`crc32`] of bytes that arrive in pieces.
#[derive(Debug, Clone, Default)]
pub struct Crc32(crc32fast::Hasher);

impl Crc32 {
    /// Folds in the next bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        self.0.update(bytes);
    }

    /// Folds in the bytes `other` was given, as if they followed this one's.
    pub fn combine(&mut self, other: &Crc32) {
        self.0.combine(&other.0);
    }

    /// The checksum of every byte folded in.
    pub fn finish(self) -> u32 {
        self.0.finalize()
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn crc32_matches_the_standard_check_value() {
        assert_eq!(super::crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn pieces_agree_with_the_bitwise_definition() {
        let bytes: alloc::vec::Vec<u8> = (0..1000u32)
            .map(|i| i.wrapping_mul(2_654_435_761) as u8)
            .collect();
        // The definition, a bit at a time.
        let bitwise = |b: &[u8]| {
            let mut c = !0u32;
            for &x in b {
                c ^= u32::from(x);
                for _ in 0..8 {
                    c = if c & 1 != 0 {
                        0xEDB8_8320 ^ (c >> 1)
                    } else {
                        c >> 1
                    };
                }
            }
            !c
        };
        for len in [0, 1, 7, 8, 9, 63, 64, 65, 127, 1000] {
            assert_eq!(super::crc32(&bytes[..len]), bitwise(&bytes[..len]));
        }
        let mut c = super::Crc32::default();
        for piece in bytes.chunks(13) {
            c.update(piece);
        }
        assert_eq!(c.finish(), bitwise(&bytes));
        // Pieces checked apart, then combined in order.
        let mut whole = super::Crc32::default();
        for piece in bytes.chunks(300) {
            let mut c = super::Crc32::default();
            c.update(piece);
            whole.combine(&c);
        }
        assert_eq!(whole.finish(), bitwise(&bytes));
    }
}
