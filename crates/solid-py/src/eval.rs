//! Binding of `solid_lidar::eval`: docs/spec.md §5 scoring of a detector's candidates against poses.

use numpy::{
    IntoPyArray, PyArray1, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use solid_lidar::eval::{self, Evaluation, Queries, NO_CANDIDATE};

use crate::args;
use crate::errors::{core_err, SolidError};

/// The per-query outcomes and the summary metrics of one scored run (docs/spec.md §5).
#[pyclass(name = "Scores", module = "solid", frozen)]
pub struct PyScores {
    inner: Evaluation,
}

fn f64s<'py>(py: Python<'py>, v: &[f64]) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, v)
}

fn opt(v: Option<f64>) -> f64 {
    v.unwrap_or(f64::NAN)
}

/// A curve as three float64 arrays (thresholds and the two rates).
type Curve<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
);

fn curve(py: Python<'_>, (t, x, y): (Vec<f64>, Vec<f64>, Vec<f64>)) -> Curve<'_> {
    (t.into_pyarray(py), x.into_pyarray(py), y.into_pyarray(py))
}

#[pymethods]
impl PyScores {
    /// Radius in metres.
    #[getter]
    fn radius(&self) -> f64 {
        self.inner.radius
    }
    /// Whether some eligible place lies within the radius, per query (bool array).
    #[getter]
    fn gt_positive<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        PyArray1::from_slice(py, &self.inner.gt_positive)
    }
    /// Whether the best candidate lies within the radius and its estimated pose, if any, within
    /// the pose tolerance, per query (bool array).
    #[getter]
    fn correct<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        PyArray1::from_slice(py, &self.inner.correct)
    }
    /// Whether the best candidate lies within the radius, whatever its pose (bool array).
    #[getter]
    fn place_correct<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        PyArray1::from_slice(py, &self.inner.place_correct)
    }
    /// Largest translation error (metres) of a correct loop's pose.
    #[getter]
    fn pose_tolerance_m(&self) -> f64 {
        self.inner.truth.translation_m
    }
    /// Largest rotation error (degrees) of a correct loop's pose.
    #[getter]
    fn pose_tolerance_deg(&self) -> f64 {
        self.inner.truth.rotation_deg
    }
    /// 1-based rank of the first candidate within the radius (0: none), per query.
    #[getter]
    fn first_hit<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        PyArray1::from_slice(py, &self.inner.first_hit)
    }
    /// Metres from each query to its best candidate (NaN: none).
    #[getter]
    fn candidate_distance_m<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        f64s(py, &self.inner.candidate_distance_m)
    }
    /// True heading between each query and its best candidate, degrees (NaN: none).
    #[getter]
    fn true_heading_deg<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        f64s(py, &self.inner.true_heading_deg)
    }
    /// Number of GT-positive queries.
    #[getter]
    fn n_gt(&self) -> usize {
        self.inner.n_gt()
    }
    /// Recall@n (NaN without GT-positive queries).
    fn recall_at(&self, #[pyo3(from_py_with = args::n)] n: usize) -> f64 {
        opt(self.inner.recall_at(n))
    }
    /// (thresholds, precision, recall) arrays of the PR curve.
    fn pr_curve<'py>(&self, py: Python<'py>) -> Curve<'py> {
        curve(py, self.inner.pr_curve())
    }
    /// (thresholds, false-positive rate, true-positive rate) arrays of the ROC curve.
    fn roc_curve<'py>(&self, py: Python<'py>) -> Curve<'py> {
        curve(py, self.inner.roc_curve())
    }
    /// (F1 max, its threshold); (NaN, NaN) for an empty curve.
    fn f1_max(&self) -> (f64, f64) {
        self.inner.f1_max().unwrap_or((f64::NAN, f64::NAN))
    }
    /// AUC of correct vs incorrect top-1s (NaN when a class is empty).
    fn auc(&self) -> f64 {
        opt(self.inner.auc())
    }
    /// (accepted, correct accepted, precision, recall) when accepting scores <= threshold.
    fn at_threshold(&self, threshold: f64) -> (usize, usize, f64, f64) {
        self.inner.at_threshold(threshold)
    }
    /// (place-false, pose-false) among the top-1s accepted with scores <= threshold.
    fn false_at_threshold(&self, threshold: f64) -> (usize, usize) {
        self.inner.false_at_threshold(threshold)
    }
    /// Translation error (metres) of each query's estimated pose (NaN: none).
    #[getter]
    fn pose_error_m<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        f64s(py, &self.inner.pose_error_m)
    }
    /// Rotation error (degrees) of each query's estimated pose (NaN: none).
    #[getter]
    fn pose_error_deg<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        f64s(py, &self.inner.pose_error_deg)
    }
    /// Heading errors of the correct top-1s, degrees in [0, 180].
    fn rotation_errors<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.rotation_errors().into_pyarray(py)
    }
    fn __len__(&self) -> usize {
        self.inner.len()
    }
}

