"""The lpvid model file: versioned JSON, written whole or not at all.

Format (version 1, or 2 when a scheduling parameter is on the log scale)::

    {
      "format": "lpvid-model",
      "version": 1 or 2,
      "content": {
        "n_states": n, "n_inputs": r, "n_outputs": l, "n_basis": Nb,
        "Ts": float or null,              # null: continuous time
        "basis": {"kind": "polynomial" | "legendre", "degree": d,
                  "domain": [[lo, hi], ...] or null, "n_params": Np,
                  "scale": ["linear" | "log", ...]},   # version 2 only
        "p_range": [lo, hi] or [[lo, hi], ...] or null,
        "info": {...},                    # free-form notes (LpvModel.info)
        "A": [...], "B": [...], "C": [...], "D": [...]   # nested lists (Nb+1, rows, cols)
      },
      "sha256": hex digest of the canonical JSON of "content"
    }

Floats are written with Python's shortest round-trip representation, so a
model read back is equal to the one saved, to the last bit. The checksum
catches a damaged file. A basis with a parameter on the log scale
(``Polynomial(..., scale="log")``) writes its ``"scale"`` and makes the file
version 2, which lpvid before the scale refuses rather than read as a
linear basis; every other file stays version 1, as before. A file without
``"scale"`` is read as linear on every parameter.

MATLAB export (``.mat``, readable with ``load`` in MATLAB): ``A`` as an
``n x n x (Nb+1)`` array with ``A(:,:,1)`` the constant part and
``A(:,:,i+1)`` the coefficient of ``psi_i`` (likewise ``B``, ``C``, ``D``),
``Ts`` (empty for continuous time), ``basis_kind``, ``basis_degree``,
``basis_domain`` (one row ``[lo hi]`` per scheduling parameter, empty for
none), ``basis_n_params``, ``basis_scale`` (a cell array, ``'linear'`` or
``'log'`` per parameter), ``basis_names``, ``p_range`` (empty for none),
``description``, and ``lpvid_model``: the JSON document above as text.

Reading a ``.mat`` file reads its arrays: the model returned holds the
numbers of ``A``, ``B``, ``C``, ``D``, ``Ts``, the basis variables and
``p_range``. When the file also holds ``lpvid_model`` (as lpvid writes it),
every variable must equal that copy, to the last bit, or the file is refused
with the names of the variables that differ; a file edited in MATLAB can be
read as edited by removing ``lpvid_model`` from it (``clear lpvid_model``
before saving). Without ``lpvid_model`` the model is built from the
variables alone (``D``, ``basis_domain``, ``basis_n_params``,
``basis_scale``, ``basis_names`` and ``p_range`` may then be absent), and
``info`` is empty. ``basis_scale`` may be absent in every ``.mat`` file
(files written before it): linear on every parameter.

This module works on the model through its attributes (those of
``lpvid.model._protocol.ModelLike``) and is handed the class to build
(:meth:`lpvid.LpvModel.load`), so that it does not import :mod:`lpvid.model.lpv`.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from lpvid._files import mat_variables, write_atomic, write_mat
from lpvid.data.basis import basis_from_dict
from lpvid.data.schedule import scale_list
from lpvid.model._protocol import ModelLike

__all__ = [
    "FORMAT",
    "VERSION",
    "MATRICES",
    "file_version",
    "save_model",
    "load_model",
    "model_content",
]

FORMAT = "lpvid-model"
#: The newest file version: 2 holds a basis's scales (:func:`file_version`).
VERSION = 2
#: The coefficient arrays of a model, in file order.
MATRICES = ("A", "B", "C", "D")

ModelT = TypeVar("ModelT", bound=ModelLike)


def _canonical(content: dict[str, Any]) -> bytes:
    return json.dumps(content, sort_keys=True, separators=(",", ":"), allow_nan=False).encode()


def model_content(model: ModelLike) -> dict[str, Any]:
    """The ``content`` part of the file for a model (plain lists and numbers)."""
    n, r, l, nb = model.shape
    content: dict[str, Any] = {
        "n_states": n,
        "n_inputs": r,
        "n_outputs": l,
        "n_basis": nb,
        "Ts": model.Ts,
        "basis": model.basis.to_dict(),
        "p_range": model.p_range,
        "info": model.info,
    }
    for name, arr in model.matrices().items():
        content[name] = arr.tolist()
    return content


def _build(cls: Callable[..., ModelT], content: dict[str, Any]) -> ModelT:
    """Build a model of class ``cls`` from a ``content`` dict and check its sizes."""
    basis = basis_from_dict(content["basis"])
    model = cls(
        *(np.array(content[x], dtype=np.float64) for x in MATRICES),
        basis=basis,
        Ts=content["Ts"],
        p_range=content.get("p_range"),
        info=content.get("info"),
    )
    expected = (content["n_states"], content["n_inputs"], content["n_outputs"], content["n_basis"])
    if model.shape != tuple(expected):
        raise ValueError(f"sizes {model.shape} differ from the recorded {tuple(expected)}")
    return model


def file_version(content: dict[str, Any]) -> int:
    """The version a model's file is written as: 2 when its basis has scales, else 1.

    A basis on the log scale writes ``"scale"``; an lpvid that reads
    version 1 only would take it for a linear basis, so such a file is
    version 2, which that lpvid refuses.
    """
    return 2 if "scale" in content["basis"] else 1


def _scales(basis: dict[str, Any]) -> list[str]:
    """The scale of every parameter a basis description holds (linear where it says none)."""
    return list(basis.get("scale") or ["linear"] * int(basis["n_params"]))


def _document(content: dict[str, Any]) -> bytes:
    doc = {
        "format": FORMAT,
        "version": file_version(content),
        "content": content,
        "sha256": hashlib.sha256(_canonical(content)).hexdigest(),
    }
    return json.dumps(doc, indent=1, allow_nan=False).encode()


def save_model(model: ModelLike, path: str | os.PathLike[str]) -> Path:
    """Write ``model`` to ``path``: lpvid JSON (``.json``) or MATLAB (``.mat``).

    See :meth:`lpvid.LpvModel.save`.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in (".json", ".mat"):
        raise ValueError(f"path: expected a .json or .mat file, got {Path(path).name!r}")
    content = model_content(model)
    text = _document(content)
    if suffix == ".json":
        return write_atomic(path, lambda fh: fh.write(text))
    return write_mat(path, _matlab_variables(content, model.basis.names, text.decode()))


