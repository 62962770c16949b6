//! The poses of a database file: in version 3 (and in version 4 when a rotation is not one to
//! [`EXACT`]) as an id and the 3×4 matrix, 100 bytes a place; in version 4 as a quaternion
//! scaled to a largest component of 1 and the translation, 56 bytes, with the ids only when
//! some place has no pose.

use alloc::format;
use alloc::vec::Vec;

use super::{bad, read_section, Section, Source};
use crate::db::database::PoseStore;
use crate::db::format::try_vec;
use crate::db::{Database, DbError};

/// Bytes of a pose with its id (`poses`, version 3).
pub(super) const POSE: usize = 100;
/// Bytes of a pose as a unit quaternion and a translation (`pose_q`, version 4).
pub(super) const POSE_Q: usize = 56;
/// Bytes of a place id (`pose_ids`).
pub(super) const ID: usize = 4;

/// Largest difference between a rotation's entries and those its stored quaternion gives back
/// (about 2e-14 for a rotation matrix, from the rounding of [`snap`]); a pose further from a
/// rotation than this is stored as its matrix.
pub(super) const EXACT: f64 = 1e-12;

/// Adding and subtracting it rounds a value of magnitude at most 1 to a multiple of 2^-46
/// (1.5 · 2^6: the sum lies in [64, 128), whose `f64` spacing is 2^-46).
const SNAP: f64 = 96.0;

/// The poses of a database, `(id, [R|t] row-major)` by increasing id.
pub(super) type Poses = Vec<(u32, [f64; 12])>;

/// `v` rounded to a multiple of 2^-46 (`|v| ≤ 1`); zero is `+0.0`.
fn snap(v: f64) -> f64 {
    (v + SNAP) - SNAP + 0.0
}

/// The rotation of quaternion `q` = (w, x, y, z) of any non-zero length, row-major.
fn rotation(q: &[f64; 4]) -> [f64; 9] {
    let [w, x, y, z] = *q;
    let s = 2.0 / (w * w + x * x + y * y + z * z);
    [
        1.0 - s * (y * y + z * z),
        s * (x * y - w * z),
        s * (x * z + w * y),
        s * (x * y + w * z),
        1.0 - s * (x * x + z * z),
        s * (y * z - w * x),
        s * (x * z - w * y),
        s * (y * z + w * x),
        1.0 - s * (x * x + y * y),
    ]
}

