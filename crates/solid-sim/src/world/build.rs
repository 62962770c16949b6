//! Building the city's blocks and street sides: the buildings, trees, poles, fences and parked
//! cars of one block, in the block's local frame.

use super::SIDEWALK;
use crate::prim::{Kind, Primitive, Shape};
use crate::rng::Rng;

/// Accumulates primitives in world coordinates, with a local frame for blocks.
pub(super) struct Builder<'a> {
    pub(super) prims: &'a mut Vec<Primitive>,
    pub(super) slope: [f64; 2],
    /// Local frame origin and axis (cos, sin): local (u, v) → world.
    pub(super) origin: [f64; 2],
    pub(super) axis: [f64; 2],
}

impl Builder<'_> {
    /// A wall along the lot's front edge (`u` in `0..w`, centred on `v`, `half_thick` thick on
    /// each side, `height` tall), open between `u = gate - 2 gap` and `u = gate + gap`.
    pub(super) fn add_gated_wall(
        &mut self,
        w: f64,
        gate: f64,
        gap: f64,
        v: f64,
        half_thick: f64,
        height: f64,
    ) {
        let left = gate / 2.0 - gap;
        let half = [(gate - 2.0 * gap) / 2.0, half_thick];
        self.add_wall(left, v, half, height);
        let rest = w - gate - gap;
        let half = [rest / 2.0, half_thick];
        self.add_wall(w - rest / 2.0, v, half, height);
    }

    /// An upright wall piece (`add_box` of kind `Wall`, not turned, from below the ground).
    pub(super) fn add_wall(&mut self, u: f64, v: f64, half: [f64; 2], height: f64) {
        self.add_box(u, v, half, 0.0, 0.0, height, Kind::Wall, 0.35);
    }

    /// The world position of local (u, v) and the ground height there.
    fn placed(&self, u: f64, v: f64) -> ([f64; 2], f64) {
        let c = self.to_world(u, v);
        (c, self.ground(c[0], c[1]))
    }

    pub(super) fn ground(&self, x: f64, y: f64) -> f64 {
        self.slope[0] * x + self.slope[1] * y
    }
    pub(super) fn to_world(&self, u: f64, v: f64) -> [f64; 2] {
        let [c, s] = self.axis;
        [
            self.origin[0] + c * u - s * v,
            self.origin[1] + s * u + c * v,
        ]
    }
    /// A box with centre (u, v) in the local frame, local yaw `yaw` (radians), from ground − 1 m
    /// to ground + height (measured at its centre); `z_lo` lifts the bottom above the ground.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn add_box(
        &mut self,
        u: f64,
        v: f64,
        half: [f64; 2],
        yaw: f64,
        z_lo: f64,
        height: f64,
        kind: Kind,
        refl: f32,
    ) {
        let (c, g) = self.placed(u, v);
        let (s0, c0) = libm::sincos(yaw);
        let [ca, sa] = self.axis;
        let rot = [ca * c0 - sa * s0, sa * c0 + ca * s0];
        let bottom = if z_lo > 0.0 { g + z_lo } else { g - 1.0 };
        self.prims.push(Primitive {
            shape: Shape::Box {
                center: c,
                half,
                rot,
                z: [bottom, g + height],
            },
            kind,
            reflectivity: refl,
        });
    }
    pub(super) fn add_cylinder(
        &mut self,
        u: f64,
        v: f64,
        radius: f64,
        height: f64,
        kind: Kind,
        refl: f32,
    ) {
        let (c, g) = self.placed(u, v);
        self.prims.push(Primitive {
            shape: Shape::Cylinder {
                center: c,
                radius,
                z: [g - 1.0, g + height],
            },
            kind,
            reflectivity: refl,
        });
    }
    pub(super) fn add_tree(&mut self, u: f64, v: f64, rng: &mut Rng) {
        let trunk_h = rng.range(1.8, 3.5);
        let rxy = rng.range(1.5, 3.5);
        let rz = rng.range(1.5, 4.0);
        let (c, g) = self.placed(u, v);
        let zc = g + trunk_h + 0.8 * rz;
        self.add_cylinder(
            u,
            v,
            rng.range(0.12, 0.3),
            trunk_h + 0.5 * rz,
            Kind::Trunk,
            0.25,
        );
        self.prims.push(Primitive {
            shape: Shape::Ellipsoid {
                center: [c[0], c[1], zc],
                radii: [rxy, rxy, rz],
            },
            kind: Kind::Crown,
            reflectivity: 0.15,
        });
    }
    /// A parked car centred at (u, v), its length along local yaw `yaw`.
    pub(super) fn add_car(&mut self, u: f64, v: f64, yaw: f64, rng: &mut Rng) {
        let refl = rng.range(0.4, 0.9) as f32;
        if rng.chance(0.15) {
            // Van.
            let len = rng.range(4.8, 5.8);
            let h = rng.range(2.0, 2.6);
            self.add_box(u, v, [len / 2.0, 1.0], yaw, 0.3, h, Kind::Car, refl);
        } else {
            let len = rng.range(4.1, 4.9);
            let wid = rng.range(1.72, 1.9);
            self.add_box(u, v, [len / 2.0, wid / 2.0], yaw, 0.3, 1.0, Kind::Car, refl);
            let (s, c) = libm::sincos(yaw);
            let back = -rng.range(0.0, 0.4);
            self.add_box(
                u + c * back,
                v + s * back,
                [rng.range(1.0, 1.35), wid / 2.0 - 0.08],
                yaw,
                1.0,
                rng.range(1.4, 1.6),
                Kind::Car,
                refl,
            );
        }
    }
    /// A straight fence from (u0, v) to (u1, v) along local u: posts and a top rail.
    pub(super) fn add_fence(&mut self, u0: f64, u1: f64, v: f64, height: f64) {
        let n = ((u1 - u0) / 2.5).ceil().max(1.0) as usize;
        for i in 0..=n {
            let u = u0 + (u1 - u0) * i as f64 / n as f64;
            self.add_cylinder(u, v, 0.05, height, Kind::Fence, 0.55);
        }
        self.add_box(
            (u0 + u1) / 2.0,
            v,
            [(u1 - u0) / 2.0, 0.04],
            0.0,
            height - 0.12,
            height,
            Kind::Fence,
            0.55,
        );
    }
}

