//! Reading the shared scans (the formats of shared/data/README.md): the core's tests and the
//! benchmarks (`benches/src/lib.rs` includes this file) read them with this one reader.

/// x, y, z rows of a shared scan as `f32` (exact for the float32 formats).
pub fn read_xyz_f32(path: &std::path::Path) -> Vec<f32> {
    read_scan(path).into_iter().map(|v| v as f32).collect()
}

fn f32s(bytes: &[u8], record: usize, n_fields: usize) -> Vec<f32> {
    assert_eq!(bytes.len() % record, 0, "truncated file");
    bytes
        .chunks_exact(record)
        .flat_map(|r| {
            (0..n_fields).map(move |f| f32::from_le_bytes(r[4 * f..4 * f + 4].try_into().unwrap()))
        })
        .collect()
}

/// A scan as f64 x, y, z rows (stride 3), whatever its file format.
pub fn read_scan(path: &std::path::Path) -> Vec<f64> {
    let bytes = std::fs::read(path).unwrap();
    let name = path.to_string_lossy();
    let xyz: Vec<f32> = if name.ends_with(".pcd") {
        let marker = b"DATA binary\n";
        let at = bytes
            .windows(marker.len())
            .position(|w| w == marker)
            .expect("binary PCD");
        let header = std::str::from_utf8(&bytes[..at]).unwrap();
        let fields = header
            .lines()
            .find(|l| l.starts_with("FIELDS"))
            .unwrap()
            .split_whitespace()
            .count()
            - 1;
        let body = &bytes[at + marker.len()..];
        let all = f32s(body, 4 * fields, fields);
        all.chunks_exact(fields)
            .flat_map(|p| p[..3].to_vec())
            .collect()
    } else if name.contains("helipr_aeva") {
        f32s(&bytes, 29, 3)
    } else if name.contains("helipr_avia") {
        f32s(&bytes, 19, 3)
    } else if name.contains("nclt") {
        assert_eq!(bytes.len() % 8, 0);
        return bytes
            .chunks_exact(8)
            .flat_map(|r| {
                (0..3).map(move |i| {
                    f64::from(u16::from_le_bytes([r[2 * i], r[2 * i + 1]])) * 0.005 - 100.0
                })
            })
            .collect();
    } else {
        let all = f32s(&bytes, 16, 4);
        all.chunks_exact(4).flat_map(|p| p[..3].to_vec()).collect()
    };
    xyz.into_iter().map(f64::from).collect()
}

/// A KITTI `.bin` as its raw float32 N×4 array.
pub fn read_kitti(path: &std::path::Path) -> Vec<f32> {
    f32s(&std::fs::read(path).unwrap(), 16, 4)
}
