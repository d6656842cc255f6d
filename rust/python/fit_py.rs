//! Fitting routines for Python: Levenberg-Marquardt, the reweighted l2,1
//! fit and the gamma path. The GIL is released during the fit and taken
//! back once per iteration to call the progress callback and to notice
//! Ctrl-C.

use super::convert::{bool_vec, detached, real_vec};
use super::outcome_py::{iteration_dict, PyConeStep, PyFitOutcome, PyPathOutcome};
use super::time_py::target;
use super::trust_py::PyFrozenRange;
use crate::base::layout::{FreeSet, Shape};
use crate::eval::objective::Objective;
use crate::fit::lm::{levenberg_marquardt, LmSettings};
use crate::fit::stable::Stable;
use crate::fit::{Iteration, Monitor};
use crate::l21::{fit_l21, l21_path, single_cone_step, L21Settings, Weighting};
use crate::socp::Pinned;
use faer::Mat;
use numpy::{PyReadonlyArray1, PyReadonlyArray2};
use pyo3::conversion::FromPyObjectOwned;
use pyo3::exceptions::{PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict};

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

fn weighting(name: &str) -> PyResult<Weighting> {
    match name {
        "relative" => Ok(Weighting::Relative),
        "scaled" => Ok(Weighting::Scaled),
        "plain" => Ok(Weighting::Plain),
        other => Err(PyValueError::new_err(format!(
            "weights: expected 'relative', 'scaled' or 'plain', got {other:?}"
        ))),
    }
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

/// Read an optional setting, keeping `default` when absent.
fn setting<'py, T: FromPyObjectOwned<'py>>(
    d: &Bound<'py, PyDict>,
    key: &str,
    default: T,
) -> PyResult<T> {
    match d.get_item(key)? {
        Some(v) => v
            .extract()
            .map_err(|_| PyValueError::new_err(format!("{key}: has the wrong type"))),
        None => Ok(default),
    }
}

fn check_keys(d: &Bound<'_, PyDict>, known: &[&str]) -> PyResult<()> {
    for key in d.keys() {
        let key: String = key.extract()?;
        if !known.contains(&key.as_str()) {
            return Err(PyValueError::new_err(format!("unknown setting {key:?}")));
        }
    }
    Ok(())
}

fn lm_settings(d: &Bound<'_, PyDict>) -> PyResult<LmSettings> {
    check_keys(d, &["max_iter", "xtol", "ftol", "gtol", "lambda0"])?;
    let base = LmSettings::default();
    let s = LmSettings {
        max_iter: setting(d, "max_iter", base.max_iter)?,
        xtol: setting(d, "xtol", base.xtol)?,
        ftol: setting(d, "ftol", base.ftol)?,
        gtol: setting(d, "gtol", base.gtol)?,
        lambda0: setting(d, "lambda0", base.lambda0)?,
    };
    s.validate()?;
    Ok(s)
}

fn weighting_name(w: Weighting) -> &'static str {
    match w {
        Weighting::Relative => "relative",
        Weighting::Scaled => "scaled",
        Weighting::Plain => "plain",
    }
}

/// The settings as a dict: the names Python's `L21Settings` mirrors.
fn l21_dict<'py>(py: Python<'py>, s: &L21Settings) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("gamma", s.gamma)?;
    d.set_item("eps", s.eps)?;
    d.set_item("weights", weighting_name(s.weighting))?;
    d.set_item("dtheta_min", s.dtheta_min)?;
    d.set_item("dphi_min", s.dphi_min)?;
    d.set_item("dvnls_min", s.dvnls_min)?;
    d.set_item("threshold", s.threshold)?;
    d.set_item("cone_tol", s.cone_tol)?;
    d.set_item("ftol", s.ftol)?;
    d.set_item("max_outer", s.max_outer)?;
    d.set_item("max_inner", s.max_inner)?;
    d.set_item("lambda0", s.lambda0)?;
    Ok(d)
}

/// Read settings from a dict with the keys of [`l21_dict`] (any subset).
fn l21_settings(d: &Bound<'_, PyDict>) -> PyResult<L21Settings> {
    let base = L21Settings::default();
    let known = l21_dict(d.py(), &base)?;
    for key in d.keys() {
        if !known.contains(&key)? {
            return Err(PyValueError::new_err(format!("unknown setting {key}")));
        }
    }
    let name: String = setting(d, "weights", weighting_name(base.weighting).to_string())?;
    let s = L21Settings {
        gamma: setting(d, "gamma", base.gamma)?,
        eps: setting(d, "eps", base.eps)?,
        weighting: weighting(&name)?,
        dtheta_min: setting(d, "dtheta_min", base.dtheta_min)?,
        dphi_min: setting(d, "dphi_min", base.dphi_min)?,
        dvnls_min: setting(d, "dvnls_min", base.dvnls_min)?,
        threshold: setting(d, "threshold", base.threshold)?,
        cone_tol: setting(d, "cone_tol", base.cone_tol)?,
        ftol: setting(d, "ftol", base.ftol)?,
        max_outer: setting(d, "max_outer", base.max_outer)?,
        max_inner: setting(d, "max_inner", base.max_inner)?,
        lambda0: setting(d, "lambda0", base.lambda0)?,
        ..base
    };
    s.validate()?;
    Ok(s)
}

