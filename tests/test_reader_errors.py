"""Measured-FRF files that cannot be used: each error names the file and the record."""

import sys

import numpy as np
import pytest
from frf_files import coherence_for, write_csv, write_manifest, write_mat, write_uff

import lpvid

F = np.linspace(10.0, 20.0, 11)
P = (30.0, 36.0, 42.0)
BY_NODE = """
outputs = [{ name = "head", node = 3 }, { name = "carriage", node = 2 }]
inputs = [{ name = "torque", node = 1 }]
"""


def frf(q, l=2, r=1):
    k = np.arange(F.size)[:, None, None]
    return (1.0 + q + 0.1 * k) * np.exp(1j * 0.2 * k) * np.ones((1, l, r))


def uff_experiment(folder, records="labels", header="", point1=None, ext="uff"):
    """Three points of a 2-output, 1-input system as UFF; point1 overrides point 1's writer."""
    points = []
    for q, p in enumerate(P):
        name = f"tube{int(p)}.{ext}"
        if q == 1 and point1 is not None:
            point1(folder / name)
        else:
            write_uff(folder / name, F, frf(q))
        points.append((p, name))
    head = f'records = "{records}"\n{header}\n{BY_NODE}'
    return write_manifest(folder / "m.toml", head, points)


def load(manifest, **kw):
    return lpvid.FrfData.from_files(manifest, **kw)


# ------------------------------------------------------------------ the four cases
@pytest.mark.parametrize(
    "records, message",
    [
        (
            "labels",
            r"^tube36.uff: no FRF record matches output 'carriage' / input 'torque'; tube36.uff "
            r"\(looked for node 2 / node 1\) holds the FRF records node 3 \+X / node 1 \+Z "
            r"\(record 1\)$",
        ),
        ("output-major", r"tube36.uff: missing FRF records: found 1, expected 2"),
    ],
)
def test_missing_record(tmp_path, records, message):
    manifest = uff_experiment(
        tmp_path, records, point1=lambda path: write_uff(path, F, frf(1), drop=(1, 0))
    )
    with pytest.raises(ValueError, match=message):
        load(manifest)


@pytest.mark.parametrize("records", ["labels", "output-major"])
def test_auto_spectrum_instead_of_frf(tmp_path, records):
    manifest = uff_experiment(
        tmp_path, records, point1=lambda path: write_uff(path, F, frf(1), func_type=2)
    )
    message = r"tube36.uff, record 1: a record of type auto spectrum \(function type 2\), "
    with pytest.raises(ValueError, match=message + "expected an FRF"):
        load(manifest)


@pytest.mark.parametrize("fmt", ["csv", "mat"])
def test_nan_lines(tmp_path, fmt):
    def broken(path):
        g = frf(1)
        g[3, 1, 0] = np.nan
        if fmt == "csv":
            write_csv(path, F, g)
        else:
            write_mat(path, F, g, unit="Hz")

    points = []
    for q, p in enumerate(P):
        name = f"tube{int(p)}.{fmt}"
        if q == 1:
            broken(tmp_path / name)
        elif fmt == "csv":
            write_csv(tmp_path / name, F, frf(q))
        else:
            write_mat(tmp_path / name, F, frf(q), unit="Hz")
        points.append((p, name))
    header = 'outputs = ["head", "carriage"]\ninputs = ["torque"]\n'
    manifest = write_manifest(tmp_path / "m.toml", header, points)
    record = (
        r"columns 'carriage/torque re \[.*\]', 'carriage/torque im \[.*\]'"
        if fmt == "csv"
        else (r"sys.ResponseData\(2,1,:\)")
    )
    with pytest.raises(
        ValueError,
        match=rf"tube36.{fmt}, {record}: NaN or Inf at 1 of 11 frequency lines \(13 Hz\)",
    ):
        load(manifest)


def test_inconsistent_units_between_points(tmp_path):
    manifest = uff_experiment(
        tmp_path, point1=lambda path: write_uff(path, F, frf(1), units=("g", "N m"))
    )
    with pytest.raises(
        ValueError,
        match=r"tube36.uff, record 1: inconsistent units: 'g/N m' for head/torque, but "
        r"tube30.uff, record 1 has 'm/s\^2/N m'",
    ):
        load(manifest)


def test_units_that_disagree_with_the_manifest(tmp_path):
    manifest = uff_experiment(tmp_path)
    text = (
        manifest.read_text()
        .replace('name = "head", node = 3', 'name = "head", node = 3, unit = "mm/s^2"')
        .replace('name = "torque", node = 1', 'name = "torque", node = 1, unit = "N m"')
    )
    manifest.write_text(text)
    with pytest.raises(
        ValueError,
        match=r"tube30.uff, record 1: inconsistent units: the file says 'm/s\^2/N m', the "
        r"manifest 'mm/s\^2/N m'",
    ):
        load(manifest)


