"""Time records of a system along a varying scheduling trajectory (global data)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import positive_float, positive_int, real_array
from lpvid.data.schedule import scheduling_range

__all__ = ["TimeData"]


def _is_records(value: Any) -> bool:
    """Whether ``value`` is a list or tuple of arrays: one array per record."""
    return (
        isinstance(value, (list, tuple))
        and len(value) > 0
        and all(isinstance(v, np.ndarray) for v in value)
    )


def _columns(value: Any, name: str) -> NDArray[np.float64]:
    """A record's samples as ``(T, k)``: a 1-D array is one column."""
    arr = real_array(value, name, ndim=(1, 2))
    if arr.shape[0] == 0:
        raise ValueError(f"{name}: needs at least one sample")
    arr = arr[:, None] if arr.ndim == 1 else arr
    if arr.shape[1] == 0:
        raise ValueError(f"{name}: needs at least one column, got shape {arr.shape}")
    return arr


def _sigma(value: Any, name: str, t_len: int, l: int) -> NDArray[np.float64]:
    """Standard deviations of one record as ``(T, l)``."""
    s = real_array(value, name, ndim=(0, 1, 2))
    if s.ndim == 0:
        s = np.full((t_len, l), float(s))
    elif s.ndim == 1 and s.size == l:
        s = np.broadcast_to(s, (t_len, l)).copy()
    elif s.ndim == 1 and l == 1 and s.size == t_len:
        s = s[:, None]
    if s.shape != (t_len, l):
        raise ValueError(
            f"{name}: expected one number, one per output ({l},) or one per sample "
            f"({t_len}, {l}), got shape {s.shape}"
        )
    if np.any(s <= 0):
        raise ValueError(f"{name}: standard deviations must be > 0 everywhere")
    return s


