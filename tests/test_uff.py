"""The UFF reader on its own: dataset 58 records as pyuff writes them, and damaged files.

Files are written by pyuff (never by lpvid's writers), or by hand from a
pyuff file where a malformed one is needed; what is read is compared with
what was written, and every refusal's message with the dataset and line of
the file that it names (counted here from the bytes of the file).
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from lpvid.readers.records import COHERENCE, FRF, Channel, FileError
from lpvid.readers.uff import _record, read_uff

pyuff = pytest.importorskip("pyuff")

#: An uneven frequency axis in Hz (pyuff writes abscissas as E13.5: 6 digits).
FREQS = np.array([0.5, 1.25, 2.0, 3.5, 7.0, 12.5])
PAD = b" " * 74  # what pads a 6-column '    -1' line to 80 columns


def dataset(func_type=4, data=None, **fields):
    """A pyuff dataset 58 dict: response node 3 -Y, reference node 1 +Z, unless told."""
    if data is None:
        data = np.arange(1, FREQS.size + 1) * (1 - 0.5j)
    common = dict(
        binary=0,
        func_type=func_type,
        id1="lpvid uff test",
        rsp_node=3,
        rsp_dir=-2,
        ref_node=1,
        ref_dir=3,
        x=FREQS,
        abscissa_spacing=0,
        abscissa_spec_data_type=18,
        abscissa_axis_units_lab="Hz",
        ordinate_spec_data_type=12,
        orddenom_spec_data_type=13,
    )
    common.update(fields)
    return pyuff.prepare_58(data=np.asarray(data), **common)


def write(path, sets):
    """The sets written by pyuff to a new file (mode add: see frf_files.write_uff)."""
    path.unlink(missing_ok=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        pyuff.UFF(str(path)).write_sets(sets, mode="add")
    return path


def marks(data: bytes) -> list[int]:
    """1-based line numbers of the lines that are exactly '    -1' (ASCII datasets)."""
    return [i + 1 for i, line in enumerate(data.split(b"\n")) if line.rstrip(b"\r") == b"    -1"]


def refused(path, pattern):
    with pytest.raises(FileError, match=pattern):
        read_uff(path)


def rng_frf(seed, n=FREQS.size):
    rng = np.random.default_rng(seed)
    return rng.standard_normal(n) + 1j * rng.standard_normal(n)


# ------------------------------------------------------------------ what is read
@pytest.mark.parametrize("binary", [0, 1])
def test_records_read_as_written(tmp_path, binary):
    """Rejects a reader that drops entity names, the frequency unit or a lone ordinate unit."""
    g = rng_frf(1)
    coh = np.linspace(0.3, 0.95, FREQS.size)
    psd = np.linspace(1.0, 2.0, FREQS.size) * 1e-3
    sets = [
        dataset(
            4,
            g,
            binary=binary,
            rsp_ent_name="head",
            ref_ent_name="torque",
            ordinate_axis_units_lab="m/s^2",
            orddenom_axis_units_lab="N m",
        ),
        dataset(6, coh, binary=binary, rsp_node=7, rsp_dir=1, ref_node=2, ref_dir=-3),
        dataset(2, psd, binary=binary, ordinate_axis_units_lab="g^2", abscissa_axis_units_lab=""),
    ]
    path = write(tmp_path / "a.uff", sets)
    frf, c, auto = read_uff(path)
    assert [r.name for r in (frf, c, auto)] == ["record 1", "record 2", "record 3"]
    assert {r.file for r in (frf, c, auto)} == {"a.uff"}
    assert (frf.kind, c.kind) == (FRF, COHERENCE)
    assert auto.kind == "auto spectrum (function type 2)"
    assert frf.response == Channel(label="head", node=3, direction=-2)
    assert frf.reference == Channel(label="torque", node=1, direction=3)
    assert c.response == Channel(label=None, node=7, direction=1)  # pyuff writes NONE
    assert c.reference == Channel(label=None, node=2, direction=-3)
    assert (frf.units, c.units, auto.units) == ("m/s^2/N m", None, "g^2")
    assert (frf.freq_unit, c.freq_unit, auto.freq_unit) == ("Hz", "Hz", None)
    for r in (frf, c, auto):
        np.testing.assert_allclose(r.freqs_hz, FREQS, rtol=5e-6)
    # ASCII ordinates have 12 significant digits; binary ones are the doubles written.
    rtol = 0 if binary else 1e-11
    assert frf.values.dtype == np.complex128
    np.testing.assert_allclose(frf.values, g, rtol=rtol, atol=rtol * np.abs(g).max())
    assert c.values.dtype == np.float64 and not np.iscomplexobj(c.values)
    np.testing.assert_allclose(c.values, coh, rtol=rtol)
    np.testing.assert_allclose(auto.values, psd, rtol=rtol)


def test_blank_entity_names_and_units_are_no_labels(tmp_path):
    """Rejects a reader that keeps a blank name or unit field as an empty label."""
    path = write(tmp_path / "a.uff", [dataset(4, rsp_ent_name="head", ordinate_axis_units_lab="m")])
    text = path.read_bytes().split(b"\n")
    # Record 6 with the entity names blanked (columns 31-41 and 56-66), as some analyzers write.
    assert text[7][30:41].strip() == b"head" and text[7][55:66].strip() == b"NONE"
    text[7] = text[7][:30] + b" " * 11 + text[7][41:55] + b" " * 11 + text[7][66:]
    assert text[9][46:].strip() == b"Hz"
    text[9] = text[9][:46]  # record 8 without its last field: no abscissa units
    path.write_bytes(b"\n".join(text))
    (r,) = read_uff(path)
    assert r.response == Channel(label=None, node=3, direction=-2)
    assert r.reference == Channel(label=None, node=1, direction=3)
    assert r.freq_unit is None and r.units == "m"


def test_other_datasets_are_skipped_and_counted(tmp_path):
    """Rejects a reader that stops at the first dataset that is not a 58."""
    g1, g2 = rng_frf(2), rng_frf(3)
    sets = [
        pyuff.prepare_151(model_name="tube", description="lpvid test", db_app="x", program="pyuff"),
        dataset(4, g1, rsp_node=3),
        pyuff.prepare_164(
            units_code=1,
            units_description="SI",
            temp_mode=1,
            length=1.0,
            force=1.0,
            temp=1.0,
            temp_offset=273.15,
        ),
        dataset(4, g2, rsp_node=2),
    ]
    path = write(tmp_path / "a.uff", sets)
    a, b = read_uff(path)
    assert (a.name, b.name) == ("record 2", "record 4")  # datasets counted from the 151
    assert (a.response.node, b.response.node) == (3, 2)
    np.testing.assert_allclose(a.values, g1, rtol=1e-11)
    np.testing.assert_allclose(b.values, g2, rtol=1e-11)


@pytest.mark.parametrize(
    "func_type, kind",
    [
        (9, "power spectral density (function type 9)"),
        (27, "order function (function type 27)"),
        (99, "unknown function (function type 99)"),
    ],
)
def test_other_function_types_are_named(tmp_path, func_type, kind):
    """Rejects a reader that names a function type outside the UFF table as 'None'."""
    path = write(tmp_path / "a.uff", [dataset(4)])
    lines = path.read_bytes().split(b"\n")
    assert lines[7][:5] == b"    4"  # record 6 field 1 (pyuff writes only some types)
    lines[7] = b"%5d" % func_type + lines[7][5:]
    path.write_bytes(b"\n".join(lines))
    (r,) = read_uff(path)
    assert r.kind == kind


@pytest.mark.parametrize(
    "axis, kind",
    [
        (1, FRF),  # general: taken as frequency
        (0, FRF),  # unknown: taken as frequency
        (17, "function over time (abscissa data type 17), not over frequency"),
        (20, "function over order (abscissa data type 20), not over frequency"),
        (5, "function over specific data type 5 (abscissa data type 5), not over frequency"),
    ],
)
def test_an_abscissa_that_is_not_frequency_is_named(tmp_path, axis, kind):
    """Rejects a reader that ignores the abscissa data type or names an unknown one 'None'."""
    (r,) = read_uff(write(tmp_path / "a.uff", [dataset(4, abscissa_spec_data_type=axis)]))
    assert r.kind == kind


def test_a_complex_coherence_is_refused(tmp_path):
    """Rejects a reader that drops the imaginary part of a coherence record."""
    sets = [dataset(4), dataset(6, np.full(FREQS.size, 0.5 + 0.1j))]
    refused(write(tmp_path / "a.uff", sets), r"^a.uff, record 2: coherence record holds complex")


def test_a_dataset_without_optional_fields():
    """Rejects a reader that fails on a dataset dict without nodes, labels or types.

    Another pyuff version (or parser) may leave out what a file does not say:
    the function type is then 0 (general), the abscissa unknown (frequency).
    """
    r = _record({"data": np.array([1.0, 2.0]), "x": np.array([1.0, 2.0])}, "a.uff", 3)
    assert r.kind == "general or unknown function (function type 0)"
    assert r.name == "record 3" and r.file == "a.uff"
    assert r.response == Channel() and r.reference == Channel()
    assert r.units is None and r.freq_unit is None
    np.testing.assert_array_equal(r.freqs_hz, [1.0, 2.0])


# ------------------------------------------------------------------ delimiter lines
def test_delimiter_lines_padded_to_80_columns(tmp_path):
    """Rejects a reader that does not take a '    -1' padded with blanks as a delimiter."""
    g1, g2 = rng_frf(4), rng_frf(5)
    path = write(tmp_path / "a.uff", [dataset(4, g1), dataset(4, g2, rsp_node=2)])
    data = path.read_bytes()
    assert data.endswith(b"    -1\n")
    # Fixed-width writers pad every line to 80 columns: here the last one.
    path.write_bytes(data[:-1] + PAD + b"\n")
    a, b = read_uff(path)
    np.testing.assert_allclose(a.values, g1, rtol=1e-11)
    np.testing.assert_allclose(b.values, g2, rtol=1e-11)
    assert b.response.node == 2


def test_a_padded_last_delimiter_without_end_of_line_is_not_a_delimiter(tmp_path):
    """Rejects a reader that sees a dataset closed where pyuff does not (it would drop it)."""
    path = write(tmp_path / "a.uff", [dataset(4), dataset(4, rsp_node=2)])
    data = path.read_bytes()
    path.write_bytes(data[:-1] + PAD)  # exactly 80 columns, then the end of the file
    opened = marks(data)[2]
    last = data.count(b"\n")
    refused(
        path,
        rf"^a.uff: truncated: the file ends at line {last}, inside dataset 58 \(record 2, "
        rf"from line {opened}\), before the line '    -1' that closes it",
    )


@pytest.mark.parametrize("text", ["    -1 run 3, tube at 24 mm", "    -1X sweep"])
def test_a_text_line_starting_like_a_delimiter_is_not_one(tmp_path, text):
    """Rejects a reader that takes '    -1' followed by other text for a delimiter line."""
    g = rng_frf(6)
    (r,) = read_uff(write(tmp_path / "a.uff", [dataset(4, g, id2=text)]))
    np.testing.assert_allclose(r.values, g, rtol=1e-11)


# ------------------------------------------------------------------ damaged files
def two_frfs(tmp_path, lead=b""):
    """A file of two FRF datasets (after ``lead`` bytes) and its bytes."""
    path = write(tmp_path / "a.uff", [dataset(4), dataset(4, rsp_node=2)])
    data = lead + path.read_bytes()
    path.write_bytes(data)
    return path, data


def cut_message(data: bytes, cut: int, what: str, record: int) -> str:
    """The refusal of ``data[:cut]``, its lines counted here."""
    kept = data[:cut]
    last = kept.count(b"\n") + (0 if kept.endswith(b"\n") else 1)
    opened = marks(data)[2 * (record - 1)]
    return (
        rf"^a.uff: truncated: the file ends at line {last}, inside {what} \(record {record}, "
        rf"from line {opened}\), before the line '    -1' that closes it; export or copy "
        r"the file again$"
    )


def test_cut_after_a_leading_blank_line(tmp_path):
    """Rejects a reader that counts lines from the second byte of the file."""
    path, data = two_frfs(tmp_path, lead=b"\n")
    cut = data.rindex(b"\n    -1") - 40  # inside the last value line of dataset 2
    path.write_bytes(data[:cut])
    assert marks(data)[0] == 2
    refused(path, cut_message(data, cut, "dataset 58", 2))


def test_cut_at_the_end_of_a_line(tmp_path):
    """Rejects a reader that counts one line too many when the file ends with a newline."""
    path, data = two_frfs(tmp_path)
    opening = data.index(b"    -1\n    58", 10)  # dataset 2
    cut = opening + len(b"    -1\n")  # nothing after its opening line
    path.write_bytes(data[:cut])
    assert data[:cut].endswith(b"\n")
    refused(path, cut_message(data, cut, "a dataset", 2))


def test_cut_after_the_dataset_number(tmp_path):
    """Rejects a reader that needs a third line to name the dataset it was cut in."""
    path, data = two_frfs(tmp_path)
    opening = data.index(b"    -1\n    58", 10)
    cut = opening + len(b"    -1\n    58")
    path.write_bytes(data[:cut])
    refused(path, cut_message(data, cut, "dataset 58", 2))


def test_cut_in_a_dataset_after_another_kind(tmp_path):
    """Rejects a reader that names the first dataset of the file instead of the cut one."""
    sets = [
        pyuff.prepare_151(model_name="tube", description="d", db_app="x", program="pyuff"),
        dataset(4),
    ]
    path = write(tmp_path / "a.uff", sets)
    data = path.read_bytes()
    cut = len(data) - 60
    path.write_bytes(data[:cut])
    refused(path, cut_message(data, cut, "dataset 58", 2))


def test_cut_in_a_dataset_with_a_garbled_number(tmp_path):
    """Rejects a reader that fails on (rather than refuses) non-ASCII bytes where the number is."""
    path, data = two_frfs(tmp_path)
    opening = data.index(b"    -1\n    58", 10)
    start = opening + len(b"    -1\n")
    data = data[:start] + b"\xff\xfe  58" + data[start + 6 :]
    cut = len(data) - 60
    path.write_bytes(data[:cut])
    refused(path, cut_message(data, cut, "a dataset", 2))


def test_a_header_field_missing(tmp_path):
    """Rejects a reader that lets pyuff's parse error through without dataset and line."""
    path, data = two_frfs(tmp_path)
    lines = data.split(b"\n")
    record6 = marks(data)[2] - 1 + 7  # 0-based index of dataset 2's record 6
    assert lines[record6].split()[0] == b"4"
    lines[record6] = b" " * 5 + lines[record6][5:]  # its function type left blank
    path.write_bytes(b"\n".join(lines))
    refused(
        path,
        rf"^a.uff, record 2 \(line {marks(data)[2]}\): dataset 58 cannot be read \(.+\); "
        r"a binary file from some analyzers needs pyuff.fix_58b first$",
    )


