//! Array conversions and the one place where core errors become Python
//! exceptions.

use crate::error::Error;
use numpy::{Complex64, PyArray1, PyReadonlyArray1};
use pyo3::exceptions::{PyArithmeticError, PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        match e {
            Error::InvalidArgument { .. } | Error::Unstable { .. } => {
                PyValueError::new_err(e.to_string())
            }
            Error::Singular { .. } | Error::Overflow { .. } => {
                super::SingularModelError::new_err(e.to_string())
            }
            Error::Numerical(_) => PyArithmeticError::new_err(e.to_string()),
            Error::Interrupted => PyKeyboardInterrupt::new_err(e.to_string()),
        }
    }
}

/// Copy a 1-D float64 array (any strides).
pub fn real_vec(a: &PyReadonlyArray1<'_, f64>) -> Vec<f64> {
    a.as_array().iter().copied().collect()
}

/// Copy a 1-D complex128 array (any strides).
pub fn complex_vec(a: &PyReadonlyArray1<'_, Complex64>) -> Vec<Complex64> {
    a.as_array().iter().copied().collect()
}

/// Copy a 1-D bool array (any strides).
pub fn bool_vec(a: &PyReadonlyArray1<'_, bool>) -> Vec<bool> {
    a.as_array().iter().copied().collect()
}

/// Hand a vector to numpy without copying.
pub fn to_py<'py, T: numpy::Element>(py: Python<'py>, v: Vec<T>) -> Bound<'py, PyArray1<T>> {
    PyArray1::from_vec(py, v)
}
