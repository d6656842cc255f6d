//! `Problem` and `frequency_response` for Python.

use super::convert::{bool_vec, complex_vec, detached, guarded, real_vec, to_py};
use super::model_py::PyModelView;
use crate::base::data::FrfData;
use crate::base::layout::FreeSet;
use crate::eval::problem::Problem;
use crate::eval::response::frequency_response;
use numpy::{Complex64, PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;

/// Frequency response of an LPV model at its view's scheduling points,
/// `(N*F*l*r,)` complex, row-major `(N, F, l, r)`.
#[pyfunction]
#[pyo3(name = "frequency_response")]
fn frequency_response_py<'py>(
    py: Python<'py>,
    view: &Bound<'py, PyModelView>,
    z: PyReadonlyArray1<'py, Complex64>,
) -> PyResult<Bound<'py, PyArray1<Complex64>>> {
    let z = complex_vec(&z);
    let out = view
        .get()
        .with_model(py, |model| detached(py, || frequency_response(&model, &z)))?;
    Ok(to_py(py, out))
}

/// An identification problem: model shape, FRF data and basis values.
#[pyclass(name = "Problem", module = "lpvid._core", frozen)]
pub struct PyProblem {
    pub(crate) inner: Problem,
}

#[pymethods]
impl PyProblem {
    /// Build from the model's view at the data's scheduling points (its
    /// shape and basis values; the fits pass their own `theta`), `z` of
    /// length `F`, `g` and `sigma` of length `N*F*l*r` (row-major `(N, F, l, r)`).
    #[new]
    fn new(
        py: Python<'_>,
        view: &Bound<'_, PyModelView>,
        z: PyReadonlyArray1<'_, Complex64>,
        g: PyReadonlyArray1<'_, Complex64>,
        sigma: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<Self> {
        let (z, g, sigma) = (complex_vec(&z), complex_vec(&g), real_vec(&sigma));
        let inner = view.get().with_model(py, |model| {
            guarded(|| {
                let shape = model.shape;
                let data = FrfData::new(model.n_points, shape.l, shape.r, z, g, &sigma)?;
                Problem::new(shape, data, model.basis)
            })
        })?;
        Ok(PyProblem { inner })
    }

    /// Number of complex residuals `N F l r`.
    #[getter]
    fn n_residuals(&self) -> usize {
        self.inner.n_residuals()
    }

    /// Weighted residual `(G - Gm) / sigma`, flat complex.
    fn residual<'py>(
        &self,
        py: Python<'py>,
        theta: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray1<Complex64>>> {
        let theta = real_vec(&theta);
        let out = detached(py, || self.inner.residual(&theta))?;
        Ok(to_py(py, out))
    }

    /// `V_NLS(theta)`.
    fn vnls(&self, py: Python<'_>, theta: PyReadonlyArray1<'_, f64>) -> PyResult<f64> {
        let theta = real_vec(&theta);
        detached(py, || self.inner.cost(&theta))
    }

    /// `(V_NLS, gradient, J^T J)` over the free parameters (all when `free`
    /// is None); `J^T J` flat column-major.
    #[pyo3(signature = (theta, free=None))]
    #[allow(clippy::type_complexity)]
    fn gauss_newton<'py>(
        &self,
        py: Python<'py>,
        theta: PyReadonlyArray1<'py, f64>,
        free: Option<PyReadonlyArray1<'py, bool>>,
    ) -> PyResult<(f64, Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>)> {
        let theta = real_vec(&theta);
        let mask = free.as_ref().map(bool_vec);
        let free = FreeSet::for_shape(self.inner.shape(), mask.as_deref())?;
        let gn = detached(py, || self.inner.gauss_newton(&theta, &free))?;
        Ok((gn.vnls, to_py(py, gn.gradient), to_py(py, gn.gram)))
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(frequency_response_py, m)?)?;
    m.add_class::<PyProblem>()?;
    Ok(())
}
