//! The output-error cost of time records as an [`Objective`].

use super::columns::Columns;
use super::frames::Coefficients;
use super::record::{InitialState, Record};
use super::schur::{eliminate, estimate};
use super::sensitivity::{Normal, Pass};
use super::StageTimes;
use crate::base::layout::{FreeSet, Shape};
use crate::error::{invalid, Result};
use crate::eval::model::ModelAt;
use crate::eval::objective::{GaussNewton, Objective};
use crate::memory::try_vec;
use crate::simulate::{simulate, simulate_zoh, Trajectory};
use std::time::Instant;

/// Largest weighted residual accepted: a model whose output error grows
/// past it diverges along the record. Far below the overflow of its
/// square, so that the sensitivities (larger by up to the record length)
/// and their Gram matrix stay finite too.
const LARGEST_RESIDUAL: f64 = 1e100;

/// Time records of one system, the model shape, the time domain and how
/// the initial states and the first samples are treated.
#[derive(Debug, Clone)]
pub struct TimeProblem {
    shape: Shape,
    records: Vec<Record>,
    initial: InitialState,
    hold: Option<f64>,
    skip: usize,
    /// Tests: the hold's derivative as computed before.
    #[cfg(test)]
    pub(super) reference: bool,
}

/// A record simulated at one parameter vector.
struct Evaluated {
    x0: Vec<f64>,
    /// States `x(0..=T)`, when asked for.
    states: Vec<f64>,
    /// Weighted residual `(y_model - y) / sigma`, `T x l`, zero before `skip`.
    residual: Vec<f64>,
}

impl Evaluated {
    /// The record's share of the cost.
    fn cost(&self) -> f64 {
        self.residual.iter().map(|v| v * v).sum()
    }
}

impl TimeProblem {
    /// Checked constructor. `hold` is the sample time of a continuous-time
    /// model (zero-order hold of `u` and `p`), None for a discrete-time
    /// one; the first `skip` samples of every record are simulated but left
    /// out of the cost.
    pub fn new(
        shape: Shape,
        records: Vec<Record>,
        initial: InitialState,
        hold: Option<f64>,
        skip: usize,
    ) -> Result<Self> {
        if records.is_empty() {
            return Err(invalid("records", "needs at least one time record"));
        }
        if let Some(dt) = hold {
            if !(dt.is_finite() && dt > 0.0) {
                return Err(invalid(
                    "dt",
                    format!("expected a finite sample time > 0, got {dt}"),
                ));
            }
        }
        if let Some(k) = records.iter().position(|r| r.len() <= skip) {
            return Err(invalid(
                "skip",
                format!(
                    "{skip} samples skipped leave nothing of record {k} ({} samples)",
                    records[k].len()
                ),
            ));
        }
        if let InitialState::Given(x0) = &initial {
            if x0.len() != records.len() * shape.n {
                return Err(invalid(
                    "x0",
                    format!(
                        "expected {} initial states ({} records x {} states), got {}",
                        records.len() * shape.n,
                        records.len(),
                        shape.n,
                        x0.len()
                    ),
                ));
            }
            if !x0.iter().all(|v| v.is_finite()) {
                return Err(invalid("x0", "contains NaN or Inf"));
            }
        }
        Ok(TimeProblem {
            shape,
            records,
            initial,
            hold,
            skip,
            #[cfg(test)]
            reference: false,
        })
    }

    /// The model shape.
    pub fn shape(&self) -> &Shape {
        &self.shape
    }

    /// The records.
    pub fn records(&self) -> &[Record] {
        &self.records
    }

    /// Number of real residuals in the cost, `sum (T - skip) l`: the noise
    /// floor.
    pub fn n_residuals(&self) -> usize {
        self.records
            .iter()
            .map(|r| (r.len() - self.skip) * self.shape.l)
            .sum()
    }

