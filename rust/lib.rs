//! lpvid: identification of linear parameter-varying state-space models from
//! frequency-response data at frozen scheduling values, with reweighted
//! l2,1-norm regularisation (Turk, Gillis, Pipeleers and Swevers, 2018).
//!
//! The numerical core knows nothing of Python; the binding lives in
//! [`python`] behind the `python` feature.

#![warn(missing_docs)]

pub mod data;
pub mod dense;
pub mod error;
pub mod fit;
pub mod gram_product;
pub mod kron_gram;
pub mod l21;
pub mod lanes;
pub mod layout;
pub mod lm;
pub mod lti;
pub mod memory;
pub mod objective;
pub mod point_factors;
pub mod point_sums;
pub mod problem;
pub mod response;
pub mod route;
pub mod sensitivity;
pub mod simulate;
pub mod socp;
pub mod stable;
pub mod sum;
#[doc(hidden)]
pub mod testing;
pub mod time;

#[cfg(feature = "python")]
mod python;

pub use data::FrfData;
pub use error::{Error, Result};
pub use fit::{Fit, Iteration, Monitor, Silent, StepKind, Stop};
pub use l21::{fit_l21, l21_path, L21Settings, Weighting};
pub use layout::{FreeSet, Group, Matrix, Shape};
pub use lm::{levenberg_marquardt, LmSettings};
pub use objective::{GaussNewton, Objective};
pub use problem::Problem;
pub use response::frequency_response;
pub use stable::{FrozenRange, Stable};
pub use sum::Sum;
pub use time::{InitialState, Record, TimeProblem};
