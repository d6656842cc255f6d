"""The small parts of the readers, each against an independent answer.

Records and units (records.py), sigma from variance and coherence (sigma.py),
one frequency axis for all records (lines.py) and the choice of a point's
records by order or by labels (pairing.py). Values are checked against the
documented formulas computed here, axes against numpy, and every refusal's
message in full.
"""

import math
import re

import numpy as np
import pytest

from lpvid.readers.lines import ATOL, RTOL, align_lines
from lpvid.readers.manifest import ChannelSpec
from lpvid.readers.pairing import select_records
from lpvid.readers.records import (
    COHERENCE,
    FRF,
    VARIANCE,
    Channel,
    FileError,
    Record,
    check_axis,
    check_values,
    hz_per_unit,
    parse_direction,
    same_units,
)
from lpvid.readers.sigma import sigma_from_coherence, sigma_from_variance, sigma_relative
from lpvid.readers.table import read_csv


def refused(exc, message, call, *args, **kw):
    """The call's refusal, its whole message matched."""
    with pytest.raises(exc, match="^" + re.escape(message) + "$"):
        call(*args, **kw)


# ------------------------------------------------------------------ records.py: units
SECONDS = {"s": 1, "ms": 1e-3, "us": 1e-6, "min": 60, "h": 3600}
SPELLINGS = {
    "s": ["s", "sec", "second", "seconds"],
    "ms": ["ms", "millisecond", "milliseconds"],
    "us": ["us", "microsecond", "microseconds"],
    "min": ["min", "minute", "minutes"],
    "h": ["h", "hour", "hours"],
}


@pytest.mark.parametrize(
    "unit", [None, "", "NONE", "Hz", " hz ", "1/s", "cycles/s", "Cycles/Second"]
)
def test_hz_spellings_give_one(unit):
    """Rejects: a spelling of Hz (or no unit) not known or scaled."""
    assert hz_per_unit(unit, "w") == 1.0


@pytest.mark.parametrize(
    ("unit", "want"),
    [
        ("kHz", 1e3),
        ("KHZ", 1e3),
        ("rpm", 1 / 60),
        ("rev/min", 1 / 60),
        ("rad / s", 1 / (2 * math.pi)),
    ],
)
def test_khz_rpm_and_rad_per_second(unit, want):
    """Rejects: kHz, rpm or rad/s (blanks and case ignored) scaled wrongly."""
    assert hz_per_unit(unit, "w") == pytest.approx(want, rel=1e-14)


@pytest.mark.parametrize("base", list(SPELLINGS))
def test_every_time_unit_spelling_for_rad_and_cycles(base):
    """Rejects: a time unit's spelling or factor wrong, rad not 2 pi per cycle."""
    for word in SPELLINGS[base]:
        period = SECONDS[base]
        assert hz_per_unit(f"cycles/{word}", "w") == pytest.approx(1 / period, rel=1e-14)
        assert hz_per_unit(f"rad/{word}", "w") == pytest.approx(
            1 / (2 * math.pi * period), rel=1e-14
        )
        # MATLAB: the unit per TimeUnit, named apart (blanks and case ignored)
        got = hz_per_unit("rad/TimeUnit", "w", time_unit=f" {word.upper()} ")
        assert got == pytest.approx(1 / (2 * math.pi * period), rel=1e-14)
        assert hz_per_unit("cycles/TimeUnit", "w", word) == pytest.approx(1 / period, rel=1e-14)


def test_time_unit_defaults_to_seconds_and_unknown_units_are_refused():
    """Rejects: another default TimeUnit, or refusals not naming the unit and the known ones."""
    assert hz_per_unit("rad/TimeUnit", "w") == pytest.approx(1 / (2 * math.pi), rel=1e-14)
    refused(
        FileError,
        "f.mat: unknown TimeUnit 'fortnights' (known: seconds, milliseconds, microseconds, "
        "minutes, hours)",
        hz_per_unit,
        "rad/TimeUnit",
        "f.mat",
        "fortnights",
    )
    for unit in [" furlong/s ", "rad/fortnight", "deg/s", "Hz/s", "deg/TimeUnit"]:
        refused(
            FileError,
            f"w: unknown frequency unit {unit.strip()!r} (known: Hz, kHz, rad/s, rpm, "
            "rad/TimeUnit, cycles/TimeUnit)",
            hz_per_unit,
            unit,
            "w",
            "fortnights",  # the TimeUnit is not looked at for another unit
        )


