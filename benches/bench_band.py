"""Is the spread's band right beyond first order? The band against a profile of V_NLS.

The spread between the points (``result.between.spread``) adds the
first-order 95 % band of the directions the points see to the
committee's part. On few points that band is often ten or more times the
actual error while the model is right (``benches/bench_few.py``). This
script measures why, and what a check of the band beyond first order
would give, on the draws of ``bench_few.py`` (the same systems, placements
and noise; identify's defaults with D fixed, no validation data).

**The check.** The band's covariance ``C = S S^T`` (free parameters) is
taken along its leading directions: the eigenvectors ``z`` of ``S^T W S``,
``W`` the relative FRF's sensitivity over the range
(:func:`lpvid.experiment.design.target`), so that ``d = S z`` is a step of
one standard deviation along which the FRF between the points moves most.
Along ``d`` (both signs), V_NLS is profiled: at ``theta + t d`` it is
minimised over every other direction by ``--iters`` Levenberg-Marquardt
steps holding ``a^T theta`` (``a = S^+T z``, the quantity ``d`` moves);
first order says it rises by ``t^2 / 2``. The 95 % reach is the largest
``t`` (halving from 1.96) whose profiled rise stays at or below
``chi2_1(0.95) / 2 = 1.92``; the band along ``d`` is scaled by
``reach / 1.96`` (never widened). The leading directions are taken until
they hold ``--top`` of the band's variance over the range, at most
``--most``.

Printed per draw: the worst error, the band's and the checked band's
worst relative width over the error, the scale of each leading direction
(reach / 1.96), the check's seconds; per
(case, points): the share of draws whose spread covers the truth at nine
in ten (line, point) pairs and the share within ten times the actual worst
error (as ``bench_few.py``), first order and checked.

Run: python benches/bench_band.py [--cases mor onegroup cross2] [--points 4 5]
     [--draws 20] [--iters 30]
"""

from __future__ import annotations

import argparse
import time
import types
import warnings
from dataclasses import replace

import numpy as np
from bench_few import CASES, FIXED, coverage, measured, unseen

import lpvid
from lpvid.experiment.design import GridParts, target
from lpvid.fit.cost import build_problem
from lpvid.testing import worst_relative_error
from lpvid.trust.silent import range_grid
from lpvid.trust.uncertainty import _lti_index, band_radius

#: The rise of V_NLS at the 95 % bound of one direction: chi2_1(0.95) / 2.
LEVEL = 1.92
#: The 95 % bound of one direction in standard deviations.
Z95 = 1.96


def profiled_rise(problem, theta, v0, free, d, a, t: float, iters: int) -> float:
    """V_NLS at ``theta + t d``, minimised over the directions that keep ``a^T theta``, less v0."""
    th = theta.copy()
    th[free] += t * d
    v, g, h = problem.gauss_newton(th, free)
    m = g.size
    h = h.reshape(m, m)
    an = a / np.linalg.norm(a)
    hold = np.eye(m) - np.outer(an, an)
    lam = 1e-3
    for _ in range(iters):
        if v - v0 <= LEVEL:
            break
        A = hold @ h @ hold + np.outer(an, an) * np.max(np.diag(h))
        A += lam * np.diag(np.maximum(np.diag(A), np.finfo(float).tiny))
        trial = th.copy()
        trial[free] += hold @ np.linalg.solve(A, -hold @ g / 2)
        vt, gt, ht = problem.gauss_newton(trial, free)
        if vt < v:
            th, v, g, h, lam = trial, vt, gt, ht.reshape(m, m), lam * 0.3
        else:
            lam *= 10
    return float(v - v0)


