//! Portable, deterministic math helpers.
//!
//! Only IEEE-754 basic operations (`+ - * /`, `sqrt`) are used, which are correctly rounded on every
//! platform, so results are the same bits on x86-64 and AArch64, with or without `std`.

use core::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// tan(π/8): the polynomial below covers `|u| <= TAN_PI_8`.
const TAN_PI_8: f32 = 0.414_213_57;

/// Coefficients of `atan(u) ≈ u · P(u²)` on `|u| <= tan(π/8)`, fitted by least squares on Chebyshev
/// nodes against a 40-digit reference (max abs error 2.9e-13 rad in `f64`), rounded to `f32`:
/// the error is then that of `f32` arithmetic, a few 1e-7 rad, far below any bin width.
const ATAN_FIT: [f64; 8] = [
    0.999_999_999_999_270_9,
    -0.333_333_332_783_842_14,
    0.199_999_931_888_795_25,
    -0.142_853_912_594_656_55,
    0.111_035_349_208_560_91,
    -0.089_932_173_490_933_77,
    0.069_770_056_381_327_31,
    -0.037_701_746_387_426_04,
];

/// [`ATAN_FIT`] in `f32`.
const ATAN_COEFFS: [f32; 8] = {
    let mut c = [0.0; 8];
    let mut i = 0;
    while i < 8 {
        c[i] = ATAN_FIT[i] as f32;
        i += 1;
    }
    c
};

/// `u · P(u²)`, with `P` evaluated by Estrin's scheme (a shorter dependency chain than Horner's).
#[inline(always)]
fn atan_poly(u: f32) -> f32 {
    let c = &ATAN_COEFFS;
    let s = u * u;
    let s2 = s * s;
    let s4 = s2 * s2;
    let p01 = c[0] + c[1] * s;
    let p23 = c[2] + c[3] * s;
    let p45 = c[4] + c[5] * s;
    let p67 = c[6] + c[7] * s;
    let p03 = p01 + s2 * p23;
    let p47 = p45 + s2 * p67;
    u * (p03 + s4 * p47)
}

/// `atan2(y, x)` in radians, in `[-π, π]`; `atan2(0, 0) = 0`. Absolute error below 5e-7, in
/// `f32`: eight lanes to a 256-bit vector, and `f32` division and square root are about twice as
/// fast as `f64`'s ([spec §7](crate::spec#7-matching-the-golden-outputs) allows `f32`).
///
/// Branch-free (selects only) with one division: with `mn <= mx` the absolute values, the octant
/// angle is `atan(mn/mx)`, reduced when `mn/mx > tan(π/8)` by `atan(t) = π/4 + atan((t−1)/(t+1))`,
/// and `(t−k)/(1+kt)` with `t = mn/mx` is `(mn − k·mx)/(mx + k·mn)` for `k` in {0, 1}.
#[inline(always)]
pub(crate) fn atan2(y: f32, x: f32) -> f32 {
    let ax = x.abs();
    let ay = y.abs();
    // Selects, not `f32::max`/`min`: those also order NaN, which costs a compare and a blend.
    let swap = ay > ax;
    let mx = if swap { ay } else { ax };
    let mn = if swap { ax } else { ay };
    let big = mn > TAN_PI_8 * mx;
    let k = if big { 1.0 } else { 0.0 };
    let den = mx + k * mn;
    // den == 0 only at the origin, where mn == 0 too: divide by 1 to get 0.
    let u = (mn - k * mx) / if den == 0.0 { 1.0 } else { den };
    let mut a = k * FRAC_PI_4 + atan_poly(u);
    a = if swap { FRAC_PI_2 - a } else { a };
    a = if x < 0.0 { PI - a } else { a };
    if y < 0.0 {
        -a
    } else {
        a
    }
}

/// Correctly rounded square root (IEEE 754 requires it, so both paths give the same bits); the
/// `std` one is an LLVM intrinsic the compiler can vectorise, `libm`'s is inline assembly.
#[inline(always)]
pub(crate) fn sqrt(x: f64) -> f64 {
    #[cfg(feature = "std")]
    {
        x.sqrt()
    }
    #[cfg(not(feature = "std"))]
    {
        libm::sqrt(x)
    }
}

/// [`sqrt`] of an `f32` (also correctly rounded).
#[inline(always)]
pub(crate) fn sqrtf(x: f32) -> f32 {
    #[cfg(feature = "std")]
    {
        x.sqrt()
    }
    #[cfg(not(feature = "std"))]
    {
        libm::sqrtf(x)
    }
}

/// How a compiled copy of `describe` takes ⌊v⌋ of an `f64`. Every way is exact, so every copy
/// gives the same bits; they differ in the instructions available to them.
pub(crate) trait Floor {
    /// ⌊v⌋ for |v| < 2^51; other inputs (huge, infinite, NaN) give an unspecified value, never
    /// a panic.
    fn floor_i64(v: f64) -> i64;
    /// ⌊v⌋ of an `f32` for 0 <= v < 2^22; other inputs give an unspecified value, never a panic.
    fn floor_u32(v: f32) -> u32;
}

