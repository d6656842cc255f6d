"""Experiments as labs have them: UFF, CSV and MATLAB files in one manifest.

Every file here is written by pyuff, numpy or scipy.io (see frf_files.py),
never by lpvid; the example manifest of docs/data.md is read back from files written as
its comments describe them.
"""

import re
from pathlib import Path

import numpy as np
import pytest
from frf_files import (
    EXAMPLE_AVERAGES,
    INPUTS,
    example_manifest,
    write_complex_csv,
    write_csv,
    write_example_files,
    write_manifest,
    write_mat,
    write_uff,
)

import lpvid

F = np.linspace(10.0, 20.0, 11)


@pytest.fixture(scope="module")
def gantry_data():
    return lpvid.datasets.gantry().identification


def test_the_data_page_manifest_round_trip(tmp_path, gantry_data):
    text = example_manifest()
    doc = write_example_files(tmp_path, text, gantry_data)
    (tmp_path / "gantry.toml").write_text(text)
    loaded = lpvid.FrfData.from_files(tmp_path / "gantry.toml")
    p = [pt["p"] for pt in doc["points"]]
    data = gantry_data.subset([int(np.flatnonzero(gantry_data.p == x)[0]) for x in p])
    exts = [Path(pt.get("file") or pt["files"][0]).suffix for pt in doc["points"]]
    assert exts == [".uff", ".uff", ".csv", ".mat"]  # the data page's mix
    np.testing.assert_array_equal(loaded.p, p)
    assert loaded.Ts == data.Ts
    np.testing.assert_allclose(loaded.freqs_hz, data.freqs_hz, rtol=5e-6)  # UFF's E13.5
    # ASCII UFF ordinates have 12 digits; binary UFF, numpy's %.18e and .mat are exact.
    np.testing.assert_allclose(loaded.G[0], data.G[0], rtol=5e-12, atol=0)
    np.testing.assert_array_equal(loaded.G[1:], data.G[1:])
    # sigma from coherence (12 digits, 1 - gamma^2 ~ 1e-5: 1e-6) and from variances.
    np.testing.assert_allclose(loaded.sigma[:2], data.sigma[:2], rtol=1e-6)
    np.testing.assert_allclose(loaded.sigma[2:], data.sigma[2:], rtol=1e-15)
    records = [pt["records"] for pt in loaded.provenance["points"]]
    assert records[0] == ["tube24-head.uff, record 1", "tube24-carriage.uff, record 1"]
    assert records[1] == ["tube30.uff, record 3", "tube30.uff, record 1"]  # carriage first
    assert records[3] == [
        "tube42.mat, sys.ResponseData(2,1,:)",
        "tube42.mat, sys.ResponseData(1,1,:)",
    ]
    assert [pt["sigma"] for pt in loaded.provenance["points"]] == [
        f"coherence, {EXAMPLE_AVERAGES} averages"
    ] * 2 + ["variance records"] * 2


def refused(path, message):
    """A manifest of one point, the file ``path`` of a 2 x 1 system, fails with ``message``."""
    header = 'outputs = ["head", "carriage"]\ninputs = ["torque"]'
    manifest = write_manifest(path.parent / "m.toml", header, [(0, path.name)])
    with pytest.raises(ValueError, match=message):
        lpvid.FrfData.from_files(manifest)


# ------------------------------------------------------------------ complex CSV cells
@pytest.mark.parametrize("spelling", ["numpy", "matlab", "matlab-old", "spaced"])
def test_complex_csv_cells(tmp_path, rng, spelling):
    G = (rng.normal(size=(F.size, 2, 1)) + 1j * rng.normal(size=(F.size, 2, 1))) * 10.0 ** (
        rng.integers(-8, 8, size=(F.size, 2, 1))
    )
    G[3, 0, 0] = -G[3, 0, 0].real  # a real value: 1+0i, (1+0j)
    G[4, 1, 0] = 1j * G[4, 1, 0].imag  # a pure imaginary one
    var = np.abs(G) ** 2 * 1e-4
    path = write_complex_csv(tmp_path / "a.csv", F, G, spelling=spelling, variance=var)
    text = path.read_text()
    assert {"numpy": "j)", "matlab": "i,", "matlab-old": "+-", "spaced": " - "}[spelling] in text
    header = 'records = "labels"\noutputs = ["head", "carriage"]\ninputs = ["torque"]\n'
    header += 'sigma = { from = "variance" }'
    loaded = lpvid.FrfData.from_files(write_manifest(tmp_path / "m.toml", header, [(0, "a.csv")]))
    np.testing.assert_array_equal(loaded.freqs_hz, F)
    np.testing.assert_array_equal(loaded.G[0], G)  # %.18e and %.17g round-trip every double
    np.testing.assert_allclose(loaded.sigma[0], np.sqrt(var), rtol=1e-15)


