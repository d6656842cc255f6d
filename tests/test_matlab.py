"""MATLAB frd/idfrd files read field by field: what read_mat gives back is what was saved.

Every file here is written with scipy.io.savemat the way MATLAB's ``save``
stores ``s = struct(sys)`` of an idfrd (or the arrays saved by hand): cell
arrays of names as l x 1 / r x 1 object arrays, ResponseData l x r x F
complex, Frequency an F x 1 column, CovarianceData l x r x F x 2 x 2.
"""

import math
import textwrap

import numpy as np
import pytest
from scipy.io import savemat

import lpvid
from lpvid.readers.matlab import read_mat
from lpvid.readers.records import COHERENCE, FRF, VARIANCE, FileError

L, R, F = 2, 3, 5  # outputs, inputs, lines: all different, so that no axis can stand for another
OUTPUTS = ("head", "carriage")
INPUTS = ("torque", "force", "")  # MATLAB's default name is '' (unlabelled)
OUT_UNITS = ("m/s^2", "")  # the carriage's unit left empty
IN_UNITS = ("N m", "N", "V")


def cell(items):
    """A MATLAB cell column (n x 1) as scipy.io writes and reads it."""
    arr = np.empty((len(items), 1), dtype=object)
    arr[:, 0] = list(items)
    return arr


def idfrd(rng, **changes):
    """The fields of struct(sys) of a 2 x 3 idfrd with 5 lines, some MATLAB extras included."""
    G = rng.standard_normal((L, R, F)) + 1j * rng.standard_normal((L, R, F))
    cov = np.zeros((L, R, F, 2, 2))
    cov[..., 0, 0] = rng.uniform(0.1, 1.0, (L, R, F))  # var(Re G)
    cov[..., 1, 1] = rng.uniform(1.0, 3.0, (L, R, F))  # var(Im G), unlike var(Re G)
    cov[..., 0, 1] = cov[..., 1, 0] = 0.05  # correlation of Re and Im: not in E|dG|^2
    fields = {
        "ResponseData": G,
        "Frequency": np.linspace(1.0, 9.0, F)[:, None],  # MATLAB keeps it a column
        "FrequencyUnit": "rad/TimeUnit",
        "TimeUnit": "seconds",
        "Ts": 0.0,
        "OutputName": cell(OUTPUTS),
        "InputName": cell(INPUTS),
        "OutputUnit": cell(OUT_UNITS),
        "InputUnit": cell(IN_UNITS),
        "CovarianceData": cov,
        "IODelay": np.zeros((L, R)),
        "Name": "",
        "Notes": np.empty((0, 0), dtype=object),
    }
    fields.update(changes)
    return {k: v for k, v in fields.items() if v is not None}


def save(path, fields, name="sys"):
    savemat(path, {name: fields} if name else fields)
    return path


def by_kind(records, kind):
    return [rec for rec in records if rec.kind == kind]


def test_idfrd_struct_gives_every_pair_output_major_with_its_names_units_and_variance(
    tmp_path, rng
):
    """Rejects: pairs misplaced or mislabelled, units dropped or given to variances, wrong tags."""
    fields = idfrd(rng, Coherence=rng.uniform(0.2, 0.9, (L, R, F)))
    records, Ts = read_mat(save(tmp_path / "x.mat", fields))
    assert Ts == 0.0
    assert [rec.kind for rec in records] == [FRF] * 6 + [VARIANCE] * 6 + [COHERENCE] * 6
    G, cov, coh = fields["ResponseData"], fields["CovarianceData"], fields["Coherence"]
    w = fields["Frequency"].ravel()
    pairs = [(i, j) for i in range(L) for j in range(R)]  # output-major
    for kind, tag, want in (
        (FRF, "ResponseData", G),
        # the docstring's E|dG|^2: var(Re) + var(Im), the Re/Im covariance left out
        (VARIANCE, "CovarianceData", cov[..., 0, 0] + cov[..., 1, 1]),
        (COHERENCE, "Coherence", coh),
    ):
        for rec, (i, j) in zip(by_kind(records, kind), pairs, strict=True):
            assert rec.file == "x.mat"
            assert rec.name == f"sys.{tag}({i + 1},{j + 1},:)"
            assert (rec.response.label, rec.response.index) == (OUTPUTS[i], i)
            assert (rec.reference.label, rec.reference.index) == (INPUTS[j] or None, j)
            np.testing.assert_allclose(rec.values, want[i, j], rtol=1e-15, atol=0)
            # rad/s to Hz
            np.testing.assert_allclose(rec.checked().freqs_hz, w / (2 * math.pi), rtol=1e-15)
            if kind == FRF and i == 0:
                assert rec.units == f"m/s^2/{IN_UNITS[j]}"
            else:  # no output unit; a variance or coherence has not the FRF's units
                assert rec.units is None


