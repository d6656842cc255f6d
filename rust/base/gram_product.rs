//! The Gram products of [`crate::eval::kron_gram`]: `C += V U^T` for row-major
//! `V` (`m x k`) and `U` (`p x k`) into a column-major `C`; and, for the
//! updates of the Cholesky factorisation ([`super::cholesky`]), the same
//! sums of column-major `V` and `U` ([`gram_product_columns`]).
//!
//! Products of more than [`FAER_ENTRIES`] entries run on the core's own
//! kernels, with every entry summed in one order on every processor: entry
//! `(i, j)` is `C_ij + (((0 + v_i0 u_j0) + v_i1 u_j1) + ...)`, each step one
//! fused multiply-add, its samples in their order. The kernels vectorise
//! across entries (rows of `C`), never across the samples of one entry, so
//! the AVX-512 kernel (8 rows a register), the AVX2 kernel (4) and the
//! plain loop give the same bits: a result does not depend on the
//! processor's vector width. That is the order `gemm` (under faer) sums
//! these products in on an AVX2 processor, so the models are the ones
//! faer's products gave; on AVX-512 processors the kernels are about twice
//! the speed of `gemm`'s AVX2 kernels (its AVX-512 kernels need a nightly
//! compiler).
//!
//! Smaller products stay on faer: `gemm` computes them with dot-product
//! kernels that sum each entry's samples in another order, and the small
//! models (SISO, n <= 4) keep the bits they have always had.

use faer::linalg::matmul::matmul;
use faer::{Accum, MatMut, MatRef, Par};

use crate::base::route::Route;

/// Rows of `C` and columns per register block of each kernel.
const MR_512: usize = 16;
const NR_512: usize = 12;
const MR_256: usize = 8;
const NR_256: usize = 6;

/// Which kernel a product runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Kernel {
    /// The plain loop (`f64::mul_add`).
    Plain,
    /// AVX2 and FMA, 8 x 6 blocks.
    Avx2,
    /// AVX-512F, 16 x 12 blocks.
    Avx512,
}

impl Kernel {
    /// The kernel of the route the core runs ([`crate::base::route::Route::current`]:
    /// the processor's widest unless `LPVID_KERNEL` asks for a narrower one).
    pub fn best() -> Kernel {
        Kernel::of(Route::current())
    }

    /// The kernel of a route.
    pub fn of(route: Route) -> Kernel {
        match route {
            Route::Avx512 => Kernel::Avx512,
            Route::Avx2 => Kernel::Avx2,
            Route::Portable => Kernel::Plain,
        }
    }

    /// Whether this processor runs the kernel.
    pub fn available(self) -> bool {
        self <= Kernel::of(Route::detected())
    }
}

/// Length of the scratch [`gram_product`] needs for `p` columns of `C` and
/// `k` samples, on any kernel.
pub fn scratch_len(p: usize, k: usize) -> usize {
    MR_512 * k + p.div_ceil(NR_256) * NR_256 * k + NR_512 * k + MR_512 * NR_512
}

/// Products of at most this many entries (`m p`) run on faer: `gemm`'s
/// dot-product kernels take them (`m n <= 16 * 16` in `gemm-common`), in
/// another order of the samples than the core's kernels.
pub const FAER_ENTRIES: usize = 256;

/// The samples a product runs over, in order: `count` runs of `len`
/// consecutive samples, run `i` from sample `first + i step`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Samples {
    /// The first sample of the first run.
    pub first: usize,
    /// From the start of one run to the next.
    pub step: usize,
    /// Samples per run.
    pub len: usize,
    /// Runs.
    pub count: usize,
}

impl Samples {
    /// The first `k` samples.
    pub fn first(k: usize) -> Self {
        Samples {
            first: 0,
            step: k,
            len: k,
            count: 1,
        }
    }

    /// How many samples.
    pub fn total(&self) -> usize {
        self.len * self.count
    }

    /// One past the last sample (0 when there is none).
    fn end(&self) -> usize {
        match self.total() {
            0 => 0,
            _ => self.first + (self.count - 1) * self.step + self.len,
        }
    }

    /// Every sample, in order.
    fn iter(self) -> impl Iterator<Item = usize> {
        (0..self.count).flat_map(move |i| {
            let start = self.first + i * self.step;
            start..start + self.len
        })
    }
}

