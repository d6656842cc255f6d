//! Stability of the frozen models over a scheduling range, and an
//! [`Objective`] that refuses parameters whose frozen models leave the
//! stable set.
//!
//! The stability margin of a frozen model (the rule of Python's
//! `lpvid.model.frozen.stability_margin`, which a test compares with this one):
//! discrete time `1 - max |lambda|`; continuous time the smallest
//! `-Re lambda / |lambda|` over the poles (the damping ratio of the least
//! damped pole; 0 for a pole at the origin). A frozen model is stable when
//! its margin is positive.
//!
//! Fits that keep stability may give their check points a floor (continuous
//! time): a pole is then measured against `max(|lambda|, floor)`, so that a
//! real pole's margin falls to zero as it nears the origin instead of
//! staying 1 until it crosses (a damping ratio does not see how near zero a
//! real pole is): a fit cannot then bring a real pole to within
//! `tol * floor` of the origin at the check points, and push it across
//! between them unseen.
//!
//! The range is given as the basis values at an ordered list of check
//! points (for one scheduling parameter: a fine uniform grid). [`FrozenRange::worst`]
//! evaluates every `stride`-th point, then every point between the coarse
//! neighbours of the smallest local minima of the margin: the minimum is
//! resolved to the spacing of the check points, and a dip narrower than the
//! coarse spacing is found when it lies next to a local minimum of the
//! coarse samples. Python checks the continuum afterwards
//! (`lpvid.stability`) and adds the points it finds.

use crate::base::layout::{FreeSet, Matrix, Shape};
use crate::base::spread::{self, worth_spreading};
use crate::error::{invalid, Error, Result};
use crate::eval::objective::{GaussNewton, Objective};
use nalgebra::linalg::Schur;
use nalgebra::DMatrix;
use num_complex::Complex64 as C64;
use std::sync::Mutex;

/// Local minima of the coarse margins refined by [`FrozenRange::worst`].
const REFINED_MINIMA: usize = 4;

/// The stability margin of a frozen model from its poles (see the module
/// documentation); `-inf` when a pole is not finite.
pub fn margin(poles: &[C64], discrete: bool) -> f64 {
    floored_margin(poles, discrete, 0.0)
}

/// [`margin`] with every continuous-time pole measured against
/// `max(|lambda|, floor)` (the module documentation); the same as
/// [`margin`] for `floor = 0` and in discrete time.
pub fn floored_margin(poles: &[C64], discrete: bool, floor: f64) -> f64 {
    if poles
        .iter()
        .any(|p| !(p.re.is_finite() && p.im.is_finite()))
    {
        return f64::NEG_INFINITY;
    }
    if discrete {
        1.0 - poles.iter().fold(0.0f64, |a, p| a.max(p.norm()))
    } else {
        poles.iter().fold(f64::INFINITY, |a, p| {
            let size = p.norm().max(floor);
            a.min(if size > 0.0 { -p.re / size } else { 0.0 })
        })
    }
}

/// Most QR sweeps of the Schur decomposition before giving up.
const MAX_SWEEPS: usize = 10_000;

/// Eigenvalues of a real `n x n` matrix (column-major), by nalgebra's
/// Schur decomposition (Francis double-shift QR).
pub fn eigenvalues(a: &[f64], n: usize) -> Result<Vec<C64>> {
    if a.len() != n * n {
        return Err(invalid(
            "a",
            format!("expected {} entries, got {}", n * n, a.len()),
        ));
    }
    if n == 0 {
        return Ok(Vec::new());
    }
    if a.iter().any(|v| !v.is_finite()) {
        return Err(Error::Numerical("A(p) contains NaN or Inf".into()));
    }
    let m = DMatrix::from_column_slice(n, n, a);
    let schur = Schur::try_new(m, f64::EPSILON, MAX_SWEEPS).ok_or_else(|| {
        Error::Numerical("eigenvalues of A(p): the QR iteration did not converge".into())
    })?;
    Ok(schur
        .complex_eigenvalues()
        .iter()
        .map(|z| C64::new(z.re, z.im))
        .collect())
}