/// The core's default l2,1 settings as a dict (what `lpvid.L21Settings` mirrors).
#[pyfunction]
#[pyo3(name = "l21_defaults")]
fn l21_defaults_py(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    l21_dict(py, &L21Settings::default())
}

/// Levenberg-Marquardt on V_NLS; `settings` as in `LmSettings`.
#[pyfunction]
#[pyo3(name = "fit_nls", signature = (problem, theta, free, settings, callback=None, stable=None))]
fn fit_nls_py<'py>(
    py: Python<'py>,
    problem: &Bound<'py, PyAny>,
    theta: PyReadonlyArray1<'py, f64>,
    free: Option<PyReadonlyArray1<'py, bool>>,
    settings: &Bound<'py, PyDict>,
    callback: Option<Py<PyAny>>,
    stable: Option<PyRef<'py, PyFrozenRange>>,
) -> PyResult<PyFitOutcome> {
    let theta = real_vec(&theta);
    let target = target(problem)?;
    let problem = target.objective();
    let free = free_set(problem.shape(), free)?;
    let settings = lm_settings(settings)?;
    let stable = stable.as_deref();
    let (fit, signalled) = with_monitor(py, callback, |monitor| {
        problem.shape().check_theta(&theta)?;
        with_stability(problem, stable, |objective| {
            levenberg_marquardt(objective, &theta, &free, &settings, monitor)
        })
    })?;
    PyFitOutcome::new(py, fit, signalled)
}

/// Reweighted l2,1 fit (Algorithm 1); `settings` as in `L21Settings`.
#[pyfunction]
#[pyo3(name = "fit_l21", signature = (problem, theta, sup_norms, free, settings, callback=None, stable=None, pinned=None))]
#[allow(clippy::too_many_arguments)]
fn fit_l21_py<'py>(
    py: Python<'py>,
    problem: &Bound<'py, PyAny>,
    theta: PyReadonlyArray1<'py, f64>,
    sup_norms: PyReadonlyArray1<'py, f64>,
    free: Option<PyReadonlyArray1<'py, bool>>,
    settings: &Bound<'py, PyDict>,
    callback: Option<Py<PyAny>>,
    stable: Option<PyRef<'py, PyFrozenRange>>,
    pinned: Option<(PyReadonlyArray2<'py, f64>, PyReadonlyArray2<'py, f64>, f64)>,
) -> PyResult<PyFitOutcome> {
    let theta = real_vec(&theta);
    let sup = real_vec(&sup_norms);
    let target = target(problem)?;
    let problem = target.objective();
    let free = free_set(problem.shape(), free)?;
    let settings = l21_settings(settings)?;
    let stable = stable.as_deref();
    let pinned = pinned
        .map(|(dirs, exempt, weight)| pinned_directions(&dirs, &exempt, weight, free.len()))
        .transpose()?;
    let (fit, signalled) = with_monitor(py, callback, |monitor| {
        with_stability(problem, stable, |objective| {
            fit_l21(
                objective,
                &theta,
                &free,
                &sup,
                &settings,
                pinned.as_ref(),
                monitor,
            )
        })
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
#[allow(clippy::too_many_arguments)]
fn l21_path_py<'py>(
    py: Python<'py>,
    problem: &Bound<'py, PyAny>,
    theta: PyReadonlyArray1<'py, f64>,
    sup_norms: PyReadonlyArray1<'py, f64>,
    gammas: PyReadonlyArray1<'py, f64>,
    free: Option<PyReadonlyArray1<'py, bool>>,
    settings: &Bound<'py, PyDict>,
    callback: Option<Py<PyAny>>,
    stable: Option<PyRef<'py, PyFrozenRange>>,
) -> PyResult<PyPathOutcome> {
    let theta = real_vec(&theta);
    let sup = real_vec(&sup_norms);
    let gammas = real_vec(&gammas);
    let target = target(problem)?;
    let problem = target.objective();
    let free = free_set(problem.shape(), free)?;
    let settings = l21_settings(settings)?;
    let stable = stable.as_deref();
    let (fits, signalled) = with_monitor(py, callback, |monitor| {
        with_stability(problem, stable, |objective| {
            l21_path(objective, &theta, &free, &sup, &gammas, &settings, monitor)
        })
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
    settings: &Bound<'py, PyDict>,
    mu: f64,
) -> PyResult<PyConeStep> {
    let theta = real_vec(&theta);
    let sup = real_vec(&sup_norms);
    let target = target(problem)?;
    let problem = target.objective();
    let free = free_set(problem.shape(), free)?;
    let settings = l21_settings(settings)?;
    let report = detached(py, || {
        single_cone_step(problem, &theta, &free, &sup, &settings, mu)
    })?;
    Ok(PyConeStep::new(py, report))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyFitOutcome>()?;
    m.add_class::<PyPathOutcome>()?;
    m.add_class::<PyConeStep>()?;
    m.add_function(wrap_pyfunction!(cone_step_py, m)?)?;
    m.add_function(wrap_pyfunction!(l21_defaults_py, m)?)?;
    m.add_function(wrap_pyfunction!(fit_nls_py, m)?)?;
    m.add_function(wrap_pyfunction!(fit_l21_py, m)?)?;
    m.add_function(wrap_pyfunction!(l21_path_py, m)?)?;
    Ok(())
}