def test_inconsistent_units_within_a_csv_pair(tmp_path):
    path = write_csv(tmp_path / "a.csv", F, frf(0, 1, 1))
    path.write_text(path.read_text().replace("im [m/s^2/N m]", "im [g/N]"))
    manifest = write_manifest(
        tmp_path / "m.toml", 'outputs = ["y"]\ninputs = ["u"]', [(0, "a.csv")]
    )
    with pytest.raises(
        ValueError, match=r"a.csv: columns .* inconsistent units \[m/s\^2/N m\] and \[g/N\]"
    ):
        load(manifest)


# ------------------------------------------------------------------ other bad files
def test_frequency_unit_that_is_not_known(tmp_path):
    write_csv(tmp_path / "a.csv", F, frf(0, 1, 1), freq_unit="furlong")
    manifest = write_manifest(
        tmp_path / "m.toml", 'outputs = ["y"]\ninputs = ["u"]', [(0, "a.csv")]
    )
    with pytest.raises(
        ValueError, match=r"a.csv, columns .*: frequency axis: unknown frequency unit 'furlong'"
    ):
        load(manifest)


def test_csv_cell_that_is_not_a_number(tmp_path):
    path = write_csv(tmp_path / "a.csv", F, frf(0, 1, 1))
    lines = path.read_text().splitlines()
    lines[4] = lines[4].split(",")[0] + ", x, 1.0"
    path.write_text("\n".join(lines))
    manifest = write_manifest(
        tmp_path / "m.toml", 'outputs = ["y"]\ninputs = ["u"]', [(0, "a.csv")]
    )
    with pytest.raises(
        ValueError, match=r"a.csv, line 5, column 'head/torque re .*': not a number: 'x'"
    ):
        load(manifest)


def test_file_that_is_not_uff(tmp_path):
    manifest = uff_experiment(tmp_path, point1=lambda path: path.write_text("hello\n"))
    with pytest.raises(ValueError, match=r"tube36.uff: no dataset 58 .*no UFF datasets"):
        load(manifest)


def test_uff_without_pyuff_says_how_to_install_it(tmp_path, monkeypatch):
    manifest = uff_experiment(tmp_path)
    monkeypatch.setitem(sys.modules, "pyuff", None)
    with pytest.raises(ValueError, match=r"tube30.uff: reading UFF files needs .*lpvid\[uff\]"):
        load(manifest)


def test_coherence_of_one_names_the_record(tmp_path):
    def noise_free(path):
        coh = coherence_for(frf(1), np.full((F.size, 2, 1), 1e-3), 10)
        coh[4, 1, 0] = 1.0
        write_uff(path, F, frf(1), coherence=coh)

    def with_coherence(path):
        write_uff(path, F, frf(0), coherence=np.full((F.size, 2, 1), 0.9))

    manifest = uff_experiment(
        tmp_path, header='sigma = { from = "coherence", averages = 10 }', point1=noise_free
    )
    for q in (0, 2):
        with_coherence(tmp_path / f"tube{int(P[q])}.uff")
    with pytest.raises(
        ValueError, match=r"tube36.uff, record 4: coherence must lie in \(0, 1\); found 1 at line 5"
    ):
        load(manifest)


def test_missing_coherence_record(tmp_path):
    manifest = uff_experiment(tmp_path, header='sigma = { from = "coherence", averages = 10 }')
    with pytest.raises(
        ValueError,
        match=r"^tube30.uff: no coherence record matches output 'head' / input 'torque'; "
        r"tube30.uff \(looked for node 3 / node 1\) holds no coherence records$",
    ):
        load(manifest)


def test_mat_without_response_data(tmp_path):
    from scipy.io import savemat

    manifest = uff_experiment(
        tmp_path,
        records="output-major",
        point1=lambda path: savemat(path, {"sys": {"Frequency": F, "Ts": 0.0}}),
        ext="mat",
    )
    for q in (0, 2):
        write_mat(tmp_path / f"tube{int(P[q])}.mat", F, frf(q))
    with pytest.raises(ValueError, match=r"tube36.mat, sys: no field ResponseData"):
        load(manifest)


