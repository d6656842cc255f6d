"""The LPV state-space model (method.md (1)-(5))."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid import _core
from lpvid._checks import real_array, sample_time
from lpvid.data.basis import Basis, Polynomial
from lpvid.data.frf import z_points
from lpvid.model import _simulate, handoff
from lpvid.model import file as modelfile
from lpvid.model._view import model_view
from lpvid.model.groups import GroupNorms, group_norms

__all__ = ["LpvModel"]


def _coefficients(value: Any, name: str, n_coef: int | None) -> NDArray[np.float64]:
    arr = real_array(value, name, ndim=(2, 3))
    if arr.ndim == 2:
        arr = arr[None]
    if n_coef is not None and arr.shape[0] != n_coef:
        raise ValueError(
            f"{name}: expected {n_coef} coefficient matrices (Nb+1 for a basis of "
            f"{n_coef - 1} functions), got {arr.shape[0]}"
        )
    return arr


class LpvModel:
    r"""A linear parameter-varying state-space model.

    Discrete time (``Ts`` given)::

        x(t+1) = A(p) x(t) + B(p) u(t)
        y(t)   = C(p) x(t) + D(p) u(t)

    or continuous time (``Ts=None``) with ``dx/dt`` on the left, where every
    matrix depends on the scheduling through the basis::

        X(p) = X(0) + sum_{i=1..Nb} X(i) psi_i(p),   X in {A, B, C, D}.

    Parameters
    ----------
    A : array_like, shape (Nb+1, n, n)
        Coefficient matrices of A; index 0 is the constant part. A 2-D array
        is an LTI model (Nb = 0).
    B : array_like, shape (Nb+1, n, r)
    C : array_like, shape (Nb+1, l, n)
    D : array_like, shape (Nb+1, l, r), optional
        Default zero.
    basis : Basis, optional
        The functions psi_1..psi_Nb; None means no scheduling dependency.
    Ts : float, optional
        Sample time in seconds, None for continuous time.
    p_range : (lo, hi) or sequence of (lo, hi), optional
        The scheduling range the model is meant for; used by
        :meth:`group_norms` for ``||psi_i||_inf``. Defaults to the basis
        domain when it has one.
    info : dict, optional
        Free-form, JSON-ready notes on how the model was obtained (for
        example the coherent form SMILE used); saved with the model.

    Examples
    --------
    >>> import numpy as np, lpvid
    >>> basis = lpvid.Polynomial(1, domain=(0.0, 1.0))
    >>> A = np.array([[[0.5]], [[0.1]]]); B = np.ones((2, 1, 1)); C = np.ones((2, 1, 1))
    >>> m = lpvid.LpvModel(A, B, C, basis=basis, Ts=1.0)
    >>> m.at(1.0)[0]
    array([[0.6]])

    """

    def __init__(
        self,
        A: ArrayLike,
        B: ArrayLike,
        C: ArrayLike,
        D: ArrayLike | None = None,
        basis: Basis | None = None,
        Ts: float | None = None,
        p_range: Any = None,
        info: dict[str, Any] | None = None,
    ) -> None:
        if basis is None:
            basis = Polynomial(0)
        if not isinstance(basis, Basis):
            raise TypeError(f"basis: expected an lpvid basis, got {type(basis).__name__}")
        n_coef = len(basis) + 1
        a = _coefficients(A, "A", n_coef)
        b = _coefficients(B, "B", n_coef)
        c = _coefficients(C, "C", n_coef)
        n = a.shape[1]
        if n == 0 or a.shape[2] != n:
            raise ValueError(f"A: expected square matrices, got shape {a.shape}")
        if b.shape[1] != n or b.shape[2] == 0:
            raise ValueError(f"B: expected shape (Nb+1, {n}, r) with r >= 1, got {b.shape}")
        if c.shape[2] != n or c.shape[1] == 0:
            raise ValueError(f"C: expected shape (Nb+1, l, {n}) with l >= 1, got {c.shape}")
        r, l = b.shape[2], c.shape[1]
        d = np.zeros((n_coef, l, r)) if D is None else _coefficients(D, "D", n_coef)
        if d.shape[1:] != (l, r):
            raise ValueError(f"D: expected shape (Nb+1, {l}, {r}), got {d.shape}")
        self.A, self.B, self.C, self.D = a, b, c, d
        for arr in (a, b, c, d):
            arr.setflags(write=False)
        self.basis = basis
        self.Ts = sample_time(Ts)
        if p_range is None and getattr(basis, "domain", None) is not None:
            dom = basis.domain  # type: ignore[attr-defined]
            p_range = dom[0] if len(dom) == 1 else dom
        if p_range is not None:
            p_range = np.asarray(real_array(p_range, "p_range")).tolist()
            basis.sup_norms(p_range)  # validates the range
        self.p_range = p_range
        if info is not None and not isinstance(info, dict):
            raise TypeError(f"info: expected a dict, got {type(info).__name__}")
        self.info: dict[str, Any] = dict(info or {})

    # ------------------------------------------------------------------ sizes
    @property
    def n_states(self) -> int:
        """Number of states n."""
        return int(self.A.shape[1])

    @property
    def n_inputs(self) -> int:
        """Number of inputs r."""
        return int(self.B.shape[2])

    @property
    def n_outputs(self) -> int:
        """Number of outputs l."""
        return int(self.C.shape[1])

    @property
    def n_basis(self) -> int:
        """Number of basis functions Nb."""
        return len(self.basis)

    @property
    def shape(self) -> tuple[int, int, int, int]:
        """``(n, r, l, Nb)``."""
        return self.n_states, self.n_inputs, self.n_outputs, self.n_basis

    def matrices(self) -> dict[str, NDArray[np.float64]]:
        """The coefficient arrays by name, ``{"A": A, "B": B, "C": C, "D": D}``."""
        return {"A": self.A, "B": self.B, "C": self.C, "D": self.D}

    # ------------------------------------------------------------------ theta
    @property
    def theta(self) -> NDArray[np.float64]:
        """Flat parameter vector ``[theta_A; theta_B; theta_C; theta_D]``.

        ``theta_X = [vec X(0); ...; vec X(Nb)]`` with column-major ``vec``
        (method.md (3)-(5)).
        """
        return np.concatenate([x.transpose(0, 2, 1).ravel() for x in self.matrices().values()])

    def with_theta(self, theta: ArrayLike) -> LpvModel:
        """Return a model of the same structure with other parameters.

        Parameters
        ----------
        theta : array_like
            Parameter vector in the layout of :attr:`theta`.

        Returns
        -------
        LpvModel

        """
        t = real_array(theta, "theta", ndim=1)
        size = sum(x.size for x in self.matrices().values())
        if t.size != size:
            raise ValueError(f"theta: expected {size} parameters, got {t.size}")
        # Built without the constructor's checks, which these pass by
        # construction: finite C-ordered float64 arrays of this model's
        # shapes, a range already checked against the basis. The fits build
        # a model for every result (measured: the checks again took 0.017 s
        # of the threads' time in a small ``identify``).
        model = object.__new__(LpvModel)
        start = 0
        for name, x in self.matrices().items():
            k, rows, cols = x.shape
            part = t[start : start + x.size].reshape(k, cols, rows).transpose(0, 2, 1)
            arr = np.array(part, order="C")
            arr.setflags(write=False)
            setattr(model, name, arr)
            start += x.size
        model.basis, model.Ts, model.p_range = self.basis, self.Ts, self.p_range
        model.info = {}
        return model

    # -------------------------------------------------------------- evaluation
    def basis_values(self, p: ArrayLike) -> NDArray[np.float64]:
        """``psi_1..psi_Nb`` at ``p`` as ``(N, Nb)``, checked to be finite."""
        values = self.basis(p)
        if not np.all(np.isfinite(values)):
            raise ValueError("basis: a basis function is not finite at the given scheduling values")
        return values

    def at(self, p: ArrayLike) -> tuple[NDArray[np.float64], ...]:
        """The frozen LTI matrices at one scheduling value.

        Parameters
        ----------
        p : float or array_like of shape (Np,)
            One scheduling value.

        Returns
        -------
        (A, B, C, D) : tuple of ndarray

        """
        psi = self.basis_values(p)
        if psi.shape[0] != 1:
            raise ValueError("p: expected a single scheduling value")
        w = np.concatenate([[1.0], psi[0]])
        return tuple(np.tensordot(w, x, axes=1) for x in self.matrices().values())

    def frf(self, freqs_hz: ArrayLike, p: ArrayLike) -> NDArray[np.complex128]:
        """Frequency response at frozen scheduling values.

        Parameters
        ----------
        freqs_hz : array_like, shape (F,)
            Frequencies in Hz.
        p : array_like, shape (N,) or (N, Np)
            Scheduling values.

        Returns
        -------
        ndarray, shape (N, F, l, r), complex
            ``C(p) (zI - A(p))^-1 B(p) + D(p)`` with ``z = exp(j w Ts)`` or ``j w``.

        Raises
        ------
        SingularModelError
            When a frozen model has a pole exactly at an evaluation point, or
            the response overflows (is not finite) at one; the message names
            the point and the frequency line.

        """
        f = real_array(freqs_hz, "freqs_hz", ndim=(0, 1)).ravel()
        psi = self.basis_values(p)
        _, r, l, _ = self.shape
        out = _core.frequency_response(model_view(self, psi), z_points(f, self.Ts))
        return out.reshape(psi.shape[0], f.size, l, r)

    def simulate(
        self,
        u: ArrayLike,
        p: ArrayLike,
        x0: ArrayLike | None = None,
        *,
        dt: float | None = None,
        return_states: bool = False,
        on_divergence: str = "warn",
    ) -> Any:
        """Simulate the model in time along a scheduling trajectory ``p(t)``.

        Discrete time (``Ts`` given), sample ``t = 0..T-1``::

            x(t+1) = A(p(t)) x(t) + B(p(t)) u(t)
            y(t)   = C(p(t)) x(t) + D(p(t)) u(t)

        Continuous time (``Ts`` None): ``u`` and ``p`` are held constant over
        each sample of ``dt`` seconds (zero-order hold) and the state
        equation is solved exactly over the sample, ``x(t+1) = Ad x(t) +
        Bd u(t)`` with ``[[Ad, Bd], [0, I]] = expm([[A, B], [0, 0]] dt)``
        and ``A``, ``B`` frozen at ``p(t)``; ``y(t)`` as above. At a constant
        ``p`` this is the usual ZOH discretisation of the frozen model (one
        matrix exponential per sample, so slower than discrete time).

        The recursion runs in the Rust core without the GIL; the basis is
        evaluated in Python at every ``p(t)``.

        Parameters
        ----------
        u : array_like, shape (T, r) or (T,) for one input
            Inputs.
        p : float or array_like, shape (T,) or (T, Np)
            Scheduling value at every sample (a single number for a constant
            ``p`` with one scheduling parameter).
        x0 : array_like, shape (n,), optional
            Initial state (default zero).
        dt : float, optional
            Sample time of ``u`` in seconds; required for a continuous-time
            model, and for a discrete-time one only allowed equal to ``Ts``.
        return_states : bool, optional
            Also return the states.
        on_divergence : {"warn", "raise"}, optional
            What happens when the simulation leaves the range of floating
            point (a model unstable along ``p(t)``): ``"warn"`` (default)
            returns the outputs as computed, Inf or NaN from that sample on,
            with a ``RuntimeWarning`` that names the first sample whose
            output (or returned state) is not finite and the scheduling
            value there; ``"raise"`` raises a ``ValueError`` with the same
            message instead.

        Returns
        -------
        y : ndarray, shape (T, l)
            Outputs.
        x : ndarray, shape (T + 1, n)
            Only with ``return_states``: ``x[t]`` is the state at sample ``t``;
            the last row is the state after the last sample (pass it as
            ``x0`` to continue).

        Raises
        ------
        ValueError, TypeError
            When ``u`` has the wrong number of inputs, ``p`` the wrong
            length, ``x0`` the wrong size, ``dt`` is missing or inconsistent,
            a value is NaN or Inf, or the basis is not finite along ``p``;
            with ``on_divergence="raise"``, when the simulation diverges.

        Warns
        -----
        RuntimeWarning
            With ``on_divergence="warn"``, when the simulation diverges.

        Examples
        --------
        >>> import numpy as np, lpvid
        >>> m = lpvid.LpvModel([[0.5]], [[1.0]], [[1.0]], Ts=1.0)
        >>> m.simulate(np.ones(4), 0.0).ravel()
        array([0.  , 1.  , 1.5 , 1.75])

        """
        return _simulate.simulate(
            self,
            u,
            p,
            x0,
            dt=dt,
            return_states=return_states,
            on_divergence=on_divergence,
        )

    def poles(self, p: ArrayLike) -> NDArray[np.complex128]:
        """Eigenvalues of ``A(p)`` at one scheduling value."""
        return np.linalg.eigvals(self.at(p)[0])

    def group_norms(self, p_range: Any = None) -> GroupNorms:
        """Magnitudes of the groups ``theta_X(i)`` as in the paper's Tables 1-4.

        Parameters
        ----------
        p_range : (lo, hi) or sequence of (lo, hi), optional
            Scheduling range for ``||psi_i||_inf``; default :attr:`p_range`.

        Returns
        -------
        GroupNorms
            ``.absolute[X, i-1] = ||theta_X(i)||_2`` and ``.relative[X, i-1]
            = ||theta_X(i)|| ||psi_i||_inf / ||theta_X(0)||`` (or
            ``||theta_X(i)|| ||psi_i||_inf`` when ``X(0) = 0``); printing it
            gives the table.

        """
        return group_norms(self, p_range)

    # ------------------------------------------------------------------- files
    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the model to a file, whole or not at all.

        ``.json``: lpvid's versioned model file (see :mod:`lpvid.model.file`).
        ``.mat``: a MATLAB file with ``A`` as ``n x n x (Nb+1)`` (``A(:,:,1)``
        the constant part) and likewise ``B``, ``C``, ``D``, the basis and
        ``Ts``; lpvid reads it back exactly.

        Parameters
        ----------
        path : str or path-like
            Target file (``.json`` or ``.mat``).

        Returns
        -------
        pathlib.Path

        """
        return modelfile.save_model(self, path)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> LpvModel:
        """Read a model file: what :meth:`save` writes.

        A ``.mat`` file is read from its arrays (``A``, ``B``, ``C``, ``D``,
        ``Ts``, the basis variables, ``p_range``); when it holds lpvid's own
        copy of the model (``lpvid_model``, as :meth:`save` writes it), every
        array must equal that copy to the last bit (see :mod:`lpvid.model.file`).

        Raises
        ------
        ValueError
            When the file is damaged, of another format or of another
            version, or a ``.mat`` file's arrays differ from its embedded
            copy (the message names the variables that differ).

        """
        return modelfile.load_model(path, cls)

    def to_control(self, p: ArrayLike) -> Any:
        """The frozen model at ``p`` as a python-control ``StateSpace``.

        Needs the optional extra python-control (``pip install "lpvid[control]"``).

        Parameters
        ----------
        p : float or array_like of shape (Np,)
            One scheduling value.

        Returns
        -------
        control.StateSpace
            Discrete time with ``dt = Ts``, or continuous time.
        """
        try:
            import control
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ImportError(
                'to_control needs python-control: pip install "lpvid[control]"'
            ) from exc
        A, B, C, D = self.at(p)
        return control.ss(A, B, C, D, 0 if self.Ts is None else self.Ts)

    def to_control_lpv(self, names: Any = None, **options: Any) -> Any:
        """The LPV model as a python-control ``NonlinearIOSystem``, inputs ``u`` then ``p``.

        Discrete or continuous time as the model is; ``control.input_output_response``
        simulates it along ``p(t)`` and ``control.create_statefbk_iosystem(...,
        gainsched_indices=...)`` schedules a gain on it. Needs python-control
        (``pip install "lpvid[control]"``). ``names``: an FrfData read from
        files or a built-in data set, whose labels name the signals;
        ``options``: ``inputs``, ``outputs``, ``parameters``, ``full_state``,
        ``name`` (see :func:`lpvid.model.handoff.to_control_lpv`).
        """
        return handoff.to_control_lpv(self, names, **options)

    def save_grid(
        self, path: str | os.PathLike[str], grid: Any = None, names: Any = None, **options: Any
    ) -> Path:
        """Write the frozen A, B, C, D on a grid of scheduling values to a MATLAB file.

        MATLAB reads it without lpvid as a model array: ``s = load(path); sys
        = ss(s.A, s.B, s.C, s.D, s.Ts); sys.SamplingGrid = s.SamplingGrid``.
        Layout, ``grid`` (default 21 values per parameter over ``p_range``;
        ``count=`` sets the number), ``names`` and ``options``:
        :func:`lpvid.model.handoff.save_grid`.
        """
        return handoff.save_grid(self, path, grid, names, **options)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, LpvModel):
            return NotImplemented
        return (
            self.basis == other.basis
            and self.Ts == other.Ts
            and all(
                a.shape == b.shape and np.array_equal(a, b)
                for a, b in zip(self.matrices().values(), other.matrices().values(), strict=True)
            )
        )

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        n, r, l, nb = self.shape
        kind = "continuous time" if self.Ts is None else f"Ts={self.Ts:g} s"
        return f"LpvModel(n={n}, r={r}, l={l}, Nb={nb}, basis={self.basis!r}, {kind})"
