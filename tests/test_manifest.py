"""The experiment manifest, key by key, and the experiment's sample time, units and sigma.

Manifests here are TOML texts written by the tests; data files by numpy and
scipy (frf_files.py). Every refusal must name the manifest and the key.
"""

import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from frf_files import write_csv, write_manifest, write_mat

import lpvid
from lpvid.readers.experiment import _check_units, _point_label, _sample_time, read_file
from lpvid.readers.manifest import ChannelSpec, SigmaSpec, read_manifest
from lpvid.readers.records import Channel, FileError, Record

HEAD = 'outputs = ["y1", "y2"]\ninputs = ["u"]\n'
POINT = '[[points]]\np = 1.0\nfile = "a.uff"\n'
F = np.linspace(10.0, 20.0, 11)


def manifest(folder: Path, text: str):
    """The manifest ``text`` read, with empty data files a.uff, b.csv, c.mat, d.txt next to it."""
    for name in ("a.uff", "b.csv", "c.mat", "d.txt"):
        (folder / name).write_text("")
    (folder / "m.toml").write_text(text)
    return read_manifest(folder / "m.toml")


def refused(folder: Path, text: str, message: str) -> None:
    with pytest.raises(FileError, match=message):
        manifest(folder, text)


# ------------------------------------------------------------------ what is read
def test_defaults_and_the_values_given(tmp_path):
    """Rejects lost defaults, formats, paths and records modes."""
    m = manifest(tmp_path, HEAD + POINT)
    assert (m.Ts, m.parameters, m.records, m.name) == (None, None, "output-major", "m.toml")
    (pt,) = m.points
    assert (pt.index, pt.p, pt.sigma, pt.variable, pt.records) == (0, (1.0,), None, None, m.records)
    assert pt.files == (tmp_path.resolve() / "a.uff",)
    assert pt.formats == ("uff",)
    assert m.outputs == (ChannelSpec("y1"), ChannelSpec("y2")) and m.inputs == (ChannelSpec("u"),)


def test_formats_from_suffixes_and_as_given(tmp_path):
    """Rejects a format key ignored, refused or lost, and suffixes read wrongly."""
    for name in ("e.UNV", "f.uf", "g.MAT"):
        (tmp_path / name).write_text("")
    text = (
        HEAD + 'format = "csv"\nrecords = "labels"\nvariable = " sys "\nTs = 0.5\n'
        '[[points]]\np = 1.0\nfiles = ["d.txt", "a.uff"]\n'
        '[[points]]\np = 2.0\nfile = "d.txt"\nformat = "mat"\nrecords = "input-major"\n'
        'variable = "other"\n'
    )
    m = manifest(tmp_path, text)
    assert m.Ts == 0.5 and m.records == "labels"
    assert [pt.formats for pt in m.points] == [("csv", "csv"), ("mat",)]
    assert [pt.records for pt in m.points] == ["labels", "input-major"]
    assert [pt.variable for pt in m.points] == ["sys", "other"]
    text = HEAD + '[[points]]\np = 1.0\nfiles = ["e.UNV", "f.uf", "g.MAT", "b.csv", "c.mat"]\n'
    assert manifest(tmp_path, text).points[0].formats == ("uff", "uff", "mat", "csv", "mat")


def test_an_absolute_file_path_is_kept(tmp_path):
    """Rejects absolute paths resolved against the manifest's folder."""
    other = tmp_path / "elsewhere"
    other.mkdir()
    (other / "x.csv").write_text("")
    m = manifest(tmp_path, HEAD + f'[[points]]\np = 1.0\nfile = "{(other / "x.csv").as_posix()}"\n')
    assert m.points[0].files == (other / "x.csv",)


