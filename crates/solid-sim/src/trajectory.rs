//! Trajectories: routes along the world's roads, sampled at a fixed spacing, with exact poses.

use crate::error::{check, check_in, try_vec, SimError};
use crate::pose::Pose;
use crate::world::World;
use core::f64::consts::{FRAC_PI_2, PI};

/// How a route is turned into poses.
#[derive(Clone, Debug, PartialEq)]
pub struct RouteOptions {
    /// Distance between consecutive frames along the path, measured on the map (x, y), metres.
    pub spacing: f64,
    /// Lateral offset of the driven lane from the road centreline, metres (positive = right of
    /// the direction of travel, i.e. right-hand traffic).
    pub lane_offset: f64,
    /// Radius of the arcs that round the corners, metres.
    pub corner_radius: f64,
    /// Speed, metres per second (sets the time stamps).
    pub speed: f64,
    /// Height of the sensor above the ground, metres.
    pub mount_height: f64,
}

impl Default for RouteOptions {
    fn default() -> Self {
        RouteOptions {
            spacing: 1.0,
            lane_offset: 1.75,
            corner_radius: 8.0,
            speed: 10.0,
            mount_height: 1.73,
        }
    }
}

impl RouteOptions {
    fn validate(&self) -> Result<(), SimError> {
        check(
            "spacing",
            self.spacing,
            self.spacing >= 0.01 && self.spacing <= 1000.0,
            "[0.01, 1000] m",
        )?;
        check(
            "lane_offset",
            self.lane_offset,
            self.lane_offset.abs() <= 50.0,
            "|offset| <= 50 m",
        )?;
        check(
            "corner_radius",
            self.corner_radius,
            self.corner_radius >= 0.0 && self.corner_radius <= 100.0,
            "[0, 100] m",
        )?;
        check(
            "speed",
            self.speed,
            self.speed > 0.0 && self.speed <= 100.0,
            "(0, 100] m/s",
        )?;
        check(
            "mount_height",
            self.mount_height,
            self.mount_height >= 0.0 && self.mount_height <= 10.0,
            "[0, 10] m",
        )?;
        Ok(())
    }
}

/// The most frames a route may be sampled into (1000 km at the default 1 m spacing): a longer
/// route or a finer spacing is refused up front rather than exhausting memory.
pub const MAX_FRAMES: usize = 1_000_000;

/// Names accepted by [`Trajectory::by_name`].
pub const TRAJECTORY_KINDS: [&str; 4] = ["loop", "figure-eight", "reverse", "crossing"];

/// A sequence of sensor poses (`T_world_sensor`) with time stamps.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    /// One pose per frame.
    pub poses: Vec<Pose>,
    /// One time stamp per frame, seconds from the start.
    pub times: Vec<f64>,
}

#[derive(Clone, Copy, Debug)]
enum Piece {
    Line {
        a: [f64; 2],
        u: [f64; 2],
        len: f64,
    },
    Arc {
        c: [f64; 2],
        r: f64,
        a0: f64,
        sweep: f64,
    },
}

impl Piece {
    fn len(&self) -> f64 {
        match *self {
            Piece::Line { len, .. } => len,
            Piece::Arc { r, sweep, .. } => r * sweep.abs(),
        }
    }
    /// Position and heading (radians) at arc length `s` from the piece's start.
    fn at(&self, s: f64) -> ([f64; 2], f64) {
        match *self {
            Piece::Line { a, u, .. } => {
                ([a[0] + s * u[0], a[1] + s * u[1]], libm::atan2(u[1], u[0]))
            }
            Piece::Arc { c, r, a0, sweep } => {
                let sign = if sweep >= 0.0 { 1.0 } else { -1.0 };
                let ang = a0 + sign * s / r;
                let (sn, cs) = libm::sincos(ang);
                ([c[0] + r * cs, c[1] + r * sn], ang + sign * FRAC_PI_2)
            }
        }
    }
}

fn line(a: [f64; 2], b: [f64; 2]) -> Option<Piece> {
    let d = [b[0] - a[0], b[1] - a[1]];
    let len = libm::sqrt(d[0] * d[0] + d[1] * d[1]);
    (len > 1e-9).then(|| Piece::Line {
        a,
        u: [d[0] / len, d[1] / len],
        len,
    })
}

fn add(a: [f64; 2], b: [f64; 2], k: f64) -> [f64; 2] {
    [a[0] + k * b[0], a[1] + k * b[1]]
}

