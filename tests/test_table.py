"""CSV tables read column by column: what read_csv gives back is what the file says.

Every file here is plain text written by hand, as an analyser's export, a
spreadsheet's "save as CSV" or ``np.savetxt`` lays it out; the expected
numbers are computed from the cells with numpy (magnitude and phase to
complex, dB to magnitude), not copied from lpvid.
"""

import re

import numpy as np
import pytest

from lpvid.readers.records import COHERENCE, FRF, VARIANCE, Channel, FileError
from lpvid.readers.table import read_csv

FREQS = np.array([1.0, 2.5, 4.0])


def write(tmp_path, lines, name="a.csv"):
    """The lines as a file, one per line, as a text editor saves them."""
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def refused(path, message):
    """read_csv's refusal of the file, its whole message matched (escaped)."""
    with pytest.raises(FileError, match="^" + re.escape(message) + "$"):
        read_csv(path)


def one_frf(records):
    assert [rec.kind for rec in records] == [FRF]
    return records[0]


# ------------------------------------------------------------------ what is read
def test_two_pairs_re_im_with_coherence_and_variance_every_field(tmp_path):
    """Rejects: records of coh/var dropped or missing file, column, units, axis unit or labels."""
    re1, im1 = [0.5, -0.25, 0.125], [-1.5, 0.75, 2.0]
    coh, var = [0.99, 0.9, 0.5], [1e-4, 2e-4, 4e-4]
    re2, im2 = [3.0, 2.0, 1.0], [0.0, -1.0, -2.0]
    head = (
        "freq [rad/s], head/torque re [m/s^2/N m], head/torque im, head/torque coh, "
        "head/torque var [(m/s^2/N m)^2], carriage/torque re, carriage/torque im [m/N m]"
    )
    rows = [
        f"{f}, {a}, {b}, {c}, {v}, {d}, {e}"
        for f, a, b, c, v, d, e in zip(FREQS, re1, im1, coh, var, re2, im2, strict=True)
    ]
    records = read_csv(write(tmp_path, [head, *rows]))
    assert [rec.kind for rec in records] == [FRF, COHERENCE, VARIANCE, FRF]
    head_ch, carriage, torque = Channel("head"), Channel("carriage"), Channel("torque")
    want = [
        ("columns 'head/torque re [m/s^2/N m]', 'head/torque im'", head_ch, "m/s^2/N m"),
        ("column 'head/torque coh'", head_ch, None),
        ("column 'head/torque var [(m/s^2/N m)^2]'", head_ch, "(m/s^2/N m)^2"),
        ("columns 'carriage/torque re', 'carriage/torque im [m/N m]'", carriage, "m/N m"),
    ]
    values = [
        np.array(re1) + 1j * np.array(im1),
        np.array(coh),
        np.array(var),
        np.array(re2) + 1j * np.array(im2),
    ]
    for rec, (col, response, units), v in zip(records, want, values, strict=True):
        assert rec.file == "a.csv"
        assert rec.name == col
        assert rec.response == response and rec.reference == torque
        assert rec.units == units
        assert rec.freq_unit == "rad/s"
        np.testing.assert_array_equal(rec.freqs_hz, FREQS)  # in the file's unit until checked()
        np.testing.assert_allclose(rec.values, v, rtol=1e-15, atol=0)
        if rec.kind != FRF:
            assert not np.iscomplexobj(rec.values)


def test_units_stated_on_only_one_of_re_and_im_are_the_pairs_units(tmp_path):
    """Rejects: the stated unit of re or im dropped when the other column states none."""
    for re_col, im_col in (("y/u re [g/N]", "y/u im"), ("y/u re", "y/u im [g/N]")):
        path = write(tmp_path, [f"freq [Hz], {re_col}, {im_col}", "1.0, 2.0, 3.0"])
        assert one_frf(read_csv(path)).units == "g/N"
    path = write(tmp_path, ["freq [Hz], y/u re, y/u im", "1.0, 2.0, 3.0"])
    assert one_frf(read_csv(path)).units is None