def test_channels_as_tables_and_a_point_naming_them_anew(tmp_path):
    """Rejects a point's override losing the label, node or direction it does not give."""
    text = (
        'outputs = [{ name = "y1", label = "Y1", node = 3, dir = "-Z", unit = " m " }, "y2"]\n'
        'inputs = [{ name = "u", node = 1, dir = 3, unit = "N" }]\n'
        '[[points]]\np = [1.0, 2.0]\nfile = "a.uff"\n'
        'outputs = [{ name = "y1", label = "first" }, { name = "y2", node = 7 }]\n'
        '[[points]]\np = [2.0, 3.0]\nfile = "a.uff"\n'
        'inputs = [{ name = "u", node = 5 }]\n'
        '[[points]]\np = [3.0, 4.0]\nfile = "a.uff"\n'
        'outputs = [{ name = "y1", node = 4, dir = "X" }]\n'
    )
    m = manifest(tmp_path, text)
    y1 = ChannelSpec("y1", label="Y1", node=3, direction=-3, unit="m")
    u = ChannelSpec("u", node=1, direction=3, unit="N")
    assert m.outputs == (y1, ChannelSpec("y2")) and m.inputs == (u,)
    first, second, third = m.points
    assert first.outputs == (
        ChannelSpec("y1", label="first", node=3, direction=-3, unit="m"),
        ChannelSpec("y2", node=7),
    )
    assert first.inputs == (u,)
    assert second.outputs == m.outputs
    assert second.inputs == (ChannelSpec("u", node=5, direction=3, unit="N"),)
    assert third.outputs[0] == ChannelSpec("y1", label="Y1", node=4, direction=1, unit="m")
    assert [pt.p for pt in m.points] == [(1.0, 2.0), (2.0, 3.0), (3.0, 4.0)]


@pytest.mark.parametrize(
    "sigma, spec",
    [
        ('{ from = "coherence", averages = 2 }', SigmaSpec("coherence", averages=2)),
        ('{ from = "variance" }', SigmaSpec("variance")),
        ('{ from = "relative", level = 0.25 }', SigmaSpec("relative", level=0.25)),
    ],
)
def test_sigma_sources(tmp_path, sigma, spec):
    """Rejects two averages refused and a source or level lost."""
    text = HEAD + f"sigma = {sigma}\n" + POINT + POINT.replace("1.0", "2.0")
    text += 'sigma = { from = "relative", level = 3 }\n'
    m = manifest(tmp_path, text)
    assert [pt.sigma for pt in m.points] == [spec, SigmaSpec("relative", level=3.0)]


def test_parameters(tmp_path):
    """Rejects the names of the scheduling parameters lost."""
    text = HEAD + 'parameters = ["a", "b"]\n' + POINT.replace("1.0", "[1.0, 2]")
    assert manifest(tmp_path, text).parameters == ("a", "b")


