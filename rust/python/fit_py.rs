//! Fitting routines for Python: Levenberg-Marquardt, the reweighted l2,1
//! fit and the gamma path. The GIL is released during the fit and taken
//! back once per iteration to call the progress callback and to notice
//! Ctrl-C.

use super::convert::{bool_vec, detached, real_vec};
use super::outcome_py::{iteration_dict, PyConeStep, PyFitOutcome, PyPathOutcome};
use super::settings_py::{L21Arg, LmArg};
use super::time_py::{target, Target};
use super::trust_py::PyFrozenRange;
use crate::base::layout::{FreeSet, Shape};
use crate::eval::objective::Objective;
use crate::fit::lm::levenberg_marquardt;
use crate::fit::stable::Stable;
use crate::fit::{Iteration, Monitor};
use crate::l21::{fit_l21, l21_path, single_cone_step};
use crate::socp::Pinned;
use faer::Mat;
use numpy::{PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBool;

/// Calls the Python callback with one dict per iteration; stops the fit when
/// the callback returns `False`, raises, or Ctrl-C arrives. Ctrl-C is
/// remembered (`signalled`) so that the result says so: the fit returns its
/// best model, and a caller running several fits can stop them all.
struct PyMonitor {
    callback: Option<Py<PyAny>>,
    error: Option<PyErr>,
    signalled: bool,
}

impl Monitor for PyMonitor {
    fn iteration(&mut self, it: &Iteration) -> bool {
        Python::attach(|py| {
            if let Err(e) = py.check_signals() {
                // Python's SIGINT handler raised KeyboardInterrupt; any other
                // handler's exception stops the fit and is raised afterwards.
                if e.is_instance_of::<PyKeyboardInterrupt>(py) {
                    self.signalled = true;
                } else {
                    self.error = Some(e);
                }
                return false;
            }
            let Some(cb) = &self.callback else {
                return true;
            };
            let result = iteration_dict(py, it).and_then(|row| cb.bind(py).call1((row,)));
            match result {
                // Only an explicit False stops the fit.
                Ok(ret) => !ret.is_instance_of::<PyBool>() || ret.is_truthy().unwrap_or(true),
                // Ctrl-C while the callback ran: stop like Ctrl-C anywhere else.
                Err(e) if e.is_instance_of::<PyKeyboardInterrupt>(py) => {
                    self.signalled = true;
                    false
                }
                Err(e) => {
                    self.error = Some(e);
                    false
                }
            }
        })
    }
}

/// Run a fit with the GIL released and a monitor for the callback; an
/// exception the callback raised is raised again afterwards. Also returns
/// whether Ctrl-C stopped the run.
fn with_monitor<T: Send>(
    py: Python<'_>,
    callback: Option<Py<PyAny>>,
    run: impl FnOnce(&mut PyMonitor) -> crate::Result<T> + Send,
) -> PyResult<(T, bool)> {
    let mut monitor = PyMonitor {
        callback,
        error: None,
        signalled: false,
    };
    let out = detached(py, || run(&mut monitor))?;
    match monitor.error {
        Some(e) => Err(e),
        None => Ok((out, monitor.signalled)),
    }
}

fn free_set(shape: &Shape, free: Option<PyReadonlyArray1<'_, bool>>) -> PyResult<FreeSet> {
    let mask = free.as_ref().map(bool_vec);
    Ok(FreeSet::for_shape(shape, mask.as_deref())?)
}

/// The problem's objective, wrapped so that unstable frozen models on the
/// range are refused when `stable` is given.
fn with_stability<T>(
    problem: &dyn Objective,
    stable: Option<&PyFrozenRange>,
    run: impl FnOnce(&dyn Objective) -> crate::Result<T>,
) -> crate::Result<T> {
    match stable {
        Some(range) => run(&Stable::new(problem, range.inner.clone(), range.tol)?),
        None => run(problem),
    }
}

/// What every fit binding reads first, once: the cost behind `problem`,
/// the start `theta`, the free parameters and the stability range.
struct FitStart<'a> {
    target: Target<'a>,
    theta: Vec<f64>,
    free: FreeSet,
    stable: Option<&'a PyFrozenRange>,
}

