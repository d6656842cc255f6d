//! The Cholesky factorisation of [`super::dense::factor_lower`]: faer's, to
//! the last bit, with its trailing updates on the core's Gram kernel where
//! the processor runs AVX-512.
//!
//! faer 0.21 factors a matrix wider than 64 in blocks of up to 128 columns
//! (each block again by this recursion), and after each block subtracts
//! `L10 L10^T` from the lower triangle of the rest: most of the work.
//! That product runs on `gemm`, whose AVX-512 kernels need a nightly
//! compiler, so on an AVX-512 processor it ran on the AVX2 kernels. Here
//! the same recursion calls faer for everything but the large rectangles
//! of that update, which go to the AVX-512 kernel of
//! [`super::gram_product`]. That kernel sums every entry in the order
//! `gemm` sums it on AVX2 (each sample one fused multiply-add from `+0`,
//! then added to the entry), and the update's rectangles are cut where
//! faer cuts them (halves down to 16 rows, whose diagonal blocks and
//! products of at most [`FAER_ENTRIES`] entries stay on faer), so the
//! factor is faer's bit for bit: the same models on every route. faer's
//! `-1 x (L L^T)` added is `(-L) L^T` added: the kernel takes the rows of
//! `L` negated (negation is exact). A rectangle goes to the kernel
//! [`COLUMNS`] columns at a time, so that the panel of those columns stays
//! in the core's cache while every row of the rectangle passes it.
//!
//! Elsewhere (the AVX2 and portable routes) the factorisation is faer's own.

use crate::base::dense::scratch;
use crate::base::gram_product::{gram_product_columns, scratch_len, Kernel, FAER_ENTRIES};
use crate::error::Result;
use crate::memory::try_grow;
use faer::dyn_stack::MemStack;
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::matmul::matmul;
use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::{Accum, MatMut, MatRef, Par};

/// Widest block faer factors without blocking (its `recursion_threshold`).
const BASE: usize = 64;
/// Widest block of columns faer factors at a time (its `blocksize`).
const BLOCK: usize = 128;
/// Rows of the update's blocks on the diagonal, which faer computes whole.
const DIAGONAL: usize = 16;
/// Columns of a rectangle the kernel takes at a time: their panel (of up
/// to 128 samples, faer's block) is 240 KB.
pub const COLUMNS: usize = 240;

/// Factor `a` in place, `L` in its lower triangle, as faer's
/// `cholesky_in_place` does; `kernel` runs the updates' large rectangles
/// (None: faer's own factorisation). False when `a` is not numerically
/// positive definite.
pub fn factor(a: MatMut<'_, f64>, kernel: Option<Kernel>, par: Par) -> Result<bool> {
    let n = a.nrows();
    // faer's factorisation takes a column of `n`; this one factors faer's
    // way blocks of at most BASE.
    let widest = if kernel.is_some() { n.min(BASE) } else { n };
    let req = cholesky_in_place_scratch::<f64>(widest, par, Default::default());
    let mut mem = scratch(req, "the scratch space of a Cholesky factorisation")?;
    let stack = MemStack::new(&mut mem);
    match kernel {
        None => Ok(base(a, par, stack)),
        Some(kernel) => blocked(a, kernel, par, stack, &mut Vec::new()),
    }
}

/// The kernel [`super::dense::factor_lower`] hands the updates to: the
/// AVX-512 one where the route runs it (elsewhere `gemm`'s kernels are the
/// same width).
pub fn kernel_for_updates() -> Option<Kernel> {
    (Kernel::best() == Kernel::Avx512).then_some(Kernel::Avx512)
}

/// faer's factorisation of `a` (for a block of at most [`BASE`] columns,
/// its unblocked one).
fn base(a: MatMut<'_, f64>, par: Par, stack: &mut MemStack) -> bool {
    cholesky_in_place(a, Default::default(), par, stack, Default::default()).is_ok()
}

/// faer's recursion (`cholesky_recursion` of its LDL^T module, as `L L^T`);
/// `scratch` is the kernel's, grown when needed and kept for the next
/// rectangle.
fn blocked(
    mut a: MatMut<'_, f64>,
    kernel: Kernel,
    par: Par,
    stack: &mut MemStack,
    scratch: &mut Vec<f64>,
) -> Result<bool> {
    let n = a.ncols();
    if n <= BASE {
        return Ok(base(a, par, stack));
    }
    let width = (n.next_power_of_two() / 2).min(BLOCK);
    let mut j = 0;
    while j < n {
        let bs = width.min(n - j);
        let (mut a00, _, mut a10, a11) = a.as_mut().get_mut(j.., j..).split_at_mut(bs, bs);
        if !blocked(a00.as_mut(), kernel, par, stack, scratch)? {
            return Ok(false);
        }
        solve_lower_triangular_in_place(a00.as_ref(), a10.as_mut().transpose_mut(), par);
        update(a11, a10.as_ref(), kernel, par, scratch)?;
        j += bs;
    }
    Ok(true)
}

