//! The model as the bindings see it: one [`PyModelView`] (shape, parameters
//! and basis values), built once by Python (`lpvid.model._view.model_view`),
//! checked at construction and handed to the core as one [`ModelAt`], and
//! the shape alone ([`ShapeArg`]) for the
//! bindings that take no basis values (time records, memory estimates).

use super::convert::flat;
use crate::base::layout::Shape;
use crate::eval::model::ModelAt;
use numpy::{PyArray2, PyArrayMethods, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use std::borrow::Cow;

/// A model shape from Python's `(n, r, l, nb)`, checked (`Shape::new`); pyo3
/// names the argument in the TypeError of a wrong type.
pub struct ShapeArg(pub Shape);

impl<'a, 'py> FromPyObject<'a, 'py> for ShapeArg {
    type Error = PyErr;

    fn extract(ob: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        let (n, r, l, nb): (usize, usize, usize, usize) = ob.extract().map_err(|_| {
            PyTypeError::new_err(format!(
                "expected a tuple (n, r, l, nb) of integers >= 0, got {}",
                ob.repr()
                    .map_or_else(|_| "?".to_string(), |s| s.to_string())
            ))
        })?;
        Ok(ShapeArg(Shape::new(n, r, l, nb)?))
    }
}

/// A model seen at some scheduling points: its shape `(n, r, l, nb)`, its
/// parameters `theta` (length checked against the shape) and the basis
/// values `psi_1..psi_Nb` at `N` points as an `(N, Nb)` float64 array
/// (`Nb` checked against the shape). Whether the values are finite is left
/// to the routines that use them, as before.
///
/// The basis array is held, not copied (a simulation's trajectory may be
/// tens of megabytes): the caller passes an array that nothing writes to
/// while the core runs (lpvid passes its own fresh arrays).
#[pyclass(name = "ModelView", module = "lpvid._core", frozen)]
pub struct PyModelView {
    shape: Shape,
    theta: Vec<f64>,
    basis: Py<PyArray2<f64>>,
    n_points: usize,
}

#[pymethods]
impl PyModelView {
    #[new]
    fn new(
        shape: ShapeArg,
        theta: PyReadonlyArray1<'_, f64>,
        basis: Bound<'_, PyArray2<f64>>,
    ) -> PyResult<Self> {
        let shape = shape.0;
        let theta = flat(&theta).into_owned();
        shape.check_theta_len(&theta)?;
        let dims = basis.shape();
        let (n_points, cols) = (dims[0], dims[1]);
        if cols != shape.nb {
            let nb = shape.nb;
            return Err(crate::error::invalid(
                "psi",
                format!(
                    "expected {} basis values ({n_points} points x {nb} functions), got {} \
                     ({n_points} x {cols})",
                    n_points * nb,
                    n_points * cols
                ),
            )
            .into());
        }
        Ok(PyModelView {
            shape,
            theta,
            basis: basis.unbind(),
            n_points,
        })
    }

    /// `(n, r, l, nb)`.
    #[getter(shape)]
    fn shape_tuple(&self) -> (usize, usize, usize, usize) {
        let s = self.shape;
        (s.n, s.r, s.l, s.nb)
    }

    /// Number of scheduling points `N`.
    #[getter(n_points)]
    fn points(&self) -> usize {
        self.n_points
    }
}

impl PyModelView {
    /// Run `work` on the core's view of the model: the checked shape, the
    /// parameters (length checked; finiteness is the core's to check) and
    /// the basis values, flat row-major `N x Nb`, borrowed when the array
    /// is contiguous and copied otherwise.
    pub fn with_model<T>(
        &self,
        py: Python<'_>,
        work: impl FnOnce(ModelAt<'_>) -> PyResult<T>,
    ) -> PyResult<T> {
        let array = self.basis.bind(py).try_readonly().map_err(|e| {
            PyValueError::new_err(format!("psi: the basis values cannot be read: {e}"))
        })?;
        let values: Cow<'_, [f64]> = flat(&array);
        work(ModelAt::new(
            self.shape,
            &self.theta,
            &values,
            self.n_points,
        ))
    }
}
