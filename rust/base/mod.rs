//! The foundations every other folder stands on: the parameter layout
//! ([`layout`]), FRF data ([`data`]), complex numbers in lanes ([`lanes`]),
//! the choice of vector route ([`route`]), small dense algebra
//! ([`dense`], with the Gram products `C += V U^T` of [`gram_product`] and
//! the Cholesky factorisation of [`cholesky`]) and whether a loop's work is worth the thread pool
//! ([`spread`]).

pub mod cholesky;
pub mod data;
pub mod dense;
pub mod gram_product;
pub mod lanes;
pub mod layout;
pub mod route;
pub mod spread;
