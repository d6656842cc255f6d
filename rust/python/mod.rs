//! The Python binding `lpvid._core`: conversions, exceptions and thin
//! wrappers. Nothing numerical happens here.

mod convert;
mod fit_py;
mod memory_py;
mod model_py;
mod outcome_py;
mod pool;
mod problem_py;
mod settings_py;
mod simulate_py;
mod time_py;
mod trust_py;

use pyo3::prelude::*;

/// The extension's own allocations: large blocks mapped whole and reused
/// whole, so that a run's resident memory follows its live arrays
/// ([`crate::memory::blocks`]).
#[cfg(target_os = "linux")]
#[global_allocator]
static ALLOCATOR: crate::memory::blocks::Blocks = crate::memory::blocks::Blocks::new();

pyo3::create_exception!(
    _core,
    SingularModelError,
    pyo3::exceptions::PyArithmeticError,
    "zI - A(p) is singular, or the frequency response overflowed, at some scheduling point \
     and frequency."
);

/// The instruction-set extensions this build may use (build.rs), between a
/// marker and a semicolon: `python/lpvid/_cpu.py` finds this string in the
/// module's file and checks the processor before the module is loaded (code
/// built for AVX2 may use it anywhere, module initialisation included).
const TARGET_FEATURES: &str = concat!("lpvid-target-features:", env!("LPVID_TARGET_FEATURES"), ";");

/// The route of the core's hand-written vector code that this process runs
/// (`"avx512"`, `"avx2"` or `"portable"`; [`crate::base::route`]).
#[pyfunction]
fn kernel_route() -> &'static str {
    crate::base::route::Route::current().name()
}

/// From now on, run every loop of the core started from this thread in
/// order on it (`here`), or on the thread pool when its work is worth it;
/// returns the setting before ([`crate::base::spread::in_order_here`]).
#[pyfunction]
fn _loops_here(here: bool) -> bool {
    crate::base::spread::in_order_here(here)
}

/// The compiled core of lpvid (private: use the `lpvid` package).
#[pymodule]
#[pyo3(name = "_core")]
fn core_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    #[cfg(target_os = "linux")]
    crate::memory::blocks::system_heaps();
    pool::loaded_here();
    // faer's calls that are not told their parallelism run on one thread:
    // some of them sum in another order on another number of threads (see
    // `crate::base::dense`), and no result may depend on the machine's cores.
    faer::set_global_parallelism(faer::Par::Seq);
    // The package version, from Cargo.toml (lpvid.__version__).
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("__target_features__", TARGET_FEATURES)?;
    m.add(
        "SingularModelError",
        m.py().get_type::<SingularModelError>(),
    )?;
    m.add_function(wrap_pyfunction!(kernel_route, m)?)?;
    m.add_function(wrap_pyfunction!(_loops_here, m)?)?;
    m.add_class::<model_py::PyModelView>()?;
    problem_py::register(m)?;
    fit_py::register(m)?;
    settings_py::register(m)?;
    memory_py::register(m)?;
    simulate_py::register(m)?;
    time_py::register(m)?;
    trust_py::register(m)?;
    Ok(())
}
