//! Indoor worlds for the failure modes of loop closure: a grid of corridors built from one
//! repeated module (places a module apart look nearly the same), and a small furnished room (a
//! sensor turning in place sees views that share nothing).

use super::{Layout, World, WorldConfig};
use crate::error::{check, check_in, SimError};
use crate::prim::{Kind, Primitive, Shape};
use crate::rng::{mix_seed, Rng};
use crate::world::build::Builder;

/// Thickness of walls, ceilings and floors' edges, metres.
const WALL: f64 = 0.3;

/// Parameters of a look-alike corridor world ([`World::corridors`]).
///
/// The corridors follow a road grid of `blocks × blocks` solid blocks (one block: a square ring of
/// four corridors). Every corridor between two intersections is `modules` copies of one module
/// `module_length` metres long (pillar pairs carrying ceiling beams, doors, cabinets and benches
/// along the walls); each copy moves every feature by up to `jitter` metres and leaves it out with
/// probability `dropout`, so places one module apart look nearly, not exactly, the same.
#[derive(Clone, Debug, PartialEq)]
pub struct CorridorConfig {
    /// Seed of the module template and of every copy's variation.
    pub seed: u64,
    /// Blocks per side enclosed by the corridors (1..=16).
    pub blocks: usize,
    /// Modules per corridor between two intersections (1..=64).
    pub modules: usize,
    /// Length of one module, metres ([10, 200]).
    pub module_length: f64,
    /// Wall-to-wall width of a corridor, metres ([2, 20]).
    pub width: f64,
    /// Ceiling height, metres ([2.2, 10]).
    pub height: f64,
    /// Largest displacement of a feature (and change of its size) between copies, metres ([0, 2]).
    pub jitter: f64,
    /// Probability that a copy leaves a feature out ([0, 1]).
    pub dropout: f64,
    /// Edge of the acceleration grid's square cells, metres ([0.5, 100]).
    pub cell_size: f64,
}

impl Default for CorridorConfig {
    fn default() -> Self {
        CorridorConfig {
            seed: 0,
            blocks: 1,
            modules: 4,
            module_length: 45.0,
            width: 6.0,
            height: 3.0,
            jitter: 0.15,
            dropout: 0.1,
            cell_size: 4.0,
        }
    }
}

impl CorridorConfig {
    /// Distance between parallel corridors' centrelines: the modules plus one corridor width.
    pub fn pitch(&self) -> f64 {
        self.modules as f64 * self.module_length + self.width
    }
}

/// Parameters of a small furnished room ([`World::room`]), centred on the origin.
#[derive(Clone, Debug, PartialEq)]
pub struct RoomConfig {
    /// Seed of the furniture's placement and sizes.
    pub seed: u64,
    /// Inner extent along x and y, metres (each in [3, 30]).
    pub size: [f64; 2],
    /// Ceiling height, metres ([2, 10]).
    pub height: f64,
    /// Pieces of furniture along the walls (0..=64); a table stands free in one corner.
    pub furniture: usize,
    /// Edge of the acceleration grid's square cells, metres ([0.25, 100]).
    pub cell_size: f64,
}

impl Default for RoomConfig {
    fn default() -> Self {
        RoomConfig {
            seed: 0,
            size: [6.0, 4.5],
            height: 2.6,
            furniture: 8,
            cell_size: 1.0,
        }
    }
}

fn axis_box(prims: &mut Vec<Primitive>, f: [f64; 4], z: [f64; 2], kind: Kind, refl: f32) {
    prims.push(Primitive {
        shape: Shape::Box {
            center: [(f[0] + f[2]) / 2.0, (f[1] + f[3]) / 2.0],
            half: [(f[2] - f[0]) / 2.0, (f[3] - f[1]) / 2.0],
            rot: [1.0, 0.0],
            z,
        },
        kind,
        reflectivity: refl,
    });
}