def test_record_checked_converts_its_axis_to_hz_and_names_itself():
    """Rejects: an axis left in rad/s, the unit kept, or a message without file and record."""
    w = np.array([2.0, 4.0, 6.0]) * np.pi
    rec = Record("a.csv", "column 'x'", FRF, Channel("y"), Channel("u"), w, w * 1j, "m/N", "rad/s")
    assert rec.where == "a.csv, column 'x'"
    out = rec.checked()
    np.testing.assert_allclose(out.freqs_hz, [1.0, 2.0, 3.0], rtol=1e-15)
    assert out.freq_unit is None and out.units == "m/N"
    np.testing.assert_array_equal(out.values, w * 1j)
    # values as the reader gave them (a list, a column) become one value per line
    col = Record("a.csv", "c", FRF, Channel(), Channel(), [1.0, 2.0], [[1j], [2j]]).checked()
    assert isinstance(col.values, np.ndarray) and col.values.shape == (2,)
    np.testing.assert_array_equal(col.values, [1j, 2j])
    refused(
        FileError,
        "a.csv, column 'x': negative frequency -1 Hz",
        Record("a.csv", "column 'x'", FRF, Channel(), Channel(), [-1.0, 2.0], [1.0, 1.0]).checked,
    )
    bad = Record("a.csv", "column 'x'", FRF, Channel(), Channel(), w, w, None, "deg")
    refused(
        FileError,
        "a.csv, column 'x': frequency axis: unknown frequency unit 'deg' (known: Hz, kHz, rad/s, "
        "rpm, rad/TimeUnit, cycles/TimeUnit)",
        bad.checked,
    )


def test_check_axis_accepts_an_increasing_axis_and_names_what_is_wrong():
    """Rejects: an axis not flattened to float, or refusals naming the wrong line or value."""
    f = check_axis([[0, 1], [2, 5]], "w")
    assert f.dtype == np.float64
    np.testing.assert_array_equal(f, [0.0, 1.0, 2.0, 5.0])
    refused(FileError, "w: no frequency lines", check_axis, [], "w")
    refused(
        FileError, "w: frequency axis has NaN or Inf at line 3", check_axis, [1, 2, np.inf], "w"
    )
    refused(FileError, "w: negative frequency -0.5 Hz", check_axis, [0.0, 0.5, -0.5, -2.0], "w")
    refused(
        FileError,
        "w: frequencies must increase strictly; line 3 (2 Hz) follows 2 Hz",
        check_axis,
        [1.0, 2.0, 2.0, 3.0],
        "w",
    )
    refused(
        FileError,
        "w: frequencies must increase strictly; line 4 (1.5 Hz) follows 3 Hz",
        check_axis,
        [1.0, 2.0, 3.0, 1.5],
        "w",
    )


def test_check_values_names_the_bad_lines_by_frequency():
    """Rejects: a length mismatch let through, or the NaN lines miscounted or misnamed."""
    f = np.arange(1.0, 9.0)
    v = check_values(np.ones((2, 4)), f, "w")
    assert v.shape == (8,)
    refused(FileError, "w: 3 values for 8 frequency lines", check_values, [1, 2, 3], f, "w")
    five = np.ones(8)
    five[[0, 2, 3, 5, 7]] = np.nan
    refused(
        FileError,
        "w: NaN or Inf at 5 of 8 frequency lines (1, 3, 4, 6, 8 Hz); remove those lines or fix "
        "the export",
        check_values,
        five,
        f,
        "w",
    )
    six = np.full(8, np.nan)
    six[[2, 6]] = 0.0
    refused(
        FileError,
        "w: NaN or Inf at 6 of 8 frequency lines (1, 2, 4, 5, 6 and 1 more Hz); remove those "
        "lines or fix the export",
        check_values,
        six,
        f,
        "w",
    )
    seven = np.full(8, np.inf + 0j)
    seven[4] = 1.0
    refused(
        FileError,
        "w: NaN or Inf at 7 of 8 frequency lines (1, 2, 3, 4, 6 and 2 more Hz); remove those "
        "lines or fix the export",
        check_values,
        seven,
        f,
        "w",
    )