/// The rows of `N` values of a flat C-contiguous array, copied (MemoryError naming `what` when
/// they do not fit).
fn rows<const N: usize>(flat: &[f64], what: &str) -> PyResult<Vec<[f64; N]>> {
    let mut out = args::try_vec(flat.len() / N, what)?;
    out.extend(flat.chunks_exact(N).map(|c| {
        let mut m = [0.0; N];
        m.copy_from_slice(c);
        m
    }));
    Ok(out)
}

/// Scores candidates against poses (docs/spec.md §5); see `solid.evaluation` for the friendly form.
#[pyfunction]
#[pyo3(signature = (query, eligible, ids, score, heading_deg, poses, radius, pose=None, pose_tolerance_m=eval::DEFAULT_POSE_TOLERANCE_M, pose_tolerance_deg=eval::DEFAULT_POSE_TOLERANCE_DEG))]
#[allow(clippy::too_many_arguments)]
fn score_candidates(
    py: Python<'_>,
    query: PyReadonlyArray1<'_, i64>,
    eligible: PyReadonlyArray1<'_, i64>,
    ids: PyReadonlyArray2<'_, i64>,
    score: PyReadonlyArray1<'_, f64>,
    heading_deg: PyReadonlyArray1<'_, f64>,
    poses: PyReadonlyArray3<'_, f64>,
    radius: f64,
    pose: Option<PyReadonlyArray3<'_, f64>>,
    pose_tolerance_m: f64,
    pose_tolerance_deg: f64,
) -> PyResult<PyScores> {
    let to_u32 = |name: &str, v: &[i64], allow_missing: bool| -> PyResult<Vec<u32>> {
        let mut out = args::try_vec(v.len(), name)?;
        for &x in v {
            out.push(if allow_missing && x < 0 {
                NO_CANDIDATE
            } else {
                u32::try_from(x)
                    .ok()
                    .filter(|&u| u != NO_CANDIDATE)
                    .ok_or_else(|| SolidError::new_err(format!("{name}: {x} is not a valid id")))?
            });
        }
        Ok(out)
    };
    let shape = poses.shape();
    if shape.len() != 3 || shape[1] != 3 || shape[2] != 4 {
        return Err(SolidError::new_err(format!(
            "poses must have shape (N, 3, 4), got {shape:?}"
        )));
    }
    let k = ids.shape()[1];
    let query = to_u32("query", query.as_slice()?, false)?;
    let eligible = to_u32("eligible", eligible.as_slice()?, false)?;
    let ids = to_u32("ids", ids.as_slice()?, true)?;
    let (score, heading) = (score.as_slice()?, heading_deg.as_slice()?);
    let poses: Vec<[f64; 12]> = rows(poses.as_slice()?, "poses")?;
    let est: Vec<[f64; 16]> = match &pose {
        None => Vec::new(),
        Some(p) => {
            let sh = p.shape();
            if sh.len() != 3 || sh[0] != query.len() || sh[1] != 4 || sh[2] != 4 {
                return Err(SolidError::new_err(format!(
                    "pose must have shape ({}, 4, 4), got {sh:?}",
                    query.len()
                )));
            }
            rows(p.as_slice()?, "pose")?
        }
    };
    let q = Queries {
        pose: &est,
        query: &query,
        eligible: &eligible,
        k,
        ids: &ids,
        score,
        heading_deg: heading,
    };
    let inner = py
        .detach(|| {
            let truth = eval::Truth {
                radius,
                translation_m: pose_tolerance_m,
                rotation_deg: pose_tolerance_deg,
            };
            eval::score_with(&q, &poses, &truth)
        })
        .map_err(core_err)?;
    Ok(PyScores { inner })
}

/// Registers the scoring function and class.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("DEFAULT_RADIUS", eval::DEFAULT_RADIUS)?;
    m.add("DEFAULT_POSE_TOLERANCE_M", eval::DEFAULT_POSE_TOLERANCE_M)?;
    m.add(
        "DEFAULT_POSE_TOLERANCE_DEG",
        eval::DEFAULT_POSE_TOLERANCE_DEG,
    )?;
    m.add_class::<PyScores>()?;
    add_functions! { m, score_candidates }
    Ok(())
}
