//! The SOLiD descriptor, step by step as [spec §2](crate::spec#2-the-descriptor) defines it.

use crate::math::{atan2, sqrtf, Floor, PortableFloor};
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

/// Slots of the voxel hash table for `n` points: a power of two at least twice `n`.
fn table_slots(n: usize) -> usize {
    n.saturating_mul(2).max(16).next_power_of_two()
}

/// Words of a voxel record: key, sum x, sum y, sum z, count.
const REC: usize = 5;
/// Words of a hash-table slot: the voxel key ([`OUTSIDE`] when empty) and its record's index.
/// Keeping the key in the slot leaves one memory access on a lookup's critical path.
const SLOT: usize = 2;

/// The hash table and the voxel records for `n` points, from a scratch buffer of at least
/// `describe_scratch_len(n, _)` elements (checked by the callers).
fn voxel_scratch(scratch: &mut [Scratch], n: usize) -> (&mut [[u64; SLOT]], &mut [[u64; REC]]) {
    let (table, recs) = scratch.split_at_mut(table_slots(n) * SLOT);
    (
        bytemuck::cast_slice_mut(table),
        bytemuck::cast_slice_mut(&mut recs[..n * REC]),
    )
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

/// Bin geometry derived once per call from a validated config: every division of [spec §2](crate::spec#2-the-descriptor) step 5
/// becomes a multiplication by a precomputed factor (a point exactly on a bin edge may land one
/// bin over, well within [spec §7](crate::spec#7-matching-the-golden-outputs)'s tolerance; the result is still the same bits everywhere).
///
/// Binning computes in `f32` (which §7 allows): twice the lanes of `f64` and faster division
/// and square root; a point moves to a neighbouring bin only within about 1e-6 of an edge.
struct Binner {
    range_scale: f32,
    azimuth_scale: f32,
    elevation_scale: f32,
    fov_down: f32,
    nr_max: f32,
    na_max: f32,
    ne_max: f32,
}

impl Binner {
    fn new(cfg: &Config) -> Self {
        use core::f64::consts::PI;
        let deg = PI / 180.0;
        Binner {
            range_scale: (cfg.n_range as f64 / cfg.max_range) as f32,
            azimuth_scale: (cfg.n_azimuth as f64 / (2.0 * PI)) as f32,
            elevation_scale: (cfg.n_elevation as f64 / ((cfg.fov_up - cfg.fov_down) * deg)) as f32,
            fov_down: (cfg.fov_down * deg) as f32,
            nr_max: (cfg.n_range - 1) as f32,
            na_max: (cfg.n_azimuth - 1) as f32,
            ne_max: (cfg.n_elevation - 1) as f32,
        }
    }

    /// Packed bin indices `i | j << 10 | k << 22` of one point ([spec §2](crate::spec#2-the-descriptor) steps 4–5).
    #[inline(always)]
    fn bin<F: Floor>(&self, x: f32, y: f32, z: f32) -> u32 {
        use core::f32::consts::TAU;
        let r = sqrtf(x * x + y * y);
        let theta = atan2(y, x);
        let theta = if theta < 0.0 { theta + TAU } else { theta };
        let phi = atan2(z, r);
        // Clamp, then floor: floor(min(v, n - 1)) = min(floor(v), n - 1) for integer n. Range and
        // azimuth quotients are >= 0; the elevation one is clamped at 0, so points on or past the
        // last edge (or above the field of view) join the last bin and points below the field of
        // view the first. NaN goes to a bound too. Branch-free, so blocks vectorise.
        let i = F::floor_u32(below(r * self.range_scale, self.nr_max));
        let j = F::floor_u32(below(theta * self.azimuth_scale, self.na_max));
        let k = F::floor_u32(below(
            above((phi - self.fov_down) * self.elevation_scale, 0.0),
            self.ne_max,
        ));
        i | (j << 10) | (k << 22)
    }

    /// Bins of the first `n` points of `xyz` into `out`.
    #[inline(always)]
    fn bin_block<F: Floor>(&self, xyz: &[[f32; BLOCK]; 3], n: usize, out: &mut [u32; BLOCK]) {
        for i in 0..n.min(BLOCK) {
            out[i] = self.bin::<F>(xyz[0][i], xyz[1][i], xyz[2][i]);
        }
    }
}

/// `min(v, hi)`, and `hi` when `v` is NaN: one instruction, unlike [`f32::min`].
#[inline(always)]
fn below(v: f32, hi: f32) -> f32 {
    if v < hi {
        v
    } else {
        hi
    }
}

/// `max(v, lo)`, and `lo` when `v` is NaN: one instruction, unlike [`f32::max`].
#[inline(always)]
fn above(v: f32, lo: f32) -> f32 {
    if v > lo {
        v
    } else {
        lo
    }
}

#[inline(always)]
fn unpack(b: u32) -> (usize, usize, usize) {
    let b = b as usize;
    (b & 0x3ff, (b >> 10) & 0xfff, b >> 22)
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

/// The body of [`describe`], inlined into each of its compiled copies.
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
    let needed = describe_scratch_len(n, cfg);
    for (buffer, needed, got) in [
        ("scratch", needed, scratch.len()),
        ("r_out", cfg.n_range, r_out.len()),
        ("a_out", cfg.n_azimuth, a_out.len()),
    ] {
        if got < needed {
            return Err(Error::BufferTooSmall {
                buffer,
                needed,
                got,
            });
        }
    }
    let (nr, na, ne) = (cfg.n_range, cfg.n_azimuth, cfg.n_elevation);
    let (acc, rest) = scratch.split_at_mut(nr + na + 2 * ne);
    let acc: &mut [f64] = bytemuck::cast_slice_mut(acc);
    let (r_acc, acc) = acc.split_at_mut(nr);
    let (a_acc, acc) = acc.split_at_mut(na);
    let (iev, ec) = acc.split_at_mut(ne);
    let ec: &mut [u64] = bytemuck::cast_slice_mut(ec);
    ec.fill(0);

    let binner = Binner::new(cfg);
    let mut xyz = [[0f64; BLOCK]; 3];
    let mut xyz32 = [[0f32; BLOCK]; 3];
    let mut block_bins = [0u32; BLOCK];
    let (n_in_range, bins): (usize, &[u32]) = if cfg.voxel_size > 0.0 {
        let (table, recs) = voxel_scratch(rest, n);
        let (n_in, m) = voxelize::<T, F>(points, cfg, table, recs);
        let table: &mut [u32] = bytemuck::cast_slice_mut(table);
        // Centroids block by block, their bins written over the table (no longer needed).
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
    } else {
        let bins: &mut [u32] = &mut bytemuck::cast_slice_mut(rest)[..n];
        let (min2, max2) = squared_range(cfg);
        let mut m = 0;
        for block in points.data.chunks(BLOCK * points.stride) {
            let nb = deinterleave(block, points.stride, &mut xyz);
            // Keep the points in range, compacted to the front of the block (branch-free).
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
    };
    for &b in bins {
        ec[unpack(b).2] += 1;
    }

    // IEV (spec §2 step 7): min-max normalised elevation counts; flat counts give all ones.
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
    // R-SOLiD = REC · IEV and A-SOLiD = AEC · IEV, accumulated point by point.
    r_acc.fill(0.0);
    a_acc.fill(0.0);
    for &b in bins {
        let (i, j, k) = unpack(b);
        r_acc[i] += iev[k];
        a_acc[j] += iev[k];
    }
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
        let needed = describe_scratch_len(n, cfg);
        if scratch.len() < needed {
            return Err(Error::BufferTooSmall {
                buffer: "scratch",
                needed,
                got: scratch.len(),
            });
        }
        let (table, recs) = voxel_scratch(scratch, n);
        let (n_in, m) = voxelize_on(Isa::best(), points, cfg, table, recs);
        if out_xyz.len() < 3 * m {
            return Err(Error::BufferTooSmall {
                buffer: "out_xyz",
                needed: 3 * m,
                got: out_xyz.len(),
            });
        }
        for (rec, out) in recs[..m].iter().zip(out_xyz.chunks_exact_mut(3)) {
            out.copy_from_slice(&centroid(rec, cfg.voxel_size));
        }
        Ok((n_in, m))
    }
}

/// Voxel downsampling on an origin-anchored grid ([spec §2](crate::spec#2-the-descriptor) step 3): accumulates each occupied
/// voxel's coordinate sums and count into `recs` (in order of first occupation) through an
/// open-addressing hash table. Returns (points in range, voxels occupied).
///
/// Points go through in blocks of [`BLOCK`], in passes without a branch on the data:
/// 1. keys: each point's voxel key (or [`OUTSIDE`]) and its offset inside the voxel in fixed
///    point, vectorised;
/// 2. runs: consecutive points of a scan line often share a voxel (124,668 points of a KITTI
///    scan make 23,000 runs in 11,000 voxels): a vectorised comparison of neighbouring keys
///    marks where runs end, and prefix sums of the offsets give every run's sums;
/// 3. the runs of points in range and their sums;
/// 4. table: one hash-table lookup per run (an insertion for a new voxel, without a branch on
///    whether it is new), then the runs' sums are added to their voxels' records.
///
/// Branches on the data (is this point in the same voxel as the last one, is this voxel new)
/// mispredict often on real scans and were most of the time of the previous version.
///
/// Sums are integers (offsets in units of `voxel_size / 2^FRAC_BITS`), so a voxel's sum is exact
/// and does not depend on how its points were split into runs and blocks.
#[inline(always)]
fn voxelize<T: Coord, F: Floor>(
    points: Points<'_, T>,
    cfg: &Config,
    table: &mut [[u64; SLOT]],
    recs: &mut [[u64; REC]],
) -> (usize, usize) {
    // Constant strides let the key pass use fixed shuffles; others take the general path.
    match points.stride {
        3 => voxelize_strided::<T, F, 3>(points, cfg, table, recs),
        4 => voxelize_strided::<T, F, 4>(points, cfg, table, recs),
        _ => voxelize_strided::<T, F, 0>(points, cfg, table, recs),
    }
}

/// Key of a point outside the range filter, and of an empty table slot (no real key has all 64
/// bits set).
const OUTSIDE: u64 = u64::MAX;
const BLOCK: usize = 512;

/// Bits of a coordinate's offset inside its voxel: offsets are `⌊x / v · 2^FRAC_BITS⌋ mod
/// 2^FRAC_BITS`, so a centroid is the mean of its points rounded to `v / 2^24` at worst.
const FRAC_BITS: u32 = 23;
const FRAC_MASK: u64 = (1 << FRAC_BITS) - 1;
/// Two offsets share a word (x and y; z and the point count), 32 bits each: a block's sums must
/// not carry from one half into the other.
const HALF: u64 = u32::MAX as u64;
const _: () = assert!(BLOCK as u64 * FRAC_MASK <= HALF);
/// Bias of a voxel index in its key: in-range indices lie in (-2^19, 2^19].
const BIAS: i64 = 1 << 20;
const AXIS_BITS: u32 = 21;
const AXIS_MASK: u64 = (1 << AXIS_BITS) - 1;

/// Copies x, y, z of the points of `rows` (stride `s`) into `xyz` as `f64`; returns the count.
#[inline(always)]
fn deinterleave<T: Coord>(rows: &[T], s: usize, xyz: &mut [[f64; BLOCK]; 3]) -> usize {
    let mut n = 0;
    for (i, p) in rows.chunks_exact(s).enumerate() {
        xyz[0][i] = p[0].to_f64();
        xyz[1][i] = p[1].to_f64();
        xyz[2][i] = p[2].to_f64();
        n = i + 1;
    }
    n
}

/// `(min_range², max_range²)`, the bounds [`in_range`] compares squared norms with.
#[inline(always)]
fn squared_range(cfg: &Config) -> (f64, f64) {
    (cfg.min_range * cfg.min_range, cfg.max_range * cfg.max_range)
}

/// Whether each point is finite and within `(min_range, max_range)` ([spec §2](crate::spec#2-the-descriptor) steps 1–2; the
/// squared-norm test also rejects NaN and infinities).
#[inline(always)]
fn in_range(x: f64, y: f64, z: f64, min2: f64, max2: f64) -> bool {
    let d2 = x * x + y * y + z * z;
    (d2 > min2) & (d2 < max2)
}

/// A block of points reduced to keys and fixed-point offsets, then to runs of equal keys.
struct Block {
    /// Voxel key of each point ([`OUTSIDE`] when out of range), then an [`OUTSIDE`] sentinel.
    keys: [u64; BLOCK + 1],
    /// Offsets inside the voxel in two words, then their prefix sums: x in the low half and y
    /// in the high half of the first; z in the low half and 1 (the point) in the high half of
    /// the second. (Side by side, the prefix sums take one 128-bit add and store a point.)
    xy_zc: [[u64; 2]; BLOCK],
    /// Bit `i % 64` of word `i / 64` is set when point `i` ends a run (the next key differs).
    ends: [u64; BLOCK / 64],
    /// The runs of points in range: key and sums (words as in `xy_zc`).
    run_key: [u64; BLOCK],
    run_sums: [[u64; 2]; BLOCK],
    /// The voxel (record index) of each run.
    run_voxel: [usize; BLOCK],
}

impl Block {
    fn new() -> Self {
        Block {
            keys: [OUTSIDE; BLOCK + 1],
            xy_zc: [[0; 2]; BLOCK],
            ends: [0; BLOCK / 64],
            run_key: [OUTSIDE; BLOCK],
            run_sums: [[0; 2]; BLOCK],
            run_voxel: [0; BLOCK],
        }
    }

    /// Pass 1: keys of the points of `rows` (up to [`BLOCK`]; three 21-bit biased voxel indices)
    /// and their offsets; returns their number. Branch-free, so it vectorises.
    #[inline(always)]
    fn keys<T: Coord, F: Floor>(
        &mut self,
        rows: &[T],
        s: usize,
        scale: f64,
        min2: f64,
        max2: f64,
    ) -> usize {
        let mut n = 0;
        for (i, p) in rows.chunks_exact(s).take(BLOCK).enumerate() {
            let (x, y, z) = (p[0].to_f64(), p[1].to_f64(), p[2].to_f64());
            n = i + 1;
            // In range, |x / v| < 2^19 (validated), so ⌊x / v · 2^FRAC_BITS⌋ + 2^20 · 2^FRAC_BITS
            // is positive with the biased voxel index ⌊x / v⌋ + 2^20 in its top 21 bits (exactly:
            // scaling by a power of two rounds nothing) and the offset in its low bits. Out of
            // range the values are garbage and the key is discarded.
            let [ux, uy, uz] =
                [x, y, z].map(|c| F::floor_i64(c * scale).wrapping_add(BIAS << FRAC_BITS) as u64);
            let key = ux >> FRAC_BITS
                | (uy >> FRAC_BITS) << AXIS_BITS
                | (uz >> FRAC_BITS) << (2 * AXIS_BITS);
            self.keys[i] = if in_range(x, y, z, min2, max2) {
                key
            } else {
                OUTSIDE
            };
            self.xy_zc[i] = [
                (ux & FRAC_MASK) | (uy & FRAC_MASK) << 32,
                (uz & FRAC_MASK) | 1 << 32,
            ];
        }
        self.keys[n] = OUTSIDE;
        n
    }

    /// Pass 2: marks the last point of every run of equal keys among the first `n` points
    /// (vectorised comparisons) and turns the offsets into prefix sums (a one-cycle chain).
    #[inline(always)]
    fn runs(&mut self, n: usize) {
        let n = n.min(BLOCK);
        for (w, end) in self.ends.iter_mut().enumerate() {
            let keys = &self.keys[w * 64..w * 64 + 65];
            let mut bits = 0u64;
            for j in 0..64 {
                bits |= u64::from(keys[j] != keys[j + 1]) << j;
            }
            // Keys past `n` are left from an earlier block.
            let valid = n.saturating_sub(w * 64);
            *end = if valid >= 64 {
                bits
            } else {
                bits & ((1u64 << valid) - 1)
            };
        }
        // Four points at a time: their own prefix sums first, off the chain of the running sum,
        // which then takes one add per four points instead of one per point.
        let add = |a: [u64; 2], b: [u64; 2]| [a[0] + b[0], a[1] + b[1]];
        let mut sum = [0u64; 2];
        let mut quads = self.xy_zc[..n].chunks_exact_mut(4);
        for q in &mut quads {
            let p1 = add(q[0], q[1]);
            let p2 = add(p1, q[2]);
            let p3 = add(p2, q[3]);
            (q[0], q[1], q[2], q[3]) = (add(sum, q[0]), add(sum, p1), add(sum, p2), add(sum, p3));
            sum = q[3];
        }
        for v in quads.into_remainder() {
            sum = add(sum, *v);
            *v = sum;
        }
    }

    /// Pass 3: the runs of points in range, with their sums: the difference of the prefix sums
    /// at a run's last point and at the previous run's, half by half (each half only grows
    /// within the block, so nothing borrows across halves). Returns their number.
    ///
    /// Branch-free. (Where a scan line grazes a voxel boundary its points alternate between
    /// two voxels, A B A B; merging such runs here, as before, cost more than the table updates
    /// it spared.)
    #[inline(always)]
    fn collect_runs(&mut self) -> usize {
        let (mut r, mut before) = (0, [0u64; 2]);
        for (w, &end) in self.ends.iter().enumerate() {
            let mut bits = end;
            while bits != 0 {
                let i = (w * 64 + bits.trailing_zeros() as usize) & (BLOCK - 1);
                bits &= bits - 1;
                let (key, sums) = (self.keys[i], self.xy_zc[i]);
                // A run out of range is written, then overwritten by the next one. (r < i + 1:
                // the mask only spares a bounds check.)
                self.run_key[r & (BLOCK - 1)] = key;
                self.run_sums[r & (BLOCK - 1)] = [sums[0] - before[0], sums[1] - before[1]];
                before = sums;
                r += usize::from(key != OUTSIDE);
            }
        }
        r
    }
}

/// Bytes between two reads ahead of the current block (a page).
const PAGE: usize = 4096;

#[inline(always)]
fn voxelize_strided<T: Coord, F: Floor, const S: usize>(
    points: Points<'_, T>,
    cfg: &Config,
    table: &mut [[u64; SLOT]],
    recs: &mut [[u64; REC]],
) -> (usize, usize) {
    let s = if S == 0 { points.stride } else { S };
    let scale = (1.0 / cfg.voxel_size) * (1u64 << FRAC_BITS) as f64;
    let (min2, max2) = squared_range(cfg);
    let mut acc = VoxelTable::new(table, recs, points.len());
    let mut b = Block::new();
    let mut n_in = 0u64;
    let mut ahead = points.data.chunks(BLOCK * s).skip(1);
    for block in points.data.chunks(BLOCK * s) {
        // Read one value per 4 KiB of the next block: the page's translation is ready and the
        // hardware prefetcher, which stops at page boundaries, starts streaming the page while
        // this block is processed. (One read per cache line instead costs more than it saves
        // when the scan is already in cache: each read waits for its line in order.)
        if let Some(next) = ahead.next() {
            let mut touched = 0;
            for line in next.iter().step_by(PAGE / core::mem::size_of::<T>()) {
                touched ^= line.to_f64().to_bits();
            }
            core::hint::black_box(touched);
        }
        let nb = b.keys::<T, F>(block, s, scale, min2, max2);
        b.runs(nb);
        let runs = b.collect_runs();
        n_in += acc.add_runs(&mut b, runs);
    }
    (n_in as usize, acc.m)
}

/// The centroid of a voxel record (key, integer offset sums, count).
#[inline(always)]
fn centroid(rec: &[u64], voxel_size: f64) -> [f64; 3] {
    const UNIT: f64 = 1.0 / (1u64 << FRAC_BITS) as f64;
    // One division per voxel, not one per coordinate: divisions are the slow part here.
    let unit_per_point = UNIT / rec[4] as f64;
    let mut c = [0.0; 3];
    for (d, c) in c.iter_mut().enumerate() {
        let index = ((rec[0] >> (d as u32 * AXIS_BITS)) & AXIS_MASK) as i64 - BIAS;
        // Offsets were floored: add half a unit so the mean is not biased.
        *c = (index as f64 + rec[1 + d] as f64 * unit_per_point + 0.5 * UNIT) * voxel_size;
    }
    c
}

/// The voxel hash table and its records.
struct VoxelTable<'a> {
    /// Slots: a voxel key ([`OUTSIDE`] when free) and the index of its record.
    table: &'a mut [[u64; SLOT]],
    recs: &'a mut [[u64; REC]],
    /// Slots in use (a power of two), and the shift that maps a hash to one of them.
    cap: usize,
    shift: u32,
    /// Voxels so far.
    m: usize,
}