/// One feature of the corridor module, in module coordinates: `u` along the corridor, `side` +1
/// on the left wall, −1 on the right.
#[derive(Clone, Copy, Debug)]
enum Feature {
    /// A pillar pair (both walls) carrying a ceiling beam across the corridor.
    Pillars { u: f64, along: f64, out: f64 },
    /// A door: two jambs and a lintel standing out of the wall.
    Door { u: f64, side: f64, width: f64 },
    /// A cabinet or bench against the wall.
    Cabinet {
        u: f64,
        side: f64,
        len: f64,
        depth: f64,
        height: f64,
    },
}

fn module_template(seed: u64, m: f64) -> Vec<Feature> {
    let mut rng = Rng::new(mix_seed(&[seed, 20]));
    let mut out = Vec::new();
    let n_pillars = 2 + rng.below(3) as usize;
    let p = m / n_pillars as f64;
    let u0 = rng.range(0.2, 0.8) * p;
    let mut taken: Vec<(f64, f64)> = Vec::new();
    for k in 0..n_pillars {
        let u = u0 + k as f64 * p;
        let along = rng.range(0.25, 0.45);
        out.push(Feature::Pillars {
            u,
            along,
            out: rng.range(0.3, 0.6),
        });
        taken.push((u - along - 0.8, u + along + 0.8));
    }
    let place = |rng: &mut Rng, len: f64, taken: &mut Vec<(f64, f64)>| -> Option<f64> {
        for _ in 0..20 {
            let u = rng.range(1.0 + len / 2.0, m - 1.0 - len / 2.0);
            if taken
                .iter()
                .all(|&(a, b)| u + len / 2.0 < a || u - len / 2.0 > b)
            {
                taken.push((u - len / 2.0 - 0.5, u + len / 2.0 + 0.5));
                return Some(u);
            }
        }
        None
    };
    for _ in 0..3 + rng.below(3) {
        let width = rng.range(0.9, 1.8);
        let side = if rng.chance(0.5) { 1.0 } else { -1.0 };
        if let Some(u) = place(&mut rng, width + 0.3, &mut taken) {
            out.push(Feature::Door { u, side, width });
        }
    }
    for _ in 0..2 + rng.below(3) {
        let len = rng.range(0.8, 3.0);
        let side = if rng.chance(0.5) { 1.0 } else { -1.0 };
        let (depth, height) = (rng.range(0.35, 0.7), rng.range(0.45, 2.0));
        if let Some(u) = place(&mut rng, len, &mut taken) {
            out.push(Feature::Cabinet {
                u,
                side,
                len,
                depth,
                height,
            });
        }
    }
    out
}