def checked(result, iters: int, top: float, most: int):
    """The band's covariance checked along its leading directions, and their reaches.

    See the module notes; a reach between two halvings is their geometric
    middle.
    """
    between, model, data = result.between, result.model, result.data
    free = ~between.held
    C = between.band.theta[np.ix_(free, free)]
    lam, U = np.linalg.eigh(0.5 * (C + C.T))
    keep = lam > lam.max() * 1e-13
    S, Sp = U[:, keep] * np.sqrt(lam[keep]), U[:, keep] / np.sqrt(lam[keep])
    W = target(GridParts(model, data.freqs_hz, range_grid(model, data)), _lti_index(model))
    w, Z = np.linalg.eigh(S.T @ W[np.ix_(free, free)] @ S)
    w, Z = np.maximum(w[::-1], 0.0), Z[:, ::-1]
    k = min(most, int(np.searchsorted(np.cumsum(w) / max(w.sum(), 1e-300), top)) + 1)
    problem = build_problem(model, data)
    theta = model.theta
    v0 = problem.vnls(theta)
    scale = np.ones(Z.shape[1])
    for j in range(k):
        d, a = S @ Z[:, j], Sp @ Z[:, j]
        reach = []
        for sign in (1.0, -1.0):
            t = Z95
            while t > Z95 * 2.0**-14 and (
                profiled_rise(problem, theta, v0, free, sign * d, a, t, iters) > LEVEL
            ):
                t /= 2
            reach.append(t if t == Z95 or t <= Z95 * 2.0**-14 else t * np.sqrt(2.0))
        scale[j] = max(reach) / Z95
    full = np.zeros_like(between.band.theta)
    full[np.ix_(free, free)] = S @ (Z * scale**2) @ Z.T @ S.T
    return replace(between.band, theta=full), scale[:k]


def main() -> None:
    """Run the draws and print the rows and summaries."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", choices=sorted(CASES), default=["mor"])
    parser.add_argument("--points", nargs="+", type=int, default=None)
    parser.add_argument("--draws", type=int, default=20)
    parser.add_argument("--iters", type=int, default=30)
    parser.add_argument("--top", type=float, default=0.95)
    parser.add_argument("--most", type=int, default=10)
    args = parser.parse_args()
    lines = []
    for name in args.cases:
        case = CASES[name]
        for n_points in args.points or case.default_points:
            seen = {"first order": [], "checked": []}
            for draw in range(args.draws):
                true, data, lo, hi = measured(case, n_points, draw)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    res = lpvid.identify(data, case.n, true.basis, fixed=FIXED)
                at, f = unseen(case, lo, hi), case.freqs_hz
                err = worst_relative_error(res.model, true, f, at)
                b = res.between
                if b.band is None or b.held is None:
                    print(f"  {name} N={n_points} draw {draw}: no band ({b.note})", flush=True)
                    continue
                t0 = time.perf_counter()
                band, reach = checked(res, args.iters, args.top, args.most)
                seconds = time.perf_counter() - t0
                other = replace(b)
                other.__dict__.update(_open=b._open, band=band)
                for key, between in (("first order", b), ("checked", other)):
                    view = types.SimpleNamespace(model=res.model, between=between)
                    seen[key].append(coverage(view, true, f, at))
                width = [
                    np.max(
                        np.linalg.norm(
                            (band_radius(0.95) * c.frf_std(f, at)).reshape(len(at), -1),
                            axis=1,
                        )
                        / np.linalg.norm(true.frf(f, at).reshape(len(at), -1), axis=1)
                    )
                    / err
                    for c in (b.band, band)
                ]
                print(
                    f"  {name} N={n_points} draw {draw}: error {err:.4f}, band/error "
                    f"{width[0]:.3g} -> {width[1]:.3g}; leading directions scaled by "
                    f"{' '.join(f'{r:.2g}' for r in reach)}; {seconds:.2f} s",
                    flush=True,
                )
            parts = []
            for key, rows in seen.items():
                cover = np.mean([inside >= 0.9 for inside, _ in rows])
                within = np.mean([1 <= ratio <= 10 for _, ratio in rows])
                median = np.median([ratio for _, ratio in rows])
                parts.append(
                    f"{key}: covers {cover:.0%}, within 10x {within:.0%}, spread/error "
                    f"median {median:.3g}"
                )
            head = f"## {name} N={n_points} ({len(seen['checked'])} draws): "
            lines.append(head + "; ".join(parts))
            print(lines[-1], flush=True)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