/// Fills a square block of side `w` (local coordinates [0, w]²) with one of several layouts.
pub(super) fn fill_block(b: &mut Builder<'_>, w: f64, rng: &mut Rng) {
    let kind = rng.uniform();
    if kind < 0.55 {
        // Buildings along the four sides.
        for side in 0..4 {
            let mut s = rng.range(0.0, 6.0);
            while s < w - 6.0 {
                let front = rng.range(8.0, 30.0).min(w - s);
                let depth = rng.range(8.0, 25.0).min(w / 2.0 - 1.0);
                let setback = rng.range(0.0, 4.0);
                let height = if rng.chance(0.1) {
                    rng.range(25.0, 45.0)
                } else {
                    rng.range(4.0, 22.0)
                };
                let jitter = if rng.chance(0.2) {
                    rng.range(-0.14, 0.14)
                } else {
                    0.0
                };
                let (u, v) = (s + front / 2.0, setback + depth / 2.0);
                // Side k: rotate the strip (u along the side, v inwards) by k·90° about the centre.
                let (uu, vv, yaw) = match side {
                    0 => (u, v, 0.0),
                    1 => (w - v, u, core::f64::consts::FRAC_PI_2),
                    2 => (w - u, w - v, core::f64::consts::PI),
                    _ => (v, w - u, -core::f64::consts::FRAC_PI_2),
                };
                let refl = rng.range(0.25, 0.6) as f32;
                b.add_box(
                    uu,
                    vv,
                    [front / 2.0, depth / 2.0],
                    yaw + jitter,
                    0.0,
                    height,
                    Kind::Building,
                    refl,
                );
                s += front
                    + if rng.chance(0.3) {
                        rng.range(10.0, 20.0)
                    } else {
                        rng.range(0.0, 6.0)
                    };
            }
        }
    } else if kind < 0.75 {
        // Park: scattered trees, a fence with an entrance on each side, maybe a pavilion.
        let n = 10 + rng.below(25) as usize;
        for _ in 0..n {
            let (u, v) = (rng.range(3.0, w - 3.0), rng.range(3.0, w - 3.0));
            b.add_tree(u, v, rng);
        }
        let gate = rng.range(0.3, 0.7) * w;
        let h = rng.range(1.0, 1.8);
        b.add_fence(0.0, gate - 2.5, 0.0, h);
        b.add_fence(gate + 2.5, w, 0.0, h);
        b.add_fence(0.0, w, w, h);
        // Side fences along v: use a rotated local frame.
        let saved = (b.origin, b.axis);
        let left = b.to_world(0.0, 0.0);
        b.origin = left;
        b.axis = [-saved.1[1], saved.1[0]];
        b.add_fence(0.0, w, 0.0, h);
        b.origin = b.to_world(0.0, -w);
        b.add_fence(0.0, w * 0.4, 0.0, h);
        b.add_fence(w * 0.4 + 4.0, w, 0.0, h);
        b.origin = saved.0;
        b.axis = saved.1;
        if rng.chance(0.5) {
            let (u, v) = (rng.range(15.0, w - 15.0), rng.range(15.0, w - 15.0));
            b.add_box(
                u,
                v,
                [4.0, 4.0],
                rng.range(0.0, 1.5),
                0.0,
                3.5,
                Kind::Building,
                0.4,
            );
        }
    } else if kind < 0.9 {
        // Parking lot: rows of cars, light poles, a low wall.
        let rows = 2 + rng.below(3) as usize;
        for r in 0..rows {
            let v = 8.0 + r as f64 * (w - 16.0) / (rows as f64 - 1.0).max(1.0);
            let mut u = 4.0;
            while u < w - 4.0 {
                if rng.chance(0.7) {
                    b.add_car(u, v, core::f64::consts::FRAC_PI_2, rng);
                }
                u += 2.6;
            }
            b.add_cylinder(w / 2.0, v + 3.5, 0.15, 9.0, Kind::Pole, 0.7);
        }
        let gate = rng.range(0.2, 0.8) * w;
        b.add_gated_wall(w, gate, 2.5, 0.3, 0.15, 0.9);
    } else {
        // Walled compound with one or two buildings.
        let h = rng.range(2.0, 3.0);
        let gate = rng.range(0.3, 0.7) * w;
        b.add_gated_wall(w, gate, 2.0, 0.2, 0.2, h);
        b.add_wall(w / 2.0, w - 0.2, [w / 2.0, 0.2], h);
        b.add_wall(0.2, w / 2.0, [0.2, w / 2.0 - 0.4], h);
        b.add_wall(w - 0.2, w / 2.0, [0.2, w / 2.0 - 0.4], h);
        let n = 1 + rng.below(2) as usize;
        for i in 0..n {
            let u = w * (i as f64 + 1.0) / (n as f64 + 1.0);
            let half = [rng.range(5.0, 12.0), rng.range(5.0, 12.0)];
            b.add_box(
                u,
                w / 2.0,
                half,
                0.0,
                0.0,
                rng.range(6.0, 18.0),
                Kind::Building,
                0.45,
            );
        }
    }
}