    /// Simulate record `k` from `x0`; an error naming the record and the
    /// sample when the model leaves the finite numbers.
    fn simulate(&self, theta: &[f64], k: usize, x0: &[f64], states: bool) -> Result<Trajectory> {
        let rec = &self.records[k];
        let model = ModelAt::new(self.shape, theta, rec.psi(), rec.len());
        let traj = match self.hold {
            None => simulate(&model, rec.u(), x0, states),
            Some(dt) => simulate_zoh(&model, rec.u(), x0, dt, states),
        }?;
        let l = self.shape.l;
        if let Some(t) = traj
            .y
            .chunks_exact(l)
            .position(|y| !y.iter().all(|v| v.is_finite()))
        {
            return Err(invalid(
                "model",
                format!(
                    "diverges along time record {k}: its simulated output is not finite from \
                     sample {t} on (the model is unstable along this scheduling trajectory)"
                ),
            ));
        }
        Ok(traj)
    }

    /// The weighted residual of a simulated record, zero before `skip`; an
    /// error naming the sample where it grows past [`LARGEST_RESIDUAL`]
    /// (its square would leave the floating-point range).
    fn residual_of(&self, k: usize, y: &[f64]) -> Result<Vec<f64>> {
        let rec = &self.records[k];
        let l = self.shape.l;
        let r: Vec<f64> = y
            .iter()
            .zip(rec.y())
            .zip(rec.weight())
            .enumerate()
            .map(|(e, ((m, d), w))| if e / l < self.skip { 0.0 } else { (m - d) * w })
            .collect();
        if let Some(e) = r
            .iter()
            .position(|v| v.is_nan() || v.abs() > LARGEST_RESIDUAL)
        {
            return Err(invalid(
                "model",
                format!(
                    "diverges along time record {k}: its output error exceeds {LARGEST_RESIDUAL:e} \
                     sigma at sample {} (the model is unstable along this scheduling trajectory)",
                    e / l
                ),
            ));
        }
        Ok(r)
    }

    /// Simulate record `k` at `theta` from its initial state (estimated,
    /// zero or given).
    fn evaluate(
        &self,
        theta: &[f64],
        coef: &Coefficients,
        k: usize,
        states: bool,
        times: &mut StageTimes,
    ) -> Result<Evaluated> {
        let n = self.shape.n;
        let x0 = match &self.initial {
            InitialState::Zero => vec![0.0; n],
            InitialState::Given(v) => v[k * n..(k + 1) * n].to_vec(),
            InitialState::Estimate => {
                let clock = Instant::now();
                let rest = self.simulate(theta, k, &vec![0.0; n], false)?;
                times.simulation += clock.elapsed().as_secs_f64();
                let residual = self.residual_of(k, &rest.y)?;
                let columns = Columns::initial_only(n);
                let normal = self.pass(coef, k, &[], &residual, &columns, times)?;
                let x0 = estimate(&normal)?;
                if !x0.iter().all(|v| v.is_finite()) {
                    return Err(invalid(
                        "model",
                        format!(
                            "the initial state of time record {k} cannot be estimated (not finite)"
                        ),
                    ));
                }
                x0
            }
        };
        let clock = Instant::now();
        let traj = self.simulate(theta, k, &x0, states)?;
        times.simulation += clock.elapsed().as_secs_f64();
        Ok(Evaluated {
            x0,
            residual: self.residual_of(k, &traj.y)?,
            states: traj.x.unwrap_or_default(),
        })
    }

    fn pass(
        &self,
        coef: &Coefficients,
        k: usize,
        states: &[f64],
        residual: &[f64],
        columns: &Columns,
        times: &mut StageTimes,
    ) -> Result<Normal> {
        Pass {
            coef,
            record: &self.records[k],
            hold: self.hold,
            skip: self.skip,
            states,
            residual,
            columns,
            #[cfg(test)]
            reference: self.reference,
        }
        .run(times)
    }

    /// The initial state of every record at `theta`, `records x n`
    /// row-major (estimated, zero or given).
    pub fn initial_states(&self, theta: &[f64]) -> Result<Vec<f64>> {
        self.shape.check_theta(theta)?;
        let coef = Coefficients::new(&self.shape, theta);
        let mut times = StageTimes::default();
        let mut out = Vec::new();
        for k in 0..self.records.len() {
            out.extend(self.evaluate(theta, &coef, k, false, &mut times)?.x0);
        }
        Ok(out)
    }

