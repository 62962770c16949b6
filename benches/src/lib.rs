//! Shared helpers of the criterion benchmarks: locating and reading the shared scans.

use std::path::PathBuf;

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
