//! Criterion benchmarks of the numerical core on a gantry-size problem
//! (n=6, l=2, r=1, Nb=4, N=5, F=300, discrete time), and of time-domain
//! simulation of a model of that size.

use criterion::{criterion_group, criterion_main, Criterion};
use lpvid::simulate::{simulate, simulate_zoh};
use lpvid::testing::Lcg;
use lpvid::{FreeSet, FrfData, ModelAt, Problem, Shape};
use num_complex::Complex64 as C64;
use std::hint::black_box;

/// A gantry-size problem with a stable random model and its own FRF as data.
pub fn gantry_problem() -> (Problem, Vec<f64>) {
    let shape = Shape::new(6, 1, 2, 4).expect("shape");
    let mut rng = Lcg(7);
    let mut theta: Vec<f64> = (0..shape.len()).map(|_| 0.1 * rng.next_f64()).collect();
    // A(0) = 0.5 I keeps every frozen model stable.
    let a0 = shape.block(lpvid::Matrix::A, 0);
    for k in 0..shape.n {
        theta[a0.start + k * (shape.n + 1)] += 0.5;
    }
    let (n_points, n_lines) = (5, 300);
    let ts = 1e-3;
    let z: Vec<C64> = (0..n_lines)
        .map(|k| {
            let f = 50.0 + 250.0 * k as f64 / (n_lines - 1) as f64;
            C64::from_polar(1.0, 2.0 * std::f64::consts::PI * f * ts)
        })
        .collect();
    let basis: Vec<f64> = (0..n_points)
        .flat_map(|q| {
            let s = -1.0 + 0.5 * q as f64;
            (1..=4).map(move |i| s.powi(i))
        })
        .collect();
    let len = n_points * n_lines * 2;
    let g: Vec<C64> = (0..len)
        .map(|_| C64::new(rng.next_f64(), rng.next_f64()))
        .collect();
    let data = FrfData::new(n_points, 2, 1, z, g, &vec![0.1; len]).expect("data");
    (Problem::new(shape, data, &basis).expect("problem"), theta)
}

fn bench_evaluation(c: &mut Criterion) {
    let (problem, theta) = gantry_problem();
    let free = FreeSet::all(theta.len());
    c.bench_function("gantry: residual + V_NLS + gradient + J^T J", |b| {
        b.iter(|| black_box(problem.gauss_newton(black_box(&theta), &free).expect("gn")))
    });
    c.bench_function("gantry: V_NLS only", |b| {
        b.iter(|| black_box(problem.cost(black_box(&theta)).expect("cost")))
    });
}

fn bench_steps(c: &mut Criterion) {
    let (problem, theta) = gantry_problem();
    let free = FreeSet::all(theta.len());
    let gn = problem.gauss_newton(&theta, &free).expect("gn");
    let diag = lpvid::fit::lm::marquardt_diagonal(&gn);
    let mu = 1e-4;
    c.bench_function(
        "gantry: LM iteration (step, J^T J and V_NLS at the new point)",
        |b| {
            b.iter(|| {
                let d = lpvid::fit::lm::lm_step(&gn, &diag, mu)
                    .expect("memory")
                    .expect("step");
                let trial = free.add_step(&theta, &d);
                black_box(problem.gauss_newton(&trial, &free).expect("gn"))
            })
        },
    );
    c.bench_function("gantry: LM step solve only (Cholesky)", |b| {
        b.iter(|| black_box(lpvid::fit::lm::lm_step(&gn, &diag, mu)))
    });
    let sup = vec![1.0; 4];
    let settings = lpvid::L21Settings::default();
    let groups =
        lpvid::l21::cone_groups(problem.shape(), &free, &sup, &theta, &settings).expect("groups");
    let cone = lpvid::socp::ConeProblem {
        gn: &gn,
        diag: &diag,
        theta: &theta,
        groups: &groups,
        gamma: 1e-3,
        n_residuals: problem.n_residuals() as f64,
        pinned: None,
        newton: true,
    };
    let by_clarabel = lpvid::socp::ConeProblem {
        newton: false,
        ..cone
    };
    c.bench_function(
        "gantry: SOCP solve only (Newton, Clarabel where it gives up)",
        |b| {
            let mut solver = lpvid::socp::ConeSolver::default();
            b.iter(|| black_box(cone.solve(mu, &mut solver)))
        },
    );
    c.bench_function("gantry: SOCP solve only (build + Clarabel)", |b| {
        let mut solver = lpvid::socp::ConeSolver::default();
        b.iter(|| black_box(by_clarabel.solve(mu, &mut solver)))
    });
    c.bench_function(
        "gantry: SOCP step (build + solve, trial V_NLS, J^T J at new point)",
        |b| {
            let mut solver = lpvid::socp::ConeSolver::default();
            b.iter(|| {
                let step = cone.solve(mu, &mut solver).expect("memory");
                let d = step.step.expect("solved");
                let trial = free.add_step(&theta, &d);
                let v = problem.cost(&trial).expect("cost");
                black_box((v, problem.gauss_newton(&trial, &free).expect("gn")))
            })
        },
    );
}

