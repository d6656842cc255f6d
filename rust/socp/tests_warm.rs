//! Unit tests of [`WarmSteps`]: a rejected step's successor started from
//! it ends at the minimiser a cold start finds, in fewer iterations.

use super::several::several;
use super::*;
use crate::testing::relative_gap;

fn cold(c: &Case, mu: f64) -> ConeStep {
    c.cone()
        .solve(mu, &mut ConeSolver::new(1e-10))
        .expect("memory")
}

#[test]
fn a_rejected_steps_successor_starts_from_it_and_ends_where_a_cold_start_does() {
    let mut fewer = 0;
    for seed in 0..6 {
        for gamma in [0.02, 0.2] {
            let c = several(seed, gamma, 1.0);
            let mut steps = WarmSteps::new(1e-10);
            let first = steps.solve(&c.cone(), c.mu).expect("memory");
            assert_eq!(
                first.step,
                cold(&c, c.mu).step,
                "the first starts from zero"
            );
            // The damping a rejection gives, the same point and weights.
            let mu = 4.0 * c.mu;
            let warm = steps.solve(&c.cone(), mu).expect("memory");
            let cold = cold(&c, mu);
            let (w, k) = (warm.step.unwrap(), cold.step.unwrap());
            assert!(relative_gap(&w, &k) < 1e-9, "seed {seed}, gamma {gamma}");
            assert_eq!(warm.zeroed, cold.zeroed);
            assert!(
                warm.iterations <= cold.iterations,
                "seed {seed}, gamma {gamma}"
            );
            fewer += usize::from(warm.iterations < cold.iterations);
        }
    }
    assert!(fewer >= 6, "fewer iterations on {fewer} of 12 programs");
}

#[test]
fn a_start_at_the_minimiser_is_one_iteration_and_forget_starts_from_zero() {
    let c = several(1, 0.2, 1.0);
    let mut steps = WarmSteps::new(1e-10);
    let cold_step = cold(&c, c.mu);
    assert!(cold_step.iterations > 1);
    steps.solve(&c.cone(), c.mu).expect("memory");
    // The same program again: Newton's method starts at its minimiser.
    let again = steps.solve(&c.cone(), c.mu).expect("memory");
    assert_eq!(again.iterations, 1);
    assert!(
        relative_gap(
            again.step.as_ref().unwrap(),
            cold_step.step.as_ref().unwrap()
        ) < 1e-12
    );
    steps.forget();
    let fresh = steps.solve(&c.cone(), c.mu).expect("memory");
    assert_eq!(fresh.step, cold_step.step);
    assert_eq!(fresh.iterations, cold_step.iterations);
}
