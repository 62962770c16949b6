//! The procedural world: ground plane, road grid, buildings, street furniture, and ray casting
//! through a uniform 2-D grid.

use crate::error::{check, SimError};
use crate::prim::{slab, Hit, Kind, Primitive};
use crate::rng::{mix_seed, Rng};
use build::{fill_block, fill_street_side, Builder};
pub use indoor::{CorridorConfig, RoomConfig};

mod build;
mod indoor;

/// Parameters of a procedural world. `World::new` validates them.
#[derive(Clone, Debug, PartialEq)]
pub struct WorldConfig {
    /// Seed of everything random in the world.
    pub seed: u64,
    /// Number of city blocks per side inside the road grid (there are `blocks + 1` roads per
    /// direction, and a ring of blocks outside the outermost roads).
    pub blocks: usize,
    /// Distance between neighbouring parallel roads, metres.
    pub block_pitch: f64,
    /// Half width of the carriageway, metres (the sidewalk adds 4 m on each side).
    pub road_half_width: f64,
    /// Ground gradient (dz/dx, dz/dy); the ground is the plane z = sx·x + sy·y.
    pub slope: [f64; 2],
    /// Probability that a block or street side copies one of a few shared templates, which makes
    /// some places look alike.
    pub repetition: f64,
    /// Edge of the acceleration grid's square cells, metres.
    pub cell_size: f64,
}

impl Default for WorldConfig {
    fn default() -> Self {
        WorldConfig {
            seed: 0,
            blocks: 4,
            block_pitch: 80.0,
            road_half_width: 7.0,
            slope: [0.01, -0.006],
            repetition: 0.3,
            cell_size: 4.0,
        }
    }
}

/// What a cast ray hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Distance along the (unit) ray direction, metres.
    pub t: f64,
    /// Unit outward normal at the hit.
    pub normal: [f64; 3],
    /// Reflectivity of the surface in [0, 1].
    pub reflectivity: f32,
    /// The class of the hit primitive; `None` for the ground.
    pub kind: Option<Kind>,
}

/// Reflectivity of the road surface.
pub const GROUND_REFLECTIVITY: f32 = 0.12;
const SIDEWALK: f64 = 4.0;
const N_TEMPLATES: u64 = 3;

#[derive(Clone, Debug)]
struct Grid {
    x0: f64,
    y0: f64,
    cell: f64,
    nx: usize,
    ny: usize,
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl Grid {
    fn build(prims: &[Primitive], cell: f64) -> Grid {
        let mut b = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for p in prims {
            let f = p.shape.footprint();
            b[0] = b[0].min(f[0]);
            b[1] = b[1].min(f[1]);
            b[2] = b[2].max(f[2]);
            b[3] = b[3].max(f[3]);
        }
        if prims.is_empty() {
            b = [0.0, 0.0, cell, cell];
        }
        let x0 = b[0] - 1e-6;
        let y0 = b[1] - 1e-6;
        let nx = (((b[2] - x0) / cell).floor() as usize + 1).max(1);
        let ny = (((b[3] - y0) / cell).floor() as usize + 1).max(1);
        let cell_range = |f: [f64; 4]| {
            let ix0 = (((f[0] - x0) / cell).floor().max(0.0) as usize).min(nx - 1);
            let ix1 = (((f[2] - x0) / cell).floor().max(0.0) as usize).min(nx - 1);
            let iy0 = (((f[1] - y0) / cell).floor().max(0.0) as usize).min(ny - 1);
            let iy1 = (((f[3] - y0) / cell).floor().max(0.0) as usize).min(ny - 1);
            (ix0, ix1, iy0, iy1)
        };
        let mut counts = vec![0u32; nx * ny + 1];
        for p in prims {
            let (ix0, ix1, iy0, iy1) = cell_range(p.shape.footprint());
            for iy in iy0..=iy1 {
                for ix in ix0..=ix1 {
                    counts[iy * nx + ix + 1] += 1;
                }
            }
        }
        for i in 1..counts.len() {
            counts[i] += counts[i - 1];
        }
        let starts = counts;
        let mut fill = starts.clone();
        let mut items = vec![0u32; starts[nx * ny] as usize];
        for (id, p) in prims.iter().enumerate() {
            let (ix0, ix1, iy0, iy1) = cell_range(p.shape.footprint());
            for iy in iy0..=iy1 {
                for ix in ix0..=ix1 {
                    let c = iy * nx + ix;
                    items[fill[c] as usize] = id as u32;
                    fill[c] += 1;
                }
            }
        }
        Grid {
            x0,
            y0,
            cell,
            nx,
            ny,
            starts,
            items,
        }
    }

    fn cell_items(&self, ix: usize, iy: usize) -> &[u32] {
        let c = iy * self.nx + ix;
        &self.items[self.starts[c] as usize..self.starts[c + 1] as usize]
    }
}

/// Which generator made a world.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Layout {
    /// The procedural city of [`World::new`].
    City,
    /// The look-alike corridor grid of [`World::corridors`].
    Corridors(CorridorConfig),
    /// The small furnished room of [`World::room`].
    Room(RoomConfig),
}

