"""SMILE: interpolation of local LTI models in coherent coordinates (method.md 5, 5a).

State-space Model Interpolation of Local Estimates: bring the local models
to coherent state coordinates (:mod:`lpvid.initial.coherent`), then fit every matrix
entry over the basis functions by linear least squares. With N points and
N - 1 polynomial terms the interpolation is exact, so the LPV model
reproduces every local model.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import real_array
from lpvid._rows import unique_rows
from lpvid._threads import single_blas
from lpvid.data.basis import Basis
from lpvid.data.frf import z_points
from lpvid.data.schedule import model_range
from lpvid.fit.settings import FORMS
from lpvid.initial.coherent import (
    CoherenceError,
    balance,
    krylov_form,
    modal_form,
    pairwise_form,
)
from lpvid.initial.localmodels import LocalModels, local_p, lti_models
from lpvid.model.frozen import lti_frf
from lpvid.model.lpv import LpvModel

__all__ = ["FORMS", "smile", "smile_candidates"]


Ss = tuple[NDArray[np.float64], ...]


def _local_list(local_models: Any) -> tuple[list[Ss], float | None, LocalModels | None]:
    """The models as (A, B, C, D) tuples, their Ts, and the LocalModels (or None)."""
    models = lti_models(local_models)
    carrier = local_models if isinstance(local_models, LocalModels) else None
    mats = [tuple(x[0].copy() for x in m.matrices().values()) for m in models]
    return mats, models[0].Ts, carrier


def _check_p(arr: NDArray[np.float64], basis: Basis) -> NDArray[np.float64]:
    """Scheduling values as (N, Np), checked to be distinct and to fit the basis."""
    rows = arr.reshape(arr.shape[0], -1)
    _, first, counts = unique_rows(rows)
    if np.any(counts > 1):
        dup = rows[first[np.argmax(counts > 1)]]
        raise ValueError(f"p: scheduling values must be distinct (duplicate point {dup.tolist()})")
    pts = basis._points(arr)
    return pts


def _regressors(basis: Basis, p: NDArray[np.float64]) -> NDArray[np.float64]:
    """``[1, psi_1(p), ..., psi_Nb(p)]`` as (N, Nb+1), checked for rank."""
    psi = basis(p)
    if not np.all(np.isfinite(psi)):
        raise ValueError("basis: a basis function is not finite at the scheduling values")
    phi = np.concatenate([np.ones((p.shape[0], 1)), psi], axis=1)
    n, k = phi.shape
    if n < k:
        raise ValueError(
            f"p: {n} points cannot determine the {k} coefficients per entry of a basis of "
            f"{k - 1} functions plus the constant; give at least {k} points or a smaller basis"
        )
    s = np.linalg.svd(phi, compute_uv=False)
    if s[-1] <= 1e-12 * s[0]:
        raise ValueError(
            "basis: the basis functions are linearly dependent at these scheduling values "
            "(the interpolation is not unique)"
        )
    return phi


def _interpolate(
    models: list[Ss], phi: NDArray[np.float64]
) -> tuple[list[NDArray[np.float64]], dict[str, float]]:
    """Least-squares coefficients of every entry and the relative residual per matrix."""
    coefs, resid = [], {}
    total_r = total_x = 0.0
    for j, name in enumerate("ABCD"):
        X = np.stack([m[j] for m in models])  # (N, rows, cols)
        flat = X.reshape(X.shape[0], -1)
        c = np.linalg.lstsq(phi, flat, rcond=None)[0]
        r = float(np.linalg.norm(phi @ c - flat))
        x = float(np.linalg.norm(flat))
        resid[name] = r / x if x > 0 else 0.0
        total_r += r**2
        total_x += x**2
        coefs.append(c.reshape((phi.shape[1], *X.shape[1:])))
    resid["all"] = float(np.sqrt(total_r / total_x)) if total_x > 0 else 0.0
    return coefs, resid


def _default_freqs(models: list[Ss], Ts: float | None) -> NDArray[np.float64]:
    """A frequency grid covering the local models' poles (for leave-one-out checks)."""
    if Ts is not None:
        return np.linspace(0.0, 0.5 / Ts, 201)[1:-1]
    lam = np.concatenate([np.linalg.eigvals(m[0]) for m in models])
    w = np.abs(lam[np.abs(lam) > 0])
    if w.size == 0:
        return np.logspace(-2, 2, 200)
    return np.logspace(np.log10(w.min() / 3), np.log10(w.max() * 3), 200) / (2 * np.pi)