/// Adds one copy of the module at `u_start` of a corridor (local frame of `b`, v = 0 on the
/// centreline), varied by `rng`.
fn fill_module(
    b: &mut Builder<'_>,
    template: &[Feature],
    u_start: f64,
    c: &CorridorConfig,
    rng: &mut Rng,
) {
    let half_w = c.width / 2.0;
    let h = c.height;
    for f in template {
        // Every feature draws the same numbers whether it is kept or not, so one copy's dropout
        // does not change the next feature's variation.
        let keep = !rng.chance(c.dropout);
        let du = rng.range(-c.jitter, c.jitter);
        let ds = rng.range(-0.5, 0.5) * c.jitter;
        if !keep {
            continue;
        }
        match *f {
            Feature::Pillars { u, along, out } => {
                let u = u_start + u + du;
                let out = (out + ds).max(0.1);
                for side in [1.0, -1.0] {
                    let v = side * (half_w - out / 2.0);
                    b.add_box(u, v, [along, out / 2.0], 0.0, 0.0, h, Kind::Wall, 0.5);
                }
                // Narrower than the pillars, so no face of the beam lies in a pillar's face.
                b.add_box(
                    u,
                    0.0,
                    [0.8 * along, half_w],
                    0.0,
                    h - 0.4,
                    h,
                    Kind::Ceiling,
                    0.45,
                );
            }
            Feature::Door { u, side, width } => {
                let u = u_start + u + du;
                let width = (width + ds).max(0.6);
                let v = side * (half_w - 0.08);
                for end in [-1.0, 1.0] {
                    let uj = u + end * (width / 2.0 + 0.06);
                    b.add_box(uj, v, [0.06, 0.08], 0.0, 0.0, 2.1, Kind::Wall, 0.6);
                }
                b.add_box(
                    u,
                    v,
                    [width / 2.0 + 0.12, 0.08],
                    0.0,
                    2.1,
                    2.3,
                    Kind::Wall,
                    0.6,
                );
                // The door leaf, a little proud of the wall.
                let v = side * (half_w - 0.02);
                b.add_box(u, v, [width / 2.0, 0.02], 0.0, 0.0, 2.1, Kind::Wall, 0.3);
            }
            Feature::Cabinet {
                u,
                side,
                len,
                depth,
                height,
            } => {
                let u = u_start + u + du;
                let depth = (depth + ds).max(0.2);
                let v = side * (half_w - depth / 2.0);
                let refl = 0.55;
                b.add_box(
                    u,
                    v,
                    [len / 2.0, depth / 2.0],
                    0.0,
                    0.0,
                    (height + ds).max(0.3),
                    Kind::Furniture,
                    refl,
                );
            }
        }
    }
}

impl World {
    /// Generates the look-alike corridor world described by `config` (flat ground at z = 0,
    /// corridors along the roads of [`World::config`]).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a parameter outside the range its field documents.
    pub fn corridors(config: CorridorConfig) -> Result<World, SimError> {
        let c = &config;
        check(
            "blocks",
            c.blocks as f64,
            (1..=16).contains(&c.blocks),
            "1..=16",
        )?;
        check(
            "modules",
            c.modules as f64,
            (1..=64).contains(&c.modules),
            "1..=64",
        )?;
        check_in("module_length", c.module_length, 10.0, 200.0, "[10, 200] m")?;
        check_in("width", c.width, 2.0, 20.0, "[2, 20] m")?;
        check_in("height", c.height, 2.2, 10.0, "[2.2, 10] m")?;
        check_in("jitter", c.jitter, 0.0, 2.0, "[0, 2] m")?;
        check_in("dropout", c.dropout, 0.0, 1.0, "[0, 1]")?;
        check_in("cell_size", c.cell_size, 0.5, 100.0, "[0.5, 100] m")?;
        let pitch = c.pitch();
        let nb = c.blocks;
        let first = -(nb as f64) * pitch / 2.0;
        let roads: Vec<f64> = (0..=nb).map(|k| first + k as f64 * pitch).collect();
        let half_w = c.width / 2.0;
        let (lo, hi) = (roads[0] - half_w, roads[nb] + half_w);
        let mut prims = Vec::new();
        // Walls: along each corridor on both sides, open where a crossing corridor continues on
        // that side; the outermost walls run through and close the corners.
        for (i, &r) in roads.iter().enumerate() {
            for side in [1.0f64, -1.0] {
                let crossing_continues = if side > 0.0 { i < nb } else { i > 0 };
                let mut cuts = vec![lo - WALL];
                if crossing_continues {
                    for &q in &roads {
                        cuts.push(q - half_w);
                        cuts.push(q + half_w);
                    }
                }
                cuts.push(hi + WALL);
                let v = r + side * (half_w + WALL / 2.0);
                for seg in cuts.chunks_exact(2) {
                    let (a, z) = (seg[0], seg[1]);
                    if z - a < 1e-9 {
                        continue;
                    }
                    let (f_x, f_y) = (
                        [a, v - WALL / 2.0, z, v + WALL / 2.0],
                        [v - WALL / 2.0, a, v + WALL / 2.0, z],
                    );
                    axis_box(&mut prims, f_x, [-1.0, c.height], Kind::Wall, 0.4);
                    axis_box(&mut prims, f_y, [-1.0, c.height], Kind::Wall, 0.4);
                }
            }
            // The ceiling over the whole corridor.
            let across = [r - half_w - WALL, r + half_w + WALL];
            let z = [c.height, c.height + WALL];
            axis_box(
                &mut prims,
                [lo, across[0], hi, across[1]],
                z,
                Kind::Ceiling,
                0.3,
            );
            axis_box(
                &mut prims,
                [across[0], lo, across[1], hi],
                z,
                Kind::Ceiling,
                0.3,
            );
        }
        // Modules: every corridor between two intersections, laid in the direction a
        // counter-clockwise lap around the grid drives it, so every copy is seen the same way.
        let template = module_template(c.seed, c.module_length);
        let mut copy = 0u64;
        for dir in 0..2 {
            for (i, &r) in roads.iter().enumerate() {
                let forward = if dir == 0 { 2 * i < nb } else { 2 * i >= nb };
                for j in 0..nb {
                    let (a, z) = (roads[j] + half_w, roads[j + 1] - half_w);
                    let (start, sign) = if forward { (a, 1.0) } else { (z, -1.0) };
                    let (origin, axis) = if dir == 0 {
                        ([start, r], [sign, 0.0])
                    } else {
                        ([r, start], [0.0, sign])
                    };
                    let mut b = Builder {
                        prims: &mut prims,
                        slope: [0.0, 0.0],
                        origin,
                        axis,
                    };
                    for k in 0..c.modules {
                        copy += 1;
                        let mut rng = Rng::new(mix_seed(&[c.seed, 21, copy]));
                        let u = k as f64 * c.module_length;
                        fill_module(&mut b, &template, u, c, &mut rng);
                    }
                }
            }
        }
        let grid = flat_grid(c.seed, nb, pitch, half_w, 1.0, c.cell_size);
        Ok(World::assemble(
            grid,
            Layout::Corridors(config),
            prims,
            roads,
        ))
    }

