"""Writers of measured-FRF files for the reader tests: UFF 58, CSV, MATLAB structs, manifests.

Each writes what an analyzer or MATLAB would, from arrays of one point:
freqs (F,), G (F, l, r), and optionally coherence or variance (F, l, r).
The files are written by pyuff, numpy and scipy.io, never by lpvid.
:func:`write_example_files` writes the files docs/data.md's example manifest names.
"""

from __future__ import annotations

import re
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

OUT_NODES = (3, 2)  # UFF response nodes of the outputs (direction +X)
IN_NODES = (1, 4)  # UFF reference nodes of the inputs (direction +Z)
OUTPUTS = ("head", "carriage")
INPUTS = ("torque", "force")
EXAMPLE_AVERAGES = 20  # the averages of docs/data.md's coherence


def write_uff(
    path: Path,
    freqs: np.ndarray,
    G: np.ndarray,
    *,
    binary: bool = False,
    coherence: np.ndarray | None = None,
    func_type: int = 4,
    units: tuple[str, str] = ("m/s^2", "N m"),
    drop: tuple[int, int] | None = None,
    rows: tuple[int, ...] | None = None,
) -> Path:
    """One UFF file, per pair (output-major) an FRF record, then its coherence record.

    ``rows``: only these outputs (an analyzer's one file per channel pair).
    """
    import pyuff

    sets = []
    for i in range(G.shape[1]) if rows is None else rows:
        for j in range(G.shape[2]):
            if drop == (i, j):
                continue
            common = dict(
                binary=int(binary),
                rsp_node=OUT_NODES[i],
                rsp_dir=1,
                ref_node=IN_NODES[j],
                ref_dir=3,
                x=np.asarray(freqs, dtype=float),
                id1="lpvid test",
                abscissa_spacing=0,
                abscissa_spec_data_type=18,
                abscissa_axis_units_lab="Hz",
            )
            sets.append(
                pyuff.prepare_58(
                    func_type=func_type,
                    data=np.asarray(G[:, i, j], dtype=complex),
                    ordinate_spec_data_type=12,
                    ordinate_axis_units_lab=units[0],
                    orddenom_spec_data_type=13,
                    orddenom_axis_units_lab=units[1],
                    **common,
                )
            )
            if coherence is not None:
                sets.append(
                    pyuff.prepare_58(
                        func_type=6,
                        data=np.asarray(coherence[:, i, j], dtype=float),
                        ordinate_spec_data_type=0,
                        orddenom_spec_data_type=0,
                        **common,
                    )
                )
    path.unlink(missing_ok=True)
    # mode="add" on a new file: pyuff 2.5.8's "overwrite" truncates binary records,
    # and its binary writer leaves a file handle to the garbage collector.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        pyuff.UFF(str(path)).write_sets(sets, mode="add")
    return path


def write_csv(
    path: Path,
    freqs: np.ndarray,
    G: np.ndarray,
    *,
    layout: str = "re/im",
    variance: np.ndarray | None = None,
    coherence: np.ndarray | None = None,
    unit: str = "m/s^2/N m",
    freq_unit: str = "Hz",
) -> Path:
    """A CSV table in lpvid's layout; numbers written with repr (exact round trip)."""
    header = [f"freq [{freq_unit}]"]
    columns = [np.asarray(freqs, dtype=float)]
    for i in range(G.shape[1]):
        for j in range(G.shape[2]):
            label = f"{OUTPUTS[i]}/{INPUTS[j]}"
            g = G[:, i, j]
            if layout == "re/im":
                header += [f"{label} re [{unit}]", f"{label} im [{unit}]"]
                columns += [g.real, g.imag]
            elif layout == "mag/deg":
                header += [f"{label} mag [{unit}]", f"{label} phase [deg]"]
                columns += [np.abs(g), np.degrees(np.angle(g))]
            else:
                header += [f"{label} db [{unit}]", f"{label} phase [rad]"]
                columns += [20 * np.log10(np.abs(g)), np.angle(g)]
            if variance is not None:
                header.append(f"{label} var")
                columns.append(variance[:, i, j])
            if coherence is not None:
                header.append(f"{label} coh")
                columns.append(coherence[:, i, j])
    rows = [", ".join(repr(float(c[k])) for c in columns) for k in range(len(freqs))]
    path.write_text("# lpvid test data\n" + ", ".join(header) + "\n" + "\n".join(rows) + "\n")
    return path


def write_mat(
    path: Path,
    freqs: np.ndarray,
    G: np.ndarray,
    *,
    Ts: float | None = None,
    variance: np.ndarray | None = None,
    unit: str | None = "rad/s",
    struct: bool = True,
    outputs: tuple[str, ...] = OUTPUTS,
) -> Path:
    """frd/idfrd data as MATLAB saves struct(sys): ResponseData l x r x F, Frequency, ..."""
    from scipy.io import savemat

    l, r = G.shape[1:]
    fields: dict[str, object] = {"ResponseData": np.transpose(G, (1, 2, 0))}
    scale = 2 * np.pi if unit in (None, "rad/s") else 1.0
    fields["Frequency"] = np.asarray(freqs, dtype=float)[:, None] * scale
    if unit is not None:
        fields["FrequencyUnit"] = unit
    fields["Ts"] = 0.0 if Ts is None else Ts
    fields["TimeUnit"] = "seconds"
    names = np.empty((l, 1), dtype=object)
    names[:, 0] = outputs[:l]
    fields["OutputName"] = names
    names = np.empty((r, 1), dtype=object)
    names[:, 0] = INPUTS[:r]
    fields["InputName"] = names
    if variance is not None:
        cov = np.zeros((l, r, len(freqs), 2, 2))
        cov[..., 0, 0] = cov[..., 1, 1] = np.transpose(variance, (1, 2, 0)) / 2
        fields["CovarianceData"] = cov
    savemat(path, {"sys": fields} if struct else fields)
    return path