def test_same_units_ignores_blanks_and_an_unstated_unit():
    """Rejects: an unstated unit on one side taken as a disagreement, or blanks counted."""
    assert same_units(None, "m/N") and same_units("m/N", None) and same_units(None, None)
    assert same_units("m / N", "m/N")
    assert not same_units("m/N", "mm/N")


def test_parse_direction_takes_codes_and_names_and_refuses_others():
    """Rejects: codes beyond -6..6 accepted, the ends refused, or messages not in full."""
    assert [parse_direction(k, "d") for k in (-6, -1, 0, 1, 6)] == [-6, -1, 0, 1, 6]
    assert parse_direction(" -rz ", "d") == -6
    assert parse_direction("Z", "d") == 3
    assert parse_direction("+ry", "d") == 5
    for code in (-7, 7):
        refused(
            FileError,
            f"d: direction codes run from -6 to 6, got {code}",
            parse_direction,
            code,
            "d",
        )
    refused(
        FileError, "d: expected a direction such as '+X' or 3, got True", parse_direction, True, "d"
    )
    for value in ("+Q", 3.0, None):
        refused(
            FileError,
            f"d: expected a direction such as '+X', '-Z', 'RY' or 3, got {value!r}",
            parse_direction,
            value,
            "d",
        )


def test_channel_description_leaves_out_what_is_not_known():
    """Rejects: an empty label or a zero direction shown."""
    assert Channel(label="", node=3, direction=0).describe() == "node 3"
    assert Channel(label="a", index=2).describe() == "'a' #3"


# ------------------------------------------------------------------ sigma.py
def test_sigma_from_coherence_is_the_documented_formula():
    """Rejects: a wrong formula, no broadcasting of the coherence, or a wrong n."""
    G = np.array([[3.0 + 4.0j, -2.0], [0.5j, 1.0 - 1.0j]])
    coh = np.array([0.9, 0.25])  # per column, broadcast over rows
    n = 16
    want = np.empty((2, 2))
    for i in range(2):
        for j in range(2):
            g2 = G[i, j].real ** 2 + G[i, j].imag ** 2
            want[i, j] = math.sqrt(g2 * (1 - coh[j]) / (n * coh[j]))
    got = sigma_from_coherence(G, coh, n)
    assert got.shape == (2, 2)
    np.testing.assert_allclose(got, want, rtol=1e-13)
    # sigma^2 is twice Bendat and Piersol's variance of |G_hat|
    var_mag = abs(G[0, 0]) ** 2 * (1 - 0.9) / (2 * n * 0.9)
    assert got[0, 0] ** 2 == pytest.approx(2 * var_mag, rel=1e-13)


def test_sigma_from_coherence_refuses_a_coherence_of_zero_or_one_in_full():
    """Rejects: a coherence of 0 (or 1, or below 0) let through to an infinite or zero sigma."""
    tail = " (1 means no noise and gives no sigma: take sigma from a variance or a relative level)"
    for coh, shown in [(0.0, "0"), (1.0, "1"), (-0.25, "-0.25"), (1.5, "1.5")]:
        refused(
            ValueError,
            f"rec: coherence must lie in (0, 1); found {shown} at line 2" + tail,
            sigma_from_coherence,
            [1.0, 1.0, 1.0],
            [0.5, coh, 0.5],
            10,
            where="rec",
        )
    refused(
        ValueError,
        "coherence: the FRF is 0j at line 2, which gives sigma 0 (a relative or coherence-based "
        "sigma needs |G| > 0)",
        sigma_from_coherence,
        np.array([1.0, 0.0j]),
        0.5,
        10,
    )


def test_single_precision_coherence_and_variance_give_sigma_in_double_precision():
    """Rejects: float32 data (as a MATLAB file may hold) computed in single precision."""
    coh32 = np.array([0.9, 0.3, 0.7], dtype=np.float32)
    var32 = np.array([2.0, 3.0, 0.1], dtype=np.float32)
    c, v = coh32.astype(np.float64), var32.astype(np.float64)
    got = sigma_from_coherence([1.0, 2.0, 3.0], coh32, 20)
    want = np.array([1.0, 2.0, 3.0]) * np.sqrt((1 - c) / (20 * c))
    assert got.dtype == np.float64
    np.testing.assert_allclose(got, want, rtol=1e-13)
    got = sigma_from_variance(var32)
    assert got.dtype == np.float64
    np.testing.assert_allclose(got, [math.sqrt(x) for x in v], rtol=1e-14)


