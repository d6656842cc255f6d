"""Time-domain simulation of a gantry-size LPV model: 10^6 samples.

Model: n=6 states, r=1 input, l=2 outputs, Nb=4 basis functions (a degree-4
polynomial of a scheduling parameter on 24..48), discrete time; a random
input and a scheduling parameter swept slowly over its range. Prints the
median wall time over repetitions of

- the whole call ``model.simulate(u, p)`` (checks, basis evaluation in
  Python, the Rust recursion),
- the Rust core alone (basis values given),
- the basis evaluation alone,
- the Rust core on the continuous-time twin of the model (``A(0) - 1.5 I``
  stable in continuous time, zero-order hold with ``dt = 1e-3``: one matrix
  exponential per sample) over the first 10^5 samples.

The machines are shared and noisy: compare medians.

Run: python benches/bench_simulate.py [--repeat 20] [--samples 1000000]
"""

from __future__ import annotations

import argparse

import numpy as np
from bench_core import median_time

import lpvid
from lpvid import _core


def gantry_size_model(seed: int = 0) -> lpvid.LpvModel:
    """A random LPV model of gantry size, stable over the scheduling range."""
    rng = np.random.default_rng(seed)
    n, r, l, nb = 6, 1, 2, 4
    A = 0.05 * rng.normal(size=(nb + 1, n, n))
    A[0] += 0.6 * np.eye(n)
    return lpvid.LpvModel(
        A,
        rng.normal(size=(nb + 1, n, r)),
        rng.normal(size=(nb + 1, l, n)),
        rng.normal(size=(nb + 1, l, r)),
        lpvid.Polynomial(nb, domain=(24.0, 48.0)),
        Ts=1e-3,
    )


def continuous_twin(model: lpvid.LpvModel) -> lpvid.LpvModel:
    """The same matrices as a continuous-time model, with ``A(0) - 1.5 I`` (stable)."""
    A = model.A.copy()
    A[0] -= 1.5 * np.eye(A.shape[1])
    return lpvid.LpvModel(A, model.B, model.C, model.D, model.basis, Ts=None)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--samples", type=int, default=1_000_000)
    args = parser.parse_args()
    model = gantry_size_model()
    T = args.samples
    rng = np.random.default_rng(1)
    u = rng.normal(size=T)
    p = 36.0 + 12.0 * np.sin(2 * np.pi * np.arange(T) / T)
    n, r, l, nb = model.shape
    psi = model.basis(p)
    theta = model.theta
    view, flat_u, x0 = _core.ModelView(model.shape, theta, psi), u.copy(), np.zeros(n)
    y = model.simulate(u, p)
    assert y.shape == (T, l) and np.all(np.isfinite(y))
    t_all = median_time(lambda: model.simulate(u, p), args.repeat)
    t_core = median_time(lambda: _core.simulate(view, flat_u, x0), args.repeat)
    t_basis = median_time(lambda: model.basis(p), args.repeat)
    ct_theta = continuous_twin(model).theta
    t_ct = min(T, 100_000)
    ct_view = _core.ModelView(model.shape, ct_theta, psi[:t_ct].copy())
    ct_u = flat_u[:t_ct].copy()
    t_zoh = median_time(lambda: _core.simulate(ct_view, ct_u, x0, 1e-3), args.repeat)
    print(f"simulate {T} samples: n={n}, r={r}, l={l}, Nb={nb}, discrete time")
    print(f"  model.simulate(u, p) (whole call)  : {t_all * 1e3:8.2f} ms median")
    print(f"  Rust core (basis values given)     : {t_core * 1e3:8.2f} ms median")
    print(f"  basis evaluation in Python         : {t_basis * 1e3:8.2f} ms median")
    print(f"  core per sample                    : {t_core / T * 1e9:8.1f} ns")
    print(f"continuous time (ZOH, dt=1e-3), {t_ct} samples, core only:")
    print(f"  Rust core (basis values given)     : {t_zoh * 1e3:8.2f} ms median")
    print(f"  core per sample                    : {t_zoh / t_ct * 1e9:8.1f} ns")


if __name__ == "__main__":
    main()
