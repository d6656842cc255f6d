//! Memory of the fits: the estimate of `lpvid::fit::estimate` against
//! the peak that a counting allocator measures, and the fallible
//! allocations of a fit made to fail one after the other (an error naming
//! the size every time, never a panic or an abort).
//!
//! The tests of this file share the allocator's counters: they take a lock.

use lpvid::fit::estimate::{FitSizes, Method, TimeSizes};
use lpvid::memory::{allocation_failure_pending, fail_allocation_after, guarded_allocation};
use lpvid::testing::Lcg;
use lpvid::{
    fit_l21, frequency_response, levenberg_marquardt, Error, FreeSet, FrfData, InitialState,
    L21Settings, LmSettings, Matrix, ModelAt, Objective, Problem, Record, Shape, Silent,
    TimeProblem,
};
use num_complex::Complex64 as C64;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

/// The system allocator, counting the bytes in use and their peak.
struct Counting;

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
/// While set: the largest allocation made outside lpvid's fallible helpers.
static RECORD: AtomicBool = AtomicBool::new(false);
static LARGEST_UNGUARDED: AtomicUsize = AtomicUsize::new(0);

fn grew(bytes: usize) {
    let now = CURRENT.fetch_add(bytes, Ordering::SeqCst) + bytes;
    PEAK.fetch_max(now, Ordering::SeqCst);
    if RECORD.load(Ordering::Relaxed) && !guarded_allocation() {
        LARGEST_UNGUARDED.fetch_max(bytes, Ordering::SeqCst);
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc(layout);
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc_zeroed(layout);
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout);
        CURRENT.fetch_sub(layout.size(), Ordering::SeqCst);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = System.realloc(ptr, layout, new_size);
        if !p.is_null() {
            // Old and new blocks both live during the copy.
            grew(new_size);
            CURRENT.fetch_sub(layout.size(), Ordering::SeqCst);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

static SERIAL: Mutex<()> = Mutex::new(());

/// `f()` and the peak of the bytes it allocated beyond those in use before.
fn peak_of<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = CURRENT.load(Ordering::SeqCst);
    PEAK.store(base, Ordering::SeqCst);
    let out = f();
    (out, PEAK.load(Ordering::SeqCst).saturating_sub(base))
}

/// A stable discrete-time model of the shape: A(0) contracting, a small
/// scheduling dependency.
fn model(shape: Shape, rng: &mut Lcg) -> Vec<f64> {
    let mut theta = vec![0.0; shape.len()];
    for i in 0..shape.n_coef() {
        let size = if i == 0 { 1.0 } else { 0.1 };
        for x in Matrix::ALL {
            for t in shape.block(x, i) {
                theta[t] = size * rng.next_f64() / (shape.n as f64).sqrt();
            }
        }
    }
    let a0 = shape.block(Matrix::A, 0).start;
    for k in 0..shape.n {
        theta[a0 + k * (shape.n + 1)] += 0.5;
    }
    theta
}

/// The problem of the FRF of [`model`] with a perturbation at `points`
/// points and `lines` lines, and a start near the model.
fn problem(shape: Shape, points: usize, lines: usize) -> (Problem, Vec<f64>) {
    let mut rng = Lcg(11);
    let theta = model(shape, &mut rng);
    let p: Vec<f64> = (0..points)
        .map(|q| -1.0 + 2.0 * q as f64 / (points.max(2) - 1) as f64)
        .collect();
    let basis: Vec<f64> = p
        .iter()
        .flat_map(|&x| (1..=shape.nb).map(move |i| x.powi(i as i32)))
        .collect();
    let z: Vec<C64> = (0..lines)
        .map(|k| C64::from_polar(1.0, 0.05 + 3.0 * k as f64 / lines as f64))
        .collect();
    let mut g = frequency_response(&ModelAt::new(shape, &theta, &basis, points), &z).unwrap();
    g.iter_mut()
        .for_each(|v| *v += 0.01 * C64::new(rng.next_f64(), rng.next_f64()));
    let sigma = vec![0.01; g.len()];
    let data = FrfData::new(points, shape.l, shape.r, z, g, &sigma).unwrap();
    let start = theta
        .iter()
        .map(|t| t * (1.0 + 0.01 * rng.next_f64()))
        .collect();
    (Problem::new(shape, data, &basis).unwrap(), start)
}

/// A time record of [`model`] along a slow scheduling sweep (`samples`
/// long, noisy outputs), the problem with the initial state estimated, and
/// a start near the model. `hold`: the sample time of a continuous-time
/// model (the same numbers, taken as continuous-time matrices).
fn time_problem(shape: Shape, samples: usize, hold: Option<f64>) -> (TimeProblem, Vec<f64>) {
    let mut rng = Lcg(17);
    let mut theta = model(shape, &mut rng);
    if hold.is_some() {
        // Continuous time: shift A(0) to the left half-plane.
        let a0 = shape.block(Matrix::A, 0).start;
        for k in 0..shape.n {
            theta[a0 + k * (shape.n + 1)] -= 1.5;
        }
    }
    let psi: Vec<f64> = (0..samples)
        .flat_map(|t| {
            let p = (t as f64 * 0.002).sin();
            (1..=shape.nb).map(move |i| p.powi(i as i32))
        })
        .collect();
    let u: Vec<f64> = (0..samples * shape.r).map(|_| rng.next_f64()).collect();
    let x0 = vec![0.0; shape.n];
    let model = ModelAt::new(shape, &theta, &psi, samples);
    let traj = match hold {
        None => lpvid::simulate::simulate(&model, &u, &x0, false),
        Some(dt) => lpvid::simulate::simulate_zoh(&model, &u, &x0, dt, false),
    }
    .unwrap();
    let y: Vec<f64> = traj.y.iter().map(|v| v + 0.01 * rng.next_f64()).collect();
    let sigma = vec![0.01; y.len()];
    let record = Record::new(&shape, u, psi, y, &sigma).unwrap();
    let p = TimeProblem::new(shape, vec![record], InitialState::Estimate, hold, 0).unwrap();
    let start = theta
        .iter()
        .map(|t| t * (1.0 + 0.01 * rng.next_f64()))
        .collect();
    (p, start)
}

fn sizes(shape: Shape, frf: Option<(usize, usize)>, time: Option<TimeSizes>) -> FitSizes {
    FitSizes {
        shape,
        free: FreeSet::all(shape.len()),
        frf,
        time,
        threads: rayon::current_num_threads(),
    }
}

/// The estimate is at least the measured peak, and without its allowance
/// for scratch space at most 1.5 times it (plus 2 MB).
fn assert_bounds(what: &str, measured: usize, estimate: usize, scratch: usize) {
    println!(
        "{what}: measured {:.1} MB, estimate {:.1} MB ({:.2}; {:.2} without the scratch)",
        measured as f64 / 1e6,
        estimate as f64 / 1e6,
        estimate as f64 / measured as f64,
        (estimate - scratch) as f64 / measured as f64
    );
    assert!(
        measured <= estimate,
        "{what}: measured {measured} bytes above the estimate {estimate}"
    );
    assert!(
        (estimate - scratch) as f64 <= 1.5 * measured as f64 + 2e6,
        "{what}: estimate {estimate} bytes far above the measured {measured}"
    );
}

#[test]
fn the_estimate_bounds_the_peak_of_an_frf_evaluation_and_fits() {
    let _lock = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    // Warm the thread pool and its per-thread buffers (allocated once per
    // process, not by each fit).
    let (p, theta) = problem(Shape::new(4, 1, 1, 1).unwrap(), 3, 50);
    p.gauss_newton(&theta, &FreeSet::all(theta.len())).unwrap();
    let mut by_newton = 0;
    for (shape, points, lines) in [
        (Shape::new(16, 2, 2, 3).unwrap(), 9, 500),
        (Shape::new(24, 3, 3, 1).unwrap(), 3, 300),
        (Shape::new(6, 1, 2, 4).unwrap(), 25, 300),
        (Shape::new(10, 2, 2, 2).unwrap(), 7, 2000),
    ] {
        let (p, theta) = problem(shape, points, lines);
        let free = FreeSet::all(shape.len());
        let est = sizes(shape, Some((points, lines)), None);
        let lm_est = est.estimate(Method::Lm);
        let label = format!(
            "n={} {}x{} Nb={} N={points} F={lines}",
            shape.n, shape.l, shape.r, shape.nb
        );
        let (gn, peak) = peak_of(|| p.gauss_newton(&theta, &free).unwrap());
        drop(gn);
        let e = lm_est.evaluation + lm_est.scratch;
        assert_bounds(&format!("{label} evaluation"), peak, e, lm_est.scratch);
        let lm = LmSettings {
            max_iter: 2,
            ..LmSettings::default()
        };
        // Each fit on a copy: a problem keeps its evaluations' workspaces
        // (the small ones), which a fit's peak includes.
        let q = p.clone();
        let (fit, peak) =
            peak_of(|| levenberg_marquardt(&q, &theta, &free, &lm, &mut Silent).unwrap());
        drop(fit);
        assert_bounds(&format!("{label} LM"), peak, lm_est.total, lm_est.scratch);
        // The estimate is Clarabel's (Newton's method may give any step to
        // it): measured with Clarabel alone, and bounding Newton's method's.
        let l21 = L21Settings {
            gamma: 1e-3,
            max_outer: 1,
            max_inner: 2,
            newton: false,
            ..L21Settings::default()
        };
        let sup = vec![1.0; shape.nb];
        let q = p.clone();
        let (fit, peak) =
            peak_of(|| fit_l21(&q, &theta, &free, &sup, &l21, None, &mut Silent).unwrap());
        drop(fit);
        let e = est.estimate(Method::L21 { pinned: false });
        assert_bounds(&format!("{label} l21"), peak, e.total, e.scratch);
        let newton = L21Settings {
            newton: true,
            ..l21
        };
        let q = p.clone();
        let (fit, peak) =
            peak_of(|| fit_l21(&q, &theta, &free, &sup, &newton, None, &mut Silent).unwrap());
        by_newton += fit
            .history
            .iter()
            .filter(|h| h.status == "Solved (Newton)")
            .count();
        drop(fit);
        assert!(
            peak <= e.total,
            "{label} l21 by Newton: {peak} above {}",
            e.total
        );
    }
    assert!(by_newton > 0, "no step of these fits by Newton's method");
}

#[test]
fn the_estimate_bounds_the_peak_of_a_time_record_fit() {
    let _lock = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (p, theta) = problem(Shape::new(4, 1, 1, 1).unwrap(), 3, 50);
    p.gauss_newton(&theta, &FreeSet::all(theta.len())).unwrap();
    for (shape, samples, hold) in [
        (Shape::new(16, 1, 2, 2).unwrap(), 3000, None),
        (Shape::new(8, 2, 2, 1).unwrap(), 1500, Some(0.01)),
    ] {
        let (p, theta) = time_problem(shape, samples, hold);
        let free = FreeSet::all(shape.len());
        let time = TimeSizes {
            lengths: vec![samples],
            hold: hold.is_some(),
            estimate_x0: true,
        };
        let est = sizes(shape, None, Some(time)).estimate(Method::Lm);
        let label = format!(
            "n={} {}x{} Nb={} T={samples}{}",
            shape.n,
            shape.l,
            shape.r,
            shape.nb,
            if hold.is_some() { " (hold)" } else { "" }
        );
        let (gn, peak) = peak_of(|| p.gauss_newton(&theta, &free).unwrap());
        drop(gn);
        let e = est.evaluation + est.scratch;
        assert_bounds(&format!("{label} evaluation"), peak, e, est.scratch);
        let lm = LmSettings {
            max_iter: 2,
            ..LmSettings::default()
        };
        // Each fit on a copy: a problem keeps its evaluations' workspaces
        // (the small ones), which a fit's peak includes.
        let q = p.clone();
        let (fit, peak) =
            peak_of(|| levenberg_marquardt(&q, &theta, &free, &lm, &mut Silent).unwrap());
        drop(fit);
        assert_bounds(&format!("{label} LM"), peak, est.total, est.scratch);
    }
}

/// Runs `fit` with the allocation after the first `k` fallible ones made
/// to fail, for k = 0, 1, ... until a run makes fewer: every run that met
/// the failure must return `Error::OutOfMemory` (a panic would fail the
/// test, an abort would end it, and a run that met it and went on took it
/// for a rejected step). Returns the number of failures met.
fn every_failure<T>(what: &str, fit: impl Fn() -> lpvid::Result<T>) -> usize {
    let mut met = 0;
    for k in 0.. {
        fail_allocation_after(Some(k));
        let out = fit();
        let fired = !allocation_failure_pending();
        fail_allocation_after(None);
        match out {
            Err(Error::OutOfMemory { bytes, what: array }) => {
                assert!(bytes > 0, "{what}: failure {k} names no size");
                assert!(!array.is_empty());
                met += 1;
            }
            Err(e) => panic!("{what}: failure {k} gave {e:?}, not OutOfMemory"),
            Ok(_) => {
                assert!(!fired, "{what}: failure {k} was met and swallowed");
                break;
            }
        }
        assert!(k < 10_000, "{what}: no end to the fallible allocations");
    }
    met
}

#[test]
fn every_fallible_allocation_of_a_fit_fails_as_an_error() {
    let _lock = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let shape = Shape::new(4, 1, 2, 2).unwrap();
    let (p, theta) = problem(shape, 5, 120);
    let free = FreeSet::all(shape.len());
    let lm = LmSettings {
        max_iter: 2,
        ..LmSettings::default()
    };
    let met = every_failure("LM", || {
        levenberg_marquardt(&p, &theta, &free, &lm, &mut Silent)
    });
    // The residuals, the accumulators of both threads, the pieces of every
    // block of lines, the points' Gram matrices, the pair sums, J^T J and
    // the step's factor, twice over.
    assert!(
        met > 20,
        "only {met} fallible allocations in a Levenberg-Marquardt fit"
    );
    let l21 = L21Settings {
        max_outer: 1,
        max_inner: 2,
        ..L21Settings::default()
    };
    let sup = vec![1.0; shape.nb];
    let met = every_failure("l21", || {
        fit_l21(&p, &theta, &free, &sup, &l21, None, &mut Silent)
    });
    assert!(met > 20, "only {met} fallible allocations in an l2,1 fit");
    let (t, theta) = time_problem(shape, 400, None);
    let met = every_failure("time LM", || {
        levenberg_marquardt(&t, &theta, &free, &lm, &mut Silent)
    });
    assert!(met > 10, "only {met} fallible allocations in a time fit");
    // After the hook: the same fit runs to its end.
    assert!(levenberg_marquardt(&p, &theta, &free, &lm, &mut Silent).is_ok());
}

/// The largest allocation `f` makes outside lpvid's fallible helpers (and
/// outside the probed set-up of a Clarabel solver).
fn largest_unguarded<T>(f: impl FnOnce() -> T) -> usize {
    LARGEST_UNGUARDED.store(0, Ordering::SeqCst);
    RECORD.store(true, Ordering::SeqCst);
    let out = f();
    RECORD.store(false, Ordering::SeqCst);
    drop(out);
    LARGEST_UNGUARDED.load(Ordering::SeqCst)
}

/// Allocations outside the fallible helpers that a fit may make: faer's
/// matrix products pack their operands into buffers of their own (a
/// cache-sized slab per thread, a panel up to the size of a product's
/// operand; 1-3.6 MB here), which the estimate's scratch allowance covers.
const UNGUARDED: usize = 4 << 20;

#[test]
fn the_large_arrays_of_a_fit_are_all_made_fallibly() {
    let _lock = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let lm = LmSettings {
        max_iter: 2,
        ..LmSettings::default()
    };
    // n = 38 SISO LTI: the Gram pieces of a block of lines 4.3-4.9 MB, the
    // points' Gram matrices, their sum, J^T J and the step's factor 18.5 MB.
    let shape = Shape::new(38, 1, 1, 0).unwrap();
    let (p, theta) = problem(shape, 2, 128);
    let free = FreeSet::all(shape.len());
    let largest = largest_unguarded(|| levenberg_marquardt(&p, &theta, &free, &lm, &mut Silent));
    assert!(
        largest <= UNGUARDED,
        "LM: {largest} bytes allocated infallibly"
    );
    // n = 16 2x2 Nb = 3: the cone step's dense block 7.6 MB, its program's
    // P 7.6 MB and Clarabel's arrays (probed), J^T J 13.4 MB.
    let shape = Shape::new(16, 2, 2, 3).unwrap();
    let (p, theta) = problem(shape, 9, 500);
    let free = FreeSet::all(shape.len());
    let l21 = L21Settings {
        max_outer: 1,
        max_inner: 2,
        ..L21Settings::default()
    };
    let sup = vec![1.0; shape.nb];
    let largest = largest_unguarded(|| fit_l21(&p, &theta, &free, &sup, &l21, None, &mut Silent));
    assert!(
        largest <= UNGUARDED,
        "l21: {largest} bytes allocated infallibly"
    );
    // Time records: the Jacobian block 14.4 MB, each thread's sums 6.2 MB.
    let (t, theta) = time_problem(Shape::new(16, 1, 2, 2).unwrap(), 3000, None);
    let free = FreeSet::all(t.shape().len());
    let largest = largest_unguarded(|| levenberg_marquardt(&t, &theta, &free, &lm, &mut Silent));
    assert!(
        largest <= UNGUARDED,
        "time: {largest} bytes allocated infallibly"
    );
}
