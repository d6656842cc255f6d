//! The columns of a record's Jacobian: which parameter each one is, and
//! how it enters the LPV recursion.
//!
//! With `z(t) = [x(t); u(t)]`, entry `(a, b)` of `A(i)` (`b < n`) or of
//! `B(i)` (`b = n + input`) drives the state: its sensitivity follows the
//! recursion `s(t+1) = Ad(t) s(t) + psi_i(t) e_a z_b(t)` (discrete time).
//! Entry `(j, b)` of `C(i)` or `D(i)` enters the output alone:
//! `dy_j(t) = psi_i(t) z_b(t)`. An entry `a` of the initial state starts a
//! state sensitivity `s(0) = e_a` without forcing.

use crate::base::layout::{FreeSet, Matrix, Shape};

/// A column whose sensitivity runs through the state recursion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum StateColumn {
    /// `A(i)[a, zb]` (`zb < n`) or `B(i)[a, zb - n]`.
    Theta { i: usize, a: usize, zb: usize },
    /// Entry `a` of the initial state.
    Initial { a: usize },
}

/// `C(i)[j, zb]` (`zb < n`) or `D(i)[j, zb - n]`: enters output `j` only.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct OutputColumn {
    pub i: usize,
    pub j: usize,
    pub zb: usize,
}

/// The columns of a record's Jacobian in the order the engine computes
/// them: state columns of theta, initial-state columns, output columns.
/// The free parameters of theta come in the order of `theta` (A and B
/// before C and D), so dropping the initial-state columns gives the free
/// order.
#[derive(Debug, Clone)]
pub(crate) struct Columns {
    pub state: Vec<StateColumn>,
    pub output: Vec<OutputColumn>,
    /// Number of theta columns among `state` (they come first).
    pub theta_state: usize,
}

/// Where parameter `index` of theta sits: matrix, basis index, row, column.
pub(crate) fn locate(shape: &Shape, index: usize) -> (Matrix, usize, usize, usize) {
    for x in Matrix::ALL {
        let first = shape.block(x, 0).start;
        let len = shape.matrix_len(x);
        if index < first + shape.n_coef() * len {
            let (rows, _) = shape.dims(x);
            let (i, p) = ((index - first) / len, (index - first) % len);
            return (x, i, p % rows, p / rows);
        }
    }
    unreachable!("index {index} is beyond theta (checked by the caller)")
}

impl Columns {
    /// Columns of the free parameters, and of the initial state when `initial`.
    pub fn new(shape: &Shape, free: &FreeSet, initial: bool) -> Columns {
        let n = shape.n;
        let mut state = Vec::new();
        let mut output = Vec::new();
        for &index in free.indices() {
            let (x, i, row, col) = locate(shape, index);
            match x {
                Matrix::A => state.push(StateColumn::Theta { i, a: row, zb: col }),
                Matrix::B => state.push(StateColumn::Theta {
                    i,
                    a: row,
                    zb: n + col,
                }),
                Matrix::C => output.push(OutputColumn { i, j: row, zb: col }),
                Matrix::D => output.push(OutputColumn {
                    i,
                    j: row,
                    zb: n + col,
                }),
            }
        }
        let theta_state = state.len();
        if initial {
            state.extend((0..n).map(|a| StateColumn::Initial { a }));
        }
        Columns {
            state,
            output,
            theta_state,
        }
    }

    /// The initial-state columns alone.
    pub fn initial_only(n: usize) -> Columns {
        Columns {
            state: (0..n).map(|a| StateColumn::Initial { a }).collect(),
            output: Vec::new(),
            theta_state: 0,
        }
    }

    /// Number of columns.
    pub fn len(&self) -> usize {
        self.state.len() + self.output.len()
    }

    /// Number of initial-state columns.
    pub fn n_initial(&self) -> usize {
        self.state.len() - self.theta_state
    }

    /// Whether any column needs the nominal trajectory (all but the
    /// initial-state ones).
    pub fn need_trajectory(&self) -> bool {
        self.theta_state > 0 || !self.output.is_empty()
    }

    /// For every column in engine order: its position among the free
    /// parameters, or `None` for an initial-state column.
    pub fn free_positions(&self) -> Vec<Option<usize>> {
        let ts = self.theta_state;
        let mut out: Vec<Option<usize>> = (0..ts).map(Some).collect();
        out.extend((0..self.n_initial()).map(|_| None));
        out.extend((0..self.output.len()).map(|k| Some(ts + k)));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locate_inverts_the_layout() {
        let s = Shape::new(3, 2, 4, 2).unwrap();
        for x in Matrix::ALL {
            let (rows, _) = s.dims(x);
            for i in 0..=s.nb {
                for (p, index) in s.block(x, i).enumerate() {
                    assert_eq!(locate(&s, index), (x, i, p % rows, p / rows));
                }
            }
        }
    }

    #[test]
    fn columns_follow_the_free_order() {
        let s = Shape::new(2, 1, 1, 1).unwrap();
        let mut mask = vec![true; s.len()];
        mask[1] = false;
        let free = FreeSet::from_mask(&mask);
        let c = Columns::new(&s, &free, true);
        assert_eq!(c.theta_state, 2 * 4 - 1 + 2 * 2);
        assert_eq!(c.n_initial(), 2);
        assert_eq!(c.output.len(), 2 * (2 + 1));
        let pos = c.free_positions();
        assert_eq!(pos.iter().flatten().count(), free.len());
        assert!(pos.iter().flatten().enumerate().all(|(k, &p)| k == p));
        // Index 2 of theta: A(0)[0, 1] (index 1, A(0)[1, 0], is fixed).
        assert_eq!(c.state[1], StateColumn::Theta { i: 0, a: 0, zb: 1 });
    }
}
