//! The parameter layout of method.md (3)-(5).
//!
//! `theta = [theta_A; theta_B; theta_C; theta_D]` with
//! `theta_X = [vec X(0); vec X(1); ...; vec X(Nb)]` and column-major `vec`.
//! A *group* is `theta_X(i)` for one matrix `X` and one `i >= 1`.

use crate::error::{invalid, Result};
use std::ops::Range;

/// One of the four state-space matrices.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Matrix {
    /// State matrix, `n x n`.
    A,
    /// Input matrix, `n x r`.
    B,
    /// Output matrix, `l x n`.
    C,
    /// Feedthrough matrix, `l x r`.
    D,
}

impl Matrix {
    /// The four matrices in the order of `theta`.
    pub const ALL: [Matrix; 4] = [Matrix::A, Matrix::B, Matrix::C, Matrix::D];

    /// Position of the matrix in [`Matrix::ALL`].
    pub fn index(self) -> usize {
        match self {
            Matrix::A => 0,
            Matrix::B => 1,
            Matrix::C => 2,
            Matrix::D => 3,
        }
    }

    /// The matrix's letter.
    pub fn name(self) -> &'static str {
        ["A", "B", "C", "D"][self.index()]
    }
}

/// Sizes of an LPV model: `n` states, `r` inputs, `l` outputs and `nb`
/// basis functions besides the constant one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shape {
    /// Number of states.
    pub n: usize,
    /// Number of inputs.
    pub r: usize,
    /// Number of outputs.
    pub l: usize,
    /// Number of basis functions `psi_1..psi_Nb` (the constant `psi_0 = 1`
    /// is not counted).
    pub nb: usize,
}

/// One group `theta_X(i)`, `i >= 1`, of the l2,1 penalty.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Group {
    /// Which matrix.
    pub matrix: Matrix,
    /// Basis index `i` in `1..=nb`.
    pub basis: usize,
    /// Where the group sits in `theta`.
    pub range: Range<usize>,
}

impl Shape {
    /// Checked constructor: `n`, `r` and `l` must be positive.
    pub fn new(n: usize, r: usize, l: usize, nb: usize) -> Result<Self> {
        if n == 0 {
            return Err(invalid("n", "the model needs at least one state"));
        }
        if r == 0 {
            return Err(invalid("r", "the model needs at least one input"));
        }
        if l == 0 {
            return Err(invalid("l", "the model needs at least one output"));
        }
        Ok(Shape { n, r, l, nb })
    }

    /// Number of coefficient matrices per state-space matrix, `nb + 1`.
    pub fn n_coef(&self) -> usize {
        self.nb + 1
    }

    /// Rows and columns of one coefficient matrix `X(i)`.
    pub fn dims(&self, x: Matrix) -> (usize, usize) {
        match x {
            Matrix::A => (self.n, self.n),
            Matrix::B => (self.n, self.r),
            Matrix::C => (self.l, self.n),
            Matrix::D => (self.l, self.r),
        }
    }

    /// Number of entries of one coefficient matrix `X(i)`.
    pub fn matrix_len(&self, x: Matrix) -> usize {
        let (rows, cols) = self.dims(x);
        rows * cols
    }

    /// Offset of `vec X` in the parameter vector of one LTI model
    /// `[vec A; vec B; vec C; vec D]`.
    pub fn lti_offset(&self, x: Matrix) -> usize {
        Matrix::ALL[..x.index()]
            .iter()
            .map(|&m| self.matrix_len(m))
            .sum()
    }

    /// Number of parameters of one LTI model.
    pub fn lti_len(&self) -> usize {
        Matrix::ALL.iter().map(|&m| self.matrix_len(m)).sum()
    }

    /// Length of `theta`.
    pub fn len(&self) -> usize {
        self.n_coef() * self.lti_len()
    }

    /// Always false: a shape has at least one parameter.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Range of `theta_X(i)` in `theta`, for `i` in `0..=nb`.
    pub fn block(&self, x: Matrix, i: usize) -> Range<usize> {
        let len = self.matrix_len(x);
        let start = self.n_coef() * self.lti_offset(x) + i * len;
        start..start + len
    }

    /// The `4 * nb` groups in the order A(1..nb), B(1..nb), C(1..nb), D(1..nb).
    pub fn groups(&self) -> Vec<Group> {
        Matrix::ALL
            .iter()
            .flat_map(|&matrix| {
                (1..=self.nb).map(move |basis| Group {
                    matrix,
                    basis,
                    range: self.block(matrix, basis),
                })
            })
            .collect()
    }

