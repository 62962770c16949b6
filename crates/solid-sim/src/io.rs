//! Writing simulated sequences in the KITTI odometry layout.

use crate::error::{check, SimError};
use crate::pose::Pose;
use crate::sensor::Sensor;
use crate::trajectory::Trajectory;
use crate::world::World;
use std::fs;
use std::io::Write;
use std::path::Path;

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename, so a reader
/// never sees a half-written file.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), SimError> {
    // Only a regular file is ever replaced: a FIFO, a device or a folder there is refused.
    if let Ok(m) = fs::metadata(path) {
        if !m.is_file() {
            return Err(SimError::Io(std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                format!(
                    "{}: exists and is not a regular file: refusing to replace it",
                    path.display()
                ),
            )));
        }
    }
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = std::path::PathBuf::from(tmp);
    {
        let mut f = fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
    }
    fs::rename(&tmp, path)?;
    Ok(())
}

fn scan_bytes(points: &[[f32; 4]]) -> Vec<u8> {
    let mut out = Vec::with_capacity(points.len() * 16);
    for p in points {
        for v in p {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

/// Writes `poses` to the file `path` in the KITTI layout (one row-major 3×4 matrix per line, 12
/// numbers), through a temporary file and a rename: the simulator writes the truth as
/// `poses.txt` and a drifting odometry ([`crate::Trajectory::odometry`]) as `odometry.txt`.
///
/// # Errors
/// [`SimError::Io`] on I/O failure.
pub fn write_poses(path: &Path, poses: &[Pose]) -> Result<(), SimError> {
    let mut text = String::with_capacity(poses.len() * 200);
    for p in poses {
        let line: Vec<String> = p.m.iter().map(|v| format!("{v:.12e}")).collect();
        text.push_str(&line.join(" "));
        text.push('\n');
    }
    write_atomic(path, text.as_bytes())
}

fn write_meta(dir: &Path, poses: &[Pose], times: &[f64]) -> Result<(), SimError> {
    write_poses(&dir.join("poses.txt"), poses)?;
    let mut text = String::with_capacity(times.len() * 20);
    for t in times {
        text.push_str(&format!("{t:.6e}\n"));
    }
    write_atomic(&dir.join("times.txt"), text.as_bytes())
}

/// Writes already simulated scans as a KITTI-layout folder: `velodyne/NNNNNN.bin` (little-endian
/// float32 N×4: x, y, z, intensity in the sensor frame), `poses.txt` (one row-major 3×4
/// `T_world_sensor` per line, 12 numbers) and `times.txt` (seconds). Every file is written to a
/// temporary name and renamed. Returns the number of frames written.
///
/// # Errors
/// [`SimError::InvalidParameter`] when the three lengths differ; [`SimError::Io`] on I/O failure.
pub fn write_scans(
    dir: &Path,
    scans: &[Vec<[f32; 4]>],
    poses: &[Pose],
    times: &[f64],
) -> Result<usize, SimError> {
    let n = scans.len();
    check(
        "poses",
        poses.len() as f64,
        poses.len() == n && times.len() == n,
        "one pose and one time per scan",
    )?;
    let vel = dir.join("velodyne");
    fs::create_dir_all(&vel)?;
    for (i, s) in scans.iter().enumerate() {
        write_atomic(&vel.join(format!("{i:06}.bin")), &scan_bytes(s))?;
    }
    write_meta(dir, poses, times)?;
    Ok(n)
}

/// Simulates `sensor` along `trajectory` in `world` (frame `i` uses noise frame index `i`) and
/// writes the result like [`write_scans`], one scan at a time. `progress` is called after each
/// frame with (frames done, total). Returns the number of frames written.
///
/// # Errors
/// As [`Sensor::scan`] and [`write_scans`].
pub fn write_sequence(
    dir: &Path,
    world: &World,
    sensor: &Sensor,
    trajectory: &Trajectory,
    mut progress: impl FnMut(usize, usize),
) -> Result<usize, SimError> {
    sensor.validate()?;
    let n = trajectory.poses.len();
    check(
        "times",
        trajectory.times.len() as f64,
        trajectory.times.len() == n,
        "one time per pose",
    )?;
    let vel = dir.join("velodyne");
    fs::create_dir_all(&vel)?;
    for (i, pose) in trajectory.poses.iter().enumerate() {
        let pts = sensor.scan(world, pose, i as u64)?;
        write_atomic(&vel.join(format!("{i:06}.bin")), &scan_bytes(&pts))?;
        progress(i + 1, n);
    }
    write_meta(dir, &trajectory.poses, &trajectory.times)?;
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectory::RouteOptions;

    #[test]
    fn writes_kitti_layout() {
        let dir = std::env::temp_dir().join(format!("solid-lidar-sim-io-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        let world = World::city(0, 2);
        let mut traj = Trajectory::figure_eight(
            &world,
            &RouteOptions {
                spacing: 5.0,
                ..RouteOptions::default()
            },
        )
        .unwrap();
        traj.poses.truncate(3);
        traj.times.truncate(3);
        let sensor = Sensor::preset("vlp16").unwrap();
        let mut calls = 0;
        assert_eq!(
            write_sequence(&dir, &world, &sensor, &traj, |_, _| calls += 1).unwrap(),
            3
        );
        assert_eq!(calls, 3);
        let bin = fs::read(dir.join("velodyne/000001.bin")).unwrap();
        let expected = sensor.scan(&world, &traj.poses[1], 1).unwrap();
        assert_eq!(bin.len(), expected.len() * 16);
        assert_eq!(
            f32::from_le_bytes(bin[16..20].try_into().unwrap()),
            expected[1][0]
        );
        let poses = fs::read_to_string(dir.join("poses.txt")).unwrap();
        let lines: Vec<&str> = poses.lines().collect();
        assert_eq!(lines.len(), 3);
        let nums: Vec<f64> = lines[2]
            .split_whitespace()
            .map(|s| s.parse().unwrap())
            .collect();
        assert_eq!(nums.len(), 12);
        for (a, b) in nums.iter().zip(traj.poses[2].m) {
            assert!((a - b).abs() <= 1e-11 * b.abs().max(1.0));
        }
        assert_eq!(
            fs::read_to_string(dir.join("times.txt"))
                .unwrap()
                .lines()
                .count(),
            3
        );
        assert!(fs::read_dir(dir.join("velodyne")).unwrap().all(|e| !e
            .unwrap()
            .file_name()
            .to_string_lossy()
            .ends_with(".tmp")));
        fs::remove_dir_all(&dir).unwrap();
    }

    /// Issue 39: a writer never replaces what it did not write (a FIFO of the test's own making
    /// here; a device or a folder alike).
    #[cfg(unix)]
    #[test]
    fn never_replaces_what_is_not_a_regular_file() {
        use std::os::unix::fs::FileTypeExt;
        let dir = std::env::temp_dir().join(format!("solid-lidar-sim-fifo-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let fifo = dir.join("poses.txt");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            eprintln!("skipped: no mkfifo");
            return;
        }
        let err = write_poses(&fifo, &[]).unwrap_err();
        assert!(err.to_string().contains("refusing to replace it"), "{err}");
        assert!(fs::metadata(&fifo).unwrap().file_type().is_fifo());
        fs::remove_dir_all(&dir).unwrap();
    }
}