/// Builds the lane path (lines and arcs) of a centreline polyline.
fn build_path(wps: &[[f64; 2]], opts: &RouteOptions) -> Result<Vec<Piece>, SimError> {
    let mut pts: Vec<[f64; 2]> = Vec::with_capacity(wps.len());
    for &p in wps {
        check(
            "waypoint",
            p[0],
            p[0].is_finite() && p[1].is_finite(),
            "finite coordinates",
        )?;
        if pts
            .last()
            .is_none_or(|q| (q[0] - p[0]).abs() + (q[1] - p[1]).abs() > 1e-9)
        {
            pts.push(p);
        }
    }
    check(
        "waypoints",
        pts.len() as f64,
        pts.len() >= 2,
        "at least two distinct waypoints",
    )?;
    let segs: Vec<([f64; 2], f64)> = pts
        .windows(2)
        .map(|w| {
            let d = [w[1][0] - w[0][0], w[1][1] - w[0][1]];
            let len = libm::sqrt(d[0] * d[0] + d[1] * d[1]);
            ([d[0] / len, d[1] / len], len)
        })
        .collect();
    let o = opts.lane_offset;
    let right = |u: [f64; 2]| [u[1], -u[0]];
    let mut pieces = Vec::new();
    let mut start = add(pts[0], right(segs[0].0), o);
    for j in 1..segs.len() {
        let (u0, l0) = segs[j - 1];
        let (u1, l1) = segs[j];
        let v = pts[j];
        let cross = u0[0] * u1[1] - u0[1] * u1[0];
        let dot = u0[0] * u1[0] + u0[1] * u1[1];
        let theta = libm::atan2(cross, dot);
        if theta.abs() < 1e-9 {
            continue;
        }
        if theta.abs() > PI - 1e-6 {
            check(
                "lane_offset",
                o,
                o.abs() >= 0.1,
                "|offset| >= 0.1 m for a U-turn",
            )?;
            let e = add(v, right(u0), o);
            pieces.extend(line(start, e));
            let a0 = libm::atan2(e[1] - v[1], e[0] - v[0]);
            pieces.push(Piece::Arc {
                c: v,
                r: o.abs(),
                a0,
                sweep: if o > 0.0 { PI } else { -PI },
            });
            start = add(v, right(u1), o);
            continue;
        }
        // Corner of the two offset lines: v + o·r0 + s·u0 = v + o·r1 + t·u1.
        let (r0, r1) = (right(u0), right(u1));
        let w = [o * (r1[0] - r0[0]), o * (r1[1] - r0[1])];
        let s = (w[0] * u1[1] - w[1] * u1[0]) / cross;
        let corner = add(add(v, r0, o), u0, s);
        let tan_half = libm::tan(theta.abs() / 2.0);
        let d = (opts.corner_radius * tan_half).min(0.5 * l0.min(l1));
        let r_eff = d / tan_half;
        let a = add(corner, u0, -d);
        let b = add(corner, u1, d);
        pieces.extend(line(start, a));
        if r_eff > 1e-9 {
            let n = if theta > 0.0 {
                [-u0[1], u0[0]]
            } else {
                [u0[1], -u0[0]]
            };
            let c = add(a, n, r_eff);
            pieces.push(Piece::Arc {
                c,
                r: r_eff,
                a0: libm::atan2(a[1] - c[1], a[0] - c[0]),
                sweep: theta,
            });
        }
        start = b;
    }
    let (ul, _) = segs[segs.len() - 1];
    pieces.extend(line(start, add(pts[pts.len() - 1], right(ul), o)));
    Ok(pieces)
}

impl Trajectory {
    /// The pose of a sensor at (x, y) with heading `heading_rad` on the world's ground: its
    /// z axis is the ground normal, its x axis the heading projected onto the ground plane, and
    /// it sits `mount_height` above the ground along the normal.
    pub fn pose_on_ground(
        world: &World,
        x: f64,
        y: f64,
        heading_rad: f64,
        mount_height: f64,
    ) -> Pose {
        let n = world.ground_normal();
        let [sx, sy] = world.config().slope;
        let (s, c) = libm::sincos(heading_rad);
        let f = [c, s, sx * c + sy * s];
        let fl = libm::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
        let f = [f[0] / fl, f[1] / fl, f[2] / fl];
        let l = [
            n[1] * f[2] - n[2] * f[1],
            n[2] * f[0] - n[0] * f[2],
            n[0] * f[1] - n[1] * f[0],
        ];
        let g = world.ground_height(x, y);
        let t = [
            x + mount_height * n[0],
            y + mount_height * n[1],
            g + mount_height * n[2],
        ];
        Pose::from_axes(f, l, n, t)
    }