def write_complex_csv(
    path: Path,
    freqs: np.ndarray,
    G: np.ndarray,
    *,
    spelling: str = "numpy",
    labels: tuple[str, ...] = OUTPUTS,
    variance: np.ndarray | None = None,
) -> Path:
    """A CSV table with one complex column per pair, as numpy or MATLAB writes it.

    ``spelling``: ``"numpy"`` is ``np.savetxt`` of a complex array with the
    header as its comment line (every column complex, ``(50+0j)``);
    ``"matlab"`` is ``fprintf('%.17g%+.17gi')`` (``1-2i``), ``"matlab-old"``
    writematrix before R2020b (``1+-2i``), ``"spaced"`` ``1 - 2i``.
    """
    header = ["freq [Hz]"]
    columns = [np.asarray(freqs, dtype=complex)]
    for i in range(G.shape[1]):
        for j in range(G.shape[2]):
            label = f"{labels[i]}/{INPUTS[j]}"
            header.append(f"{label} frf [m/s^2/N m]")
            columns.append(G[:, i, j])
            if variance is not None:
                header.append(f"{label} var")
                columns.append(variance[:, i, j].astype(complex))
    if spelling == "numpy":
        np.savetxt(path, np.stack(columns, axis=1), delimiter=",", header=", ".join(header))
        return path

    def cell(z: complex, real: bool) -> str:
        if real:
            return f"{z.real:.17g}"
        if spelling == "matlab":
            return f"{z.real:.17g}{z.imag:+.17g}i"
        if spelling == "matlab-old":
            return f"{z.real:.17g}+{z.imag:.17g}i"
        return f"{z.real:.17g} {'-' if z.imag < 0 else '+'} {abs(z.imag):.17g}i"

    real = [not h.split(" [")[0].endswith("frf") for h in header]
    rows = [
        ",".join(cell(c[k], r) for c, r in zip(columns, real, strict=True))
        for k in range(len(freqs))
    ]
    path.write_text(",".join(header) + "\n" + "\n".join(rows) + "\n")
    return path


def write_manifest(path: Path, header: str, points: list[tuple[object, object]]) -> Path:
    """A manifest: the header text, then one [[points]] table per (p, file or files)."""
    parts = [header.strip(), ""]
    for p, files in points:
        value = repr([float(x) for x in p]) if isinstance(p, list | tuple) else repr(float(p))
        parts.append("[[points]]")
        parts.append(f"p = {value}")
        if isinstance(files, list):
            parts.append("files = [" + ", ".join(f'"{f}"' for f in files) + "]")
        else:
            parts.append(f'file = "{files}"')
        parts.append("")
    path.write_text("\n".join(parts))
    return path


def coherence_for(G: np.ndarray, sigma: np.ndarray, averages: int) -> np.ndarray:
    """The coherence whose Bendat-Piersol sigma is the given one (inverse of the formula)."""
    return 1.0 / (1.0 + averages * sigma**2 / np.abs(G) ** 2)


def example_manifest() -> str:
    """The example manifest of docs/data.md ("Measured FRF files", its first TOML block)."""
    page = (Path(__file__).parents[1] / "docs" / "data.md").read_text()
    return re.search(r"```toml\n(# gantry.toml\n.*?)```", page, re.S).group(1)


def write_example_files(folder: Path, text: str, data: Any) -> dict[str, Any]:
    """Every file the manifest names, from the data at its p, as its comments describe it.

    Records are written carriage first wherever the format allows, so that
    matching by order instead of by node or label would swap the outputs.
    """
    doc = tomllib.loads(text)
    labels = [out.get("label", out["name"]) for out in doc["outputs"]]
    coh = coherence_for(data.G, data.sigma, EXAMPLE_AVERAGES)
    swap = [1, 0]
    for point in doc["points"]:
        q = int(np.flatnonzero(data.p == point["p"])[0])
        files = point.get("files") or [point["file"]]
        g, var = data.G[q], data.sigma[q] ** 2
        for name in files:
            path = folder / name
            if name.endswith(".uff"):
                if len(files) == 1:
                    rows = (1, 0)
                else:  # one file per channel pair, named after the output
                    rows = (0,) if "head" in name else (1,)
                write_uff(path, data.freqs_hz, g, coherence=coh[q], rows=rows, binary=q % 2 == 1)
            elif name.endswith(".csv"):
                out = tuple(labels[i] for i in swap)
                write_complex_csv(
                    path, data.freqs_hz, g[:, swap], labels=out, variance=var[:, swap]
                )
            else:
                own = {o["name"]: o["label"] for o in point["outputs"]}
                out = tuple(own[doc["outputs"][i]["name"]] for i in swap)
                write_mat(
                    path,
                    data.freqs_hz,
                    g[:, swap],
                    Ts=data.Ts,
                    variance=var[:, swap],
                    outputs=out,
                )
    return doc