/// A deterministic procedural world.
#[derive(Clone, Debug)]
pub struct World {
    config: WorldConfig,
    layout: Layout,
    prims: Vec<Primitive>,
    roads: Vec<f64>,
    z_top: f64,
    grid: Grid,
}
impl World {
    /// Generates the world described by `config`.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for blocks outside 1..=64, a pitch not greater than
    /// 2·(road_half_width + 4) + 20 m, a slope steeper than 0.2, a repetition outside [0, 1],
    /// or a cell size outside [0.5, 100] m.
    pub fn new(config: WorldConfig) -> Result<World, SimError> {
        let c = &config;
        check(
            "blocks",
            c.blocks as f64,
            (1..=64).contains(&c.blocks),
            "1..=64",
        )?;
        check(
            "road_half_width",
            c.road_half_width,
            c.road_half_width >= 2.0 && c.road_half_width <= 30.0,
            "2..=30 m",
        )?;
        check(
            "block_pitch",
            c.block_pitch,
            c.block_pitch > 2.0 * (c.road_half_width + SIDEWALK) + 20.0 && c.block_pitch <= 1000.0,
            "> 2·(road_half_width + 4) + 20 and <= 1000 m",
        )?;
        for s in c.slope {
            check("slope", s, s.abs() <= 0.2, "|slope| <= 0.2")?;
        }
        check(
            "repetition",
            c.repetition,
            (0.0..=1.0).contains(&c.repetition),
            "[0, 1]",
        )?;
        check(
            "cell_size",
            c.cell_size,
            (0.5..=100.0).contains(&c.cell_size),
            "[0.5, 100] m",
        )?;

        let pitch = c.block_pitch;
        let first = -(c.blocks as f64) * pitch / 2.0;
        let roads: Vec<f64> = (0..=c.blocks).map(|k| first + k as f64 * pitch).collect();
        let mut prims = Vec::new();
        let margin = c.road_half_width + SIDEWALK;
        let w = pitch - 2.0 * margin;
        // Blocks, including a ring outside the outermost roads.
        let nb = c.blocks as i64;
        for by in -1..=nb {
            for bx in -1..=nb {
                let id = ((by + 1) * (nb + 2) + (bx + 1)) as u64;
                let mut pick = Rng::new(mix_seed(&[c.seed, 1, id]));
                let template = if pick.chance(c.repetition) {
                    1_000_000 + pick.below(N_TEMPLATES)
                } else {
                    id
                };
                let mut rng = Rng::new(mix_seed(&[c.seed, 2, template]));
                let mut b = Builder {
                    prims: &mut prims,
                    slope: c.slope,
                    origin: [
                        first + bx as f64 * pitch + margin,
                        first + by as f64 * pitch + margin,
                    ],
                    axis: [1.0, 0.0],
                };
                fill_block(&mut b, w, &mut rng);
            }
        }
        // Street sides: for each road line and each gap between crossing roads (plus the two
        // stubs to the world's edge), both sides of the street.
        let ext_lo = first - pitch;
        let ext_hi = first + c.blocks as f64 * pitch + pitch;
        let mut breaks = vec![ext_lo];
        breaks.extend(roads.iter().copied());
        breaks.push(ext_hi);
        let mut street_id = 0u64;
        for dir in 0..2 {
            for &r in &roads {
                for seg in breaks.windows(2) {
                    let a = if seg[0] == ext_lo {
                        seg[0]
                    } else {
                        seg[0] + margin
                    };
                    let z = if seg[1] == ext_hi {
                        seg[1]
                    } else {
                        seg[1] - margin
                    };
                    if z - a < 5.0 {
                        continue;
                    }
                    for side in [1.0f64, -1.0] {
                        street_id += 1;
                        let mut pick = Rng::new(mix_seed(&[c.seed, 3, street_id]));
                        let template = if pick.chance(c.repetition) {
                            1_000_000 + pick.below(N_TEMPLATES)
                        } else {
                            street_id
                        };
                        let mut rng = Rng::new(mix_seed(&[c.seed, 4, template]));
                        // Local u along the street, v away from the centreline on this side.
                        let (origin, axis) = if dir == 0 {
                            // Road along x at y = r.
                            if side > 0.0 {
                                ([a, r], [1.0, 0.0])
                            } else {
                                ([z, r], [-1.0, 0.0])
                            }
                        } else if side > 0.0 {
                            ([r, z], [0.0, -1.0])
                        } else {
                            ([r, a], [0.0, 1.0])
                        };
                        let mut b = Builder {
                            prims: &mut prims,
                            slope: c.slope,
                            origin,
                            axis,
                        };
                        // With axis (c, s), local +v is (-s, c): the left of the street direction.
                        fill_street_side(&mut b, z - a, c.road_half_width, &mut rng);
                    }
                }
            }
        }
        Ok(World::assemble(config, Layout::City, prims, roads))
    }