    /// Drives along the centreline polyline `waypoints` (metres) in the lane given by
    /// `opts.lane_offset`, rounding corners with arcs and making U-turns (180° reversals) as
    /// half circles, and samples a pose every `opts.spacing` metres, the first at the start.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for invalid options, fewer than two distinct waypoints,
    /// non-finite coordinates, a U-turn with a lane offset below 0.1 m, or more than
    /// [`MAX_FRAMES`] frames; [`SimError::OutOfMemory`] when the poses do not fit in memory.
    pub fn from_waypoints(
        world: &World,
        waypoints: &[[f64; 2]],
        opts: &RouteOptions,
    ) -> Result<Trajectory, SimError> {
        Self::sample(world, waypoints, opts, f64::INFINITY)
    }

    fn sample(
        world: &World,
        waypoints: &[[f64; 2]],
        opts: &RouteOptions,
        max_len: f64,
    ) -> Result<Trajectory, SimError> {
        opts.validate()?;
        let pieces = build_path(waypoints, opts)?;
        let total: f64 = pieces.iter().map(Piece::len).sum::<f64>().min(max_len);
        let frames = (total / opts.spacing + 1e-9).floor() + 1.0;
        check(
            "frames",
            frames,
            frames <= MAX_FRAMES as f64,
            "at most 1000000 frames (route length / spacing + 1): shorten the route or increase the spacing",
        )?;
        let n = frames as usize;
        let mut poses = try_vec(n, "trajectory poses")?;
        let mut times = try_vec(n, "trajectory times")?;
        let (mut piece, mut piece_start) = (0usize, 0.0f64);
        for k in 0..n {
            let s = k as f64 * opts.spacing;
            while piece + 1 < pieces.len() && s > piece_start + pieces[piece].len() {
                piece_start += pieces[piece].len();
                piece += 1;
            }
            let local = (s - piece_start).min(pieces[piece].len());
            let (p, heading) = pieces[piece].at(local);
            poses.push(Self::pose_on_ground(
                world,
                p[0],
                p[1],
                heading,
                opts.mount_height,
            ));
            times.push(s / opts.speed);
        }
        Ok(Trajectory { poses, times })
    }

    fn centre(world: &World) -> (f64, f64, f64) {
        let roads = world.roads();
        let c = roads[roads.len() / 2];
        (c, c, world.config().block_pitch)
    }

    /// [`Trajectory::centre`] of a world with the 2 blocks or more that a route around the
    /// central intersection needs, else an error saying `expected` of `blocks`.
    fn crossing(world: &World, expected: &'static str) -> Result<(f64, f64, f64), SimError> {
        let blocks = world.config().blocks;
        check("blocks", blocks as f64, blocks >= 2, expected)?;
        Ok(Self::centre(world))
    }

    /// Laps counter-clockwise around a rectangle of `bx × by` blocks near the world's centre,
    /// starting in the middle of its southern edge; `laps` may be fractional (1.0 returns to the
    /// start; 1.5 drives half of the loop a second time).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] when the rectangle does not fit the world's road grid, when
    /// `laps` is outside (0, 20], or for invalid options.
    pub fn closed_loop(
        world: &World,
        bx: usize,
        by: usize,
        laps: f64,
        opts: &RouteOptions,
    ) -> Result<Trajectory, SimError> {
        let blocks = world.config().blocks;
        check("bx", bx as f64, bx >= 1 && bx <= blocks, "1..=blocks")?;
        check("by", by as f64, by >= 1 && by <= blocks, "1..=blocks")?;
        check("laps", laps, laps > 0.0 && laps <= 20.0, "(0, 20]")?;
        let roads = world.roads();
        let (i0, j0) = ((blocks - bx) / 2, (blocks - by) / 2);
        let (x0, x1, y0, y1) = (roads[i0], roads[i0 + bx], roads[j0], roads[j0 + by]);
        let start = [(x0 + x1) / 2.0, y0];
        let n = libm::ceil(laps) as usize;
        let mut wps = vec![start];
        for _ in 0..n {
            wps.extend([[x1, y0], [x1, y1], [x0, y1], [x0, y0], start]);
        }
        let per_lap: f64 = build_path(&wps, opts)?.iter().map(Piece::len).sum::<f64>() / n as f64;
        Self::sample(world, &wps, opts, laps * per_lap + 1e-9)
    }