    /// Generates the furnished room described by `config`: four walls and a ceiling around
    /// x ∈ [−size₀/2, size₀/2], y ∈ [−size₁/2, size₁/2] on flat ground at z = 0, a pillar
    /// standing out of one wall, cabinets, shelves and boxes along the walls and a table in one
    /// corner. Nothing stands within 1.2 m of the centre, so a sensor can turn there.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a parameter outside the range its field documents.
    pub fn room(config: RoomConfig) -> Result<World, SimError> {
        let c = &config;
        for s in c.size {
            check_in("size", s, 3.0, 30.0, "[3, 30] m")?;
        }
        check_in("height", c.height, 2.0, 10.0, "[2, 10] m")?;
        check("furniture", c.furniture as f64, c.furniture <= 64, "0..=64")?;
        check_in("cell_size", c.cell_size, 0.25, 100.0, "[0.25, 100] m")?;
        let (hx, hy, h) = (c.size[0] / 2.0, c.size[1] / 2.0, c.height);
        let mut prims = Vec::new();
        let z = [-1.0, h];
        axis_box(
            &mut prims,
            [-hx - WALL, -hy - WALL, -hx, hy + WALL],
            z,
            Kind::Wall,
            0.4,
        );
        axis_box(
            &mut prims,
            [hx, -hy - WALL, hx + WALL, hy + WALL],
            z,
            Kind::Wall,
            0.4,
        );
        axis_box(&mut prims, [-hx, -hy - WALL, hx, -hy], z, Kind::Wall, 0.4);
        axis_box(&mut prims, [-hx, hy, hx, hy + WALL], z, Kind::Wall, 0.4);
        axis_box(
            &mut prims,
            [-hx - WALL, -hy - WALL, hx + WALL, hy + WALL],
            [h, h + WALL],
            Kind::Ceiling,
            0.3,
        );
        let mut rng = Rng::new(mix_seed(&[c.seed, 30]));
        // Footprints taken so far, [xmin, ymin, xmax, ymax].
        let mut taken: Vec<[f64; 4]> = Vec::new();
        let free = |f: [f64; 4], taken: &[[f64; 4]]| {
            // Clear of the centre (nearest point of the footprint) and of earlier pieces.
            let nx = 0.0f64.clamp(f[0], f[2]);
            let ny = 0.0f64.clamp(f[1], f[3]);
            libm::sqrt(nx * nx + ny * ny) >= 1.2
                && taken
                    .iter()
                    .all(|t| f[2] <= t[0] || f[0] >= t[2] || f[3] <= t[1] || f[1] >= t[3])
        };
        // A pillar standing out of the middle of one wall breaks the room's symmetry.
        let (pw, pd) = (rng.range(0.4, 0.7), rng.range(0.3, 0.5));
        let at = rng.range(-0.3, 0.3) * c.size[0];
        let pillar = [at - pw / 2.0, hy - pd, at + pw / 2.0, hy];
        axis_box(&mut prims, pillar, z, Kind::Wall, 0.5);
        taken.push(pillar);
        // The table in one corner: a top on four legs.
        let (tx, ty) = (rng.range(0.6, 0.9), rng.range(0.6, 0.9));
        let (sx, sy) = if rng.chance(0.5) {
            (1.0, -1.0)
        } else {
            (-1.0, -1.0)
        };
        let centre = [sx * (hx - 0.3 - tx), sy * (hy - 0.3 - ty)];
        let top = [
            centre[0] - tx,
            centre[1] - ty,
            centre[0] + tx,
            centre[1] + ty,
        ];
        if free(top, &taken) {
            axis_box(&mut prims, top, [0.72, 0.76], Kind::Furniture, 0.5);
            for (lx, ly) in [
                (top[0], top[1]),
                (top[2], top[1]),
                (top[0], top[3]),
                (top[2], top[3]),
            ] {
                let (lx, ly) = (lx + (centre[0] - lx) * 0.1, ly + (centre[1] - ly) * 0.1);
                prims.push(Primitive {
                    shape: Shape::Cylinder {
                        center: [lx, ly],
                        radius: 0.03,
                        z: [-1.0, 0.72],
                    },
                    kind: Kind::Furniture,
                    reflectivity: 0.5,
                });
            }
            taken.push(top);
        }
        for _ in 0..c.furniture {
            let len = rng.range(0.5, 2.0);
            let depth = rng.range(0.3, 0.7);
            let height = rng.range(0.4, 2.1);
            let refl = rng.range(0.2, 0.8) as f32;
            let wall = rng.below(4);
            let s = rng.uniform();
            // Along the wall and away from it, then turned to the wall's axis.
            let horizontal = wall < 2;
            let (span, half_across) = if horizontal {
                (c.size[0], hy)
            } else {
                (c.size[1], hx)
            };
            let along = -span / 2.0 + len / 2.0 + s * (span - len);
            let across = if wall.is_multiple_of(2) {
                -half_across + depth / 2.0
            } else {
                half_across - depth / 2.0
            };
            let (x, y, ex, ey) = if horizontal {
                (along, across, len / 2.0, depth / 2.0)
            } else {
                (across, along, depth / 2.0, len / 2.0)
            };
            let f = [x - ex, y - ey, x + ex, y + ey];
            if free(f, &taken) {
                axis_box(&mut prims, f, [-1.0, height], Kind::Furniture, refl);
                taken.push(f);
            }
        }
        let pitch = c.size[0].max(c.size[1]);
        let grid = flat_grid(c.seed, 0, pitch, 0.0, 0.0, c.cell_size);
        Ok(World::assemble(
            grid,
            Layout::Room(config),
            prims,
            Vec::new(),
        ))
    }
}

