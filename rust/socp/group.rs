//! A penalised group as the cone step sees it.

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