# ------------------------------------------------------------------ what is refused
BAD = [
    # the top of the manifest
    ("Ts = 0\n" + HEAD + POINT, r"^m\.toml: Ts: expected a number > 0, got 0$"),
    ("Ts = -0.1\n" + HEAD + POINT, r"^m\.toml: Ts: expected a number > 0"),
    ("Ts = inf\n" + HEAD + POINT, r"^m\.toml: Ts: expected a finite number, got inf$"),
    ("Ts = true\n" + HEAD + POINT, r"^m\.toml: Ts: expected a number, got True$"),
    ('outputs = "y1"\ninputs = ["u"]\n' + POINT, r"^m\.toml: outputs: expected a list of names"),
    ('outputs = []\ninputs = ["u"]\n' + POINT, r"^m\.toml: outputs: expected a list of names"),
    ('outputs = ["y"]\n' + POINT, r"^m\.toml: inputs: expected a list of names or tables"),
    ('outputs = [3]\ninputs = ["u"]\n' + POINT, r"^m\.toml: outputs\[0\]: expected a name or a"),
    (
        'outputs = [{ name = "y", colour = 1 }]\ninputs = ["u"]\n' + POINT,
        r"^m\.toml: outputs\[0\]: unknown key\(s\) colour \(known: dir, label, name, node, unit\)$",
    ),
    ('outputs = ["y", " "]\ninputs = ["u"]\n' + POINT, r"^m\.toml: outputs\[1\]\.name: expected"),
    ('outputs = [{ label = "y" }]\ninputs = ["u"]\n' + POINT, r"^m\.toml: outputs\[0\]\.name: mi"),
    ('outputs = ["y"]\ninputs = [{ name = "u", unit = 2 }]\n' + POINT, r"inputs\[0\]\.unit: exp"),
    ('outputs = [{ name = "y", node = true }]\ninputs = ["u"]\n' + POINT, r"outputs\[0\]\.node: "),
    ('outputs = [{ name = "y", node = "3" }]\ninputs = ["u"]\n' + POINT, r"outputs\[0\]\.node: "),
    (
        'outputs = [{ name = "y", node = 1, dir = "up" }]\ninputs = ["u"]\n' + POINT,
        r"^m\.toml: outputs\[0\]\.dir: expected a direction",
    ),
    (
        'outputs = [{ name = "y", label = "" }]\ninputs = ["u"]\n' + POINT,
        r"^m\.toml: outputs\[0\]\.label: expected a non-empty string, got ''$",
    ),
    (HEAD + 'format = "xls"\n' + POINT, r"^m\.toml: format: expected one of \['csv', 'mat', 'uff'"),
    (HEAD + "variable = 3\n" + POINT, r"^m\.toml: variable: expected a non-empty string, got 3$"),
    (HEAD + 'variable = "  "\n' + POINT, r"^m\.toml: variable: expected a non-empty string"),
    (HEAD + 'sigma = "coherence"\n' + POINT, r"^m\.toml: sigma: expected a table such as \{ fr"),
    (
        HEAD + 'sigma = { from = "variance", averages = 3 }\n' + POINT,
        r"^m\.toml: sigma: unknown key\(s\) averages",
    ),
    (HEAD + 'sigma = { from = "coherence", averages = 1 }\n' + POINT, r"sigma\.averages: exp"),
    (HEAD + 'sigma = { from = "coherence", averages = 2.0 }\n' + POINT, r"sigma\.averages: exp"),
    (HEAD + 'sigma = { from = "coherence", averages = true }\n' + POINT, r"sigma\.averages: "),
    (HEAD + 'sigma = { from = "relative" }\n' + POINT, r"^m\.toml: sigma\.level: missing \(sigma"),
    (HEAD + 'sigma = { from = "relative", level = 0 }\n' + POINT, r"^m\.toml: sigma\.level: exp"),
    (HEAD + 'parameters = "a"\n' + POINT, r"^m\.toml: parameters: expected a list of names$"),
    (HEAD + 'parameters = ["a", 3]\n' + POINT, r"^m\.toml: parameters: expected a list of names$"),
    (
        "Ts = 1\nsampletime = 2\nrate = 3\n" + HEAD + POINT,
        r"^m\.toml: unknown key\(s\) rate, sampletime \(known: Ts, description, format, inputs",
    ),
    # the points
    (HEAD, r"^m\.toml: points: expected one or more \[\[points\]\] tables .*, got nothing$"),
    (HEAD + "points = 3\n", r"^m\.toml: points: expected one or more .*, got int$"),
    (HEAD + "points = []\n", r"^m\.toml: points: expected one or more .*, got list$"),
    (HEAD + "points = [1]\n", r"^m\.toml: points\[0\]: expected a table with p and file$"),
    (HEAD + POINT + "filez = 1\n", r"^m\.toml: points\[0\]: unknown key\(s\) filez \(known: f"),
    (HEAD + '[[points]]\nfile = "a.uff"\n', r"^m\.toml: points\[0\]\.p: missing \(the sched"),
    (HEAD + POINT.replace("1.0", "[]"), r"^m\.toml: points\[0\]\.p: expected at least one sch"),
    (HEAD + POINT.replace("1.0", '[1.0, "x"]'), r"^m\.toml: points\[0\]\.p\[1\]: expected a num"),
    (
        HEAD + POINT + POINT + POINT.replace("1.0", "[1.0, 2.0]"),
        r"^m\.toml: points\[2\]\.p: 2 scheduling values, but points\[0\] has 1$",
    ),
    (HEAD + "[[points]]\np = 1\n", r"^m\.toml: points\[0\]: give either file = \"\.\.\.\" or f"),
    (HEAD + POINT + 'files = ["a.uff"]\n', r"^m\.toml: points\[0\]: give either file"),
    (HEAD + '[[points]]\np = 1\nfiles = "a.uff"\n', r"^m\.toml: points\[0\]\.files: expected a l"),
    (HEAD + "[[points]]\np = 1\nfiles = []\n", r"^m\.toml: points\[0\]\.files: expected a list"),
    (HEAD + "[[points]]\np = 1\nfile = 3\n", r"^m\.toml: points\[0\]\.file: expected file names"),
    (HEAD + '[[points]]\np = 1\nfiles = [" "]\n', r"^m\.toml: points\[0\]\.files: expected file"),
    (
        HEAD + '[[points]]\np = 1\nfile = "d.txt"\n',
        r"^m\.toml: points\[0\]: cannot tell the format of d\.txt from its suffix "
        r"\(known: \.uff, \.unv, \.uf, \.csv, \.mat\)",
    ),
    (HEAD + POINT + 'format = "xls"\n', r"^m\.toml: points\[0\]\.format: expected one of"),
    (HEAD + POINT + 'variable = ""\n', r"^m\.toml: points\[0\]\.variable: expected a non-empty"),
    (HEAD + POINT + 'sigma = { from = "x" }\n', r"^m\.toml: points\[0\]\.sigma\.from: expected"),
    (HEAD + POINT + 'records = "rows"\n', r"^m\.toml: points\[0\]\.records: expected one of"),
    (
        HEAD + POINT + 'outputs = "y1"\n',
        r'^m\.toml: points\[0\]\.outputs: expected a list of tables such as \{ name = "y1", '
        r'label = "\.\.\." \}$',
    ),
    (HEAD + POINT + "inputs = [3]\n", r"^m\.toml: points\[0\]\.inputs\[0\]: expected a table"),
    (
        HEAD + POINT + 'outputs = [{ name = "y1", unit = "m" }]\n',
        r"^m\.toml: points\[0\]\.outputs\[0\]: unknown key\(s\) unit \(known: dir, label, name",
    ),
    (
        HEAD + POINT + 'outputs = [{ name = "y3", label = "x" }]\n',
        r"^m\.toml: points\[0\]\.outputs\[0\]\.name: expected one of the outputs \['y1', 'y2'\], "
        r"got 'y3'$",
    ),
    (
        HEAD + POINT + 'outputs = [{ name = "y2", label = "x" }, { name = "y2", node = 2 }]\n',
        r"^m\.toml: points\[0\]\.outputs\[1\]\.name: 'y2' given twice for this point$",
    ),
    (
        HEAD + POINT + 'outputs = [{ name = "y2", node = 2, dir = "W" }]\n',
        r"^m\.toml: points\[0\]\.outputs\[0\]\.dir: expected a direction",
    ),
]


