//! `J^T J` and `J^T r` of the frozen LTI model at one scheduling point,
//! from the Kronecker structure of the Jacobian rows, without the Jacobian.
//!
//! Write the frozen parameters as one matrix `Theta = [A B; C D]`
//! (`(n + l) x (n + r)`). The derivative of `G_jc(z)` with respect to
//! `Theta_ab` is `u_ja v_cb`, with `u_j = [Y_j,:  e_j]` (row `j` of
//! `Y = C (zI - A)^-1`, then the unit vector) and `v_c = [X_:,c; e_c]`
//! (`X = (zI - A)^-1 B`): every Jacobian row is an outer product. With the
//! weights `w_jc` of the residuals (one line; the sums run over the lines),
//!
//! ```text
//! (J^T J)[ab, a'b'] = Re sum_{j,c} w_jc^2 conj(u_ja) u_ja' conj(v_cb) v_cb'
//!                   = Re sum_s U_s[a, a'] V_s[b, b'],
//! ```
//!
//! `s` running over the fewer of the outputs and the inputs: by outputs,
//! `U_s = conj(u_s) u_s^T` and `V_s = sum_c w_sc^2 conj(v_c) v_c^T` (by
//! inputs the other way round). Both are Hermitian, so their real parts are
//! symmetric and their imaginary parts antisymmetric: on one triangle of
//! each, two real matrix products over all samples (line, s) give
//! `S1 = sum Re U Re V` and `S2 = sum Im U Im V`, and
//! `(J^T J)[ab, a'b'] = S1 - S2`, `(J^T J)[a'b, ab'] = S1 + S2` (`a <= a'`,
//! `b <= b'`). Against `J^T J` from the rows of `J` (a triangle of
//! `lti^2` times `2 l r` per line) this takes `2 max(l, r)` times fewer
//! flops: 4x on a 2x2 system, 6x on a 3x3.

use crate::base::gram_product::{
    gram_product, gram_product_with, scratch_len, Kernel, Samples, FAER_ENTRIES,
};
use crate::base::lanes::{Cx, LANES};
use crate::base::layout::{Matrix, Shape};
use crate::error::Result;
use crate::eval::lti::Resolvent;
use crate::memory::{try_grow, try_vec, try_zeros};
use faer::{Accum, Mat};

/// Samples (line and group index) per matrix product: large enough for an
/// efficient product, small enough to stay in cache.
const BLOCK_SAMPLES: usize = 256;

/// Entries of the upper triangle of a `d x d` matrix, diagonal included.
fn packed(d: usize) -> usize {
    d * (d + 1) / 2
}

/// Entries strictly above the diagonal of a `d x d` matrix.
fn strict(d: usize) -> usize {
    d * d.saturating_sub(1) / 2
}

/// Entries of the upper triangle of a `d x d` matrix, its diagonal or not.
fn triangle(d: usize, diagonal: bool) -> usize {
    if diagonal {
        packed(d)
    } else {
        strict(d)
    }
}

/// The entries of column `n + j` of a triangle (its diagonal or not) that
/// are not zero at every sample: rows `0..n`, and with the diagonal the
/// rest of the column (the `j` zeros before the diagonal with it).
fn last_rows(n: usize, j: usize, diagonal: bool) -> std::ops::Range<usize> {
    let start = triangle(n + j, diagonal);
    if diagonal {
        start..packed(n + j + 1)
    } else {
        start..start + n
    }
}

/// Accumulates `S1`, `S2` and `J^T r` over the lines of one point.
#[derive(Debug, Clone)]
pub struct KronGram {
    n: usize,
    l: usize,
    r: usize,
    /// One product per output (`l <= r`), or per input.
    by_output: bool,
    /// `u` of every output, `l x (n + l)`, and `v` of every input, `r x (n + r)`.
    u: Vec<Cx>,
    v: Vec<Cx>,
    /// Real and imaginary triangles of `U` and `V`, one row per entry and
    /// one column per sample (row-major, `BLOCK_SAMPLES` wide).
    u_re: Vec<f64>,
    u_im: Vec<f64>,
    v_re: Vec<f64>,
    v_im: Vec<f64>,
    /// Samples in the current block.
    filled: usize,
    /// Whether `S1` and `S2` hold nothing of the lines added yet (stale
    /// values, or zeros): the next block's products overwrite them.
    fresh: bool,
    /// `S1` (`packed(n + r) x packed(n + l)`) and `S2` (strict triangles).
    s1: Mat<f64>,
    s2: Mat<f64>,
    /// `J^T r` per lane, indexed `a + b (n + l)`.
    jtr: Vec<[f64; LANES]>,
    /// Scratch of [`KronGram::add`]: the squared weights of one sample's
    /// weighted side, and `sum_c conj(v_c) w_jc err_jc` of one output.
    squares: Vec<[f64; LANES]>,
    t: Vec<Cx>,
    /// Scratch of the products in [`KronGram::flush`].
    panels: Vec<f64>,
}