def test_empty_covariance_of_an_idfrd_without_one_gives_no_variance(tmp_path, rng):
    """Rejects: an empty CovarianceData (MATLAB's [] when none was estimated) taken as data."""
    fields = idfrd(rng, CovarianceData=np.zeros((0, 0)))
    records, _ = read_mat(save(tmp_path / "x.mat", fields))
    assert [rec.kind for rec in records] == [FRF] * 6


def test_single_precision_variance_and_coherence_fields_are_read(tmp_path, rng):
    """Rejects: Variance/Coherence fields ignored, or refused when saved as single (3-D, r = 1)."""
    var = rng.uniform(0.5, 2.0, (L, 1, F)).astype(np.float32)
    coh = rng.uniform(0.2, 0.9, (L, 1, F)).astype(np.float32)
    fields = idfrd(
        rng,
        ResponseData=np.ones((L, 1, F)) * (1 - 2j),
        InputName=cell(["torque"]),
        InputUnit=cell(["N m"]),
        CovarianceData=np.zeros((0, 0)),
        Variance=var,
        Coherence=coh,
    )
    records, _ = read_mat(save(tmp_path / "x.mat", fields))
    assert [rec.kind for rec in records] == [FRF] * 2 + [VARIANCE] * 2 + [COHERENCE] * 2
    for tag, kind, want in (("Variance", VARIANCE, var), ("Coherence", COHERENCE, coh)):
        for i, rec in enumerate(by_kind(records, kind)):
            assert rec.name == f"sys.{tag}({i + 1},1,:)"
            assert (rec.response.index, rec.reference.index) == (i, 0)
            np.testing.assert_array_equal(rec.values, want[i, 0].astype(np.float64))


@pytest.mark.parametrize("column", [False, True])
def test_one_pair_saved_by_hand_as_vectors(tmp_path, rng, column):
    """Rejects: 1 x F (or F x 1) ResponseData, Variance, Coherence misread; empty units refused."""
    n = 7
    g = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    var, coh = rng.uniform(0.1, 1.0, n), rng.uniform(0.1, 0.9, n)
    shape = (n, 1) if column else (1, n)
    fields = {
        "ResponseData": g.reshape(shape),
        "Variance": var.reshape(shape),
        "Coherence": coh.reshape(shape),
        "Frequency": np.arange(2, 2 + n),  # integers, as np.arange gives them
        "FrequencyUnit": "Hz",
        "OutputName": "y",  # a char, not a cell, for the one output
        "InputName": "u",
        "OutputUnit": np.empty((0, 0), dtype=object),  # {}: no units
        "InputUnit": np.zeros((0, 0)),  # []
    }
    records, Ts = read_mat(save(tmp_path / "h.mat", fields, name=None))
    assert Ts is None  # the file says nothing of the sample time
    assert [(r.kind, r.name) for r in records] == [
        (FRF, "ResponseData(1,1,:)"),
        (VARIANCE, "Variance(1,1,:)"),
        (COHERENCE, "Coherence(1,1,:)"),
    ]
    for rec, want in zip(records, (g, var, coh), strict=True):
        assert (rec.response.label, rec.reference.label) == ("y", "u")
        assert rec.units is None
        np.testing.assert_array_equal(rec.values, want)
        np.testing.assert_array_equal(rec.checked().freqs_hz, np.arange(2.0, 2.0 + n))


