//! The SOLiD descriptor, step by step as [spec §2](crate::spec#2-the-descriptor) defines it.
//!
//! The steps are functions inlined into [`describe`]'s compiled copies: the per-point range filter
//! and bin indices (steps 1–2, 4–5) in `bin`, the voxel grid (step 3) in `voxel`, the counts and
//! weights (steps 6–8) here.

mod bin;
mod voxel;

use bin::{deinterleave, in_range, squared_range, unpack, Binner, BLOCK};
use voxel::{centroid, table_slots, voxel_scratch, voxelize, REC, SLOT};

use crate::math::{Floor, PortableFloor};
use crate::{Config, Error};

/// One element of the caller-owned scratch buffer of [`describe`].
///
/// Allocate `describe_scratch_len(n_points, &cfg)` of them (any initial value) and reuse them across
/// calls: `describe` never allocates.
pub type Scratch = u64;

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// A point coordinate type that [`describe`] reads: `f32` or `f64`.
pub trait Coord: Copy + sealed::Sealed {
    /// The value as `f64` (exact for both types).
    fn to_f64(self) -> f64;
}

impl Coord for f32 {
    #[inline(always)]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
}

impl Coord for f64 {
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
}

/// A borrowed point cloud: a flat row-major slice with `stride` values per point, of which the
/// first three are x, y, z (metres, sensor frame: x forward, y left, z up). Extra columns such as
/// intensity or time are ignored, so an N×4 KITTI array is read in place.
#[derive(Debug, Clone, Copy)]
pub struct Points<'a, T> {
    data: &'a [T],
    stride: usize,
}

impl<'a, T: Coord> Points<'a, T> {
    /// Wraps `data` holding `data.len() / stride` points.
    ///
    /// # Errors
    /// [`Error::BadPointLayout`] when `stride < 3` or `data.len()` is not a multiple of `stride`.
    pub fn new(data: &'a [T], stride: usize) -> Result<Self, Error> {
        if stride < 3 || !data.len().is_multiple_of(stride) {
            return Err(Error::BadPointLayout {
                len: data.len(),
                stride,
            });
        }
        Ok(Points { data, stride })
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.data.len() / self.stride
    }

    /// True when there are no points.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Values per point.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// The flat slice the points are read from.
    pub fn as_slice(&self) -> &'a [T] {
        self.data
    }
}

/// Point counts of one [`describe`] call.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Stats {
    /// Points passed in (before any filtering).
    pub n_points: usize,
    /// Points left after the finite and range filters ([spec §2](crate::spec#2-the-descriptor) steps 1–2).
    pub n_in_range: usize,
    /// Points binned: voxel centroids after downsampling (step 3), or `n_in_range` without it.
    pub n_kept: usize,
}

/// How many [`Scratch`] elements [`describe`] needs for `n_points` points under `cfg`.
///
/// Grows linearly with `n_points`: 9 to 13 words a point with voxel downsampling (hash table and
/// voxel accumulators), half a word a point without, plus a few words per bin. Only what a scan
/// occupies is touched, so a generous buffer costs address space, not time.
pub fn describe_scratch_len(n_points: usize, cfg: &Config) -> usize {
    let bins = cfg.n_range + cfg.n_azimuth + 2 * cfg.n_elevation;
    let per_point = if cfg.voxel_size > 0.0 {
        (table_slots(n_points) * SLOT).saturating_add(n_points.saturating_mul(REC))
    } else {
        n_points.div_ceil(2)
    };
    bins.saturating_add(per_point)
}

