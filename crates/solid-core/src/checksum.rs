//! The checksum of every byte format of the crate (the database file, a place on the wire, a
//! compact cloud): CRC-32, so that each format checks its bytes the same way.

/// `TABLES[0]` is the byte-at-a-time table; `TABLES[k][b]` advances `TABLES[0][b]` by `k` zero
/// bytes, so that eight bytes are folded per step (slicing by 8).
const TABLES: [[u32; 256]; 8] = {
    let mut t = [[0u32; 256]; 8];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
            k += 1;
        }
        t[0][i] = c;
        i += 1;
    }
    let mut i = 0;
    while i < 256 {
        let mut k = 1;
        while k < 8 {
            let prev = t[k - 1][i];
            t[k][i] = (prev >> 8) ^ t[0][(prev & 0xff) as usize];
            k += 1;
        }
        i += 1;
    }
    t
};

/// CRC-32 (IEEE 802.3, the one of zlib and PNG) of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = Crc32::default();
    c.update(bytes);
    c.finish()
}

/// [`crc32`] of bytes that arrive in pieces.
#[derive(Debug, Clone, Copy)]
pub struct Crc32(u32);

impl Default for Crc32 {
    fn default() -> Self {
        Crc32(!0)
    }
}

impl Crc32 {
    /// Folds in the next bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        let t = &TABLES;
        let mut c = self.0;
        let mut words = bytes.chunks_exact(8);
        for w in &mut words {
            let lo = c ^ u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
            c = t[7][(lo & 0xff) as usize]
                ^ t[6][((lo >> 8) & 0xff) as usize]
                ^ t[5][((lo >> 16) & 0xff) as usize]
                ^ t[4][(lo >> 24) as usize]
                ^ t[3][w[4] as usize]
                ^ t[2][w[5] as usize]
                ^ t[1][w[6] as usize]
                ^ t[0][w[7] as usize];
        }
        for &b in words.remainder() {
            c = t[0][((c ^ b as u32) & 0xff) as usize] ^ (c >> 8);
        }
        self.0 = c;
    }

    /// The checksum of every byte folded in.
    pub fn finish(self) -> u32 {
        !self.0
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn crc32_matches_the_standard_check_value() {
        assert_eq!(super::crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn pieces_and_slicing_agree_with_the_bytewise_definition() {
        let bytes: alloc::vec::Vec<u8> = (0..1000u32)
            .map(|i| i.wrapping_mul(2_654_435_761) as u8)
            .collect();
        let bytewise = |b: &[u8]| {
            let mut c = !0u32;
            for &x in b {
                c = super::TABLES[0][((c ^ x as u32) & 0xff) as usize] ^ (c >> 8);
            }
            !c
        };
        for len in [0, 1, 7, 8, 9, 63, 1000] {
            assert_eq!(super::crc32(&bytes[..len]), bytewise(&bytes[..len]));
        }
        let mut c = super::Crc32::default();
        for piece in bytes.chunks(13) {
            c.update(piece);
        }
        assert_eq!(c.finish(), bytewise(&bytes));
    }
}