@pytest.mark.parametrize("text, message", BAD)
def test_bad_manifests_name_the_key(tmp_path, text, message):
    """Rejects a wrong value accepted, or refused without naming the manifest and the key."""
    refused(tmp_path, text, message)


def test_a_manifest_that_cannot_be_read(tmp_path):
    """Rejects a folder given as the manifest going unnamed."""
    (tmp_path / "m.toml").mkdir()
    with pytest.raises(FileError, match=r"^m\.toml: cannot read the manifest"):
        read_manifest(tmp_path / "m.toml")


# ------------------------------------------------------------------ the sample time
def sample_time(Ts, file_ts):
    return _sample_time(SimpleNamespace(Ts=Ts, name="m.toml"), file_ts)


def test_sample_time_from_the_files():
    """Rejects the files' sample time lost, or 0 and -1 taken for one."""
    assert sample_time(None, [("a.mat", 0.01), ("b.mat", 0.01 * (1 + 1e-12))]) == 0.01
    assert sample_time(None, [("a.mat", 1.0)]) == 1.0
    assert sample_time(None, [("a.mat", 0.0), ("b.mat", 0.0)]) is None
    assert sample_time(None, []) is None
    assert sample_time(0.5, [("a.mat", -1.0), ("b.mat", 0.5), ("c.mat", -1.0)]) == 0.5
    assert sample_time(0.5, []) == 0.5


@pytest.mark.parametrize(
    "Ts, file_ts, message",
    [
        (
            None,
            [("a.mat", 0.0), ("b.mat", 0.01)],
            r"^b\.mat: Ts = 0\.01 s, but a\.mat has Ts = 0 s \(0: continuous time\)$",
        ),
        (
            None,
            [("a.mat", 0.01), ("b.mat", 0.02)],
            r"^b\.mat: Ts = 0\.02 s, but a\.mat has Ts = 0\.01 s",
        ),
        (
            None,
            [("a.mat", 0.01), ("b.mat", 0.0)],
            r"^b\.mat: Ts = 0 s, but a\.mat has Ts = 0\.01 s",
        ),
        (
            0.5,
            [("a.mat", 0.5), ("b.mat", 0.25)],
            r"^b\.mat: Ts = 0\.25 s, but m\.toml gives Ts = 0\.5 s$",
        ),
    ],
)
def test_sample_times_that_disagree(Ts, file_ts, message):
    """Rejects files of different sample times (or continuous and discrete) mixed silently."""
    with pytest.raises(FileError, match=message):
        sample_time(Ts, file_ts)


# ------------------------------------------------------------------ units
def record(i, units, name, kind="frf"):
    ch = Channel(label=None, node=None, direction=None, index=i)
    return Record("f.uff", name, kind, ch, ch, F, np.ones(F.size, complex), units)