class TimeData:
    """Time records of a system along a scheduling trajectory ``p(t)``.

    Each record holds the inputs ``u(t)``, the scheduling values ``p(t)``
    and the measured outputs ``y(t)`` at ``T`` samples ``dt`` seconds apart,
    with the standard deviation ``sigma`` of the output noise. Unlike
    :class:`lpvid.FrfData` (frozen scheduling values), these data see how
    the system responds while ``p`` moves: they tell apart LPV models that
    agree at every frozen ``p``.

    Parameters
    ----------
    u : array_like, shape (T, r) or (T,) for one input
        Inputs. Several records: a list (or tuple) of arrays, one per record.
    p : array_like, shape (T,) or (T, Np)
        Scheduling values at every sample (a list for several records).
    y : array_like, shape (T, l) or (T,) for one output
        Measured outputs (a list for several records).
    dt : float
        Sample time in seconds. A discrete-time model must run at this
        sample time; a continuous-time model is simulated with ``u`` and
        ``p`` held over each sample (zero-order hold).
    sigma : float or array_like, optional
        Standard deviation of the output noise: one number, one per output
        (shape ``(l,)``), or one per sample (the shape of ``y``; a list for
        several records). Default 1, which makes the cost a plain sum of
        squares.

    Attributes
    ----------
    u, p, y, sigma : list of ndarray
        Per record: ``u`` as ``(T, r)``, ``p`` as given (``(T,)`` or
        ``(T, Np)``), ``y`` and ``sigma`` as ``(T, l)``. Read-only.
    dt : float

    Raises
    ------
    ValueError, TypeError
        When lengths or widths disagree (within a record or between
        records), a value is NaN or Inf, sigma is not positive, or the
        records are given as lists for some arguments and not others. The
        message names the argument (and the record: ``u[1]``).

    Examples
    --------
    >>> import numpy as np, lpvid
    >>> t = np.arange(200) * 1e-3
    >>> td = lpvid.TimeData(np.sin(50 * t), 0.5 + 0.5 * np.sin(3 * t), np.zeros((200, 2)),
    ...                     dt=1e-3, sigma=[0.01, 0.02])
    >>> td.n_records, td.n_inputs, td.n_outputs, td.n_residuals
    (1, 1, 2, 400)

    """

    def __init__(
        self,
        u: ArrayLike | Sequence[ArrayLike],
        p: ArrayLike | Sequence[ArrayLike],
        y: ArrayLike | Sequence[ArrayLike],
        dt: float,
        sigma: ArrayLike | Sequence[ArrayLike] | float | None = None,
    ) -> None:
        self.dt = positive_float(dt, "dt")
        several = [_is_records(v) for v in (u, p, y)]
        if any(several) and not all(several):
            names = ", ".join(n for n, s in zip(("u", "p", "y"), several, strict=True) if not s)
            raise TypeError(
                f"{names}: several records are given as lists of arrays (one per record) for "
                "some of u, p, y: give all three that way"
            )
        if all(several):
            us, ps, ys = list(u), list(p), list(y)  # type: ignore[arg-type]
            if not len(us) == len(ps) == len(ys):
                raise ValueError(
                    f"records: {len(us)} input, {len(ps)} scheduling and {len(ys)} output "
                    "records given"
                )
            tag = [f"[{k}]" for k in range(len(us))]
        else:
            us, ps, ys, tag = [u], [p], [y], [""]
        n_rec = len(us)
        if _is_records(sigma):
            sigmas = list(sigma)  # type: ignore[arg-type]
            if len(sigmas) != n_rec:
                raise ValueError(f"sigma: {len(sigmas)} arrays given for {n_rec} records")
        else:
            sigmas = [1.0 if sigma is None else sigma] * n_rec
        self.u: list[NDArray[np.float64]] = []
        self.p: list[NDArray[np.float64]] = []
        self.y: list[NDArray[np.float64]] = []
        self.sigma: list[NDArray[np.float64]] = []
        for k in range(n_rec):
            uk = _columns(us[k], f"u{tag[k]}")
            yk = _columns(ys[k], f"y{tag[k]}")
            pk = real_array(ps[k], f"p{tag[k]}", ndim=(1, 2))
            t_len = uk.shape[0]
            for name, arr in ((f"p{tag[k]}", pk), (f"y{tag[k]}", yk)):
                if arr.shape[0] != t_len:
                    raise ValueError(
                        f"{name}: expected one row per sample of u{tag[k]} (T={t_len}), "
                        f"got {arr.shape[0]}"
                    )
            if pk.ndim == 2 and pk.shape[1] == 0:
                raise ValueError(f"p{tag[k]}: needs at least one scheduling parameter")
            if k > 0:
                first = (self.u[0].shape[1], self.y[0].shape[1], self._n_params(self.p[0]))
                here = (uk.shape[1], yk.shape[1], self._n_params(pk))
                if here != first:
                    raise ValueError(
                        f"records: record {k} has {here[0]} inputs, {here[1]} outputs and "
                        f"{here[2]} scheduling parameters, record 0 {first[0]}, {first[1]} "
                        f"and {first[2]}"
                    )
            sk = _sigma(sigmas[k], f"sigma{tag[k]}", t_len, yk.shape[1])
            for arr in (uk, pk, yk, sk):
                arr.setflags(write=False)
            self.u.append(uk)
            self.p.append(pk)
            self.y.append(yk)
            self.sigma.append(sk)

    @staticmethod
    def _n_params(p: NDArray[np.float64]) -> int:
        return 1 if p.ndim == 1 else int(p.shape[1])

    # ------------------------------------------------------------------ sizes
    @property
    def n_records(self) -> int:
        """Number of records."""
        return len(self.u)

    @property
    def n_inputs(self) -> int:
        """Number of inputs r."""
        return int(self.u[0].shape[1])

    @property
    def n_outputs(self) -> int:
        """Number of outputs l."""
        return int(self.y[0].shape[1])

    @property
    def n_params(self) -> int:
        """Number of scheduling parameters Np."""
        return self._n_params(self.p[0])

    @property
    def n_samples(self) -> list[int]:
        """Number of samples T of every record."""
        return [int(u.shape[0]) for u in self.u]

    @property
    def n_residuals(self) -> int:
        """Number of real residuals ``sum T l``: the noise floor of the output error.

        With ``skip`` samples left out of a fit (:func:`lpvid.fit_time`), the
        floor is ``sum (T - skip) l``.
        """
        return sum(self.n_samples) * self.n_outputs

    @property
    def p_range(self) -> Any:
        """The scheduling range the records visit, in lpvid's convention."""
        if self.n_params == 1:
            return scheduling_range(np.concatenate([p.ravel() for p in self.p]))
        return scheduling_range(np.concatenate(self.p))

    def record(self, k: int) -> TimeData:
        """Record ``k`` alone, as a TimeData."""
        k = positive_int(k, "k", minimum=0)
        if k >= self.n_records:
            raise ValueError(f"k: expected a record index < {self.n_records}, got {k}")
        return TimeData(self.u[k], self.p[k], self.y[k], self.dt, self.sigma[k])

    def __repr__(self) -> str:
        return (
            f"TimeData({self.n_records} record(s) of {self.n_samples} samples, dt={self.dt:g} s, "
            f"{self.n_inputs} inputs, {self.n_outputs} outputs, {self.n_params} scheduling "
            "parameter(s))"
        )
