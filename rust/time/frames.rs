//! The matrices of the recursion at every sample of a block: the state
//! transition `Ad(t)`, the output matrix `C(t)`, the basis weights
//! `[1, psi(t)]` and, for continuous-time models, the forcing vectors of
//! the state columns (the derivative of the zero-order hold).

use super::hold::Hold;
#[cfg(test)]
use super::hold_reference;
use super::record::Record;
use crate::base::layout::{Matrix, Shape};
use crate::error::{Error, Result};
use crate::memory::try_vec;
use rayon::prelude::*;

/// Samples per parallel task when the frames are filled (the hold of a
/// continuous-time model costs far more per sample than a discrete-time
/// frame; 64 keeps both cores busy on one block of samples either way).
const FILL_BLOCK: usize = 64;

/// The coefficient matrices `X(0..=Nb)` row-major, one after the other.
#[derive(Debug, Clone)]
pub(crate) struct Coefficients {
    pub n: usize,
    pub r: usize,
    pub l: usize,
    pub m: usize,
    a: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
}

impl Coefficients {
    /// From `theta` (checked by the caller).
    pub fn new(shape: &Shape, theta: &[f64]) -> Coefficients {
        let m = shape.n_coef();
        let take = |x: Matrix| {
            let (rows, cols) = shape.dims(x);
            let mut out = vec![0.0; m * rows * cols];
            for i in 0..m {
                let block = &theta[shape.block(x, i)];
                for row in 0..rows {
                    for col in 0..cols {
                        out[(i * rows + row) * cols + col] = block[row + col * rows];
                    }
                }
            }
            out
        };
        Coefficients {
            n: shape.n,
            r: shape.r,
            l: shape.l,
            m,
            a: take(Matrix::A),
            b: take(Matrix::B),
            c: take(Matrix::C),
        }
    }

    /// `out = sum_i w_i X(i)` for coefficient matrices of `size` entries.
    fn combine(coefs: &[f64], size: usize, w: &[f64], out: &mut [f64]) {
        out.copy_from_slice(&coefs[..size]);
        for (i, &wi) in w.iter().enumerate().skip(1) {
            if wi != 0.0 {
                let x = &coefs[i * size..(i + 1) * size];
                out.iter_mut().zip(x).for_each(|(o, v)| *o += wi * v);
            }
        }
    }
}

/// The frames of a block of samples.
#[derive(Debug, Clone)]
pub(crate) struct Frames {
    n: usize,
    l: usize,
    m: usize,
    s: usize,
    /// `Ad(t)`, `n x n` row-major per sample.
    ad: Vec<f64>,
    /// `C(t)`, `l x n` row-major per sample.
    c: Vec<f64>,
    /// `[1, psi_1(t), ..., psi_Nb(t)]` per sample.
    psi1: Vec<f64>,
    /// Continuous time with state columns: `dt L(M, e_a e_b^T) z(t)` at
    /// `((a s + b) n + c)` per sample; empty otherwise.
    forcing: Vec<f64>,
    /// Tests: compute the hold's derivative the way it was computed
    /// before ([`hold_reference`]).
    #[cfg(test)]
    pub reference: bool,
}

impl Frames {
    /// Room for `capacity` samples; `forcing` when the hold's derivative
    /// is needed. [`crate::Error::OutOfMemory`] when they cannot be had.
    pub fn new(coef: &Coefficients, capacity: usize, forcing: bool) -> Result<Frames> {
        let (n, l, m) = (coef.n, coef.l, coef.m);
        let s = n + coef.r;
        let what = "the matrices of a block of samples";
        Ok(Frames {
            n,
            l,
            m,
            s,
            ad: try_vec(capacity * n * n, 0.0, what)?,
            c: try_vec(capacity * l * n, 0.0, what)?,
            psi1: try_vec(capacity * m, 0.0, what)?,
            forcing: if forcing {
                try_vec(
                    capacity * n * s * n,
                    0.0,
                    "the hold's derivatives of a block of samples",
                )?
            } else {
                Vec::new()
            },
            #[cfg(test)]
            reference: false,
        })
    }