@pytest.mark.parametrize(
    ("unit", "time_unit", "hz_per_unit"),
    [
        ("rad/TimeUnit", "seconds", 1 / (2 * math.pi)),
        ("rad/TimeUnit", "milliseconds", 1000 / (2 * math.pi)),
        (None, "milliseconds", 1000 / (2 * math.pi)),  # MATLAB's default unit, in rad/ms
        (None, None, 1 / (2 * math.pi)),  # and its default TimeUnit, seconds
        ("cycles/TimeUnit", "minutes", 1 / 60),
        ("rad/s", "minutes", 1 / (2 * math.pi)),  # a unit in seconds ignores TimeUnit
        ("Hz", "hours", 1.0),
        ("kHz", None, 1000.0),
        ("rpm", None, 1 / 60),
    ],
)
def test_frequency_unit_and_time_unit_give_the_axis_in_hz(
    tmp_path, rng, unit, time_unit, hz_per_unit
):
    """Rejects: FrequencyUnit or TimeUnit ignored, or the wrong default unit."""
    fields = idfrd(rng, FrequencyUnit=unit, TimeUnit=time_unit)
    records, _ = read_mat(save(tmp_path / "x.mat", fields))
    want = fields["Frequency"].ravel() * hz_per_unit
    for rec in records:
        np.testing.assert_allclose(rec.checked().freqs_hz, want, rtol=1e-14)


@pytest.mark.parametrize(
    ("ts", "time_unit", "seconds"),
    [
        (0.0, "milliseconds", 0.0),  # continuous time in any unit
        (np.int64(0), None, 0.0),  # saved by hand from Python: an integer
        (-1.0, "milliseconds", -1.0),  # discrete, sample time unknown
        (1.0, "milliseconds", 1e-3),
        (0.5, cell(["milliseconds"]), 5e-4),  # a unit saved as a 1 x 1 cell
        (2.5, "minutes", 150.0),
        (np.float32(0.25), "seconds", 0.25),  # single precision
        (np.zeros((0, 0)), "seconds", None),  # Ts = [] says nothing
        (None, None, None),
    ],
)
def test_sample_time_in_seconds(tmp_path, rng, ts, time_unit, seconds):
    """Rejects: Ts not converted from TimeUnit, 0 / -1 / [] / integers / singles mishandled."""
    fields = idfrd(rng, Ts=ts, TimeUnit=time_unit, FrequencyUnit="Hz")
    _, Ts = read_mat(save(tmp_path / "x.mat", fields))
    if seconds is None:
        assert Ts is None
    else:
        assert Ts == pytest.approx(seconds, rel=1e-15)


def test_the_struct_with_response_data_is_chosen_or_the_one_named(tmp_path, rng):
    """Rejects: another struct taken, several data structs read silently, variable ignored."""
    a, b = idfrd(rng), idfrd(rng)
    path = tmp_path / "two.mat"
    savemat(path, {"meta": {"operator": "jd", "p": 24.0}, "a": a})
    records, _ = read_mat(path)
    assert records[0].name == "a.ResponseData(1,1,:)"
    np.testing.assert_array_equal(records[0].values, a["ResponseData"][0, 0])

    savemat(path, {"b": b, "a": a})
    with pytest.raises(
        FileError,
        match=r"^two\.mat: several structs with ResponseData \(a, b\); "
        r'say which with variable = "\.\.\." in the manifest$',
    ):
        read_mat(path)
    for name, fields in (("a", a), ("b", b)):
        records, _ = read_mat(path, variable=name)
        assert records[-1].name == f"{name}.CovarianceData(2,3,:)"
        np.testing.assert_array_equal(records[5].values, fields["ResponseData"][1, 2])
    with pytest.raises(
        FileError, match=r"^two\.mat: no struct named 'c' \(structs: \['a', 'b'\]\)$"
    ):
        read_mat(path, variable="c")

    save(tmp_path / "hand.mat", {"ResponseData": a["ResponseData"], "Frequency": np.ones(F)}, None)
    with pytest.raises(FileError, match=r"^hand\.mat: no struct named 'sys' \(structs: none\)$"):
        read_mat(tmp_path / "hand.mat", variable="sys")


def test_top_level_data_beside_one_other_struct_are_read(tmp_path, rng):
    """Rejects: a lone struct without ResponseData taken over top-level ResponseData."""
    g = rng.standard_normal((1, 1, F)) + 1j
    savemat(
        tmp_path / "hand.mat",
        {"ResponseData": g, "Frequency": np.arange(1.0, F + 1), "info": {"operator": "jd"}},
    )
    records, _ = read_mat(tmp_path / "hand.mat")
    assert [rec.name for rec in records] == ["ResponseData(1,1,:)"]
    np.testing.assert_array_equal(records[0].values, g[0, 0])


