//! # solid-lidar-sim
//!
//! A deterministic LiDAR simulator for testing the SOLiD place-recognition descriptor: a seeded
//! procedural city (ground with a gentle slope, a road grid, buildings, poles, trees, parked cars,
//! walls and fences), exact ray casting through a uniform 2-D grid, sensor models as data
//! (HDL-64E, VLP-16, OS1-64, a Livox-Avia-like rosette, an Aeva-like narrow raster) with
//! horizontal field-of-view limits, range noise and dropout, trajectories with exact poses, and a
//! writer for KITTI-layout sequences.
//!
//! Everything random comes from a seeded xoshiro256** stream and all transcendental functions go
//! through `libm`, so a seed gives the same bits on every platform.
//!
//! ```
//! use solid_lidar_sim::{Pose, Sensor, Trajectory, World, WorldConfig};
//!
//! let world = World::new(WorldConfig { seed: 7, blocks: 2, ..WorldConfig::default() }).unwrap();
//! let sensor = Sensor::preset("vlp16").unwrap();
//! let traj = Trajectory::closed_loop(&world, 1, 1, 1.0, &Default::default()).unwrap();
//! let points = sensor.scan(&world, &traj.poses[0], 0).unwrap();
//! assert!(points.len() > 10_000);
//! ```
#![deny(missing_docs)]
#![forbid(unsafe_code)]

mod error;
mod io;
mod odometry;
mod pose;
mod prim;
pub mod rng;
mod sensor;
mod trajectory;
mod world;

/// The crate README's examples, compiled as doctests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;

pub use error::SimError;
pub use io::{write_poses, write_scans, write_sequence};
pub use odometry::DriftOptions;
pub use pose::Pose;
pub use prim::{Hit, Kind, Primitive, Shape};
pub use sensor::{hdl64_elevations, wrap180, Pattern, Sensor, SENSOR_PRESETS};
pub use trajectory::{RouteOptions, Trajectory, TurnOptions, MAX_FRAMES, TRAJECTORY_KINDS};
pub use world::{
    CorridorConfig, Layout, RayHit, RoomConfig, World, WorldConfig, GROUND_REFLECTIVITY,
};