def test_frf_column_of_complex_cells_in_numpy_and_matlab_spellings(tmp_path):
    """Rejects: MATLAB's capital-I or sign-pair spellings misread, the frf record unnamed."""
    cells = ["(0.5+-0.25j)", "0.5 - 0.25i", "0.5+-0.25I", "0.5-+0.25i", "(-0.5--0.25j)", "2"]
    want = [0.5 - 0.25j, 0.5 - 0.25j, 0.5 - 0.25j, 0.5 - 0.25j, -0.5 + 0.25j, 2.0]
    lines = ["freq [kHz]; y1/u2 frf [V/V]"] + [f"{k + 1}; {c}" for k, c in enumerate(cells)]
    rec = one_frf(read_csv(write(tmp_path, lines)))
    assert rec.name == "column 'y1/u2 frf [V/V]'"
    assert (rec.response, rec.reference) == (Channel("y1"), Channel("u2"))
    assert rec.units == "V/V" and rec.freq_unit == "kHz"
    np.testing.assert_array_equal(rec.freqs_hz, np.arange(1.0, 7.0))
    np.testing.assert_allclose(rec.values, want, rtol=1e-15, atol=0)


def test_mag_and_phase_in_degrees_and_db_with_phase_in_radians(tmp_path):
    """Rejects: the mag/phase record unnamed, unitless or not per column; 'db [dB]' as FRF unit."""
    mag, deg = np.array([2.0, 0.5, 1.0]), np.array([30.0, -120.0, 180.0])
    db, rad = np.array([6.0, -20.0, 0.0]), np.array([0.5, -1.0, 3.0])
    head = "freq [Hz], y/u mag [m/N], y/u phase [deg], y/w db [dB], y/w phase [rad]"
    rows = [
        f"{f}, {m}, {p}, {d}, {r}" for f, m, p, d, r in zip(FREQS, mag, deg, db, rad, strict=True)
    ]
    first, second = read_csv(write(tmp_path, [head, *rows]))
    assert first.name == "columns 'y/u mag [m/N]', 'y/u phase [deg]'"
    assert first.units == "m/N"
    np.testing.assert_allclose(first.values, mag * np.exp(1j * np.deg2rad(deg)), rtol=1e-14)
    assert second.name == "columns 'y/w db [dB]', 'y/w phase [rad]'"
    assert second.reference == Channel("w")
    assert second.units is None  # dB says how the magnitude is written, not the FRF's unit
    np.testing.assert_allclose(second.values, 10 ** (db / 20) * np.exp(1j * rad), rtol=1e-14)


@pytest.mark.parametrize(("unit", "want"), [(None, None), ("DB", None), ("m/N", "m/N")])
def test_db_column_unit(tmp_path, unit, want):
    """Rejects: a 'db' column without unit crashing, '[DB]' kept as unit, a real unit dropped."""
    col = "y/u db" if unit is None else f"y/u db [{unit}]"
    path = write(tmp_path, [f"freq [Hz], {col}, y/u phase [DEG]", "1.0, 20.0, 90.0"])
    rec = one_frf(read_csv(path))
    assert rec.units == want
    np.testing.assert_allclose(rec.values, [10j], rtol=1e-14)


def test_unlabelled_single_pair_has_unlabelled_channels(tmp_path):
    """Rejects: a missing label read as some text (the response labelled where none was given)."""
    rec = one_frf(read_csv(write(tmp_path, ["freq [Hz], re, im", "1.0, 2.0, 3.0"])))
    assert rec.response == Channel(None) and rec.reference == Channel(None)
    np.testing.assert_array_equal(rec.values, [2 + 3j])


