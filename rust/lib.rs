//! lpvid: identification of linear parameter-varying state-space models from
//! frequency-response data at frozen scheduling values, with reweighted
//! l2,1-norm regularisation (Turk, Gillis, Pipeleers and Swevers, 2018).
//!
//! The numerical core knows nothing of Python; the binding lives in
//! [`python`] behind the `python` feature.

#![warn(missing_docs)]

pub mod data;
pub mod error;
pub mod lanes;
pub mod layout;
pub mod lti;
pub mod problem;
pub mod response;
pub mod simulate;

#[cfg(feature = "python")]
mod python;

pub use data::FrfData;
pub use error::{Error, Result};
pub use layout::{FreeSet, Group, Matrix, Shape};
pub use problem::{GaussNewton, Problem};
pub use response::frequency_response;
