//! Bindings of the LiDAR simulator (`solid-lidar-sim`), exposed as private `_sim_*` functions and
//! `_SimWorld` / `_SimSensor` classes; the typed API is `solid.sim` (python/solid/sim.py).

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use solid_lidar_sim::{
    CorridorConfig, DriftOptions, Layout, Pose, RoomConfig, RouteOptions, Sensor, Trajectory,
    TurnOptions, World, WorldConfig,
};
use std::path::PathBuf;

use crate::args;
use crate::errors::{core_err, ConfigError, SolidError};

/// A generated world (immutable).
#[pyclass(name = "_SimWorld", module = "solid._solid", frozen)]
pub struct PySimWorld {
    inner: World,
}

#[pymethods]
impl PySimWorld {
    /// Seed the world was generated from.
    #[getter]
    fn seed(&self) -> u64 {
        self.inner.config().seed
    }
    /// Number of blocks per side inside the road grid.
    #[getter]
    fn blocks(&self) -> usize {
        self.inner.config().blocks
    }
    /// Distance between parallel roads, metres.
    #[getter]
    fn block_pitch(&self) -> f64 {
        self.inner.config().block_pitch
    }
    /// Road centreline coordinates.
    #[getter]
    fn roads(&self) -> Vec<f64> {
        self.inner.roads().to_vec()
    }
    /// Extent of the objects (xmin, ymin, xmax, ymax).
    #[getter]
    fn bounds(&self) -> (f64, f64, f64, f64) {
        let b = self.inner.bounds();
        (b[0], b[1], b[2], b[3])
    }
    /// Which generator made the world: "city", "corridors" or "room".
    #[getter]
    fn layout(&self) -> &'static str {
        match self.inner.layout() {
            Layout::Corridors(_) => "corridors",
            Layout::Room(_) => "room",
            _ => "city",
        }
    }
    /// Number of primitives.
    fn __len__(&self) -> usize {
        self.inner.primitives().len()
    }
    /// Ground height at (x, y).
    fn ground_height(&self, x: f64, y: f64) -> f64 {
        self.inner.ground_height(x, y)
    }
    /// (kinds, footprints (P, 4) float64 [xmin, ymin, xmax, ymax], tops (P,) float64).
    #[allow(clippy::type_complexity)]
    fn footprints<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(
        Vec<&'static str>,
        Bound<'py, PyAny>,
        Bound<'py, PyArray1<f64>>,
    )> {
        let prims = self.inner.primitives();
        let kinds = prims.iter().map(|p| p.kind.name()).collect();
        let fp: Vec<f64> = prims.iter().flat_map(|p| p.shape.footprint()).collect();
        let tops: Vec<f64> = prims.iter().map(|p| p.shape.top()).collect();
        let fp = PyArray1::from_vec(py, fp).reshape([prims.len(), 4])?;
        Ok((kinds, fp.into_any(), PyArray1::from_vec(py, tops)))
    }
    fn __repr__(&self) -> String {
        let c = self.inner.config();
        format!(
            "_SimWorld(layout={:?}, seed={}, blocks={}, block_pitch={}, primitives={})",
            self.layout(),
            c.seed,
            c.blocks,
            c.block_pitch,
            self.inner.primitives().len()
        )
    }
}

/// A sensor model (immutable).
#[pyclass(name = "_SimSensor", module = "solid._solid", frozen)]
pub struct PySimSensor {
    inner: Sensor,
}

