//! A model seen at some scheduling points: its shape, its parameters and
//! the basis values at the points ([`ModelAt`]), which the responses, the
//! LTI Jacobian and the simulation take as one; and the basis values with
//! the constant function in front ([`with_constant`]).

use crate::base::layout::Shape;
use crate::error::{invalid, Result};

/// A model at `n_points` scheduling points: the shape, the parameters
/// `theta` and the basis values `psi_1..psi_Nb` at the points, `n_points x
/// Nb` row-major. Borrowed, not copied (a simulation's trajectory may be
/// tens of megabytes), and not checked here: the routines that take it
/// check what they use, `theta`'s length and values and the number and
/// values of the basis values, and name the offending argument.
#[derive(Debug, Clone, Copy)]
pub struct ModelAt<'a> {
    /// The model's sizes.
    pub shape: Shape,
    /// The parameters, laid out as [`Shape::block`] says.
    pub theta: &'a [f64],
    /// `psi_1..psi_Nb` at each point, `n_points x Nb` row-major (the
    /// constant `psi_0 = 1` is not included).
    pub basis: &'a [f64],
    /// Number of scheduling points.
    pub n_points: usize,
}

impl<'a> ModelAt<'a> {
    /// The model `(shape, theta)` at `n_points` points with the given basis
    /// values.
    pub fn new(shape: Shape, theta: &'a [f64], basis: &'a [f64], n_points: usize) -> Self {
        ModelAt {
            shape,
            theta,
            basis,
            n_points,
        }
    }

    /// Check `theta` (length, finite) and the basis values (count, finite)
    /// in that order, and return the basis values with the constant in
    /// front (see [`with_constant`]).
    pub fn checked_psi(&self) -> Result<Vec<f64>> {
        self.shape.check_theta(self.theta)?;
        with_constant(self.basis, self.n_points, self.shape.nb)
    }
}

/// Prepend the constant basis function to `N x Nb` basis values, giving the
/// `N x (Nb + 1)` rows `[1, psi_1(p[q]), ..., psi_Nb(p[q])]`.
pub fn with_constant(basis: &[f64], n_points: usize, nb: usize) -> Result<Vec<f64>> {
    if basis.len() != n_points * nb {
        return Err(invalid(
            "psi",
            format!(
                "expected {} basis values ({} points x {} functions), got {}",
                n_points * nb,
                n_points,
                nb,
                basis.len()
            ),
        ));
    }
    if basis.iter().any(|v| !v.is_finite()) {
        return Err(invalid("psi", "basis values contain NaN or Inf"));
    }
    let mut psi = Vec::with_capacity(n_points * (nb + 1));
    for q in 0..n_points {
        psi.push(1.0);
        psi.extend_from_slice(&basis[q * nb..(q + 1) * nb]);
    }
    Ok(psi)
}
