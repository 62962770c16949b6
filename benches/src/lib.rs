//! Shared helpers of the criterion benchmarks: locating and reading the shared scans.

use std::path::{Path, PathBuf};

/// `SOLID_SHARED`, else `<repo>/../shared`.
pub fn shared_dir() -> PathBuf {
    match std::env::var_os("SOLID_SHARED") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared"),
    }
}

// The shared scans' formats: the core's test reader, one reader for the tests and the benches.
#[path = "../../crates/solid-core/tests/common/scan.rs"]
mod scan;

/// A KITTI `.bin` (float32 N×4) under `shared/data/`, as its flat array.
///
/// # Panics
/// When the file is missing or not a whole number of 16-byte records: benchmarks need the data.
pub fn kitti(rel: &str) -> Vec<f32> {
    let path = shared_dir().join("data").join(rel);
    assert!(
        path.is_file(),
        "{}: missing (benchmarks need ../shared/data)",
        path.display()
    );
    scan::read_kitti(&path)
}

/// x, y, z of a shared scan (the formats of shared/data/README.md).
///
/// # Panics
/// When the file is missing or not in one of those formats: benchmarks need the data.
pub fn read_xyz(path: &Path) -> Vec<f32> {
    scan::read_xyz_f32(path)
}

/// splitmix64: a small seeded generator, so that every run benchmarks the same data.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// A standard normal value (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let (u, v) = (self.unit().max(1e-300), self.unit());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}