impl<'a> VoxelTable<'a> {
    #[inline(always)]
    fn new(table: &'a mut [[u64; SLOT]], recs: &'a mut [[u64; REC]], n_points: usize) -> Self {
        // Start with a table for a voxel per four points (a scan has fewer), cache-resident for
        // a scan's worth of points, and double it whenever it could get over half full; the
        // scratch holds room for the worst case (every point its own voxel).
        let cap = table
            .len()
            .min((n_points / 4).next_power_of_two().max(MIN_SLOTS));
        clear_slots(&mut table[..cap]);
        VoxelTable {
            table,
            recs,
            cap,
            shift: 64 - cap.trailing_zeros(),
            m: 0,
        }
    }

    /// Pass 4: adds the runs of `b` to their voxels; returns the number of points added.
    /// Whether a voxel is new is data, not a branch.
    #[inline(never)]
    fn add_runs(&mut self, b: &mut Block, runs: usize) -> u64 {
        self.reserve(BLOCK);
        // Locals, not fields, so that they stay in registers.
        let (mask, shift, m0) = (self.cap - 1, self.shift, self.m);
        let mut m = m0;
        let table = &mut self.table[..self.cap];
        let keys = &b.run_key[..runs];
        let voxel = &mut b.run_voxel[..runs];
        // First every run's voxel (a lookup, and an insertion for a new one), then the sums:
        // the loads of the records no longer wait behind the probes of the runs before them.
        for (&key, v_out) in keys.iter().zip(voxel.iter_mut()) {
            // Stop at the key or at a free slot in one comparison: keys are below 2^63 and a
            // free slot holds 2^64 - 1, so `k ^ key` is 0 for the key, negative for a free slot
            // and positive for another key. (Two comparisons become two branches, one of which,
            // "is the voxel new", mispredicts half the time.)
            let other = |k: u64| ((k ^ key) as i64) > 0;
            // The first step of the probe is arithmetic, not a branch, and the slot is read
            // again rather than selected so that the compiler cannot turn the selection back
            // into a branch; the second read hits the same cache line.
            let s0 = slot_of(key, shift);
            let mut slot = (s0 + usize::from(other(table[s0][0]))) & mask;
            let mut k = table[slot][0];
            while other(k) {
                slot = (slot + 1) & mask;
                k = table[slot][0];
            }
            // A free slot holds index 2^64 - 1, so this is the stored index of a voxel seen
            // before and `m` for a new one (a minimum, not a branch).
            let v = (table[slot][1] as usize).min(m);
            table[slot] = [key, v as u64];
            m += usize::from(k != key);
            *v_out = v;
        }
        // New voxels take the next records, cleared: adding to them is the same operation as
        // adding to an existing one. (m < number of points: there is room.)
        self.recs[m0..m].fill([0; REC]);
        self.m = m;
        let recs = &mut *self.recs;
        let mut n_in = 0u64;
        for ((&key, &[xy, zc]), &v) in keys.iter().zip(&b.run_sums).zip(voxel.iter()) {
            n_in += zc >> 32;
            let rec = &mut recs[v];
            rec[0] = key;
            rec[1] += xy & HALF;
            rec[2] += xy >> 32;
            rec[3] += zc & HALF;
            rec[4] += zc >> 32;
        }
        n_in
    }