    /// `Ad` at sample `k` of the block.
    #[inline(always)]
    pub fn ad(&self, k: usize) -> &[f64] {
        let nn = self.n * self.n;
        &self.ad[k * nn..(k + 1) * nn]
    }

    /// `C` at sample `k` of the block.
    #[inline(always)]
    pub fn c(&self, k: usize) -> &[f64] {
        let ln = self.l * self.n;
        &self.c[k * ln..(k + 1) * ln]
    }

    /// `[1, psi(t)]` at sample `k` of the block.
    #[inline(always)]
    pub fn psi1(&self, k: usize) -> &[f64] {
        &self.psi1[k * self.m..(k + 1) * self.m]
    }

    /// The forcing vectors at sample `k` (continuous time), if computed.
    #[inline(always)]
    pub fn forcing(&self, k: usize) -> Option<&[f64]> {
        let size = self.n * self.s * self.n;
        (!self.forcing.is_empty()).then(|| &self.forcing[k * size..(k + 1) * size])
    }

    /// Fill samples `t0..t1` of `record`, in parallel. `hold` is the sample
    /// time of a continuous-time model (None: discrete time); `states`
    /// the nominal trajectory `(T + 1) x n`, needed for the forcing.
    pub fn fill(
        &mut self,
        coef: &Coefficients,
        record: &Record,
        states: &[f64],
        hold: Option<f64>,
        (t0, t1): (usize, usize),
    ) -> Result<()> {
        let (n, l, m, s) = (self.n, self.l, self.m, self.s);
        let (nn, ln, fs) = (n * n, l * n, n * s * n);
        let len = t1 - t0;
        let with_forcing = !self.forcing.is_empty();
        let mut forcing_parts: Vec<&mut [f64]> = if with_forcing {
            self.forcing[..len * fs]
                .chunks_mut(FILL_BLOCK * fs)
                .collect()
        } else {
            Vec::new()
        };
        forcing_parts.resize_with(len.div_ceil(FILL_BLOCK), Default::default);
        let tasks: Vec<_> = self.ad[..len * nn]
            .chunks_mut(FILL_BLOCK * nn)
            .zip(self.c[..len * ln].chunks_mut(FILL_BLOCK * ln))
            .zip(self.psi1[..len * m].chunks_mut(FILL_BLOCK * m))
            .zip(forcing_parts)
            .enumerate()
            .collect();
        let nb = m - 1;
        #[cfg(test)]
        let reference = self.reference;
        #[cfg(not(test))]
        let reference = false;
        tasks.into_par_iter().try_for_each_init(
            || None,
            |work: &mut Option<Sample>, (task, (((ad, c), psi1), forcing))| {
                for (k, psi1) in psi1.chunks_exact_mut(m).enumerate() {
                    let t = t0 + task * FILL_BLOCK + k;
                    psi1[0] = 1.0;
                    psi1[1..].copy_from_slice(&record.psi()[t * nb..(t + 1) * nb]);
                    Coefficients::combine(&coef.c, ln, psi1, &mut c[k * ln..(k + 1) * ln]);
                    let adk = &mut ad[k * nn..(k + 1) * nn];
                    match hold {
                        None => Coefficients::combine(&coef.a, nn, psi1, adk),
                        Some(dt) => {
                            let f = with_forcing.then(|| &mut forcing[k * fs..(k + 1) * fs]);
                            let sample = match work {
                                Some(sample) => sample,
                                None => work.insert(Sample::new(coef, reference)?),
                            };
                            // With AVX2 and FMA where the route has them.
                            let step = || sample.hold(coef, record, states, dt, t, psi1, adk, f);
                            let held = match crate::base::route::Route::avx2() {
                                true => pulp::Arch::new().dispatch(step),
                                false => step(),
                            };
                            held.map_err(|e| {
                                Error::Numerical(format!("{e} (zero-order hold at sample {t})"))
                            })?;
                        }
                    }
                }
                Ok(())
            },
        )
    }
}

