//! A penalised group as the cone step sees it ([`ConeGroup`]), and as its
//! Newton's method sees it ([`NewtonGroup`], shared by `newton` and
//! `factored`).

/// One penalised group as the cone step sees it.
#[derive(Debug, Clone)]
pub struct ConeGroup {
    /// Every entry of `theta_g`: its index in theta and, when free, its
    /// position among the free parameters.
    pub entries: Vec<(usize, Option<usize>)>,
    /// Reweighting weight `phi_g`.
    pub phi: f64,
    /// Scale `varphi_g` of (25).
    pub varphi: f64,
}

impl ConeGroup {
    /// `|| theta_g ||` at a parameter vector.
    pub fn norm_at(&self, theta: &[f64]) -> f64 {
        self.entries
            .iter()
            .map(|&(i, _)| theta[i] * theta[i])
            .sum::<f64>()
            .sqrt()
    }

    /// The relative magnitude `varphi || theta_g ||` of (23) and (25): the
    /// size that is compared with the threshold of a group in use.
    pub fn magnitude(&self, theta: &[f64]) -> f64 {
        self.varphi * self.norm_at(theta)
    }

    /// `|| theta_g + d_g ||` for a step over the free parameters.
    pub fn norm_after(&self, theta: &[f64], d: &[f64]) -> f64 {
        self.entries
            .iter()
            .map(|&(i, pos)| {
                let v = theta[i] + pos.map_or(0.0, |p| d[p]);
                v * v
            })
            .sum::<f64>()
            .sqrt()
    }

    /// Whether any entry is free.
    pub fn is_active(&self) -> bool {
        self.entries.iter().any(|e| e.1.is_some())
    }

    /// Whether a step can bring the whole group to zero: every fixed entry is zero.
    pub(super) fn can_vanish(&self, theta: &[f64]) -> bool {
        self.entries
            .iter()
            .all(|&(i, pos)| pos.is_some() || theta[i] == 0.0)
    }

    /// `|| v_g ||` over the free entries of a vector over the free parameters.
    pub(super) fn free_norm(&self, v: &[f64]) -> f64 {
        self.entries
            .iter()
            .filter_map(|e| e.1)
            .map(|p| v[p] * v[p])
            .sum::<f64>()
            .sqrt()
    }

    pub(super) fn free_positions(&self) -> impl Iterator<Item = usize> + '_ {
        self.entries.iter().filter_map(|e| e.1)
    }
}

/// One group of the program as Newton's method sees it (`newton`):
/// its free entries are `x[start..start + alpha.len()]`.
#[derive(Debug, Clone)]
pub(super) struct NewtonGroup {
    pub(super) start: usize,
    /// `z = beta + alpha o x` over the free entries.
    pub(super) alpha: Vec<f64>,
    pub(super) beta: Vec<f64>,
    /// `sum beta^2` over the fixed entries (constant).
    pub(super) fixed_squares: f64,
    /// The weight `c_g` of `||z_g||`.
    pub(super) weight: f64,
}

impl NewtonGroup {
    pub(super) fn range(&self) -> std::ops::Range<usize> {
        self.start..self.start + self.alpha.len()
    }

    pub(super) fn z<'a>(&'a self, x: &'a [f64]) -> impl Iterator<Item = f64> + 'a {
        let xs = &x[self.range()];
        self.alpha
            .iter()
            .zip(&self.beta)
            .zip(xs)
            .map(|((a, b), x)| b + a * x)
    }

    pub(super) fn norm(&self, x: &[f64]) -> f64 {
        (self.z(x).map(|z| z * z).sum::<f64>() + self.fixed_squares).sqrt()
    }

    /// The smallest `||z_g||` on the segment from `x` to `x + dx`.
    pub(super) fn closest(&self, x: &[f64], dx: &[f64]) -> f64 {
        let w: Vec<f64> = self
            .alpha
            .iter()
            .zip(&dx[self.range()])
            .map(|(a, d)| a * d)
            .collect();
        let z: Vec<f64> = self.z(x).collect();
        let ww = dot(&w, &w);
        let t = if ww > 0.0 {
            (-dot(&z, &w) / ww).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let moved: Vec<f64> = z.iter().zip(&w).map(|(z, w)| z + t * w).collect();
        (dot(&moved, &moved) + self.fixed_squares).sqrt()
    }
}

/// The dot product of two vectors.
pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::ConeGroup;

    /// Entries 0 and 3 free (positions 1 and 0 among the free parameters),
    /// entry 2 fixed.
    fn group() -> ConeGroup {
        ConeGroup {
            entries: vec![(0, Some(1)), (2, None), (3, Some(0))],
            phi: 2.0,
            varphi: 0.5,
        }
    }

    #[test]
    fn norms_before_and_after_a_step_over_the_free_parameters() {
        let g = group();
        let theta = [3.0, 100.0, 4.0, 12.0];
        // sqrt(9 + 16 + 144); the magnitude scales it by varphi.
        assert_eq!(g.norm_at(&theta), 13.0);
        assert_eq!(g.magnitude(&theta), 6.5);
        // d moves entry 3 by -12 (position 0) and entry 0 by -3 (position 1):
        // only the fixed entry 2 is left.
        assert_eq!(g.norm_after(&theta, &[-12.0, -3.0]), 4.0);
        assert_eq!(g.norm_after(&theta, &[0.0, 0.0]), 13.0);
        assert_eq!(g.free_norm(&[3.0, 4.0, 100.0]), 5.0);
        assert_eq!(g.free_positions().collect::<Vec<_>>(), vec![1, 0]);
    }

    #[test]
    fn active_when_an_entry_is_free_and_vanishing_when_every_fixed_one_is_zero() {
        let g = group();
        assert!(g.is_active());
        assert!(!g.can_vanish(&[3.0, 0.0, 4.0, 12.0]));
        assert!(g.can_vanish(&[3.0, 7.0, 0.0, 12.0]));
        let fixed = ConeGroup {
            entries: vec![(0, None), (1, None)],
            ..group()
        };
        assert!(!fixed.is_active());
        assert!(fixed.can_vanish(&[0.0, 0.0]) && !fixed.can_vanish(&[0.0, 1.0]));
    }
}