impl<'a> FitStart<'a> {
    fn read(
        problem: &'a Bound<'_, PyAny>,
        theta: &PyReadonlyArray1<'_, f64>,
        free: Option<PyReadonlyArray1<'_, bool>>,
        stable: Option<&'a PyFrozenRange>,
    ) -> PyResult<Self> {
        let theta = real_vec(theta);
        let target = target(problem)?;
        let free = free_set(target.objective().shape(), free)?;
        Ok(FitStart {
            target,
            theta,
            free,
            stable,
        })
    }

    /// Run `fit` on the cost (refusing unstable frozen models when a range
    /// was given) with the GIL released and the callback's monitor; also
    /// returns whether Ctrl-C stopped it.
    fn run<T: Send>(
        &self,
        py: Python<'_>,
        callback: Option<Py<PyAny>>,
        fit: impl FnOnce(&dyn Objective, &mut PyMonitor) -> crate::Result<T> + Send,
    ) -> PyResult<(T, bool)> {
        let (problem, stable) = (self.target.objective(), self.stable);
        with_monitor(py, callback, |monitor| {
            with_stability(problem, stable, |objective| fit(objective, monitor))
        })
    }
}

/// Levenberg-Marquardt on V_NLS; `settings` as in `LmSettings`.
#[pyfunction]
#[pyo3(name = "fit_nls", signature = (problem, theta, free, settings, callback=None, stable=None))]
fn fit_nls_py<'py>(
    py: Python<'py>,
    problem: &Bound<'py, PyAny>,
    theta: PyReadonlyArray1<'py, f64>,
    free: Option<PyReadonlyArray1<'py, bool>>,
    settings: LmArg,
    callback: Option<Py<PyAny>>,
    stable: Option<PyRef<'py, PyFrozenRange>>,
) -> PyResult<PyFitOutcome> {
    let start = FitStart::read(problem, &theta, free, stable.as_deref())?;
    start.target.objective().shape().check_theta(&start.theta)?;
    let (fit, signalled) = start.run(py, callback, |objective, monitor| {
        levenberg_marquardt(objective, &start.theta, &start.free, &settings.0, monitor)
    })?;
    PyFitOutcome::new(py, fit, signalled)
}

/// Reweighted l2,1 fit (Algorithm 1); `settings` as in `L21Settings`.
#[pyfunction]
#[pyo3(name = "fit_l21", signature = (problem, theta, sup_norms, free, settings, callback=None, stable=None, pinned=None))]
// One Rust parameter per Python parameter (PyO3), and Python's signature stays.
#[allow(clippy::too_many_arguments)]
fn fit_l21_py<'py>(
    py: Python<'py>,
    problem: &Bound<'py, PyAny>,
    theta: PyReadonlyArray1<'py, f64>,
    sup_norms: PyReadonlyArray1<'py, f64>,
    free: Option<PyReadonlyArray1<'py, bool>>,
    settings: L21Arg,
    callback: Option<Py<PyAny>>,
    stable: Option<PyRef<'py, PyFrozenRange>>,
    pinned: Option<(PyReadonlyArray2<'py, f64>, PyReadonlyArray2<'py, f64>, f64)>,
) -> PyResult<PyFitOutcome> {
    let start = FitStart::read(problem, &theta, free, stable.as_deref())?;
    let sup = real_vec(&sup_norms);
    let pinned = pinned
        .map(|(dirs, exempt, weight)| pinned_directions(&dirs, &exempt, weight, start.free.len()))
        .transpose()?;
    let (fit, signalled) = start.run(py, callback, |objective, monitor| {
        let (theta, free) = (&start.theta, &start.free);
        fit_l21(
            objective,
            theta,
            free,
            &sup,
            &settings.0,
            pinned.as_ref(),
            monitor,
        )
    })?;
    PyFitOutcome::new(py, fit, signalled)
}