/// The grid parameters an indoor world reports: flat ground, its own pitch and roads.
fn flat_grid(
    seed: u64,
    blocks: usize,
    block_pitch: f64,
    road_half_width: f64,
    repetition: f64,
    cell_size: f64,
) -> WorldConfig {
    WorldConfig {
        seed,
        blocks,
        block_pitch,
        road_half_width,
        slope: [0.0, 0.0],
        repetition,
        cell_size,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectory::{RouteOptions, Trajectory, TurnOptions};

    fn walk() -> RouteOptions {
        RouteOptions {
            spacing: 2.0,
            lane_offset: 0.0,
            corner_radius: 3.0,
            speed: 1.5,
            mount_height: 1.2,
        }
    }

    /// Casts a fan of rays around `o` and returns the farthest hit (infinite when one escapes).
    fn farthest_hit(world: &World, o: [f64; 3], elevation: f64) -> f64 {
        let mut far = 0.0f64;
        for k in 0..360 {
            let az = (k as f64).to_radians();
            let (se, ce) = libm::sincos(elevation);
            let d = [ce * libm::cos(az), ce * libm::sin(az), se];
            far = far.max(world.cast(o, d, 1e4).map_or(f64::INFINITY, |h| h.t));
        }
        far
    }

    #[test]
    fn corridor_lap_stays_inside_a_closed_corridor() {
        let c = CorridorConfig::default();
        let world = World::corridors(c.clone()).unwrap();
        assert_eq!(world.roads().len(), 2);
        let traj = Trajectory::closed_loop(&world, 1, 1, 1.0, &walk()).unwrap();
        for p in traj.poses.iter().step_by(5) {
            let o = p.translation();
            // Nothing stands in the walking line, and the corridor is closed: every level ray
            // ends on a wall, a pillar or a piece of furniture, never at the range limit.
            for q in world.primitives() {
                if let Shape::Box { .. } = q.shape {
                    let f = q.shape.footprint();
                    let inside = o[0] > f[0] && o[0] < f[2] && o[1] > f[1] && o[1] < f[3];
                    assert!(!inside || q.kind == Kind::Ceiling, "{o:?} inside {q:?}");
                }
            }
            assert!(farthest_hit(&world, o, 0.0) < c.pitch() + c.width, "{o:?}");
            // Straight up is the ceiling.
            let up = world.cast(o, [0.0, 0.0, 1.0], 100.0).unwrap();
            assert!((up.t - (c.height - o[2])).abs() < 0.41, "{o:?} {}", up.t);
        }
    }

    #[test]
    fn corridor_grid_matches_brute_force() {
        let world = World::corridors(CorridorConfig {
            blocks: 2,
            modules: 2,
            ..CorridorConfig::default()
        })
        .unwrap();
        let traj = Trajectory::figure_eight(&world, &walk()).unwrap();
        let mut rng = Rng::new(3);
        for p in traj.poses.iter().step_by(7) {
            let o = p.translation();
            for _ in 0..50 {
                let az = rng.range(0.0, core::f64::consts::TAU);
                let el = rng.range(-0.5, 0.5);
                let d = [
                    libm::cos(el) * libm::cos(az),
                    libm::cos(el) * libm::sin(az),
                    libm::sin(el),
                ];
                assert_eq!(world.cast(o, d, 300.0), world.cast_brute_force(o, d, 300.0));
            }
        }
    }

    #[test]
    fn module_copies_differ_by_the_jitter_only() {
        let c = CorridorConfig {
            dropout: 0.0,
            ..CorridorConfig::default()
        };
        let world = World::corridors(c.clone()).unwrap();
        // Features of the southern corridor (walls and ceilings excluded), by module.
        let r = world.roads();
        let (lo, hi) = (r[0] - c.width / 2.0, r[0] + c.width / 2.0);
        let end = r[1] - c.width / 2.0;
        let mut per_module: Vec<Vec<[f64; 2]>> = vec![Vec::new(); c.modules];
        let start = world.roads()[0] + c.width / 2.0;
        for p in world.primitives() {
            let f = p.shape.footprint();
            let (x, y) = ((f[0] + f[2]) / 2.0, (f[1] + f[3]) / 2.0);
            let long = f[2] - f[0] > c.module_length;
            if y > lo && y < hi && !long && p.kind != Kind::Ceiling && x > start && x < end {
                let k = ((x - start) / c.module_length) as usize;
                per_module[k.min(c.modules - 1)].push([x - start - k as f64 * c.module_length, y]);
            }
        }
        let n = per_module[0].len();
        assert!(n >= 10, "{n} features per module");
        for m in &per_module[1..] {
            assert_eq!(m.len(), n);
            for (a, b) in per_module[0].iter().zip(m) {
                // Copies are within 2 × jitter of each other, never identical.
                assert!((a[0] - b[0]).abs() <= 2.0 * c.jitter + 1e-9, "{a:?} {b:?}");
                assert!((a[1] - b[1]).abs() <= c.jitter + 1e-9, "{a:?} {b:?}");
            }
            assert_ne!(per_module[0], *m);
        }
        assert!(World::corridors(CorridorConfig {
            width: 1.0,
            ..CorridorConfig::default()
        })
        .is_err());
    }

    #[test]
    fn room_is_closed_and_clear_around_its_centre() {
        let c = RoomConfig::default();
        let world = World::room(c.clone()).unwrap();
        assert!(world.roads().is_empty());
        let furniture = world
            .primitives()
            .iter()
            .filter(|p| p.kind == Kind::Furniture)
            .count();
        assert!(furniture >= 4, "{furniture}");
        let o = [0.0, 0.0, 1.2];
        let diag = libm::sqrt(c.size[0].powi(2) + c.size[1].powi(2)) / 2.0;
        for el in [-0.6, -0.2, 0.0, 0.3, 0.6] {
            let far = farthest_hit(&world, o, el);
            assert!(far <= diag / libm::cos(el) + 0.01, "{el}: {far}");
        }
        let mut near = f64::INFINITY;
        for k in 0..360 {
            let az = (k as f64).to_radians();
            let d = [libm::cos(az), libm::sin(az), 0.0];
            near = near.min(world.cast(o, d, 100.0).unwrap().t);
        }
        assert!(near >= 1.2, "{near}");
        assert!(World::room(RoomConfig {
            size: [2.0, 4.0],
            ..RoomConfig::default()
        })
        .is_err());
    }

    #[test]
    fn turning_in_place_stays_within_the_wobble() {
        let world = World::room(RoomConfig::default()).unwrap();
        let opts = TurnOptions {
            wobble: 0.3,
            seed: 2,
            ..TurnOptions::default()
        };
        let t = Trajectory::turn_in_place(&world, 0.0, 0.0, &opts).unwrap();
        assert_eq!(t.poses.len(), 166);
        let mut far = 0.0f64;
        for (k, p) in t.poses.iter().enumerate() {
            let o = p.translation();
            far = far.max(libm::sqrt(o[0] * o[0] + o[1] * o[1]));
            let want = crate::sensor::wrap180(2.0 * k as f64);
            assert!((crate::sensor::wrap180(p.yaw_deg() - want)).abs() < 1e-9);
            assert!((o[2] - 1.2).abs() < 1e-12);
        }
        assert!(far <= 0.3 && far > 0.1, "{far}");
        let still = Trajectory::turn_in_place(&world, 0.5, 0.0, &TurnOptions::default()).unwrap();
        assert!(still
            .poses
            .iter()
            .all(|p| p.translation()[..2] == [0.5, 0.0]));
        assert!(Trajectory::turn_in_place(
            &world,
            0.0,
            0.0,
            &TurnOptions {
                wobble: 6.0,
                ..TurnOptions::default()
            }
        )
        .is_err());
    }
}