#[pymethods]
impl PySimSensor {
    /// Model name.
    #[getter]
    fn name(&self) -> String {
        self.inner.name.clone()
    }
    /// Horizontal window width, degrees.
    #[getter]
    fn h_fov(&self) -> f64 {
        self.inner.h_fov_deg
    }
    /// Horizontal window centre, degrees.
    #[getter]
    fn h_centre(&self) -> f64 {
        self.inner.h_centre_deg
    }
    /// Minimum range, metres.
    #[getter]
    fn min_range(&self) -> f64 {
        self.inner.min_range
    }
    /// Maximum range, metres.
    #[getter]
    fn max_range(&self) -> f64 {
        self.inner.max_range
    }
    /// Range noise standard deviation, metres.
    #[getter]
    fn noise(&self) -> f64 {
        self.inner.range_noise_sd
    }
    /// Dropout probability.
    #[getter]
    fn dropout(&self) -> f64 {
        self.inner.dropout
    }
    /// Noise seed.
    #[getter]
    fn seed(&self) -> u64 {
        self.inner.noise_seed
    }
    /// (fov_down, fov_up) of the beams in degrees.
    #[getter]
    fn vertical_fov(&self) -> (f64, f64) {
        match &self.inner.pattern {
            solid_lidar_sim::Pattern::Spinning { elevations_deg, .. } => {
                let lo = elevations_deg.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = elevations_deg
                    .iter()
                    .copied()
                    .fold(f64::NEG_INFINITY, f64::max);
                (lo, hi)
            }
            solid_lidar_sim::Pattern::Rosette {
                half_height_deg, ..
            } => (-half_height_deg, *half_height_deg),
        }
    }
    /// Number of beams (spinning) or emitters (rosette).
    #[getter]
    fn channels(&self) -> usize {
        match &self.inner.pattern {
            solid_lidar_sim::Pattern::Spinning { elevations_deg, .. } => elevations_deg.len(),
            solid_lidar_sim::Pattern::Rosette { emitters, .. } => *emitters,
        }
    }
    /// Rays fired in frame `frame` (after the horizontal window).
    #[pyo3(signature = (frame = 0))]
    fn n_rays(&self, #[pyo3(from_py_with = args::frame)] frame: u64) -> usize {
        self.inner.ray_directions(frame).len()
    }
    fn __repr__(&self) -> String {
        let s = &self.inner;
        format!(
            "_SimSensor(name={:?}, h_fov={}, h_centre={}, max_range={}, noise={}, dropout={}, seed={})",
            s.name, s.h_fov_deg, s.h_centre_deg, s.max_range, s.range_noise_sd, s.dropout, s.noise_seed
        )
    }
}

#[pyfunction]
#[pyo3(signature = (seed = 0, blocks = 4, block_pitch = 80.0, road_half_width = 7.0, slope = (0.01, -0.006), repetition = 0.3, cell_size = 4.0))]
#[allow(clippy::too_many_arguments)]
fn _sim_world(
    py: Python<'_>,
    #[pyo3(from_py_with = args::seed)] seed: u64,
    #[pyo3(from_py_with = args::blocks)] blocks: usize,
    block_pitch: f64,
    road_half_width: f64,
    slope: (f64, f64),
    repetition: f64,
    cell_size: f64,
) -> PyResult<PySimWorld> {
    let cfg = WorldConfig {
        seed,
        blocks,
        block_pitch,
        road_half_width,
        slope: [slope.0, slope.1],
        repetition,
        cell_size,
    };
    let inner = py.detach(|| World::new(cfg)).map_err(core_err)?;
    Ok(PySimWorld { inner })
}

/// A count argument of the indoor worlds (the simulator checks the range).
fn count(name: &'static str) -> impl Fn(&Bound<'_, PyAny>) -> PyResult<usize> {
    move |v| args::int_arg(v, name, 0, usize::MAX as i128)
}

fn modules(v: &Bound<'_, PyAny>) -> PyResult<usize> {
    count("modules")(v)
}

fn furniture(v: &Bound<'_, PyAny>) -> PyResult<usize> {
    count("furniture")(v)
}