def test_single_data_row(tmp_path):
    """Rejects: a table of one frequency line taken for one without data."""
    rec = one_frf(read_csv(write(tmp_path, ["freq [Hz], y/u frf", "5.0, 1+1i"])))
    np.testing.assert_array_equal(rec.freqs_hz, [5.0])
    np.testing.assert_array_equal(rec.values, [1 + 1j])


def test_blank_and_empty_cell_rows_are_skipped_not_the_end(tmp_path):
    """Rejects: a blank line ending the table, a spreadsheet's row of empty cells taken as data."""
    lines = ["freq [Hz],y/u re,y/u im", "1,1,-1", "", "2.5,2,-2", ",,", " , , ", "4,3,-3", ",,"]
    rec = one_frf(read_csv(write(tmp_path, lines)))
    np.testing.assert_array_equal(rec.freqs_hz, FREQS)
    np.testing.assert_array_equal(rec.values, [1 - 1j, 2 - 2j, 3 - 3j])


def test_tab_and_semicolon_separated_tables(tmp_path):
    """Rejects: the delimiter of the header ignored when the cells are split."""
    for sep in ("\t", ";"):
        lines = [f"freq [Hz]{sep}y/u re{sep}y/u im", f"1.0{sep}0.5{sep}-0.5", f"2.5{sep}1{sep}2"]
        rec = one_frf(read_csv(write(tmp_path, lines)))
        np.testing.assert_array_equal(rec.freqs_hz, [1.0, 2.5])
        np.testing.assert_array_equal(rec.values, [0.5 - 0.5j, 1 + 2j])


def test_delimiter_is_not_taken_from_letters_of_the_labels(tmp_path):
    """Rejects: the header split at a letter (labels 3X/1X: more X than commas)."""
    lines = ["freq [Hz],3X/1X re,3X/1X im", "1.0,0.5,0.25"]
    rec = one_frf(read_csv(write(tmp_path, lines)))
    assert (rec.response, rec.reference) == (Channel("3X"), Channel("1X"))
    np.testing.assert_array_equal(rec.values, [0.5 + 0.25j])


def test_utf8_bom_of_a_spreadsheet_export_is_not_part_of_the_header(tmp_path):
    """Rejects: the byte-order mark Excel writes ('CSV UTF-8') left in front of 'freq'."""
    path = tmp_path / "a.csv"
    path.write_bytes(b"\xef\xbb\xbffreq [Hz],y/u frf\r\n1.0,(1+2j)\r\n")
    rec = one_frf(read_csv(path))
    assert rec.freq_unit == "Hz"
    np.testing.assert_array_equal(rec.values, [1 + 2j])


def test_comment_lines_before_the_header_indented_or_not(tmp_path):
    """Rejects: comment lines after the first miscounted or an indented '#' line taken as header."""
    lines = ["# gantry, tube 24 mm", "", "   # averages: 20", "freq [Hz], y/u frf", "1.0, 2i"]
    rec = one_frf(read_csv(write(tmp_path, lines)))
    np.testing.assert_array_equal(rec.values, [2j])


@pytest.mark.parametrize("sep", [",", "\t"])
def test_header_as_last_comment_line_as_np_savetxt_writes_it(tmp_path, sep):
    """Rejects: the '#' header's cells split at commas only, its '#' dropped with a letter more."""
    # np.savetxt(path, table, delimiter=sep, header=..., comments="#"): no space after '#'
    lines = ["# gantry", f"#freq [Hz]{sep}y/u frf", f"1.0{sep}(1+2j)", f"2.5{sep}(3-4j)"]
    rec = one_frf(read_csv(write(tmp_path, lines)))
    assert rec.name == "column 'y/u frf'"
    np.testing.assert_array_equal(rec.freqs_hz, [1.0, 2.5])
    np.testing.assert_array_equal(rec.values, [1 + 2j, 3 - 4j])


