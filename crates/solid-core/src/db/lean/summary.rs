//! The [`Summary`] of a database file in format version 3 or 4 (what `solid map info` prints): its
//! header, section table, sessions and metadata, no descriptor or cloud read.

use alloc::string::String;
use alloc::vec::Vec;

use super::*;

/// What a database file holds, from its header and small sections alone (see
/// [`Database::summary`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Format version of the file.
    pub version: u32,
    /// The configuration every entry was described with.
    pub config: Config,
    /// Its fingerprint.
    pub fingerprint: u64,
    /// Number of places.
    pub places: usize,
    /// Places that have a stored cloud.
    pub places_with_cloud: usize,
    /// Bytes of the stored clouds.
    pub cloud_bytes: u64,
    /// Per session, by increasing session: places, places with a pose, first and last timestamp
    /// (NaN: none).
    pub sessions: Vec<SessionSummary>,
    /// [`Database::metadata`].
    pub metadata: String,
}

/// One session of a [`Summary`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SessionSummary {
    /// The session.
    pub session: u32,
    /// Its places.
    pub places: usize,
    /// Those with a pose.
    pub with_pose: usize,
    /// Its first timestamp (NaN: none).
    pub first_time: f64,
    /// Its last timestamp (NaN: none).
    pub last_time: f64,
}

#[cfg(feature = "std")]
fn summarise(
    version: u32,
    config: Config,
    places: usize,
    runs: &[Run],
    clouds: (usize, u64),
    metadata: String,
) -> Summary {
    let mut sessions: Vec<SessionSummary> = Vec::new();
    for r in runs {
        let at = sessions.partition_point(|s| s.session < r.session);
        if sessions.get(at).is_none_or(|s| s.session != r.session) {
            sessions.insert(
                at,
                SessionSummary {
                    session: r.session,
                    places: 0,
                    with_pose: 0,
                    first_time: f64::NAN,
                    last_time: f64::NAN,
                },
            );
        }
        let s = &mut sessions[at];
        s.places += r.places as usize;
        s.with_pose += r.with_pose as usize;
        (s.first_time, s.last_time) =
            super::runs::span(&[s.first_time, s.last_time, r.first, r.last]);
    }
    Summary {
        version,
        config,
        fingerprint: config.fingerprint(),
        places,
        places_with_cloud: clouds.0,
        cloud_bytes: clouds.1,
        sessions,
        metadata,
    }
}

#[cfg(feature = "std")]
/// The [`Summary`] of `db` (as its file in format version `version` would give it).
pub(in crate::db) fn summary_of(db: &Database, version: u32) -> Summary {
    summarise(
        version,
        *db.config(),
        db.len(),
        &runs(db),
        (db.clouds_stored(), db.cloud_bytes() as u64),
        String::from(db.metadata()),
    )
}

#[cfg(feature = "std")]
/// The [`Summary`] of a file in format version 3 or 4: its header, table, sessions and metadata only.
pub(in crate::db) fn summary(src: &(impl Source + ?Sized)) -> Result<Summary, DbError> {
    let l = layout(src)?;
    let runs = match l.get(SESSIONS) {
        Some(s) => runs_of(src, s)?,
        None => Vec::new(),
    };
    if runs.iter().map(|r| r.places as u64).sum::<u64>() != l.count as u64 {
        return Err(bad(String::from(
            "corrupted sessions section: the runs do not add up to the places",
        )));
    }
    let clouds = l.get(CLOUDS).map_or((0, 0), |c| (c.items as usize, c.len));
    let metadata = metadata_of(src, &l)?;
    Ok(summarise(
        l.version, l.config, l.count, &runs, clouds, metadata,
    ))
}