/// The unit quaternion of the rotation in pose `p` (either sign), from its largest diagonal term
/// (Shepperd's choice, stable for every angle).
fn unit_quaternion(p: &[f64; 12]) -> [f64; 4] {
    let (m00, m01, m02) = (p[0], p[1], p[2]);
    let (m10, m11, m12) = (p[4], p[5], p[6]);
    let (m20, m21, m22) = (p[8], p[9], p[10]);
    let trace = m00 + m11 + m22;
    let sqrt = crate::math::sqrt;
    if trace > 0.0 {
        let s = 2.0 * sqrt(trace + 1.0);
        [s / 4.0, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s]
    } else if m00 >= m11 && m00 >= m22 {
        let s = 2.0 * sqrt((1.0 + m00 - m11 - m22).max(0.0));
        [(m21 - m12) / s, s / 4.0, (m01 + m10) / s, (m02 + m20) / s]
    } else if m11 >= m22 {
        let s = 2.0 * sqrt((1.0 + m11 - m00 - m22).max(0.0));
        [(m02 - m20) / s, (m01 + m10) / s, s / 4.0, (m12 + m21) / s]
    } else {
        let s = 2.0 * sqrt((1.0 + m22 - m00 - m11).max(0.0));
        [(m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, s / 4.0]
    }
}

/// The stored form of the rotation in pose `p`: its quaternion divided by its largest component
/// (which becomes 1), the others rounded to multiples of 2^-46, the sign making the first
/// component of magnitude 1 positive. So a pose read back and saved again gives the same bytes:
/// the quaternion of the rotation read back is within about 1e-16 of the stored one, which the
/// division and the rounding bring back to it.
fn stored_quaternion(p: &[f64; 12]) -> [f64; 4] {
    let q = unit_quaternion(p);
    let k = (1..4).fold(0, |k, i| if q[i].abs() > q[k].abs() { i } else { k });
    let mut s = [0.0; 4];
    for (i, v) in s.iter_mut().enumerate() {
        *v = if i == k { 1.0 } else { snap(q[i] / q[k]) };
    }
    if s.iter().find(|v| v.abs() == 1.0).is_some_and(|v| *v < 0.0) {
        s = s.map(|v| -v + 0.0);
    }
    s
}

/// Pose `p` as its stored quaternion and translation, when the rotation they give back is within
/// [`EXACT`] of `p`'s.
fn lean(p: &[f64; 12]) -> Option<[f64; 7]> {
    let v = lean_record(p);
    let r = rotation(&[v[0], v[1], v[2], v[3]]);
    let close = (0..9).all(|k| (r[k] - p[k / 3 * 4 + k % 3]).abs() <= EXACT);
    close.then_some(v)
}

/// The pose that a quaternion and a translation stand for.
pub(crate) fn matrix(v: &[f64; 7]) -> [f64; 12] {
    let r = rotation(&[v[0], v[1], v[2], v[3]]);
    [
        r[0], r[1], r[2], v[4], r[3], r[4], r[5], v[5], r[6], r[7], r[8], v[6],
    ]
}

/// Whether every pose of `db` is stored as a quaternion (version 4).
pub(super) fn all_lean(db: &Database) -> bool {
    (0..db.len() as u32).all(|id| db.pose(id).is_none_or(|p| lean(&p).is_some()))
}

/// The record of pose `p` as a quaternion and a translation (what [`all_lean`] checked).
pub(super) fn lean_record(p: &[f64; 12]) -> [f64; 7] {
    let q = stored_quaternion(p);
    [q[0], q[1], q[2], q[3], p[3], p[7], p[11]]
}

fn f64_at(b: &[u8], k: usize) -> f64 {
    f64::from_le_bytes(b[k..k + 8].try_into().unwrap_or([0; 8]))
}

/// Refuses a place id that does not follow the previous one or is not a place.
fn check_id(id: u32, prev: Option<u32>, n: usize) -> Result<(), DbError> {
    if id as usize >= n || prev.is_some_and(|prev| prev >= id) {
        return Err(bad(format!(
            "corrupted poses section: place id {id} out of order or range"
        )));
    }
    Ok(())
}

fn check_finite(id: u32, v: &[f64]) -> Result<(), DbError> {
    if v.iter().any(|v| !v.is_finite()) {
        return Err(bad(format!("entry {id}: non-finite pose")));
    }
    Ok(())
}

/// A pose's rotation checked as an add checks it ([`crate::db::check_pose`]).
pub(in crate::db) fn check_rotation(id: u32, p: &[f64; 12]) -> Result<(), DbError> {
    crate::db::check_pose(p).map_err(|e| bad(format!("entry {id}: {e}")))
}

/// The poses of a `poses` section (an id and a matrix each).
pub(super) fn with_ids(
    src: &(impl Source + ?Sized),
    s: Section,
    n: usize,
) -> Result<Poses, DbError> {
    let mut poses = try_vec::<(u32, [f64; 12])>(s.items as usize)?;
    read_section(src, s, POSE, |b| {
        for rec in b.chunks_exact(POSE) {
            let id = u32::from_le_bytes([rec[0], rec[1], rec[2], rec[3]]);
            let mut p = [0.0; 12];
            for (k, v) in p.iter_mut().enumerate() {
                *v = f64_at(rec, 4 + 8 * k);
            }
            check_id(id, poses.last().map(|(prev, _)| *prev), n)?;
            check_finite(id, &p)?;
            check_rotation(id, &p)?;
            poses.push((id, p));
        }
        Ok(())
    })?;
    Ok(poses)
}

/// The poses of a `pose_q` section, of the places that `ids` lists (every place without it), kept
/// as their records ([`matrix`] gives each pose).
pub(super) fn quaternions(
    src: &(impl Source + ?Sized),
    s: Section,
    ids: Option<Section>,
    n: usize,
) -> Result<PoseStore, DbError> {
    let mut which = try_vec::<u32>(s.items as usize)?;
    match ids {
        Some(ids) => read_section(src, ids, ID, |b| {
            for rec in b.chunks_exact(ID) {
                let id = u32::from_le_bytes([rec[0], rec[1], rec[2], rec[3]]);
                check_id(id, which.last().copied(), n)?;
                which.push(id);
            }
            Ok(())
        })?,
        None => which.extend(0..s.items as u32),
    }
    let mut poses = try_vec::<[f64; 7]>(s.items as usize)?;
    let mut at = which.iter();
    read_section(src, s, POSE_Q, |b| {
        for rec in b.chunks_exact(POSE_Q) {
            let id = *at.next().unwrap_or(&0);
            let mut v = [0.0; 7];
            for (k, x) in v.iter_mut().enumerate() {
                *x = f64_at(rec, 8 * k);
            }
            check_finite(id, &v)?;
            let largest = v[..4].iter().fold(0.0f64, |m, x| m.max(x.abs()));
            if largest != 1.0 {
                return Err(bad(format!(
                    "entry {id}: its pose's quaternion is not scaled to a largest component of 1"
                )));
            }
            poses.push(v);
        }
        Ok(())
    })?;
    Ok(PoseStore::from_lean(which, poses))
}

/// Why the pose sections of a version 4 file do not fit together, if they do not.
pub(super) fn check_pose_sections(
    poses: Option<Section>,
    ids: Option<Section>,
    q: Option<Section>,
    n: u64,
) -> Result<(), DbError> {
    let wrong = |what: &str| Err(bad(format!("corrupted section table: {what}")));
    match (poses, ids, q) {
        (Some(_), None, None) | (None, None, None) => Ok(()),
        (None, None, Some(q)) if q.items == n => Ok(()),
        (None, Some(i), Some(q)) if i.items == q.items && q.items < n => Ok(()),
        (Some(_), _, Some(_)) => wrong("poses stored twice"),
        (_, Some(_), None) => wrong("pose ids without their poses"),
        _ => wrong("the pose_ids section does not list the poses"),
    }
}
