//! The evaluation of FRF data: a model at its scheduling points
//! ([`model`]), frozen models and their responses ([`lti`], [`response`]),
//! the residual, V_NLS, its gradient and the Gauss-Newton matrix of a
//! [`problem::Problem`] from the Kronecker structure of the Jacobian
//! ([`kron_gram`], on [`crate::base::gram_product`]; [`point_sums`], [`point_factors`];
//! the evaluations' scratch space in `workspace`),
//! the sensitivities ([`sensitivity`]), and what the optimisers need of
//! any cost ([`objective`], [`sum`]).

pub mod kron_gram;
pub mod lti;
pub mod model;
pub mod objective;
pub mod point_factors;
pub mod point_sums;
pub mod problem;
pub mod response;
pub mod sensitivity;
pub mod sum;
pub(crate) mod workspace;
