//! Writing the columns of a bulk add in chunks: the R-SOLiD scales and the A-SOLiDs quantised to
//! 8 bits (checked on the way), shared among the pool's threads with `parallel`.

use super::check_bins;
use crate::math::inverse_step;
use crate::search::{self, SKETCH_BLOCK};
use crate::Error;

/// Rows of a chunk that one task of [`Database::append_vectors`](super::Database::append_vectors) or
/// [`Database::extend_sketch`](super::Database::extend_sketch) writes (a whole number of sketch blocks).
pub(super) const CHUNK_ROWS: usize = 64 * SKETCH_BLOCK;

/// Runs `fill` on every chunk of a batch of `m` rows: shared among the pool's threads (with
/// `parallel`) from two chunks on, stopping at the first error.
pub(super) fn in_chunks<I, F>(chunks: I, m: usize, fill: F) -> Result<(), Error>
where
    I: Iterator + Send,
    I::Item: Send,
    F: Fn(I::Item) -> Result<(), Error> + Sync + Send,
{
    #[cfg(feature = "parallel")]
    if let Some(threads) = (m >= 2 * CHUNK_ROWS).then(crate::pool::work).flatten() {
        use rayon::iter::{ParallelBridge, ParallelIterator};
        return threads.install(|| chunks.par_bridge().try_for_each(fill));
    }
    let _ = m;
    chunks.into_iter().try_for_each(fill)
}

/// The input rows of a chunk and where their scales and A-SOLiD codes go.
pub(super) struct ChunkOut<'a> {
    pub(super) r: &'a [f32],
    pub(super) a: &'a [f32],
    pub(super) scale: &'a mut [f32],
    pub(super) a_codes: &'a mut [u8],
    pub(super) a_scale: &'a mut [f32],
}

impl<'a> ChunkOut<'a> {
    /// The R-SOLiD scales and the quantised A-SOLiDs, checking every value (compiled for AVX2
    /// as well, which `std` picks when the CPU has it: the same operations, so the same bits).
    pub(super) fn fill(&mut self, nr: usize, na: usize) -> Result<(), Error> {
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        if std::is_x86_feature_detected!("avx2") {
            #[allow(unsafe_code)]
            // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
            // calling a function compiled with `#[target_feature(enable = "avx2")]`.
            return unsafe { self.fill_avx2(nr, na) };
        }
        self.fill_dims(nr, na)
    }

    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[target_feature(enable = "avx2")]
    fn fill_avx2(&mut self, nr: usize, na: usize) -> Result<(), Error> {
        self.fill_dims(nr, na)
    }

    /// [`ChunkOut::fill_impl`], compiled a second time for the default dimensions (every
    /// preset's) as constants, so that the compiler unrolls each row's loops (docs/performance.md#database).
    #[inline(always)]
    fn fill_dims(&mut self, nr: usize, na: usize) -> Result<(), Error> {
        use crate::config::{DEFAULT_N_AZIMUTH, DEFAULT_N_RANGE};
        if (nr, na) == (DEFAULT_N_RANGE, DEFAULT_N_AZIMUTH) {
            self.fill_impl(DEFAULT_N_RANGE, DEFAULT_N_AZIMUTH)
        } else {
            self.fill_impl(nr, na)
        }
    }