#[pyfunction]
#[pyo3(signature = (seed = 0, blocks = 1, modules = 4, module_length = 45.0, width = 6.0, height = 3.0, jitter = 0.15, dropout = 0.1, cell_size = 4.0))]
#[allow(clippy::too_many_arguments)]
fn _sim_corridor_world(
    py: Python<'_>,
    #[pyo3(from_py_with = args::seed)] seed: u64,
    #[pyo3(from_py_with = args::blocks)] blocks: usize,
    #[pyo3(from_py_with = modules)] modules: usize,
    module_length: f64,
    width: f64,
    height: f64,
    jitter: f64,
    dropout: f64,
    cell_size: f64,
) -> PyResult<PySimWorld> {
    let cfg = CorridorConfig {
        seed,
        blocks,
        modules,
        module_length,
        width,
        height,
        jitter,
        dropout,
        cell_size,
    };
    let inner = py.detach(|| World::corridors(cfg)).map_err(core_err)?;
    Ok(PySimWorld { inner })
}

#[pyfunction]
#[pyo3(signature = (seed = 0, size = (6.0, 4.5), height = 2.6, furniture = 8, cell_size = 1.0))]
fn _sim_room_world(
    py: Python<'_>,
    #[pyo3(from_py_with = args::seed)] seed: u64,
    size: (f64, f64),
    height: f64,
    #[pyo3(from_py_with = furniture)] furniture: usize,
    cell_size: f64,
) -> PyResult<PySimWorld> {
    let cfg = RoomConfig {
        seed,
        size: [size.0, size.1],
        height,
        furniture,
        cell_size,
    };
    let inner = py.detach(|| World::room(cfg)).map_err(core_err)?;
    Ok(PySimWorld { inner })
}

#[pyfunction]
#[pyo3(signature = (name, h_fov = None, h_centre = 0.0, min_range = None, max_range = None, noise = None, dropout = 0.0, seed = 0, points = None))]
#[allow(clippy::too_many_arguments)]
fn _sim_sensor(
    name: &str,
    h_fov: Option<f64>,
    h_centre: f64,
    min_range: Option<f64>,
    max_range: Option<f64>,
    noise: Option<f64>,
    dropout: f64,
    #[pyo3(from_py_with = args::seed)] seed: u64,
    #[pyo3(from_py_with = args::points)] points: Option<usize>,
) -> PyResult<PySimSensor> {
    let mut s = Sensor::preset(name).map_err(core_err)?;
    if let Some(w) = h_fov {
        s.h_fov_deg = w;
    }
    s.h_centre_deg = h_centre;
    if let Some(r) = min_range {
        s.min_range = r;
    }
    if let Some(r) = max_range {
        s.max_range = r;
    }
    if let Some(n) = noise {
        s.range_noise_sd = n;
    }
    s.dropout = dropout;
    s.noise_seed = seed;
    if let Some(n) = points {
        match &mut s.pattern {
            solid_lidar_sim::Pattern::Rosette { points, .. } => *points = n,
            solid_lidar_sim::Pattern::Spinning { .. } => {
                return Err(ConfigError::new_err(
                    "points applies to the rosette (avia) sensor only",
                ))
            }
        }
    }
    s.validate().map_err(core_err)?;
    Ok(PySimSensor { inner: s })
}

/// Reads a (M, 3, 4) or (3, 4) float64 C-contiguous array as poses.
fn read_poses(poses: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<Vec<Pose>> {
    let shape = poses.shape();
    let ok = (shape.len() == 3 && shape[1] == 3 && shape[2] == 4)
        || (shape.len() == 2 && shape == [3, 4]);
    if !ok || !poses.is_c_contiguous() {
        return Err(SolidError::new_err(format!(
            "poses must be a C-contiguous float64 array of shape (M, 3, 4) or (3, 4), got shape {shape:?}"
        )));
    }
    let data = poses
        .as_slice()
        .map_err(|e| SolidError::new_err(e.to_string()))?;
    let mut out = args::try_vec(data.len() / 12, "poses")?;
    for chunk in data.chunks_exact(12) {
        if chunk.iter().any(|v| !v.is_finite()) {
            return Err(ConfigError::new_err("poses must be finite"));
        }
        let mut m = [0.0; 12];
        m.copy_from_slice(chunk);
        out.push(Pose { m });
    }
    Ok(out)
}

fn points_array<'py>(py: Python<'py>, pts: Vec<[f32; 4]>) -> PyResult<Bound<'py, PyAny>> {
    let n = pts.len();
    let mut flat = args::try_vec(n.saturating_mul(4), "scan points")?;
    flat.extend(pts.into_iter().flatten());
    Ok(PyArray1::from_vec(py, flat).reshape([n, 4])?.into_any())
}