/// Per-thread scratch space of the continuous-time frames.
struct Sample {
    hold: Hold,
    a: Vec<f64>,
    b: Vec<f64>,
    v: Vec<f64>,
    /// Tests: the reference derivative and its matrices.
    #[cfg(test)]
    reference: Option<(hold_reference::Hold, Vec<f64>, Vec<f64>)>,
}

impl Sample {
    fn new(coef: &Coefficients, reference: bool) -> Result<Sample> {
        let (n, r) = (coef.n, coef.r);
        #[cfg(not(test))]
        let _ = reference;
        Ok(Sample {
            hold: Hold::new(n)?,
            a: vec![0.0; n * n],
            b: vec![0.0; n * r],
            v: vec![0.0; n],
            #[cfg(test)]
            reference: reference.then(|| {
                let s = n + r;
                (
                    hold_reference::Hold::new(n, r),
                    vec![0.0; s * s],
                    vec![0.0; s * s],
                )
            }),
        })
    }

    /// `Ad(t)` and, when asked, `dt L(M, e_a e_b^T) z(t)` into `forcing`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn hold(
        &mut self,
        coef: &Coefficients,
        record: &Record,
        states: &[f64],
        dt: f64,
        t: usize,
        psi1: &[f64],
        ad: &mut [f64],
        forcing: Option<&mut [f64]>,
    ) -> Result<()> {
        let (n, r) = (coef.n, coef.r);
        Coefficients::combine(&coef.a, n * n, psi1, &mut self.a);
        Coefficients::combine(&coef.b, n * r, psi1, &mut self.b);
        let u = &record.u()[t * r..(t + 1) * r];
        #[cfg(test)]
        if let Some((hold, m, e)) = &mut self.reference {
            return reference(
                hold,
                m,
                e,
                (&self.a, &self.b),
                states,
                u,
                dt,
                t,
                ad,
                forcing,
            );
        }
        self.a.iter_mut().for_each(|x| *x *= dt);
        match forcing {
            None => self.hold.compute(&self.a, None, ad),
            Some(f) => {
                for (i, v) in self.v.iter_mut().enumerate() {
                    *v = dt
                        * self.b[i * r..(i + 1) * r]
                            .iter()
                            .zip(u)
                            .map(|(p, q)| p * q)
                            .sum::<f64>();
                }
                let x = &states[t * n..(t + 1) * n];
                self.hold.compute(&self.a, Some((&self.v, x)), ad)?;
                self.hold.forcing(dt, u, f);
                Ok(())
            }
        }
    }
}

/// [`Sample::hold`] the way it was computed before: one Van Loan
/// exponential per row on `[[A, B], [0, 0]] dt` of size `n + r`.
#[cfg(test)]
#[allow(clippy::too_many_arguments)]
fn reference(
    hold: &mut hold_reference::Hold,
    m: &mut [f64],
    e: &mut [f64],
    (a, b): (&[f64], &[f64]),
    states: &[f64],
    u: &[f64],
    dt: f64,
    t: usize,
    ad: &mut [f64],
    forcing: Option<&mut [f64]>,
) -> Result<()> {
    let (n, r) = (ad.len().isqrt(), u.len());
    let s = n + r;
    m.fill(0.0);
    for i in 0..n {
        for j in 0..n {
            m[i * s + j] = dt * a[i * n + j];
        }
        for j in 0..r {
            m[i * s + n + j] = dt * b[i * r + j];
        }
    }
    match forcing {
        None => hold.compute(m, None, e, &mut [])?,
        Some(f) => {
            let mut z = states[t * n..(t + 1) * n].to_vec();
            z.extend_from_slice(u);
            hold.compute(m, Some(&z), e, f)?;
            f.iter_mut().for_each(|v| *v *= dt);
        }
    }
    for i in 0..n {
        ad[i * n..(i + 1) * n].copy_from_slice(&e[i * s..i * s + n]);
    }
    Ok(())
}