/// What one point's lines add up to: `S1`, `S2` and `J^T r` in LTI order.
#[derive(Debug, Clone)]
pub struct GramParts {
    s1: Mat<f64>,
    s2: Mat<f64>,
    /// `J^T r` over `[vec A; vec B; vec C; vec D]`.
    pub jtr: Vec<f64>,
}

impl KronGram {
    /// An empty accumulator for a model of the given shape, or
    /// [`crate::Error::OutOfMemory`].
    pub fn new(shape: &Shape) -> Result<Self> {
        let Shape { n, r, l, .. } = *shape;
        let (da, db) = (n + l, n + r);
        let by_output = l <= r;
        let cols = Self::block_columns(shape);
        let (s1, s2) = Self::sums(shape)?;
        let samples = "the sample buffers of a Gram accumulator";
        Ok(KronGram {
            n,
            l,
            r,
            by_output,
            u: vec![Cx::default(); l * da],
            v: vec![Cx::default(); r * db],
            u_re: try_vec(packed(da) * cols, 0.0, samples)?,
            u_im: try_vec(strict(da) * cols, 0.0, samples)?,
            v_re: try_vec(packed(db) * cols, 0.0, samples)?,
            v_im: try_vec(strict(db) * cols, 0.0, samples)?,
            filled: 0,
            fresh: true,
            s1,
            s2,
            jtr: vec![[0.0; LANES]; da * db],
            squares: vec![[0.0; LANES]; l.max(r)],
            t: vec![Cx::default(); db],
            panels: try_vec(scratch_len(packed(da), cols), 0.0, samples)?,
        })
    }

    /// Columns of the sample buffers (samples per matrix product).
    pub fn block_columns(shape: &Shape) -> usize {
        let groups = shape.l.min(shape.r);
        BLOCK_SAMPLES.div_ceil(groups * LANES) * groups * LANES
    }

    /// Zero `S1` and `S2` for a model of the given shape, or
    /// [`crate::Error::OutOfMemory`].
    pub fn sums(shape: &Shape) -> Result<(Mat<f64>, Mat<f64>)> {
        let (da, db) = (shape.n + shape.l, shape.n + shape.r);
        let what = "the Gram pieces S1, S2 of a block of lines";
        Ok((
            try_zeros(packed(db), packed(da), what)?,
            try_zeros(strict(db), strict(da), what)?,
        ))
    }

    /// Bytes of one accumulator (its buffers and sums) for a model of the
    /// given shape.
    pub fn bytes(shape: &Shape) -> usize {
        let (da, db) = (shape.n + shape.l, shape.n + shape.r);
        let cols = Self::block_columns(shape);
        let buffers = (packed(da) + strict(da) + packed(db) + strict(db)) * cols;
        8 * (buffers + scratch_len(packed(da), cols)) + GramParts::bytes(shape)
    }

    /// Columns of the sample buffers.
    fn cols(&self) -> usize {
        self.u_re.len() / packed(self.n + self.l)
    }

