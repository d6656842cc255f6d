//! Time records for Python: `TimeProblem`, the sum of an FRF problem and a
//! time problem (`SumProblem`), and the one place where the fitting
//! functions find the cost they minimise.

use super::convert::{bool_vec, detached, guarded, real_vec, to_py};
use super::model_py::ShapeArg;
use super::problem_py::PyProblem;
use crate::base::layout::FreeSet;
use crate::eval::objective::Objective;
use crate::eval::sum::Sum;
use crate::time::{InitialState, Record, StageTimes, TimeProblem};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Output error of time records of a model of `shape` `(n, r, l, nb)`: `u`, `psi`, `y` and `sigma` hold one flat
/// row-major array per record (`T x r`, `T x Nb`, `T x l`, `T x l`); `dt`
/// the sample time of a continuous-time model (None: discrete time); `x0`
/// "estimate", "zero" or "given" (with `x0_values`, `records x n`).
#[pyclass(name = "TimeProblem", module = "lpvid._core", frozen)]
pub struct PyTimeProblem {
    pub(crate) inner: TimeProblem,
}

fn initial_state(x0: &str, values: Option<PyReadonlyArray1<'_, f64>>) -> PyResult<InitialState> {
    match (x0, values) {
        ("estimate", None) => Ok(InitialState::Estimate),
        ("zero", None) => Ok(InitialState::Zero),
        ("given", Some(v)) => Ok(InitialState::Given(real_vec(&v))),
        ("given", None) => Err(PyValueError::new_err("x0: 'given' needs x0_values")),
        (other, _) => Err(PyValueError::new_err(format!(
            "x0: expected 'estimate', 'zero' or 'given' (values only with 'given'), got {other:?}"
        ))),
    }
}

fn stage_dict<'py>(py: Python<'py>, t: &StageTimes) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("simulation_s", t.simulation)?;
    d.set_item("discretisation_s", t.discretisation)?;
    d.set_item("sensitivities_s", t.sensitivities)?;
    d.set_item("gram_s", t.gram)?;
    d.set_item("schur_s", t.schur)?;
    d.set_item("total_s", t.total)?;
    Ok(d)
}

#[pymethods]
impl PyTimeProblem {
    #[new]
    #[pyo3(signature = (shape, u, psi, y, sigma, dt=None, x0="estimate", x0_values=None, skip=0))]
    // One Rust parameter per Python parameter (PyO3), and Python's signature stays.
    #[allow(clippy::too_many_arguments)]
    fn new(
        shape: ShapeArg,
        u: Vec<PyReadonlyArray1<'_, f64>>,
        psi: Vec<PyReadonlyArray1<'_, f64>>,
        y: Vec<PyReadonlyArray1<'_, f64>>,
        sigma: Vec<PyReadonlyArray1<'_, f64>>,
        dt: Option<f64>,
        x0: &str,
        x0_values: Option<PyReadonlyArray1<'_, f64>>,
        skip: usize,
    ) -> PyResult<Self> {
        let shape = shape.0;
        let k = u.len();
        if psi.len() != k || y.len() != k || sigma.len() != k {
            return Err(PyValueError::new_err(format!(
                "records: {k} inputs, {} basis values, {} outputs and {} sigmas given",
                psi.len(),
                y.len(),
                sigma.len()
            )));
        }
        let arrays: Vec<_> = (0..k)
            .map(|i| {
                (
                    real_vec(&u[i]),
                    real_vec(&psi[i]),
                    real_vec(&y[i]),
                    real_vec(&sigma[i]),
                )
            })
            .collect();
        let initial = initial_state(x0, x0_values)?;
        let inner = guarded(|| {
            let records = arrays
                .into_iter()
                .map(|(u, psi, y, sigma)| Record::new(&shape, u, psi, y, &sigma))
                .collect::<crate::Result<Vec<_>>>()?;
            TimeProblem::new(shape, records, initial, dt, skip)
        })?;
        Ok(PyTimeProblem { inner })
    }

    /// Number of real residuals in the cost: the noise floor.
    #[getter]
    fn n_residuals(&self) -> usize {
        self.inner.n_residuals()
    }

    /// The cost at `theta`.
    fn vnls(&self, py: Python<'_>, theta: PyReadonlyArray1<'_, f64>) -> PyResult<f64> {
        let theta = real_vec(&theta);
        detached(py, || self.inner.cost(&theta))
    }

