"""The scale ladder: identify() on problems from the paper's gantry to industrial MIMO stages.

Each rung is a lightly damped flexible system whose mode frequencies and
shapes move with the scheduling parameter, measured as noisy FRFs (40 dB,
known sigma) at N points with validation data between them, and identified
with ``lpvid.identify(data, n, basis, validation=...)`` as a user runs it.
For every rung it prints the time of identify and of its every stage, the
process's CPU seconds (every thread's; the cores they make on average, and
the time with every core busy throughout: a floor more overlap cannot
beat), the mean LM iteration and cone step (with its solver's iterations:
Newton's method's, or Clarabel's interior-point iterations where Newton's
method gave up), the
number of steps, the chosen model's V_NLS and validation V_NLS against their
noise floors and the groups kept, and the peak memory of the process beside
what it held before identify and lpvid's estimate of identify's peak
(``lpvid.fit.memory.pipeline_memory``, the figure identify checks before it runs).

Each rung runs in a fresh process (peak memory is per rung). The machines
are shared and noisy: compare medians over --repeat runs.

The rungs n32 (4x4) and grid81 (two scheduling parameters on a 9 x 9 grid,
total-degree-2 basis) are the sizes users bring next; n32 takes long (run
it alone, with --progress to see its stages as they come).

Run: python benches/bench_scale.py [--rungs gantry n10 ...] [--repeat 3] [--json out.json]
[--cone-tol 1e-6] [--progress]
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass

import numpy as np

import lpvid
from lpvid._spread import cores


@dataclass(frozen=True)
class Rung:
    """One problem size."""

    name: str
    n: int
    l: int
    r: int
    nb: int
    points: int
    lines: int
    note: str
    params: int = 1  # scheduling parameters: 2 puts the points on a square grid


RUNGS = {
    "gantry": None,  # the built-in data set (lpvid.datasets.gantry())
    "n10": Rung("n10", 10, 2, 2, 2, 7, 400, "n=10, 2x2, Nb=2, N=7, F=400"),
    "n16": Rung("n16", 16, 2, 2, 4, 9, 500, "n=16, 2x2, Nb=4, N=9, F=500"),
    "points25": Rung("points25", 6, 2, 1, 4, 25, 300, "gantry size, N=25, F=300"),
    "lines3000": Rung("lines3000", 6, 2, 1, 4, 5, 3000, "gantry size, N=5, F=3000"),
    "n24": Rung("n24", 24, 3, 3, 3, 9, 1000, "n=24, 3x3, Nb=3, N=9, F=1000"),
    "n32": Rung("n32", 32, 4, 4, 4, 9, 500, "n=32, 4x4, Nb=4, N=9, F=500"),
    # 9 x 9 points in (s1, s2), total degree 2 (Nb = 5: s1, s2, s1^2, s1 s2, s2^2)
    "grid81": Rung(
        "grid81", 8, 2, 2, 2, 81, 300, "n=8, 2x2, 2 parameters, degree 2, N=81 (9x9), F=300", 2
    ),
}


def flexible_system(rung: Rung, seed: int = 0):
    """A modal flexible system: ``n/2`` lightly damped modes moving with p in [-1, 1].

    Mode k has natural frequency ``w_k(s) = w_k0 (1 + a_k s + b_k s^2)``
    (a_k up to +-25 %), damping 1-3 %, and input and output shapes that
    change linearly with s. Returns ``physics(s) -> (A, B, C, D)`` in
    continuous time (positions and velocities of the modes as outputs mix).
    With two scheduling parameters ``s = (s1, s2)``: ``w_k = w_k0 (1 + a_k
    s1 + a2_k s2)`` and shapes linear in both, so that A, B and C are of
    total degree 2 (what the rung's basis represents).
    """
    rng = np.random.default_rng(seed)
    modes = rung.n // 2
    w0 = 2 * np.pi * np.geomspace(20.0, 250.0, modes) * (1 + 0.05 * rng.standard_normal(modes))
    a = rng.uniform(-0.25, 0.25, modes)
    b = rng.uniform(-0.05, 0.05, modes)
    zeta = rng.uniform(0.01, 0.03, modes)
    bin0 = rng.standard_normal((modes, rung.r))
    bin1 = 0.3 * rng.standard_normal((modes, rung.r))
    cout0 = rng.standard_normal((rung.l, modes))
    cout1 = 0.3 * rng.standard_normal((rung.l, modes))
    mix = rng.uniform(0.2, 1.0, (rung.l, modes))
    if rung.params == 2:  # drawn after the others: the one-parameter rungs stay as they were
        a2 = rng.uniform(-0.25, 0.25, modes)
        bin2 = 0.3 * rng.standard_normal((modes, rung.r))
        cout2 = 0.3 * rng.standard_normal((rung.l, modes))

    def physics(p):
        s, t = (float(p), 0.0) if rung.params == 1 else (float(p[0]), float(p[1]))
        A = np.zeros((rung.n, rung.n))
        B = np.zeros((rung.n, rung.r))
        C = np.zeros((rung.l, rung.n))
        for k in range(modes):
            if rung.params == 1:
                w = w0[k] * (1 + a[k] * s + b[k] * s * s)
                bk, ck = bin0[k] + s * bin1[k], cout0[:, k] + s * cout1[:, k]
            else:
                w = w0[k] * (1 + a[k] * s + a2[k] * t)
                bk = bin0[k] + s * bin1[k] + t * bin2[k]
                ck = cout0[:, k] + s * cout1[:, k] + t * cout2[:, k]
            i = 2 * k
            A[i : i + 2, i : i + 2] = [[0.0, 1.0], [-(w**2), -2 * zeta[k] * w]]
            B[i + 1] = bk * w
            C[:, i] = ck * w * (1 - mix[:, k])
            C[:, i + 1] = ck * mix[:, k]
        return A, B, C, np.zeros((rung.l, rung.r))

    return physics


def measured(rung: Rung, physics, p: np.ndarray, rng: np.random.Generator) -> lpvid.FrfData:
    """Noisy FRFs (40 dB, known sigma) of the continuous-time system.

    In continuous time the modal matrices are polynomials of degree 2 in s,
    which every rung's basis represents: the data can be fitted to the noise
    floor.
    """
    freqs = np.linspace(10.0, 400.0, rung.lines)
    z = 2j * np.pi * freqs
    G = np.stack([lpvid.model.frozen.lti_frf(*physics(s), z) for s in p])
    rms = np.sqrt(np.mean(np.abs(G) ** 2, axis=1, keepdims=True))
    sigma = np.broadcast_to(0.01 * rms, G.shape)
    noise = (rng.standard_normal(G.shape) + 1j * rng.standard_normal(G.shape)) / np.sqrt(2)
    return lpvid.FrfData(p, freqs, G + sigma * noise, sigma)


def problem(name: str | Rung):
    """Identification data, validation data, order and basis of a rung (its name, or a Rung)."""
    if name == "gantry":
        ds = lpvid.datasets.gantry()
        return ds.identification, ds.validation, ds.order, ds.basis, "the built-in gantry"
    rung = RUNGS[name] if isinstance(name, str) else name
    assert rung is not None
    physics = flexible_system(rung)
    rng = np.random.default_rng(1)
    if rung.params == 1:
        p = np.linspace(-1.0, 1.0, rung.points)
        mid = (p[:-1] + p[1:]) / 2
        val = mid[:: max(1, mid.size // 4)][:4]
        basis = lpvid.Polynomial(rung.nb, domain=(-1.0, 1.0))
    else:
        side = np.linspace(-1.0, 1.0, round(np.sqrt(rung.points)))
        p = np.array([(s, t) for s in side for t in side])
        mid = (side[:-1] + side[1:]) / 2  # 4 cell centres spread over the square
        val = np.array([(mid[1], mid[2]), (mid[2], mid[5]), (mid[5], mid[1]), (mid[6], mid[6])])
        basis = lpvid.Polynomial(rung.nb, domain=[(-1.0, 1.0), (-1.0, 1.0)])
    data = measured(rung, physics, p, rng)
    validation = measured(rung, physics, val, rng)
    return data, validation, rung.n, basis, rung.note


def run_one(name: str | Rung, cone_tol: float | None = None, progress: bool = False) -> dict:
    """One identify() of a rung, with its figures (in this process).

    With ``progress``, identify's progress messages go to stderr as they
    come, each with the seconds since identify started.
    """
    data, validation, n, basis, note = problem(name)
    settings = None if cone_tol is None else lpvid.L21Settings(max_outer=10, cone_tol=cone_tol)
    before_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    estimate_mb = lpvid.fit.memory.pipeline_memory(data, n, basis)[0] / 2**20
    t0, c0 = time.perf_counter(), time.process_time()

    def say(message: str) -> None:
        print(f"[{time.perf_counter() - t0:8.1f} s] {message}", file=sys.stderr, flush=True)

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = lpvid.identify(
            data,
            n,
            basis,
            validation=validation,
            settings=settings,
            progress=say if progress else None,
        )
    total, cpu = time.perf_counter() - t0, time.process_time() - c0
    lm = [row for c in result.candidates if c.fit for row in c.fit.history]
    socp = [row for r in result.path for row in r.history]
    e = result.entry
    return {
        "rung": name if isinstance(name, str) else name.name,
        "note": note,
        "free": int(lpvid.free_mask(result.model).sum()),
        "identify_s": total,
        "cpu_s": cpu,
        "timings": result.timings,
        "lm_steps": len(lm),
        "lm_iter_s": statistics.mean(r["seconds"] for r in lm) if lm else float("nan"),
        "cone_steps": len(socp),
        "cone_step_s": statistics.mean(r["seconds"] for r in socp) if socp else float("nan"),
        "ip_iterations": statistics.mean(r["solver_iterations"] for r in socp) if socp else 0,
        "newton_steps": sum(r["status"] == "Solved (Newton)" for r in socp),
        "zero_steps": sum(r["status"] == "Solved (every group at zero)" for r in socp),
        "steps_per_gamma": [r.n_iter for r in result.path],
        "pinned": sum(e.pinned for e in result.entries),
        "vnls_ratio": e.vnls / e.noise_floor,
        "validation_ratio": e.validation_vnls / e.validation_floor,
        "groups": e.n_groups,
        "nonzero_groups": e.nonzero_groups,
        "chosen_gamma": e.gamma,
        "start": result.start,
        "warnings": [str(w.message) for w in caught],
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "before_mb": before_mb,
        "estimate_mb": estimate_mb,
    }


def report(runs: list[dict]) -> None:
    first = runs[0]
    med = {
        k: statistics.median(r[k] for r in runs)
        for k in (
            "identify_s",
            "cpu_s",
            "lm_iter_s",
            "cone_step_s",
            "ip_iterations",
            "peak_mb",
            "before_mb",
            "estimate_mb",
        )
    }
    stages = {
        k: statistics.median(r["timings"].get(k, 0.0) for r in runs) for k in first["timings"]
    }
    print(f"\n== {first['rung']}: {first['note']} ({first['free']} free parameters)")
    print(
        f"identify {med['identify_s']:.2f} s (median of {len(runs)}: "
        + ", ".join(f"{r['identify_s']:.2f}" for r in runs)
        + f"); CPU {med['cpu_s']:.2f} s (every thread: {med['cpu_s'] / med['identify_s']:.2f} of "
        f"{cores()} cores; with every core busy throughout {med['cpu_s'] / cores():.2f} s)"
    )
    print("stages: " + ", ".join(f"{k} {v:.2f}" for k, v in stages.items()))
    print(
        f"LM: {first['lm_steps']} steps in the starts, {1e3 * med['lm_iter_s']:.1f} ms each; "
        f"cone: {first['cone_steps']} steps {first['steps_per_gamma']}, "
        f"{1e3 * med['cone_step_s']:.1f} ms each, {med['ip_iterations']:.1f} solver iterations "
        f"({first.get('newton_steps', 0)} by Newton's method, {first.get('zero_steps', 0)} with "
        "every group at zero, the others by Clarabel)"
        + (f"; {first['pinned']} kept fit(s) pinned" if first.get("pinned") else "")
    )
    print(
        f"chosen: gamma {first['chosen_gamma']:g} from {first['start']}, {first['groups']} groups "
        f"{first['nonzero_groups']}, V/floor {first['vnls_ratio']:.4f}, "
        f"validation V/floor {first['validation_ratio']:.4f}"
    )
    print(
        f"peak memory {med['peak_mb']:.0f} MB ({med['before_mb']:.0f} MB before identify: "
        f"identify's own {med['peak_mb'] - med['before_mb']:.0f} MB against lpvid's estimate "
        f"{med['estimate_mb']:.0f} MB)"
    )
    for w in first["warnings"]:
        print(f"warning: {w}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    default = [r for r in RUNGS if r != "n32"]  # n32 only when asked: it takes long
    parser.add_argument("--rungs", nargs="+", default=default, choices=list(RUNGS))
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--json", help="write every run's figures to this file")
    parser.add_argument(
        "--cone-tol", type=float, help="L21Settings.cone_tol of the path (default its default)"
    )
    parser.add_argument(
        "--progress",
        action="store_true",
        help="print identify's progress messages (stderr), with the time since it started",
    )
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(run_one(args.one, args.cone_tol, args.progress)))
        return
    everything = {}
    for name in args.rungs:
        runs = []
        for _ in range(args.repeat):
            out = subprocess.run(
                [sys.executable, __file__, "--one", name]
                + ([] if args.cone_tol is None else ["--cone-tol", str(args.cone_tol)])
                + (["--progress"] if args.progress else []),
                stdout=subprocess.PIPE,
                stderr=None if args.progress else subprocess.PIPE,
                text=True,
                check=True,
            )
            runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
        report(runs)
        everything[name] = runs
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(everything, fh, indent=1)


if __name__ == "__main__":
    main()