/// Computes the SOLiD descriptor of one scan ([spec §2](crate::spec#2-the-descriptor)): R-SOLiD into `r_out[..n_range]` and
/// A-SOLiD into `a_out[..n_azimuth]`.
///
/// Non-finite points and points outside `(min_range, max_range)` are dropped; an empty result is
/// valid and gives all-zero vectors. Allocates nothing.
///
/// # Errors
/// - [`Error::InvalidParameter`] when `cfg` is invalid (see [`Config::validate`]).
/// - [`Error::BufferTooSmall`] when `scratch` is shorter than [`describe_scratch_len`] or an output
///   is shorter than its vector.
///
/// With `std` on x86-64, a copy of the same code compiled for AVX-512 (F, DQ, VL, BW) or else
/// AVX2 runs when the CPU has it (no FMA is asked for, and Rust never fuses a multiply and an add
/// by itself, so every operation rounds as in the portable copy: the same bits either way, which
/// the tests check on every shared scan and on random clouds); [`stages::describe_portable`] is
/// the portable copy.
///
/// # Panics
/// Never.
pub fn describe<T: Coord>(
    points: Points<'_, T>,
    cfg: &Config,
    scratch: &mut [Scratch],
    r_out: &mut [f32],
    a_out: &mut [f32],
) -> Result<Stats, Error> {
    describe_on(Isa::best(), points, cfg, scratch, r_out, a_out)
}

/// The compiled copies of [`describe`]'s pipeline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Isa {
    /// The code compiled for the baseline CPU of the target.
    Portable,
    /// x86-64 with AVX2.
    Avx2,
    /// x86-64 with AVX-512 F, DQ, VL and BW: twice the lanes of AVX2 in the key and binning
    /// passes. (Compiled where the compiler has these target features, Rust 1.89 on; see
    /// build.rs.)
    Avx512,
}

impl Isa {
    /// The copies this CPU runs, fastest first; the portable one always.
    fn available() -> impl Iterator<Item = Isa> {
        [Isa::Avx512, Isa::Avx2, Isa::Portable]
            .into_iter()
            .filter(|isa| isa.runs_here())
    }

    /// The fastest copy this CPU runs.
    fn best() -> Isa {
        Isa::available().next().unwrap_or(Isa::Portable)
    }

    /// Whether this build has the copy and this CPU the features it is compiled for.
    fn runs_here(self) -> bool {
        match self {
            Isa::Portable => true,
            #[cfg(all(feature = "std", target_arch = "x86_64", solid_avx512))]
            Isa::Avx512 => {
                std::is_x86_feature_detected!("avx512f")
                    && std::is_x86_feature_detected!("avx512dq")
                    && std::is_x86_feature_detected!("avx512vl")
                    && std::is_x86_feature_detected!("avx512bw")
            }
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            Isa::Avx2 => std::is_x86_feature_detected!("avx2"),
            #[allow(unreachable_patterns)]
            _ => false,
        }
    }
}