/// The directions a fit keeps its cone steps off (see `socp::Pinned`):
/// two arrays over the free parameters, one direction per column.
fn pinned_directions(
    dirs: &PyReadonlyArray2<'_, f64>,
    exempt: &PyReadonlyArray2<'_, f64>,
    weight: f64,
    n_free: usize,
) -> PyResult<Pinned> {
    let matrix = |a: &PyReadonlyArray2<'_, f64>, name: &str| -> PyResult<Mat<f64>> {
        let v = a.as_array();
        if v.nrows() != n_free {
            return Err(PyValueError::new_err(format!(
                "pinned: {name} needs one row per free parameter ({n_free}), got {}",
                v.nrows()
            )));
        }
        if v.iter().any(|x| !x.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "pinned: {name} holds NaN or Inf"
            )));
        }
        Ok(Mat::from_fn(v.nrows(), v.ncols(), |i, j| v[[i, j]]))
    };
    if !(weight.is_finite() && weight >= 0.0) {
        return Err(PyValueError::new_err(format!(
            "pinned: the weight must be finite and >= 0, got {weight}"
        )));
    }
    Ok(Pinned {
        dirs: matrix(dirs, "dirs")?,
        exempt: matrix(exempt, "exempt")?,
        weight,
    })
}

/// Warm-started gamma path: one fit per gamma, largest gamma first.
#[pyfunction]
#[pyo3(name = "l21_path", signature = (problem, theta, sup_norms, gammas, free, settings, callback=None, stable=None))]
// One Rust parameter per Python parameter (PyO3), and Python's signature stays.
#[allow(clippy::too_many_arguments)]
fn l21_path_py<'py>(
    py: Python<'py>,
    problem: &Bound<'py, PyAny>,
    theta: PyReadonlyArray1<'py, f64>,
    sup_norms: PyReadonlyArray1<'py, f64>,
    gammas: PyReadonlyArray1<'py, f64>,
    free: Option<PyReadonlyArray1<'py, bool>>,
    settings: L21Arg,
    callback: Option<Py<PyAny>>,
    stable: Option<PyRef<'py, PyFrozenRange>>,
) -> PyResult<PyPathOutcome> {
    let start = FitStart::read(problem, &theta, free, stable.as_deref())?;
    let (sup, gammas) = (real_vec(&sup_norms), real_vec(&gammas));
    let (fits, signalled) = start.run(py, callback, |objective, monitor| {
        let (theta, free) = (&start.theta, &start.free);
        l21_path(objective, theta, free, &sup, &gammas, &settings.0, monitor)
    })?;
    PyPathOutcome::new(py, fits, signalled)
}

/// One cone step at `theta` with damping `mu` (for tests and inspection).
#[pyfunction]
#[pyo3(name = "cone_step", signature = (problem, theta, sup_norms, free, settings, mu))]
fn cone_step_py<'py>(
    py: Python<'py>,
    problem: &Bound<'py, PyAny>,
    theta: PyReadonlyArray1<'py, f64>,
    sup_norms: PyReadonlyArray1<'py, f64>,
    free: Option<PyReadonlyArray1<'py, bool>>,
    settings: L21Arg,
    mu: f64,
) -> PyResult<PyConeStep> {
    let start = FitStart::read(problem, &theta, free, None)?;
    let sup = real_vec(&sup_norms);
    let (objective, theta, free) = (start.target.objective(), &start.theta, &start.free);
    let report = detached(py, || {
        single_cone_step(objective, theta, free, &sup, &settings.0, mu)
    })?;
    Ok(PyConeStep::new(py, report))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyFitOutcome>()?;
    m.add_class::<PyPathOutcome>()?;
    m.add_class::<PyConeStep>()?;
    m.add_function(wrap_pyfunction!(cone_step_py, m)?)?;
    m.add_function(wrap_pyfunction!(fit_nls_py, m)?)?;
    m.add_function(wrap_pyfunction!(fit_l21_py, m)?)?;
    m.add_function(wrap_pyfunction!(l21_path_py, m)?)?;
    Ok(())
}