    /// A figure-eight through the central intersection: counter-clockwise around the block to its
    /// north-east, straight through the intersection (heading south, 90° from the first pass),
    /// clockwise around the block to its south-west, and on along the first street again.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for worlds with fewer than 2 blocks or invalid options.
    pub fn figure_eight(world: &World, opts: &RouteOptions) -> Result<Trajectory, SimError> {
        let (xc, yc, p) = Self::crossing(world, ">= 2 for a figure-eight")?;
        let wps = [
            [xc - p / 2.0, yc],
            [xc + p, yc],
            [xc + p, yc + p],
            [xc, yc + p],
            [xc, yc - p],
            [xc - p, yc - p],
            [xc - p, yc],
            [xc + p / 2.0, yc],
        ];
        Self::from_waypoints(world, &wps, opts)
    }

    /// Drives `blocks` block lengths east along the central street, makes a U-turn and drives
    /// back in the opposite lane: every place is revisited in the reverse direction.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] when `blocks` is 0 or exceeds the world's blocks, or for
    /// invalid options.
    pub fn reverse_revisit(
        world: &World,
        blocks: usize,
        opts: &RouteOptions,
    ) -> Result<Trajectory, SimError> {
        let nb = world.config().blocks;
        check(
            "blocks",
            blocks as f64,
            blocks >= 1 && blocks <= nb,
            "1..=world blocks",
        )?;
        let roads = world.roads();
        let i0 = (nb - blocks) / 2;
        let (xa, xb, y) = (
            roads[i0] + 0.5 * opts.corner_radius,
            roads[i0 + blocks],
            Self::centre(world).1,
        );
        Self::from_waypoints(world, &[[xa, y], [xb, y], [xa, y]], opts)
    }

    /// Crosses the central intersection twice at headings 90° apart: east along the central
    /// street, around the block to the south-east, then north through the same intersection.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for worlds with fewer than 2 blocks or invalid options.
    pub fn heading_revisit(world: &World, opts: &RouteOptions) -> Result<Trajectory, SimError> {
        let (xc, yc, p) = Self::crossing(world, ">= 2")?;
        let wps = [
            [xc - p, yc],
            [xc + p, yc],
            [xc + p, yc - p],
            [xc, yc - p],
            [xc, yc + p],
        ];
        Self::from_waypoints(world, &wps, opts)
    }

    /// One of [`TRAJECTORY_KINDS`] with default geometry: `loop` (1×1 block, `laps` laps),
    /// `figure-eight`, `reverse` (2 blocks out and back), `crossing` ([`Trajectory::heading_revisit`]).
    ///
    /// # Errors
    /// [`SimError::UnknownName`] for other names; otherwise as the builders.
    pub fn by_name(
        world: &World,
        kind: &str,
        laps: f64,
        opts: &RouteOptions,
    ) -> Result<Trajectory, SimError> {
        match kind {
            "loop" => Self::closed_loop(world, 1, 1, laps, opts),
            "figure-eight" => Self::figure_eight(world, opts),
            "reverse" => Self::reverse_revisit(world, 2.min(world.config().blocks), opts),
            "crossing" => Self::heading_revisit(world, opts),
            _ => Err(SimError::UnknownName {
                what: "trajectory kind",
                name: kind.to_string(),
            }),
        }
    }

    /// Poses at one place (x, y) on the ground with the given headings in degrees (for heading
    /// experiments); time stamps are the frame indices.
    pub fn spin(
        world: &World,
        x: f64,
        y: f64,
        headings_deg: &[f64],
        mount_height: f64,
    ) -> Trajectory {
        Trajectory {
            poses: headings_deg
                .iter()
                .map(|h| Self::pose_on_ground(world, x, y, h.to_radians(), mount_height))
                .collect(),
            times: (0..headings_deg.len()).map(|i| i as f64).collect(),
        }
    }
}

