//! Newton's method on the cone step's program when every group in it
//! stays away from zero.
//!
//! With `t_g` eliminated the program of [`super::ConeProblem::solve_with`]
//! is the convex function
//!
//! ```text
//! f(x) = 1/2 x^T P x + q^T x + sum_g c_g || z_g(x) ||,   z_g(x) = beta_g + alpha_g o x_g
//! ```
//!
//! (`alpha` zero at a group's fixed entries), smooth wherever no `z_g` is
//! zero. Its Hessian there is `P` plus, per group, `c_g / ||z|| diag(alpha)
//! (I - u u^T) diag(alpha)` with `u = z / ||z||`: one dense Cholesky
//! factorisation per iteration, as one interior-point iteration needs, but
//! from a good start Newton's method needs a few iterations where the
//! interior-point method needs about ten. A damped Newton step (backtracking
//! on `f`) converges on a convex function from any start; near the minimum
//! the full step is taken and the convergence is quadratic.
//!
//! Measured (`benches/bench_scale.py`): 93 % of the gantry path's steps
//! by Newton's method, its path 0.76 -> 0.24 s, the same chosen model; on
//! n = 10 and n = 16, where Clarabel stopped at "AlmostSolved" on most
//! steps, the paths it gave moved with a change of 1e-12 in the data
//! (other step counts, one more group at n = 16) and Newton's do not.
//!
//! A group that shrinks towards zero or that two cut steps were headed
//! for ([`KINK`]: the minimum may sit at its kink, where Newton's method
//! crawls) is held at zero, and let go again when zero is not its minimum
//! (see [`iterate`]); a group that cannot be held (a fixed entry off zero)
//! is named to the caller. It gives up when the Hessian is not positive
//! definite, when a group is let go more than [`RELEASES`] times, or after
//! [`MAX_ITERATIONS`]; the caller then has Clarabel solve the program.

use super::factored::FactoredHessian;
use super::group::{dot, NewtonGroup};
use super::packed::Quadratic;
use super::{ConeGroup, ConeProblem};
use crate::base::dense::{cholesky_solve, factor_lower};
use crate::error::Result;
use faer::{Mat, MatRef};

/// Most Newton iterations before the cone solver takes over.
const MAX_ITERATIONS: u32 = 40;

/// A group whose `||z_g||` falls below this during the iterations may be
/// on its way to zero (the relative magnitude of (25), as
/// [`super::SNAP`]): it is held there.
const COLLAPSE: f64 = 1e-6;

/// Sufficient decrease of the backtracking line search (a fraction of the
/// decrease the Newton model predicts).
const ARMIJO: f64 = 0.25;

/// Shortest step of the line search before giving up.
const MIN_STEP: f64 = 1e-10;

/// Two steps in a row cut by the line search whose full length would take
/// the same group within this fraction of its norm of zero are taken for a
/// minimum at (or next to) that group's kink. Newton's method crawls there, the group's
/// norm shrinking by a factor per iteration (measured: steps cut to 1/8,
/// then 1/128, then 1e-4 and less, the group's norm 0.66, 0.035, 5e-4 ...)
/// where holding it at zero (and letting it go if zero is not optimal)
/// takes a few.
const KINK: f64 = 0.1;

/// Times a group held at zero may be let go again (see [`iterate`]).
const RELEASES: u32 = 2;

/// The smallest tolerance on the Newton decrement (relative to `|f|`):
/// below it the line search's test of sufficient decrease would compare
/// rounding errors of `f`.
const FLOOR_TOL: f64 = 1e-13;

/// How Newton's method ended, with the iterations it took.
#[derive(Debug, Clone)]
pub(super) enum Newton {
    /// The minimiser.
    Solved { x: Vec<f64>, iterations: u32 },
    /// It gave up with this group (an index into the groups given) on its
    /// way to zero: its minimum may sit at that group's kink.
    Kink { group: usize, iterations: u32 },
    /// It gave up for another reason (see the module notes).
    GaveUp { iterations: u32 },
}

/// `f` along the line `x + t dx`, from the quadratic's pieces at `x`.
struct Line<'a> {
    x: &'a [f64],
    dx: &'a [f64],
    groups: &'a [NewtonGroup],
    /// `1/2 x^T P x + q^T x`, `(P x + q)^T dx` and `dx^T P dx`.
    value: f64,
    slope: f64,
    curvature: f64,
}

