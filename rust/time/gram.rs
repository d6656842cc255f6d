//! The Gram matrix `J^T J` and `J^T r` of a record's weighted Jacobian,
//! summed block of samples by block of samples, each thread over its own
//! share of the samples with its own sums.
//!
//! The output columns (`psi_i(t) z_b(t)` in one output, zero in the
//! others) are kept apart by output, so that their zeros are never
//! multiplied.

use super::columns::OutputColumn;
use crate::error::Result;
use crate::memory::{try_vec, try_zeros};
use faer::linalg::matmul::matmul;
use faer::linalg::matmul::triangular::{matmul as tri_matmul, BlockStructure};
use faer::{Accum, Mat, MatMut, MatRef, Par};

/// `J^T J` (full, symmetric, column-major) and `J^T r` of a record.
#[derive(Debug, Clone)]
pub(crate) struct Normal {
    pub k: usize,
    pub gram: Vec<f64>,
    pub jtr: Vec<f64>,
}

/// `dst += a^T b` (`Lower`: the lower triangle only, for `a = b`).
fn gram_add(dst: MatMut<'_, f64>, a: MatRef<'_, f64>, b: MatRef<'_, f64>, lower: bool, par: Par) {
    if lower {
        tri_matmul(
            dst,
            BlockStructure::TriangularLower,
            Accum::Add,
            a.transpose(),
            BlockStructure::Rectangular,
            b,
            BlockStructure::Rectangular,
            1.0,
            par,
        );
    } else {
        matmul(dst, Accum::Add, a.transpose(), b, 1.0, par);
    }
}

/// The output columns grouped by the output they enter.
pub(super) struct ByOutput {
    /// Positions (in `columns.output`) of the columns of output `j`.
    pub index: Vec<Vec<usize>>,
    pub cols: Vec<Vec<OutputColumn>>,
    /// Their values in one block of samples, row-major.
    pub values: Vec<Vec<f64>>,
}

impl ByOutput {
    pub fn new(output: &[OutputColumn], l: usize, block: usize) -> Result<ByOutput> {
        let index: Vec<Vec<usize>> = (0..l)
            .map(|j| (0..output.len()).filter(|&k| output[k].j == j).collect())
            .collect();
        let cols: Vec<Vec<OutputColumn>> = index
            .iter()
            .map(|ix| ix.iter().map(|&k| output[k]).collect())
            .collect();
        let values = cols
            .iter()
            .map(|c| {
                try_vec(
                    block * c.len(),
                    0.0,
                    "the output columns of a block of samples",
                )
            })
            .collect::<Result<_>>()?;
        Ok(ByOutput {
            values,
            index,
            cols,
        })
    }
}

/// The sums one thread accumulates over its share of the rows.
pub(super) struct Sums {
    /// `J_s^T J_s` (lower triangle) and `J_s^T r` of the state columns.
    gss: Mat<f64>,
    jtr_s: Mat<f64>,
    /// Per output `j`: `K_j^T J_s` (`len_j x n_state`), `K_j^T K_j` (lower
    /// triangle) and `K_j^T r_j`.
    cross: Vec<Mat<f64>>,
    own: Vec<Mat<f64>>,
    jtr_o: Vec<Mat<f64>>,
}

impl Sums {
    pub fn new(n_state: usize, outs: &ByOutput) -> Result<Sums> {
        let cols = &outs.cols;
        let what = "the Gram sums of a thread";
        let each = |rows: &dyn Fn(usize) -> (usize, usize)| -> Result<Vec<Mat<f64>>> {
            cols.iter()
                .map(|c| {
                    let (r, k) = rows(c.len());
                    try_zeros(r, k, what)
                })
                .collect()
        };
        Ok(Sums {
            gss: try_zeros(n_state, n_state, what)?,
            jtr_s: try_zeros(n_state, 1, what)?,
            cross: each(&|len| (len, n_state))?,
            own: each(&|len| (len, len))?,
            jtr_o: each(&|len| (len, 1))?,
        })
    }