    /// Rows at a time: first what each row needs (its sum of squares, its A-SOLiD's step), then
    /// the scales and codes from those, so that one row's chain of dependent operations (sums,
    /// maxima, a square root, divisions) overlaps the next rows' instead of holding up its own
    /// codes, [`a_top`] finding the largest value and checking the row in one maximum of bits:
    /// faster, with the same bits (docs/performance.md#database).
    #[inline(always)]
    fn fill_impl(&mut self, nr: usize, na: usize) -> Result<(), Error> {
        const ROWS: usize = 64;
        for (rows, scales) in self.r.chunks(ROWS * nr).zip(self.scale.chunks_mut(ROWS)) {
            let mut sums = [0.0f64; ROWS];
            let sums = &mut sums[..scales.len()];
            // Four rows at a time, then one at a time.
            let mut groups = rows.chunks_exact(4 * nr);
            let mut out = sums.chunks_exact_mut(4);
            for (g, out) in (&mut groups).zip(&mut out) {
                let (r0, rest) = g.split_at(nr);
                let (r1, rest) = rest.split_at(nr);
                let (r2, r3) = rest.split_at(nr);
                out.copy_from_slice(&search::square_sums([r0, r1, r2, r3]));
            }
            for (row, out) in groups
                .remainder()
                .chunks_exact(nr)
                .zip(out.into_remainder())
            {
                *out = search::square_sums([row])[0];
            }
            // A non-finite value makes its row's sum non-finite; negative ones are looked for
            // without a branch per value. Either way `check_bins` names the first bad value.
            let bad = rows.iter().fold(false, |neg, &x| neg | (x < 0.0));
            if bad || !sums.iter().all(|s| s.is_finite()) {
                for row in rows.chunks_exact(nr) {
                    check_bins("r_solid", row)?;
                }
            }
            for (scale, &sum) in scales.iter_mut().zip(sums.iter()) {
                *scale = search::norm_scale(sum);
            }
        }
        for ((rows, codes), steps) in self
            .a
            .chunks(ROWS * na)
            .zip(self.a_codes.chunks_mut(ROWS * na))
            .zip(self.a_scale.chunks_mut(ROWS))
        {
            // The largest values first, then the steps and their inverses in a loop of their own
            // (which the compiler vectorises), then the codes.
            let (mut top, mut inv) = ([0.0f32; ROWS], [0.0f32; ROWS]);
            for (row, top) in rows.chunks_exact(na).zip(&mut top) {
                // `a_top` refuses exactly what `check_bins` names.
                *top = a_top(row).map_or_else(|| check_bins("a_solid", row).map(|()| 0.0), Ok)?;
            }
            for ((step, inv), &top) in steps.iter_mut().zip(&mut inv).zip(&top) {
                *step = a_step(top);
                *inv = inverse_step(*step);
            }
            for ((row, codes), &inv) in rows
                .chunks_exact(na)
                .zip(codes.chunks_exact_mut(na))
                .zip(&inv)
            {
                quantize_a_with(row, inv, codes);
            }
        }
        Ok(())
    }
}

/// Quantises one A-SOLiD to 8 bits per value into `codes`; returns its step (see
/// [`Database::a`]): `max / 255`, codes rounded half up; `None` when a value is negative or not
/// finite (what descriptors never hold, SPEC §3).
#[cfg(test)]
fn quantize_a(a: &[f32], codes: &mut [u8]) -> Option<f32> {
    let step = a_step(a_top(a)?);
    quantize_a_with(a, inverse_step(step), codes);
    Some(step)
}

/// The largest value of an A-SOLiD (at least `+0.0`); `None` when a value is negative or not
/// finite. Found on the values' bits, read as `u32`: those of non-negative finite values are in
/// the order of the values and below infinity's, and those of every negative value (but `-0.0`,
/// read as `+0.0`), infinity and NaN are at or above infinity's; so one maximum, in eight lanes,
/// both finds the largest value and checks them all. A last group of eight overlaps the one
/// before (which changes no maximum) instead of a tail of single values.
#[inline(always)]
fn a_top(a: &[f32]) -> Option<f32> {
    const NEGATIVE_ZERO: u32 = 0x8000_0000;
    let mut top = [0u32; 8];
    let mut take = |group: &[f32]| {
        for (t, &v) in top.iter_mut().zip(group) {
            let bits = v.to_bits();
            *t = (*t).max(if bits == NEGATIVE_ZERO { 0 } else { bits });
        }
    };
    if a.len() >= 8 {
        let groups = a.chunks_exact(8);
        let tail = !groups.remainder().is_empty();
        groups.for_each(&mut take);
        if tail {
            take(&a[a.len() - 8..]);
        }
    } else {
        // Zeros change no maximum.
        let mut padded = [0.0f32; 8];
        padded[..a.len()].copy_from_slice(a);
        take(&padded);
    }
    let top = top.iter().fold(0, |m, &t| m.max(t));
    (top < f32::INFINITY.to_bits()).then(|| f32::from_bits(top))
}

/// The step of the 8-bit codes of an A-SOLiD whose largest value is `top` (see
/// [`Database::a`](super::Database::a)): `top / 255`; its values are quantised by [`quantize_a_with`].
#[inline(always)]
fn a_step(top: f32) -> f32 {
    top / 255.0
}

/// The codes of an A-SOLiD, given [`inverse_step`] of its [`a_step`]: rounded half up, saturated
/// into `0..=255`.
#[inline(always)]
fn quantize_a_with(a: &[f32], inv: f32, codes: &mut [u8]) {
    for (c, &v) in codes.iter_mut().zip(a) {
        *c = crate::math::to_u8(v * inv + 0.5);
    }
}

