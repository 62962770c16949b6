//! The exclusion rule of the loop detector ([spec §5](crate::spec#5-evaluating-loop-closure-against-poses)):
//! which of its own session's earlier places a query may not see. One function, so that the
//! detector, the bindings and a baseline that ranks places its own way exclude the same ones.

/// How many of its own session's `places` earlier places (oldest first) a query may search: the
/// first `m` of them. The others are too recent: among its last `frames` places, or (when
/// `meters > 0`) within `meters` metres of path, or (when `seconds > 0`) within `seconds`
/// seconds. Places of other sessions (a prior map, another robot) are never excluded.
///
/// `travelled` is the path length in metres at each of the session's places (NaN: added without
/// a pose, which counts as far) and at the query; `timestamps` the time in seconds at each place
/// (non-decreasing) and at the query. Each is read only when its window is on (pass `(&[], NaN)`
/// otherwise).
///
/// ```
/// use solid_lidar::db::visible_own_places;
///
/// // 60 places, 50 excluded by frames: the query sees places 0..10.
/// assert_eq!(visible_own_places(60, 50, 0.0, 0.0, (&[], f64::NAN), (&[], f64::NAN)), 10);
/// // Within 5 m of path: the places at 0, 2 and 4 m are visible from 10 m, not the one at 6 m.
/// let path = [0.0, 2.0, 4.0, 6.0];
/// assert_eq!(visible_own_places(4, 0, 5.0, 0.0, (&path, 10.0), (&[], f64::NAN)), 3);
/// ```
pub fn visible_own_places(
    places: usize,
    frames: usize,
    meters: f64,
    seconds: f64,
    travelled: (&[f64], f64),
    timestamps: (&[f64], f64),
) -> usize {
    let mut visible = places.saturating_sub(frames);
    if meters > 0.0 {
        let (path, at) = travelled;
        let limit = at - meters;
        visible = visible.min(path.partition_point(|&t| t.is_nan() || t <= limit));
    }
    if seconds > 0.0 {
        let (times, at) = timestamps;
        let limit = at - seconds;
        visible = visible.min(times.partition_point(|&t| t <= limit));
    }
    visible
}
