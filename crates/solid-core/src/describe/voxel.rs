//! Voxel downsampling on an origin-anchored grid ([spec §2](crate::spec#2-the-descriptor)
//! step 3): keys, runs of equal keys and the open-addressing hash table of the voxels' sums.

use super::bin::{in_range, squared_range, BLOCK};
use super::{Coord, Points, Scratch};
use crate::math::Floor;
use crate::Config;

/// Slots of the voxel hash table for `n` points: a power of two at least twice `n`.
pub(super) fn table_slots(n: usize) -> usize {
    n.saturating_mul(2).max(16).next_power_of_two()
}

/// Words of a voxel record: key, sum x, sum y, sum z, count.
pub(super) const REC: usize = 5;
/// Words of a hash-table slot: the voxel key ([`OUTSIDE`] when empty) and its record's index.
/// Keeping the key in the slot leaves one memory access on a lookup's critical path.
pub(super) const SLOT: usize = 2;

/// The hash table and the voxel records for `n` points, from a scratch buffer of at least
/// `describe_scratch_len(n, _)` elements (checked by the callers).
pub(super) fn voxel_scratch(
    scratch: &mut [Scratch],
    n: usize,
) -> (&mut [[u64; SLOT]], &mut [[u64; REC]]) {
    let (table, recs) = scratch.split_at_mut(table_slots(n) * SLOT);
    (
        bytemuck::cast_slice_mut(table),
        bytemuck::cast_slice_mut(&mut recs[..n * REC]),
    )
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
pub(super) fn voxelize<T: Coord, F: Floor>(
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
pub(super) const OUTSIDE: u64 = u64::MAX;

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

/// A block of points reduced to keys and fixed-point offsets, then to runs of equal keys.
pub(super) struct Block {
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
    pub(super) fn new() -> Self {
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
    pub(super) fn keys<T: Coord, F: Floor>(
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
    pub(super) fn runs(&mut self, n: usize) {
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
    pub(super) fn collect_runs(&mut self) -> usize {
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
pub(super) fn voxelize_strided<T: Coord, F: Floor, const S: usize>(
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
pub(super) fn centroid(rec: &[u64], voxel_size: f64) -> [f64; 3] {
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
pub(super) struct VoxelTable<'a> {
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
    pub(super) fn new(
        table: &'a mut [[u64; SLOT]],
        recs: &'a mut [[u64; REC]],
        n_points: usize,
    ) -> Self {
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
    pub(super) fn add_runs(&mut self, b: &mut Block, runs: usize) -> u64 {
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
    pub(super) fn reserve(&mut self, more: usize) {
        while 2 * (self.m + more) > self.cap && self.cap < self.table.len() {
            self.grow();
        }
    }

    #[cold]
    pub(super) fn grow(&mut self) {
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
pub(super) const MIN_SLOTS: usize = 1 << 12;

/// Marks every slot of `table` free.
pub(super) fn clear_slots(table: &mut [[u64; SLOT]]) {
    table.fill([OUTSIDE, u64::MAX]);
}

#[inline(always)]
pub(super) fn slot_of(key: u64, shift: u32) -> usize {
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> shift) as usize
}

/// Clears `table` and re-inserts the records `recs` (keys in their first word).
pub(super) fn rehash(table: &mut [[u64; SLOT]], recs: &[[u64; REC]], shift: u32) {
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