/// Defines the copies of [`describe_impl`] and [`voxelize`] compiled for the target features
/// `$features` (which imply SSE4.1's rounding instructions, hence `NativeFloor`), and the
/// functions that run a given [`Isa`]'s copy: that copy where [`Isa::runs_here`], else the
/// portable code. Every copy is the same source: no FMA is asked for, and Rust never fuses a
/// multiply and an add by itself, so every operation rounds as in the portable copy.
macro_rules! cpu_copies {
    ($($isa:ident: $describe:ident, $voxelize:ident, $features:literal, [$($cfg:meta),*];)*) => {
        $(
            #[cfg(all(feature = "std", target_arch = "x86_64", $($cfg),*))]
            #[target_feature(enable = $features)]
            fn $describe<T: Coord>(
                points: Points<'_, T>,
                cfg: &Config,
                scratch: &mut [Scratch],
                r_out: &mut [f32],
                a_out: &mut [f32],
            ) -> Result<Stats, Error> {
                describe_impl::<T, crate::math::NativeFloor>(points, cfg, scratch, r_out, a_out)
            }

            #[cfg(all(feature = "std", target_arch = "x86_64", $($cfg),*))]
            #[target_feature(enable = $features)]
            fn $voxelize<T: Coord>(
                points: Points<'_, T>,
                cfg: &Config,
                table: &mut [[u64; SLOT]],
                recs: &mut [[u64; REC]],
            ) -> (usize, usize) {
                voxelize::<T, crate::math::NativeFloor>(points, cfg, table, recs)
            }
        )*

        /// [`describe_impl`] in the copy `isa`, or the portable one where `isa` does not run.
        fn describe_on<T: Coord>(
            isa: Isa,
            points: Points<'_, T>,
            cfg: &Config,
            scratch: &mut [Scratch],
            r_out: &mut [f32],
            a_out: &mut [f32],
        ) -> Result<Stats, Error> {
            match isa {
                $(
                    #[cfg(all(feature = "std", target_arch = "x86_64", $($cfg),*))]
                    #[allow(unsafe_code)]
                    // SAFETY: the CPU has the copy's target features (checked by the guard), the
                    // only requirement for calling it.
                    Isa::$isa if isa.runs_here() => unsafe {
                        $describe(points, cfg, scratch, r_out, a_out)
                    },
                )*
                _ => describe_impl::<T, PortableFloor>(points, cfg, scratch, r_out, a_out),
            }
        }

        /// [`voxelize`] in the copy `isa`, or the portable one where `isa` does not run.
        fn voxelize_on<T: Coord>(
            isa: Isa,
            points: Points<'_, T>,
            cfg: &Config,
            table: &mut [[u64; SLOT]],
            recs: &mut [[u64; REC]],
        ) -> (usize, usize) {
            match isa {
                $(
                    #[cfg(all(feature = "std", target_arch = "x86_64", $($cfg),*))]
                    #[allow(unsafe_code)]
                    // SAFETY: as in `describe_on`.
                    Isa::$isa if isa.runs_here() => unsafe { $voxelize(points, cfg, table, recs) },
                )*
                _ => voxelize::<T, PortableFloor>(points, cfg, table, recs),
            }
        }
    };
}

cpu_copies! {
    Avx512: describe_avx512, voxelize_avx512, "avx512f,avx512dq,avx512vl,avx512bw", [solid_avx512];
    Avx2: describe_avx2, voxelize_avx2, "avx2", [];
}

/// The body of [`describe`], inlined into each of its compiled copies: the steps of
/// [spec §2](crate::spec#2-the-descriptor) in order, each a function inlined here.
#[inline(always)]
fn describe_impl<T: Coord, F: Floor>(
    points: Points<'_, T>,
    cfg: &Config,
    scratch: &mut [Scratch],
    r_out: &mut [f32],
    a_out: &mut [f32],
) -> Result<Stats, Error> {
    cfg.validate()?;
    let n = points.len();
    check_buffers(n, cfg, scratch.len(), r_out.len(), a_out.len())?;
    let (nr, na, ne) = (cfg.n_range, cfg.n_azimuth, cfg.n_elevation);
    let (acc, rest) = scratch.split_at_mut(nr + na + 2 * ne);
    let acc: &mut [f64] = bytemuck::cast_slice_mut(acc);
    let (r_acc, acc) = acc.split_at_mut(nr);
    let (a_acc, acc) = acc.split_at_mut(na);
    let (iev, ec) = acc.split_at_mut(ne);
    let ec: &mut [u64] = bytemuck::cast_slice_mut(ec);

    let binner = Binner::new(cfg);
    let (n_in_range, bins) = if cfg.voxel_size > 0.0 {
        bin_centroids::<T, F>(points, cfg, &binner, rest)
    } else {
        bin_in_range::<T, F>(points, cfg, &binner, rest)
    };
    elevation_counts(bins, ec);
    elevation_weights(ec, iev);
    weighted_sums(bins, iev, r_acc, a_acc);
    for (o, &v) in r_out.iter_mut().zip(r_acc.iter()) {
        *o = v as f32;
    }
    for (o, &v) in a_out.iter_mut().zip(a_acc.iter()) {
        *o = v as f32;
    }
    Ok(Stats {
        n_points: n,
        n_in_range,
        n_kept: bins.len(),
    })
}