def test_sigma_from_variance_and_relative():
    """Rejects: sigma not the square root of the variance, or not level |G|."""
    var = np.array([[9.0, 1e-6], [2.0, 0.5]])
    np.testing.assert_allclose(
        sigma_from_variance(var), [[3.0, 1e-3], [math.sqrt(2), math.sqrt(0.5)]], rtol=1e-15
    )
    np.testing.assert_allclose(sigma_from_variance([4, 1]), [2.0, 1.0], rtol=1e-15)
    np.testing.assert_allclose(sigma_relative([3 + 4j, -2], 0.01), [0.05, 0.02], rtol=1e-14)
    refused(
        ValueError,
        "variance: variance must be > 0; found nan at line 1",
        sigma_from_variance,
        [np.nan, 1.0],
    )
    refused(
        ValueError,
        "G: the FRF is 0.0 at line 3, which gives sigma 0 (a relative or coherence-based sigma "
        "needs |G| > 0)",
        sigma_relative,
        [1.0, 2.0, 0.0],
        0.1,
    )


# ------------------------------------------------------------------ lines.py
def rec_on(freqs, name="r", file="a.csv"):
    """A checked FRF record on the axis ``freqs``, its values the axis itself."""
    f = np.asarray(freqs, dtype=float)
    return Record(file, name, FRF, Channel("y"), Channel("u"), f, f + 0j)


def test_same_lines_within_the_tolerance_keep_the_first_records_axis():
    """Rejects: lines that agree to RTOL (or ATOL at 0 Hz) taken as different."""
    ref = np.array([0.0, 1.0, 10.0, 1000.0])
    other = ref * (1 + 0.5 * RTOL) + np.array([0.5 * ATOL, 0, 0, 0])
    lines = align_lines([rec_on(ref), rec_on(other)], ["p0", "p1"], "same")
    np.testing.assert_array_equal(lines.freqs_hz, ref)
    for j in lines.index:
        np.testing.assert_array_equal(j, np.arange(4))
    assert lines.dropped == [0, 0]


def test_common_lines_are_those_every_record_has():
    """Rejects: a line kept that a record lacks, wrong indices or dropped counts."""
    a = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    b = np.array([0.5, 2.0, 3.0, 5.0])
    c = np.array([2.0, 5.0])  # two lines
    d = np.array([5.0])  # one line
    lines = align_lines([rec_on(a), rec_on(b), rec_on(c)], ["p0", "p1", "p2"], "common")
    want = np.intersect1d(np.intersect1d(a, b), c)
    np.testing.assert_array_equal(lines.freqs_hz, want)
    for rec, j in zip([a, b, c], lines.index, strict=True):
        np.testing.assert_array_equal(rec[j], want)
    assert lines.dropped == [a.size - want.size, b.size - want.size, c.size - want.size]
    one = align_lines([rec_on(a), rec_on(d)], ["p0", "p1"], "common")
    np.testing.assert_array_equal(one.freqs_hz, [5.0])
    np.testing.assert_array_equal(one.index[1], [0])
    np.testing.assert_array_equal(one.index[0], [4])


def test_lines_that_differ_are_named_with_both_axes_and_the_first_difference():
    """Rejects: the message's ranges, sizes, first differing line or reference point wrong."""
    ref = [0.0, 1.0, 2.0, 3.0, 4.0]
    near = [0.0, 1.0 + 0.5e-5, 2.0, 3.5, 4.0]  # line 2 within RTOL, line 4 not
    refused(
        FileError,
        "p2: b.csv, r has 5 frequency lines (0-4 Hz) that differ from the 5 lines (0-4 Hz) of "
        "a.csv, r (p0); first at line 4: 3.5 Hz against 3 Hz; pass lines='common' to keep the "
        "lines all records share",
        align_lines,
        [rec_on(ref), rec_on(ref), rec_on(near, file="b.csv")],
        ["p0", "p1", "p2"],
        "same",
    )
    longer = [0.5, 1.0, 2.0, 3.0, 4.0, 7.0]
    refused(
        FileError,
        "p1: b.csv, r has 6 frequency lines (0.5-7 Hz) that differ from the 3 lines (1-3 Hz) of "
        "a.csv, r (p0); first at line 1: 0.5 Hz against 1 Hz; pass lines='common' to keep the "
        "lines all records share",
        align_lines,
        [rec_on([1.0, 2.0, 3.0]), rec_on(longer, file="b.csv")],
        ["p0", "p1"],
        "same",
    )
    # the same first lines, one more line: no line differs, only the count
    refused(
        FileError,
        "p1: b.csv, r has 4 frequency lines (1-4 Hz) that differ from the 3 lines (1-3 Hz) of "
        "a.csv, r (p0); pass lines='common' to keep the lines all records share",
        align_lines,
        [rec_on([1.0, 2.0, 3.0]), rec_on([1.0, 2.0, 3.0, 4.0], file="b.csv")],
        ["p0", "p1"],
        "same",
    )


