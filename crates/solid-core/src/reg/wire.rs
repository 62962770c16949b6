//! A compact, quantised encoding of one place's cloud (its fine points), for the robot that is
//! asked to verify a loop with a place another robot saw.
//!
//! Multi-robot exchange stays descriptor-only ([`crate::db::encode_place`]); a robot sends a
//! place's cloud only when a peer asks to verify a candidate. The receiver rebuilds the
//! prepared cloud with [`super::PreparedCloud::from_downsampled`], exactly as the sender built
//! its own from the same fine points (the coarse level is voxelised from them on both sides).
//!
//! Each point is split into the index of its cell on an origin-anchored grid of edge `grid`
//! (21 bits per axis) and its offset within the cell, quantised to `bits` bits per axis. The
//! cells' Morton codes (x, y, z bits interleaved), sorted, are sent as LEB128 varints of their
//! differences: neighbouring cells of a surface are close in Morton order, so most differences
//! take one or two bytes. The offsets follow, bit-packed. A point decodes to the centre of its
//! quantisation step: at most `grid / 2^(bits+1)` off per axis.
//!
//! ```text
//! offset  size  field
//! 0       2     magic "SC"
//! 2       1     format version (1)
//! 3       1     bits per axis of the offsets (1..=16)
//! 4       4     f32 grid edge (metres)
//! 8       4     u32 point count n
//! 12      ...   n varints: Morton code differences, in increasing code order
//! ...     ...   ⌈3·bits·n / 8⌉ bytes: offsets x, y, z per point, in the same order, LSB first
//! end-4   4     u32 CRC-32 (IEEE) of every byte before it
//! ```
//!
//! 8 bits per axis keep a decoded cloud registering as the original; sizes and pose changes per
//! setting: docs/performance.md#cloud-wire-form.

use alloc::vec::Vec;

use super::RegError;
use crate::checksum::crc32;
use crate::Error;

const MAGIC: [u8; 2] = *b"SC";
const VERSION: u8 = 1;
const HEADER: usize = 12;
/// Cell indices are biased by 2^20 into 21 bits per axis.
const BIAS: i64 = 1 << 20;

/// Offset bits per axis by default: 8, so a point moves by at most `grid / 512` per axis (1 mm
/// on a 0.5 m grid), far below what registration resolves.
pub const DEFAULT_BITS: u8 = 8;