/// Checks the lengths of [`describe`]'s buffers for `n` points.
///
/// # Errors
/// [`Error::BufferTooSmall`] naming the first buffer that is too short.
#[inline(always)]
fn check_buffers(
    n: usize,
    cfg: &Config,
    scratch: usize,
    r_out: usize,
    a_out: usize,
) -> Result<(), Error> {
    for (buffer, needed, got) in [
        ("scratch", describe_scratch_len(n, cfg), scratch),
        ("r_out", cfg.n_range, r_out),
        ("a_out", cfg.n_azimuth, a_out),
    ] {
        Error::check_buffer(buffer, needed, got)?;
    }
    Ok(())
}

/// Steps 1–5 with voxels: the voxel centroids of the points in range ([`voxelize`]), binned
/// block by block, their packed bins written over the hash table (no longer needed). Returns the
/// points in range and one packed bin per centroid: step 6's REC and AEC, one entry per count.
#[inline(always)]
fn bin_centroids<'s, T: Coord, F: Floor>(
    points: Points<'_, T>,
    cfg: &Config,
    binner: &Binner,
    rest: &'s mut [Scratch],
) -> (usize, &'s [u32]) {
    let mut xyz32 = [[0f32; BLOCK]; 3];
    let mut block_bins = [0u32; BLOCK];
    let (table, recs) = voxel_scratch(rest, points.len());
    let (n_in, m) = voxelize::<T, F>(points, cfg, table, recs);
    let table: &mut [u32] = bytemuck::cast_slice_mut(table);
    for (out, recs) in table[..m].chunks_mut(BLOCK).zip(recs[..m].chunks(BLOCK)) {
        let nb = out.len();
        for (i, rec) in recs.iter().enumerate() {
            let c = centroid(rec, cfg.voxel_size);
            for d in 0..3 {
                xyz32[d][i] = c[d] as f32;
            }
        }
        binner.bin_block::<F>(&xyz32, nb, &mut block_bins);
        out.copy_from_slice(&block_bins[..nb]);
    }
    (n_in, &table[..m])
}

/// Steps 1–2 and 4–5 without voxels: the points in range, compacted to the front of each block
/// without a branch, and binned. Returns their number and one packed bin per point (as
/// [`bin_centroids`]).
#[inline(always)]
fn bin_in_range<'s, T: Coord, F: Floor>(
    points: Points<'_, T>,
    cfg: &Config,
    binner: &Binner,
    rest: &'s mut [Scratch],
) -> (usize, &'s [u32]) {
    let mut xyz = [[0f64; BLOCK]; 3];
    let mut xyz32 = [[0f32; BLOCK]; 3];
    let mut block_bins = [0u32; BLOCK];
    let bins: &mut [u32] = &mut bytemuck::cast_slice_mut(rest)[..points.len()];
    let (min2, max2) = squared_range(cfg);
    let mut m = 0;
    for block in points.data.chunks(BLOCK * points.stride) {
        let nb = deinterleave(block, points.stride, &mut xyz);
        let mut kept = 0;
        let [xs, ys, zs] = &xyz;
        for ((&x, &y), &z) in xs[..nb].iter().zip(&ys[..nb]).zip(&zs[..nb]) {
            xyz32[0][kept] = x as f32;
            xyz32[1][kept] = y as f32;
            xyz32[2][kept] = z as f32;
            kept += usize::from(in_range(x, y, z, min2, max2));
        }
        binner.bin_block::<F>(&xyz32, kept, &mut block_bins);
        bins[m..m + kept].copy_from_slice(&block_bins[..kept]);
        m += kept;
    }
    (m, &bins[..m])
}

/// Step 7's elevation counts: `EC[k] = Σᵢ REC[i,k]`, the points binned in ring `k`.
#[inline(always)]
fn elevation_counts(bins: &[u32], ec: &mut [u64]) {
    ec.fill(0);
    for &b in bins {
        ec[unpack(b).2] += 1;
    }
}