    /// A world of the given primitives, with its acceleration grid.
    fn assemble(
        config: WorldConfig,
        layout: Layout,
        prims: Vec<Primitive>,
        roads: Vec<f64>,
    ) -> World {
        let z_top = prims
            .iter()
            .map(|p| p.shape.top())
            .fold(f64::NEG_INFINITY, f64::max);
        let grid = Grid::build(&prims, config.cell_size);
        World {
            config,
            layout,
            prims,
            roads,
            z_top,
            grid,
        }
    }

    /// The road grid and ground of the world: for [`World::new`] the configuration it was
    /// generated from; for the corridor and room worlds the equivalent grid the trajectory
    /// builders drive on (corridors are its roads, the ground is flat; a room has no roads).
    pub fn config(&self) -> &WorldConfig {
        &self.config
    }

    /// Which generator made the world, with its parameters.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// All primitives.
    pub fn primitives(&self) -> &[Primitive] {
        &self.prims
    }

    /// Road centreline coordinates: roads run along x at each of these y and along y at each of
    /// these x.
    pub fn roads(&self) -> &[f64] {
        &self.roads
    }

    /// The extent `[xmin, ymin, xmax, ymax]` covered by objects.
    pub fn bounds(&self) -> [f64; 4] {
        let g = &self.grid;
        [
            g.x0,
            g.y0,
            g.x0 + g.nx as f64 * g.cell,
            g.y0 + g.ny as f64 * g.cell,
        ]
    }

    /// Ground height at (x, y).
    pub fn ground_height(&self, x: f64, y: f64) -> f64 {
        self.config.slope[0] * x + self.config.slope[1] * y
    }

    /// Unit upward normal of the ground plane.
    pub fn ground_normal(&self) -> [f64; 3] {
        let [sx, sy] = self.config.slope;
        let n = libm::sqrt(sx * sx + sy * sy + 1.0);
        [-sx / n, -sy / n, 1.0 / n]
    }

    fn ground_hit(&self, o: [f64; 3], d: [f64; 3], t_max: f64) -> Option<RayHit> {
        let [sx, sy] = self.config.slope;
        let denom = d[2] - sx * d[0] - sy * d[1];
        if denom >= 0.0 {
            return None;
        }
        let h = o[2] - self.ground_height(o[0], o[1]);
        let t = h / -denom;
        if t > 0.0 && t < t_max {
            Some(RayHit {
                t,
                normal: self.ground_normal(),
                reflectivity: GROUND_REFLECTIVITY,
                kind: None,
            })
        } else {
            None
        }
    }

