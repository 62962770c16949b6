//! Shared helpers of the criterion benchmarks: locating and reading the shared scans.

use std::path::{Path, PathBuf};

/// `SOLID_SHARED`, else `<repo>/../shared`.
pub fn shared_dir() -> PathBuf {
    match std::env::var_os("SOLID_SHARED") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared"),
    }
}

/// A KITTI `.bin` (float32 N×4) under `shared/data/`, as its flat array.
///
/// # Panics
/// When the file is missing or not a whole number of 16-byte records: benchmarks need the data.
pub fn kitti(rel: &str) -> Vec<f32> {
    let path = shared_dir().join("data").join(rel);
    let bytes = std::fs::read(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (benchmarks need ../shared/data)", path.display()));
    assert_eq!(bytes.len() % 16, 0, "{}: truncated", path.display());
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

fn f32_records(bytes: &[u8], record: usize) -> Vec<f32> {
    bytes
        .chunks_exact(record)
        .flat_map(|r| {
            (0..3).map(move |i| f32::from_le_bytes(r[4 * i..4 * i + 4].try_into().unwrap()))
        })
        .collect()
}

/// x, y, z of a shared scan (the formats of shared/data/README.md).
///
/// # Panics
/// When the file is missing or not in one of those formats: benchmarks need the data.
pub fn read_xyz(path: &Path) -> Vec<f32> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let name = path.to_string_lossy();
    if name.ends_with(".pcd") {
        let marker = b"DATA binary\n";
        let at = bytes
            .windows(marker.len())
            .position(|w| w == marker)
            .expect("binary PCD");
        let header = std::str::from_utf8(&bytes[..at]).unwrap();
        let field = |key: &str| -> Vec<&str> {
            header
                .lines()
                .find(|l| l.starts_with(key))
                .unwrap()
                .split_whitespace()
                .skip(1)
                .collect()
        };
        let rec = 4 * field("FIELDS").len();
        let n: usize = field("POINTS")[0].parse().unwrap();
        f32_records(&bytes[at + marker.len()..at + marker.len() + n * rec], rec)
    } else if name.contains("helipr_avia") {
        f32_records(&bytes, 19)
    } else if name.contains("nclt") {
        bytes
            .chunks_exact(8)
            .flat_map(|r| {
                (0..3).map(move |i| {
                    (f64::from(u16::from_le_bytes([r[2 * i], r[2 * i + 1]])) * 0.005 - 100.0) as f32
                })
            })
            .collect()
    } else {
        f32_records(&bytes, 16)
    }
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
