//! Batched frequency responses of an LPV model at frozen scheduling values.

use crate::base::lanes::LANES;
use crate::base::spread::{self, worth_spreading};
use crate::error::{Error, Result};
use crate::eval::lti::{lanes_of, Frozen, Hessenberg, Resolvent};
use crate::eval::model::ModelAt;
use num_complex::Complex64 as C64;

/// Evaluate the resolvent of every frozen model at every line, `LANES`
/// lines at a time, in parallel over the points, and let `fill` write what
/// it needs of lines `first..end` into the point's chunk of
/// `z.len() * per_line` values: `fill(q, chunk, res, first, end)`. `sides`
/// asks the resolvent for `X = (zI - A)^-1 B` and `Y = C (zI - A)^-1` too.
///
/// Checks the model's `theta` and basis values; fails with
/// [`Error::Singular`] where `zI - A(p)` cannot be inverted. Returns the
/// `(N, F, per_line)` values.
pub(crate) fn sweep_lines<F>(
    model: &ModelAt<'_>,
    z: &[C64],
    per_line: usize,
    sides: bool,
    fill: F,
) -> Result<Vec<C64>>
where
    F: Fn(usize, &mut [C64], &Resolvent, usize, usize) -> Result<()> + Sync,
{
    let psi = model.checked_psi()?;
    let (shape, theta, n_points) = (&model.shape, model.theta, model.n_points);
    let m = shape.n_coef();
    let stride = z.len() * per_line;
    let what = "the frequency responses (or their derivatives) at every point and line";
    let mut out = crate::memory::try_vec(n_points * stride, C64::new(0.0, 0.0), what)?;
    if stride == 0 {
        return Ok(out);
    }
    // About 8 n^2 flops for each input column (and output row, with the
    // sides) of a line.
    let sweeps = if sides { shape.l + shape.r } else { shape.r };
    let work = (8 * shape.n * shape.n * sweeps * z.len() * n_points) as f64;
    let chunks = out.chunks_mut(stride).enumerate().collect();
    spread::try_for_each_init(
        chunks,
        worth_spreading(n_points, work),
        || (),
        |_, (q, chunk)| {
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
        },
    )?;
    Ok(out)
}

/// Frequency response `C (zI - A)^-1 B + D` of the LPV model at every
/// (point, line) pair of the model at its `N` points, `(N, F, l, r)`
/// row-major.
///
/// Fails with [`Error::Singular`] where `zI - A(p)` cannot be inverted and
/// with [`Error::Overflow`] where the response is not finite: never returns
/// NaN or Inf.
pub fn frequency_response(model: &ModelAt<'_>, z: &[C64]) -> Result<Vec<C64>> {
    let (l, r) = (model.shape.l, model.shape.r);
    sweep_lines(model, z, l * r, false, |q, chunk, res, first, end| {
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
    })
}