@pytest.mark.parametrize(
    "file_ts, manifest_ts, message",
    [
        (0.001, "Ts = 0.002", r"tube30.mat: Ts = 0.001 s, but m.toml gives Ts = 0.002 s"),
        (None, "Ts = 0.002", r"tube30.mat: continuous-time data \(Ts = 0\), but m.toml gives"),
        (-1.0, "", r"tube30.mat: discrete-time data with an unknown sample time"),
    ],
)
def test_sample_time_of_a_mat_file_disagrees(tmp_path, file_ts, manifest_ts, message):
    points = []
    for q, p in enumerate(P):
        write_mat(tmp_path / f"tube{int(p)}.mat", F, frf(q), Ts=file_ts, unit="Hz")
        points.append((p, f"tube{int(p)}.mat"))
    header = f'{manifest_ts}\noutputs = ["head", "carriage"]\ninputs = ["torque"]'
    with pytest.raises(ValueError, match=message):
        load(write_manifest(tmp_path / "m.toml", header, points))


def test_duplicate_scheduling_values_name_the_manifest(tmp_path):
    manifest = uff_experiment(tmp_path)
    manifest.write_text(manifest.read_text().replace("p = 42.0", "p = 30.0"))
    with pytest.raises(ValueError, match=r"m.toml: p: scheduling values must be distinct"):
        load(manifest)


# ------------------------------------------------------------------ bad manifests
@pytest.mark.parametrize(
    "edit, message",
    [
        (("Ts = 1", "Ts = 1\nsampletime = 2"), r"m.toml: unknown key\(s\) sampletime"),
        (("Ts = 1", 'Ts = "fast"'), r"m.toml: Ts: expected a number, got 'fast'"),
        (("p = 36.0", 'p = "x"'), r"m.toml: points\[1\].p: expected a number, got 'x'"),
        (("p = 36.0", "p = [36.0, 1.0]"), r"points\[1\].p: 2 scheduling values, but points\[0\]"),
        (('file = "tube36.uff"', 'file = "nope.uff"'), r"points\[1\].file: no such file: nope"),
        (('file = "tube36.uff"', 'file = "tube36.txt"'), r"cannot tell the format of tube36.txt"),
        (("Ts = 1", 'Ts = 1\nsigma = { from = "coherence" }'), r"sigma.averages: expected the"),
        (("Ts = 1", 'Ts = 1\nsigma = { from = "psd" }'), r"sigma.from: expected one of"),
        (("Ts = 1", 'Ts = 1\nsigma = { from = "relative", level = -1 }'), r"level: expected a"),
        (("Ts = 1", 'Ts = 1\nparameters = ["a", "b"]'), r"parameters: 2 names for 1 scheduling"),
        (('records = "labels"', 'records = "by-name"'), r"records: expected one of"),
        (('{ name = "carriage", node = 2 }', '{ name = "head" }'), r"outputs: names must differ"),
        (('{ name = "torque", node = 1 }', '{ name = "torque", dir = 3 }'), r"dir: needs node"),
        (("inputs = ", "inputz = "), r"m.toml: unknown key\(s\) inputz"),
        (("[[points]]", "[points"), r"m.toml: not a valid TOML file"),
    ],
)
def test_bad_manifest(tmp_path, edit, message):
    manifest = uff_experiment(tmp_path, header="Ts = 1")
    (tmp_path / "tube36.txt").write_text("an export of unknown kind\n")
    old, new = edit
    text = manifest.read_text()
    assert old in text
    manifest.write_text(text.replace(old, new, 1))
    with pytest.raises(ValueError, match=message):
        load(manifest)


def test_sigma_given_for_some_points_only(tmp_path):
    manifest = uff_experiment(tmp_path)
    text = manifest.read_text().replace(
        'file = "tube36.uff"', 'file = "tube36.uff"\nsigma = { from = "relative", level = 0.1 }'
    )
    manifest.write_text(text)
    with pytest.raises(ValueError, match=r"m.toml: points\[0\] has no sigma while other points"):
        load(manifest)


def test_missing_manifest(tmp_path):
    with pytest.raises(ValueError, match=r"nothing.toml: no such manifest"):
        load(tmp_path / "nothing.toml")


def test_manifest_argument_of_the_wrong_type():
    with pytest.raises(TypeError, match=r"^manifest: expected the path of a \.toml file, got int"):
        load(3)


def test_direction_codes_and_channel_texts():
    from lpvid.readers.records import Channel, direction_name, parse_direction

    names = ["+X", "+Y", "+Z", "+RX", "+RY", "+RZ"]
    assert [direction_name(k) for k in range(1, 7)] == names
    assert [direction_name(-k) for k in range(1, 7)] == [n.replace("+", "-") for n in names]
    assert direction_name(0) == direction_name(None) == ""
    # parse_direction is its inverse
    assert all(parse_direction(direction_name(k), "d") == k for k in [*range(-6, 0), *range(1, 7)])
    assert Channel(label="head", node=3, direction=-5, index=None).describe() == "'head' node 3 -RY"
    assert Channel(label=None, node=None, direction=None, index=0).describe() == "#1"
    assert Channel(label=None, node=None, direction=None, index=None).describe() == "unlabelled"