/// Step 7's IEV: the elevation counts min-max normalised; flat counts (an empty scan too) give
/// all ones.
#[inline(always)]
fn elevation_weights(ec: &[u64], iev: &mut [f64]) {
    let (lo, hi) = ec
        .iter()
        .fold((u64::MAX, 0), |(lo, hi), &c| (lo.min(c), hi.max(c)));
    let span = (hi - lo) as f64;
    for (w, &c) in iev.iter_mut().zip(ec.iter()) {
        *w = if hi == lo {
            1.0
        } else {
            (c - lo) as f64 / span
        };
    }
}

/// Step 8: R-SOLiD = REC · IEV and A-SOLiD = AEC · IEV, accumulated point by point in `f64`.
#[inline(always)]
fn weighted_sums(bins: &[u32], iev: &[f64], r_acc: &mut [f64], a_acc: &mut [f64]) {
    r_acc.fill(0.0);
    a_acc.fill(0.0);
    for &b in bins {
        let (i, j, k) = unpack(b);
        r_acc[i] += iev[k];
        a_acc[j] += iev[k];
    }
}

/// Steps of the pipeline on their own, for users who need one (a downsampled cloud, say) and for
/// the benchmarks. [`describe`] runs them all in one pass and is what place recognition wants.
pub mod stages {
    use super::*;

    /// [`describe`] without the runtime choice of a CPU-specific copy: the portable code, for
    /// checking that every copy gives the same bits.
    ///
    /// # Errors
    /// As [`describe`].
    pub fn describe_portable<T: Coord>(
        points: Points<'_, T>,
        cfg: &Config,
        scratch: &mut [Scratch],
        r_out: &mut [f32],
        a_out: &mut [f32],
    ) -> Result<Stats, Error> {
        describe_on(Isa::Portable, points, cfg, scratch, r_out, a_out)
    }

    /// Number of points that are finite and within `(min_range, max_range)` ([spec §2](crate::spec#2-the-descriptor) steps 1–2).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] when `cfg` is invalid.
    pub fn count_in_range<T: Coord>(points: Points<'_, T>, cfg: &Config) -> Result<usize, Error> {
        cfg.validate()?;
        let (min2, max2) = squared_range(cfg);
        Ok(points
            .data
            .chunks_exact(points.stride)
            .filter(|p| in_range(p[0].to_f64(), p[1].to_f64(), p[2].to_f64(), min2, max2))
            .count())
    }

    /// Voxel downsampling ([spec §2](crate::spec#2-the-descriptor) steps 1–3): writes the centroid of every occupied voxel as x, y, z
    /// rows into `out_xyz`, in order of first occupation, and returns (points in range, voxels).
    /// A centroid is the mean of its points to within `voxel_size / 2^24` (their offsets inside
    /// the voxel are summed exactly, in fixed point). Runs the same CPU-specific copy as
    /// [`describe`].
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] when `cfg` is invalid or its `voxel_size` is 0;
    /// [`Error::BufferTooSmall`] when `scratch` is shorter than [`describe_scratch_len`] or `out_xyz`
    /// shorter than three values per voxel.
    pub fn voxel_downsample<T: Coord>(
        points: Points<'_, T>,
        cfg: &Config,
        scratch: &mut [Scratch],
        out_xyz: &mut [f64],
    ) -> Result<(usize, usize), Error> {
        cfg.validate()?;
        if cfg.voxel_size <= 0.0 {
            return Err(Error::InvalidParameter {
                name: "voxel_size",
                value: cfg.voxel_size,
                expected: "a voxel size > 0 for voxel_downsample",
            });
        }
        let n = points.len();
        Error::check_buffer("scratch", describe_scratch_len(n, cfg), scratch.len())?;
        let (table, recs) = voxel_scratch(scratch, n);
        let (n_in, m) = voxelize_on(Isa::best(), points, cfg, table, recs);
        Error::check_buffer("out_xyz", 3 * m, out_xyz.len())?;
        for (rec, out) in recs[..m].iter().zip(out_xyz.chunks_exact_mut(3)) {
            out.copy_from_slice(&centroid(rec, cfg.voxel_size));
        }
        Ok((n_in, m))
    }
}

#[cfg(test)]
mod tests;
