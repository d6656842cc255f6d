//! Batched frequency responses of an LPV model at frozen scheduling values.

use crate::base::lanes::LANES;
use crate::base::layout::Shape;
use crate::error::{invalid, Error, Result};
use crate::eval::lti::{lanes_of, Frozen, Hessenberg, Resolvent};
use num_complex::Complex64 as C64;
use rayon::prelude::*;

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

/// Evaluate the resolvent of every frozen model at every line, `LANES`
/// lines at a time, in parallel over the points, and let `fill` write what
/// it needs of lines `first..end` into the point's chunk of
/// `z.len() * per_line` values: `fill(q, chunk, res, first, end)`. `sides`
/// asks the resolvent for `X = (zI - A)^-1 B` and `Y = C (zI - A)^-1` too.
///
/// Checks `theta` and `basis`; fails with [`Error::Singular`] where `zI -
/// A(p)` cannot be inverted. Returns the `(N, F, per_line)` values.
#[allow(clippy::too_many_arguments)]
pub(crate) fn sweep_lines<F>(
    shape: &Shape,
    theta: &[f64],
    basis: &[f64],
    n_points: usize,
    z: &[C64],
    per_line: usize,
    sides: bool,
    fill: F,
) -> Result<Vec<C64>>
where
    F: Fn(usize, &mut [C64], &Resolvent, usize, usize) -> Result<()> + Sync,
{
    shape.check_theta(theta)?;
    let psi = with_constant(basis, n_points, shape.nb)?;
    let m = shape.n_coef();
    let stride = z.len() * per_line;
    let what = "the frequency responses (or their derivatives) at every point and line";
    let mut out = crate::memory::try_vec(n_points * stride, C64::new(0.0, 0.0), what)?;
    if stride == 0 {
        return Ok(out);
    }
    out.par_chunks_mut(stride)
        .enumerate()
        .try_for_each(|(q, chunk)| {
            let form = Hessenberg::new(shape, &Frozen::at(shape, theta, &psi[q * m..(q + 1) * m]));
            let mut res = Resolvent::new(shape);
            for first in (0..z.len()).step_by(LANES) {
                let end = (first + LANES).min(z.len());
                res.evaluate(&form, &lanes_of(z, first, end), sides)
                    .map_err(|lane| Error::Singular {
                        point: q,
                        line: (first + lane).min(end - 1),
                    })?;
                fill(q, chunk, &res, first, end)?;
            }
            Ok(())
        })?;
    Ok(out)
}

/// Frequency response `C (zI - A)^-1 B + D` of the LPV model at every
/// (point, line) pair, `(N, F, l, r)` row-major. `basis` holds the `N x Nb`
/// basis values `psi_1..psi_Nb` at the points.
///
/// Fails with [`Error::Singular`] where `zI - A(p)` cannot be inverted and
/// with [`Error::Overflow`] where the response is not finite: never returns
/// NaN or Inf.
pub fn frequency_response(
    shape: &Shape,
    theta: &[f64],
    basis: &[f64],
    n_points: usize,
    z: &[C64],
) -> Result<Vec<C64>> {
    let (l, r) = (shape.l, shape.r);
    sweep_lines(
        shape,
        theta,
        basis,
        n_points,
        z,
        l * r,
        false,
        |q, chunk, res, first, end| {
            for (lane, k) in (first..end).enumerate() {
                for j in 0..l {
                    for c in 0..r {
                        let g = res.g[j + c * l].lane(lane);
                        if !g.is_finite() {
                            return Err(Error::Overflow { point: q, line: k });
                        }
                        chunk[(k * l + j) * r + c] = g;
                    }
                }
            }
            Ok(())
        },
    )
}