/// A path as Python receives it: the poses, (m, 4, 4), and their times.
type PathArrays<'py> = (Bound<'py, PyAny>, Bound<'py, PyArray1<f64>>);

/// How a route is driven, from the keywords of `_sim_trajectory` and `_sim_route`.
fn route_options(
    spacing: f64,
    lane_offset: f64,
    corner_radius: f64,
    speed: f64,
    mount_height: f64,
) -> RouteOptions {
    RouteOptions {
        spacing,
        lane_offset,
        corner_radius,
        speed,
        mount_height,
    }
}

fn trajectory_arrays(py: Python<'_>, t: Trajectory) -> PyResult<PathArrays<'_>> {
    let m = t.poses.len();
    let mut flat = args::try_vec(m.saturating_mul(12), "trajectory poses")?;
    flat.extend(t.poses.iter().flat_map(|p| p.m));
    let poses = PyArray1::from_vec(py, flat).reshape([m, 3, 4])?.into_any();
    Ok((poses, PyArray1::from_vec(py, t.times)))
}

#[pyfunction]
#[pyo3(signature = (world, sensor, pose, frame = 0))]
fn _sim_scan<'py>(
    py: Python<'py>,
    world: &Bound<'py, PySimWorld>,
    sensor: &Bound<'py, PySimSensor>,
    pose: PyReadonlyArrayDyn<'py, f64>,
    #[pyo3(from_py_with = args::frame)] frame: u64,
) -> PyResult<Bound<'py, PyAny>> {
    let poses = read_poses(&pose)?;
    if poses.len() != 1 {
        return Err(SolidError::new_err("pose must have shape (3, 4)"));
    }
    let (w, s) = (world.get(), sensor.get());
    let pts = py
        .detach(|| s.inner.scan(&w.inner, &poses[0], frame))
        .map_err(core_err)?;
    points_array(py, pts)
}

#[pyfunction]
#[pyo3(signature = (world, sensor, poses, first_frame = 0))]
fn _sim_scans<'py>(
    py: Python<'py>,
    world: &Bound<'py, PySimWorld>,
    sensor: &Bound<'py, PySimSensor>,
    poses: PyReadonlyArrayDyn<'py, f64>,
    #[pyo3(from_py_with = args::first_frame)] first_frame: u64,
) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let poses = read_poses(&poses)?;
    let (w, s) = (world.get(), sensor.get());
    let scans = py
        .detach(|| {
            poses
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    s.inner
                        .scan(&w.inner, p, first_frame.wrapping_add(i as u64))
                })
                .collect::<Result<Vec<_>, _>>()
        })
        .map_err(core_err)?;
    scans.into_iter().map(|p| points_array(py, p)).collect()
}

#[pyfunction]
#[pyo3(signature = (world, kind, spacing = 1.0, laps = 1.0, lane_offset = 1.75, corner_radius = 8.0, speed = 10.0, mount_height = 1.73))]
#[allow(clippy::too_many_arguments)]
fn _sim_trajectory<'py>(
    py: Python<'py>,
    world: &Bound<'py, PySimWorld>,
    kind: &str,
    spacing: f64,
    laps: f64,
    lane_offset: f64,
    corner_radius: f64,
    speed: f64,
    mount_height: f64,
) -> PyResult<PathArrays<'py>> {
    let opts = route_options(spacing, lane_offset, corner_radius, speed, mount_height);
    let t = Trajectory::by_name(&world.get().inner, kind, laps, &opts).map_err(core_err)?;
    trajectory_arrays(py, t)
}

