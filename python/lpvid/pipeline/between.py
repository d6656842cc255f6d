"""What the measured points leave open between them, for the model :func:`lpvid.identify` returns.

Two things, both in :class:`Between`:

- the count of :mod:`lpvid.trust.silent`: how many directions of the
  returned model's structure the points leave open, and at least how many
  more points would determine it;
- a spread between the points: at every line and scheduling value, the
  95 % band of the covariance on the directions the points see (the
  noise's part, first order: :func:`lpvid.trust.silent.seen_covariance`,
  narrowed along its leading directions where V_NLS rises faster than
  first order says: :func:`lpvid.trust.profile.checked_band`) plus the
  committee's disagreement (:mod:`lpvid.pipeline.fewpoints`: the
  distances from the returned model's FRF to the FRFs of the other fits
  within the noise of the routes whose choices competed), two parts of
  different origin added. Where the points leave the returned structure
  open, the committee shows what the data leave to the prior, and its part
  is the largest distance. Where they determine it, the band is the
  noise's part of that structure, the other fits are votes that the
  choice among the routes has weighed already, and the committee's part
  is their median distance: one far fit is one vote. (On the benchmark of
  ``benches/bench_few.py`` the median there, not the largest, put the
  spread within ten times the actual error in more draws at six to eight
  points, with the same coverage of the truth.) The fits counted are
  those whose frozen models are stable between the points when there are
  any (:attr:`Between.voters`), as in the consensus that chose the model:
  a fit unstable between the points is no account of a system measured
  stable at them. (On ``bench_few.py``'s 160 draws of two systems at three
  to six points, and on 160 fresh ones, it put the spread within ten times
  the actual error in 6 more draws of each set, and covered the truth at
  nine in ten lines and points in 1 and 2 fewer; ``crossing_lpv(2)`` at
  six to eight points the same.)

:func:`lpvid.resampled` replaces that spread by one that measures the
pipeline itself: the models of runs of :func:`lpvid.identify` on data
simulated from the returned model (:attr:`Between.resampled`), the spread
:data:`RESAMPLED_SCALE` times the median distance from it of these models
and the committee's voters together (:mod:`lpvid.pipeline.resample`): the
runs say what the pipeline returns on data like these, the committee what
these data allow, and either alone misses where the other sees.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import real_array
from lpvid._threads import single_blas
from lpvid.data.frf import FrfData
from lpvid.model.lpv import LpvModel
from lpvid.trust.profile import BandCheck, checked_band
from lpvid.trust.silent import SilentCount, openness, range_grid
from lpvid.trust.uncertainty import Covariance, band_radius

__all__ = ["RESAMPLED_SCALE", "Between", "Member"]

#: The spread from resampling (:attr:`Between.resampled`) is this many times
#: the median distance from the model returned, entry by entry, of the
#: resampled models and the run's own fits within the noise
#: (:attr:`Between.voters`) together. Measured, not derived (2.1 to 2.9
#: times the median make a 95 % point of a Gaussian distance, but neither
#: kind of fit is a draw around the truth): on ``benches/bench_few.py``'s
#: draws (``docs/fewpoints.md``) 4, 5 and 6 put the spread within ten times
#: the actual error in at least 86, 88 and 85 % of the draws of each of the
#: three cases it was chosen on, 3 in 79 %; 5 then measured on fresh draws.
RESAMPLED_SCALE = 5.0


@dataclass(frozen=True, eq=False)
class Member:
    """A fit of the committee: an entry of one route's path.

    Attributes
    ----------
    route : int
        Index of its route.
    index : int
        Index of its entry on that route's path.
    name : str
        The route's start and the entry's gamma, e.g. ``"blocks:0, gamma 0.01"``.
    model : LpvModel
    vnls : float
    stable : bool
        Whether its frozen models are stable at and between the points.
    """

    route: int
    index: int
    name: str
    model: LpvModel
    vnls: float
    stable: bool


@dataclass(eq=False)
class Between:
    """What the measured points leave open between them (module notes).

    The count and the band on the seen directions are computed when first
    asked for (:attr:`count`, :attr:`band`, :meth:`spread`, :meth:`summary`),
    not by :func:`lpvid.identify` (dense algebra of the size of the model's
    free parameters, over a grid of the range).

    Attributes
    ----------
    model : LpvModel
        The model :func:`lpvid.identify` returned.
    members : list of Member
        The other fits within the noise that the pipeline made (empty when
        it followed one route only).
    covariance : Covariance or None
        The returned model's covariance (every identifiable direction).
    data : FrfData or None
        The identification data.
    held : ndarray of bool or None
        The model's held parameters (fixed, and the dropped groups'); None:
        not counted.
    threshold : float
        Relative group magnitude at or below which a group counts as dropped.
    note : str
        Why the count cannot be made, when it cannot.
    resampled : list of LpvModel
        The models :func:`lpvid.resampled` identified on data simulated
        from :attr:`model` (empty until it ran): when there are any, the
        spread is :data:`RESAMPLED_SCALE` times the median distance of
        them and the :attr:`voters` together, not the band and the
        committee's.
    resampled_warned : list of str
        The first warning of each of those runs that warned (the summary
        says how many, and the first).
    """

    model: LpvModel
    members: list[Member] = field(default_factory=list)
    covariance: Covariance | None = None
    data: FrfData | None = field(default=None, repr=False)
    held: NDArray[np.bool_] | None = field(default=None, repr=False)
    threshold: float = 1e-6
    note: str = ""
    resampled: list[LpvModel] = field(default_factory=list, repr=False)
    resampled_warned: list[str] = field(default_factory=list, repr=False)

    @cached_property
    def _open(self) -> tuple[SilentCount, NDArray[np.float64]] | None:
        if self.note or self.data is None or self.held is None:
            return None
        return openness(self.model, self.data, self.held, threshold=self.threshold)

    @property
    def count(self) -> SilentCount | None:
        """Directions of the model's structure the points leave open (None: not counted)."""
        opened = self._open
        return None if opened is None else opened[0]

    @cached_property
    def _seen(self) -> Covariance | None:
        """:attr:`covariance` with its silent directions left out (None: not counted)."""
        opened, cov = self._open, self.covariance
        if opened is None or cov is None:
            return None
        count, theta = opened
        return replace(cov, theta=theta, n_unidentified=cov.n_unidentified + count.silent)

    @cached_property
    def _checked(self) -> tuple[Covariance | None, BandCheck | None]:
        seen = self._seen
        if seen is None or self.data is None or self.held is None:
            return self.covariance, None
        return checked_band(seen, self.data, self.held)

    @property
    def band(self) -> Covariance | None:
        """The covariance on the directions the points see, checked (the spread's band).

        :attr:`covariance` with its silent directions left out
        (:func:`lpvid.trust.silent.seen_covariance`), then narrowed along
        its leading directions where V_NLS rises faster than first order
        (:func:`lpvid.trust.profile.checked_band`, :attr:`check`);
        :attr:`covariance` itself when not counted.
        """
        return self._checked[0]

    @property
    def check(self) -> BandCheck | None:
        """What the band's check beyond first order found (None: not counted)."""
        return self._checked[1]

    @property
    def determined(self) -> bool | None:
        """Whether the points determine the structure between them (None: not counted)."""
        return None if self.count is None else self.count.determined

    @property
    def voters(self) -> list[Member]:
        """The members the spread's committee part counts (module notes).

        Those whose frozen models are stable between the points when there
        are any, as in the consensus (:func:`lpvid.pipeline.fewpoints.consensus`);
        else every member.
        """
        return [m for m in self.members if m.stable] or list(self.members)

    def spread(self, freqs_hz: ArrayLike, p: ArrayLike, level: float = 0.95) -> NDArray:
        """The spread around ``model.frf(freqs_hz, p)``: shape ``(M, F, l, r)`` (module notes).

        Entry by entry, the covariance's band of coverage ``level`` plus the
        largest distance to another fit within the noise (of :attr:`voters`),
        or their median distance where the points determine the structure
        (:attr:`determined`). With :attr:`resampled` models: instead
        :data:`RESAMPLED_SCALE` times the median distance of them and the
        voters together (:mod:`lpvid.pipeline.resample`; ``level`` is then
        not used).
        """
        return self._around(freqs_hz, p, level)[0]

    def relative_spread(self, freqs_hz: ArrayLike, p: ArrayLike) -> NDArray[np.float64]:
        """``||spread(p)|| / ||G(p)||`` at every scheduling value of ``p``: shape ``(M,)``.

        Frobenius norms over every line, output and input; ``G`` the
        returned model's frozen FRF.
        """
        s, G = self._around(freqs_hz, p, 0.95)
        num = np.linalg.norm(s.reshape(len(s), -1), axis=1)
        den = np.linalg.norm(G.reshape(len(G), -1), axis=1)
        return num / np.maximum(den, np.finfo(float).tiny)

    @single_blas
    def _around(self, freqs_hz: ArrayLike, p: ArrayLike, level: float) -> tuple[NDArray, NDArray]:
        """The spread (:meth:`spread`) and the model's frozen FRF it is around."""
        f = real_array(freqs_hz, "freqs_hz", ndim=(0, 1)).ravel()
        G = self.model.frf(f, p)
        fits = [*self.resampled, *(m.model for m in self.voters)]
        apart = [np.abs(m.frf(f, p) - G) for m in fits]
        if self.resampled:
            return RESAMPLED_SCALE * np.median(apart, axis=0), G
        band = np.zeros(G.shape)
        if self.band is not None:
            band = band_radius(level) * self.band.frf_std(f, p)
        far = np.zeros(G.shape)
        if apart and self.determined:
            far = np.median(apart, axis=0)
        else:
            for d in apart:
                far = np.maximum(far, d)
        return band + far, G

    def worst(self) -> tuple[float, NDArray[np.float64]]:
        """The largest relative spread over the range, and where.

        On the data's lines and the grid of :func:`lpvid.trust.silent.range_grid`:
        ``max_p ||spread(p)|| / ||G(p)||`` (Frobenius norms over every line,
        output and input) and the ``p`` of that maximum.
        """
        data = self.data
        if data is None:
            raise ValueError("between: has no data to take the range and lines from")
        grid = range_grid(self.model, data)
        rel = self.relative_spread(data.freqs_hz, grid)
        k = int(np.argmax(rel))
        return float(rel[k]), grid[k]

    def summary(self) -> str:
        """A few lines for people."""
        lines = []
        if self.count is not None:
            lines.append(f"between the points: {self.count.describe()}")
        else:
            lines.append(f"between the points: not counted ({self.note})")
        if self.members:
            routes = len({m.name.split(",")[0] for m in self.members})
            lines.append(
                f"  {len(self.members)} other fit(s) within the noise, from {routes} route(s); "
                + (
                    "the points determine the returned structure: the spread below adds "
                    "their median distance to its band"
                    if self.determined and not self.resampled
                    else "where they disagree with the model returned, the data are silent"
                )
            )
            left = len(self.members) - len(self.voters)
            if left:
                lines.append(
                    f"  {left} of them unstable between the points, left out of the "
                    "spread (as out of the choice)"
                )
        if self.resampled:
            warned = self.resampled_warned
            said = f"; {len(warned)} of those runs warned, the first: {warned[0]}" if warned else ""
            voters = len(self.voters)
            lines.append(
                f"  the spread below: {RESAMPLED_SCALE:g} times the median distance of the "
                f"{len(self.resampled)} models identified again on data simulated from the "
                "model returned (lpvid.resampled)"
                + (f" and of the {voters} other fit(s) counted above" if voters else "")
                + said
            )
        elif not self.members and self.determined is False:
            lines.append(
                "  no other fit within the noise was made (validation data judged, or one "
                "route only): the spread below is the noise's part on the directions the "
                "points see, not what the open ones allow"
            )
        if not self.resampled and self.determined is False:
            lines.append(
                "  a spread that measures what another run would return: "
                "lpvid.resampled(result) (identify again on data simulated from this model; "
                "lpvid fit --resample 5)"
            )
        check = None if self.resampled else self.check
        if check is not None and np.any(check.scales < 1.0):
            lines.append(f"  the band: {check.describe()}")
        if self.data is not None and (self.band is not None or self.members or self.resampled):
            rel, where = self.worst()
            at = ", ".join(f"{x:.4g}" for x in where)
            lines.append(
                f"  largest relative spread between the points {rel:.3g} (at p = {at}): "
                "measuring there would say most (lpvid.next_points)"
            )
        return "\n".join(lines)
