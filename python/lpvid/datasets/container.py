"""The built-in data-set object: data, suggested settings and the true system."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import real_array
from lpvid.data.basis import Basis
from lpvid.data.frf import FrfData, z_points
from lpvid.datasets.synthesis import Matrices, _frf, _sampled, _scalar

__all__ = ["Dataset"]


@dataclass(frozen=True)
class Dataset:
    """A built-in identification problem: data, suggested settings, the truth.

    Attributes
    ----------
    name : str
        Short name (``"gantry"``, ``"positioning_stage"``).
    description : str
        A few lines for reports: the system, the data, the noise.
    identification : FrfData
        Data at the identification points.
    validation : FrfData
        Data at scheduling values between the identification points, with
        the same lines, noise level and sample time.
    order : int
        Number of states of the true system (the order to identify).
    basis : Basis
        A suggested basis, normalised to the identification range.
    fixed : dict or None
        Suggested fixed parameters, e.g. ``{"D": True}`` when the true
        system has no feedthrough; None when everything is free.
    snr_db : float or None
        The signal-to-noise ratio the noise was drawn at; None for
        noise-free data.
    inputs, outputs : tuple of str
        Names and units of the inputs and outputs, for plots.
    scheduling : str
        Name and unit of the scheduling parameter.
    physics : callable
        ``physics(p) -> (A, B, C, D)``: the continuous-time physical model
        at a scheduling value, before sampling. Prefer :meth:`true_system`.

    """

    name: str
    description: str
    identification: FrfData
    validation: FrfData
    order: int
    basis: Basis
    fixed: dict[str, bool] | None
    snr_db: float | None
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    scheduling: str
    physics: Callable[[float], Matrices] = field(repr=False, compare=False)

    @property
    def Ts(self) -> float | None:
        """Sample time of the data in seconds; None for continuous time."""
        return self.identification.Ts

    def continuous_system(self, p: float) -> Matrices:
        """The continuous-time physical model frozen at ``p``.

        Parameters
        ----------
        p : float
            Scheduling value (any value where the physics makes sense, not
            only the data's points).

        Returns
        -------
        (A, B, C, D) : tuple of ndarray
            ``dx/dt = A x + B u``, ``y = C x + D u``.

        """
        return self.physics(_scalar(p))

    def true_system(self, p: float) -> Matrices:
        """The true frozen model at ``p`` in the time domain of the data.

        Parameters
        ----------
        p : float
            Scheduling value.

        Returns
        -------
        (A, B, C, D) : tuple of ndarray
            Discrete time when the data are: zero-order-hold sampling of
            :meth:`continuous_system` with ``Ts``, then all states scaled by
            one number so that ``||B|| = ||C||``. Continuous time: the
            physical model itself.

        """
        return _sampled(self.physics(_scalar(p)), self.Ts)

    def true_frf(self, p: ArrayLike, freqs_hz: ArrayLike | None = None) -> NDArray[np.complex128]:
        """Noise-free FRF of the true system.

        Parameters
        ----------
        p : float or array_like, shape (N,)
            Scheduling values.
        freqs_hz : array_like, optional
            Frequencies in Hz; default the data's lines.

        Returns
        -------
        ndarray, shape (N, F, l, r), complex

        """
        ps = real_array(p, "p", ndim=(0, 1)).ravel()
        f = self.identification.freqs_hz if freqs_hz is None else freqs_hz
        f = real_array(f, "freqs_hz", ndim=(0, 1)).ravel()
        z = z_points(f, self.Ts)
        return np.stack([_frf(self.true_system(float(pq)), z) for pq in ps])

    def resonances_hz(self, p: float) -> NDArray[np.float64]:
        """Natural frequencies of the lightly damped modes at ``p``, ascending.

        The undamped natural frequencies ``|lambda| / (2 pi)`` of the poles
        of :meth:`continuous_system` with damping ratio below 0.3 and
        positive imaginary part.

        Parameters
        ----------
        p : float
            Scheduling value.

        Returns
        -------
        ndarray of float
            Frequencies in Hz.

        """
        lam = np.linalg.eigvals(self.continuous_system(p)[0])
        lam = lam[lam.imag > 0]
        light = lam[-lam.real / np.abs(lam) < 0.3]
        return np.sort(np.abs(light)) / (2 * np.pi)


def _ranges(ds: Dataset) -> str:
    """The resonances at both ends of the identification range, for a description.

    Parameters
    ----------
    ds : Dataset
        A built-in data set.

    Returns
    -------
    str
        ``"lo -> hi"`` in Hz for each lightly damped mode, comma separated.
    """
    lo = ds.resonances_hz(ds.identification.p_range[0])
    hi = ds.resonances_hz(ds.identification.p_range[1])
    return ", ".join(f"{a:.0f} -> {b:.0f}" for a, b in zip(lo, hi, strict=True))