def test_no_shared_line_bad_mode_and_lines_that_cannot_be_told_apart():
    """Rejects: disjoint axes, a wrong mode or lines closer than RTOL let through."""
    refused(
        FileError,
        "no frequency line is shared by every record (the first is a.csv, r, p0, 3 lines 1-3 Hz)",
        align_lines,
        [rec_on([1.0, 2.0, 3.0]), rec_on([4.0, 5.0]), rec_on([1.0, 2.0])],
        ["p0", "p1", "p2"],
        "common",
    )
    refused(
        ValueError,
        "lines: expected one of ('same', 'common'), got 'all'",
        align_lines,
        [rec_on([1.0])],
        ["p0"],
        "all",
    )
    close = [1.0, 2.0, 2.0 * (1 + 0.5 * RTOL), 3.0]
    refused(
        FileError,
        "b.csv, r: frequency lines closer than 1e-05 relative cannot be told apart",
        align_lines,
        [rec_on(close), rec_on([1.0, 2.0, 3.0], file="b.csv")],
        ["p0", "p1"],
        "common",
    )
    with pytest.raises(ValueError):  # a label per record
        align_lines([rec_on([1.0]), rec_on([1.0])], ["p0"], "common")


# ------------------------------------------------------------------ pairing.py
F3 = [1.0, 2.0, 3.0]


def rec(name, kind=FRF, out=None, inp=None, file="a.csv", value=1.0):
    """A record on F3, its values ``value`` (complex for an FRF)."""
    v = np.full(3, value + 0j) if kind == FRF else np.full(3, value)
    return Record(file, name, kind, out or Channel(), inp or Channel(), np.array(F3), v)


Y, U = [ChannelSpec("y1"), ChannelSpec("y2")], [ChannelSpec("u1"), ChannelSpec("u2")]


def names(grid):
    return [[r.name for r in row] for row in grid]


@pytest.mark.parametrize(
    ("mode", "want"),
    [
        ("output-major", [["r0", "r1"], ["r2", "r3"]]),
        ("input-major", [["r0", "r2"], ["r1", "r3"]]),
    ],
)
def test_records_by_order_fill_the_grid_in_the_named_order(mode, want):
    """Rejects: output-major and input-major swapped or a wrong position in the grid."""
    records = [rec(f"r{k}") for k in range(4)]
    records.insert(2, rec("c", COHERENCE, value=0.5))
    grid = select_records(records, Y, U, mode, [FRF], "a.csv")
    assert names(grid[FRF]) == want
    refused(
        FileError,
        f"a.csv: missing coherence records: found 1, expected 4 (2 output(s) x 2 input(s), taken "
        f"in {mode} order)",
        select_records,
        records,
        Y,
        U,
        mode,
        [COHERENCE],
        "a.csv",
    )