    /// Weighted residual of the samples in the cost, record after record.
    fn residual<'py>(
        &self,
        py: Python<'py>,
        theta: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let theta = real_vec(&theta);
        Ok(to_py(py, detached(py, || self.inner.residual(&theta))?))
    }

    /// Initial state of every record, flat `records x n`.
    fn initial_states<'py>(
        &self,
        py: Python<'py>,
        theta: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let theta = real_vec(&theta);
        Ok(to_py(
            py,
            detached(py, || self.inner.initial_states(&theta))?,
        ))
    }

    /// `(V, gradient, J^T J, stage seconds)` over the free parameters.
    #[pyo3(signature = (theta, free=None))]
    #[allow(clippy::type_complexity)]
    fn gauss_newton<'py>(
        &self,
        py: Python<'py>,
        theta: PyReadonlyArray1<'py, f64>,
        free: Option<PyReadonlyArray1<'py, bool>>,
    ) -> PyResult<(
        f64,
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyDict>,
    )> {
        let theta = real_vec(&theta);
        let mask = free.as_ref().map(bool_vec);
        let free = FreeSet::for_shape(self.inner.shape(), mask.as_deref())?;
        let (gn, times) = detached(py, || self.inner.gauss_newton_timed(&theta, &free))?;
        Ok((
            gn.vnls,
            to_py(py, gn.gradient),
            to_py(py, gn.gram),
            stage_dict(py, &times)?,
        ))
    }
}

/// FRF data and time records together: the costs add.
#[pyclass(name = "SumProblem", module = "lpvid._core", frozen)]
pub struct PySumProblem {
    frf: Py<PyProblem>,
    time: Py<PyTimeProblem>,
}

impl PySumProblem {
    fn sum(&self) -> Sum<'_> {
        Sum::new(vec![&self.frf.get().inner, &self.time.get().inner])
            .expect("shapes checked at construction")
    }
}

#[pymethods]
impl PySumProblem {
    #[new]
    fn new(frf: Py<PyProblem>, time: Py<PyTimeProblem>) -> PyResult<Self> {
        Sum::new(vec![&frf.get().inner, &time.get().inner])?;
        Ok(PySumProblem { frf, time })
    }

    /// Complex residuals of the FRF data plus real residuals of the records.
    #[getter]
    fn n_residuals(&self) -> usize {
        self.sum().n_residuals()
    }

    /// The summed cost at `theta`.
    fn vnls(&self, py: Python<'_>, theta: PyReadonlyArray1<'_, f64>) -> PyResult<f64> {
        let theta = real_vec(&theta);
        let sum = self.sum();
        detached(py, || sum.cost(&theta))
    }

    /// `(V, gradient, J^T J)` of the sum over the free parameters.
    #[pyo3(signature = (theta, free=None))]
    #[allow(clippy::type_complexity)]
    fn gauss_newton<'py>(
        &self,
        py: Python<'py>,
        theta: PyReadonlyArray1<'py, f64>,
        free: Option<PyReadonlyArray1<'py, bool>>,
    ) -> PyResult<(f64, Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>)> {
        let theta = real_vec(&theta);
        let sum = self.sum();
        let mask = free.as_ref().map(bool_vec);
        let free = FreeSet::for_shape(sum.shape(), mask.as_deref())?;
        let gn = detached(py, || sum.gauss_newton(&theta, &free))?;
        Ok((gn.vnls, to_py(py, gn.gradient), to_py(py, gn.gram)))
    }
}

/// The cost a fitting function minimises, borrowed from its Python object.
pub(crate) enum Target<'a> {
    One(&'a dyn Objective),
    Sum(Sum<'a>),
}

impl Target<'_> {
    /// The cost.
    pub fn objective(&self) -> &dyn Objective {
        match self {
            Target::One(o) => *o,
            Target::Sum(s) => s,
        }
    }
}

/// The cost behind a `Problem`, `TimeProblem` or `SumProblem`.
pub(crate) fn target<'a>(problem: &'a Bound<'_, PyAny>) -> PyResult<Target<'a>> {
    if let Ok(p) = problem.cast::<PyProblem>() {
        return Ok(Target::One(&p.get().inner));
    }
    if let Ok(p) = problem.cast::<PyTimeProblem>() {
        return Ok(Target::One(&p.get().inner));
    }
    if let Ok(p) = problem.cast::<PySumProblem>() {
        return Ok(Target::Sum(p.get().sum()));
    }
    Err(PyTypeError::new_err(format!(
        "problem: expected a Problem, TimeProblem or SumProblem, got {}",
        problem.get_type().name()?
    )))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyTimeProblem>()?;
    m.add_class::<PySumProblem>()?;
    Ok(())
}