impl Line<'_> {
    fn at(&self, t: f64) -> f64 {
        let trial: Vec<f64> = self.x.iter().zip(self.dx).map(|(x, d)| x + t * d).collect();
        let penalty: f64 = self.groups.iter().map(|g| g.weight * g.norm(&trial)).sum();
        self.value + t * self.slope + 0.5 * t * t * self.curvature + penalty
    }
}

/// Minimise `f` from `x = 0`, or from `start`, to `tol` (the Newton
/// decrement `g^T H^-1 g` at most `tol max(1, |f|)`, `tol` at least
/// [`FLOOR_TOL`], then one more full step: quadratically closer), or why
/// Newton's method gave up (see the module notes); the error is
/// [`crate::Error::OutOfMemory`] only.
///
/// The Hessians are formed and factored in `p` itself, `P` kept packed
/// (half a dense matrix) and written back on return: at n = 16, a second
/// dense matrix for each of the two steps solved at once (13 MB each) put
/// the fit above its memory estimate, which counts Clarabel's program.
pub(super) fn newton(
    p: &mut Mat<f64>,
    q: &[f64],
    groups: &[NewtonGroup],
    tol: f64,
    start: Option<Vec<f64>>,
    factored: Option<&FactoredHessian>,
    schur: Option<MatRef<'_, f64>>,
) -> Result<Newton> {
    let quadratic = Quadratic::of(p, schur)?;
    let x = start.unwrap_or_else(|| vec![0.0; q.len()]);
    let out = iterate(p, &quadratic, q, groups, tol, x, factored);
    quadratic.fill(p);
    out
}

impl NewtonGroup {
    /// Whether the group can be held at zero (no fixed entry off zero).
    fn can_hold(&self) -> bool {
        self.fixed_squares == 0.0
    }

    /// Put the group at zero: `x_g = -beta / alpha`.
    fn hold(&self, x: &mut [f64]) {
        for ((xk, a), b) in x[self.range()].iter_mut().zip(&self.alpha).zip(&self.beta) {
            *xk = -b / a;
        }
    }

    /// The gradient of the quadratic on the group's entries divided by
    /// `alpha` (`w`): zero is optimal for the group held there when
    /// `||w|| <= c_g`, the subgradient condition that
    /// [`super::ConeProblem::solve`] checks (with the same margin).
    fn w(&self, quad_grad: &[f64]) -> Vec<f64> {
        self.alpha
            .iter()
            .zip(&quad_grad[self.range()])
            .map(|(a, d)| d / a)
            .collect()
    }

    fn zero_is_optimal(&self, quad_grad: &[f64]) -> bool {
        let w = self.w(quad_grad);
        dot(&w, &w).sqrt() <= self.weight * (1.0 + 1e-9)
    }

    /// Move the group from zero along its direction of steepest descent,
    /// `z_g = -t w`, to the minimum of `f` on that ray (the quadratic's
    /// curvature along it against the slope `||w|| (c_g - ||w||)`).
    /// Newton's method cannot start at a kink; from this point it converges
    /// in a few iterations.
    fn release(&self, quadratic: &Quadratic, quad_grad: &[f64], x: &mut [f64]) {
        let w = self.w(quad_grad);
        let size = dot(&w, &w).sqrt();
        let mut v = vec![0.0; x.len()];
        for ((slot, a), wk) in v[self.range()].iter_mut().zip(&self.alpha).zip(&w) {
            *slot = -wk / a;
        }
        let curvature = dot(&v, &quadratic.times(&v));
        let t = (size - self.weight) * size / curvature;
        if t.is_finite() && t > 0.0 {
            for (xk, vk) in x[self.range()].iter_mut().zip(&v[self.range()]) {
                *xk += t * vk;
            }
        }
    }
}

/// `P x + q`.
fn quad_gradient(quadratic: &Quadratic, q: &[f64], x: &[f64]) -> Vec<f64> {
    quadratic
        .times(x)
        .iter()
        .zip(q)
        .map(|(a, b)| a + b)
        .collect()
}

