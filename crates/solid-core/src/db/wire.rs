//! The wire form of one place, for exchange between robots.

use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;

use super::format::{is_bin_value, Reader};
use super::DbError;
use crate::checksum::crc32;
use crate::Error;

/// One place decoded from its wire form.
#[derive(Debug, Clone, PartialEq)]
pub struct Place {
    /// R-SOLiD.
    pub r: Vec<f32>,
    /// A-SOLiD.
    pub a: Vec<f32>,
    /// Fingerprint of the config that made it.
    pub fingerprint: u64,
    /// Whether it travelled quantised (then `r` and `a` are approximations).
    pub quantized: bool,
}

const WIRE_MAGIC: [u8; 2] = *b"SP";
const WIRE_VERSION: u8 = 1;
const WIRE_F32: u8 = 1;
const WIRE_U8: u8 = 2;
const WIRE_HEADER: usize = 16;

/// Encodes one place (R-SOLiD, A-SOLiD and config fingerprint) for exchange between robots.
///
/// Layout (little-endian): `"SP"`, version `u8` (1), kind `u8` (1 = float32, 2 = quantised),
/// `u16` n_range, `u16` n_azimuth, `u64` fingerprint, then the payload, then a `u32` CRC-32 of
/// everything before it. Float32 payload: the vectors as `f32` (400 B for Nr = 40, Na = 60; 420 B
/// in all). Quantised payload: per vector an `f32` scale (its maximum) and one `u8` per bin,
/// `round(255 · √(v / max))` (square-root companding keeps relative precision in the sparse far
/// bins): 124 + 4 = 128 B in all for the defaults.
///
/// # Errors
/// [`Error::InvalidParameter`] when a vector is longer than 65535 values, or holds a negative or
/// non-finite value (no descriptor does, SPEC §3); [`Error::Empty`] when a vector is empty.
pub fn encode_place(
    r: &[f32],
    a: &[f32],
    fingerprint: u64,
    quantized: bool,
) -> Result<Vec<u8>, Error> {
    for (name, v) in [("r_solid", r), ("a_solid", a)] {
        if v.is_empty() {
            return Err(Error::Empty { what: name });
        }
        if v.len() > u16::MAX as usize {
            return Err(Error::InvalidParameter {
                name,
                value: v.len() as f64,
                expected: "at most 65535 values",
            });
        }
        if let Some(bad) = v.iter().find(|x| !is_bin_value(**x)) {
            return Err(Error::InvalidParameter {
                name,
                value: f64::from(*bad),
                expected: "finite, non-negative values",
            });
        }
    }
    let payload = if quantized {
        8 + r.len() + a.len()
    } else {
        4 * (r.len() + a.len())
    };
    let mut out = Vec::with_capacity(WIRE_HEADER + payload + 4);
    out.extend_from_slice(&WIRE_MAGIC);
    out.push(WIRE_VERSION);
    out.push(if quantized { WIRE_U8 } else { WIRE_F32 });
    out.extend_from_slice(&(r.len() as u16).to_le_bytes());
    out.extend_from_slice(&(a.len() as u16).to_le_bytes());
    out.extend_from_slice(&fingerprint.to_le_bytes());
    if quantized {
        for v in [r, a] {
            let max = v.iter().fold(0.0f32, |m, &x| m.max(x));
            out.extend_from_slice(&max.to_le_bytes());
            for &x in v {
                let q = if max > 0.0 {
                    libm::round(255.0 * libm::sqrt(f64::from(x) / f64::from(max))) as u8
                } else {
                    0
                };
                out.push(q);
            }
        }
    } else {
        for &x in r.iter().chain(a) {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    let crc = crc32(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    Ok(out)
}

/// Decodes a place encoded by [`encode_place`].
///
/// # Errors
/// [`DbError::Format`] naming the reason: not a place, an unknown version or kind, a wrong
/// length, a checksum mismatch, negative or non-finite values (which no encoder writes).
pub fn decode_place(bytes: &[u8]) -> Result<Place, DbError> {
    let bad = |reason: String| DbError::Format { file: None, reason };
    if bytes.len() < WIRE_HEADER + 4 || bytes[..2] != WIRE_MAGIC {
        return Err(bad(String::from(
            "not a SOLiD place (wrong magic or too short)",
        )));
    }
    if bytes[2] != WIRE_VERSION {
        return Err(bad(format!(
            "place format version {} is not supported (this library reads {WIRE_VERSION})",
            bytes[2]
        )));
    }
    let kind = bytes[3];
    let mut rd = Reader { b: bytes, at: 4 };
    let nr = u16::from_le_bytes(rd.take()) as usize;
    let na = u16::from_le_bytes(rd.take()) as usize;
    let fingerprint = rd.u64();
    let payload = match kind {
        WIRE_F32 => 4 * (nr + na),
        WIRE_U8 => 8 + nr + na,
        _ => return Err(bad(format!("unknown place kind {kind}"))),
    };
    let expected = WIRE_HEADER + payload + 4;
    if bytes.len() != expected {
        return Err(bad(format!(
            "wrong length: {} bytes, expected {expected}",
            bytes.len()
        )));
    }
    let stored = u32::from_le_bytes([
        bytes[expected - 4],
        bytes[expected - 3],
        bytes[expected - 2],
        bytes[expected - 1],
    ]);
    if crc32(&bytes[..expected - 4]) != stored {
        return Err(bad(String::from(
            "checksum mismatch: the place is corrupted",
        )));
    }
    let (r, a) = if kind == WIRE_F32 {
        let r: Vec<f32> = (0..nr).map(|_| rd.f32()).collect();
        let a: Vec<f32> = (0..na).map(|_| rd.f32()).collect();
        (r, a)
    } else {
        let mut dequant = |n: usize| -> Vec<f32> {
            let max = rd.f32();
            (0..n)
                .map(|_| {
                    let q = f64::from(rd.take::<1>()[0]) / 255.0;
                    (q * q * f64::from(max)) as f32
                })
                .collect()
        };
        let r = dequant(nr);
        let a = dequant(na);
        (r, a)
    };
    if !r.iter().chain(&a).all(|v| is_bin_value(*v)) {
        return Err(bad(String::from(
            "negative or non-finite value in the place",
        )));
    }
    Ok(Place {
        r,
        a,
        fingerprint,
        quantized: kind == WIRE_U8,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_sizes() {
        let r = vec![1.0f32; 40];
        let a = vec![2.0f32; 60];
        assert_eq!(encode_place(&r, &a, 7, false).unwrap().len(), 420);
        assert!(encode_place(&r, &a, 7, true).unwrap().len() <= 200);
    }
}
