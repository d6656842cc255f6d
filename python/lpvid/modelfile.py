"""The lpvid model file: versioned JSON, written whole or not at all.

Format (version 1)::

    {
      "format": "lpvid-model",
      "version": 1,
      "content": {
        "n_states": n, "n_inputs": r, "n_outputs": l, "n_basis": Nb,
        "Ts": float or null,              # null: continuous time
        "basis": {"kind": "polynomial" | "legendre", "degree": d,
                  "domain": [[lo, hi], ...] or null, "n_params": Np},
        "p_range": [lo, hi] or [[lo, hi], ...] or null,
        "info": {...},                    # free-form notes (LpvModel.info)
        "A": [...], "B": [...], "C": [...], "D": [...]   # nested lists (Nb+1, rows, cols)
      },
      "sha256": hex digest of the canonical JSON of "content"
    }

Floats are written with Python's shortest round-trip representation, so a
model read back is equal to the one saved, to the last bit. The checksum
catches a damaged file.

MATLAB export (``.mat``, readable with ``load`` in MATLAB): ``A`` as an
``n x n x (Nb+1)`` array with ``A(:,:,1)`` the constant part and
``A(:,:,i+1)`` the coefficient of ``psi_i`` (likewise ``B``, ``C``, ``D``),
``Ts`` (empty for continuous time), ``basis_kind``, ``basis_degree``,
``basis_domain`` (one row ``[lo hi]`` per scheduling parameter),
``basis_names``, ``p_range``, ``description``, and ``lpvid_model``: the JSON
document above as text, from which :func:`load_model` reads the model back
exactly.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from lpvid._files import mat_variables, write_atomic
from lpvid.basis import basis_from_dict
from lpvid.model import LpvModel

__all__ = ["FORMAT", "VERSION", "save_model", "load_model", "model_to_dict", "model_from_dict"]

FORMAT = "lpvid-model"
VERSION = 1


def _canonical(content: dict[str, Any]) -> bytes:
    return json.dumps(content, sort_keys=True, separators=(",", ":"), allow_nan=False).encode()


def model_to_dict(model: LpvModel) -> dict[str, Any]:
    """The ``content`` part of the file for a model."""
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


def model_from_dict(content: dict[str, Any]) -> LpvModel:
    """Rebuild a model from the ``content`` part of a file."""
    basis = basis_from_dict(content["basis"])
    model = LpvModel(
        *(np.array(content[x], dtype=np.float64) for x in ("A", "B", "C", "D")),
        basis=basis,
        Ts=content["Ts"],
        p_range=content.get("p_range"),
        info=content.get("info"),
    )
    expected = (content["n_states"], content["n_inputs"], content["n_outputs"], content["n_basis"])
    if model.shape != tuple(expected):
        raise ValueError(f"sizes {model.shape} differ from the recorded {tuple(expected)}")
    return model


def _document(model: LpvModel) -> bytes:
    content = model_to_dict(model)
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "content": content,
        "sha256": hashlib.sha256(_canonical(content)).hexdigest(),
    }
    return json.dumps(doc, indent=1, allow_nan=False).encode()


def save_model(model: LpvModel, path: str | os.PathLike[str]) -> Path:
    """Write ``model`` to ``path``: lpvid JSON (``.json``) or MATLAB (``.mat``).

    See :meth:`LpvModel.save`.
    """
    suffix = Path(path).suffix.lower()
    text = _document(model)
    if suffix == ".json":
        return write_atomic(path, lambda fh: fh.write(text))
    if suffix == ".mat":
        from scipy.io import savemat

        variables = _matlab_variables(model, text.decode())
        return write_atomic(path, lambda fh: savemat(fh, variables, do_compression=True))
    raise ValueError(f"path: expected a .json or .mat file, got {Path(path).name!r}")


def _matlab_variables(model: LpvModel, document: str) -> dict[str, Any]:
    basis = model.basis.to_dict()
    domain = basis.get("domain")
    out: dict[str, Any] = {name: np.moveaxis(arr, 0, -1) for name, arr in model.matrices().items()}
    out.update(
        Ts=np.array([]) if model.Ts is None else np.array(model.Ts),
        basis_kind=basis["kind"],
        basis_degree=np.array(basis["degree"], dtype=float),
        basis_domain=np.zeros((0, 2)) if domain is None else np.array(domain, dtype=float),
        basis_names=np.array(model.basis.names, dtype=object),
        p_range=np.zeros((0, 2)) if model.p_range is None else np.atleast_2d(model.p_range),
        description=(
            "lpvid LPV model: X(p) = X(:,:,1) + sum_i psi_i(p) X(:,:,i+1) for X in A, B, C, D; "
            "psi_i as named in basis_names, with s = p mapped from basis_domain to [-1, 1]; "
            + ("continuous time" if model.Ts is None else f"discrete time, Ts = {model.Ts:g} s")
        ),
        lpvid_model=document,
    )
    return out


def load_model(path: str | os.PathLike[str]) -> LpvModel:
    """Read a model file (``.json`` or ``.mat`` written by lpvid); see :meth:`LpvModel.load`."""
    p = Path(path)
    if p.suffix.lower() == ".mat":
        try:
            raw = mat_variables(p).get("lpvid_model")
        except ValueError as exc:
            raise ValueError(f"path: {exc}") from exc
        if raw is None or raw.dtype.kind != "U":
            raise ValueError(f"path: {p.name} is not an lpvid model file (no lpvid_model)")
        data = str(raw.ravel()[0]).encode()
    else:
        data = p.read_bytes()
    try:
        doc = json.loads(data)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(
            f"path: {p.name} is not an lpvid model file (not valid JSON: {exc})"
        ) from exc
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f"path: {p.name} is not an lpvid model file")
    if doc.get("version") != VERSION:
        raise ValueError(
            f"path: {p.name} has model file version {doc.get('version')!r}; this lpvid reads "
            f"version {VERSION}"
        )
    content = doc.get("content")
    if (
        not isinstance(content, dict)
        or doc.get("sha256") != hashlib.sha256(_canonical(content)).hexdigest()
    ):
        raise ValueError(f"path: {p.name} is damaged (its checksum does not match its content)")
    try:
        return model_from_dict(content)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"path: {p.name} is damaged ({exc})") from exc