def test_a_complex_cell_in_a_real_column_names_line_and_column(tmp_path):
    path = write_csv(tmp_path / "a.csv", F, np.ones((F.size, 2, 1)) * (1 + 1j))
    lines = path.read_text().splitlines()
    cells = lines[4].split(",")
    cells[1] = " 1+2i"
    lines[4] = ",".join(cells)
    path.write_text("\n".join(lines))
    refused(
        path,
        r"^a.csv, line 5, column 'head/torque re \[m/s\^2/N m\]': a complex number where "
        r"a real one belongs: '1\+2i'",
    )


# ------------------------------------------------------------------ nothing matches
def mismatch(folder, kind):
    """One point of a 2 x 1 system whose files do not hold output 'head'."""
    g = np.ones((F.size, 2, 1)) * (1 + 1j)
    if kind == "csv":
        write_complex_csv(folder / "tube42.csv", F, g, labels=("carriage", "tip"))
        files = "tube42.csv"
    elif kind == "mat":
        write_mat(folder / "tube42.mat", F, g, unit="Hz", outputs=("y1", "y2"))
        files = "tube42.mat"
    else:  # a UFF file (nodes 3 and 2) with a CSV file beside it
        write_uff(folder / "tube42.uff", F, g, rows=(1,))
        write_complex_csv(folder / "tube42.csv", F, g[:, :1], labels=("tip",))
        files = ["tube42.uff", "tube42.csv"]
    header = 'records = "labels"\n'
    header += (
        'outputs = [{ name = "head", node = 7, dir = "+X" }, { name = "carriage", node = 2 }]\n'
    )
    header += f'inputs = [{{ name = "{INPUTS[0]}", node = 1 }}]'
    return write_manifest(folder / "m.toml", header, [(42.0, files)])


@pytest.mark.parametrize(
    "kind, message",
    [
        (
            "csv",
            r"^tube42.csv: no FRF record matches output 'head' / input 'torque'; tube42.csv "
            r"\(looked for label 'head' / label 'torque'\) holds the FRF records "
            r"'carriage/torque', 'tip/torque'$",
        ),
        (
            "mat",
            r"^tube42.mat: no FRF record matches output 'head' / input 'torque'; tube42.mat "
            r"\(looked for label 'head' / label 'torque'\) holds the FRF records "
            r"'y1' / 'torque' \(sys.ResponseData\(1,1,:\)\), "
            r"'y2' / 'torque' \(sys.ResponseData\(2,1,:\)\)$",
        ),
        (
            "both",
            r"^tube42.uff, tube42.csv: no FRF record matches output 'head' / input 'torque'; "
            r"tube42.uff \(looked for node 7 \+X / node 1\) holds the FRF records "
            r"node 2 \+X / node 1 \+Z \(record 1\); "
            r"tube42.csv \(looked for label 'head' / label 'torque'\) holds the FRF records "
            r"'tip/torque'$",
        ),
    ],
)
def test_no_match_lists_what_each_file_holds(tmp_path, kind, message):
    with pytest.raises(ValueError, match=message):
        lpvid.FrfData.from_files(mismatch(tmp_path, kind))