    /// Add the lines of one batch: `res` evaluated with `yt`, `w[e]` the
    /// weights and `err[e]` the weighted residuals of entry `e = j r + c`
    /// per lane (zero weight on lanes past the batch's lines).
    pub fn add(&mut self, res: &Resolvent, w: &[[f64; LANES]], err: &[Cx]) {
        let (n, l, r) = (self.n, self.l, self.r);
        let (da, db) = (n + l, n + r);
        for j in 0..l {
            let u = &mut self.u[j * da..(j + 1) * da];
            u[..n].copy_from_slice(&res.yt[j * n..(j + 1) * n]);
            for (k, slot) in u[n..].iter_mut().enumerate() {
                *slot = Cx::real(f64::from(u8::from(k == j)));
            }
        }
        for c in 0..r {
            let v = &mut self.v[c * db..(c + 1) * db];
            v[..n].copy_from_slice(&res.x[c * n..(c + 1) * n]);
            for (k, slot) in v[n..].iter_mut().enumerate() {
                *slot = Cx::real(f64::from(u8::from(k == c)));
            }
        }
        let cols = self.cols();
        let groups = l.min(r);
        for s in 0..groups {
            let col = self.filled + s * LANES;
            // The rank-one side and the weighted side of sample s.
            for (o, sq) in self.squares.iter_mut().enumerate() {
                let e = if self.by_output { s * r + o } else { o * r + s };
                for k in 0..LANES {
                    sq[k] = w[e][k] * w[e][k];
                }
            }
            let one = [[1.0; LANES]];
            let sq = &self.squares;
            if self.by_output {
                let u = &self.u[s * da..(s + 1) * da];
                hermitian(u, &one, da, &mut self.u_re, &mut self.u_im, cols, col);
                hermitian(&self.v, sq, db, &mut self.v_re, &mut self.v_im, cols, col);
            } else {
                let v = &self.v[s * db..(s + 1) * db];
                hermitian(v, &one, db, &mut self.v_re, &mut self.v_im, cols, col);
                hermitian(&self.u, sq, da, &mut self.u_re, &mut self.u_im, cols, col);
            }
        }
        // J^T r: Re sum_{j,c} w_jc conj(u_ja v_cb) err_jc.
        let t = &mut self.t;
        for j in 0..l {
            t.iter_mut().for_each(|x| *x = Cx::default());
            for c in 0..r {
                let z = err[j * r + c].scale_lanes(&w[j * r + c]);
                for (tb, vb) in t.iter_mut().zip(&self.v[c * db..(c + 1) * db]) {
                    for k in 0..LANES {
                        tb.re[k] += vb.re[k] * z.re[k] + vb.im[k] * z.im[k];
                        tb.im[k] += vb.re[k] * z.im[k] - vb.im[k] * z.re[k];
                    }
                }
            }
            let u = &self.u[j * da..(j + 1) * da];
            for (b, tb) in t.iter().enumerate() {
                for (a, ua) in u.iter().enumerate() {
                    let g = &mut self.jtr[a + b * da];
                    for (k, gk) in g.iter_mut().enumerate() {
                        *gk += ua.re[k] * tb.re[k] + ua.im[k] * tb.im[k];
                    }
                }
            }
        }
        self.filled += groups * LANES;
        if self.filled + groups * LANES > cols {
            self.flush();
        }
    }

    /// Multiply out the samples of the current block into `S1` and `S2`:
    /// the samples filled, not the whole block. A block left part empty
    /// (the last of a task: 168 of its 264 columns at 3 x 3) once ran its
    /// products over zeroed columns, which add nothing (`x + 0 y` is `x`):
    /// the same sums, a third of n = 24's products for nothing.
    ///
    /// The rank-one side's entries of `Theta`'s last rows (`u_s`'s unit
    /// vector `e_s` by outputs, `v_s`'s by inputs) are zero but on their
    /// own sample's runs: entry `(a, n + j)` is `conj(u_sa)` at the samples
    /// of `s = j` and zero at the others, `(n + j', n + j)` zero but on the
    /// diagonal. Those entries' products run over their own runs of samples
    /// alone, the same sums without the zero terms (14 % of the products
    /// at 3 x 3, 10 % at 2 x 2); products small enough to run on faer
    /// (another order of the sums) run whole.
    ///
    /// The first block after [`KronGram::finish`] or [`KronGram::clear`]
    /// writes its sums over whatever the sums held (no pass of zeros
    /// before: 2.1 MB a task at 3 x 3), the entries that are zero at every
    /// sample set to zero.
    fn flush(&mut self) {
        if self.filled == 0 {
            return;
        }
        let accum = if std::mem::take(&mut self.fresh) {
            Accum::Replace
        } else {
            Accum::Add
        };
        let cols = self.cols();
        let (n, groups, filled) = (self.n, self.l.min(self.r), self.filled);
        let by_output = self.by_output;
        let own = |j: usize| Samples {
            first: j * LANES,
            step: groups * LANES,
            len: LANES,
            count: filled / (groups * LANES),
        };
        let panels = &mut self.panels;
        for (out, vs, us, diagonal) in [
            (&mut self.s1, &self.v_re, &self.u_re, true),
            (&mut self.s2, &self.v_im, &self.u_im, false),
        ] {
            if groups == 1 || out.nrows() * out.ncols() <= FAER_ENTRIES {
                gram_product(out.as_mut(), accum, vs, us, cols, filled, panels);
                continue;
            }
            if matches!(accum, Accum::Replace) {
                for j in 0..groups {
                    let zero = last_rows(n, j, diagonal).end..triangle(n + j + 1, diagonal);
                    let (start, len) = (zero.start, zero.len());
                    match by_output {
                        true => out.as_mut().subcols_mut(start, len).fill(0.0),
                        false => out.as_mut().subrows_mut(start, len).fill(0.0),
                    }
                }
            }
            let mut parts = vec![(0..triangle(n, diagonal), Samples::first(filled))];
            parts.extend((0..groups).map(|j| (last_rows(n, j, diagonal), own(j))));
            for (range, samples) in parts {
                let best = Kernel::best();
                let at = range.start * cols;
                if by_output {
                    let c = out.as_mut().subcols_mut(range.start, range.len());
                    gram_product_with(best, c, accum, vs, &us[at..], cols, samples, panels);
                } else {
                    let c = out.as_mut().subrows_mut(range.start, range.len());
                    gram_product_with(best, c, accum, &vs[at..], us, cols, samples, panels);
                }
            }
        }
        self.filled = 0;
    }

