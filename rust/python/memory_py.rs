//! The memory estimate of a fit for Python, and the test hook of the
//! out-of-memory path.

use super::convert::bool_vec;
use super::model_py::ShapeArg;
use crate::base::layout::FreeSet;
use crate::fit::estimate::{FitSizes, Method, TimeSizes};
use crate::memory::fail_allocation_after;
use numpy::PyReadonlyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Bytes a fit of a model of `shape` `(n, r, l, nb)` needs at its peak, by part (`evaluation`, `held`, `step`,
/// `total`), and the `threads` it was estimated for. `method`: "lm" or
/// "l21"; `frf`: (points, lines) of FRF data; `records`: the lengths of
/// the time records.
#[pyfunction]
#[pyo3(name = "fit_memory", signature = (shape, method, free=None, frf=None, records=None, hold=false, estimate_x0=false, pinned=false))]
// One Rust parameter per Python parameter (PyO3), and Python's signature stays.
#[allow(clippy::too_many_arguments)]
fn fit_memory_py<'py>(
    py: Python<'py>,
    shape: ShapeArg,
    method: &str,
    free: Option<PyReadonlyArray1<'py, bool>>,
    frf: Option<(usize, usize)>,
    records: Option<Vec<usize>>,
    hold: bool,
    estimate_x0: bool,
    pinned: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let shape = shape.0;
    let mask = free.as_ref().map(bool_vec);
    let free = FreeSet::for_shape(&shape, mask.as_deref())?;
    let method = match method {
        "lm" => Method::Lm,
        "l21" => Method::L21 { pinned },
        other => {
            return Err(PyValueError::new_err(format!(
                "method: expected 'lm' or 'l21', got {other:?}"
            )))
        }
    };
    let sizes = FitSizes {
        shape,
        free,
        frf,
        time: records.map(|lengths| TimeSizes {
            lengths,
            hold,
            estimate_x0,
        }),
        threads: rayon::current_num_threads(),
    };
    let e = sizes.estimate(method);
    let d = PyDict::new(py);
    d.set_item("evaluation", e.evaluation)?;
    d.set_item("held", e.held)?;
    d.set_item("step", e.step)?;
    d.set_item("total", e.total)?;
    d.set_item("threads", sizes.threads)?;
    Ok(d)
}

/// Test hook: the fallible allocation after the next `count` fails (once);
/// None disarms it.
#[pyfunction]
#[pyo3(name = "_fail_allocation_after", signature = (count=None))]
fn fail_allocation_after_py(count: Option<usize>) {
    fail_allocation_after(count);
}

/// Test hook: bytes of freed large blocks the extension's allocator keeps
/// for reuse, and the most it keeps (`crate::memory::blocks`); None where
/// it is not in use (not Linux).
#[pyfunction]
#[pyo3(name = "_kept_blocks")]
fn kept_blocks_py() -> Option<(usize, usize)> {
    #[cfg(target_os = "linux")]
    return Some((
        super::ALLOCATOR.kept_bytes(),
        crate::memory::blocks::KEEP_BYTES,
    ));
    #[cfg(not(target_os = "linux"))]
    None
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(fit_memory_py, m)?)?;
    m.add_function(wrap_pyfunction!(fail_allocation_after_py, m)?)?;
    m.add_function(wrap_pyfunction!(kept_blocks_py, m)?)?;
    Ok(())
}
