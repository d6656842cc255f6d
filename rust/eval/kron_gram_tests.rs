//! Unit tests of the Gram accumulator (`super`): what it does with the
//! sums it is handed, and the size of its blocks.

use super::*;
use crate::eval::lti::{lanes_of, Frozen, Hessenberg};
use crate::testing::Lcg;
use num_complex::Complex64 as C64;

/// A random model of the shape, its `A`'s diagonal shifted by -2 to keep
/// its poles off the `count` lines on the imaginary axis it comes with
/// (not a proof of stability: `evaluate` checks each shape's lines).
fn model(shape: &Shape, count: usize, rng: &mut Lcg) -> (Hessenberg, Vec<C64>) {
    let theta: Vec<f64> = (0..shape.len()).map(|_| rng.next_f64() - 0.5).collect();
    let mut frozen = Frozen::at(shape, &theta, &[1.0]);
    let n = shape.n;
    for k in 0..n {
        frozen.a[k + k * n] -= 2.0;
    }
    let lines = (0..count)
        .map(|k| C64::new(0.0, 0.05 + 0.1 * k as f64))
        .collect();
    (Hessenberg::new(shape, &frozen), lines)
}

/// The lines added to `acc` in batches of [`LANES`], with random weights
/// and residuals (zero weight on the lanes past the last line).
fn add_lines(acc: &mut KronGram, shape: &Shape, form: &Hessenberg, lines: &[C64], seed: u64) {
    let mut rng = Lcg(seed);
    let lr = shape.l * shape.r;
    let mut res = Resolvent::new(shape);
    for first in (0..lines.len()).step_by(LANES) {
        let end = (first + LANES).min(lines.len());
        res.evaluate(form, &lanes_of(lines, first, end), true)
            .expect("the shifted model is regular on these lines");
        let mut w = vec![[0.0; LANES]; lr];
        let mut err = vec![Cx::default(); lr];
        for lane in (first..end).map(|k| k - first) {
            for e in 0..lr {
                w[e][lane] = 0.5 + rng.next_f64();
                err[e].re[lane] = rng.next_f64() - 0.5;
                err[e].im[lane] = rng.next_f64() - 0.5;
            }
        }
        acc.add(&res, &w, &err);
    }
}

fn filled(rows: usize, cols: usize, value: f64) -> Mat<f64> {
    Mat::from_fn(rows, cols, |_, _| value)
}

/// Shapes whose products run in parts (by outputs and by inputs, more than
/// [`FAER_ENTRIES`] entries), and one whose products run whole.
const SHAPES: [(usize, usize, usize); 4] = [(6, 3, 2), (6, 2, 3), (5, 3, 3), (4, 1, 1)];

#[test]
fn the_sums_handed_in_are_written_over_whatever_they_hold() {
    // The sums a task's accumulator is handed come from a summed part
    // (`PointSums::next_sums`): whatever they hold, NaN here, is written
    // over, the entries no sample reaches (those of `Theta`'s last rows
    // off their own output's or input's samples) set to zero.
    for (k, &(n, r, l)) in SHAPES.iter().enumerate() {
        let shape = Shape::new(n, r, l, 0).unwrap();
        let (form, lines) = model(&shape, 150, &mut Lcg(7 + k as u64));
        let mut clean = KronGram::new(&shape).unwrap();
        add_lines(&mut clean, &shape, &form, &lines, 11);
        let want = clean.finish(&shape, KronGram::sums(&shape).unwrap());

        let mut stale = KronGram::new(&shape).unwrap();
        let (s1, s2) = KronGram::sums(&shape).unwrap();
        let nan = (
            filled(s1.nrows(), s1.ncols(), f64::NAN),
            filled(s2.nrows(), s2.ncols(), f64::NAN),
        );
        // No line yet: the sums of none, and the NaN sums are its next.
        let none = stale.finish(&shape, nan);
        assert!(none.bits().iter().all(|&b| b == 0), "({n}, {r}, {l})");
        add_lines(&mut stale, &shape, &form, &lines, 11);
        let got = stale.finish(&shape, KronGram::sums(&shape).unwrap());
        assert_eq!(got.bits(), want.bits(), "({n}, {r}, {l})");
        // And the same after a clear: lines added and dropped first.
        let mut dropped = KronGram::new(&shape).unwrap();
        add_lines(&mut dropped, &shape, &form, &lines[..37], 5);
        dropped.clear();
        add_lines(&mut dropped, &shape, &form, &lines, 11);
        let again = dropped.finish(&shape, KronGram::sums(&shape).unwrap());
        assert_eq!(again.bits(), want.bits(), "({n}, {r}, {l}) after a clear");
    }
}

#[test]
fn a_block_holds_the_samples_of_whole_batches_and_at_least_block_samples() {
    // Every sample of a batch of lines (one per lane and per group) goes
    // into one block, and a block is as small as that allows above
    // BLOCK_SAMPLES.
    for (n, r, l) in [
        (4, 1, 1),
        (6, 2, 1),
        (6, 1, 3),
        (6, 2, 2),
        (5, 3, 3),
        (5, 5, 4),
    ] {
        let shape = Shape::new(n, r, l, 0).unwrap();
        let batch = l.min(r) * LANES;
        let cols = KronGram::block_columns(&shape);
        assert_eq!(cols % batch, 0, "({n}, {r}, {l}): {cols}");
        assert!(
            cols >= BLOCK_SAMPLES && cols < BLOCK_SAMPLES + batch,
            "({n}, {r}, {l}): {cols}"
        );
        assert_eq!(KronGram::new(&shape).unwrap().cols(), cols);
    }
}

#[test]
fn its_bytes_are_those_of_its_buffers_and_sums() {
    // What the memory estimates count (`lpvid.fit_memory`, the workspaces
    // kept between evaluations): the four sample buffers and the products'
    // scratch, `S1` and `S2`, and the `J^T r` of the part it hands back.
    for (n, r, l) in [(4, 1, 1), (6, 2, 1), (6, 1, 3), (5, 3, 3), (5, 5, 4)] {
        let shape = Shape::new(n, r, l, 0).unwrap();
        let mut acc = KronGram::new(&shape).unwrap();
        let entries = |m: &Mat<f64>| m.nrows() * m.ncols();
        let buffers = [&acc.u_re, &acc.u_im, &acc.v_re, &acc.v_im, &acc.panels]
            .iter()
            .map(|b| b.len())
            .sum::<usize>();
        let part = acc.finish(&shape, KronGram::sums(&shape).unwrap());
        let sums = entries(&part.s1) + entries(&part.s2);
        assert_eq!(
            GramParts::bytes(&shape),
            8 * (sums + part.jtr.len()),
            "({n}, {r}, {l})"
        );
        assert_eq!(
            KronGram::bytes(&shape),
            8 * (buffers + sums + part.jtr.len()),
            "({n}, {r}, {l})"
        );
    }
}