/// The Newton step `-H^-1 grad` by the dense Hessian, formed and factored
/// in `p` (its lower triangle): `P`, then each open group's block; a held
/// group's entries a unit row and column. `None` when it is not
/// numerically positive definite.
fn dense_step(
    p: &mut Mat<f64>,
    quadratic: &Quadratic,
    groups: &[NewtonGroup],
    norms: &[f64],
    held: &[bool],
    x: &[f64],
    grad: &[f64],
) -> Result<Option<Vec<f64>>> {
    let n = grad.len();
    quadratic.fill_lower(p);
    for ((g, &s), _) in groups.iter().zip(norms).zip(held).filter(|(_, &h)| !h) {
        let z: Vec<f64> = g.z(x).collect();
        let c = g.weight / s;
        for (a, (&za, &aa)) in z.iter().zip(&g.alpha).enumerate() {
            for (b, (&zb, &ab)) in z.iter().zip(&g.alpha).enumerate().take(a + 1) {
                let eye = if a == b { 1.0 } else { 0.0 };
                p[(g.start + a, g.start + b)] += c * aa * ab * (eye - za * zb / (s * s));
            }
        }
    }
    for (g, _) in groups.iter().zip(held).filter(|(_, &h)| h) {
        for i in g.range() {
            for j in 0..n {
                p[(i, j)] = 0.0;
                p[(j, i)] = 0.0;
            }
            p[(i, i)] = 1.0;
        }
    }
    if !factor_lower(p.as_mut())? {
        return Ok(None);
    }
    let mut step = Mat::from_fn(n, 1, |i, _| -grad[i]);
    cholesky_solve(p.as_ref(), step.as_mut());
    Ok(Some((0..n).map(|i| step[(i, 0)]).collect()))
}