/// How [`Trajectory::turn_in_place`] turns.
#[derive(Clone, Debug, PartialEq)]
pub struct TurnOptions {
    /// Heading of the first frame, degrees.
    pub start_deg: f64,
    /// Total turn, degrees (negative: clockwise); nonzero, |sweep| <= 3600.
    pub sweep_deg: f64,
    /// Turn between consecutive frames, degrees ((0, 180]).
    pub step_deg: f64,
    /// Largest distance of any frame from the turning point, metres ([0, 5]): the position
    /// wanders smoothly inside this disc, as a hand-held or walking sensor does.
    pub wobble: f64,
    /// Seed of the wobble's path.
    pub seed: u64,
    /// Height of the sensor above the ground, metres ([0, 10]).
    pub mount_height: f64,
    /// Time between frames, seconds ((0, 3600]).
    pub period_s: f64,
}

impl Default for TurnOptions {
    fn default() -> Self {
        TurnOptions {
            start_deg: 0.0,
            sweep_deg: 330.0,
            step_deg: 2.0,
            wobble: 0.0,
            seed: 0,
            mount_height: 1.2,
            period_s: 0.1,
        }
    }
}

impl Trajectory {
    /// A sensor standing at (x, y) and turning through `opts.sweep_deg` in steps of
    /// `opts.step_deg` (the first frame at `opts.start_deg`), its position wandering within
    /// `opts.wobble` metres of (x, y); time stamps `opts.period_s` apart.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a non-finite point or an option outside its range.
    pub fn turn_in_place(
        world: &World,
        x: f64,
        y: f64,
        opts: &TurnOptions,
    ) -> Result<Trajectory, SimError> {
        check("x", x, true, "finite")?;
        check("y", y, true, "finite")?;
        check("start_deg", opts.start_deg, true, "finite")?;
        check(
            "sweep_deg",
            opts.sweep_deg,
            opts.sweep_deg != 0.0 && opts.sweep_deg.abs() <= 3600.0,
            "nonzero, |sweep| <= 3600",
        )?;
        check(
            "step_deg",
            opts.step_deg,
            opts.step_deg > 0.0 && opts.step_deg <= 180.0,
            "(0, 180]",
        )?;
        check_in("wobble", opts.wobble, 0.0, 5.0, "[0, 5] m")?;
        check_in("mount_height", opts.mount_height, 0.0, 10.0, "[0, 10] m")?;
        check(
            "period_s",
            opts.period_s,
            opts.period_s > 0.0 && opts.period_s <= 3600.0,
            "(0, 3600] s",
        )?;
        let frames = (opts.sweep_deg.abs() / opts.step_deg + 1e-9).floor() + 1.0;
        check(
            "frames",
            frames,
            frames <= MAX_FRAMES as f64,
            "at most 1000000 frames (|sweep| / step + 1): increase the step",
        )?;
        let n = frames as usize;
        let sign = opts.sweep_deg.signum();
        let mut rng = crate::rng::Rng::new(crate::rng::mix_seed(&[opts.seed, 40]));
        let (f1, f2) = (rng.range(0.6, 1.6), rng.range(0.6, 1.6));
        let (p1, p2) = (
            rng.range(0.0, core::f64::consts::TAU),
            rng.range(0.0, core::f64::consts::TAU),
        );
        // Each axis within wobble/√2, so the offset stays within the wobble disc.
        let amp = opts.wobble * core::f64::consts::FRAC_1_SQRT_2;
        let mut poses = try_vec(n, "trajectory poses")?;
        let mut times = try_vec(n, "trajectory times")?;
        for k in 0..n {
            let u = k as f64 / n.max(2).saturating_sub(1) as f64;
            let ox = amp * libm::sin(core::f64::consts::TAU * f1 * u + p1);
            let oy = amp * libm::sin(core::f64::consts::TAU * f2 * u + p2);
            let heading = opts.start_deg + sign * k as f64 * opts.step_deg;
            poses.push(Self::pose_on_ground(
                world,
                x + ox,
                y + oy,
                heading.to_radians(),
                opts.mount_height,
            ));
            times.push(k as f64 * opts.period_s);
        }
        Ok(Trajectory { poses, times })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::WorldConfig;

    fn world() -> World {
        World::new(WorldConfig::default()).unwrap()
    }

    /// The default route options with poses `spacing` metres apart.
    fn spaced(spacing: f64) -> RouteOptions {
        RouteOptions {
            spacing,
            ..RouteOptions::default()
        }
    }

    fn dist(a: &Pose, b: &Pose) -> f64 {
        let (p, q) = (a.translation(), b.translation());
        libm::sqrt((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2))
    }

    #[test]
    fn routes_of_more_than_max_frames_are_refused_up_front() {
        let w = world();
        let opts = spaced(0.01);
        // 1e9 m at 0.01 m would be 1e11 poses (10 TB): an error, not an allocation.
        match Trajectory::from_waypoints(&w, &[[0.0, 0.0], [1e9, 0.0]], &opts) {
            Err(SimError::InvalidParameter { name: "frames", .. }) => {}
            other => panic!("expected a frames error, got {other:?}"),
        }
        let just = (MAX_FRAMES - 1) as f64 * 0.01;
        let t = Trajectory::from_waypoints(&w, &[[0.0, 0.0], [just, 0.0]], &opts).unwrap();
        assert_eq!(t.poses.len(), MAX_FRAMES);
        assert!(Trajectory::from_waypoints(&w, &[[0.0, 0.0], [just + 0.011, 0.0]], &opts).is_err());
    }

    #[test]
    fn poses_are_rigid_spaced_and_on_the_ground() {
        let w = world();
        let opts = RouteOptions::default();
        for kind in TRAJECTORY_KINDS {
            let t = Trajectory::by_name(&w, kind, 1.0, &opts).unwrap();
            assert!(t.poses.len() > 100, "{kind}");
            for (i, p) in t.poses.iter().enumerate() {
                let r = p.compose(&p.inverse());
                assert!(r
                    .m
                    .iter()
                    .zip(Pose::IDENTITY.m)
                    .all(|(a, b)| (a - b).abs() < 1e-12));
                let tr = p.translation();
                let h = tr[2] - w.ground_height(tr[0], tr[1]);
                assert!((h - 1.73).abs() < 0.01, "{kind} {i}");
                if i > 0 {
                    let d = dist(p, &t.poses[i - 1]);
                    // Spacing is measured on the map (x, y); the slope adds < 0.01 %.
                    assert!(d <= 1.0005 && d > 0.9, "{kind} step {i}: {d}");
                }
            }
        }
    }

    #[test]
    fn loop_returns_to_start() {
        let w = world();
        let t = Trajectory::closed_loop(&w, 1, 1, 1.0, &RouteOptions::default()).unwrap();
        let (first, last) = (&t.poses[0], t.poses.last().unwrap());
        assert!(dist(first, last) < 1.0);
        let rel = first.inverse().compose(last).yaw_deg();
        assert!(rel.abs() < 1e-6, "{rel}");
        let t2 = Trajectory::closed_loop(&w, 1, 1, 1.5, &RouteOptions::default()).unwrap();
        assert!((t2.poses.len() as f64 / t.poses.len() as f64 - 1.5).abs() < 0.01);
    }

    #[test]
    fn reverse_and_crossing_revisit_at_the_expected_headings() {
        let w = world();
        let t = Trajectory::reverse_revisit(&w, 2, &RouteOptions::default()).unwrap();
        let n = t.poses.len();
        let rel = t.poses[10].inverse().compose(&t.poses[n - 11]);
        assert!((rel.yaw_deg().abs() - 180.0).abs() < 1e-6);
        assert!((dist(&t.poses[10], &t.poses[n - 11]) - 3.5).abs() < 0.1);
        let c = Trajectory::heading_revisit(&w, &RouteOptions::default()).unwrap();
        // Closest pair of poses far apart in time: 90° apart.
        let mut best = (f64::INFINITY, 0, 0);
        for i in 0..c.poses.len() {
            for j in i + 60..c.poses.len() {
                let d = dist(&c.poses[i], &c.poses[j]);
                if d < best.0 {
                    best = (d, i, j);
                }
            }
        }
        assert!(best.0 < 3.0, "{best:?}");
        let rel = c.poses[best.1]
            .inverse()
            .compose(&c.poses[best.2])
            .yaw_deg();
        assert!((rel.abs() - 90.0).abs() < 1.0, "{rel}");
    }

    #[test]
    fn invalid_options_are_rejected() {
        let w = world();
        assert!(Trajectory::figure_eight(&w, &spaced(0.0)).is_err());
        assert!(Trajectory::closed_loop(&w, 9, 1, 1.0, &RouteOptions::default()).is_err());
        assert!(Trajectory::by_name(&w, "spiral", 1.0, &RouteOptions::default()).is_err());
    }
}
