//! The `sessions` section: runs of consecutive places of one session, with how many have a pose
//! and their first and last time, checked against the places when a file is read.

use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;

use super::{bad, read_section, Section, Source, RUN};
use crate::db::format::try_vec;
use crate::db::{Database, DbError};

/// A run of consecutive places of one session.
#[derive(Debug, Clone, Copy)]
pub(super) struct Run {
    pub(super) session: u32,
    pub(super) places: u32,
    pub(super) with_pose: u32,
    pub(super) first: f64,
    pub(super) last: f64,
}

pub(super) fn runs_of(src: &(impl Source + ?Sized), sec: Section) -> Result<Vec<Run>, DbError> {
    let mut runs = try_vec::<Run>(sec.items as usize)?;
    read_section(src, sec, RUN, |b| {
        for r in b.chunks_exact(RUN) {
            let u = |k: usize| u32::from_le_bytes([r[k], r[k + 1], r[k + 2], r[k + 3]]);
            let f = |k: usize| f64::from_le_bytes(r[k..k + 8].try_into().unwrap_or([0; 8]));
            if u(12) != 0 {
                return Err(bad(String::from(
                    "corrupted sessions section: reserved field not 0",
                )));
            }
            runs.push(Run {
                session: u(0),
                places: u(4),
                with_pose: u(8),
                first: f(16),
                last: f(24),
            });
        }
        Ok(())
    })?;
    Ok(runs)
}

/// The sessions of the places from the runs, checked against the places, their times and poses.
pub(super) fn sessions_of(
    runs: &[Run],
    n: usize,
    timestamps: &[f64],
    posed: impl Iterator<Item = u32>,
) -> Result<Vec<u32>, DbError> {
    let wrong = |what: &str| bad(format!("corrupted sessions section: {what}"));
    let mut sessions = try_vec::<u32>(n)?;
    let mut posed = posed.map(|id| id as usize).peekable();
    for run in runs {
        let start = sessions.len();
        let end = start
            .checked_add(run.places as usize)
            .filter(|&e| e <= n && run.places > 0)
            .ok_or_else(|| wrong("the runs do not add up to the places"))?;
        if crate::db::check_session(run.session).is_err() {
            return Err(wrong(
                "session 2^32 - 1 (never a session: the one after it must be numbered)",
            ));
        }
        sessions.extend(core::iter::repeat_n(run.session, run.places as usize));
        let mut with = 0u32;
        while posed.next_if(|&id| id < end).is_some() {
            with += 1;
        }
        let (first, last) = span(&timestamps[start..end]);
        if with != run.with_pose
            || first.to_bits() != run.first.to_bits()
            || last.to_bits() != run.last.to_bits()
        {
            return Err(wrong("a run's summary does not match its places"));
        }
    }
    if sessions.len() != n {
        return Err(wrong("the runs do not add up to the places"));
    }
    Ok(sessions)
}

/// The first and last of the timestamps that are not NaN (NaN, NaN: none).
pub(super) fn span(t: &[f64]) -> (f64, f64) {
    t.iter()
        .filter(|t| !t.is_nan())
        .fold((f64::NAN, f64::NAN), |(lo, hi), &t| {
            (
                if lo.is_nan() { t } else { lo.min(t) },
                if hi.is_nan() { t } else { hi.max(t) },
            )
        })
}

/// The runs of consecutive places of one session.
pub(super) fn runs(db: &Database) -> Vec<Run> {
    let s = db.sessions();
    let mut out: Vec<Run> = Vec::new();
    let mut start = 0;
    let poses: Vec<u32> = (0..db.len() as u32)
        .filter(|&i| db.pose(i).is_some())
        .collect();
    let mut posed = poses.iter().peekable();
    while start < s.len() {
        let mut end = start + 1;
        while end < s.len() && s[end] == s[start] && end - start < u32::MAX as usize {
            end += 1;
        }
        let mut with = 0;
        while posed.next_if(|&&id| (id as usize) < end).is_some() {
            with += 1;
        }
        let (first, last) = span(&db.timestamps()[start..end]);
        out.push(Run {
            session: s[start],
            places: (end - start) as u32,
            with_pose: with,
            first,
            last,
        });
        start = end;
    }
    out
}