def test_a_point_names_its_channels_anew(tmp_path):
    """Per point: its own records order and its own labels; the rest from the top."""
    g = [np.ones((F.size, 2, 1)) * (1 + q + 1j) for q in range(3)]
    write_uff(tmp_path / "a.uff", F, g[0], rows=(1, 0))
    write_complex_csv(tmp_path / "b.csv", F, g[1][:, ::-1], labels=("Carriage", "Head"))
    write_mat(tmp_path / "c.mat", F, g[2], unit="Hz", outputs=("", ""))  # no names
    header = 'records = "labels"\n'
    header += 'outputs = [{ name = "head", node = 3 }, { name = "carriage", node = 2 }]\n'
    header += 'inputs = [{ name = "torque", node = 1 }]\n'
    manifest = write_manifest(
        tmp_path / "m.toml", header, [(0, "a.uff"), (1, "b.csv"), (2, "c.mat")]
    )
    text = manifest.read_text()
    text = text.replace(
        'file = "b.csv"',
        'file = "b.csv"\noutputs = [{ name = "head", label = "Head" }, '
        '{ name = "carriage", label = "Carriage" }]',
    ).replace('file = "c.mat"', 'file = "c.mat"\nrecords = "output-major"')
    manifest.write_text(text)
    loaded = lpvid.FrfData.from_files(manifest)
    np.testing.assert_allclose(loaded.G, np.stack(g), rtol=5e-12)
    assert loaded.provenance["points"][0]["records"] == ["a.uff, record 2", "a.uff, record 1"]


@pytest.mark.parametrize(
    "point, message",
    [
        ('outputs = [{ name = "tip", label = "x" }]', r"points\[0\].outputs\[0\].name: expected "),
        ('outputs = [{ name = "head", unit = "g" }]', r"points\[0\].outputs\[0\]: unknown key"),
        ('inputs = [{ name = "torque", dir = 3 }]', r"points\[0\].inputs\[0\].dir: needs node"),
        ('outputs = ["head"]', r"points\[0\].outputs\[0\]: expected a table with name"),
        ("outputs = []", r"points\[0\].outputs: expected a list of tables"),
        ('records = "by-name"', r"points\[0\].records: expected one of"),
        (
            'outputs = [{ name = "head", label = "a" }, { name = "head", label = "b" }]',
            r"points\[0\].outputs\[1\].name: 'head' given twice",
        ),
    ],
)
def test_bad_point_naming(tmp_path, point, message):
    write_csv(tmp_path / "a.csv", F, np.ones((F.size, 1, 1)) * (1 + 1j))
    header = 'outputs = ["head"]\ninputs = ["torque"]'
    manifest = write_manifest(tmp_path / "m.toml", header, [(0, "a.csv")])
    manifest.write_text(manifest.read_text().replace('file = "a.csv"', f'file = "a.csv"\n{point}'))
    with pytest.raises(ValueError, match=r"^m.toml: " + message):
        lpvid.FrfData.from_files(manifest)


# ------------------------------------------------------------------ truncated UFF files
def delimiters(data: bytes) -> tuple[list[int], list[int]]:
    """Byte offsets and 1-based line numbers of the '    -1' marks that open and close datasets.

    In a binary dataset the closing mark follows the last value's bytes on its line.
    """
    offsets = [m.start() for m in re.finditer(rb"    -1(?=\r?\n|\Z)", data)]
    return offsets, [data.count(b"\n", 0, at) + 1 for at in offsets]


@pytest.mark.parametrize("binary", [False, True])
def test_a_uff_file_cut_inside_a_dataset_is_refused(tmp_path, binary):
    g = np.ones((F.size, 2, 1)) * (1 + 1j)
    path = write_uff(tmp_path / "a.uff", F, g, binary=binary, coherence=np.full(g.shape, 0.9))
    data = path.read_bytes()
    offsets, lines = delimiters(data)
    assert len(offsets) == 8  # four datasets: FRF, coherence, FRF, coherence
    # Cut the file in the middle of the third dataset (the second FRF).
    cut = (offsets[4] + offsets[5]) // 2
    path.write_bytes(data[:cut])
    last = data[:cut].count(b"\n") + 1
    refused(
        path,
        rf"^a.uff: truncated: the file ends at line {last}, inside dataset 58 \(record 3, "
        rf"from line {lines[4]}\), before the line '    -1' that closes it",
    )


def test_a_uff_dataset_shorter_than_its_header_is_refused(tmp_path):
    g = np.ones((F.size, 2, 1)) * (1 + 1j)
    path = write_uff(tmp_path / "a.uff", F, g)
    _, marks = delimiters(path.read_bytes())
    lines = path.read_bytes().split(b"\n")
    # The second FRF record: 13 header lines after its '-1', then one line per value.
    del lines[marks[2] + 13 : marks[2] + 15]
    path.write_bytes(b"\n".join(lines))
    refused(
        path,
        rf"^a.uff, record 2 \(dataset 58 from line {marks[2]}\): truncated: 9 values where "
        r"its header announces 11",
    )