/// The values of a quantised A-SOLiD (see [`a_step`]).
pub(super) fn dequantize_a(codes: &[u8], step: f32, out: &mut [f32]) {
    for (o, v) in out.iter_mut().zip(dequantized(codes, step)) {
        *o = v;
    }
}

/// The values of quantised A-SOLiD codes, without allocating.
pub(super) fn dequantized(codes: &[u8], step: f32) -> impl Iterator<Item = f32> + '_ {
    codes.iter().map(move |&c| f32::from(c) * step)
}

#[cfg(test)]
mod tests {
    use super::{dequantize_a, quantize_a};
    use crate::math::XorShift32;

    /// The AVX2 copy of the checks and quantisation of a bulk add gives the portable copy's
    /// bits (scales, A-SOLiD codes and steps), and the same error for a bad value.
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[test]
    fn avx2_fill_gives_the_portable_bits() {
        use super::ChunkOut;
        if !std::is_x86_feature_detected!("avx2") {
            eprintln!("no AVX2 on this CPU: nothing to compare");
            return;
        }
        let (nr, na, n) = (40, 60, 37);
        let mut rng = XorShift32(0x2545_f491);
        let mut next = move || (rng.next_u32() % 100_000) as f32 * 1e-2;
        let mut r: Vec<f32> = (0..n * nr).map(|_| next()).collect();
        let mut a: Vec<f32> = (0..n * na).map(|_| next()).collect();
        r[3 * nr..4 * nr].fill(0.0);
        a[5 * na..6 * na].fill(0.0);
        a[7 * na + 2] = 1e-40;
        let run = |r: &[f32], a: &[f32], avx2: bool| {
            let (mut scale, mut codes, mut step) = (vec![9.0; n], vec![9u8; n * na], vec![9.0; n]);
            let mut out = ChunkOut {
                r,
                a,
                scale: &mut scale,
                a_codes: &mut codes,
                a_scale: &mut step,
            };
            let res = if avx2 {
                out.fill(nr, na)
            } else {
                out.fill_impl(nr, na)
            };
            let bits = |v: &[f32]| v.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            (
                res.map_err(|e| e.to_string()),
                bits(&scale),
                codes,
                bits(&step),
            )
        };
        assert_eq!(run(&r, &a, true), run(&r, &a, false));
        r[9 * nr + 1] = -1.0;
        let bad = run(&r, &a, true);
        assert!(bad.0.is_err());
        assert_eq!(bad.0, run(&r, &a, false).0);
    }

    /// A bulk add gives each row what the one-row functions give it alone, whatever the
    /// number of rows (every remainder of the groups of four and the blocks of 64) and the
    /// dimensions (the defaults, compiled as constants, and others).
    #[test]
    fn fill_gives_every_row_what_it_gets_alone() {
        use super::ChunkOut;
        use crate::search::inverse_norm;
        let mut rng = XorShift32(0x9e37_79b9);
        let mut next = move || {
            // Zeros one time in eight, then values over six orders of magnitude.
            let x = rng.next_u32();
            if x.is_multiple_of(8) {
                0.0
            } else {
                (x % 1_000_000) as f32 * 1e-3
            }
        };
        for (nr, na) in [(40, 60), (7, 5), (13, 17), (1, 1)] {
            for n in (1..=70).chain([127, 128, 129, 200]) {
                let r: Vec<f32> = (0..n * nr).map(|_| next()).collect();
                let a: Vec<f32> = (0..n * na).map(|_| next()).collect();
                let (mut scale, mut codes, mut step) =
                    (vec![9.0; n], vec![9u8; n * na], vec![9.0; n]);
                ChunkOut {
                    r: &r,
                    a: &a,
                    scale: &mut scale,
                    a_codes: &mut codes,
                    a_scale: &mut step,
                }
                .fill(nr, na)
                .unwrap();
                for i in 0..n {
                    let row = &r[i * nr..(i + 1) * nr];
                    let at = format!("row {i} of {n} ({nr}, {na})");
                    assert_eq!(
                        scale[i].to_bits(),
                        inverse_norm(row).unwrap().to_bits(),
                        "{at}"
                    );
                    let mut alone = vec![0u8; na];
                    let s = quantize_a(&a[i * na..(i + 1) * na], &mut alone).unwrap();
                    assert_eq!(step[i].to_bits(), s.to_bits(), "{at}");
                    assert_eq!(codes[i * na..(i + 1) * na], alone[..], "{at}");
                }
            }
        }
    }

