//! The fits' settings as Python passes them: a dict of any subset of the
//! keys of `LmSettings` or `L21Settings`, read by PyO3 (as the type of the
//! `settings` argument) into the core's typed settings and validated. An
//! unknown key is refused, a missing key keeps its default, and a value of
//! the wrong type is named by its key.

use crate::fit::lm::LmSettings;
use crate::l21::{L21Settings, Weighting};
use pyo3::conversion::FromPyObjectOwned;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A settings dict, its keys checked against those it may have.
struct Keyed<'a, 'py>(Borrowed<'a, 'py, PyDict>);

impl<'a, 'py> Keyed<'a, 'py> {
    fn new(ob: Borrowed<'a, 'py, PyAny>, known: &[&str]) -> PyResult<Self> {
        let d = ob.cast::<PyDict>()?;
        for key in d.keys() {
            let name: Option<String> = key.extract().ok();
            if !name.is_some_and(|k| known.contains(&k.as_str())) {
                return Err(PyValueError::new_err(format!(
                    "unknown setting {}",
                    key.repr()?
                )));
            }
        }
        Ok(Keyed(d))
    }

    /// The value of `key`, or `default` when the dict has none.
    fn get<T: FromPyObjectOwned<'py>>(&self, key: &str, default: T) -> PyResult<T> {
        match self.0.get_item(key)? {
            Some(v) => v
                .extract()
                .map_err(|_| PyValueError::new_err(format!("{key}: has the wrong type"))),
            None => Ok(default),
        }
    }
}

/// `fit_nls`'s settings: [`LmSettings`] from a dict of its keys, validated.
pub struct LmArg(pub LmSettings);

impl<'a, 'py> FromPyObject<'a, 'py> for LmArg {
    type Error = PyErr;

    fn extract(ob: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        let d = Keyed::new(ob, &["max_iter", "xtol", "ftol", "gtol", "lambda0"])?;
        let base = LmSettings::default();
        let s = LmSettings {
            max_iter: d.get("max_iter", base.max_iter)?,
            xtol: d.get("xtol", base.xtol)?,
            ftol: d.get("ftol", base.ftol)?,
            gtol: d.get("gtol", base.gtol)?,
            lambda0: d.get("lambda0", base.lambda0)?,
        };
        s.validate()?;
        Ok(LmArg(s))
    }
}

/// The keys of [`L21Arg`]: those [`l21_dict`] writes (Python passes them all
/// back, so a key missing here fails every l2,1 fit of the Python tests).
const L21_KEYS: [&str; 12] = [
    "gamma",
    "eps",
    "weights",
    "dtheta_min",
    "dphi_min",
    "dvnls_min",
    "threshold",
    "cone_tol",
    "ftol",
    "max_outer",
    "max_inner",
    "lambda0",
];

/// The settings of `fit_l21`, `l21_path` and `cone_step`: [`L21Settings`]
/// from a dict of the keys of [`l21_dict`], validated.
pub struct L21Arg(pub L21Settings);

impl<'a, 'py> FromPyObject<'a, 'py> for L21Arg {
    type Error = PyErr;

    fn extract(ob: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        let d = Keyed::new(ob, &L21_KEYS)?;
        let base = L21Settings::default();
        let name: String = d.get("weights", weighting_name(base.weighting).to_string())?;
        let s = L21Settings {
            gamma: d.get("gamma", base.gamma)?,
            eps: d.get("eps", base.eps)?,
            weighting: weighting(&name)?,
            dtheta_min: d.get("dtheta_min", base.dtheta_min)?,
            dphi_min: d.get("dphi_min", base.dphi_min)?,
            dvnls_min: d.get("dvnls_min", base.dvnls_min)?,
            threshold: d.get("threshold", base.threshold)?,
            cone_tol: d.get("cone_tol", base.cone_tol)?,
            ftol: d.get("ftol", base.ftol)?,
            max_outer: d.get("max_outer", base.max_outer)?,
            max_inner: d.get("max_inner", base.max_inner)?,
            lambda0: d.get("lambda0", base.lambda0)?,
            ..base
        };
        s.validate()?;
        Ok(L21Arg(s))
    }
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

/// The core's default l2,1 settings as a dict (what `lpvid.L21Settings` mirrors).
#[pyfunction]
#[pyo3(name = "l21_defaults")]
fn l21_defaults_py(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    l21_dict(py, &L21Settings::default())
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(l21_defaults_py, m)?)?;
    Ok(())
}
