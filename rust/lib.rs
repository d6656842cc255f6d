//! lpvid: identification of linear parameter-varying state-space models from
//! frequency-response data at frozen scheduling values, with reweighted
//! l2,1-norm regularisation (Turk, Gillis, Pipeleers and Swevers, 2018).
//!
//! The numerical core knows nothing of Python; the binding lives in the
//! private `python` module, behind the `python` feature.

#![warn(missing_docs)]

pub mod base;
pub mod error;
pub mod eval;
pub mod fit;
pub mod l21;
pub mod memory;
pub mod simulate;
pub mod socp;
#[doc(hidden)]
pub mod testing;
pub mod time;

#[cfg(feature = "python")]
mod python;

pub use base::data::FrfData;
pub use base::layout::{FreeSet, Group, Matrix, Shape};
pub use error::{Error, Result};
pub use eval::model::ModelAt;
pub use eval::objective::{GaussNewton, Objective};
pub use eval::problem::Problem;
pub use eval::response::frequency_response;
pub use eval::sum::Sum;
pub use fit::lm::{levenberg_marquardt, LmSettings};
pub use fit::stable::{FrozenRange, Stable};
pub use fit::{Fit, Iteration, Monitor, Silent, StepKind, Stop};
pub use l21::{fit_l21, l21_path, L21Settings, Weighting};
pub use time::{InitialState, Record, TimeProblem};