/// ⌊v⌋ with add, subtract and compare only ([`floor_i64`]): vectorises with any SIMD unit.
pub(crate) struct MagicFloor;

impl Floor for MagicFloor {
    #[inline(always)]
    fn floor_i64(v: f64) -> i64 {
        floor_i64(v)
    }
    #[inline(always)]
    fn floor_u32(v: f32) -> u32 {
        // As floor_i64, in 32-bit lanes.
        let r = v + ROUND_MAGIC_F32;
        let nearest = r.to_bits().wrapping_sub(ROUND_MAGIC_F32.to_bits());
        let back = r - ROUND_MAGIC_F32;
        nearest.wrapping_sub(u32::from(back > v))
    }
}

/// ⌊v⌋ with the CPU's rounding instruction (x86 SSE4.1 `roundpd`, AArch64 `frintm`), then the
/// exact conversion of an integral value by [`ROUND_MAGIC`]: two instructions fewer than
/// [`MagicFloor`], for the copies compiled where that instruction exists.
#[cfg(feature = "std")]
pub(crate) struct NativeFloor;

#[cfg(feature = "std")]
impl Floor for NativeFloor {
    #[inline(always)]
    fn floor_i64(v: f64) -> i64 {
        let r = v.floor() + ROUND_MAGIC;
        r.to_bits().wrapping_sub(ROUND_MAGIC.to_bits()) as i64
    }
    #[inline(always)]
    fn floor_u32(v: f32) -> u32 {
        let r = v.floor() + ROUND_MAGIC_F32;
        r.to_bits().wrapping_sub(ROUND_MAGIC_F32.to_bits())
    }
}

/// The floor of the portable copy: the native one where the baseline CPU has it.
#[cfg(all(feature = "std", target_arch = "aarch64"))]
pub(crate) type PortableFloor = NativeFloor;
/// The floor of the portable copy: the native one where the baseline CPU has it.
#[cfg(not(all(feature = "std", target_arch = "aarch64")))]
pub(crate) type PortableFloor = MagicFloor;

/// 1.5 · 2^52: adding it to |v| < 2^51 rounds v to an integer held in the low mantissa bits.
const ROUND_MAGIC: f64 = 6_755_399_441_055_744.0;
/// 1.5 · 2^23, the same for `f32` and |v| < 2^22.
const ROUND_MAGIC_F32: f32 = 12_582_912.0;

/// ⌊v⌋ for |v| < 2^51, with only add, subtract and compare in 64-bit lanes (vectorisable, unlike
/// the saturating `as` cast): `v + 1.5·2^52` lies in [2^52, 2^53), where its bits are those of
/// the magic number plus round-to-nearest(v). Other inputs (huge, infinite, NaN) give an
/// unspecified value, never a panic.
#[inline(always)]
pub(crate) fn floor_i64(v: f64) -> i64 {
    let r = v + ROUND_MAGIC;
    let nearest = r.to_bits().wrapping_sub(ROUND_MAGIC.to_bits()) as i64;
    let back = r - ROUND_MAGIC;
    nearest.wrapping_sub(i64::from(back > v))
}

/// `y as u8` (toward zero, saturating into 0..=255, NaN to 0) in operations that vectorise:
/// the cast itself compiles to a conversion with a scalar fix-up per value, a large part of the
/// bulk add's quantisation loop (docs/performance.md#database). Clamped first (a NaN compares
/// false), then converted toward zero without the fix-up, which a value in 0..=255 never needs.
/// For a caller that needs the code as an `f32` as well, [`floor_to_u8`] compiles better.
#[cfg(any(feature = "alloc", test))]
#[inline(always)]
pub(crate) fn to_u8(y: f32) -> u8 {
    let c = if y > 0.0 { y } else { 0.0 };
    let c = if c < 255.0 { c } else { 255.0 };
    #[allow(unsafe_code)]
    // SAFETY: `c` is finite and in [0, 255], so it converts into an `i32`.
    let i: i32 = unsafe { c.to_int_unchecked() };
    i as u8
}

/// [`to_u8`] in float operations: clamped, then floored by rounding to an integer with 2²³
/// (exact below 2²³) and stepping back when that rounded up; the integer is then the low byte
/// of `f + 2²³`'s bits. Where the code is needed as an `f32` too (the sketch's error), the
/// compiler kept this in eight lanes, while [`to_u8`] there assembled the bytes one by one
/// (docs/performance.md#sketch).
#[inline(always)]
pub(crate) fn floor_to_u8(y: f32) -> u8 {
    const MAGIC: f32 = 8_388_608.0;
    // A NaN compares false: to 0, as the cast.
    let c = if y > 0.0 { y } else { 0.0 };
    let c = if c < 255.0 { c } else { 255.0 };
    let r = (c + MAGIC) - MAGIC;
    let f = if r > c { r - 1.0 } else { r };
    (f + MAGIC).to_bits() as u8
}