/// Check points of a scheduling range: the basis values `[1, psi_1, ...,
/// psi_Nb]` at each, in the order in which neighbours are adjacent.
#[derive(Debug, Clone)]
pub struct FrozenRange {
    nb: usize,
    /// `M x (Nb + 1)` row-major, first column all ones.
    psi: Vec<f64>,
    stride: usize,
    discrete: bool,
    /// Continuous time: poles measured against `max(|lambda|, floor)`.
    floor: f64,
}

impl FrozenRange {
    /// `basis` holds `psi_1..psi_Nb` at the `n_points` check points, row-major.
    /// Every `stride`-th point (and the last) is evaluated first; `stride = 1`
    /// evaluates them all.
    pub fn new(
        nb: usize,
        basis: &[f64],
        n_points: usize,
        stride: usize,
        discrete: bool,
    ) -> Result<Self> {
        if n_points == 0 {
            return Err(invalid("p_range", "needs at least one check point"));
        }
        if stride == 0 {
            return Err(invalid("stride", "must be at least 1"));
        }
        let psi = crate::eval::model::with_constant(basis, n_points, nb)?;
        Ok(FrozenRange {
            nb,
            psi,
            stride,
            discrete,
            floor: 0.0,
        })
    }

    /// The range with its margins floored at `floor` (finite, >= 0): see
    /// [`floored_margin`].
    pub fn with_floor(mut self, floor: f64) -> Result<Self> {
        if !(floor.is_finite() && floor >= 0.0) {
            return Err(invalid(
                "floor",
                format!("expected a finite number >= 0, got {floor}"),
            ));
        }
        self.floor = floor;
        Ok(self)
    }

    /// Number of check points.
    pub fn len(&self) -> usize {
        self.psi.len() / (self.nb + 1)
    }

    /// Always false: a range has at least one point.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Number of basis functions besides the constant one.
    pub fn nb(&self) -> usize {
        self.nb
    }

    /// Whether the models are in discrete time.
    pub fn discrete(&self) -> bool {
        self.discrete
    }

    fn check_shape(&self, shape: &Shape, theta: &[f64]) -> Result<()> {
        if shape.nb != self.nb {
            return Err(invalid(
                "p_range",
                format!(
                    "check points carry {} basis functions, the model {}",
                    self.nb, shape.nb
                ),
            ));
        }
        shape.check_theta(theta)
    }

    /// `A(p_k)`, column-major.
    fn a_at(&self, shape: &Shape, theta: &[f64], k: usize) -> Vec<f64> {
        let m = self.nb + 1;
        let psi = &self.psi[k * m..(k + 1) * m];
        let mut a = vec![0.0; shape.n * shape.n];
        for (i, &w) in psi.iter().enumerate() {
            if w != 0.0 {
                for (o, &t) in a.iter_mut().zip(&theta[shape.block(Matrix::A, i)]) {
                    *o += w * t;
                }
            }
        }
        a
    }

    fn margin_at(&self, shape: &Shape, theta: &[f64], k: usize) -> Result<f64> {
        let poles = eigenvalues(&self.a_at(shape, theta, k), shape.n)?;
        Ok(floored_margin(&poles, self.discrete, self.floor))
    }

    /// The margin at every check point.
    pub fn margins(&self, shape: &Shape, theta: &[f64]) -> Result<Vec<f64>> {
        self.check_shape(shape, theta)?;
        self.margins_at(shape, theta, (0..self.len()).collect())
    }

    /// The margin at each of the check points `points`, in their order (on
    /// the pool when the eigenvalues are worth it: [`margin_work`] each).
    fn margins_at(&self, shape: &Shape, theta: &[f64], points: Vec<usize>) -> Result<Vec<f64>> {
        let work = margin_work(shape.n) * points.len() as f64;
        let spread = worth_spreading(points.len(), work);
        spread::map(points, spread, |k| self.margin_at(shape, theta, k))
            .into_iter()
            .collect()
    }