def test_a_file_that_cannot_be_read(tmp_path):
    """Rejects a reader that loses the file's name when the file cannot be opened."""
    (tmp_path / "a.uff").mkdir()
    refused(tmp_path / "a.uff", r"^a.uff: cannot read the file \(.+\)$")
    refused(tmp_path / "b.uff", r"^b.uff: cannot read the file \(.*No such file.*\)$")


def test_pyuff_failing_on_the_file(tmp_path, monkeypatch):
    """Rejects a reader that loses the file's name when pyuff cannot parse the file."""
    path = write(tmp_path / "a.uff", [dataset(4)])

    def broken(filename):
        raise Exception(f"Error refreshing UFF file: {filename}")  # as pyuff words it

    monkeypatch.setattr(pyuff, "UFF", broken)
    refused(path, r"^a.uff: not a readable UFF file \(Error refreshing UFF file: .*a.uff\)$")


def test_marks_helper_counts_what_the_file_holds(tmp_path):
    """The line counting of these tests: two datasets, four delimiter lines, 13 header lines."""
    _, data = two_frfs(tmp_path)
    m = marks(data)
    assert len(m) == 4 and m[0] == 1
    assert re.match(rb"\s+58", data.split(b"\n")[m[2]])  # the line after dataset 2's opening


def test_a_file_without_dataset_58(tmp_path):
    """Rejects a reader whose refusal does not list the datasets the file holds instead."""
    units = dict(units_code=1, units_description="SI", temp_mode=1, length=1.0, force=1.0)
    sets = [
        pyuff.prepare_164(temp=1.0, temp_offset=273.15, **units),
        pyuff.prepare_151(model_name="tube", description="d", db_app="x", program="pyuff"),
        pyuff.prepare_164(temp=1.0, temp_offset=273.15, **units),
    ]
    refused(
        write(tmp_path / "a.uff", sets),
        r"^a.uff: no dataset 58 \(function record\) in the file \(datasets \[151, 164\]\)$",
    )
    (tmp_path / "b.uff").write_text("hello\n")
    refused(
        tmp_path / "b.uff",
        r"^b.uff: no dataset 58 \(function record\) in the file \(no UFF datasets\)$",
    )