def units_manifest(out_units=(None, None), in_unit=None):
    outs = tuple(ChannelSpec(f"y{i + 1}", unit=u) for i, u in enumerate(out_units))
    return SimpleNamespace(outputs=outs, inputs=(ChannelSpec("u", unit=in_unit),))


def test_pairs_of_different_units():
    """Rejects the units of one pair compared with those of another."""
    chosen = [record(0, "m/N", "r1"), record(1, "rad/N", "r2")] * 2
    slots = [(q, "frf", i, 0) for q in (0, 1) for i in (0, 1)]
    _check_units(units_manifest(), chosen, slots)
    _check_units(units_manifest(("m", "rad"), "N"), chosen, slots)


def test_units_checked_past_unstated_units_and_coherence():
    """Rejects the check stopping at a record without units or one of coherence."""
    for first in (record(0, None, "r0"), record(0, None, "c0", kind="coherence")):
        chosen = [record(0, "m/N", "r1"), first, record(0, "m/N", "r2"), record(0, "mm/N", "r3")]
        slots = [(0, "frf", 0, 0), (0, first.kind, 0, 0), (1, "frf", 0, 0), (2, "frf", 0, 0)]
        with pytest.raises(FileError, match=r"^f\.uff, r3: inconsistent units: 'mm/N' for y1/u"):
            _check_units(units_manifest((None,)), chosen, slots)
        with pytest.raises(FileError, match=r"^f\.uff, r3: inconsistent units: the file says"):
            _check_units(units_manifest(("m",), "N"), chosen, slots)


# ------------------------------------------------------------------ reading files
def test_point_label_of_several_scheduling_values(tmp_path):
    """Rejects a point of two scheduling values labelled by its first one."""
    text = HEAD + POINT.replace("1.0", "[1.5, 2.0]") + POINT.replace("1.0", "[3, 4]")
    m = manifest(tmp_path, text)
    assert [_point_label(pt) for pt in m.points] == [
        "points[0] (p=[1.5, 2.0])",
        "points[1] (p=[3.0, 4.0])",
    ]
    m = manifest(tmp_path, HEAD + POINT)
    assert _point_label(m.points[0]) == "points[0] (p=1.0)"


def test_read_file_of_an_unknown_format(tmp_path):
    """Rejects a format other than uff, csv and mat going unnamed."""
    with pytest.raises(ValueError, match=r"^fmt: expected 'uff', 'csv' or 'mat', got 'xls'$"):
        read_file(tmp_path / "a.xls", "xls")


def frf(q, l=2, r=1):
    k = np.arange(F.size)[:, None, None]
    return (1.0 + q + 0.1 * k) * np.exp(1j * 0.2 * k) * np.ones((1, l, r))


def test_the_variable_the_manifest_names_is_read(tmp_path):
    """Rejects the manifest's variable ignored when a MAT file holds two systems."""
    from scipy.io import loadmat, savemat

    write_mat(tmp_path / "one.mat", F, frf(0))
    write_mat(tmp_path / "two.mat", F, frf(5))
    both = {
        "sysA": loadmat(tmp_path / "one.mat")["sys"],
        "sysB": loadmat(tmp_path / "two.mat")["sys"],
    }
    savemat(tmp_path / "both.mat", both)
    header = 'outputs = ["head", "carriage"]\ninputs = ["torque"]\nvariable = "sysB"'
    data = lpvid.FrfData.from_files(
        write_manifest(tmp_path / "m.toml", header, [(1.0, "both.mat")])
    )
    np.testing.assert_array_equal(data.G[0], frf(5))


def test_a_point_without_sigma_and_several_scheduling_values(tmp_path):
    """Rejects p of two columns, the parameter names or the 'no sigma' provenance lost."""
    for q in range(3):
        write_mat(tmp_path / f"t{q}.mat", F, frf(q))
    header = 'outputs = ["head", "carriage"]\ninputs = ["torque"]\nparameters = ["a", "b"]'
    points = [([float(q), 2.0 * q], f"t{q}.mat") for q in range(3)]
    data = lpvid.FrfData.from_files(write_manifest(tmp_path / "m.toml", header, points))
    np.testing.assert_array_equal(data.p, [[0, 0], [1, 2], [2, 4]])
    np.testing.assert_array_equal(data.G, [frf(q) for q in range(3)])
    prov = data.provenance
    assert [pt["sigma"] for pt in prov["points"]] == ["none (sigma = 1)"] * 3
    assert [pt["p"] for pt in prov["points"]] == [[0.0, 0.0], [1.0, 2.0], [2.0, 4.0]]
    assert prov["parameters"] == ["a", "b"]