#[pyfunction]
#[pyo3(signature = (world, waypoints, spacing = 1.0, lane_offset = 1.75, corner_radius = 8.0, speed = 10.0, mount_height = 1.73))]
#[allow(clippy::too_many_arguments)]
fn _sim_route<'py>(
    py: Python<'py>,
    world: &Bound<'py, PySimWorld>,
    waypoints: Vec<(f64, f64)>,
    spacing: f64,
    lane_offset: f64,
    corner_radius: f64,
    speed: f64,
    mount_height: f64,
) -> PyResult<PathArrays<'py>> {
    let opts = route_options(spacing, lane_offset, corner_radius, speed, mount_height);
    let wps: Vec<[f64; 2]> = waypoints.into_iter().map(|(x, y)| [x, y]).collect();
    let t = Trajectory::from_waypoints(&world.get().inner, &wps, &opts).map_err(core_err)?;
    trajectory_arrays(py, t)
}

#[pyfunction]
#[pyo3(signature = (world, x, y, headings, mount_height = 1.73))]
fn _sim_spin<'py>(
    py: Python<'py>,
    world: &Bound<'py, PySimWorld>,
    x: f64,
    y: f64,
    headings: Vec<f64>,
    mount_height: f64,
) -> PyResult<PathArrays<'py>> {
    if !(x.is_finite() && y.is_finite() && mount_height.is_finite())
        || headings.iter().any(|h| !h.is_finite())
    {
        return Err(ConfigError::new_err(
            "x, y, headings and mount_height must be finite",
        ));
    }
    let t = Trajectory::spin(&world.get().inner, x, y, &headings, mount_height);
    trajectory_arrays(py, t)
}

#[pyfunction]
#[pyo3(signature = (world, x, y, start = 0.0, sweep = 330.0, step = 2.0, wobble = 0.0, seed = 0, mount_height = 1.2, period = 0.1))]
#[allow(clippy::too_many_arguments)]
fn _sim_turn<'py>(
    py: Python<'py>,
    world: &Bound<'py, PySimWorld>,
    x: f64,
    y: f64,
    start: f64,
    sweep: f64,
    step: f64,
    wobble: f64,
    #[pyo3(from_py_with = args::seed)] seed: u64,
    mount_height: f64,
    period: f64,
) -> PyResult<PathArrays<'py>> {
    let opts = TurnOptions {
        start_deg: start,
        sweep_deg: sweep,
        step_deg: step,
        wobble,
        seed,
        mount_height,
        period_s: period,
    };
    let t = Trajectory::turn_in_place(&world.get().inner, x, y, &opts).map_err(core_err)?;
    trajectory_arrays(py, t)
}

#[pyfunction]
#[pyo3(signature = (poses, times, yaw_bias_deg_per_m = 0.0, yaw_bias_deg_per_frame = 0.0, scale_error = 0.0, translation_noise = 0.0, rotation_noise_deg = 0.0, seed = 0, breakdown = None, breakdown_jump_m = 0.0, breakdown_climb_m = 0.0))]
#[allow(clippy::too_many_arguments)]
fn _sim_odometry<'py>(
    py: Python<'py>,
    poses: PyReadonlyArrayDyn<'py, f64>,
    times: Vec<f64>,
    yaw_bias_deg_per_m: f64,
    yaw_bias_deg_per_frame: f64,
    scale_error: f64,
    translation_noise: f64,
    rotation_noise_deg: f64,
    #[pyo3(from_py_with = args::seed)] seed: u64,
    breakdown: Option<(usize, usize)>,
    breakdown_jump_m: f64,
    breakdown_climb_m: f64,
) -> PyResult<PathArrays<'py>> {
    // None: no breakdown (a tuple default would not read back in the signature stubtest checks).
    let breakdown = breakdown.unwrap_or((0, 0));
    let truth = Trajectory {
        poses: read_poses(&poses)?,
        times,
    };
    let opts = DriftOptions {
        yaw_bias_deg_per_m,
        yaw_bias_deg_per_frame,
        scale_error,
        translation_noise,
        rotation_noise_deg,
        seed,
        breakdown: [breakdown.0, breakdown.1],
        breakdown_jump_m,
        breakdown_climb_m,
    };
    let t = py.detach(|| truth.odometry(&opts)).map_err(core_err)?;
    trajectory_arrays(py, t)
}

