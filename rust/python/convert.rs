//! Array conversions and the one place where core errors become Python
//! exceptions.

use super::pool::in_this_process;
use crate::error::{catch_panic, Error};
use numpy::ndarray::Dimension;
use numpy::{Complex64, PyArray1, PyReadonlyArray, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::{
    PyArithmeticError, PyKeyboardInterrupt, PyMemoryError, PyRuntimeError, PyValueError,
};
use pyo3::prelude::*;
use std::borrow::Cow;

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
            Error::OutOfMemory { .. } => PyMemoryError::new_err(e.to_string()),
            Error::Internal(_) => PyRuntimeError::new_err(e.to_string()),
        }
    }
}

/// Run core work with the GIL released. A panic inside becomes a Python
/// exception (MemoryError for a failed allocation, RuntimeError for a
/// bug), never a `PanicException`: every call into the core from Python
/// goes through here or [`guarded`], and in a process forked from the one
/// that loaded the module runs on a thread pool of its own
/// ([`super::pool`]).
pub fn detached<T: Send>(
    py: Python<'_>,
    work: impl FnOnce() -> crate::Result<T> + Send,
) -> PyResult<T> {
    Ok(py.detach(|| catch_panic(|| in_this_process(work)))?)
}

/// Run core work that keeps the GIL (constructors), as [`detached`].
pub fn guarded<T: Send>(work: impl FnOnce() -> crate::Result<T> + Send) -> PyResult<T> {
    Ok(catch_panic(|| in_this_process(work))?)
}

/// Copy a 1-D float64 array (any strides).
pub fn real_vec(a: &PyReadonlyArray1<'_, f64>) -> Vec<f64> {
    a.as_array().iter().copied().collect()
}

/// A float64 array's data, flat in row-major order: borrowed when it is
/// C-contiguous (long arrays are not copied: a fresh copy of tens of
/// megabytes costs more than a whole simulation), copied otherwise
/// (`as_slice` alone would also take a Fortran-ordered array as it lies).
pub fn flat<'a, D: Dimension>(a: &'a PyReadonlyArray<'_, f64, D>) -> Cow<'a, [f64]> {
    if a.is_c_contiguous() {
        if let Ok(s) = a.as_slice() {
            return Cow::Borrowed(s);
        }
    }
    Cow::Owned(a.as_array().iter().copied().collect())
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
