//! The per-point steps of [spec §2](crate::spec#2-the-descriptor): the range filter (steps 1–2)
//! and the bin indices (steps 4–5), on blocks of points.

use super::Coord;
use crate::math::{atan2, sqrtf, Floor};
use crate::Config;

/// Points handled at a time by the passes of [`super::describe`] and [`super::voxel`].
pub(super) const BLOCK: usize = 512;

/// Bin geometry derived once per call from a validated config: every division of [spec §2](crate::spec#2-the-descriptor) step 5
/// becomes a multiplication by a precomputed factor (a point exactly on a bin edge may land one
/// bin over, well within [spec §7](crate::spec#7-matching-the-golden-outputs)'s tolerance; the result is still the same bits everywhere).
///
/// Binning computes in `f32` (which §7 allows): twice the lanes of `f64` and faster division
/// and square root; a point moves to a neighbouring bin only within about 1e-6 of an edge.
pub(super) struct Binner {
    range_scale: f32,
    azimuth_scale: f32,
    elevation_scale: f32,
    fov_down: f32,
    nr_max: f32,
    na_max: f32,
    ne_max: f32,
}

impl Binner {
    pub(super) fn new(cfg: &Config) -> Self {
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
    pub(super) fn bin<F: Floor>(&self, x: f32, y: f32, z: f32) -> u32 {
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
    pub(super) fn bin_block<F: Floor>(
        &self,
        xyz: &[[f32; BLOCK]; 3],
        n: usize,
        out: &mut [u32; BLOCK],
    ) {
        for i in 0..n.min(BLOCK) {
            out[i] = self.bin::<F>(xyz[0][i], xyz[1][i], xyz[2][i]);
        }
    }
}

/// `min(v, hi)`, and `hi` when `v` is NaN: one instruction, unlike [`f32::min`].
#[inline(always)]
pub(super) fn below(v: f32, hi: f32) -> f32 {
    if v < hi {
        v
    } else {
        hi
    }
}

/// `max(v, lo)`, and `lo` when `v` is NaN: one instruction, unlike [`f32::max`].
#[inline(always)]
pub(super) fn above(v: f32, lo: f32) -> f32 {
    if v > lo {
        v
    } else {
        lo
    }
}

#[inline(always)]
pub(super) fn unpack(b: u32) -> (usize, usize, usize) {
    let b = b as usize;
    (b & 0x3ff, (b >> 10) & 0xfff, b >> 22)
}

/// Copies x, y, z of the points of `rows` (stride `s`) into `xyz` as `f64`; returns the count.
#[inline(always)]
pub(super) fn deinterleave<T: Coord>(rows: &[T], s: usize, xyz: &mut [[f64; BLOCK]; 3]) -> usize {
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
pub(super) fn squared_range(cfg: &Config) -> (f64, f64) {
    (cfg.min_range * cfg.min_range, cfg.max_range * cfg.max_range)
}

/// Whether each point is finite and within `(min_range, max_range)` ([spec §2](crate::spec#2-the-descriptor) steps 1–2; the
/// squared-norm test also rejects NaN and infinities).
#[inline(always)]
pub(super) fn in_range(x: f64, y: f64, z: f64, min2: f64, max2: f64) -> bool {
    let d2 = x * x + y * y + z * z;
    (d2 > min2) & (d2 < max2)
}
