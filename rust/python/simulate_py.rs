//! `simulate` for Python.

use super::convert::{detached, real_vec, to_py};
use crate::layout::Shape;
use crate::simulate::{simulate, simulate_zoh};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use std::borrow::Cow;

/// The array's data: borrowed when contiguous (long trajectories are not
/// copied: a fresh copy of tens of megabytes costs more than the whole
/// simulation), copied otherwise.
fn data<'a>(a: &'a PyReadonlyArray1<'_, f64>) -> Cow<'a, [f64]> {
    match a.as_slice() {
        Ok(s) => Cow::Borrowed(s),
        Err(_) => Cow::Owned(real_vec(a)),
    }
}

/// Simulate an LPV model along a trajectory: `basis` is `T x Nb`, `u`
/// `T x r`, both row-major and flat; `dt` None for a discrete-time model,
/// the sample time for a continuous-time one (zero-order hold). Returns
/// `(y, x, diverged)`: `y` and `x` flat `T x l` and `(T + 1) x n`
/// row-major, `x` None unless `states`; `diverged` the first sample whose
/// output `y(t)` or (with `states`) state `x(t + 1)` is not finite, or None.
///
/// The GIL is released while the arrays are read: the caller passes arrays
/// that no other thread writes to (`LpvModel.simulate` passes its own
/// copies).
#[pyfunction]
#[pyo3(name = "simulate", signature = (n, r, l, nb, theta, basis, u, x0, dt=None, states=false))]
#[allow(clippy::too_many_arguments)]
#[allow(clippy::type_complexity)]
fn simulate_py<'py>(
    py: Python<'py>,
    n: usize,
    r: usize,
    l: usize,
    nb: usize,
    theta: PyReadonlyArray1<'py, f64>,
    basis: PyReadonlyArray1<'py, f64>,
    u: PyReadonlyArray1<'py, f64>,
    x0: PyReadonlyArray1<'py, f64>,
    dt: Option<f64>,
    states: bool,
) -> PyResult<(
    Bound<'py, PyArray1<f64>>,
    Option<Bound<'py, PyArray1<f64>>>,
    Option<usize>,
)> {
    let shape = Shape::new(n, r, l, nb)?;
    let (theta, basis, u, x0) = (data(&theta), data(&basis), data(&u), data(&x0));
    let traj = detached(py, || match dt {
        None => simulate(&shape, &theta, &basis, &u, &x0, states),
        Some(dt) => simulate_zoh(&shape, &theta, &basis, &u, &x0, dt, states),
    })?;
    Ok((
        to_py(py, traj.y),
        traj.x.map(|x| to_py(py, x)),
        traj.diverged,
    ))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(simulate_py, m)?)?;
    Ok(())
}
