"""Basis functions psi_1..psi_Nb of the scheduling dependency (method.md (2)).

A basis maps scheduling values ``p`` (shape ``(N,)`` or ``(N, Np)``) to the
``(N, Nb)`` array of ``psi_i(p[q])``. The constant ``psi_0 = 1`` is implicit.

The polynomial bases take every parameter on a scale (``scale="linear"``,
the default, or ``"log"``): on the log scale ``log10(p)``, not ``p``, is
mapped affinely to [-1, 1], so that a variable spanning decades is followed
by a low degree. The model applies the scale itself: everything takes
``p`` in the user's units.
"""

from __future__ import annotations

import itertools
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.polynomial import legendre as npleg
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import positive_int, real_array
from lpvid.data.schedule import check_positive, range_pairs, scale_grid, scale_list

__all__ = ["Basis", "Polynomial", "Legendre", "CustomBasis", "basis_from_dict"]

Domain = tuple[float, float]

#: Ranges whose sup norms a polynomial basis keeps (see ``_ScaledBasis.sup_norms``).
_SUP_KEPT = 64


def _domains(domain: Any, n_params: int | None, required: bool) -> list[Domain] | None:
    """Normalise ``domain`` to a list of (lo, hi) pairs, one per parameter."""
    if domain is None:
        if required:
            raise ValueError("domain: required, e.g. domain=(p_min, p_max)")
        return None
    return range_pairs(domain, n_params, "domain")


def _exponents(degree: int, n_params: int) -> list[tuple[int, ...]]:
    """Multi-indices of total degree 1..degree, graded, then lexicographic (descending)."""
    out: list[tuple[int, ...]] = []
    for total in range(1, degree + 1):
        level = [e for e in itertools.product(range(total + 1), repeat=n_params) if sum(e) == total]
        out.extend(sorted(level, reverse=True))
    return out