/// An update's panel `L` (`m x k`, the rows below the block just
/// factored) and the kernel its rectangles go to.
struct Panel<'a> {
    l: MatRef<'a, f64>,
    kernel: Kernel,
}

/// `a11 -= l l^T` on the lower triangle of `a11`, as faer's triangular
/// product (`mat_x_mat_into_lower`).
fn update(
    a11: MatMut<'_, f64>,
    l: MatRef<'_, f64>,
    kernel: Kernel,
    par: Par,
    scratch: &mut Vec<f64>,
) -> Result<()> {
    if l.nrows() == 0 {
        return Ok(());
    }
    lower(a11, &Panel { l, kernel }, 0, par, scratch)
}

/// The lower triangle of `dst -= L_r L_r^T`, `L_r` the panel's rows from
/// `r0` on (as many as `dst` has): halves, as faer cuts them. Where the
/// halves run side by side, the second has a scratch of its own.
fn lower(
    dst: MatMut<'_, f64>,
    panel: &Panel<'_>,
    r0: usize,
    par: Par,
    scratch: &mut Vec<f64>,
) -> Result<()> {
    let n = dst.nrows();
    let k = panel.l.ncols();
    if n <= DIAGONAL {
        let l = panel.l.subrows(r0, n);
        triangular::matmul(
            dst,
            BlockStructure::TriangularLower,
            Accum::Add,
            l,
            BlockStructure::Rectangular,
            l.transpose(),
            BlockStructure::Rectangular,
            -1.0,
            Par::Seq,
        );
        return Ok(());
    }
    let h = n / 2;
    let (top, _, left, bottom) = dst.split_at_mut(h, h);
    let square = |scratch: &mut Vec<f64>| rectangle(left, panel, r0 + h, r0, scratch);
    let triangles = |scratch: &mut Vec<f64>| -> Result<()> {
        lower(top, panel, r0, par, scratch)?;
        lower(bottom, panel, r0 + h, par, scratch)
    };
    // faer's own limit for running the halves side by side (no bit depends on it).
    if matches!(par, Par::Rayon(_)) && n * n * k >= BLOCK * BLOCK * BLOCK {
        let (a, b) = rayon::join(|| square(scratch), || triangles(&mut Vec::new()));
        a.and(b)
    } else {
        square(scratch)?;
        triangles(scratch)
    }
}

/// `dst -= L_i L_j^T`, `L_i` the panel's rows from `i0` on and `L_j` from
/// `j0` (as many as `dst` has rows and columns): on faer as faer's product
/// computes it when it has at most [`FAER_ENTRIES`] entries, else on the
/// kernel, [`COLUMNS`] columns at a time (`scratch` grown when shorter
/// than the kernel needs).
fn rectangle(
    mut dst: MatMut<'_, f64>,
    panel: &Panel<'_>,
    i0: usize,
    j0: usize,
    scratch: &mut Vec<f64>,
) -> Result<()> {
    let (m, p) = dst.shape();
    let k = panel.l.ncols();
    if m * p <= FAER_ENTRIES {
        let li = panel.l.subrows(i0, m);
        let lj = panel.l.subrows(j0, p);
        matmul(dst, Accum::Add, li, lj.transpose(), -1.0, Par::Seq);
        return Ok(());
    }
    let need = scratch_len(p.min(COLUMNS), k);
    if scratch.len() < need {
        try_grow(
            scratch,
            need - scratch.len(),
            "the scratch of a Cholesky factor's update",
        )?;
        scratch.resize(need, 0.0);
    }
    let li = panel.l.subrows(i0, m);
    for c0 in (0..p).step_by(COLUMNS) {
        let cols = COLUMNS.min(p - c0);
        gram_product_columns(
            panel.kernel,
            dst.as_mut().subcols_mut(c0, cols),
            Accum::Add,
            li,
            panel.l.subrows(j0 + c0, cols),
            true,
            scratch,
        );
    }
    Ok(())
}

#[cfg(test)]
#[path = "cholesky_tests.rs"]
mod tests;