    /// The smallest margin found and its check point: every `stride`-th
    /// point, then every point between the coarse neighbours of the
    /// `REFINED_MINIMA` smallest local minima. Stops early when a coarse
    /// point is below `tol`.
    pub fn worst(&self, shape: &Shape, theta: &[f64], tol: f64) -> Result<(usize, f64)> {
        self.check_shape(shape, theta)?;
        let last = self.len() - 1;
        let mut coarse: Vec<usize> = (0..=last).step_by(self.stride).collect();
        if coarse.last() != Some(&last) {
            coarse.push(last);
        }
        let values = self.margins_at(shape, theta, coarse.clone())?;
        let mut best = (0..coarse.len())
            .map(|i| (coarse[i], values[i]))
            .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
        if best.1 < tol || self.stride == 1 {
            return Ok(best);
        }
        let mut minima: Vec<usize> = (0..coarse.len())
            .filter(|&i| {
                (i == 0 || values[i] <= values[i - 1])
                    && (i + 1 == coarse.len() || values[i] <= values[i + 1])
            })
            .collect();
        minima.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
        minima.truncate(REFINED_MINIMA);
        // Each minimum's neighbourhood: up to 2 stride + 1 check points.
        let each = margin_work(shape.n) * (2 * self.stride + 1) as f64;
        let spread = worth_spreading(minima.len(), each * minima.len() as f64);
        let refined: Vec<(usize, f64)> = spread::map(minima, spread, |i| {
            let lo = coarse[i.saturating_sub(1)];
            let hi = coarse[(i + 1).min(coarse.len() - 1)];
            (lo..=hi)
                .map(|k| self.margin_at(shape, theta, k).map(|v| (k, v)))
                .try_fold((lo, f64::INFINITY), |a, b| {
                    b.map(|b| if b.1 < a.1 { b } else { a })
                })
        })
        .into_iter()
        .collect::<Result<_>>()?;
        for r in refined {
            if r.1 < best.1 {
                best = r;
            }
        }
        Ok(best)
    }
}

/// The time of one margin (the eigenvalues of `A(p)`) in flops of
/// [`crate::base::spread::SPREAD_FLOPS`]'s pace: 100 n^3 (measured 7.7 us
/// at n = 10, 17 us at 16 and 110 us at 32).
fn margin_work(n: usize) -> f64 {
    100.0 * (n * n * n) as f64
}

/// An objective that is undefined where a frozen model on the range is
/// unstable: [`Objective::cost`] and [`Objective::gauss_newton`] return
/// [`Error::Unstable`] when the smallest margin found by
/// [`FrozenRange::worst`] is below `tol`. Levenberg-Marquardt and the l2,1
/// fit reject such trial steps, so that a fit from a stable start stays stable.
pub struct Stable<'a> {
    inner: &'a dyn Objective,
    range: FrozenRange,
    tol: f64,
    /// The last theta checked and its outcome: the l2,1 fit evaluates the
    /// cost and then the Gauss-Newton pieces at the same point.
    last: Mutex<Option<Checked>>,
}

/// A theta and, when it failed the check, the point and margin found.
type Checked = (Vec<f64>, Option<(usize, f64)>);

impl<'a> Stable<'a> {
    /// Wrap `inner`; a margin below `tol` (> 0, finite) counts as unstable.
    pub fn new(inner: &'a dyn Objective, range: FrozenRange, tol: f64) -> Result<Self> {
        if !(tol.is_finite() && tol >= 0.0) {
            return Err(invalid(
                "tol",
                format!("expected a finite number >= 0, got {tol}"),
            ));
        }
        if inner.shape().nb != range.nb {
            return Err(invalid(
                "p_range",
                "check points and model differ in basis size",
            ));
        }
        Ok(Stable {
            inner,
            range,
            tol,
            last: Mutex::new(None),
        })
    }

