//! Complex numbers in lanes: `LANES` frequencies processed side by side, so
//! that the small per-frequency loops of the resolvent do `LANES` times the
//! work per iteration and vectorise.

// Lane loops index several parallel arrays at once; an index reads best.
#![allow(clippy::needless_range_loop)]

use num_complex::Complex64 as C64;
use std::ops::{Add, AddAssign, Mul, Sub, SubAssign};

/// Number of frequencies evaluated together.
pub const LANES: usize = 4;

/// `LANES` complex numbers, real and imaginary parts apart.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Cx {
    /// Real parts.
    pub re: [f64; LANES],
    /// Imaginary parts.
    pub im: [f64; LANES],
}

impl Cx {
    /// All lanes equal to the real number `v`.
    #[inline(always)]
    pub fn real(v: f64) -> Cx {
        Cx {
            re: [v; LANES],
            im: [0.0; LANES],
        }
    }

    /// From one complex number per lane.
    #[inline(always)]
    pub fn from_lanes(v: &[C64; LANES]) -> Cx {
        let mut out = Cx::default();
        for k in 0..LANES {
            out.re[k] = v[k].re;
            out.im[k] = v[k].im;
        }
        out
    }

    /// Lane `k` as a complex number.
    #[inline(always)]
    pub fn lane(&self, k: usize) -> C64 {
        C64::new(self.re[k], self.im[k])
    }

    /// `|v|^2` per lane.
    #[inline(always)]
    pub fn norm_sqr(&self) -> [f64; LANES] {
        let mut out = [0.0; LANES];
        for k in 0..LANES {
            out[k] = self.re[k] * self.re[k] + self.im[k] * self.im[k];
        }
        out
    }

    /// `1 / v` per lane, or `None` when a lane is zero or not finite.
    #[inline(always)]
    pub fn inv(&self) -> Option<Cx> {
        let n2 = self.norm_sqr();
        let mut out = Cx::default();
        let mut ok = true;
        for k in 0..LANES {
            ok &= n2[k] != 0.0 && n2[k].is_finite();
            out.re[k] = self.re[k] / n2[k];
            out.im[k] = -self.im[k] / n2[k];
        }
        ok.then_some(out)
    }

    /// Multiply lane `k` by `s[k]`.
    #[inline(always)]
    pub fn scale_lanes(&self, s: &[f64; LANES]) -> Cx {
        let mut out = *self;
        for k in 0..LANES {
            out.re[k] *= s[k];
            out.im[k] *= s[k];
        }
        out
    }

    /// First lane that is zero or not finite.
    pub fn bad_lane(&self) -> Option<usize> {
        let n2 = self.norm_sqr();
        (0..LANES).find(|&k| !(n2[k] != 0.0 && n2[k].is_finite()))
    }

    /// Exchange the lanes of `a` and `b` where `mask` is set.
    #[inline(always)]
    pub fn swap_where(mask: &[bool; LANES], a: &mut Cx, b: &mut Cx) {
        for k in 0..LANES {
            if mask[k] {
                std::mem::swap(&mut a.re[k], &mut b.re[k]);
                std::mem::swap(&mut a.im[k], &mut b.im[k]);
            }
        }
    }
}

impl Add for Cx {
    type Output = Cx;
    #[inline(always)]
    fn add(mut self, o: Cx) -> Cx {
        self += o;
        self
    }
}

impl AddAssign for Cx {
    #[inline(always)]
    fn add_assign(&mut self, o: Cx) {
        for k in 0..LANES {
            self.re[k] += o.re[k];
            self.im[k] += o.im[k];
        }
    }
}

impl Sub for Cx {
    type Output = Cx;
    #[inline(always)]
    fn sub(mut self, o: Cx) -> Cx {
        self -= o;
        self
    }
}

impl SubAssign for Cx {
    #[inline(always)]
    fn sub_assign(&mut self, o: Cx) {
        for k in 0..LANES {
            self.re[k] -= o.re[k];
            self.im[k] -= o.im[k];
        }
    }
}

impl Mul for Cx {
    type Output = Cx;
    #[inline(always)]
    fn mul(self, o: Cx) -> Cx {
        let mut out = Cx::default();
        for k in 0..LANES {
            out.re[k] = self.re[k] * o.re[k] - self.im[k] * o.im[k];
            out.im[k] = self.re[k] * o.im[k] + self.im[k] * o.re[k];
        }
        out
    }
}

impl Mul<f64> for Cx {
    type Output = Cx;
    #[inline(always)]
    fn mul(self, s: f64) -> Cx {
        let mut out = self;
        for k in 0..LANES {
            out.re[k] *= s;
            out.im[k] *= s;
        }
        out
    }
}