    /// Drop everything added so far.
    pub fn clear(&mut self) {
        self.filled = 0;
        self.fresh = true;
        self.jtr.iter_mut().for_each(|g| *g = [0.0; LANES]);
    }

    /// Everything added since the last call, which leaves the accumulator
    /// empty for the next lines, on `next`: `S1` and `S2` of the shape's
    /// sizes, whatever they hold (the next block's products overwrite
    /// them; its sample buffers are kept too: every column is written
    /// before it is read).
    pub fn finish(&mut self, shape: &Shape, next: (Mat<f64>, Mat<f64>)) -> GramParts {
        self.flush();
        if std::mem::replace(&mut self.fresh, true) {
            // No line since the last call: the sums of none.
            self.s1.as_mut().fill(0.0);
            self.s2.as_mut().fill(0.0);
        }
        let da = self.n + self.l;
        let mut jtr = vec![0.0; shape.lti_len()];
        for (ab, g) in self.jtr.iter_mut().enumerate() {
            jtr[lti_index(shape, ab % da, ab / da)] = g.iter().sum();
            *g = [0.0; LANES];
        }
        let s1 = std::mem::replace(&mut self.s1, next.0);
        let s2 = std::mem::replace(&mut self.s2, next.1);
        GramParts { s1, s2, jtr }
    }
}

impl GramParts {
    /// Bytes of one part (`S1`, `S2` and `J^T r`) for a model of the given shape.
    pub fn bytes(shape: &Shape) -> usize {
        let (da, db) = (shape.n + shape.l, shape.n + shape.r);
        8 * (packed(db) * packed(da) + strict(db) * strict(da) + shape.lti_len())
    }

    /// A part of the given pieces (tests of what sums the parts).
    #[cfg(test)]
    pub(crate) fn of(s1: Mat<f64>, s2: Mat<f64>, jtr: Vec<f64>) -> Self {
        GramParts { s1, s2, jtr }
    }

    /// The bits of every entry of `S1`, `S2` and `J^T r`.
    #[cfg(test)]
    pub(crate) fn bits(&self) -> Vec<u64> {
        let mats = [&self.s1, &self.s2];
        let entries = mats
            .iter()
            .flat_map(|m| (0..m.ncols()).flat_map(move |j| (0..m.nrows()).map(move |i| m[(i, j)])));
        entries
            .chain(self.jtr.iter().copied())
            .map(f64::to_bits)
            .collect()
    }

    /// Its `S1` and `S2`, for reuse.
    pub fn into_sums(self) -> (Mat<f64>, Mat<f64>) {
        (self.s1, self.s2)
    }

    /// Add another part of the same point.
    pub fn merge(&mut self, other: &GramParts) {
        self.s1 += &other.s1;
        self.s2 += &other.s2;
        self.jtr
            .iter_mut()
            .zip(&other.jtr)
            .for_each(|(x, y)| *x += y);
    }