#[pyfunction]
#[pyo3(signature = (poses, frame))]
fn _sim_in_frame<'py>(
    py: Python<'py>,
    poses: PyReadonlyArrayDyn<'py, f64>,
    frame: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Bound<'py, PyAny>> {
    let frame = read_poses(&frame)?;
    if frame.len() != 1 {
        return Err(SolidError::new_err("frame must have shape (3, 4)"));
    }
    let traj = Trajectory {
        poses: read_poses(&poses)?,
        times: Vec::new(),
    };
    Ok(trajectory_arrays(py, traj.in_frame(&frame[0]))?.0)
}

#[pyfunction]
#[pyo3(signature = (path, poses))]
fn _sim_write_poses<'py>(
    py: Python<'py>,
    path: PathBuf,
    poses: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<()> {
    let poses = read_poses(&poses)?;
    py.detach(|| solid_lidar_sim::write_poses(&path, &poses))
        .map_err(core_err)
}

#[pyfunction]
#[pyo3(signature = (directory, world, sensor, poses, times))]
fn _sim_write_sequence<'py>(
    py: Python<'py>,
    directory: PathBuf,
    world: &Bound<'py, PySimWorld>,
    sensor: &Bound<'py, PySimSensor>,
    poses: PyReadonlyArrayDyn<'py, f64>,
    times: Vec<f64>,
) -> PyResult<usize> {
    let traj = Trajectory {
        poses: read_poses(&poses)?,
        times,
    };
    let (w, s) = (world.get(), sensor.get());
    py.detach(|| solid_lidar_sim::write_sequence(&directory, &w.inner, &s.inner, &traj, |_, _| {}))
        .map_err(core_err)
}

#[pyfunction]
#[pyo3(signature = (directory, scans, poses, times))]
fn _sim_write_scans<'py>(
    py: Python<'py>,
    directory: PathBuf,
    scans: Vec<PyReadonlyArrayDyn<'py, f32>>,
    poses: PyReadonlyArrayDyn<'py, f64>,
    times: Vec<f64>,
) -> PyResult<usize> {
    let poses = read_poses(&poses)?;
    let mut owned: Vec<Vec<[f32; 4]>> = Vec::with_capacity(scans.len());
    for (i, s) in scans.iter().enumerate() {
        let shape = s.shape();
        if shape.len() != 2 || shape[1] != 4 || !s.is_c_contiguous() {
            return Err(SolidError::new_err(format!(
                "scan {i} must be a C-contiguous float32 array of shape (N, 4), got {shape:?}"
            )));
        }
        let data = s
            .as_slice()
            .map_err(|e| SolidError::new_err(e.to_string()))?;
        owned.push(
            data.chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect(),
        );
    }
    py.detach(|| solid_lidar_sim::write_scans(&directory, &owned, &poses, &times))
        .map_err(core_err)
}

/// Adds the simulator's classes and functions to the extension module.
///
/// # Errors
/// Propagates failures of `add_class` / `add_function`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("_SIM_SENSORS", solid_lidar_sim::SENSOR_PRESETS.to_vec())?;
    m.add(
        "_SIM_TRAJECTORIES",
        solid_lidar_sim::TRAJECTORY_KINDS.to_vec(),
    )?;
    m.add_class::<PySimWorld>()?;
    m.add_class::<PySimSensor>()?;
    add_functions! {
        m,
        _sim_world, _sim_sensor, _sim_scan, _sim_scans, _sim_trajectory, _sim_route, _sim_spin,
        _sim_write_sequence, _sim_write_scans, _sim_corridor_world, _sim_room_world, _sim_turn,
        _sim_odometry, _sim_in_frame, _sim_write_poses,
    }
    Ok(())
}
