//! # solid-lidar
//!
//! SOLiD (Kim et al., IEEE RA-L 2024): a LiDAR place-recognition descriptor made of two short
//! vectors per scan, R-SOLiD (range, to recognise a place) and A-SOLiD (azimuth, to estimate the
//! heading between two visits). This crate computes them exactly as [the specification](spec)
//! (the repository's `docs/spec.md`, cited as "spec §n") defines, compares them, and searches
//! databases of them.
//!
//! `#![no_std]` and allocation-free: every function takes caller-owned input, output and scratch
//! slices. The `alloc` feature adds owning conveniences ([`Describer`], [`Descriptor`]); `std`
//! (the default) adds `std::error::Error`. All floating-point math goes through `libm` or plain
//! IEEE arithmetic, so every build on every platform gives the same bits.
//!
//! ```
//! use solid_lidar::{describe, describe_scratch_len, Config, Points, Scratch};
//!
//! let cfg = Config::preset("hdl64").unwrap();
//! // Three points, x y z per row (a KITTI N x 4 array would use stride 4).
//! let xyz = [10.0f32, 0.0, -1.0, 0.0, 12.0, 0.5, -20.0, -3.0, -2.0];
//! let points = Points::new(&xyz, 3).unwrap();
//! let mut scratch = vec![Scratch::default(); describe_scratch_len(points.len(), &cfg)];
//! let (mut r, mut a) = (vec![0.0f32; cfg.n_range], vec![0.0f32; cfg.n_azimuth]);
//! let stats = describe(points, &cfg, &mut scratch, &mut r, &mut a).unwrap();
//! assert_eq!(stats.n_kept, 3);
//! ```
// Unit tests run under the test harness, which needs `std` anyway: they keep its prelude (`vec!`,
// `Vec`) under every feature set.
#![cfg_attr(not(any(feature = "std", test)), no_std)]
#![deny(missing_docs)]
#![deny(unsafe_code)] // exceptions: each marked `#[allow(unsafe_code)]` with a SAFETY note

#[cfg(feature = "alloc")]
extern crate alloc;

pub mod angle;
#[cfg(feature = "alloc")]
mod checksum;
mod compare;
mod config;
#[cfg(feature = "alloc")]
pub mod db;
mod describe;
#[cfg(feature = "alloc")]
pub mod detector;
mod error;
#[cfg(feature = "alloc")]
pub mod eval;
pub mod lzf;
mod math;
pub mod params;
// The crate's thread pools: crate-private, except with the feature `unstable-internals`
// (outside semver, for the Python module's `describe_batch` workers).
#[cfg(all(feature = "parallel", feature = "unstable-internals"))]
#[doc(hidden)]
pub mod pool;
#[cfg(all(feature = "parallel", not(feature = "unstable-internals")))]
pub(crate) mod pool;
#[cfg(feature = "alloc")]
pub mod reg;
pub mod search;

/// The specification of what this crate computes (the repository's `docs/spec.md`).
///
/// Doc comments cite it as "spec §n". It contains no code: it is here so that it ships with the
/// crate and reads on docs.rs.
#[doc = include_str!("../spec.md")]
pub mod spec {}

#[cfg(feature = "alloc")]
mod owned;

/// The project README's Rust examples, compiled as doctests.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;

/// The crate README's examples (what crates.io shows), compiled as doctests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct CrateReadmeDoctests;

pub use compare::{
    aligned_distance, cosine_distance, heading, heading_minima, heading_refined, Heading,
    MAX_MINIMA,
};
pub use config::{Config, Preset, LOOP_THRESHOLD_MEASUREMENT, MAX_VOXELS_PER_AXIS, PRESETS};
pub use describe::{describe, describe_scratch_len, stages, Coord, Points, Scratch, Stats};
pub use error::Error;
#[cfg(feature = "alloc")]
pub use owned::{Describer, Descriptor};