def test_records_by_order_counted_per_kind_and_refused_in_full():
    """Rejects: too many / missing mixed up, l*r miscomputed, or a record of another type taken."""
    one_two = ([ChannelSpec("y")], U)
    refused(
        FileError,
        "f: missing FRF records: found 1, expected 2 (1 output(s) x 2 input(s), taken in "
        "output-major order)",
        select_records,
        [rec("r0")],
        *one_two,
        "output-major",
        [FRF],
        "f",
    )
    refused(
        FileError,
        "f: too many FRF records: found 3, expected 2 (1 output(s) x 2 input(s), taken in "
        "input-major order)",
        select_records,
        [rec("r0"), rec("r1"), rec("r2")],
        *one_two,
        "input-major",
        [FRF],
        "f",
    )
    refused(
        FileError,
        "f: missing variance records: found 0, expected 2 (1 output(s) x 2 input(s), taken in "
        "output-major order)",
        select_records,
        [rec("r0"), rec("r1")],
        *one_two,
        "output-major",
        [VARIANCE],
        "f",
    )
    refused(
        FileError,
        'a.csv, r1: a record of type auto, expected an FRF; with records = "input-major", every '
        "function record of the files must be an FRF (coherence records aside): remove the "
        "others or match records by labels",
        select_records,
        [rec("r0"), rec("r1", "auto")],
        *one_two,
        "input-major",
        [FRF],
        "f",
    )


def indexed(i, j, kind=FRF):
    """A MATLAB record at ResponseData(i+1, j+1, :)."""
    return Record(
        "m.mat",
        f"ResponseData({i + 1},{j + 1},:)",
        kind,
        Channel(f"y{i + 1}", index=i),
        Channel(f"u{j + 1}", index=j),
        np.array(F3),
        np.full(3, 1.0 + 0j if kind == FRF else 0.5),
    )


@pytest.mark.parametrize("shape", [(1, 2), (2, 1), (2, 2), (2, 3)])
def test_records_with_a_position_are_placed_by_it_whatever_their_order(shape):
    """Rejects: positions ignored for file order, rows or columns miscounted."""
    l, r = shape
    cells = [(i, j) for j in range(r) for i in range(l)][::-1]  # neither order
    records = [indexed(i, j) for i, j in cells] + [indexed(i, j, COHERENCE) for i, j in cells]
    outs = [ChannelSpec(f"y{i + 1}") for i in range(l)]
    ins = [ChannelSpec(f"u{j + 1}") for j in range(r)]
    for mode in ("output-major", "input-major"):
        grid = select_records(records, outs, ins, mode, [FRF, COHERENCE], "m.mat")
        for kind in (FRF, COHERENCE):
            want = [[f"ResponseData({i + 1},{j + 1},:)" for j in range(r)] for i in range(l)]
            assert names(grid[kind]) == want
            assert all(g.kind == kind for row in grid[kind] for g in row)
    refused(
        FileError,
        f"m.mat: the FRF data are {l} outputs x {r} inputs, the manifest names {l + 1} x {r}",
        select_records,
        records,
        [*outs, ChannelSpec("extra")],
        ins,
        "output-major",
        [FRF],
        "m.mat",
    )
    refused(
        FileError,
        f"m.mat: the coherence data are {l} outputs x {r} inputs, the manifest names {l} x {r + 1}",
        select_records,
        records,
        outs,
        [*ins, ChannelSpec("extra")],
        "output-major",
        [COHERENCE],
        "m.mat",
    )


CSV = [
    "freq [Hz], acc/force re [m/s^2/N], acc/force im, acc/force coh, pos/force re, pos/force im, "
    "pos/force coh",
    "1, 1, 0, 0.9, 5, 1, 0.8",
    "2, 2, 0, 0.9, 6, 1, 0.8",
    "3, 3, 0, 0.9, 7, 1, 0.8",
]


def test_records_by_labels_from_a_hand_written_csv(tmp_path):
    """Rejects: a label matched to the wrong column, or the name preferred to the label."""
    path = tmp_path / "p.csv"
    path.write_text("\n".join(CSV) + "\n", encoding="utf-8")
    records = read_csv(path)
    outs = [ChannelSpec("position", label="pos"), ChannelSpec("acc")]
    grid = select_records(records, outs, [ChannelSpec("force")], "labels", [FRF, COHERENCE], "p")
    np.testing.assert_array_equal(grid[FRF][0][0].values, [5 + 1j, 6 + 1j, 7 + 1j])
    np.testing.assert_array_equal(grid[FRF][1][0].values, [1, 2, 3])
    np.testing.assert_array_equal(grid[COHERENCE][0][0].values, [0.8, 0.8, 0.8])
    np.testing.assert_array_equal(grid[COHERENCE][1][0].values, [0.9, 0.9, 0.9])
    refused(
        FileError,
        "p: no FRF record matches output 'position' / input 'force'; p.csv (looked for label "
        "'position' / label 'force') holds the FRF records 'acc/force', 'pos/force'",
        select_records,
        records,
        [ChannelSpec("position")],
        [ChannelSpec("force")],
        "labels",
        [FRF],
        "p",
    )