def _matlab_variables(content: dict[str, Any], names: list[str], document: str) -> dict[str, Any]:
    basis = content["basis"]
    domain, ts, p_range = basis.get("domain"), content["Ts"], content["p_range"]
    out: dict[str, Any] = {
        x: np.moveaxis(np.array(content[x], dtype=np.float64), 0, -1) for x in MATRICES
    }
    out.update(
        Ts=np.array([]) if ts is None else np.array(ts),
        basis_kind=basis["kind"],
        basis_degree=np.array(basis["degree"], dtype=float),
        basis_domain=np.zeros((0, 2)) if domain is None else np.array(domain, dtype=float),
        basis_n_params=np.array(basis["n_params"], dtype=float),
        basis_scale=np.array(_scales(basis), dtype=object),
        basis_names=np.array(names, dtype=object),
        p_range=np.zeros((0, 2)) if p_range is None else np.atleast_2d(p_range),
        description=(
            "lpvid LPV model: X(p) = X(:,:,1) + sum_i psi_i(p) X(:,:,i+1) for X in A, B, C, D; "
            "psi_i as named in basis_names, with s = p mapped from basis_domain to [-1, 1] "
            "(log10(p) from log10(basis_domain) where basis_scale is 'log'); "
            + ("continuous time" if ts is None else f"discrete time, Ts = {ts:g} s")
        ),
        lpvid_model=document,
    )
    return out


def load_model(path: str | os.PathLike[str], cls: Callable[..., ModelT]) -> ModelT:
    """Read a model file (``.json`` or ``.mat``) into a model of class ``cls``.

    See :meth:`lpvid.LpvModel.load`; the rules for ``.mat`` files are in the
    module docstring.
    """
    p = Path(path)
    content = _read_mat(p) if p.suffix.lower() == ".mat" else _parse(p.read_bytes(), p.name)
    try:
        return _build(cls, content)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"path: {p.name} is damaged ({exc})") from exc