/// `C += V U^T` (`accum` [`Accum::Add`]) or `C = V U^T` ([`Accum::Replace`],
/// whatever `C` held: the same bits as `C = 0` and `+=`) over the first `k`
/// samples: `V` is `m x stride` row-major (`v[i * stride + s]`), `U`
/// `p x stride`, `C` `m x p`; on faer when `C` has at most [`FAER_ENTRIES`]
/// entries, else on the widest kernel the processor runs. `scratch` holds
/// at least [`scratch_len`]`(p, k)` values (its contents are overwritten).
pub fn gram_product(
    mut c: MatMut<'_, f64>,
    accum: Accum,
    v: &[f64],
    u: &[f64],
    stride: usize,
    k: usize,
    scratch: &mut [f64],
) {
    let (m, p) = (c.nrows(), c.ncols());
    if m * p <= FAER_ENTRIES {
        let vm = MatRef::from_row_major_slice(&v[..m * stride], m, stride).get(.., ..k);
        let um = MatRef::from_row_major_slice(&u[..p * stride], p, stride).get(.., ..k);
        if matches!(accum, Accum::Replace) {
            c.fill(0.0);
        }
        matmul(c, Accum::Add, vm, um.transpose(), 1.0, Par::Seq);
        return;
    }
    let samples = Samples::first(k);
    gram_product_with(Kernel::best(), c, accum, v, u, stride, samples, scratch);
}

/// [`gram_product`] on a given kernel (the plain loop when the processor
/// does not run it), over the given samples: each entry's sum runs over
/// them in their order, so leaving out samples whose products are zero
/// (`0 y` for finite `y`) leaves every entry's bits as they were. Each sum
/// starts from `+0`, and fused multiply-adds from `+0` never give `-0`: so
/// replacing `C` by the sums is adding them to zeros, to the last bit.
#[allow(clippy::too_many_arguments)]
pub fn gram_product_with(
    kernel: Kernel,
    mut c: MatMut<'_, f64>,
    accum: Accum,
    v: &[f64],
    u: &[f64],
    stride: usize,
    samples: Samples,
    scratch: &mut [f64],
) {
    let (m, p) = (c.nrows(), c.ncols());
    let k = samples.total();
    assert!(samples.end() <= stride, "samples past the stride {stride}");
    assert!(v.len() >= m * stride && u.len() >= p * stride);
    assert!(scratch.len() >= scratch_len(p, k), "scratch too short");
    let add = matches!(accum, Accum::Add);
    if nothing_to_sum(c.as_mut(), add, k) {
        return;
    }
    let kernel = if kernel.available() {
        kernel
    } else {
        Kernel::Plain
    };
    if kernel == Kernel::Plain {
        return plain(c, add, v, u, stride, samples);
    }
    blocks(
        kernel,
        c,
        add,
        k,
        scratch,
        |panel, r0, width| pack(panel, v, stride, samples, r0, width, m),
        |panel, r0, width| pack(panel, u, stride, samples, r0, width, p),
    );
}

/// `C += V U^T` (or `C = V U^T`, `accum` [`Accum::Replace`]) for
/// column-major `V` (`m x k`) and `U` (`p x k`), `V` negated when
/// `negate_v` (exactly: `(-V) U^T`): the sums of [`gram_product_with`]
/// over their `k` samples on `kernel` (the plain loop when the processor
/// does not run it), whatever the size of `C`. Each sample's values of a
/// block of rows lie together here, so their panels are copies rather
/// than transposes. `scratch` holds at least [`scratch_len`]`(p, k)` values.
pub fn gram_product_columns(
    kernel: Kernel,
    c: MatMut<'_, f64>,
    accum: Accum,
    v: MatRef<'_, f64>,
    u: MatRef<'_, f64>,
    negate_v: bool,
    scratch: &mut [f64],
) {
    let (m, p) = (c.nrows(), c.ncols());
    let k = v.ncols();
    assert!(v.nrows() == m && u.nrows() == p && u.ncols() == k, "shapes");
    assert!(scratch.len() >= scratch_len(p, k), "scratch too short");
    let add = matches!(accum, Accum::Add);
    let mut c = c;
    if nothing_to_sum(c.as_mut(), add, k) {
        return;
    }
    let sign = if negate_v { -1.0 } else { 1.0 };
    blocks(
        kernel,
        c,
        add,
        k,
        scratch,
        |panel, r0, width| pack_columns(panel, v, r0, width, sign),
        |panel, r0, width| pack_columns(panel, u, r0, width, 1.0),
    );
}