def test_indented_savetxt_header_and_a_single_row(tmp_path):
    """Rejects: the '#' header's leading blanks kept, a one-row savetxt table read past its end."""
    rec = one_frf(read_csv(write(tmp_path, ["  #freq [Hz],y/u frf", "1.0,(0.5+0j)"])))
    np.testing.assert_array_equal(rec.values, [0.5])


# ------------------------------------------------------------------ refusals
def test_unreadable_file_is_named(tmp_path):
    """Rejects: the reason of a decoding failure lost from the message."""
    path = tmp_path / "a.csv"
    path.write_bytes(b"# phase in \xb0\nfreq [Hz],y/u frf\n1,1\n")  # Latin-1 degree sign
    with pytest.raises(
        FileError, match=r"^a\.csv: cannot read the CSV file \(.*can't decode byte 0xb0"
    ):
        read_csv(path)


def test_file_of_only_comments_has_no_header(tmp_path):
    """Rejects: a file of comments and blank lines read past its end."""
    path = write(tmp_path, ["# gantry", "", "# nothing measured"])
    refused(path, "a.csv: no header line (expected e.g. 'freq [Hz], y1/u1 re, y1/u1 im')")


def test_header_column_not_in_the_layout_names_its_line(tmp_path):
    """Rejects: the file or line number of a bad header column wrong or missing."""
    path = write(tmp_path, ["# gantry", "# tube 24 mm", "freq [Hz], y/u real", "1, 2"])
    refused(
        path,
        "a.csv, line 3: column 'y/u real': expected '[OUTPUT/INPUT] QUANTITY [UNIT]' with "
        "QUANTITY one of freq, frf, re, im, mag, db, phase, coh, var",
    )
    path = write(tmp_path, ["# gantry", "# freq [Hz], y/u frq", "1, 2"])  # np.savetxt's header
    with pytest.raises(FileError, match=r"^a\.csv, line 2: column 'y/u frq': expected"):
        read_csv(path)


def test_savetxt_table_names_data_lines_by_their_line_in_the_file(tmp_path):
    """Rejects: data lines under a '#' header counted as if the header were a line of its own."""
    path = write(tmp_path, ["# gantry", "# freq [Hz], y/u frf", "1.0, (1+2j)", "2.0, oops"])
    refused(path, "a.csv, line 4, column 'y/u frf': not a number: 'oops'")


def test_frequency_first_with_its_unit_and_only_once(tmp_path):
    """Rejects: messages of the frequency column's refusals lost or naming another column."""
    path = write(tmp_path, ["y/u frf, freq [Hz]", "1, 2"])
    refused(path, "a.csv: the first column must be the frequency, e.g. 'freq [Hz]'")
    path = write(tmp_path, ["freq, y/u frf", "1, 2"])
    refused(path, "a.csv: column 'freq': state the frequency unit, e.g. 'freq [Hz]'")
    path = write(tmp_path, ["freq [Hz], y/u frf, f [Hz]", "1, 2, 1"])
    refused(path, "a.csv: column 'f [Hz]': a second frequency column")


def test_no_frf_columns_or_no_data(tmp_path):
    """Rejects: a table of frequencies only, or a header without rows, refused without reason."""
    refused(
        write(tmp_path, ["freq [Hz]", "1.0", "2.0"]),
        "a.csv: no FRF columns after the frequency column",
    )
    refused(
        write(tmp_path, ["# freq [Hz]", "1.0", "2.0"]),
        "a.csv: no FRF columns after the frequency column",
    )
    refused(
        write(tmp_path, ["freq [Hz], y/u frf", "", ",", ""]), "a.csv: no data rows under the header"
    )


def test_rows_of_the_wrong_length_and_cells_that_are_not_numbers(tmp_path):
    """Rejects: a short row's message without counts, a broken complex cell read as a sum."""
    path = write(tmp_path, ["freq [Hz], y/u re, y/u im", "1, 2, 3", "2, 4"])
    refused(path, "a.csv, line 3: 2 cells, the header has 3")
    for cell in ("(0.5+0.25j", "0.5+0.25j)", "((0.5+0.25j))", "()"):
        path = write(tmp_path, ["freq [Hz], y/u frf", f"1, {cell}"])
        refused(path, f"a.csv, line 2, column 'y/u frf': not a number: '{cell}'")


