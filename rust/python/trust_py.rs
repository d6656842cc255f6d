//! Uncertainty and stability pieces for Python: the LTI Jacobian of the
//! frozen response and the check points of a scheduling range.

use super::convert::{complex_vec, detached, guarded, real_vec, to_py};
use super::model_py::PyModelView;
use crate::base::layout::Shape;
use crate::error::invalid;
use crate::eval::sensitivity::lti_jacobian;
use crate::fit::stable::{margin, FrozenRange};
use numpy::{Complex64, PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;

/// Jacobian of the frozen response with respect to the frozen LTI
/// parameters at the view's scheduling points, flat complex, row-major
/// `(N, F, l, r, lti_len)`.
#[pyfunction]
#[pyo3(name = "lti_jacobian")]
fn lti_jacobian_py<'py>(
    py: Python<'py>,
    view: &Bound<'py, PyModelView>,
    z: PyReadonlyArray1<'py, Complex64>,
) -> PyResult<Bound<'py, PyArray1<Complex64>>> {
    let z = complex_vec(&z);
    let out = view
        .get()
        .with_model(py, |model| detached(py, || lti_jacobian(&model, &z)))?;
    Ok(to_py(py, out))
}

/// Stability margin from poles (the core's rule), for the test that
/// compares it with Python's.
#[pyfunction]
#[pyo3(name = "stability_margin")]
fn stability_margin_py(poles: PyReadonlyArray1<'_, Complex64>, discrete: bool) -> f64 {
    margin(&complex_vec(&poles), discrete)
}

/// Check points of a scheduling range for fits that keep stability: the
/// model's view at the points (its shape and basis values; the margins
/// are taken at the `theta` each call passes); every `stride`-th point is
/// checked first; a margin below `tol` is unstable. `floor` (continuous
/// time) measures every pole against `max(|lambda|, floor)`
/// (`stable::floored_margin`).
#[pyclass(name = "FrozenRange", module = "lpvid._core", frozen)]
pub struct PyFrozenRange {
    pub(crate) inner: FrozenRange,
    pub(crate) tol: f64,
    shape: Shape,
}

#[pymethods]
impl PyFrozenRange {
    #[new]
    #[pyo3(signature = (view, stride, discrete, tol, floor = 0.0))]
    fn new(
        py: Python<'_>,
        view: &Bound<'_, PyModelView>,
        stride: usize,
        discrete: bool,
        tol: f64,
        floor: f64,
    ) -> PyResult<Self> {
        if !(tol.is_finite() && tol >= 0.0) {
            return Err(invalid("tol", format!("expected a finite number >= 0, got {tol}")).into());
        }
        let (inner, shape) = view.get().with_model(py, |model| {
            let (nb, basis, n_points) = (model.shape.nb, model.basis, model.n_points);
            let inner = guarded(|| {
                FrozenRange::new(nb, basis, n_points, stride, discrete)?.with_floor(floor)
            })?;
            Ok((inner, model.shape))
        })?;
        Ok(PyFrozenRange { inner, tol, shape })
    }

    /// Number of check points.
    fn __len__(&self) -> usize {
        self.inner.len()
    }

    /// The margin at every check point of the model with parameters `theta`.
    fn margins<'py>(
        &self,
        py: Python<'py>,
        theta: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let theta = real_vec(&theta);
        let out = detached(py, || self.inner.margins(&self.shape, &theta))?;
        Ok(to_py(py, out))
    }

    /// `(index, margin)` of the smallest margin the coarse-then-fine search finds.
    fn worst(&self, py: Python<'_>, theta: PyReadonlyArray1<'_, f64>) -> PyResult<(usize, f64)> {
        let theta = real_vec(&theta);
        detached(py, || self.inner.worst(&self.shape, &theta, self.tol))
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(lti_jacobian_py, m)?)?;
    m.add_function(wrap_pyfunction!(stability_margin_py, m)?)?;
    m.add_class::<PyFrozenRange>()?;
    Ok(())
}