def test_struct_without_data_names_both_missing_fields(tmp_path):
    """Rejects: the lone struct's missing fields not named, or a misleading message."""
    save(tmp_path / "x.mat", {"Ts": 0.0, "Notes": "nothing"})
    with pytest.raises(
        FileError,
        match=r"^x\.mat, sys: no field ResponseData and Frequency "
        r"\(frd/idfrd data need ResponseData \(l x r x F\) and Frequency\)$",
    ):
        read_mat(tmp_path / "x.mat")


def test_struct_array_is_refused(tmp_path, rng):
    """Rejects: a struct array of several systems read as its first element."""
    arr = np.empty((1, 2), dtype=[("ResponseData", object), ("Frequency", object)])
    for k in range(2):
        arr[0, k] = (np.ones((1, 1, F)), np.arange(1.0, F + 1))
    savemat(tmp_path / "x.mat", {"sys": arr})
    with pytest.raises(FileError, match=r"^x\.mat, sys: a struct array of 2; expected one struct$"):
        read_mat(tmp_path / "x.mat")


def test_damaged_file_is_a_file_error_naming_it(tmp_path):
    """Rejects: scipy's error lost on the way to a FileError."""
    (tmp_path / "x.mat").write_bytes(b"MATLAB 5.0 MAT-file" + bytes(200))
    with pytest.raises(FileError, match=r"^x\.mat: not a readable \.mat file \(\w+: "):
        read_mat(tmp_path / "x.mat")


SHAPE = r"\(2, 3, 5\)"


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"ResponseData": "abc"}, r"^x\.mat, sys\.ResponseData: expected numbers, got <U3$"),
        (
            {"ResponseData": np.ones((L, R, F, 2))},
            r"^x\.mat, sys\.ResponseData: expected an l x r x F array, got shape \(2, 3, 5, 2\)$",
        ),
        (
            {"Frequency": np.arange(F) * (1 + 1j)},
            r"^x\.mat, sys\.Frequency: expected real numbers$",
        ),
        ({"Frequency": "abcde"}, r"^x\.mat, sys\.Frequency: expected real numbers$"),
        (
            {"Frequency": np.arange(1.0, F)},
            r"^x\.mat, sys: Frequency has 4 lines, ResponseData 5 \(l x r x F\)$",
        ),
        (
            {"FrequencyUnit": "furlongs"},
            r"^x\.mat, sys\.FrequencyUnit: unknown frequency unit 'furlongs'",
        ),
        ({"OutputName": cell("abc")}, r"^x\.mat, sys\.OutputName: 3 names for 2 channels$"),
        ({"InputName": cell("ab")}, r"^x\.mat, sys\.InputName: 2 names for 3 channels$"),
        ({"OutputUnit": cell("a")}, r"^x\.mat, sys\.OutputUnit: 1 names for 2 channels$"),
        ({"InputUnit": cell("abcd")}, r"^x\.mat, sys\.InputUnit: 4 names for 3 channels$"),
        (
            {"CovarianceData": np.ones((L, R, F, 4))},
            r"^x\.mat, sys\.CovarianceData: expected l x r x F x 2 x 2 = \(2, 3, 5, 2, 2\), "
            r"got \(2, 3, 5, 4\)$",
        ),
        (
            {"Variance": np.ones((L, R, F))},
            r"^x\.mat, sys: both CovarianceData and Variance; keep one$",
        ),
        (
            {"CovarianceData": None, "Variance": np.ones((L, R, F)) * 1j},
            r"^x\.mat, sys\.Variance: expected real numbers$",
        ),
        (
            {"Coherence": np.full((L, R, F), 0.5, dtype=object)},  # a cell array
            r"^x\.mat, sys\.Coherence: expected real numbers$",
        ),
        (
            {"Coherence": np.full((R, F), 0.5)},
            rf"^x\.mat, sys\.Coherence: expected l x r x F = {SHAPE}, got \(3, 5\)$",
        ),
        (
            {"CovarianceData": None, "Variance": np.ones((L, R, F - 1))},
            rf"^x\.mat, sys\.Variance: expected l x r x F = {SHAPE}, got \(2, 3, 4\)$",
        ),
        ({"Ts": np.array([0.1, 0.2])}, r"^x\.mat, sys\.Ts: expected one number$"),
        ({"Ts": "0.1"}, r"^x\.mat, sys\.Ts: expected one number$"),
        (
            {"Ts": -2.0},
            r"^x\.mat, sys\.Ts: expected 0 \(continuous\), -1 or a sample time > 0, got -2\.0$",
        ),
        ({"Ts": np.inf}, r"^x\.mat, sys\.Ts: expected 0 \(continuous\), -1 .*, got inf$"),
        ({"Ts": np.nan}, r"^x\.mat, sys\.Ts: expected 0 \(continuous\), -1 .*, got nan$"),
        (
            {"Ts": 0.1, "TimeUnit": "fortnights", "FrequencyUnit": "Hz"},
            r"^x\.mat, sys\.TimeUnit: unknown TimeUnit 'fortnights' \(known: seconds, ",
        ),
        (
            {"TimeUnit": "fortnights"},  # the frequencies in rad/fortnight
            r"^x\.mat, sys\.FrequencyUnit: unknown TimeUnit 'fortnights' \(known: seconds, ",
        ),
    ],
)
def test_refusals_name_the_file_field_and_numbers(tmp_path, rng, changes, message):
    """Rejects: a wrong field read, or refused without the file, the field and the sizes."""
    fields = idfrd(rng)
    fields.update(changes)
    fields = {k: v for k, v in fields.items() if v is not None}
    with pytest.raises(FileError, match=message):
        read_mat(save(tmp_path / "x.mat", fields))