    /// Casts the ray `o + t·d` (`d` a unit vector) and returns the nearest hit with 0 < t < t_max,
    /// using the acceleration grid.
    pub fn cast(&self, o: [f64; 3], d: [f64; 3], t_max: f64) -> Option<RayHit> {
        let mut best = self.ground_hit(o, d, t_max);
        let mut limit = best.map_or(t_max, |h| h.t);
        if d[2] > 0.0 {
            let t_ceiling = (self.z_top - o[2]) / d[2];
            if t_ceiling <= 0.0 {
                return best;
            }
            limit = limit.min(t_ceiling + 1e-9);
        }
        let g = &self.grid;
        let (x1, y1) = (g.x0 + g.nx as f64 * g.cell, g.y0 + g.ny as f64 * g.cell);
        let Some((tx0, tx1)) = slab(o[0], d[0], g.x0, x1) else {
            return best;
        };
        let Some((ty0, ty1)) = slab(o[1], d[1], g.y0, y1) else {
            return best;
        };
        let t_enter = tx0.max(ty0).max(0.0);
        let t_exit = tx1.min(ty1).min(limit);
        if t_enter >= t_exit {
            return best;
        }
        let cell = g.cell;
        let px = o[0] + t_enter * d[0];
        let py = o[1] + t_enter * d[1];
        let mut ix = (((px - g.x0) / cell).floor().max(0.0) as usize).min(g.nx - 1);
        let mut iy = (((py - g.y0) / cell).floor().max(0.0) as usize).min(g.ny - 1);
        let (step_x, mut next_x, delta_x) = dda_axis(o[0], d[0], g.x0, cell, ix);
        let (step_y, mut next_y, delta_y) = dda_axis(o[1], d[1], g.y0, cell, iy);
        loop {
            let cell_exit = next_x.min(next_y).min(t_exit);
            for &id in g.cell_items(ix, iy) {
                nearer(&self.prims[id as usize], o, d, &mut limit, &mut best);
            }
            if limit <= cell_exit || cell_exit >= t_exit {
                break;
            }
            if next_x < next_y {
                match step(ix, step_x, g.nx) {
                    Some(i) => ix = i,
                    None => break,
                }
                next_x += delta_x;
            } else {
                match step(iy, step_y, g.ny) {
                    Some(i) => iy = i,
                    None => break,
                }
                next_y += delta_y;
            }
        }
        best
    }

    /// Reference ray cast that tests every primitive (slow; for tests and validation).
    pub fn cast_brute_force(&self, o: [f64; 3], d: [f64; 3], t_max: f64) -> Option<RayHit> {
        let mut best = self.ground_hit(o, d, t_max);
        let mut limit = best.map_or(t_max, |h| h.t);
        for p in &self.prims {
            nearer(p, o, d, &mut limit, &mut best);
        }
        best
    }
}

/// Makes the hit of the ray `o + t d` on `p` the `best` when it lies before `limit`, which
/// then becomes its distance.
#[inline]
fn nearer(p: &Primitive, o: [f64; 3], d: [f64; 3], limit: &mut f64, best: &mut Option<RayHit>) {
    if let Some(Hit { t, normal }) = p.shape.intersect(o, d, 0.0, *limit) {
        *limit = t;
        *best = Some(RayHit {
            t,
            normal,
            reflectivity: p.reflectivity,
            kind: Some(p.kind),
        });
    }
}

/// (step, t of the next boundary crossing, t between crossings) for one DDA axis.
fn dda_axis(o: f64, d: f64, lo: f64, cell: f64, i: usize) -> (i8, f64, f64) {
    if d > 0.0 {
        (1, (lo + (i + 1) as f64 * cell - o) / d, cell / d)
    } else if d < 0.0 {
        (-1, (lo + i as f64 * cell - o) / d, -cell / d)
    } else {
        (0, f64::INFINITY, f64::INFINITY)
    }
}

fn step(i: usize, s: i8, n: usize) -> Option<usize> {
    match s {
        1 if i + 1 < n => Some(i + 1),
        -1 if i > 0 => Some(i - 1),
        _ => None,
    }
}

