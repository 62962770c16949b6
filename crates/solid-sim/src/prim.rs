//! Geometric primitives and exact ray intersections.

/// What a primitive represents in the world (used for reflectivity and for map plots).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kind {
    /// A building block.
    Building,
    /// A street-light or sign pole.
    Pole,
    /// A tree trunk.
    Trunk,
    /// A tree crown.
    Crown,
    /// A parked car (body or cabin).
    Car,
    /// A solid wall.
    Wall,
    /// A fence post or rail.
    Fence,
    /// Indoor furniture: benches, cabinets, shelves, tables.
    Furniture,
    /// An indoor ceiling or a ceiling beam.
    Ceiling,
}

impl Kind {
    /// A short lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Building => "building",
            Kind::Pole => "pole",
            Kind::Trunk => "trunk",
            Kind::Crown => "crown",
            Kind::Car => "car",
            Kind::Wall => "wall",
            Kind::Fence => "fence",
            Kind::Furniture => "furniture",
            Kind::Ceiling => "ceiling",
        }
    }
}

/// The shape of a primitive. All shapes stand upright in the world frame (z up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A box rotated about z: centre (x, y), half extents along its own axes, yaw (cos, sin) of its
    /// first axis, and vertical extent `[z0, z1]`.
    Box {
        /// Centre in x, y.
        center: [f64; 2],
        /// Half extents along the box's own first and second axes.
        half: [f64; 2],
        /// (cos yaw, sin yaw) of the box's first axis.
        rot: [f64; 2],
        /// Vertical extent.
        z: [f64; 2],
    },
    /// A vertical cylinder with flat caps.
    Cylinder {
        /// Axis position in x, y.
        center: [f64; 2],
        /// Radius.
        radius: f64,
        /// Vertical extent.
        z: [f64; 2],
    },
    /// An axis-aligned ellipsoid.
    Ellipsoid {
        /// Centre.
        center: [f64; 3],
        /// Semi-axes along x, y, z.
        radii: [f64; 3],
    },
}

/// A ray hit: parameter `t` (distance, for a unit direction) and the outward unit normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray.
    pub t: f64,
    /// Unit surface normal at the hit, pointing out of the surface.
    pub normal: [f64; 3],
}

/// A primitive in the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Primitive {
    /// Geometry.
    pub shape: Shape,
    /// Semantic class.
    pub kind: Kind,
    /// Lambertian reflectivity in [0, 1], used for the intensity channel.
    pub reflectivity: f32,
}

fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let n = libm::sqrt(dot3(v, v));
    [v[0] / n, v[1] / n, v[2] / n]
}

/// Slab interval of one axis: returns (t_near, t_far) or None when the ray is parallel and outside.
pub(crate) fn slab(o: f64, d: f64, lo: f64, hi: f64) -> Option<(f64, f64)> {
    if d == 0.0 {
        if o < lo || o > hi {
            None
        } else {
            Some((f64::NEG_INFINITY, f64::INFINITY))
        }
    } else {
        let t1 = (lo - o) / d;
        let t2 = (hi - o) / d;
        Some(if t1 < t2 { (t1, t2) } else { (t2, t1) })
    }
}

/// Smallest root of `a t² + 2 b t + c = 0` inside (t_min, t_max), trying the near root first.
fn quadratic_roots(a: f64, b: f64, c: f64) -> Option<(f64, f64)> {
    if a <= 0.0 {
        return None;
    }
    let disc = b * b - a * c;
    if disc < 0.0 {
        return None;
    }
    let sq = libm::sqrt(disc);
    // Numerically stable pair of roots.
    let q = if b > 0.0 { -(b + sq) } else { -b + sq };
    let (r1, r2) = if q == 0.0 {
        (-b / a, -b / a)
    } else {
        (q / a, c / q)
    };
    Some(if r1 < r2 { (r1, r2) } else { (r2, r1) })
}

impl Shape {
    /// Axis-aligned footprint `[xmin, ymin, xmax, ymax]`.
    pub fn footprint(&self) -> [f64; 4] {
        match *self {
            Shape::Box {
                center, half, rot, ..
            } => {
                let ex = libm::fabs(rot[0]) * half[0] + libm::fabs(rot[1]) * half[1];
                let ey = libm::fabs(rot[1]) * half[0] + libm::fabs(rot[0]) * half[1];
                [
                    center[0] - ex,
                    center[1] - ey,
                    center[0] + ex,
                    center[1] + ey,
                ]
            }
            Shape::Cylinder { center, radius, .. } => [
                center[0] - radius,
                center[1] - radius,
                center[0] + radius,
                center[1] + radius,
            ],
            Shape::Ellipsoid { center, radii } => [
                center[0] - radii[0],
                center[1] - radii[1],
                center[0] + radii[0],
                center[1] + radii[1],
            ],
        }
    }

    /// Highest z of the shape.
    pub fn top(&self) -> f64 {
        match *self {
            Shape::Box { z, .. } | Shape::Cylinder { z, .. } => z[1],
            Shape::Ellipsoid { center, radii } => center[2] + radii[2],
        }
    }