/// Whether a product of `k` samples into `c` has no sum to take: `c` is
/// empty, or `k` is zero (then `c` is left, or zeroed when not `add`).
fn nothing_to_sum(mut c: MatMut<'_, f64>, add: bool, k: usize) -> bool {
    if c.nrows() == 0 || c.ncols() == 0 {
        return true;
    }
    if k == 0 && !add {
        c.fill(0.0);
    }
    k == 0
}

/// Rows `r0..r0 + width` of a column-major matrix times `sign`, sample by
/// sample: `panel[s * width + q] = sign x[r0 + q, s]`, zero past its rows.
fn pack_columns(panel: &mut [f64], x: MatRef<'_, f64>, r0: usize, width: usize, sign: f64) {
    let live = x.nrows().saturating_sub(r0).min(width);
    for s in 0..x.ncols() {
        let to = &mut panel[s * width..(s + 1) * width];
        let col = x.col(s);
        for (q, slot) in to[..live].iter_mut().enumerate() {
            *slot = sign * col[r0 + q];
        }
        to[live..].fill(0.0);
    }
}

/// The products of [`gram_product_with`] and [`gram_product_columns`] on a
/// blocking kernel (the plain loop on packed panels when the processor does
/// not run `kernel`, or for [`Kernel::Plain`]): `pack_v(panel, r0, width)`
/// and `pack_u` fill a panel of `width` rows from `r0` on, sample by sample.
fn blocks(
    kernel: Kernel,
    mut c: MatMut<'_, f64>,
    add: bool,
    k: usize,
    scratch: &mut [f64],
    pack_v: impl Fn(&mut [f64], usize, usize),
    pack_u: impl Fn(&mut [f64], usize, usize),
) {
    let (m, p) = (c.nrows(), c.ncols());
    let kernel = if kernel.available() {
        kernel
    } else {
        Kernel::Plain
    };
    let (mr, nr) = match kernel {
        Kernel::Plain | Kernel::Avx2 => (MR_256, NR_256),
        Kernel::Avx512 => (MR_512, NR_512),
    };
    // Panels: `mr` rows of V (and `nr` of U) side by side per sample, rows
    // past the end zero (their entries are computed and dropped).
    let (vp, rest) = scratch.split_at_mut(mr * k);
    let (up, rest) = rest.split_at_mut(p.div_ceil(nr) * nr * k);
    let block = &mut rest[..mr * nr];
    for (jp, panel) in up.chunks_mut(nr * k).enumerate() {
        pack_u(panel, jp * nr, nr);
    }
    // Whole blocks of a C with contiguous columns are added to (or
    // written) in place; the others summed from zero in `block`.
    let ldc = usize::try_from(c.col_stride())
        .ok()
        .filter(|_| c.row_stride() == 1);
    for i0 in (0..m).step_by(mr) {
        pack_v(vp, i0, mr);
        for (jp, panel) in up.chunks(nr * k).enumerate() {
            let j0 = jp * nr;
            let whole = i0 + mr <= m && j0 + nr <= p;
            let (out, ld, onto) = match ldc {
                Some(ld) if whole => (c.as_mut().get_mut(i0.., j0..).as_ptr_mut(), ld, add),
                _ => {
                    block.iter_mut().for_each(|x| *x = 0.0);
                    (block.as_mut_ptr(), mr, true)
                }
            };
            // SAFETY: the kernel is available (checked above); the panels
            // hold `k` samples of `mr` (`nr`) values, and `out` is an
            // `mr x nr` block with columns `ld` apart: in `C` (a whole
            // block of it, its columns contiguous) or in `block`.
            unsafe {
                match kernel {
                    #[cfg(target_arch = "x86_64")]
                    Kernel::Avx512 => x86::block_512(vp, panel, k, out, ld, onto),
                    #[cfg(target_arch = "x86_64")]
                    Kernel::Avx2 => x86::block_256(vp, panel, k, out, ld, onto),
                    _ => block_plain(vp, panel, k, mr, nr, out, ld, onto),
                }
            };
            if out == block.as_mut_ptr() {
                for jj in 0..nr.min(p - j0) {
                    let mut col = c.as_mut().col_mut(j0 + jj);
                    for ii in 0..mr.min(m - i0) {
                        let sum = block[jj * mr + ii];
                        col[i0 + ii] = if add { col[i0 + ii] + sum } else { sum };
                    }
                }
            }
        }
    }
}

