//! `Problem` and `frequency_response` for Python.

use super::convert::{bool_vec, complex_vec, detached, guarded, real_vec, to_py};
use crate::data::FrfData;
use crate::layout::{FreeSet, Shape};
use crate::problem::Problem;
use crate::response::frequency_response;
use numpy::{Complex64, PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;

/// Frequency response of an LPV model, `(N*F*l*r,)` complex, row-major
/// `(N, F, l, r)`.
#[pyfunction]
#[pyo3(name = "frequency_response")]
#[allow(clippy::too_many_arguments)]
fn frequency_response_py<'py>(
    py: Python<'py>,
    n: usize,
    r: usize,
    l: usize,
    nb: usize,
    theta: PyReadonlyArray1<'py, f64>,
    basis: PyReadonlyArray1<'py, f64>,
    n_points: usize,
    z: PyReadonlyArray1<'py, Complex64>,
) -> PyResult<Bound<'py, PyArray1<Complex64>>> {
    let shape = Shape::new(n, r, l, nb)?;
    let (theta, basis, z) = (real_vec(&theta), real_vec(&basis), complex_vec(&z));
    let out = detached(py, || {
        frequency_response(&shape, &theta, &basis, n_points, &z)
    })?;
    Ok(to_py(py, out))
}

/// An identification problem: model shape, FRF data and basis values.
#[pyclass(name = "Problem", module = "lpvid._core", frozen)]
pub struct PyProblem {
    pub(crate) inner: Problem,
}

#[pymethods]
impl PyProblem {
    /// Build from flat arrays: `g` and `sigma` of length `N*F*l*r`
    /// (row-major `(N, F, l, r)`), `basis` of length `N*Nb`, `z` of length `F`.
    #[new]
    #[allow(clippy::too_many_arguments)]
    fn new(
        n: usize,
        r: usize,
        l: usize,
        nb: usize,
        n_points: usize,
        z: PyReadonlyArray1<'_, Complex64>,
        g: PyReadonlyArray1<'_, Complex64>,
        sigma: PyReadonlyArray1<'_, f64>,
        basis: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<Self> {
        let (z, g, sigma, basis) = (
            complex_vec(&z),
            complex_vec(&g),
            real_vec(&sigma),
            real_vec(&basis),
        );
        let inner = guarded(|| {
            let shape = Shape::new(n, r, l, nb)?;
            let data = FrfData::new(n_points, l, r, z, g, &sigma)?;
            Problem::new(shape, data, &basis)
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
