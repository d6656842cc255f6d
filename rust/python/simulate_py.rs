//! `simulate` for Python.

use super::convert::{detached, flat, to_py};
use super::model_py::PyModelView;
use crate::simulate::{simulate, simulate_zoh};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;

/// Simulate an LPV model along a trajectory: `view` holds the model and
/// its basis values at the `T` samples (`T x Nb`), `u` is `T x r`
/// row-major and flat; `dt` None for a discrete-time model, the sample
/// time for a continuous-time one (zero-order hold). Returns
/// `(y, x, diverged)`: `y` and `x` flat `T x l` and `(T + 1) x n`
/// row-major, `x` None unless `states`; `diverged` the first sample whose
/// output `y(t)` or (with `states`) state `x(t + 1)` is not finite, or None.
///
/// The GIL is released while the arrays are read (contiguous ones are not
/// copied): the caller passes arrays that no other thread writes to
/// (`LpvModel.simulate` passes its own copies).
#[pyfunction]
#[pyo3(name = "simulate", signature = (view, u, x0, dt=None, states=false))]
#[allow(clippy::type_complexity)]
fn simulate_py<'py>(
    py: Python<'py>,
    view: &Bound<'py, PyModelView>,
    u: PyReadonlyArray1<'py, f64>,
    x0: PyReadonlyArray1<'py, f64>,
    dt: Option<f64>,
    states: bool,
) -> PyResult<(
    Bound<'py, PyArray1<f64>>,
    Option<Bound<'py, PyArray1<f64>>>,
    Option<usize>,
)> {
    let (u, x0) = (flat(&u), flat(&x0));
    let traj = view.get().with_model(py, |model| {
        detached(py, || match dt {
            None => simulate(&model, &u, &x0, states),
            Some(dt) => simulate_zoh(&model, &u, &x0, dt, states),
        })
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
