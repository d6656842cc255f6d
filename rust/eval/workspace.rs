//! The scratch space of a Gauss-Newton evaluation ([`crate::eval::problem`]):
//! a resolvent and a Gram accumulator for every piece of its parallel loop,
//! kept by the problem from one evaluation to the next when small.
//!
//! A workspace holds the accumulator's sample buffers and sums
//! ([`KronGram::bytes`]: 0.7 MiB at n = 10 SISO, 2.1 MiB at n = 16 2 x 2,
//! 5.8 MiB at n = 24 3 x 3, 12.8 MiB at n = 32 4 x 4). Made anew for every
//! evaluation, they were allocated and zeroed every Levenberg-Marquardt
//! step: on a small problem (n = 10 SISO, 200 lines, six points, a step
//! about 0.2 ms a point) that zeroing and the one of every point's Gram
//! matrix before its unfolding (`GramParts::gram`, which now writes every
//! entry once) were 3 % of `identify`'s samples.
//! Workspaces of at most [`KEEP_BYTES`] are kept for the next evaluation;
//! larger ones only for the pieces of the same evaluation, as before: their
//! allocation is a small part of a large evaluation, and what the largest
//! problems hold between evaluations counts against their memory (n = 32
//! within 2 GB). A workspace holds nothing from one task to the next that
//! the task reads (the accumulator starts empty, [`KronGram::finish`]
//! leaves it so and an error clears it), so a kept one gives the same bits
//! as a new one.

use crate::base::layout::Shape;
use crate::error::{Error, Result};
use crate::eval::kron_gram::KronGram;
use crate::eval::lti::Resolvent;
use std::sync::{Mutex, MutexGuard};

/// Per-thread scratch space of the Gauss-Newton evaluation: the resolvent
/// and the Gram accumulator, reused from task to task.
pub(crate) struct Workspace {
    pub(crate) resolvent: Resolvent,
    pub(crate) gram: KronGram,
}

impl Workspace {
    fn new(shape: &Shape) -> Result<Self> {
        Ok(Workspace {
            resolvent: Resolvent::new(shape),
            gram: KronGram::new(shape)?,
        })
    }
}

/// Workspaces of at most this many bytes are kept from one evaluation to
/// the next (those of n = 16 2 x 2 and smaller).
const KEEP_BYTES: usize = 4 << 20;

/// Whether a problem of `shape` keeps its workspaces from one evaluation
/// to the next (its Gram accumulator at most [`KEEP_BYTES`]).
pub(crate) fn kept(shape: &Shape) -> bool {
    KronGram::bytes(shape) <= KEEP_BYTES
}

/// The workspaces not lent out: as many as an evaluation's loop had pieces
/// running at once (one per thread). A copy of a problem starts with none.
#[derive(Default)]
pub(crate) struct Spares(Mutex<Vec<Workspace>>);

impl Spares {
    /// A spare workspace, or a new one for `shape`, lent until the loan is
    /// dropped.
    pub(crate) fn lend(&self, shape: &Shape) -> Result<Lent<'_>> {
        let ws = match self.locked().pop() {
            Some(ws) => ws,
            None => Workspace::new(shape)?,
        };
        Ok(Lent {
            ws: Some(ws),
            spares: self,
        })
    }

    /// The spares, whole even when a holder panicked (every change under
    /// the lock is a push or a pop).
    fn locked(&self) -> MutexGuard<'_, Vec<Workspace>> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// At the end of an evaluation: drop the spares unless [`kept`].
    pub(crate) fn trim(&self, shape: &Shape) {
        if !kept(shape) {
            self.locked().clear();
        }
    }

    /// How many are kept.
    pub(crate) fn count(&self) -> usize {
        self.locked().len()
    }
}

impl Clone for Spares {
    fn clone(&self) -> Self {
        Spares::default()
    }
}

impl std::fmt::Debug for Spares {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Spares({} workspaces)", self.count())
    }
}

/// A workspace lent to one piece of a parallel loop, given back to the
/// spares when the piece is done: rayon starts every piece it splits off
/// with a fresh state, a dozen or more per evaluation.
pub(crate) struct Lent<'a> {
    ws: Option<Workspace>,
    spares: &'a Spares,
}

impl Lent<'_> {
    /// The workspace (held until the loan is dropped).
    pub(crate) fn get(&mut self) -> Result<&mut Workspace> {
        self.ws
            .as_mut()
            .ok_or_else(|| Error::Internal("a lent workspace was given back early".into()))
    }
}

impl Drop for Lent<'_> {
    /// Give the workspace back, but not from a piece that panicked: its
    /// accumulator may hold part of a block.
    fn drop(&mut self) {
        if let Some(ws) = self.ws.take() {
            if !std::thread::panicking() {
                self.spares.locked().push(ws);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape(n: usize, l: usize) -> Shape {
        Shape { n, r: l, l, nb: 0 }
    }

    #[test]
    fn small_workspaces_are_kept_for_the_next_evaluation_and_large_ones_not() {
        for (s, kept) in [(shape(10, 1), 1), (shape(16, 2), 1), (shape(24, 3), 0)] {
            assert_eq!(super::kept(&s), kept == 1);
            let spares = Spares::default();
            {
                // Two pieces at once, then one: two workspaces, reused.
                let (mut a, mut b) = (spares.lend(&s).unwrap(), spares.lend(&s).unwrap());
                assert!(a.get().is_ok() && b.get().is_ok());
            }
            drop(spares.lend(&s).unwrap());
            assert_eq!(spares.count(), 2);
            // Debug names the count, not the megabytes of samples.
            assert_eq!(format!("{spares:?}"), "Spares(2 workspaces)");
            spares.trim(&s);
            assert_eq!(spares.count(), 2 * kept);
            assert_eq!(spares.clone().count(), 0, "a copy starts with none");
        }
    }

    #[test]
    fn a_workspace_lent_to_a_piece_that_panicked_is_not_given_back() {
        let (s, spares) = (shape(3, 1), Spares::default());
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let _lent = spares.lend(&s).unwrap();
            panic!("a piece fails halfway");
        }));
        assert!(caught.is_err());
        assert_eq!(spares.count(), 0);
        drop(spares.lend(&s).unwrap());
        assert_eq!(spares.count(), 1);
    }
}