    /// The nearest intersection of the ray `o + t·d` with `t_min < t < t_max`, if any.
    /// `d` need not be unit length (then `t` is in units of `|d|`). If the origin is inside the
    /// shape, the exit point is returned (with the outward normal).
    pub fn intersect(&self, o: [f64; 3], d: [f64; 3], t_min: f64, t_max: f64) -> Option<Hit> {
        match *self {
            Shape::Box {
                center,
                half,
                rot,
                z,
            } => {
                let (c, s) = (rot[0], rot[1]);
                let px = o[0] - center[0];
                let py = o[1] - center[1];
                let lo = [c * px + s * py, -s * px + c * py, o[2]];
                let ld = [c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]];
                let bounds = [(-half[0], half[0]), (-half[1], half[1]), (z[0], z[1])];
                let mut t_near = f64::NEG_INFINITY;
                let mut t_far = f64::INFINITY;
                let mut near_axis = 0;
                let mut far_axis = 0;
                for axis in 0..3 {
                    let (a, b) = slab(lo[axis], ld[axis], bounds[axis].0, bounds[axis].1)?;
                    if a > t_near {
                        t_near = a;
                        near_axis = axis;
                    }
                    if b < t_far {
                        t_far = b;
                        far_axis = axis;
                    }
                }
                if t_near > t_far {
                    return None;
                }
                let (t, axis, sign) = if t_near > t_min {
                    (
                        t_near,
                        near_axis,
                        if ld[near_axis] > 0.0 { -1.0 } else { 1.0 },
                    )
                } else if t_far > t_min {
                    (t_far, far_axis, if ld[far_axis] > 0.0 { 1.0 } else { -1.0 })
                } else {
                    return None;
                };
                if t >= t_max {
                    return None;
                }
                let normal = match axis {
                    0 => [c * sign, s * sign, 0.0],
                    1 => [-s * sign, c * sign, 0.0],
                    _ => [0.0, 0.0, sign],
                };
                Some(Hit { t, normal })
            }
            Shape::Cylinder { center, radius, z } => {
                let px = o[0] - center[0];
                let py = o[1] - center[1];
                let mut best: Option<Hit> = None;
                let consider = |t: f64, normal: [f64; 3], best: &mut Option<Hit>| {
                    if t > t_min && t < t_max && best.is_none_or(|h| t < h.t) {
                        *best = Some(Hit { t, normal });
                    }
                };
                let a = d[0] * d[0] + d[1] * d[1];
                let b = px * d[0] + py * d[1];
                let cc = px * px + py * py - radius * radius;
                if let Some((r1, r2)) = quadratic_roots(a, b, cc) {
                    for t in [r1, r2] {
                        let zz = o[2] + t * d[2];
                        if zz >= z[0] && zz <= z[1] {
                            let nx = (px + t * d[0]) / radius;
                            let ny = (py + t * d[1]) / radius;
                            consider(t, [nx, ny, 0.0], &mut best);
                        }
                    }
                }
                if d[2] != 0.0 {
                    for (zc, nz) in [(z[0], -1.0), (z[1], 1.0)] {
                        let t = (zc - o[2]) / d[2];
                        let x = px + t * d[0];
                        let y = py + t * d[1];
                        if x * x + y * y <= radius * radius {
                            consider(t, [0.0, 0.0, nz], &mut best);
                        }
                    }
                }
                best
            }
            Shape::Ellipsoid { center, radii } => {
                let op = [
                    (o[0] - center[0]) / radii[0],
                    (o[1] - center[1]) / radii[1],
                    (o[2] - center[2]) / radii[2],
                ];
                let dp = [d[0] / radii[0], d[1] / radii[1], d[2] / radii[2]];
                let (r1, r2) = quadratic_roots(dot3(dp, dp), dot3(op, dp), dot3(op, op) - 1.0)?;
                let t = if r1 > t_min {
                    r1
                } else if r2 > t_min {
                    r2
                } else {
                    return None;
                };
                if t >= t_max {
                    return None;
                }
                let p = [op[0] + t * dp[0], op[1] + t * dp[1], op[2] + t * dp[2]];
                let normal = normalize([p[0] / radii[0], p[1] / radii[1], p[2] / radii[2]]);
                Some(Hit { t, normal })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Where a ray from `o` along `d` first meets `shape` within 100 m (it must).
    fn hit(shape: &Shape, o: [f64; 3], d: [f64; 3]) -> Hit {
        shape.intersect(o, d, 0.0, 100.0).unwrap()
    }

    /// Whether that ray misses `shape` within 100 m.
    fn misses(shape: &Shape, o: [f64; 3], d: [f64; 3]) -> bool {
        shape.intersect(o, d, 0.0, 100.0).is_none()
    }

    fn unit(v: [f64; 3]) -> [f64; 3] {
        normalize(v)
    }

    #[test]
    fn axis_aligned_box_faces() {
        let b = Shape::Box {
            center: [10.0, 0.0],
            half: [2.0, 3.0],
            rot: [1.0, 0.0],
            z: [-1.0, 4.0],
        };
        let h = hit(&b, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
        assert_eq!(h.t, 8.0);
        assert_eq!(h.normal, [-1.0, 0.0, 0.0]);
        // Top face from above.
        let h = hit(&b, [10.5, 1.0, 10.0], [0.0, 0.0, -1.0]);
        assert_eq!(h.t, 6.0);
        assert_eq!(h.normal, [0.0, 0.0, 1.0]);
        // Miss above, miss because of t_max, miss behind.
        assert!(misses(&b, [0.0, 0.0, 5.0], [1.0, 0.0, 0.0]));
        assert!(b
            .intersect([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], 0.0, 7.9)
            .is_none());
        assert!(misses(&b, [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0]));
        // From inside: exit face.
        let h = hit(&b, [10.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert_eq!(h.t, 3.0);
        assert_eq!(h.normal, [0.0, 1.0, 0.0]);
    }

    #[test]
    fn rotated_box_diagonal() {
        // A 45°-rotated unit square: its corner points at the origin along -x.
        let r = core::f64::consts::FRAC_1_SQRT_2;
        let b = Shape::Box {
            center: [10.0, 0.0],
            half: [1.0, 1.0],
            rot: [r, r],
            z: [-1.0, 1.0],
        };
        let h = hit(&b, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
        assert!((h.t - (10.0 - core::f64::consts::SQRT_2)).abs() < 1e-12);
        // Ray at y = 0.5 hits the face whose outward normal is (-r, -r) or (-r, r).
        let h = hit(&b, [0.0, 0.5, 0.0], [1.0, 0.0, 0.0]);
        assert!((h.t - (10.0 - core::f64::consts::SQRT_2 + 0.5)).abs() < 1e-12);
        assert!((h.normal[0] + r).abs() < 1e-12 && (h.normal[1] - r).abs() < 1e-12);
        let fp = b.footprint();
        let s2 = core::f64::consts::SQRT_2;
        assert!((fp[0] - (10.0 - s2)).abs() < 1e-12 && (fp[3] - s2).abs() < 1e-12);
    }

    #[test]
    fn cylinder_side_and_caps() {
        let c = Shape::Cylinder {
            center: [5.0, 0.0],
            radius: 0.5,
            z: [0.0, 3.0],
        };
        let h = hit(&c, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
        assert!((h.t - 4.5).abs() < 1e-12);
        assert!((h.normal[0] + 1.0).abs() < 1e-12);
        // Offset ray: chord geometry t = 5 - sqrt(r² - y²).
        let h = hit(&c, [0.0, 0.3, 1.0], [1.0, 0.0, 0.0]);
        assert!((h.t - (5.0 - libm::sqrt(0.25 - 0.09))).abs() < 1e-12);
        // Above the top: miss; straight down onto the cap: hit the cap.
        assert!(misses(&c, [0.0, 0.0, 3.5], [1.0, 0.0, 0.0]));
        let h = hit(&c, [5.1, 0.1, 10.0], [0.0, 0.0, -1.0]);
        assert!((h.t - 7.0).abs() < 1e-12);
        assert_eq!(h.normal, [0.0, 0.0, 1.0]);
        // A slanted ray through the top cap rim: enters through the cap.
        let d = unit([1.0, 0.0, -1.0]);
        let h = hit(&c, [0.0, 0.0, 8.0], d);
        // Reaches z = 3 at x = 5 (inside the disc): t = 5·√2.
        assert!((h.t - 5.0 * core::f64::consts::SQRT_2).abs() < 1e-12);
        assert_eq!(h.normal, [0.0, 0.0, 1.0]);
    }

    #[test]
    fn ellipsoid_exact() {
        let e = Shape::Ellipsoid {
            center: [0.0, 10.0, 5.0],
            radii: [2.0, 3.0, 4.0],
        };
        let h = hit(&e, [0.0, 0.0, 5.0], [0.0, 1.0, 0.0]);
        assert!((h.t - 7.0).abs() < 1e-12);
        assert!((h.normal[1] + 1.0).abs() < 1e-12);
        let h = hit(&e, [0.0, 10.0, 20.0], [0.0, 0.0, -1.0]);
        assert!((h.t - 11.0).abs() < 1e-12);
        // General direction: the hit point satisfies the ellipsoid equation and is the near root.
        let d = unit([0.1, 1.0, 0.05]);
        let o = [0.0, 0.0, 4.0];
        let h = hit(&e, o, d);
        let p = [o[0] + h.t * d[0], o[1] + h.t * d[1], o[2] + h.t * d[2]];
        let f = (p[0] / 2.0).powi(2) + ((p[1] - 10.0) / 3.0).powi(2) + ((p[2] - 5.0) / 4.0).powi(2);
        assert!((f - 1.0).abs() < 1e-12);
        assert!(p[1] < 10.0);
        assert!(misses(&e, [5.0, 0.0, 5.0], [0.0, 1.0, 0.0]));
    }
}