    /// `J^T J` over `[vec A; vec B; vec C; vec D]`, column-major, both
    /// triangles, or [`crate::Error::OutOfMemory`].
    pub fn gram(&self, shape: &Shape) -> Result<Vec<f64>> {
        let Shape { n, r, l, .. } = *shape;
        let (da, db) = (n + l, n + r);
        let lti = shape.lti_len();
        debug_assert_eq!(lti, da * db);
        // No pass of zeros first: every entry is written below.
        let mut h = Vec::new();
        try_grow(&mut h, lti * lti, "the Gram matrix of one scheduling point")?;
        let room = &mut h.spare_capacity_mut()[..lti * lti];
        let mut put = |x: usize, y: usize, v: f64| {
            room[x + y * lti].write(v);
            room[y + x * lti].write(v);
        };
        // `lti_index(a, b)` of every `Theta_ab`, at `a + b da`.
        let index: Vec<usize> = (0..da * db)
            .map(|ab| lti_index(shape, ab % da, ab / da))
            .collect();
        let at = |a: usize, b: usize| index[a + b * da];
        for b2 in 0..db {
            for b in 0..=b2 {
                let iv = b2 * (b2 + 1) / 2 + b;
                let sv = (b < b2).then(|| b2 * (b2 - 1) / 2 + b);
                for a2 in 0..da {
                    for a in 0..=a2 {
                        let s1 = self.s1[(iv, a2 * (a2 + 1) / 2 + a)];
                        let s2 = match sv {
                            Some(sv) if a < a2 => self.s2[(sv, a2 * (a2 - 1) / 2 + a)],
                            _ => 0.0,
                        };
                        put(at(a, b), at(a2, b2), s1 - s2);
                        put(at(a2, b), at(a, b2), s1 + s2);
                    }
                }
            }
        }
        // SAFETY: `try_grow` made room for `lti^2` values, and every one is
        // written: `at` maps the `da db = lti` pairs `(a, b)` one to one onto
        // the LTI indices, and for any two pairs, with `b <= b2` and `a <= a2`
        // their smaller and larger row and column indices, the loops reach
        // `(a, b, a2, b2)`, whose two `put`s write the entries of
        // `(at(a, b), at(a2, b2))` and `(at(a2, b), at(a, b2))` both ways
        // round: the two pairs are one of these.
        unsafe { h.set_len(lti * lti) };
        Ok(h)
    }
}

/// Write the upper triangle of `sum_o c_o conj(x_o) x_o^T` (`d x d`, the
/// vectors `x_o` back to back in `xs`) into column `col` (its [`LANES`]
/// lanes side by side) of the real (diagonal included) and imaginary
/// (strict) sample buffers, `cols` wide.
fn hermitian(
    xs: &[Cx],
    coef: &[[f64; LANES]],
    d: usize,
    re: &mut [f64],
    im: &mut [f64],
    cols: usize,
    col: usize,
) {
    for i2 in 0..d {
        for i in 0..=i2 {
            let (mut sr, mut si) = ([0.0; LANES], [0.0; LANES]);
            for (x, c) in xs.chunks(d).zip(coef) {
                let (p, q) = (&x[i], &x[i2]);
                for k in 0..LANES {
                    sr[k] += c[k] * (p.re[k] * q.re[k] + p.im[k] * q.im[k]);
                    si[k] += c[k] * (p.re[k] * q.im[k] - p.im[k] * q.re[k]);
                }
            }
            let at = (i2 * (i2 + 1) / 2 + i) * cols + col;
            re[at..at + LANES].copy_from_slice(&sr);
            if i < i2 {
                let at = (i2 * (i2 - 1) / 2 + i) * cols + col;
                im[at..at + LANES].copy_from_slice(&si);
            }
        }
    }
}

/// Index of `Theta_ab` (`Theta = [A B; C D]`) in `[vec A; vec B; vec C; vec D]`.
fn lti_index(shape: &Shape, a: usize, b: usize) -> usize {
    let n = shape.n;
    let (x, row, col) = match (a < n, b < n) {
        (true, true) => (Matrix::A, a, b),
        (true, false) => (Matrix::B, a, b - n),
        (false, true) => (Matrix::C, a - n, b),
        (false, false) => (Matrix::D, a - n, b - n),
    };
    let rows = if a < n { n } else { shape.l };
    shape.lti_offset(x) + row + col * rows
}

#[cfg(test)]
#[path = "kron_gram_tests.rs"]
mod tests;