class Basis(ABC):
    """A set of basis functions ``psi_1..psi_Nb`` of the scheduling parameters."""

    #: Number of scheduling parameters the basis takes.
    n_params: int = 1

    @property
    @abstractmethod
    def names(self) -> list[str]:
        """Readable name of each function, e.g. ``["s", "s^2"]``."""

    @abstractmethod
    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        """Values at ``p`` of shape ``(N, Np)``, as ``(N, Nb)``."""

    def __len__(self) -> int:
        return len(self.names)

    @property
    def scales(self) -> tuple[str, ...]:
        """The scale of every scheduling parameter: ``"linear"`` unless the basis says otherwise."""
        return ("linear",) * self.n_params

    def _points(self, p: ArrayLike, name: str = "p") -> NDArray[np.float64]:
        arr = real_array(p, name, ndim=(0, 1, 2))
        if arr.ndim == 0:
            arr = arr.reshape(1, 1)
        elif arr.ndim == 1:
            arr = arr[:, None] if self.n_params == 1 else arr[None, :]
        if arr.shape[1] != self.n_params:
            raise ValueError(
                f"{name}: the basis takes {self.n_params} scheduling parameter(s), "
                f"got {arr.shape[1]} per point"
            )
        return arr

    def __call__(self, p: ArrayLike) -> NDArray[np.float64]:
        """Evaluate the basis.

        Parameters
        ----------
        p : array_like, shape (N,) or (N, Np)
            Scheduling values (a scalar is one point).

        Returns
        -------
        ndarray, shape (N, Nb)
            ``psi_i(p[q])`` in row ``q``, column ``i - 1``.

        """
        pts = self._points(p)
        out = np.asarray(self._evaluate(pts), dtype=np.float64)
        if out.shape != (pts.shape[0], len(self)):
            raise ValueError(
                f"basis: expected values of shape {(pts.shape[0], len(self))}, got {out.shape}"
            )
        return out

    def sup_norms(self, p_range: Any) -> NDArray[np.float64]:
        """Largest ``|psi_i(p)|`` over a scheduling range (method.md (25)).

        Parameters
        ----------
        p_range : (lo, hi) or sequence of (lo, hi)
            The scheduling range, one pair per parameter.

        Returns
        -------
        ndarray, shape (Nb,)
            ``||psi_i||_inf`` over the box, from a grid that contains its
            corners (exact for the polynomial bases).

        """
        box = _domains(p_range, self.n_params, required=True)
        assert box is not None
        values = self(self._sup_points(box))
        if not np.all(np.isfinite(values)):
            raise ValueError("basis: a basis function is not finite on the scheduling range")
        return np.max(np.abs(values), axis=0)

    def _sup_points(self, box: list[Domain]) -> NDArray[np.float64]:
        """Where :meth:`sup_norms` looks in ``box``: a grid even on every scale, corners in."""
        per_axis = {1: 2001, 2: 101}.get(self.n_params, 11)
        return scale_grid(box, per_axis, self.scales)

    @abstractmethod
    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready description from which :func:`basis_from_dict` rebuilds the basis."""

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Basis):
            return NotImplemented
        try:
            return self.to_dict() == other.to_dict()
        except TypeError:
            return self is other

    def __hash__(self) -> int:
        return id(self)


class _ScaledBasis(Basis):
    """Shared machinery of the polynomial bases: affine scaling and multi-indices."""

    kind = ""

    def __init__(
        self,
        degree: int,
        domain: Any,
        n_params: int | None,
        domain_required: bool,
        scale: str | Sequence[str] = "linear",
    ):
        self.degree = positive_int(degree, "degree", minimum=0)
        self.domain = _domains(domain, n_params, required=domain_required)
        if self.domain is not None:
            self.n_params = len(self.domain)
        elif n_params is None and isinstance(scale, (list, tuple)):
            self.n_params = positive_int(len(scale), "scale")  # one scale per parameter
        else:
            self.n_params = positive_int(1 if n_params is None else n_params, "n_params")
        self._scales = scale_list(scale, self.n_params)
        for k, (sc, (lo, hi)) in enumerate(zip(self._scales, self.domain or [], strict=False)):
            if sc == "log" and lo <= 0:
                which = "" if self.n_params == 1 else f" of parameter {k + 1}"
                raise ValueError(
                    f"domain: a log scale needs a range above zero; the range{which} "
                    f"({lo:g}, {hi:g}) reaches {lo:g} (take it on scale='linear')"
                )
        self._log = np.array([sc == "log" for sc in self._scales])
        # The domain on every parameter's scale, rows lo and hi.
        self._ends = None if self.domain is None else self.transform(np.array(self.domain).T)
        self.exponents = _exponents(self.degree, self.n_params)

    @property
    def scales(self) -> tuple[str, ...]:
        """The scale of every scheduling parameter, ``"linear"`` or ``"log"``."""
        return self._scales

    def _points(self, p: ArrayLike, name: str = "p") -> NDArray[np.float64]:
        arr = super()._points(p, name)
        check_positive(arr, self._scales, name)
        return arr

    def sup_norms(self, p_range: Any) -> NDArray[np.float64]:
        """Largest ``|psi_i(p)|`` over a scheduling range (method.md (25)).

        As :meth:`Basis.sup_norms`; a range that reaches zero or below on a
        parameter taken on the log scale is refused (naming ``p_range``).
        The answer for a range is kept and given again (as a new array).
        """
        box = _domains(p_range, self.n_params, required=True)
        assert box is not None
        key = tuple(box)
        known = self._sup_known.get(key)
        if known is None:
            check_positive(np.array(box).T, self._scales, "p_range")
            known = super().sup_norms(p_range)
            known.setflags(write=False)
            if len(self._sup_known) >= _SUP_KEPT:
                self._sup_known.clear()
            self._sup_known[key] = known
        return known.copy()

    @property
    def _sup_known(self) -> dict[tuple[Domain, ...], NDArray[np.float64]]:
        """The sup norms found so far, by range.

        A polynomial's do not change, and every model built checks its range
        by them (measured: the basis evaluated on the range for each fit's
        model took 0.014 s of the threads' time in a small ``identify``).
        """
        return self.__dict__.setdefault("_sup_norms", {})

    def __getstate__(self) -> dict[str, Any]:
        """The basis without the sup norms found so far (a copy finds them again)."""
        return {k: v for k, v in self.__dict__.items() if k != "_sup_norms"}

    def transform(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        """``p`` (N, Np) on every parameter's scale: ``log10(p)`` on the log scale, else ``p``."""
        if not self._log.any():
            return p
        check_positive(p, self._scales)
        return np.where(self._log, np.log10(np.where(self._log, p, 1.0)), p)

    def scale(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        """Map ``p`` (N, Np) to ``s``: on its scale, then affinely so the domain becomes [-1, 1]."""
        u = self.transform(p)
        if self._ends is None:
            return u
        lo, hi = self._ends
        return (2.0 * u - (lo + hi)) / (hi - lo)

    def _var(self, k: int) -> str:
        index = "" if self.n_params == 1 else str(k + 1)
        if self._scales[k] == "log":
            return f"s{index}(log p{index})" if self.domain is not None else f"log10(p{index})"
        return f"{'s' if self.domain is not None else 'p'}{index}"

    def to_dict(self) -> dict[str, Any]:
        """The description; ``"scale"`` only when a parameter is not on the linear scale."""
        out: dict[str, Any] = {
            "kind": self.kind,
            "degree": self.degree,
            "domain": None if self.domain is None else [list(d) for d in self.domain],
            "n_params": self.n_params,
        }
        if self._log.any():
            out["scale"] = list(self._scales)
        return out

    def __repr__(self) -> str:
        dom = (
            None if self.domain is None else (self.domain[0] if self.n_params == 1 else self.domain)
        )
        text = f"{type(self).__name__}({self.degree}, domain={dom}"
        if self._log.any():
            sc = self._scales[0] if len(set(self._scales)) == 1 else self._scales
            text += f", scale={sc!r}"
        return text + ")"


class Polynomial(_ScaledBasis):
    """Monomials ``psi_i(p) = s^i``, i = 1..degree, with ``s`` the scaled ``p``.

    ``s`` is ``p`` (or ``log10(p)`` on the log scale) mapped affinely from
    the domain to [-1, 1].

    Parameters
    ----------
    degree : int
        Highest power (0 gives no basis function: an LTI model).
    domain : (lo, hi) or sequence of (lo, hi), optional
        Scheduling range mapped affinely to ``s`` in [-1, 1]. Recommended:
        raw values such as p = 48 mm give p^4 = 5.3e6 and a badly scaled
        problem. None uses ``s = p`` (``log10(p)`` on the log scale) unchanged.
    n_params : int, optional
        Number of scheduling parameters when ``domain`` is None (default 1,
        or one per entry of a sequence ``scale``). With several parameters
        the basis holds every monomial of total degree 1..degree.
    scale : {"linear", "log"} or sequence of them, optional
        The scale of every parameter, or one per parameter: ``"log"`` maps
        ``log10(p)`` (not ``p``) from the log of the domain to [-1, 1], for
        a variable that spans decades. It needs a domain above zero, and
        scheduling values above zero wherever the basis is evaluated (a
        ValueError naming the argument otherwise). Default ``"linear"``.

    Examples
    --------
    >>> import lpvid
    >>> lpvid.Polynomial(2, domain=(0.0, 2.0))([0.0, 1.0, 2.0])
    array([[-1.,  1.],
           [ 0.,  0.],
           [ 1.,  1.]])
    >>> b = lpvid.Polynomial(2, domain=(0.1, 10.0), scale="log")
    >>> b([0.1, 1.0, 10.0]), b.names
    (array([[-1.,  1.],
           [ 0.,  0.],
           [ 1.,  1.]]), ['s(log p)', 's(log p)^2'])

    """

    kind = "polynomial"

    def __init__(
        self,
        degree: int,
        domain: Any = None,
        n_params: int | None = None,
        scale: str | Sequence[str] = "linear",
    ) -> None:
        super().__init__(degree, domain, n_params, domain_required=False, scale=scale)

    @property
    def names(self) -> list[str]:
        """Names such as ``s``, ``s^2``, ``s1*s2^2``, ``s(log p)^2`` or ``log10(p)^2``."""
        out = []
        for e in self.exponents:
            parts = [self._var(k) + (f"^{d}" if d > 1 else "") for k, d in enumerate(e) if d > 0]
            out.append("*".join(parts))
        return out

    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        s = self.scale(p)
        # Integer powers by repeated multiplication: a float ``**`` costs
        # about ten times more, which shows on long trajectories (simulate).
        powers = {1: s}
        for d in range(2, self.degree + 1):
            powers[d] = powers[d - 1] * s
        out = np.empty((p.shape[0], len(self.exponents)))
        for col, e in enumerate(self.exponents):
            factors = [powers[d][:, k] for k, d in enumerate(e) if d]
            out[:, col] = factors[0]
            for f in factors[1:]:
                out[:, col] *= f
        return out

    def _sup_points(self, box: list[Domain]) -> NDArray[np.float64]:
        """The corners of ``box``: each monomial is largest in size at one of them.

        ``|s^e|`` grows with every ``|s_k|``, and ``|s_k|`` is largest at an
        end of its axis (``s`` is affine in ``p``). The grid of
        :class:`Basis` holds the corners and finds the same values bit for
        bit (``tests/test_basis.py``), at 2001 evaluations a parameter
        where these are 2: ``LpvModel`` checks its range this way at every
        construction.
        """
        return scale_grid(box, 2)


class Legendre(_ScaledBasis):
    """Legendre polynomials ``psi_i(p) = P_i(s)``, i = 1..degree, on the scaled ``p``.

    Better conditioned than monomials for high degrees. With several
    parameters the basis holds the products ``P_a(s1) P_b(s2) ...`` of total
    degree 1..degree.

    Parameters
    ----------
    degree : int
        Highest degree.
    domain : (lo, hi) or sequence of (lo, hi)
        Scheduling range mapped to [-1, 1] (required).
    scale : {"linear", "log"} or sequence of them, optional
        The scale of every parameter, or one per parameter, as in
        :class:`Polynomial`.

    """

    kind = "legendre"

    def __init__(self, degree: int, domain: Any, scale: str | Sequence[str] = "linear") -> None:
        super().__init__(degree, domain, None, domain_required=True, scale=scale)

    @property
    def names(self) -> list[str]:
        """Names such as ``P1(s)``, ``P1(s1)*P2(s2)`` or ``P2(s(log p))``."""
        out = []
        for e in self.exponents:
            parts = [f"P{d}({self._var(k)})" for k, d in enumerate(e) if d > 0]
            out.append("*".join(parts))
        return out

    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        s = self.scale(p)
        cols = []
        for e in self.exponents:
            col = np.ones(p.shape[0])
            for k, d in enumerate(e):
                if d:
                    col = col * npleg.legval(s[:, k], np.eye(d + 1)[d])
            cols.append(col)
        return np.stack(cols, axis=1) if cols else np.zeros((p.shape[0], 0))


class CustomBasis(Basis):
    """Basis functions given as Python callables.

    Parameters
    ----------
    funcs : sequence of callable
        Each maps scheduling values (shape ``(N,)`` for one parameter,
        ``(N, Np)`` for several) to ``N`` real values.
    names : sequence of str, optional
        Names for tables and plots; default ``f1, f2, ...``.
    n_params : int, optional
        Number of scheduling parameters (default 1).

    Notes
    -----
    A model with a custom basis cannot be saved to a file, since the
    functions are Python code.

    """

    kind = "custom"

    def __init__(
        self,
        funcs: Sequence[Callable[[NDArray[np.float64]], ArrayLike]],
        names: Sequence[str] | None = None,
        n_params: int = 1,
    ) -> None:
        funcs = list(funcs)
        if not all(callable(f) for f in funcs):
            raise TypeError("funcs: every entry must be callable")
        self.funcs = funcs
        self.n_params = positive_int(n_params, "n_params")
        if names is None:
            names = [getattr(f, "__name__", "") or f"f{k + 1}" for k, f in enumerate(funcs)]
            names = [n if n != "<lambda>" else f"f{k + 1}" for k, n in enumerate(names)]
        names = [str(n) for n in names]
        if len(names) != len(funcs):
            raise ValueError(f"names: {len(names)} names for {len(funcs)} functions")
        self._names = names

    @property
    def names(self) -> list[str]:
        """The names given (or ``f1, f2, ...``)."""
        return list(self._names)

    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        arg = p[:, 0] if self.n_params == 1 else p
        cols = []
        for name, f in zip(self._names, self.funcs, strict=True):
            v = np.asarray(f(arg), dtype=np.float64)
            v = np.broadcast_to(v, (p.shape[0],)) if v.ndim == 0 else v.reshape(-1)
            if v.shape != (p.shape[0],):
                raise ValueError(
                    f"basis: function {name} returned {v.shape[0]} values for {p.shape[0]} points"
                )
            cols.append(v)
        return np.stack(cols, axis=1) if cols else np.zeros((p.shape[0], 0))

    def to_dict(self) -> dict[str, Any]:
        """Refuse: the functions are Python code, which no file can hold."""
        raise TypeError(
            "CustomBasis holds Python functions, which cannot be written to a file; "
            "use Polynomial or Legendre to save the model"
        )

    def __repr__(self) -> str:
        return f"CustomBasis({self._names})"


def basis_from_dict(d: dict[str, Any]) -> Basis:
    """Rebuild a basis from :meth:`Basis.to_dict`.

    Parameters
    ----------
    d : dict
        The description.

    Returns
    -------
    Basis

    """
    kind = d.get("kind")
    scale = d.get("scale", "linear")  # written only when a parameter is not linear
    if kind == "polynomial":
        return Polynomial(d["degree"], d.get("domain"), n_params=d.get("n_params"), scale=scale)
    if kind == "legendre":
        return Legendre(d["degree"], d["domain"], scale=scale)
    raise ValueError(f"basis: unknown kind {kind!r}")