/// What values are multiplied by to give their codes of quantisation step `step`: `1 / step`,
/// or 0 for a step of 0 (every value 0) or below.
#[inline(always)]
pub(crate) fn inverse_step(step: f32) -> f32 {
    if step > 0.0 {
        1.0 / step
    } else {
        0.0
    }
}

/// Marsaglia's 32-bit xorshift (13, 17, 5): the crate's unit tests' source of reproducible
/// values.
#[cfg(test)]
pub(crate) struct XorShift32(pub(crate) u32);

#[cfg(test)]
impl XorShift32 {
    /// The next state, which is also the value.
    pub(crate) fn next_u32(&mut self) -> u32 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.0 = x;
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn to_u8_and_floor_to_u8_are_the_cast() {
        for y in [
            f32::NAN,
            -f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -0.0,
            0.0,
            f32::MIN_POSITIVE,
            1e-45,
            0.5,
            0.999_999_94,
            1.0,
            1.5,
            2.5,
            254.5,
            254.999_98,
            255.0,
            255.5,
            256.0,
            1e30,
            -1.0,
            -0.5,
        ] {
            assert_eq!((to_u8(y), floor_to_u8(y)), (y as u8, y as u8), "{y}");
        }
        // Every 257th bit pattern (every sign, exponent and mantissa region), and every value
        // from -2 to 258 in steps of 1/1024.
        for bits in (0..=u32::MAX).step_by(257) {
            let y = f32::from_bits(bits);
            assert_eq!(
                (to_u8(y), floor_to_u8(y)),
                (y as u8, y as u8),
                "{y} ({bits:#x})"
            );
        }
        for i in -2048..=258 * 1024 {
            let y = i as f32 / 1024.0;
            assert_eq!((to_u8(y), floor_to_u8(y)), (y as u8, y as u8), "{y}");
        }
    }

    #[test]
    fn floor_i64_is_floor() {
        for v in [
            -2.5,
            -2.0,
            -1.5,
            -1e-300,
            -0.0,
            0.0,
            0.5,
            1.0,
            1.5,
            2.5,
            3.999_999,
            -524_287.9,
            524_287.9,
            1_073_741_823.5,
            -1_073_741_824.0,
        ] {
            assert_eq!(floor_i64(v), libm::floor(v) as i64, "{v}");
        }
        let mut x = -1000.0;
        while x < 1000.0 {
            assert_eq!(floor_i64(x), libm::floor(x) as i64, "{x}");
            x += 0.123_456_789;
        }
        // Out of contract: no panic.
        let _ = (
            floor_i64(f64::NAN),
            floor_i64(1e300),
            floor_i64(f64::NEG_INFINITY),
        );
        assert_eq!(floor_i64(-1.5e15), -1_500_000_000_000_000);
    }

    #[test]
    fn floor_u32_is_floor() {
        let mut v = 0.0f32;
        while v < 5000.0 {
            assert_eq!(MagicFloor::floor_u32(v), libm::floorf(v) as u32, "{v}");
            #[cfg(feature = "std")]
            assert_eq!(NativeFloor::floor_u32(v), libm::floorf(v) as u32, "{v}");
            v += 0.0625 * 1.01;
        }
        for v in [
            0.0f32,
            1.0,
            0.999_999_94,
            39.0,
            38.999_996,
            4_194_303.5,
            4_194_303.0,
        ] {
            assert_eq!(MagicFloor::floor_u32(v), libm::floorf(v) as u32, "{v}");
        }
    }

    #[test]
    fn atan2_matches_libm_everywhere() {
        use core::f64::consts::PI as PI64;
        let mut worst: f64 = 0.0;
        let n = 2000;
        for i in 0..n {
            let ang = -PI64 + 2.0 * PI64 * (i as f64 + 0.37) / n as f64;
            for &rad in &[1e-30, 1e-3, 1.0, 37.5, 1e30] {
                let (y, x) = ((rad * libm::sin(ang)) as f32, (rad * libm::cos(ang)) as f32);
                let err = (f64::from(atan2(y, x)) - libm::atan2(f64::from(y), f64::from(x))).abs();
                worst = worst.max(err);
            }
        }
        assert!(worst < 5e-7, "worst error {worst}");
        // Axes and the degenerate origin.
        assert_eq!(atan2(0.0, 1.0), 0.0);
        assert_eq!(atan2(1.0, 0.0), FRAC_PI_2);
        assert_eq!(atan2(0.0, -1.0), PI);
        assert_eq!(atan2(-1.0, 0.0), -FRAC_PI_2);
        assert_eq!(atan2(0.0, 0.0), 0.0);
    }
}
