//! Rigid poses as 3×4 row-major matrices (`T_world_sensor`, KITTI layout).

/// A rigid transform stored as a 3×4 row-major matrix `[R | t]`: a point `p` in the local frame maps
/// to `R·p + t` in the parent frame. For sensor poses the local frame is the sensor (x forward,
/// y left, z up) and the parent is the world, i.e. `T_world_sensor`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Row-major `[r00, r01, r02, t0, r10, r11, r12, t1, r20, r21, r22, t2]`.
    pub m: [f64; 12],
}

impl Default for Pose {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Pose {
    /// The identity transform.
    pub const IDENTITY: Pose = Pose {
        m: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
    };

    /// A translation by (x, y, z) followed by a rotation of `yaw_deg` degrees about +z
    /// (counter-clockwise seen from above).
    pub fn from_xyz_yaw(x: f64, y: f64, z: f64, yaw_deg: f64) -> Pose {
        let (s, c) = libm::sincos(yaw_deg.to_radians());
        Pose {
            m: [c, -s, 0.0, x, s, c, 0.0, y, 0.0, 0.0, 1.0, z],
        }
    }

    /// A pose from rotation columns (forward, left, up) and a translation.
    pub fn from_axes(x_axis: [f64; 3], y_axis: [f64; 3], z_axis: [f64; 3], t: [f64; 3]) -> Pose {
        Pose {
            m: [
                x_axis[0], y_axis[0], z_axis[0], t[0], x_axis[1], y_axis[1], z_axis[1], t[1],
                x_axis[2], y_axis[2], z_axis[2], t[2],
            ],
        }
    }

    /// The translation part.
    pub fn translation(&self) -> [f64; 3] {
        [self.m[3], self.m[7], self.m[11]]
    }

    /// `R·v` (a direction, no translation).
    pub fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        let m = &self.m;
        [
            m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
            m[4] * v[0] + m[5] * v[1] + m[6] * v[2],
            m[8] * v[0] + m[9] * v[1] + m[10] * v[2],
        ]
    }

    /// `R·p + t`.
    pub fn transform(&self, p: [f64; 3]) -> [f64; 3] {
        let r = self.rotate(p);
        [r[0] + self.m[3], r[1] + self.m[7], r[2] + self.m[11]]
    }

    /// The composition `self · other` (apply `other` first).
    pub fn compose(&self, other: &Pose) -> Pose {
        let a = &self.m;
        let b = &other.m;
        let mut m = [0.0; 12];
        for i in 0..3 {
            for j in 0..4 {
                let mut v = a[4 * i] * b[j] + a[4 * i + 1] * b[4 + j] + a[4 * i + 2] * b[8 + j];
                if j == 3 {
                    v += a[4 * i + 3];
                }
                m[4 * i + j] = v;
            }
        }
        Pose { m }
    }

    /// The inverse transform `[Rᵀ | −Rᵀt]`.
    pub fn inverse(&self) -> Pose {
        let m = &self.m;
        let rt = [m[0], m[4], m[8], m[1], m[5], m[9], m[2], m[6], m[10]];
        let t = [m[3], m[7], m[11]];
        let mut out = [0.0; 12];
        for i in 0..3 {
            out[4 * i] = rt[3 * i];
            out[4 * i + 1] = rt[3 * i + 1];
            out[4 * i + 2] = rt[3 * i + 2];
            out[4 * i + 3] = -(rt[3 * i] * t[0] + rt[3 * i + 1] * t[1] + rt[3 * i + 2] * t[2]);
        }
        Pose { m: out }
    }

    /// The yaw of the rotation in degrees, `atan2(r10, r00)`, in (−180°, 180°].
    pub fn yaw_deg(&self) -> f64 {
        let y = libm::atan2(self.m[4], self.m[0]).to_degrees();
        if y <= -180.0 {
            y + 360.0
        } else {
            y
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &[f64], b: &[f64]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
    }

    #[test]
    fn compose_inverse_is_identity() {
        let p = Pose::from_xyz_yaw(3.0, -2.0, 1.5, 37.0);
        let q = p.compose(&p.inverse());
        assert!(close(&q.m, &Pose::IDENTITY.m));
        let x = p.transform([1.0, 2.0, 3.0]);
        assert!(close(&p.inverse().transform(x), &[1.0, 2.0, 3.0]));
    }

    #[test]
    fn yaw_of_relative_pose() {
        let a = Pose::from_xyz_yaw(0.0, 0.0, 0.0, 170.0);
        let b = Pose::from_xyz_yaw(5.0, 1.0, 0.0, -150.0);
        let rel = a.inverse().compose(&b);
        assert!((rel.yaw_deg() - 40.0).abs() < 1e-9);
        assert!((Pose::from_xyz_yaw(0.0, 0.0, 0.0, 180.0).yaw_deg() - 180.0).abs() < 1e-9);
    }
}