def node(n, d, label=None):
    return Channel(label=label, node=n, direction=d)


def test_records_by_nodes_and_what_a_missing_pair_names():
    """Rejects: node, direction or entity name misused, or a message not naming what was sought."""
    uff = [
        rec("record 1", out=node(3, 1, "head"), inp=node(1, 3, "shaker"), file="a.uff"),
        rec("record 2", out=node(3, 2, "head"), inp=node(1, 3, "shaker"), file="a.uff", value=2.0),
        rec("record 3", COHERENCE, out=node(3, 2), inp=node(1, 3), file="a.uff", value=0.5),
    ]
    csv = [
        rec("column 'x'", out=Channel(None), inp=Channel("u"), file="b.csv"),
        rec("column 'z'", out=Channel("z"), inp=Channel(None), file="b.csv"),
    ]
    out_y = ChannelSpec("y", node=3, direction=2)
    inp = ChannelSpec("u", node=1)
    grid = select_records(uff, [out_y], [inp], "labels", [FRF, COHERENCE], "a.uff")
    assert grid[FRF][0][0].name == "record 2" and grid[COHERENCE][0][0].name == "record 3"
    # no node in the manifest: the entity name, by the label given
    refused(
        FileError,
        "a.uff, b.csv: no FRF record matches output 'y' / input 'u'; a.uff (looked for entity "
        "name 'tip' / node 1) holds the FRF records 'head' node 3 +X / 'shaker' node 1 +Z "
        "(record 1), 'head' node 3 +Y / 'shaker' node 1 +Z (record 2); b.csv (looked for label "
        "'tip' / label 'u') holds the FRF records '/u', 'z/'",
        select_records,
        uff + csv,
        [ChannelSpec("y", label="tip")],
        [inp],
        "labels",
        [FRF],
        "a.uff, b.csv",
    )
    refused(
        FileError,
        "a.uff: no coherence record matches output 'y' / input 'u'; a.uff (looked for node 3 -Z "
        "/ node 1) holds the coherence records node 3 +Y / node 1 +Z (record 3)",
        select_records,
        uff,
        [ChannelSpec("y", node=3, direction=-3)],
        [inp],
        "labels",
        [COHERENCE],
        "a.uff",
    )
    refused(
        FileError,
        "b.csv: no variance record matches output 'y' / input 'u'; b.csv (looked for label 'y' / "
        "label 'u') holds no variance records",
        select_records,
        csv,
        [ChannelSpec("y")],
        [ChannelSpec("u")],
        "labels",
        [VARIANCE],
        "b.csv",
    )


def test_records_by_labels_refuse_two_records_for_a_pair_or_one_of_another_type():
    """Rejects: a duplicate pair taken silently, or an auto spectrum taken for an FRF."""
    two = [
        rec("column 1", out=Channel("y"), inp=Channel("u")),
        rec("column 2", out=Channel("y"), inp=Channel("u")),
        rec("column 3", COHERENCE, out=Channel("y"), inp=Channel("u"), value=0.5),
        rec("column 4", COHERENCE, out=Channel("y"), inp=Channel("u"), value=0.5),
    ]
    y, u = [ChannelSpec("y")], [ChannelSpec("u")]
    refused(
        FileError,
        "f: 2 FRF records for output 'y' / input 'u': a.csv, column 1, a.csv, column 2",
        select_records,
        two,
        y,
        u,
        "labels",
        [FRF],
        "f",
    )
    refused(
        FileError,
        "f: 2 coherence records for output 'y' / input 'u': a.csv, column 4, a.csv, column 3",
        select_records,
        two[::-1][:2],
        y,
        u,
        "labels",
        [COHERENCE],
        "f",
    )
    auto = [rec("record 1", "auto", out=node(2, 1), inp=node(2, 1), file="a.uff")]
    refused(
        FileError,
        "a.uff, record 1: a record of type auto, expected an FRF; it is the record the "
        "manifest's labels point to",
        select_records,
        auto,
        [ChannelSpec("y", node=2)],
        [ChannelSpec("u", node=2, direction=1)],
        "labels",
        [FRF],
        "f",
    )