    /// `Ok` when every frozen model found is stable with margin >= `tol`.
    pub fn check(&self, theta: &[f64]) -> Result<()> {
        let cached = self
            .last
            .lock()
            .ok()
            .and_then(|g| g.as_ref().filter(|(t, _)| t == theta).map(|(_, r)| *r));
        let failure = match cached {
            Some(r) => r,
            None => {
                let (k, m) = self.range.worst(self.inner.shape(), theta, self.tol)?;
                // A NaN margin fails too.
                let r = if m >= self.tol { None } else { Some((k, m)) };
                if let Ok(mut g) = self.last.lock() {
                    *g = Some((theta.to_vec(), r));
                }
                r
            }
        };
        match failure {
            Some((point, margin)) => Err(Error::Unstable { point, margin }),
            None => Ok(()),
        }
    }
}

impl Objective for Stable<'_> {
    fn shape(&self) -> &Shape {
        self.inner.shape()
    }

    fn n_residuals(&self) -> usize {
        self.inner.n_residuals()
    }

    fn cost(&self, theta: &[f64]) -> Result<f64> {
        self.check(theta)?;
        self.inner.cost(theta)
    }

    fn gauss_newton(&self, theta: &[f64], free: &FreeSet) -> Result<GaussNewton> {
        self.check(theta)?;
        self.inner.gauss_newton(theta, free)
    }

    fn response(&self, theta: &[f64]) -> Result<Vec<f64>> {
        self.inner.response(theta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scalar_model(a0: f64, a1: f64) -> (Shape, Vec<f64>) {
        // n = r = l = 1, nb = 1: theta = [A0, A1, B0, B1, C0, C1, D0, D1].
        let shape = Shape::new(1, 1, 1, 1).expect("valid shape");
        (shape, vec![a0, a1, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    }

    #[test]
    fn margin_rules() {
        let z = [C64::new(0.5, 0.5), C64::new(0.9, 0.0)];
        assert!((margin(&z, true) - 0.1).abs() < 1e-15);
        let s = [C64::new(-1.0, 1.0), C64::new(-3.0, 0.0)];
        assert!((margin(&s, false) - 0.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(margin(&[C64::new(0.0, 0.0)], false), 0.0);
        assert!(margin(&[C64::new(0.1, 2.0)], false) < 0.0);
    }

    #[test]
    fn a_floor_makes_a_real_pole_near_the_origin_count_as_near_the_boundary() {
        let slow = [C64::new(-1e-9, 0.0), C64::new(-3.0, 4.0)];
        assert_eq!(margin(&slow, false), 0.6);
        assert!((floored_margin(&slow, false, 1.0) - 1e-9).abs() < 1e-24);
        // poles larger than the floor, and discrete time, as without it
        assert_eq!(floored_margin(&slow[1..], false, 1.0), 0.6);
        let z = [C64::new(0.5, 0.5)];
        assert_eq!(floored_margin(&z, true, 1.0), margin(&z, true));
        assert!(floored_margin(&[C64::new(1e-12, 0.0)], false, 1.0) < 0.0);
        let range = FrozenRange::new(0, &[], 1, 1, false).expect("valid range");
        assert!(range.clone().with_floor(f64::NAN).is_err());
        assert!(range.with_floor(-1.0).is_err());
    }

    #[test]
    fn eigenvalues_of_a_rotation() {
        let (c, s) = (0.6f64, 0.8f64);
        let a = [0.9 * c, 0.9 * s, -0.9 * s, 0.9 * c];
        let mut ev = eigenvalues(&a, 2).expect("finite matrix");
        ev.sort_by(|x, y| x.im.total_cmp(&y.im));
        assert!((ev[0] - C64::new(0.54, -0.72)).norm() < 1e-12);
        assert!((ev[1] - C64::new(0.54, 0.72)).norm() < 1e-12);
        assert!(eigenvalues(&[f64::NAN], 1).is_err());
    }

    #[test]
    fn a_narrow_dip_next_to_a_coarse_minimum_is_found() {
        // a(p) = a0 + a1 psi(p); psi has a narrow spike between coarse points.
        let m = 161;
        let spike = 83; // not a multiple of the stride
        let basis: Vec<f64> = (0..m)
            .map(|k| {
                let base = (k as f64 / (m - 1) as f64 - 0.5).abs();
                if k == spike {
                    -0.2
                } else {
                    base
                }
            })
            .collect();
        let range = FrozenRange::new(1, &basis, m, 16, true).expect("valid range");
        let (shape, theta) = scalar_model(0.9, -0.3);
        let (k, worst) = range.worst(&shape, &theta, 0.0).expect("evaluates");
        assert_eq!(k, spike);
        assert!((worst - (1.0 - 0.96)).abs() < 1e-12);
        let all = range.margins(&shape, &theta).expect("evaluates");
        let min = all.iter().cloned().fold(f64::INFINITY, f64::min);
        assert_eq!(min, worst);
    }

    #[test]
    fn levenberg_marquardt_stays_stable() {
        // Data of x+ = 1.05 x + u, y = x (unstable): the unconstrained fit
        // finds a = 1.05, the fit through Stable stops inside the unit circle.
        let shape = Shape::new(1, 1, 1, 0).expect("valid shape");
        let z: Vec<C64> = (1..40)
            .map(|k| C64::from_polar(1.0, 0.08 * k as f64))
            .collect();
        let g: Vec<C64> = z.iter().map(|&z| 1.0 / (z - 1.05)).collect();
        let data =
            crate::base::data::FrfData::new(1, 1, 1, z, g, &vec![1.0; 39]).expect("valid data");
        let problem = crate::Problem::new(shape, data, &[]).expect("valid problem");
        let theta0 = vec![0.5, 1.0, 1.0, 0.0];
        let free = FreeSet::from_mask(&[true, false, false, false]);
        let settings = crate::LmSettings::default();
        let mut silent = crate::Silent;
        let free_fit = crate::levenberg_marquardt(&problem, &theta0, &free, &settings, &mut silent)
            .expect("fits");
        assert!((free_fit.theta[0] - 1.05).abs() < 1e-6);
        let range = FrozenRange::new(0, &[], 1, 1, true).expect("valid range");
        let stable = Stable::new(&problem, range, 1e-6).expect("valid tolerance");
        let fit = crate::levenberg_marquardt(&stable, &theta0, &free, &settings, &mut silent)
            .expect("fits");
        assert!(
            fit.theta[0] < 1.0 - 1e-6 && fit.theta[0] > 0.9,
            "{}",
            fit.theta[0]
        );
        assert!(fit.vnls > free_fit.vnls);
    }

    #[test]
    fn unstable_points_make_the_objective_fail() {
        let m = 33;
        let basis: Vec<f64> = (0..m).map(|k| k as f64 / (m - 1) as f64).collect();
        let range = FrozenRange::new(1, &basis, m, 4, false).expect("valid range");
        let shape = Shape::new(1, 1, 1, 1).expect("valid shape");
        let data = crate::base::data::FrfData::new(
            1,
            1,
            1,
            vec![C64::new(0.0, 1.0)],
            vec![C64::new(1.0, 0.0)],
            &[1.0],
        )
        .expect("valid data");
        let problem = crate::Problem::new(shape, data, &[0.5]).expect("valid problem");
        let stable = Stable::new(&problem, range, 1e-9).expect("valid tolerance");
        // A(p) = -1 + 2 p crosses zero at p = 0.5: unstable above.
        let theta = vec![-1.0, 2.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0];
        match stable.cost(&theta) {
            Err(Error::Unstable { margin, .. }) => assert!(margin <= 0.0),
            other => panic!("expected Unstable, got {other:?}"),
        }
        let ok = vec![-1.0, 0.5, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0];
        let v = stable.cost(&ok).expect("stable");
        assert_eq!(v, problem.cost(&ok).expect("evaluates"));
        let free = FreeSet::all(8);
        assert!(stable.gauss_newton(&theta, &free).is_err());
    }
}