/// A stable gantry-size model (n=6, r=1, l=2, Nb=4) and a trajectory of
/// `t_len` samples: basis values of a slowly swept scheduling parameter and
/// a random input.
pub fn simulation_problem(t_len: usize) -> (Shape, Vec<f64>, Vec<f64>, Vec<f64>) {
    let shape = Shape::new(6, 1, 2, 4).expect("shape");
    let mut rng = Lcg(11);
    let mut theta: Vec<f64> = (0..shape.len()).map(|_| 0.1 * rng.next_f64()).collect();
    let a0 = shape.block(lpvid::Matrix::A, 0);
    for k in 0..shape.n {
        theta[a0.start + k * (shape.n + 1)] += 0.5;
    }
    let basis: Vec<f64> = (0..t_len)
        .flat_map(|t| {
            let s = (t as f64 * 1e-4).sin();
            (1..=4).map(move |i| s.powi(i))
        })
        .collect();
    let u: Vec<f64> = (0..t_len).map(|_| rng.next_f64()).collect();
    (shape, theta, basis, u)
}

fn bench_simulation(c: &mut Criterion) {
    let mut group = c.benchmark_group("simulate");
    group.sample_size(20);
    let (shape, theta, basis, u) = simulation_problem(1_000_000);
    let x0 = vec![0.0; shape.n];
    let model = ModelAt::new(shape, &theta, &basis, u.len());
    group.bench_function("discrete, 1e6 samples, n=6 l=2 r=1 Nb=4", |b| {
        b.iter(|| black_box(simulate(&model, black_box(&u), &x0, false).expect("sim")))
    });
    // Continuous time: a matrix exponential per sample (p varies every sample).
    let mut ct = theta.clone();
    let a0 = shape.block(lpvid::Matrix::A, 0);
    for k in 0..shape.n {
        ct[a0.start + k * (shape.n + 1)] -= 1.5;
    }
    let t_ct = 100_000;
    let continuous = ModelAt::new(shape, &ct, &basis[..t_ct * 4], t_ct);
    group.bench_function("continuous (ZOH), 1e5 samples, n=6 l=2 r=1 Nb=4", |b| {
        b.iter(|| black_box(simulate_zoh(&continuous, &u[..t_ct], &x0, 1e-3, false).expect("sim")))
    });
    group.finish();
}

/// The Cholesky factorisation of the Levenberg-Marquardt step at n = 16 2x2
/// (1620 wide) and of n = 32's refit (3600): faer's own and the core's
/// (faer's to the last bit, its updates on the AVX-512 kernel), on the pool.
fn bench_cholesky(c: &mut Criterion) {
    use faer::Par;
    use lpvid::base::cholesky::factor;
    use lpvid::base::gram_product::Kernel;
    let mut group = c.benchmark_group("cholesky");
    group.sample_size(10);
    for n in [1620, 3600] {
        let a = lpvid::testing::spd_matrix(n, 0.0);
        for (name, kernel) in [("faer", None), ("core, AVX-512", Some(Kernel::Avx512))] {
            if kernel.is_some_and(|k: Kernel| !k.available()) {
                continue;
            }
            group.bench_function(format!("{n} wide, {name}"), |bench| {
                bench.iter(|| {
                    let mut l = a.clone();
                    black_box(factor(l.as_mut(), kernel, Par::rayon(0)).expect("scratch"))
                })
            });
        }
    }
    group.finish();
}

criterion_group!(
    benches,
    bench_evaluation,
    bench_steps,
    bench_simulation,
    bench_cholesky
);
criterion_main!(benches);