/// Rows `r0..r0 + width` of a row-major `rows x stride` matrix at the
/// given samples, sample by sample (run after run; [`pack_run`]).
fn pack(
    panel: &mut [f64],
    x: &[f64],
    stride: usize,
    samples: Samples,
    r0: usize,
    width: usize,
    rows: usize,
) {
    let len = samples.len;
    for i in 0..samples.count {
        let from = samples.first + i * samples.step;
        pack_run(
            &mut panel[i * len * width..],
            &x[from..],
            stride,
            len,
            r0,
            width,
            rows,
        );
    }
}

/// Rows `r0..r0 + width` of a row-major `rows x stride` matrix, sample by
/// sample: `panel[s * width + q] = x[(r0 + q) * stride + s]`, zero past
/// `rows`. Where the processor runs AVX2 (every one whose kernels pack),
/// four rows by four samples at a time are transposed in registers: a copy
/// either way, the same panels.
fn pack_run(
    panel: &mut [f64],
    x: &[f64],
    stride: usize,
    k: usize,
    r0: usize,
    width: usize,
    rows: usize,
) {
    let panel = &mut panel[..k * width];
    let live = rows.saturating_sub(r0).min(width);
    let mut q = 0;
    #[cfg(target_arch = "x86_64")]
    if Route::avx2() {
        let whole = k / 4 * 4;
        while q + 4 <= live {
            let rows4 = &x[(r0 + q) * stride..];
            // SAFETY: AVX2 is available; rows `r0 + q..r0 + q + 4` of `x`
            // have `k` samples each, and the panel `k * width` values.
            unsafe { x86::transpose4(panel, rows4, stride, whole, q, width) };
            for s in whole..k {
                for qq in q..q + 4 {
                    panel[s * width + qq] = x[(r0 + qq) * stride + s];
                }
            }
            q += 4;
        }
    }
    for qq in q..width {
        if qq < live {
            let row = &x[(r0 + qq) * stride..(r0 + qq) * stride + k];
            for (s, &value) in row.iter().enumerate() {
                panel[s * width + qq] = value;
            }
        } else {
            for s in 0..k {
                panel[s * width + qq] = 0.0;
            }
        }
    }
}

/// The plain loop, entry by entry.
fn plain(mut c: MatMut<'_, f64>, add: bool, v: &[f64], u: &[f64], stride: usize, samples: Samples) {
    let (m, p) = (c.nrows(), c.ncols());
    for j in 0..p {
        let uj = &u[j * stride..(j + 1) * stride];
        for i in 0..m {
            let vi = &v[i * stride..(i + 1) * stride];
            let mut acc = 0.0f64;
            for s in samples.iter() {
                acc = vi[s].mul_add(uj[s], acc);
            }
            c[(i, j)] = if add { c[(i, j)] + acc } else { acc };
        }
    }
}

/// Adds a block of `mr x nr` sums from the panels to `out` (columns `ld`
/// apart), or writes them there (`add` false), plainly (other
/// architectures, and processors without the kernel asked for).
///
/// # Safety
/// `out` is an `mr x nr` block with columns `ld` apart.
#[allow(clippy::too_many_arguments)]
unsafe fn block_plain(
    vp: &[f64],
    up: &[f64],
    k: usize,
    mr: usize,
    nr: usize,
    out: *mut f64,
    ld: usize,
    add: bool,
) {
    for jj in 0..nr {
        for ii in 0..mr {
            let mut acc = 0.0f64;
            for s in 0..k {
                acc = vp[s * mr + ii].mul_add(up[s * nr + jj], acc);
            }
            let at = out.add(jj * ld + ii);
            *at = if add { *at + acc } else { acc };
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[path = "gram_x86.rs"]
mod x86;

#[cfg(test)]
#[path = "gram_product_tests.rs"]
mod tests;