#[cfg(test)]
impl World {
    /// The city grid of `blocks` blocks from `seed`, every other parameter its default.
    pub(crate) fn city(seed: u64, blocks: usize) -> World {
        World::new(WorldConfig {
            seed,
            blocks,
            ..WorldConfig::default()
        })
        .unwrap()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_matches_brute_force_on_random_rays() {
        let world = World::city(11, 2);
        assert!(world.primitives().len() > 200);
        let mut rng = Rng::new(5);
        let b = world.bounds();
        let mut hits = 0;
        let mut object_hits = 0;
        for i in 0..20_000 {
            let x = rng.range(b[0] - 20.0, b[2] + 20.0);
            let y = rng.range(b[1] - 20.0, b[3] + 20.0);
            let z = world.ground_height(x, y) + rng.range(0.2, if i % 4 == 0 { 60.0 } else { 4.0 });
            let az = rng.range(0.0, core::f64::consts::TAU);
            let el = rng.range(-0.6, 0.4);
            let d = [
                libm::cos(el) * libm::cos(az),
                libm::cos(el) * libm::sin(az),
                libm::sin(el),
            ];
            let t_max = if i % 3 == 0 { 1e4 } else { 80.0 };
            let fast = world.cast([x, y, z], d, t_max);
            let slow = world.cast_brute_force([x, y, z], d, t_max);
            assert_eq!(fast.map(|h| h.t), slow.map(|h| h.t), "ray {i}");
            assert_eq!(fast, slow, "ray {i}");
            hits += usize::from(fast.is_some());
            object_hits += usize::from(fast.is_some_and(|h| h.kind.is_some()));
        }
        assert!(hits > 10_000 && object_hits > 3_000, "{hits} {object_hits}");
    }

    #[test]
    fn axis_parallel_rays_match_brute_force() {
        let world = World::city(3, 1);
        let mut rng = Rng::new(9);
        for _ in 0..2000 {
            let x = rng.range(-100.0, 100.0);
            let y = rng.range(-100.0, 100.0);
            let z = world.ground_height(x, y) + 1.5;
            for d in [
                [1.0, 0.0, 0.0],
                [-1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, -1.0, 0.0],
                [0.0, 0.0, 1.0],
                [0.0, 0.0, -1.0],
            ] {
                assert_eq!(
                    world.cast([x, y, z], d, 300.0),
                    world.cast_brute_force([x, y, z], d, 300.0)
                );
            }
        }
    }

    #[test]
    fn same_seed_same_world_different_seed_different_world() {
        let blocks = WorldConfig::default().blocks;
        let (a, b, c) = (
            World::city(1, blocks),
            World::city(1, blocks),
            World::city(2, blocks),
        );
        assert_eq!(a.primitives(), b.primitives());
        assert_ne!(a.primitives(), c.primitives());
    }

    #[test]
    fn driving_lanes_are_clear() {
        let world = World::new(WorldConfig::default()).unwrap();
        for p in world.primitives() {
            let f = p.shape.footprint();
            for &r in world.roads() {
                // No footprint reaches into the lanes (|offset| < 3.5 m) of any road.
                assert!(
                    !(f[1] < r + 3.5 && f[3] > r - 3.5),
                    "{p:?} on the road y = {r}"
                );
                assert!(
                    !(f[0] < r + 3.5 && f[2] > r - 3.5),
                    "{p:?} on the road x = {r}"
                );
            }
        }
    }
}

#[cfg(test)]
mod stability {
    use super::*;
    use crate::prim::Shape;

    fn fnv(h: &mut u64, v: f64) {
        for b in v.to_bits().to_le_bytes() {
            *h ^= u64::from(b);
            *h = h.wrapping_mul(0x0100_0000_01B3);
        }
    }

    /// The default world of seed 0 is what the Python tests' measured figures refer to; this
    /// fingerprint changes whenever generation changes (deliberately or by a platform difference
    /// in the maths), which means those figures must be measured again.
    #[test]
    fn default_world_fingerprint() {
        let world = World::new(WorldConfig::default()).unwrap();
        let mut h = 0xCBF2_9CE4_8422_2325u64;
        for p in world.primitives() {
            match p.shape {
                Shape::Box {
                    center,
                    half,
                    rot,
                    z,
                } => {
                    for v in [
                        center[0], center[1], half[0], half[1], rot[0], rot[1], z[0], z[1],
                    ] {
                        fnv(&mut h, v);
                    }
                }
                Shape::Cylinder { center, radius, z } => {
                    for v in [center[0], center[1], radius, z[0], z[1]] {
                        fnv(&mut h, v);
                    }
                }
                Shape::Ellipsoid { center, radii } => {
                    for v in center.into_iter().chain(radii) {
                        fnv(&mut h, v);
                    }
                }
            }
            fnv(&mut h, f64::from(p.reflectivity));
        }
        assert_eq!((world.primitives().len(), h), (2926, 3066258509322139664));
        // And one noisy scan along a trajectory (trigonometry, ray casting, noise stream).
        let traj = crate::Trajectory::closed_loop(&world, 1, 1, 1.0, &Default::default()).unwrap();
        let pts = crate::Sensor::preset("vlp16")
            .unwrap()
            .scan(&world, &traj.poses[17], 17)
            .unwrap();
        let mut h = 0xCBF2_9CE4_8422_2325u64;
        for p in &pts {
            for v in p {
                fnv(&mut h, f64::from(*v));
            }
        }
        assert_eq!((pts.len(), h), (25770, 12897894411886631762));
    }
}