    /// A bulk add with bad values names the first bad value of the first bad R-SOLiD row, and of
    /// the first bad A-SOLiD row only when every R-SOLiD is good: across groups of four rows and
    /// blocks of 64, and within a row.
    #[test]
    fn fill_names_the_first_bad_value() {
        use super::{ChunkOut, Error};
        let (nr, na, n) = (40, 60, 140);
        let named = |r: &[f32], a: &[f32]| {
            let (mut scale, mut codes, mut step) = (vec![0.0; n], vec![0u8; n * na], vec![0.0; n]);
            let out = ChunkOut {
                r,
                a,
                scale: &mut scale,
                a_codes: &mut codes,
                a_scale: &mut step,
            }
            .fill(nr, na);
            match out {
                Err(Error::InvalidParameter { name, value, .. }) => (name, value.to_bits()),
                other => panic!("expected a bad value, got {other:?}"),
            }
        };
        let bits = |v: f32| f64::from(v).to_bits();
        let (mut r, mut a) = (vec![0.5f32; n * nr], vec![0.5f32; n * na]);
        a[3 * na + 7] = -7.0;
        a[2 * na + 59] = f32::INFINITY;
        assert_eq!(named(&r, &a), ("a_solid", bits(f32::INFINITY)));
        r[70 * nr + 1] = f32::NAN;
        assert!(f64::from_bits(named(&r, &a).1).is_nan());
        r[129 * nr + 39] = -1.0;
        r[66 * nr + 5] = -2.0;
        r[66 * nr + 9] = f32::NEG_INFINITY;
        assert_eq!(named(&r, &a), ("r_solid", bits(-2.0)));
        r[66 * nr + 2] = f32::INFINITY;
        assert_eq!(named(&r, &a), ("r_solid", bits(f32::INFINITY)));
        r[1] = -1e-45;
        assert_eq!(named(&r, &a), ("r_solid", bits(-1e-45)));
    }

    /// `a_top` (a maximum of bits) is the largest value, or refuses what is negative or not
    /// finite, as comparisons of the values say, for every length (under eight: padded).
    #[test]
    fn a_top_is_the_largest_value_of_finite_non_negative_values() {
        let special = [
            0.0,
            -0.0,
            f32::MIN_POSITIVE,
            1e-45,
            -1e-45,
            1.0,
            -1.0,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
            f32::from_bits(0x7f80_0001),
            3.5,
        ];
        let mut rng = XorShift32(0x2545_f491);
        for len in 1..=20 {
            for _ in 0..200 {
                let a: Vec<f32> = (0..len)
                    .map(|_| {
                        let x = rng.next_u32();
                        if x.is_multiple_of(4) {
                            special[(x / 4) as usize % special.len()]
                        } else {
                            (x % 1000) as f32 * 0.25
                        }
                    })
                    .collect();
                let valid = a.iter().all(|v| v.is_finite() && *v >= 0.0);
                let top = a.iter().fold(0.0f32, |m, &v| if v > m { v } else { m });
                let want = valid.then_some(top.to_bits());
                assert_eq!(super::a_top(&a).map(f32::to_bits), want, "{a:?}");
            }
        }
    }

    #[test]
    fn quantising_what_was_dequantised_gives_the_same_codes_and_step() {
        // A database saved, loaded and saved again writes the same bytes (the fuzz target
        // db_from_bytes relies on it): largest values from subnormal to 1e37.
        let mut rng = XorShift32(0x2545_f491);
        for i in 0..4000 {
            let x = rng.next_u32();
            let top = if i % 10 == 0 {
                f32::from_bits(1 + x % 0x0080_0000)
            } else {
                (1.0 + (x % 1_000_000) as f32 / 1e6) * 10f32.powi(i % 75 - 38)
            };
            let a: [f32; 6] = [top, 0.5 * top, 0.0, 0.25 * top, 0.7 * top, 0.1 * top];
            let mut codes = [0u8; 6];
            let step = quantize_a(&a, &mut codes).unwrap();
            let mut values = [0.0f32; 6];
            dequantize_a(&codes, step, &mut values);
            let mut again = [0u8; 6];
            assert_eq!(quantize_a(&values, &mut again), Some(step), "top {top}");
            assert_eq!(again, codes, "top {top}");
            // Within half a step, but for subnormal steps (1 / step overflows).
            if top >= 1e-30 {
                for (v, w) in values.iter().zip(&a) {
                    assert!((v - w).abs() <= 0.5 * step * 1.0001, "{v} vs {w}");
                }
            }
        }
    }
}
