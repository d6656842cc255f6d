//! What the fitting routines return to Python: one typed, read-only object
//! per kind ([`PyFitOutcome`] for `fit_nls` and `fit_l21`,
//! [`PyPathOutcome`] for `l21_path`, [`PyConeStep`] for `cone_step`), read
//! by `python/lpvid/fit/results.py`. The rows of a fit's history stay dicts:
//! they are what the progress callback receives and what
//! `lpvid.FitResult.history` holds.

use super::convert::to_py;
use crate::fit::{Fit, Iteration, StepKind, Stop};
use crate::l21::ConeStepReport;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// One row of a fit's history (and the progress callback's argument).
pub(super) fn iteration_dict<'py>(py: Python<'py>, it: &Iteration) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let kind = match it.kind {
        StepKind::Lm => "lm",
        StepKind::Socp => "socp",
    };
    d.set_item("kind", kind)?;
    d.set_item("outer", it.outer)?;
    d.set_item("vnls", it.vnls)?;
    d.set_item("objective", it.objective)?;
    d.set_item("step_norm", it.step_norm)?;
    d.set_item("lambda", it.lambda)?;
    d.set_item("accepted", it.accepted)?;
    d.set_item("gain_ratio", it.gain_ratio)?;
    d.set_item("status", &it.status)?;
    d.set_item("solver_iterations", it.solver_iterations)?;
    d.set_item("seconds", it.seconds)?;
    Ok(d)
}

fn stop_code(stop: Stop) -> &'static str {
    match stop {
        Stop::StepSize => "step_size",
        Stop::CostChange => "cost_change",
        Stop::Gradient => "gradient",
        Stop::Weights => "weights",
        Stop::Settled => "settled",
        Stop::MaxIterations => "max_iterations",
        Stop::Damping => "damping",
        Stop::Interrupted => "interrupted",
        Stop::NothingFree => "nothing_free",
    }
}

/// Stop code and message of the fit for Python; `signalled`: Ctrl-C stopped it.
fn stop_of(fit: &Fit, signalled: bool) -> (&'static str, &'static str) {
    if signalled && fit.stop == Stop::Interrupted {
        (
            "keyboard_interrupt",
            "interrupted by Ctrl-C (SIGINT); the best model so far is returned",
        )
    } else {
        (stop_code(fit.stop), fit.stop.message())
    }
}

/// The outcome of one fit (`fit_nls`, `fit_l21`, or one gamma of `l21_path`).
#[pyclass(name = "FitOutcome", module = "lpvid._core", frozen, get_all)]
pub struct PyFitOutcome {
    /// The best parameters reached.
    theta: Py<PyArray1<f64>>,
    /// V_NLS at `theta`.
    vnls: f64,
    /// The minimised objective at `theta`.
    objective: f64,
    /// Short code of the reason for stopping.
    stop: &'static str,
    /// The reason in words.
    message: &'static str,
    /// Whether a convergence test stopped the fit.
    converged: bool,
    /// Whether the callback or Ctrl-C stopped the fit.
    interrupted: bool,
    /// Reweighting iterations run (l2,1 fits).
    outer_iterations: usize,
    /// Steps computed and not taken.
    n_rejected: usize,
    /// Mean seconds per Levenberg-Marquardt step (NaN when none ran).
    lm_iter_s: f64,
    /// Mean seconds per cone step (NaN when none ran).
    socp_iter_s: f64,
    /// Seconds of the whole fit.
    total_s: f64,
    /// One dict per computed step, as the callback received them.
    history: Py<PyList>,
    /// The final reweighting weights, one per group (l2,1 fits).
    weights: Py<PyArray1<f64>>,
}

impl PyFitOutcome {
    /// The outcome of `fit`; `signalled`: Ctrl-C stopped it.
    pub(super) fn new(py: Python<'_>, fit: Fit, signalled: bool) -> PyResult<Self> {
        let (stop, message) = stop_of(&fit, signalled);
        let history = PyList::empty(py);
        for it in &fit.history {
            history.append(iteration_dict(py, it)?)?;
        }
        Ok(PyFitOutcome {
            vnls: fit.vnls,
            objective: fit.objective,
            stop,
            message,
            converged: fit.stop.converged(),
            interrupted: fit.stop == Stop::Interrupted,
            outer_iterations: fit.outer_iterations,
            n_rejected: fit.rejected(),
            lm_iter_s: fit.mean_seconds(StepKind::Lm),
            socp_iter_s: fit.mean_seconds(StepKind::Socp),
            total_s: fit.total_seconds,
            history: history.unbind(),
            weights: to_py(py, fit.weights).unbind(),
            theta: to_py(py, fit.theta).unbind(),
        })
    }
}

/// The outcome of a warm-started gamma path: one fit per gamma, largest
/// gamma first (fewer than asked when Ctrl-C stopped the path).
#[pyclass(name = "PathOutcome", module = "lpvid._core", frozen, get_all)]
pub struct PyPathOutcome {
    /// The gammas fitted, largest first.
    gammas: Vec<f64>,
    /// The fit at each gamma.
    fits: Vec<Py<PyFitOutcome>>,
}

impl PyPathOutcome {
    /// The outcome of the path's `(gamma, fit)` pairs; `signalled`: Ctrl-C stopped it.
    pub(super) fn new(py: Python<'_>, path: Vec<(f64, Fit)>, signalled: bool) -> PyResult<Self> {
        let mut gammas = Vec::with_capacity(path.len());
        let mut fits = Vec::with_capacity(path.len());
        for (gamma, fit) in path {
            gammas.push(gamma);
            fits.push(Py::new(py, PyFitOutcome::new(py, fit, signalled)?)?);
        }
        Ok(PyPathOutcome { gammas, fits })
    }
}

#[pymethods]
impl PyPathOutcome {
    /// Number of fits.
    fn __len__(&self) -> usize {
        self.fits.len()
    }
}

/// One cone step (for tests and inspection).
#[pyclass(name = "ConeStep", module = "lpvid._core", frozen, get_all)]
pub struct PyConeStep {
    /// The step over the free parameters, or None when the solver gave none.
    step: Option<Py<PyArray1<f64>>>,
    /// The subproblem's objective at the step.
    objective: f64,
    /// Clarabel's status.
    status: String,
    /// The reweighting weight `phi` of every group.
    phi: Py<PyArray1<f64>>,
    /// The scale `varphi` of every group.
    varphi: Py<PyArray1<f64>>,
}

impl PyConeStep {
    pub(super) fn new(py: Python<'_>, report: ConeStepReport) -> Self {
        let groups = &report.groups;
        PyConeStep {
            phi: to_py(py, groups.iter().map(|g| g.phi).collect()).unbind(),
            varphi: to_py(py, groups.iter().map(|g| g.varphi).collect()).unbind(),
            step: report.step.map(|s| to_py(py, s).unbind()),
            objective: report.objective,
            status: report.status,
        }
    }
}