def _parse(data: bytes, name: str) -> dict[str, Any]:
    """The checked ``content`` of a JSON model document."""
    try:
        doc = json.loads(data)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(
            f"path: {name} is not an lpvid model file (not valid JSON: {exc})"
        ) from exc
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f"path: {name} is not an lpvid model file")
    if doc.get("version") not in range(1, VERSION + 1):
        raise ValueError(
            f"path: {name} has model file version {doc.get('version')!r}; this lpvid reads "
            f"versions 1 to {VERSION}"
        )
    content = doc.get("content")
    if (
        not isinstance(content, dict)
        or doc.get("sha256") != hashlib.sha256(_canonical(content)).hexdigest()
    ):
        raise ValueError(f"path: {name} is damaged (its checksum does not match its content)")
    return content


def _read_mat(p: Path) -> dict[str, Any]:
    """The ``content`` held by the MATLAB variables of ``p``, checked against ``lpvid_model``."""
    try:
        raw = mat_variables(p)
    except ValueError as exc:
        raise ValueError(f"path: {exc}") from exc
    embedded = None
    if "lpvid_model" in raw:
        text = raw["lpvid_model"]
        if not isinstance(text, np.ndarray) or text.dtype.kind != "U" or text.size != 1:
            raise ValueError(f"path: {p.name}: lpvid_model is not the text lpvid writes")
        embedded = _parse(str(text.ravel()[0]).encode(), p.name)
    elif "basis_kind" not in raw or "A" not in raw:
        raise ValueError(
            f"path: {p.name} is not an lpvid model file (neither lpvid_model nor A and basis_kind)"
        )
    try:
        content = _from_variables(raw, require_all=embedded is not None)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"path: {p.name}: {exc}") from exc
    if embedded is None:
        return content
    differ = _differences(content, embedded, compare_n_params="basis_n_params" in raw)
    if differ:
        raise ValueError(
            f"path: {p.name}: the MATLAB variable{'s' if len(differ) > 1 else ''} "
            f"{', '.join(differ)} differ{'' if len(differ) > 1 else 's'} from the model "
            "lpvid wrote into the file (lpvid_model); the file was edited after it was "
            "written. To read the edited arrays, remove lpvid_model from the file"
        )
    return embedded


def _text(value: Any) -> str:
    arr = np.asarray(value)
    if arr.dtype.kind != "U" or arr.size != 1:
        raise ValueError("expected a text")
    return str(arr.ravel()[0])


def _texts(value: Any) -> list[str]:
    """A MATLAB cell array of texts (as loadmat reads it) as a list."""
    arr = np.asarray(value)
    if arr.size == 0:
        return []
    if arr.dtype.kind == "U" and arr.ndim == 1:
        return [str(x) for x in arr]
    return [_text(x) for x in arr.ravel()]


def _floats(value: Any, name: str) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype.kind not in "fiu":
        raise TypeError(f"{name}: expected real numbers, got dtype {arr.dtype}")
    return arr.astype(np.float64)


def _number(value: Any, name: str) -> float:
    arr = _floats(value, name)
    if arr.size != 1:
        raise ValueError(f"{name}: expected one number, got shape {arr.shape}")
    return float(arr.ravel()[0])


def _pairs(value: Any, name: str) -> list[list[float]] | None:
    """Rows ``[lo hi]``, or None for an empty array or none."""
    if value is None:
        return None
    arr = _floats(value, name)
    if arr.size == 0:
        return None
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name}: expected rows [lo hi], got shape {arr.shape}")
    return arr.tolist()