/// Spreads the low 21 bits of `v` to every third bit.
fn spread(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// Inverse of [`spread`].
fn compact(v: u64) -> u64 {
    let mut x = v & 0x1249_2492_4924_9249;
    x = (x | x >> 2) & 0x10c3_0c30_c30c_30c3;
    x = (x | x >> 4) & 0x100f_00f0_0f00_f00f;
    x = (x | x >> 8) & 0x001f_0000_ff00_00ff;
    x = (x | x >> 16) & 0x001f_0000_0000_ffff;
    x = (x | x >> 32) & 0x1f_ffff;
    x
}

fn morton(c: [u64; 3]) -> u64 {
    spread(c[0]) | spread(c[1]) << 1 | spread(c[2]) << 2
}

fn unmorton(m: u64) -> [u64; 3] {
    [compact(m), compact(m >> 1), compact(m >> 2)]
}

/// Encodes `points` (x, y, z, metres) on a grid of edge `grid` metres with `bits` bits per axis
/// for the position within a cell. The order of the points is not kept (they are sent in Morton
/// order of their cells). Allocates the output and a sort buffer.
///
/// # Errors
/// [`Error::InvalidParameter`] (inside [`RegError::Core`]) naming `grid` (not finite and > 0),
/// `bits` (not in 1..=16) or `points` (a non-finite coordinate, a coordinate beyond
/// `2^20 · grid` metres, or more than `u32::MAX` points).
pub fn encode_cloud(points: &[[f64; 3]], grid: f64, bits: u8) -> Result<Vec<u8>, RegError> {
    if !(grid.is_finite() && grid > 0.0 && (grid as f32) > 0.0) {
        return Err(Error::InvalidParameter {
            name: "grid",
            value: grid,
            expected: "a finite grid edge > 0 metres",
        }
        .into());
    }
    if !(1..=16).contains(&bits) {
        return Err(Error::InvalidParameter {
            name: "bits",
            value: f64::from(bits),
            expected: "an integer in 1..=16",
        }
        .into());
    }
    if points.len() > u32::MAX as usize {
        return Err(Error::InvalidParameter {
            name: "points",
            value: points.len() as f64,
            expected: "at most 2^32 - 1 points",
        }
        .into());
    }
    // The grid the decoder sees is the f32 one: quantise against exactly that.
    let g = f64::from(grid as f32);
    let steps = f64::from(1u32 << bits);
    let max_q = (1u64 << bits) - 1;
    // Each point as one integer, its cell's Morton code above its three offsets: sorting the
    // integers sorts by (cell, offsets), and a primitive sort is cheaper than one by key.
    let mut cells: Vec<u128> = Vec::with_capacity(points.len());
    for p in points {
        let mut c = [0u64; 3];
        let mut q = [0u16; 3];
        for d in 0..3 {
            let u = p[d] / g;
            if !(u.is_finite() && u.abs() < BIAS as f64) {
                return Err(Error::InvalidParameter {
                    name: "points",
                    value: p[d],
                    expected: "finite coordinates within 2^20 grid cells of the origin",
                }
                .into());
            }
            let i = libm::floor(u);
            c[d] = (i as i64 + BIAS) as u64;
            q[d] = ((u - i) * steps).clamp(0.0, max_q as f64) as u16;
        }
        let q = (u128::from(q[0]) << 32) | (u128::from(q[1]) << 16) | u128::from(q[2]);
        cells.push((u128::from(morton(c)) << 48) | q);
    }
    cells.sort_unstable();
    let mut out =
        Vec::with_capacity(HEADER + points.len() * (2 + (3 * bits as usize).div_ceil(8)) + 4);
    out.extend_from_slice(&MAGIC);
    out.push(VERSION);
    out.push(bits);
    out.extend_from_slice(&(grid as f32).to_le_bytes());
    out.extend_from_slice(&(points.len() as u32).to_le_bytes());
    let mut prev = 0u64;
    for &cell in &cells {
        let m = (cell >> 48) as u64;
        let mut d = m - prev;
        prev = m;
        loop {
            let byte = (d & 0x7f) as u8;
            d >>= 7;
            if d == 0 {
                out.push(byte);
                break;
            }
            out.push(byte | 0x80);
        }
    }
    let mut acc = 0u64;
    let mut n_acc = 0u32;
    for &cell in &cells {
        for v in [(cell >> 32) as u16, (cell >> 16) as u16, cell as u16] {
            acc |= u64::from(v) << n_acc;
            n_acc += u32::from(bits);
            while n_acc >= 8 {
                out.push(acc as u8);
                acc >>= 8;
                n_acc -= 8;
            }
        }
    }
    if n_acc > 0 {
        out.push(acc as u8);
    }
    let crc = crc32(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    Ok(out)
}

/// Checks what says a cloud's bytes are whole, without decoding them: the magic, the version and
/// the checksum (what a store of clouds checks before it hands one out or copies it).
///
/// # Errors
/// [`RegError::Format`] naming the reason, as [`decode_cloud`].
pub fn check_cloud(bytes: &[u8]) -> Result<(), RegError> {
    let bad = |reason: &'static str| RegError::Format { reason };
    if bytes.len() < HEADER + 4 || bytes[..2] != MAGIC {
        return Err(bad("wrong magic or too short"));
    }
    if bytes[2] != VERSION {
        return Err(bad("unsupported format version"));
    }
    let stored = u32::from_le_bytes([
        bytes[bytes.len() - 4],
        bytes[bytes.len() - 3],
        bytes[bytes.len() - 2],
        bytes[bytes.len() - 1],
    ]);
    if crc32(&bytes[..bytes.len() - 4]) != stored {
        return Err(bad("checksum mismatch: the cloud is corrupted"));
    }
    Ok(())
}

/// The number of points of a cloud encoded by [`encode_cloud`], without decoding it.
///
/// # Errors
/// As [`check_cloud`].
pub fn cloud_points(bytes: &[u8]) -> Result<usize, RegError> {
    check_cloud(bytes)?;
    Ok(u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize)
}

/// Decodes a cloud encoded by [`encode_cloud`] (points in Morton order of their cells).
///
/// # Errors
/// [`RegError::Format`] naming the reason: not a cloud, an unknown version, a bad header, a
/// wrong length, a checksum mismatch.
pub fn decode_cloud<B: AsRef<[u8]>>(bytes: B) -> Result<Vec<[f64; 3]>, RegError> {
    let bytes = bytes.as_ref();
    let bad = |reason: &'static str| RegError::Format { reason };
    check_cloud(bytes)?;
    let bits = bytes[3];
    if !(1..=16).contains(&bits) {
        return Err(bad("offset bits outside 1..=16"));
    }
    let grid = f64::from(f32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]));
    if !(grid.is_finite() && grid > 0.0) {
        return Err(bad("grid edge not finite and positive"));
    }
    let n = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize;
    let body = &bytes[HEADER..bytes.len() - 4];
    // Every point takes at least one varint byte: bound n before allocating.
    if n > body.len() {
        return Err(bad("point count larger than the payload"));
    }
    let mut codes = Vec::with_capacity(n);
    let mut at = 0;
    let mut prev = 0u64;
    for _ in 0..n {
        let mut d = 0u64;
        let mut shift = 0;
        loop {
            let Some(&byte) = body.get(at) else {
                return Err(bad("truncated cell codes"));
            };
            at += 1;
            if shift > 63 || (shift == 63 && byte > 1) {
                return Err(bad("cell code difference overflows"));
            }
            d |= u64::from(byte & 0x7f) << shift;
            shift += 7;
            if byte & 0x80 == 0 {
                break;
            }
        }
        prev = prev
            .checked_add(d)
            .filter(|&m| m < 1 << 63)
            .ok_or(bad("cell code overflows"))?;
        codes.push(prev);
    }
    let packed = &body[at..];
    if packed.len() != (3 * bits as usize * n).div_ceil(8) {
        return Err(bad("wrong length of the offsets"));
    }
    let steps = f64::from(1u32 << bits);
    let mask = (1u64 << bits) - 1;
    let mut acc = 0u64;
    let mut n_acc = 0u32;
    let mut bytes_in = packed.iter();
    let mut next = || -> u64 {
        while n_acc < u32::from(bits) {
            // Lengths were checked: the packed bytes hold every offset.
            acc |= u64::from(*bytes_in.next().unwrap_or(&0)) << n_acc;
            n_acc += 8;
        }
        let v = acc & mask;
        acc >>= bits;
        n_acc -= u32::from(bits);
        v
    };
    let mut out = Vec::with_capacity(n);
    for m in codes {
        let c = unmorton(m);
        let mut p = [0.0; 3];
        for d in 0..3 {
            let q = next() as f64;
            p[d] = ((c[d] as i64 - BIAS) as f64 + (q + 0.5) / steps) * grid;
        }
        out.push(p);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;

    #[test]
    fn the_bytes_of_a_known_cloud() {
        // Written by the encoder before it sorted packed integers (0.1.0 of 2026-12-06): the
        // format is the same, byte for byte, with a duplicate point and two in one cell.
        let pts = [
            [1.3, -2.7, 0.4],
            [1.31, -2.69, 0.41],
            [-5.0, 3.25, 1.0],
            [0.0, 0.0, 0.0],
            [1.3, -2.7, 0.4],
            [7.77, 0.01, -3.3],
        ];
        let want: [u8; 72] = [
            83, 67, 1, 8, 0, 0, 0, 63, 6, 0, 0, 0, 205, 148, 201, 164, 146, 201, 164, 146, 57, 203,
            179, 219, 237, 182, 219, 237, 182, 27, 0, 0, 224, 217, 237, 182, 219, 237, 182, 219,
            13, 136, 222, 237, 182, 219, 237, 182, 219, 13, 138, 5, 102, 153, 153, 204, 153, 153,
            204, 158, 158, 209, 0, 128, 0, 0, 0, 0, 176, 59, 139, 213,
        ];
        assert_eq!(encode_cloud(&pts, 0.5, 8).unwrap(), want);
    }

    #[test]
    fn morton_round_trips() {
        for c in [
            [0, 0, 0],
            [1, 2, 3],
            [0x1f_ffff, 0, 0x1f_ffff],
            [12345, 678_910, 2_000_000],
        ] {
            assert_eq!(unmorton(morton(c)), c);
        }
    }

    #[test]
    fn round_trip_within_the_quantisation_step() {
        let mut pts = vec![];
        for i in 0..500 {
            let f = i as f64;
            pts.push([
                libm::sin(f) * 40.0,
                libm::cos(f * 0.7) * 30.0 - 5.0,
                f * 0.01 - 2.0,
            ]);
        }
        pts.push([0.0, 0.0, 0.0]);
        pts.push([-0.25, 0.25, -1e-9]);
        for bits in [1u8, 4, 8, 16] {
            let bytes = encode_cloud(&pts, 0.5, bits).unwrap();
            let back = decode_cloud(&bytes).unwrap();
            assert_eq!(back.len(), pts.len());
            let tol = 0.5 / f64::from(1u32 << (bits + 1)) + 1e-9;
            // Match each decoded point to its nearest original.
            for b in &back {
                let best = pts
                    .iter()
                    .map(|p| (0..3).map(|d| libm::fabs(p[d] - b[d])).fold(0.0, f64::max))
                    .fold(f64::INFINITY, f64::min);
                assert!(best <= tol, "bits {bits}: {best} > {tol}");
            }
        }
        assert!(decode_cloud(encode_cloud(&[], 0.5, 8).unwrap())
            .unwrap()
            .is_empty());
    }

    #[test]
    fn bad_input_and_corruption_are_errors() {
        let pts = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]];
        for (grid, bits) in [(0.0, 8), (f64::NAN, 8), (0.5, 0), (0.5, 17)] {
            assert!(matches!(
                encode_cloud(&pts, grid, bits),
                Err(RegError::Core(_))
            ));
        }
        assert!(encode_cloud(&[[f64::NAN, 0.0, 0.0]], 0.5, 8).is_err());
        assert!(encode_cloud(&[[1e9, 0.0, 0.0]], 0.5, 8).is_err());
        let bytes = encode_cloud(&pts, 0.5, 8).unwrap();
        for i in 0..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x10;
            assert!(decode_cloud(&b).is_err(), "flip at {i}");
        }
        for len in 0..bytes.len() {
            assert!(decode_cloud(&bytes[..len]).is_err());
        }
    }
}
