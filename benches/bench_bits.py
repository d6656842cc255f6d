"""Is the result a property of the data? identify under 1e-12 changes of the data, on few points.

For every draw of :mod:`bench_few` (its systems, placements and noise),
``lpvid.identify`` runs on the data and on the data multiplied by
``1 + 1e-12 e`` for two draws of a standard normal ``e`` (the last bits a
processor, a BLAS kernel or a file round trip may change). A draw *moves*
when any of the three returns another start, gamma or set of groups, or
models more than 1e-6 apart between the points (the worst relative FRF
difference at :func:`bench_few.unseen`'s scheduling values); its line gives
each run's choice and worst error against the truth. A summary line per
(case, N) counts the draws that moved, the ones whose local models moved
(their V_NLS by more than 1e-9 relative, or their coordinates: theta by
more than 1e-6 relative), and the largest ratio of two runs' worst errors.

Run: python benches/bench_bits.py [--cases mor onegroup cross2] [--points 4 5]
     [--draws 10] [--first 0]
"""

from __future__ import annotations

import argparse
import warnings
from dataclasses import dataclass

import numpy as np
from bench_few import CASES, FIXED, measured, unseen

import lpvid
from lpvid.testing import worst_relative_error

EPS = 1e-12
SEEDS = (1, 2)


@dataclass
class Run:
    """One identify of a draw: its choice, its worst error against the truth, its models."""

    choice: tuple[str, float, str]
    error: float
    model: lpvid.LpvModel
    local: lpvid.LocalModels


def runs(name: str, n_points: int, draw: int) -> tuple[list[Run], np.ndarray]:
    """The result on the draw's data, then on its two perturbations; the unseen values."""
    case = CASES[name]
    true, data, lo, hi = measured(case, n_points, draw)
    at = unseen(case, lo, hi)
    out = []
    for seed in (None, *SEEDS):
        G = data.G
        if seed is not None:
            G = G * (1 + EPS * np.random.default_rng(seed).standard_normal(G.shape))
        d = lpvid.FrfData(data.p, data.freqs_hz, G, sigma=data.sigma)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = lpvid.identify(d, case.n, true.basis, fixed=FIXED)
        choice = (res.start, res.entry.gamma, str(res.entry.nonzero_groups))
        error = worst_relative_error(res.model, true, case.freqs_hz, at)
        out.append(Run(choice, error, res.model, res.local))
    return out, at


def _local_moved(a, b) -> bool:
    costs = np.max(np.abs(np.asarray(a.vnls) - np.asarray(b.vnls)) / np.asarray(a.vnls))
    theta = max(
        float(np.linalg.norm(x.theta - y.theta) / np.linalg.norm(x.theta))
        for x, y in zip(a, b, strict=True)
    )
    return bool(costs > 1e-9 or theta > 1e-6)


def main() -> None:
    """Run the cases and print a line per draw and a summary per (case, N)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=["mor", "onegroup"])
    parser.add_argument("--points", nargs="+", type=int, default=[4, 5])
    parser.add_argument("--draws", type=int, default=10)
    parser.add_argument("--first", type=int, default=0, help="the first draw")
    args = parser.parse_args()
    lines = []
    for name in args.cases:
        for n in args.points:
            moved = local = 0
            ratio = 1.0
            for draw in range(args.first, args.first + args.draws):
                found, at = runs(name, n, draw)
                base, freqs = found[0], CASES[name].freqs_hz
                apart = max(worst_relative_error(r.model, base.model, freqs, at) for r in found[1:])
                same = all(r.choice == base.choice for r in found) and apart <= 1e-6
                moved += not same
                local += any(_local_moved(base.local, r.local) for r in found[1:])
                errors = [r.error for r in found]
                ratio = max(ratio, max(errors) / min(errors))
                print(
                    f"  {name} N={n} draw {draw}: {'same' if same else 'MOVED'} "
                    f"(models {apart:.1e} apart), errors "
                    + " / ".join(f"{e:.3g}" for e in errors)
                    + ("" if same else "; " + " | ".join(f"{r.choice}" for r in found)),
                    flush=True,
                )
            lines.append(
                f"## {name} N={n}: {moved}/{args.draws} draws moved under {EPS:g} changes "
                f"of the data, local models moved in {local}; largest error ratio {ratio:.3g}"
            )
            print(lines[-1], flush=True)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