    /// The weighted residual `(y_model - y) / sigma` of the samples in the
    /// cost, record after record (`(T - skip) x l` each, row-major).
    pub fn residual(&self, theta: &[f64]) -> Result<Vec<f64>> {
        self.shape.check_theta(theta)?;
        let coef = Coefficients::new(&self.shape, theta);
        let mut times = StageTimes::default();
        let l = self.shape.l;
        let mut out = Vec::with_capacity(self.n_residuals());
        for k in 0..self.records.len() {
            let ev = self.evaluate(theta, &coef, k, false, &mut times)?;
            out.extend_from_slice(&ev.residual[self.skip * l..]);
        }
        Ok(out)
    }

    /// The cost `sum ((y_model - y) / sigma)^2`, summed as
    /// [`TimeProblem::gauss_newton_timed`] sums it (record by record): the
    /// same bits.
    pub fn cost(&self, theta: &[f64]) -> Result<f64> {
        self.shape.check_theta(theta)?;
        let coef = Coefficients::new(&self.shape, theta);
        let mut times = StageTimes::default();
        let mut vnls = 0.0;
        for k in 0..self.records.len() {
            vnls += self.evaluate(theta, &coef, k, false, &mut times)?.cost();
        }
        Ok(vnls)
    }

    /// Cost, gradient and `J^T J` over the free parameters, with the time
    /// each stage took.
    pub fn gauss_newton_timed(
        &self,
        theta: &[f64],
        free: &FreeSet,
    ) -> Result<(GaussNewton, StageTimes)> {
        let start = Instant::now();
        self.shape.check_theta(theta)?;
        if free.full_len() != self.shape.len() {
            return Err(invalid("free", "mask length differs from theta"));
        }
        let coef = Coefficients::new(&self.shape, theta);
        let mut times = StageTimes::default();
        let nf = free.len();
        let estimate_x0 = self.initial == InitialState::Estimate;
        let columns = Columns::new(&self.shape, free, estimate_x0);
        let positions = columns.free_positions();
        let initial: Vec<usize> = (0..columns.len())
            .filter(|&q| positions[q].is_none())
            .collect();
        let mut vnls = 0.0;
        let mut gradient = vec![0.0; nf];
        let mut gram = try_vec(nf * nf, 0.0, "the Gauss-Newton matrix J^T J")?;
        for k in 0..self.records.len() {
            let ev = self.evaluate(theta, &coef, k, columns.need_trajectory(), &mut times)?;
            vnls += ev.cost();
            if nf == 0 {
                continue;
            }
            let normal = self.pass(&coef, k, &ev.states, &ev.residual, &columns, &mut times)?;
            let clock = Instant::now();
            let (jtr, h) = if initial.is_empty() {
                (normal.jtr, normal.gram)
            } else {
                eliminate(&normal, &initial)?
            };
            times.schur += clock.elapsed().as_secs_f64();
            // Without initial-state columns the engine order is the free order.
            for (g, v) in gradient.iter_mut().zip(&jtr) {
                *g += 2.0 * v;
            }
            for (g, v) in gram.iter_mut().zip(&h) {
                *g += v;
            }
        }
        let finite = vnls.is_finite()
            && gradient.iter().all(|v| v.is_finite())
            && gram.iter().all(|v| v.is_finite());
        if !finite {
            return Err(invalid(
                "model",
                "the output error or its derivatives overflow along the time records (the model \
                 is far from the data or unstable along the scheduling trajectory)",
            ));
        }
        times.total = start.elapsed().as_secs_f64();
        Ok((
            GaussNewton {
                vnls,
                gradient,
                gram,
                factors: None,
            },
            times,
        ))
    }
}

impl Objective for TimeProblem {
    fn shape(&self) -> &Shape {
        TimeProblem::shape(self)
    }

    fn n_residuals(&self) -> usize {
        TimeProblem::n_residuals(self)
    }

    fn cost(&self, theta: &[f64]) -> Result<f64> {
        TimeProblem::cost(self, theta)
    }

    fn gauss_newton(&self, theta: &[f64], free: &FreeSet) -> Result<GaussNewton> {
        Ok(self.gauss_newton_timed(theta, free)?.0)
    }

    fn response(&self, theta: &[f64]) -> Result<Vec<f64>> {
        self.residual(theta)
    }
}