@pytest.mark.parametrize(
    "sigma, message",
    [
        ('{ from = "variance" }', r"t1\.csv, column 'carriage/torque var': variance must be > 0"),
        (
            '{ from = "relative", level = 0.1 }',
            r"^t1\.csv, columns 'carriage/torque re .*: the FRF is 0j at line 5",
        ),
    ],
)
def test_sigma_that_cannot_be_made_names_the_record(tmp_path, sigma, message):
    """Rejects a zero variance or a zero FRF reported without its file and record."""
    for q in range(2):
        G, var = frf(q), np.full((F.size, 2, 1), 0.01)
        if q == 1:
            var[4, 1, 0] = 0.0
            G[4, 1, 0] = 0.0
        write_csv(tmp_path / f"t{q}.csv", F, G, variance=var)
    header = f'outputs = ["head", "carriage"]\ninputs = ["torque"]\nsigma = {sigma}'
    points = [(float(q), f"t{q}.csv") for q in range(2)]
    with pytest.raises(ValueError, match=message):
        lpvid.FrfData.from_files(write_manifest(tmp_path / "m.toml", header, points))


def test_sigma_for_some_points_only_says_how_to_fix_it(tmp_path):
    """Rejects the message of sigma missing at some points without its remedy."""
    for q in range(2):
        write_mat(tmp_path / f"t{q}.mat", F, frf(q))
    header = 'outputs = ["head", "carriage"]\ninputs = ["torque"]'
    path = write_manifest(tmp_path / "m.toml", header, [(float(q), f"t{q}.mat") for q in range(2)])
    path.write_text(path.read_text() + 'sigma = { from = "relative", level = 0.1 }\n')
    message = re.escape(
        "m.toml: points[0] has no sigma while other points have one; give sigma for every point "
        "(or one at the top of the manifest for all)"
    )
    with pytest.raises(ValueError, match=f"^{message}$"):
        lpvid.FrfData.from_files(path)


def test_read_experiment_returns_the_names_and_where_they_came_from(tmp_path):
    """Rejects names, parameters, the manifest path or the files lost, or lines not 'same'."""
    from lpvid.readers.experiment import read_experiment

    for q in range(2):
        write_mat(tmp_path / f"t{q}.mat", F, frf(q))
    header = 'outputs = ["head", "carriage"]\ninputs = ["torque"]\nparameters = ["side"]'
    path = write_manifest(tmp_path / "m.toml", header, [(float(q), f"t{q}.mat") for q in range(2)])
    exp = read_experiment(str(path))
    assert (exp.outputs, exp.inputs, exp.parameters) == (
        ("head", "carriage"),
        ("torque",),
        ("side",),
    )
    assert exp.provenance["manifest"] == str(path)
    assert [pt["files"] for pt in exp.provenance["points"]] == [["t0.mat"], ["t1.mat"]]
    assert exp.provenance["lines"] == {"mode": "same", "kept": F.size, "dropped": [0, 0]}
    np.testing.assert_array_equal(exp.p, [0.0, 1.0])


def test_dropped_lines_are_reported_once(tmp_path):
    """Rejects the warning of dropped lines lost or not naming the point."""
    write_mat(tmp_path / "t0.mat", F, frf(0))
    write_mat(tmp_path / "t1.mat", F[1:], frf(1)[1:])
    header = 'outputs = ["head", "carriage"]\ninputs = ["torque"]'
    path = write_manifest(tmp_path / "m.toml", header, [(0.0, "t0.mat"), (1.0, "t1.mat")])
    with pytest.warns(UserWarning, match=r"dropped 1 at points\[0\] \(p=0\.0\)$") as caught:
        lpvid.FrfData.from_files(path, lines="common")
    assert len(caught) == 1  # its stacklevel is not tested: mutmut's trampoline adds frames


def test_units_of_coherence_records_are_not_those_of_the_frf():
    """Rejects a coherence record's own units checked against the FRF's."""
    chosen = [record(0, "m/N", "r1"), record(0, "1", "c1", kind="coherence")]
    _check_units(units_manifest(("m",), "N"), chosen, [(0, "frf", 0, 0), (0, "coherence", 0, 0)])
