//! The foundations every other folder stands on: the parameter layout
//! ([`layout`]), FRF data ([`data`]), complex numbers in lanes ([`lanes`]),
//! the choice of vector route ([`route`]) and small dense algebra
//! ([`dense`]).

pub mod data;
pub mod dense;
pub mod lanes;
pub mod layout;
pub mod route;