    /// Grows the table so that `more` new voxels keep it at most half full. (It stops at the
    /// size of the scratch, which is enough for every point to be its own voxel.)
    #[inline(always)]
    fn reserve(&mut self, more: usize) {
        while 2 * (self.m + more) > self.cap && self.cap < self.table.len() {
            self.grow();
        }
    }

    #[cold]
    fn grow(&mut self) {
        self.cap *= 2;
        self.shift -= 1;
        rehash(
            &mut self.table[..self.cap],
            &self.recs[..self.m],
            self.shift,
        );
    }
}

/// Smallest hash-table size in slots (64 KiB).
const MIN_SLOTS: usize = 1 << 12;

/// Marks every slot of `table` free.
fn clear_slots(table: &mut [[u64; SLOT]]) {
    table.fill([OUTSIDE, u64::MAX]);
}

#[inline(always)]
fn slot_of(key: u64, shift: u32) -> usize {
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> shift) as usize
}

/// Clears `table` and re-inserts the records `recs` (keys in their first word).
fn rehash(table: &mut [[u64; SLOT]], recs: &[[u64; REC]], shift: u32) {
    clear_slots(table);
    let mask = table.len() - 1;
    for (v, rec) in recs.iter().enumerate() {
        let mut slot = slot_of(rec[0], shift);
        while table[slot][0] != OUTSIDE {
            slot = (slot + 1) & mask;
        }
        table[slot] = [rec[0], v as u64];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> Config {
        Config::preset("hdl64").unwrap()
    }

    fn run(xyz: &[f64], cfg: &Config) -> (Vec<f32>, Vec<f32>, Stats) {
        let pts = Points::new(xyz, 3).unwrap();
        let mut scratch = vec![0; describe_scratch_len(pts.len(), cfg)];
        let mut r = vec![0.0; cfg.n_range];
        let mut a = vec![0.0; cfg.n_azimuth];
        let s = describe(pts, cfg, &mut scratch, &mut r, &mut a).unwrap();
        (r, a, s)
    }

    #[test]
    fn empty_scan_is_all_zero() {
        let (r, a, s) = run(&[], &cfg());
        assert!(r.iter().chain(&a).all(|&v| v == 0.0));
        assert_eq!(s, Stats::default());
    }

    #[test]
    fn single_point_lands_in_its_bins() {
        // x = 10, y = 10: r = 14.14 m -> bin 7 of 40 over 80 m; azimuth 45° -> bin 7 of 60;
        // flat EC (one point in one bin, but min = 0 over 64 bins) -> IEV of its bin is 1.
        let (r, a, s) = run(&[10.0, 10.0, -1.0], &cfg());
        assert_eq!(s.n_kept, 1);
        let nz: Vec<usize> = (0..40).filter(|&i| r[i] != 0.0).collect();
        assert_eq!(nz, [7]);
        assert_eq!(r[7], 1.0);
        let nz: Vec<usize> = (0..60).filter(|&j| a[j] != 0.0).collect();
        assert_eq!(nz, [7]);
    }

    #[test]
    fn range_filter_is_strict_and_drops_non_finite() {
        let c = Config {
            voxel_size: 0.0,
            ..cfg()
        };
        let pts = [
            3.0,
            0.0,
            0.0, // on min_range: dropped
            80.0,
            0.0,
            0.0, // on max_range: dropped
            f64::NAN,
            1.0,
            1.0,
            f64::INFINITY,
            0.0,
            0.0,
            1e200,
            0.0,
            0.0,
            5.0,
            0.0,
            0.0, // kept
        ];
        let (_, _, s) = run(&pts, &c);
        assert_eq!((s.n_points, s.n_in_range, s.n_kept), (6, 1, 1));
    }

    #[test]
    fn voxel_centroids_merge_points() {
        // Two points in voxel (20,0,0) and one in (21,0,0) with v = 0.5.
        let pts = [10.1, 0.1, 0.1, 10.2, 0.2, 0.2, 10.6, 0.1, 0.1];
        let (_, _, s) = run(&pts, &cfg());
        assert_eq!((s.n_in_range, s.n_kept), (3, 2));
        // Negative coordinates floor away from zero: -0.1 and 0.1 are different voxels.
        let pts = [10.1, -0.1, 0.1, 10.1, 0.1, 0.1];
        let (_, _, s) = run(&pts, &cfg());
        assert_eq!(s.n_kept, 2);
    }

    /// Centroids of `xyz` (stride 3) grouped naively, in order of first occupation, and the
    /// number of points in range.
    fn naive_voxels(xyz: &[f64], c: &Config) -> (Vec<[f64; 3]>, usize) {
        let mut order: Vec<[i64; 3]> = Vec::new();
        let mut sums: std::collections::HashMap<[i64; 3], [f64; 4]> = Default::default();
        let mut n_in = 0;
        for p in xyz.chunks_exact(3) {
            let d = libm::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            if !(d > c.min_range && d < c.max_range) {
                continue;
            }
            n_in += 1;
            let k = [0, 1, 2].map(|i| libm::floor(p[i] / c.voxel_size) as i64);
            let g = sums.entry(k).or_insert_with(|| {
                order.push(k);
                [0.0; 4]
            });
            *g = [g[0] + p[0], g[1] + p[1], g[2] + p[2], g[3] + 1.0];
        }
        let cents = order
            .iter()
            .map(|k| {
                let g = sums[k];
                [g[0] / g[3], g[1] / g[3], g[2] / g[3]]
            })
            .collect();
        (cents, n_in)
    }

    #[test]
    fn voxels_keep_their_order_through_runs_flicker_and_blocks() {
        // A scan line that grazes voxel boundaries (A B A B ...), long runs in one voxel that
        // span several blocks, points out of range and not finite between points of one voxel,
        // and voxels revisited far apart: the order of first occupation, the counts and the
        // centroids must be those of a naive grouping.
        let c = cfg();
        let mut xyz = Vec::new();
        for i in 0..3000 {
            let t = i as f64;
            // Flicker across x = 10 and y = 0 (negative coordinates floor away from zero).
            xyz.extend([10.0 + 0.01 * libm::sin(t), 0.01 * libm::cos(1.7 * t), -1.0]);
            if i % 97 == 0 {
                xyz.extend([f64::NAN, 0.0, 0.0]);
                xyz.extend([0.5, 0.5, 0.5]); // inside min_range
            }
        }
        for i in 0..1500 {
            xyz.extend([20.1 + 1e-4 * i as f64, 5.2, 0.3]); // one voxel over three blocks
        }
        for i in 0..3000 {
            let t = i as f64 * 0.05;
            xyz.extend([
                30.0 * libm::cos(t),
                30.0 * libm::sin(t),
                0.1 * libm::sin(7.0 * t),
            ]);
        }
        xyz.extend([10.001, 0.001, -0.999, 20.2, 5.3, 0.4]); // back to early voxels
        let (naive, n_naive) = naive_voxels(&xyz, &c);
        let pts = Points::new(&xyz, 3).unwrap();
        let mut scratch = vec![0; describe_scratch_len(pts.len(), &c)];
        let mut out = vec![0.0; xyz.len()];
        let (n_in, m) = stages::voxel_downsample(pts, &c, &mut scratch, &mut out).unwrap();
        assert_eq!((n_in, m), (n_naive, naive.len()));
        for (ours, theirs) in out.chunks_exact(3).zip(&naive) {
            for i in 0..3 {
                assert!((ours[i] - theirs[i]).abs() < 0.5 / (1u64 << 24) as f64 + 1e-12);
            }
        }
    }

    #[test]
    fn voxel_table_grows_and_matches_a_naive_grouping() {
        // 60k pseudo-random points, many sharing voxels, enough distinct voxels to force several
        // table doublings; centroids must equal a BTreeMap grouping.
        use std::collections::BTreeMap;
        let mut state = 0x1234_5678_9abc_def0u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut xyz = Vec::new();
        for _ in 0..60_000 {
            xyz.extend([
                next() * 120.0 - 60.0,
                next() * 120.0 - 60.0,
                next() * 8.0 - 4.0,
            ]);
        }
        let c = cfg();
        let pts = Points::new(&xyz, 3).unwrap();
        let mut scratch = vec![0; describe_scratch_len(pts.len(), &c)];
        let mut out = vec![0.0; xyz.len()];
        let (n_in, m) = stages::voxel_downsample(pts, &c, &mut scratch, &mut out).unwrap();
        let mut groups: BTreeMap<[i64; 3], (f64, f64, f64, f64)> = BTreeMap::new();
        let mut n_naive = 0;
        for p in xyz.chunks_exact(3) {
            let d = libm::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            if !(d > 3.0 && d < 80.0) {
                continue;
            }
            n_naive += 1;
            let k = [0, 1, 2].map(|i| libm::floor(p[i] / 0.5) as i64);
            let g = groups.entry(k).or_insert((0.0, 0.0, 0.0, 0.0));
            *g = (g.0 + p[0], g.1 + p[1], g.2 + p[2], g.3 + 1.0);
        }
        assert_eq!(n_in, n_naive);
        assert_eq!(m, groups.len());
        let initial_slots = (xyz.len() / 3 / 4).next_power_of_two();
        assert!(
            m > initial_slots,
            "test must force two table doublings ({m} voxels)"
        );
        let mut ours: Vec<[f64; 3]> = out[..3 * m]
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        let mut naive: Vec<[f64; 3]> = groups
            .values()
            .map(|g| [g.0 / g.3, g.1 / g.3, g.2 / g.3])
            .collect();
        ours.sort_by(|a, b| a.partial_cmp(b).unwrap());
        naive.sort_by(|a, b| a.partial_cmp(b).unwrap());
        for (a, b) in ours.iter().zip(&naive) {
            for i in 0..3 {
                // Offsets are summed in units of v / 2^23: the mean is off by v / 2^24 at most.
                assert!(
                    (a[i] - b[i]).abs() < 0.5 / (1u64 << 24) as f64 + 1e-12,
                    "{a:?} vs {b:?}"
                );
            }
        }
    }

    /// The output of one compiled copy of [`describe`] (stats and the bits of R-SOLiD and
    /// A-SOLiD), and of [`stages::voxel_downsample`]'s voxelisation (points in range, then every
    /// voxel record).
    fn run_copy<T: Coord>(isa: Isa, pts: Points<'_, T>, c: &Config) -> (Stats, Vec<u32>, Vec<u64>) {
        let mut scratch = vec![0; describe_scratch_len(pts.len(), c)];
        let (mut r, mut a) = (vec![0f32; c.n_range], vec![0f32; c.n_azimuth]);
        let stats = describe_on(isa, pts, c, &mut scratch, &mut r, &mut a).unwrap();
        let bits = r.iter().chain(&a).map(|x| x.to_bits()).collect();
        let mut voxels = Vec::new();
        if c.voxel_size > 0.0 {
            let (table, recs) = voxel_scratch(&mut scratch, pts.len());
            let (n_in, m) = voxelize_on(isa, pts, c, table, recs);
            voxels.push(n_in as u64);
            voxels.extend(recs[..m].iter().flatten());
        }
        (stats, bits, voxels)
    }

    /// A synthetic spinning-LiDAR scan: rings of points in scan order (so runs, voxel-boundary
    /// flicker and revisited voxels occur as on a real scan), then scattered points, with
    /// points out of range and not finite mixed in. Three values a point, plus `extra` columns.
    fn ring_scan() -> impl proptest::strategy::Strategy<Value = (Vec<f64>, usize)> {
        use proptest::prelude::*;
        let ring = (3.0f64..70.0, -3.0f64..3.0, 16usize..900, 0.0f64..0.2);
        let scattered = (-90.0f64..90.0, -90.0f64..90.0, -5.0f64..5.0);
        (
            prop::collection::vec(ring, 1..6),
            prop::collection::vec(scattered, 0..200),
            0usize..3,
            any::<u64>(),
        )
            .prop_map(|(rings, scattered, extra, seed)| {
                let mut state = seed | 1;
                let mut next = move || {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state >> 11) as f64 / (1u64 << 53) as f64
                };
                let mut xyz = Vec::new();
                let push = |p: [f64; 3], xyz: &mut Vec<f64>| {
                    xyz.extend(p);
                    xyz.extend((0..extra).map(|e| e as f64));
                };
                for (rho, z, n, noise) in rings {
                    for i in 0..n {
                        let t = core::f64::consts::TAU * i as f64 / n as f64;
                        let rho = rho + noise * (next() - 0.5);
                        let p = match (next() * 40.0) as u32 {
                            0 => [f64::NAN, 1.0, 0.0],
                            1 => [0.1, 0.2, 0.3],
                            2 => [90.0, 0.0, 0.0],
                            _ => [rho * libm::cos(t), rho * libm::sin(t), z],
                        };
                        push(p, &mut xyz);
                    }
                }
                for (x, y, z) in scattered {
                    push([x, y, z], &mut xyz);
                }
                (xyz, 3 + extra)
            })
    }

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config::with_cases(64))]

        /// Every compiled copy of `describe` this CPU runs gives the bits of the portable one, for
        /// `f64` and `f32` points, any stride, with and without voxels.
        #[test]
        fn every_copy_gives_the_portable_bits(
            (xyz, stride) in ring_scan(),
            voxel in proptest::sample::select(vec![0.0, 0.1, 0.25, 0.5, 1.3]),
        ) {
            let c = Config { voxel_size: voxel, ..cfg() };
            let f32s: Vec<f32> = xyz.iter().map(|&v| v as f32).collect();
            let wide = Points::new(&xyz, stride).unwrap();
            let narrow = Points::new(&f32s, stride).unwrap();
            let (want64, want32) = (
                run_copy(Isa::Portable, wide, &c),
                run_copy(Isa::Portable, narrow, &c),
            );
            for isa in Isa::available() {
                proptest::prop_assert_eq!(&run_copy(isa, wide, &c), &want64, "{:?} on f64", isa);
                proptest::prop_assert_eq!(&run_copy(isa, narrow, &c), &want32, "{:?} on f32", isa);
            }
        }
    }

    #[test]
    fn out_of_fov_points_go_to_edge_bins() {
        let c = Config {
            voxel_size: 0.0,
            ..cfg()
        };
        // Straight up and straight down: elevation bins 63 and 0; both counted, nothing wraps.
        let (r, _, s) = run(&[0.0, 0.0, 10.0, 0.0, 0.0, -10.0, 20.0, 0.0, 0.0], &c);
        assert_eq!(s.n_kept, 3);
        assert!(r.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn buffers_too_small_are_errors() {
        let c = cfg();
        let xyz = [10.0f32, 0.0, 0.0];
        let pts = Points::new(&xyz, 3).unwrap();
        let need = describe_scratch_len(1, &c);
        let mut scratch = vec![0; need - 1];
        let mut r = vec![0.0; 40];
        let mut a = vec![0.0; 60];
        assert_eq!(
            describe(pts, &c, &mut scratch, &mut r, &mut a),
            Err(Error::BufferTooSmall {
                buffer: "scratch",
                needed: need,
                got: need - 1
            })
        );
        let mut scratch = vec![0; need];
        assert!(matches!(
            describe(pts, &c, &mut scratch, &mut r[..39], &mut a),
            Err(Error::BufferTooSmall {
                buffer: "r_out",
                ..
            })
        ));
        assert!(matches!(
            describe(pts, &c, &mut scratch, &mut r, &mut a[..1]),
            Err(Error::BufferTooSmall {
                buffer: "a_out",
                ..
            })
        ));
    }

    #[test]
    fn bad_layout_is_an_error() {
        let xyz = [1.0f32; 8];
        assert!(Points::new(&xyz, 3).is_err());
        assert!(Points::new(&xyz, 2).is_err());
        assert_eq!(Points::new(&xyz, 4).unwrap().len(), 2);
    }
}
