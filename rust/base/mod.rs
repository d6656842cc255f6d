//! The foundations every other folder stands on: the parameter layout
//! ([`layout`]), FRF data ([`data`]), complex numbers in lanes ([`lanes`]),
//! the choice of vector route ([`route`]), small dense algebra
//! ([`dense`]) and whether a loop's work is worth the thread pool
//! ([`spread`]).

pub mod data;
pub mod dense;
pub mod lanes;
pub mod layout;
pub mod route;
pub mod spread;