    /// Check that a parameter vector has the right length and is finite.
    pub fn check_theta(&self, theta: &[f64]) -> Result<()> {
        self.check_theta_len(theta)?;
        if theta.iter().any(|v| !v.is_finite()) {
            return Err(invalid("theta", "contains NaN or Inf"));
        }
        Ok(())
    }

    /// Check that a parameter vector has the right length.
    pub fn check_theta_len(&self, theta: &[f64]) -> Result<()> {
        if theta.len() != self.len() {
            return Err(invalid(
                "theta",
                format!(
                    "expected {} parameters for n={}, r={}, l={}, Nb={}, got {}",
                    self.len(),
                    self.n,
                    self.r,
                    self.l,
                    self.nb,
                    theta.len()
                ),
            ));
        }
        Ok(())
    }
}

/// Which parameters are optimisation variables.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FreeSet {
    indices: Vec<usize>,
    position: Vec<Option<usize>>,
}

impl FreeSet {
    /// All parameters free.
    pub fn all(len: usize) -> Self {
        FreeSet {
            indices: (0..len).collect(),
            position: (0..len).map(Some).collect(),
        }
    }

    /// From a mask, `true` meaning free.
    pub fn from_mask(mask: &[bool]) -> Self {
        let indices: Vec<usize> = (0..mask.len()).filter(|&i| mask[i]).collect();
        let mut position = vec![None; mask.len()];
        for (k, &i) in indices.iter().enumerate() {
            position[i] = Some(k);
        }
        FreeSet { indices, position }
    }

    /// From a mask checked against a shape.
    pub fn for_shape(shape: &Shape, mask: Option<&[bool]>) -> Result<Self> {
        match mask {
            None => Ok(FreeSet::all(shape.len())),
            Some(m) if m.len() == shape.len() => Ok(FreeSet::from_mask(m)),
            Some(m) => Err(invalid(
                "free",
                format!("mask has {} entries, theta has {}", m.len(), shape.len()),
            )),
        }
    }

    /// Indices of the free parameters in `theta`, increasing.
    pub fn indices(&self) -> &[usize] {
        &self.indices
    }

    /// Position of parameter `i` among the free ones, if free.
    pub fn position(&self, i: usize) -> Option<usize> {
        self.position.get(i).copied().flatten()
    }

    /// Number of free parameters.
    pub fn len(&self) -> usize {
        self.indices.len()
    }

    /// True when nothing is free.
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// Length of the full parameter vector.
    pub fn full_len(&self) -> usize {
        self.position.len()
    }

    /// Gather the free entries of a full vector.
    pub fn gather(&self, full: &[f64]) -> Vec<f64> {
        self.indices.iter().map(|&i| full[i]).collect()
    }

    /// `full[free] += step`.
    pub fn add_step(&self, full: &[f64], step: &[f64]) -> Vec<f64> {
        let mut out = full.to_vec();
        for (&i, &s) in self.indices.iter().zip(step) {
            out[i] += s;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_tile_theta_in_order() {
        let s = Shape::new(3, 2, 4, 2).unwrap();
        let mut next = 0;
        for x in Matrix::ALL {
            for i in 0..=s.nb {
                let b = s.block(x, i);
                assert_eq!(b.start, next);
                assert_eq!(b.len(), s.matrix_len(x));
                next = b.end;
            }
        }
        assert_eq!(next, s.len());
        assert_eq!(s.groups().len(), 4 * s.nb);
        assert_eq!(s.lti_len(), 9 + 6 + 12 + 8);
    }

    #[test]
    fn free_set_maps_both_ways() {
        let f = FreeSet::from_mask(&[true, false, true, true, false]);
        assert_eq!(f.indices(), &[0, 2, 3]);
        assert_eq!(f.position(2), Some(1));
        assert_eq!(f.position(1), None);
        assert_eq!(
            f.add_step(&[1.0; 5], &[1.0, 2.0, 3.0]),
            vec![2.0, 1.0, 3.0, 4.0, 1.0]
        );
    }

    #[test]
    fn zero_sizes_are_refused() {
        assert!(Shape::new(0, 1, 1, 0).is_err());
        assert!(Shape::new(1, 0, 1, 0).is_err());
        assert!(Shape::new(1, 1, 0, 0).is_err());
    }
}