/// [`newton`]'s iterations from `x`, `p` the work space.
///
/// **Groups held at zero.** A group within [`COLLAPSE`] of zero, or that
/// two cut steps in a row were headed for ([`KINK`]), is held at zero: its
/// entries leave the Newton system (a unit row and column, no gradient)
/// and its penalty is constant. Where the other groups have converged, a
/// held group whose zero is not optimal (its subgradient condition fails)
/// is let go along its direction of steepest descent, each at most
/// [`RELEASES`] times (more would be a cycle: the cone solver takes the
/// program). So a minimum at a kink is found without leaving Newton's
/// method, and one next to a kink too. Measured on the n = 16 path
/// (`benches/bench_scale.py`): the caller's rounds fixed one such group at
/// a time, each round a Newton solve from zero, and 11 of its 160 steps
/// ended in Clarabel's solution of the program (0.5 to 1.5 s each, 7 s of
/// the path's 18); now every step is Newton's.
fn iterate(
    p: &mut Mat<f64>,
    quadratic: &Quadratic,
    q: &[f64],
    groups: &[NewtonGroup],
    tol: f64,
    mut x: Vec<f64>,
    factored: Option<&FactoredHessian>,
) -> Result<Newton> {
    let mut held = vec![false; groups.len()];
    let mut released = vec![0u32; groups.len()];
    // Held groups are checked at the start and where the others converged.
    let mut check = true;
    // The group the last step was cut on its way to.
    let mut kink = None;
    for iteration in 1..=MAX_ITERATIONS {
        let gave_up = Newton::GaveUp {
            iterations: iteration,
        };
        for (k, g) in groups.iter().enumerate() {
            if !held[k] && g.norm(&x) <= COLLAPSE {
                if !g.can_hold() {
                    return Ok(Newton::Kink {
                        group: k,
                        iterations: iteration,
                    });
                }
                g.hold(&mut x);
                held[k] = true;
            }
        }
        if std::mem::take(&mut check) {
            let quad_grad = quad_gradient(quadratic, q, &x);
            for (k, g) in groups.iter().enumerate() {
                if held[k] && !g.zero_is_optimal(&quad_grad) {
                    if released[k] == RELEASES {
                        return Ok(gave_up);
                    }
                    released[k] += 1;
                    held[k] = false;
                    g.release(quadratic, &quad_grad, &mut x);
                }
            }
        }
        let norms: Vec<f64> = groups.iter().map(|g| g.norm(&x)).collect();
        if norms.iter().any(|s| !s.is_finite()) {
            return Ok(gave_up);
        }
        let px = quadratic.times(&x);
        let quad_grad: Vec<f64> = px.iter().zip(q).map(|(a, b)| a + b).collect();
        let mut grad = quad_grad.clone();
        for ((g, &s), _) in groups.iter().zip(&norms).zip(&held).filter(|(_, &h)| !h) {
            let c = g.weight / s;
            for (a, (za, &aa)) in g.z(&x).zip(&g.alpha).enumerate() {
                grad[g.start + a] += c * aa * za;
            }
        }
        for (g, _) in groups.iter().zip(&held).filter(|(_, &h)| h) {
            grad[g.range()].iter_mut().for_each(|v| *v = 0.0);
        }
        let prepared = match factored {
            Some(f) => f.prepare(groups, &norms, &held, &x)?,
            None => None,
        };
        let dx = match prepared {
            Some(solver) => solver.solve(&grad.iter().map(|g| -g).collect::<Vec<_>>()),
            None => match dense_step(p, quadratic, groups, &norms, &held, &x, &grad)? {
                Some(dx) => dx,
                None => return Ok(gave_up),
            },
        };
        let decrement = -dot(&grad, &dx);
        let value = 0.5 * dot(&x, &px) + dot(q, &x);
        let penalty: f64 = groups.iter().zip(&norms).map(|(g, s)| g.weight * s).sum();
        let f = value + penalty;
        if !(decrement.is_finite() && f.is_finite() && decrement >= 0.0) {
            return Ok(gave_up);
        }
        if decrement <= tol.max(FLOOR_TOL) * f.abs().max(1.0) {
            // Within reach of the minimum: the full step, quadratically
            // closer; done unless a held group is to be let go.
            x.iter_mut().zip(&dx).for_each(|(x, d)| *x += d);
            let quad_grad = quad_gradient(quadratic, q, &x);
            let optimal = |(g, &h): (&NewtonGroup, &bool)| !h || g.zero_is_optimal(&quad_grad);
            if groups.iter().zip(&held).all(optimal) {
                return Ok(Newton::Solved {
                    x,
                    iterations: iteration,
                });
            }
            check = true;
            kink = None;
            continue;
        }
        let line = Line {
            x: &x,
            dx: &dx,
            groups,
            value,
            slope: dot(&quad_grad, &dx),
            curvature: dot(&dx, &quadratic.times(&dx)),
        };
        let mut t = 1.0;
        while line.at(t) > f - ARMIJO * t * decrement {
            t *= 0.5;
            if t < MIN_STEP {
                return Ok(gave_up);
            }
        }
        let headed = (t < 1.0)
            .then(|| {
                groups
                    .iter()
                    .zip(&norms)
                    .zip(&held)
                    .position(|((g, &s), &h)| !h && g.closest(&x, &dx) < KINK * s)
            })
            .flatten();
        x.iter_mut().zip(&dx).for_each(|(x, d)| *x += t * d);
        if let Some(k) = headed.filter(|_| headed == kink) {
            if !groups[k].can_hold() {
                return Ok(Newton::Kink {
                    group: k,
                    iterations: iteration,
                });
            }
            groups[k].hold(&mut x);
            held[k] = true;
            kink = None;
        } else {
            kink = headed;
        }
    }
    Ok(Newton::GaveUp {
        iterations: MAX_ITERATIONS,
    })
}

impl ConeProblem<'_> {
    /// The open groups as Newton's method sees them (see [`newton`]): the
    /// same `z_g = varphi (theta_g + S e_g)` as the cones of [`Self::program`].
    pub(super) fn newton_groups(&self, open: &[&ConeGroup], scale: &[f64]) -> Vec<NewtonGroup> {
        let mut start = 0;
        open.iter()
            .map(|g| {
                let mut group = NewtonGroup {
                    start,
                    alpha: Vec::new(),
                    beta: Vec::new(),
                    fixed_squares: 0.0,
                    weight: self.gamma * g.phi,
                };
                for &(i, pos) in &g.entries {
                    let beta = g.varphi * self.theta[i];
                    match pos {
                        Some(p) => {
                            group.alpha.push(g.varphi * scale[p]);
                            group.beta.push(beta);
                        }
                        None => group.fixed_squares += beta * beta,
                    }
                }
                start += group.alpha.len();
                group
            })
            .collect()
    }
}

#[cfg(test)]
#[path = "newton_tests.rs"]
mod tests;