/// Fills one side of a street segment. Local frame: u along the street from 0 to `len`, v the
/// distance from the road centreline (positive = away from the road, on this side).
pub(super) fn fill_street_side(b: &mut Builder<'_>, len: f64, road_half: f64, rng: &mut Rng) {
    let pole_pitch = rng.range(25.0, 40.0);
    let mut u = rng.range(2.0, pole_pitch);
    while u < len - 2.0 {
        let tall = rng.chance(0.8);
        let (r, h) = if tall {
            (rng.range(0.1, 0.16), rng.range(6.0, 9.0))
        } else {
            (0.05, rng.range(2.2, 3.0))
        };
        b.add_cylinder(u, road_half + 1.0, r, h, Kind::Pole, 0.7);
        u += pole_pitch * rng.range(0.8, 1.2);
    }
    if rng.chance(0.55) {
        let pitch = rng.range(7.0, 13.0);
        let mut u = rng.range(1.0, pitch);
        while u < len - 1.0 {
            if rng.chance(0.85) {
                b.add_tree(u, road_half + 2.5 + rng.range(-0.3, 0.3), rng);
            }
            u += pitch * rng.range(0.9, 1.1);
        }
    }
    if rng.chance(0.5) {
        let fill = rng.range(0.4, 0.95);
        let mut u = rng.range(3.0, 10.0);
        while u < len - 3.0 {
            if rng.chance(fill) {
                b.add_car(u, road_half - 1.4, 0.0, rng);
            }
            u += rng.range(5.3, 7.0);
        }
    }
    if rng.chance(0.15) {
        // A low wall or a fence at the back of the sidewalk.
        let (a, z) = (rng.range(0.0, len * 0.5), rng.range(len * 0.5, len));
        if rng.chance(0.5) {
            b.add_wall(
                (a + z) / 2.0,
                road_half + SIDEWALK - 0.3,
                [(z - a) / 2.0, 0.15],
                rng.range(0.8, 2.2),
            );
        } else {
            b.add_fence(a, z, road_half + SIDEWALK - 0.3, rng.range(1.0, 1.6));
        }
    }
}
