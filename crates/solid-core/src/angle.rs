//! The angle conventions of [spec §3](crate::spec#3-comparing-descriptors): headings in degrees
//! in `(−180, 180]`, and the yaw of a rotation as `atan2(r10, r00)`. Every heading the crate
//! computes or compares goes through these two functions.

/// `d` degrees wrapped into `(−180, 180]`.
pub fn wrap180(d: f64) -> f64 {
    let w = d - 360.0 * libm::floor((d + 180.0) / 360.0);
    if w <= -180.0 {
        w + 360.0
    } else {
        w
    }
}

/// The yaw in degrees, `(−180, 180]`, of a rotation whose first column is `(r00, r10, ·)`:
/// `atan2(r10, r00)`, the heading of [spec §3](crate::spec#3-comparing-descriptors).
pub fn yaw_degrees(r00: f64, r10: f64) -> f64 {
    wrap180(libm::atan2(r10, r00).to_degrees())
}

#[cfg(test)]
mod tests {
    use super::{wrap180, yaw_degrees};

    #[test]
    fn wrap_and_yaw_stay_in_the_half_open_range() {
        assert_eq!(wrap180(180.0), 180.0);
        assert_eq!(wrap180(-180.0), 180.0);
        assert_eq!(wrap180(190.0), -170.0);
        assert_eq!(wrap180(-190.0), 170.0);
        assert_eq!(wrap180(720.0), 0.0);
        // atan2(-0.0, -1) is -180°: the range's open end gives 180°.
        assert_eq!(yaw_degrees(-1.0, -0.0), 180.0);
        assert!((yaw_degrees(0.0, 1.0) - 90.0).abs() < 1e-12);
    }
}