def _from_variables(raw: dict[str, Any], require_all: bool) -> dict[str, Any]:
    """The model ``content`` the MATLAB variables hold (``require_all``: no default)."""

    def get(name: str, optional: bool = False) -> Any:
        if name not in raw:
            if optional and not require_all:
                return None
            raise ValueError(f"{name}: missing")
        return raw[name]

    arrays = {}
    for x in MATRICES:
        value = get(x, optional=x == "D")
        if value is None:
            continue
        arr = _floats(value, x)
        if arr.ndim == 2:  # MATLAB drops a trailing dimension of 1 (Nb = 0)
            arr = arr[:, :, None]
        if arr.ndim != 3:
            raise ValueError(f"{x}: expected rows x columns x (Nb+1), got shape {arr.shape}")
        arrays[x] = np.moveaxis(arr, -1, 0)
    if "D" not in arrays:
        nb1, l, r = arrays["A"].shape[0], arrays["C"].shape[1], arrays["B"].shape[2]
        arrays["D"] = np.zeros((nb1, l, r))
    ts = _floats(get("Ts"), "Ts")
    domain = _pairs(get("basis_domain", optional=True), "basis_domain")
    n_params = get("basis_n_params", optional=True) if "basis_n_params" in raw else None
    basis: dict[str, Any] = {
        "kind": _text(get("basis_kind")),
        "degree": _number(get("basis_degree"), "basis_degree"),
        "domain": domain,
        "n_params": (
            _number(n_params, "basis_n_params")
            if n_params is not None
            else (1 if domain is None else len(domain))
        ),
    }
    for key in ("degree", "n_params"):
        if not float(basis[key]).is_integer():
            raise ValueError(f"basis_{key}: expected an integer, got {basis[key]}")
        basis[key] = int(basis[key])
    # Optional even beside lpvid_model: files written before the scale have none.
    if "basis_scale" in raw:
        scale = scale_list(_texts(raw["basis_scale"]), basis["n_params"], "basis_scale")
        if "log" in scale:
            basis["scale"] = list(scale)
    p_range = _pairs(get("p_range", optional=True), "p_range")
    if p_range is not None and len(p_range) == 1:
        p_range = p_range[0]
    names_raw = get("basis_names", optional=True)
    names = None if names_raw is None else _texts(names_raw)
    a, b, c = arrays["A"], arrays["B"], arrays["C"]
    content = {
        "n_states": a.shape[1],
        "n_inputs": b.shape[2],
        "n_outputs": c.shape[1],
        "n_basis": a.shape[0] - 1,
        "Ts": None if ts.size == 0 else _number(ts, "Ts"),
        "basis": basis,
        "p_range": p_range,
        "info": {},
        **{x: arrays[x].tolist() for x in MATRICES},
    }
    built = basis_from_dict(basis).names
    if names is not None and names != built:
        raise ValueError(
            f"basis_names: {names} do not match the basis of basis_kind, basis_degree, "
            f"basis_domain and basis_scale ({built})"
        )
    return content


def _differences(
    content: dict[str, Any], embedded: dict[str, Any], compare_n_params: bool
) -> list[str]:
    """Names of the MATLAB variables whose values differ from the embedded copy.

    Exact comparisons: lpvid writes both from the same float64 numbers.
    """

    def same_array(a: Any, b: Any, pairs: bool = False) -> bool:
        if a is None or b is None:
            return a is None and b is None
        x, y = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
        if pairs:  # [lo, hi] and [[lo, hi]] mean the same range
            x, y = np.atleast_2d(x), np.atleast_2d(y)
        return x.shape == y.shape and bool(np.array_equal(x, y))

    out = [x for x in MATRICES if not same_array(content[x], embedded.get(x))]
    if content["Ts"] != embedded.get("Ts"):
        out.append("Ts")
    basis, other = content["basis"], embedded.get("basis") or {}
    for key in ("kind", "degree", "n_params")[: 3 if compare_n_params else 2]:
        if basis[key] != other.get(key):
            out.append(f"basis_{key}")
    if not same_array(basis["domain"], other.get("domain"), pairs=True):
        out.append("basis_domain")
    if _scales(basis) != _scales(other):
        out.append("basis_scale")
    # basis_names were checked against the file's own basis variables
    if not same_array(content["p_range"], embedded.get("p_range"), pairs=True):
        out.append("p_range")
    return out