def _leave_one_out(
    form: str,
    models: list[Ss],
    phi: NDArray[np.float64],
    p: NDArray[np.float64],
    Ts: float | None,
    z: NDArray[np.complex128],
) -> float | None:
    """RMS relative FRF error at interior points predicted from the other points.

    Each interior point (not at the edge of the range in any parameter) is
    left out in turn: the other points alone are brought to the coherent
    form and interpolated with the first ``min(Nb, N - 2)`` basis functions,
    and the model at the left-out value is compared with the local model
    there (FRFs do not depend on state coordinates). Building the form
    without the left-out point matters: a form that aligns neighbours to each
    other would otherwise predict them deceptively well. None when no point
    is interior or a form cannot be built without one of them.
    """
    N, k = phi.shape
    interior = np.all((p > p.min(axis=0)) & (p < p.max(axis=0)), axis=1)
    if N < 3 or not np.any(interior):
        return None
    errs = []
    for q in np.flatnonzero(interior):
        keep = np.flatnonzero(np.arange(N) != q)
        cols = min(k, N - 1)
        sub = phi[keep][:, :cols]
        if np.linalg.matrix_rank(sub) < cols:
            continue
        try:
            coherent, _ = _coherent(form, [models[i] for i in keep], p[keep], Ts)
        except (CoherenceError, np.linalg.LinAlgError):
            return None
        coefs, _ = _interpolate(coherent, sub)
        pred = tuple(np.tensordot(phi[q, :cols], c, axes=1) for c in coefs)
        g_ref = lti_frf(*models[q], z)
        with np.errstate(all="ignore"):
            g = lti_frf(*pred, z)
        err = float(np.linalg.norm(g - g_ref) / np.linalg.norm(g_ref))
        errs.append(err if np.isfinite(err) else np.inf)
    if not errs:
        return None
    return float(np.sqrt(np.mean(np.square(errs))))


def _coherent(
    form: str, models: list[Ss], p: NDArray[np.float64], Ts: float | None
) -> tuple[list[Ss], dict[str, Any]]:
    if form in ("observability", "controllability"):
        return krylov_form(models, form)
    if form == "modal":
        return modal_form(models, p, Ts, norm="balanced")
    if form == "modal_input":
        return modal_form(models, p, Ts, norm="input")
    if form == "pairwise":
        return pairwise_form(models, p)
    raise ValueError(f"form: unknown coherent form {form!r}; choose from {FORMS} or 'auto'")


def _build(
    form: str,
    models: list[Ss],
    p: NDArray[np.float64],
    basis: Basis,
    phi: NDArray[np.float64],
    Ts: float | None,
    balanced: bool,
    z: NDArray[np.complex128] | None,
) -> LpvModel:
    coherent, notes = _coherent(form, models, p, Ts)
    coefs, resid = _interpolate(coherent, phi)
    rng = model_range(p)
    model = LpvModel(*coefs, basis=basis, Ts=Ts, p_range=rng)
    nb = len(basis)
    info: dict[str, Any] = {
        "method": "smile",
        "form": form,
        "balanced": balanced,
        "condition": float(notes["condition"]),
        "interp_residual": resid["all"],
        "interp_residual_by_matrix": {k: resid[k] for k in "ABCD"},
        "loo_error": None if z is None else _leave_one_out(form, models, phi, p, Ts, z),
        "n_groups": 4 * nb,
    }
    if "reference" in notes:
        info["reference"] = int(notes["reference"])
    if nb and rng is not None:
        info["constant_groups"] = 4 * nb - model.group_norms().count(1e-6)
    model.info.update(info)
    return model


