//! The descriptor: [`SolidDescriber`] (a configuration and its reusable scratch), the R-SOLiD
//! distance and the A-SOLiD heading (docs/spec.md §2-3).

use std::sync::Mutex;

use solid_lidar::{cosine_distance, describe, describe_scratch_len, heading, heading_refined};
use solid_lidar::{Config, Scratch};

use crate::config::SolidConfig;
use crate::{guard, new_handle, nonnull, points, put, release, slice, slice_mut, with_points};
use crate::{Failure, SolidPoints, SolidStatus};

/// What one description kept of the scan.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct SolidDescribeStats {
    /// Points given.
    pub n_points: usize,
    /// Points with finite coordinates within (min_range, max_range).
    pub n_in_range: usize,
    /// Points binned (after voxel downsampling).
    pub n_kept: usize,
}

/// Describes scans with one configuration, reusing its scratch memory from call to call (after
/// the first scans of a size, a description allocates nothing).
///
/// Threads: may be shared; calls on one describer run one at a time. Give each thread its own
/// describer to describe in parallel.
pub struct SolidDescriber {
    cfg: Config,
    scratch: Mutex<Vec<Scratch>>,
}

/// Makes a describer for `config` (copied: later changes to `config` do not affect it) in
/// `*out`; release it with [`solid_describer_free`].
#[no_mangle]
pub unsafe extern "C" fn solid_describer_new(
    config: *const SolidConfig,
    out_describer: *mut *mut SolidDescriber,
) -> SolidStatus {
    new_handle(
        "solid_describer_new",
        out_describer,
        "out_describer",
        || {
            let cfg = nonnull(config, "config")?.cfg;
            cfg.validate()?;
            Ok(SolidDescriber {
                cfg,
                scratch: Mutex::new(Vec::new()),
            })
        },
    )
}

/// Releases a describer (NULL: nothing).
#[no_mangle]
pub unsafe extern "C" fn solid_describer_free(describer: *mut SolidDescriber) {
    release(describer);
}

/// Describes one scan: writes its R-SOLiD (`n_range` values) to `r_out` and its A-SOLiD
/// (`n_azimuth` values) to `a_out` (lengths from `solid_config_lengths`), and when `stats` is not
/// NULL, what was kept. The points are read in place (see [`SolidPoints`]); points with a
/// non-finite coordinate are skipped. Bit for bit the values of the Rust and Python APIs.
#[no_mangle]
pub unsafe extern "C" fn solid_describe(
    describer: *const SolidDescriber,
    points_in: *const SolidPoints,
    r_out: *mut f32,
    r_len: usize,
    a_out: *mut f32,
    a_len: usize,
    stats: *mut SolidDescribeStats,
) -> SolidStatus {
    guard("solid_describe", || {
        let d = nonnull(describer, "describer")?;
        let pts = points(points_in)?;
        let r = slice_mut(r_out, r_len, "r_out")?;
        let a = slice_mut(a_out, a_len, "a_out")?;
        let mut scratch = d.scratch.lock().map_err(|_| {
            Failure::new(
                SolidStatus::Panic,
                "describer unusable after an internal error",
            )
        })?;
        let n = with_points!(pts, |p| p.len());
        let need = describe_scratch_len(n, &d.cfg);
        let have = scratch.len();
        if have < need {
            scratch
                .try_reserve_exact(need - have)
                .map_err(|_| Failure::new(SolidStatus::OutOfMemory, "describe scratch"))?;
            scratch.resize(need, 0);
        }
        let s = with_points!(pts, |p| describe(p, &d.cfg, &mut scratch, r, a))?;
        if let Some(st) = stats.as_mut() {
            *st = SolidDescribeStats {
                n_points: s.n_points,
                n_in_range: s.n_in_range,
                n_kept: s.n_kept,
            };
        }
        Ok(())
    })
}

/// The cosine distance of two R-SOLiDs of `len` values (docs/spec.md §3): in [0, 1], 1 when
/// either is all zeros.
#[no_mangle]
pub unsafe extern "C" fn solid_distance(
    r_query: *const f32,
    r_candidate: *const f32,
    len: usize,
    distance: *mut f64,
) -> SolidStatus {
    guard("solid_distance", || {
        let (q, c) = pair(r_query, r_candidate, len, ["r_query", "r_candidate"])?;
        put(distance, "distance", cosine_distance(q, c)?)
    })
}

/// The heading of the query relative to the candidate from their A-SOLiDs of `len` values,
/// degrees in (-180, 180] (docs/spec.md §3: the query scan is about the candidate scan rotated by
/// this angle counter-clockwise about +z). `refine` non-zero interpolates between bins (what
/// the loop detector reports).
#[no_mangle]
pub unsafe extern "C" fn solid_heading(
    a_query: *const f32,
    a_candidate: *const f32,
    len: usize,
    refine: bool,
    heading_deg: *mut f64,
) -> SolidStatus {
    guard("solid_heading", || {
        let (q, c) = pair(a_query, a_candidate, len, ["a_query", "a_candidate"])?;
        let h = if refine {
            heading_refined(q, c)?
        } else {
            heading(q, c)?
        };
        put(heading_deg, "heading_deg", h.degrees)
    })
}

/// The query's and the candidate's vectors of `len` values, named as the arguments.
///
/// # Safety
/// As [`slice`].
unsafe fn pair<'a>(
    query: *const f32,
    candidate: *const f32,
    len: usize,
    names: [&str; 2],
) -> Result<(&'a [f32], &'a [f32]), Failure> {
    Ok((
        slice(query, len, names[0])?,
        slice(candidate, len, names[1])?,
    ))
}
