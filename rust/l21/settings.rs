//! Settings of the reweighted l2,1 fit ([`super::fit_l21`]), with their
//! defaults and checks.

use crate::error::{invalid, Result};
use crate::socp::DEFAULT_CONE_TOL;

/// The reweighting rule (method.md (21)-(23)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Weighting {
    /// (23) with the scale (25): `phi = 1 / (||theta_i|| ||psi_i|| / ||theta_0|| + eps)`.
    /// Groups whose `X(0)` is zero or fixed fall back to (22).
    Relative,
    /// (22): `phi = 1 / (||theta_i|| ||psi_i|| + eps)`, scale `||psi_i||`.
    Scaled,
    /// (21): `phi = 1 / (||theta_i|| + eps)`, scale 1.
    Plain,
}

/// Settings of [`fit_l21`](crate::l21::fit_l21).
#[derive(Debug, Clone, Copy)]
pub struct L21Settings {
    /// Regularisation weight (normalised: multiplies the penalty next to `V_NLS / M`).
    pub gamma: f64,
    /// `eps` of the weights.
    pub eps: f64,
    /// The reweighting rule.
    pub weighting: Weighting,
    /// Inner loop stops when `||d|| <= dtheta_min (||theta_free|| + dtheta_min)`.
    pub dtheta_min: f64,
    /// Outer loop stops when `max_g |phi_g - phi_prev_g| / phi_prev_g <= dphi_min`.
    pub dphi_min: f64,
    /// Outer loop also stops when the groups in use stay the same and V_NLS
    /// changes by at most `dvnls_min` (relative) over an outer iteration.
    pub dvnls_min: f64,
    /// Relative magnitude (23) above which a group counts as in use.
    pub threshold: f64,
    /// Accuracy of the cone solves (Clarabel's gap and feasibility
    /// tolerances; Newton's method's decrement, relative to the objective).
    pub cone_tol: f64,
    /// Solve each cone step by Newton's method first, by Clarabel where it
    /// gives up (see [`crate::socp`]); false: by Clarabel alone. Not a
    /// Python setting: the core's own tests measure Clarabel's worst case
    /// with it.
    pub newton: bool,
    /// Inner loop also stops when an accepted step lowers the objective by
    /// less than `ftol` times its value (about `V_NLS / M`: the default
    /// 1e-4 is far below the noise in `V_NLS / M`, `1 / sqrt(M)`).
    pub ftol: f64,
    /// Most outer (reweighting) iterations (the stopping tests are made
    /// once more after the last).
    pub max_outer: usize,
    /// Most cone steps per outer iteration. Few steps per reweighting work
    /// best: long inner loops mostly slide along similarity transforms.
    pub max_inner: usize,
    /// Initial damping `lambda`.
    pub lambda0: f64,
}

impl Default for L21Settings {
    fn default() -> Self {
        L21Settings {
            gamma: 1e-3,
            eps: 1e-3,
            weighting: Weighting::Relative,
            dtheta_min: 1e-6,
            dphi_min: 1e-3,
            dvnls_min: 1e-3,
            threshold: 1e-6,
            cone_tol: DEFAULT_CONE_TOL,
            newton: true,
            ftol: 1e-4,
            max_outer: 20,
            max_inner: 10,
            lambda0: 1e-2,
        }
    }
}

impl L21Settings {
    /// Check every field.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("gamma", self.gamma),
            ("dtheta_min", self.dtheta_min),
            ("dphi_min", self.dphi_min),
            ("dvnls_min", self.dvnls_min),
            ("threshold", self.threshold),
            ("ftol", self.ftol),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(
                    name,
                    format!("expected a finite number >= 0, got {v}"),
                ));
            }
        }
        for (name, v) in [
            ("eps", self.eps),
            ("lambda0", self.lambda0),
            ("cone_tol", self.cone_tol),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(invalid(
                    name,
                    format!("expected a finite number > 0, got {v}"),
                ));
            }
        }
        if self.max_outer == 0 || self.max_inner == 0 {
            return Err(invalid("max_outer", "iteration limits must be at least 1"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::L21Settings;
    use crate::error::Error;

    /// The name of the field `validate` refuses after `change`, if any.
    fn refused(change: impl Fn(&mut L21Settings)) -> Option<&'static str> {
        let mut s = L21Settings::default();
        change(&mut s);
        match s.validate() {
            Ok(()) => None,
            Err(Error::InvalidArgument { name, .. }) => Some(name),
            Err(e) => panic!("not an argument error: {e:?}"),
        }
    }

    type Field = fn(&mut L21Settings) -> &mut f64;

    #[test]
    fn fields_that_may_be_zero_refuse_negative_and_non_finite_values() {
        let fields: [(&str, Field); 6] = [
            ("gamma", |s| &mut s.gamma),
            ("dtheta_min", |s| &mut s.dtheta_min),
            ("dphi_min", |s| &mut s.dphi_min),
            ("dvnls_min", |s| &mut s.dvnls_min),
            ("threshold", |s| &mut s.threshold),
            ("ftol", |s| &mut s.ftol),
        ];
        assert_eq!(refused(|_| ()), None);
        for (name, field) in fields {
            assert_eq!(refused(|s| *field(s) = 0.0), None, "{name} = 0");
            for bad in [-1e-300, f64::NAN, f64::INFINITY] {
                assert_eq!(refused(|s| *field(s) = bad), Some(name), "{name} = {bad}");
            }
        }
    }

    #[test]
    fn fields_that_must_be_positive_refuse_zero() {
        let fields: [(&str, Field); 3] = [
            ("eps", |s| &mut s.eps),
            ("lambda0", |s| &mut s.lambda0),
            ("cone_tol", |s| &mut s.cone_tol),
        ];
        for (name, field) in fields {
            assert_eq!(refused(|s| *field(s) = 1e-300), None, "{name} = 1e-300");
            for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
                assert_eq!(refused(|s| *field(s) = bad), Some(name), "{name} = {bad}");
            }
        }
    }

    #[test]
    fn iteration_limits_are_at_least_one() {
        assert_eq!(refused(|s| s.max_outer = 0), Some("max_outer"));
        assert_eq!(refused(|s| s.max_inner = 0), Some("max_outer"));
        assert_eq!(
            refused(|s| {
                s.max_outer = 1;
                s.max_inner = 1
            }),
            None
        );
    }
}
