//! Numpy arrays in and out of the bindings: point and row arrays checked and borrowed for reading
//! without the GIL, query vectors, poses.

use numpy::ndarray::Array2;
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use solid_lidar::reg::Pose;

use crate::errors::SolidError;

/// A point array checked and borrowed for reading without the GIL.
pub enum PointSlice<'a> {
    /// float32 rows.
    F32(&'a [f32], usize),
    /// float64 rows.
    F64(&'a [f64], usize),
}

impl<'a> PointSlice<'a> {
    /// The values as `f32` (float32 read in place, float64 rounded into a copy).
    pub fn to_f32(&self) -> std::borrow::Cow<'a, [f32]> {
        match *self {
            PointSlice::F32(s, _) => std::borrow::Cow::Borrowed(s),
            PointSlice::F64(s, _) => s.iter().map(|&v| v as f32).collect(),
        }
    }
}

/// Keeps the numpy read-only borrow alive while its slice is used.
pub enum Borrowed<'py> {
    /// float32 array.
    F32(numpy::PyReadonlyArray2<'py, f32>),
    /// float64 array.
    F64(numpy::PyReadonlyArray2<'py, f64>),
}

impl Borrowed<'_> {
    /// Number of rows.
    pub fn rows(&self) -> usize {
        match self {
            Borrowed::F32(a) => a.shape()[0],
            Borrowed::F64(a) => a.shape()[0],
        }
    }

    /// The flat slice and its stride.
    pub fn slice(&self) -> PointSlice<'_> {
        match self {
            // Contiguity and alignment were checked in `borrow_2d`.
            Borrowed::F32(a) => {
                PointSlice::F32(a.as_slice().expect("checked C-contiguous"), a.shape()[1])
            }
            Borrowed::F64(a) => {
                PointSlice::F64(a.as_slice().expect("checked C-contiguous"), a.shape()[1])
            }
        }
    }
}

/// Checks a points argument (numpy, 2-D, ≥ 3 columns, float32/float64, C-contiguous, aligned)
/// and borrows it read-only. `what` names the argument in messages.
pub fn borrow_points<'py>(points: &Bound<'py, PyAny>, what: &str) -> PyResult<Borrowed<'py>> {
    borrow_2d(points, what, Columns::AtLeast(3))
}

/// Every scan of a batch checked ([`borrow_points`], named `scans[i]`) and borrowed.
pub fn borrow_scans<'py>(items: &[Bound<'py, PyAny>]) -> PyResult<Vec<Borrowed<'py>>> {
    items
        .iter()
        .enumerate()
        .map(|(i, p)| borrow_points(p, &format!("scans[{i}]")))
        .collect()
}

/// The columns a 2-D array argument must have.
#[derive(Clone, Copy)]
pub enum Columns {
    /// At least this many (points: x, y, z first).
    AtLeast(usize),
    /// Exactly this many (descriptor rows).
    Exactly(usize),
}

/// Checks a 2-D float32/float64 array argument (columns, C-contiguity, alignment) and borrows
/// it read-only. `what` names the argument in messages.
pub fn borrow_2d<'py>(
    points: &Bound<'py, PyAny>,
    what: &str,
    columns: Columns,
) -> PyResult<Borrowed<'py>> {
    let want = match columns {
        Columns::AtLeast(3) => String::from("(N, >=3) with x, y, z first"),
        Columns::AtLeast(c) => format!("(N, >={c})"),
        Columns::Exactly(c) => format!("(N, {c})"),
    };
    let arr = points.cast::<PyUntypedArray>().map_err(|_| {
        let ty = points.get_type().name().map(|n| n.to_string()).unwrap_or_default();
        PyTypeError::new_err(format!(
            "{what} must be a numpy array of shape {want}, got {ty}; convert with np.asarray({what}, dtype=np.float32)"
        ))
    })?;
    let shape = arr.shape().to_vec();
    let fits = shape.len() == 2
        && match columns {
            Columns::AtLeast(c) => shape[1] >= c,
            Columns::Exactly(c) => shape[1] == c,
        };
    if !fits {
        return Err(SolidError::new_err(format!(
            "{what} must have shape {want}; got shape {}",
            fmt_shape(&shape)
        )));
    }
    let borrowed = if let Ok(a) = points.cast::<PyArray2<f32>>() {
        Borrowed::F32(
            a.try_readonly()
                .map_err(|e| SolidError::new_err(format!("{what}: {e}")))?,
        )
    } else if let Ok(a) = points.cast::<PyArray2<f64>>() {
        Borrowed::F64(
            a.try_readonly()
                .map_err(|e| SolidError::new_err(format!("{what}: {e}")))?,
        )
    } else {
        let dt = arr.dtype().str().map(|s| s.to_string()).unwrap_or_default();
        return Err(PyTypeError::new_err(format!(
            "{what} has dtype {dt}; solid reads native float32 or float64: convert with {what}.astype(np.float32)"
        )));
    };
    if !arr.is_c_contiguous() {
        return Err(SolidError::new_err(format!(
            "{what} is not C-contiguous (Fortran-ordered or a strided view); reading it in place would be wrong: pass np.ascontiguousarray({what})"
        )));
    }
    let (ptr, align) = match &borrowed {
        Borrowed::F32(a) => (a.as_array().as_ptr() as usize, std::mem::align_of::<f32>()),
        Borrowed::F64(a) => (a.as_array().as_ptr() as usize, std::mem::align_of::<f64>()),
    };
    if ptr % align != 0 {
        return Err(SolidError::new_err(format!(
            "{what} is not aligned for its dtype; pass np.array({what}) (an aligned copy)"
        )));
    }
    Ok(borrowed)
}