def _prepare(
    local_models: Any, p: ArrayLike | None, basis: Any, freqs_hz: ArrayLike | None, do_balance: bool
) -> tuple[list[Ss], NDArray[np.float64], Basis, NDArray[np.float64], float | None, bool, Any]:
    models, Ts, carrier = _local_list(local_models)
    p_arr = local_p(local_models, p)
    if not isinstance(basis, Basis):
        raise TypeError(f"basis: expected an lpvid basis, got {type(basis).__name__}")
    pts = _check_p(p_arr, basis)
    phi = _regressors(basis, pts)
    if freqs_hz is None and carrier is not None:
        freqs_hz = carrier.freqs_hz
    f = _default_freqs(models, Ts) if freqs_hz is None else real_array(freqs_hz, "freqs_hz", ndim=1)
    balanced = False
    if do_balance:
        models, balanced = balance(models, Ts)
    return models, pts, basis, phi, Ts, balanced, z_points(f, Ts)


@single_blas
def smile_candidates(
    local_models: Any,
    p: ArrayLike | None = None,
    basis: Basis | None = None,
    *,
    forms: Sequence[str] | None = None,
    balance: bool = True,
    freqs_hz: ArrayLike | None = None,
    loo: bool = True,
) -> dict[str, LpvModel]:
    """SMILE models in every coherent form that can be built.

    Parameters
    ----------
    local_models, p, basis, balance, freqs_hz
        As in :func:`smile`.
    forms : sequence of str, optional
        Which forms to try; default all of :data:`FORMS`.
    loo : bool
        Give each model its leave-one-out FRF error (``info["loo_error"]``,
        see :func:`smile`); False leaves it None and skips its cost, one
        coherent form per interior point and form (:func:`lpvid.identify`
        refines every form and judges the fits instead).

    Returns
    -------
    dict of str to LpvModel
        One model per form that could be built, keyed by form; a form that
        fails for these models (see :mod:`lpvid.initial.coherent`) is left out and
        its reason recorded in every model's ``info["unavailable"]``.

    """
    wanted = FORMS if forms is None else tuple(forms)
    for form in wanted:
        if form not in FORMS:
            raise ValueError(f"forms: unknown coherent form {form!r}; choose from {FORMS}")
    return _candidates(local_models, p, basis, wanted, balance, freqs_hz, loo)[0]


def _candidates(
    local_models: Any,
    p: ArrayLike | None,
    basis: Any,
    forms: Sequence[str],
    do_balance: bool,
    freqs_hz: ArrayLike | None,
    loo: bool = True,
) -> tuple[dict[str, LpvModel], dict[str, str]]:
    models, pts, basis_, phi, Ts, balanced, z = _prepare(
        local_models, p, basis, freqs_hz, do_balance
    )
    out: dict[str, LpvModel] = {}
    failed: dict[str, str] = {}
    for form in forms:
        try:
            out[form] = _build(form, models, pts, basis_, phi, Ts, balanced, z if loo else None)
        except (CoherenceError, np.linalg.LinAlgError) as exc:
            failed[form] = str(exc)
    for m in out.values():
        m.info["unavailable"] = dict(failed)
    return out, failed