def test_field_refusals_of_data_saved_by_hand_name_the_file_alone(tmp_path, rng):
    """Rejects: messages of top-level data naming a struct that is not there."""
    fields = {"ResponseData": np.ones((1, 1, F)), "Frequency": np.arange(1.0, F)}
    with pytest.raises(FileError, match=r"^h\.mat: Frequency has 4 lines, ResponseData 5 "):
        read_mat(save(tmp_path / "h.mat", fields, name=None))
    fields = {"ResponseData": np.ones((1, F)), "Frequency": np.arange(1.0, F + 1), "Ts": -3.0}
    with pytest.raises(FileError, match=r"^h\.mat\.Ts: expected 0 "):
        read_mat(save(tmp_path / "h.mat", fields, name=None))


@pytest.mark.parametrize("source", ["variance", "coherence"])
def test_sigma_of_the_loaded_data_follows_the_documented_formulas(tmp_path, rng, source):
    """Rejects: sigma not sqrt(var Re + var Im) of CovarianceData, or coherence not carried."""
    n_avg = 20
    points, want = [], []
    for q in range(2):
        fields = idfrd(rng, Ts=1e-3, Coherence=rng.uniform(0.3, 0.95, (L, R, F)))
        save(tmp_path / f"p{q}.mat", fields)
        points.append(f'[[points]]\np = {float(q)}\nfile = "p{q}.mat"\n')
        G, cov, coh = fields["ResponseData"], fields["CovarianceData"], fields["Coherence"]
        if source == "variance":
            sigma = np.sqrt(cov[..., 0, 0] + cov[..., 1, 1])
        else:  # Bendat and Piersol, as docs/data.md gives it
            sigma = np.abs(G) * np.sqrt((1 - coh) / (n_avg * coh))
        want.append(np.transpose(sigma, (2, 0, 1)))  # l x r x F to F x l x r
    spec = (
        '{ from = "variance" }'
        if source == "variance"
        else f'{{ from = "coherence", averages = {n_avg} }}'
    )
    manifest = textwrap.dedent(f"""\
        sigma = {spec}
        outputs = ["head", "carriage"]
        inputs = ["torque", "force", "voltage"]
        """) + "\n".join(points)
    (tmp_path / "m.toml").write_text(manifest)
    data = lpvid.FrfData.from_files(tmp_path / "m.toml")
    assert data.Ts == pytest.approx(1e-3, rel=1e-15)
    np.testing.assert_allclose(data.sigma, np.stack(want), rtol=1e-13)