fn fmt_shape(shape: &[usize]) -> String {
    let parts: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    if parts.len() == 1 {
        format!("({},)", parts[0])
    } else {
        format!("({})", parts.join(", "))
    }
}

/// A contiguous 1-D float32/float64 array read directly, as [`PointSlice::to_f32`] reads points;
/// `None` for anything else (read as a sequence then, which makes a numpy scalar of each value).
pub fn contiguous_query(q: &Bound<'_, PyAny>) -> Option<Vec<f32>> {
    if let Ok(a) = q.cast::<PyArray1<f32>>() {
        let a = a.try_readonly().ok()?;
        let v = a.as_slice().ok()?;
        return Some(PointSlice::F32(v, v.len()).to_f32().into_owned());
    }
    let a = q.cast::<PyArray1<f64>>().ok()?.try_readonly().ok()?;
    let v = a.as_slice().ok()?;
    Some(PointSlice::F64(v, v.len()).to_f32().into_owned())
}

/// A pose argument: `None`, 12 floats, or a 3×4 nested sequence / array (row-major `[R|t]`).
pub fn parse_pose(pose: Option<&Bound<'_, PyAny>>) -> PyResult<Option<[f64; 12]>> {
    let Some(p) = pose else { return Ok(None) };
    if p.is_none() {
        return Ok(None);
    }
    let msg =
        "pose must be None, 12 floats, or a 3x4 or 4x4 array (row-major [R|t], T_world_sensor)";
    let bad = |m: String| SolidError::new_err(m);
    let flat: Vec<f64> = match p.extract::<Vec<Vec<f64>>>() {
        Ok(rows) if rows.len() == 3 && rows.iter().all(|r| r.len() == 4) => {
            rows.into_iter().flatten().collect()
        }
        Ok(rows) if rows.len() == 4 && rows.iter().all(|r| r.len() == 4) => {
            if rows[3] != [0.0, 0.0, 0.0, 1.0] {
                return Err(bad(format!(
                    "a 4x4 pose must end with the row [0, 0, 0, 1], got {:?}",
                    rows[3]
                )));
            }
            rows.into_iter().take(3).flatten().collect()
        }
        Ok(_) => return Err(bad(msg.to_string())),
        Err(_) => p.extract::<Vec<f64>>().map_err(|_| bad(msg.to_string()))?,
    };
    let arr: [f64; 12] = flat
        .try_into()
        .map_err(|v: Vec<f64>| bad(format!("{msg}; got {} values", v.len())))?;
    Ok(Some(arr))
}

/// Per-entry poses of a batch: `None`, or a float64 array of shape (N, 3, 4), (N, 4, 4) (last
/// row 0, 0, 0, 1) or (N, 12), row-major `[R|t]`.
pub fn parse_poses(poses: Option<&Bound<'_, PyAny>>, n: usize) -> PyResult<Option<Vec<[f64; 12]>>> {
    let Some(p) = poses.filter(|p| !p.is_none()) else {
        return Ok(None);
    };
    let msg = "poses must be None or a float64 array of shape (N, 3, 4), (N, 4, 4) or (N, 12)";
    let arr = p
        .extract::<numpy::PyReadonlyArrayDyn<'_, f64>>()
        .map_err(|_| PyTypeError::new_err(msg))?;
    let view = arr.as_array();
    let shape = view.shape().to_vec();
    let rows_per = match shape[..] {
        [m, 3, 4] | [m, 4, 4] | [m, 12] if m == n => shape[1..].iter().product::<usize>(),
        _ => {
            return Err(PyValueError::new_err(format!(
                "{msg}, with N = {n} rows; got shape {shape:?}"
            )))
        }
    };
    let flat: Vec<f64> = view.iter().copied().collect();
    let mut out = Vec::with_capacity(n);
    for (i, p) in flat.chunks_exact(rows_per).enumerate() {
        if rows_per == 16 && p[12..] != [0.0, 0.0, 0.0, 1.0] {
            return Err(PyValueError::new_err(format!(
                "poses[{i}]: a 4x4 pose must end with the row [0, 0, 0, 1]"
            )));
        }
        let mut pose = [0.0; 12];
        pose.copy_from_slice(&p[..12]);
        out.push(pose);
    }
    Ok(Some(out))
}

/// A (4, 4) float64 array of a pose.
pub fn pose_array<'py>(py: Python<'py>, p: &Pose) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((4, 4), |(i, j)| p[i][j]).into_pyarray(py)
}

/// A (6, 6) float64 array of a Hessian or an information matrix.
pub fn matrix6<'py>(py: Python<'py>, m: &[[f64; 6]; 6]) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((6, 6), |(i, j)| m[i][j]).into_pyarray(py)
}
