"""Identify again on data simulated from the model returned: a spread that measures the pipeline.

With few measured points the data leave a family of fits, and which of them
:func:`lpvid.identify` returns follows the noise of the data (and, where the
fits land along the family, the last bits of the arithmetic:
``docs/fewpoints.md``). The spread of :class:`lpvid.pipeline.between.Between`
tells what one run saw: the covariance's band on the directions the points
see, plus the committee of the fits the run made. :func:`resampled` asks
what another run would return. ``draws`` times, FRFs are simulated from the
returned model at the measured points (its frozen FRF plus circular complex
Gaussian noise of the data's sigma, lpvid's noise model:
:func:`lpvid.data.noise.circular_noise`), validation data likewise at their
points, and identified with the same problem (order, basis, fixed
parameters, settings, range). The result returned carries their models in
:attr:`~lpvid.IdentifyResult.between`, whose spread is then
:data:`~lpvid.pipeline.between.RESAMPLED_SCALE` times the median distance
from the model returned, entry by entry, of these models and the run's own
fits within the noise (:attr:`~lpvid.Between.voters`) together. Where to
measure next is not theirs: :func:`lpvid.next_points` follows the committee
of the run's own fits, as without resampling
(:mod:`lpvid.experiment.nextpoints`: measured, the resampled spread placed
points no better).

It costs ``draws`` runs of :func:`lpvid.identify`. Measured on
``benches/bench_few.py`` (``python benches/bench_few.py --resample 5``,
``docs/fewpoints.md``): with five draws the spread is within ten times the
actual worst error between the points, and at least that error, in 85 to
100 % of the draws of three systems at three to eight points (the
resampled models alone, three times their median distance: 76 to 100 %),
where the band and the committee's spread are in 60 to 95 %.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np

from lpvid._capture import collected
from lpvid._checks import generator, positive_int
from lpvid._progress import Progress, check_progress, say
from lpvid.data.frf import FrfData
from lpvid.data.noise import circular_noise
from lpvid.model.lpv import LpvModel
from lpvid.pipeline.between import Between
from lpvid.pipeline.result import IdentifyResult
from lpvid.pipeline.run import identify

__all__ = ["DRAWS", "resampled", "simulated"]

#: Runs of :func:`resampled` by default: five put the spread within ten
#: times the actual error in 85-100 % of the draws of every case of
#: ``benches/bench_few.py`` measured (``docs/fewpoints.md``).
DRAWS = 5


def simulated(model: LpvModel, data: FrfData, rng: np.random.Generator) -> FrfData:
    """``data`` as ``model`` would have given them: its frozen FRF plus noise of the data's sigma.

    At the data's scheduling values and lines, with their sigma and sample
    time; the noise circular complex Gaussian
    (:func:`lpvid.data.noise.circular_noise`), drawn from ``rng``.
    """
    G = model.frf(data.freqs_hz, data.p)
    return FrfData(data.p, data.freqs_hz, G + circular_noise(data.sigma, rng), data.sigma, data.Ts)


def resampled(
    result: IdentifyResult,
    draws: int = DRAWS,
    *,
    seed: Any = 0,
    progress: Progress | None = None,
) -> IdentifyResult:
    """``result`` with a spread measured by identifying again on simulated data (module notes).

    Parameters
    ----------
    result : IdentifyResult
        What :func:`lpvid.identify` returned.
    draws : int, optional
        Runs of :func:`lpvid.identify` on data simulated from
        ``result.model`` (default :data:`DRAWS`).
    seed : None, int or numpy Generator, optional
        Source of the simulated noise (default 0: the same spread on every
        call).
    progress : callable, optional
        Called with a line of text as each run starts (the same line goes
        to the ``lpvid`` logger at INFO).

    Returns
    -------
    IdentifyResult
        ``result`` with :attr:`~lpvid.IdentifyResult.between` carrying the
        models identified (``between.resampled``): its
        :meth:`~lpvid.Between.spread`, :meth:`~lpvid.Between.worst` and
        summary are theirs and the voters' together
        (:func:`lpvid.next_points` still follows the run's committee).
        ``timings["resample_s"]`` is the time taken. The runs' warnings
        are not raised: the summary says how many warned, and the first
        (``between.resampled_warned``).

    Raises
    ------
    TypeError
        When ``result`` is not an IdentifyResult, or on a bad ``draws`` or
        ``seed``.
    ValueError
        When ``result`` does not hold the problem it was identified from
        (made by hand), or was identified with time records (they are not
        simulated here).

    Examples
    --------
    >>> import numpy as np, lpvid, lpvid.testing
    >>> true = lpvid.testing.synthetic_parametric(10)
    >>> f = np.logspace(0.5, 3.5, 60) / (2 * np.pi)
    >>> data = lpvid.testing.noisy_data(true, [0.02, 0.5, 1.0], f, np.random.default_rng(0), 0.01)
    >>> res = lpvid.identify(data, 10, true.basis, fixed={"D": True})  # doctest: +SKIP
    >>> again = lpvid.resampled(res)  # doctest: +SKIP
    >>> len(again.between.resampled)  # doctest: +SKIP
    5
    """
    if not isinstance(result, IdentifyResult):
        raise TypeError(f"result: expected an IdentifyResult, got {type(result).__name__}")
    draws = positive_int(draws, "draws")
    progress = check_progress(progress)
    rng = generator(seed)
    problem = result.problem
    if problem is None:
        raise ValueError(
            "result: holds no problem to identify again (results of lpvid.identify do)"
        )
    if problem.time_data is not None:
        raise ValueError(
            "result: identified with time records, which lpvid.resampled does not simulate"
        )
    t = time.perf_counter()
    models, warned = [], []
    for k in range(draws):
        say(progress, f"resampling: identify on simulated data, run {k + 1} of {draws}")
        data = simulated(result.model, problem.data, rng)
        validation = None
        if problem.validation is not None:
            validation = simulated(result.model, problem.validation, rng)
        # The runs' warnings are about models no one is shown: kept, and said
        # in the summary (Between.resampled_warned), not raised.
        with collected() as said:
            again = identify(replace(problem, data=data, validation=validation))
        models.append(again.model)
        if said:
            warned.append(said[0][1])
    between = result.between or Between(result.model, data=result.data)
    return replace(
        result,
        between=replace(between, resampled=models, resampled_warned=warned),
        timings={**result.timings, "resample_s": time.perf_counter() - t},
    )