def test_complex_cell_outside_an_frf_column(tmp_path):
    """Rejects: the hint where complex values go lost from the message."""
    path = write(tmp_path, ["freq [Hz], y/u re, y/u im", "1, (2+1j), 3"])
    refused(
        path,
        "a.csv, line 2, column 'y/u re': a complex number where a real one belongs: '(2+1j)' "
        "(complex FRF values go in an 'OUT/IN frf' column)",
    )


def test_same_quantity_twice_in_a_pair(tmp_path):
    """Rejects: the message of a repeated column without the column and the pair."""
    path = write(tmp_path, ["freq [Hz], y/u re [N], y/u im, y/u re", "1, 2, 3, 4"])
    refused(path, "a.csv: column 'y/u re': re of 'y/u' twice")


@pytest.mark.parametrize(
    ("columns", "why"),
    [
        ("y/u frf, y/u re", "give one of frf, re/im or mag/phase columns, not frf and re"),
        ("re, im, mag, phase [deg]", "give one of frf, re/im or mag/phase columns, not re and mag"),
        ("re, im, db, phase [deg]", "give one of frf, re/im or mag/phase columns, not re and db"),
        ("y/u frf, y/u mag", "give one of frf, re/im or mag/phase columns, not frf and mag"),
        ("y/u frf, y/u im", "an frf column takes no im or phase column"),
        ("y/u frf, y/u phase [deg]", "an frf column takes no im or phase column"),
        ("y/u re, y/u im, y/u phase [deg]", "give re/im or mag/phase columns, not both"),
        (
            "y/u mag, y/u db, y/u phase [deg]",
            "needs an frf column, re and im columns, or mag (or db) and phase columns; "
            "found db, mag, phase",
        ),
        (
            "y/u mag, y/u coh",
            "needs an frf column, re and im columns, or mag (or db) and phase columns; "
            "found coh, mag",
        ),
        (
            "y/u phase [rad], y/u im",
            "needs an frf column, re and im columns, or mag (or db) and phase columns; "
            "found im, phase",
        ),
    ],
)
def test_columns_of_a_pair_that_do_not_make_one_frf(tmp_path, columns, why):
    """Rejects: a pair of mixed or incomplete forms read from part of its columns, or misnamed."""
    n = columns.count(",") + 2
    path = write(tmp_path, [f"freq [Hz], {columns}", ", ".join(["1"] * n)])
    shown = "'y/u'" if "y/u" in columns else "the unlabelled pair"
    refused(path, f"a.csv: {shown}: {why}")


@pytest.mark.parametrize("unit", [None, "grad"])
def test_phase_unit_must_be_deg_or_rad(tmp_path, unit):
    """Rejects: a phase without unit or in an unknown unit read (or crashing) instead of named."""
    col = "y/u phase" if unit is None else f"y/u phase [{unit}]"
    path = write(tmp_path, [f"freq [Hz], y/u mag, {col}", "1, 2, 3"])
    refused(path, f"a.csv: column '{col}': state the phase unit, [deg] or [rad]")


def test_inconsistent_re_and_im_units_name_both_columns(tmp_path):
    """Rejects: the columns of disagreeing units left out of the message."""
    path = write(
        tmp_path,
        [
            "freq [Hz], y/u re [m/s^2/N m], y/u im [m/s^2/Nm], x/u re [g/N], x/u im [m/N]",
            "1, 2, 3, 4, 5",
        ],
    )
    refused(
        path,
        "a.csv: columns 'x/u re [g/N]' and 'x/u im [m/N]': inconsistent units [g/N] and [m/N]",
    )
