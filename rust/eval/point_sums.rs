//! The Gram pieces of every scheduling point, summed in task order as the
//! tasks finish.
//!
//! A Gauss-Newton evaluation cuts every point's lines into tasks and runs
//! them in parallel ([`crate::eval::problem`]); each task leaves its `S1`, `S2`
//! and `J^T r` ([`GramParts`]), and a point's parts are summed in task
//! order, so that the sum is the same to the last bit however the tasks
//! were scheduled. Summed as they come in (a part waits only for the
//! earlier tasks of its point), a few parts are alive at a time instead of
//! all of them, and the buffers of a part once summed are handed to the
//! next task instead of fresh memory, whose first products write over them
//! ([`KronGram::finish`]): at n = 24 3 x 3, 162 parts of 2.1 MB an
//! evaluation, whose page faults and zeroing took about 15 % of it.

use crate::base::layout::Shape;
use crate::error::Result;
use crate::eval::kron_gram::{GramParts, KronGram};
use faer::Mat;
use std::sync::{Mutex, MutexGuard};

/// The running sums of every point, and the spare buffers.
#[derive(Debug)]
pub struct PointSums {
    points: Vec<Mutex<Pending>>,
    spare: Mutex<Vec<(Mat<f64>, Mat<f64>)>>,
}

/// One point's sum of its first `next` tasks' parts, and the parts of later
/// tasks that came in before an earlier one.
#[derive(Debug, Default)]
struct Pending {
    next: usize,
    sum: Option<GramParts>,
    waiting: Vec<(usize, GramParts)>,
}

/// A lock whose holder may have panicked: its data is whole (every change
/// under the lock is a push, a pop or a completed merge).
fn locked<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl PointSums {
    /// Empty sums for `n_points` points.
    pub fn new(n_points: usize) -> Self {
        PointSums {
            points: (0..n_points).map(|_| Mutex::default()).collect(),
            spare: Mutex::new(Vec::new()),
        }
    }

    /// `S1` and `S2` for a task's accumulator to write over: a spare pair
    /// (holding a summed part's values), or zeros
    /// ([`crate::Error::OutOfMemory`] when they cannot be had).
    pub fn next_sums(&self, shape: &Shape) -> Result<(Mat<f64>, Mat<f64>)> {
        let spare = locked(&self.spare).pop();
        match spare {
            Some(pair) => Ok(pair),
            None => KronGram::sums(shape),
        }
    }

    /// Add the part of task `index` (counted from 0 within its point) of
    /// `point`: summed into the point's sum at once if every earlier task's
    /// part is, else kept until they are.
    pub fn add(&self, point: usize, index: usize, part: GramParts) {
        let mut freed = Vec::new();
        {
            let mut p = locked(&self.points[point]);
            p.waiting.push((index, part));
            while let Some(at) = p.waiting.iter().position(|(i, _)| *i == p.next) {
                let (_, part) = p.waiting.swap_remove(at);
                match &mut p.sum {
                    None => p.sum = Some(part),
                    Some(sum) => {
                        sum.merge(&part);
                        freed.push(part.into_sums());
                    }
                }
                p.next += 1;
            }
        }
        locked(&self.spare).extend(freed);
    }

    /// Every point's sum over its tasks (`None` for a point without any),
    /// or `None` when some task's part did not come in.
    pub fn into_sums(self) -> Option<Vec<Option<GramParts>>> {
        self.points
            .into_iter()
            .map(|m| {
                let p = m.into_inner().unwrap_or_else(|e| e.into_inner());
                p.waiting.is_empty().then_some(p.sum)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::Lcg;

    /// Shape of the parts below: `S1` 6 x 6, `S2` 3 x 3, 9 LTI entries.
    fn shape() -> Shape {
        Shape {
            n: 2,
            r: 1,
            l: 1,
            nb: 0,
        }
    }

    /// A part whose entries span twenty decades: their sum depends on the
    /// order of the terms.
    fn part(rng: &mut Lcg) -> GramParts {
        let mut x = || rng.next_f64() * 10f64.powf(20.0 * rng.next_f64());
        let s1 = Mat::from_fn(6, 6, |_, _| x());
        let s2 = Mat::from_fn(3, 3, |_, _| x());
        GramParts::of(s1, s2, (0..9).map(|_| x()).collect())
    }

    /// Parts summed one after the other in this order.
    fn in_order(parts: &[GramParts], order: impl Iterator<Item = usize>) -> Vec<u64> {
        let mut order = order.map(|i| parts[i].clone());
        let mut sum = order.next().expect("a part");
        order.for_each(|p| sum.merge(&p));
        sum.bits()
    }

    #[test]
    fn parts_coming_in_any_order_are_summed_in_task_order() {
        let mut rng = Lcg(5);
        let parts: Vec<Vec<GramParts>> = (0..2)
            .map(|_| (0..7).map(|_| part(&mut rng)).collect())
            .collect();
        let arrival = [(1, 3), (0, 6), (1, 0), (0, 2), (0, 0), (1, 1), (0, 1)]
            .into_iter()
            .chain([(1, 2), (0, 5), (1, 6), (0, 3), (1, 5), (0, 4), (1, 4)]);
        let sums = PointSums::new(3);
        for (point, task) in arrival.clone() {
            sums.add(point, task, parts[point][task].clone());
        }
        let got = sums.into_sums().expect("every part came in");
        assert!(got[2].is_none(), "a point without tasks has no sum");
        for q in 0..2 {
            let want = in_order(&parts[q], 0..7);
            assert_eq!(got[q].as_ref().expect("a sum").bits(), want);
            // The order matters: summed as they came in, the bits differ.
            let came = arrival.clone().filter(|&(p, _)| p == q).map(|(_, t)| t);
            assert_ne!(in_order(&parts[q], came), want);
        }
    }

    #[test]
    fn a_missing_part_leaves_no_sum() {
        let mut rng = Lcg(6);
        let sums = PointSums::new(1);
        sums.add(0, 0, part(&mut rng));
        sums.add(0, 2, part(&mut rng));
        assert!(sums.into_sums().is_none());
    }

    #[test]
    fn the_buffers_of_summed_parts_are_handed_out_again() {
        let mut rng = Lcg(7);
        let sums = PointSums::new(1);
        let parts: Vec<GramParts> = (0..3).map(|_| part(&mut rng)).collect();
        for (task, p) in parts.iter().enumerate() {
            sums.add(0, task, p.clone());
        }
        // Two parts were summed into the first: their buffers are spare,
        // the last one's first, as they were.
        assert_eq!(locked(&sums.spare).len(), 2);
        let (s1, s2) = sums.next_sums(&shape()).expect("a spare pair");
        let (w1, w2) = parts[2].clone().into_sums();
        assert_eq!((&s1, &s2), (&w1, &w2));
        assert_eq!(locked(&sums.spare).len(), 1);
        // With no spare left, zeros of the shape's sizes.
        let _ = sums.next_sums(&shape()).expect("the last spare");
        let (f1, f2) = sums.next_sums(&shape()).expect("fresh sums");
        assert_eq!(
            (f1.nrows(), f1.ncols(), f2.nrows(), f2.ncols()),
            (6, 6, 3, 3)
        );
        let zero =
            |m: &Mat<f64>| (0..m.ncols()).all(|j| (0..m.nrows()).all(|i| m[(i, j)].to_bits() == 0));
        assert!(zero(&f1) && zero(&f2));
    }
}
