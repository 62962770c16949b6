//! The exclusion rule of the loop detector ([spec §5](crate::spec#5-evaluating-loop-closure-against-poses)):
//! which of its own session's earlier places a query may not see. One function, so that the
//! detector, the bindings and a baseline that ranks places its own way exclude the same ones.

/// How many of its own session's `places` earlier places (oldest first) a query may search: the
/// first `m` of them. The others are too recent: among its last `frames` places, or (when
/// `meters > 0`) within `meters` metres of path, or (when `seconds > 0`) within `seconds`
/// seconds. Places of other sessions (a prior map, another robot) are never excluded.
///
/// `travelled` is the path length in metres at each of the session's places (non-decreasing; NaN
/// for the places added before the session's first pose, which count as far) and at the query;
/// `timestamps` the time in seconds at each place (likewise) and at the query. A query without a
/// pose (time), given as NaN, is not excluded by metres (seconds): nothing says where (when) it
/// is. Each is read only when its window is on (pass `(&[], NaN)` otherwise).
///
/// ```
/// use solid_lidar::db::visible_own_places;
///
/// // 60 places, 50 excluded by frames: the query sees places 0..10.
/// assert_eq!(visible_own_places(60, 50, 0.0, 0.0, (&[], f64::NAN), (&[], f64::NAN)), 10);
/// // Within 5 m of path: the places at 0, 2 and 4 m are visible from 10 m, not the one at 6 m.
/// let path = [0.0, 2.0, 4.0, 6.0];
/// assert_eq!(visible_own_places(4, 0, 5.0, 0.0, (&path, 10.0), (&[], f64::NAN)), 3);
/// // A query without a pose: only the frames rule applies.
/// assert_eq!(visible_own_places(4, 0, 5.0, 0.0, (&path, f64::NAN), (&[], f64::NAN)), 4);
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
    for (window, (along, at)) in [(meters, travelled), (seconds, timestamps)] {
        if window > 0.0 && !at.is_nan() {
            let limit = at - window;
            visible = visible.min(along.partition_point(|&t| t.is_nan() || t <= limit));
        }
    }
    visible
}