    /// Add samples `a..b` of a block: state rows `js` (row-major, `l` rows
    /// per sample), residual `rr` and the output columns' values.
    pub fn add(
        &mut self,
        js: &[f64],
        rr: &[f64],
        outs: &ByOutput,
        l: usize,
        (a, b): (usize, usize),
    ) {
        let n_state = self.gss.nrows();
        let (len, rows) = (b - a, (b - a) * l);
        let js = &js[a * l * n_state..b * l * n_state];
        let rr = &rr[a * l..b * l];
        if n_state > 0 {
            let jm = MatRef::from_row_major_slice(js, rows, n_state);
            let rm = MatRef::from_column_major_slice(rr, rows, 1);
            gram_add(self.gss.as_mut(), jm, jm, true, Par::Seq);
            gram_add(self.jtr_s.as_mut(), jm, rm, false, Par::Seq);
        }
        // Output columns: nonzero only in the rows of their output.
        for (j, cols) in outs.cols.iter().enumerate() {
            let width = cols.len();
            if width == 0 {
                continue;
            }
            let kj =
                MatRef::from_row_major_slice(&outs.values[j][a * width..b * width], len, width);
            let rj = MatRef::from_row_major_slice_with_stride(&rr[j..], len, 1, l);
            if n_state > 0 {
                let jsj = MatRef::from_row_major_slice_with_stride(
                    &js[j * n_state..],
                    len,
                    n_state,
                    l * n_state,
                );
                gram_add(self.cross[j].as_mut(), kj, jsj, false, Par::Seq);
            }
            gram_add(self.own[j].as_mut(), kj, kj, true, Par::Seq);
            gram_add(self.jtr_o[j].as_mut(), kj, rj, false, Par::Seq);
        }
    }

    /// `self += other`.
    fn merge(&mut self, other: &Sums) {
        let add = |a: &mut Mat<f64>, b: &Mat<f64>| *a += b;
        add(&mut self.gss, &other.gss);
        add(&mut self.jtr_s, &other.jtr_s);
        for j in 0..self.cross.len() {
            add(&mut self.cross[j], &other.cross[j]);
            add(&mut self.own[j], &other.own[j]);
            add(&mut self.jtr_o[j], &other.jtr_o[j]);
        }
    }

    /// The sum of every thread's sums (in the first).
    pub fn total(sums: &mut [Sums]) -> &Sums {
        let (first, others) = sums.split_at_mut(1);
        for other in others.iter() {
            first[0].merge(other);
        }
        &first[0]
    }

    /// `J^T J` and `J^T r` in engine order: state columns, then output columns.
    pub fn assemble(&self, outs: &ByOutput, kcols: usize) -> Result<Normal> {
        let (sum, l) = (self, outs.index.len());
        let n_state = sum.gss.nrows();
        // Assemble in engine order: state columns, then output columns.
        let mut full = try_vec(kcols * kcols, 0.0, "the Gram matrix of a time record")?;
        let mut put = |a: usize, b: usize, v: f64| {
            full[a + b * kcols] = v;
            full[b + a * kcols] = v;
        };
        for b in 0..n_state {
            for a in b..n_state {
                put(a, b, sum.gss[(a, b)]);
            }
        }
        let mut jtr: Vec<f64> = (0..n_state).map(|i| sum.jtr_s[(i, 0)]).collect();
        jtr.resize(kcols, 0.0);
        for j in 0..l {
            let ix = &outs.index[j];
            for (p, &q) in ix.iter().enumerate() {
                let row = n_state + q;
                for b in 0..n_state {
                    put(row, b, sum.cross[j][(p, b)]);
                }
                for (p2, &q2) in ix.iter().enumerate().take(p + 1) {
                    put(row, n_state + q2, sum.own[j][(p, p2)]);
                }
                jtr[row] = sum.jtr_o[j][(p, 0)];
            }
        }
        Ok(Normal {
            k: kcols,
            gram: full,
            jtr,
        })
    }
}