@single_blas
def smile(
    local_models: Any,
    p: ArrayLike | None = None,
    basis: Basis | None = None,
    *,
    form: str = "auto",
    balance: bool = True,
    freqs_hz: ArrayLike | None = None,
) -> LpvModel:
    """Interpolate local LTI models into an LPV model (SMILE).

    Parameters
    ----------
    local_models : LocalModels or sequence of LpvModel
        One LTI model (Nb = 0) per scheduling point, all of one order, Ts
        and size, e.g. from :func:`lpvid.identify_lti`.
    p : array_like, shape (N,) or (N, Np), optional
        Scheduling value of each model, all distinct; default
        ``local_models.p`` for a :class:`~lpvid.LocalModels`.
    basis : Basis
        Basis functions of the LPV model; needs at least Nb + 1 points.
    form : str
        Coherent state coordinates: ``"observability"``,
        ``"controllability"`` (the SMILE authors' transforms),
        ``"modal"`` (tracked modes, ``||b|| = ||c||`` per mode),
        ``"modal_input"`` (tracked modes, one column of B constant),
        ``"pairwise"`` (least-squares alignment of neighbours), or
        ``"auto"`` (default): build every form and keep the one with the
        smallest leave-one-out FRF error at interior points (the condition
        number when no point is interior).
    balance : bool
        Balance every local model first (when all are stable).
    freqs_hz : array_like, optional
        Lines for the leave-one-out check; default the data's lines for a
        :class:`~lpvid.LocalModels`, else a grid around the poles.

    Returns
    -------
    LpvModel
        With ``p_range`` from ``p`` and ``info`` holding ``form``,
        ``condition`` (worst condition number of the coherence transforms),
        ``interp_residual`` (relative least-squares residual of the entries,
        also ``interp_residual_by_matrix``), ``loo_error``,
        ``constant_groups`` (groups of relative magnitude below 1e-6) and
        ``n_groups``; for ``"auto"`` also ``candidates``.

    Raises
    ------
    ValueError, TypeError
        On malformed or inconsistent input: mismatched models, duplicate or
        too few scheduling values, a rank-deficient basis, an unknown form.
    lpvid.initial.coherent.CoherenceError
        When the requested form cannot be built (a ValueError).

    Notes
    -----
    Every form reproduces the local models exactly when the basis has N - 1
    functions; they differ between the points, and there by orders of
    magnitude (on a gantry-like chain: modal forms 1e-4, observability 1e-3,
    controllability and pairwise 1e-2 relative FRF error). What cannot be
    untangled: the modal forms fail when a pole pair splits into real poles
    between the points, and two modes that cross between neighbouring points
    with similar residue directions (always so for a single-input
    single-output system) may be swapped; the Krylov forms degrade when a
    mode is nearly unobservable (uncontrollable) at some point. Then choose
    another form, add points, or lower the degree of the basis.

    Examples
    --------
    >>> import numpy as np, lpvid
    >>> locs = [lpvid.LpvModel([[a]], [[1.0]], [[1.0]], Ts=1.0) for a in (0.2, 0.4, 0.6)]
    >>> m = lpvid.smile(locs, [0.0, 1.0, 2.0], lpvid.Polynomial(2, domain=(0, 2)))
    >>> round(float(m.at(0.5)[0][0, 0]), 12)
    0.3

    """
    if form != "auto" and form not in FORMS:
        raise ValueError(f"form: unknown coherent form {form!r}; choose from {FORMS} or 'auto'")
    if form != "auto":
        models, pts, basis_, phi, Ts, balanced, z = _prepare(
            local_models, p, basis, freqs_hz, balance
        )
        return _build(form, models, pts, basis_, phi, Ts, balanced, z)
    cands, failed = _candidates(local_models, p, basis, FORMS, balance, freqs_hz)
    if not cands:
        reasons = "; ".join(f"{k}: {v}" for k, v in failed.items())
        raise CoherenceError(f"local_models: no coherent form could be built ({reasons})")
    have_loo = all(m.info["loo_error"] is not None for m in cands.values())
    if have_loo:
        best = min(cands, key=lambda k: (cands[k].info["loo_error"], cands[k].info["condition"]))
    else:
        best = min(cands, key=lambda k: cands[k].info["condition"])
    chosen = cands[best]
    chosen.info["selected_by"] = "leave-one-out" if have_loo else "condition"
    chosen.info["candidates"] = {
        k: {"loo_error": m.info["loo_error"], "condition": m.info["condition"]}
        for k, m in cands.items()
    }
    return chosen
