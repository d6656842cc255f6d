//! Sensitivity of the frozen frequency response to the parameters of the
//! frozen LTI model, at any scheduling values and frequencies.
//!
//! For an LPV model the derivative of `G(p, z)` with respect to the entry
//! `X(i)_ab` of theta is `psi_i(p)` times the derivative with respect to
//! `X_ab` of the frozen model (method.md section 3), so the LTI Jacobian
//! `J(p, z)` (one row per output and input, one column per entry of
//! `[vec A; vec B; vec C; vec D]`) carries all the information; uncertainty
//! propagation combines it with the parameter covariance folded by the
//! basis values (see Python's `lpvid.Covariance.frf_std`).

use crate::base::layout::Shape;
use crate::error::Result;
use crate::eval::model::ModelAt;
use crate::eval::response::sweep_lines;
use num_complex::Complex64 as C64;

/// Jacobian of the frozen frequency response with respect to the frozen LTI
/// parameters at every (point, line) of the model at its `N` points,
/// `(N, F, l, r, lti_len)` row-major, complex.
///
/// With `X = (zI - A)^-1 B` and `Y = C (zI - A)^-1`:
/// `dG_jc/dA_ab = Y_ja X_bc`, `dG_jc/dB_ac = Y_ja`, `dG_jc/dC_jb = X_bc`,
/// `dG_jc/dD_jc = 1`; the columns follow `vec A, vec B, vec C, vec D`
/// (column-major within each matrix).
pub fn lti_jacobian(model: &ModelAt<'_>, z: &[C64]) -> Result<Vec<C64>> {
    let shape = &model.shape;
    let Shape { n, r, l, .. } = *shape;
    let (na, nb, nc) = (n * n, n * r, l * n);
    let row = shape.lti_len();
    let per_line = l * r * row;
    sweep_lines(model, z, per_line, true, |_, chunk, res, first, end| {
        for (lane, k) in (first..end).enumerate() {
            for j in 0..l {
                for c in 0..r {
                    let dst = &mut chunk[k * per_line + (j * r + c) * row..][..row];
                    for b in 0..n {
                        let xb = res.x[c * n + b].lane(lane);
                        for a in 0..n {
                            dst[a + b * n] = res.yt[j * n + a].lane(lane) * xb;
                        }
                    }
                    for a in 0..n {
                        dst[na + a + c * n] = res.yt[j * n + a].lane(lane);
                    }
                    for b in 0..n {
                        dst[na + nb + j + b * l] = res.x[c * n + b].lane(lane);
                    }
                    dst[na + nb + nc + j + c * l] = C64::new(1.0, 0.0);
                }
            }
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::response::frequency_response;
    use crate::testing::Lcg;

    #[test]
    fn matches_finite_differences_of_the_response() {
        let shape = Shape::new(3, 2, 2, 1).expect("valid shape");
        let mut rng = Lcg(7);
        let mut theta: Vec<f64> = (0..shape.len()).map(|_| 0.6 * rng.next_f64()).collect();
        // A stable constant part.
        for i in 0..3 {
            theta[shape.block(crate::base::layout::Matrix::A, 0).start + i * 4] = -1.0 - i as f64;
        }
        let basis = [0.4];
        let z = [C64::new(0.0, 0.7), C64::new(0.0, 2.0)];
        let jac = lti_jacobian(&ModelAt::new(shape, &theta, &basis, 1), &z).expect("evaluates");
        let lti = shape.lti_len();
        let (l, r) = (shape.l, shape.r);
        // The LTI parameter u maps to theta entries of X(0) (weight 1) and
        // X(1) (weight psi): perturb X(0) only, which moves the frozen model by h.
        let h = 1e-6;
        let mut u = 0;
        for x in crate::base::layout::Matrix::ALL {
            let block = shape.block(x, 0);
            for t in block {
                let mut plus = theta.clone();
                let mut minus = theta.clone();
                plus[t] += h;
                minus[t] -= h;
                let at = |theta| ModelAt::new(shape, theta, &basis, 1);
                let gp = frequency_response(&at(&plus), &z).expect("evaluates");
                let gm = frequency_response(&at(&minus), &z).expect("evaluates");
                for k in 0..z.len() {
                    for e in 0..l * r {
                        let fd = (gp[k * l * r + e] - gm[k * l * r + e]) / (2.0 * h);
                        let an = jac[(k * l * r + e) * lti + u];
                        assert!((fd - an).norm() < 1e-6 * (1.0 + an.norm()), "u {u}");
                    }
                }
                u += 1;
            }
        }
        assert_eq!(u, lti);
    }
}
