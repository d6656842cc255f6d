"""The model handed on: to python-control as a scheduled system, to MATLAB as a gridded one.

:func:`to_control_lpv` gives a python-control ``NonlinearIOSystem`` whose
inputs are the model's inputs followed by its scheduling parameters, for
simulation along ``p(t)`` (``control.input_output_response``) and for
gain-scheduled design (``control.create_statefbk_iosystem(...,
gainsched_indices=...)``). :func:`save_grid` writes the frozen ``A``,
``B``, ``C``, ``D`` on a grid of scheduling values to a MATLAB file that
MATLAB reads as a model array (``ss`` with ``SamplingGrid``), without
lpvid. Both are reached as :meth:`lpvid.LpvModel.to_control_lpv` and
:meth:`lpvid.LpvModel.save_grid`.

Signal names come from the data set when it knows them: an
:class:`~lpvid.FrfData` read with :meth:`~lpvid.FrfData.from_files` (the
manifest's outputs, inputs and parameters) or a built-in data set
(:mod:`lpvid.datasets`); otherwise ``u[i]``, ``y[i]``, ``p[i]``.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid._checks import positive_int, real_array
from lpvid._files import write_mat
from lpvid.data.schedule import axis_values, range_pairs
from lpvid.model._protocol import ModelLike

__all__ = ["GRID_POINTS", "SignalNames", "save_grid", "signal_names", "to_control_lpv"]

#: Grid points per scheduling parameter that :func:`save_grid` takes by default.
GRID_POINTS = 21

SignalNames = tuple[list[str], list[str], list[str]]


def signal_names(
    model: ModelLike,
    names: Any = None,
    *,
    inputs: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    parameters: Sequence[str] | None = None,
) -> SignalNames:
    """Names of the model's inputs, outputs and scheduling parameters.

    Parameters
    ----------
    model : LpvModel
    names : FrfData or lpvid.datasets.Dataset, optional
        Where the names come from: an ``FrfData`` read from files (its
        ``provenance``) or a built-in data set (``inputs``, ``outputs``,
        ``scheduling``). Default ``u[i]``, ``y[i]``, ``p[i]``.
    inputs, outputs, parameters : sequence of str, optional
        Names given here replace those of ``names``.

    Returns
    -------
    (inputs, outputs, parameters) : tuple of lists of str

    Raises
    ------
    TypeError
        When ``names`` is neither; ValueError when a count differs from the
        model's, or names repeat, or one is empty or holds a ``.`` (which
        python-control keeps for ``system.signal``).
    """
    n, r, l, _ = model.shape
    n_params = model.basis.n_params
    found = _names_of(names)
    given = {"inputs": inputs, "outputs": outputs, "parameters": parameters}
    sizes = {"inputs": r, "outputs": l, "parameters": n_params}
    defaults = {"inputs": "u", "outputs": "y", "parameters": "p"}
    out: dict[str, list[str]] = {}
    for key, size in sizes.items():
        value, source = given[key], key
        if value is None and found.get(key) is not None:
            value, source = found[key], f"names: the data set's {key}"
        if value is None:
            out[key] = [f"{defaults[key]}[{i}]" for i in range(size)]
            continue
        if isinstance(value, str) or not all(isinstance(x, str) for x in value):
            raise TypeError(f"{key}: expected a list of names, got {value!r}")
        value = list(value)
        if len(value) != size:
            raise ValueError(
                f"{source}: {len(value)} names for a model with {size} {key} ({value})"
            )
        bad = [x for x in value if not x.strip() or "." in x]
        if bad:
            raise ValueError(
                f"{source}: {bad[0]!r} cannot name a python-control signal (empty, or with "
                "a '.'); give other names"
            )
        out[key] = value
    for group in (out["inputs"] + out["parameters"], out["outputs"]):
        twice = sorted({x for x in group if group.count(x) > 1})
        if twice:
            raise ValueError(f"names: {twice} name more than one signal; give other names")
    return out["inputs"], out["outputs"], out["parameters"]


def _names_of(source: Any) -> dict[str, list[str] | None]:
    if source is None:
        return {}
    from lpvid.data.frf import FrfData

    if isinstance(source, FrfData):
        prov = source.provenance or {}
        return {k: prov.get(k) for k in ("inputs", "outputs", "parameters")}
    # A built-in data set (lpvid.datasets.Dataset, a folder above this one):
    # known by the names it carries.
    if all(hasattr(source, a) for a in ("inputs", "outputs", "scheduling", "identification")):
        return {
            "inputs": list(source.inputs),
            "outputs": list(source.outputs),
            "parameters": [source.scheduling],
        }
    raise TypeError(
        f"names: expected an FrfData or a built-in data set, got {type(source).__name__}"
    )


def _stacked(model: ModelLike) -> NDArray[np.float64]:
    """``[[A, B], [C, D]]`` per coefficient, flattened: shape (Nb+1, (n+l)(n+r))."""
    top = np.concatenate([model.A, model.B], axis=2)
    bottom = np.concatenate([model.C, model.D], axis=2)
    return np.concatenate([top, bottom], axis=1).reshape(len(model.basis) + 1, -1)


def to_control_lpv(
    model: ModelLike,
    names: Any = None,
    *,
    inputs: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    parameters: Sequence[str] | None = None,
    full_state: bool = False,
    name: str | None = None,
) -> Any:
    """The LPV model as a python-control ``NonlinearIOSystem``: inputs ``u`` then ``p``.

    The system's state equation is the model's, with the scheduling
    parameters as inputs after the model's ``r`` inputs::

        x(t+1) or dx/dt = A(p) x + B(p) u,   y = C(p) x + D(p) u

    It is discrete time with ``dt = Ts`` when the model is, else continuous
    time. ``control.input_output_response`` simulates it: in discrete time
    sample by sample as :meth:`lpvid.LpvModel.simulate` does; in continuous
    time with ``solve_ivp`` and ``u``, ``p`` interpolated linearly between
    the given times, where :meth:`~lpvid.LpvModel.simulate` holds them over
    each sample (zero-order hold), so the two agree only as the samples
    shrink or on inputs held constant over each call.

    Parameters
    ----------
    model : LpvModel
    names : FrfData or lpvid.datasets.Dataset, optional
        The data set whose labels name the signals (see :func:`signal_names`).
    inputs, outputs, parameters : sequence of str, optional
        Names that replace those of ``names``.
    full_state : bool, optional
        Outputs are the states ``x[0]``, ... instead of ``y``: the plant
        that ``control.create_statefbk_iosystem`` expects for state
        feedback without an estimator.
    name : str, optional
        The system's name (python-control's default otherwise).

    Returns
    -------
    control.NonlinearIOSystem

    Raises
    ------
    ImportError
        Without python-control (``pip install "lpvid[control]"``).
    ValueError
        From the system's functions during a simulation, when the scheduling
        input is not finite or the basis is not finite there.

    Examples
    --------
    >>> import numpy as np, control, lpvid
    >>> m = lpvid.LpvModel([[[0.5]], [[0.2]]], [[[1.0]], [[0.0]]], [[[1.0]], [[0.0]]],
    ...                    basis=lpvid.Polynomial(1), Ts=1.0)
    >>> sys = m.to_control_lpv()
    >>> sys.input_labels, sys.dt
    (['u[0]', 'p[0]'], 1.0)
    >>> T = np.arange(3.0)
    >>> control.input_output_response(sys, T, [np.ones(3), [0.0, 1.0, 1.0]]).y[0].tolist()
    [0.0, 1.0, 1.7]

    """
    try:
        import control
    except ImportError as exc:
        raise ImportError(
            'to_control_lpv needs python-control: pip install "lpvid[control]"'
        ) from exc
    if not isinstance(full_state, bool):
        raise TypeError(f"full_state: expected True or False, got {full_state!r}")
    u_names, y_names, p_names = signal_names(
        model, names, inputs=inputs, outputs=outputs, parameters=parameters
    )
    n, r, l, _ = model.shape
    coef = _stacked(model)
    one_param = model.basis.n_params == 1
    # The last scheduling value and its matrix, replaced as one pair (threads may share it).
    last: list[tuple[bytes, NDArray[np.float64]] | None] = [None]

    def frozen(t: float, v: NDArray[np.float64]) -> NDArray[np.float64]:
        p = v[r:]
        key, hit = p.tobytes(), last[0]
        if hit is not None and hit[0] == key:
            return hit[1]
        if not np.all(np.isfinite(p)):
            raise ValueError(f"p: the scheduling input is {p.tolist()} at t = {t:g}")
        psi = model.basis_values(p if one_param else p[None, :])[0]
        matrix = (coef[0] + psi @ coef[1:]).reshape(n + l, n + r)
        last[0] = (key, matrix)
        return matrix

    def update(t: float, x: Any, v: Any, params: Any) -> NDArray[np.float64]:
        v = np.asarray(v, dtype=np.float64)
        return frozen(t, v)[:n] @ np.concatenate([np.asarray(x, dtype=np.float64), v[:r]])

    def output(t: float, x: Any, v: Any, params: Any) -> NDArray[np.float64]:
        v = np.asarray(v, dtype=np.float64)
        return frozen(t, v)[n:] @ np.concatenate([np.asarray(x, dtype=np.float64), v[:r]])

    states = [f"x[{i}]" for i in range(n)]
    return control.nlsys(
        update,
        None if full_state else output,
        inputs=u_names + p_names,
        outputs=states if full_state else y_names,
        states=states,
        dt=0 if model.Ts is None else model.Ts,
        name=name,
    )


def _grid_axes(model: ModelLike, grid: Any, count: int) -> list[NDArray[np.float64]]:
    n_params = model.basis.n_params
    if grid is None:
        count = positive_int(count, "count")
        if model.p_range is None:
            raise ValueError(
                "grid: the model has no p_range to spread the grid over; give the grid values"
            )
        pairs = range_pairs(model.p_range, n_params)
        return [
            axis_values(lo, hi, count, sc)
            for (lo, hi), sc in zip(pairs, model.basis.scales, strict=True)
        ]
    axes = [grid] if n_params == 1 else list(grid)
    if len(axes) != n_params:
        raise ValueError(
            f"grid: expected one array of values per scheduling parameter ({n_params}), "
            f"got {len(axes)}"
        )
    out = []
    for k, axis in enumerate(axes):
        where = "grid" if n_params == 1 else f"grid[{k}]"
        values = real_array(axis, where, ndim=(0, 1)).ravel()
        if values.size == 0 or np.any(np.diff(values) <= 0):
            raise ValueError(f"{where}: expected strictly increasing values, got {values}")
        out.append(values)
    return out


def _matlab_names(names: list[str]) -> list[str]:
    """MATLAB field names for the parameters: letters, digits and _; p, p1, p2 otherwise."""
    fields = [re.sub(r"\W+", "_", x).strip("_")[:63] for x in names]
    ok = all(re.match(r"^[A-Za-z]\w*$", f) for f in fields) and len(set(fields)) == len(fields)
    ok = ok and not all(re.match(r"^p\[\d+\]$", x) for x in names)  # lpvid's default names
    if ok:
        return fields
    return ["p"] if len(names) == 1 else [f"p{k + 1}" for k in range(len(names))]


def save_grid(
    model: ModelLike,
    path: str | os.PathLike[str],
    grid: Any = None,
    names: Any = None,
    *,
    count: int = GRID_POINTS,
    inputs: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    parameters: Sequence[str] | None = None,
) -> Path:
    """Write the frozen models on a grid of scheduling values to a MATLAB file.

    The file is read without lpvid (MATLAB's ``load``, ``scipy.io.loadmat``)
    and holds:

    - ``A``: ``n x n x G`` with ``A(:,:,k)`` the model frozen at the k-th
      grid value (``n x n x G1 x G2`` for two parameters on
      ``grid{1} x grid{2}``, and so on); ``B``, ``C``, ``D`` likewise;
    - ``SamplingGrid``: a struct with one field per scheduling parameter
      (its name made a MATLAB identifier, or ``p``, ``p1``, ``p2``, ...)
      holding the value of every model, the array MATLAB's
      ``sys.SamplingGrid`` takes;
    - ``grid``: a cell array of the grid values per parameter (columns);
    - ``Ts``: the sample time in seconds, 0 for continuous time (MATLAB's
      convention); ``InputName``, ``OutputName``, ``SchedulingName``: cell
      arrays of names; ``description``: this layout in a sentence.

    In MATLAB: ``s = load(file); sys = ss(s.A, s.B, s.C, s.D, s.Ts,
    'InputName', s.InputName, 'OutputName', s.OutputName);
    sys.SamplingGrid = s.SamplingGrid;`` gives the gridded model array.

    Parameters
    ----------
    model : LpvModel
    path : str or path-like
        A ``.mat`` file, written whole or not at all.
    grid : array_like or sequence of array_like, optional
        Strictly increasing scheduling values (one array per parameter for
        several: a full grid). Default: ``count`` evenly spaced values per
        parameter over ``model.p_range`` (evenly in ``log10(p)`` for a
        parameter the basis takes on the log scale).
    names : FrfData or lpvid.datasets.Dataset, optional
        Where the names come from (see :func:`signal_names`).
    count : int, optional
        Values per parameter of the default grid (:data:`GRID_POINTS`, 21).
    inputs, outputs, parameters : sequence of str, optional
        Names that replace those of ``names``.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ValueError
        For a path that is not ``.mat``, a grid that is not strictly
        increasing or has NaN, no grid and no ``p_range``, or a basis that
        is not finite on the grid.
    """
    target = Path(path)
    if target.suffix.lower() != ".mat":
        raise ValueError(f"path: expected a .mat file, got {target.name!r}")
    u_names, y_names, p_names = signal_names(
        model, names, inputs=inputs, outputs=outputs, parameters=parameters
    )
    axes = _grid_axes(model, grid, count)
    mesh = np.meshgrid(*axes, indexing="ij")  # MATLAB's ndgrid
    shape = mesh[0].shape
    points = np.stack([m.ravel() for m in mesh], axis=1)
    psi = model.basis_values(points[:, 0] if len(axes) == 1 else points)
    weights = np.concatenate([np.ones((len(points), 1)), psi], axis=1)
    variables: dict[str, Any] = {}
    for key, coef in model.matrices().items():
        frozen = np.tensordot(weights, coef, axes=1)  # (G, rows, cols)
        variables[key] = np.moveaxis(frozen, 0, -1).reshape(*coef.shape[1:], *shape)
    fields = _matlab_names(p_names)
    columns = shape if len(axes) > 1 else (shape[0], 1)
    variables["SamplingGrid"] = {f: m.reshape(columns) for f, m in zip(fields, mesh, strict=True)}
    cell = np.empty(len(axes), dtype=object)  # a MATLAB cell array of column vectors
    for k, values in enumerate(axes):
        cell[k] = values.reshape(-1, 1)
    variables["grid"] = cell
    variables["Ts"] = np.array(0.0 if model.Ts is None else model.Ts)
    named = {"InputName": u_names, "OutputName": y_names, "SchedulingName": p_names}
    for key, value in named.items():
        variables[key] = np.array(value, dtype=object).reshape(-1, 1)
    variables["description"] = (
        "lpvid LPV model frozen on a grid: A(:,:,k) is A(p) at the k-th grid point "
        "(A(:,:,i,j) at grid{1}(i), grid{2}(j) for two parameters), likewise B, C, D; "
        "SamplingGrid holds the scheduling values of every model; "
        + ("continuous time (Ts = 0)" if model.Ts is None else f"Ts = {model.Ts:g} s")
        + ". In MATLAB: s = load(file); sys = ss(s.A, s.B, s.C, s.D, s.Ts, 'InputName', "
        "s.InputName, 'OutputName', s.OutputName); sys.SamplingGrid = s.SamplingGrid;"
    )
    return write_mat(target, variables)
